//! Single-channel 32-bit float OpenEXR encoder, writing to memory: the `exr` crate (pinned)
//! writes the header, offset table and chunk layout; the ZIP blocks are compressed here.
//!
//! Output: one part, scanline blocks, one channel `"Y"` of `f32` samples (row-major, row 0 at the
//! top), `lineOrder = INCREASING_Y`. The bytes depend only on the inputs, never on the machine or
//! the thread count:
//!
//! * Blocks are compressed independently (on rayon's threads) and written in increasing `y`
//!   order, so the file is the same on one thread or many.
//! * The `exr` crate keeps custom attributes in a `HashMap` whose iteration order changes from
//!   one map to the next, so it writes them in a different order on each call. After writing,
//!   [`encode_exr`] therefore sorts all header attributes by name (byte-wise, as the OpenEXR C++
//!   library writes them). The header keeps its length, so the chunk offsets stay valid.
//!
//! ## Why ZIP blocks are compressed here (write your own only where speed requires it)
//!
//! The `exr` crate 1.74.2 deflates ZIP blocks with miniz_oxide at a fixed level 4 (no option),
//! about 190 ms per 1440² image: three quarters of the CPU time of the whole protocol. So for
//! [`ExrCompression::Zip`] (16 scan lines per block) and [`ExrCompression::Zips`] (1 line) this
//! module does the OpenEXR ZIP preprocessing itself, exactly as the OpenEXR library and the
//! `exr` crate do (little-endian samples; even-indexed bytes to the first half of the block and
//! odd-indexed bytes to the second; then each byte replaced by `(b[i] − b[i−1] + 128) mod 256`,
//! the first byte kept), compresses the result into a zlib stream with the encoder made for these
//! bytes in [`exr_deflate`](crate::output::exr_deflate) (Huffman codes from each block's own
//! counts and runs at distance 1; the same bytes on every platform), and hands the finished blocks to the crate's chunk writer (`exr::block`). As in both libraries, a block
//! whose compressed form is not smaller than its raw form is stored raw (readers recognise it by
//! its size). The bytes it deflates are exactly the crate's (a test inflates both).
//! [`ExrCompression::Rle`] and [`ExrCompression::None`] blocks come from the crate's own
//! compressor (`Compression::compress_image_section_to_le`).

use ::exr::block::chunk::{Chunk, CompressedBlock, CompressedScanLineBlock};
use ::exr::block::writer::ChunksWriter;
use ::exr::meta::attribute::{AttributeValue, IntegerBounds, Text};
use ::exr::meta::header::{Header, standard_names};
use ::exr::prelude::*;
use rayon::prelude::*;
use std::io::Cursor;
use std::result::Result;

/// The value of a custom EXR header attribute.
#[derive(Debug, Clone, PartialEq)]
pub enum ExrAttr {
    /// An OpenEXR `string` attribute (Latin-1 characters only, i.e. code points ≤ 255).
    Text(String),
    /// An OpenEXR `double` attribute.
    F64(f64),
    /// An OpenEXR `int` attribute.
    I32(i32),
}

pub use crate::scenario::ExrCompression;

/// The `exr` crate's compression for a scenario's `exr_compression`.
fn to_exr(compression: ExrCompression) -> Compression {
    match compression {
        ExrCompression::None => Compression::Uncompressed,
        ExrCompression::Rle => Compression::RLE,
        ExrCompression::Zip => Compression::ZIP16,
        ExrCompression::Zips => Compression::ZIP1,
    }
}

/// Encodes a `width × height` row-major `f32` image as a single-channel (`"Y"`) OpenEXR file in
/// memory with [`ExrCompression::Zip`]; see [`encode_exr_with`].
pub fn encode_exr(
    width: u32,
    height: u32,
    pixels: &[f32],
    attributes: &[(&str, ExrAttr)],
) -> Result<Vec<u8>, String> {
    encode_exr_with(width, height, pixels, attributes, ExrCompression::default())
}

/// Encodes a `width × height` row-major `f32` image as a single-channel (`"Y"`) OpenEXR file in
/// memory with the given compression.
///
/// Each `(name, value)` of `attributes` becomes a header attribute. Names must be non-empty,
/// Latin-1, unique, and not one of OpenEXR's standard attribute names
/// (`exr::meta::header::standard_names::ALL`, e.g. `channels`, `owner`, `comments`), except
/// these, which set the standard attribute of that name: `"software"` ([`ExrAttr::Text`]),
/// `"xDensity"` (pixels per inch, [`ExrAttr::F64`], stored as a float) and `"pixelAspectRatio"`
/// (a pixel's width over its height, [`ExrAttr::F64`], stored as a float; default 1).
/// Errors: a pixel count that is not `width · height`, a zero or too large dimension, a
/// rejected attribute, or an encoder failure.
pub fn encode_exr_with(
    width: u32,
    height: u32,
    pixels: &[f32],
    attributes: &[(&str, ExrAttr)],
    compression: ExrCompression,
) -> Result<Vec<u8>, String> {
    encode_exr_channels(width, height, &[("Y", pixels)], attributes, compression)
}

/// Encodes several `f32` channels of one `width × height` image (each row-major) as one
/// OpenEXR part, as [`encode_exr_with`] does for one channel. Channel names must be unique,
/// non-empty Latin-1; the file lists them sorted byte-wise, as OpenEXR requires, and each scan
/// line stores the channels in that order.
pub fn encode_exr_channels(
    width: u32,
    height: u32,
    channels: &[(&str, &[f32])],
    attributes: &[(&str, ExrAttr)],
    compression: ExrCompression,
) -> Result<Vec<u8>, String> {
    if width == 0 || height == 0 || width > i32::MAX as u32 || height > i32::MAX as u32 {
        return Err(format!("EXR image size {width}×{height} is not supported"));
    }
    let mut sorted: Vec<(&str, &[f32])> = channels.to_vec();
    sorted.sort_by(|a, b| a.0.as_bytes().cmp(b.0.as_bytes()));
    if sorted.is_empty() {
        return Err("an EXR image needs at least one channel".into());
    }
    for (i, (name, pixels)) in sorted.iter().enumerate() {
        if name.is_empty() || (i > 0 && sorted[i - 1].0 == *name) {
            return Err(format!("EXR channel name {name:?} is empty or given twice"));
        }
        latin1("channel name", name)?;
        if pixels.len() as u64 != u64::from(width) * u64::from(height) {
            return Err(format!(
                "EXR image is {width}×{height} but {} pixels were given",
                pixels.len()
            ));
        }
    }
    let (layer_attributes, pixel_aspect) = layer_attributes(attributes)?;
    let (w, h) = (width as usize, height as usize);
    // The header exactly as the crate's image writer infers it; the samples are not needed here.
    let layer = Layer::new(
        (w, h),
        layer_attributes,
        Encoding {
            compression: to_exr(compression),
            blocks: Blocks::ScanLines,
            line_order: LineOrder::Increasing,
        },
        AnyChannels::sort(SmallVec::from_vec(
            sorted
                .iter()
                .map(|(name, _)| AnyChannel::new(*name, FlatSamples::F32(Vec::new())))
                .collect(),
        )),
    );
    let mut image_attributes = ImageAttributes::new(IntegerBounds::new(
        layer.attributes.layer_position,
        layer.size,
    ));
    image_attributes.pixel_aspect = pixel_aspect;
    let headers = Image::new(image_attributes, layer)
        .write()
        .infer_meta_data();
    // A scan line holds each channel's samples in turn (sorted order).
    let interleaved: std::borrow::Cow<[f32]> = if sorted.len() == 1 {
        std::borrow::Cow::Borrowed(sorted[0].1)
    } else {
        let mut v = Vec::with_capacity(w * h * sorted.len());
        for y in 0..h {
            for (_, pixels) in &sorted {
                v.extend_from_slice(&pixels[y * w..(y + 1) * w]);
            }
        }
        std::borrow::Cow::Owned(v)
    };
    let blocks = compress_blocks(&headers[0], w, sorted.len(), h, &interleaved, compression)?;
    let mut out = Cursor::new(Vec::with_capacity(
        blocks.iter().map(|b| b.len() + 8).sum::<usize>() + 4096,
    ));
    let lines = to_exr(compression).scan_lines_per_block();
    ::exr::block::write(&mut out, headers, true, |_meta, writer| {
        for (index, block) in blocks.into_iter().enumerate() {
            let chunk = Chunk {
                layer_index: 0,
                compressed_block: CompressedBlock::ScanLine(CompressedScanLineBlock {
                    y_coordinate: (index * lines) as i32,
                    compressed_pixels_le: block,
                }),
            };
            writer.write_chunk(index, chunk)?;
        }
        Ok(())
    })
    .map_err(|e| format!("EXR encoding failed: {e}"))?;
    let mut bytes = out.into_inner();
    sort_header_attributes(&mut bytes)?;
    Ok(bytes)
}

/// The pixel blocks of the file in increasing `y`, each as stored (compressed or raw, little
/// endian). Blocks are independent, so they are compressed in parallel and collected in order.
fn compress_blocks(
    header: &Header,
    w: usize,
    channels: usize,
    h: usize,
    pixels: &[f32],
    compression: ExrCompression,
) -> Result<Vec<Vec<u8>>, String> {
    let line = w * channels;
    let lines = to_exr(compression).scan_lines_per_block();
    let count = h.div_ceil(lines);
    (0..count)
        .into_par_iter()
        .map(|index| {
            let y = index * lines;
            let rows = lines.min(h - y);
            let block = &pixels[y * line..(y + rows) * line];
            match compression {
                ExrCompression::Zip | ExrCompression::Zips => Ok(zip_block(block)),
                ExrCompression::None | ExrCompression::Rle => {
                    let ne: Vec<u8> = block.iter().flat_map(|v| v.to_ne_bytes()).collect();
                    let bounds = IntegerBounds::new(Vec2(0, y as i32), Vec2(w, rows));
                    to_exr(compression)
                        .compress_image_section_to_le(header, ne, bounds)
                        .map_err(|e| format!("EXR encoding failed: {e}"))
                }
            }
        })
        .collect()
}

/// One OpenEXR ZIP block: the samples as little-endian bytes, split into even- and odd-indexed
/// bytes, delta-coded (`b[i] − b[i−1] + 128`), then compressed as a zlib stream by
/// [`exr_deflate`](crate::output::exr_deflate). Stored raw (little-endian samples) if that is not
/// larger than the compressed form, as OpenEXR does.
fn zip_block(samples: &[f32]) -> Vec<u8> {
    let n = samples.len() * 4;
    let compressed = crate::output::exr_deflate::zlib_compress(&zip_predicted(samples));
    if compressed.len() < n {
        compressed
    } else {
        samples.iter().flat_map(|v| v.to_le_bytes()).collect()
    }
}

/// The bytes OpenEXR's ZIP compression deflates for one block of samples: little-endian bytes
/// split into even- and odd-indexed halves, then delta-coded (`b[i] − b[i−1] + 128`, the first
/// byte kept). Public for `examples/encoder_levels.rs`.
pub fn zip_predicted(samples: &[f32]) -> Vec<u8> {
    let n = samples.len() * 4;
    let mut split = vec![0u8; n];
    let (even, odd) = split.split_at_mut(n / 2);
    for ((v, e), o) in samples
        .iter()
        .zip(even.chunks_exact_mut(2))
        .zip(odd.chunks_exact_mut(2))
    {
        let b = v.to_le_bytes();
        e.copy_from_slice(&[b[0], b[2]]);
        o.copy_from_slice(&[b[1], b[3]]);
    }
    let mut previous = split[0];
    for b in &mut split[1..] {
        let current = *b;
        *b = current.wrapping_sub(previous).wrapping_add(128);
        previous = current;
    }
    split
}

fn latin1(what: &str, s: &str) -> Result<Text, String> {
    Text::new_or_none(s).ok_or_else(|| format!("EXR {what} must be Latin-1: {s:?}"))
}

/// The layer's attributes and the image's pixel aspect ratio (default 1).
fn layer_attributes(attributes: &[(&str, ExrAttr)]) -> Result<(LayerAttributes, f32), String> {
    let mut la = LayerAttributes::default();
    let mut pixel_aspect = 1.0f32;
    for (i, (name, value)) in attributes.iter().enumerate() {
        if name.is_empty() || name.contains('\0') {
            return Err(format!(
                "EXR attribute name {name:?} is empty or contains NUL"
            ));
        }
        if attributes[..i].iter().any(|(n, _)| n == name) {
            return Err(format!("EXR attribute {name:?} is given twice"));
        }
        let key = latin1("attribute name", name)?;
        match (*name, value) {
            ("software", ExrAttr::Text(s)) => {
                la.software_name = Some(latin1("attribute \"software\"", s)?);
                continue;
            }
            ("xDensity", &ExrAttr::F64(v)) => {
                la.horizontal_density = Some(positive_f32(name, v)?);
                continue;
            }
            ("pixelAspectRatio", &ExrAttr::F64(v)) => {
                pixel_aspect = positive_f32(name, v)?;
                continue;
            }
            ("software" | "xDensity" | "pixelAspectRatio", _) => {
                return Err(format!(
                    "EXR attribute {name:?} must be {}",
                    if *name == "software" {
                        "text"
                    } else {
                        "a number"
                    }
                ));
            }
            _ => {}
        }
        if standard_names::ALL.contains(&key.as_slice()) {
            return Err(format!(
                "EXR attribute name {name:?} is reserved by OpenEXR"
            ));
        }
        let value = match value {
            ExrAttr::Text(s) => AttributeValue::Text(latin1(&format!("attribute {name:?}"), s)?),
            ExrAttr::F64(v) => AttributeValue::F64(*v),
            ExrAttr::I32(v) => AttributeValue::I32(*v),
        };
        la.other.insert(key, value);
    }
    Ok((la, pixel_aspect))
}

/// `v` as a finite, positive `f32` for a standard float attribute.
fn positive_f32(name: &str, v: f64) -> Result<f32, String> {
    let f = v as f32;
    if f.is_finite() && f > 0.0 {
        Ok(f)
    } else {
        Err(format!(
            "EXR attribute {name:?} must be a positive number, not {v}"
        ))
    }
}

/// Reorders the attributes of a single-part EXR header by name, in place. The header is the
/// sequence `name\0 type\0 size:i32le value[size]` after the 8-byte magic and version, ended by
/// a single `\0`; reordering keeps its length, so the offset table that follows stays valid.
fn sort_header_attributes(bytes: &mut [u8]) -> Result<(), String> {
    let bad = || "EXR header could not be parsed for canonical ordering".to_string();
    if bytes.len() < 8 || bytes[..4] != [0x76, 0x2f, 0x31, 0x01] || bytes[5] & 0x10 != 0 {
        return Err(bad()); // not EXR, or multi-part (flag bit 12)
    }
    let cstr_end = |from: usize| bytes[from..].iter().position(|&b| b == 0).map(|p| from + p);
    let mut attrs: Vec<(usize, usize, usize)> = Vec::new(); // (start, name end, end)
    let mut pos = 8;
    loop {
        let name_end = cstr_end(pos).ok_or_else(bad)?;
        if name_end == pos {
            break; // the empty name ends the header
        }
        let type_end = cstr_end(name_end + 1).ok_or_else(bad)?;
        let size_at = type_end + 1;
        let size = bytes.get(size_at..size_at + 4).ok_or_else(bad)?;
        let size = i32::from_le_bytes(size.try_into().unwrap());
        let end = usize::try_from(size)
            .ok()
            .and_then(|s| (size_at + 4).checked_add(s))
            .ok_or_else(bad)?;
        if end > bytes.len() {
            return Err(bad());
        }
        attrs.push((pos, name_end, end));
        pos = end;
    }
    let (start, stop) = (8, pos);
    let mut sorted = attrs.clone();
    sorted.sort_by(|a, b| bytes[a.0..a.1].cmp(&bytes[b.0..b.1]));
    if sorted == attrs {
        return Ok(());
    }
    let mut header = Vec::with_capacity(stop - start);
    for &(s, _, e) in &sorted {
        header.extend_from_slice(&bytes[s..e]);
    }
    bytes[start..stop].copy_from_slice(&header);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::NoiseKey;

    const ALL: [ExrCompression; 4] = [
        ExrCompression::None,
        ExrCompression::Rle,
        ExrCompression::Zip,
        ExrCompression::Zips,
    ];

    fn noisy(w: usize, h: usize, level: f64, i_max: u16) -> Vec<f32> {
        crate::output::test_image::noisy_disc(
            w,
            h,
            level,
            i_max,
            &NoiseKey::derive(4, 0, 0, "exr", "test"),
        )
        .into_iter()
        .map(f32::from)
        .collect()
    }

    fn attrs() -> Vec<(&'static str, ExrAttr)> {
        vec![
            ("software", ExrAttr::Text("rsasim 0.1".into())),
            ("rsasim_run", ExrAttr::Text("n2-r07".into())),
            ("sid_mm", ExrAttr::F64(1800.25)),
            ("pixel_pitch_mm", ExrAttr::F64(0.298_611)),
            ("seed", ExrAttr::I32(-42)),
            ("bpp", ExrAttr::I32(16)),
            ("noise_level", ExrAttr::F64(0.45)),
            ("exposure", ExrAttr::Text("ap".into())),
            ("detector", ExrAttr::Text("det_a".into())),
            (
                "a_long_attribute_name_longer_than_31_bytes",
                ExrAttr::Text("Zürich".into()),
            ),
        ]
    }

    type Flat = Image<Layer<AnyChannels<FlatSamples>>>;

    fn read_back(bytes: &[u8]) -> Flat {
        read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .first_valid_layer()
            .all_attributes()
            .non_parallel()
            .from_buffered(Cursor::new(bytes))
            .unwrap()
    }

    #[test]
    fn several_channels_round_trip_by_name_for_every_compression() {
        let (w, h) = (37u32, 21u32);
        let n = (w * h) as usize;
        let bone = awkward(n, 3);
        let metal: Vec<f32> = (0..n).map(|i| i as f32 * 0.25).collect();
        for compression in [
            ExrCompression::None,
            ExrCompression::Rle,
            ExrCompression::Zip,
            ExrCompression::Zips,
        ] {
            // Given out of order: the file sorts them.
            let bytes = encode_exr_channels(
                w,
                h,
                &[
                    ("pathlength_mm.metal", &metal),
                    ("pathlength_mm.bone", &bone),
                ],
                &[],
                compression,
            )
            .unwrap();
            let img = read_back(&bytes);
            let list = &img.layer_data.channel_data.list;
            assert_eq!(list.len(), 2);
            assert_eq!(list[0].name.to_string(), "pathlength_mm.bone");
            assert_eq!(list[1].name.to_string(), "pathlength_mm.metal");
            let got: Vec<f32> = list[0].sample_data.values_as_f32().collect();
            assert!(same_bits(&got, &bone), "{compression:?}");
            let got: Vec<f32> = list[1].sample_data.values_as_f32().collect();
            assert!(same_bits(&got, &metal), "{compression:?}");
        }
        assert!(
            encode_exr_channels(
                w,
                h,
                &[("a", &metal), ("a", &bone)],
                &[],
                ExrCompression::Zip
            )
            .is_err()
        );
    }

    #[test]
    fn round_trip_and_deterministic_for_every_compression() {
        let (w, h) = (131u32, 45u32);
        let mut px = noisy(w as usize, h as usize, 0.3, 4095);
        px[0] = -1.5;
        px[1] = f32::MAX;
        px[2] = 1e-40; // subnormal
        for c in ALL {
            let first = encode_exr_with(w, h, &px, &attrs(), c).unwrap();
            for _ in 0..4 {
                let again = encode_exr_with(w, h, &px, &attrs(), c).unwrap();
                assert!(again == first, "{c:?}: two encodes differ");
            }
            let img = read_back(&first);
            let layer = &img.layer_data;
            assert_eq!(layer.size, Vec2(w as usize, h as usize));
            assert_eq!(layer.encoding.compression, to_exr(c));
            assert_eq!(layer.encoding.line_order, LineOrder::Increasing);
            assert_eq!(layer.channel_data.list.len(), 1);
            let ch = &layer.channel_data.list[0];
            assert_eq!(ch.name, Text::from("Y"));
            let back: Vec<f32> = ch.sample_data.values_as_f32().collect();
            assert!(
                back.iter()
                    .zip(&px)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "{c:?}"
            );
            let a = &layer.attributes;
            assert_eq!(a.software_name, Some(Text::from("rsasim 0.1")));
            for (name, value) in attrs().into_iter().skip(1) {
                let got = a
                    .other
                    .get(&Text::new_or_panic(name))
                    .unwrap_or_else(|| panic!("{name}"));
                match (value, got) {
                    (ExrAttr::Text(s), AttributeValue::Text(t)) => {
                        assert_eq!(*t, Text::new_or_panic(&s))
                    }
                    (ExrAttr::F64(v), AttributeValue::F64(g)) => {
                        assert_eq!(v.to_bits(), g.to_bits())
                    }
                    (ExrAttr::I32(v), AttributeValue::I32(g)) => assert_eq!(v, *g),
                    (v, g) => panic!("{name}: wrote {v:?}, read {g:?}"),
                }
            }
            assert_eq!(a.other.len(), attrs().len() - 1);
        }
    }

    /// Bit patterns that must survive: signs, zeros, subnormals, infinities, extremes, and
    /// pseudo-random bits (no NaN) that deflate cannot shrink, so those blocks are stored raw.
    fn awkward(n: usize, seed: u64) -> Vec<f32> {
        let mut x = seed | 1;
        (0..n)
            .map(|i| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                match i % 11 {
                    0 => -0.0,
                    1 => f32::INFINITY,
                    2 => f32::from_bits(1), // smallest subnormal
                    3 => -f32::MAX,
                    4 => 65535.0,
                    _ => {
                        let v = f32::from_bits(x as u32);
                        if v.is_nan() { 1.0 } else { v }
                    }
                }
            })
            .collect()
    }

    fn decode_y(bytes: &[u8]) -> Vec<f32> {
        read_back(bytes).layer_data.channel_data.list[0]
            .sample_data
            .values_as_f32()
            .collect()
    }

    fn same_bits(a: &[f32], b: &[f32]) -> bool {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
    }

    #[test]
    fn round_trip_bit_identical_for_awkward_sizes_and_values() {
        for (w, h) in [
            (1, 1),
            (1, 17),
            (1, 16),
            (7, 1),
            (3, 15),
            (16, 16),
            (33, 47),
            (200, 40),
        ] {
            let images = [
                noisy(w, h, 0.3, 4095),
                noisy(w, h, 0.0, 65535),
                awkward(w * h, (w * 1000 + h) as u64),
            ];
            for px in &images {
                for c in ALL {
                    let bytes = encode_exr_with(w as u32, h as u32, px, &[], c).unwrap();
                    let img = read_back(&bytes);
                    assert_eq!(img.layer_data.size, Vec2(w, h));
                    assert_eq!(img.layer_data.encoding.compression, to_exr(c));
                    assert!(same_bits(&decode_y(&bytes), px), "{w}×{h} {c:?}");
                }
            }
        }
    }

    /// Our ZIP blocks hold exactly the bytes the `exr` crate's blocks hold (both inflated), or are
    /// stored raw exactly where the crate stores them raw, for ZIP (16 lines) and ZIPS (1 line),
    /// compressible and incompressible data.
    #[test]
    fn zip_blocks_hold_the_exr_crates_bytes() {
        let (w, h) = (37usize, 35usize);
        for px in [noisy(w, h, 0.3, 65535), awkward(w * h, 9)] {
            for c in [ExrCompression::Zip, ExrCompression::Zips] {
                let layer = Layer::new(
                    (w, h),
                    LayerAttributes::default(),
                    Encoding {
                        compression: to_exr(c),
                        blocks: Blocks::ScanLines,
                        line_order: LineOrder::Increasing,
                    },
                    AnyChannels::sort(SmallVec::from_vec(vec![AnyChannel::new(
                        "Y",
                        FlatSamples::F32(Vec::new()),
                    )])),
                );
                let header = Image::from_layer(layer).write().infer_meta_data().remove(0);
                let lines = to_exr(c).scan_lines_per_block();
                for y in (0..h).step_by(lines) {
                    let rows = lines.min(h - y);
                    let block = &px[y * w..(y + rows) * w];
                    let ne: Vec<u8> = block.iter().flat_map(|v| v.to_ne_bytes()).collect();
                    let bounds = IntegerBounds::new(Vec2(0, y as i32), Vec2(w, rows));
                    let theirs = to_exr(c)
                        .compress_image_section_to_le(&header, ne, bounds)
                        .unwrap();
                    let ours = zip_block(block);
                    // A block is stored raw (little-endian samples, its size) or deflated (the
                    // predicted bytes): both decode to the samples, and every deflated block of
                    // the crate inflates to our prediction.
                    let raw = block.len() * 4;
                    let le: Vec<u8> = block.iter().flat_map(|v| v.to_le_bytes()).collect();
                    for (who, b) in [("ours", &ours), ("theirs", &theirs)] {
                        let holds = if b.len() == raw {
                            b.to_vec() == le
                        } else {
                            miniz_oxide::inflate::decompress_to_vec_zlib(b).unwrap()
                                == zip_predicted(block)
                        };
                        assert!(holds, "{who}: {c:?} block at y = {y}");
                    }
                    assert!(ours.len() <= raw, "{c:?} block at y = {y}");
                }
            }
        }
    }

    /// The file layout (header, offset table, chunks) is the crate's image writer's: with
    /// compression None every byte matches a file written by `exr::image`.
    #[test]
    fn layout_matches_the_exr_crate_image_writer() {
        let (w, h) = (29u32, 18u32);
        let px = noisy(w as usize, h as usize, 0.3, 4095);
        let ours = encode_exr_with(w, h, &px, &attrs(), ExrCompression::None).unwrap();
        let layer = Layer::new(
            (w as usize, h as usize),
            layer_attributes(&attrs()).unwrap().0,
            Encoding {
                compression: Compression::Uncompressed,
                blocks: Blocks::ScanLines,
                line_order: LineOrder::Increasing,
            },
            AnyChannels::sort(SmallVec::from_vec(vec![AnyChannel::new(
                "Y",
                FlatSamples::F32(px.clone()),
            )])),
        );
        let mut theirs = Cursor::new(Vec::new());
        Image::from_layer(layer)
            .write()
            .non_parallel()
            .to_buffered(&mut theirs)
            .unwrap();
        let mut theirs = theirs.into_inner();
        sort_header_attributes(&mut theirs).unwrap();
        assert!(ours == theirs);
    }

    #[test]
    fn same_bytes_on_one_and_many_threads() {
        let (w, h) = (300u32, 75u32);
        let px = noisy(w as usize, h as usize, 0.45, 65535);
        for c in ALL {
            let on = |threads: usize| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap()
                    .install(|| encode_exr_with(w, h, &px, &attrs(), c).unwrap())
            };
            let one = on(1);
            assert!(on(2) == one && on(5) == one, "{c:?}");
        }
    }

    #[test]
    fn header_attributes_are_sorted_by_name() {
        let bytes = encode_exr(4, 2, &[0.0; 8], &attrs()).unwrap();
        let mut names = Vec::new();
        let mut pos = 8;
        while bytes[pos] != 0 {
            let n = bytes[pos..].iter().position(|&b| b == 0).unwrap();
            names.push(bytes[pos..pos + n].to_vec());
            let t = bytes[pos + n + 1..].iter().position(|&b| b == 0).unwrap();
            let size_at = pos + n + 1 + t + 1;
            let size = i32::from_le_bytes(bytes[size_at..size_at + 4].try_into().unwrap());
            pos = size_at + 4 + size as usize;
        }
        let mut sorted = names.clone();
        sorted.sort();
        assert_eq!(names, sorted);
        assert!(names.contains(&b"sid_mm".to_vec()) && names.contains(&b"channels".to_vec()));
    }

    #[test]
    fn default_is_zip_and_no_attributes_is_fine() {
        let px: Vec<f32> = (0..12).map(|i| i as f32).collect();
        let a = encode_exr(4, 3, &px, &[]).unwrap();
        assert_eq!(
            a,
            encode_exr_with(4, 3, &px, &[], ExrCompression::Zip).unwrap()
        );
        let back: Vec<f32> = read_back(&a).layer_data.channel_data.list[0]
            .sample_data
            .values_as_f32()
            .collect();
        assert_eq!(back, px);
    }

    #[test]
    fn rejects_bad_input() {
        let ok = |a: &[(&str, ExrAttr)]| encode_exr(2, 1, &[0.0, 1.0], a);
        assert!(encode_exr(2, 2, &[0.0; 3], &[]).is_err());
        assert!(encode_exr(0, 2, &[], &[]).is_err());
        assert!(ok(&[("channels", ExrAttr::I32(1))]).is_err());
        assert!(ok(&[("owner", ExrAttr::Text("x".into()))]).is_err());
        assert!(ok(&[("", ExrAttr::I32(1))]).is_err());
        assert!(ok(&[("x", ExrAttr::I32(1)), ("x", ExrAttr::I32(2))]).is_err());
        assert!(ok(&[("x", ExrAttr::Text("€".into()))]).is_err());
        assert!(ok(&[("software", ExrAttr::F64(1.0))]).is_err());
        assert!(ok(&[("xDensity", ExrAttr::Text("1".into()))]).is_err());
        assert!(ok(&[("xDensity", ExrAttr::F64(0.0))]).is_err());
        assert!(ok(&[("pixelAspectRatio", ExrAttr::F64(f64::NAN))]).is_err());
        assert!(ok(&[("x", ExrAttr::Text("ok".into()))]).is_ok());
    }

    #[test]
    fn density_and_pixel_aspect_are_the_standard_attributes() {
        // A 0.3 × 0.25 mm pitch: 25.4 / 0.3 pixels per inch, pixels 1.2 times as wide as high.
        let a = encode_exr(
            2,
            1,
            &[0.0, 1.0],
            &[
                ("xDensity", ExrAttr::F64(25.4 / 0.3)),
                ("pixelAspectRatio", ExrAttr::F64(0.3 / 0.25)),
            ],
        )
        .unwrap();
        let back = read_back(&a);
        assert_eq!(back.attributes.pixel_aspect, 1.2f32);
        assert_eq!(
            back.layer_data.attributes.horizontal_density,
            Some((25.4f64 / 0.3) as f32)
        );
        assert!(back.layer_data.attributes.other.is_empty());
        let plain = read_back(&encode_exr(2, 1, &[0.0, 1.0], &[]).unwrap());
        assert_eq!(plain.attributes.pixel_aspect, 1.0);
        assert_eq!(plain.layer_data.attributes.horizontal_density, None);
    }

    #[test]
    fn serde_names_and_default() {
        assert_eq!(ExrCompression::default(), ExrCompression::Zip);
        let names: Vec<String> = ALL
            .iter()
            .map(|c| serde_json::to_string(c).unwrap())
            .collect();
        assert_eq!(names, ["\"none\"", "\"rle\"", "\"zip\"", "\"zips\""]);
        let _ = schemars::schema_for!(ExrCompression);
    }

    /// Timings for the report:
    /// `cargo test --release --lib output::exr::tests::bench -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn bench_exr_1440() {
        let w = 1440u32;
        let px = noisy(w as usize, w as usize, 15000.0 / 65535.0, 65535);
        for c in ALL {
            let mut times = Vec::new();
            let mut size = 0;
            for _ in 0..5 {
                let t = std::time::Instant::now();
                let bytes = encode_exr_with(w, w, &px, &attrs(), c).unwrap();
                times.push(t.elapsed().as_secs_f64());
                size = bytes.len();
            }
            times.sort_by(f64::total_cmp);
            let bytes = encode_exr_with(w, w, &px, &attrs(), c).unwrap();
            let t = std::time::Instant::now();
            let img = read_back(&bytes);
            let dt = t.elapsed().as_secs_f64();
            let back: Vec<f32> = img.layer_data.channel_data.list[0]
                .sample_data
                .values_as_f32()
                .collect();
            assert_eq!(back, px);
            println!(
                "exr 1440² {c:?}: encode median {:6.1} ms, {size:8} bytes ({:.2} bytes/px), decode {:.1} ms",
                times[2] * 1e3,
                size as f64 / (w * w) as f64,
                dt * 1e3
            );
        }
    }
}

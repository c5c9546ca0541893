//! Single-channel 32-bit float OpenEXR encoder (the `exr` crate, pinned), writing to memory.
//!
//! Output: one part, scanline blocks, one channel `"Y"` of `f32` samples (row-major, row 0 at the
//! top), `lineOrder = INCREASING_Y`, compressed on one thread. The bytes depend only on the
//! inputs:
//!
//! * Increasing line order with sequential compression writes the blocks in a fixed order (the
//!   `exr` crate gives different bytes on each write with other line orders and parallel
//!   compression).
//! * The `exr` crate keeps custom attributes in a `HashMap` whose iteration order changes from
//!   one map to the next, so it writes them in a different order on each call. After writing,
//!   [`encode_exr`] therefore sorts all header attributes by name (byte-wise, as the OpenEXR C++
//!   library writes them). The header keeps its length, so the chunk offsets stay valid.

use ::exr::meta::attribute::{AttributeValue, Text};
use ::exr::meta::header::standard_names;
use ::exr::prelude::*;
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

impl ExrCompression {
    fn to_exr(self) -> Compression {
        match self {
            ExrCompression::None => Compression::Uncompressed,
            ExrCompression::Rle => Compression::RLE,
            ExrCompression::Zip => Compression::ZIP16,
            ExrCompression::Zips => Compression::ZIP1,
        }
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
/// `"software"`, which with an [`ExrAttr::Text`] value sets the standard Software attribute.
/// Errors: a pixel count that is not `width · height`, a zero or too large dimension, a
/// rejected attribute, or an encoder failure.
pub fn encode_exr_with(
    width: u32,
    height: u32,
    pixels: &[f32],
    attributes: &[(&str, ExrAttr)],
    compression: ExrCompression,
) -> Result<Vec<u8>, String> {
    if width == 0 || height == 0 || width > i32::MAX as u32 || height > i32::MAX as u32 {
        return Err(format!("EXR image size {width}×{height} is not supported"));
    }
    if pixels.len() as u64 != u64::from(width) * u64::from(height) {
        return Err(format!(
            "EXR image is {width}×{height} but {} pixels were given",
            pixels.len()
        ));
    }
    let layer_attributes = layer_attributes(attributes)?;
    let channel = AnyChannel::new("Y", FlatSamples::F32(pixels.to_vec()));
    let encoding = Encoding {
        compression: compression.to_exr(),
        blocks: Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    };
    let layer = Layer::new(
        (width as usize, height as usize),
        layer_attributes,
        encoding,
        AnyChannels::sort(SmallVec::from_vec(vec![channel])),
    );
    let image = Image::from_layer(layer);
    let mut out = Cursor::new(Vec::with_capacity(pixels.len() * 4 + 4096));
    image
        .write()
        .non_parallel()
        .to_buffered(&mut out)
        .map_err(|e| format!("EXR encoding failed: {e}"))?;
    let mut bytes = out.into_inner();
    sort_header_attributes(&mut bytes)?;
    Ok(bytes)
}

fn latin1(what: &str, s: &str) -> Result<Text, String> {
    Text::new_or_none(s).ok_or_else(|| format!("EXR {what} must be Latin-1: {s:?}"))
}

fn layer_attributes(attributes: &[(&str, ExrAttr)]) -> Result<LayerAttributes, String> {
    let mut la = LayerAttributes::default();
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
        if *name == "software" {
            match value {
                ExrAttr::Text(s) => la.software_name = Some(latin1("attribute \"software\"", s)?),
                _ => return Err("EXR attribute \"software\" must be text".to_string()),
            }
            continue;
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
    Ok(la)
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
            assert_eq!(layer.encoding.compression, c.to_exr());
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
        assert!(ok(&[("x", ExrAttr::Text("ok".into()))]).is_ok());
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

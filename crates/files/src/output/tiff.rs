//! 16-bit grayscale TIFF encoder (the `tiff` crate, pinned), writing to memory.
//!
//! Output: one image, `Gray16` (BitsPerSample 16, SampleFormat unsigned), PhotometricInterpretation
//! MinIsBlack, strips of about 1 MB (one row per strip for PackBits, as the `tiff` crate
//! requires), with ImageDescription and Software tags, the pixel pitch as XResolution and
//! YResolution in pixels per centimetre (ResolutionUnit 3, centimetre; [`pixels_per_cm`]), and
//! I_max = 2^bpp − 1 as MaxSampleValue (baseline TIFF's tag for the largest value used, which
//! tells readers how many of the 16 bits hold data). The bytes depend only on the inputs (no
//! clock, no thread schedule); the byte order is the machine's (`II` on every little-endian
//! platform).
//!
//! **Deflate strips are compressed here** (the `tiff` crate still lays out the file and its
//! tags): each strip, horizontal predictor applied (per row, `d[i] = p[i] − p[i−1]` wrapping,
//! `d[0] = p[0]`), is one zlib stream from the pinned `fdeflate` crate (pure scalar Rust; the
//! image-rs project's fast deflate for PNG), strips compressed in parallel and stored in order.
//! Measured on the biplanar protocol's images (1440², all five noise levels, one thread,
//! when version 0.5.0 chose it, see CHANGELOG.md): fdeflate 10 ms and 2.82 MB per image against 35 ms and 2.47 MB
//! for the `tiff` crate's Deflate (miniz_oxide, fast level), so a TIFF costs a third of its
//! former time for files 14 % larger. Any zlib reader decodes it.

use ::tiff::encoder::{
    Compression, DirectoryEncoder, Predictor, Rational, TiffEncoder, TiffKindStandard,
    colortype::Gray16,
};
use ::tiff::tags::{CompressionMethod, PhotometricInterpretation, ResolutionUnit, Tag};
use rayon::prelude::*;
use std::io::Cursor;

pub use crate::scenario::TiffCompression;

/// The `tiff` crate's settings for the compressions it encodes; `None` for Deflate, whose strips
/// are compressed here ([`encode_deflate`]).
fn settings(compression: TiffCompression) -> Option<(Compression, Predictor)> {
    match compression {
        TiffCompression::None => Some((Compression::Uncompressed, Predictor::None)),
        TiffCompression::Lzw => Some((Compression::Lzw, Predictor::Horizontal)),
        TiffCompression::Deflate => None,
        TiffCompression::Packbits => Some((Compression::Packbits, Predictor::None)),
    }
}

/// Rows per strip: about 1 MB of raw samples per strip (the `tiff` crate's rule).
fn rows_per_strip(width: u32) -> u32 {
    let row_bytes = 2 * u64::from(width);
    1_000_000u64.div_ceil(row_bytes).min(u64::from(u32::MAX)) as u32
}

/// What a TIFF file states besides its pixels.
#[derive(Debug, Clone, Copy)]
pub struct TiffFacts<'a> {
    /// The ImageDescription tag (ASCII without NUL).
    pub description: &'a str,
    /// The Software tag (ASCII without NUL).
    pub software: &'a str,
    /// Pixel pitch `[x, y]`, mm (positive): XResolution and YResolution.
    pub pixel_pitch_mm: [f64; 2],
    /// The largest value the detector stores: MaxSampleValue.
    pub i_max: u16,
}

/// Encodes a `width × height` row-major 16-bit grayscale image as a TIFF file in memory, with
/// the tags of `facts`.
///
/// Errors: a pixel count that is not `width · height`, a zero dimension, a non-ASCII text, a
/// pitch that is not positive and finite, or an encoder failure.
pub fn encode_tiff(
    width: u32,
    height: u32,
    pixels: &[u16],
    compression: TiffCompression,
    facts: &TiffFacts,
) -> Result<Vec<u8>, String> {
    check(width, height, pixels, facts)?;
    match settings(compression) {
        Some((compression, predictor)) => {
            encode_with(width, height, pixels, compression, predictor, facts)
        }
        None => encode_deflate(width, height, pixels, facts),
    }
}

/// Encodes a volume of `depth` pages of `width × height` 16-bit samples (page-major, then
/// row-major) as one multi-page TIFF in memory: one IFD per page in page order, LZW with the
/// horizontal predictor, PhotometricInterpretation MinIsBlack, one sample per pixel, unsigned,
/// and the tags of `facts` on every page (what Autoscoper's `Volume::Volume` reads: page k is
/// slice k, and every page the same size and depth).
pub fn encode_tiff_stack(
    width: u32,
    height: u32,
    depth: u32,
    samples: &[u16],
    facts: &TiffFacts,
) -> Result<Vec<u8>, String> {
    let page = width as usize * height as usize;
    if depth == 0 || samples.len() as u64 != page as u64 * u64::from(depth) {
        return Err(format!(
            "TIFF volume is {width}×{height}×{depth} but {} samples were given",
            samples.len()
        ));
    }
    check(width, height, &samples[..page], facts)?;
    let mut out = Cursor::new(Vec::with_capacity(samples.len() / 4 + 4096));
    {
        let mut encoder = TiffEncoder::new(&mut out)
            .map_err(tiff_error)?
            .with_compression(Compression::Lzw)
            .with_predictor(Predictor::Horizontal);
        for k in 0..depth as usize {
            let mut image = encoder
                .new_image::<Gray16>(width, height)
                .map_err(tiff_error)?;
            write_facts(image.encoder(), facts)?;
            image
                .write_data(&samples[k * page..(k + 1) * page])
                .map_err(tiff_error)?;
        }
    }
    Ok(out.into_inner())
}

/// The TIFF resolution of a pitch: pixels per centimetre, `10 / pitch_mm`, as a rational. The
/// pitch's shortest decimal form (what the scenario wrote, e.g. `0.3` gives `100/3`) is used
/// exactly when the reduced fraction fits 32 bits; otherwise the closest fraction with 32-bit
/// terms (continued fractions), e.g. `430 / 1440` mm gives `1440/43`. `None` for a pitch that is
/// not positive and finite.
pub fn pixels_per_cm(pitch_mm: f64) -> Option<Rational> {
    if !(pitch_mm.is_finite() && pitch_mm > 0.0) {
        return None;
    }
    let fits = |n: u128, d: u128| {
        let g = gcd(n, d);
        let (n, d) = (n / g, d / g);
        (n <= u128::from(u32::MAX) && d <= u128::from(u32::MAX) && n > 0).then(|| Rational {
            n: n as u32,
            d: d as u32,
        })
    };
    if let Some((digits, scale)) = decimal(pitch_mm) {
        // 10 / (digits / scale) = 10·scale / digits
        if let Some(r) = scale.checked_mul(10).and_then(|n| fits(n, digits)) {
            return Some(r);
        }
    }
    best_fraction(10.0 / pitch_mm)
}

/// `v > 0` as `digits / 10^k` from its shortest decimal form, if that fits 128 bits.
fn decimal(v: f64) -> Option<(u128, u128)> {
    let text = format!("{v}");
    let (int, frac) = text.split_once('.').unwrap_or((&text, ""));
    let digits: u128 = format!("{int}{frac}").parse().ok()?;
    let scale = 10u128.checked_pow(u32::try_from(frac.len()).ok()?)?;
    (digits > 0).then_some((digits, scale))
}

fn gcd(mut a: u128, mut b: u128) -> u128 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a.max(1)
}

/// The last continued-fraction convergent of `x > 0` whose terms fit 32 bits.
fn best_fraction(x: f64) -> Option<Rational> {
    let limit = f64::from(u32::MAX);
    if !(x.is_finite() && x > 0.0 && x <= limit) {
        return None;
    }
    let (mut h0, mut h1, mut k0, mut k1) = (0f64, 1f64, 1f64, 0f64);
    let mut rest = x;
    for _ in 0..64 {
        let a = rest.floor();
        let (h2, k2) = (a * h1 + h0, a * k1 + k0);
        if h2 > limit || k2 > limit {
            break;
        }
        (h0, h1, k0, k1) = (h1, h2, k1, k2);
        let frac = rest - a;
        if frac < 1e-12 {
            break;
        }
        rest = 1.0 / frac;
    }
    (h1 >= 1.0 && k1 >= 1.0).then(|| Rational {
        n: h1 as u32,
        d: k1 as u32,
    })
}

/// The inputs' errors: empty image, wrong pixel count, pitch not positive and finite, text not
/// ASCII without NUL.
fn check(width: u32, height: u32, pixels: &[u16], facts: &TiffFacts) -> Result<(), String> {
    if facts
        .pixel_pitch_mm
        .map(pixels_per_cm)
        .iter()
        .any(Option::is_none)
    {
        return Err(format!(
            "TIFF pixel pitch {:?} mm is not positive and finite",
            facts.pixel_pitch_mm
        ));
    }
    if width == 0 || height == 0 {
        return Err(format!("TIFF image must not be empty ({width}×{height})"));
    }
    if pixels.len() as u64 != u64::from(width) * u64::from(height) {
        return Err(format!(
            "TIFF image is {width}×{height} but {} pixels were given",
            pixels.len()
        ));
    }
    for (name, text) in [
        ("ImageDescription", facts.description),
        ("Software", facts.software),
    ] {
        if !text.is_ascii() || text.contains('\0') {
            return Err(format!("TIFF {name} must be ASCII without NUL: {text:?}"));
        }
    }
    Ok(())
}

fn tiff_error(e: ::tiff::TiffError) -> String {
    format!("TIFF encoding failed: {e}")
}

/// The tags of `facts` ([`check`]ed): description, software, resolution, MaxSampleValue.
fn write_facts<W: std::io::Write + std::io::Seek>(
    dir: &mut DirectoryEncoder<'_, W, TiffKindStandard>,
    facts: &TiffFacts,
) -> Result<(), String> {
    let [Some(x_resolution), Some(y_resolution)] = facts.pixel_pitch_mm.map(pixels_per_cm) else {
        return Err(format!(
            "TIFF pixel pitch {:?} mm is not positive and finite",
            facts.pixel_pitch_mm
        ));
    };
    dir.write_tag(Tag::ImageDescription, facts.description)
        .map_err(tiff_error)?;
    dir.write_tag(Tag::Software, facts.software)
        .map_err(tiff_error)?;
    dir.write_tag(Tag::XResolution, x_resolution)
        .map_err(tiff_error)?;
    dir.write_tag(Tag::YResolution, y_resolution)
        .map_err(tiff_error)?;
    dir.write_tag(Tag::ResolutionUnit, ResolutionUnit::Centimeter)
        .map_err(tiff_error)?;
    dir.write_tag(Tag::MaxSampleValue, facts.i_max)
        .map_err(tiff_error)
}

/// The `tiff` crate's encoder, for the compressions it does itself.
fn encode_with(
    width: u32,
    height: u32,
    pixels: &[u16],
    compression: Compression,
    predictor: Predictor,
    facts: &TiffFacts,
) -> Result<Vec<u8>, String> {
    let mut out = Cursor::new(Vec::with_capacity(pixels.len() * 2 + 4096));
    {
        let mut encoder = TiffEncoder::new(&mut out)
            .map_err(tiff_error)?
            .with_compression(compression)
            .with_predictor(predictor);
        let mut image = encoder
            .new_image::<Gray16>(width, height)
            .map_err(tiff_error)?;
        write_facts(image.encoder(), facts)?;
        image.write_data(pixels).map_err(tiff_error)?;
    }
    Ok(out.into_inner())
}

/// One Deflate strip: `rows` (whole rows of `width`) with the horizontal predictor, in the
/// file's (native) byte order, as a zlib stream from `fdeflate`.
fn deflate_strip(rows: &[u16], width: usize) -> Vec<u8> {
    fdeflate::compress_to_vec(&horizontal_predicted(rows, width))
}

/// Whole rows of `width` samples with TIFF's horizontal predictor (per row `d[0] = p[0]`,
/// `d[i] = p[i] − p[i−1]` wrapping), as native-endian bytes: what a Deflate strip compresses.
/// Public for `examples/encoder_levels.rs`.
pub fn horizontal_predicted(rows: &[u16], width: usize) -> Vec<u8> {
    let mut predicted = Vec::with_capacity(rows.len() * 2);
    for row in rows.chunks_exact(width) {
        let mut previous = 0u16;
        for &p in row {
            predicted.extend_from_slice(&p.wrapping_sub(previous).to_ne_bytes());
            previous = p;
        }
    }
    predicted
}

/// A Deflate TIFF ([`check`]ed inputs): the strips compressed in parallel ([`deflate_strip`]),
/// then written in order with the tags the `tiff` crate writes for its own Deflate images
/// (ImageWidth, ImageLength, BitsPerSample 16, Compression 8, PhotometricInterpretation
/// MinIsBlack, StripOffsets, SamplesPerPixel 1, RowsPerStrip, StripByteCounts, Predictor 2,
/// SampleFormat unsigned) and those of `facts`.
fn encode_deflate(
    width: u32,
    height: u32,
    pixels: &[u16],
    facts: &TiffFacts,
) -> Result<Vec<u8>, String> {
    let rows = rows_per_strip(width);
    let strip_pixels = rows as usize * width as usize;
    let strips: Vec<Vec<u8>> = pixels
        .par_chunks(strip_pixels)
        .map(|strip| deflate_strip(strip, width as usize))
        .collect();
    let mut out = Cursor::new(Vec::with_capacity(
        strips.iter().map(Vec::len).sum::<usize>() + 4096,
    ));
    let mut encoder = TiffEncoder::new(&mut out).map_err(tiff_error)?;
    let mut dir = encoder.image_directory().map_err(tiff_error)?;
    let mut offsets = Vec::with_capacity(strips.len());
    let mut counts = Vec::with_capacity(strips.len());
    for strip in &strips {
        let offset = dir.write_data(&strip[..]).map_err(tiff_error)?;
        offsets.push(u32::try_from(offset).map_err(|_| "TIFF larger than 4 GiB".to_string())?);
        counts.push(u32::try_from(strip.len()).map_err(|_| "TIFF strip larger than 4 GiB")?);
    }
    let tags: [(Tag, u16); 5] = [
        (Tag::Compression, CompressionMethod::Deflate.to_u16()),
        (Tag::Predictor, 2), // horizontal differencing
        (
            Tag::PhotometricInterpretation,
            PhotometricInterpretation::BlackIsZero.to_u16(),
        ),
        (Tag::SamplesPerPixel, 1),
        (Tag::BitsPerSample, 16),
    ];
    for (tag, value) in tags {
        dir.write_tag(tag, value).map_err(tiff_error)?;
    }
    dir.write_tag(Tag::ImageWidth, width).map_err(tiff_error)?;
    dir.write_tag(Tag::ImageLength, height)
        .map_err(tiff_error)?;
    dir.write_tag(Tag::RowsPerStrip, rows).map_err(tiff_error)?;
    dir.write_tag(Tag::SampleFormat, &[1u16][..])
        .map_err(tiff_error)?;
    dir.write_tag(Tag::StripOffsets, &offsets[..])
        .map_err(tiff_error)?;
    dir.write_tag(Tag::StripByteCounts, &counts[..])
        .map_err(tiff_error)?;
    write_facts(&mut dir, facts)?;
    dir.finish().map_err(tiff_error)?;
    drop(encoder);
    Ok(out.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::NoiseKey;
    use ::tiff::decoder::{Decoder, DecodingResult};
    use ::tiff::encoder::DeflateLevel;

    /// Our Deflate files carry the same tags, with the same values, as the `tiff` crate's own
    /// Deflate encoding of the same image (bar where the strips are), the pixels decode equal,
    /// and the strips are valid zlib streams of the predicted rows (decoded by miniz_oxide).
    #[test]
    fn deflate_files_have_the_tiff_crate_tags_and_decode_equal() {
        let (w, h) = (700u32, 1500u32); // strips of 715 rows: 715, 715, 70
        let px = noisy(w as usize, h as usize, 0.45, 65535);
        let f = facts("rsasim deflate", "rsasim test");
        let ours = encode_tiff(w, h, &px, TiffCompression::Deflate, &f).unwrap();
        let theirs = encode_with(
            w,
            h,
            &px,
            Compression::Deflate(DeflateLevel::Fast),
            Predictor::Horizontal,
            &f,
        )
        .unwrap();
        let tags = |bytes: &[u8]| {
            let mut d = Decoder::new(Cursor::new(bytes.to_vec())).unwrap();
            let mut v: Vec<(u16, String)> = d
                .tag_iter()
                .map(|t| t.unwrap())
                .filter(|(t, _)| !matches!(t, Tag::StripOffsets | Tag::StripByteCounts))
                .map(|(t, value)| (t.to_u16(), format!("{value:?}")))
                .collect();
            v.sort();
            v
        };
        assert_eq!(tags(&ours), tags(&theirs));
        assert_eq!(decode(&ours).2, px);
        let mut d = Decoder::new(Cursor::new(ours.clone())).unwrap();
        let offsets = d.get_tag_u32_vec(Tag::StripOffsets).unwrap();
        let counts = d.get_tag_u32_vec(Tag::StripByteCounts).unwrap();
        assert_eq!(offsets.len(), 3);
        let rows = rows_per_strip(w) as usize;
        for (s, (&o, &n)) in offsets.iter().zip(&counts).enumerate() {
            let strip = &ours[o as usize..(o + n) as usize];
            let raw = miniz_oxide::inflate::decompress_to_vec_zlib(strip).unwrap();
            let first = s * rows;
            let last = (first + rows).min(h as usize);
            assert_eq!(raw.len(), (last - first) * w as usize * 2);
            // Row starts hold the pixel itself, the rest the wrapping difference.
            let at = |i: usize| u16::from_ne_bytes([raw[2 * i], raw[2 * i + 1]]);
            let p = |j: usize, i: usize| px[(first + j) * w as usize + i];
            assert_eq!(at(0), p(0, 0));
            assert_eq!(at(5), p(0, 5).wrapping_sub(p(0, 4)));
            assert_eq!(at(w as usize), p(1, 0));
        }
    }

    const ALL: [TiffCompression; 4] = [
        TiffCompression::None,
        TiffCompression::Lzw,
        TiffCompression::Deflate,
        TiffCompression::Packbits,
    ];

    fn noisy(w: usize, h: usize, level: f64, i_max: u16) -> Vec<u16> {
        crate::output::test_image::noisy_disc(
            w,
            h,
            level,
            i_max,
            &NoiseKey::derive(3, 0, 0, "tiff", "test"),
        )
    }

    fn facts<'a>(description: &'a str, software: &'a str) -> TiffFacts<'a> {
        TiffFacts {
            description,
            software,
            pixel_pitch_mm: [0.3, 0.25],
            i_max: 4095,
        }
    }

    fn decode(bytes: &[u8]) -> (u32, u32, Vec<u16>, String, String, u16, u16) {
        let mut d = Decoder::new(Cursor::new(bytes)).unwrap();
        let (w, h) = d.dimensions().unwrap();
        let desc = d.get_tag_ascii_string(Tag::ImageDescription).unwrap();
        let sw = d.get_tag_ascii_string(Tag::Software).unwrap();
        let photometric = d.get_tag_u32(Tag::PhotometricInterpretation).unwrap() as u16;
        let bps = d.get_tag_u32(Tag::BitsPerSample).unwrap() as u16;
        match d.read_image().unwrap() {
            DecodingResult::U16(v) => (w, h, v, desc, sw, photometric, bps),
            other => panic!("expected U16, got {:?}", std::mem::discriminant(&other)),
        }
    }

    #[test]
    fn round_trip_and_deterministic_for_every_compression() {
        let (w, h) = (123u32, 77u32);
        let px = noisy(w as usize, h as usize, 0.3, 4095);
        for c in ALL {
            let a = encode_tiff(
                w,
                h,
                &px,
                c,
                &facts("rsasim test; sid_mm=1800", "rsasim 0.1"),
            )
            .unwrap();
            let b = encode_tiff(
                w,
                h,
                &px,
                c,
                &facts("rsasim test; sid_mm=1800", "rsasim 0.1"),
            )
            .unwrap();
            assert_eq!(a, b, "{c:?}: two encodes differ");
            let (dw, dh, back, desc, sw, photometric, bps) = decode(&a);
            assert_eq!((dw, dh), (w, h));
            assert_eq!(back, px, "{c:?}");
            assert_eq!(desc, "rsasim test; sid_mm=1800");
            assert_eq!(sw, "rsasim 0.1");
            assert_eq!(photometric, 1, "MinIsBlack");
            assert_eq!(bps, 16);
        }
    }

    #[test]
    fn resolution_and_max_sample_value_tags() {
        let bytes =
            encode_tiff(2, 2, &[0, 1, 2, 3], TiffCompression::None, &facts("", "")).unwrap();
        let mut d = Decoder::new(Cursor::new(&bytes)).unwrap();
        let rational = |d: &mut Decoder<_>, tag| match d.get_tag(tag).unwrap() {
            ::tiff::decoder::ifd::Value::Rational(n, d) => (n, d),
            other => panic!("{tag:?} is {other:?}"),
        };
        // 10 / 0.3 = 100/3 and 10 / 0.25 = 40 pixels per centimetre.
        assert_eq!(rational(&mut d, Tag::XResolution), (100, 3));
        assert_eq!(rational(&mut d, Tag::YResolution), (40, 1));
        assert_eq!(d.get_tag_u32(Tag::ResolutionUnit).unwrap(), 3, "centimetre");
        assert_eq!(d.get_tag_u32(Tag::MaxSampleValue).unwrap(), 4095);
        let mut bad = facts("", "");
        bad.pixel_pitch_mm = [0.0, 0.1];
        assert!(encode_tiff(1, 1, &[0], TiffCompression::None, &bad).is_err());
    }

    #[test]
    fn pixels_per_cm_is_exact_for_decimal_pitches() {
        let r = |p| pixels_per_cm(p).map(|r| (r.n, r.d));
        assert_eq!(r(0.3), Some((100, 3)));
        assert_eq!(r(0.1), Some((100, 1)));
        assert_eq!(r(0.298611), Some((10_000_000, 298_611)));
        assert_eq!(r(0.148), Some((2500, 37)));
        assert_eq!(r(2.0), Some((5, 1)));
        // 430 / 1440 has no short decimal form: the continued fraction finds 1440/43.
        assert_eq!(r(430.0 / 1440.0), Some((1440, 43)));
        assert_eq!(r(0.0), None);
        assert_eq!(r(-1.0), None);
        assert_eq!(r(f64::NAN), None);
        // Tiny or huge pitches: the nearest representable fraction, within 1e-9 relative.
        for p in [1e-6, 12345.678901234, 0.123456789012345] {
            let q = pixels_per_cm(p).unwrap();
            let got = f64::from(q.n) / f64::from(q.d);
            assert!(
                (got - 10.0 / p).abs() <= 1e-9 * (10.0 / p),
                "{p}: {}/{}",
                q.n,
                q.d
            );
        }
    }

    #[test]
    fn extreme_values_round_trip() {
        let px: Vec<u16> = (0..64 * 3)
            .map(|i| [0u16, 65535, 1, 65534][i % 4])
            .collect();
        for c in ALL {
            let bytes = encode_tiff(64, 3, &px, c, &facts("", "")).unwrap();
            assert_eq!(decode(&bytes).2, px, "{c:?}");
        }
    }

    #[test]
    fn rejects_bad_input() {
        assert!(encode_tiff(4, 4, &[0; 15], TiffCompression::None, &facts("", "")).is_err());
        assert!(encode_tiff(0, 4, &[], TiffCompression::None, &facts("", "")).is_err());
        assert!(encode_tiff(1, 1, &[0], TiffCompression::None, &facts("µ", "")).is_err());
        assert!(encode_tiff(1, 1, &[0], TiffCompression::None, &facts("", "a\0b")).is_err());
    }

    #[test]
    fn serde_names_and_default() {
        assert_eq!(TiffCompression::default(), TiffCompression::Deflate);
        let names: Vec<String> = ALL
            .iter()
            .map(|c| serde_json::to_string(c).unwrap())
            .collect();
        assert_eq!(
            names,
            ["\"none\"", "\"lzw\"", "\"deflate\"", "\"packbits\""]
        );
        let back: TiffCompression = serde_json::from_str("\"packbits\"").unwrap();
        assert_eq!(back, TiffCompression::Packbits);
        let schema = serde_json::to_string(&schemars::schema_for!(TiffCompression)).unwrap();
        assert!(schema.contains("deflate") && schema.contains("horizontal predictor"));
    }

    /// Timings for the report:
    /// `cargo test --release --lib output::tiff::tests::bench -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn bench_tiff_1440() {
        let w = 1440u32;
        let n = (w * w) as usize;
        // A smooth image (what a noise-free path-length mode could give) for comparison.
        let smooth: Vec<u16> = (0..n)
            .map(|k| {
                let (i, j) = ((k % 1440) as f64, (k / 1440) as f64);
                (20000.0 + 15000.0 * libm::sin(i / 200.0) * libm::cos(j / 300.0)) as u16
            })
            .collect();
        let images: Vec<(&str, Vec<u16>)> = vec![
            ("binary, no noise", noisy(1440, 1440, 0.0, 65535)),
            ("noise λ≈66 (level 0.001)", noisy(1440, 1440, 0.001, 65535)),
            ("noise λ≈15000", noisy(1440, 1440, 15000.0 / 65535.0, 65535)),
            ("noise level 0.9 (λ≈58982)", noisy(1440, 1440, 0.9, 65535)),
            ("smooth, no noise", smooth),
        ];
        let cases: Vec<(&str, Compression, Predictor)> = vec![
            ("none", Compression::Uncompressed, Predictor::None),
            ("packbits", Compression::Packbits, Predictor::None),
            ("lzw", Compression::Lzw, Predictor::None),
            ("lzw + pred", Compression::Lzw, Predictor::Horizontal),
            (
                "deflate fast",
                Compression::Deflate(DeflateLevel::Fast),
                Predictor::None,
            ),
            (
                "deflate fast + pred",
                Compression::Deflate(DeflateLevel::Fast),
                Predictor::Horizontal,
            ),
            (
                "deflate balanced",
                Compression::Deflate(DeflateLevel::Balanced),
                Predictor::None,
            ),
            (
                "deflate balanced + pred",
                Compression::Deflate(DeflateLevel::Balanced),
                Predictor::Horizontal,
            ),
            (
                "deflate best + pred",
                Compression::Deflate(DeflateLevel::Best),
                Predictor::Horizontal,
            ),
        ];
        for (image, px) in &images {
            for (name, c, p) in &cases {
                let mut times = Vec::new();
                let mut bytes = Vec::new();
                for _ in 0..5 {
                    let t = std::time::Instant::now();
                    bytes = encode_with(w, w, px, *c, *p, &facts("bench", "rsasim")).unwrap();
                    times.push(t.elapsed().as_secs_f64());
                }
                times.sort_by(f64::total_cmp);
                let t = std::time::Instant::now();
                let back = decode(&bytes).2;
                let dt = t.elapsed().as_secs_f64();
                assert_eq!(&back, px);
                println!(
                    "tiff 1440² {image:27} {name:24}: encode {:6.1} ms, {:8} bytes ({:.2} B/px), decode {:5.1} ms",
                    times[2] * 1e3,
                    bytes.len(),
                    bytes.len() as f64 / n as f64,
                    dt * 1e3
                );
            }
        }
    }
}

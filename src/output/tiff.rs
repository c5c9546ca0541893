//! 16-bit grayscale TIFF encoder (the `tiff` crate, pinned), writing to memory.
//!
//! Output: one image, `Gray16` (BitsPerSample 16, SampleFormat unsigned), PhotometricInterpretation
//! MinIsBlack, strips of about 1 MB (one row per strip for PackBits, as the `tiff` crate
//! requires), with ImageDescription and Software tags. The bytes depend only on the inputs (no
//! clock, no thread schedule); the byte order is the machine's (`II` on every little-endian
//! platform).

use ::tiff::encoder::{Compression, DeflateLevel, Predictor, TiffEncoder, colortype::Gray16};
use ::tiff::tags::Tag;
use std::io::Cursor;

pub use crate::scenario::TiffCompression;

/// The Deflate level used for [`TiffCompression::Deflate`].
const DEFLATE_LEVEL: DeflateLevel = DeflateLevel::Fast;

impl TiffCompression {
    fn settings(self) -> (Compression, Predictor) {
        match self {
            TiffCompression::None => (Compression::Uncompressed, Predictor::None),
            TiffCompression::Lzw => (Compression::Lzw, Predictor::Horizontal),
            TiffCompression::Deflate => {
                (Compression::Deflate(DEFLATE_LEVEL), Predictor::Horizontal)
            }
            TiffCompression::Packbits => (Compression::Packbits, Predictor::None),
        }
    }
}

/// Encodes a `width × height` row-major 16-bit grayscale image as a TIFF file in memory.
///
/// `description` goes into the ImageDescription tag and `software` into the Software tag; both
/// must be ASCII without NUL (TIFF ASCII fields). Errors: a pixel count that is not
/// `width · height`, a zero dimension, a non-ASCII text, or an encoder failure.
pub fn encode_tiff(
    width: u32,
    height: u32,
    pixels: &[u16],
    compression: TiffCompression,
    description: &str,
    software: &str,
) -> Result<Vec<u8>, String> {
    let (compression, predictor) = compression.settings();
    encode_with(
        width,
        height,
        pixels,
        compression,
        predictor,
        description,
        software,
    )
}

fn encode_with(
    width: u32,
    height: u32,
    pixels: &[u16],
    compression: Compression,
    predictor: Predictor,
    description: &str,
    software: &str,
) -> Result<Vec<u8>, String> {
    if width == 0 || height == 0 {
        return Err(format!("TIFF image must not be empty ({width}×{height})"));
    }
    if pixels.len() as u64 != u64::from(width) * u64::from(height) {
        return Err(format!(
            "TIFF image is {width}×{height} but {} pixels were given",
            pixels.len()
        ));
    }
    for (name, text) in [("ImageDescription", description), ("Software", software)] {
        if !text.is_ascii() || text.contains('\0') {
            return Err(format!("TIFF {name} must be ASCII without NUL: {text:?}"));
        }
    }
    let err = |e: ::tiff::TiffError| format!("TIFF encoding failed: {e}");
    let mut out = Cursor::new(Vec::with_capacity(pixels.len() * 2 + 4096));
    {
        let mut encoder = TiffEncoder::new(&mut out)
            .map_err(err)?
            .with_compression(compression)
            .with_predictor(predictor);
        let mut image = encoder.new_image::<Gray16>(width, height).map_err(err)?;
        image
            .encoder()
            .write_tag(Tag::ImageDescription, description)
            .map_err(err)?;
        image
            .encoder()
            .write_tag(Tag::Software, software)
            .map_err(err)?;
        image.write_data(pixels).map_err(err)?;
    }
    Ok(out.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::NoiseKey;
    use ::tiff::decoder::{Decoder, DecodingResult};

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
            let a = encode_tiff(w, h, &px, c, "rsasim test; sid_mm=1800", "rsasim 0.1").unwrap();
            let b = encode_tiff(w, h, &px, c, "rsasim test; sid_mm=1800", "rsasim 0.1").unwrap();
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
    fn extreme_values_round_trip() {
        let px: Vec<u16> = (0..64 * 3)
            .map(|i| [0u16, 65535, 1, 65534][i % 4])
            .collect();
        for c in ALL {
            let bytes = encode_tiff(64, 3, &px, c, "", "").unwrap();
            assert_eq!(decode(&bytes).2, px, "{c:?}");
        }
    }

    #[test]
    fn rejects_bad_input() {
        assert!(encode_tiff(4, 4, &[0; 15], TiffCompression::None, "", "").is_err());
        assert!(encode_tiff(0, 4, &[], TiffCompression::None, "", "").is_err());
        assert!(encode_tiff(1, 1, &[0], TiffCompression::None, "µ", "").is_err());
        assert!(encode_tiff(1, 1, &[0], TiffCompression::None, "", "a\0b").is_err());
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
                    bytes = encode_with(w, w, px, *c, *p, "bench", "rsasim").unwrap();
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

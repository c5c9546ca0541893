//! Size against time of the deflate encoders rsasim could use for its TIFF and EXR files, on a
//! protocol's own images (a measurement, not a test; docs/src/results/speed.md, "The EXR encoder").
//!
//! It reads `runs/n{0..4}-r00/{calibration,model}-det1.tiff` of a written biplanar protocol (the
//! five noise levels, both exposures: 10 images of 1440²), rebuilds the bytes each format
//! deflates (TIFF: strips of ~1 MB, horizontal predictor; EXR: ZIP blocks of 16 rows of `f32`,
//! OpenEXR's byte split and delta) and times every encoder on one thread, best of 3, per image.
//!
//! `cargo run --release --example encoder_levels -- OUT_DIR`

use std::time::Instant;

use rsasim::output::exr::zip_predicted;
use rsasim::output::tiff::horizontal_predicted;

use miniz_oxide_exr::deflate::core::{
    CompressorOxide, TDEFLFlush, TDEFLStatus, compress, create_comp_flags_from_zip_params,
};

/// miniz_oxide 0.8.9 (EXR blocks up to 0.4.0) at `level`, zlib stream: its length.
fn miniz(input: &[u8], level: i32) -> usize {
    let flags = create_comp_flags_from_zip_params(level, 1, 0);
    let mut c = CompressorOxide::new(flags);
    let mut out = vec![0u8; input.len() + input.len() / 10 + 1024];
    let (status, _, n) = compress(&mut c, input, &mut out, TDEFLFlush::Finish);
    assert!(matches!(status, TDEFLStatus::Done), "miniz_oxide failed");
    n
}

/// libdeflate (through libdeflater; EXR blocks in 0.5.0) at `level`, zlib stream: its length.
fn libdeflate(input: &[u8], level: i32) -> usize {
    let mut c = libdeflater::Compressor::new(libdeflater::CompressionLvl::new(level).unwrap());
    let mut out = vec![0u8; c.zlib_compress_bound(input.len())];
    c.zlib_compress(input, &mut out).unwrap()
}

/// miniz_oxide 0.9.1 (the `tiff` crate's Deflate, through flate2) at `level`.
fn miniz_09(input: &[u8], level: u8) -> usize {
    miniz_oxide::deflate::compress_to_vec_zlib(input, level).len()
}

/// zlib-rs (the zlib-ng port) at `level`, default strategy.
fn zlib_rs(input: &[u8], level: i32) -> usize {
    let mut out = vec![0u8; zlib_rs::compress_bound(input.len())];
    let config = zlib_rs::DeflateConfig {
        level,
        ..zlib_rs::DeflateConfig::default()
    };
    let (c, rc) = zlib_rs::compress_slice(&mut out, input, config);
    assert_eq!(rc, zlib_rs::ReturnCode::Ok, "zlib-rs failed");
    c.len()
}

fn main() {
    let dir = std::env::args()
        .nth(1)
        .expect("usage: encoder_levels OUT_DIR (a written scenarios/biplanar.toml protocol)");
    let (mut tiff_strips, mut exr_blocks) = (Vec::new(), Vec::new());
    for level in 0..5 {
        for image in ["calibration-det1", "model-det1"] {
            let path = format!("{dir}/runs/n{level}-r00/{image}.tiff");
            let file = std::fs::File::open(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
            let mut d = tiff::decoder::Decoder::new(std::io::BufReader::new(file)).unwrap();
            let (w, _) = d.dimensions().unwrap();
            let tiff::decoder::DecodingResult::U16(px) = d.read_image().unwrap() else {
                panic!("{path}: not 16-bit")
            };
            let w = w as usize;
            let rows = 1_000_000usize.div_ceil(2 * w);
            for strip in px.chunks(w * rows) {
                tiff_strips.push(horizontal_predicted(strip, w));
            }
            for block in px.chunks(w * 16) {
                let samples: Vec<f32> = block.iter().map(|&v| f32::from(v)).collect();
                exr_blocks.push(zip_predicted(&samples));
            }
        }
    }
    type Encoder = (&'static str, fn(&[u8]) -> usize);
    let encoders: [Encoder; 12] = [
        ("rsasim exr_deflate (EXR now)", |x| {
            rsasim::output::exr_deflate::zlib_compress(x).len()
        }),
        ("libdeflate level 1 (EXR in 0.5.0)", |x| libdeflate(x, 1)),
        ("libdeflate level 2", |x| libdeflate(x, 2)),
        ("libdeflate level 4", |x| libdeflate(x, 4)),
        ("miniz_oxide 0.9 level 1", |x| miniz_09(x, 1)),
        ("miniz_oxide 0.8 level 1", |x| miniz(x, 1)),
        ("miniz_oxide 0.8 level 2", |x| miniz(x, 2)),
        ("miniz_oxide 0.8 level 4", |x| miniz(x, 4)),
        ("zlib-rs level 1", |x| zlib_rs(x, 1)),
        ("zlib-rs level 2", |x| zlib_rs(x, 2)),
        ("zlib-rs level 6", |x| zlib_rs(x, 6)),
        ("fdeflate", |x| fdeflate::compress_to_vec(x).len()),
    ];
    let images = 10.0;
    for (format, data) in [("TIFF", &tiff_strips), ("EXR", &exr_blocks)] {
        let raw: usize = data.iter().map(Vec::len).sum();
        println!(
            "{format}: {:.2} MB per image before compression",
            raw as f64 / images / 1e6
        );
        println!("| encoder | ms per image | MB per image | of raw |");
        println!("|---|---|---|---|");
        for (name, encode) in encoders {
            let mut best = f64::INFINITY;
            let mut size = 0;
            for _ in 0..3 {
                let t = Instant::now();
                size = data.iter().map(|b| encode(b)).sum::<usize>();
                best = best.min(t.elapsed().as_secs_f64());
            }
            println!(
                "| {name} | {:.1} | {:.2} | {:.1} % |",
                best * 1e3 / images,
                size as f64 / images / 1e6,
                100.0 * size as f64 / raw as f64
            );
        }
    }
}

//! The EXR files of a simulated protocol, read by two independent readers: the `exr` crate
//! decodes every pixel equal to the TIFF written beside it, and every ZIP block's zlib stream
//! (rsasim's own encoder, `crates/files/src/output/exr_deflate`) inflates by miniz_oxide to exactly OpenEXR's
//! predicted bytes of those pixels.

use crate::common;

use common::{read_tiff, run_scenario};
use exr::block::chunk::CompressedBlock;
use exr::prelude::*;

#[test]
fn protocol_exr_blocks_decode_to_the_tiff_pixels() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    run_scenario("scenarios/golden/small_biplanar.toml", &out, &[]);
    let mut checked = (0, 0);
    for run in std::fs::read_dir(out.join("runs")).unwrap() {
        let run = run.unwrap().path();
        for image in [
            "calibration-det1",
            "calibration-det2",
            "model-det1",
            "model-det2",
        ] {
            let (w, h, tiff) = read_tiff(&run.join(format!("{image}.tiff")));
            let samples: Vec<f32> = tiff.iter().map(|&v| f32::from(v)).collect();
            let bytes = std::fs::read(run.join(format!("{image}.exr"))).unwrap();
            // Reader 1: the exr crate, pixel for pixel.
            let img = read_first_flat_layer_from_file(run.join(format!("{image}.exr"))).unwrap();
            assert_eq!(img.layer_data.size, Vec2(w as usize, h as usize));
            assert_eq!(img.layer_data.encoding.compression, Compression::ZIP16);
            let decoded: Vec<f32> = img.layer_data.channel_data.list[0]
                .sample_data
                .values_as_f32()
                .collect();
            assert!(decoded == samples, "{}: {image}", run.display());
            // Reader 2: each block's stream through miniz_oxide, against OpenEXR's prediction.
            let chunks = exr::block::read(std::io::Cursor::new(bytes), true)
                .unwrap()
                .all_chunks(true)
                .unwrap();
            for chunk in chunks {
                let CompressedBlock::ScanLine(block) = chunk.unwrap().compressed_block else {
                    panic!("scan line blocks expected")
                };
                let y = block.y_coordinate as usize;
                let rows = &samples[y * w as usize..((y + 16).min(h as usize)) * w as usize];
                let stored = &block.compressed_pixels_le;
                if stored.len() == rows.len() * 4 {
                    let le: Vec<u8> = rows.iter().flat_map(|v| v.to_le_bytes()).collect();
                    assert!(*stored == le);
                    checked.1 += 1;
                } else {
                    let inflated = miniz_oxide::inflate::decompress_to_vec_zlib(stored).unwrap();
                    assert!(inflated == rsasim::output::exr::zip_predicted(rows));
                    checked.0 += 1;
                }
            }
        }
    }
    // Both noise levels' images: compressed blocks, none of them stored raw.
    assert!(checked.0 >= 4 * 4 * 15 && checked.1 == 0, "{checked:?}");
}

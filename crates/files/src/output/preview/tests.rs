//! Tests of the PNG previews: decoded size, window, area averaging, layout, determinism.

use std::io::Cursor;

use sha2::{Digest, Sha256};

use super::*;

/// Decodes a PNG: (width, height, grey values); asserts it is 8-bit grayscale.
fn decode(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
    let mut reader = png::Decoder::new(Cursor::new(bytes)).read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, ColorType::Grayscale);
    assert_eq!(info.bit_depth, BitDepth::Eight);
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

#[test]
fn the_longer_side_is_scaled_to_the_limit_and_the_aspect_ratio_kept() {
    let pixels: Vec<u16> = (0..100 * 40).map(|i| (i * 7 % 1000) as u16).collect();
    let (w, h, v) = decode(&preview_png(&pixels, 100, 40, 50));
    assert_eq!((w, h, v.len()), (50, 20, 1000));
    let (w, h, _) = decode(&preview_png(&pixels, 40, 100, 30));
    assert_eq!((w, h), (12, 30));
    // Never enlarged.
    let (w, h, _) = decode(&preview_png(&pixels, 100, 40, 4000));
    assert_eq!((w, h), (100, 40));
}

#[test]
fn the_percentile_pixels_map_to_black_and_white() {
    // A ramp 0, 3, …, 2997: the 0.5th percentile is pixel 4 (rank ⌊0.005·999⌋ = 4, value 12),
    // the 99.5th pixel 995 (rank ⌈0.995·999⌉ = 995, value 2985).
    let pixels: Vec<u16> = (0..1000).map(|i| i as u16 * 3).collect();
    let (_, _, v) = decode(&preview_png(&pixels, 1000, 1, 1000));
    assert!(v[..=4].iter().all(|&g| g == 0), "{:?}", &v[..8]);
    assert!(v[995..].iter().all(|&g| g == 255), "{:?}", &v[990..]);
    assert_eq!(
        v[5], 0,
        "just above the low percentile: 255·3/2973 rounds to 0"
    );
    assert_eq!(v[6], 1);
    // Linear in between: value 3·500 → 255·(1500 − 12)/(2985 − 12).
    let expected = (255.0 * 1488.0 / 2973.0 + 0.5f64).floor() as u8;
    assert_eq!(v[500], expected);
    assert!(v.windows(2).all(|w| w[0] <= w[1]), "monotone");
}

#[test]
fn a_flat_image_is_mid_grey_and_outliers_of_a_nearly_flat_one_are_black_or_white() {
    let (w, h, v) = decode(&preview_png(&[700; 64], 8, 8, 8));
    assert_eq!((w, h), (8, 8));
    assert!(v.iter().all(|&g| g == 128));
    // One dark and one bright pixel among 1000: both beyond the percentiles.
    let mut pixels = vec![700u16; 1000];
    pixels[3] = 10;
    pixels[500] = 60_000;
    let (_, _, v) = decode(&preview_png(&pixels, 1000, 1, 1000));
    assert_eq!((v[3], v[500], v[0]), (0, 255, 128));
}

#[test]
fn area_averaging_matches_the_hand_computed_means() {
    // Eight pixels: the window is [min, max] = [0, 255], so grey = value.
    let pixels = [0, 10, 20, 30, 40, 50, 60, 255];
    let (w, h, v) = decode(&preview_png(&pixels, 4, 2, 2));
    assert_eq!((w, h), (2, 1));
    // (0 + 10 + 40 + 50) / 4 = 25; (20 + 30 + 60 + 255) / 4 = 91.25.
    assert_eq!(v, [25, 91]);
    // A non-integer ratio: 3 → 2 pixels, each output covers 1.5 inputs.
    let (_, _, v) = decode(&preview_png(&[0, 100, 255], 3, 1, 2));
    // (0 + 0.5·100) / 1.5 = 33.3; (0.5·100 + 255) / 1.5 = 203.3.
    assert_eq!(v, [33, 203]);
}

#[test]
fn side_by_side_places_each_windowed_image_with_a_white_gap() {
    let a: Vec<u16> = vec![0, 1000, 0, 1000, 0, 1000, 0, 1000];
    let b: Vec<u16> = vec![5, 6, 5, 6, 5, 6];
    let (w, h, v) = decode(&side_by_side(&[(&a, 4, 2), (&b, 2, 3)], 4));
    assert_eq!((w, h), (4 + GAP_PX + 2, 3));
    let at = |x: u32, y: u32| v[(y * w + x) as usize];
    // `a` (2 rows) is centred in 3 rows: top offset 0, its third row is white fill.
    assert_eq!([at(0, 0), at(1, 0), at(0, 1), at(1, 1)], [0, 255, 0, 255]);
    assert_eq!(at(0, 2), 255);
    // The gap is white; `b` is windowed on its own values [5, 6].
    assert!((4..4 + GAP_PX).all(|x| (0..3).all(|y| at(x, y) == 255)));
    assert_eq!([at(4 + GAP_PX, 0), at(5 + GAP_PX, 0)], [0, 255]);
    // One image alone is the same picture as preview_png.
    assert_eq!(side_by_side(&[(&a, 4, 2)], 4), preview_png(&a, 4, 2, 4));
}

#[test]
fn degenerate_inputs_give_a_small_valid_png() {
    for bytes in [
        preview_png(&[], 0, 0, 10),
        preview_png(&[], 5, 0, 10),
        side_by_side(&[], 10),
    ] {
        assert_eq!(decode(&bytes), (1, 1, vec![128]));
    }
    // max_side 0 counts as 1; a short pixel slice reads as zeros.
    assert_eq!(decode(&preview_png(&[1, 2, 3, 4], 2, 2, 0)).0, 1);
    let (w, h, v) = decode(&preview_png(&[100, 200], 2, 2, 2));
    assert_eq!((w, h), (2, 2));
    assert_eq!(v, [128, 255, 0, 0]);
}

#[test]
fn the_bytes_are_deterministic_and_pinned() {
    let pixels: Vec<u16> = (0u32..240 * 160)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 16) as u16)
        .collect();
    let first = preview_png(&pixels, 240, 160, 100);
    assert_eq!(first, preview_png(&pixels, 240, 160, 100));
    let hash: String = Sha256::digest(&first)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    // A change here means the png crate or the settings changed the bytes: deliberate only.
    assert_eq!(
        hash,
        "1696dcd5382ff3e5889b55d902fc1f7afdc43c86b82047fb1609646c51670ead"
    );
}

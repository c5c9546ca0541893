//! The paper's noise model: on every pixel that the objects do not cover, a Poisson count with
//! mean `level · I_max`, clamped to `I_max`.
//!
//! In binary mode a clean image holds `I_max` where an object covers the pixel and 0 elsewhere,
//! so "not covered" means "value 0"; pixels with any other value are left as they are.
//!
//! **Which sample lands where.** Row `j` draws from its own stream (see [`stream`]): pixel `i`
//! of the row takes the `i`-th `u64` of the stream, turned into a sample of the law of
//! `min(X, I_max)`, `X ~ Poisson(level · I_max)`, by the inversion table of [`table`] (one table
//! per image, one `u64` per pixel), if it is background; a covered pixel draws its `u64` and
//! discards it. So the noise value of a background pixel depends only on the key, its row and
//! its column, never on which other pixels are covered (the same seed gives the same noise
//! field under a different phantom pose), and a reviewer can recompute any pixel without the
//! mask. `level == 0` draws nothing and leaves the image unchanged.
//!
//! Rows are independent, so [`add_noise`] runs them in parallel and its output is byte-identical
//! to a sequential loop over [`add_noise_row`] whatever the number of threads.

pub mod normal;
pub mod poisson;
pub mod stream;
pub mod table;

pub use normal::standard_normal;
pub use poisson::Poisson;
pub use stream::NoiseKey;
pub use table::PoissonTable;

use rayon::prelude::*;

/// Adds noise to one image row in place.
///
/// Every pixel whose value is 0 becomes `min(sample, i_max)` where `sample` is drawn from a
/// Poisson law of mean `level · i_max` on the stream of row `row_index`; pixels ≠ 0 are
/// unchanged (their samples are drawn and discarded, see the module documentation).
/// `level == 0` returns at once. It builds the image's table for this one row; [`add_noise`]
/// builds it once for all rows.
///
/// # Panics
/// When `level` is negative, NaN or infinite.
pub fn add_noise_row(row: &mut [u16], row_index: u32, level: f64, i_max: u16, key: &NoiseKey) {
    if let Some(table) = image_table(level, i_max) {
        noise_row(row, row_index, &table, key);
    }
}

/// The inversion table of an image's noise, the law of `min(X, i_max)` with
/// `X ~ Poisson(level · i_max)`; `None` for `level == 0` or `i_max == 0` (nothing is drawn).
///
/// # Panics
/// When `level` is negative, NaN or infinite.
fn image_table(level: f64, i_max: u16) -> Option<PoissonTable> {
    assert!(
        level.is_finite() && level >= 0.0,
        "noise level must be finite and ≥ 0, got {level}"
    );
    let lambda = level * f64::from(i_max);
    (lambda > 0.0).then(|| PoissonTable::new(lambda, u64::from(i_max)))
}

/// [`add_noise_row`] with the image's table already built.
fn noise_row(row: &mut [u16], row_index: u32, table: &PoissonTable, key: &NoiseKey) {
    let mut rng = key.row_rng(row_index);
    // One sample per pixel, in order (`fill` = `sample` once per pixel, only faster).
    let mut samples = vec![0u64; row.len()];
    table.fill(&mut rng, &mut samples);
    for (px, &sample) in row.iter_mut().zip(&samples) {
        if *px == 0 {
            // The table's values never exceed its cap, i_max.
            *px = sample as u16;
        }
    }
}

/// Adds noise to a whole row-major image (`pixels.len()` a multiple of `width`) in place, all
/// rows in parallel with rayon. Row `j` is `pixels[j·width .. (j+1)·width]` and uses stream `j`;
/// the result is identical to calling [`add_noise_row`] on each row in order.
///
/// # Panics
/// When `width` is 0, `pixels.len()` is not a multiple of `width`, the image has more than
/// 2³² rows, or `level` is negative, NaN or infinite.
pub fn add_noise(pixels: &mut [u16], width: usize, level: f64, i_max: u16, key: &NoiseKey) {
    assert!(width > 0, "image width must be positive");
    assert!(
        pixels.len().is_multiple_of(width),
        "pixel count {} is not a multiple of the width {width}",
        pixels.len()
    );
    assert!(
        (pixels.len() / width) as u64 <= 1u64 << 32,
        "more than 2³² rows"
    );
    let Some(table) = image_table(level, i_max) else {
        return;
    };
    pixels
        .par_chunks_mut(width)
        .enumerate()
        .for_each(|(j, row)| noise_row(row, j as u32, &table, key));
}

/// The noise field alone, `width × height`: what [`add_noise`] puts on an image with no covered
/// pixel (every pixel `min(sample, i_max)`; all 0 when `level == 0`). With [`overlay`] it gives
/// [`add_noise`]'s image byte for byte, and it can be drawn while the clean image is still being
/// projected, since a background pixel's noise never depends on the mask.
///
/// # Panics
/// As [`add_noise`].
pub fn noise_field(
    width: usize,
    height: usize,
    level: f64,
    i_max: u16,
    key: &NoiseKey,
) -> Vec<u16> {
    let mut field = vec![0u16; width * height];
    add_noise(&mut field, width, level, i_max, key);
    field
}

/// Lays a clean binary-mode image over a [`noise_field`] of the same size: every pixel the
/// objects cover (non-zero in `clean`) takes its clean value, every other pixel keeps its noise.
///
/// # Panics
/// When the two images differ in size.
pub fn overlay(clean: &[u16], field: &mut [u16]) {
    assert_eq!(
        clean.len(),
        field.len(),
        "image and noise field differ in size"
    );
    for (f, &c) in field.iter_mut().zip(clean) {
        if c != 0 {
            *f = c;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_noise_field_overlaid_equals_noise_added() {
        let (w, h, i_max) = (97, 41, 4095);
        let clean = clean_image(w, h, i_max);
        for level in [0.0, 0.002, 0.45, 0.9] {
            let mut added = clean.clone();
            add_noise(&mut added, w, level, i_max, &key());
            let mut field = noise_field(w, h, level, i_max, &key());
            overlay(&clean, &mut field);
            assert_eq!(field, added, "level {level}");
        }
    }

    fn key() -> NoiseKey {
        NoiseKey::derive(7, 1, 3, "ap", "det_a")
    }

    /// A binary-mode test image: a disc and a bar of `i_max` on a 0 background.
    fn clean_image(w: usize, h: usize, i_max: u16) -> Vec<u16> {
        let mut v = vec![0u16; w * h];
        for j in 0..h {
            for i in 0..w {
                let (x, y) = (i as f64 - w as f64 / 3.0, j as f64 - h as f64 / 2.0);
                if x * x + y * y < (w as f64 / 6.0).powi(2) || (i > 3 * w / 4 && i < 3 * w / 4 + 5)
                {
                    v[j * w + i] = i_max;
                }
            }
        }
        v
    }

    #[test]
    fn level_zero_is_a_no_op() {
        let clean = clean_image(64, 48, 4095);
        let mut img = clean.clone();
        add_noise(&mut img, 64, 0.0, 4095, &key());
        assert_eq!(img, clean);
        let mut row = vec![0u16; 10];
        add_noise_row(&mut row, 0, 0.0, 4095, &key());
        assert_eq!(row, vec![0u16; 10]);
    }

    #[test]
    fn covered_pixels_stay_and_background_changes() {
        let i_max = 65535;
        let clean = clean_image(128, 96, i_max);
        let mut img = clean.clone();
        add_noise(&mut img, 128, 0.3, i_max, &key());
        for (c, n) in clean.iter().zip(&img) {
            if *c == i_max {
                assert_eq!(*n, i_max);
            } else {
                assert!(*n > 0, "λ≈19660 never gives 0");
            }
        }
    }

    #[test]
    fn nonzero_pixels_untouched_whatever_their_value() {
        let mut row = vec![0u16, 1, 2, 0, 500, 0];
        add_noise_row(&mut row, 4, 0.5, 1000, &key());
        assert_eq!([row[1], row[2], row[4]], [1, 2, 500]);
    }

    #[test]
    fn clamps_at_i_max() {
        // λ = 1.5·I_max: almost every sample exceeds I_max and is clamped.
        let i_max = 255;
        let mut img = vec![0u16; 64 * 64];
        add_noise(&mut img, 64, 1.5, i_max, &key());
        assert!(img.iter().all(|&v| v <= i_max));
        assert!(img.iter().filter(|&&v| v == i_max).count() > 64 * 64 * 99 / 100);
    }

    #[test]
    fn background_noise_independent_of_coverage() {
        let i_max = 4095;
        let mut a = vec![0u16; 256];
        let mut b = a.clone();
        for v in &mut b[40..90] {
            *v = i_max;
        }
        add_noise_row(&mut a, 9, 0.45, i_max, &key());
        add_noise_row(&mut b, 9, 0.45, i_max, &key());
        for i in (0..40).chain(90..256) {
            assert_eq!(a[i], b[i], "pixel {i}");
        }
    }

    #[test]
    fn parallel_equals_sequential_for_1_and_2_threads() {
        let (w, h, i_max) = (97, 61, 16383);
        let clean = clean_image(w, h, i_max);
        let mut seq = clean.clone();
        for (j, row) in seq.chunks_mut(w).enumerate() {
            add_noise_row(row, j as u32, 0.45, i_max, &key());
        }
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut par = clean.clone();
            pool.install(|| add_noise(&mut par, w, 0.45, i_max, &key()));
            assert_eq!(par, seq, "{threads} threads");
        }
    }

    #[test]
    fn noise_statistics_over_512_squared() {
        let (w, i_max) = (512usize, 4095u16);
        for level in [0.001, 0.1, 0.45, 0.9] {
            let lambda = level * f64::from(i_max);
            let mut img = vec![0u16; w * w];
            add_noise(&mut img, w, level, i_max, &key());
            let n = img.len() as f64;
            let mean = img.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
            let var = img
                .iter()
                .map(|&v| (f64::from(v) - mean).powi(2))
                .sum::<f64>()
                / (n - 1.0);
            assert!(
                (mean - lambda).abs() < 5.0 * (lambda / n).sqrt(),
                "level {level}: mean {mean}"
            );
            let se_var = ((lambda + 2.0 * lambda * lambda) / n).sqrt();
            assert!(
                (var - lambda).abs() < 5.0 * se_var,
                "level {level}: var {var}"
            );
        }
    }

    #[test]
    fn rows_use_their_own_streams() {
        let mut img = vec![0u16; 32 * 4];
        add_noise(&mut img, 32, 0.5, 1000, &key());
        assert_ne!(img[..32], img[32..64]);
        let mut row2 = vec![0u16; 32];
        add_noise_row(&mut row2, 2, 0.5, 1000, &key());
        assert_eq!(row2[..], img[64..96]);
    }

    /// Timing for the report: `cargo test --release --lib noise::tests::bench -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn bench_noise_1440() {
        let (w, i_max) = (1440usize, 65535u16);
        let clean = vec![0u16; w * w];
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut times = Vec::new();
            for _ in 0..5 {
                let mut img = clean.clone();
                let t = std::time::Instant::now();
                pool.install(|| add_noise(&mut img, w, 0.45, i_max, &key()));
                times.push(t.elapsed().as_secs_f64());
                std::hint::black_box(&img);
            }
            times.sort_by(f64::total_cmp);
            let med = times[2];
            println!(
                "noise 1440² level 0.45 bpp 16, {threads} thread(s): median {:.1} ms = {:.1} ns/pixel",
                med * 1e3,
                med * 1e9 / (w * w) as f64
            );
        }
    }
}

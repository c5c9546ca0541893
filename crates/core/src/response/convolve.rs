//! Separable convolution of an image with one kernel per axis, borders renormalised: the
//! detector PSF's blur (see [`super::psf`]).
//!
//! Output pixel `(i, j)` along a row is `Σ_k w_k · x_{i+k} / Σ_k w_k`, both sums over the taps
//! `k = −R … R` (ascending, from 0) whose pixel `i + k` lies in the image: the kernel truncated
//! at the border and renormalised there, so a uniform image stays uniform (within rounding) and
//! interior pixels divide by the kernel's own sum (1 within rounding). A pixel within the
//! half-width `R` of the border is such a renormalised mean, so an object closer than `2R` to
//! the border does not keep its total exactly; an isolated one does (test
//! `a_symmetric_blob_keeps_its_centroid_and_total`). Rows first, then columns.
//! Every output value is the same sequence of IEEE operations whatever the number of threads.

use rayon::prelude::*;

/// `img` (`w × h`, row-major) convolved along rows with `kx` and along columns with `ky`
/// (odd lengths, centre in the middle).
pub(crate) fn convolve(img: &[f64], w: usize, h: usize, kx: &[f64], ky: &[f64]) -> Vec<f64> {
    assert_eq!(img.len(), w * h, "image is not w × h");
    assert!(
        kx.len() % 2 == 1 && ky.len() % 2 == 1,
        "kernels have odd lengths"
    );
    if w == 0 || h == 0 {
        return img.to_vec();
    }
    // Along rows.
    let norm_x = border_sums(kx, w);
    let mut rows = vec![0.0; w * h];
    rows.par_chunks_mut(w)
        .zip(img.par_chunks(w))
        .for_each(|(out, input)| {
            out.fill(0.0);
            for_taps(kx, w, |wk, dst, src| {
                for (o, &x) in out[dst].iter_mut().zip(&input[src]) {
                    *o += wk * x;
                }
            });
            for (o, n) in out.iter_mut().zip(&norm_x) {
                *o /= n;
            }
        });
    // Along columns: output row j adds whole input rows j + k.
    let norm_y = border_sums(ky, h);
    let mut out = vec![0.0; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(j, out)| {
        out.fill(0.0);
        let r = ky.len() / 2;
        for (t, &wk) in ky.iter().enumerate() {
            let Some(src) = (j + t).checked_sub(r).filter(|&s| s < h) else {
                continue;
            };
            for (o, &x) in out.iter_mut().zip(&rows[src * w..(src + 1) * w]) {
                *o += wk * x;
            }
        }
        for o in out.iter_mut() {
            *o /= norm_y[j];
        }
    });
    out
}

/// Calls `f(w_k, destination range, source range)` for every tap of `kernel` (ascending) over a
/// line of `n` values, the ranges clipped to the line: `out[dst] += w_k · in[src]`.
fn for_taps(
    kernel: &[f64],
    n: usize,
    mut f: impl FnMut(f64, std::ops::Range<usize>, std::ops::Range<usize>),
) {
    let r = kernel.len() / 2;
    for (t, &wk) in kernel.iter().enumerate() {
        // Offset d = t − r: out[i] takes in[i + d] for 0 ≤ i, i + d < n.
        let (lo, hi) = if t >= r {
            let d = t - r;
            (0, n.saturating_sub(d))
        } else {
            let d = r - t;
            (d.min(n), n)
        };
        if lo < hi {
            let src = (lo + t) - r..(hi + t) - r;
            f(wk, lo..hi, src);
        }
    }
}

/// For every position of a line of `n` values, the sum of the kernel's taps that fall inside
/// the line, in the order [`convolve`] adds them (ascending, from 0).
pub(crate) fn border_sums(kernel: &[f64], n: usize) -> Vec<f64> {
    let mut sums = vec![0.0; n];
    for_taps(kernel, n, |wk, dst, _| {
        for s in &mut sums[dst] {
            *s += wk;
        }
    });
    sums
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The definition, one pixel at a time.
    fn direct(img: &[f64], w: usize, h: usize, kx: &[f64], ky: &[f64]) -> Vec<f64> {
        let line = |get: &dyn Fn(isize) -> Option<f64>, k: &[f64], i: isize| {
            let r = (k.len() / 2) as isize;
            let (mut s, mut n) = (0.0, 0.0);
            for (t, &wk) in k.iter().enumerate() {
                if let Some(x) = get(i + t as isize - r) {
                    s += wk * x;
                    n += wk;
                }
            }
            s / n
        };
        let mut rows = vec![0.0; w * h];
        for j in 0..h {
            for i in 0..w {
                let get = |c: isize| {
                    (0..w as isize)
                        .contains(&c)
                        .then(|| img[j * w + c as usize])
                };
                rows[j * w + i] = line(&get, kx, i as isize);
            }
        }
        let mut out = vec![0.0; w * h];
        for j in 0..h {
            for i in 0..w {
                let get = |r: isize| {
                    (0..h as isize)
                        .contains(&r)
                        .then(|| rows[r as usize * w + i])
                };
                out[j * w + i] = line(&get, ky, j as isize);
            }
        }
        out
    }

    #[test]
    fn equals_the_definition_bit_for_bit_with_kernels_wider_than_the_image() {
        let (w, h) = (13, 7);
        let img: Vec<f64> = (0..w * h).map(|p| ((p * 37) % 101) as f64 * 1.3).collect();
        let kx = [0.05, 0.1, 0.2, 0.3, 0.2, 0.1, 0.05];
        let ky: Vec<f64> = (0..19)
            .map(|t| 1.0 / (1.0 + (t as f64 - 9.0).abs()))
            .collect();
        let got = convolve(&img, w, h, &kx, &ky);
        let want = direct(&img, w, h, &kx, &ky);
        for (a, b) in got.iter().zip(&want) {
            assert_eq!(a.to_bits(), b.to_bits());
        }
        // A one-tap kernel changes nothing.
        assert_eq!(convolve(&img, w, h, &[1.0], &[1.0]), img);
    }

    #[test]
    fn a_uniform_image_stays_uniform_at_the_borders() {
        let (w, h) = (40, 30);
        let k = [0.1, 0.2, 0.4, 0.2, 0.1];
        let out = convolve(&vec![7.25; w * h], w, h, &k, &k);
        assert!(out.iter().all(|&v| (v - 7.25).abs() < 1e-14 * 7.25));
    }

    #[test]
    fn a_symmetric_blob_keeps_its_centroid_and_total() {
        use crate::response::{Psf, PsfShape};
        // A smooth MTF (a tabulated Gaussian, 41 rows down to 10⁻⁶): a short kernel.
        let mtf = PsfShape::Mtf {
            table: (0..=40)
                .map(|i| {
                    let f = 2.0 * i as f64 / 40.0;
                    [f, libm::exp(-f * f * 3.4539)]
                })
                .collect(),
        };
        for shape in [PsfShape::Gaussian { sigma_mm: 0.35 }, mtf] {
            let psf = Psf::new(shape, [0.2, 0.3]).unwrap();
            // Isolated: no output pixel within the kernel's reach of the blob has a window cut
            // by the border (closer, the renormalisation would scale its share).
            let (rx, ry) = (psf.kernel_x().len() / 2, psf.kernel_y().len() / 2);
            let (w, h) = (4 * rx + 11, 4 * ry + 9);
            let (mx, my) = ((w / 2) as f64, (h / 2) as f64);
            // Blobs symmetric about a pixel centre and about a pixel corner: x(c + d) = x(c − d).
            for (cx, cy) in [(mx + 0.5, my + 0.5), (mx, my)] {
                let img: Vec<f64> = (0..w * h)
                    .map(|p| {
                        let (x, y) = ((p % w) as f64 + 0.5 - cx, (p / w) as f64 + 0.5 - cy);
                        let r2 = x * x / 16.0 + y * y / 9.0;
                        if r2 < 1.0 {
                            1000.0 * (1.0 - r2) + 7.0
                        } else {
                            0.0
                        }
                    })
                    .collect();
                let out = convolve(&img, w, h, psf.kernel_x(), psf.kernel_y());
                let moments = |v: &[f64]| {
                    let (mut m0, mut mx, mut my) = (0.0, 0.0, 0.0);
                    for (p, &a) in v.iter().enumerate() {
                        m0 += a;
                        mx += a * ((p % w) as f64 + 0.5);
                        my += a * ((p / w) as f64 + 0.5);
                    }
                    (m0, mx / m0, my / m0)
                };
                let (t0, x0, y0) = moments(&img);
                let (t1, x1, y1) = moments(&out);
                assert!((t1 - t0).abs() < 1e-12 * t0, "total {t1} vs {t0}");
                assert!(
                    (x1 - cx).abs() < 1e-9 && (y1 - cy).abs() < 1e-9,
                    "{x1} {y1}"
                );
                assert!((x0 - cx).abs() < 1e-9 && (y0 - cy).abs() < 1e-9);
                // And it did blur.
                assert!(
                    out.iter().filter(|&&v| v > 0.0).count()
                        > img.iter().filter(|&&v| v > 0.0).count()
                );
            }
        }
    }
}

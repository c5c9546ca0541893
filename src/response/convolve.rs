//! Separable convolution of an image with one kernel per axis, borders renormalised: the
//! detector PSF's blur (see [`super::psf`]).
//!
//! Output pixel `(i, j)` along a row is `Σ_k w_k · x_{i+k} / Σ_k w_k`, both sums over the taps
//! `k = −R … R` (ascending, from 0) whose pixel `i + k` lies in the image: the kernel truncated
//! at the border and renormalised there, so a uniform image stays uniform (within rounding) and
//! interior pixels divide by the kernel's own sum (1 within rounding). Rows first, then columns.
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
}

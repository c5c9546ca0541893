//! Scatter as a broad blur of the primary image (an approximation; see [`Scatter`]).
//!
//! `K ∗ x` is computed per axis as [`SCATTER_PASSES`] passes of a running box sum, a cascade
//! whose kernel is a piecewise cubic close to a Gaussian (it differs from the Gaussian of the
//! nominal σ by at most 3.6 % of the peak; its variance is within 0.1 % of `σ²` for σ ≥ 20 px
//! and within 2 % at 6.7 px, test `the_cascade_is_close_to_the_gaussian`): box widths are odd, `w_l` or
//! `w_l + 2`, chosen as in Kovesi's "fast almost-Gaussian filtering" (2010) so that the summed
//! variance `Σ (w² − 1)/12` is the closest such sum to `σ²/p²`. Each line is padded with zeros
//! by the sum of the box radii on both sides before the passes, so the result inside the image
//! is exactly the cascade's full kernel truncated at the border; dividing by the same cascade of
//! the image's indicator (1 inside, 0 outside) renormalises the truncated kernel, so a uniform
//! image comes out unchanged (within a few ulp). The running sums are compensated (Neumaier
//! two-sum: a sum and its rounding error), so they do not drift along a line. Rows first, then
//! columns; each pass runs as vectors across a strip of lines (rows gathered into a strip for
//! the first), in buffers reused from strip to strip, and every value is the same sequence of
//! IEEE operations on any number of threads. The cost does not depend on σ.

use rayon::prelude::*;

use super::psf::check_pitch;

/// Box passes per axis.
pub const SCATTER_PASSES: usize = 4;

/// The largest scatter-to-primary ratio accepted.
pub const MAX_SCATTER_RATIO: f64 = 100.0;

/// The largest scatter kernel σ accepted, mm.
pub const MAX_SCATTER_SIGMA_MM: f64 = 1000.0;

/// The largest scatter kernel σ accepted, in pixels of either axis.
pub const MAX_SCATTER_SIGMA_PX: f64 = 1e4;

/// Lines (rows or columns) per strip of the passes.
const STRIP: usize = 64;

/// Scatter added to the expected image before the quantum noise, as a constant
/// scatter-to-primary ratio (SPR) and a broad normalised kernel `K` (2-D, separable, close to a
/// Gaussian of `sigma_mm`): `Q ← Q + SPR · K ∗ Q`, `E ← E + SPR · K ∗ E`.
///
/// **An approximation.** Real scatter depends on the object (the SPR grows with the thickness
/// crossed, the kernel with the air gap and the field size), its photons have lower energy than
/// the primary ones, and an anti-scatter grid changes both; here one SPR and one kernel hold
/// for the whole image, and scattered photons deposit the mean energy of the primary ones
/// around them. The flat field of a radiograph has no scatter in it. Made only by
/// [`Scatter::new`], so its numbers are always valid.
#[derive(Debug, Clone, PartialEq)]
pub struct Scatter {
    ratio: f64,
    sigma_mm: f64,
    /// Box radii per axis `[x, y]` (box width `2r + 1`), one per pass.
    radii: [Vec<usize>; 2],
}

impl Scatter {
    /// Scatter of ratio `ratio` (SPR, finite, 0 … [`MAX_SCATTER_RATIO`]) and kernel SD
    /// `sigma_mm` (finite, > 0, ≤ [`MAX_SCATTER_SIGMA_MM`], and at most
    /// [`MAX_SCATTER_SIGMA_PX`] pixels) on pixels of `pitch_mm` `[x, y]`. The error names the
    /// field and what would be valid.
    pub fn new(ratio: f64, sigma_mm: f64, pitch_mm: [f64; 2]) -> Result<Scatter, String> {
        check_pitch(pitch_mm)?;
        if !(0.0..=MAX_SCATTER_RATIO).contains(&ratio) {
            return Err(format!(
                "scatter ratio = {ratio} is not valid (must be finite and between 0 and \
                 {MAX_SCATTER_RATIO}: the scatter-to-primary ratio)"
            ));
        }
        if !(sigma_mm > 0.0 && sigma_mm <= MAX_SCATTER_SIGMA_MM) {
            return Err(format!(
                "scatter sigma_mm = {sigma_mm} is not valid (must be finite, > 0 and ≤ \
                 {MAX_SCATTER_SIGMA_MM} mm)"
            ));
        }
        let px = pitch_mm.map(|p| sigma_mm / p);
        if px.iter().any(|&s| s > MAX_SCATTER_SIGMA_PX) {
            return Err(format!(
                "scatter sigma_mm = {sigma_mm} is more than {MAX_SCATTER_SIGMA_PX} pixels of \
                 pitch {:?} mm (use a smaller sigma_mm)",
                pitch_mm
            ));
        }
        Ok(Scatter {
            ratio,
            sigma_mm,
            radii: px.map(box_radii),
        })
    }

    /// The scatter-to-primary ratio.
    pub fn ratio(&self) -> f64 {
        self.ratio
    }

    /// The kernel's nominal SD, mm.
    pub fn sigma_mm(&self) -> f64 {
        self.sigma_mm
    }

    /// The box widths of the passes along x and along y, px (odd).
    pub fn box_widths_px(&self) -> [Vec<usize>; 2] {
        self.radii
            .clone()
            .map(|r| r.iter().map(|r| 2 * r + 1).collect())
    }

    /// The variance of the kernel actually applied along x and along y, px²:
    /// `Σ (w² − 1)/12` over the passes (compare with `(σ/p)²`).
    pub fn kernel_variance_px2(&self) -> [f64; 2] {
        self.box_widths_px()
            .map(|w| w.iter().map(|&w| ((w * w - 1) as f64) / 12.0).sum())
    }

    /// `x + SPR · K ∗ x` for the `w × h` image `x` (row-major).
    pub(crate) fn add_to(&self, x: &[f64], w: usize, h: usize) -> Vec<f64> {
        blur_with(x, w, h, &self.radii, |p, s| x[p] + self.ratio * s)
    }
}

/// Kovesi's box radii for a Gaussian of `sigma_px`.
fn box_radii(sigma_px: f64) -> Vec<usize> {
    let n = SCATTER_PASSES as f64;
    let var = sigma_px * sigma_px;
    let ideal = libm::sqrt(12.0 * var / n + 1.0);
    let mut wl = libm::floor(ideal) as usize;
    if wl.is_multiple_of(2) {
        wl = wl.saturating_sub(1);
    }
    let wl = wl.max(1);
    let wlf = wl as f64;
    let m = (12.0 * var - n * wlf * wlf - 4.0 * n * wlf - 3.0 * n) / (-4.0 * wlf - 4.0);
    let m = libm::round(m).clamp(0.0, n) as usize;
    (0..SCATTER_PASSES)
        .map(|k| if k < m { wl / 2 } else { wl / 2 + 1 })
        .collect()
}

/// `K ∗ x` normalised (module documentation): rows, then columns.
#[cfg(test)]
fn blur(x: &[f64], w: usize, h: usize, radii: &[Vec<usize>; 2]) -> Vec<f64> {
    blur_with(x, w, h, radii, |_, s| s)
}

/// `finish(p, (K ∗ x)_p)` for every pixel `p` (row-major), `K ∗ x` normalised (module
/// documentation): along the rows, then along the columns. Each pass runs the cascade on strips
/// of [`STRIP`] lines, a line per lane (rows gathered into a strip for the first pass, columns
/// for the second), in buffers reused from strip to strip; every value is the same sequence of
/// IEEE operations whatever the strips and the threads.
fn blur_with(
    x: &[f64],
    w: usize,
    h: usize,
    radii: &[Vec<usize>; 2],
    finish: impl Fn(usize, f64) -> f64 + Sync,
) -> Vec<f64> {
    if w == 0 || h == 0 {
        return x.iter().enumerate().map(|(p, &v)| finish(p, v)).collect();
    }
    let along_rows = blur_rows(x, w, h, &radii[0]);
    blur_columns(&along_rows, w, h, &radii[1], finish)
}

/// The cascade of the indicator of a line of `n` values padded by `pad` on both sides
/// (integers below 2⁵³, so exact): what a border pixel's sum is divided by.
fn denominators(n: usize, pad: usize, radii: &[usize]) -> Vec<f64> {
    let len = n + 2 * pad;
    let mut ind = vec![0.0; len];
    ind[pad..pad + n].fill(1.0);
    let mut scratch = Vec::new();
    cascade(&mut ind, &mut scratch, 1, radii);
    ind
}

/// The box cascade along every row of the `w × h` image `x`, renormalised at the borders:
/// [`STRIP`] rows at a time, each row a lane of a `(w + 2·pad) × rows` strip.
fn blur_rows(x: &[f64], w: usize, h: usize, radii: &[usize]) -> Vec<f64> {
    let pad: usize = radii.iter().sum();
    let len = w + 2 * pad;
    let den = denominators(w, pad, radii);
    let mut out = vec![0.0; w * h];
    out.par_chunks_mut(w * STRIP)
        .zip(x.par_chunks(w * STRIP))
        .for_each_init(
            || (Vec::new(), Vec::new()),
            |(a, b), (out, x)| {
                let sr = x.len() / w;
                a.clear();
                a.resize(len * sr, 0.0);
                for (k, row) in x.chunks_exact(w).enumerate() {
                    for (i, &v) in row.iter().enumerate() {
                        a[(pad + i) * sr + k] = v;
                    }
                }
                cascade(a, b, sr, radii);
                for (k, row) in out.chunks_exact_mut(w).enumerate() {
                    for (i, o) in row.iter_mut().enumerate() {
                        *o = a[(pad + i) * sr + k] / den[pad + i];
                    }
                }
            },
        );
    out
}

/// The output image, written by several strips at once, each into its own columns.
struct Columns(*mut f64);

// SAFETY: the strips of `blur_columns` write disjoint columns of the image behind the pointer,
// which outlives them.
unsafe impl Sync for Columns {}

/// `finish(p, ·)` of the box cascade along every column of the `w × h` image `x`, renormalised
/// at the borders: [`STRIP`] columns at a time, each a lane of a `(h + 2·pad) × columns` strip.
fn blur_columns(
    x: &[f64],
    w: usize,
    h: usize,
    radii: &[usize],
    finish: impl Fn(usize, f64) -> f64 + Sync,
) -> Vec<f64> {
    let pad: usize = radii.iter().sum();
    let len = h + 2 * pad;
    let den = denominators(h, pad, radii);
    let mut out = vec![0.0; w * h];
    let target = Columns(out.as_mut_ptr());
    (0..w)
        .step_by(STRIP)
        .collect::<Vec<_>>()
        .into_par_iter()
        .for_each_init(
            || (Vec::new(), Vec::new()),
            |(a, b), c0| {
                let sw = STRIP.min(w - c0);
                a.clear();
                a.resize(len * sw, 0.0);
                for j in 0..h {
                    a[(pad + j) * sw..(pad + j + 1) * sw]
                        .copy_from_slice(&x[j * w + c0..j * w + c0 + sw]);
                }
                cascade(a, b, sw, radii);
                let target = &target;
                for j in 0..h {
                    let d = den[pad + j];
                    for (k, &v) in a[(pad + j) * sw..(pad + j + 1) * sw].iter().enumerate() {
                        let p = j * w + c0 + k;
                        // SAFETY: `p < w·h`, and column c0 + k belongs to this strip alone.
                        unsafe { *target.0.add(p) = finish(p, v / d) };
                    }
                }
            },
        );
    out
}

/// The passes of box sums of radii `radii` down the rows of `a` (`len × sw`, row-major, zero
/// outside), each a compensated running sum per column; the result is left in `a`, `b` is
/// scratch.
fn cascade(a: &mut Vec<f64>, b: &mut Vec<f64>, sw: usize, radii: &[usize]) {
    let len = a.len() / sw;
    b.clear();
    b.resize(a.len(), 0.0);
    let (mut hi, mut lo) = (vec![0.0; sw], vec![0.0; sw]);
    for &r in radii {
        hi.fill(0.0);
        lo.fill(0.0);
        for i in 0..r.min(len) {
            two_sum(&mut hi, &mut lo, &a[i * sw..(i + 1) * sw], 1.0);
        }
        for i in 0..len {
            if i + r < len {
                two_sum(&mut hi, &mut lo, &a[(i + r) * sw..(i + r + 1) * sw], 1.0);
            }
            if i > r {
                two_sum(&mut hi, &mut lo, &a[(i - r - 1) * sw..(i - r) * sw], -1.0);
            }
            for ((o, &h), &l) in b[i * sw..(i + 1) * sw].iter_mut().zip(&hi).zip(&lo) {
                *o = h + l;
            }
        }
        std::mem::swap(a, b);
    }
}

/// `(hi, lo) += sign · x` per lane: Neumaier's two-sum, the rounding error kept in `lo`.
#[inline(always)]
fn two_sum(hi: &mut [f64], lo: &mut [f64], x: &[f64], sign: f64) {
    for ((h, l), &v) in hi.iter_mut().zip(lo.iter_mut()).zip(x) {
        let v = sign * v;
        let s = *h + v;
        let bb = s - *h;
        *l += (*h - (s - bb)) + (v - bb);
        *h = s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cascade's 1-D kernel (box widths convolved), unnormalised, centre in the middle.
    fn cascade_kernel(radii: &[usize]) -> Vec<f64> {
        let mut k = vec![1.0];
        for &r in radii {
            let mut next = vec![0.0; k.len() + 2 * r];
            for (i, &v) in k.iter().enumerate() {
                for t in 0..=2 * r {
                    next[i + t] += v;
                }
            }
            k = next;
        }
        k
    }

    #[test]
    fn a_uniform_image_gets_exactly_one_plus_spr_times_itself() {
        for (w, h, ratio, sigma, pitch) in [
            (300, 200, 0.3, 40.0, [0.2986, 0.2986]),
            (97, 61, 2.5, 5.0, [0.14, 0.3]),
            (50, 40, 0.7, 0.2, [0.2, 0.2]),
        ] {
            let s = Scatter::new(ratio, sigma, pitch).unwrap();
            for c in [1.0, 12_345.678_9, 3.3e-7] {
                let out = s.add_to(&vec![c; w * h], w, h);
                let want = c * (1.0 + ratio);
                for v in &out {
                    assert!((v - want).abs() <= 1e-12 * want, "{v} vs {want}");
                }
            }
        }
    }

    #[test]
    fn equals_the_truncated_renormalised_cascade_kernel() {
        // The definition pixel by pixel: Σ K(i−i', j−j') x(i', j') / Σ K over the image, with
        // K the product of the per-axis cascade kernels, on an image narrower than the kernel.
        let (w, h) = (23, 17);
        let s = Scatter::new(1.0, 3.0, [0.5, 0.4]).unwrap();
        let (kx, ky) = (cascade_kernel(&s.radii[0]), cascade_kernel(&s.radii[1]));
        assert!(kx.len() > w && ky.len() > h, "{} {}", kx.len(), ky.len());
        let x: Vec<f64> = (0..w * h)
            .map(|p| 1.0 + ((p * 31) % 17) as f64 * 100.0)
            .collect();
        let got = blur(&x, w, h, &s.radii);
        let (rx, ry) = ((kx.len() / 2) as isize, (ky.len() / 2) as isize);
        for j in 0..h as isize {
            for i in 0..w as isize {
                let (mut num, mut den) = (0.0, 0.0);
                for jj in 0..h as isize {
                    for ii in 0..w as isize {
                        let (dx, dy) = (ii - i + rx, jj - j + ry);
                        if (0..kx.len() as isize).contains(&dx)
                            && (0..ky.len() as isize).contains(&dy)
                        {
                            let k = kx[dx as usize] * ky[dy as usize];
                            num += k * x[(jj * w as isize + ii) as usize];
                            den += k;
                        }
                    }
                }
                let g = got[(j * w as isize + i) as usize];
                assert!(
                    (g - num / den).abs() < 1e-12 * g,
                    "({i}, {j}): {g} vs {}",
                    num / den
                );
            }
        }
    }

    #[test]
    fn the_cascade_is_close_to_the_gaussian() {
        // σ = 40 mm at 0.2986 mm (134 px) and 2 mm at 0.3 mm (6.7 px): the applied variance
        // within 1 % (resp. 5 %) of σ², the kernel within 3.6 % of the Gaussian's peak anywhere
        // (4 passes; measured 3.5 % at 134 px, 2.8 % at 6.7 px).
        for (sigma, p, var_tol) in [(40.0, 0.2986, 0.01), (2.0, 0.3, 0.05), (60.0, 0.14, 0.01)] {
            let s = Scatter::new(0.3, sigma, [p, p]).unwrap();
            let sp = sigma / p;
            let var = s.kernel_variance_px2()[0];
            assert!(
                (var / (sp * sp) - 1.0).abs() < var_tol,
                "σ {sp} px: variance {var}"
            );
            let k = cascade_kernel(&s.radii[0]);
            let sum: f64 = k.iter().sum();
            let r = (k.len() / 2) as f64;
            let peak = 1.0 / (sp * (2.0 * std::f64::consts::PI).sqrt());
            let worst = k
                .iter()
                .enumerate()
                .map(|(i, v)| {
                    let x = i as f64 - r;
                    (v / sum - peak * libm::exp(-x * x / (2.0 * sp * sp))).abs()
                })
                .fold(0.0, f64::max);
            assert!(worst < 0.036 * peak, "σ {sp} px: {}", worst / peak);
            // The box variances add up to what the kernel has.
            let kv: f64 = k
                .iter()
                .enumerate()
                .map(|(i, v)| v / sum * (i as f64 - r).powi(2))
                .sum();
            assert!((kv - var).abs() < 1e-9 * var);
        }
    }

    #[test]
    fn invalid_numbers_name_the_field() {
        for (ratio, sigma, pitch, want) in [
            (-0.1, 40.0, [0.3, 0.3], "scatter ratio = -0.1"),
            (f64::NAN, 40.0, [0.3, 0.3], "scatter ratio = NaN"),
            (101.0, 40.0, [0.3, 0.3], "between 0 and 100"),
            (0.3, 0.0, [0.3, 0.3], "scatter sigma_mm = 0"),
            (0.3, f64::INFINITY, [0.3, 0.3], "≤ 1000 mm"),
            (0.3, 40.0, [0.0, 0.3], "pixel_pitch_mm[0] = 0"),
            (0.3, 500.0, [0.01, 0.3], "more than 10000 pixels"),
        ] {
            let e = Scatter::new(ratio, sigma, pitch).unwrap_err();
            assert!(e.contains(want), "{e}");
        }
        let s = Scatter::new(0.0, 40.0, [0.3, 0.3]).unwrap();
        assert_eq!((s.ratio(), s.sigma_mm()), (0.0, 40.0));
    }
}

//! The detector's point-spread function as one kernel per pixel axis, built from a Gaussian σ
//! or from an MTF table for a given pixel pitch.
//!
//! **Weights.** Kernel weight `w_k` (`k` pixels from the centre) is the line-spread function
//! (LSF) integrated over pixel `k`, i.e. the fraction of a line of light at the centre of pixel 0
//! that lands in pixel `k`:
//!
//! * Gaussian of SD `σ` (mm), pitch `p`: `w_k = Φ((k+½)p/σ) − Φ((k−½)p/σ)`, computed with
//!   `libm::erf` (k = 0) and `libm::erfc` (k ≥ 1, so the tails keep their relative precision);
//!   the kernel's variance is `σ²/p² + 1/12` px² (a Gaussian convolved with the pixel's box)
//!   within 1 % for `σ ≥ 0.55 p`; a narrower Gaussian, sampled at whole pixels, gives a kernel
//!   narrower than that (−2.4 % at `σ = 0.5 p`, −13 % at `0.4 p`).
//! * MTF table `[(f_i, M_i)]` (cycles/mm, ascending from `(0, 1)`): `M(f)` is the linear
//!   interpolation of the table up to its last frequency and 0 beyond. The LSF is its cosine
//!   transform `LSF(x) = 2 ∫₀^∞ M(f) cos(2πfx) df` (per mm), and the weight its integral over
//!   pixel `k`: `w_k = 2 ∫₀^{f_last·p} M(u/p) · sinc(u) · cos(2πku) du` with `u = f·p` in
//!   cycles per pixel and `sinc(u) = sin(πu)/(πu)` (the pixel's box). The integral runs per table
//!   segment with 8-point Gauss–Legendre on panels at most half a period of the fastest cosine
//!   wide; `cos(2πku)` by the Chebyshev recurrence from `libm::cos(2πu)`.
//!
//! **Truncation and normalisation.** The half-width `R` is the largest `k` with `|w_k| ≥ 10⁻⁶`
//! (weights before normalisation, whose untruncated sum is 1), searched up to [`MAX_HALF_WIDTH_MM`]
//! and at most [`MAX_HALF_WIDTH_PX`]; a Gaussian that would need more is refused. The kernel is
//! `w_{−R} … w_R` with `w_{−k}` the same value as `w_k`, each divided by their sum (taken from
//! `−R` up): normalised (sum 1 within rounding) and symmetric bit for bit.

/// Weights below this (before normalisation) at the kernel's ends are cut.
pub const KERNEL_CUTOFF: f64 = 1e-6;

/// No kernel reaches further than this from its centre, mm: an MTF whose LSF still has weights
/// above [`KERNEL_CUTOFF`] there (a table that stops sharply above 0) is cut at this width.
pub const MAX_HALF_WIDTH_MM: f64 = 50.0;

/// No kernel has more than this many pixels on each side of its centre.
pub const MAX_HALF_WIDTH_PX: usize = 4096;

/// The largest Gaussian σ accepted, mm.
pub const MAX_SIGMA_MM: f64 = 10.0;

/// The largest MTF frequency accepted, cycles/mm.
pub const MAX_MTF_FREQUENCY: f64 = 100.0;

/// The shape of a detector PSF, as a scenario gives it.
#[derive(Debug, Clone, PartialEq)]
pub enum PsfShape {
    /// A Gaussian of this standard deviation, mm (finite, > 0, ≤ [`MAX_SIGMA_MM`]).
    Gaussian {
        /// SD of the Gaussian, mm.
        sigma_mm: f64,
    },
    /// A modulation transfer function as rows `[frequency in cycles/mm, value]`: at least 2,
    /// the first `[0, 1]`, frequencies ascending (≤ [`MAX_MTF_FREQUENCY`]), values in `[0, 1]`;
    /// linearly interpolated, 0 beyond the last row.
    Mtf {
        /// The rows `[cycles_per_mm, value]`.
        table: Vec<[f64; 2]>,
    },
}

/// A detector PSF built for one pixel pitch: a normalised, symmetric kernel per axis (module
/// documentation). Made only by [`Psf::new`], so its kernels are always valid.
#[derive(Debug, Clone, PartialEq)]
pub struct Psf {
    shape: PsfShape,
    pitch_mm: [f64; 2],
    kernel_x: Vec<f64>,
    kernel_y: Vec<f64>,
}

impl Psf {
    /// Builds the kernels of `shape` for pixels of `pitch_mm` `[x, y]` (along a row, along a
    /// column). The error names the field and what would be valid.
    pub fn new(shape: PsfShape, pitch_mm: [f64; 2]) -> Result<Psf, String> {
        check_pitch(pitch_mm)?;
        check_shape(&shape)?;
        let kernel = |p: f64| match &shape {
            PsfShape::Gaussian { sigma_mm } => gaussian_kernel(*sigma_mm, p),
            PsfShape::Mtf { table } => mtf_kernel(table, p),
        };
        let kernel_x = kernel(pitch_mm[0])?;
        let kernel_y = kernel(pitch_mm[1])?;
        Ok(Psf {
            shape,
            pitch_mm,
            kernel_x,
            kernel_y,
        })
    }

    /// The shape it was built from.
    pub fn shape(&self) -> &PsfShape {
        &self.shape
    }

    /// The pitch it was built for, mm `[x, y]`.
    pub fn pitch_mm(&self) -> [f64; 2] {
        self.pitch_mm
    }

    /// The kernel along a row (odd length `2R + 1`, centre at index `R`).
    pub fn kernel_x(&self) -> &[f64] {
        &self.kernel_x
    }

    /// The kernel along a column (odd length `2R + 1`, centre at index `R`).
    pub fn kernel_y(&self) -> &[f64] {
        &self.kernel_y
    }
}

/// Checks a pixel pitch `[x, y]`: each finite and > 0 mm.
pub(crate) fn check_pitch(pitch_mm: [f64; 2]) -> Result<(), String> {
    for (a, p) in pitch_mm.iter().enumerate() {
        if !(*p > 0.0 && p.is_finite()) {
            return Err(format!(
                "pixel_pitch_mm[{a}] = {p} is not valid (must be finite and > 0 mm)"
            ));
        }
    }
    Ok(())
}

fn check_shape(shape: &PsfShape) -> Result<(), String> {
    match shape {
        PsfShape::Gaussian { sigma_mm } => {
            let s = *sigma_mm;
            if !(s > 0.0 && s <= MAX_SIGMA_MM) {
                return Err(format!(
                    "psf sigma_mm = {s} is not valid (must be finite, > 0 and ≤ {MAX_SIGMA_MM} mm)"
                ));
            }
        }
        PsfShape::Mtf { table } => {
            if table.len() < 2 {
                return Err(format!(
                    "mtf has {} row(s) (needs at least 2 rows [cycles_per_mm, value], the first \
                     [0.0, 1.0])",
                    table.len()
                ));
            }
            if table[0] != [0.0, 1.0] {
                return Err(format!(
                    "mtf row 0 = [{}, {}] is not valid (must be [0.0, 1.0]: value 1 at \
                     frequency 0)",
                    table[0][0], table[0][1]
                ));
            }
            for (i, pair) in table.windows(2).enumerate() {
                let ([f0, _], [f, v]) = (pair[0], pair[1]);
                if !(f > f0 && f <= MAX_MTF_FREQUENCY) {
                    return Err(format!(
                        "mtf row {} has frequency {f} (frequencies must ascend strictly from 0, \
                         each above the previous {f0} and ≤ {MAX_MTF_FREQUENCY} cycles/mm)",
                        i + 1
                    ));
                }
                if !(0.0..=1.0).contains(&v) {
                    return Err(format!(
                        "mtf row {} has value {v} (values must be in [0, 1])",
                        i + 1
                    ));
                }
            }
        }
    }
    Ok(())
}

/// The largest half-width searched at pitch `p`, px.
fn max_half_width(p: f64) -> usize {
    let by_mm = (MAX_HALF_WIDTH_MM / p).ceil();
    if by_mm < MAX_HALF_WIDTH_PX as f64 {
        by_mm as usize
    } else {
        MAX_HALF_WIDTH_PX
    }
}

/// The Gaussian's weights `w_0, w_1, …` (module documentation), cut and normalised.
fn gaussian_kernel(sigma_mm: f64, p: f64) -> Result<Vec<f64>, String> {
    let a = p / (sigma_mm * std::f64::consts::SQRT_2);
    let max = max_half_width(p);
    let mut half = vec![libm::erf(0.5 * a)];
    loop {
        let k = half.len() as f64;
        let w = 0.5 * (libm::erfc((k - 0.5) * a) - libm::erfc((k + 0.5) * a));
        if w < KERNEL_CUTOFF {
            break;
        }
        if half.len() > max {
            return Err(format!(
                "psf sigma_mm = {sigma_mm} at pixel pitch {p} mm needs a kernel wider than {max} \
                 px on each side (use a smaller sigma_mm or a coarser pitch)"
            ));
        }
        half.push(w);
    }
    Ok(symmetric(&half))
}

/// 8-point Gauss–Legendre nodes on `[−1, 1]` (positive half) and their weights.
const GL_NODES: [f64; 4] = [
    0.183_434_642_495_649_8,
    0.525_532_409_916_329,
    0.796_666_477_413_626_7,
    0.960_289_856_497_536_3,
];
const GL_WEIGHTS: [f64; 4] = [
    0.362_683_783_378_362,
    0.313_706_645_877_887_3,
    0.222_381_034_453_374_47,
    0.101_228_536_290_376_26,
];

/// The MTF table's weights (module documentation), cut and normalised.
fn mtf_kernel(table: &[[f64; 2]], p: f64) -> Result<Vec<f64>, String> {
    let acc = mtf_weights(table, p, max_half_width(p));
    let r = acc
        .iter()
        .rposition(|w| w.abs() >= KERNEL_CUTOFF)
        .unwrap_or(0);
    let half = &acc[..=r];
    if !(half[0] > 0.0) {
        return Err(
            "mtf gives a line-spread function that is not positive at its centre (an MTF \
             table should describe a blur: values falling from 1 towards 0)"
                .to_string(),
        );
    }
    let kernel = symmetric(half);
    if !(kernel.iter().sum::<f64>() > 0.0) {
        return Err("mtf gives a kernel whose weights do not sum to a positive value".to_string());
    }
    Ok(kernel)
}

/// The MTF table's weights `w_0 … w_{k_max}` at pitch `p` before cutting and normalising
/// (module documentation).
fn mtf_weights(table: &[[f64; 2]], p: f64, k_max: usize) -> Vec<f64> {
    let mut acc = vec![0.0; k_max + 1];
    let mut cos = vec![0.0; k_max + 1];
    for seg in table.windows(2) {
        let ([f0, m0], [f1, m1]) = (seg[0], seg[1]);
        let (u0, u1) = (f0 * p, f1 * p);
        // Panels at most half a period of cos(2π·k_max·u) wide.
        let panels = ((u1 - u0) * 2.0 * (k_max as f64 + 1.0)).ceil().max(1.0) as usize;
        let h = (u1 - u0) / panels as f64;
        for n in 0..panels {
            let mid = u0 + (n as f64 + 0.5) * h;
            for (node, gw) in GL_NODES.iter().zip(GL_WEIGHTS) {
                for u in [mid - 0.5 * h * node, mid + 0.5 * h * node] {
                    let m = m0 + (m1 - m0) * ((u - u0) / (u1 - u0));
                    let sinc = if u == 0.0 {
                        1.0
                    } else {
                        let x = std::f64::consts::PI * u;
                        libm::sin(x) / x
                    };
                    let g = 2.0 * m * sinc * gw * 0.5 * h;
                    chebyshev_cosines(libm::cos(std::f64::consts::TAU * u), &mut cos);
                    for (a, c) in acc.iter_mut().zip(&cos) {
                        *a += g * c;
                    }
                }
            }
        }
    }
    acc
}

/// `cos(k·θ)` for `k = 0..out.len()` from `c1 = cos θ`: `c_{k+1} = 2·c1·c_k − c_{k−1}`.
fn chebyshev_cosines(c1: f64, out: &mut [f64]) {
    let (mut prev, mut cur) = (1.0, c1);
    for (k, o) in out.iter_mut().enumerate() {
        if k == 0 {
            *o = 1.0;
            continue;
        }
        *o = cur;
        let next = 2.0 * c1 * cur - prev;
        prev = cur;
        cur = next;
    }
}

/// The kernel `w_R … w_1, w_0, w_1 … w_R` of the half `[w_0, …, w_R]`, each divided by the
/// sum of the `2R + 1` weights (from `−R` up): mirror weights are the same bits.
fn symmetric(half: &[f64]) -> Vec<f64> {
    let r = half.len() - 1;
    let full: Vec<f64> = (0..=2 * r).map(|i| half[i.abs_diff(r)]).collect();
    let sum = full.iter().fold(0.0, |s, &w| s + w);
    full.iter().map(|w| w / sum).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn variance(k: &[f64]) -> f64 {
        let r = (k.len() / 2) as f64;
        k.iter()
            .enumerate()
            .map(|(i, w)| w * (i as f64 - r).powi(2))
            .sum()
    }

    fn gaussian(sigma_mm: f64, pitch: [f64; 2]) -> Psf {
        Psf::new(PsfShape::Gaussian { sigma_mm }, pitch).unwrap()
    }

    fn assert_normalised_symmetric(k: &[f64]) {
        assert_eq!(k.len() % 2, 1);
        let sum: f64 = k.iter().sum();
        assert!((sum - 1.0).abs() < 1e-14, "sum {sum}");
        for i in 0..k.len() / 2 {
            assert_eq!(k[i].to_bits(), k[k.len() - 1 - i].to_bits(), "tap {i}");
        }
    }

    #[test]
    fn gaussian_kernels_are_normalised_symmetric_and_cut_at_the_documented_weight() {
        for (sigma, pitch) in [
            (0.15, [0.2986, 0.14]),
            (0.05, [0.3, 0.3]),
            (1.0, [0.1, 0.25]),
            (10.0, [0.2, 1.0]),
        ] {
            let psf = gaussian(sigma, pitch);
            for (k, p) in [(psf.kernel_x(), pitch[0]), (psf.kernel_y(), pitch[1])] {
                assert_normalised_symmetric(k);
                // The first weight cut is below the cutoff, the last kept is not.
                let r = k.len() / 2;
                let a = p / (sigma * std::f64::consts::SQRT_2);
                let w = |k: f64| 0.5 * (libm::erfc((k - 0.5) * a) - libm::erfc((k + 0.5) * a));
                assert!(w(r as f64 + 1.0) < KERNEL_CUTOFF);
                assert!(r == 0 || w(r as f64) >= KERNEL_CUTOFF);
            }
        }
        // σ = 0.15 mm at 0.2986 mm: taps −2..2.
        assert_eq!(gaussian(0.15, [0.2986, 0.2986]).kernel_x().len(), 5);
    }

    #[test]
    fn gaussian_kernel_variance_is_sigma_over_pitch_squared_plus_a_twelfth() {
        for (sigma, pitch) in [
            (0.15, [0.25, 0.14]),
            (0.3, [0.2, 0.5]),
            (1.0, [0.1, 0.25]),
            (4.0, [0.3, 0.3]),
        ] {
            let psf = gaussian(sigma, pitch);
            for (k, p) in [(psf.kernel_x(), pitch[0]), (psf.kernel_y(), pitch[1])] {
                let want = (sigma / p).powi(2) + 1.0 / 12.0;
                let got = variance(k);
                assert!(
                    (got - want).abs() < 0.01 * want,
                    "σ {sigma} pitch {p}: {got} vs {want}"
                );
            }
        }
        // Below σ ≈ 0.55 px the whole-pixel sampling makes the kernel narrower (documented):
        // σ = 0.15 mm at 0.2986 mm (0.50 px) is 2.4 % below the formula.
        let got = variance(gaussian(0.15, [0.2986, 0.2986]).kernel_x());
        let want = (0.15f64 / 0.2986).powi(2) + 1.0 / 12.0;
        assert!((got / want - 1.0 + 0.024).abs() < 0.002, "{got} vs {want}");
    }

    #[test]
    fn lsf_of_a_gaussian_mtf_table_is_the_gaussian_kernel() {
        for (sigma, pitch) in [(0.15, [0.2986, 0.14]), (0.4, [0.2, 0.3])] {
            // MTF of a Gaussian LSF: exp(−2π²σ²f²), tabulated every 0.01/σ up to where it is
            // below 1e-9.
            let f_max = (libm::log(1e9) / (2.0 * std::f64::consts::PI.powi(2))).sqrt() / sigma;
            let n = 700;
            let table: Vec<[f64; 2]> = (0..=n)
                .map(|i| {
                    let f = f_max * i as f64 / n as f64;
                    let pi = std::f64::consts::PI;
                    [f, libm::exp(-2.0 * pi * pi * sigma * sigma * f * f)]
                })
                .collect();
            let mtf = Psf::new(PsfShape::Mtf { table }, pitch).unwrap();
            let g = gaussian(sigma, pitch);
            for (a, b) in [
                (mtf.kernel_x(), g.kernel_x()),
                (mtf.kernel_y(), g.kernel_y()),
            ] {
                assert_normalised_symmetric(a);
                let (ra, rb) = (a.len() / 2, b.len() / 2);
                for d in -(ra.max(rb) as isize)..=(ra.max(rb) as isize) {
                    let at = |k: &[f64], r: usize| {
                        usize::try_from(d + r as isize)
                            .ok()
                            .and_then(|i| k.get(i))
                            .copied()
                            .unwrap_or(0.0)
                    };
                    let (x, y) = (at(a, ra), at(b, rb));
                    assert!((x - y).abs() < 1e-3, "σ {sigma}, tap {d}: {x} vs {y}");
                }
            }
        }
    }

    #[test]
    fn a_triangular_mtf_gives_the_sinc_squared_lsf_pixel_integrated() {
        // M(f) = 1 − f/fc up to fc: LSF(x) = fc·sinc²(fc·x). Weight k by direct quadrature of
        // the LSF over the pixel (Simpson, fine) must match.
        let (fc, p) = (2.0, 0.25);
        let w = mtf_weights(&[[0.0, 1.0], [fc, 0.0]], p, 12);
        let lsf = |x: f64| {
            let t = std::f64::consts::PI * fc * x;
            if t == 0.0 {
                fc
            } else {
                fc * (libm::sin(t) / t).powi(2)
            }
        };
        for (d, &got) in w.iter().enumerate() {
            let (a, b) = ((d as f64 - 0.5) * p, (d as f64 + 0.5) * p);
            let n = 2000;
            let h = (b - a) / n as f64;
            let mut s = lsf(a) + lsf(b);
            for i in 1..n {
                s += lsf(a + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
            }
            let want = s * h / 3.0;
            assert!((got - want).abs() < 1e-9, "tap {d}: {got} vs {want}");
        }
        let psf = Psf::new(
            PsfShape::Mtf {
                table: vec![[0.0, 1.0], [fc, 0.0]],
            },
            [p, p],
        )
        .unwrap();
        assert_normalised_symmetric(psf.kernel_x());
        // The sinc² tails (∝ 1/x²) keep weights above the cutoff out to the 50 mm limit.
        assert!(psf.kernel_x().len() > 2 * 190, "{}", psf.kernel_x().len());
    }

    #[test]
    fn invalid_shapes_and_pitches_name_the_field() {
        let cases: Vec<(PsfShape, [f64; 2], &str)> = vec![
            (
                PsfShape::Gaussian { sigma_mm: 0.0 },
                [0.3, 0.3],
                "psf sigma_mm = 0",
            ),
            (PsfShape::Gaussian { sigma_mm: 11.0 }, [0.3, 0.3], "≤ 10 mm"),
            (
                PsfShape::Gaussian { sigma_mm: f64::NAN },
                [0.3, 0.3],
                "sigma_mm = NaN",
            ),
            (
                PsfShape::Gaussian { sigma_mm: 0.2 },
                [0.3, -1.0],
                "pixel_pitch_mm[1] = -1",
            ),
            (
                PsfShape::Gaussian { sigma_mm: 10.0 },
                [1e-3, 1.0],
                "wider than 4096 px",
            ),
            (
                PsfShape::Mtf {
                    table: vec![[0.0, 1.0]],
                },
                [0.3, 0.3],
                "at least 2 rows",
            ),
            (
                PsfShape::Mtf {
                    table: vec![[0.1, 1.0], [1.0, 0.5]],
                },
                [0.3, 0.3],
                "mtf row 0 = [0.1, 1]",
            ),
            (
                PsfShape::Mtf {
                    table: vec![[0.0, 0.9], [1.0, 0.5]],
                },
                [0.3, 0.3],
                "value 1 at frequency 0",
            ),
            (
                PsfShape::Mtf {
                    table: vec![[0.0, 1.0], [1.0, 0.5], [1.0, 0.2]],
                },
                [0.3, 0.3],
                "mtf row 2 has frequency 1",
            ),
            (
                PsfShape::Mtf {
                    table: vec![[0.0, 1.0], [1.0, 1.5]],
                },
                [0.3, 0.3],
                "mtf row 1 has value 1.5",
            ),
            (
                PsfShape::Mtf {
                    table: vec![[0.0, 1.0], [f64::NAN, 0.5]],
                },
                [0.3, 0.3],
                "mtf row 1 has frequency NaN",
            ),
            (
                PsfShape::Mtf {
                    table: vec![[0.0, 1.0], [1e3, 0.5]],
                },
                [0.3, 0.3],
                "≤ 100 cycles/mm",
            ),
        ];
        for (shape, pitch, want) in cases {
            let e = Psf::new(shape.clone(), pitch).unwrap_err();
            assert!(e.contains(want), "{shape:?}: {e}");
        }
    }
}

//! From an expected image to stored values with the detector's unsharpness and extra noise
//! ([`render_expected`]), in the order of the physics:
//!
//! 1. scatter (optional) added to the expected quanta and energy;
//! 2. quantum noise, exactly as [`super::render`] (same streams, same draw order);
//! 3. the detector PSF (optional) on the noisy signal `S` (and on the flat field `S_open` of a
//!    radiograph), which correlates the noise;
//! 4. electronic noise (optional), Gaussian, on its own streams;
//! 5. digitisation as in [`super::render`]; `saturated` counts the clipped raw values after all
//!    of this.
//!
//! With every option off ([`Unsharpness::default`]) the output is [`super::render`]'s, bit for
//! bit: both call the same per-pixel code ([`super::digitise::Digitiser`]).

use std::borrow::Cow;

use rayon::prelude::*;

use super::convolve::convolve;
use super::digitise::Digitiser;
use super::{DetectorModel, Expected, Polarity, Rendered, Unsharpness};
use crate::noise::{NoiseKey, standard_normal};

/// Renders an expected image: scatter, quantum noise, detector PSF, electronic noise and
/// digitisation (module documentation), each option as `unsharp` says.
///
/// Quantum noise: row `j` draws from `key.row_rng(j)`, one Poisson sample per pixel left to
/// right with mean `Q` (after scatter), as [`super::render`]. Electronic noise: row `j` draws
/// from `electronic_key.row_rng(j)` (see [`NoiseKey::derive_electronic`]), one
/// [`standard_normal`] per pixel left to right (two `u64`s each), times
/// `unsharp.electronic_noise_dn`; none is drawn when it is 0. Rows run in parallel; the output is
/// the same on any number of threads.
///
/// `expected_open_max` is `offset + gain · max_p S_open` (the open field before any PSF).
/// Never panics on values: a NaN, negative or infinite `electronic_noise_dn` counts as 0 (see
/// [`Unsharpness::check`]); expected values are sanitised as in [`super::render`].
///
/// # Panics
/// When the three images of `expected` are not `width × height` ([`Expected::is_consistent`])
/// or it has more than 2³² rows.
pub fn render_expected(
    det: &DetectorModel,
    expected: &Expected,
    unsharp: &Unsharpness,
    key: &NoiseKey,
    electronic_key: &NoiseKey,
) -> Rendered {
    assert!(
        expected.is_consistent(),
        "the expected image is not width × height in all three values"
    );
    assert!(
        expected.height as u64 <= 1u64 << 32,
        "more than 2³² rows (noise streams are numbered by u32)"
    );
    let w = expected.width;
    let mut pixels = vec![0u16; expected.quanta.len()];
    if w == 0 {
        return Rendered {
            pixels,
            saturated: 0,
            expected_open_max: det.offset,
        };
    }
    let open_max = expected.open_signal.iter().fold(0.0f64, |m, &v| m.max(v));
    let digitiser = Digitiser::new(det);
    let h = expected.height;
    // 1. Scatter on the expected values (E only where the signal reads it).
    let (quanta, energy_kev) = match &unsharp.scatter {
        Some(s) => (
            Cow::Owned(s.add_to(&expected.quanta, w, h)),
            if digitiser.integrating() {
                Cow::Owned(s.add_to(&expected.energy_kev, w, h))
            } else {
                Cow::Borrowed(&expected.energy_kev[..])
            },
        ),
        None => (
            Cow::Borrowed(&expected.quanta[..]),
            Cow::Borrowed(&expected.energy_kev[..]),
        ),
    };
    let saturated = match &unsharp.psf {
        // 2, 4, 5 in one pass per row.
        None => pixels
            .par_chunks_mut(w)
            .enumerate()
            .map_init(Vec::new, |signal, (j, row)| {
                let k = j * w..(j + 1) * w;
                let (q, e) = (&quanta[k.clone()], &energy_kev[k.clone()]);
                let mut rng = key.row_rng(j as u32);
                signal.resize(w, 0.0);
                digitiser.detect_row(q, e, &mut rng, signal);
                store_row(
                    &digitiser,
                    unsharp,
                    electronic_key,
                    j,
                    signal,
                    &expected.open_signal[k],
                    row,
                )
            })
            .sum(),
        Some(psf) => {
            // 2. Quantum noise into a signal image.
            let mut signal = vec![0.0; w * h];
            signal.par_chunks_mut(w).enumerate().for_each(|(j, s)| {
                let k = j * w..(j + 1) * w;
                let (q, e) = (&quanta[k.clone()], &energy_kev[k]);
                let mut rng = key.row_rng(j as u32);
                digitiser.detect_row(q, e, &mut rng, s);
            });
            // 3. The PSF on the signal, and on the flat field of a radiograph.
            let signal = convolve(&signal, w, h, psf.kernel_x(), psf.kernel_y());
            let open = match det.polarity {
                Polarity::Radiograph { .. } => Cow::Owned(convolve(
                    &expected.open_signal,
                    w,
                    h,
                    psf.kernel_x(),
                    psf.kernel_y(),
                )),
                Polarity::Raw => Cow::Borrowed(&expected.open_signal[..]),
            };
            // 4, 5.
            pixels
                .par_chunks_mut(w)
                .enumerate()
                .map(|(j, row)| {
                    let k = j * w..(j + 1) * w;
                    store_row(
                        &digitiser,
                        unsharp,
                        electronic_key,
                        j,
                        &signal[k.clone()],
                        &open[k],
                        row,
                    )
                })
                .sum()
        }
    };
    Rendered {
        pixels,
        saturated,
        expected_open_max: det.offset + det.gain * open_max,
    }
}

/// Electronic noise (when `unsharp` has some) and digitisation of row `j`: pixel `i` has the
/// signal `signal[i]` and the open field `open[i]`.
/// Returns the pixels clipped at the top.
fn store_row(
    digitiser: &Digitiser,
    unsharp: &Unsharpness,
    electronic_key: &NoiseKey,
    j: usize,
    signal: &[f64],
    open: &[f64],
    row: &mut [u16],
) -> usize {
    match unsharp.electronic_sd_dn() {
        None => digitiser.store_row(signal, open, row),
        Some(sd) => {
            // The row's draws first, in pixel order, then its values in one pass.
            let mut rng = electronic_key.row_rng(j as u32);
            let mut noise: Vec<f64> = (0..row.len())
                .map(|_| sd * standard_normal(&mut rng))
                .collect();
            digitiser.store_row_with_read_noise(signal, open, &mut noise, row)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::response::{
        Beam, Layer, PointSourceFluence, Polarity, Response, Scene, expected, render,
    };

    fn key() -> NoiseKey {
        NoiseKey::derive(5, 1, 2, "ap", "det_a")
    }

    fn ekey() -> NoiseKey {
        NoiseKey::derive_electronic(5, 1, 2, "ap", "det_a")
    }

    fn detector(response: Response, polarity: Polarity, gain: f64, offset: f64) -> DetectorModel {
        DetectorModel {
            response,
            efficiency: vec![0.9, 0.7, 0.5],
            gain,
            offset,
            i_max: u16::MAX,
            polarity,
            quantum_noise: true,
        }
    }

    /// A 53 × 41 scene: a tissue block with a nested metal rectangle taken from it and a bead
    /// layer, under a point source (fluence by rows), three bins.
    fn with_scene<T>(f: impl FnOnce(&Beam, &Scene) -> T) -> T {
        let (w, h) = (53usize, 41usize);
        let frame = crate::geometry::DetectorFrame {
            pose: crate::geometry::Pose::from_position_euler_deg(
                [1.0, -2.0, -300.0],
                [3.0, -5.0, 20.0],
            ),
            pixels: [w as u32, h as u32],
            pixel_pitch_mm: [0.8, 0.6],
        };
        let fluence = PointSourceFluence::new(&frame, glam::DVec3::new(10.0, 5.0, 700.0));
        let outer: Vec<f64> = (0..40 * 30).map(|p| 20.0 + (p % 13) as f64 * 0.7).collect();
        let inner: Vec<f64> = (0..8 * 6).map(|p| 2.0 + (p % 5) as f64 * 0.4).collect();
        let bead: Vec<f64> = (0..3 * 3).map(|p| [0.3, 0.9, 0.3][p % 3]).collect();
        let layers = [
            Layer {
                material: 0,
                sign: 1.0,
                columns: 5..45,
                rows: 4..34,
                length_mm: &outer,
            },
            Layer {
                material: 0,
                sign: -1.0,
                columns: 20..28,
                rows: 10..16,
                length_mm: &inner,
            },
            Layer {
                material: 1,
                sign: 1.0,
                columns: 20..28,
                rows: 10..16,
                length_mm: &inner,
            },
            Layer {
                material: 2,
                sign: 1.0,
                columns: 40..43,
                rows: 30..33,
                length_mm: &bead,
            },
        ];
        let mu = vec![
            vec![0.05, 0.03, 0.025],
            vec![2.5, 1.1, 0.6],
            vec![9.0, 4.0, 2.0],
        ];
        let beam = Beam {
            energies_kev: vec![40.0, 60.0, 80.0],
            photons_per_pixel: vec![300.0, 900.0, 400.0],
        };
        let scene = Scene {
            width: w,
            height: h,
            mu_per_mm: &mu,
            layers: &layers,
            fluence: crate::response::Fluence::PointSource(&fluence),
        };
        f(&beam, &scene)
    }

    /// A 12-bit detector whose open field at the reference point sits at `fraction · i_max`.
    fn det_12bit(
        beam: &Beam,
        response: Response,
        polarity: Polarity,
        offset: f64,
        fraction: f64,
    ) -> DetectorModel {
        let eta = [0.9, 0.7, 0.5];
        let gain = DetectorModel::auto_gain(&response, beam, &eta, offset, fraction, 4095);
        let mut det = detector(response, polarity, gain, offset);
        det.i_max = 4095;
        det
    }

    fn polarities() -> [Polarity; 2] {
        [Polarity::Raw, Polarity::Radiograph { range: 6.0 }]
    }

    #[test]
    fn with_every_option_off_it_is_render_bit_for_bit() {
        with_scene(|beam, scene| {
            for polarity in polarities() {
                for response in [Response::EnergyIntegrating, Response::PhotonCounting] {
                    let det = det_12bit(beam, response, polarity, 50.0, 0.99);
                    let e = expected(beam, &det, scene);
                    let want = render(beam, &det, scene, &key());
                    let got = render_expected(&det, &e, &Unsharpness::default(), &key(), &ekey());
                    assert_eq!(got, want, "{polarity:?} {response:?}");
                    assert_eq!(
                        got.expected_open_max.to_bits(),
                        want.expected_open_max.to_bits()
                    );
                    // The air saturates somewhere in raw values: the count is compared too.
                    assert!(want.saturated > 0 || polarity != Polarity::Raw);
                    // The expected quanta are expected_quanta's.
                    let q = crate::response::expected_quanta(beam, &det, scene);
                    assert!(
                        q.iter()
                            .zip(&e.quanta)
                            .all(|(a, b)| a.to_bits() == b.to_bits())
                    );
                    let s_ref = crate::response::open_signal_per_fluence(&det, beam);
                    assert!(e.open_signal.iter().all(|&o| o <= s_ref && o > 0.5 * s_ref));
                }
            }
        });
    }

    #[test]
    fn electronic_noise_has_its_mean_and_sd() {
        // No photons: the raw value is offset + noise (sd 40 DN), rounded (+1/12 variance).
        let (w, h) = (400, 250);
        let n = w * h;
        let e = expected_of(w, h, 1.0, |_, _| 0.0);
        let det = detector(Response::EnergyIntegrating, Polarity::Raw, 1.0, 1000.0);
        let unsharp = Unsharpness {
            electronic_noise_dn: 40.0,
            ..Default::default()
        };
        let r = render_expected(&det, &e, &unsharp, &key(), &ekey());
        let v: Vec<f64> = r.pixels.iter().map(|&p| f64::from(p)).collect();
        let nf = n as f64;
        let mean = v.iter().sum::<f64>() / nf;
        let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (nf - 1.0)).sqrt();
        let want_sd = (1600.0f64 + 1.0 / 12.0).sqrt();
        assert!(
            (mean - 1000.0).abs() < 4.0 * want_sd / nf.sqrt(),
            "mean {mean}"
        );
        assert!(
            (sd - want_sd).abs() < 4.0 * want_sd / (2.0 * nf).sqrt(),
            "sd {sd}"
        );
        // Row j, pixel i is the documented sample: offset + sd · z_i of stream j.
        let mut rng = ekey().row_rng(7);
        for i in 0..w {
            let z = standard_normal(&mut rng);
            let raw = 1000.0 + 40.0 * z;
            assert_eq!(
                r.pixels[7 * w + i],
                super::super::digitise::quantise(raw, u16::MAX)
            );
        }
        // Off when 0: the plain render.
        let off = render_expected(&det, &e, &Unsharpness::default(), &key(), &ekey());
        assert!(off.pixels.iter().all(|&p| p == 1000));
    }

    #[test]
    fn electronic_noise_in_a_radiograph_is_noise_over_gain_on_the_signal() {
        // Photon counting, Q = 0 (S = 0 would be white): with noise, S = e/gain; negative e
        // stays white, positive e gives ln(S_open · gain / e) / range · i_max.
        let (w, h) = (64, 8);
        let e = expected_of(w, h, 5000.0, |_, _| 0.0);
        let det = detector(
            Response::PhotonCounting,
            Polarity::Radiograph { range: 7.0 },
            0.5,
            0.0,
        );
        let unsharp = Unsharpness {
            electronic_noise_dn: 3.0,
            ..Default::default()
        };
        let r = render_expected(&det, &e, &unsharp, &key(), &ekey());
        let formula = |s: f64, s0: f64| {
            super::super::digitise::radiograph(s, s0, 7.0, libm::exp(7.0), u16::MAX)
        };
        for j in 0..h {
            let mut rng = ekey().row_rng(j as u32);
            for i in 0..w {
                let noise = 3.0 * standard_normal(&mut rng);
                let want = formula(noise / 0.5, 5000.0);
                assert_eq!(r.pixels[j * w + i], want, "({i}, {j})");
            }
        }
        assert!(r.pixels.iter().any(|&p| p < u16::MAX) && r.pixels.contains(&u16::MAX));
    }

    #[test]
    fn check_names_the_field() {
        for bad in [-1.0, f64::NAN, f64::INFINITY] {
            let u = Unsharpness {
                electronic_noise_dn: bad,
                ..Default::default()
            };
            let e = u.check().unwrap_err();
            assert!(
                e.contains("electronic_noise_dn") && e.contains("≥ 0"),
                "{e}"
            );
        }
        assert!(Unsharpness::default().check().is_ok());
    }

    /// A `w × h` expected image of quanta `q(i, j)`, energy 60 keV per quantum, open field
    /// `open`.
    fn expected_of(w: usize, h: usize, open: f64, q: impl Fn(usize, usize) -> f64) -> Expected {
        let quanta: Vec<f64> = (0..w * h).map(|p| q(p % w, p / w)).collect();
        Expected {
            width: w,
            height: h,
            energy_kev: quanta.iter().map(|q| 60.0 * q).collect(),
            quanta,
            open_signal: vec![open; w * h],
        }
    }

    fn gaussian_psf(sigma_mm: f64, pitch: [f64; 2]) -> crate::response::Psf {
        crate::response::Psf::new(crate::response::PsfShape::Gaussian { sigma_mm }, pitch).unwrap()
    }

    /// Lag-1 correlation along rows (`dx = 1`) or columns, and the variance.
    fn lag1(v: &[f64], w: usize, along_rows: bool) -> (f64, f64) {
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
        let (mut c, mut m) = (0.0, 0.0);
        for p in 0..v.len() {
            let q = if along_rows { p + 1 } else { p + w };
            if q < v.len() && (!along_rows || q % w != 0) {
                c += (v[p] - mean) * (v[q] - mean);
                m += 1.0;
            }
        }
        (c / m / var, var)
    }

    /// The distance between the 90 % and 10 % crossings of a falling edge profile (1 → 0),
    /// each found by linear interpolation between pixel centres, px.
    fn width_10_90(y: &[f64]) -> f64 {
        let cross = |level: f64| {
            let t = (0..y.len() - 1)
                .find(|&t| y[t] >= level && y[t + 1] < level)
                .expect("the profile crosses the level");
            t as f64 + (y[t] - level) / (y[t] - y[t + 1])
        };
        cross(0.1) - cross(0.9)
    }

    #[test]
    fn a_noise_free_step_has_the_predicted_10_to_90_width() {
        // 10¹² quanta: the quantum noise is 10⁻⁶ of the signal, ~0.05 DN. A pixel-integrated
        // Gaussian makes the edge sampled at pixel centres exactly Φ(x/σ) (x from the edge, in
        // px), so the 10–90 % width is 2 · 1.28155 · σ/p.
        let (sigma, pitch) = (0.45, [0.15, 0.2]);
        let psf = gaussian_psf(sigma, pitch);
        let det = detector(Response::PhotonCounting, Polarity::Raw, 6e-8, 100.0);
        for along_rows in [true, false] {
            let (w, h) = (120, 100);
            let e = expected_of(w, h, 1e12, |i, j| {
                let left = if along_rows { i < w / 2 } else { j < h / 2 };
                if left { 1e12 } else { 2e11 }
            });
            let unsharp = Unsharpness {
                psf: Some(psf.clone()),
                ..Default::default()
            };
            let r = render_expected(&det, &e, &unsharp, &key(), &ekey());
            // The profile across the edge, averaged along it.
            let n = if along_rows { w } else { h };
            let profile: Vec<f64> = (0..n)
                .map(|t| {
                    let line: Vec<f64> = (10..(if along_rows { h } else { w }) - 10)
                        .map(|u| {
                            let (i, j) = if along_rows { (t, u) } else { (u, t) };
                            f64::from(r.pixels[j * w + i])
                        })
                        .collect();
                    line.iter().sum::<f64>() / line.len() as f64
                })
                .collect();
            let (hi, lo) = (profile[5], profile[n - 5]);
            let measured = width_10_90(
                &profile
                    .iter()
                    .map(|v| (v - lo) / (hi - lo))
                    .collect::<Vec<_>>(),
            );
            // What the kernel predicts: the edge at n/2, y_t = Σ_{k < n/2 − t} w_k.
            let k = if along_rows {
                psf.kernel_x()
            } else {
                psf.kernel_y()
            };
            let half = (k.len() / 2) as isize;
            let predicted: Vec<f64> = (0..n as isize)
                .map(|t| {
                    (-half..=half)
                        .filter(|&d| d < n as isize / 2 - t)
                        .map(|d| k[(d + half) as usize])
                        .sum()
                })
                .collect();
            let want = width_10_90(&predicted);
            assert!(
                (measured / want - 1.0).abs() < 0.01,
                "{measured} px vs {want} px"
            );
            // Which is the continuous Gaussian edge 1 − Φ(x/σ) sampled at pixel centres, whose
            // 10–90 % width is 2 · 1.28155 · σ/p (the linear interpolation between pixel
            // centres adds 1–3 % here).
            let sp = sigma / if along_rows { pitch[0] } else { pitch[1] };
            for (t, &y) in predicted.iter().enumerate() {
                let x = (t as f64 + 0.5 - (n / 2) as f64) / sp;
                let phi = 0.5 * libm::erfc(-x / std::f64::consts::SQRT_2);
                assert!(
                    (y - (1.0 - phi)).abs() < 3e-6,
                    "t {t}: {y} vs {}",
                    1.0 - phi
                );
            }
            let continuous = 2.0 * 1.281_551_565_545 * sp;
            assert!(
                (want / continuous - 1.0).abs() < 0.03,
                "{want} vs {continuous}"
            );
            // Without the PSF the edge is one pixel.
            let sharp = render_expected(&det, &e, &Unsharpness::default(), &key(), &ekey());
            assert_ne!(sharp.pixels, r.pixels);
        }
    }

    #[test]
    fn the_psf_correlates_the_quantum_noise_and_not_the_electronic_noise() {
        // Quantum noise through the PSF: variance Q · Σwx² · Σwy², lag-1 correlation
        // Σ w_k w_{k+1} / Σ w_k² along each axis (NPS ∝ MTF²). Electronic noise, added after
        // the PSF, stays white.
        let (w, h, q) = (320, 320, 1e4);
        let psf = gaussian_psf(0.3, [0.3, 0.2]);
        let det = detector(Response::PhotonCounting, Polarity::Raw, 1.0, 0.0);
        let e = expected_of(w, h, q, |_, _| q);
        let unsharp = Unsharpness {
            psf: Some(psf.clone()),
            ..Default::default()
        };
        let r = render_expected(&det, &e, &unsharp, &key(), &ekey());
        let v: Vec<f64> = r.pixels.iter().map(|&p| f64::from(p)).collect();
        let sq = |k: &[f64]| k.iter().map(|x| x * x).sum::<f64>();
        let lag = |k: &[f64]| k.windows(2).map(|p| p[0] * p[1]).sum::<f64>() / sq(k);
        let signal_var = q * sq(psf.kernel_x()) * sq(psf.kernel_y());
        let n = (w * h) as f64;
        for (along_rows, k) in [(true, psf.kernel_x()), (false, psf.kernel_y())] {
            let (rho, var) = lag1(&v, w, along_rows);
            // Rounding adds 1/12 of uncorrelated variance.
            let want = lag(k) * signal_var / (signal_var + 1.0 / 12.0);
            assert!(
                (rho - want).abs() < 4.0 * 2.0 / n.sqrt(),
                "ρ {rho} vs {want}"
            );
            let want_var = signal_var + 1.0 / 12.0;
            assert!(
                (var / want_var - 1.0).abs() < 4.0 * 3.0 * (2.0 / n).sqrt(),
                "{var}"
            );
            assert!(want > 0.3, "a real correlation: {want}");
        }
        // Electronic noise alone (no photons), with the PSF on: uncorrelated.
        let dark = expected_of(w, h, q, |_, _| 0.0);
        let mut det = det.clone();
        det.offset = 1000.0;
        let unsharp = Unsharpness {
            psf: Some(psf),
            electronic_noise_dn: 20.0,
            ..Default::default()
        };
        let r = render_expected(&det, &dark, &unsharp, &key(), &ekey());
        let v: Vec<f64> = r.pixels.iter().map(|&p| f64::from(p)).collect();
        for along_rows in [true, false] {
            let (rho, var) = lag1(&v, w, along_rows);
            assert!(rho.abs() < 4.0 / n.sqrt(), "ρ {rho}");
            assert!((var / (400.0 + 1.0 / 12.0) - 1.0).abs() < 4.0 * (2.0 / n).sqrt());
        }
    }

    #[test]
    fn scatter_lifts_a_uniform_field_by_the_ratio() {
        let (w, h, q) = (200, 150, 5000.0);
        let det = detector(Response::EnergyIntegrating, Polarity::Raw, 0.002, 0.0);
        let e = expected_of(w, h, q * 60.0, |_, _| q);
        let unsharp = Unsharpness {
            scatter: Some(crate::response::Scatter::new(0.4, 30.0, [0.3, 0.3]).unwrap()),
            ..Default::default()
        };
        let r = render_expected(&det, &e, &unsharp, &key(), &ekey());
        let n = (w * h) as f64;
        let mean = r.pixels.iter().map(|&p| f64::from(p)).sum::<f64>() / n;
        // S = n · 60 keV, n ~ Poisson(1.4 · q): mean 0.002 · 60 · 7000 = 840 DN.
        let sd = 0.002 * 60.0 * (1.4 * q).sqrt();
        assert!((mean - 840.0).abs() < 4.0 * sd / n.sqrt(), "mean {mean}");
    }

    #[test]
    fn every_option_gives_the_same_bytes_on_1_and_4_threads() {
        with_scene(|beam, scene| {
            let pitch = [0.8, 0.6];
            let mtf = crate::response::PsfShape::Mtf {
                table: vec![[0.0, 1.0], [0.2, 0.7], [0.5, 0.2], [0.7, 0.0]],
            };
            for polarity in polarities() {
                for response in [Response::EnergyIntegrating, Response::PhotonCounting] {
                    let det = det_12bit(beam, response, polarity, 20.0, 0.8);
                    let e = expected(beam, &det, scene);
                    for psf in [
                        gaussian_psf(1.1, pitch),
                        crate::response::Psf::new(mtf.clone(), pitch).unwrap(),
                    ] {
                        let unsharp = Unsharpness {
                            scatter: Some(crate::response::Scatter::new(0.5, 6.0, pitch).unwrap()),
                            psf: Some(psf),
                            electronic_noise_dn: 3.0,
                        };
                        let images: Vec<Rendered> = [1, 4]
                            .into_iter()
                            .map(|threads| {
                                rayon::ThreadPoolBuilder::new()
                                    .num_threads(threads)
                                    .build()
                                    .unwrap()
                                    .install(|| {
                                        render_expected(&det, &e, &unsharp, &key(), &ekey())
                                    })
                            })
                            .collect();
                        assert_eq!(images[0], images[1], "{polarity:?} {response:?}");
                        let plain =
                            render_expected(&det, &e, &Unsharpness::default(), &key(), &ekey());
                        assert_ne!(images[0].pixels, plain.pixels);
                    }
                }
            }
        });
    }
}

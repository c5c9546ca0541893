//! Whole-module tests of the detector response: values against hand sums, noise statistics,
//! draw order, thread independence, polarity, saturation and invalid inputs.

use super::*;
use crate::noise::{NoiseKey, Poisson};

fn key() -> NoiseKey {
    NoiseKey::derive(11, 0, 3, "ap", "det_a")
}

fn mono(photons: f64) -> Beam {
    Beam {
        energies_kev: vec![60.0],
        photons_per_pixel: vec![photons],
    }
}

fn detector(response: Response, efficiency: Vec<f64>, polarity: Polarity) -> DetectorModel {
    DetectorModel {
        response,
        efficiency,
        gain: 1.0,
        offset: 0.0,
        i_max: u16::MAX,
        polarity,
        quantum_noise: true,
    }
}

/// Mean and unbiased variance.
fn mean_var(v: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let n = v.clone().count() as f64;
    let mean = v.clone().sum::<f64>() / n;
    let var = v.map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0);
    (mean, var)
}

#[test]
fn mono_beam_through_known_lengths_is_beer_lambert() {
    let lengths = vec![0.0, 0.5, 1.0, 10.0, 37.25, 100.0, 400.0, 1e-9];
    let fluence = vec![1.0, 0.9, 0.75, 1.0, 0.5, 0.99, 1.0, 0.3];
    let (n0, eta, mu) = (12_345.0, 0.83, 0.0437);
    let mu_rows = vec![vec![mu]];
    let len_rows = vec![lengths.clone()];
    let scene = Scene {
        width: 4,
        height: 2,
        mu_per_mm: &mu_rows,
        layers: &Layer::images(4, 2, &len_rows),
        fluence: Fluence::Image(&fluence),
    };
    let det = detector(Response::PhotonCounting, vec![eta], Polarity::Raw);
    let q = expected_quanta(&mono(n0), &det, &scene);
    for p in 0..8 {
        let expected = fluence[p] * n0 * eta * libm::exp(-mu * lengths[p]);
        assert!(
            (q[p] - expected).abs() <= 1e-12 * expected,
            "pixel {p}: {} vs {expected}",
            q[p]
        );
    }
}

#[test]
fn two_materials_three_bins_equal_the_hand_sum() {
    let beam = Beam {
        energies_kev: vec![40.0, 60.0, 80.0],
        photons_per_pixel: vec![1000.0, 3000.0, 1500.0],
    };
    let eta = vec![0.9, 0.7, 0.5];
    // Material 0 (bone-like), material 1 (metal-like), material 2 has no lengths at all.
    let mu = vec![
        vec![0.12, 0.06, 0.045],
        vec![3.1, 1.2, 0.61],
        vec![9.0, 9.0, 9.0],
    ];
    let (w, h) = (3, 2);
    let l0 = vec![0.0, 5.0, 20.0, 0.0, 12.5, 1.0];
    let l1 = vec![0.0, 0.0, 0.0, 2.0, 0.75, 0.1];
    let lengths = vec![l0.clone(), l1.clone(), vec![]];
    let fluence = vec![1.0, 0.98, 0.95, 0.97, 0.9, 0.85];
    let scene = Scene {
        width: w,
        height: h,
        mu_per_mm: &mu,
        layers: &Layer::images(w, h, &lengths),
        fluence: Fluence::Image(&fluence),
    };
    let det = detector(Response::EnergyIntegrating, eta.clone(), Polarity::Raw);
    let q = expected_quanta(&beam, &det, &scene);
    for p in 0..w * h {
        let mut hand = 0.0;
        for b in 0..3 {
            hand += beam.photons_per_pixel[b]
                * eta[b]
                * libm::exp(-(mu[0][b] * l0[p] + mu[1][b] * l1[p]));
        }
        hand *= fluence[p];
        assert!(
            (q[p] - hand).abs() <= 1e-12 * hand,
            "pixel {p}: {} vs {hand}",
            q[p]
        );
    }
    // Open-field pixel 0: exactly f · Σ N·η.
    assert_eq!(q[0], 1000.0 * 0.9 + 3000.0 * 0.7 + 1500.0 * 0.5);
}

/// A uniform field of 200 000 pixels at mean λ (photon counting, gain 1, offset 0, raw).
fn uniform_field(lambda: f64, response: Response, gain: f64) -> (Rendered, DetectorModel) {
    let (w, h) = (500, 400);
    let fluence = vec![1.0; w * h];
    let mut det = detector(response, vec![1.0], Polarity::Raw);
    det.gain = gain;
    let scene = Scene {
        width: w,
        height: h,
        mu_per_mm: &[],
        layers: &[],
        fluence: Fluence::Image(&fluence),
    };
    (render(&mono(lambda), &det, &scene, &key()), det)
}

#[test]
fn photon_counting_noise_is_poisson_at_50_and_5000() {
    for lambda in [50.0, 5000.0] {
        let (r, _) = uniform_field(lambda, Response::PhotonCounting, 1.0);
        let n = r.pixels.len() as f64;
        let (mean, var) = mean_var(r.pixels.iter().map(|&v| f64::from(v)));
        let se_mean = (lambda / n).sqrt();
        let se_var = ((lambda + 2.0 * lambda * lambda) / n).sqrt();
        assert!(
            (mean - lambda).abs() < 4.0 * se_mean,
            "λ={lambda}: mean {mean}"
        );
        assert!((var - lambda).abs() < 4.0 * se_var, "λ={lambda}: var {var}");
        assert_eq!(r.saturated, 0);
    }
}

#[test]
fn every_pixel_draws_with_its_own_mean() {
    // λ from 20 to 20 000 across the image (an attenuating wedge): the standardised residuals
    // (n − Q)/√Q have mean 0 and variance 1; a noise drawn at one shared λ would not.
    let (w, h) = (400, 500);
    let lengths: Vec<f64> = (0..w * h).map(|p| (p % w) as f64 * 0.1).collect();
    let (mu, len) = (vec![vec![0.1727]], vec![lengths]);
    let fluence = vec![1.0; w * h];
    let scene = Scene {
        width: w,
        height: h,
        mu_per_mm: &mu,
        layers: &Layer::images(w, h, &len),
        fluence: Fluence::Image(&fluence),
    };
    let det = detector(Response::PhotonCounting, vec![1.0], Polarity::Raw);
    let beam = mono(20_000.0);
    let q = expected_quanta(&beam, &det, &scene);
    let r = render(&beam, &det, &scene, &key());
    let z = r
        .pixels
        .iter()
        .zip(&q)
        .map(|(&v, &q)| (f64::from(v) - q) / q.sqrt());
    let (mean, var) = mean_var(z);
    let n = (w * h) as f64;
    assert!(mean.abs() < 4.0 / n.sqrt(), "mean {mean}");
    assert!(
        (var - 1.0).abs() < 4.0 * (2.0 / n).sqrt() * 1.5,
        "var {var}"
    );
    assert!(q[w - 1] < 25.0 && q[0] == 20_000.0);
}

#[test]
fn draw_order_is_row_stream_then_pixels_left_to_right() {
    // The documented order, replayed by hand: row j's stream, one sample per pixel in order,
    // each with the pixel's own expected quanta.
    let (w, h) = (37, 5);
    let lengths: Vec<f64> = (0..w * h).map(|p| ((p * 7) % 11) as f64 * 3.0).collect();
    let (mu, len) = (vec![vec![0.08]], vec![lengths]);
    let fluence: Vec<f64> = (0..w * h).map(|p| 1.0 - p as f64 * 1e-3).collect();
    let scene = Scene {
        width: w,
        height: h,
        mu_per_mm: &mu,
        layers: &Layer::images(w, h, &len),
        fluence: Fluence::Image(&fluence),
    };
    let det = detector(Response::PhotonCounting, vec![0.9], Polarity::Raw);
    let beam = mono(300.0);
    let q = expected_quanta(&beam, &det, &scene);
    let r = render(&beam, &det, &scene, &key());
    for j in 0..h {
        let mut rng = key().row_rng(j as u32);
        for i in 0..w {
            let n = Poisson::new(q[j * w + i]).sample(&mut rng);
            assert_eq!(u64::from(r.pixels[j * w + i]), n, "pixel ({i}, {j})");
        }
    }
}

#[test]
fn energy_integrating_mean_is_gain_times_expected_energy() {
    let beam = Beam {
        energies_kev: vec![30.0, 50.0, 70.0],
        photons_per_pixel: vec![400.0, 900.0, 300.0],
    };
    let eta = vec![0.95, 0.8, 0.6];
    let (w, h) = (500, 400);
    let fluence = vec![1.0; w * h];
    let scene = Scene {
        width: w,
        height: h,
        mu_per_mm: &[],
        layers: &[],
        fluence: Fluence::Image(&fluence),
    };
    let q0 = 400.0 * 0.95 + 900.0 * 0.8 + 300.0 * 0.6;
    let e0 = 400.0 * 0.95 * 30.0 + 900.0 * 0.8 * 50.0 + 300.0 * 0.6 * 70.0;
    let mut det = detector(Response::EnergyIntegrating, eta, Polarity::Raw);
    det.gain = 0.4;
    let r = render(&beam, &det, &scene, &key());
    let (mean, var) = mean_var(r.pixels.iter().map(|&v| f64::from(v)));
    // Each of the ~Poisson(Q) photons counts E/Q keV: SD = gain · (E/Q) · √Q.
    let sd = det.gain * e0 / q0 * q0.sqrt();
    let n = r.pixels.len() as f64;
    assert!(
        (mean - det.gain * e0).abs() < 4.0 * sd / n.sqrt(),
        "mean {mean}"
    );
    // Variance: that of the scaled count plus the rounding's 1/12.
    let expected_var = sd * sd + 1.0 / 12.0;
    assert!((var - expected_var).abs() < 4.0 * expected_var * (2.0 / n).sqrt() * 1.2);
}

#[test]
fn same_bytes_on_one_and_two_threads() {
    let (w, h) = (61, 47);
    let l0: Vec<f64> = (0..w * h).map(|p| ((p * 13) % 29) as f64).collect();
    let l1: Vec<f64> = (0..w * h)
        .map(|p| if p % 5 == 0 { 2.5 } else { 0.0 })
        .collect();
    let mu = vec![vec![0.05, 0.03], vec![2.0, 0.9]];
    let len = vec![l0, l1];
    let fluence: Vec<f64> = (0..w * h).map(|p| 0.8 + (p % 7) as f64 * 0.02).collect();
    let scene = Scene {
        width: w,
        height: h,
        mu_per_mm: &mu,
        layers: &Layer::images(w, h, &len),
        fluence: Fluence::Image(&fluence),
    };
    let beam = Beam {
        energies_kev: vec![45.0, 70.0],
        photons_per_pixel: vec![2000.0, 1000.0],
    };
    for polarity in [Polarity::Raw, Polarity::Radiograph { range: 5.0 }] {
        for response in [Response::EnergyIntegrating, Response::PhotonCounting] {
            let det = detector(response, vec![0.9, 0.6], polarity);
            let images: Vec<Rendered> = [1, 2]
                .into_iter()
                .map(|threads| {
                    rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap()
                        .install(|| render(&beam, &det, &scene, &key()))
                })
                .collect();
            assert_eq!(images[0], images[1], "{polarity:?} {response:?}");
        }
    }
}

#[test]
fn radiograph_of_air_is_black_and_of_the_range_is_white() {
    // Left half air, right half μL = range = 7; 8-bit so the noise is far below one DN in air.
    let (w, h, mu) = (200, 100, 0.1);
    let lengths: Vec<f64> = (0..w * h)
        .map(|p| if p % w < w / 2 { 0.0 } else { 7.0 / mu })
        .collect();
    let (mu_rows, len) = (vec![vec![mu]], vec![lengths]);
    let fluence = vec![1.0; w * h];
    let scene = Scene {
        width: w,
        height: h,
        mu_per_mm: &mu_rows,
        layers: &Layer::images(w, h, &len),
        fluence: Fluence::Image(&fluence),
    };
    let mut det = detector(
        Response::EnergyIntegrating,
        vec![1.0],
        Polarity::Radiograph {
            range: DEFAULT_RADIOGRAPH_RANGE,
        },
    );
    det.i_max = 255;
    // Air at twice i_max in raw values (saturated), behind the object far below.
    det.gain = 2.0 * 255.0 / (1e6 * 60.0);
    let r = render(&mono(1e6), &det, &scene, &key());
    let half = |right: bool| {
        let v: Vec<f64> = r
            .pixels
            .iter()
            .enumerate()
            .filter(|(p, _)| (p % w >= w / 2) == right)
            .map(|(_, &v)| f64::from(v))
            .collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    assert_eq!(half(false), 0.0, "air is black");
    // Behind μL = 7: λ ≈ 912, ln ratio = 7 ± 0.033 → 255 ± 1.2 DN, clipped above.
    let white = half(true);
    assert!(white > 254.0 && white <= 255.0, "mean {white}");
    // Saturation is about the raw detector: the air half would have been clipped.
    assert_eq!(r.saturated, w * h / 2);
}

#[test]
fn radiograph_of_air_averages_zero_at_16_bits() {
    // At 16 bits the noise shows: ln(S_open/S) ~ N(0, 1/λ) clipped at 0, so the mean is
    // i_max/range · σ/√(2π) ≈ 9362 · 10⁻³ · 0.399 ≈ 3.7 DN, the median 0.
    let (r, _) = {
        let (w, h) = (400, 250);
        let fluence = vec![1.0; w * h];
        let det = detector(
            Response::PhotonCounting,
            vec![1.0],
            Polarity::Radiograph { range: 7.0 },
        );
        let scene = Scene {
            width: w,
            height: h,
            mu_per_mm: &[],
            layers: &[],
            fluence: Fluence::Image(&fluence),
        };
        (render(&mono(1e6), &det, &scene, &key()), ())
    };
    let (mean, _) = mean_var(r.pixels.iter().map(|&v| f64::from(v)));
    let expected = 65535.0 / 7.0 * 1e-3 / (2.0 * std::f64::consts::PI).sqrt();
    assert!(
        (mean - expected).abs() < 0.1 * expected,
        "mean {mean} vs {expected}"
    );
    let zeros = r.pixels.iter().filter(|&&v| v == 0).count();
    assert!(
        zeros * 2 >= r.pixels.len() - r.pixels.len() / 50,
        "{zeros} zeros"
    );
}

#[test]
fn saturation_is_counted_and_clipped() {
    // The same key and means with a 16-bit and a 5000 DN ceiling: the same counts n, so the
    // clipped image is min(n, 5000) and `saturated` counts n > 5000.
    let (wide, _) = uniform_field(5000.0, Response::PhotonCounting, 1.0);
    let (w, h) = (500, 400);
    let fluence = vec![1.0; w * h];
    let scene = Scene {
        width: w,
        height: h,
        mu_per_mm: &[],
        layers: &[],
        fluence: Fluence::Image(&fluence),
    };
    let mut det = detector(Response::PhotonCounting, vec![1.0], Polarity::Raw);
    det.i_max = 5000;
    let clipped = render(&mono(5000.0), &det, &scene, &key());
    let over = wide.pixels.iter().filter(|&&v| v > 5000).count();
    assert_eq!(clipped.saturated, over);
    assert!(over > 90_000 && over < 110_000, "{over}");
    for (&c, &n) in clipped.pixels.iter().zip(&wide.pixels) {
        assert_eq!(c, n.min(5000));
    }
    assert_eq!(clipped.expected_open_max, 5000.0);
}

#[test]
fn auto_gain_puts_the_open_field_at_the_fraction() {
    let beam = Beam {
        energies_kev: vec![40.0, 60.0],
        photons_per_pixel: vec![5000.0, 10_000.0],
    };
    let eta = [0.8, 0.5];
    let (offset, fraction, i_max) = (100.0, 0.8, 4095u16);
    let g = DetectorModel::auto_gain(
        &Response::PhotonCounting,
        &beam,
        &eta,
        offset,
        fraction,
        i_max,
    );
    assert_eq!(g, (0.8 * 4095.0 - 100.0) / 9000.0);
    let g = DetectorModel::auto_gain(
        &Response::EnergyIntegrating,
        &beam,
        &eta,
        offset,
        fraction,
        i_max,
    );
    assert_eq!(g, (0.8 * 4095.0 - 100.0) / (4000.0 * 40.0 + 5000.0 * 60.0));
    // Rendered at that gain, the open field at f = 1 sits at fraction · i_max on average.
    let (w, h) = (300, 200);
    let fluence = vec![1.0; w * h];
    let scene = Scene {
        width: w,
        height: h,
        mu_per_mm: &[],
        layers: &[],
        fluence: Fluence::Image(&fluence),
    };
    let det = DetectorModel {
        response: Response::EnergyIntegrating,
        efficiency: eta.to_vec(),
        gain: g,
        offset,
        i_max,
        polarity: Polarity::Raw,
        quantum_noise: true,
    };
    let r = render(&beam, &det, &scene, &key());
    let (mean, _) = mean_var(r.pixels.iter().map(|&v| f64::from(v)));
    assert!((mean - fraction * 4095.0).abs() < 1.0, "mean {mean}");
    assert!((r.expected_open_max - fraction * 4095.0).abs() < 1e-9);
    // No beam: no gain.
    let dark = Beam {
        energies_kev: vec![50.0],
        photons_per_pixel: vec![0.0],
    };
    assert_eq!(
        DetectorModel::auto_gain(&Response::PhotonCounting, &dark, &[1.0], 0.0, 0.8, 255),
        0.0
    );
}

#[test]
fn fluence_scales_the_mean_and_a_dark_pixel_gives_offset() {
    let fluence = vec![1.0, 0.5, 0.0, 0.25];
    let scene = Scene {
        width: 2,
        height: 2,
        mu_per_mm: &[],
        layers: &[],
        fluence: Fluence::Image(&fluence),
    };
    let mut det = detector(Response::PhotonCounting, vec![1.0], Polarity::Raw);
    det.offset = 7.0;
    let q = expected_quanta(&mono(1000.0), &det, &scene);
    assert_eq!(q, vec![1000.0, 500.0, 0.0, 250.0]);
    let r = render(&mono(1000.0), &det, &scene, &key());
    assert_eq!(r.pixels[2], 7, "no photons: the offset alone");
}

#[test]
fn invalid_values_never_panic_and_are_reported() {
    let (w, h) = (8, 4);
    let bad_lengths: Vec<f64> = (0..w * h)
        .map(|p| match p % 4 {
            0 => f64::NAN,
            1 => -5.0,
            2 => f64::INFINITY,
            _ => 1e308,
        })
        .collect();
    let mu = vec![vec![f64::NAN, 0.2], vec![-3.0, f64::INFINITY]];
    let len = vec![bad_lengths.clone(), bad_lengths];
    let fluence: Vec<f64> = (0..w * h)
        .map(|p| [f64::NAN, -1.0, f64::INFINITY, 1e300][p % 4])
        .collect();
    let scene = Scene {
        width: w,
        height: h,
        mu_per_mm: &mu,
        layers: &Layer::images(w, h, &len),
        fluence: Fluence::Image(&fluence),
    };
    let beam = Beam {
        energies_kev: vec![f64::NAN, -1.0],
        photons_per_pixel: vec![f64::INFINITY, -1e300],
    };
    for response in [Response::EnergyIntegrating, Response::PhotonCounting] {
        for polarity in [
            Polarity::Raw,
            Polarity::Radiograph { range: f64::NAN },
            Polarity::Radiograph { range: -1.0 },
        ] {
            let det = DetectorModel {
                response,
                efficiency: vec![f64::NAN, 2.0],
                gain: f64::NAN,
                offset: f64::INFINITY,
                i_max: 255,
                polarity,
                quantum_noise: true,
            };
            let r = render(&beam, &det, &scene, &key());
            assert_eq!(r.pixels.len(), w * h);
            assert!(r.pixels.iter().all(|&v| v <= 255));
            let e = check_inputs(&beam, &det, &scene).unwrap_err();
            assert!(e.contains("energies_kev[0]"), "{e}");
        }
    }
    // check_inputs names each kind of fault.
    let good_beam = mono(100.0);
    let det = detector(Response::PhotonCounting, vec![1.0], Polarity::Raw);
    let ok_fluence = vec![1.0; 4];
    let one_mu = vec![vec![0.1]];
    let cases: [(Vec<Vec<f64>>, &str); 4] = [
        (vec![vec![0.0, 1.0, -2.0, 0.0]], "layer 0 length_mm[2] = -2"),
        (
            vec![vec![0.0; 3]],
            "layer 0 covers columns 0..2 and rows 0..2 with 3 values",
        ),
        (vec![vec![]], ""),
        (vec![vec![], vec![0.0; 4]], "layer 0 has material 1 of 1"),
    ];
    for (lengths, expected) in cases {
        let scene = Scene {
            width: 2,
            height: 2,
            mu_per_mm: &one_mu,
            layers: &Layer::images(2, 2, &lengths),
            fluence: Fluence::Image(&ok_fluence),
        };
        match check_inputs(&good_beam, &det, &scene) {
            Ok(()) => assert_eq!(expected, ""),
            Err(e) => assert!(e.contains(expected), "{e}"),
        }
    }
}

#[test]
fn empty_image_is_empty() {
    let scene = Scene {
        width: 0,
        height: 0,
        mu_per_mm: &[],
        layers: &[],
        fluence: Fluence::Image(&[]),
    };
    let det = detector(Response::PhotonCounting, vec![1.0], Polarity::Raw);
    let r = render(&mono(10.0), &det, &scene, &key());
    assert!(r.pixels.is_empty());
    assert!(expected_quanta(&mono(10.0), &det, &scene).is_empty());
}

#[test]
fn rectangle_layers_and_row_fluence_equal_full_images() {
    // A 37 × 23 image: material 0 over a 20 × 15 rectangle with a nested 6 × 5 rectangle taken
    // from it (and given to material 1), plus rounding residue below zero; the same scene as
    // full per-material images (the layers added into zeroed images in order, negatives set to
    // 0) with the point source's fluence as a map.
    let (w, h) = (37usize, 23usize);
    let frame = crate::geometry::DetectorFrame {
        pose: crate::geometry::Pose::from_position_euler_deg(
            [3.0, -2.0, -400.0],
            [4.0, -7.0, 30.0],
        ),
        pixels: [w as u32, h as u32],
        pixel_pitch_mm: [0.7, 0.9],
    };
    let source = glam::DVec3::new(20.0, 10.0, 900.0);
    let outer: Vec<f64> = (0..20 * 15).map(|p| 5.0 + (p % 11) as f64 * 0.37).collect();
    let inner: Vec<f64> = (0..6 * 5).map(|p| 1.0 + (p % 4) as f64 * 0.5).collect();
    let residue = vec![1e-9; 4];
    let layers = [
        Layer {
            material: 0,
            sign: 1.0,
            columns: 9..29,
            rows: 4..19,
            length_mm: &outer,
        },
        Layer {
            material: 0,
            sign: -1.0,
            columns: 12..18,
            rows: 6..11,
            length_mm: &inner,
        },
        Layer {
            material: 1,
            sign: 1.0,
            columns: 12..18,
            rows: 6..11,
            length_mm: &inner,
        },
        Layer {
            material: 1,
            sign: -1.0,
            columns: 30..32,
            rows: 0..2,
            length_mm: &residue,
        },
    ];
    let mut images = vec![vec![0.0; w * h]; 2];
    for l in &layers {
        let cols = l.columns.len();
        for (r, row) in l.length_mm.chunks(cols).enumerate() {
            let start = (l.rows.start + r) * w + l.columns.start;
            for (dst, &v) in images[l.material][start..start + cols].iter_mut().zip(row) {
                *dst += l.sign * v;
            }
        }
    }
    for v in images.iter_mut().flatten() {
        if *v < 0.0 {
            *v = 0.0;
        }
    }
    let fluence_map = point_source_fluence(&frame, source);
    let fluence_rows = PointSourceFluence::new(&frame, source);
    let mu = vec![vec![0.02, 0.03, 0.05], vec![0.4, 0.7, 1.9]];
    let beam = Beam {
        energies_kev: vec![80.0, 50.0, 30.0],
        photons_per_pixel: vec![3000.0, 5000.0, 800.0],
    };
    let det = detector(
        Response::EnergyIntegrating,
        vec![0.6, 0.8, 0.95],
        Polarity::Raw,
    );
    let by_layers = Scene {
        width: w,
        height: h,
        mu_per_mm: &mu,
        layers: &layers,
        fluence: Fluence::PointSource(&fluence_rows),
    };
    let by_images = Scene {
        width: w,
        height: h,
        mu_per_mm: &mu,
        layers: &Layer::images(w, h, &images),
        fluence: Fluence::Image(&fluence_map),
    };
    check_inputs(&beam, &det, &by_layers).expect("valid layers");
    let (q1, q2) = (
        expected_quanta(&beam, &det, &by_layers),
        expected_quanta(&beam, &det, &by_images),
    );
    assert!(q1.iter().zip(&q2).all(|(a, b)| a.to_bits() == b.to_bits()));
    // The nested rectangle attenuates more than the outer one around it.
    assert!(q1[8 * w + 14] < q1[8 * w + 10]);
    let (r1, r2) = (
        render(&beam, &det, &by_layers, &key()),
        render(&beam, &det, &by_images, &key()),
    );
    assert_eq!(r1, r2);
}

#[test]
fn single_material_pixels_take_the_table_within_its_bound() {
    // 320 × 200 pixels, 30 bins: soft tissue-like material 0 over most of the image (lengths
    // 0–180 mm), a bone-like material 1 over a band inside it. Pixels crossing material 0 alone
    // come from its table (module `transmission`): within 10⁻¹⁰ of the per-bin sum, and not
    // bit for bit the sum (the table is used). Pixels crossing both keep the sum exactly.
    let (w, h) = (320usize, 200usize);
    let nbins = 30;
    let energies: Vec<f64> = (0..nbins).map(|b| 15.0 + 2.3 * b as f64).collect();
    let beam = Beam {
        photons_per_pixel: energies.iter().map(|e| 50.0 * (85.0 - e)).collect(),
        energies_kev: energies.clone(),
    };
    let eta: Vec<f64> = energies.iter().map(|e| 1.0 - (-(40.0 / e)).exp()).collect();
    let mu = vec![
        energies
            .iter()
            .map(|e| 0.02 + 0.03 * (30.0 / e).powi(3))
            .collect::<Vec<f64>>(),
        energies
            .iter()
            .map(|e| 0.03 + 0.25 * (30.0 / e).powi(3))
            .collect(),
    ];
    let tissue: Vec<f64> = (0..w * h)
        .map(|p| {
            let (i, j) = ((p % w) as f64, (p / w) as f64);
            if i < 10.0 {
                0.0
            } else {
                180.0 * (1.0 - ((i - 165.0) / 160.0).powi(2)) * (0.6 + j / 500.0)
            }
        })
        .collect();
    let bone: Vec<f64> = (0..w * h)
        .map(|p| {
            if (90..110).contains(&(p / w)) {
                12.0 + (p % 7) as f64
            } else {
                0.0
            }
        })
        .collect();
    let lengths = vec![tissue.clone(), bone.clone()];
    let fluence = vec![1.0; w * h];
    let scene = Scene {
        width: w,
        height: h,
        mu_per_mm: &mu,
        layers: &Layer::images(w, h, &lengths),
        fluence: Fluence::Image(&fluence),
    };
    let det = detector(Response::EnergyIntegrating, eta.clone(), Polarity::Raw);
    let e = expected(&beam, &det, &scene);
    let (mut worst, mut tabled, mut exact) = (0.0f64, 0usize, 0usize);
    for p in 0..w * h {
        // The per-bin sums in the response's own order with its own exp.
        let (mut q, mut en) = (0.0, 0.0);
        for b in 0..nbins {
            let t = exp::exp(-(0.0 + mu[0][b] * tissue[p] + mu[1][b] * bone[p]));
            let wq = beam.photons_per_pixel[b] * eta[b];
            q += wq * t;
            en += wq * energies[b] * t;
        }
        if tissue[p] > 0.0 && bone[p] == 0.0 {
            worst = worst
                .max(((e.quanta[p] - q) / q).abs())
                .max(((e.energy_kev[p] - en) / en).abs());
            tabled += usize::from(e.quanta[p].to_bits() != q.to_bits());
        } else {
            assert_eq!(e.quanta[p].to_bits(), q.to_bits(), "pixel {p}");
            assert_eq!(e.energy_kev[p].to_bits(), en.to_bits(), "pixel {p}");
            exact += 1;
        }
    }
    assert!(worst <= 1e-10 + 1e-14, "{worst:e}");
    assert!(tabled > (w * h) / 2, "{tabled} pixels from the table");
    assert!(exact > 20 * w, "{exact}");
    // The quanta are the same whether or not the energy is wanted.
    let q = expected_quanta(&beam, &det, &scene);
    assert!(
        q.iter()
            .zip(&e.quanta)
            .all(|(a, b)| a.to_bits() == b.to_bits())
    );
}

//! Criterion benchmarks of the attenuation-mode detector response (`rsasim::response`) on a
//! synthetic 1440² knee-like scene: a soft-tissue elliptic cylinder over most of the image, a
//! bone cylinder inside it, a cobalt-chromium block and 8 tantalum beads, from a point source
//! 1800 mm above the detector centre (0.2986 mm pitch). About 20 000 photons per pixel in air.
//!
//! Functions (criterion ids `response/<function>`), all with the default rayon pool (all cores)
//! unless named `_1t` (a 1-thread pool):
//! - `fluence`: `point_source_fluence` alone.
//! - `mono_raw`, `mono_raw_1t`, `mono_radiograph`: one 60 keV bin, photon counting.
//! - `poly30_expected`: `expected_quanta` alone, 30 bins (20–90 keV).
//! - `poly30_raw`, `poly30_radiograph`: the whole response with 30 bins, energy integrating.
//! - `poly30_expected_image`: `expected` (Q, E and S_open of every pixel), 30 bins.
//! - `from_expected_plain`: `render_expected` of that image with every option off (the same
//!   bytes as `poly30_raw`: quantum noise and digitisation only).
//! - `from_expected_psf`, `from_expected_scatter`, `from_expected_scatter_psf_e`: with a
//!   Gaussian PSF of σ = 0.15 mm, scatter (SPR 0.3, σ = 40 mm), and both plus 2 DN of
//!   electronic noise.
//!
//! Run with `cargo bench --bench response`. This asserts nothing; medians are in
//! `target/criterion/response/<function>/new/estimates.json`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;
use rsasim::geometry::{DetectorFrame, Pose};
use rsasim::noise::NoiseKey;
use rsasim::response::{
    Beam, DetectorModel, Fluence, Layer, Polarity, Psf, PsfShape, Response, Scatter, Scene,
    Unsharpness, expected, expected_quanta, point_source_fluence, render, render_expected,
};

const N: usize = 1440;

/// Path lengths (mm) of tissue, bone, CoCr and tantalum over the image, row-major.
fn lengths() -> Vec<Vec<f64>> {
    let pitch = 0.2986;
    let mut out = vec![vec![0.0; N * N]; 4];
    let beads: Vec<(f64, f64)> = (0..8)
        .map(|k| (-40.0 + 11.0 * k as f64, -90.0 + 23.0 * k as f64))
        .collect();
    for j in 0..N {
        let y = (j as f64 + 0.5 - N as f64 / 2.0) * pitch;
        for i in 0..N {
            let x = (i as f64 + 0.5 - N as f64 / 2.0) * pitch;
            let p = j * N + i;
            // Elliptic cylinder along y: half-widths 160 mm (x) and 60 mm (depth).
            let chord = |a: f64, b: f64, c: f64| {
                let t = 1.0 - ((x - c) / a).powi(2);
                if t > 0.0 { 2.0 * b * t.sqrt() } else { 0.0 }
            };
            let tissue = chord(160.0, 60.0, 0.0);
            let bone = chord(25.0, 25.0, 5.0);
            out[0][p] = tissue - bone;
            out[1][p] = bone;
            if (x - 5.0).abs() < 30.0 && (y - 60.0).abs() < 25.0 {
                out[2][p] = 4.0 + 0.2 * (x - 5.0).abs();
            }
            for &(bx, by) in &beads {
                let r2 = (x - bx).powi(2) + (y - by).powi(2);
                if r2 < 0.25 {
                    out[3][p] = 2.0 * (0.25 - r2).sqrt();
                }
            }
        }
    }
    out
}

/// μ per mm of the four materials at `e` keV: a rough `E⁻³` photoelectric term plus Compton.
fn mu(e: f64) -> Vec<f64> {
    let pe = (60.0 / e).powi(3);
    vec![
        0.0185 + 0.0021 * pe,
        0.034 + 0.027 * pe,
        0.45 + 1.7 * pe,
        1.2 + 9.0 * pe,
    ]
}

/// CPU time of this process (all threads), seconds.
fn cpu_seconds() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec.
    unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

fn bench(c: &mut Criterion) {
    let frame = DetectorFrame {
        pose: Pose::from_position_euler_deg([0.0, 0.0, -500.0], [0.0, 0.0, 0.0]),
        pixels: [N as u32, N as u32],
        pixel_pitch_mm: [0.2986, 0.2986],
    };
    let source = DVec3::new(0.0, 0.0, 1300.0);
    let fluence = point_source_fluence(&frame, source);
    let lengths = lengths();
    let layers = Layer::images(N, N, &lengths);
    let key = NoiseKey::derive(1, 0, 0, "bench", "det");
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a 1-thread rayon pool");

    let mono_mu: Vec<Vec<f64>> = mu(60.0).into_iter().map(|m| vec![m]).collect();
    let mono = Beam {
        energies_kev: vec![60.0],
        photons_per_pixel: vec![20_000.0],
    };
    let energies: Vec<f64> = (0..30).map(|b| 20.0 + 70.0 * b as f64 / 29.0).collect();
    let poly = Beam {
        photons_per_pixel: energies
            .iter()
            .map(|&e| 2000.0 * (e - 15.0) * (95.0 - e) / 1600.0)
            .collect(),
        energies_kev: energies.clone(),
    };
    let per_bin: Vec<Vec<f64>> = energies.iter().map(|&e| mu(e)).collect();
    let poly_mu: Vec<Vec<f64>> = (0..4)
        .map(|m| per_bin.iter().map(|row| row[m]).collect())
        .collect();
    let scene = |mu: &'static [Vec<f64>]| Scene {
        width: N,
        height: N,
        mu_per_mm: mu,
        layers: &layers,
        fluence: Fluence::Image(&fluence),
    };
    let mono_mu: &'static [Vec<f64>] = Box::leak(mono_mu.into_boxed_slice());
    let poly_mu: &'static [Vec<f64>] = Box::leak(poly_mu.into_boxed_slice());
    let detector = |response, bins: usize, beam: &Beam, polarity| {
        let efficiency = vec![0.7; bins];
        let gain = DetectorModel::auto_gain(&response, beam, &efficiency, 0.0, 0.8, u16::MAX);
        DetectorModel {
            response,
            efficiency,
            gain,
            offset: 0.0,
            i_max: u16::MAX,
            polarity,
            quantum_noise: true,
        }
    };
    let radiograph = Polarity::Radiograph { range: 7.0 };
    let mono_raw = detector(Response::PhotonCounting, 1, &mono, Polarity::Raw);
    let mono_rad = detector(Response::PhotonCounting, 1, &mono, radiograph);
    let poly_raw = detector(Response::EnergyIntegrating, 30, &poly, Polarity::Raw);
    let poly_rad = detector(Response::EnergyIntegrating, 30, &poly, radiograph);

    let pitch = [0.2986, 0.2986];
    let ekey = NoiseKey::derive_electronic(1, 0, 0, "bench", "det");
    let image = expected(&poly, &poly_raw, &scene(poly_mu));
    let psf = Psf::new(PsfShape::Gaussian { sigma_mm: 0.15 }, pitch).expect("a valid PSF");
    let scatter = Scatter::new(0.3, 40.0, pitch).expect("valid scatter");
    let plain = Unsharpness::default();
    let with_psf = Unsharpness {
        psf: Some(psf.clone()),
        ..Default::default()
    };
    let with_scatter = Unsharpness {
        scatter: Some(scatter.clone()),
        ..Default::default()
    };
    let with_all = Unsharpness {
        scatter: Some(scatter),
        psf: Some(psf),
        electronic_noise_dn: 2.0,
    };

    // CPU time over all threads (immune to other processes on a shared machine), median of 3.
    let cases: [(&str, &dyn Fn()); 10] = [
        ("mono_raw", &|| {
            drop(render(&mono, &mono_raw, &scene(mono_mu), &key))
        }),
        ("mono_radiograph", &|| {
            drop(render(&mono, &mono_rad, &scene(mono_mu), &key))
        }),
        ("poly30_expected", &|| {
            drop(expected_quanta(&poly, &poly_raw, &scene(poly_mu)))
        }),
        ("poly30_raw", &|| {
            drop(render(&poly, &poly_raw, &scene(poly_mu), &key))
        }),
        ("poly30_radiograph", &|| {
            drop(render(&poly, &poly_rad, &scene(poly_mu), &key))
        }),
        ("poly30_expected_image", &|| {
            drop(expected(&poly, &poly_raw, &scene(poly_mu)))
        }),
        ("from_expected_plain", &|| {
            drop(render_expected(&poly_raw, &image, &plain, &key, &ekey))
        }),
        ("from_expected_psf", &|| {
            drop(render_expected(&poly_raw, &image, &with_psf, &key, &ekey))
        }),
        ("from_expected_scatter", &|| {
            drop(render_expected(
                &poly_raw,
                &image,
                &with_scatter,
                &key,
                &ekey,
            ))
        }),
        ("from_expected_scatter_psf_e", &|| {
            drop(render_expected(&poly_raw, &image, &with_all, &key, &ekey))
        }),
    ];
    for (name, f) in cases {
        let mut t: Vec<f64> = (0..3)
            .map(|_| {
                let start = cpu_seconds();
                f();
                cpu_seconds() - start
            })
            .collect();
        t.sort_by(f64::total_cmp);
        println!("{name}: {:.1} ms of CPU (all threads)", t[1] * 1e3);
    }

    let mut g = c.benchmark_group("response");
    g.sample_size(10).measurement_time(Duration::from_secs(4));
    g.bench_function("fluence", |b| {
        b.iter(|| point_source_fluence(&frame, black_box(source)))
    });
    g.bench_function("mono_raw", |b| {
        b.iter(|| render(&mono, &mono_raw, &scene(mono_mu), black_box(&key)))
    });
    g.bench_function("mono_raw_1t", |b| {
        b.iter(|| one.install(|| render(&mono, &mono_raw, &scene(mono_mu), black_box(&key))))
    });
    g.bench_function("mono_radiograph", |b| {
        b.iter(|| render(&mono, &mono_rad, &scene(mono_mu), black_box(&key)))
    });
    g.bench_function("poly30_expected", |b| {
        b.iter(|| expected_quanta(black_box(&poly), &poly_raw, &scene(poly_mu)))
    });
    g.bench_function("poly30_raw", |b| {
        b.iter(|| render(&poly, &poly_raw, &scene(poly_mu), black_box(&key)))
    });
    g.bench_function("poly30_radiograph", |b| {
        b.iter(|| render(&poly, &poly_rad, &scene(poly_mu), black_box(&key)))
    });
    g.bench_function("poly30_expected_image", |b| {
        b.iter(|| expected(black_box(&poly), &poly_raw, &scene(poly_mu)))
    });
    for (name, unsharp) in [
        ("from_expected_plain", &plain),
        ("from_expected_psf", &with_psf),
        ("from_expected_scatter", &with_scatter),
        ("from_expected_scatter_psf_e", &with_all),
    ] {
        g.bench_function(name, |b| {
            b.iter(|| render_expected(&poly_raw, &image, unsharp, black_box(&key), &ekey))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

//! Adaptive sampling against full sampling on a scenario's first run (a measurement, not a
//! test): for every exposure and detector, the expected image both ways, the share of pixels
//! refined, and the difference in units of each pixel's quantum-noise SD (`|ΔQ|/√Q`, and the
//! energy's `|ΔE|/(E/√Q)`), with the time each took. "one ray": the share of pixels adaptive
//! sampling left at the sharp value (one ray to the centre from the spot's centre).
//!
//! `cargo run --release --example adaptive_check -- scenarios/biplanar_realistic_blurred.toml`

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use rsasim::attenuation::{parts, sampled};
use rsasim::sampling::Sampling;
use rsasim::simulate::{self, Allowances};
use rsasim::trace::MeshBvh;

fn main() {
    let path = PathBuf::from(
        std::env::args()
            .nth(1)
            .expect("usage: adaptive_check SCENARIO"),
    );
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let allow = Allowances {
        dirs: vec![root.join("scenarios/models")],
        large: true,
    };
    let plan = simulate::prepare_with(&path, &allow).unwrap_or_else(|d| {
        eprintln!("{d:?}");
        std::process::exit(2)
    });
    let setup = plan.setup.as_ref().expect("attenuation mode");
    let mut sampling = Sampling::from_imaging(&plan.loaded.scenario.imaging);
    let run = &plan.runs[0];
    let bvhs: Vec<Option<Arc<MeshBvh>>> = plan
        .models
        .iter()
        .map(|m| m.mesh.as_ref().map(|mesh| Arc::new(MeshBvh::new(mesh))))
        .collect();
    println!(
        "| exposure | detector | one ray | full (s) | adaptive (s) | max ΔQ/σ | p99.9 ΔQ/σ | mean ΔQ/σ | max ΔE/σ_E |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---:|---:|");
    for exposure in &run.exposures {
        let ps = parts(
            &plan.loaded.scenario,
            setup,
            &plan.models,
            &bvhs,
            run,
            exposure,
        )
        .expect("parts");
        for det in &run.detectors {
            let (frame, source) = (det.frame(), run.source_of(det));
            let beam = setup.beam(&frame, source, 1.0);
            let detector = setup.detector(&beam, det.i_max());
            let exposed = rsasim::attenuation::Exposure {
                setup,
                parts: &ps,
                frame: &frame,
                source_mm: source,
            };
            sampling.adaptive = false;
            let t = Instant::now();
            let full = sampled::expected(&exposed, &beam, &detector, &sampling);
            let t_full = t.elapsed().as_secs_f64();
            sampling.adaptive = true;
            let t = Instant::now();
            let fast = sampled::expected_adaptive_of(&exposed, &beam, &detector, &sampling);
            let t_fast = t.elapsed().as_secs_f64();
            let sharp = sampled::expected(
                &exposed,
                &beam,
                &detector,
                &Sampling {
                    heel: sampling.heel.clone(),
                    ..Sampling::from_imaging(&rsasim::scenario::Imaging::default())
                },
            );
            let mut dq: Vec<f64> = Vec::with_capacity(full.quanta.len());
            let (mut de_max, mut sum, mut kept) = (0.0f64, 0.0, 0usize);
            for p in 0..full.quanta.len() {
                let q = full.quanta[p].max(1e-300);
                let sd = q.sqrt();
                let d = (fast.quanta[p] - full.quanta[p]) / sd;
                sum += d;
                kept += usize::from(fast.quanta[p] == sharp.quanta[p]);
                dq.push(d.abs());
                de_max = de_max.max(
                    (fast.energy_kev[p] - full.energy_kev[p]).abs() / (full.energy_kev[p] / sd),
                );
            }
            let n = dq.len();
            let mean = sum / n as f64;
            dq.sort_by(f64::total_cmp);
            println!(
                "| {} | {} | {:.1} % | {t_full:.2} | {t_fast:.2} | {:.4} | {:.4} | {mean:.2e} | {de_max:.4} |",
                exposure.id,
                det.id,
                100.0 * kept as f64 / n as f64,
                dq[n - 1],
                dq[(n as f64 * 0.999) as usize],
            );
        }
    }
}

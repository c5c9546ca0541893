//! Per-image cost of the biplanar protocol: one calibration image and one model image, each
//! traced, noised and encoded in every format, timed separately by stage. Median of 7 runs.
//!
//! Run with `cargo bench --bench images` (release profile, one thread: the protocol runs images
//! in parallel, one per core). The criterion benches of the projector and the noise, on the same
//! run and detector, are in `benches/projector.rs`; `bench/run.sh` runs both (BENCHMARKS.md).

use std::path::Path;
use std::time::Instant;

use rsasim::noise::{self, NoiseKey};
use rsasim::output::{exr, tiff};
use rsasim::simulate;
use rsasim::trace::{MeshBvh, Object, render_binary};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let plan =
        simulate::prepare(Path::new("scenarios/biplanar.toml")).expect("biplanar.toml is valid");
    let s = &plan.loaded.scenario;
    // Run n2-r07: noise level 0.45.
    let run = plan
        .runs
        .iter()
        .find(|r| r.id == "n2-r07")
        .expect("run n2-r07");
    let det = &run.detectors[0];
    let frame = det.frame();
    let source = run.source_of(det);
    let bvh_start = Instant::now();
    let femur = plan.models.iter().position(|m| m.id == "femur").unwrap();
    let bvh = MeshBvh::new(plan.models[femur].mesh.as_ref().unwrap());
    println!(
        "femur BVH build ({} triangles): {:.1} ms",
        plan.models[femur].mesh.as_ref().unwrap().triangles.len(),
        bvh_start.elapsed().as_secs_f64() * 1e3
    );

    let box_index = plan.models.iter().position(|m| m.id == "box").unwrap();
    let calibration: Vec<Object> = run.phantoms[box_index]
        .markers
        .iter()
        .map(|m| Object::Sphere {
            centre_mm: m.position_mm,
            radius_mm: m.diameter_mm / 2.0,
        })
        .collect();
    let mut model: Vec<Object> = run.phantoms[femur]
        .markers
        .iter()
        .map(|m| Object::Sphere {
            centre_mm: m.position_mm,
            radius_mm: m.diameter_mm / 2.0,
        })
        .collect();
    model.push(Object::Mesh {
        bvh: &bvh,
        pose: run.phantoms[femur].pose(),
    });

    for (name, objects) in [("calibration", &calibration), ("model", &model)] {
        let (mut trace_ms, mut noise_ms, mut tiff_ms, mut exr_ms) =
            (vec![], vec![], vec![], vec![]);
        let mut covered = 0;
        for _ in 0..7 {
            let t = Instant::now();
            let mut px = render_binary(&frame, source, objects, det.i_max());
            trace_ms.push(t.elapsed().as_secs_f64() * 1e3);
            covered = px.iter().filter(|&&p| p == det.i_max()).count();
            let t = Instant::now();
            let key = NoiseKey::derive(s.seed, run.noise_level_index, run.run_index, name, &det.id);
            noise::add_noise(
                &mut px,
                det.pixels[0] as usize,
                run.noise_level,
                det.i_max(),
                &key,
            );
            noise_ms.push(t.elapsed().as_secs_f64() * 1e3);
            let t = Instant::now();
            let bytes = tiff::encode_tiff(
                1440,
                1440,
                &px,
                s.output.tiff_compression,
                "bench",
                "rsasim",
            )
            .unwrap();
            tiff_ms.push(t.elapsed().as_secs_f64() * 1e3);
            std::hint::black_box(bytes);
            let t = Instant::now();
            let f: Vec<f32> = px.iter().map(|&p| p as f32).collect();
            let bytes = exr::encode_exr(1440, 1440, &f, &[]).unwrap();
            exr_ms.push(t.elapsed().as_secs_f64() * 1e3);
            std::hint::black_box(bytes);
        }
        let (tr, no, ti, ex) = (
            median(trace_ms),
            median(noise_ms),
            median(tiff_ms),
            median(exr_ms),
        );
        println!(
            "{name:<11} image 1440² ({covered} covered px): trace {tr:.1} ms, noise {no:.1} ms, TIFF {ti:.1} ms, EXR {ex:.1} ms, total {:.1} ms",
            tr + no + ti + ex
        );
    }
}

//! Per-image cost of the biplanar protocol: one calibration image and one model image, each
//! traced, noised and encoded in every format, timed separately by stage. Median of 7 runs.
//!
//! Run with `cargo bench --bench images` (release profile, one thread: the protocol runs images
//! in parallel, one per core). The criterion benches of the projector and the noise, on the same
//! run and detector, are in `benches/projector.rs`; `bench/run.sh` runs both (docs/src/development/benchmarks.md).

#[path = "common/scenes.rs"]
mod scenes;

use std::time::Instant;

use rsasim::noise;
use rsasim::output::{exr, tiff};
use rsasim::scenario::TiffCompression;
use rsasim::trace::{MeshBvh, render_binary};
use scenes::Scenes;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    // Run n2-r07 (noise level 0.45), detector det1: the scenes of the criterion benches.
    let s = Scenes::load();
    let bvh_start = Instant::now();
    std::hint::black_box(MeshBvh::new(&s.femur.mesh));
    println!(
        "femur BVH build ({} triangles): {:.1} ms",
        s.femur.mesh.triangles.len(),
        bvh_start.elapsed().as_secs_f64() * 1e3
    );
    let [w, h] = s.frame.pixels;
    for (name, objects) in [("calibration", s.calibration()), ("model", s.model())] {
        let (mut trace_ms, mut noise_ms, mut tiff_ms, mut exr_ms) =
            (vec![], vec![], vec![], vec![]);
        let mut covered = 0;
        for _ in 0..7 {
            let t = Instant::now();
            let mut px = render_binary(&s.frame, s.source, &objects, s.i_max);
            trace_ms.push(t.elapsed().as_secs_f64() * 1e3);
            covered = px.iter().filter(|&&p| p == s.i_max).count();
            let t = Instant::now();
            let key = s.noise_key(name);
            noise::add_noise(&mut px, s.width(), s.noise_level, s.i_max, &key);
            noise_ms.push(t.elapsed().as_secs_f64() * 1e3);
            let t = Instant::now();
            // biplanar.toml's TIFF compression.
            let facts = tiff::TiffFacts {
                description: "bench",
                software: "rsasim",
                pixel_pitch_mm: [0.3, 0.3],
                i_max: s.i_max,
            };
            let bytes = tiff::encode_tiff(w, h, &px, TiffCompression::Deflate, &facts).unwrap();
            tiff_ms.push(t.elapsed().as_secs_f64() * 1e3);
            std::hint::black_box(bytes);
            let t = Instant::now();
            let f: Vec<f32> = px.iter().map(|&p| p as f32).collect();
            let bytes = exr::encode_exr(w, h, &f, &[]).unwrap();
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

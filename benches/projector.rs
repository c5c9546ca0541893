//! Criterion benchmarks of the projector and the noise stage on fixed 1440² scenes (see
//! `benches/common/scenes.rs`): run `n2-r07` (noise level 0.45) of `scenarios/biplanar.toml`,
//! detector `det1`.
//!
//! Groups and functions (criterion ids `group/function`):
//! - `calibration`, `model`, `sphere`: one image each.
//!   - `binary_1t`: `trace::render_binary` (the default projector) in a 1-thread rayon pool.
//!   - `traced_1t`: `trace::render_binary_traced` (the BVH ray tracer), 1 thread.
//!   - `binary_noise`: a finished noisy image, `binary::sharp_noisy_image` (the projection and the
//!     noise field at once, then overlaid), with the default rayon pool (all cores), as the
//!     protocol makes each image.
//! - `model` also has `mesh_binary_1t` and `mesh_traced_1t`: the femoral component's mesh alone,
//!   without its 6 beads, which is the scene the Embree peer casts (`bench/peers.py`).
//! - `path`: the femoral component's mesh alone (no beads), 1 thread: `mesh_binary_1t`
//!   (`trace::render_binary`) against `mesh_path_1t` (`trace::path_lengths`: scan conversion of
//!   front and back faces with depth, attenuation mode's per-object step).
//! - `noise`: `add_noise` alone on a clean 1440² model image (level 0.45, I_max 65535), `1t` in a
//!   1-thread pool and `all` with the default pool.
//!
//! Run with `cargo bench --bench projector` (or `bench/run.sh` for the whole suite with peers).
//! Medians are in `target/criterion/<group>/<function>/new/estimates.json`.

#[path = "common/scenes.rs"]
mod scenes;

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, SamplingMode, criterion_group, criterion_main};
use rayon::ThreadPool;
use rsasim::noise;
use rsasim::trace::{Object, path_lengths, render_binary, render_binary_traced};
use scenes::{Scenes, covered_fraction};

fn one_thread() -> ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a 1-thread rayon pool")
}

fn image_group(c: &mut Criterion, s: &Scenes, pool: &ThreadPool, name: &str, objects: &[Object]) {
    let image = render_binary(&s.frame, s.source, objects, s.i_max);
    println!(
        "{name}: 1440² image, {:.2} % of the pixels covered",
        100.0 * covered_fraction(&image)
    );
    let key = s.noise_key(if name == "calibration" {
        "calibration"
    } else {
        "model"
    });
    let mut g = c.benchmark_group(name);
    // Every sample runs the same number of iterations (the images take 0.1–500 ms each).
    g.sampling_mode(SamplingMode::Flat);
    g.bench_function("binary_1t", |b| {
        b.iter(|| pool.install(|| render_binary(&s.frame, black_box(s.source), objects, s.i_max)))
    });
    g.bench_function("traced_1t", |b| {
        b.iter(|| {
            pool.install(|| render_binary_traced(&s.frame, black_box(s.source), objects, s.i_max))
        })
    });
    g.bench_function("binary_noise", |b| {
        b.iter(|| {
            rsasim::binary::sharp_noisy_image(
                &s.frame,
                black_box(s.source),
                objects,
                s.noise_level,
                s.i_max,
                &key,
            )
        })
    });
    if name == "model" {
        let mesh = s.femur_mesh();
        g.bench_function("mesh_binary_1t", |b| {
            b.iter(|| pool.install(|| render_binary(&s.frame, black_box(s.source), &mesh, s.i_max)))
        });
        g.bench_function("mesh_traced_1t", |b| {
            b.iter(|| {
                pool.install(|| render_binary_traced(&s.frame, black_box(s.source), &mesh, s.i_max))
            })
        });
    }
    g.finish();
}

fn projector(c: &mut Criterion) {
    let s = Scenes::load();
    let pool = one_thread();
    println!(
        "scenes: run n2-r07 det1, source {:?} mm; femoral component {} triangles; sphere r = {:.2} mm, {} triangles",
        s.source,
        s.femur.mesh.triangles.len(),
        s.sphere_radius_mm,
        s.sphere.mesh.triangles.len()
    );
    image_group(c, &s, &pool, "calibration", &s.calibration());
    image_group(c, &s, &pool, "model", &s.model());
    image_group(c, &s, &pool, "sphere", &s.sphere());

    let femur = [s.femur.object()];
    let mut g = c.benchmark_group("path");
    g.sampling_mode(SamplingMode::Flat);
    g.bench_function("mesh_binary_1t", |b| {
        b.iter(|| pool.install(|| render_binary(&s.frame, black_box(s.source), &femur, s.i_max)))
    });
    g.bench_function("mesh_path_1t", |b| {
        b.iter(|| pool.install(|| path_lengths(&s.frame, black_box(s.source), &femur[0])))
    });
    g.finish();

    let clean = render_binary(&s.frame, s.source, &s.model(), s.i_max);
    let key = s.noise_key("model");
    let mut g = c.benchmark_group("noise");
    for (id, threads) in [("1t", Some(&pool)), ("all", None)] {
        g.bench_function(id, |b| {
            b.iter_batched_ref(
                || clean.clone(),
                |px| match threads {
                    Some(p) => {
                        p.install(|| noise::add_noise(px, s.width(), s.noise_level, s.i_max, &key))
                    }
                    None => noise::add_noise(px, s.width(), s.noise_level, s.i_max, &key),
                },
                criterion::BatchSize::LargeInput,
            )
        });
    }
    g.finish();
}

criterion_group! {
    name = benches;
    // Modest sampling so that the suite takes a few minutes on 2 cores.
    config = Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(4));
    targets = projector
}
criterion_main!(benches);

//! Attenuation mode against its peers (`bench/attenuation.sh`): times `attenuation::render` for
//! one image and exports what `bench/peers_attenuation.py` needs to run gVirtualXray and Embree on the same
//! scene.
//!
//! ```sh
//! cargo run --release --example attenuation_bench -- DIR [REPEATS]
//! ```
//!
//! Scenes (run 0, detector `det1`, exposure `model`; `ATTENUATION_BENCH_ONLY=a,b` picks some):
//! - `mono`: `bench/attenuation/mono.toml`, the femoral component alone (CoCr F75), 60 keV;
//! - `poly`: `bench/attenuation/poly.toml`, the same with the 80 kVp / 2.5 mm Al spectrum;
//! - `realistic_mono`: `bench/attenuation/realistic_mono.toml`, issue 11's speed scene (femoral
//!   component + cortical and cancellous femur + soft tissue + 6 tantalum beads, nested) at
//!   biplanar_realistic's run-0 geometry, 60 keV;
//! - `realistic_poly`: `bench/attenuation/realistic_poly.toml`, the same with biplanar_realistic's
//!   85 kVp spectrum in 40 bins;
//! - `realistic`: `scenarios/biplanar_realistic.toml` itself (its energy-integrating CsI
//!   detector and its exposure; timing only, not exported);
//! - `realistic_unsharp`: `bench/attenuation/realistic_unsharp.toml`, issue 12's speed scene:
//!   `realistic_mono` with 2×2 rays per pixel, a 1.2 mm focal spot of 3×3 sub-sources and a
//!   detector PSF (timing only, not exported).
//!
//! DIR receives `attenuation.json` (timings; per exported scene the source, the detector frame as
//! in `examples/bench_scene.rs`, the energies, photons and detector efficiency per bin, the
//! material names, densities and mass fractions, μ per material and bin, and `parts_exported`:
//! per part its kind, material, parent part and parent material (the part it displaces), its
//! files and the chord error of its tessellation) and per exported scene
//! `NAME.partK.stl` / `NAME.partK.tris.f32` (part K's closed surface in world coordinates, mm:
//! meshes as they are, the elliptic cylinder with `CYLINDER_SECTORS` sectors, the beads as
//! geodesic spheres of level `SPHERE_LEVEL`), `NAME.lengths.f32` (the net path length per
//! material in the beam, as the EXR layers hold it, mm, f32 little-endian, one row-major layer
//! per entry of `lengths_materials`), `NAME.image.u16` and `NAME.open.u16` (the detector image
//! with and without the parts) and `NAME.spectrum.tsv` (energy_kev, photons per bin).
//!
//! Timings: one warm-up, then the median of REPEATS (default 5) calls of `attenuation::render`
//! on all of rayon's threads; the BVHs and the parts are built outside the timing. Each scene is
//! timed as it is written (`render_ms`; the scenes compared with gVXR write the expected image,
//! `quantum_noise = false`, as gVXR's image without noise) and at 1000 photons per pixel with
//! quantum noise (`render_1000_photons_ms`, as gVXR's image with Poisson noise).

#[path = "common/export.rs"]
mod export;

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use export::{
    CYLINDER_SECTORS, SPHERE_LEVEL, Tessellation, arr, cuboid_tessellation, detector_json,
    elliptic_cylinder_tessellation, sphere_tessellation, write, write_triangles,
};
use rsasim::attenuation::{self, Part};
use rsasim::geometry::DVec3;
use rsasim::noise::NoiseKey;
use rsasim::phantom::TriMesh;
use rsasim::sampling::Sampling;
use rsasim::simulate::{self, Allowances, Plan};
use rsasim::trace::{MeshBvh, Object};
use serde_json::{Value, json};

fn median_ms(mut samples: Vec<f64>) -> f64 {
    samples.sort_by(f64::total_cmp);
    let n = samples.len();
    if n % 2 == 1 {
        samples[n / 2]
    } else {
        0.5 * (samples[n / 2 - 1] + samples[n / 2])
    }
}

fn plan(root: &Path, rel: &str) -> Plan {
    let allow = Allowances {
        dirs: vec![root.join("scenarios/models")],
        large: true,
    };
    match simulate::prepare_with(&root.join(rel), &allow) {
        Ok(p) => p,
        Err(diags) => {
            for d in diags {
                eprintln!("{rel}: {d:?}");
            }
            std::process::exit(2);
        }
    }
}

fn u16_bytes(image: &[u16]) -> Vec<u8> {
    image.iter().flat_map(|p| p.to_le_bytes()).collect()
}

/// Times (and for `export`, writes) one scene; returns its JSON record.
fn scene(root: &Path, dir: &Path, name: &str, rel: &str, repeats: usize, export: bool) -> Value {
    let plan = plan(root, rel);
    let s = &plan.loaded.scenario;
    let setup = plan.setup.as_ref().expect("an attenuation-mode scenario");
    let bvhs: Vec<Option<Arc<MeshBvh>>> = plan
        .models
        .iter()
        .map(|m| m.mesh.as_ref().map(|mesh| Arc::new(MeshBvh::new(mesh))))
        .collect();
    let run = &plan.runs[0];
    let exposure = run
        .exposures
        .iter()
        .find(|e| e.id == "model")
        .expect("an exposure `model`");
    let parts: Vec<Part> = attenuation::parts(s, setup, &plan.models, &bvhs, run, exposure)
        .unwrap_or_else(|(_, e)| panic!("{rel}: {e}"));
    let det = &run.detectors[0];
    let frame = det.frame();
    let source = run.source_of(det);
    let key = NoiseKey::derive(
        s.seed,
        run.noise_level_index,
        run.run_index,
        &exposure.id,
        &det.id,
    );
    let factor = run.exposure_factor.unwrap_or(1.0);
    // The scene's own sampling and detector unsharpness (none unless its [imaging] asks).
    let sampling = Sampling::from_imaging(&s.imaging);
    let unsharp = setup.unsharpness(&det.id);
    let electronic_key = NoiseKey::derive_electronic(
        s.seed,
        run.noise_level_index,
        run.run_index,
        &exposure.id,
        &det.id,
    );
    // The noisy rows draw quantum noise even where the scene writes the expected image
    // (`quantum_noise = false`, the rows without noise, like gVXR's image without noise).
    let noisy_setup = attenuation::Setup {
        quantum_noise: true,
        ..setup.clone()
    };
    let render_with = |setup: &attenuation::Setup, parts: &[Part], keep: bool, factor: f64| {
        let exposed = attenuation::Exposure {
            setup,
            parts,
            frame: &frame,
            source_mm: source,
        };
        attenuation::render(
            &exposed,
            factor,
            det.i_max(),
            &key,
            keep,
            attenuation::Formation {
                sampling: &sampling,
                unsharp: &unsharp,
                electronic_key: &electronic_key,
                pulse: &[],
            },
        )
        .unwrap_or_else(|e| panic!("{rel}: {e}"))
    };
    let render = |parts: &[Part], keep: bool, factor: f64| render_with(setup, parts, keep, factor);
    let time = |setup: &attenuation::Setup, factor: f64| {
        let first = render_with(setup, &parts, false, factor);
        let mut times = Vec::with_capacity(repeats);
        for _ in 0..repeats {
            let t = Instant::now();
            let image = render_with(setup, &parts, false, factor);
            times.push(1e3 * t.elapsed().as_secs_f64());
            assert_eq!(image.pixels, first.pixels, "render is deterministic");
        }
        times
    };
    let first = render(&parts, export, factor);
    let times = time(setup, factor);
    let ms = median_ms(times.clone());
    // The peer's noisy image has 1000 photons per pixel (gVXR `setMonoChromatic(…, 1000)` or
    // bins summing to 1000, `setmAs(1)`): the same count here, with quantum noise, for the rows
    // "with noise". The scenes that compare transmissions write the expected image
    // (`quantum_noise = false`) at 1e12 photons, which only sets the scale.
    let reference_photons: f64 = setup
        .beam(&frame, source, 1.0)
        .photons_per_pixel
        .iter()
        .sum();
    let noisy_factor = 1000.0 / reference_photons;
    let noisy_times = if reference_photons > 1e6 || !setup.quantum_noise {
        time(&noisy_setup, noisy_factor)
    } else {
        times.clone()
    };
    let noisy_ms = median_ms(noisy_times.clone());
    println!(
        "rsasim {name}: attenuation::render {ms:.1} ms ({}), at 1000 photons per pixel with quantum noise {noisy_ms:.1} ms (medians of {repeats}; {} threads), {} parts, {} bins",
        if setup.quantum_noise {
            "with quantum noise"
        } else {
            "expected image, no quantum noise"
        },
        rayon::current_num_threads(),
        parts.len(),
        setup.energies_kev.len()
    );
    let mut record = json!({
        "scenario": rel,
        "run": run.id,
        "detector_id": det.id,
        "exposure": exposure.id,
        "parts": parts.len(),
        "bins": setup.energies_kev.len(),
        "render_ms": ms,
        "render_runs_ms": times,
        "quantum_noise": setup.quantum_noise,
        "render_1000_photons_ms": noisy_ms,
        "render_1000_photons_runs_ms": noisy_times,
        "threads": rayon::current_num_threads(),
    });
    if !export {
        return record;
    }
    // Every part as a closed world-space surface (meshes as they are, the analytic solids
    // tessellated), with its material and the part it displaces.
    let mut part_records = Vec::with_capacity(parts.len());
    for (k, part) in parts.iter().enumerate() {
        let (kind, t) = match &part.object {
            Object::Mesh { pose, .. } => {
                let mesh = plan.models[part.phantom]
                    .mesh
                    .as_deref()
                    .expect("a mesh part's phantom has its mesh");
                let world = TriMesh {
                    vertices: mesh
                        .vertices
                        .iter()
                        .map(|v| {
                            let w = pose.to_world(DVec3::from_array(v.map(f64::from)));
                            [w.x as f32, w.y as f32, w.z as f32]
                        })
                        .collect(),
                    triangles: mesh.triangles.clone(),
                };
                let t = Tessellation {
                    mesh: world,
                    chord_error_mm: 0.0,
                };
                ("mesh", t)
            }
            Object::Sphere {
                centre_mm,
                radius_mm,
            } => (
                "sphere",
                sphere_tessellation(*centre_mm, *radius_mm, SPHERE_LEVEL),
            ),
            Object::EllipticCylinder {
                pose,
                radii_mm,
                half_length_mm,
            } => (
                "elliptic_cylinder",
                elliptic_cylinder_tessellation(pose, *radii_mm, *half_length_mm, CYLINDER_SECTORS),
            ),
            Object::Cuboid { pose, half_size_mm } => {
                ("cuboid", cuboid_tessellation(pose, *half_size_mm))
            }
        };
        if let Err(e) = t.mesh.check_closed() {
            panic!("{rel}: part {} is not a closed surface: {e}", part.label);
        }
        assert!(
            t.mesh.signed_volume_mm3() > 0.0,
            "{rel}: part {} is wound inwards",
            part.label
        );
        let file = format!("{name}.part{k}");
        write_triangles(dir, &file, &t.mesh);
        part_records.push(json!({
            "label": part.label,
            "kind": kind,
            "material": part.material,
            "parent": part.parent,
            "parent_material": part.parent.map(|p| parts[p].material),
            "stl": format!("{file}.stl"),
            "tris_f32": format!("{file}.tris.f32"),
            "triangles": t.mesh.triangles.len(),
            "chord_error_mm": t.chord_error_mm,
        }));
    }
    // The net path length per material (what the EXR layers hold), one f32 layer per material
    // in the beam.
    let lengths = first.lengths_mm.as_ref().expect("kept lengths");
    let in_beam: Vec<usize> = (0..lengths.len())
        .filter(|&m| !lengths[m].is_empty())
        .collect();
    let l: Vec<u8> = in_beam
        .iter()
        .flat_map(|&m| lengths[m].iter())
        .flat_map(|&x| (x as f32).to_le_bytes())
        .collect();
    write(dir.join(format!("{name}.lengths.f32")), &l);
    write(
        dir.join(format!("{name}.image.u16")),
        &u16_bytes(&first.pixels),
    );
    let open = render(&[], false, factor);
    write(
        dir.join(format!("{name}.open.u16")),
        &u16_bytes(&open.pixels),
    );
    let total: f64 = setup.spectrum_photons.iter().sum();
    let tsv: String = setup
        .energies_kev
        .iter()
        .zip(&setup.spectrum_photons)
        .map(|(e, n)| format!("{e:.6}\t{:.9e}\n", n / total))
        .collect();
    write(
        dir.join(format!("{name}.spectrum.tsv")),
        format!(
            "# energy_kev\tphotons (fraction of the total), rsasim {}\n{tsv}",
            env!("CARGO_PKG_VERSION")
        )
        .as_bytes(),
    );
    let materials: Vec<Value> = setup
        .materials
        .iter()
        .zip(&setup.names)
        .map(|(mat, n)| {
            json!({
                "name": n,
                "density_g_cm3": mat.density_g_cm3,
                "mass_fractions_z": mat.mass_fractions,
            })
        })
        .collect();
    let extra = json!({
        "source_mm": arr(source),
        "detector": detector_json(&frame),
        "i_max": det.i_max(),
        "parts_exported": part_records,
        "lengths_f32": format!("{name}.lengths.f32"),
        "lengths_materials": in_beam,
        "image_u16": format!("{name}.image.u16"),
        "open_u16": format!("{name}.open.u16"),
        "spectrum_tsv": format!("{name}.spectrum.tsv"),
        "materials": materials,
        "energies_kev": setup.energies_kev,
        "spectrum_photons": setup.spectrum_photons,
        "efficiency": setup.efficiency,
        "mu_per_mm": setup.mu_per_mm,
        "response": format!("{:?}", setup.response),
        "saturated": first.saturated,
    });
    if let (Value::Object(r), Value::Object(e)) = (&mut record, extra) {
        r.extend(e);
    }
    record
}

fn main() {
    let mut args = std::env::args().skip(1);
    let dir = PathBuf::from(
        args.next()
            .expect("usage: cargo run --release --example attenuation_bench -- DIR [REPEATS]"),
    );
    let repeats: usize = args
        .next()
        .map_or(5, |r| r.parse().expect("REPEATS: a whole number"));
    std::fs::create_dir_all(&dir).expect("create the output folder");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    // `ATTENUATION_BENCH_ONLY=mono` (a comma-separated list) times only those scenes, e.g. to
    // profile one of them.
    let only = std::env::var("ATTENUATION_BENCH_ONLY").ok();
    let wanted = |name: &str| {
        only.as_deref()
            .is_none_or(|o| o.split(',').any(|n| n == name))
    };
    let mut scenes = serde_json::Map::new();
    for (name, rel, export) in [
        ("mono", "bench/attenuation/mono.toml", true),
        ("poly", "bench/attenuation/poly.toml", true),
        (
            "realistic_mono",
            "bench/attenuation/realistic_mono.toml",
            true,
        ),
        (
            "realistic_poly",
            "bench/attenuation/realistic_poly.toml",
            true,
        ),
        ("realistic", "scenarios/biplanar_realistic.toml", false),
        (
            "realistic_unsharp",
            "bench/attenuation/realistic_unsharp.toml",
            false,
        ),
    ] {
        if wanted(name) {
            scenes.insert(name.into(), scene(root, &dir, name, rel, repeats, export));
        }
    }
    let out = json!({
        "format": "rsasim-attenuation-bench/1",
        "rsasim_version": env!("CARGO_PKG_VERSION"),
        "repeats": repeats,
        "scenes": scenes,
    });
    write(
        dir.join("attenuation.json"),
        serde_json::to_string_pretty(&out).expect("JSON").as_bytes(),
    );
    println!("wrote {}", dir.display());
}

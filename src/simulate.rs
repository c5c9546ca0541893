//! The whole simulation of a scenario: prepare (load, build phantoms, expand, check), then for
//! every run, exposure and detector trace → noise → encode → write, plus the truth, the phantom
//! files and the manifest. This is the only module that sees every stage; each stage stays
//! ignorant of the ones after it.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use rayon::prelude::*;

use crate::diagnostic::Diagnostic;
use crate::expand::{self, Run};
use crate::geometry::DetectorFrame;
use crate::noise::{self, NoiseKey};
use crate::output::atomic::write_staged;
use crate::output::commit::{FolderKind, OutputTarget};
use crate::output::exr::{ExrAttr, encode_exr_with};
use crate::output::tiff::encode_tiff;
use crate::output::{self, FileRef, ImageTruth, Manifest, ManifestFile, ProjectedMarker, Truth};
use crate::phantom::{self, PhantomModel};
use crate::scenario::{self, ImageFormat, LoadedScenario, Scenario};
use crate::trace::{self, MeshBvh, Object};
use glam::DVec3;

/// A scenario checked and expanded, ready to run: nothing has been written yet.
pub struct Plan {
    /// The scenario as loaded.
    pub loaded: LoadedScenario,
    /// Every phantom in its local frame.
    pub models: Vec<PhantomModel>,
    /// Every run of the protocol.
    pub runs: Vec<Run>,
    /// Warnings from every stage (errors stop preparation).
    pub warnings: Vec<Diagnostic>,
}

impl Plan {
    /// Number of images (per format) the plan writes.
    pub fn image_count(&self) -> usize {
        let s = &self.loaded.scenario;
        self.runs.len() * s.exposures.len() * s.detectors.len()
    }
}

/// Loads, validates, builds phantoms, expands and checks the geometry of every run.
pub fn prepare(path: &Path) -> Result<Plan, Vec<Diagnostic>> {
    let loaded = scenario::load(path)?;
    prepare_loaded(loaded)
}

/// [`prepare`] for a scenario already loaded (e.g. from text).
pub fn prepare_loaded(loaded: LoadedScenario) -> Result<Plan, Vec<Diagnostic>> {
    let models = phantom::build(&loaded)?;
    let runs = expand::expand(&loaded.scenario, &models);
    let findings = expand::check_geometry(&loaded, &models, &runs);
    let (errors, warnings): (Vec<_>, Vec<_>) = findings.into_iter().partition(Diagnostic::is_error);
    if !errors.is_empty() {
        return Err(errors);
    }
    let mut all_warnings = loaded.warnings.clone();
    all_warnings.extend(warnings);
    Ok(Plan {
        loaded,
        models,
        runs,
        warnings: all_warnings,
    })
}

/// What a finished simulation wrote.
pub struct Summary {
    /// The output folder.
    pub out_dir: PathBuf,
    /// Number of image files written (all formats).
    pub image_files: usize,
    /// Number of runs.
    pub runs: usize,
    /// What the commit wants the user to know (e.g. an old output it could not remove).
    pub notes: Vec<String>,
}

/// Claims `out_dir` for the output of `plan`, before any simulation work: refuses (as errors for
/// the user) an existing folder without `force`, and with `force` anything but an earlier rsasim
/// output, the current folder or its ancestors, a folder holding the scenario or a file it reads,
/// a symbolic link or a file; takes the one-writer lock and cleans what killed runs left
/// ([`crate::output::commit`]).
pub fn claim_output(
    plan: &Plan,
    out_dir: &Path,
    force: bool,
) -> Result<OutputTarget, Vec<Diagnostic>> {
    let mut inputs = vec![plan.loaded.path.clone()];
    inputs.extend(plan.models.iter().filter_map(|m| m.mesh_file.clone()));
    OutputTarget::claim(out_dir, FolderKind::Simulation { force, inputs }).map_err(|d| vec![*d])
}

/// Writes the whole protocol into the claimed `target`: staged beside it, swapped in only once
/// complete. `progress` is called once per finished image (exposure × detector, all formats).
pub fn simulate(
    plan: &Plan,
    target: OutputTarget,
    progress: &(dyn Fn() + Sync),
) -> std::io::Result<Summary> {
    let staged = target.stage()?;
    let root = staged.path();
    let s = &plan.loaded.scenario;
    let bvhs: Vec<Option<Arc<MeshBvh>>> = plan
        .models
        .iter()
        .map(|m| m.mesh.as_ref().map(|mesh| Arc::new(MeshBvh::new(mesh))))
        .collect();

    let mut files = write_phantoms(plan, root)?;
    let readme = output::folder_readme::folder_readme(s, &plan.runs);
    files.push(manifest_entry(
        root,
        &root.join("README.md"),
        readme.as_bytes(),
    )?);
    let per_run: Vec<Vec<ManifestFile>> = plan
        .runs
        .par_iter()
        .map(|run| write_run(s, &plan.models, &bvhs, run, root, progress))
        .collect::<std::io::Result<_>>()?;
    let image_files = per_run
        .iter()
        .flatten()
        .filter(|f| !f.path.ends_with("truth.json"))
        .count();
    files.extend(per_run.into_iter().flatten());
    files.sort_by(|a, b| a.path.cmp(&b.path));

    let manifest = Manifest {
        format: output::MANIFEST_FORMAT.into(),
        program: output::program(),
        scenario: s.name.clone(),
        scenario_sha256: plan.loaded.sha256.clone(),
        seed: s.seed,
        runs: plan.runs.len(),
        files,
    };
    write_staged(&root.join("manifest.json"), &json_bytes(&manifest))?;
    let committed = staged.commit()?;
    Ok(Summary {
        out_dir: committed.path,
        image_files,
        runs: plan.runs.len(),
        notes: committed.notes,
    })
}

/// Pretty JSON with a final newline.
fn json_bytes<T: serde::Serialize>(value: &T) -> Vec<u8> {
    let mut v = serde_json::to_vec_pretty(value).expect("records serialise");
    v.push(b'\n');
    v
}

fn manifest_entry(root: &Path, path: &Path, bytes: &[u8]) -> std::io::Result<ManifestFile> {
    let sha256 = write_staged(path, bytes)?;
    let rel = path.strip_prefix(root).expect("inside the output folder");
    Ok(ManifestFile {
        path: slash_path(rel),
        sha256,
        bytes: bytes.len() as u64,
    })
}

fn slash_path(p: &Path) -> String {
    p.components()
        .map(|c| c.as_os_str().to_string_lossy())
        .collect::<Vec<_>>()
        .join("/")
}

/// `phantoms/`: bead tables (CSV, each phantom's local frame; the box's is the box frame) and
/// mesh files, plus `scenario.toml` as run, pointing at those copies.
fn write_phantoms(plan: &Plan, root: &Path) -> std::io::Result<Vec<ManifestFile>> {
    let dir = root.join("phantoms");
    std::fs::create_dir_all(&dir)?;
    let mut out = Vec::new();
    let mut resolved: Scenario = plan.loaded.scenario.clone();
    for (model, ph) in plan.models.iter().zip(resolved.phantoms.iter_mut()) {
        if !model.markers.is_empty() {
            let mut csv = String::from("id,plate,role,x_mm,y_mm,z_mm,diameter_mm\n");
            for m in &model.markers {
                let role = match m.role {
                    Some(scenario::PlateRole::Fiducial) => "fiducial",
                    Some(scenario::PlateRole::Control) => "control",
                    None => "",
                };
                let p = m.position_mm;
                csv += &format!(
                    "{},{},{role},{},{},{},{}\n",
                    m.id,
                    m.plate.as_deref().unwrap_or(""),
                    p.x,
                    p.y,
                    p.z,
                    m.diameter_mm
                );
            }
            let name = if model.mesh.is_some() {
                format!("{}-beads.csv", model.id)
            } else {
                format!("{}.csv", model.id)
            };
            out.push(manifest_entry(root, &dir.join(name), csv.as_bytes())?);
        }
        if let (Some(file), Some(mesh)) = (&model.mesh_file, ph.mesh.as_mut()) {
            let ext = file
                .extension()
                .and_then(|e| e.to_str())
                .unwrap_or("mesh")
                .to_ascii_lowercase();
            let name = format!("{}.{ext}", model.id);
            let bytes = std::fs::read(file)?;
            out.push(manifest_entry(root, &dir.join(&name), &bytes)?);
            mesh.unit_mm = Some(
                mesh.unit_mm
                    .unwrap_or_else(|| phantom::mesh_io::default_unit_mm(file)),
            );
            mesh.file = format!("phantoms/{name}");
        }
    }
    let text = format!(
        "# The scenario as run by {} (defaults resolved, mesh paths pointing at phantoms/).\n# Source file SHA-256: {}\n\n{}",
        output::program(),
        plan.loaded.sha256,
        toml::to_string_pretty(&resolved).expect("scenario serialises")
    );
    out.push(manifest_entry(
        root,
        &root.join("scenario.toml"),
        text.as_bytes(),
    )?);
    Ok(out)
}

/// One noisy binary-mode image: the clean projection ([`trace::render_binary`]) and the noise
/// field ([`noise::noise_field`]) computed at the same time on the rayon pool, then overlaid.
/// Byte for byte the image of `render_binary` followed by [`noise::add_noise`], in less wall time
/// when cores are free (the projection is single-threaded, the noise row-parallel).
pub fn noisy_image(
    frame: &DetectorFrame,
    source_mm: DVec3,
    objects: &[Object],
    noise_level: f64,
    i_max: u16,
    key: &NoiseKey,
) -> Vec<u16> {
    let [w, h] = frame.pixels.map(|n| n as usize);
    let (clean, mut field) = rayon::join(
        || trace::render_binary(frame, source_mm, objects, i_max),
        || noise::noise_field(w, h, noise_level, i_max, key),
    );
    noise::overlay(&clean, &mut field);
    field
}

/// One run folder: every image in every format, and `truth.json`.
fn write_run(
    s: &Scenario,
    models: &[PhantomModel],
    bvhs: &[Option<Arc<MeshBvh>>],
    run: &Run,
    root: &Path,
    progress: &(dyn Fn() + Sync),
) -> std::io::Result<Vec<ManifestFile>> {
    let dir = root.join("runs").join(&run.id);
    std::fs::create_dir_all(&dir)?;
    let mut files = Vec::new();
    let mut images = Vec::new();
    for exposure in &run.exposures {
        let in_beam: Vec<usize> = exposure
            .phantoms
            .iter()
            .map(|id| {
                models
                    .iter()
                    .position(|m| &m.id == id)
                    .expect("validated phantom id")
            })
            .collect();
        let mut objects = Vec::new();
        for &pi in &in_beam {
            let state = &run.phantoms[pi];
            objects.extend(state.markers.iter().map(|m| Object::Sphere {
                centre_mm: m.position_mm,
                radius_mm: m.diameter_mm / 2.0,
            }));
            if let Some(bvh) = &bvhs[pi] {
                objects.push(Object::Mesh {
                    bvh,
                    pose: state.pose(),
                });
            }
        }
        for det in &run.detectors {
            let frame = det.frame();
            let source = run.source_of(det);
            let key = NoiseKey::derive(
                s.seed,
                run.noise_level_index,
                run.run_index,
                &exposure.id,
                &det.id,
            );
            let pixels = noisy_image(&frame, source, &objects, run.noise_level, det.i_max(), &key);

            let stem = format!("{}-{}", exposure.id, det.id);
            let mut refs = Vec::new();
            for format in &s.output.formats {
                let name = format!("{stem}.{}", format.extension());
                let bytes = encode_image(s, run, &exposure.id, det, &pixels, *format);
                let entry = manifest_entry(root, &dir.join(&name), &bytes)?;
                refs.push(FileRef {
                    path: name,
                    sha256: entry.sha256.clone(),
                });
                files.push(entry);
            }
            let markers = in_beam
                .iter()
                .flat_map(|&pi| {
                    let ph = &run.phantoms[pi];
                    ph.markers.iter().map(move |m| (ph, m))
                })
                .map(|(ph, m)| {
                    let uv = frame
                        .project(source, m.position_mm)
                        .expect("checked: beads lie between source and detector");
                    ProjectedMarker {
                        phantom: ph.id.clone(),
                        id: m.id.clone(),
                        pixel: [uv.x, uv.y],
                        inside: frame.contains_pixel(uv),
                    }
                })
                .collect();
            images.push(ImageTruth {
                exposure: exposure.id.clone(),
                detector: det.id.clone(),
                files: refs,
                markers,
            });
            progress();
        }
    }
    let truth = Truth {
        format: output::TRUTH_FORMAT.into(),
        program: output::program(),
        scenario: s.name.clone(),
        run: run.clone(),
        images,
    };
    files.push(manifest_entry(
        root,
        &dir.join("truth.json"),
        &json_bytes(&truth),
    )?);
    Ok(files)
}

fn encode_image(
    s: &Scenario,
    run: &Run,
    exposure: &str,
    det: &expand::DetectorState,
    pixels: &[u16],
    format: ImageFormat,
) -> Vec<u8> {
    let [w, h] = det.pixels;
    match format {
        ImageFormat::Tiff => {
            let description = format!(
                "rsasim scenario={} run={} noise_level={} exposure={exposure} detector={} pixel_pitch_mm={}x{} bpp={}",
                s.name,
                run.id,
                run.noise_level,
                det.id,
                det.pixel_pitch_mm[0],
                det.pixel_pitch_mm[1],
                det.bpp
            );
            encode_tiff(
                w,
                h,
                pixels,
                s.output.tiff_compression,
                &description,
                &output::program(),
            )
            .expect("in-memory TIFF encoding of a valid image")
        }
        ImageFormat::Exr => {
            let values: Vec<f32> = pixels.iter().map(|&p| p as f32).collect();
            let attrs = [
                ("rsasim_scenario", ExrAttr::Text(s.name.clone())),
                ("rsasim_run", ExrAttr::Text(run.id.clone())),
                ("rsasim_noise_level", ExrAttr::F64(run.noise_level)),
                ("rsasim_exposure", ExrAttr::Text(exposure.to_string())),
                ("rsasim_detector", ExrAttr::Text(det.id.clone())),
                (
                    "rsasim_pixel_pitch_x_mm",
                    ExrAttr::F64(det.pixel_pitch_mm[0]),
                ),
                (
                    "rsasim_pixel_pitch_y_mm",
                    ExrAttr::F64(det.pixel_pitch_mm[1]),
                ),
                ("rsasim_bpp", ExrAttr::I32(det.bpp as i32)),
                ("rsasim_program", ExrAttr::Text(output::program())),
            ];
            encode_exr_with(w, h, &values, &attrs, s.output.exr_compression)
                .expect("in-memory EXR encoding of a valid image")
        }
    }
}

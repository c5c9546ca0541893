//! The whole simulation of a scenario: prepare (load, build phantoms, expand, check), then for
//! every run, exposure and detector trace → noise → encode → write, plus the truth, the phantom
//! files and the manifest. This is the only module that sees every stage; each stage stays
//! ignorant of the ones after it.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use rayon::prelude::*;

use crate::attenuation::{self, Setup};
use crate::cost::{self, Cost};
use crate::diagnostic::{Diagnostic, KeyPath};
use crate::expand::{self, Run};
use crate::noise::NoiseKey;
use crate::output::atomic::write_staged;
use crate::output::commit::{FolderKind, OutputTarget};
use crate::output::dicom::describe::{ImageRef, NominalView, describe};
use crate::output::dicom::encode_dx;
use crate::output::exr::{ExrAttr, encode_exr_channels, encode_exr_with};
use crate::output::tiff::{TiffFacts, encode_tiff};
use crate::output::{
    self, FileRef, ImageTruth, ImagesBinding, Layout, Manifest, ManifestFile, ProjectedMarker,
    ShardRecord, Truth,
};
use crate::phantom::{self, PhantomModel};
use crate::sampling::Sampling;
use crate::scenario::hex;
use crate::scenario::{self, ImageFile, ImageFormat, LoadedScenario, Scenario};
use crate::shard::ShardSpec;
use crate::trace::{self, MeshBvh, Object};
use sha2::{Digest, Sha256};

/// A scenario checked run by run, with its cost: what `validate` and `expand` need. Its runs
/// are not kept (see [`expand::runs`] to stream them).
pub struct Checked {
    /// The scenario as loaded.
    pub loaded: LoadedScenario,
    /// Every phantom in its local frame.
    pub models: Vec<PhantomModel>,
    /// Attenuation mode: materials, spectrum and detector resolved.
    pub setup: Option<Setup>,
    /// What the simulation will write and use.
    pub cost: Cost,
    /// Warnings from every stage (errors stop preparation).
    pub warnings: Vec<Diagnostic>,
    /// Each model's mesh in a BVH (`None` for a model without a mesh), built once.
    pub bvhs: Vec<Option<Arc<MeshBvh>>>,
}

/// A scenario checked and expanded, ready to run: nothing has been written yet.
pub struct Plan {
    /// The scenario as loaded.
    pub loaded: LoadedScenario,
    /// Every phantom in its local frame.
    pub models: Vec<PhantomModel>,
    /// Each model's mesh in a BVH (`None` for a model without a mesh), built once.
    pub bvhs: Vec<Option<Arc<MeshBvh>>>,
    /// Attenuation mode: materials, spectrum and detector resolved.
    pub setup: Option<Setup>,
    /// Also write an 8-bit PNG preview beside every image (`--preview png`).
    pub previews: bool,
    /// Every run of the protocol.
    pub runs: Vec<Run>,
    /// Write only the runs of this shard (`--shard K/N`; [`crate::shard`]); `None`: every run.
    pub shard: Option<ShardSpec>,
    /// Warnings from every stage (errors stop preparation).
    pub warnings: Vec<Diagnostic>,
    /// What the simulation will write and use.
    pub cost: Cost,
    /// The nominal set-up's distances and directions per exposure and detector, for the DICOM
    /// files (empty when `formats` does not list `"dicom"`).
    pub dicom_views: Vec<NominalView>,
}

impl Plan {
    /// Number of images (per format) the plan writes.
    pub fn image_count(&self) -> usize {
        let s = &self.loaded.scenario;
        self.written_runs().len() * s.exposures.len() * s.detectors.len()
    }

    /// The runs the plan writes: every run, or those of its shard.
    pub fn written_runs(&self) -> Vec<&Run> {
        match self.shard {
            None => self.runs.iter().collect(),
            Some(spec) => spec
                .runs(self.runs.len())
                .into_iter()
                .map(|p| &self.runs[p])
                .collect(),
        }
    }

    /// The manifest record of the plan's shard.
    fn shard_record(&self) -> Option<ShardRecord> {
        self.shard.map(|spec| ShardRecord {
            index: spec.index,
            count: spec.count,
            runs: self.written_runs().iter().map(|r| r.id.clone()).collect(),
            protocol_runs: self.runs.iter().map(|r| r.id.clone()).collect(),
        })
    }
}

/// What the command line grants a scenario beyond its defaults.
#[derive(Debug, Clone, Default)]
pub struct Allowances {
    /// Folders besides the scenario file's own that its meshes (and their buffers) may be read
    /// from (`--allow-dir`).
    pub dirs: Vec<PathBuf>,
    /// Lift the caps on runs, pixels, bytes and memory (`--allow-large`).
    pub large: bool,
}

/// Loads, validates, builds phantoms, checks the cost against the caps and the geometry of every
/// run, one run at a time; `allow` widens what may be read and lifts the caps.
pub fn check(path: &Path, allow: &Allowances) -> Result<Checked, Vec<Diagnostic>> {
    let mut loaded = scenario::load(path)?;
    loaded.allowed_dirs = allow.dirs.clone();
    check_loaded(loaded, allow.large)
}

/// [`check`] for a scenario already loaded (e.g. from text).
pub fn check_loaded(loaded: LoadedScenario, allow_large: bool) -> Result<Checked, Vec<Diagnostic>> {
    let (models, mesh_warnings) = phantom::build_with_warnings(&loaded)?;
    let setup = if loaded.scenario.imaging.is_attenuation() {
        Some(Setup::build(&loaded, &models)?)
    } else {
        None
    };
    let cost = Cost::estimate(&loaded.scenario, &models, rayon::current_num_threads());
    let errors = cost.check(
        &loaded.scenario,
        &loaded.locator,
        allow_large,
        cost::available_memory_bytes(),
    );
    if !errors.is_empty() {
        return Err(errors);
    }
    // One BVH per mesh for every check and the simulation; the meshes are built in parallel
    // (each build is single-threaded, so its layout is deterministic).
    let bvhs: Vec<Option<Arc<MeshBvh>>> = models
        .par_iter()
        .map(|m| m.mesh.as_ref().map(|mesh| Arc::new(MeshBvh::new(mesh))))
        .collect();
    let mut findings = expand::check_geometry(&loaded, &models, &bvhs);
    if let Some(setup) = &setup {
        if !findings.iter().any(Diagnostic::is_error) {
            findings.extend(attenuation::check::check_runs(
                &loaded, &models, setup, &bvhs,
            ));
        }
    }
    let (errors, warnings): (Vec<_>, Vec<_>) = findings.into_iter().partition(Diagnostic::is_error);
    if !errors.is_empty() {
        return Err(errors);
    }
    let mut all_warnings = loaded.warnings.clone();
    all_warnings.extend(mesh_warnings);
    all_warnings.extend(warnings);
    if let Some(setup) = &setup {
        all_warnings.extend(attenuation::check::spectral_tolerance_warning(
            &loaded, setup,
        ));
    }
    Ok(Checked {
        loaded,
        models,
        setup,
        cost,
        warnings: all_warnings,
        bvhs,
    })
}

/// Loads, validates, builds phantoms, checks the cost within the default caps and the geometry
/// of every run, and expands the runs.
pub fn prepare(path: &Path) -> Result<Plan, Vec<Diagnostic>> {
    prepare_with(path, &Allowances::default())
}

/// [`prepare`] with what the command line allows (`--allow-dir`, `--allow-large`).
pub fn prepare_with(path: &Path, allow: &Allowances) -> Result<Plan, Vec<Diagnostic>> {
    check(path, allow).map(Plan::from)
}

/// [`prepare`] for a scenario already loaded (e.g. from text).
pub fn prepare_loaded(loaded: LoadedScenario) -> Result<Plan, Vec<Diagnostic>> {
    check_loaded(loaded, false).map(Plan::from)
}

impl From<Checked> for Plan {
    /// Expands every run of a checked scenario.
    fn from(c: Checked) -> Plan {
        let runs = expand::expand(&c.loaded.scenario, &c.models);
        let s = &c.loaded.scenario;
        let dicom_views = if s.output.formats.contains(&ImageFormat::Dicom) {
            output::dicom::describe::nominal_views(s, &c.models)
        } else {
            Vec::new()
        };
        Plan {
            dicom_views,
            loaded: c.loaded,
            models: c.models,
            bvhs: c.bvhs,
            setup: c.setup,
            previews: false,
            runs,
            shard: None,
            warnings: c.warnings,
            cost: c.cost,
        }
    }
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

/// Writes the whole protocol into the claimed `target` ([`claim_output`]): staged beside it,
/// swapped in only once complete. `progress` is called once per finished image (exposure ×
/// detector, all formats).
///
/// With `truth` (the blind layout, claimed the same way after [`check_truth_dir`]), `target` gets
/// only what the software under test may see (images, `phantoms/`, the nominal set-up without
/// seed or random ranges) and `truth` the truth: every `runs/<id>/truth.json`, the full scenario
/// as run with its `phantoms/`, and a manifest that binds the images folder by the SHA-256 of its
/// manifest file. The images folder is committed first, then the truth folder.
pub fn simulate(
    plan: &Plan,
    target: OutputTarget,
    truth: Option<OutputTarget>,
    progress: &(dyn Fn() + Sync),
) -> std::io::Result<Summary> {
    let images_folder_name = target.name().to_string();
    let staged = target.stage()?;
    let truth_staged = truth.map(OutputTarget::stage).transpose()?;
    let root = staged.path();
    let truth_root = truth_staged.as_ref().map(|t| t.path());
    let bvhs = &plan.bvhs;

    let sampling = Sampling::from_imaging(&plan.loaded.scenario.imaging);
    let mut files = write_phantoms(plan, root, truth_root.is_some())?;
    let layout = truth_root.map(|_| Layout::Images);
    files.push(write_readme(plan, root, layout)?);
    let runs = plan.written_runs();
    let per_run: Vec<RunFiles> = runs
        .par_iter()
        .map(|run| write_run(plan, bvhs, &sampling, run, root, truth_root, progress))
        .collect::<std::io::Result<_>>()?;
    let image_files = per_run.iter().map(|r| r.images.len()).sum();
    let mut truth_files = Vec::new();
    for r in per_run {
        files.extend(r.images);
        truth_files.extend(r.truth);
    }
    if let Some(design) = &plan.loaded.scenario.study {
        // The study's design and migration truth: truth, so in the truth folder of a blind layout.
        let study = output::study::study_truth(&plan.loaded.scenario, design);
        let study_root = truth_root.unwrap_or(root);
        truth_files.push(manifest_entry(
            study_root,
            &study_root.join(crate::output::study::STUDY_FILE),
            &json_bytes(&study),
        )?);
    }
    let mut manifest = new_manifest(plan, Vec::new());
    match truth_root {
        None => {
            files.extend(truth_files);
            manifest.files = sorted(files);
        }
        Some(truth_root) => {
            let images = Manifest {
                layout: Some(Layout::Images),
                scenario_sha256: None,
                seed: None,
                files: sorted(files),
                ..manifest.clone()
            };
            let images_bytes = images.to_bytes();
            write_staged(&root.join("manifest.json"), &images_bytes)?;
            truth_files.extend(write_phantoms(plan, truth_root, false)?);
            truth_files.push(write_readme(plan, truth_root, Some(Layout::Truth))?);
            manifest.layout = Some(Layout::Truth);
            manifest.images = Some(ImagesBinding {
                manifest_sha256: hex(&Sha256::digest(&images_bytes)),
                folder: images_folder_name,
            });
            manifest.files = sorted(truth_files);
        }
    }
    let manifest_root = truth_root.unwrap_or(root);
    write_staged(&manifest_root.join("manifest.json"), &manifest.to_bytes())?;
    let committed = staged.commit()?;
    let mut notes = committed.notes;
    if let Some(truth) = truth_staged {
        notes.extend(truth.commit()?.notes);
    }
    Ok(Summary {
        out_dir: committed.path,
        image_files,
        runs: runs.len(),
        notes,
    })
}

/// `README.md` of a folder of the given layout ([`output::folder_readme`]), written and listed.
fn write_readme(plan: &Plan, root: &Path, layout: Option<Layout>) -> std::io::Result<ManifestFile> {
    let text = output::folder_readme::folder_readme(&plan.loaded.scenario, &plan.runs, layout);
    manifest_entry(root, &root.join("README.md"), text.as_bytes())
}

/// The manifest of an ordinary output folder with `files`: program, exact build, output-format
/// version, scenario, seed.
fn new_manifest(plan: &Plan, files: Vec<ManifestFile>) -> Manifest {
    let s = &plan.loaded.scenario;
    Manifest {
        format: output::MANIFEST_FORMAT.into(),
        manifest_sha256: String::new(),
        program: output::program(),
        build: Some(crate::build_info::build()),
        output_format: output::OUTPUT_FORMAT,
        layout: None,
        scenario: s.name.clone(),
        scenario_sha256: Some(plan.loaded.sha256.clone()),
        seed: Some(s.seed),
        runs: plan.written_runs().len(),
        images: None,
        shard: plan.shard_record(),
        files,
    }
}

/// Whether `out` already holds the complete shard `plan` would write (`--shard`): its manifest
/// is the one this build would write for the same scenario, seed and shard, and every file it
/// lists verifies (size and SHA-256). A replaced pod or a requeued array task then finds its
/// work done and writes nothing.
pub fn finished_shard(plan: &Plan, out: &Path) -> bool {
    if plan.shard.is_none() || !out.join("manifest.json").is_file() {
        return false;
    }
    let v = output::verify::verify_folder(out);
    let ok = v.ok();
    let Some(existing) = v.manifest.filter(|_| ok) else {
        return false;
    };
    let previews = existing.files.iter().any(|f| f.path.ends_with(".png"));
    let expected = Manifest {
        manifest_sha256: existing.manifest_sha256.clone(),
        ..new_manifest(plan, existing.files.clone())
    };
    existing == expected && previews == plan.previews
}

fn sorted(mut files: Vec<ManifestFile>) -> Vec<ManifestFile> {
    files.sort_by(|a, b| a.path.cmp(&b.path));
    files
}

/// Checks a blind layout's truth folder against the images folder `out_dir`: they must differ
/// and neither may lie inside the other (the truth would be handed out with the images).
pub fn check_truth_dir(out_dir: &Path, truth_dir: &Path) -> Result<(), Vec<Diagnostic>> {
    let absolute = |p: &Path| {
        std::path::absolute(p)
            .map(|a| {
                a.components()
                    .filter(|c| !matches!(c, std::path::Component::CurDir))
                    .collect::<PathBuf>()
            })
            .unwrap_or_else(|_| p.to_path_buf())
    };
    // Where each path really leads, links followed as far as the path exists: a truth folder
    // reaching into the images folder through a symbolic link is caught here, before anything
    // runs, not at the final swap.
    let real = |p: &Path| {
        let mut path = absolute(p);
        // A dangling link (a truth folder not yet written, linked into the images folder) leads
        // where its target would be: followed by hand, at most 40 times, as the kernel would.
        for _ in 0..40 {
            let mut existing = path.clone();
            let mut rest = Vec::new();
            while std::fs::symlink_metadata(&existing).is_err() {
                match (existing.file_name(), existing.parent()) {
                    (Some(name), Some(parent)) => {
                        rest.push(name.to_os_string());
                        existing = parent.to_path_buf();
                    }
                    _ => break,
                }
            }
            let resolved = match existing.canonicalize() {
                Ok(c) => c,
                Err(_) => match std::fs::read_link(&existing) {
                    Ok(target) => {
                        let base = existing.parent().map(Path::to_path_buf).unwrap_or_default();
                        let mut next = absolute(&base.join(target));
                        next.extend(rest.iter().rev());
                        path = next;
                        continue;
                    }
                    Err(_) => existing,
                },
            };
            let mut real = resolved;
            real.extend(rest.iter().rev());
            return real;
        }
        path
    };
    let (out, truth) = (absolute(out_dir), absolute(truth_dir));
    let (out_real, truth_real) = (real(out_dir), real(truth_dir));
    if truth.starts_with(&out)
        || out.starts_with(&truth)
        || truth_real.starts_with(&out_real)
        || out_real.starts_with(&truth_real)
    {
        return Err(vec![
            Diagnostic::file_error(
                truth_dir,
                format!(
                    "the truth folder must lie outside the images folder {} (and not contain it)",
                    out_dir.display()
                ),
            )
            .with_help("e.g. --out blind/knee --truth-dir truth/knee: hand out only blind/knee"),
        ]);
    }
    if truth.file_name().is_none() {
        return Err(vec![Diagnostic::file_error(
            truth_dir,
            "give a folder name for the truth (e.g. --truth-dir out/knee-truth)",
        )]);
    }
    Ok(())
}

/// Warnings for a blind layout: a seed below 2^32 can be found by trying seeds until the
/// regenerated images match the blind folder's (its nominal set-up is all one needs besides).
pub fn blind_warnings(plan: &Plan) -> Vec<Diagnostic> {
    let seed = plan.loaded.scenario.seed;
    if seed >= 1 << 32 {
        return Vec::new();
    }
    vec![plan
        .loaded
        .locator
        .warning(
            KeyPath::root().key("seed"),
            format!("seed {seed} is small enough to be guessed: with the blind folder's nominal set-up, anyone can try seeds until the images match and so recover the truth"),
        )
        .with_help("for a blind study use a large random seed, e.g. the number `od -An -N7 -tu8 /dev/urandom` prints, and keep the scenario file with the truth")]
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
/// With `nominal`, the scenario is the nominal set-up of a blind images folder: no seed, no random
/// ranges, no hash of the source file ([`nominal_scenario_text`]).
fn write_phantoms(plan: &Plan, root: &Path, nominal: bool) -> std::io::Result<Vec<ManifestFile>> {
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
        // The mesh as read and checked, self-contained (phantom::mesh_io::MeshPackage).
        if let (Some(file), Some(pkg), Some(mesh)) =
            (&model.mesh_file, &model.mesh_package, ph.mesh.as_mut())
        {
            let name = format!("{}.{}", model.id, pkg.extension);
            out.push(manifest_entry(root, &dir.join(&name), &pkg.bytes)?);
            mesh.unit_mm = Some(
                mesh.unit_mm
                    .unwrap_or_else(|| phantom::mesh_io::default_unit_mm(file)),
            );
            mesh.file = format!("phantoms/{name}");
        }
    }
    // A user spectrum goes with the output, like the meshes.
    if let Some(bytes) = plan
        .setup
        .as_ref()
        .and_then(|s| s.spectrum_file_bytes.as_ref())
    {
        out.push(manifest_entry(root, &dir.join("spectrum.tsv"), bytes)?);
        resolved.imaging.spectrum_file = Some("phantoms/spectrum.tsv".into());
    }
    let text = if nominal {
        nominal_scenario_text(&resolved)
    } else {
        format!(
            "# The scenario as run by {} (defaults resolved, mesh paths pointing at phantoms/).\n# Source file SHA-256: {}\n\n{}",
            output::program(),
            plan.loaded.sha256,
            scenario_toml(&resolved)
        )
    };
    out.push(manifest_entry(
        root,
        &root.join("scenario.toml"),
        text.as_bytes(),
    )?);
    Ok(out)
}

/// A resolved scenario as TOML. In attenuation mode the binary mode's default `noise_levels`
/// are left out (the mode refuses them); binary mode's text is the records' own serialisation.
/// A study's text has no `[protocol]` (the study refuses one).
fn scenario_toml(resolved: &Scenario) -> String {
    if !resolved.imaging.is_attenuation() && resolved.study.is_none() {
        return toml::to_string_pretty(resolved).expect("scenario serialises");
    }
    let mut value = toml::Table::try_from(resolved).expect("scenario serialises");
    drop_binary_levels(resolved, &mut value);
    if resolved.study.is_some() {
        value.remove("protocol");
    }
    toml::to_string_pretty(&value).expect("TOML tables serialise")
}

/// Removes `protocol.noise_levels` from an attenuation-mode scenario table.
fn drop_binary_levels(resolved: &Scenario, value: &mut toml::Table) {
    if resolved.imaging.is_attenuation() {
        if let Some(toml::Value::Table(p)) = value.get_mut("protocol") {
            p.remove("noise_levels");
        }
    }
}

/// The nominal set-up of a blind images folder as TOML: the scenario as run without `seed`,
/// without any `randomize` table (the random ranges) and without any phantom's `motion` (a
/// sequence's kinematics), so neither the draws, the motion nor the noise can be regenerated
/// from it. `rsasim reconstruct` reads it like any `scenario.toml` (a missing seed
/// reads as 0, missing ranges as none).
pub fn nominal_scenario_text(resolved: &Scenario) -> String {
    let mut value = toml::Table::try_from(resolved).expect("scenario serialises");
    drop_binary_levels(resolved, &mut value);
    value.remove("seed");
    // A study's exams carry the prescribed migration and its failures: truth.
    value.remove("study");
    for list in ["sources", "detectors", "phantoms"] {
        if let Some(toml::Value::Array(items)) = value.get_mut(list) {
            for item in items {
                if let toml::Value::Table(t) = item {
                    t.remove("randomize");
                    // A sequence's keyframes are its kinematics: truth.
                    t.remove("motion");
                }
            }
        }
    }
    format!(
        "# The nominal set-up written by {} for the software under test (defaults resolved, mesh\n# paths pointing at phantoms/; random ranges left out). The truth is kept in a separate folder.\n\n{}",
        output::program(),
        toml::to_string_pretty(&value).expect("TOML tables serialise")
    )
}

/// The files one run wrote: its images (all formats) and its `truth.json`.
struct RunFiles {
    images: Vec<ManifestFile>,
    /// `truth.json` and the path-length layers.
    truth: Vec<ManifestFile>,
}

/// Longer side of a PNG preview, pixels.
pub const PREVIEW_MAX_SIDE_PX: u32 = 1024;

/// The objects of the phantoms `in_beam` of `run` for binary-mode tracing: every bead, every
/// mesh at its phantom's pose, every elliptic cylinder.
fn objects_of<'a>(
    run: &Run,
    in_beam: &[usize],
    models: &[phantom::PhantomModel],
    bvhs: &'a [Option<Arc<MeshBvh>>],
) -> Vec<Object<'a>> {
    let mut objects = Vec::new();
    for &pi in in_beam {
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
        for v in &models[pi].volumes {
            if let phantom::VolumeShape::EllipticCylinder {
                radii_mm,
                half_length_mm,
            } = v.shape
            {
                objects.push(Object::EllipticCylinder {
                    pose: state.pose(),
                    radii_mm,
                    half_length_mm,
                });
            }
        }
    }
    objects
}

/// One run folder: every image in every format, and `truth.json` (in `truth_root` when given).
fn write_run(
    plan: &Plan,
    bvhs: &[Option<Arc<MeshBvh>>],
    sampling: &Sampling,
    run: &Run,
    root: &Path,
    truth_root: Option<&Path>,
    progress: &(dyn Fn() + Sync),
) -> std::io::Result<RunFiles> {
    let s = &plan.loaded.scenario;
    let models = &plan.models[..];
    let dir = root.join("runs").join(&run.id);
    std::fs::create_dir_all(&dir)?;
    let mut files = Vec::new();
    let mut images = Vec::new();
    let mut truth_extra = Vec::new();
    let truth_root = truth_root.unwrap_or(root);
    let truth_dir = truth_root.join("runs").join(&run.id);
    std::fs::create_dir_all(&truth_dir)?;
    // A frame of a sequence whose phantoms move during its pulse: the poses its image is the
    // mean of (none otherwise), and where each marker's blur begins and ends.
    let pulse = expand::sequence::pulse_runs(s, models, run);
    let pulse_ends = expand::sequence::pulse_ends(s, models, run);
    for (exposure_index, exposure) in run.exposures.iter().enumerate() {
        let in_beam = exposure.phantom_indices(models);
        let objects = objects_of(run, &in_beam, models, bvhs);
        // The exposure is blurred when a phantom in its beam moves during the pulse.
        let moving = |r: &Run| in_beam.iter().any(|&pi| r.phantoms[pi] != run.phantoms[pi]);
        let pulse_all: &[Run] = &pulse;
        let pulse: &[Run] = if pulse.iter().any(moving) {
            &pulse
        } else {
            &[]
        };
        // Binary mode: the objects that stand still, and the others at each pose of the pulse.
        let (still, movers): (Vec<usize>, Vec<usize>) = in_beam
            .iter()
            .partition(|&&pi| pulse.iter().all(|r| r.phantoms[pi] == run.phantoms[pi]));
        let still_objects = objects_of(run, &still, models, bvhs);
        let pulse_objects: Vec<Vec<Object>> = pulse
            .iter()
            .map(|r| objects_of(r, &movers, models, bvhs))
            .collect();
        let parts = match &plan.setup {
            Some(setup) => Some(
                attenuation::parts(s, setup, models, bvhs, run, exposure)
                    .map_err(|(_, e)| std::io::Error::new(std::io::ErrorKind::InvalidData, e))?,
            ),
            None => None,
        };
        let pulse_parts = match &plan.setup {
            Some(setup) => pulse
                .iter()
                .map(|r| attenuation::parts(s, setup, models, bvhs, r, exposure))
                .collect::<Result<Vec<_>, _>>()
                .map_err(|(_, e)| std::io::Error::new(std::io::ErrorKind::InvalidData, e))?,
            None => Vec::new(),
        };
        for (detector_index, det) in run.detectors.iter().enumerate() {
            let frame = det.frame();
            let source = run.source_of(det);
            let noise_exposure = run.noise_exposure(&exposure.id);
            let key = NoiseKey::derive(
                s.seed,
                run.noise_level_index,
                run.run_index,
                &noise_exposure,
                &det.id,
            );
            let (pixels, visibility, saturated) = match (&plan.setup, &parts) {
                (Some(setup), Some(parts)) => {
                    let electronic_key = NoiseKey::derive_electronic(
                        s.seed,
                        run.noise_level_index,
                        run.run_index,
                        &noise_exposure,
                        &det.id,
                    );
                    let unsharp = setup.unsharpness(&det.id);
                    let exposed = attenuation::Exposure {
                        setup,
                        parts,
                        frame: &frame,
                        source_mm: source,
                    };
                    let image = attenuation::render(
                        &exposed,
                        run.exposure_factor.unwrap_or(1.0),
                        det.i_max(),
                        &key,
                        s.imaging.path_length_layers,
                        attenuation::Formation {
                            sampling,
                            unsharp: &unsharp,
                            electronic_key: &electronic_key,
                            pulse: &pulse_parts,
                        },
                    )
                    .map_err(|e| {
                        // The scene itself is wrong (a nested solid pokes out): an input error.
                        std::io::Error::new(
                            std::io::ErrorKind::InvalidData,
                            format!(
                                "run {}, exposure {}, detector {}: {e}",
                                run.id, exposure.id, det.id
                            ),
                        )
                    })?;
                    if let Some(lengths) = &image.lengths_mm {
                        let name = format!("{}-{}-pathlength.exr", exposure.id, det.id);
                        let bytes = path_length_exr(setup, lengths, det, s)?;
                        truth_extra.push((
                            name.clone(),
                            manifest_entry(truth_root, &truth_dir.join(&name), &bytes)?,
                        ));
                    }
                    (
                        image.pixels,
                        Some(image.beads),
                        Some(image.saturated as u64),
                    )
                }
                _ if !pulse_objects.is_empty() => (
                    crate::binary::noisy_image_in_motion(
                        &frame,
                        source,
                        crate::binary::Pulse {
                            still: &still_objects,
                            moving: &pulse_objects,
                        },
                        sampling,
                        run.noise_level,
                        det.i_max(),
                        &key,
                    ),
                    None,
                    None,
                ),
                _ => (
                    crate::binary::noisy_image(
                        &frame,
                        source,
                        &objects,
                        sampling,
                        run.noise_level,
                        det.i_max(),
                        &key,
                    ),
                    None,
                    None,
                ),
            };

            let stem = format!("{}-{}", exposure.id, det.id);
            let mut refs = Vec::new();
            for file in s.output.image_files() {
                let name = file.name(&stem);
                let image = ImageRef {
                    scenario: s,
                    scenario_sha256: &plan.loaded.sha256,
                    run,
                    exposure_index,
                    detector_index,
                    intent: match file {
                        ImageFile::Dicom(intent) => intent,
                        _ => scenario::DicomIntent::Presentation,
                    },
                };
                let bytes = encode_image(&image, &plan.dicom_views, &pixels, file);
                let entry = manifest_entry(root, &dir.join(&name), &bytes)?;
                refs.push(FileRef {
                    path: name,
                    sha256: entry.sha256.clone(),
                });
                files.push(entry);
            }
            if plan.previews {
                let name = format!("{stem}.png");
                let [w, h] = det.pixels;
                let png = output::preview::preview_png(&pixels, w, h, PREVIEW_MAX_SIDE_PX);
                files.push(manifest_entry(root, &dir.join(&name), &png)?);
            }
            // Binary mode: a bead is occluded when its disc shares a pixel with the shadow of a
            // solid (mesh, cylinder) of the exposure ([`trace::bead_occluded`]).
            let occluders: Vec<&Object> = objects
                .iter()
                .filter(|o| !matches!(o, Object::Sphere { .. }))
                .collect();
            let markers = in_beam
                .iter()
                .flat_map(|&pi| {
                    let ph = &run.phantoms[pi];
                    ph.markers
                        .iter()
                        .enumerate()
                        .map(move |(bi, m)| (pi, ph, bi, m))
                })
                .map(|(pi, ph, bi, m)| {
                    let uv = frame
                        .project(source, m.position_mm)
                        .expect("checked: beads lie between source and detector");
                    let seen = visibility
                        .as_ref()
                        .and_then(|v| v.iter().find(|b| b.phantom == pi && b.bead == bi));
                    ProjectedMarker {
                        phantom: ph.id.clone(),
                        id: m.id.clone(),
                        pixel: [uv.x, uv.y],
                        inside: frame.contains_pixel(uv),
                        occluded: match &visibility {
                            Some(_) => seen.map(|b| b.occluded),
                            None => Some(trace::bead_occluded(
                                &frame,
                                source,
                                m.position_mm,
                                m.diameter_mm / 2.0,
                                &occluders,
                            )),
                        },
                        metal_fraction: seen.map(|b| b.metal_fraction),
                        blur_px: pulse_ends.as_ref().map(|(start, end)| {
                            // The projected centre's path over the pulse: through its place at
                            // the start, at each of the pulse's poses, and at the end.
                            // The frame's own poses are checked to lie between source and
                            // detector, the pulse's in between are not: a place that does not
                            // project is left out of the path.
                            let at = |r: &Run| {
                                frame.project(source, r.phantoms[pi].markers[bi].position_mm)
                            };
                            let points: Vec<_> = std::iter::once(start)
                                .chain(pulse_all.iter())
                                .chain(std::iter::once(end))
                                .filter_map(at)
                                .collect();
                            points.windows(2).map(|p| (p[1] - p[0]).length()).sum()
                        }),
                    }
                })
                .collect();
            images.push(ImageTruth {
                exposure: exposure.id.clone(),
                detector: det.id.clone(),
                files: refs,
                markers,
                saturated_pixels: saturated,
                path_lengths: truth_extra
                    .last()
                    .filter(|(n, _)| n == &format!("{stem}-pathlength.exr"))
                    .map(|(n, e)| FileRef {
                        path: n.clone(),
                        sha256: e.sha256.clone(),
                    }),
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
    let truth = manifest_entry(
        truth_root,
        &truth_dir.join("truth.json"),
        &json_bytes(&truth),
    )?;
    let mut truth = vec![truth];
    truth.extend(truth_extra.into_iter().map(|(_, e)| e));
    Ok(RunFiles {
        images: files,
        truth,
    })
}

/// The path-length truth of one image: one EXR channel `pathlength_mm.<material>` per material
/// in use (f32, mm, net of nesting), ZIP-compressed.
fn path_length_exr(
    setup: &Setup,
    lengths: &[Vec<f64>],
    det: &expand::DetectorState,
    s: &Scenario,
) -> std::io::Result<Vec<u8>> {
    let names: Vec<String> = setup
        .names
        .iter()
        .map(|n| format!("pathlength_mm.{n}"))
        .collect();
    let values: Vec<Vec<f32>> = lengths
        .iter()
        .map(|l| l.iter().map(|&x| x as f32).collect())
        .collect();
    let channels: Vec<(&str, &[f32])> = names
        .iter()
        .map(String::as_str)
        .zip(values.iter().map(Vec::as_slice))
        .collect();
    let [w, h] = det.pixels;
    encode_exr_channels(
        w,
        h,
        &channels,
        &[
            ("rsasim_scenario", ExrAttr::Text(s.name.clone())),
            ("rsasim_detector", ExrAttr::Text(det.id.clone())),
            ("rsasim_program", ExrAttr::Text(output::program())),
            ("xDensity", ExrAttr::F64(exr_x_density(det.pixel_pitch_mm))),
            (
                "pixelAspectRatio",
                ExrAttr::F64(det.pixel_pitch_mm[0] / det.pixel_pitch_mm[1]),
            ),
        ],
        s.output.exr_compression,
    )
    .map_err(std::io::Error::other)
}

/// OpenEXR's standard `xDensity`: pixels per inch along a row, for a pitch `[x, y]` in mm.
fn exr_x_density(pixel_pitch_mm: [f64; 2]) -> f64 {
    25.4 / pixel_pitch_mm[0]
}

/// One image file's bytes: `image`'s pixels in the file's format (`views` for DICOM).
fn encode_image(
    image: &ImageRef,
    views: &[NominalView],
    pixels: &[u16],
    file: ImageFile,
) -> Vec<u8> {
    let (s, run) = (image.scenario, image.run);
    let exposure = s.exposures[image.exposure_index].id.as_str();
    let det = &run.detectors[image.detector_index];
    let [w, h] = det.pixels;
    match file {
        ImageFile::Tiff => {
            let mut description = format!(
                "rsasim scenario={} run={} noise_level={} exposure={exposure} detector={} pixel_pitch_mm={}x{} bpp={}",
                s.name,
                run.id,
                run.noise_level,
                det.id,
                det.pixel_pitch_mm[0],
                det.pixel_pitch_mm[1],
                det.bpp
            );
            if let Some(f) = run.exposure_factor {
                description += &format!(" imaging=attenuation exposure_factor={f}");
            }
            encode_tiff(
                w,
                h,
                pixels,
                s.output.tiff_compression,
                &TiffFacts {
                    description: &description,
                    software: &output::program(),
                    pixel_pitch_mm: det.pixel_pitch_mm,
                    i_max: det.i_max(),
                },
            )
            .expect("in-memory TIFF encoding of a valid image")
        }
        ImageFile::Dicom(_) => encode_dx(&describe(image, views, pixels))
            .expect("in-memory DICOM encoding of a checked image"),
        ImageFile::Exr => {
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
                ("xDensity", ExrAttr::F64(exr_x_density(det.pixel_pitch_mm))),
                (
                    "pixelAspectRatio",
                    ExrAttr::F64(det.pixel_pitch_mm[0] / det.pixel_pitch_mm[1]),
                ),
            ];
            let mut attrs = attrs.to_vec();
            if let Some(f) = run.exposure_factor {
                attrs.push(("rsasim_imaging", ExrAttr::Text("attenuation".into())));
                attrs.push(("rsasim_exposure_factor", ExrAttr::F64(f)));
            }
            encode_exr_with(w, h, &values, &attrs, s.output.exr_compression)
                .expect("in-memory EXR encoding of a valid image")
        }
    }
}

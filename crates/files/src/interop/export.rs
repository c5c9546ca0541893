//! `rsasim export OUT --to xmalab|autoscoper --dir DEST`: an rsasim output folder as the files
//! XMALab or Autoscoper open, with the exam's known (true) calibration, or the calibration a
//! software measured.
//!
//! Layout of DEST (one folder per trial: a run, since every run has its own geometry, or a
//! sequence, whose frames share one; see [`super::trials`]):
//!
//! ```text
//! DEST/README.md
//! DEST/<trial>/calibration/<detector>_MayaCam.txt   MayaCam 2.0, one per detector (both programs)
//! DEST/<trial>/calibration/dlt11.csv                 DLT-11: 11 rows, one column per detector (xmalab)
//! DEST/<trial>/calibration/frame_specification.csv   the box beads, box frame (xmalab)
//! DEST/<trial>/calibration/references.ref            four reference beads (xmalab)
//! DEST/<trial>/images/<exposure>-<detector>/<exposure>-<detector>.<NNNN>.tif   a frame each: 0001 for a run, frame index + 1 in a sequence
//! DEST/<trial>/models/<phantom>_markers.csv          bead names and local coordinates (xmalab)
//! DEST/<trial>/models/<phantom>.obj | .stl           the model mesh, local frame, mm
//! DEST/<trial>/<exposure>.cfg                        Autoscoper trial per exposure with a model (autoscoper)
//! DEST/<trial>/truth/<exposure>_<phantom>.tra        the true pose of each volume, a line per frame (autoscoper)
//! DEST/volumes/<phantom>.tif | .stl                each model as Autoscoper's volume and mesh (autoscoper)
//! ```
//!
//! `<trial>` is the run id of a run without frames, the sequence id (`n0-r00`) of a sequence's
//! frames (`n0-r00-f0000` …).

use std::path::{Path, PathBuf};

use glam::DVec3;

use super::camera::PinholeCamera;
use super::{autoscoper, reference_beads, trials, volume, xmalab};
use crate::diagnostic::Diagnostic;
use crate::expand::{DetectorState, Run};
use crate::geometry::rotation_from_rows;
use crate::output::atomic::write_staged;
use crate::output::commit::{FolderKind, OutputTarget};
use crate::output::decode::read_image;
use crate::output::exam::{Setup, load_setup};
use crate::output::received::ReceivedFolder;
use crate::output::tiff::{TiffCompression, TiffFacts, encode_tiff};
use crate::output::{Measured, Truth};

/// The program the export is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// XMALab: MayaCam 2.0 per camera, DLT-11, calibration object, marker reference CSV, OBJ.
    Xmalab,
    /// Autoscoper: MayaCam 2.0 per camera, a `.cfg` per exposure with models, STL.
    Autoscoper,
}

impl Target {
    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Target::Xmalab => "xmalab",
            Target::Autoscoper => "autoscoper",
        }
    }
}

/// How dense matter looks in exported images.
///
/// Both programs expect it dark by default: XMALab's marker detection (method 0, its default)
/// and its calibration-object blob detection look for dark blobs unless the frame specification's
/// header holds `white` (`CalibrationObject::loadCoords`); Autoscoper's radiograph kernels
/// compare the images with digitally reconstructed radiographs rendered as `1 − value`, so dense
/// matter is dark there too.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DenseMatter {
    /// Beads and implants dark on a bright background (the default): raw detector images are
    /// written as they are, binary-mode and `polarity = "radiograph"` images as `I_max − value`.
    #[default]
    Dark,
    /// Beads and implants bright: binary-mode and radiograph images as they are, raw detector
    /// images as `I_max − value`. XMALab's frame specification then says `white`.
    Bright,
}

/// Whether the run's own images show dense matter bright: binary mode (beads and models at
/// I_max) and attenuation mode with `polarity = "radiograph"`; raw detector values show it dark.
pub fn dense_matter_bright_in(setup: &Setup) -> bool {
    match &setup.physics {
        None => true,
        Some(p) => matches!(
            p.polarity,
            rsasim_core::response::Polarity::Radiograph { .. }
        ),
    }
}

/// Whether an XMALab export holds the calibration box as XMALab's calibration object (frame
/// specification and four reference beads, for XMALab's own cube calibration).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CalibrationObject {
    /// In every run whose box has four reference beads by the rule of [`reference_beads`];
    /// other runs are named in a note and in the export's README.
    #[default]
    WhenPossible,
    /// In every run; an input error (nothing written) when a run's box has no four.
    Required,
    /// Never: the cameras alone (XMALab's "external calibration").
    Omit,
}

/// Whether the export writes `I_max − value`: where the run's images show dense matter other
/// than `dense_matter` asks.
fn inverts(setup: &Setup, dense_matter: DenseMatter) -> bool {
    dense_matter_bright_in(setup) != (dense_matter == DenseMatter::Bright)
}

/// Options of `rsasim export`.
#[derive(Debug, Clone)]
pub struct Options {
    /// The program.
    pub target: Target,
    /// Run ids to export; empty: every run.
    pub runs: Vec<String>,
    /// How dense matter (beads, implants, bone) looks in the exported images.
    pub dense_matter: DenseMatter,
    /// Autoscoper: the voxel size of the model volumes, mm.
    pub voxel_mm: f64,
    /// Whether to write the calibration box as XMALab's calibration object (XMALab only).
    pub calibration_object: CalibrationObject,
    /// Take each beamline's source and detector pose from this results file of every run folder
    /// (e.g. `measured-rsasim-dlt-markers.json`) instead of the truth.
    pub calibration_from: Option<String>,
}

/// What an export wrote.
#[derive(Debug)]
pub struct Summary {
    /// Trials exported: runs without a frame, and sequences.
    pub runs: usize,
    /// Of those, sequences.
    pub sequences: usize,
    /// Frames exported: one per run without a frame, and every frame of every sequence.
    pub frames: usize,
    /// Files written.
    pub files: usize,
    /// The export folder as given.
    pub dir: PathBuf,
    /// What the user should know.
    pub notes: Vec<String>,
}

pub use super::failure::Error;

/// One run (a run without a frame, or one frame of a sequence), read and checked.
struct RunExport {
    truth: Truth,
    dir: PathBuf,
}

/// One trial ([`trials`]), read and checked, ready to be written: a run without a frame, or the
/// frames of a sequence present in the output, in frame order (never none).
struct TrialExport {
    /// The folder name: the run id, or the sequence id.
    id: String,
    frames: Vec<RunExport>,
    /// The cameras of every frame (one geometry per trial).
    cameras: Vec<(String, PinholeCamera)>,
    /// XMALab: the calibration box and its four reference beads, or why no four qualify.
    references: Option<(usize, Result<[usize; 4], reference_beads::NoFour>)>,
}

impl TrialExport {
    /// The trial's first frame: its cameras, models and trials are every frame's.
    fn first(&self) -> &RunExport {
        &self.frames[0]
    }

    /// `run <id>` or `sequence <id>`, as messages name it.
    fn label(&self) -> String {
        trials::trial_label(&self.first().truth.run)
    }

    fn is_sequence(&self) -> bool {
        self.first().truth.run.frame.is_some()
    }
}

/// Exports `out` into the new folder `dest` (see the module docs). With `truth_dir` (the blind
/// layout) `out` is the images folder and `truth_dir` its truth folder, bound to it by the SHA-256
/// of its manifest.
///
/// `out` (and `truth_dir`) are received folders: the truth (every `truth.json` and
/// `scenario.toml`) is verified against the manifest before it is parsed, every id that becomes
/// part of an exported path is a plain name, each run folder is named after its run id and each
/// frame's run id is its sequence's and index's, so nothing is written outside `dest` and no
/// trial or frame replaces another.
pub fn export(
    out: &Path,
    truth_dir: Option<&Path>,
    dest: &Path,
    options: &Options,
) -> Result<Summary, Error> {
    crate::output::check_output_folder(out)?;
    if let Some(t) = truth_dir {
        crate::output::check_output_folder(t)?;
    }
    let truth_root = truth_dir.unwrap_or(out);
    let manifest = crate::output::truth_check::verify_truth(truth_root, truth_dir.map(|_| out))?;
    let truth_folder = ReceivedFolder::listed(truth_root, &manifest);
    let images_folder = match truth_dir {
        None => truth_folder.clone(),
        Some(_) => {
            let (images_manifest, _) = crate::output::verify::read_manifest(out)
                .map_err(|f| vec![Diagnostic::file_error(&out.join(&f.path), f.problem)])?;
            ReceivedFolder::listed(out, &images_manifest)
        }
    };
    let setup = load_setup(truth_root)?;
    check_run_options(out, &options.runs)?;
    let mut runs = Vec::new();
    for id in truth_folder.sub_folders("runs")? {
        if !may_be_selected(&options.runs, &id) {
            continue;
        }
        if !truth_folder.exists(&format!("runs/{id}/truth.json")) {
            continue;
        }
        let truth = crate::output::truth::read_run_truth(&truth_folder, &id)?;
        let dir = images_folder.sub_folder(&format!("runs/{id}"))?;
        refuse_frame_selection(&options.runs, &truth.run, &dir)?;
        runs.push(RunExport { truth, dir });
    }
    let grouped = trials::group(runs, |r| &r.truth.run, |r| r.dir.join("truth.json"))?;
    refuse_missing(truth_root, &options.runs, &grouped)?;
    let mut trials = Vec::new();
    for (id, frames) in grouped {
        trials.push(trial_export(id, frames, &setup, &images_folder, options)?);
    }
    if let Some(t) = truth_dir {
        refuse_inside(t, dest)?;
    }
    check_images(&trials)?;
    let volumes = if options.target == Target::Autoscoper {
        model_volumes(
            &trials,
            &setup,
            options.voxel_mm,
            &truth_root.join("scenario.toml"),
        )?
    } else {
        Vec::new()
    };
    refuse_inside(out, dest)?;
    let target =
        OutputTarget::claim(dest, FolderKind::Export).map_err(|d| Error::Input(vec![*d]))?;
    let mut notes = target.notes.clone();
    notes.extend(cube_note(&trials));
    notes.extend(trials.iter().filter_map(partial_sequence));
    let staged = target.stage().map_err(|e| Error::Write(e.to_string()))?;
    let root = staged.path().to_path_buf();
    let mut files = 0usize;
    let mut write = |rel: &str, bytes: &[u8]| -> Result<(), Error> {
        let path = root.join(rel);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(|e| Error::Write(format!("{rel}: {e}")))?;
        }
        write_staged(&path, bytes).map_err(|e| Error::Write(format!("{rel}: {e}")))?;
        files += 1;
        Ok(())
    };
    write(
        "README.md",
        readme(out, options, &trials, &setup).as_bytes(),
    )?;
    for v in &volumes {
        write(&format!("volumes/{}.tif", v.phantom), &v.tiff)?;
        write(&format!("volumes/{}.stl", v.phantom), &v.stl)?;
    }
    for trial in &trials {
        write_trial(trial, &setup, options, &volumes, &mut write)?;
    }
    let committed = staged.commit().map_err(|e| Error::Write(e.to_string()))?;
    notes.extend(committed.notes);
    Ok(Summary {
        runs: trials.len(),
        sequences: trials.iter().filter(|t| t.is_sequence()).count(),
        frames: trials.iter().map(|t| t.frames.len()).sum(),
        files,
        dir: committed.path,
        notes,
    })
}

/// Refuses a `--run` value that is no plain name.
fn check_run_options(out: &Path, runs: &[String]) -> Result<(), Error> {
    for name in runs {
        if let Some(why) = crate::output::received::name_problem(name) {
            return Err(Error::Input(vec![
                Diagnostic::file_error(
                    &out.join("runs"),
                    format!(
                        "--run {:?} is not a run or sequence id: {why}",
                        crate::diagnostic::cut(name)
                    ),
                )
                .with_help(RUN_IDS_HELP),
            ]));
        }
    }
    Ok(())
}

/// How `--run` names what to export.
const RUN_IDS_HELP: &str = "give run ids as the folders of OUT/runs are named (e.g. n0-r00), and for a sequence its id, the run id without the frame (n0-r00 for n0-r00-f0000 …)";

/// Whether the run folder `id` may belong to what `--run` selects (every run when it selects
/// nothing): a run id given, or a frame of a sequence id given (`<sequence>-f<k>`), to be told
/// apart by its truth ([`refuse_frame_selection`]).
fn may_be_selected(selected: &[String], id: &str) -> bool {
    selected.is_empty()
        || selected.iter().any(|r| {
            id == r
                || id
                    .strip_prefix(r.as_str())
                    .is_some_and(|rest| rest.starts_with("-f"))
        })
}

/// Refuses a frame selected by its own run id: a sequence is exported whole, as one trial.
fn refuse_frame_selection(selected: &[String], run: &Run, dir: &Path) -> Result<(), Error> {
    let trial = trials::trial_id(run);
    match &run.frame {
        Some(f) if !selected.is_empty() && !selected.iter().any(|r| r == trial) => {
            Err(Error::Input(vec![
                Diagnostic::file_error(
                    &dir.join("truth.json"),
                    format!(
                        "--run {} is frame {} of sequence {trial}: a sequence is exported whole, as one trial",
                        run.id, f.index
                    ),
                )
                .with_help(format!("give the sequence id: --run {trial}")),
            ]))
        }
        _ => Ok(()),
    }
}

/// Refuses an export with nothing to export, or with a `--run` that names no run or sequence.
fn refuse_missing(
    truth_root: &Path,
    selected: &[String],
    grouped: &[(String, Vec<RunExport>)],
) -> Result<(), Error> {
    let missing: Vec<&String> = selected
        .iter()
        .filter(|r| !grouped.iter().any(|(id, _)| id == *r))
        .collect();
    if missing.is_empty() && !grouped.is_empty() {
        return Ok(());
    }
    let what = if missing.is_empty() {
        "no run folder with a truth.json".to_string()
    } else {
        format!(
            "no run {} in this output",
            missing
                .iter()
                .map(|m| format!("`{}`", crate::diagnostic::cut(m)))
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    Err(Error::Input(vec![
        Diagnostic::file_error(&truth_root.join("runs"), what).with_help(format!(
            "{RUN_IDS_HELP}; an export needs the truth: give the ordinary output folder, or a blind images folder with --truth TRUTH_DIR"
        )),
    ]))
}

/// One trial, read and checked: its frames' cameras (the same in every frame: a mismatch is an
/// input error naming the frame), the exported cameras (the truth's, or those measured in the
/// first frame's `--calibration-from` file) and XMALab's reference beads.
fn trial_export(
    id: String,
    frames: Vec<RunExport>,
    setup: &Setup,
    images_folder: &ReceivedFolder,
    options: &Options,
) -> Result<TrialExport, Error> {
    let Some(first) = frames.first() else {
        return Err(Error::Write(format!("trial {id} has no frame")));
    };
    let true_cameras = cameras(&first.truth.run, None, &first.dir, options)?;
    for frame in &frames[1..] {
        check_same_setup(first, frame, &true_cameras, options)?;
    }
    let cameras = match &options.calibration_from {
        None => true_cameras,
        Some(name) => {
            let measured = read_calibration(images_folder, &first.truth.run.id, name)?;
            cameras(&first.truth.run, Some(&measured), &first.dir, options)?
        }
    };
    let mut trial = TrialExport {
        id,
        frames,
        cameras,
        references: None,
    };
    trial.references = references(&trial, setup, options)?;
    Ok(trial)
}

/// Refuses a frame whose true cameras, exposures or phantoms are not those of the sequence's
/// first frame: a sequence's frames share one geometry by construction, and its trial has one
/// calibration, one set of models and one line per frame in each `.tra`.
fn check_same_setup(
    first: &RunExport,
    frame: &RunExport,
    first_cameras: &[(String, PinholeCamera)],
    options: &Options,
) -> Result<(), Error> {
    let own = cameras(&frame.truth.run, None, &frame.dir, options)?;
    let phantom_ids = |r: &RunExport| -> Vec<String> {
        r.truth.run.phantoms.iter().map(|p| p.id.clone()).collect()
    };
    let differs = if own != first_cameras {
        own.iter()
            .zip(first_cameras)
            .find(|(a, b)| a != b)
            .map_or_else(
                || "the detectors differ".to_string(),
                |(a, _)| format!("the camera of detector `{}` differs", a.0),
            )
    } else if frame.truth.run.exposures != first.truth.run.exposures {
        "the exposures differ".to_string()
    } else if phantom_ids(frame) != phantom_ids(first) {
        "the phantoms differ".to_string()
    } else {
        return Ok(());
    };
    Err(Error::Input(vec![
        Diagnostic::file_error(
            &frame.dir.join("truth.json"),
            format!(
                "frame {} of {}: {differs} from frame {}'s; the frames of a sequence share one geometry, and its trial one calibration",
                frame.truth.run.id,
                trials::trial_label(&frame.truth.run),
                first.truth.run.id
            ),
        )
        .with_help("the sources, detectors, exposures and phantoms of every frame's truth.json must be the same: this output was edited or mixes outputs"),
    ]))
}

/// The results file `name` (`--calibration-from`) of run `run_id`, parsed.
fn read_calibration(
    images_folder: &ReceivedFolder,
    run_id: &str,
    name: &str,
) -> Result<Measured, Error> {
    crate::output::received::check_name(
        Path::new("--calibration-from"),
        "--calibration-from",
        name,
    )?;
    let rel = format!("runs/{run_id}/{name}");
    let file = images_folder.path(&rel);
    let bytes = images_folder
        .read(&rel, crate::output::received::MAX_JSON_BYTES)
        .map_err(|d| {
            vec![d.with_help("give a results file every run folder holds (for a sequence, its first frame's), e.g. measured-rsasim-dlt-markers.json")]
        })?;
    parse_json::<Measured>(&file, &bytes, "schemas/measured.schema.json")
}

/// XMALab's calibration object of a trial (unless `--calibration-object none`): the box and its
/// four reference beads, chosen over every calibration view of every frame, or why no four
/// qualify (an input error with `--calibration-object required`).
#[allow(clippy::type_complexity)]
fn references(
    trial: &TrialExport,
    setup: &Setup,
    options: &Options,
) -> Result<Option<(usize, Result<[usize; 4], reference_beads::NoFour>)>, Error> {
    if options.target != Target::Xmalab || options.calibration_object == CalibrationObject::Omit {
        return Ok(None);
    }
    let first = trial.first();
    let Some(c) = first
        .truth
        .run
        .phantoms
        .iter()
        .position(|p| p.kind == "calibration_box")
    else {
        return Ok(None);
    };
    let (beads, views) = reference_views(trial, setup, &first.truth.run.phantoms[c])?;
    let choice = reference_beads::choose(&beads, &views);
    if let (Err(e), CalibrationObject::Required) = (&choice, options.calibration_object) {
        return Err(Error::Input(vec![Diagnostic::file_error(
            &first.dir.join("truth.json"),
            format!("{}, calibration box `{}`: {e}", trial.label(), first.truth.run.phantoms[c].id),
        )
        .with_help("XMALab's cube calibration needs four beads it can tell apart in every calibration view, on plates not seen edge-on, spanning a tetrahedron; the MayaCam cameras hold the true calibration without it (XMALab: \"New dataset with external calibration\"); export with --calibration-object when-possible to write the cube files only where four qualify")]));
    }
    Ok(Some((c, choice)))
}

/// The note on trials without XMALab's calibration object, if any.
fn cube_note(trials: &[TrialExport]) -> Option<String> {
    let without: Vec<&TrialExport> = trials
        .iter()
        .filter(|r| matches!(r.references, Some((_, Err(_)))))
        .collect();
    let first = without.first()?;
    let Some((_, Err(why))) = &first.references else {
        return None;
    };
    Some(format!(
        "XMALab's calibration object (frame_specification.csv, references.ref) is not written for {} of {} {}: in {}, {why}. The cameras hold the calibration (XMALab: \"New dataset with external calibration\")",
        without.len(),
        trials.len(),
        trials_word(trials),
        first.label()
    ))
}

/// `run(s)` for an export of runs without frames, `trial(s)` when it holds a sequence.
fn trials_word(trials: &[TrialExport]) -> &'static str {
    if trials.iter().any(TrialExport::is_sequence) {
        "trial(s)"
    } else {
        "run(s)"
    }
}

/// The note on a sequence of which the output holds only some frames (a shard's), if so.
fn partial_sequence(trial: &TrialExport) -> Option<String> {
    let count = trial.first().truth.run.frame.as_ref()?.count;
    if trial.frames.len() == count as usize {
        return None;
    }
    let numbers: Vec<String> = trial
        .frames
        .iter()
        .take(6)
        .map(|f| trials::image_number(f.truth.run.frame.as_ref()))
        .collect();
    Some(format!(
        "sequence {} has {count} frames, of which this output holds {}: its trial holds those, its images numbered by frame ({}{}), so some numbers are missing; frame k of the trial (Autoscoper's line k, XMALab's frame k) is the k-th of them",
        trial.id,
        trial.frames.len(),
        numbers.join(", "),
        if trial.frames.len() > 6 { ", …" } else { "" }
    ))
}

/// Decodes every image of every run once before anything is written, so that an unreadable
/// image, or one whose size is not its detector's, is an input error (exit 2) with nothing
/// written, not even the export folder's lock. The pixels are decoded again when written: the
/// export is not worth holding every image in memory.
fn check_images(trials: &[TrialExport]) -> Result<(), Error> {
    for run in trials.iter().flat_map(|t| &t.frames) {
        for image in &run.truth.images {
            let stem = format!("{}-{}", image.exposure, image.detector);
            let (det, (w, h, _)) = run_image(run, image, &stem)?;
            if [w, h] != det.pixels {
                return Err(Error::Input(vec![Diagnostic::file_error(
                    &run.dir,
                    format!(
                        "image `{stem}` is {w} × {h} pixels, but truth.json gives detector `{}` {} × {}",
                        image.detector, det.pixels[0], det.pixels[1]
                    ),
                )]));
            }
        }
    }
    Ok(())
}

/// An image of a run, decoded, with the detector that took it.
fn run_image<'a>(
    run: &'a RunExport,
    image: &crate::output::ImageTruth,
    stem: &str,
) -> Result<(&'a DetectorState, (u32, u32, Vec<u16>)), Error> {
    let det = run
        .truth
        .run
        .detectors
        .iter()
        .find(|d| d.id == image.detector)
        .ok_or_else(|| {
            Error::Input(vec![Diagnostic::file_error(
                &run.dir.join("truth.json"),
                format!("image `{stem}` names an unknown detector"),
            )])
        })?;
    let decoded = read_image(&run.dir, stem).map_err(|e| {
        Error::Input(vec![Diagnostic::file_error(&run.dir, format!("cannot read the image: {e}"))
            .with_help("export reads the TIFF (or EXR) images of every run; give a folder written with them")])
    })?;
    Ok((det, decoded))
}

/// Refuses an export folder inside the output folder (it would add files the manifest does not
/// list).
fn refuse_inside(out: &Path, dest: &Path) -> Result<(), Error> {
    let abs = |p: &Path| {
        std::path::absolute(p)
            .unwrap_or_else(|_| p.to_path_buf())
            .components()
            .collect::<PathBuf>()
    };
    let out_real = out.canonicalize().unwrap_or_else(|_| abs(out));
    let mut existing = abs(dest);
    let mut rest = Vec::new();
    while !existing.exists() {
        match (
            existing.file_name().map(|n| n.to_os_string()),
            existing.parent(),
        ) {
            (Some(n), Some(p)) => {
                rest.push(n);
                existing = p.to_path_buf();
            }
            _ => break,
        }
    }
    let mut dest_real = existing.canonicalize().unwrap_or(existing);
    dest_real.extend(rest.iter().rev());
    if dest_real.starts_with(&out_real) {
        return Err(Error::Input(vec![
            Diagnostic::file_error(
                dest,
                format!(
                    "the export folder lies inside the output folder {}",
                    out.display()
                ),
            )
            .with_help("write the export beside it, e.g. --dir xmalab/<name>; files in the output folder must be those its manifest lists"),
        ]));
    }
    Ok(())
}

fn parse_json<T: serde::de::DeserializeOwned>(
    file: &Path,
    bytes: &[u8],
    schema: &str,
) -> Result<T, Error> {
    let text = String::from_utf8_lossy(bytes);
    serde_json::from_str(text.strip_prefix('\u{feff}').unwrap_or(&text)).map_err(|e| {
        let mut d = Diagnostic::file_error(
            file,
            format!("invalid JSON: {}", crate::diagnostic::cut(&e.to_string())),
        )
        .with_help(format!("the file must follow {schema}"));
        if e.line() > 0 {
            d.line_col = Some((e.line(), e.column()));
        }
        Error::Input(vec![d])
    })
}

/// The camera of every detector, from the truth or from a results file.
fn cameras(
    run: &Run,
    measured: Option<&Measured>,
    dir: &Path,
    options: &Options,
) -> Result<Vec<(String, PinholeCamera)>, Error> {
    let mut out = Vec::new();
    for det in &run.detectors {
        let (source, det) = match measured {
            None => {
                let source = run
                    .sources
                    .iter()
                    .find(|s| s.id == det.source)
                    .ok_or_else(|| {
                        Error::Input(vec![Diagnostic::file_error(
                            &dir.join("truth.json"),
                            format!("detector `{}` names no source of the run", det.id),
                        )])
                    })?;
                (source.position_mm, det.clone())
            }
            Some(m) => {
                let file = dir.join(options.calibration_from.as_deref().unwrap_or_default());
                let lacks = |what: &str| {
                    Error::Input(vec![Diagnostic::file_error(
                        &file,
                        format!("it has no measured {what}, which the exported calibration needs"),
                    )
                    .with_help("give a results file with the calibration (sources and detectors with rotation), e.g. measured-rsasim-dlt-markers.json, or export the true calibration")])
                };
                let s = m
                    .sources
                    .iter()
                    .find(|s| s.id == det.source)
                    .ok_or_else(|| lacks(&format!("source `{}`", det.source)))?;
                let d = m
                    .detectors
                    .iter()
                    .find(|d| d.id == det.id)
                    .ok_or_else(|| lacks(&format!("detector `{}`", det.id)))?;
                let rotation = d
                    .rotation
                    .ok_or_else(|| lacks(&format!("rotation of detector `{}`", det.id)))?;
                // The results are the sender's: positions and rotations checked for physical sense
                // here, so that the error names this file, not the cameras made from it.
                let implausible = |field: String| {
                    Error::Input(vec![Diagnostic::file_error(
                        &file,
                        format!("`{field}` is not finite within ±{:e} mm (or a rotation's entries within ±1)", crate::scenario::MAX_ABS),
                    )
                    .with_help("give a results file with a plausible calibration (mm, box frame), or export the true calibration")])
                };
                let plausible = |v: &[f64]| {
                    v.iter()
                        .all(|x| x.is_finite() && x.abs() <= crate::scenario::MAX_ABS)
                };
                if !plausible(&s.position_mm) {
                    return Err(implausible(format!(
                        "sources[{}].position_mm",
                        crate::diagnostic::cut(&s.id)
                    )));
                }
                if !plausible(&d.position_mm) {
                    return Err(implausible(format!(
                        "detectors[{}].position_mm",
                        crate::diagnostic::cut(&d.id)
                    )));
                }
                if !rotation
                    .iter()
                    .flatten()
                    .all(|x| x.is_finite() && x.abs() <= 1.0 + 1e-6)
                {
                    return Err(implausible(format!(
                        "detectors[{}].rotation",
                        crate::diagnostic::cut(&d.id)
                    )));
                }
                let posed = DetectorState {
                    position_mm: DVec3::from_array(d.position_mm),
                    rotation: rotation_from_rows(rotation),
                    ..det.clone()
                };
                (DVec3::from_array(s.position_mm), posed)
            }
        };
        let cam = PinholeCamera::of_beamline(source, &det)
            .map_err(|e| Error::Input(vec![Diagnostic::file_error(&dir.join("truth.json"), e)]))?;
        out.push((det.id.clone(), cam));
    }
    Ok(out)
}

/// A model as Autoscoper's volume: its grid, the TIFF stack and the mesh in the volume frame.
struct ModelVolume {
    phantom: String,
    grid: volume::Grid,
    tiff: Vec<u8>,
    stl: Vec<u8>,
}

/// The reference energy of the volumes' attenuation values: the mean energy of the filtered
/// spectrum in attenuation mode, 60 keV in binary mode.
pub fn volume_energy_kev(setup: &Setup) -> f64 {
    setup.physics.as_ref().map_or(60.0, |p| p.mean_energy_kev)
}

/// The volume of every mesh phantom that some exported exposure holds (see [`volume`]): inside
/// voxels hold μ of the phantom's material at [`volume_energy_kev`]; a phantom without a
/// material (binary mode) holds half of full scale, 32768.
fn model_volumes(
    trials: &[TrialExport],
    setup: &Setup,
    voxel_mm: f64,
    scenario_file: &Path,
) -> Result<Vec<ModelVolume>, Error> {
    let mut ids: Vec<&String> = trials
        .iter()
        .flat_map(|t| &t.frames)
        .flat_map(|r| r.truth.run.exposures.iter().flat_map(|e| e.phantoms.iter()))
        .filter(|p| setup.meshes.contains_key(*p))
        .collect();
    ids.sort();
    ids.dedup();
    let energy = volume_energy_kev(setup);
    let mut out = Vec::new();
    for id in ids {
        let mesh = &setup.meshes[id];
        let refuse = |why: String| {
            Error::Input(vec![Diagnostic::file_error(scenario_file, format!("phantom `{id}`: {why}"))
                .with_help("give --voxel-mm a size that keeps the model's volume within 2^28 voxels (e.g. 0.5 or 1)")])
        };
        let grid = volume::Grid::of_mesh(mesh, voxel_mm).map_err(&refuse)?;
        let material = setup
            .scenario
            .phantoms
            .iter()
            .find(|p| &p.id == id)
            .and_then(|p| p.material.as_deref())
            .and_then(|m| rsasim_core::attenuation::setup::resolve(&setup.scenario, m));
        let value = match &material {
            Some(m) => volume::voxel_value(m.linear_attenuation_per_mm(energy)),
            None => 32768,
        };
        let samples: Vec<u16> = volume::inside(mesh, &grid)
            .into_iter()
            .map(|inside| if inside { value } else { 0 })
            .collect();
        if !samples.iter().any(|&v| v > 0) {
            return Err(refuse(format!(
                "no voxel centre of {voxel_mm} mm lies inside the mesh (Autoscoper refuses an empty volume)"
            )));
        }
        let [w, h, d] = grid.dims;
        let inside = match &material {
            Some(m) => format!(
                "{value} inside = round(6553.5 * mu), mu of {} at {energy:.3} keV in 1/mm",
                m.name
            ),
            None => format!("{value} inside (no material: binary mode)"),
        };
        let description = format!(
            "rsasim export: phantom {id} as an Autoscoper volume, {w}x{h}x{d} voxels of {voxel_mm} mm, {inside}, 0 outside; VolumeFlip 0 1 1"
        );
        let tiff = crate::output::tiff::encode_tiff_stack(
            w,
            h,
            d,
            &samples,
            &TiffFacts {
                description: &description,
                software: &crate::output::program(),
                pixel_pitch_mm: [voxel_mm, voxel_mm],
                i_max: u16::MAX,
            },
        )
        .map_err(Error::Write)?;
        let mut stl = Vec::new();
        crate::phantom::mesh_io::write_stl(
            &volume::mesh_in_volume_frame(mesh, grid.offset_mm),
            &mut stl,
        )
        .map_err(Error::Write)?;
        out.push(ModelVolume {
            phantom: id.clone(),
            grid,
            tiff,
            stl,
        });
    }
    Ok(out)
}

/// The box beads (with their plates' normals) and the calibration views of a trial, for the
/// choice of XMALab's reference beads: every image of an exposure that holds the box, in every
/// frame, seen through the frame's true camera.
fn reference_views(
    trial: &TrialExport,
    setup: &Setup,
    cal: &crate::expand::PhantomState,
) -> Result<(Vec<reference_beads::BoxBead>, Vec<reference_beads::View>), Error> {
    let mut views = Vec::new();
    for run in &trial.frames {
        views.extend(calibration_views(run, cal)?);
    }
    Ok((box_beads(setup, cal), views))
}

/// The box beads of `cal`, each with its plate's normal (box frame).
fn box_beads(setup: &Setup, cal: &crate::expand::PhantomState) -> Vec<reference_beads::BoxBead> {
    // Plate normals from the scenario's plates (box frame), turned by the box's pose.
    let plates: Vec<(String, DVec3)> = setup
        .scenario
        .phantoms
        .iter()
        .filter(|p| p.id == cal.id)
        .filter_map(|p| p.calibration_box.as_ref())
        .flat_map(|b| {
            crate::phantom::calibration_box::box_markers(b)
                .into_iter()
                .zip(std::iter::repeat(b))
        })
        .filter_map(|(m, b)| {
            let plate = b.plates.iter().find(|p| Some(&p.id) == m.plate.as_ref())?;
            let local = crate::geometry::rotation_xyz_deg(plate.rotation_deg) * DVec3::Z;
            Some((m.id, cal.rotation * local))
        })
        .collect();
    cal.markers
        .iter()
        .map(|m| reference_beads::BoxBead {
            position_mm: m.position_mm,
            diameter_mm: m.diameter_mm,
            plate_normal: plates.iter().find(|(id, _)| *id == m.id).map(|(_, n)| *n),
        })
        .collect()
}

/// The views of run `run` that hold the box `cal`: each image of an exposure holding it.
fn calibration_views(
    run: &RunExport,
    cal: &crate::expand::PhantomState,
) -> Result<Vec<reference_beads::View>, Error> {
    let cameras = super::camera::run_cameras(&run.truth.run)
        .map_err(|e| Error::Input(vec![Diagnostic::file_error(&run.dir.join("truth.json"), e)]))?;
    let mut views = Vec::new();
    for image in &run.truth.images {
        let Some(exposure) = run
            .truth
            .run
            .exposures
            .iter()
            .find(|e| e.id == image.exposure)
        else {
            continue;
        };
        if !exposure.phantoms.contains(&cal.id) {
            continue;
        }
        let Some(k) = run
            .truth
            .run
            .detectors
            .iter()
            .position(|d| d.id == image.detector)
        else {
            continue;
        };
        let (source_mm, camera) = cameras[k].clone();
        let in_view: Vec<(DVec3, f64)> = run
            .truth
            .run
            .phantoms
            .iter()
            .filter(|p| exposure.phantoms.contains(&p.id))
            .flat_map(|p| p.markers.iter().map(|m| (m.position_mm, m.diameter_mm)))
            .collect();
        let hidden = cal
            .markers
            .iter()
            .map(|m| {
                image
                    .markers
                    .iter()
                    .any(|p| p.phantom == cal.id && p.id == m.id && p.occluded == Some(true))
            })
            .collect();
        views.push(reference_beads::View {
            source_mm,
            camera,
            beads: in_view,
            hidden,
        });
    }
    Ok(views)
}

/// An image for the other program: rows flipped (see [`super::camera`]), optionally inverted,
/// scaled to the full 16-bit range: `round(value · 65535 / I_max)`.
pub fn export_pixels(pixels: &[u16], width: u32, i_max: u16, invert: bool) -> Vec<u16> {
    let w = width as usize;
    let max = u64::from(i_max.max(1));
    let mut out = Vec::with_capacity(pixels.len());
    for row in pixels.chunks(w).rev() {
        out.extend(row.iter().map(|&v| {
            let v = u64::from(v).min(max);
            let v = if invert { max - v } else { v };
            ((v * 65535 + max / 2) / max) as u16
        }));
    }
    out
}

/// The files of one trial, under its folder `<trial id>/`.
type Write<'a> = dyn FnMut(&str, &[u8]) -> Result<(), Error> + 'a;

/// Writes one trial: its calibration, every frame's images, the models, and for Autoscoper the
/// trials and the truth `.tra` (a line per frame).
fn write_trial(
    trial: &TrialExport,
    setup: &Setup,
    options: &Options,
    volumes: &[ModelVolume],
    write: &mut Write,
) -> Result<(), Error> {
    write_calibration(trial, options, write)?;
    for run in &trial.frames {
        write_images(&trial.id, run, setup, options, write)?;
    }
    write_models(trial, setup, options.target == Target::Xmalab, write)?;
    if options.target == Target::Autoscoper {
        write_autoscoper_trials(trial, volumes, write)?;
    }
    Ok(())
}

/// The cameras (MayaCam 2.0; XMALab also DLT-11) and XMALab's calibration object, once per
/// trial.
fn write_calibration(
    trial: &TrialExport,
    options: &Options,
    write: &mut Write,
) -> Result<(), Error> {
    let id = &trial.id;
    let run = trial.first();
    for (det, cam) in &trial.cameras {
        write(
            &format!("{id}/calibration/{det}_MayaCam.txt"),
            cam.mayacam_text().as_bytes(),
        )?;
    }
    if options.target != Target::Xmalab {
        return Ok(());
    }
    let dlts: Vec<[f64; 11]> = trial
        .cameras
        .iter()
        .map(|(det, c)| {
            c.dlt().map_err(|e| {
                Error::Input(vec![Diagnostic::file_error(
                    &run.dir.join("truth.json"),
                    format!("detector `{det}`: {e}"),
                )])
            })
        })
        .collect::<Result<_, _>>()?;
    let text = super::camera_files::dlt11_csv(&dlts);
    write(&format!("{id}/calibration/dlt11.csv"), text.as_bytes())?;
    if let Some((c, Ok(four))) = &trial.references {
        let cal = &run.truth.run.phantoms[*c];
        let beads: Vec<DVec3> = cal.markers.iter().map(|m| m.position_mm).collect();
        let ids: Vec<String> = cal.markers.iter().map(|m| m.id.clone()).collect();
        write(
            &format!("{id}/calibration/frame_specification.csv"),
            xmalab::frame_specification(&beads, options.dense_matter == DenseMatter::Bright)
                .as_bytes(),
        )?;
        write(
            &format!("{id}/calibration/references.ref"),
            xmalab::references(&ids, four).as_bytes(),
        )?;
    }
    Ok(())
}

/// The images of one run (a frame of the trial `trial_id`), each numbered by its frame
/// ([`trials::image_number`]).
fn write_images(
    trial_id: &str,
    run: &RunExport,
    setup: &Setup,
    options: &Options,
    write: &mut Write,
) -> Result<(), Error> {
    let id = &run.truth.run.id;
    let dense_bright = options.dense_matter == DenseMatter::Bright;
    let invert = inverts(setup, options.dense_matter);
    let number = trials::image_number(run.truth.run.frame.as_ref());
    for image in &run.truth.images {
        let stem = format!("{}-{}", image.exposure, image.detector);
        let (det, (w, h, pixels)) = run_image(run, image, &stem)?;
        let converted = export_pixels(&pixels, w, det.i_max(), invert);
        let description = format!(
            "rsasim export: run {id}, image {stem}, rows flipped (bottom row first), {}scaled to 0..65535 from 0..{}, dense matter {}",
            if invert { "inverted and " } else { "" },
            det.i_max(),
            if dense_bright { "bright" } else { "dark" }
        );
        let bytes = encode_tiff(
            w,
            h,
            &converted,
            TiffCompression::Lzw,
            &TiffFacts {
                description: &description,
                software: &crate::output::program(),
                pixel_pitch_mm: det.frame().pixel_pitch_mm,
                i_max: u16::MAX,
            },
        )
        .map_err(Error::Write)?;
        write(
            &format!("{trial_id}/images/{stem}/{stem}.{number}.tif"),
            &bytes,
        )?;
    }
    Ok(())
}

/// The models of a trial: every phantom with a mesh or beads, other than the calibration box,
/// its bead table (XMALab) and its mesh, from the first frame (the same in every frame).
fn write_models(
    trial: &TrialExport,
    setup: &Setup,
    xmalab: bool,
    write: &mut Write,
) -> Result<(), Error> {
    let id = &trial.id;
    for phantom in trial
        .first()
        .truth
        .run
        .phantoms
        .iter()
        .filter(|p| p.kind != "calibration_box")
    {
        if xmalab {
            let beads: Vec<(String, DVec3)> = phantom
                .markers
                .iter()
                .map(|m| (m.id.clone(), phantom.pose().to_local(m.position_mm)))
                .collect();
            if !beads.is_empty() {
                write(
                    &format!("{id}/models/{}_markers.csv", phantom.id),
                    xmalab::marker_reference_csv(&beads).as_bytes(),
                )?;
            }
        }
        if let Some(mesh) = setup.meshes.get(&phantom.id) {
            if xmalab {
                write(
                    &format!("{id}/models/{}.obj", phantom.id),
                    super::mesh_text::obj(mesh).as_bytes(),
                )?;
            } else {
                let mut bytes = Vec::new();
                crate::phantom::mesh_io::write_stl(mesh, &mut bytes).map_err(Error::Write)?;
                write(&format!("{id}/models/{}.stl", phantom.id), &bytes)?;
            }
        }
    }
    Ok(())
}

/// Autoscoper: a `.cfg` per exposure holding a model, and each volume's true pose in every frame
/// as `truth/<exposure>_<phantom>.tra`, one line per frame in frame order.
fn write_autoscoper_trials(
    trial: &TrialExport,
    volumes: &[ModelVolume],
    write: &mut Write,
) -> Result<(), Error> {
    let id = &trial.id;
    for exposure in &trial.first().truth.run.exposures {
        let held: Vec<&ModelVolume> = exposure
            .phantoms
            .iter()
            .filter_map(|p| volumes.iter().find(|v| &v.phantom == p))
            .collect();
        if held.is_empty() {
            // Nothing to track (e.g. the box alone): Autoscoper refuses a trial without a
            // volume (`Trial::validate`: "There must be at least one volume file").
            continue;
        }
        let text = autoscoper::trial_cfg(
            &trial
                .cameras
                .iter()
                .map(|(d, _)| d.as_str())
                .collect::<Vec<_>>(),
            &exposure.id,
            &held
                .iter()
                .map(|v| autoscoper::TrialVolume {
                    phantom: &v.phantom,
                    voxel_mm: v.grid.voxel_mm,
                    offset_mm: v.grid.offset_mm.to_array(),
                })
                .collect::<Vec<_>>(),
        );
        write(&format!("{id}/{}.cfg", exposure.id), text.as_bytes())?;
        for v in held {
            let lines: Vec<String> = trial
                .frames
                .iter()
                .filter_map(|run| run.truth.run.phantoms.iter().find(|p| p.id == v.phantom))
                .map(|phantom| {
                    volume::tra_line(&volume::tra_matrix(&phantom.pose(), v.grid.offset_mm))
                })
                .collect();
            if lines.is_empty() {
                continue;
            }
            write(
                &format!("{id}/truth/{}_{}.tra", exposure.id, v.phantom),
                lines.concat().as_bytes(),
            )?;
        }
    }
    Ok(())
}

/// The export's README.md: what was exported, from which output, with which calibration.
fn readme(out: &Path, options: &Options, trials: &[TrialExport], setup: &Setup) -> String {
    let dense_bright = options.dense_matter == DenseMatter::Bright;
    let invert = inverts(setup, options.dense_matter);
    let sequences = trials.iter().any(TrialExport::is_sequence);
    let calibration = match &options.calibration_from {
        None => "the TRUE calibration (the exact source and detector poses of truth.json): the \
                 exam's known calibration"
            .to_string(),
        Some(name) if sequences => format!(
            "the calibration measured in each run's `{name}` (a sequence's: its first frame's)"
        ),
        Some(name) => format!("the calibration measured in each run's `{name}`"),
    };
    let cube = if options.target == Target::Xmalab {
        readme_cube(trials)
    } else {
        String::new()
    };
    let tra_lines = if sequences {
        "one line per frame, in frame order (one line for a run without frames), each of 16 \
         comma-separated values"
    } else {
        "one line of 16 comma-separated values"
    };
    format!(
        "# rsasim export for {program}\n\n\
         Written by {version} from the output folder `{out}` ({n}).\n\n\
         - Cameras (MayaCam 2.0{dlt}) hold {calibration}.\n\
         {cube}\
         - Images are the run's TIFFs with their rows flipped (bottom row first), {inv}scaled to \
         the full 16-bit range: dense matter (beads, implants, bone) is {shade}. The flip makes each beamline a standard pinhole camera; pixel \
         coordinates in these images are not rsasim's.\n\
         - Units: mm; world frame: the calibration box frame of truth.json.\n\
         {volumes}\
         - One folder per run, since every run has its own geometry. {sequence}See rsasim's manual, \
         docs/src/guide/xmalab-autoscoper.md, for the steps in {program} and how to score its results with \
         `rsasim evaluate`.\n{partial}",
        program = match options.target {
            Target::Xmalab => "XMALab",
            Target::Autoscoper => "Autoscoper",
        },
        version = crate::output::program(),
        out = out.display(),
        n = readme_count(trials),
        dlt = if options.target == Target::Xmalab {
            " and DLT-11"
        } else {
            ""
        },
        inv = if invert {
            "inverted (I_max − value) and "
        } else {
            ""
        },
        shade = if dense_bright { "bright" } else { "dark" },
        volumes = if options.target == Target::Autoscoper {
            format!(
                "- Volumes (`volumes/<phantom>.tif`, one multi-page 16-bit TIFF per model, \
                 `VolumeFlip 0 1 1`, voxels of {} mm): the model mesh voxelized (a voxel is \
                 inside when its centre is), inside = round(6553.5 · μ) with μ in 1/mm of the \
                 phantom's material at {:.3} keV, 0 outside; `volumes/<phantom>.stl` is the mesh \
                 in the volume frame. The volume frame is the phantom's frame shifted by the \
                 offset each trial's `.cfg` states in a comment. `<run>/truth/<exposure>_<phantom>.tra` \
                 holds the true pose of each volume: {tra_lines}, the \
                 4×4 matrix world ← volume row by row (Autoscoper's \"matrix, row\" layout). \
                 A trial is written for every exposure holding a model.\n",
                options.voxel_mm,
                volume_energy_kev(setup)
            )
        } else {
            String::new()
        },
        sequence = if sequences { READ_ME_SEQUENCES } else { "" },
        partial = readme_partial(trials),
    )
}

/// What the README's first line says was exported: `4 run(s)`, or with sequences the trials
/// and their frames.
fn readme_count(trials: &[TrialExport]) -> String {
    let sequences = trials.iter().filter(|t| t.is_sequence()).count();
    if sequences == 0 {
        return format!("{} run(s)", trials.len());
    }
    let frames: usize = trials
        .iter()
        .filter(|t| t.is_sequence())
        .map(|t| t.frames.len())
        .sum();
    format!(
        "{} trial(s): {sequences} sequence(s) of {frames} frame(s) in all, {} run(s) without frames",
        trials.len(),
        trials.len() - sequences
    )
}

/// The README's words on the layout of a sequence's trial.
const READ_ME_SEQUENCES: &str = "A sequence is one folder, one trial, named by its sequence id \
     (`n0-r00` for the runs `n0-r00-f0000`, `n0-r00-f0001`, …): its frames share one geometry, so \
     its cameras, models and trial files are written once; its images are \
     `images/<exposure>-<detector>/<exposure>-<detector>.<frame index + 1>.tif`, zero-padded to \
     one width (at least 4 digits), so that the name order XMALab and Autoscoper read them in is \
     frame order; the truth `.tra` holds one line per frame, as Autoscoper saves a tracking. Save \
     each program's results for a sequence into its folder: `rsasim evaluate` reads line (or \
     row) k as the trial's k-th frame. ";

/// The README's list of the sequences of which the output holds only some frames (a shard's).
fn readme_partial(trials: &[TrialExport]) -> String {
    let partial: Vec<String> = trials
        .iter()
        .filter_map(partial_sequence)
        .map(|n| format!("  - {n}\n"))
        .collect();
    if partial.is_empty() {
        return String::new();
    }
    format!(
        "\nThis output holds only some frames of these sequences (a shard's), so their trials \
         hold only those:\n{}",
        partial.concat()
    )
}

/// The README's paragraph on XMALab's calibration object: where it is written, the rule, and
/// why it is not where it is not.
fn readme_cube(trials: &[TrialExport]) -> String {
    let with = trials
        .iter()
        .filter(|r| matches!(r.references, Some((_, Ok(_)))))
        .count();
    let without: Vec<String> = trials
        .iter()
        .filter_map(|r| match &r.references {
            Some((_, Err(e))) => Some(format!("  - {}: {e}\n", r.label())),
            _ => None,
        })
        .collect();
    format!(
        "- XMALab's calibration object (`calibration/frame_specification.csv`, \
         `calibration/references.ref`, for XMALab's own cube calibration) is written for {} of \
         {} {}. Its four reference beads are chosen by rule: visible and at least {} bead \
         diameters from every other bead's image and from the border in every calibration \
         view, on plates seen at least {}° from edge-on, spanning a tetrahedron of at least {} \
         of the beads' bounding box.\n{}",
        with,
        trials.len(),
        trials_word(trials),
        reference_beads::MIN_SEPARATION_DIAMETERS,
        reference_beads::MIN_PLATE_ANGLE_DEG,
        reference_beads::MIN_VOLUME_FRACTION,
        if without.is_empty() {
            String::new()
        } else {
            format!("  Not written:\n{}", without.concat())
        }
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixels_are_flipped_and_scaled_by_hand() {
        // 2 × 2 image of a 12-bit detector: rows [0, 4095], [2048, 1].
        let p = export_pixels(&[0, 4095, 2048, 1], 2, 4095, false);
        // Rows swapped; 2048·65535/4095 = 32775.99… → 32776; 1·65535/4095 = 16.0037 → 16.
        assert_eq!(p, vec![32776, 16, 0, 65535]);
        let inv = export_pixels(&[0, 4095, 2048, 1], 2, 4095, true);
        assert_eq!(inv, vec![32759, 65519, 65535, 0]);
    }
}

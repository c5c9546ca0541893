//! The evaluation stage: score what a software under test reconstructed against the
//! simulator's truth, by ISO 5725 trueness and precision (docs/src/reference/conventions.md, "Accuracy"), and write the
//! paper's tables (Tables 1–4) plus the analyses RSA guidelines ask for.
//!
//! It needs no images: only each run's `truth.json` and the software's results (a
//! `measured.json` per run, or one CSV long table).

// The modules of the crates below under the names this crate's code uses (`crate::scenario`, ...).
use rsasim_core::{diagnostic, geometry, input_file, phantom};
use rsasim_files::interop;
use rsasim_migration as migration;

mod assemble;
pub mod input;
pub mod iso5725;
pub mod report;
pub mod residual;
pub mod rotation;
pub mod sequence;
pub mod stats;
pub mod study;
pub mod table;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::DVec3;
use sha2::{Digest, Sha256};

use crate::diagnostic::Diagnostic;
use assemble::{MtpmPoints, Scored, assemble};
use input::{
    RunMeasurement, check_same_entities, load_measured_csv, load_per_run, load_truths_from,
};
use rsasim_core::scenario::{self, hex};
use rsasim_files::output;
use stats::Confidence;
use table::{Report, Table};

/// Where the software's results are.
#[derive(Debug, Clone)]
pub enum MeasuredSource {
    /// The default: `measured.json` if any run folder holds one; else the one `measured*.json`
    /// name the run folders hold (e.g. `measured-rsasim-dlt-markers.json`, said in a note);
    /// several names are an error listing them.
    Auto,
    /// A file of this name in every run folder. A name ending in `.csv` is read as XMALab's
    /// export of the run's trial ([`crate::interop::xmalab::read_export`]), one ending in `.tra`
    /// as Autoscoper's tracking of it ([`crate::interop::autoscoper_tracking::read_tracking`]).
    PerRun(String),
    /// A file of this name in `dir/<run id>/` for every run (e.g. the folder `rsasim export`
    /// wrote, where XMALab's exports were saved); XMALab's and Autoscoper's files of a sequence
    /// in `dir/<sequence id>/`, one for all its frames ([`input::load_per_run`]).
    PerRunIn {
        /// The file name.
        name: String,
        /// The folder holding one sub-folder per run.
        dir: PathBuf,
    },
    /// One CSV long table for all runs.
    Csv(PathBuf),
}

/// Options of `rsasim evaluate`.
#[derive(Debug, Clone)]
pub struct Options {
    /// Where the results are.
    pub measured: MeasuredSource,
    /// τ's confidence level and sidedness.
    pub confidence: Confidence,
    /// The MTPM cells are compared with, mm ([`DEFAULT_MTPM_THRESHOLD_MM`] by default).
    pub mtpm_threshold_mm: f64,
    /// A clinical study's options (used when the folder has `study.json`).
    pub study: study::StudyOptions,
    /// How XMALab's 2-D point exports were written (y axis, first pixel), which their files
    /// do not say.
    pub xmalab_2d: crate::interop::xmalab_points2d::PixelOptions,
    /// Which source position the sources are scored against.
    pub source_truth: SourceTruth,
}

/// The true source position the sources' residuals are taken from (docs/src/reference/conventions.md,
/// "Focal spot").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SourceTruth {
    /// `position_mm`: the focal spot's geometric centre (the default).
    #[default]
    Geometric,
    /// `effective_position_mm` where the truth has it (a spot whose emission falls across it),
    /// else `position_mm`: the spot's intensity-weighted centre, what a calibration of the
    /// images finds.
    Effective,
}

/// The default MTPM threshold, mm: the continuous migration between one and two years above
/// which a knee prosthesis is at risk of loosening (Ryd et al. 1995), the smallest migration a
/// clinical RSA study of knees acts on.
pub const DEFAULT_MTPM_THRESHOLD_MM: f64 = 0.2;

/// Scores every run of the output folder `out`. Runs without results are listed as excluded;
/// malformed results are errors naming file, line and field.
pub fn evaluate(out: &Path, options: &Options) -> Result<Report, Vec<Diagnostic>> {
    evaluate_with_truth(out, None, options)
}

/// [`evaluate`], with the truth read from `truth_dir` when given (the blind layout: `out` is the
/// images folder holding the results, `truth_dir` its truth folder). The truth (every
/// `truth.json` and `scenario.toml`) is verified against its manifest first, and in the blind
/// layout the binding of both folders ([`crate::output::truth_check::verify_truth`]): a modified or missing
/// truth file is an error naming it.
pub fn evaluate_with_truth(
    out: &Path,
    truth_dir: Option<&Path>,
    options: &Options,
) -> Result<Report, Vec<Diagnostic>> {
    output::check_output_folder(out)?;
    if let Some(t) = truth_dir {
        output::check_output_folder(t)?;
    }
    let truth_root = truth_dir.unwrap_or(out);
    crate::output::truth_check::verify_truth(truth_root, truth_dir.map(|_| out))?;
    let mut truths = load_truths_from(truth_root, out)?;
    check_same_entities(&truths)?;
    if let MeasuredSource::PerRunIn { dir, .. } = &options.measured {
        for t in &mut truths {
            t.dir = dir.join(&t.truth.run.id);
        }
    }
    let mut notes = Vec::new();
    let measured = match &options.measured {
        MeasuredSource::Auto => {
            let (name, note) = default_results_name(&truths)?;
            notes.extend(note);
            MeasuredSource::PerRun(name)
        }
        other => other.clone(),
    };
    let results_file = match &measured {
        MeasuredSource::Csv(file) => file.display().to_string(),
        MeasuredSource::PerRun(name) | MeasuredSource::PerRunIn { name, .. } => name.clone(),
        MeasuredSource::Auto => String::new(),
    };
    let measurements: BTreeMap<String, RunMeasurement> = match &measured {
        MeasuredSource::Auto => BTreeMap::new(),
        MeasuredSource::Csv(file) => load_measured_csv(file, &truths)?,
        MeasuredSource::PerRun(name) => {
            load_per_run(name, None, &truths, truth_root, options.xmalab_2d)?
        }
        MeasuredSource::PerRunIn { name, dir } => {
            load_per_run(name, Some(dir), &truths, truth_root, options.xmalab_2d)?
        }
    };
    let study = study::load_study(truth_root)?;
    let csv_only = study.is_some() && options.study.migration_csv.is_some();
    if measurements.is_empty() && !csv_only {
        let what = match &measured {
            MeasuredSource::Auto => "no results found".to_string(),
            MeasuredSource::PerRun(name) => format!(
                "no run folder under {} holds a {name}",
                out.join("runs").display()
            ),
            MeasuredSource::PerRunIn { name, dir } => {
                format!("no run folder under {} holds a {name}", dir.display())
            }
            MeasuredSource::Csv(file) => format!("{} has no rows", file.display()),
        };
        return Err(vec![Diagnostic::file_error(out, what)
            .with_help("run the software under test first (e.g. `rsasim reconstruct OUT`), or point --measured / --csv at its results")]);
    }

    let study_report = match &study {
        Some(s) => Some(study::evaluate_study(
            out,
            s,
            &measurements,
            &options.confidence,
            &options.study,
        )?),
        None => None,
    };
    let scenario_file = truth_root.join("scenario.toml");
    let loaded = scenario::load(&scenario_file)?;
    let (mtpm_points, mtpm_notes) = mtpm_points(&loaded, &truths);
    notes.extend(mtpm_notes);
    let scored: Vec<Scored> = truths
        .iter()
        .map(|t| Scored {
            truth: t,
            measured: measurements.get(&t.truth.run.id),
        })
        .collect();
    let (tables, mtpm, group_analyses, excluded, runs_scored) = assemble(
        &scored,
        &mtpm_points,
        &options.confidence,
        options.source_truth,
    );
    notes.extend(source_truth_note(&truths, options.source_truth));
    let sequence = sequence::score(&loaded.scenario, &scored);
    check_finite(&tables, mtpm.as_ref(), &results_file)?;
    let repaired_rotations: usize = measurements.values().map(|m| m.repaired_rotations).sum();
    if repaired_rotations > 0 {
        notes.push(format!(
            "{repaired_rotations} rotation(s) were re-orthonormalised (deviation from a proper rotation above round-off, at most {:e}, e.g. values rounded to 6 decimals)",
            rotation::REPAIR_TOLERANCE
        ));
    }
    let manifest_sha256 = crate::output::received::ReceivedFolder::unlisted(truth_root)
        .read("manifest.json", crate::output::received::MAX_MANIFEST_BYTES)
        .map(|b| {
            format!(
                "{} (every truth.json and scenario.toml verified against it)",
                hex(&Sha256::digest(&b))
            )
        })
        .unwrap_or_else(|_| "(no manifest.json)".into());
    let mut software: Vec<String> = measurements.values().map(|m| m.software.clone()).collect();
    software.sort();
    software.dedup();
    Ok(Report {
        program: output::program(),
        scenario: loaded.scenario.name.clone(),
        manifest_sha256,
        summary: summary(&loaded.scenario, truths.len()),
        software,
        results_file,
        repaired_rotations,
        notes,
        confidence: options.confidence,
        runs_scored,
        excluded,
        tables,
        mtpm,
        mtpm_threshold_mm: options.mtpm_threshold_mm,
        group_analyses,
        study: study_report,
        sequence,
    })
}

/// What the report says of the source truth scored against, when it matters: the truth has an
/// effective source apart from the focal spot's centre.
fn source_truth_note(truths: &[input::TruthRun], chosen: SourceTruth) -> Option<String> {
    let apart = truths
        .iter()
        .flat_map(|t| &t.truth.run.sources)
        .filter_map(|s| {
            s.effective_position_mm
                .map(|e| (DVec3::from_array(e) - s.position_mm).length())
        })
        .fold(None, |m: Option<f64>, d| Some(m.map_or(d, |m| m.max(d))));
    let apart = apart?;
    Some(match chosen {
        SourceTruth::Geometric => format!(
            "sources are scored against the focal spot's geometric centre (position_mm); the spot's intensity-weighted centre, which a calibration of the images finds, lies up to {apart:.4} mm from it (score against it with --source-truth effective)"
        ),
        SourceTruth::Effective => format!(
            "sources are scored against the focal spot's intensity-weighted centre (effective_position_mm), up to {apart:.4} mm from its geometric centre"
        ),
    })
}

/// Points for MTPM per model: its beads (local frame, recovered from the first run's truth),
/// or the corners of its mesh's bounding box when it has no beads. A model that gets no points
/// (its mesh cannot be built, or it has neither beads nor a mesh) has no MTPM column; the notes
/// say which and why.
fn mtpm_points(
    loaded: &scenario::LoadedScenario,
    truths: &[input::TruthRun],
) -> (MtpmPoints, Vec<String>) {
    let run = &truths[0].truth.run;
    let built = crate::phantom::build(loaded);
    let build_error = built.as_ref().err().map(|errors| {
        errors
            .iter()
            .map(|d| d.message.clone())
            .collect::<Vec<_>>()
            .join("; ")
    });
    let models = built.ok();
    let mut notes = Vec::new();
    let mut out = MtpmPoints::new();
    for p in run.phantoms.iter().filter(|p| p.kind != "calibration_box") {
        let pose = p.pose();
        let mut points: Vec<DVec3> = p
            .markers
            .iter()
            .map(|m| pose.to_local(m.position_mm))
            .collect();
        if points.is_empty()
            && let Some(mesh) = models
                .as_ref()
                .and_then(|ms| ms.iter().find(|m| m.id == p.id))
                .and_then(|m| m.mesh.as_ref())
        {
            let (lo, hi) = mesh.bounds_mm();
            points = (0..8)
                .map(|k| {
                    DVec3::new(
                        if k & 1 == 0 { lo.x } else { hi.x },
                        if k & 2 == 0 { lo.y } else { hi.y },
                        if k & 4 == 0 { lo.z } else { hi.z },
                    )
                })
                .collect();
        }
        if points.is_empty() {
            notes.push(match &build_error {
                Some(e) => format!(
                    "no MTPM column for model {}: it has no beads and its mesh could not be built: {e}",
                    p.id
                ),
                None => format!(
                    "no MTPM column for model {}: it has neither beads nor a mesh",
                    p.id
                ),
            });
        }
        out.insert(p.id.clone(), points);
    }
    (out, notes)
}

/// Every cell's trueness, precision and RMS must be finite where defined: measured values are
/// bounded ([`input::MAX_ABS_MM`]), so anything else is a bug, reported instead of printed.
fn check_finite(
    tables: &[Table],
    mtpm: Option<&Table>,
    results: &str,
) -> Result<(), Vec<Diagnostic>> {
    for t in tables.iter().chain(mtpm) {
        for row in &t.rows {
            for c in row.cells.iter().flatten() {
                let defined = [c.trueness, c.rms];
                if defined.iter().any(|x| !x.is_finite()) || c.precision.is_infinite() {
                    return Err(vec![
                        Diagnostic::file_error(
                            Path::new(results),
                            format!(
                                "table {} at noise level {}: a statistic is not finite",
                                t.id, row.noise_level
                            ),
                        )
                        .with_help("check the results for implausible values"),
                    ]);
                }
            }
        }
    }
    Ok(())
}

/// The default results name (see [`MeasuredSource::Auto`]), with a note when it is not
/// `measured.json`.
fn default_results_name(
    truths: &[input::TruthRun],
) -> Result<(String, Option<String>), Vec<Diagnostic>> {
    const DEFAULT: &str = "measured.json";
    if truths.iter().any(|t| t.dir.join(DEFAULT).is_file()) {
        return Ok((DEFAULT.into(), None));
    }
    let mut names: Vec<String> = truths
        .iter()
        .filter_map(|t| std::fs::read_dir(&t.dir).ok())
        .flat_map(|entries| entries.flatten())
        .filter(|e| e.path().is_file())
        .filter_map(|e| e.file_name().to_str().map(str::to_string))
        .filter(|n| n.starts_with("measured") && n.ends_with(".json"))
        .collect();
    names.sort();
    names.dedup();
    match names.as_slice() {
        [] => Ok((DEFAULT.into(), None)),
        [one] => Ok((
            one.clone(),
            Some(format!(
                "results: {one} (no measured.json; the only results file name in the run folders)"
            )),
        )),
        several => {
            let dir = truths[0].dir.parent().unwrap_or(&truths[0].dir);
            Err(vec![
                Diagnostic::file_error(
                    dir,
                    format!(
                        "no measured.json, and the run folders hold {} results files: {}",
                        several.len(),
                        several.join(", ")
                    ),
                )
                .with_help(format!(
                    "say which to score, e.g. --measured {}",
                    several[0]
                )),
            ])
        }
    }
}

/// Human-readable lines describing the set-up, for the report header.
fn summary(s: &scenario::Scenario, runs: usize) -> Vec<String> {
    let levels = s.levels();
    let (what, shown): (&str, Vec<String>) = if s.imaging.is_attenuation() {
        (
            "exposure level(s)",
            levels
                .iter()
                .map(|l| format!("×{}", l.exposure_factor.unwrap_or(1.0)))
                .collect(),
        )
    } else {
        (
            "noise level(s)",
            levels
                .iter()
                .map(|l| format!("{}%", l.noise_level * 100.0))
                .collect(),
        )
    };
    let mut lines = vec![format!(
        "Protocol: {} {what} ({}) × {} run(s) = {runs} runs; seed {}",
        levels.len(),
        shown.join(", "),
        s.protocol.runs_per_level,
        s.seed
    )];
    for d in &s.detectors {
        let pitch = d.resolved_pixel_pitch_mm();
        lines.push(format!(
            "Beamline {} → {}: {}×{} px, pitch {:.4}×{:.4} mm, {} bpp",
            d.source, d.id, d.pixels[0], d.pixels[1], pitch[0], pitch[1], d.bpp
        ));
    }
    for p in &s.phantoms {
        let what = match p.shape() {
            scenario::PhantomShape::Beads(b) => format!("{} bead(s)", b.len()),
            scenario::PhantomShape::CalibrationBox(b) => {
                format!("calibration box, {} plate(s)", b.plates.len())
            }
            scenario::PhantomShape::Mesh(m) => {
                format!("mesh {}, {} bead(s)", m.file, m.beads.len())
            }
            scenario::PhantomShape::EllipticCylinder(c) => format!(
                "elliptic cylinder {}×{} mm, {} mm long",
                2.0 * c.radii_mm[0],
                2.0 * c.radii_mm[1],
                c.length_mm
            ),
        };
        lines.push(format!("Phantom {}: {what}", p.id));
    }
    lines
}

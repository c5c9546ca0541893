//! The evaluation stage: score what a software under test reconstructed against the
//! simulator's truth, by ISO 5725 trueness and precision (DESIGN.md, "Accuracy"), and write the
//! paper's tables (Tables 1–4) plus the analyses RSA guidelines ask for.
//!
//! It needs no images: only each run's `truth.json` and the software's results (a
//! `measured.json` per run, or one CSV long table).

mod assemble;
pub mod input;
pub mod iso5725;
pub mod report;
pub mod residual;
pub mod rotation;
pub mod stats;
pub mod table;
pub mod truth_check;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::DVec3;
use sha2::{Digest, Sha256};

use crate::diagnostic::Diagnostic;
use crate::output;
use crate::scenario::{self, hex};
use assemble::{MtpmPoints, Scored, assemble};
use input::{RunMeasurement, load_measured_csv, load_measured_json, load_truths_from};
use stats::Confidence;
use table::Report;

/// Where the software's results are.
#[derive(Debug, Clone)]
pub enum MeasuredSource {
    /// A file of this name in every run folder (default `measured.json`).
    PerRun(String),
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
}

/// Scores every run of the output folder `out`. Runs without results are listed as excluded;
/// malformed results are errors naming file, line and field.
pub fn evaluate(out: &Path, options: &Options) -> Result<Report, Vec<Diagnostic>> {
    evaluate_with_truth(out, None, options)
}

/// [`evaluate`], with the truth read from `truth_dir` when given (the blind layout: `out` is the
/// images folder holding the results, `truth_dir` its truth folder). The truth (every
/// `truth.json` and `scenario.toml`) is verified against its manifest first, and in the blind
/// layout the binding of both folders ([`truth_check::verify_truth`]): a modified or missing
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
    truth_check::verify_truth(truth_root, truth_dir.map(|_| out))?;
    let truths = load_truths_from(truth_root, out)?;
    let measurements: BTreeMap<String, RunMeasurement> = match &options.measured {
        MeasuredSource::Csv(file) => load_measured_csv(file, &truths)?,
        MeasuredSource::PerRun(name) => {
            let mut found = BTreeMap::new();
            let mut errors = Vec::new();
            for t in &truths {
                let file = t.dir.join(name);
                if !file.exists() {
                    continue;
                }
                match load_measured_json(&file, &t.truth) {
                    Ok(m) => drop(found.insert(t.truth.run.id.clone(), m)),
                    Err(e) => errors.extend(e),
                }
            }
            if !errors.is_empty() {
                return Err(errors);
            }
            found
        }
    };
    if measurements.is_empty() {
        let what = match &options.measured {
            MeasuredSource::PerRun(name) => format!(
                "no run folder under {} holds a {name}",
                out.join("runs").display()
            ),
            MeasuredSource::Csv(file) => format!("{} has no rows", file.display()),
        };
        return Err(vec![Diagnostic::file_error(out, what)
            .with_help("run the software under test first (e.g. `rsasim reconstruct OUT`), or point --measured / --csv at its results")]);
    }

    let scenario_file = truth_root.join("scenario.toml");
    let loaded = scenario::load(&scenario_file)?;
    let mtpm_points = mtpm_points(&loaded, &truths);
    let scored: Vec<Scored> = truths
        .iter()
        .map(|t| Scored {
            truth: t,
            measured: measurements.get(&t.truth.run.id),
        })
        .collect();
    let (tables, mtpm, group_analyses, excluded, runs_scored) =
        assemble(&scored, &mtpm_points, &options.confidence);
    let manifest_sha256 = std::fs::read(truth_root.join("manifest.json"))
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
        confidence: options.confidence,
        runs_scored,
        excluded,
        tables,
        mtpm,
        group_analyses,
    })
}

/// Points for MTPM per model: its beads (local frame, recovered from the first run's truth),
/// or the corners of its mesh's bounding box when it has no beads.
fn mtpm_points(loaded: &scenario::LoadedScenario, truths: &[input::TruthRun]) -> MtpmPoints {
    let run = &truths[0].truth.run;
    let models = crate::phantom::build(loaded).ok();
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
        out.insert(p.id.clone(), points);
    }
    out
}

/// Human-readable lines describing the set-up, for the report header.
fn summary(s: &scenario::Scenario, runs: usize) -> Vec<String> {
    let mut lines = vec![format!(
        "Protocol: {} noise level(s) ({}) × {} run(s) = {runs} runs; seed {}",
        s.protocol.noise_levels.len(),
        s.protocol
            .noise_levels
            .iter()
            .map(|l| format!("{}%", l * 100.0))
            .collect::<Vec<_>>()
            .join(", "),
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
        };
        lines.push(format!("Phantom {}: {what}", p.id));
    }
    lines
}

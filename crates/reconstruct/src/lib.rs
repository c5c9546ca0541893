//! The reference RSA program: what a real RSA software does, from the images alone.
//!
//! It sees only what an operator has: the images, the nominal set-up (the scenario without its
//! random draws), the box bead table and the model files in `OUT/phantoms/`. It never reads the
//! ground truth: nothing in this module refers to the truth records or their files.

// The modules of the crates below under the names this crate's code uses (`crate::scenario`, ...).
#[cfg(test)]
use rsasim_core::random;
use rsasim_core::{attenuation, diagnostic, expand, geometry, phantom, scenario, trace};
use rsasim_files::output;
use rsasim_migration as migration;
pub mod bead_centre;
pub mod bead_profile;
pub mod beads;
pub mod calibrate;
pub mod contour;
pub mod correspond;
pub mod density;
pub mod detect;
pub mod edge;
pub mod edge_model;
pub mod model;
pub mod model_outline;
pub mod model_shadow;
pub mod overprojection;
pub mod pipeline;
pub mod run_images;
pub mod selvik;
pub mod shadow;
pub mod silhouette;
pub mod split;
pub mod study;
pub mod winding;

use std::collections::BTreeMap;
use std::path::Path;

use rayon::prelude::*;

use crate::diagnostic::Diagnostic;
use crate::output::atomic::write_atomic;
use crate::output::exam;

/// How `reconstruct` calibrates each beamline from the box beads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// Normalised DLT on the beads of both facing plates, decomposition with the known pitch and a
    /// joint 9-parameter Levenberg–Marquardt fit ([`calibrate::calibrate`]).
    #[default]
    Dlt,
    /// Selvik's classic cage method: homography from the fiducial plate, focus from the control
    /// plate, detector from both with the known pitch ([`selvik::calibrate_selvik`]).
    Selvik,
}

impl Method {
    /// Short name, as the command line spells it.
    pub fn name(self) -> &'static str {
        match self {
            Method::Dlt => "dlt",
            Method::Selvik => "selvik",
        }
    }
}

/// Whether a DLT calibration fits the beads of the plates seen within 45° of edge-on (matched
/// once a first calibration from the facing plates predicts them). Such a plate of acrylic is
/// imaged as a dense band along its beads' dense lines; on blurred attenuation images the
/// planar background under each bead does not fit the band's edges, and the beads' centres
/// shorten the measured source distance (docs/src/results/biases.md measures it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum EdgeOnPlates {
    /// Fit them unless the plate itself is imaged (attenuation mode, a plate with a thickness).
    #[default]
    Auto,
    /// Always fit them.
    Fit,
    /// Never fit them.
    Skip,
}

impl EdgeOnPlates {
    /// Whether the beads of a plate seen edge-on are fitted, the plate being `imaged` or not.
    pub fn fits(self, imaged: bool) -> bool {
        match self {
            EdgeOnPlates::Auto => !imaged,
            EdgeOnPlates::Fit => true,
            EdgeOnPlates::Skip => false,
        }
    }
}

/// How `reconstruct` finds a model's pose.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelMethod {
    /// Marker-based RSA: triangulate the model's beads and fit its bead table
    /// ([`model::find_model`]).
    Markers,
    /// Model-based RSA: fit the model mesh's projected outline to the shadow's edges in every
    /// view ([`silhouette::fit_silhouette`]); needs no beads.
    Silhouette,
}

impl ModelMethod {
    /// Short name, as the command line spells it.
    pub fn name(self) -> &'static str {
        match self {
            ModelMethod::Markers => "markers",
            ModelMethod::Silhouette => "silhouette",
        }
    }

    /// The method for a model: `chosen` if given, else markers when the model has beads and
    /// silhouette when it has none.
    pub fn for_model(chosen: Option<ModelMethod>, has_beads: bool) -> ModelMethod {
        chosen.unwrap_or(if has_beads {
            ModelMethod::Markers
        } else {
            ModelMethod::Silhouette
        })
    }
}

/// Options of `rsasim reconstruct`.
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// How every beamline is calibrated.
    pub method: Method,
    /// How every model is found; `None`: by [`ModelMethod::for_model`].
    pub model_method: Option<ModelMethod>,
    /// File name of the results in every run folder; `None`: [`default_results_name`].
    pub measured: Option<String>,
    /// Replace a results file of that name even when another software wrote it.
    pub overwrite: bool,
    /// A clinical study's marker-stability threshold, mm; `None`:
    /// [`crate::migration::DEFAULT_STABILITY_THRESHOLD_MM`].
    pub stability_threshold_mm: Option<f64>,
    /// The profile fitted to a bead in attenuation-mode images; `None`: chosen per set-up
    /// ([`pipeline::bead_centre_method`]).
    pub bead_centre: Option<beads::Centre>,
    /// DLT: whether the beads of plates seen edge-on are fitted.
    pub edge_on_plates: EdgeOnPlates,
}

/// A run's entity that could not be reconstructed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EntityFailure {
    /// Run id.
    pub run: String,
    /// What and why, e.g. `model femur (markers): not found: …`.
    pub reason: String,
}

/// What `reconstruct` did.
pub struct Summary {
    /// Runs reconstructed (a results file written).
    pub runs: usize,
    /// Runs that failed as a whole, with the reason.
    pub failed: Vec<(String, String)>,
    /// The results file name written into every run folder.
    pub measured: String,
    /// Model fits attempted over every run.
    pub models_tried: usize,
    /// Model fits that found the model.
    pub models_found: usize,
    /// Detectors not calibrated and models not found, per run.
    pub failures: Vec<EntityFailure>,
    /// A clinical study (OUT holds `study.json`): the migration file written and its
    /// migrations count, and what could not be measured.
    pub migration: Option<study::StudyOutcome>,
}

impl Summary {
    /// Whether nothing at all was reconstructed: no run, or models to find and none found.
    pub fn nothing_reconstructed(&self) -> bool {
        self.runs == 0 || (self.models_tried > 0 && self.models_found == 0)
    }
}

/// The default results name: `measured-rsasim-<calibration>-<model>.json`, the model part being
/// the one method every model is found by, or `auto` when they differ (or there is no model).
pub fn default_results_name(method: Method, model_label: &str) -> String {
    format!("measured-rsasim-{}-{model_label}.json", method.name())
}

/// The model part of the results name and software: the method's name when every model uses
/// the same one, else `auto`.
fn model_label(setup: &exam::Setup, model_method: Option<ModelMethod>) -> &'static str {
    if let Some(m) = model_method {
        return m.name();
    }
    let mut used: Vec<&str> = setup
        .nominal
        .phantoms
        .iter()
        .filter(|p| p.kind != "calibration_box" && pipeline::fixed_to(setup, &p.id).is_none())
        .map(|p| {
            let has_beads = setup.beads.get(&p.id).is_some_and(|b| !b.is_empty());
            ModelMethod::for_model(None, has_beads).name()
        })
        .collect();
    used.sort_unstable();
    used.dedup();
    match used.as_slice() {
        [one] => one,
        _ => "auto",
    }
}

/// A results name must be a plain file name `measured*.json` (what `evaluate` looks for by
/// default), so it can never name one of the simulator's own records.
fn check_results_name(out: &Path, name: &str) -> Result<(), Vec<Diagnostic>> {
    let plain = !name.contains(['/', '\\', '\0']) && name.len() <= 200;
    if plain && name.starts_with("measured") && name.ends_with(".json") {
        return Ok(());
    }
    let shown: String = name.chars().take(80).collect();
    Err(vec![
        Diagnostic::file_error(
            out,
            format!("--measured `{shown}` is not a usable results file name"),
        )
        .with_help("give a plain file name measured*.json, e.g. measured-rsasim-dlt-markers.json"),
    ])
}

/// Whether `file` may be (re)written: it does not exist, or rsasim wrote it (its `software`
/// starts with [`pipeline::SOFTWARE_PREFIX`]; see
/// [`crate::output::measured::written_by_reference_program`]).
fn ours_or_absent(file: &Path) -> bool {
    std::fs::symlink_metadata(file).is_err()
        || crate::output::measured::written_by_reference_program(file)
}

/// Reconstructs every run folder of `out` and writes the results beside its images, under
/// `options.measured` or [`default_results_name`], calibrating every beamline by
/// `options.method` and finding each model by `options.model_method` (`None`: markers for a
/// model with beads, silhouette for one without; see [`ModelMethod::for_model`]).
///
/// A results file of that name written by another software (or that does not parse) is never
/// replaced unless `options.overwrite`: that is an error listing the files, and nothing is
/// written.
pub fn reconstruct(out: &Path, options: &Options) -> Result<Summary, Vec<Diagnostic>> {
    let setup = exam::load_setup(out)?;
    let runs = exam::run_folders(out)?;
    let label = model_label(&setup, options.model_method);
    let name = options
        .measured
        .clone()
        .unwrap_or_else(|| default_results_name(options.method, label));
    check_results_name(out, &name)?;
    if !options.overwrite {
        let foreign: Vec<Diagnostic> = runs
            .iter()
            .map(|(_, dir)| dir.join(&name))
            .filter(|file| !ours_or_absent(file))
            .map(|file| {
                Diagnostic::file_error(
                    &file,
                    "another software's results (or an unreadable file): rsasim reconstruct does not replace it",
                )
                .with_help("pass --measured NAME to write elsewhere, or --overwrite to replace it")
            })
            .collect();
        if !foreign.is_empty() {
            return Err(foreign);
        }
    }
    // A clinical study's design, read (and checked against the manifest) before any run is.
    let design = crate::output::study::read_study(out)?;
    let software = pipeline::software(
        options.method,
        label,
        options.bead_centre,
        options.edge_on_plates,
    );
    // Each mesh model that will be fitted by its outline is prepared once for all runs.
    let mut outlines = BTreeMap::new();
    for (id, mesh) in &setup.meshes {
        let has_beads = setup.beads.get(id).is_some_and(|b| !b.is_empty());
        if ModelMethod::for_model(options.model_method, has_beads) == ModelMethod::Silhouette {
            let model = model_outline::OutlineModel::new(mesh).map_err(|e| {
                vec![Diagnostic::file_error(
                    &out.join("phantoms"),
                    format!("model {id}: {e}"),
                )]
            })?;
            outlines.insert(id.clone(), model);
        }
    }
    let metal = pipeline::MetalMeshes::of(&setup);
    let methods = pipeline::Methods {
        calibration: options.method,
        model: options.model_method,
        bead_centre: options.bead_centre,
        edge_on_plates: options.edge_on_plates,
    };
    let results: Vec<(String, Result<pipeline::RunResult, String>)> = runs
        .par_iter()
        .map(|(id, dir)| {
            let r =
                pipeline::reconstruct_run(&setup, &outlines, &metal, id, dir, methods, &software)
                    .and_then(|r| {
                        let mut bytes =
                            serde_json::to_vec_pretty(&r.measured).map_err(|e| e.to_string())?;
                        bytes.push(b'\n');
                        write_atomic(&dir.join(&name), &bytes)
                            .map(|_| r)
                            .map_err(|e| format!("writing {}: {e}", dir.join(&name).display()))
                    });
            (id.clone(), r)
        })
        .collect();
    let mut summary = Summary {
        runs: 0,
        failed: Vec::new(),
        measured: name,
        models_tried: 0,
        models_found: 0,
        failures: Vec::new(),
        migration: None,
    };
    let mut measured_runs = BTreeMap::new();
    for (id, r) in results {
        match r {
            Ok(r) => {
                measured_runs.insert(id.clone(), r.measured.clone());
                summary.runs += 1;
                summary.models_tried += r.models_tried;
                summary.models_found += r.models_found;
                summary
                    .failures
                    .extend(r.failures.into_iter().map(|reason| EntityFailure {
                        run: id.clone(),
                        reason,
                    }));
            }
            Err(e) => summary.failed.push((id, e)),
        }
    }
    summary.migration = study::measure_and_write(
        out,
        design.as_ref(),
        &measured_runs,
        options
            .stability_threshold_mm
            .unwrap_or(crate::migration::DEFAULT_STABILITY_THRESHOLD_MM),
        &software,
    )?;
    Ok(summary)
}

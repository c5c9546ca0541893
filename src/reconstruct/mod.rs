//! The reference RSA program: what a real RSA software does, from the images alone.
//!
//! It sees only what an operator has: the images, the nominal set-up (the scenario without its
//! random draws), the box bead table and the model files in `OUT/phantoms/`. It never reads the
//! ground truth: nothing in this module refers to the truth records or their files.
pub mod calibrate;
pub mod contour;
pub mod correspond;
pub mod detect;
pub mod exam;
pub mod model;
pub mod model_outline;
pub mod pipeline;
pub mod rigid;
pub mod selvik;
pub mod silhouette;

use std::collections::BTreeMap;
use std::path::Path;

use rayon::prelude::*;

use crate::diagnostic::Diagnostic;
use crate::output::atomic::write_atomic;

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

/// What `reconstruct` did.
pub struct Summary {
    /// Runs reconstructed (a measured.json written).
    pub runs: usize,
    /// Runs that failed, with the reason.
    pub failed: Vec<(String, String)>,
}

/// Reconstructs every run folder of `out` and writes `measured.json` beside its images, calibrating
/// every beamline by `method` and finding each model by `model_method` (`None`: markers for a
/// model with beads, silhouette for one without; see [`ModelMethod::for_model`]).
pub fn reconstruct(
    out: &Path,
    method: Method,
    model_method: Option<ModelMethod>,
) -> Result<Summary, Vec<Diagnostic>> {
    let setup = exam::load_setup(out)?;
    let runs = exam::run_folders(out)?;
    // Each mesh model that will be fitted by its outline is prepared once for all runs.
    let mut outlines = BTreeMap::new();
    for (id, mesh) in &setup.meshes {
        let has_beads = setup.beads.get(id).is_some_and(|b| !b.is_empty());
        if ModelMethod::for_model(model_method, has_beads) == ModelMethod::Silhouette {
            let model = model_outline::OutlineModel::new(mesh).map_err(|e| {
                vec![Diagnostic::file_error(
                    &out.join("phantoms"),
                    format!("model {id}: {e}"),
                )]
            })?;
            outlines.insert(id.clone(), model);
        }
    }
    let methods = pipeline::Methods {
        calibration: method,
        model: model_method,
    };
    let results: Vec<(String, Result<(), String>)> = runs
        .par_iter()
        .map(|(id, dir)| {
            let r = pipeline::reconstruct_run(&setup, &outlines, id, dir, methods).and_then(|m| {
                let mut bytes = serde_json::to_vec_pretty(&m).map_err(|e| e.to_string())?;
                bytes.push(b'\n');
                write_atomic(&dir.join("measured.json"), &bytes)
                    .map(|_| ())
                    .map_err(|e| e.to_string())
            });
            (id.clone(), r)
        })
        .collect();
    let failed: Vec<(String, String)> = results
        .iter()
        .filter_map(|(id, r)| r.as_ref().err().map(|e| (id.clone(), e.clone())))
        .collect();
    Ok(Summary {
        runs: results.len() - failed.len(),
        failed,
    })
}

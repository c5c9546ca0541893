//! The reference RSA program: what a real RSA software does, from the images alone.
//!
//! It sees only what an operator has: the images, the nominal set-up (the scenario without its
//! random draws), the box bead table and the model files in `OUT/phantoms/`. It never reads the
//! ground truth: nothing in this module refers to the truth records or their files.
pub mod calibrate;
pub mod correspond;
pub mod detect;
pub mod exam;
pub mod model;
pub mod pipeline;
pub mod rigid;
pub mod selvik;

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

/// What `reconstruct` did.
pub struct Summary {
    /// Runs reconstructed (a measured.json written).
    pub runs: usize,
    /// Runs that failed, with the reason.
    pub failed: Vec<(String, String)>,
}

/// Reconstructs every run folder of `out` and writes `measured.json` beside its images, calibrating
/// every beamline by `method`.
pub fn reconstruct(out: &Path, method: Method) -> Result<Summary, Vec<Diagnostic>> {
    let setup = exam::load_setup(out)?;
    let runs = exam::run_folders(out)?;
    let results: Vec<(String, Result<(), String>)> = runs
        .par_iter()
        .map(|(id, dir)| {
            let r = pipeline::reconstruct_run(&setup, id, dir, method).and_then(|m| {
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

//! The attenuation-mode checks of every run before anything is written: each bead lies wholly
//! inside or outside every volume of its exposure, and never in two volumes that do not nest.
//! (That nested volumes stay inside their outer volume is checked on every pixel while
//! rendering, where the path lengths are known.)

use std::sync::Arc;

use rayon::prelude::*;

use crate::diagnostic::{Diagnostic, KeyPath};
use crate::expand;
use crate::phantom::PhantomModel;
use crate::scenario::LoadedScenario;
use crate::trace::MeshBvh;

use super::{Setup, parts};

/// Most findings reported; the rest are counted.
const MAX_FINDINGS: usize = 10;

/// Every placement problem of every run, as errors at the bead's phantom. `bvhs` holds each
/// model's mesh in a BVH (`None` for a model without a mesh).
pub fn check_runs(
    loaded: &LoadedScenario,
    models: &[PhantomModel],
    setup: &Setup,
    bvhs: &[Option<Arc<MeshBvh>>],
) -> Vec<Diagnostic> {
    let s = &loaded.scenario;
    let runs: Vec<expand::Run> = expand::runs(s, models).collect();
    let mut findings: Vec<(usize, String)> = runs
        .par_iter()
        .flat_map_iter(|run| {
            run.exposures
                .iter()
                .filter_map(|e| parts(s, setup, models, bvhs, run, e).err())
                .collect::<Vec<_>>()
        })
        .collect();
    let total = findings.len();
    findings.truncate(MAX_FINDINGS);
    let mut out: Vec<Diagnostic> = findings
        .into_iter()
        .map(|(pi, message)| {
            loaded
                .locator
                .error(KeyPath::root().key("phantoms").index(pi), message)
                .with_help("move the bead, or the volume's mesh, so that the bead sits wholly inside or wholly outside it")
        })
        .collect();
    if total > MAX_FINDINGS {
        out.push(loaded.locator.error(
            KeyPath::root().key("phantoms"),
            format!(
                "{} more bead placement problems in other runs",
                total - MAX_FINDINGS
            ),
        ));
    }
    out
}

/// A warning when `max_energy_bins` is too few for the `spectral_tolerance` the scenario asks
/// for: the traced bins hold a wider one (see [`super::spectral`]).
pub fn spectral_tolerance_warning(loaded: &LoadedScenario, setup: &Setup) -> Option<Diagnostic> {
    let im = &loaded.scenario.imaging;
    let asked = im.spectral_tolerance?;
    if setup.spectral_tolerance <= asked {
        return None;
    }
    let key = KeyPath::root().key("imaging");
    let key = if im.max_energy_bins.is_some() {
        key.key("max_energy_bins")
    } else {
        key.key("spectral_tolerance")
    };
    let reached = if setup.spectral_tolerance.is_finite() {
        format!(
            "they hold {:.3} % instead of {:.3} %",
            setup.spectral_tolerance * 100.0,
            asked * 100.0
        )
    } else {
        "even one bin per stretch between absorption edges is more; the bins are merged in equal runs and the error is not bounded".to_string()
    };
    Some(
        loaded
            .locator
            .warning(
                key,
                format!(
                    "max_energy_bins {} is too few to trace the spectrum within spectral_tolerance {asked}: {reached} (the transmission of a layer of one material, relative; `rsasim spectrum` shows each material's)",
                    im.max_bins()
                ),
            )
            .with_help("raise max_energy_bins (each bin costs time on every pixel crossing two materials or more), or state the spectral_tolerance you accept"),
    )
}

//! Geometric checks over every run: each phantom of an exposure must lie between every source
//! and its detector, and should project inside the detector's active area.

use crate::diagnostic::{Diagnostic, KeyPath};
use crate::phantom::PhantomModel;
use crate::scenario::LoadedScenario;

use super::Run;

/// Errors for phantoms that are not strictly between a source and its detector in some run, and
/// warnings for phantoms that project partly outside a detector in some runs.
pub fn check_geometry(
    loaded: &LoadedScenario,
    models: &[PhantomModel],
    runs: &[Run],
) -> Vec<Diagnostic> {
    let mut out = Vec::new();
    let s = &loaded.scenario;
    for (pi, model) in models.iter().enumerate() {
        let key = KeyPath::root().key("phantoms").index(pi).key("position_mm");
        let points: Vec<_> = model.extent_points().collect();
        for (di, det) in s.detectors.iter().enumerate() {
            let imaged = s.exposures.iter().any(|e| e.phantoms.contains(&model.id));
            if !imaged {
                continue;
            }
            let mut outside_runs = Vec::new();
            let mut misplaced: Option<(String, String)> = None;
            for run in runs {
                let dstate = &run.detectors[di];
                let frame = dstate.frame();
                let source = run.source_of(dstate);
                let s_local = frame.pose.to_local(source);
                let pose = run.phantoms[pi].pose();
                let mut outside = false;
                for &(p, radius) in &points {
                    let world = pose.to_world(p);
                    let z = frame.pose.to_local(world).z;
                    if z - radius <= 0.0 {
                        misplaced.get_or_insert((
                            run.id.clone(),
                            format!("reaches {:.1} mm behind the detector plane", radius - z),
                        ));
                        break;
                    }
                    if z + radius >= s_local.z {
                        misplaced.get_or_insert((
                            run.id.clone(),
                            "reaches the source or beyond it".into(),
                        ));
                        break;
                    }
                    let Some(uv) = frame.project(source, world) else {
                        continue;
                    };
                    let magnification = s_local.z / (s_local.z - z);
                    let r_px = radius * magnification
                        / frame.pixel_pitch_mm[0].min(frame.pixel_pitch_mm[1]);
                    let [w, h] = frame.pixels.map(f64::from);
                    if uv.x - r_px < 0.0 || uv.y - r_px < 0.0 || uv.x + r_px > w || uv.y + r_px > h
                    {
                        outside = true;
                    }
                }
                if misplaced.is_some() {
                    break;
                }
                if outside {
                    outside_runs.push(run.id.clone());
                }
            }
            if let Some((run_id, what)) = misplaced {
                out.push(
                    loaded
                        .locator
                        .error(
                            key.clone(),
                            format!(
                                "phantom `{}` is not between source `{}` and detector `{}` in run {run_id}: it {what}",
                                model.id, det.source, det.id
                            ),
                        )
                        .with_help("move the phantom, the source or the detector, or narrow the `randomize` ranges"),
                );
            } else if !outside_runs.is_empty() {
                out.push(loaded.locator.warning(
                    key.clone(),
                    format!(
                        "phantom `{}` falls partly outside the field of detector `{}` in {} of {} runs (first: {})",
                        model.id,
                        det.id,
                        outside_runs.len(),
                        runs.len(),
                        outside_runs[0]
                    ),
                ));
            }
        }
    }
    out
}

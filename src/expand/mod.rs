//! The expansion stage: a scenario and its seed turned into concrete runs (plain data).
//!
//! # Seeds
//!
//! Run `r` of noise level `n` draws its geometry from the ChaCha8 stream keyed by
//! SHA-256(`"rsasim/geometry/v1/<seed>/<n>/<r>"`) (see [`crate::random`]). So run 7 of level 2 is
//! the same whether the scenario asks for 20 or 200 runs, and adding a noise level changes no
//! other level's geometry. The draws are taken in file order: for each source 3 position
//! offsets; for each detector 3 position offsets then 3 angle offsets; for each phantom 3
//! position offsets then 3 angle offsets — always, even where a range is 0, so widening one
//! range never moves another object's draw. Each offset is uniform in [−r, +r).
//!
//! Positions are perturbed along the scanner axes; rotations about the object's own nominal
//! axes (`R = R_nominal · Rx(δα)·Ry(δβ)·Rz(δγ)`). Then everything is re-expressed in the frame
//! of the first calibration box (the scanner frame when there is none), the frame any RSA
//! software reconstructs in.

mod check;
mod run;

pub use check::check_geometry;
pub use run::*;

use glam::DVec3;
use rand_chacha::ChaCha8Rng;

use crate::geometry::{Pose, rotation_xyz_deg};
use crate::phantom::PhantomModel;
use crate::random;
use crate::scenario::{PoseRange, Scenario};

/// The label of the geometry stream of run `run_index` of noise level `level_index`.
pub fn geometry_stream_label(seed: u64, level_index: u32, run_index: u32) -> String {
    format!("rsasim/geometry/v1/{seed}/{level_index}/{run_index}")
}

/// The id of a run: `n<level>-r<run:02>`.
pub fn run_id(level_index: u32, run_index: u32) -> String {
    format!("n{level_index}-r{run_index:02}")
}

/// Every run of the protocol, level by level, run by run.
pub fn expand(s: &Scenario, models: &[PhantomModel]) -> Vec<Run> {
    let mut runs = Vec::new();
    for (n, &level) in s.protocol.noise_levels.iter().enumerate() {
        for r in 0..s.protocol.runs_per_level {
            runs.push(expand_run(s, models, n as u32, level, r));
        }
    }
    runs
}

/// One run: the draws of its geometry stream applied to the nominal set-up.
pub fn expand_run(s: &Scenario, models: &[PhantomModel], level_index: u32, level: f64, run_index: u32) -> Run {
    let label = geometry_stream_label(s.seed, level_index, run_index);
    let mut rng = random::stream(&label);

    let sources: Vec<(String, DVec3)> = s
        .sources
        .iter()
        .map(|src| (src.id.clone(), DVec3::from_array(src.position_mm) + offset(&mut rng, src.randomize.position_mm)))
        .collect();
    let detectors: Vec<Pose> = s
        .detectors
        .iter()
        .map(|d| draw_pose(&mut rng, d.position_mm, d.rotation_deg, &d.randomize))
        .collect();
    let phantoms: Vec<Pose> = s
        .phantoms
        .iter()
        .map(|p| draw_pose(&mut rng, p.position_mm, p.rotation_deg, &p.randomize))
        .collect();

    let box_pose = s
        .phantoms
        .iter()
        .position(|p| p.calibration_box.is_some())
        .map_or(Pose::IDENTITY, |i| phantoms[i]);
    let to_box = box_pose.inverse();

    Run {
        id: run_id(level_index, run_index),
        noise_level_index: level_index,
        noise_level: level,
        run_index,
        geometry_stream: label,
        box_pose_in_scanner: box_pose,
        sources: sources
            .into_iter()
            .map(|(id, p)| SourceState { id, position_mm: to_box.to_world(p) })
            .collect(),
        detectors: s
            .detectors
            .iter()
            .zip(&detectors)
            .map(|(d, pose)| {
                let pose = to_box.compose(pose);
                DetectorState {
                    id: d.id.clone(),
                    source: d.source.clone(),
                    position_mm: pose.position_mm,
                    rotation: pose.rotation,
                    pixels: d.pixels,
                    pixel_pitch_mm: d.resolved_pixel_pitch_mm(),
                    bpp: d.bpp,
                }
            })
            .collect(),
        phantoms: models
            .iter()
            .zip(&phantoms)
            .map(|(m, pose)| {
                let pose = to_box.compose(pose);
                PhantomState {
                    id: m.id.clone(),
                    kind: m.kind.to_string(),
                    position_mm: pose.position_mm,
                    rotation: pose.rotation,
                    markers: m
                        .markers
                        .iter()
                        .map(|b| MarkerState {
                            id: b.id.clone(),
                            position_mm: pose.to_world(b.position_mm),
                            diameter_mm: b.diameter_mm,
                        })
                        .collect(),
                }
            })
            .collect(),
        exposures: s
            .exposures
            .iter()
            .map(|e| ExposureState { id: e.id.clone(), phantoms: e.phantoms.clone() })
            .collect(),
    }
}

fn offset(rng: &mut ChaCha8Rng, half_widths: [f64; 3]) -> DVec3 {
    DVec3::from_array(half_widths.map(|h| random::symmetric(rng, h)))
}

fn draw_pose(rng: &mut ChaCha8Rng, position_mm: [f64; 3], rotation_deg: [f64; 3], range: &PoseRange) -> Pose {
    let position = DVec3::from_array(position_mm) + offset(rng, range.position_mm);
    let turn = range.rotation_deg.map(|h| random::symmetric(rng, h));
    Pose { position_mm: position, rotation: rotation_xyz_deg(rotation_deg) * rotation_xyz_deg(turn) }
}

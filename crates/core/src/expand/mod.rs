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
pub mod sequence;
pub mod study;

pub use check::check_geometry;
pub use run::*;

use glam::DVec3;
use rand_chacha::ChaCha8Rng;

use crate::geometry::{Pose, rotation_xyz_deg};
use crate::phantom::PhantomModel;
use crate::random;
use crate::scenario::{Level, PoseRange, Scenario};

/// The label of the geometry stream of run `run_index` of noise level `level_index`.
pub fn geometry_stream_label(seed: u64, level_index: u32, run_index: u32) -> String {
    format!("rsasim/geometry/v1/{seed}/{level_index}/{run_index}")
}

/// The id of a run: `n<level>-r<run:02>`.
pub fn run_id(level_index: u32, run_index: u32) -> String {
    format!("n{level_index}-r{run_index:02}")
}

/// Every run of the scenario: the protocol level by level, run by run; or a study patient by
/// patient, exam by exam.
pub fn expand(s: &Scenario, models: &[PhantomModel]) -> Vec<Run> {
    runs(s, models).collect()
}

/// Every run in the order of [`expand`], each built only when asked for: memory stays flat
/// however many runs the protocol has.
pub fn runs<'a>(s: &'a Scenario, models: &'a [PhantomModel]) -> impl Iterator<Item = Run> + 'a {
    (0..s.run_count()).map(move |i| run_at(s, models, i))
}

/// Run `index` (0-based, in the order of [`expand`]) of the protocol or the study.
pub fn run_at(s: &Scenario, models: &[PhantomModel], index: u64) -> Run {
    if let Some(d) = &s.study {
        let exams = d.exams.len().max(1) as u64;
        return study::expand_exam(
            s,
            d,
            models,
            (index / exams) as u32,
            (index % exams) as usize,
        );
    }
    let levels = s.levels();
    let frames = u64::from(s.frames_per_run());
    let per_level = u64::from(s.protocol.runs_per_level).max(1) * frames;
    let n = (index / per_level) as usize;
    let within = index % per_level;
    let (run_index, frame) = ((within / frames) as u32, (within % frames) as u32);
    match s.sequence {
        Some(_) => expand_frame(s, models, n as u32, levels[n], run_index, frame),
        None => expand_run(s, models, n as u32, levels[n], run_index),
    }
}

/// The nominal set-up as a run: every random range set to zero (no offsets drawn), so its
/// poses are the scenario's own, in the box frame. Its id and levels are those of run 0 of
/// level 0.
pub fn nominal_run(s: &Scenario, models: &[PhantomModel]) -> Run {
    let mut nominal = s.clone();
    for src in &mut nominal.sources {
        src.randomize = Default::default();
    }
    for d in &mut nominal.detectors {
        d.randomize = PoseRange::default();
    }
    for p in &mut nominal.phantoms {
        p.randomize = PoseRange::default();
    }
    let level = Level {
        noise_level: 0.0,
        exposure_factor: None,
    };
    // With a sequence, the moving phantoms stand where the first frame has them.
    let label = geometry_stream_label(s.seed, 0, 0);
    let drawn = draw(&nominal, &mut random::stream(&label));
    let phantoms = fixed_poses(&nominal, &drawn.phantoms, &sequence::motion_poses(s, 0.0));
    let header = RunHeader {
        id: run_id(0, 0),
        level_index: 0,
        level,
        run_index: 0,
        geometry_stream: label,
    };
    assemble(&nominal, models, header, drawn, &phantoms, &|_, b| {
        Some(b.position_mm)
    })
}

/// One run: the draws of its geometry stream applied to the nominal set-up.
pub fn expand_run(
    s: &Scenario,
    models: &[PhantomModel],
    level_index: u32,
    level: Level,
    run_index: u32,
) -> Run {
    drawn_run(s, models, level_index, level, run_index, None, 0.0)
}

/// Frame `frame` of the sequence that run `run_index` of level `level_index` becomes
/// ([`sequence`]): the run's draws, every moving phantom at its pose at the frame's time.
pub fn expand_frame(
    s: &Scenario,
    models: &[PhantomModel],
    level_index: u32,
    level: Level,
    run_index: u32,
    frame: u32,
) -> Run {
    drawn_run(s, models, level_index, level, run_index, Some(frame), 0.0)
}

/// Frame run `run` (from [`expand_frame`]) with every moving phantom where it is `offset_s`
/// seconds after the frame's time: one pose inside its pulse ([`sequence::pulse_runs`]). Same id,
/// same frame record (the frame's own time). `None` for a run that is no frame.
pub fn frame_at(s: &Scenario, models: &[PhantomModel], run: &Run, offset_s: f64) -> Option<Run> {
    let frame = run.frame.as_ref()?.index;
    let level = Level {
        noise_level: run.noise_level,
        exposure_factor: run.exposure_factor,
    };
    Some(drawn_run(
        s,
        models,
        run.noise_level_index,
        level,
        run.run_index,
        Some(frame),
        offset_s,
    ))
}

/// The run, or one frame of its sequence (its moving phantoms `offset_s` after the frame's
/// time), from its geometry stream.
fn drawn_run(
    s: &Scenario,
    models: &[PhantomModel],
    level_index: u32,
    level: Level,
    run_index: u32,
    frame: Option<u32>,
    offset_s: f64,
) -> Run {
    let label = geometry_stream_label(s.seed, level_index, run_index);
    let drawn = draw(s, &mut random::stream(&label));
    let id = run_id(level_index, run_index);
    let state = frame.and_then(|k| sequence::frame_state(s, &id, k));
    let (phantoms, id) = match (&state, frame) {
        (Some(f), Some(k)) => (
            fixed_poses(
                s,
                &drawn.phantoms,
                &sequence::motion_poses(s, f.time_s + offset_s),
            ),
            sequence::frame_run_id(&id, k, s.frames_per_run()),
        ),
        _ => (fixed_poses(s, &drawn.phantoms, &still(s)), id),
    };
    let header = RunHeader {
        id,
        level_index,
        level,
        run_index,
        geometry_stream: label,
    };
    let mut run = assemble(s, models, header, drawn, &phantoms, &|_, b| {
        Some(b.position_mm)
    });
    run.frame = state;
    let joints = sequence::joint_states(s, &run);
    if let Some(f) = run.frame.as_mut() {
        f.joints = joints;
    }
    run
}

/// What names a run and sets its noise.
struct RunHeader {
    id: String,
    level_index: u32,
    level: Level,
    run_index: u32,
    geometry_stream: String,
}

/// The draws of one geometry stream, in the scanner frame: sources, detectors, and every
/// phantom's own pose (before `fixed_to` is resolved).
struct Drawn {
    sources: Vec<(String, DVec3)>,
    detectors: Vec<Pose>,
    phantoms: Vec<Pose>,
}

/// Takes the draws of a run from `rng` in file order (see "Seeds" above).
fn draw(s: &Scenario, rng: &mut ChaCha8Rng) -> Drawn {
    let sources = s
        .sources
        .iter()
        .map(|src| {
            (
                src.id.clone(),
                DVec3::from_array(src.position_mm) + offset(rng, src.randomize.position_mm),
            )
        })
        .collect();
    let detectors = s
        .detectors
        .iter()
        .map(|d| draw_pose(rng, d.position_mm, d.rotation_deg, &d.randomize))
        .collect();
    let phantoms = s
        .phantoms
        .iter()
        .map(|p| draw_pose(rng, p.position_mm, p.rotation_deg, &p.randomize))
        .collect();
    Drawn {
        sources,
        detectors,
        phantoms,
    }
}

/// The run with the drawn sources and detectors and the phantoms at `phantoms` (scanner frame,
/// `fixed_to` resolved), all re-expressed in the box frame. `bead(phantom index, bead)` gives a
/// bead's centre in its phantom's local frame, or `None` for a bead the run leaves out.
fn assemble(
    s: &Scenario,
    models: &[PhantomModel],
    header: RunHeader,
    drawn: Drawn,
    phantoms: &[Pose],
    bead: &dyn Fn(usize, &crate::phantom::Marker) -> Option<DVec3>,
) -> Run {
    let box_pose = s
        .phantoms
        .iter()
        .position(|p| p.calibration_box.is_some())
        .map_or(Pose::IDENTITY, |i| phantoms[i]);
    let to_box = box_pose.inverse();
    let detectors: Vec<DetectorState> = s
        .detectors
        .iter()
        .zip(&drawn.detectors)
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
        .collect();
    let spot_centre = effective_spot_offset_mm(s);
    let effective = |id: &str, position: DVec3| {
        let [r, c] = spot_centre?;
        let d = detectors.iter().find(|d| d.source == id)?;
        Some((position + d.rotation.x_axis * r + d.rotation.y_axis * c).to_array())
    };

    Run {
        id: header.id,
        noise_level_index: header.level_index,
        noise_level: header.level.noise_level,
        exposure_factor: header.level.exposure_factor,
        run_index: header.run_index,
        geometry_stream: header.geometry_stream,
        box_pose_in_scanner: box_pose,
        sources: drawn
            .sources
            .into_iter()
            .map(|(id, p)| {
                let position_mm = to_box.to_world(p);
                SourceState {
                    effective_position_mm: effective(&id, position_mm),
                    id,
                    position_mm,
                }
            })
            .collect(),
        detectors,
        phantoms: models
            .iter()
            .zip(phantoms)
            .enumerate()
            .map(|(pi, (m, pose))| {
                let pose = to_box.compose(pose);
                PhantomState {
                    id: m.id.clone(),
                    kind: m.kind.to_string(),
                    position_mm: pose.position_mm,
                    rotation: pose.rotation,
                    markers: m
                        .markers
                        .iter()
                        .filter_map(|b| {
                            bead(pi, b).map(|local| MarkerState {
                                id: b.id.clone(),
                                position_mm: pose.to_world(local),
                                diameter_mm: b.diameter_mm,
                            })
                        })
                        .collect(),
                }
            })
            .collect(),
        exposures: s
            .exposures
            .iter()
            .map(|e| ExposureState {
                id: e.id.clone(),
                phantoms: e.phantoms.clone(),
            })
            .collect(),
        frame: None,
    }
}

/// The offset of the focal spot's intensity-weighted centre from its geometric centre along
/// the detector's r and c, mm: `None` when they coincide (no spot, or no fall of the emission
/// across it).
fn effective_spot_offset_mm(s: &Scenario) -> Option<[f64; 2]> {
    let spot = s.imaging.focal_spot.as_ref()?;
    spot.intensity_fall_percent.filter(|&p| p != 0.0)?;
    Some(crate::sampling::focal_spot::centroid_mm(
        &crate::sampling::focal_spot::spot_sub_sources(spot),
    ))
}

fn offset(rng: &mut ChaCha8Rng, half_widths: [f64; 3]) -> DVec3 {
    DVec3::from_array(half_widths.map(|h| random::symmetric(rng, h)))
}

fn draw_pose(
    rng: &mut ChaCha8Rng,
    position_mm: [f64; 3],
    rotation_deg: [f64; 3],
    range: &PoseRange,
) -> Pose {
    let position = DVec3::from_array(position_mm) + offset(rng, range.position_mm);
    let turn = range.rotation_deg.map(|h| random::symmetric(rng, h));
    Pose {
        position_mm: position,
        rotation: rotation_xyz_deg(rotation_deg) * rotation_xyz_deg(turn),
    }
}

/// No phantom moves: every motion the identity.
fn still(s: &Scenario) -> Vec<Pose> {
    vec![Pose::IDENTITY; s.phantoms.len()]
}

/// Every phantom's pose (scanner frame) from its draw and its motion `motion[i]` (identity for
/// a phantom that does not move; module [`sequence`]): `drawn[i]·motion[i]`, or for a phantom
/// fixed to another (`fixed_to`) the parent's pose composed with the phantom's nominal pose in
/// the parent's frame and then its motion (its own draws are taken and ignored, so the stream
/// stays aligned). Validation guarantees the `fixed_to` chains end without a cycle.
fn fixed_poses(s: &Scenario, drawn: &[Pose], motion: &[Pose]) -> Vec<Pose> {
    let mut poses: Vec<Option<Pose>> = vec![None; drawn.len()];
    fn resolve(
        s: &Scenario,
        (drawn, motion): (&[Pose], &[Pose]),
        poses: &mut [Option<Pose>],
        i: usize,
        depth: usize,
    ) -> Pose {
        if let Some(p) = poses[i] {
            return p;
        }
        let ph = &s.phantoms[i];
        let parent = ph
            .fixed_to
            .as_ref()
            .and_then(|id| s.phantoms.iter().position(|q| &q.id == id));
        let still = match parent {
            Some(k) if depth < s.phantoms.len() => {
                let parent_pose = resolve(s, (drawn, motion), poses, k, depth + 1);
                parent_pose.compose(&Pose::from_position_euler_deg(
                    ph.position_mm,
                    ph.rotation_deg,
                ))
            }
            _ => drawn[i],
        };
        let pose = if motion[i] == Pose::IDENTITY {
            still
        } else {
            still.compose(&motion[i])
        };
        poses[i] = Some(pose);
        pose
    }
    for i in 0..drawn.len() {
        resolve(s, (drawn, motion), &mut poses, i, 0);
    }
    poses
        .into_iter()
        .map(|p| p.expect("every pose resolved"))
        .collect()
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::phantom;
    use crate::scenario::from_text;

    const SCENARIO: &str = r#"name = "t"
seed = 9
[protocol]
noise_levels = [0.0, 0.5]
runs_per_level = RUNS
[[sources]]
id = "s"
position_mm = [0.0, 0.0, 1000.0]
randomize.position_mm = [SRC, 20.0, 20.0]
[[detectors]]
id = "d"
source = "s"
pixels = [10, 10]
size_mm = [400.0, 400.0]
position_mm = [0.0, 0.0, -500.0]
randomize.position_mm = [5.0, 5.0, 5.0]
randomize.rotation_deg = [1.0, 1.0, 1.0]
[[phantoms]]
id = "box"
position_mm = [1.0, 2.0, 3.0]
rotation_deg = [0.0, 0.0, 30.0]
[[phantoms.calibration_box.plates]]
id = "F"
role = "fiducial"
center_mm = [0.0, 0.0, 0.0]
size_mm = [50.0, 50.0]
grid = [2, 2]
spacing_mm = [20.0, 20.0]
[[phantoms]]
id = "b"
randomize.rotation_deg = [5.0, 5.0, 5.0]
[[phantoms.beads]]
id = "B"
position_mm = [10.0, 0.0, 0.0]
[[exposures]]
id = "e"
phantoms = ["box", "b"]
"#;

    fn runs(runs: u32, levels: &str, source_range: f64) -> Vec<Run> {
        let text = SCENARIO
            .replace("RUNS", &runs.to_string())
            .replace("[0.0, 0.5]", levels)
            .replace("SRC", &format!("{source_range:.1}"));
        let loaded = from_text(&text, Path::new("t.toml"), Path::new("."))
            .unwrap_or_else(|e| panic!("{e:?}"));
        let models = phantom::build(&loaded).unwrap();
        expand(&loaded.scenario, &models)
    }

    #[test]
    fn run_k_of_level_n_does_not_depend_on_the_run_count_or_other_levels() {
        let few = runs(3, "[0.0, 0.5]", 20.0);
        let many = runs(200, "[0.0, 0.5]", 20.0);
        assert_eq!(
            few[4],
            many.iter().find(|r| r.id == "n1-r01").unwrap().clone()
        );
        assert_eq!(many.len(), 400);
        assert_eq!(many[399].id, "n1-r199");
        // Adding a level in front shifts indices, so the level keeps its index: add one at the end.
        let more_levels = runs(3, "[0.0, 0.5, 0.9]", 20.0);
        assert_eq!(few[..], more_levels[..6]);
        // Runs differ from each other.
        assert_ne!(few[0].sources, few[1].sources);
    }

    #[test]
    fn widening_one_range_moves_no_other_object() {
        let a = runs(2, "[0.0]", 20.0);
        let b = runs(2, "[0.0]", 40.0);
        assert_ne!(a[1].sources, b[1].sources);
        assert_eq!(a[1].detectors, b[1].detectors);
        assert_eq!(a[1].phantoms, b[1].phantoms);
    }

    #[test]
    fn everything_is_expressed_in_the_box_frame() {
        let r = &runs(1, "[0.0]", 20.0)[0];
        let boxed = &r.phantoms[0];
        assert!((boxed.position_mm).length() < 1e-12);
        assert!((boxed.rotation - glam::DMat3::IDENTITY).abs_diff_eq(glam::DMat3::ZERO, 1e-12));
        // The scanner-frame box pose is recorded, and maps truth back to the scanner frame.
        let scanner_source = r.box_pose_in_scanner.to_world(r.sources[0].position_mm);
        assert!((scanner_source.z - 1000.0).abs() <= 20.0);
        assert!((r.box_pose_in_scanner.position_mm - DVec3::new(1.0, 2.0, 3.0)).length() < 1e-12);
        // A bead's world position is its phantom's pose applied to its local position.
        let bead = &r.phantoms[1];
        let expected = bead.pose().to_world(DVec3::new(10.0, 0.0, 0.0));
        assert!((bead.markers[0].position_mm - expected).length() < 1e-12);
    }
}

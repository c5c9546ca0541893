//! A dynamic exam's runs: each run of the protocol becomes a sequence of frames, one run per
//! frame.
//!
//! # Frames, ids and seeds
//!
//! Run `r` of level `n` with `[sequence]` of `F` frames at `f` frames per second becomes the runs
//! `n<n>-r<r>-f<k>` (k = 0 … F − 1, at least four digits), in that order. Every frame of a
//! sequence draws its geometry from the same stream as the run would without a sequence
//! (`"rsasim/geometry/v1/<seed>/<n>/<r>"`, parent module), so tubes, detectors, the box and every
//! phantom's set-up are the same in all its frames; only the phantoms with a motion, and those
//! fixed to them, move. Frame `k` is taken at `t_k = k/f` s (its pulse is centred there). A
//! frame's noise is keyed by its exposure id followed by `/f<k>` (`crate::noise::NoiseKey`), so
//! every frame has its own noise and frame `k` is the same whatever `F` is. Adding frames or
//! sequences changes none of the others: prefix-stable over frames and over sequences.
//!
//! # Motion
//!
//! A phantom with a motion whose trajectory ([`crate::geometry::trajectory`]) gives `M(t)` is at
//! `P(t) = P₀·M(t)`, with `P₀` its pose without motion: its drawn pose, or, when it is
//! `fixed_to` a parent, the parent's pose at `t` composed with its place on the parent. So a
//! tibia fixed to a moving femur with a motion of its own moves relative to the femur by `M(t)`.

use super::{FrameState, JointState, Run, frame_at};
use crate::geometry::Pose;
use crate::phantom::PhantomModel;
use crate::scenario::Scenario;

/// The digits of a frame number in run ids: at least four, more when the last frame needs them.
pub fn frame_digits(frames: u32) -> usize {
    frames.saturating_sub(1).to_string().len().max(4)
}

/// The id of frame `frame` of the sequence `sequence_id` with `frames` frames.
pub fn frame_run_id(sequence_id: &str, frame: u32, frames: u32) -> String {
    format!(
        "{sequence_id}-f{frame:0width$}",
        width = frame_digits(frames)
    )
}

/// The time of frame `frame`, s: `frame / frame_rate_hz`.
pub fn frame_time_s(frame_rate_hz: f64, frame: u32) -> f64 {
    f64::from(frame) / frame_rate_hz
}

/// Each phantom's motion `M(t)` at `time_s` (identity for a phantom without one).
///
/// # Panics
/// When a motion's keyframes were not validated (fewer than two, times not increasing, a half
/// turn): the scenario check refuses those first.
pub fn motion_poses(s: &Scenario, time_s: f64) -> Vec<Pose> {
    s.phantoms
        .iter()
        .map(|ph| match &ph.motion {
            Some(m) => m.trajectory().expect("validated keyframes").pose_at(time_s),
            None => Pose::IDENTITY,
        })
        .collect()
}

/// The frame record of frame `frame` of the sequence run `sequence_id`.
pub fn frame_state(s: &Scenario, sequence_id: &str, frame: u32) -> Option<FrameState> {
    let q = s.sequence.as_ref()?;
    Some(FrameState {
        sequence: sequence_id.to_string(),
        index: frame,
        count: q.frames,
        time_s: frame_time_s(q.frame_rate_hz, frame),
        joints: Vec::new(),
    })
}

/// Each joint of the sequence in `run` (its phantoms' poses, box frame): the Grood–Suntay
/// angles and translations between the anatomical frames ([`crate::geometry::joint`]).
///
/// # Panics
/// When a joint names a phantom the run does not have (the scenario check refuses that first).
pub fn joint_states(s: &Scenario, run: &Run) -> Vec<JointState> {
    let Some(q) = &s.sequence else {
        return Vec::new();
    };
    let pose_of = |id: &str| {
        run.phantoms
            .iter()
            .find(|p| p.id == id)
            .expect("validated joint phantom")
            .pose()
    };
    q.joints
        .iter()
        .map(|j| {
            let k = j.kinematics(&pose_of(&j.proximal), &pose_of(&j.distal));
            JointState {
                id: j.id.clone(),
                angles_deg: k.angles_deg,
                translation_mm: k.translation_mm,
            }
        })
        .collect()
}

/// The frame run `run` at each pose of its pulse (`Sequence::pulse_offsets_s`), in time order:
/// the poses its image is the mean of. Empty when the frame has no motion blur: no pulse, one
/// sample, no frame, or no phantom that moves during the pulse.
pub fn pulse_runs(s: &Scenario, models: &[PhantomModel], run: &Run) -> Vec<Run> {
    let Some(q) = &s.sequence else {
        return Vec::new();
    };
    let runs: Vec<Run> = q
        .pulse_offsets_s()
        .into_iter()
        .filter_map(|dt| frame_at(s, models, run, dt))
        .collect();
    match (runs.first(), runs.last()) {
        (Some(a), Some(b)) if a.phantoms != b.phantoms => runs,
        _ => Vec::new(),
    }
}

/// The frame run `run` at the start and at the end of its pulse: where the blur of each marker
/// begins and ends. `None` without a pulse.
pub fn pulse_ends(s: &Scenario, models: &[PhantomModel], run: &Run) -> Option<(Run, Run)> {
    let q = s.sequence.as_ref()?;
    if !(q.pulse_ms > 0.0) {
        return None;
    }
    let half_s = q.pulse_ms / 2000.0;
    Some((
        frame_at(s, models, run, -half_s)?,
        frame_at(s, models, run, half_s)?,
    ))
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use glam::DVec3;

    use crate::expand::{Run, expand};
    use crate::phantom;
    use crate::scenario::from_text;

    const SCENARIO: &str = r#"name = "t"
seed = 4
[protocol]
noise_levels = [0.0, 0.5]
runs_per_level = RUNS
[sequence]
frames = FRAMES
frame_rate_hz = 10
[[sources]]
id = "s"
position_mm = [0.0, 0.0, 1000.0]
randomize.position_mm = [20.0, 20.0, 20.0]
[[detectors]]
id = "d"
source = "s"
pixels = [10, 10]
size_mm = [400.0, 400.0]
position_mm = [0.0, 0.0, -500.0]
randomize.rotation_deg = [1.0, 1.0, 1.0]
[[phantoms]]
id = "box"
rotation_deg = [0.0, 0.0, 30.0]
randomize.position_mm = [3.0, 3.0, 3.0]
[[phantoms.calibration_box.plates]]
id = "F"
role = "fiducial"
center_mm = [0.0, 0.0, 0.0]
size_mm = [50.0, 50.0]
grid = [2, 2]
spacing_mm = [20.0, 20.0]
[[phantoms]]
id = "femur"
position_mm = [5.0, 0.0, 0.0]
randomize.rotation_deg = [5.0, 5.0, 5.0]
randomize.position_mm = [2.0, 2.0, 2.0]
[[phantoms.beads]]
id = "F1"
position_mm = [0.0, 10.0, 0.0]
[phantoms.motion]
keyframes = [{ time_s = 0.0 }, { time_s = 0.4, position_mm = [10.0, 0.0, 0.0], rotation_deg = [40.0, 0.0, 0.0] }]
[[phantoms]]
id = "tibia"
fixed_to = "femur"
position_mm = [0.0, -50.0, 0.0]
[[phantoms.beads]]
id = "T1"
position_mm = [0.0, 0.0, 10.0]
[phantoms.motion]
keyframes = [{ time_s = 0.0 }, { time_s = 0.4, rotation_deg = [0.0, 0.0, 20.0] }]
[[exposures]]
id = "e"
phantoms = ["box", "femur", "tibia"]
"#;

    fn runs(runs: u32, frames: u32) -> Vec<Run> {
        let text = SCENARIO
            .replace("RUNS", &runs.to_string())
            .replace("FRAMES", &frames.to_string());
        let loaded = from_text(&text, Path::new("t.toml"), Path::new("."))
            .unwrap_or_else(|e| panic!("{e:?}"));
        let models = phantom::build(&loaded).unwrap();
        expand(&loaded.scenario, &models)
    }

    #[test]
    fn every_run_becomes_its_frames_in_order_with_one_geometry() {
        let r = runs(2, 5);
        assert_eq!(r.len(), 2 * 2 * 5);
        let ids: Vec<&str> = r.iter().map(|x| x.id.as_str()).collect();
        assert_eq!(
            ids[..6],
            [
                "n0-r00-f0000",
                "n0-r00-f0001",
                "n0-r00-f0002",
                "n0-r00-f0003",
                "n0-r00-f0004",
                "n0-r01-f0000"
            ]
        );
        assert_eq!(ids[19], "n1-r01-f0004");
        for (k, run) in r[..5].iter().enumerate() {
            let f = run.frame.as_ref().unwrap();
            assert_eq!(
                (f.sequence.as_str(), f.index, f.count),
                ("n0-r00", k as u32, 5)
            );
            assert_eq!(f.time_s, k as f64 / 10.0);
            // Tubes, detectors and the box are drawn once per sequence.
            assert_eq!(run.sources, r[0].sources);
            assert_eq!(run.detectors, r[0].detectors);
            assert_eq!(run.phantoms[0], r[0].phantoms[0]);
            assert_eq!(run.geometry_stream, r[0].geometry_stream);
        }
        assert_ne!(r[5].sources, r[0].sources);
        assert_eq!(
            super::frame_run_id("n0-r00", 12_345, 20_000),
            "n0-r00-f12345"
        );
    }

    #[test]
    fn moving_phantoms_follow_their_keyframes_by_hand() {
        let r = runs(1, 5);
        let femur0 = r[0].phantoms[1].pose();
        let tibia0 = r[0].phantoms[2].pose();
        for run in &r[..5] {
            let t = run.frame.as_ref().unwrap().time_s;
            // Femur: M(t) moves 25 mm/s along its own x and turns 100°/s about it (two
            // keyframes: straight, constant speed). Bead F1 at local (0, 10, 0) lands, in the
            // femur's frame at frame 0, at (25 t, 10 cos θ, 10 sin θ).
            let theta = (100.0 * t).to_radians();
            let want = DVec3::new(25.0 * t, 10.0 * theta.cos(), 10.0 * theta.sin());
            let got = femur0.to_local(run.phantoms[1].markers[0].position_mm);
            assert!((got - want).length() < 1e-9, "t = {t}: {got} vs {want}");
            // Tibia, fixed to the femur 50 mm below its origin, turns 50°/s about its own z
            // relative to the femur: bead T1 at local (0, 0, 10) lies on that axis, so it stays at
            // (0, −50, 10) in the femur's frame, and the tibia's own x axis turns about z.
            let femur = run.phantoms[1].pose();
            let t1 = femur.to_local(run.phantoms[2].markers[0].position_mm);
            assert!((t1 - DVec3::new(0.0, -50.0, 10.0)).length() < 1e-9, "{t1}");
            let x = femur.rotation.transpose() * run.phantoms[2].rotation * DVec3::X;
            let phi = (50.0 * t).to_radians();
            assert!(
                (x - DVec3::new(phi.cos(), phi.sin(), 0.0)).length() < 1e-12,
                "{x}"
            );
        }
        // Frame 0 is the set-up without motion (both motions start at the identity).
        assert_eq!(tibia0, r[0].phantoms[2].pose());
    }

    #[test]
    fn frames_and_sequences_are_prefix_stable() {
        let few = runs(2, 3);
        let many = runs(3, 8);
        for run in &few {
            let mut other = many.iter().find(|m| m.id == run.id).unwrap().clone();
            other.frame.as_mut().unwrap().count = 3;
            assert_eq!(run, &other);
        }
    }

    #[test]
    fn without_motion_a_frame_is_the_run_without_a_sequence() {
        let text = SCENARIO
            .replace("RUNS", "2")
            .replace("FRAMES", "3")
            .replace("[phantoms.motion]\nkeyframes = [{ time_s = 0.0 }, { time_s = 0.4, position_mm = [10.0, 0.0, 0.0], rotation_deg = [40.0, 0.0, 0.0] }]\n", "")
            .replace("[phantoms.motion]\nkeyframes = [{ time_s = 0.0 }, { time_s = 0.4, rotation_deg = [0.0, 0.0, 20.0] }]\n", "");
        let still = text.replace("[sequence]\nframes = 3\nframe_rate_hz = 10\n", "");
        let expand_text = |t: &str| {
            let loaded = from_text(t, Path::new("t.toml"), Path::new(".")).unwrap();
            let models = phantom::build(&loaded).unwrap();
            expand(&loaded.scenario, &models)
        };
        let (frames, plain) = (expand_text(&text), expand_text(&still));
        assert_eq!(frames.len(), 3 * plain.len());
        for (k, run) in frames.iter().enumerate() {
            let mut same = plain[k / 3].clone();
            same.id = run.id.clone();
            same.frame = run.frame.clone();
            assert_eq!(run, &same);
        }
    }
}

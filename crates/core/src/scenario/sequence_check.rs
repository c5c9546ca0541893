//! Checks on `[sequence]` and every `[phantoms.motion]`, located at their key paths like the rest
//! of [`super::validate`].

use super::validate::Checker;
use super::*;
use crate::diagnostic::KeyPath;
use crate::geometry::trajectory::TrajectoryError;

impl Checker<'_> {
    /// Every finding on the joints of sequence `q` of scenario `s`.
    fn joints(&mut self, s: &Scenario, q: &Sequence, path: &KeyPath) {
        let path = path.key("joints");
        self.unique_ids(&path, q.joints.iter().map(|j| j.id.as_str()), "joint");
        let ids: Vec<&str> = s.phantoms.iter().map(|p| p.id.as_str()).collect();
        for (k, j) in q.joints.iter().enumerate() {
            let at = path.index(k);
            self.id(&at.key("id"), &j.id, "the joint id");
            for (key, id) in [("proximal", &j.proximal), ("distal", &j.distal)] {
                if !ids.contains(&id.as_str()) {
                    self.err(
                        at.key(key),
                        format!("no phantom has the id `{}`", crate::diagnostic::cut(id)),
                        format!("valid phantom ids: {}", super::validate::quoted(&ids)),
                    );
                }
            }
            if j.proximal == j.distal {
                self.err(
                    at.key("distal"),
                    format!("the joint's two segments are both `{}`", j.distal),
                    "name the proximal segment's phantom (the femur of a knee) and the distal one's (the tibia)",
                );
            }
            for (key, f) in [
                ("proximal_frame", &j.proximal_frame),
                ("distal_frame", &j.distal_frame),
            ] {
                self.finite3(&at.key(key).key("position_mm"), f.position_mm);
                self.finite3(&at.key(key).key("rotation_deg"), f.rotation_deg);
            }
        }
    }

    /// Every finding on the sequence and the phantoms' motions of `s`.
    pub(super) fn sequence(&mut self, s: &Scenario) {
        let root = KeyPath::root();
        if let Some(q) = &s.sequence {
            let path = root.key("sequence");
            if s.study.is_some() {
                self.err(
                    path.clone(),
                    "a scenario has either [sequence] or [study]: a study's exams are single image sets",
                    "remove [sequence], or simulate the sequence with [protocol] in a scenario of its own",
                );
            }
            if !(1..=MAX_FRAMES).contains(&q.frames) {
                self.err(
                    path.key("frames"),
                    format!("frames must lie in 1 to {MAX_FRAMES}, got {}", q.frames),
                    "the number of images per detector in one sequence, e.g. frames = 100",
                );
            }
            if !(q.frame_rate_hz.is_finite() && q.frame_rate_hz > 0.0) {
                self.err(
                    path.key("frame_rate_hz"),
                    format!(
                        "frame_rate_hz must be a positive number, got {}",
                        q.frame_rate_hz
                    ),
                    "frames per second, e.g. frame_rate_hz = 100",
                );
            } else {
                let period_ms = 1000.0 / q.frame_rate_hz;
                if !(q.pulse_ms.is_finite() && q.pulse_ms >= 0.0 && q.pulse_ms <= period_ms) {
                    self.err(
                        path.key("pulse_ms"),
                        format!(
                            "pulse_ms must lie in 0 to the frame period {period_ms} ms, got {}",
                            q.pulse_ms
                        ),
                        "the exposure time of one frame in milliseconds, e.g. pulse_ms = 1 (0: no motion blur)",
                    );
                }
            }
            self.joints(s, q, &path);
            if !(1..=MAX_PULSE_SAMPLES).contains(&q.pulse_samples) {
                self.err(
                    path.key("pulse_samples"),
                    format!(
                        "pulse_samples must lie in 1 to {MAX_PULSE_SAMPLES}, got {}",
                        q.pulse_samples
                    ),
                    "poses per pulse for the motion blur, e.g. pulse_samples = 5",
                );
            }
        }
        for (i, ph) in s.phantoms.iter().enumerate() {
            let Some(m) = &ph.motion else { continue };
            let path = root.key("phantoms").index(i).key("motion");
            if s.sequence.is_none() {
                self.err(
                    path.clone(),
                    "a motion needs [sequence]: without frames nothing moves",
                    "add [sequence] with frames and frame_rate_hz, or remove the motion",
                );
            }
            if ph.calibration_box.is_some() {
                self.err(
                    path.clone(),
                    "a calibration box cannot move: its frame is the world frame of every truth file",
                    "move the other phantoms instead (a motion is relative, so moving the box is moving everything else the other way)",
                );
                continue;
            }
            let keyframes = path.key("keyframes");
            let before = self.out.len();
            for (k, key) in m.keyframes.iter().enumerate() {
                self.finite3(&keyframes.index(k).key("position_mm"), key.position_mm);
                self.finite3(&keyframes.index(k).key("rotation_deg"), key.rotation_deg);
            }
            if self.out[before..].iter().any(|d| d.is_error()) {
                continue;
            }
            match m.trajectory() {
                Ok(_) => {}
                Err(TrajectoryError::TooFew) => self.err(
                    keyframes,
                    format!("a motion needs at least two keyframes, got {}", m.keyframes.len()),
                    "give the pose at the start and at the end, e.g. keyframes = [{ time_s = 0.0 }, { time_s = 1.0, rotation_deg = [60, 0, 0] }]",
                ),
                Err(TrajectoryError::NotIncreasing { index }) => self.err(
                    keyframes.index(index).key("time_s"),
                    format!(
                        "keyframe times must be finite and strictly increasing: {} follows {}",
                        m.keyframes[index].time_s,
                        m.keyframes[index - 1].time_s
                    ),
                    "list the keyframes in time order, each later than the one before",
                ),
                Err(TrajectoryError::HalfTurn { index, angle_deg }) => self.err(
                    keyframes.index(index).key("rotation_deg"),
                    format!(
                        "this keyframe turns {angle_deg:.3}° from the one before (as a rotation, or in one of its written angles): from 180° on, the way between them is not unique"
                    ),
                    "add a keyframe between them, so that each step turns, and changes each angle, by less than 180°",
                ),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::scenario::messages_of as messages;

    const BASE: &str = r#"
name = "t"
[[sources]]
id = "a"
position_mm = [0, 0, 1000]
[[detectors]]
id = "d"
source = "a"
pixels = [10, 10]
pixel_pitch_mm = [1, 1]
position_mm = [0, 0, -100]
[[exposures]]
id = "e"
phantoms = ["b"]
[[phantoms]]
id = "b"
[[phantoms.beads]]
id = "B1"
position_mm = [0, 0, 0]
"#;

    const MOTION: &str = "[phantoms.motion]\nkeyframes = [{ time_s = 0.0 }, { time_s = 1.0, rotation_deg = [60, 0, 0] }]\n";
    const SEQUENCE: &str = "[sequence]\nframes = 10\nframe_rate_hz = 10\n";

    #[test]
    fn a_sequence_with_a_motion_loads_without_findings() {
        assert_eq!(
            messages(&format!("{BASE}{MOTION}{SEQUENCE}")),
            Vec::<String>::new()
        );
    }

    #[test]
    fn bad_sequences_and_motions_are_refused_at_their_key() {
        let m = messages(&format!("{BASE}{MOTION}"));
        assert!(
            m.iter().any(|x| x.contains("s.toml:20:")
                && x.contains("`phantoms[0].motion`")
                && x.contains("a motion needs [sequence]")),
            "{m:?}"
        );
        let m = messages(&format!(
            "{BASE}[sequence]\nframes = 10\nframe_rate_hz = 100\npulse_ms = 12.5\npulse_samples = 0\n"
        ));
        assert!(
            m.iter().any(|x| x.contains("`sequence.pulse_ms`")
                && x.contains("pulse_ms must lie in 0 to the frame period 10 ms, got 12.5")),
            "{m:?}"
        );
        assert!(
            m.iter()
                .any(|x| x.contains("pulse_samples must lie in 1 to 64, got 0")),
            "{m:?}"
        );
        let m = messages(&format!(
            "{BASE}[sequence]\nframes = 0\nframe_rate_hz = -1\n"
        ));
        assert!(
            m.iter().any(|x| x.contains("s.toml:21:10:")
                && x.contains("frames must lie in 1 to 100000, got 0")),
            "{m:?}"
        );
        assert!(
            m.iter()
                .any(|x| x.contains("frame_rate_hz must be a positive number, got -1")),
            "{m:?}"
        );
        let m = messages(&format!(
            "{BASE}[phantoms.motion]\nkeyframes = [{{ time_s = 0.5 }}, {{ time_s = 0.5 }}]\n{SEQUENCE}"
        ));
        assert!(
            m.iter()
                .any(|x| x.contains("`phantoms[0].motion.keyframes[1].time_s`")
                    && x.contains("strictly increasing: 0.5 follows 0.5")),
            "{m:?}"
        );
        let m = messages(&format!(
            "{BASE}[phantoms.motion]\nkeyframes = [{{ time_s = 0 }}, {{ time_s = 1, rotation_deg = [0, 190, 0] }}]\n{SEQUENCE}"
        ));
        assert!(
            m.iter().any(
                |x| x.contains("`phantoms[0].motion.keyframes[1].rotation_deg`")
                    && x.contains("turns 190.000°")
                    && x.contains("the way between them is not unique")
            ),
            "{m:?}"
        );
        let m = messages(&format!(
            "{BASE}[phantoms.motion]\nkeyframes = [{{ time_s = 0 }}]\n{SEQUENCE}"
        ));
        assert!(
            m.iter()
                .any(|x| x.contains("at least two keyframes, got 1")),
            "{m:?}"
        );
        let m = messages(&format!(
            "{BASE}[phantoms.motion]\nkeyframes = [{{ time_s = 0 }}, {{ time_s = 1, position_mm = [nan, 0, 0] }}]\n{SEQUENCE}"
        ));
        assert!(
            m.iter().any(
                |x| x.contains("keyframes[1].position_mm") && x.contains("not a finite vector")
            ),
            "{m:?}"
        );
    }

    #[test]
    fn joints_name_two_phantoms_that_exist() {
        let m = messages(&format!(
            "{BASE}{MOTION}{SEQUENCE}[[sequence.joints]]\nid = \"knee\"\nproximal = \"femur\"\ndistal = \"b\"\n[[sequence.joints]]\nid = \"knee\"\nproximal = \"b\"\ndistal = \"b\"\n"
        ));
        assert!(
            m.iter().any(|x| x.contains("`sequence.joints[0].proximal`")
                && x.contains("no phantom has the id `femur`")
                && x.contains("valid phantom ids: `b`")),
            "{m:?}"
        );
        assert!(
            m.iter()
                .any(|x| x.contains("`sequence.joints[1].distal`") && x.contains("both `b`")),
            "{m:?}"
        );
        assert!(
            m.iter()
                .any(|x| x.contains("two joints have the id `knee`")),
            "{m:?}"
        );
    }

    #[test]
    fn a_calibration_box_cannot_move() {
        let text = format!(
            "{BASE}[[phantoms]]\nid = \"box\"\n[[phantoms.calibration_box.plates]]\nid = \"F\"\nrole = \"fiducial\"\ncenter_mm = [0, 0, 0]\nsize_mm = [50, 50]\ngrid = [2, 2]\nspacing_mm = [20, 20]\n{MOTION}{SEQUENCE}"
        );
        let m = messages(&text);
        assert!(
            m.iter().any(|x| x.contains("`phantoms[1].motion`")
                && x.contains("a calibration box cannot move")),
            "{m:?}"
        );
    }
}

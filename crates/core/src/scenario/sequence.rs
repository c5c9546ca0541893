//! A dynamic exam as the user writes it: `[sequence]` (how many frames, how fast) and each
//! moving phantom's `[phantoms.motion]` (its keyframes). What the keyframes mean between their
//! times is [`crate::geometry::trajectory`]'s; how frames become runs is
//! [`crate::expand::sequence`]'s.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::study::FrameSpec;
use crate::geometry::Pose;
use crate::geometry::joint::{JointAngles, grood_suntay};
use crate::geometry::trajectory::{Key, Trajectory, TrajectoryError};

/// A sequence of frames at a fixed rate: every run of the protocol becomes `frames` runs, one per
/// frame, with the same drawn geometry (tubes, detectors, box, every phantom's set-up) and each
/// moving phantom at its pose at the frame's time. Frame `k` is taken at `t = k / frame_rate_hz`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Sequence {
    /// Frames per sequence, 1 to 100 000.
    pub frames: u32,
    /// Frames per second, > 0 (e.g. 100 for dynamic RSA, up to 1000 for videoradiography).
    pub frame_rate_hz: f64,
    /// Exposure (pulse) time of each frame, ms, centred on the frame's time; at most the frame
    /// period `1000 / frame_rate_hz`. A phantom that moves during the pulse is blurred: the
    /// image is the mean of the images at `pulse_samples` poses inside the pulse. Default 0 (an
    /// instantaneous exposure: no motion blur).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub pulse_ms: f64,
    /// Poses per pulse for the motion blur, 1 to 64, at the middles of equal parts of the pulse
    /// (times `t + ((j + ½)/K − ½)·pulse`, j = 0 … K − 1). Default 5.
    #[serde(default = "Sequence::default_pulse_samples")]
    pub pulse_samples: u32,
    /// Joints whose kinematics the truth of every frame gives, in the joint coordinate system
    /// of Grood and Suntay (Conventions, "Dynamic exams"). Default: none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub joints: Vec<JointSpec>,
}

/// A joint between two phantoms, e.g. the knee between the femur (proximal) and the tibia
/// (distal). Its coordinate system is built on an anatomical frame in each: x medio-lateral in
/// the proximal one (the flexion axis), y along the long axis (proximal) in the distal one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct JointSpec {
    /// Id (letters, digits, `-`, `_`, `.`), e.g. `knee`.
    pub id: String,
    /// Id of the proximal segment's phantom (the femur of a knee).
    pub proximal: String,
    /// Id of the distal segment's phantom (the tibia of a knee).
    pub distal: String,
    /// The proximal anatomical frame in that phantom's local frame: x medio-lateral (the
    /// flexion axis), y proximal, z anterior; its origin is where translations are measured
    /// from. Default: the phantom's own frame.
    #[serde(default)]
    pub proximal_frame: FrameSpec,
    /// The distal anatomical frame in that phantom's local frame: y along its long axis
    /// (proximal), x medio-lateral, z anterior. Default: the phantom's own frame.
    #[serde(default)]
    pub distal_frame: FrameSpec,
}

impl JointSpec {
    /// The joint's kinematics ([`crate::geometry::joint`]) with its proximal phantom at
    /// `proximal` and its distal phantom at `distal` (world ← local poses): the anatomical
    /// frames are those poses composed with `proximal_frame` and `distal_frame`. The truth's
    /// `frame.joints` and `rsasim evaluate`'s measured kinematics both come from here.
    pub fn kinematics(&self, proximal: &Pose, distal: &Pose) -> JointAngles {
        let anatomical = |pose: &Pose, spec: &FrameSpec| {
            pose.compose(&Pose::from_position_euler_deg(
                spec.position_mm,
                spec.rotation_deg,
            ))
        };
        grood_suntay(
            &anatomical(proximal, &self.proximal_frame),
            &anatomical(distal, &self.distal_frame),
        )
    }
}

impl Sequence {
    fn default_pulse_samples() -> u32 {
        5
    }

    /// The offsets from a frame's time of the poses its image is the mean of, s: none without
    /// motion blur (no pulse, or one sample).
    pub fn pulse_offsets_s(&self) -> Vec<f64> {
        let k = self.pulse_samples;
        if !(self.pulse_ms > 0.0) || k <= 1 {
            return Vec::new();
        }
        let pulse_s = self.pulse_ms / 1000.0;
        (0..k)
            .map(|j| ((f64::from(j) + 0.5) / f64::from(k) - 0.5) * pulse_s)
            .collect()
    }
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// Most poses per pulse.
pub const MAX_PULSE_SAMPLES: u32 = 64;

/// How a phantom moves during a sequence: its pose over time relative to the pose it would have
/// without motion (its nominal pose with this run's random offsets, or, when `fixed_to`
/// another, its place on that phantom). A keyframe at `[0, 0, 0]` and `[0, 0, 0]` is that pose.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Motion {
    /// At least two keyframes, in strictly increasing time. Between them, positions follow a
    /// cubic (Catmull–Rom tangents) and rotations the shortest arc at constant angular speed;
    /// before the first and after the last the pose is held.
    pub keyframes: Vec<Keyframe>,
}

impl Motion {
    /// The trajectory of the keyframes, or why they make none.
    pub fn trajectory(&self) -> Result<Trajectory, TrajectoryError> {
        let keys: Vec<Key> = self
            .keyframes
            .iter()
            .map(|k| Key {
                time_s: k.time_s,
                position_mm: k.position_mm,
                rotation_deg: k.rotation_deg,
            })
            .collect();
        Trajectory::new(&keys)
    }
}

/// One pose at one time, in the phantom's frame without motion.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Keyframe {
    /// Time from the first frame, s.
    pub time_s: f64,
    /// Displacement of the phantom's local origin, mm, along its axes without motion. Default
    /// `[0, 0, 0]`.
    #[serde(default)]
    pub position_mm: [f64; 3],
    /// Rotation about its own axes, X-Y-Z Euler angles in degrees. Default `[0, 0, 0]`.
    #[serde(default)]
    pub rotation_deg: [f64; 3],
}

/// Most frames a sequence may have.
pub const MAX_FRAMES: u32 = 100_000;

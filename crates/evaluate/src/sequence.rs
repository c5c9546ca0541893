//! A dynamic exam scored over time (the report's "Dynamic exam" section): for every model and
//! every joint of `[sequence]`, per degree of freedom, the errors of every measured frame of
//! every sequence, their bias, RMS and largest value, the trueness frame by frame (the mean over
//! the repeated sequences at each frame number), and an ISO 5725-2 analysis with the frames as
//! groups and the sequences as repeats — its repeatability `s_r` is the precision over
//! sequences, its `s_L` how much the bias changes from frame to frame.
//!
//! Errors are measured − true, as in the paper's tables: a model's orientation by the X-Y-Z
//! decomposition of `R_measured·R_trueᵀ` about the box axes, its position along them
//! ([`crate::residual`]); a joint's angles and translations in its joint coordinate system
//! (Grood and Suntay), computed from the measured poses of its two phantoms with the scenario's
//! anatomical frames ([`rsasim_core::scenario::JointSpec::kinematics`], the formulas the truth's
//! `frame.joints` come from), angle differences wrapped into (−180°, 180°].
//!
//! The values beside the errors, for the plots of truth against measured over time: a model's
//! position and the X-Y-Z Euler angles of its rotation (box frame); a joint's six coordinates.

use std::collections::BTreeMap;

use glam::DMat3;
use serde::Serialize;

use crate::geometry::{Pose, euler_xyz_deg};
use crate::input::{Scored, model_ids};
use crate::iso5725::{self, Iso5725};
use crate::residual::{orientation_about, position_along, quantise};
use rsasim_core::scenario::{JointSpec, Scenario};

/// The dynamic exam's section: one part per protocol level.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SequenceSection {
    /// Frames per sequence.
    pub frames: u32,
    /// One part per level of the protocol, in protocol order.
    pub levels: Vec<SequenceLevel>,
}

/// The sequences of one protocol level.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SequenceLevel {
    /// Noise level as a fraction of I_max (0 in attenuation mode).
    pub noise_level: f64,
    /// Attenuation mode: the level's factor on the exposure.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exposure_factor: Option<f64>,
    /// The sequences with at least one measured frame, in order.
    pub sequences: Vec<String>,
    /// Every model, then every joint.
    pub entities: Vec<Entity>,
}

/// A model or a joint.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Entity {
    /// The phantom's or the joint's id.
    pub id: String,
    /// `model`, or `joint <proximal> → <distal>`.
    pub kind: String,
    /// Its six degrees of freedom; those with no measured frame are left out.
    pub dofs: Vec<Dof>,
}

/// One degree of freedom scored over every measured frame of the level's sequences.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Dof {
    /// Its name, e.g. `α`, `x`, `flexion α`, `q1`.
    pub label: String,
    /// `mm` or `deg`.
    pub unit: String,
    /// Errors scored.
    pub n: usize,
    /// Mean error over every frame of every sequence.
    pub bias: f64,
    /// Root mean square of the errors.
    pub rms: f64,
    /// The largest |error|, with its sign.
    pub max_error: f64,
    /// The run (frame) of that error.
    pub max_error_run: String,
    /// The largest |trueness| of one frame number over the sequences, with its sign.
    pub worst_frame_trueness: f64,
    /// That frame's number (0-based).
    pub worst_frame: u32,
    /// ISO 5725-2 with the frame numbers as groups and the sequences as repeats.
    pub analysis: Iso5725,
    /// Truth and measured values over time, one series per sequence.
    pub series: Vec<Series>,
}

/// One sequence's values of a degree of freedom.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Series {
    /// The sequence's id.
    pub sequence: String,
    /// Its measured frames, in frame order.
    pub points: Vec<Point>,
}

/// One frame's value of a degree of freedom.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Point {
    /// Frame number, 0-based.
    pub frame: u32,
    /// The frame's run id.
    pub run: String,
    /// The frame's time, s.
    pub time_s: f64,
    /// The true value.
    pub truth: f64,
    /// The measured value.
    pub measured: f64,
    /// The error (module documentation).
    pub error: f64,
}

/// Labels and units of a model's degrees of freedom, in the paper's order.
const MODEL_DOFS: [(&str, &str); 6] = [
    ("α", "deg"),
    ("β", "deg"),
    ("γ", "deg"),
    ("x", "mm"),
    ("y", "mm"),
    ("z", "mm"),
];

/// Labels and units of a joint's degrees of freedom (Grood and Suntay).
const JOINT_DOFS: [(&str, &str); 6] = [
    ("flexion α", "deg"),
    ("ab/adduction β", "deg"),
    ("rotation γ", "deg"),
    ("q1 (along e1)", "mm"),
    ("q2 (along e2)", "mm"),
    ("q3 (along e3)", "mm"),
];

/// What one frame gives one entity: per degree of freedom `(truth, measured, error)`, `None`
/// where it was not measured.
type Values = [Option<(f64, f64, f64)>; 6];

/// Scores the frames among `runs`; `None` when no run is a frame of a sequence.
pub fn score(scenario: &Scenario, runs: &[Scored]) -> Option<SequenceSection> {
    let frames = runs
        .iter()
        .find_map(|r| r.truth.truth.run.frame.as_ref())?
        .count;
    let joints: &[JointSpec] = scenario
        .sequence
        .as_ref()
        .map_or(&[], |q| q.joints.as_slice());
    let models = model_ids(&runs[0].truth.truth.run);
    // Runs by level (protocol order), then sequence and frame.
    let mut by_level: BTreeMap<u32, Vec<&Scored>> = BTreeMap::new();
    for r in runs.iter().filter(|r| r.truth.truth.run.frame.is_some()) {
        by_level
            .entry(r.truth.truth.run.noise_level_index)
            .or_default()
            .push(r);
    }
    let levels = by_level
        .into_values()
        .map(|mut level| {
            level.sort_by_key(|r| {
                let f = r.truth.truth.run.frame.as_ref().expect("filtered");
                (f.sequence.clone(), f.index)
            });
            score_level(&level, &models, joints)
        })
        .collect();
    Some(SequenceSection { frames, levels })
}

/// The part of one level: `runs` sorted by sequence and frame.
fn score_level(runs: &[&Scored], models: &[&str], joints: &[JointSpec]) -> SequenceLevel {
    let run = &runs[0].truth.truth.run;
    let mut sequences: Vec<String> = Vec::new();
    let mut entities = Vec::new();
    let mut score_entity = |id: &str,
                            kind: String,
                            labels: &[(&str, &str); 6],
                            f: &dyn Fn(&Scored) -> Option<Values>| {
        let mut samples: Vec<Vec<(&Scored, (f64, f64, f64))>> = vec![Vec::new(); 6];
        for r in runs {
            if let Some(values) = f(r) {
                for (k, v) in values.iter().enumerate() {
                    if let Some(v) = v {
                        samples[k].push((r, *v));
                    }
                }
            }
        }
        let dofs: Vec<Dof> = samples
            .iter()
            .zip(labels)
            .filter(|(s, _)| !s.is_empty())
            .map(|(s, (label, unit))| dof(label, unit, s))
            .collect();
        for d in &dofs {
            for s in &d.series {
                if !sequences.contains(&s.sequence) {
                    sequences.push(s.sequence.clone());
                }
            }
        }
        entities.push(Entity {
            id: id.to_string(),
            kind,
            dofs,
        });
    };
    for id in models {
        score_entity(id, "model".into(), &MODEL_DOFS, &|r| model_values(r, id));
    }
    for j in joints {
        score_entity(
            &j.id,
            format!("joint {} → {}", j.proximal, j.distal),
            &JOINT_DOFS,
            &|r| joint_values(r, j),
        );
    }
    sequences.sort();
    SequenceLevel {
        noise_level: run.noise_level,
        exposure_factor: run.exposure_factor,
        sequences,
        entities,
    }
}

/// A model's values in one frame: orientation then position.
fn model_values(r: &Scored, id: &str) -> Option<Values> {
    let t = r.truth.truth.run.phantoms.iter().find(|p| p.id == id)?;
    let (p, rot) = r.measured?.phantoms.get(id)?;
    let mut v: Values = [None; 6];
    let (tp, mp) = (t.position_mm.to_array(), p.to_array());
    let dp = position_along(&DMat3::IDENTITY, *p, t.position_mm);
    for k in 0..3 {
        v[3 + k] = Some((tp[k], mp[k], quantise(dp[k])));
    }
    if let Some(rot) = rot {
        let (ta, ma) = (euler_xyz_deg(&t.rotation), euler_xyz_deg(rot));
        let da = orientation_about(&DMat3::IDENTITY, rot, &t.rotation);
        for k in 0..3 {
            v[k] = Some((ta[k], ma[k], quantise(da[k])));
        }
    }
    Some(v)
}

/// A joint's values in one frame, when the truth has the joint and both its phantoms were
/// measured with their orientation.
fn joint_values(r: &Scored, j: &JointSpec) -> Option<Values> {
    let truth = r
        .truth
        .truth
        .run
        .frame
        .as_ref()?
        .joints
        .iter()
        .find(|x| x.id == j.id)?;
    let m = r.measured?;
    let pose = |id: &str| {
        let (p, rot) = m.phantoms.get(id)?;
        Some(Pose {
            position_mm: *p,
            rotation: (*rot)?,
        })
    };
    let k = j.kinematics(&pose(&j.proximal)?, &pose(&j.distal)?);
    let mut v: Values = [None; 6];
    for i in 0..3 {
        let (ta, ma) = (truth.angles_deg[i], k.angles_deg[i]);
        v[i] = Some((ta, ma, quantise(wrapped_deg(ma - ta))));
        let (tq, mq) = (truth.translation_mm[i], k.translation_mm[i]);
        v[3 + i] = Some((tq, mq, quantise(mq - tq)));
    }
    v.iter()
        .all(|x| x.is_some_and(|(_, m, _)| m.is_finite()))
        .then_some(v)
}

/// An angle difference in (−180°, 180°].
fn wrapped_deg(d: f64) -> f64 {
    let w = d.rem_euclid(360.0);
    if w > 180.0 { w - 360.0 } else { w }
}

/// The statistics of one degree of freedom from its samples (frames sorted by sequence, then
/// frame number).
fn dof(label: &str, unit: &str, samples: &[(&Scored, (f64, f64, f64))]) -> Dof {
    let errors: Vec<f64> = samples.iter().map(|(_, v)| v.2).collect();
    let n = errors.len();
    let bias = errors.iter().sum::<f64>() / n as f64;
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt();
    let (worst, _) = samples
        .iter()
        .enumerate()
        .fold((0, -1.0), |(bi, bv), (i, (_, v))| {
            if v.2.abs() > bv {
                (i, v.2.abs())
            } else {
                (bi, bv)
            }
        });
    let mut by_frame: BTreeMap<u32, Vec<f64>> = BTreeMap::new();
    let mut series: Vec<Series> = Vec::new();
    for (r, (truth, measured, error)) in samples {
        let f = r.truth.truth.run.frame.as_ref().expect("a frame");
        by_frame.entry(f.index).or_default().push(*error);
        if series.last().is_none_or(|s| s.sequence != f.sequence) {
            series.push(Series {
                sequence: f.sequence.clone(),
                points: Vec::new(),
            });
        }
        series.last_mut().expect("pushed").points.push(Point {
            frame: f.index,
            run: r.truth.truth.run.id.clone(),
            time_s: f.time_s,
            truth: *truth,
            measured: *measured,
            error: *error,
        });
    }
    let (worst_frame, worst_frame_trueness) = by_frame
        .iter()
        .map(|(k, e)| (*k, e.iter().sum::<f64>() / e.len() as f64))
        .fold(
            (0, 0.0),
            |(bk, bt): (u32, f64), (k, t)| {
                if t.abs() > bt.abs() { (k, t) } else { (bk, bt) }
            },
        );
    let groups: Vec<Vec<f64>> = by_frame.into_values().collect();
    Dof {
        label: label.into(),
        unit: unit.into(),
        n,
        bias,
        rms,
        max_error: errors[worst],
        max_error_run: samples[worst].0.truth.truth.run.id.clone(),
        worst_frame_trueness,
        worst_frame,
        analysis: iso5725::analyse(&groups),
        series,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angle_differences_wrap_into_the_half_open_circle() {
        assert_eq!(wrapped_deg(359.0), -1.0);
        assert_eq!(wrapped_deg(-359.0), 1.0);
        assert_eq!(wrapped_deg(180.0), 180.0);
        assert_eq!(wrapped_deg(-180.0), 180.0);
        assert!((wrapped_deg(0.25) - 0.25).abs() < 1e-15);
    }
}

//! One study's measured migration from every exam's measured segments: per patient and exam,
//! each segment's motion since the reference exam (from its markers, with marker stability, or
//! from its measured pose), then each implant's migration relative to the reference segment.
//!
//! It uses only the study's design (segments, anatomical frame, MTPM points, which run is which
//! exam) and what a program measured; never the study's migration or loose-marker records.

use std::collections::BTreeMap;

use glam::DVec3;

use super::motion::{migration, pose_in_anatomical_frame};
use super::quality_flags;
use super::stability::fit_stable;
use crate::geometry::{Pose, rotation_from_rows};
use crate::output::measured::Measured;
use crate::output::migration_measured::{
    ExcludedMarker, MIGRATION_MEASURED_FORMAT, MeasuredMigration, MigrationMeasured, SegmentExam,
};
use crate::output::study::Study;

/// What a program measured of one segment at one exam, box frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SegmentSeen {
    /// Its pose, when measured with a rotation.
    pub pose: Option<Pose>,
    /// Its markers' centres by bead id.
    pub markers: BTreeMap<String, DVec3>,
    /// The program's own ME for this exam's fit, if it reports one.
    pub mean_error_mm: Option<f64>,
    /// The program's own CN for this exam's fit, if it reports one.
    pub condition_number: Option<f64>,
    /// The exam's X-ray source positions (box frame), when the program reports them: they
    /// weigh the markers in the fit between exams ([`fit_stable`]).
    pub sources_mm: Vec<DVec3>,
}

/// What was measured at one exam, by segment id.
pub type ExamSeen = BTreeMap<String, SegmentSeen>;

/// What was seen, by patient and exam: `exam_of_run` gives the exam seen in a run (by run id),
/// `None` where nothing was measured (that exam is then left out).
pub fn seen_by_patient(
    study: &Study,
    mut exam_of_run: impl FnMut(&str) -> Option<ExamSeen>,
) -> BTreeMap<String, BTreeMap<String, ExamSeen>> {
    study
        .patients
        .iter()
        .map(|p| {
            let exams = p
                .runs
                .iter()
                .filter_map(|(exam, run)| Some((exam.clone(), exam_of_run(run)?)))
                .collect();
            (p.id.clone(), exams)
        })
        .collect()
}

/// The segments of a results file (`measured.json`): each phantom's pose (when it has a
/// rotation), its markers and the exam's sources.
pub fn exam_seen(measured: &Measured) -> ExamSeen {
    let sources_mm: Vec<DVec3> = measured
        .sources
        .iter()
        .map(|s| DVec3::from_array(s.position_mm))
        .collect();
    measured
        .phantoms
        .iter()
        .map(|p| {
            let quality = p.quality.as_ref();
            (
                p.id.clone(),
                SegmentSeen {
                    pose: p.rotation.map(|rows| Pose {
                        position_mm: DVec3::from_array(p.position_mm),
                        rotation: rotation_from_rows(rows),
                    }),
                    markers: p
                        .markers
                        .iter()
                        .map(|m| (m.id.clone(), DVec3::from_array(m.position_mm)))
                        .collect(),
                    mean_error_mm: quality.and_then(|q| q.mean_error_mm),
                    condition_number: quality.and_then(|q| q.condition_number),
                    sources_mm: sources_mm.clone(),
                },
            )
        })
        .collect()
}

/// The study's reference exam id, its reference segment id and its implant segment ids.
pub fn design_roles(study: &Study) -> Result<(String, String, Vec<String>), String> {
    let reference_exams: Vec<&str> = study
        .exams
        .iter()
        .filter(|e| e.reference)
        .map(|e| e.id.as_str())
        .collect();
    let [exam] = reference_exams.as_slice() else {
        return Err(format!(
            "the study must have exactly one reference exam, it has {}",
            reference_exams.len()
        ));
    };
    let references: Vec<&str> = study
        .segments
        .iter()
        .filter(|s| s.role == "reference")
        .map(|s| s.id.as_str())
        .collect();
    let [reference] = references.as_slice() else {
        return Err(format!(
            "the study must have exactly one segment with role `reference`, it has {}",
            references.len()
        ));
    };
    let implants: Vec<String> = study
        .segments
        .iter()
        .filter(|s| s.role == "implant")
        .map(|s| s.id.clone())
        .collect();
    if implants.is_empty() {
        return Err("the study has no segment with role `implant`".into());
    }
    Ok((exam.to_string(), reference.to_string(), implants))
}

/// A segment's motion since the reference exam: its pose at the exam, and how it was found.
struct Found {
    pose: Pose,
    record: SegmentExam,
}

/// Finds segment `id` at `exam` from its reference-exam and exam measurements.
fn find_segment(
    patient: &str,
    exam: &str,
    id: &str,
    at_reference: &SegmentSeen,
    at_exam: &SegmentSeen,
    threshold_mm: f64,
) -> Result<Found, String> {
    let reference_pose = at_reference
        .pose
        .ok_or_else(|| format!("{patient} {exam} {id}: no pose at the reference exam"))?;
    let common = at_reference
        .markers
        .keys()
        .filter(|k| at_exam.markers.contains_key(*k))
        .count();
    if common >= 3 {
        let stable = fit_stable(
            &at_reference.markers,
            &at_exam.markers,
            &at_reference.sources_mm,
            &at_exam.sources_mm,
            threshold_mm,
        )
        .map_err(|e| format!("{patient} {exam} {id}: {e}"))?;
        let (me, cn) = (stable.fit.mean_error_mm, stable.fit.condition_number);
        return Ok(Found {
            pose: stable.fit.pose.compose(&reference_pose),
            record: SegmentExam {
                patient: patient.into(),
                exam: exam.into(),
                segment: id.into(),
                method: "markers".into(),
                markers_used: stable.used.iter().map(|m| m.bead.clone()).collect(),
                excluded: stable
                    .excluded
                    .iter()
                    .map(|m| ExcludedMarker {
                        bead: m.bead.clone(),
                        residual_mm: m.residual_mm,
                    })
                    .collect(),
                mean_error_mm: Some(me),
                condition_number: cn.is_finite().then_some(cn),
                flags: quality_flags(Some(me), Some(cn)),
            },
        });
    }
    let pose = at_exam.pose.ok_or_else(|| {
        format!("{patient} {exam} {id}: {common} marker(s) seen at both exams and no pose measured")
    })?;
    let (me, cn) = (at_exam.mean_error_mm, at_exam.condition_number);
    Ok(Found {
        pose,
        record: SegmentExam {
            patient: patient.into(),
            exam: exam.into(),
            segment: id.into(),
            method: "model".into(),
            markers_used: Vec::new(),
            excluded: Vec::new(),
            mean_error_mm: me,
            condition_number: cn.filter(|c| c.is_finite()),
            flags: quality_flags(me, cn),
        },
    })
}

/// The measured migration of every patient of `study`, from `seen` (patient id → exam id → what
/// was measured); `software` names the program. Exams or segments that could not be measured are
/// listed in `failures` and left out.
pub fn measure_study(
    study: &Study,
    seen: &BTreeMap<String, BTreeMap<String, ExamSeen>>,
    threshold_mm: f64,
    software: &str,
) -> Result<MigrationMeasured, String> {
    let (reference_exam, reference, implants) = design_roles(study)?;
    let mut out = MigrationMeasured {
        format: MIGRATION_MEASURED_FORMAT.into(),
        software: software.into(),
        scenario: study.scenario.clone(),
        reference_exam: reference_exam.clone(),
        stability_threshold_mm: threshold_mm,
        segments: Vec::new(),
        migrations: Vec::new(),
        failures: Vec::new(),
    };
    let empty = BTreeMap::new();
    let nothing = SegmentSeen::default();
    for patient in &study.patients {
        let exams = seen.get(&patient.id).unwrap_or(&empty);
        let Some(at_reference) = exams.get(&reference_exam) else {
            out.failures.push(format!(
                "{}: the reference exam {reference_exam} was not measured",
                patient.id
            ));
            continue;
        };
        for exam in study.exams.iter().filter(|e| !e.reference) {
            let Some(at_exam) = exams.get(&exam.id) else {
                out.failures
                    .push(format!("{} {}: not measured", patient.id, exam.id));
                continue;
            };
            let mut found = BTreeMap::new();
            for segment in &study.segments {
                let get = |e: &'_ ExamSeen| e.get(&segment.id).unwrap_or(&nothing).clone();
                match find_segment(
                    &patient.id,
                    &exam.id,
                    &segment.id,
                    &get(at_reference),
                    &get(at_exam),
                    threshold_mm,
                ) {
                    Ok(f) => {
                        out.segments.push(f.record.clone());
                        found.insert(segment.id.clone(), f);
                    }
                    Err(e) => out.failures.push(e),
                }
            }
            let Some(bone) = found.get(&reference) else {
                continue;
            };
            let bone_ref = at_reference
                .get(&reference)
                .and_then(|s| s.pose)
                .ok_or_else(|| format!("{}: no reference pose of {reference}", patient.id))?;
            for implant in &implants {
                let (Some(found_implant), Some(implant_ref)) = (
                    found.get(implant),
                    at_reference.get(implant).and_then(|s| s.pose),
                ) else {
                    continue;
                };
                let points: Vec<DVec3> = study
                    .segments
                    .iter()
                    .find(|s| &s.id == implant)
                    .map(|s| {
                        s.mtpm_points_mm
                            .iter()
                            .map(|p| DVec3::from_array(*p))
                            .collect()
                    })
                    .unwrap_or_default();
                let m = migration(
                    &pose_in_anatomical_frame(&bone_ref, &study.anatomical_frame, &implant_ref),
                    &pose_in_anatomical_frame(
                        &bone.pose,
                        &study.anatomical_frame,
                        &found_implant.pose,
                    ),
                    &points,
                );
                let flags = [&bone.record, &found_implant.record]
                    .iter()
                    .flat_map(|r| r.flags.iter().map(move |f| format!("{}: {f}", r.segment)))
                    .collect();
                out.migrations.push(MeasuredMigration {
                    patient: patient.id.clone(),
                    exam: exam.id.clone(),
                    segment: implant.clone(),
                    translation_mm: m.translation_mm,
                    rotation_deg: m.rotation_deg,
                    mtpm_mm: m.mtpm_mm,
                    flags,
                });
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::rotation_xyz_deg;
    use crate::output::study::{StudyExam, StudyPatient, StudySegment};

    const BONE: [[f64; 3]; 6] = [
        [22.0, 60.0, 14.0],
        [-18.0, 72.0, 9.0],
        [5.0, 85.0, -16.0],
        [-24.0, 40.0, -6.0],
        [15.0, 90.0, 20.0],
        [-6.0, 52.0, 18.0],
    ];
    const IMPLANT: [[f64; 3]; 4] = [
        [30.0, 0.0, 10.0],
        [-30.0, 0.0, 10.0],
        [0.0, 15.0, -20.0],
        [0.0, -10.0, 25.0],
    ];

    fn segment(id: &str, role: &str, prefix: &str, markers: &[[f64; 3]]) -> StudySegment {
        StudySegment {
            id: id.into(),
            role: role.into(),
            markers: (1..=markers.len())
                .map(|k| format!("{prefix}{k}"))
                .collect(),
            mtpm_points_mm: markers.to_vec(),
        }
    }

    fn study() -> Study {
        let exam = |id: &str, days, reference, double_of: Option<&str>| StudyExam {
            id: id.into(),
            days,
            reference,
            double_of: double_of.map(String::from),
        };
        Study {
            format: crate::output::study::STUDY_FORMAT.into(),
            program: "test".into(),
            scenario: "unit".into(),
            segments: vec![
                segment("femur", "reference", "B", &BONE),
                segment("component", "implant", "I", &IMPLANT),
            ],
            anatomical_frame: Pose::from_position_euler_deg([0.0, 50.0, 0.0], [0.0, 0.0, 0.0]),
            rotation_order: "xyz".into(),
            exams: vec![
                exam("postop", 1, true, None),
                exam("double", 1, false, Some("postop")),
                exam("3m", 91, false, None),
            ],
            patients: vec![StudyPatient {
                id: "p01".into(),
                runs: BTreeMap::new(),
                migration: Vec::new(),
                loose_markers: Vec::new(),
            }],
        }
    }

    /// A segment as a program with perfect images would measure it at `pose`.
    fn seen(pose: Pose, prefix: &str, markers: &[[f64; 3]]) -> SegmentSeen {
        SegmentSeen {
            pose: Some(pose),
            markers: markers
                .iter()
                .enumerate()
                .map(|(k, p)| {
                    (
                        format!("{prefix}{}", k + 1),
                        pose.to_world(DVec3::from_array(*p)),
                    )
                })
                .collect(),
            mean_error_mm: None,
            condition_number: None,
            sources_mm: Vec::new(),
        }
    }

    #[test]
    fn a_prescribed_migration_is_measured_and_a_loose_bone_marker_excluded() {
        let study = study();
        let anatomical = study.anatomical_frame;
        let bone0 = Pose::from_position_euler_deg([5.0, -60.0, 3.0], [2.0, -4.0, 6.0]);
        let implant0 = Pose::from_position_euler_deg([4.0, -62.0, 2.0], [1.0, -3.0, 7.0]);
        // At 3 months: subsidence 0.2 mm, tilt 0.3° about x, about the implant's centre (the
        // centroid of its MTPM points) in the anatomical frame; the limb repositioned.
        let p0 = pose_in_anatomical_frame(&bone0, &anatomical, &implant0);
        let centre = IMPLANT
            .iter()
            .map(|p| p0.to_world(DVec3::from_array(*p)))
            .sum::<DVec3>()
            / 4.0;
        let rot = rotation_xyz_deg([0.3, 0.0, 0.0]);
        let m = Pose {
            rotation: rot,
            position_mm: centre + DVec3::new(0.0, -0.2, 0.0) - rot * centre,
        };
        let limb = Pose::from_position_euler_deg([10.0, 4.0, -8.0], [-5.0, 3.0, 12.0]);
        let bone3 = limb.compose(&bone0);
        let implant3 = bone3.compose(&anatomical).compose(&m.compose(&p0));
        let double = Pose::from_position_euler_deg([-3.0, 2.0, 1.0], [1.0, 2.0, -3.0]);
        let mut at3 = seen(bone3, "B", &BONE);
        // B4 came loose by 0.5 mm (its segment's z), B2 by 0.05 mm (noise-sized).
        at3.markers.insert(
            "B4".into(),
            bone3.to_world(DVec3::from_array(BONE[3]) + DVec3::new(0.0, 0.0, 0.5)),
        );
        at3.markers.insert(
            "B2".into(),
            bone3.to_world(DVec3::from_array(BONE[1]) + DVec3::new(0.05, 0.0, 0.0)),
        );
        let exams: BTreeMap<String, ExamSeen> = [
            (
                "postop",
                [
                    ("femur", seen(bone0, "B", &BONE)),
                    ("component", seen(implant0, "I", &IMPLANT)),
                ],
            ),
            (
                "double",
                [
                    ("femur", seen(double.compose(&bone0), "B", &BONE)),
                    ("component", seen(double.compose(&implant0), "I", &IMPLANT)),
                ],
            ),
            (
                "3m",
                [("femur", at3), ("component", seen(implant3, "I", &IMPLANT))],
            ),
        ]
        .into_iter()
        .map(|(e, s)| {
            (
                e.to_string(),
                s.into_iter().map(|(k, v)| (k.to_string(), v)).collect(),
            )
        })
        .collect();
        let seen_all = BTreeMap::from([("p01".to_string(), exams)]);
        let got = measure_study(&study, &seen_all, 0.3, "unit").unwrap();
        assert!(got.failures.is_empty(), "{:?}", got.failures);
        assert_eq!(got.migrations.len(), 2);
        let double = &got.migrations[0];
        assert_eq!(
            (double.exam.as_str(), double.segment.as_str()),
            ("double", "component")
        );
        assert!(double.mtpm_mm < 1e-9 && double.translation_mm.iter().all(|x| x.abs() < 1e-9));
        let three = &got.migrations[1];
        assert_eq!(three.exam, "3m");
        // The loose marker excluded, the 0.05 mm one kept: the bone fit is then off only by
        // B2's 0.05 mm share, a few thousandths of a millimetre at the implant.
        for (g, w) in three.translation_mm.iter().zip([0.0, -0.2, 0.0]) {
            assert!((g - w).abs() < 0.01, "{three:?}");
        }
        for (g, w) in three.rotation_deg.iter().zip([0.3, 0.0, 0.0]) {
            assert!((g - w).abs() < 0.01, "{three:?}");
        }
        let bone_at3 = got
            .segments
            .iter()
            .find(|s| s.exam == "3m" && s.segment == "femur")
            .unwrap();
        assert_eq!(bone_at3.method, "markers");
        assert_eq!(bone_at3.excluded.len(), 1);
        assert_eq!(bone_at3.excluded[0].bead, "B4");
        assert_eq!(bone_at3.markers_used, ["B1", "B2", "B3", "B5", "B6"]);
        assert!(bone_at3.flags.is_empty());
        assert!(three.flags.is_empty());
        // With the exclusion off (a threshold above the residual) the loose marker biases the
        // migration by far more.
        let lax = measure_study(&study, &seen_all, 1.0, "unit").unwrap();
        let biased = &lax.migrations[1];
        let off = biased
            .translation_mm
            .iter()
            .zip([0.0, -0.2, 0.0])
            .map(|(g, w)| (g - w).abs())
            .fold(0.0, f64::max);
        assert!(off > 0.02, "{biased:?}");
    }

    #[test]
    fn a_model_based_implant_uses_its_pose_and_missing_exams_are_failures() {
        let study = study();
        let bone = Pose::from_position_euler_deg([0.0, 0.0, 0.0], [0.0, 0.0, 0.0]);
        let implant0 = Pose::from_position_euler_deg([0.0, -50.0, 0.0], [0.0, 0.0, 0.0]);
        let implant3 = Pose::from_position_euler_deg([0.1, -50.0, 0.0], [0.0, 0.0, 0.0]);
        let model = |pose| SegmentSeen {
            pose: Some(pose),
            mean_error_mm: Some(0.5),
            ..Default::default()
        };
        let exams: BTreeMap<String, ExamSeen> = [
            (
                "postop",
                [
                    ("femur", seen(bone, "B", &BONE)),
                    ("component", model(implant0)),
                ],
            ),
            (
                "3m",
                [
                    ("femur", seen(bone, "B", &BONE)),
                    ("component", model(implant3)),
                ],
            ),
        ]
        .into_iter()
        .map(|(e, s)| {
            (
                e.to_string(),
                s.into_iter().map(|(k, v)| (k.to_string(), v)).collect(),
            )
        })
        .collect();
        let got = measure_study(
            &study,
            &BTreeMap::from([("p01".to_string(), exams)]),
            0.3,
            "unit",
        )
        .unwrap();
        assert_eq!(got.failures, ["p01 double: not measured"]);
        let m = &got.migrations[0];
        assert!((m.translation_mm[0] - 0.1).abs() < 1e-12 && (m.mtpm_mm - 0.1).abs() < 1e-12);
        assert_eq!(m.flags, ["component: ME > 0.35 mm"]);
        let implant = got
            .segments
            .iter()
            .find(|s| s.segment == "component")
            .unwrap();
        assert_eq!(implant.method, "model");
    }
}

//! The study evaluation on a made-up study: trueness cells equal mean(measured − truth), the
//! double-exam limits equal a hand computation from the measured differences, and a loose marker
//! the program excluded is reported as detected (one it kept, as missed).

use std::collections::BTreeMap;

use rsasim::evaluate::stats::Confidence;
use rsasim::evaluate::study::{StudyOptions, score};
use rsasim::geometry::Pose;
use rsasim::output::migration_measured::{
    ExcludedMarker, MeasuredMigration, MigrationMeasured, SegmentExam,
};
use rsasim::output::study::{
    LooseMarker, MigrationTruth, Study, StudyExam, StudyPatient, StudySegment,
};

fn exam(id: &str, days: u32, reference: bool, double_of: Option<&str>) -> StudyExam {
    StudyExam {
        id: id.into(),
        days,
        reference,
        double_of: double_of.map(String::from),
    }
}

fn truth(exam: &str, ty: f64, rx: f64, mtpm: f64) -> MigrationTruth {
    MigrationTruth {
        exam: exam.into(),
        segment: "component".into(),
        translation_mm: [0.0, ty, 0.0],
        rotation_deg: [rx, 0.0, 0.0],
        mtpm_mm: mtpm,
    }
}

fn measured(patient: &str, exam: &str, t: [f64; 3], r: [f64; 3], mtpm: f64) -> MeasuredMigration {
    MeasuredMigration {
        patient: patient.into(),
        exam: exam.into(),
        segment: "component".into(),
        translation_mm: t,
        rotation_deg: r,
        mtpm_mm: mtpm,
        flags: Vec::new(),
    }
}

#[test]
fn accuracy_double_exam_limits_and_loose_markers_equal_hand_computations() {
    let patients: Vec<StudyPatient> = (1..=3)
        .map(|k| StudyPatient {
            id: format!("p0{k}"),
            runs: BTreeMap::new(),
            migration: vec![truth("double", 0.0, 0.0, 0.0), truth("3m", -0.1, 0.3, 0.2)],
            loose_markers: if k == 2 {
                vec![
                    LooseMarker {
                        exam: "3m".into(),
                        segment: "femur".into(),
                        bead: "B4".into(),
                        displacement_mm: [0.0, 0.0, 0.5],
                    },
                    LooseMarker {
                        exam: "3m".into(),
                        segment: "femur".into(),
                        bead: "B5".into(),
                        displacement_mm: [0.4, 0.0, 0.0],
                    },
                ]
            } else {
                Vec::new()
            },
        })
        .collect();
    let study = Study {
        format: rsasim::output::study::STUDY_FORMAT.into(),
        program: "test".into(),
        scenario: "made_up".into(),
        segments: vec![
            StudySegment {
                id: "femur".into(),
                role: "reference".into(),
                markers: vec![],
                mtpm_points_mm: vec![],
            },
            StudySegment {
                id: "component".into(),
                role: "implant".into(),
                markers: vec![],
                mtpm_points_mm: vec![[0.0; 3]],
            },
        ],
        anatomical_frame: Pose::IDENTITY,
        rotation_order: "xyz".into(),
        exams: vec![
            exam("postop", 2, true, None),
            exam("double", 2, false, Some("postop")),
            exam("3m", 90, false, None),
        ],
        patients,
    };
    // Double-exam y differences 0.02, −0.04, 0.05; 3-month y measured −0.08, −0.13, −0.1.
    let migrations = vec![
        measured("p01", "double", [0.0, 0.02, 0.0], [0.0; 3], 0.03),
        measured("p02", "double", [0.0, -0.04, 0.0], [0.0; 3], 0.05),
        measured("p03", "double", [0.0, 0.05, 0.0], [0.0; 3], 0.06),
        measured("p01", "3m", [0.0, -0.08, 0.0], [0.31, 0.0, 0.0], 0.21),
        measured("p02", "3m", [0.0, -0.13, 0.0], [0.28, 0.0, 0.0], 0.22),
        measured("p03", "3m", [0.0, -0.1, 0.0], [0.33, 0.0, 0.0], 0.19),
    ];
    let segment = |bead: Option<&str>| SegmentExam {
        patient: "p02".into(),
        exam: "3m".into(),
        segment: "femur".into(),
        method: "markers".into(),
        markers_used: vec![],
        excluded: bead
            .map(|b| {
                vec![ExcludedMarker {
                    bead: b.into(),
                    residual_mm: 0.49,
                }]
            })
            .unwrap_or_default(),
        mean_error_mm: Some(0.05),
        condition_number: Some(30.0),
        flags: vec![],
    };
    let m = MigrationMeasured {
        format: "rsasim-migration-measured/1".into(),
        software: "ExampleRSA".into(),
        scenario: "made_up".into(),
        reference_exam: "postop".into(),
        stability_threshold_mm: 0.3,
        segments: vec![segment(Some("B4"))],
        migrations,
        failures: vec![],
    };
    let options = StudyOptions {
        limits_99: true,
        ..Default::default()
    };
    let r = score(&study, &m, "test".into(), &Confidence::default(), &options);
    // Trueness at 3 months: y residuals 0.02, −0.03, 0.0 → mean −0.00333…; Rx 0.01, −0.02, 0.03.
    let three = &r.accuracy[0].rows[1];
    assert_eq!(three.exam, "3m");
    let ty = three.cells[1].as_ref().unwrap();
    assert!(
        (ty.trueness - (0.02 - 0.03 + 0.0) / 3.0).abs() < 1e-12,
        "{ty:?}"
    );
    let rx = three.cells[3].as_ref().unwrap();
    assert!((rx.trueness - 0.02 / 3.0).abs() < 1e-12);
    let mtpm = three.cells[6].as_ref().unwrap();
    assert!((mtpm.trueness - (0.01 + 0.02 - 0.01) / 3.0).abs() < 1e-12);
    // Double exam, y: mean 0.01, SD = √((0.01² + 0.05² + 0.04²)/2) = √0.0021,
    // t(0.975, 2) = 4.302652729749462 (scipy), t(0.995, 2) = 9.924843200918287 (scipy).
    let d = &r.double_exams[0];
    assert_eq!((d.exam.as_str(), d.repeats.as_str()), ("double", "postop"));
    let y = &d.limits[1];
    let sd = 0.0021f64.sqrt();
    assert_eq!(y.n, 3);
    assert!((y.mean - 0.01).abs() < 1e-12);
    assert!((y.sd - sd).abs() < 1e-12);
    assert!((y.limits_196[0] - (0.01 - 1.96 * sd)).abs() < 1e-12);
    assert!((y.limits_196[1] - (0.01 + 1.96 * sd)).abs() < 1e-12);
    assert!((y.limit_t95 - 4.302652729749462 * sd).abs() < 1e-10);
    assert!((y.limit_t99.unwrap() - 9.924843200918287 * sd).abs() < 1e-9);
    let mtpm = &d.limits[6];
    assert_eq!(mtpm.parameter, "MTPM");
    assert_eq!(mtpm.median, Some(0.05));
    assert_eq!(mtpm.range, Some([0.03, 0.06]));
    // Loose markers above 0.3 mm: B4 (0.5 mm, excluded) and B5 (0.4 mm, kept: missed).
    assert_eq!(r.loose_markers.len(), 2);
    assert_eq!(r.loose_markers[0].bead, "B4");
    assert_eq!(r.loose_markers[0].excluded, Some(true));
    assert_eq!(r.loose_markers[1].excluded, Some(false));
    assert!(r.false_exclusions.is_empty());
    // A marker excluded that did not move is reported as such.
    let m2 = MigrationMeasured {
        segments: vec![segment(Some("B1"))],
        ..m
    };
    let r2 = score(&study, &m2, "test".into(), &Confidence::default(), &options);
    assert_eq!(r2.false_exclusions.len(), 1);
    assert!(r2.false_exclusions[0].contains("B1"));
    // Each patient's series starts at zero at the reference exam and skips the double exam.
    let s = &r.series[0];
    let exams: Vec<&str> = s.points.iter().map(|p| p.exam.as_str()).collect();
    assert_eq!(exams, ["postop", "3m"]);
    assert_eq!(s.points[1].measured.unwrap()[1], -0.08);
}

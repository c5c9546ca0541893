//! A small hand-built report for the writers' tests: two noise levels, a sources table with two
//! groups, a detector table, one positive, one negative and one non-significant cell, one N = 1
//! cell, an excluded run and one ISO 5725-2 analysis.

use crate::iso5725;
use crate::stats::{Cell, Confidence, Significance};
use crate::table::{Column, ColumnGroup, Excluded, GroupAnalysis, Report, Row, Table};

/// Residuals of the positive cell: mean 1, s = √0.025, P = 2.1318·0.15811/√5 = 0.15074.
pub const POSITIVE: [f64; 5] = [1.0, 1.1, 0.9, 1.2, 0.8];
/// Residuals of the negative cell: mean −0.5, s = √0.00625, P = 0.075371.
pub const NEGATIVE: [f64; 5] = [-0.5, -0.6, -0.4, -0.55, -0.45];
/// Residuals of a cell whose interval contains zero: mean exactly 0 (binary-exact values),
/// s = √0.1171875 = 0.34233, P = 0.32637.
pub const NONE: [f64; 5] = [-0.25, 0.5, 0.125, -0.375, 0.0];

/// A column.
pub fn column(label: &str, latex: &str, unit: &str) -> Column {
    Column {
        label: label.into(),
        latex: latex.into(),
        unit: unit.into(),
    }
}

fn cell(residuals: &[f64]) -> Option<Cell> {
    Some(Cell::from_residuals(residuals, &Confidence::default()))
}

/// The report.
pub fn report() -> Report {
    let shifted = |r: &[f64], d: f64| r.iter().map(|x| x + d).collect::<Vec<f64>>();
    let sources = Table {
        id: "sources".into(),
        caption: "Source positions (trueness ± precision), along each beamline's r, c, s".into(),
        groups: vec![
            ColumnGroup {
                label: "tube1".into(),
                columns: vec![column("x_r", "x_{r}", "mm"), column("y_c", "y_{c}", "mm")],
            },
            ColumnGroup {
                label: "tube2".into(),
                columns: vec![column("x_s", "x_{s}", "mm"), column("y_r", "y_{r}", "mm")],
            },
        ],
        rows: vec![
            Row {
                noise_level: 0.0,
                exposure_factor: None,
                cells: vec![cell(&POSITIVE), cell(&NONE), cell(&NEGATIVE), cell(&[0.3])],
            },
            Row {
                noise_level: 0.225,
                exposure_factor: None,
                cells: vec![
                    cell(&shifted(&NONE, 0.01)),
                    cell(&NONE),
                    cell(&shifted(&NONE, -0.02)),
                    None,
                ],
            },
        ],
    };
    let detector = Table {
        id: "detector-det1".into(),
        caption: "Detector det1 (trueness ± precision), along its r, c, s".into(),
        groups: vec![
            ColumnGroup {
                label: "orientation".into(),
                columns: vec![column("α_r", "\\alpha_{r}", "deg")],
            },
            ColumnGroup {
                label: "position".into(),
                columns: vec![column("s", "s", "mm")],
            },
        ],
        rows: vec![
            Row {
                noise_level: 0.0,
                exposure_factor: None,
                cells: vec![cell(&NONE), cell(&NONE[..4])],
            },
            Row {
                noise_level: 0.225,
                exposure_factor: None,
                cells: vec![cell(&shifted(&NONE, 0.03)), cell(&shifted(&NONE, -0.04))],
            },
        ],
    };
    let analysis = iso5725::analyse(&[NONE.to_vec(), shifted(&NONE, -0.04)]);
    let report = Report {
        program: "rsasim 0.1.0".into(),
        scenario: "demo_scenario".into(),
        manifest_sha256: "ab".repeat(32),
        summary: vec![
            "2 beamlines, 1 detector each".into(),
            "Protocol: 2 noise levels × 5 runs".into(),
        ],
        software: vec!["ExampleRSA 1.0 <beta>".into()],
        results_file: "measured.json".into(),
        repaired_rotations: 0,
        notes: vec!["no MTPM column for model knee: it has neither beads nor a mesh".into()],
        confidence: Confidence::default(),
        runs_scored: 10,
        excluded: vec![Excluded {
            run: "run-0007".into(),
            reason: "no measured.json".into(),
        }],
        tables: vec![sources, detector],
        mtpm: None,
        mtpm_threshold_mm: 0.2,
        group_analyses: vec![GroupAnalysis {
            table: "detector-det1".into(),
            parameter: "s".into(),
            unit: "mm".into(),
            analysis,
        }],
        study: None,
        sequence: None,
    };
    let sig: Vec<Significance> = report.tables[0].rows[0]
        .cells
        .iter()
        .flatten()
        .map(|c| c.significance)
        .collect();
    assert_eq!(
        sig,
        [
            Significance::Positive,
            Significance::None,
            Significance::Negative,
            Significance::None
        ]
    );
    report
}

/// Number of parameters (columns) over every table of `report`, MTPM included.
pub fn parameters(report: &Report) -> usize {
    report
        .tables
        .iter()
        .chain(&report.mtpm)
        .map(|t| t.groups.iter().map(|g| g.columns.len()).sum::<usize>())
        .sum()
}

//! Turning truth and measurements into the report: one table per entity in the paper's layout,
//! cells per noise level, the MTPM table and the ISO 5725-2 analyses.

use std::collections::BTreeMap;

use glam::{DMat3, DVec3};

pub use super::input::{Scored, model_ids};
use super::iso5725;
pub use super::residual::{RESOLUTION, quantise};
use super::residual::{mtpm, orientation_about, position_along};
use super::stats::{Cell, Confidence};
use super::table::{Column, ColumnGroup, Excluded, GroupAnalysis, Row, Table};

/// Residual samples of one table: `[column][level] → values`.
struct Samples {
    table: Table,
    values: Vec<Vec<Vec<f64>>>,
}

impl Samples {
    fn new(id: &str, caption: String, groups: Vec<ColumnGroup>, levels: usize) -> Samples {
        let columns: usize = groups.iter().map(|g| g.columns.len()).sum();
        Samples {
            table: Table {
                id: id.into(),
                caption,
                groups,
                rows: Vec::new(),
            },
            values: vec![vec![Vec::new(); levels]; columns],
        }
    }

    fn push(&mut self, first_column: usize, level: usize, values: &[f64]) {
        for (k, v) in values.iter().enumerate() {
            self.values[first_column + k][level].push(quantise(*v));
        }
    }
}

fn col(label: &str, latex: &str, unit: &str) -> Column {
    Column {
        label: label.into(),
        latex: latex.into(),
        unit: unit.into(),
    }
}

fn beamline_columns() -> Vec<Column> {
    vec![
        col("r", "r", "mm"),
        col("c", "c", "mm"),
        col("s", "s", "mm"),
    ]
}

fn detector_orientation_columns() -> Vec<Column> {
    vec![
        col("α_r", r"\alpha_{r}", "deg"),
        col("β_c", r"\beta_{c}", "deg"),
        col("γ_s", r"\gamma_{s}", "deg"),
    ]
}

/// Object points for MTPM, by phantom id, in the phantom's local frame.
pub type MtpmPoints = BTreeMap<String, Vec<DVec3>>;

/// Builds the tables, the MTPM table and the group analyses. Returns them with the excluded
/// runs/entities and the number of runs scored.
pub fn assemble(
    runs: &[Scored],
    mtpm_points: &MtpmPoints,
    confidence: &Confidence,
    source_truth: crate::SourceTruth,
) -> (
    Vec<Table>,
    Option<Table>,
    Vec<GroupAnalysis>,
    Vec<Excluded>,
    usize,
) {
    let mut levels: Vec<(u32, f64, Option<f64>)> = runs
        .iter()
        .map(|r| {
            (
                r.truth.truth.run.noise_level_index,
                r.truth.truth.run.noise_level,
                r.truth.truth.run.exposure_factor,
            )
        })
        .collect();
    levels.sort_by_key(|l| l.0);
    levels.dedup_by_key(|l| l.0);
    let level_of = |index: u32| {
        levels
            .iter()
            .position(|l| l.0 == index)
            .expect("level listed")
    };
    let first = &runs[0].truth.truth.run;

    let beamline_of = |source: &str| {
        first
            .detectors
            .iter()
            .find(|d| d.source == source)
            .map(|d| d.id.clone())
    };
    let mut sources = Samples::new(
        "sources",
        "Source positions (trueness ± precision), mm, along the beamline axes r, c, s of the source's detector".into(),
        first
            .sources
            .iter()
            .map(|s| ColumnGroup {
                label: match beamline_of(&s.id) {
                    Some(d) => format!("{} (beamline {d})", s.id),
                    None => s.id.clone(),
                },
                columns: beamline_columns(),
            })
            .collect(),
        levels.len(),
    );
    let mut detectors: Vec<Samples> = first
        .detectors
        .iter()
        .map(|d| {
            Samples::new(
                &format!("detector-{}", d.id),
                format!("Detector {} (beamline of source {}): orientation and position (trueness ± precision) along r, c, s", d.id, d.source),
                vec![
                    ColumnGroup { label: "orientation".into(), columns: detector_orientation_columns() },
                    ColumnGroup { label: "position".into(), columns: beamline_columns() },
                ],
                levels.len(),
            )
        })
        .collect();
    let models = model_ids(first);
    let mut phantoms: Vec<Samples> = models
        .iter()
        .map(|id| {
            Samples::new(
                &format!("phantom-{id}"),
                format!("Model {id}: orientation and position (trueness ± precision) along the box axes x, y, z"),
                vec![
                    ColumnGroup {
                        label: "orientation".into(),
                        columns: vec![col("α", r"\alpha", "deg"), col("β", r"\beta", "deg"), col("γ", r"\gamma", "deg")],
                    },
                    ColumnGroup { label: "position".into(), columns: vec![col("x", "x", "mm"), col("y", "y", "mm"), col("z", "z", "mm")] },
                ],
                levels.len(),
            )
        })
        .collect();
    let mtpm_models: Vec<&str> = models
        .iter()
        .copied()
        .filter(|id| mtpm_points.get(*id).is_some_and(|p| !p.is_empty()))
        .collect();
    let mut mtpm_samples = Samples::new(
        "mtpm",
        "Maximum total point motion (MTPM) of each model over its beads (or its bounding-box corners), mm".into(),
        mtpm_models.iter().map(|id| ColumnGroup { label: (*id).into(), columns: vec![col("MTPM", r"\mathrm{MTPM}", "mm")] }).collect(),
        levels.len(),
    );

    let mut excluded = Vec::new();
    let mut scored = 0;
    for r in runs {
        let run = &r.truth.truth.run;
        let Some(m) = r.measured else {
            excluded.push(Excluded {
                run: run.id.clone(),
                reason: "no measurement for this run".into(),
            });
            continue;
        };
        scored += 1;
        let level = level_of(run.noise_level_index);
        let mut missing = Vec::new();
        for (k, s) in run.sources.iter().enumerate() {
            let frame = run
                .detectors
                .iter()
                .find(|d| d.source == s.id)
                .map_or(DMat3::IDENTITY, |d| d.rotation);
            let truth = match (source_truth, s.effective_position_mm) {
                (crate::SourceTruth::Effective, Some(e)) => DVec3::from_array(e),
                _ => s.position_mm,
            };
            match m.sources.get(&s.id) {
                Some(p) => sources.push(3 * k, level, &position_along(&frame, *p, truth)),
                None => missing.push(format!("source {}", s.id)),
            }
        }
        for (d, samples) in run.detectors.iter().zip(&mut detectors) {
            match m.detectors.get(&d.id) {
                Some((p, rot)) => {
                    samples.push(3, level, &position_along(&d.rotation, *p, d.position_mm));
                    match rot {
                        Some(rot) => samples.push(
                            0,
                            level,
                            &orientation_about(&d.rotation, rot, &d.rotation),
                        ),
                        None => missing.push(format!("detector {} orientation", d.id)),
                    }
                }
                None => missing.push(format!("detector {}", d.id)),
            }
        }
        for (id, samples) in models.iter().zip(&mut phantoms) {
            // `check_same_entities` rejects mixed folders first; a run without this model is
            // still only an exclusion here, never a panic.
            let Some(t) = run.phantoms.iter().find(|p| p.id == *id) else {
                missing.push(format!("model {id} (not in this run's truth)"));
                continue;
            };
            match m.phantoms.get(*id) {
                Some((p, rot)) => {
                    samples.push(
                        3,
                        level,
                        &position_along(&DMat3::IDENTITY, *p, t.position_mm),
                    );
                    match rot {
                        Some(rot) => {
                            samples.push(
                                0,
                                level,
                                &orientation_about(&DMat3::IDENTITY, rot, &t.rotation),
                            );
                            if let Some(k) = mtpm_models.iter().position(|x| x == id) {
                                let v = mtpm(
                                    &mtpm_points[*id],
                                    (*p, *rot),
                                    (t.position_mm, t.rotation),
                                );
                                mtpm_samples.push(k, level, &[v]);
                            }
                        }
                        None => missing.push(format!("model {id} orientation")),
                    }
                }
                None => missing.push(format!("model {id}")),
            }
        }
        if !missing.is_empty() {
            excluded.push(Excluded {
                run: run.id.clone(),
                reason: format!("not measured: {}", missing.join(", ")),
            });
        }
    }

    let mut analyses = Vec::new();
    let finish = |s: Samples, analyses: &mut Vec<GroupAnalysis>| -> Table {
        let mut table = s.table;
        // Parameters are named with their group ("tube1 (beamline det1): r", "position: s"), so
        // tables with several groups of the same columns stay unambiguous.
        let columns: Vec<(String, Column)> = table
            .groups
            .iter()
            .flat_map(|g| {
                g.columns
                    .iter()
                    .map(move |c| (format!("{}: {}", g.label, c.label), c.clone()))
            })
            .collect();
        table.rows = levels
            .iter()
            .enumerate()
            .map(|(l, &(_, noise_level, exposure_factor))| Row {
                noise_level,
                exposure_factor,
                cells: s
                    .values
                    .iter()
                    .map(|c| {
                        (!c[l].is_empty()).then(|| {
                            Cell::from_residuals(&c[l], confidence).at_resolution(RESOLUTION)
                        })
                    })
                    .collect(),
            })
            .collect();
        for (k, c) in s.values.iter().enumerate() {
            if c.iter().filter(|v| !v.is_empty()).count() >= 2 {
                analyses.push(GroupAnalysis {
                    table: table.id.clone(),
                    parameter: columns[k].0.clone(),
                    unit: columns[k].1.unit.clone(),
                    analysis: iso5725::analyse(c),
                });
            }
        }
        table
    };
    let mut tables = vec![finish(sources, &mut analyses)];
    tables.extend(detectors.into_iter().map(|s| finish(s, &mut analyses)));
    tables.extend(phantoms.into_iter().map(|s| finish(s, &mut analyses)));
    let mtpm_table = (!mtpm_models.is_empty()).then(|| finish(mtpm_samples, &mut analyses));
    (tables, mtpm_table, analyses, excluded, scored)
}

//! The sweep file: a base scenario and the parameters to vary, read with every problem located by
//! line, column and key path (the same [`Locator`] the scenario uses).

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::diagnostic::{Diagnostic, KeyPath, Locator};

/// How the values of several parameters are combined into points.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Combine {
    /// Every combination (cartesian product), the first parameter varying slowest.
    #[default]
    Grid,
    /// The i-th value of every parameter together; every parameter with more than one value has
    /// the same number of values (a parameter with one value is fixed for every point).
    Zip,
}

/// One parameter as written in the sweep file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParameterRecord {
    /// Key path into the scenario, e.g. `sources.tube2.position_mm`; an array of tables is
    /// entered by the `id` of one of its tables (`phantoms.box.calibration_box.plates.F1.grid`).
    pub key: String,
    /// The values the key takes, one per point (grid: per step of this parameter).
    pub values: Vec<toml::Value>,
    /// What the parameter is, for the summary's column and the plots' axis. Default: the key.
    #[serde(default)]
    pub name: Option<String>,
    /// A number per value, for the summary and the plots' x axis (e.g. the angle between the
    /// tubes a pair of positions makes). Default: the value itself when it is a number.
    #[serde(default)]
    pub axis: Option<Vec<f64>>,
}

/// The sweep file's records.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepRecord {
    /// Name of the sweep. Default: the sweep file's name without `.toml`.
    #[serde(default)]
    pub name: Option<String>,
    /// The base scenario, relative to the sweep file.
    pub scenario: String,
    /// `grid` (default) or `zip`.
    #[serde(default)]
    pub combine: Combine,
    /// The parameters, at least one.
    pub parameters: Vec<ParameterRecord>,
}

/// A sweep file read and checked on its own (the base scenario is not read yet).
pub struct SweepFile {
    /// The records.
    pub record: SweepRecord,
    /// The sweep's name (given or from the file name).
    pub name: String,
    /// The file.
    pub path: PathBuf,
    /// The file's bytes (copied into the sweep folder as `sweep.toml`).
    pub bytes: Vec<u8>,
    /// The base scenario's path (resolved against the sweep file's folder).
    pub scenario_path: PathBuf,
    /// Key path → line index of the sweep file.
    pub locator: Locator,
}

/// The most points a sweep may have without `--allow-large`.
pub const MAX_POINTS: usize = 1000;

/// The most points a sweep may have with `--allow-large`: every point is a scenario prepared in
/// memory and a folder, so the cap stays finite (a grid of 2^36 points would abort on
/// allocation, not run).
pub const MAX_POINTS_LARGE: usize = 100_000;

impl SweepFile {
    /// Reads and checks a sweep file: TOML, known keys, at least one parameter, values and axis
    /// of equal length, key paths well formed and distinct, zipped lengths equal.
    pub fn read(path: &Path) -> Result<SweepFile, Vec<Diagnostic>> {
        let bytes = crate::input_file::read_named(path, crate::scenario::MAX_SCENARIO_BYTES)
            .map_err(|d| {
                vec![d.with_help(
                    "give the path of a sweep .toml file, e.g. scenarios/sweeps/tube_angle.toml",
                )]
            })?;
        let text = std::str::from_utf8(&bytes).map_err(|e| {
            vec![
                Diagnostic::file_error(
                    path,
                    format!("the file is not UTF-8 text (byte {})", e.valid_up_to()),
                )
                .with_help("sweep files are TOML, which must be UTF-8"),
            ]
        })?;
        let locator = Locator::new(path, text);
        let record: SweepRecord = toml::from_str(text).map_err(|e| {
            let message = e.message().trim_end().to_string();
            vec![locator.error_at_span(e.span(), message).with_help(
                "a sweep file holds `scenario = \"BASE.toml\"`, optional `name` and `combine = \"grid\" | \"zip\"`, and [[parameters]] tables with `key`, `values` and optional `name` and `axis` (the manual, docs/src/guide/sweeps.md)",
            )]
        })?;
        let errors = check(&record, &locator);
        if !errors.is_empty() {
            return Err(errors);
        }
        let name = record.name.clone().unwrap_or_else(|| {
            path.file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "sweep".into())
        });
        let scenario_path = path
            .parent()
            .unwrap_or(Path::new(""))
            .join(&record.scenario);
        Ok(SweepFile {
            record,
            name,
            path: path.to_path_buf(),
            bytes,
            scenario_path,
            locator,
        })
    }

    /// The key path of parameter `i`'s `field` in this file.
    pub fn parameter_path(i: usize, field: &str) -> KeyPath {
        KeyPath::root().key("parameters").index(i).key(field)
    }

    /// The number of points, or an error at `combine` when it exceeds `max`.
    pub fn point_count(&self, max: usize) -> Result<usize, Vec<Diagnostic>> {
        let mut lengths = self.record.parameters.iter().map(|p| p.values.len());
        let count = match self.record.combine {
            Combine::Grid => lengths.try_fold(1usize, |n, l| n.checked_mul(l)),
            Combine::Zip => lengths.max(),
        };
        match count {
            Some(n) if n <= max => Ok(n),
            _ => Err(vec![
                self.locator
                    .error(
                        KeyPath::root().key("parameters"),
                        format!(
                            "the sweep has {} points, more than the {max} allowed",
                            count.map_or("more than 2^64".to_string(), |n| n.to_string())
                        ),
                    )
                    .with_help(if max < MAX_POINTS_LARGE {
                        format!("use fewer values, combine = \"zip\", or pass --allow-large (which allows up to {MAX_POINTS_LARGE} points)")
                    } else {
                        format!("use fewer values or combine = \"zip\": even with --allow-large a sweep has at most {MAX_POINTS_LARGE} points; split it into several sweeps")
                    }),
            ]),
        }
    }
}

/// The most parameters a sweep file may vary. Every point applies every parameter to the base
/// scenario, and a sweep of more than a few dozen axes is not one anyone can read; the cap keeps
/// a received sweep file with 100,000 `[[parameters]]` tables from costing minutes.
pub const MAX_PARAMETERS: usize = 64;

/// Every problem of the records that needs no scenario.
fn check(record: &SweepRecord, locator: &Locator) -> Vec<Diagnostic> {
    let mut errors = Vec::new();
    if record.parameters.len() > MAX_PARAMETERS {
        return vec![
            locator
                .error(
                    KeyPath::root().key("parameters"),
                    format!(
                        "the sweep has {} [[parameters]] tables, more than the {MAX_PARAMETERS} allowed",
                        record.parameters.len()
                    ),
                )
                .with_help(format!("vary at most {MAX_PARAMETERS} keys in one sweep; split a larger study into several sweep files")),
        ];
    }
    if record.parameters.is_empty() {
        errors.push(
            locator
                .error(
                    KeyPath::root().key("parameters"),
                    "the sweep names no parameter",
                )
                .with_help("add a [[parameters]] table with `key` and `values`"),
        );
    }
    if let Some(name) = &record.name
        && (name.is_empty()
            || !name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.')))
    {
        errors.push(
            locator
                .error(
                    KeyPath::root().key("name"),
                    format!("the name `{name}` is not a plain name"),
                )
                .with_help(
                    "use letters, digits, `-`, `_` and `.` only, e.g. name = \"tube_angle\"",
                ),
        );
    }
    let mut seen: Vec<&str> = Vec::new();
    for (i, p) in record.parameters.iter().enumerate() {
        let at = |field: &str| SweepFile::parameter_path(i, field);
        if p.key.split('.').any(str::is_empty) {
            errors.push(
                locator
                    .error(at("key"), format!("`{}` is not a key path", p.key))
                    .with_help("keys joined by `.`, e.g. \"sources.tube2.position_mm\" or \"protocol.runs_per_level\""),
            );
        } else if seen.contains(&p.key.as_str()) {
            errors.push(
                locator
                    .error(at("key"), format!("the key `{}` is swept twice", p.key))
                    .with_help("list every value of a key in one [[parameters]] table"),
            );
        }
        seen.push(&p.key);
        if p.values.is_empty() {
            errors.push(
                locator
                    .error(at("values"), "no values")
                    .with_help("give at least one value, e.g. values = [0.5, 1.0]"),
            );
        }
        if let Some(axis) = &p.axis {
            if axis.len() != p.values.len() {
                errors.push(
                    locator
                        .error(
                            at("axis"),
                            format!("{} axis numbers for {} values", axis.len(), p.values.len()),
                        )
                        .with_help("give one number per value, in the same order"),
                );
            } else if let Some(bad) = axis.iter().find(|a| !a.is_finite()) {
                errors.push(
                    locator
                        .error(at("axis"), format!("the axis number {bad} is not finite"))
                        .with_help("give finite numbers"),
                );
            }
        }
    }
    if record.combine == Combine::Zip {
        let longest = record.parameters.iter().map(|p| p.values.len()).max();
        for (i, p) in record.parameters.iter().enumerate() {
            if let Some(n) = longest
                && p.values.len() > 1
                && p.values.len() != n
            {
                errors.push(
                    locator
                        .error(
                            SweepFile::parameter_path(i, "values"),
                            format!(
                                "combine = \"zip\" needs equally many values: `{}` has {}, another parameter {n}",
                                p.key,
                                p.values.len()
                            ),
                        )
                        .with_help("give every zipped parameter the same number of values (one value: fixed for every point)"),
                );
            }
        }
    }
    errors
}

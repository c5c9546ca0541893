//! The report's data: tables of "T ± P" cells, one row per noise level, and the sections beyond
//! the paper. Writers (Markdown, CSV, LaTeX, HTML) only format these records.

use serde::Serialize;

use super::stats::{Cell, Confidence};

/// A table in the paper's layout: one row per noise level, columns grouped (e.g. "orientation",
/// "position", or one group per source).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Table {
    /// Short id used in file names and anchors, e.g. `sources`, `detector-det1`, `phantom-femur`.
    pub id: String,
    /// Caption, e.g. "Source positions (trueness ± precision), along each beamline's r, c, s".
    pub caption: String,
    /// Column groups, left to right.
    pub groups: Vec<ColumnGroup>,
    /// One row per noise level, in protocol order.
    pub rows: Vec<Row>,
}

/// A group of columns under one heading.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ColumnGroup {
    /// Heading, e.g. "tube1" or "orientation".
    pub label: String,
    /// The columns.
    pub columns: Vec<Column>,
}

/// One parameter.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Column {
    /// Parameter symbol as plain text, e.g. `α_r`, `s`, `x`.
    pub label: String,
    /// The same in LaTeX math, e.g. `\alpha_{r}`.
    pub latex: String,
    /// Unit: `mm` or `deg`.
    pub unit: String,
}

/// The cells of one level of the protocol (a noise level, or an exposure level in attenuation
/// mode).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Row {
    /// Noise level as a fraction of I_max (0 in attenuation mode).
    pub noise_level: f64,
    /// Attenuation mode: the level's factor on the exposure.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exposure_factor: Option<f64>,
    /// One cell per column of every group, left to right; `None` where no run measured it.
    pub cells: Vec<Option<Cell>>,
}

/// A run that could not be scored, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Excluded {
    /// Run id.
    pub run: String,
    /// Why: e.g. "no measured.json", or "detector det2 not measured".
    pub reason: String,
}

/// ISO 5725-2 analysis of one parameter with the noise levels as groups (see `iso5725`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GroupAnalysis {
    /// Table id and column label, e.g. `detector-det1` / `s`.
    pub table: String,
    /// Column label.
    pub parameter: String,
    /// Unit.
    pub unit: String,
    /// The analysis.
    pub analysis: super::iso5725::Iso5725,
}

/// Everything `rsasim evaluate` reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// `rsasim <version>`.
    pub program: String,
    /// Scenario name.
    pub scenario: String,
    /// SHA-256 of the output folder's manifest.json (identifies the data set).
    pub manifest_sha256: String,
    /// Scenario summary lines (beamlines, detectors, phantoms, protocol).
    pub summary: Vec<String>,
    /// The software under test, as named in the measured files.
    pub software: Vec<String>,
    /// The results scored: the file name in every run folder, or the CSV file.
    pub results_file: String,
    /// Rotations re-orthonormalised because they deviated (within tolerance) from a rotation.
    pub repaired_rotations: usize,
    /// What the reader must know: the results file chosen by default, repaired rotations, and
    /// every table or column left out, with the reason.
    pub notes: Vec<String>,
    /// τ's confidence and sidedness.
    pub confidence: Confidence,
    /// Runs scored.
    pub runs_scored: usize,
    /// Runs or entities left out.
    pub excluded: Vec<Excluded>,
    /// The paper's tables: sources, each detector, each model.
    pub tables: Vec<Table>,
    /// MTPM (maximum total point motion) of each model over its beads, one table.
    pub mtpm: Option<Table>,
    /// The MTPM a cell is compared with (its upper end T + P), mm.
    pub mtpm_threshold_mm: f64,
    /// ISO 5725-2 analysis per parameter, noise levels as groups.
    pub group_analyses: Vec<GroupAnalysis>,
    /// A clinical study's migration analysis (folders with `study.json`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub study: Option<super::study::StudyReport>,
    /// A dynamic exam's scores over time (folders whose runs are frames of sequences).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sequence: Option<super::sequence::SequenceSection>,
}

impl Row {
    /// The level as a number for plots: the noise level or the exposure factor.
    pub fn level_value(&self) -> f64 {
        self.exposure_factor.unwrap_or(self.noise_level)
    }
}

impl Table {
    /// What the levels of this table are: `Noise` or `Exposure`.
    pub fn level_heading(&self) -> &'static str {
        if self.rows.iter().any(|r| r.exposure_factor.is_some()) {
            "Exposure"
        } else {
            "Noise"
        }
    }
}

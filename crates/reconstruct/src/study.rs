//! The reference program's migration step: on a clinical study's output folder (it holds
//! `study.json`), each patient's migration from the exams just reconstructed, written as
//! `migration_measured.json` and `migration_measured.csv` at the top of the folder.
//!
//! It reads of `study.json` only the design (segments, anatomical frame, MTPM points, exams and
//! which run is which exam), never its migration or loose-marker records.

use std::collections::BTreeMap;
use std::path::Path;

use crate::diagnostic::Diagnostic;
use crate::migration::analysis::{exam_seen, measure_study, seen_by_patient};
use crate::output::atomic::write_atomic;
use crate::output::measured::Measured;
use crate::output::migration_measured::{MIGRATION_MEASURED_CSV, MIGRATION_MEASURED_FILE};
use crate::output::study::{STUDY_FILE, Study};

/// What the migration step wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyOutcome {
    /// Migrations measured (patients × follow-ups × implants).
    pub migrations: usize,
    /// Markers excluded as loose, over every patient and exam.
    pub excluded_markers: usize,
    /// What could not be measured.
    pub failures: Vec<String>,
}

/// Measures and writes the study's migration when `out` holds `study.json` (`design`, as
/// [`read_study`](crate::output::study::read_study) read it); `None` otherwise. `runs` are the
/// results just written, by run id.
pub fn measure_and_write(
    out: &Path,
    design: Option<&Study>,
    runs: &BTreeMap<String, Measured>,
    threshold_mm: f64,
    software: &str,
) -> Result<Option<StudyOutcome>, Vec<Diagnostic>> {
    let Some(design) = design else {
        return Ok(None);
    };
    let file = out.join(STUDY_FILE);
    let seen = seen_by_patient(design, |run| runs.get(run).map(exam_seen));
    let measured = measure_study(design, &seen, threshold_mm, software)
        .map_err(|e| vec![Diagnostic::file_error(&file, e)])?;
    let write = |name: &str, bytes: &[u8]| {
        write_atomic(&out.join(name), bytes).map_err(|e| {
            vec![Diagnostic::file_error(
                &out.join(name),
                format!("cannot write: {e}"),
            )]
        })
    };
    let mut json = serde_json::to_vec_pretty(&measured)
        .map_err(|e| vec![Diagnostic::file_error(&file, e.to_string())])?;
    json.push(b'\n');
    write(MIGRATION_MEASURED_FILE, &json)?;
    write(
        MIGRATION_MEASURED_CSV,
        crate::migration::csv::migration_csv(&measured.migrations).as_bytes(),
    )?;
    Ok(Some(StudyOutcome {
        migrations: measured.migrations.len(),
        excluded_markers: measured.segments.iter().map(|s| s.excluded.len()).sum(),
        failures: measured.failures,
    }))
}

//! The relative-motion CSV another program may give instead of per-exam poses: one row per
//! patient, follow-up exam and implant segment, with the header
//! [`MIGRATION_CSV_HEADER`](crate::output::migration_measured::MIGRATION_CSV_HEADER).

use std::collections::{HashMap, HashSet};
use std::path::Path;

use crate::diagnostic::Diagnostic;
use crate::output::migration_measured::{MIGRATION_CSV_HEADER, MeasuredMigration};
use crate::output::study::Study;

/// Reads `file`: the header line, then `patient,exam,segment,tx_mm,ty_mm,tz_mm,rx_deg,ry_deg,
/// rz_deg,mtpm_mm` rows (numbers finite; MTPM ≥ 0). Errors name the file, line and column.
///
/// With `study`, every row must name a patient, a follow-up exam and an implant segment of the
/// study, and no (patient, exam, segment) may appear twice: a row that would be dropped or would
/// replace another is an error. At most [`MAX_ERRORS`] errors are listed; the rest are counted.
pub fn read_migration_csv(
    file: &Path,
    study: Option<&Study>,
) -> Result<Vec<MeasuredMigration>, Vec<Diagnostic>> {
    let text = crate::input_file::read_named_text(file, crate::output::received::MAX_TABLE_BYTES)
        .map_err(|d| vec![d])?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let design = study.map(|s| {
        let patients: HashSet<&str> = s.patients.iter().map(|p| p.id.as_str()).collect();
        let exams: HashSet<&str> = s
            .exams
            .iter()
            .filter(|e| !e.reference)
            .map(|e| e.id.as_str())
            .collect();
        let implants: HashSet<&str> = s
            .segments
            .iter()
            .filter(|g| g.role == "implant")
            .map(|g| g.id.as_str())
            .collect();
        (patients, exams, implants)
    });
    let mut first_line: HashMap<(String, String, String), usize> = HashMap::new();
    let mut dropped = 0usize;
    let help = format!("the first line must be `{MIGRATION_CSV_HEADER}`");
    let mut lines = text.lines().enumerate();
    let header_ok = lines
        .next()
        .is_some_and(|(_, h)| h.trim().eq_ignore_ascii_case(MIGRATION_CSV_HEADER));
    if !header_ok {
        return Err(vec![
            Diagnostic::file_error(file, "line 1: not the migration CSV header").with_help(help),
        ]);
    }
    let columns: Vec<&str> = MIGRATION_CSV_HEADER.split(',').collect();
    let mut rows = Vec::new();
    let mut errors = Vec::new();
    for (k, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let at = |msg: String| {
            Diagnostic::file_error(file, format!("line {}: {msg}", k + 1)).with_help(help.clone())
        };
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != columns.len() {
            errors.push(at(format!(
                "{} fields, expected {}",
                fields.len(),
                columns.len()
            )));
            continue;
        }
        let mut numbers = [0.0; 7];
        let mut bad = false;
        for (i, n) in numbers.iter_mut().enumerate() {
            match fields[3 + i].parse::<f64>() {
                Ok(v) if v.is_finite() && v.abs() < 1e6 => *n = v,
                _ => {
                    errors.push(at(format!(
                        "column {}: `{}` is not a finite number",
                        columns[3 + i],
                        crate::diagnostic::cut(fields[3 + i])
                    )));
                    bad = true;
                }
            }
        }
        if !bad && numbers[6] < 0.0 {
            errors.push(at(format!(
                "column mtpm_mm: {} is negative (MTPM is a length)",
                numbers[6]
            )));
            bad = true;
        }
        if bad {
            continue;
        }
        if let Some((patients, exams, implants)) = &design {
            for (column, value, known, what) in [
                ("patient", fields[0], patients, "a patient"),
                ("exam", fields[1], exams, "a follow-up exam"),
                ("segment", fields[2], implants, "an implant segment"),
            ] {
                if !known.contains(value) {
                    let mut valid: Vec<&str> = known.iter().copied().collect();
                    valid.sort_unstable();
                    valid.truncate(10);
                    errors.push(at(format!(
                        "column {column}: `{}` is not {what} of the study (e.g. {})",
                        crate::diagnostic::cut(value),
                        valid.join(", ")
                    )));
                    bad = true;
                    break;
                }
            }
            if bad {
                continue;
            }
        }
        let key = (
            fields[0].to_string(),
            fields[1].to_string(),
            fields[2].to_string(),
        );
        if let Some(first) = first_line.get(&key) {
            errors.push(at(format!(
                "repeats patient `{}`, exam `{}`, segment `{}` of line {first}: give one row each",
                crate::diagnostic::cut(fields[0]),
                crate::diagnostic::cut(fields[1]),
                crate::diagnostic::cut(fields[2])
            )));
            continue;
        }
        first_line.insert(key, k + 1);
        rows.push(MeasuredMigration {
            patient: fields[0].into(),
            exam: fields[1].into(),
            segment: fields[2].into(),
            translation_mm: [numbers[0], numbers[1], numbers[2]],
            rotation_deg: [numbers[3], numbers[4], numbers[5]],
            mtpm_mm: numbers[6],
            flags: Vec::new(),
        });
    }
    if errors.is_empty() {
        Ok(rows)
    } else {
        if errors.len() > MAX_ERRORS {
            dropped += errors.len() - MAX_ERRORS;
            errors.truncate(MAX_ERRORS);
        }
        if dropped > 0 {
            errors.push(Diagnostic::file_error(
                file,
                format!("{dropped} more problem(s) of the same kinds, not listed"),
            ));
        }
        Err(errors)
    }
}

/// Most errors listed for one migration CSV.
pub const MAX_ERRORS: usize = 20;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn written_rows_read_back_and_bad_rows_name_line_and_column() {
        let rows = vec![MeasuredMigration {
            patient: "p01".into(),
            exam: "3m".into(),
            segment: "component".into(),
            translation_mm: [0.1, -0.2, 1e-17],
            rotation_deg: [0.3, 0.0, -0.05],
            mtpm_mm: 0.25,
            flags: Vec::new(),
        }];
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("m.csv");
        std::fs::write(&file, crate::migration::csv::migration_csv(&rows)).unwrap();
        assert_eq!(read_migration_csv(&file, None).unwrap(), rows);
        std::fs::write(
            &file,
            format!("{MIGRATION_CSV_HEADER}\np01,3m,c,0,0,0,0,0,0,-1\np01,1y,c,0,x,0,0,0,0,1\n"),
        )
        .unwrap();
        let e = read_migration_csv(&file, None).unwrap_err();
        assert_eq!(e.len(), 2);
        assert!(e[0].message.contains("line 2") && e[0].message.contains("mtpm_mm"));
        assert!(e[1].message.contains("line 3") && e[1].message.contains("ty_mm"));
        std::fs::write(&file, "patient,exam\n").unwrap();
        assert!(
            read_migration_csv(&file, None).unwrap_err()[0]
                .message
                .contains("header")
        );
    }
}

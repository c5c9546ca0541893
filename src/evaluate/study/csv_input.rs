//! The relative-motion CSV another program may give instead of per-exam poses: one row per
//! patient, follow-up exam and implant segment, with the header
//! [`MIGRATION_CSV_HEADER`](crate::output::migration_measured::MIGRATION_CSV_HEADER).

use std::path::Path;

use crate::diagnostic::Diagnostic;
use crate::output::migration_measured::{MIGRATION_CSV_HEADER, MeasuredMigration};

/// Reads `file`: the header line, then `patient,exam,segment,tx_mm,ty_mm,tz_mm,rx_deg,ry_deg,
/// rz_deg,mtpm_mm` rows (numbers finite; MTPM ≥ 0). Errors name the file, line and column.
pub fn read_migration_csv(file: &Path) -> Result<Vec<MeasuredMigration>, Vec<Diagnostic>> {
    let text = std::fs::read_to_string(file)
        .map_err(|e| vec![Diagnostic::file_error(file, format!("cannot read: {e}"))])?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
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
        Err(errors)
    }
}

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
        assert_eq!(read_migration_csv(&file).unwrap(), rows);
        std::fs::write(
            &file,
            format!("{MIGRATION_CSV_HEADER}\np01,3m,c,0,0,0,0,0,0,-1\np01,1y,c,0,x,0,0,0,0,1\n"),
        )
        .unwrap();
        let e = read_migration_csv(&file).unwrap_err();
        assert_eq!(e.len(), 2);
        assert!(e[0].message.contains("line 2") && e[0].message.contains("mtpm_mm"));
        assert!(e[1].message.contains("line 3") && e[1].message.contains("ty_mm"));
        std::fs::write(&file, "patient,exam\n").unwrap();
        assert!(
            read_migration_csv(&file).unwrap_err()[0]
                .message
                .contains("header")
        );
    }
}

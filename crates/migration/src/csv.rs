//! The migration CSV table (one row per patient, follow-up exam and implant segment).

use crate::output::migration_measured::{MIGRATION_CSV_HEADER, MeasuredMigration};

/// The rows of `migrations` as the migration CSV (full precision), header first.
pub fn migration_csv(migrations: &[MeasuredMigration]) -> String {
    let mut s = format!("{MIGRATION_CSV_HEADER}\n");
    for m in migrations {
        let [tx, ty, tz] = m.translation_mm;
        let [rx, ry, rz] = m.rotation_deg;
        s.push_str(&format!(
            "{},{},{},{tx},{ty},{tz},{rx},{ry},{rz},{}\n",
            m.patient, m.exam, m.segment, m.mtpm_mm
        ));
    }
    s
}

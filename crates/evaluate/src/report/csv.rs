//! The CSV reports: every cell at full precision, and the ISO 5725-2 analyses.

use super::{columns, iso};
use crate::stats::Significance;
use crate::table::Report;

/// Header of [`csv`].
pub(crate) const HEADER: [&str; 13] = [
    "table",
    "group",
    "parameter",
    "unit",
    "noise_level",
    "n",
    "trueness",
    "precision",
    "sd",
    "tau",
    "rms",
    "significance",
    "exposure_factor",
];

/// One long table, one row per (table, group, parameter, noise level), the paper's tables first
/// and the MTPM table last. Numbers are Rust's shortest round-trip `{}` formatting (NaN where
/// undefined, e.g. the precision at N = 1), so every cell can be re-computed; a parameter no run
/// measured at a noise level has empty fields. `noise_level` is a fraction of I_max (0 in
/// attenuation mode, where the levels are exposures); `significance` is `positive`, `negative`
/// or `none`; `exposure_factor` (last, so that older column positions hold) is the level's
/// exposure factor in attenuation mode and empty in binary mode.
pub fn csv(report: &Report) -> String {
    let mut w = writer();
    w.write_record(HEADER).expect("write to memory");
    for record in records(report) {
        w.write_record(&record).expect("write to memory");
    }
    finish(w)
}

/// The rows of [`csv`] without its header, as fields (the sweep summary prefixes them with the
/// point and its parameters).
pub(crate) fn records(report: &Report) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    for table in report.tables.iter().chain(&report.mtpm) {
        for row in &table.rows {
            for ((group, column), cell) in columns(table).zip(&row.cells) {
                let mut record = vec![
                    table.id.clone(),
                    group.label.clone(),
                    column.label.clone(),
                    column.unit.clone(),
                    row.noise_level.to_string(),
                ];
                match cell {
                    Some(c) => record.extend([
                        c.n.to_string(),
                        c.trueness.to_string(),
                        c.precision.to_string(),
                        c.sd.to_string(),
                        c.tau.to_string(),
                        c.rms.to_string(),
                        significance(c.significance).into(),
                    ]),
                    None => record.extend(std::iter::repeat_n(String::new(), 7)),
                }
                record.push(
                    row.exposure_factor
                        .map_or_else(String::new, |f| f.to_string()),
                );
                out.push(record);
            }
        }
    }
    out
}

/// The ISO 5725-2 analyses, one row per parameter: `table, parameter, unit, groups,
/// n_per_group` (counts joined by `;`), `grand_mean, s_r, s_L, s_R, r, R, anova_f, df_between,
/// df_within, p_value` (full precision; empty where no ANOVA is possible) and
/// `noise_changes_result` (`yes`, `no` or `not testable`, at 5 %).
pub fn csv_iso5725(report: &Report) -> String {
    let mut w = writer();
    let keys: Vec<&str> = match report.group_analyses.first() {
        Some(g) => iso::fields(g).iter().map(|f| f.key).collect(),
        None => vec!["table", "parameter", "unit"],
    };
    w.write_record(&keys).expect("write to memory");
    for g in &report.group_analyses {
        w.write_record(iso::fields(g).iter().map(|f| f.value.exact()))
            .expect("write to memory");
    }
    finish(w)
}

/// The CSV name of a significance.
pub(crate) fn significance(s: Significance) -> &'static str {
    match s {
        Significance::Positive => "positive",
        Significance::Negative => "negative",
        Significance::None => "none",
    }
}

pub(crate) fn writer() -> ::csv::Writer<Vec<u8>> {
    ::csv::WriterBuilder::new()
        .terminator(::csv::Terminator::Any(b'\n'))
        .from_writer(Vec::new())
}

pub(crate) fn finish(w: ::csv::Writer<Vec<u8>>) -> String {
    String::from_utf8(w.into_inner().expect("flush to memory")).expect("UTF-8 fields")
}

#[cfg(test)]
mod tests {
    use super::super::fixture::report;
    use super::*;
    use crate::report::columns;

    fn parse(text: &str) -> Vec<::csv::StringRecord> {
        ::csv::Reader::from_reader(text.as_bytes())
            .records()
            .map(|r| r.unwrap())
            .collect()
    }

    fn same(a: f64, text: &str) -> bool {
        let b: f64 = text.parse().unwrap();
        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
    }

    #[test]
    fn cells_parse_back_to_the_same_numbers() {
        let r = report();
        let text = csv(&r);
        let mut rows = parse(&text).into_iter();
        assert!(text.starts_with(&(HEADER.join(",") + "\n")));
        for table in &r.tables {
            for row in &table.rows {
                for ((g, c), cell) in columns(table).zip(&row.cells) {
                    let rec = rows.next().unwrap();
                    assert_eq!(
                        (&rec[0], &rec[1], &rec[2], &rec[3]),
                        (
                            table.id.as_str(),
                            g.label.as_str(),
                            c.label.as_str(),
                            c.unit.as_str()
                        )
                    );
                    assert!(same(row.noise_level, &rec[4]));
                    match cell {
                        Some(cell) => {
                            assert_eq!(rec[5].parse::<usize>().unwrap(), cell.n);
                            for (i, x) in
                                [cell.trueness, cell.precision, cell.sd, cell.tau, cell.rms]
                                    .into_iter()
                                    .enumerate()
                            {
                                assert!(same(x, &rec[6 + i]), "{} vs {}", x, &rec[6 + i]);
                            }
                            assert_eq!(&rec[11], significance(cell.significance));
                        }
                        None => assert!(rec.iter().skip(5).take(7).all(str::is_empty)),
                    }
                    match row.exposure_factor {
                        Some(f) => assert!(same(f, &rec[12])),
                        None => assert_eq!(&rec[12], ""),
                    }
                }
            }
        }
        assert!(rows.next().is_none());
    }

    #[test]
    fn exposure_levels_are_written_in_the_last_column() {
        let mut r = report();
        for table in &mut r.tables {
            for (l, row) in table.rows.iter_mut().enumerate() {
                row.noise_level = 0.0;
                row.exposure_factor = Some([0.25, 2.0][l % 2]);
            }
        }
        let rows = parse(&csv(&r));
        assert!(!rows.is_empty());
        let mut seen: Vec<&str> = rows.iter().map(|rec| &rec[12]).collect();
        seen.dedup();
        assert!(seen.contains(&"0.25") && seen.contains(&"2"), "{seen:?}");
        assert!(rows.iter().all(|rec| &rec[4] == "0"));
        // Binary-mode rows leave it empty.
        assert!(parse(&csv(&report())).iter().all(|rec| rec[12].is_empty()));
    }

    #[test]
    fn iso5725_parses_back() {
        let r = report();
        let rows = parse(&csv_iso5725(&r));
        assert_eq!(rows.len(), 1);
        let a = &r.group_analyses[0].analysis;
        assert_eq!(&rows[0][0], "detector-det1");
        assert_eq!(&rows[0][4], "5;5");
        assert!(same(a.s_r, &rows[0][6]));
        assert!(same(a.anova.as_ref().unwrap().p_value, &rows[0][14]));
        assert_eq!(&rows[0][15], "no");
    }
}

//! The Markdown report: a header, the paper's tables, then the sections beyond the paper.

use std::fmt::Write;

use super::iso;
use super::{
    BEYOND, LEGEND, N_LEGEND, columns, confidence_text, level_text, mark, mtpm_legend, mtpm_mark,
    n_note, trueness_precision, unicode_minus, usual_n,
};
use crate::stats::{Cell, Significance};
use crate::table::{Report, Table};

/// The report as GitHub-flavoured Markdown.
///
/// Cells read "T ± P" with two significant digits and real minus signs; significant cells are
/// bold and marked ▲ (positive) or ▼ (negative); each row has an N column, and cells whose N
/// differs from it carry "(N=k)".
pub fn markdown(report: &Report) -> String {
    let mut s = String::new();
    header(&mut s, report);
    s.push_str("## Tables as in the paper\n\n");
    let _ = writeln!(
        s,
        "Trueness ± precision per noise level. {LEGEND} {N_LEGEND}\n"
    );
    for (i, table) in report.tables.iter().enumerate() {
        let _ = writeln!(
            s,
            "### Table {} (`{}`). {}\n",
            i + 1,
            table.id.replace('`', "'"),
            esc(&table.caption)
        );
        grid(&mut s, table, &|c| paper_cell(c));
    }
    s.push_str("## Beyond the paper\n\n");
    s.push_str(
        "These sections are not in Bontempi et al.; they are computed from the same residuals.\n\n",
    );
    for (heading, explanation, text) in BEYOND {
        let _ = writeln!(s, "### {heading}\n\n{}\n", esc(explanation));
        for (i, table) in report.tables.iter().enumerate() {
            let _ = writeln!(
                s,
                "#### Table {} (`{}`): {}\n",
                i + 1,
                table.id.replace('`', "'"),
                heading.to_lowercase()
            );
            grid(&mut s, table, &|c| {
                (unicode_minus(&text(c)), Significance::None)
            });
        }
    }
    s.push_str("### MTPM\n\n");
    match &report.mtpm {
        Some(t) => {
            let threshold = report.mtpm_threshold_mm;
            let _ = writeln!(s, "{}. {}\n", esc(&t.caption), esc(&mtpm_legend(threshold)));
            grid(&mut s, t, &|c| {
                let text = unicode_minus(&trueness_precision(c, " ± "));
                let text = match mtpm_mark(c, threshold) {
                    m if m.is_empty() => text,
                    m => format!("**{text}** {m}"),
                };
                (text, Significance::None)
            });
        }
        None => s.push_str("No MTPM table (no model with beads was scored).\n\n"),
    }
    iso5725(&mut s, report);
    if let Some(study) = &report.study {
        super::study::markdown(&mut s, study);
    }
    if let Some(q) = &report.sequence {
        super::sequence::markdown(&mut s, q);
    }
    s
}

/// The title and the facts that identify the data set and the scoring.
fn header(s: &mut String, r: &Report) {
    let _ = writeln!(s, "# RSA accuracy report: {}\n", esc(&r.scenario));
    let software = if r.software.is_empty() {
        "(not named)".to_string()
    } else {
        r.software.join(", ")
    };
    let _ = writeln!(s, "- **Scenario:** {}", esc(&r.scenario));
    let _ = writeln!(s, "- **Program:** {}", esc(&r.program));
    let _ = writeln!(
        s,
        "- **Manifest SHA-256:** `{}`",
        r.manifest_sha256.replace('`', "'")
    );
    let _ = writeln!(s, "- **Software under test:** {}", esc(&software));
    let _ = writeln!(s, "- **Results file:** {}", esc(&r.results_file));
    let _ = writeln!(
        s,
        "- **Rotations re-orthonormalised:** {}",
        r.repaired_rotations
    );
    let _ = writeln!(
        s,
        "- **Confidence:** {}",
        esc(&confidence_text(&r.confidence))
    );
    let _ = writeln!(s, "- **Runs scored:** {}\n", r.runs_scored);
    if !r.summary.is_empty() {
        s.push_str("## Scenario\n\n");
        for line in &r.summary {
            let _ = writeln!(s, "- {}", esc(line));
        }
        s.push('\n');
    }
    if !r.notes.is_empty() {
        s.push_str("## Notes\n\n");
        for line in &r.notes {
            let _ = writeln!(s, "- {}", esc(line));
        }
        s.push('\n');
    }
    s.push_str("## Excluded runs\n\n");
    if r.excluded.is_empty() {
        s.push_str("None.\n\n");
    } else {
        s.push_str("| Run | Reason |\n|---|---|\n");
        for e in &r.excluded {
            let _ = writeln!(s, "| {} | {} |", esc(&e.run), esc(&e.reason));
        }
        s.push('\n');
    }
}

/// "T ± P" in bold with its mark when significant.
fn paper_cell(c: &Cell) -> (String, Significance) {
    (unicode_minus(&trueness_precision(c, " ± ")), c.significance)
}

/// A table: header row "Noise | N | group: label (unit) …", one row per noise level.
fn grid(s: &mut String, table: &Table, cell: &dyn Fn(&Cell) -> (String, Significance)) {
    let _ = write!(s, "| {} | N |", table.level_heading());
    for (g, c) in columns(table) {
        let group = if g.label.is_empty() {
            String::new()
        } else {
            format!("{}: ", esc(&g.label))
        };
        let _ = write!(s, " {group}{} ({}) |", esc(&c.label), esc(&c.unit));
    }
    s.push_str("\n|---:|---:|");
    s.push_str(&"---:|".repeat(columns(table).count()));
    s.push('\n');
    for row in &table.rows {
        let usual = usual_n(row);
        let n = usual.map_or("—".to_string(), |n| n.to_string());
        let _ = write!(s, "| {} | {n} |", level_text(row));
        for c in &row.cells {
            let _ = write!(
                s,
                " {} |",
                c.as_ref()
                    .map_or("—".to_string(), |c| cell_text(c, usual, cell))
            );
        }
        s.push('\n');
    }
    s.push('\n');
}

/// One cell's Markdown: bold and marked when significant, with its N note.
fn cell_text(
    c: &Cell,
    usual: Option<usize>,
    cell: &dyn Fn(&Cell) -> (String, Significance),
) -> String {
    let (text, sig) = cell(c);
    let mut out = if sig == Significance::None {
        text
    } else {
        format!("**{text}** {}", mark(sig))
    };
    if let Some(note) = n_note(c, usual) {
        out = format!("{out} {note}");
    }
    out
}

/// ISO 5725-2 analyses: one table of every field, then the plain-English answers.
fn iso5725(s: &mut String, r: &Report) {
    s.push_str("### ISO 5725-2: does the noise level change the result?\n\n");
    if r.group_analyses.is_empty() {
        s.push_str("No analyses.\n");
        return;
    }
    s.push_str(
        "Noise levels as the groups of ISO 5725-2: repeatability s_r (within a level), between-level \
s_L, reproducibility s_R, limits r = 2.8·s_r and R = 2.8·s_R, and a one-way ANOVA of the level means.\n\n",
    );
    let heads = iso::fields(&r.group_analyses[0]);
    s.push('|');
    for f in &heads {
        let _ = write!(s, " {} |", esc(f.header));
    }
    s.push_str("\n|");
    s.push_str(&"---|".repeat(heads.len()));
    s.push('\n');
    for g in &r.group_analyses {
        s.push('|');
        for f in iso::fields(g) {
            let _ = write!(s, " {} |", esc(&f.value.unicode_text()));
        }
        s.push('\n');
    }
    s.push('\n');
    for g in &r.group_analyses {
        let _ = writeln!(s, "- {}", esc(&iso::answer(g)));
    }
}

/// Escapes Markdown's special characters in running text and table cells.
fn esc(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for ch in text.chars() {
        match ch {
            '\\' | '|' | '*' | '_' | '`' | '[' | ']' | '<' | '>' | '#' => {
                out.push('\\');
                out.push(ch);
            }
            '\n' => out.push(' '),
            _ => out.push(ch),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::super::fixture::report;
    use super::*;

    #[test]
    fn the_row_of_one_noise_level() {
        let md = markdown(&report());
        let want =
            "| 0.0% | 5 | **1.0 ± 0.15** ▲ | 0 ± 0.33 | **−0.50 ± 0.075** ▼ | 0.30 (N=1) |\n";
        assert!(md.contains(want), "{md}");
        assert!(md.contains("| Noise | N | tube1: x\\_r (mm) | tube1: y\\_c (mm) | tube2: x\\_s (mm) | tube2: y\\_r (mm) |\n"));
        assert!(md.contains("| 22.5% | 5 | 0.010 ± 0.33 | 0 ± 0.33 | −0.020 ± 0.33 | — |\n"));
        // The detector's s at 0 % has N = 4 where the row's usual N is 5.
        assert!(
            md.contains("| 0.0% | 5 | 0 ± 0.33 | 0 ± 0.47 (N=4) |\n"),
            "{md}"
        );
    }

    #[test]
    fn header_and_sections() {
        let md = markdown(&report());
        assert!(md.starts_with("# RSA accuracy report: demo\\_scenario\n"));
        assert!(md.contains("- **Manifest SHA-256:** `abab"));
        assert!(md.contains("- **Confidence:** one-sided 95 % (τ = t(0.95; N−1))\n"));
        assert!(md.contains("- **Runs scored:** 10\n"));
        assert!(md.contains("| run-0007 | no measured.json |\n"));
        for h in [
            "## Beyond the paper",
            "### Per-measurement precision",
            "#### Table 2 (`detector-det1`): rms error",
            "### MTPM",
            "### ISO 5725-2",
        ] {
            assert!(md.contains(h), "{h}");
        }
        assert!(
            md.contains("| 0.0% | 5 | 0.16 (±0.31) | 0.34 (±0.67) | 0.079 (±0.15) | n/a (N=1) |\n"),
            "{md}"
        );
        assert!(md.contains("- detector-det1 / s: no — no evidence at the 5 % level"));
        assert_eq!(esc("a|b*c_d"), "a\\|b\\*c\\_d");
    }
}

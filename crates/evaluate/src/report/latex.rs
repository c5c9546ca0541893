//! LaTeX table fragments in the paper's style (Tables 1–4 of Bontempi et al.).

use std::fmt::Write;

use super::{
    MtpmVerdict, columns, confidence_text, level_text, mtpm_verdict, n_note, trueness_precision,
    usual_n,
};
use crate::stats::{Cell, Significance};
use crate::table::{Report, Table};

/// The paper's tables (and the MTPM table) as LaTeX `table*` floats, one after the other, ready
/// for `\input`. A comment block first lists the packages the preamble needs (`xcolor` with the
/// `table` option, for `\cellcolor`).
///
/// Layout as in the paper: `\begin{tabular}{r|ccc|ccc}`, one `\multicolumn` heading per group,
/// column labels in math with their units, `\hline\hline`, cells `$T \pm P$`, significant cells
/// shaded `red!25` (positive) or `blue!25` (negative). Cells whose N differs from the row's usual
/// N (or has N = 1) carry "(N=k)"; the usual N per noise level is in the caption.
pub fn latex(report: &Report) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "% RSA accuracy tables: {}", comment(&report.scenario));
    let _ = writeln!(
        s,
        "% Written by {}; manifest SHA-256 {}",
        comment(&report.program),
        comment(&report.manifest_sha256)
    );
    let _ = writeln!(
        s,
        "% Software under test: {}; results file {}",
        comment(&report.software.join(", ")),
        comment(&report.results_file)
    );
    for note in &report.notes {
        let _ = writeln!(s, "% Note: {}", comment(note));
    }
    let _ = writeln!(
        s,
        "% Precision: {}",
        comment(&confidence_text(&report.confidence))
    );
    s.push_str("% Preamble needs:\n");
    s.push_str("%   \\usepackage[table]{xcolor}   % \\cellcolor for significant cells\n");
    s.push_str("%   \\usepackage[utf8]{inputenc}  % only for pdfLaTeX before 2018\n");
    s.push_str("% Shading: red = significant positive bias (T - P > 0), blue = significant negative bias (T + P < 0).\n\n");
    for table in &report.tables {
        table_float(&mut s, table, None);
    }
    if let Some(t) = &report.mtpm {
        table_float(&mut s, t, Some(report.mtpm_threshold_mm));
    }
    s
}

/// One table as a `table*` float. With `threshold` (MTPM, a length never tested against zero),
/// cells are shaded orange and marked when their upper end T + P exceeds it, and the caption
/// states it.
fn table_float(s: &mut String, table: &Table, threshold: Option<f64>) {
    let spec: Vec<String> = table
        .groups
        .iter()
        .map(|g| "c".repeat(g.columns.len()))
        .collect();
    s.push_str("\\begin{table*}[h]\n\t\\centering\n");
    let _ = writeln!(s, "\t\\begin{{tabular}}{{r|{}}}", spec.join("|"));
    s.push('\t');
    let last = table.groups.len().saturating_sub(1);
    for (i, g) in table.groups.iter().enumerate() {
        let bar = if i < last { "|" } else { "" };
        let _ = write!(
            s,
            " & \\multicolumn{{{}}}{{c{bar}}}{{{}}}",
            g.columns.len(),
            text(&g.label)
        );
    }
    let _ = write!(s, " \\\\\n\t{}", table.level_heading());
    for (_, c) in columns(table) {
        let _ = write!(s, " & ${}$ ({})", c.latex, text(&c.unit));
    }
    s.push_str(" \\\\\n\t\\hline\\hline\n");
    for row in &table.rows {
        let usual = usual_n(row);
        let _ = write!(s, "\t{}", text(&level_text(row)));
        for c in &row.cells {
            let _ = write!(
                s,
                " & {}",
                c.as_ref()
                    .map_or("--".to_string(), |c| cell(c, usual, threshold))
            );
        }
        s.push_str(" \\\\\n");
    }
    s.push_str("\t\\hline\\hline\n\t\\end{tabular}\n");
    let caption = text(&table.caption);
    let stop = if caption.ends_with(['.', '!', '?']) {
        ""
    } else {
        "."
    };
    let threshold_sentence = threshold.map_or(String::new(), |t| {
        format!(
            " MTPM is a length: each cell's upper end $T + P$ is compared with the threshold {} mm (shaded orange above it).",
            super::number::trimmed(t, 6)
        )
    });
    let _ = writeln!(
        s,
        "\t\\caption{{\\label{{tab:{}}}{caption}{stop} {}{threshold_sentence}}}",
        label(&table.id),
        n_caption(table)
    );
    s.push_str("\\end{table*}\n\n");
}

/// `$T \pm P$`, shaded when significant (or, with `threshold`, when above it), with its N note.
fn cell(c: &Cell, usual: Option<usize>, threshold: Option<f64>) -> String {
    let (color, mark) = match threshold {
        Some(t) if mtpm_verdict(c, t) == MtpmVerdict::Above => (
            "\\cellcolor{orange!25}",
            format!("~($>{}$)", super::number::trimmed(t, 6)),
        ),
        Some(_) => ("", String::new()),
        None => match c.significance {
            Significance::Positive => ("\\cellcolor{red!25}", String::new()),
            Significance::Negative => ("\\cellcolor{blue!25}", String::new()),
            Significance::None => ("", String::new()),
        },
    };
    let note = n_note(c, usual).map_or(String::new(), |n| format!("~{n}"));
    format!("{color}${}${mark}{note}", trueness_precision(c, " \\pm "))
}

/// The caption's sentence on N: "N = 20 per noise level." or the list per level.
fn n_caption(table: &Table) -> String {
    let ns: Vec<Option<usize>> = table.rows.iter().map(usual_n).collect();
    let shown = |n: Option<usize>| n.map_or("--".to_string(), |n| n.to_string());
    let sentence = match ns.first() {
        Some(first) if ns.iter().all(|n| n == first) => {
            format!("$N = {}$ per noise level.", shown(*first))
        }
        _ => {
            let parts: Vec<String> = table
                .rows
                .iter()
                .zip(&ns)
                .map(|(r, n)| format!("{}: {}", text(&level_text(r)), shown(*n)))
                .collect();
            format!("$N$ per noise level: {}.", parts.join(", "))
        }
    };
    format!("{sentence} Shaded cells: $T \\pm P$ excludes zero (red: positive, blue: negative).")
}

/// Escapes LaTeX's special characters in text and spells the Unicode symbols the reports use.
pub(crate) fn text(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '_' | '%' | '&' | '#' | '$' | '{' | '}' => {
                out.push('\\');
                out.push(ch);
            }
            '\\' => out.push_str("\\textbackslash{}"),
            '~' => out.push_str("\\textasciitilde{}"),
            '^' => out.push_str("\\textasciicircum{}"),
            '±' => out.push_str("$\\pm$"),
            '−' => out.push_str("$-$"),
            '·' => out.push_str("$\\cdot$"),
            '×' => out.push_str("$\\times$"),
            '√' => out.push_str("$\\surd$"),
            'α' => out.push_str("$\\alpha$"),
            'β' => out.push_str("$\\beta$"),
            'γ' => out.push_str("$\\gamma$"),
            'τ' => out.push_str("$\\tau$"),
            'Δ' => out.push_str("$\\Delta$"),
            '°' => out.push_str("$^\\circ$"),
            _ => out.push(ch),
        }
    }
    out
}

/// A `\label` key: letters, digits, `-`, `.` and `:` kept, anything else as `-`.
fn label(id: &str) -> String {
    id.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "-.:".contains(c) {
                c
            } else {
                '-'
            }
        })
        .collect()
}

/// Text for a `%` comment: one line.
fn comment(s: &str) -> String {
    s.replace(['\n', '\r'], " ")
}

#[cfg(test)]
mod tests {
    use super::super::fixture::report;
    use super::*;

    /// Braces balance, ignoring escaped ones and comments.
    fn balanced(tex: &str) -> bool {
        let mut depth = 0i64;
        for line in tex.lines() {
            let mut chars = line.chars();
            while let Some(c) = chars.next() {
                match c {
                    '\\' => {
                        chars.next();
                    }
                    '%' => break,
                    '{' => depth += 1,
                    '}' => {
                        depth -= 1;
                        if depth < 0 {
                            return false;
                        }
                    }
                    _ => {}
                }
            }
        }
        depth == 0
    }

    #[test]
    fn shading_marks_exactly_the_significant_cells() {
        let tex = latex(&report());
        assert_eq!(tex.matches("\\cellcolor{red!25}").count(), 1);
        assert_eq!(tex.matches("\\cellcolor{blue!25}").count(), 1);
        assert!(tex.contains("\\cellcolor{red!25}$1.0 \\pm 0.15$"), "{tex}");
        assert!(
            tex.contains("\\cellcolor{blue!25}$-0.50 \\pm 0.075$"),
            "{tex}"
        );
        assert!(tex.contains("$0.30$~(N=1)"));
        assert!(tex.contains("\\begin{tabular}{r|cc|cc}"));
        assert!(tex.contains(" & \\multicolumn{2}{c|}{tube1} & \\multicolumn{2}{c}{tube2} \\\\"));
        assert!(tex.contains("Noise & $\\alpha_{r}$ (deg) & $s$ (mm) \\\\"));
        assert!(tex.contains("\t22.5\\% & "));
        assert!(tex.contains("\\label{tab:detector-det1}"));
        assert!(tex.contains("\\usepackage[table]{xcolor}"));
        assert!(balanced(&tex));
        assert_eq!(
            tex.matches("\\begin{table*}").count(),
            tex.matches("\\end{table*}").count()
        );
    }

    #[test]
    fn escapes_text() {
        assert_eq!(text("a_b 5% & #1 {x}"), "a\\_b 5\\% \\& \\#1 \\{x\\}");
        assert_eq!(text("T ± P"), "T $\\pm$ P");
        assert!(!balanced("{"));
        assert!(balanced("\\{ {} % }"));
    }
}

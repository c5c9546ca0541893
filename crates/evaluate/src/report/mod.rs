//! Writers of the evaluation [`Report`]: Markdown, CSV, LaTeX and HTML (and PDF, the HTML
//! printed by a headless browser). Every text writer is a pure function from the report to text;
//! [`write_reports`] puts them on disk.
//!
//! Conventions shared by every format:
//! - Numbers: two significant digits ([`format_number`]); noise levels as percentages
//!   ([`format_noise`]). CSV alone prints full precision.
//! - A cell reads "T ± P". Where P is undefined (N < 2) it reads "T (N=1)".
//! - N: each row has a usual N, the most frequent N of its cells (Markdown and HTML print it in an
//!   "N" column, LaTeX in the caption). A cell whose N differs from its row's usual N carries its
//!   own "(N=k)".
//! - Significant cells (T ± P excludes zero) are marked ▲ (positive bias, the paper's red) or ▼
//!   (negative, the paper's blue), in bold or on a coloured background.
//! - MTPM is a length (always ≥ 0), so its cells are not marked as bias: each is compared with
//!   the report's stated threshold ([`mtpm_verdict`]).

mod csv;
#[cfg(test)]
mod fixture;
mod html;
mod iso;
mod latex;
mod markdown;
mod number;
pub mod pdf;
mod sequence;
mod study;
mod svg;
pub mod sweep;

use std::path::{Path, PathBuf};
use std::str::FromStr;

pub use self::csv::{csv, csv_iso5725};
pub use self::html::html;
pub use self::latex::latex;
pub use self::markdown::markdown;
pub use self::number::{format_exposure, format_noise, format_number, unicode_minus};

use super::stats::{Cell, Confidence, Sided, Significance};
use super::table::{Column, ColumnGroup, Report, Row, Table};

/// A report format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Format {
    /// GitHub-flavoured Markdown (`report.md`).
    Markdown,
    /// One long CSV table of every cell at full precision (`report.csv`, plus `iso5725.csv`).
    Csv,
    /// LaTeX table fragments in the paper's style (`report.tex`).
    Latex,
    /// One self-contained HTML file with tables and plots (`report.html`).
    Html,
    /// The HTML report printed to PDF by a headless browser (`report.pdf`; see [`pdf`]).
    Pdf,
}

impl Format {
    /// Every text format, in the order [`write_reports`] writes them when asked for all (PDF
    /// needs a browser and is asked for by name).
    pub const ALL: [Format; 4] = [Format::Markdown, Format::Csv, Format::Latex, Format::Html];

    /// File extension without the dot: `md`, `csv`, `tex`, `html`, `pdf`.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Markdown => "md",
            Format::Csv => "csv",
            Format::Latex => "tex",
            Format::Html => "html",
            Format::Pdf => "pdf",
        }
    }
}

/// The error of parsing a [`Format`] name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "unknown report format '{0}'; valid formats: md (or markdown), csv, tex (or latex), html, pdf"
)]
pub struct ParseFormatError(pub String);

impl FromStr for Format {
    type Err = ParseFormatError;

    /// Accepts `md`, `markdown`, `csv`, `tex`, `latex`, `html`, `pdf`, in any case.
    fn from_str(s: &str) -> Result<Format, ParseFormatError> {
        match s.trim().to_ascii_lowercase().as_str() {
            "md" | "markdown" => Ok(Format::Markdown),
            "csv" => Ok(Format::Csv),
            "tex" | "latex" => Ok(Format::Latex),
            "html" => Ok(Format::Html),
            "pdf" => Ok(Format::Pdf),
            _ => Err(ParseFormatError(s.to_string())),
        }
    }
}

/// Renders `report` in `format` (for CSV: the cells table; see [`csv_iso5725`] for the rest;
/// for PDF: the HTML document that [`pdf::print_pdf`] prints).
pub fn render(report: &Report, format: Format) -> String {
    match format {
        Format::Markdown => markdown(report),
        Format::Csv => csv(report),
        Format::Latex => latex(report),
        Format::Html | Format::Pdf => html(report),
    }
}

/// Why [`write_reports`] wrote nothing.
#[derive(Debug, thiserror::Error)]
pub enum WriteReportsError {
    /// The report folder may not be replaced (the user's mistake: exit 2).
    #[error("{0}")]
    Refused(Box<crate::diagnostic::Diagnostic>),
    /// Writing failed.
    #[error(transparent)]
    Io(#[from] std::io::Error),
}

/// Claims `dir` as a report folder before any work: refused when something there is not a
/// folder `rsasim evaluate` wrote (it holds the [`REPORT_MARKER`] file, or only report files of
/// an earlier version), a link, a file, or the current folder or one of its parents.
///
/// [`REPORT_MARKER`]: crate::output::commit::guard::REPORT_MARKER
pub fn claim_report_dir(
    dir: &Path,
) -> Result<crate::output::commit::OutputTarget, Box<crate::diagnostic::Diagnostic>> {
    use crate::output::commit::{FolderKind, OutputTarget};
    OutputTarget::claim(dir, FolderKind::Report)
}

/// [`claim_report_dir`] then [`write_reports_into`].
pub fn write_reports(
    report: &Report,
    dir: &Path,
    formats: &[Format],
    browser: Option<&pdf::Browser>,
) -> Result<Vec<PathBuf>, WriteReportsError> {
    let target = claim_report_dir(dir).map_err(WriteReportsError::Refused)?;
    Ok(write_reports_into(report, target, formats, browser)?)
}

/// Writes `report.<ext>` for each of `formats` (duplicates are written once), and `iso5725.csv`
/// beside `report.csv` when CSV is chosen (and, for a dynamic exam, `frames.csv`: every frame's
/// values), into a folder staged beside `target`, then swaps it in
/// whole: the folder holds exactly these files (and the marker), never stale ones of an earlier
/// run. PDF is printed by `browser` (an error without one; find it with [`pdf::find_browser`]
/// before claiming the folder). Returns the final paths written, in order.
pub fn write_reports_into(
    report: &Report,
    target: crate::output::commit::OutputTarget,
    formats: &[Format],
    browser: Option<&pdf::Browser>,
) -> std::io::Result<Vec<PathBuf>> {
    use crate::output::atomic::write_staged;
    if formats.contains(&Format::Pdf) && browser.is_none() {
        return Err(std::io::Error::other(
            "a PDF report needs a headless browser (none was given)",
        ));
    }
    let dir = target.shown().to_path_buf();
    let staged = target.stage()?;
    let mut written = Vec::new();
    let mut done = Vec::new();
    for &format in formats {
        if done.contains(&format) {
            continue;
        }
        done.push(format);
        let name = format!("report.{}", format.extension());
        let bytes = match (format, browser) {
            (Format::Pdf, Some(browser)) => pdf::print_pdf(browser, &html(report))?,
            _ => render(report, format).into_bytes(),
        };
        write_staged(&staged.path().join(&name), &bytes)?;
        written.push(dir.join(name));
        if format == Format::Csv {
            write_staged(
                &staged.path().join("iso5725.csv"),
                csv_iso5725(report).as_bytes(),
            )?;
            written.push(dir.join("iso5725.csv"));
            if let Some(q) = &report.sequence {
                write_staged(
                    &staged.path().join("frames.csv"),
                    sequence::frames_csv(q).as_bytes(),
                )?;
                written.push(dir.join("frames.csv"));
            }
        }
    }
    staged.commit()?;
    Ok(written)
}

/// The default report folder name: `report-<stem of the results file>`, e.g.
/// `report-measured-rsasim-dlt-markers`, so two softwares' or methods' reports never share a
/// folder. Characters other than letters, digits, `-`, `_` and `.` become `_`.
pub fn default_folder_name(report: &Report) -> String {
    let stem = std::path::Path::new(&report.results_file)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let stem: String = stem
        .chars()
        .take(100)
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect();
    if stem.is_empty() || stem.chars().all(|c| c == '.') {
        "report".into()
    } else {
        format!("report-{stem}")
    }
}

/// The columns of `table`, left to right, each with its group.
pub(crate) fn columns(table: &Table) -> impl Iterator<Item = (&ColumnGroup, &Column)> {
    table
        .groups
        .iter()
        .flat_map(|g| g.columns.iter().map(move |c| (g, c)))
}

/// The row's level as shown in reports: `45.0%` (noise) or `×0.25` (exposure).
pub(crate) fn level_text(row: &Row) -> String {
    match row.exposure_factor {
        Some(f) => format_exposure(f),
        None => format_noise(row.noise_level),
    }
}

/// The most frequent N among the row's cells (ties: the larger); `None` for a row without cells.
pub(crate) fn usual_n(row: &Row) -> Option<usize> {
    let ns: Vec<usize> = row.cells.iter().flatten().map(|c| c.n).collect();
    ns.iter()
        .copied()
        .max_by_key(|&n| (ns.iter().filter(|&&m| m == n).count(), n))
}

/// The "(N=k)" note a cell carries: when its precision is undefined or its N is not the row's.
pub(crate) fn n_note(cell: &Cell, usual: Option<usize>) -> Option<String> {
    (cell.precision.is_nan() || Some(cell.n) != usual).then(|| format!("(N={})", cell.n))
}

/// "T ± P" (or "T" alone where P is undefined) with ASCII minus signs and `pm` between.
pub(crate) fn trueness_precision(cell: &Cell, pm: &str) -> String {
    if cell.precision.is_nan() {
        format_number(cell.trueness)
    } else {
        format!(
            "{}{pm}{}",
            format_number(cell.trueness),
            format_number(cell.precision)
        )
    }
}

/// The per-measurement cell of the "Beyond the paper" section: "s (±1.96·s)".
pub(crate) fn sd_limits(cell: &Cell) -> String {
    if cell.sd.is_nan() {
        "n/a".into()
    } else {
        format!(
            "{} (±{})",
            format_number(cell.sd),
            format_number(cell.limits_95())
        )
    }
}

/// The mark of a significant cell: ▲ positive, ▼ negative, nothing otherwise.
pub(crate) fn mark(significance: Significance) -> &'static str {
    match significance {
        Significance::Positive => "▲",
        Significance::Negative => "▼",
        Significance::None => "",
    }
}

/// τ's confidence in words: "one-sided 95 % (τ = t(0.95; N−1))".
pub(crate) fn confidence_text(c: &Confidence) -> String {
    let (sided, p) = match c.sided {
        Sided::One => ("one-sided", c.level),
        Sided::Two => ("two-sided", (1.0 + c.level) / 2.0),
    };
    format!(
        "{sided} {} % (τ = t({}; N−1))",
        number::trimmed(c.level * 100.0, 4),
        number::trimmed(p, 6)
    )
}

/// How an MTPM cell compares with the report's threshold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum MtpmVerdict {
    /// The upper end T + P (T alone where P is undefined) is at or below the threshold.
    Within,
    /// The upper end exceeds the threshold.
    Above,
}

/// MTPM is a length (≥ 0), so "T ± P excludes zero" says nothing: the cell's upper end T + P
/// (T where P is undefined) is compared with `threshold_mm` instead.
pub(crate) fn mtpm_verdict(cell: &Cell, threshold_mm: f64) -> MtpmVerdict {
    let upper = if cell.precision.is_nan() {
        cell.trueness
    } else {
        cell.trueness + cell.precision
    };
    if upper > threshold_mm {
        MtpmVerdict::Above
    } else {
        MtpmVerdict::Within
    }
}

/// The mark after an MTPM cell: "> 0.2" for one above the threshold, nothing otherwise.
pub(crate) fn mtpm_mark(cell: &Cell, threshold_mm: f64) -> String {
    match mtpm_verdict(cell, threshold_mm) {
        MtpmVerdict::Above => format!("> {}", number::trimmed(threshold_mm, 6)),
        MtpmVerdict::Within => String::new(),
    }
}

/// The MTPM section's explanation, with the threshold.
pub(crate) fn mtpm_legend(threshold_mm: f64) -> String {
    format!(
        "Maximum total point motion over each model's beads (or its bounding-box corners) between \
its true and its measured pose: all of it is measurement error. MTPM is a length \
(always ≥ 0), so a cell is not tested against zero: its upper end T + P is compared with the \
threshold {} mm (`rsasim evaluate --mtpm-threshold-mm`), and a cell above it is marked \
\"> {}\".",
        number::trimmed(threshold_mm, 6),
        number::trimmed(threshold_mm, 6)
    )
}

/// The legend of significance marks, in words.
pub(crate) const LEGEND: &str = "▲ significant positive bias (T − P > 0, the paper's red); \
▼ significant negative bias (T + P < 0, the paper's blue); unmarked: the interval T ± P contains zero.";

/// The note on N, in words.
pub(crate) const N_LEGEND: &str = "N: runs per noise level; a cell with another N shows its own \
\"(N=k)\", and a cell with N = 1 has no precision.";

/// Text of a "Beyond the paper" table cell.
pub(crate) type CellText = fn(&Cell) -> String;

/// The two "Beyond the paper" views of every table: (heading, explanation, cell text).
pub(crate) const BEYOND: [(&str, &str, CellText); 2] = [
    (
        "Per-measurement precision",
        "Each cell: the sample standard deviation s of one measurement, and in parentheses the \
per-measurement 95 % limits ±1.96·s that RSA guidelines report.",
        sd_limits,
    ),
    (
        "RMS error",
        "Each cell: the root mean square of the residuals, √(mean Δ²).",
        |c| format_number(c.rms),
    ),
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_parse_and_name_their_extensions() {
        for (name, f) in [
            ("md", Format::Markdown),
            ("Markdown", Format::Markdown),
            ("csv", Format::Csv),
            ("tex", Format::Latex),
            ("LaTeX", Format::Latex),
            ("html", Format::Html),
        ] {
            assert_eq!(name.parse::<Format>().unwrap(), f);
        }
        assert_eq!("PDF".parse::<Format>().unwrap(), Format::Pdf);
        assert_eq!(Format::Pdf.extension(), "pdf");
        let err = "docx".parse::<Format>().unwrap_err().to_string();
        assert!(
            err.contains("'docx'")
                && err.contains("pdf")
                && err.contains("md")
                && err.contains("csv")
                && err.contains("tex")
                && err.contains("html"),
            "{err}"
        );
        let exts: Vec<&str> = Format::ALL.iter().map(|f| f.extension()).collect();
        assert_eq!(exts, ["md", "csv", "tex", "html"]);
    }

    #[test]
    fn writes_one_file_per_format_and_the_iso_csv() {
        let r = fixture::report();
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("eval").join("reports");
        let paths =
            write_reports(&r, &dir, &[Format::Html, Format::Csv, Format::Html], None).unwrap();
        assert_eq!(
            paths,
            [
                dir.join("report.html"),
                dir.join("report.csv"),
                dir.join("iso5725.csv")
            ]
        );
        assert_eq!(std::fs::read_to_string(&paths[0]).unwrap(), html(&r));
        assert_eq!(std::fs::read_to_string(&paths[2]).unwrap(), csv_iso5725(&r));
        // The three files and the marker that lets the next evaluate replace the folder.
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 4);
        // A second run asking for Markdown only leaves no stale file of the first.
        let paths = write_reports(&r, &dir, &[Format::Markdown], None).unwrap();
        assert_eq!(paths, [dir.join("report.md")]);
        assert!(!dir.join("report.html").exists() && !dir.join("iso5725.csv").exists());
        // A folder of the user's is never replaced.
        let mine = root.path().join("thesis");
        std::fs::create_dir(&mine).unwrap();
        std::fs::write(mine.join("chapter1.tex"), "mine").unwrap();
        assert!(matches!(
            write_reports(&r, &mine, &Format::ALL, None),
            Err(WriteReportsError::Refused(_))
        ));
        assert_eq!(std::fs::read_dir(&mine).unwrap().count(), 1);
        // For looking at the output by hand: RSASIM_REPORT_SAMPLE=/some/dir cargo test --lib report
        if let Ok(sample) = std::env::var("RSASIM_REPORT_SAMPLE") {
            write_reports(&r, Path::new(&sample), &Format::ALL, None).unwrap();
        }
    }

    #[test]
    fn a_pdf_without_a_browser_writes_nothing() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("reports");
        let err = write_reports(&fixture::report(), &dir, &[Format::Html, Format::Pdf], None)
            .unwrap_err();
        assert!(err.to_string().contains("headless browser"), "{err}");
        // Nothing but the claim's lock file (hidden, beside the folder).
        assert!(!dir.exists());
        for e in std::fs::read_dir(root.path()).unwrap() {
            assert!(
                e.unwrap()
                    .file_name()
                    .to_string_lossy()
                    .ends_with(".rsasim-lock")
            );
        }
    }

    #[test]
    fn usual_n_and_notes() {
        let r = fixture::report();
        let row = &r.tables[1].rows[0];
        assert_eq!(usual_n(row), Some(5));
        let cells: Vec<&Cell> = row.cells.iter().flatten().collect();
        assert_eq!(n_note(cells[0], Some(5)), None);
        assert_eq!(n_note(cells[1], Some(5)).as_deref(), Some("(N=4)"));
        assert_eq!(
            confidence_text(&Confidence {
                level: 0.95,
                sided: Sided::Two
            }),
            "two-sided 95 % (τ = t(0.975; N−1))"
        );
    }

    #[test]
    fn an_mtpm_table_appears_in_every_format() {
        let mut r = fixture::report();
        let mut mtpm = r.tables[1].clone();
        mtpm.id = "mtpm".into();
        mtpm.caption = "MTPM of model femur".into();
        mtpm.groups.truncate(1);
        mtpm.groups[0].label = "femur".into();
        mtpm.groups[0].columns = vec![fixture::column("MTPM", "\\mathrm{MTPM}", "mm")];
        for row in &mut mtpm.rows {
            row.cells.truncate(1);
        }
        r.mtpm = Some(mtpm);
        assert!(markdown(&r).contains("| Noise | N | femur: MTPM (mm) |"));
        assert!(latex(&r).contains("\\label{tab:mtpm}"));
        assert_eq!(
            csv(&r)
                .lines()
                .filter(|l| l.starts_with("mtpm,femur,MTPM,mm,"))
                .count(),
            2
        );
        let page = html(&r);
        assert_eq!(page.matches("<svg").count(), fixture::parameters(&r));
        assert!(page.contains("femur · MTPM"));
    }
}

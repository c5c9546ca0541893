//! The clinical-study sections of the report (Markdown and HTML): migration accuracy per exam,
//! double-exam precision, loose-marker detection, and per patient the migration over time as
//! SVG plots (truth as a line, measured points).

use std::fmt::Write;

use super::format_number;
use super::html::esc;
use crate::evaluate::stats::Cell;
use crate::evaluate::study::{PARAMETERS, PatientSeries, StudyReport};

/// A titled table of plain-text cells.
struct TextTable {
    title: String,
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

fn cell_text(c: &Option<Cell>) -> String {
    match c {
        None => "–".into(),
        Some(c) if c.n < 2 => format!("{} (N=1)", format_number(c.trueness)),
        Some(c) => format!(
            "{} ± {}",
            format_number(c.trueness),
            format_number(c.precision)
        ),
    }
}

fn header_units() -> Vec<String> {
    PARAMETERS
        .iter()
        .map(|(l, u)| format!("{l} ({u})"))
        .collect()
}

/// The study's tables, in report order.
fn tables(r: &StudyReport) -> Vec<TextTable> {
    let mut out = Vec::new();
    for t in &r.accuracy {
        let mut header = vec!["Exam".to_string(), "Days".into(), "N".into()];
        header.extend(header_units());
        out.push(TextTable {
            title: format!(
                "Migration accuracy of {} (measured − true, trueness ± precision per exam)",
                t.segment
            ),
            header,
            rows: t
                .rows
                .iter()
                .map(|row| {
                    let n = row.cells.iter().flatten().map(|c| c.n).max().unwrap_or(0);
                    let mut cells = vec![row.exam.clone(), row.days.to_string(), n.to_string()];
                    cells.extend(row.cells.iter().map(cell_text));
                    cells
                })
                .collect(),
        });
    }
    for d in &r.double_exams {
        let mut header: Vec<String> = [
            "Parameter",
            "N",
            "Mean difference",
            "SD",
            "95 % limits mean ± 1.96·SD",
            "t(0.975, N−1)",
            "95 % limit t(0.975, N−1)·SD",
        ]
        .map(String::from)
        .to_vec();
        if r.limits_99 {
            header.push("99 % limits mean ± 2.576·SD".into());
            header.push("99 % limit t(0.995, N−1)·SD".into());
        }
        header.push("Median [range] (MTPM)".into());
        let f = format_number;
        out.push(TextTable {
            title: format!(
                "Double-exam precision of {}: {} repeats {} (differences)",
                d.segment, d.exam, d.repeats
            ),
            header,
            rows: d
                .limits
                .iter()
                .map(|l| {
                    let mut row = vec![
                        format!("{} ({})", l.parameter, l.unit),
                        l.n.to_string(),
                        f(l.mean),
                        f(l.sd),
                        format!("{} to {}", f(l.limits_196[0]), f(l.limits_196[1])),
                        f(l.t_975),
                        format!("± {}", f(l.limit_t95)),
                    ];
                    if r.limits_99 {
                        row.push(
                            l.limits_2576
                                .map(|[a, b]| format!("{} to {}", f(a), f(b)))
                                .unwrap_or_default(),
                        );
                        row.push(
                            l.limit_t99
                                .map(|x| format!("± {}", f(x)))
                                .unwrap_or_default(),
                        );
                    }
                    row.push(match (l.median, l.range) {
                        (Some(m), Some([a, b])) => format!("{} [{} – {}]", f(m), f(a), f(b)),
                        _ => String::new(),
                    });
                    row
                })
                .collect(),
        });
    }
    out.push(TextTable {
        title: format!(
            "Loose markers (true displacement above {} mm)",
            r.stability_threshold_mm
        ),
        header: [
            "Patient",
            "Exam",
            "Segment",
            "Bead",
            "Displacement (mm)",
            "Excluded",
        ]
        .map(String::from)
        .to_vec(),
        rows: r
            .loose_markers
            .iter()
            .map(|l| {
                vec![
                    l.patient.clone(),
                    l.exam.clone(),
                    l.segment.clone(),
                    l.bead.clone(),
                    format_number(l.displacement_mm),
                    match l.excluded {
                        Some(true) => "yes".into(),
                        Some(false) => "NO".into(),
                        None => "not reported".into(),
                    },
                ]
            })
            .collect(),
    });
    out
}

/// Summary lines: source, loose-marker count, quality flags, notes.
fn summary(r: &StudyReport) -> Vec<String> {
    let detected = r
        .loose_markers
        .iter()
        .filter(|l| l.excluded == Some(true))
        .count();
    let mut lines = vec![
        format!("Measured migration: {}.", r.source),
        format!("Reference exam: {}.", r.reference_exam),
        format!(
            "Loose markers: {detected} of {} excluded (markers that truly moved more than {} mm); {} other exclusion(s).",
            r.loose_markers.len(),
            r.stability_threshold_mm,
            r.false_exclusions.len()
        ),
        format!(
            "Fits between exams over a guideline limit (ME 0.35 mm, CN 150): {} of {} segment-exams.",
            r.quality_flags.len(),
            r.segment_exams
        ),
    ];
    lines.extend(
        r.false_exclusions
            .iter()
            .map(|x| format!("Excluded, not loose: {x}.")),
    );
    lines.extend(r.quality_flags.iter().map(|x| format!("Flag: {x}.")));
    lines.extend(r.notes.iter().map(|n| format!("Note: {n}.")));
    lines
}

/// The study section in Markdown.
pub fn markdown(s: &mut String, r: &StudyReport) {
    let md = |t: &str| t.replace('|', "\\|");
    s.push_str("## Clinical study: migration\n\n");
    for line in summary(r) {
        let _ = writeln!(s, "- {}", md(&line));
    }
    s.push('\n');
    for t in tables(r) {
        let _ = writeln!(s, "### {}\n", md(&t.title));
        let _ = writeln!(
            s,
            "| {} |",
            t.header
                .iter()
                .map(|h| md(h))
                .collect::<Vec<_>>()
                .join(" | ")
        );
        let _ = writeln!(s, "|{}", "---|".repeat(t.header.len()));
        for row in &t.rows {
            let _ = writeln!(
                s,
                "| {} |",
                row.iter().map(|c| md(c)).collect::<Vec<_>>().join(" | ")
            );
        }
        s.push('\n');
    }
}

/// The study section in HTML, with one plot per patient, implant and parameter.
pub fn html(s: &mut String, r: &StudyReport) {
    s.push_str("<h2 id=\"study\">Clinical study: migration</h2>\n<ul>\n");
    for line in summary(r) {
        let _ = writeln!(s, "<li>{}</li>", esc(&line));
    }
    s.push_str("</ul>\n");
    for t in tables(r) {
        let _ = writeln!(s, "<h3>{}</h3>\n<table>\n<tr>", esc(&t.title));
        for h in &t.header {
            let _ = write!(s, "<th>{}</th>", esc(h));
        }
        s.push_str("</tr>\n");
        for row in &t.rows {
            s.push_str("<tr>");
            for c in row {
                let _ = write!(s, "<td>{}</td>", esc(c));
            }
            s.push_str("</tr>\n");
        }
        s.push_str("</table>\n");
    }
    s.push_str("<h3>Migration over time per patient</h3>\n<p>Lines: truth; points: measured; x: days from surgery.</p>\n");
    for series in &r.series {
        let _ = writeln!(
            s,
            "<section class=\"patient\"><h4>{} – {}</h4>",
            esc(&series.patient),
            esc(&series.segment)
        );
        for k in 0..PARAMETERS.len() {
            plot(s, series, k);
        }
        s.push_str("</section>\n");
    }
}

/// One small SVG: parameter `k` of `series` against days.
fn plot(s: &mut String, series: &PatientSeries, k: usize) {
    const W: f64 = 180.0;
    const H: f64 = 120.0;
    const PAD: f64 = 28.0;
    let (label, unit) = PARAMETERS[k];
    let days: Vec<f64> = series.points.iter().map(|p| f64::from(p.days)).collect();
    let values = series
        .points
        .iter()
        .flat_map(|p| std::iter::once(p.truth[k]).chain(p.measured.map(|m| m[k])));
    let (lo, hi) = values.fold((0.0f64, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    let span = (hi - lo).max(1e-3);
    let (lo, hi) = (lo - 0.1 * span, hi + 0.1 * span);
    let d_max = days.iter().copied().fold(1.0, f64::max);
    let x = |d: f64| PAD + (W - PAD - 6.0) * d / d_max;
    let y = |v: f64| H - PAD + (PAD + 6.0 - H) * (v - lo) / (hi - lo);
    let _ = write!(
        s,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{W}\" height=\"{H}\" viewBox=\"0 0 {W} {H}\" role=\"img\" aria-label=\"{} {label} over time\">",
        esc(&series.patient)
    );
    let _ = write!(
        s,
        "<text x=\"{PAD}\" y=\"12\" font-size=\"10\">{label} ({unit})</text><line x1=\"{PAD}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\" stroke=\"#bbb\"/>",
        y(0.0),
        W - 6.0,
        y(0.0)
    );
    let _ = write!(
        s,
        "<text x=\"2\" y=\"{:.1}\" font-size=\"8\">{}</text><text x=\"2\" y=\"{:.1}\" font-size=\"8\">{}</text><text x=\"{:.1}\" y=\"{:.1}\" font-size=\"8\" text-anchor=\"end\">{} d</text>",
        y(hi) + 8.0,
        format_number(hi),
        y(lo),
        format_number(lo),
        W - 6.0,
        H - 4.0,
        d_max
    );
    let line: Vec<String> = series
        .points
        .iter()
        .map(|p| format!("{:.1},{:.1}", x(f64::from(p.days)), y(p.truth[k])))
        .collect();
    let _ = write!(
        s,
        "<polyline fill=\"none\" stroke=\"#333\" stroke-width=\"1.5\" points=\"{}\"/>",
        line.join(" ")
    );
    for p in &series.points {
        if let Some(m) = p.measured {
            let _ = write!(
                s,
                "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"3\" fill=\"#c0392b\"><title>{}: measured {}, true {}</title></circle>",
                x(f64::from(p.days)),
                y(m[k]),
                esc(&p.exam),
                format_number(m[k]),
                format_number(p.truth[k])
            );
        }
    }
    s.push_str("</svg>\n");
}

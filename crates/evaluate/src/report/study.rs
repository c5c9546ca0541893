//! The clinical-study sections of the report (Markdown and HTML): migration accuracy per exam,
//! double-exam precision, loose-marker detection, and per patient the migration over time as
//! SVG plots (truth as a line, measured points).

use std::fmt::Write;

use super::format_number;
use crate::output::html_text::escape as esc;
use crate::stats::Cell;
use crate::study::{PARAMETERS, PatientSeries, StudyReport};

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

/// Width and height of a per-patient plot, px.
const PLOT_W: f64 = 180.0;
const PLOT_H: f64 = 120.0;
/// The plot area's margins, px: the value labels right-aligned in the left one, the title row
/// above, the day label below.
const PLOT_LEFT: f64 = 44.0;
const PLOT_TOP: f64 = 22.0;
const PLOT_RIGHT: f64 = 6.0;
const PLOT_BOTTOM: f64 = 16.0;

/// One small SVG: parameter `k` of `series` against days. The title has a row of its own and
/// the value labels stand right-aligned left of the plot area, so neither touches the other or
/// the data, whatever the numbers' length.
fn plot(s: &mut String, series: &PatientSeries, k: usize) {
    const W: f64 = PLOT_W;
    const H: f64 = PLOT_H;
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
    let x = |d: f64| PLOT_LEFT + (W - PLOT_LEFT - PLOT_RIGHT) * d / d_max;
    let y = |v: f64| PLOT_TOP + (H - PLOT_TOP - PLOT_BOTTOM) * (hi - v) / (hi - lo);
    let _ = write!(
        s,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{W}\" height=\"{H}\" viewBox=\"0 0 {W} {H}\" role=\"img\" aria-label=\"{} {label} over time\">",
        esc(&series.patient)
    );
    let _ = write!(
        s,
        "<text x=\"2\" y=\"12\" font-size=\"10\">{label} ({unit})</text><line x1=\"{PLOT_LEFT}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\" stroke=\"#bbb\"/>",
        y(0.0),
        W - PLOT_RIGHT,
        y(0.0)
    );
    let label_x = PLOT_LEFT - 3.0;
    let _ = write!(
        s,
        "<text x=\"{label_x}\" y=\"{:.1}\" font-size=\"8\" text-anchor=\"end\">{}</text><text x=\"{label_x}\" y=\"{:.1}\" font-size=\"8\" text-anchor=\"end\">{}</text><text x=\"{:.1}\" y=\"{:.1}\" font-size=\"8\" text-anchor=\"end\">{} d</text>",
        y(hi) + 3.0,
        format_number(hi),
        y(lo) + 3.0,
        format_number(lo),
        W - PLOT_RIGHT,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::SeriesPoint;

    /// The numbers of `attr="…"` in the order they appear after each `tag`.
    fn attrs(svg: &str, tag: &str, attr: &str) -> Vec<f64> {
        svg.split(tag)
            .skip(1)
            .filter_map(|rest| {
                let start = rest.find(&format!(" {attr}=\""))? + attr.len() + 3;
                rest[start..].split('"').next()?.parse().ok()
            })
            .collect()
    }

    #[test]
    fn labels_stand_clear_of_the_title_and_the_data() {
        // Long value labels (negative, four significant digits) and points at both extremes.
        let point = |exam: &str, days, v: f64| SeriesPoint {
            exam: exam.into(),
            days,
            truth: [v; 7],
            measured: Some([v * 1.3 - 0.0087; 7]),
        };
        let series = PatientSeries {
            patient: "p01".into(),
            segment: "component".into(),
            points: vec![
                point("postop", 0, 0.0),
                point("3m", 90, -0.0088),
                point("2y", 730, 0.0973),
            ],
        };
        let mut svg = String::new();
        plot(&mut svg, &series, 0);
        // Value labels: right-aligned left of the plot area, below the title row.
        let texts: Vec<&str> = svg.split("<text").skip(1).collect();
        let (xs, ys) = (attrs(&svg, "<text", "x"), attrs(&svg, "<text", "y"));
        assert_eq!(texts.len(), 4, "{svg}");
        for k in 1..=2 {
            assert!(texts[k].contains("text-anchor=\"end\""), "{}", texts[k]);
            assert!(xs[k] < PLOT_LEFT, "value label at x {}", xs[k]);
            // Font 8: a label's top is 8 px above its baseline; the title's baseline is 12.
            assert!(
                ys[k] - 8.0 >= 12.0 + 2.0,
                "value label at y {} touches the title",
                ys[k]
            );
        }
        // Every point and the truth line lie inside the plot area.
        let (cx, cy) = (attrs(&svg, "<circle", "cx"), attrs(&svg, "<circle", "cy"));
        assert_eq!(cx.len(), 3);
        for (&x, &y) in cx.iter().zip(&cy) {
            assert!(
                (PLOT_LEFT..=PLOT_W - PLOT_RIGHT).contains(&x),
                "point x {x}"
            );
            assert!(
                (PLOT_TOP..=PLOT_H - PLOT_BOTTOM).contains(&y),
                "point y {y}"
            );
            // A point's radius (3 px) stays below the title row.
            assert!(y - 3.0 > 12.0 + 2.0, "point at y {y} reaches the title");
        }
    }
}

//! The dynamic exam's section of the report ([`crate::sequence`]): a table per protocol level
//! (Markdown and HTML), plots of truth against measured and of the error over time (HTML), and
//! every frame's values at full precision (`frames.csv`).

use std::fmt::Write;

use super::number::trimmed;
use super::{format_exposure, format_noise, format_number, unicode_minus};
use crate::output::html_text::escape as esc;
use crate::sequence::{Dof, SequenceLevel, SequenceSection};

/// The facts above the tables.
fn summary(q: &SequenceSection) -> Vec<String> {
    vec![
        format!(
            "{} frame(s) per sequence; every frame is a run, scored like any other in the tables above, and here over time.",
            q.frames
        ),
        "Error = measured − true. Models: orientation α, β, γ about the box axes (X-Y-Z decomposition of R_measured·R_trueᵀ), position along x, y, z, as in the tables above. Joints: the joint coordinate system of Grood and Suntay, computed from the measured poses of both phantoms with the scenario's anatomical frames, against the truth's `frame.joints`.".into(),
        "Bias, RMS and largest error: over every measured frame of every sequence. Per-frame trueness: the mean error over the sequences at one frame number; the largest in magnitude is shown with its frame. s_r: ISO 5725-2 repeatability with the frame numbers as groups (the precision over repeated sequences); s_L: how much the bias changes between frames.".into(),
    ]
}

/// The level's heading: `noise 45.0%` or `exposure ×0.25`.
fn level_name(l: &SequenceLevel) -> String {
    match l.exposure_factor {
        Some(f) => format!("exposure {}", format_exposure(f)),
        None => format!("noise {}", format_noise(l.noise_level)),
    }
}

/// Column heads of a level's table.
const HEAD: [&str; 10] = [
    "what",
    "degree of freedom",
    "unit",
    "N",
    "bias",
    "RMS",
    "largest error (frame)",
    "largest per-frame trueness (frame)",
    "s_r over sequences",
    "s_L between frames",
];

/// A level's rows, as text.
fn rows(l: &SequenceLevel) -> Vec<[String; 10]> {
    let mut out = Vec::new();
    for e in &l.entities {
        for d in &e.dofs {
            out.push([
                format!("{} ({})", e.id, e.kind),
                d.label.clone(),
                d.unit.clone(),
                d.n.to_string(),
                unicode_minus(&format_number(d.bias)),
                format_number(d.rms),
                format!(
                    "{} ({})",
                    unicode_minus(&format_number(d.max_error)),
                    d.max_error_run
                ),
                format!(
                    "{} ({})",
                    unicode_minus(&format_number(d.worst_frame_trueness)),
                    d.worst_frame
                ),
                number_or_na(d.analysis.s_r),
                // s_L needs s_r: with one sequence per frame neither is defined.
                number_or_na(if d.analysis.s_r.is_finite() {
                    d.analysis.s_l
                } else {
                    f64::NAN
                }),
            ]);
        }
    }
    out
}

fn number_or_na(x: f64) -> String {
    if x.is_finite() {
        format_number(x)
    } else {
        "n/a".into()
    }
}

/// The section in Markdown.
pub fn markdown(s: &mut String, q: &SequenceSection) {
    let md = |t: &str| t.replace('|', "\\|");
    s.push_str("## Dynamic exam: frame by frame\n\n");
    for line in summary(q) {
        let _ = writeln!(s, "- {}", md(&line));
    }
    s.push_str("- Plots of truth against measured over time: report.html. Every frame's values: frames.csv (with the CSV format).\n\n");
    for l in &q.levels {
        let _ = writeln!(
            s,
            "### {}: {} sequence(s)\n",
            level_name(l),
            l.sequences.len()
        );
        let _ = writeln!(s, "| {} |", HEAD.join(" | "));
        let _ = writeln!(s, "|{}", "---|".repeat(HEAD.len()));
        for r in rows(l) {
            let cells: Vec<String> = r.iter().map(|c| md(c)).collect();
            let _ = writeln!(s, "| {} |", cells.join(" | "));
        }
        s.push('\n');
    }
}

/// The section in HTML: the tables, then per entity and degree of freedom two plots.
pub fn html(s: &mut String, q: &SequenceSection) {
    s.push_str("<h2 id=\"sequence\">Dynamic exam: frame by frame</h2>\n<ul>\n");
    for line in summary(q) {
        let _ = writeln!(s, "<li>{}</li>", esc(&line));
    }
    s.push_str("</ul>\n");
    for l in &q.levels {
        let _ = writeln!(
            s,
            "<h3>{}: {} sequence(s)</h3>\n<table>\n<tr>",
            esc(&level_name(l)),
            l.sequences.len()
        );
        for h in HEAD {
            let _ = write!(s, "<th>{}</th>", esc(h));
        }
        s.push_str("</tr>\n");
        for r in rows(l) {
            s.push_str("<tr>");
            for c in &r {
                let _ = write!(s, "<td>{}</td>", esc(c));
            }
            s.push_str("</tr>\n");
        }
        s.push_str("</table>\n<p class=\"legend\">Left of each pair: truth (grey lines) and measured (coloured lines), one line per sequence, against time. Right: the error of every sequence (thin coloured lines) and the per-frame trueness (black).</p>\n");
        for e in &l.entities {
            let _ = writeln!(
                s,
                "<h4>{} ({})</h4>\n<div class=\"plots\">",
                esc(&e.id),
                esc(&e.kind)
            );
            for d in &e.dofs {
                s.push_str(&values_plot(&e.id, d));
                s.push_str(&error_plot(&e.id, d));
            }
            s.push_str("</div>\n");
        }
    }
}

/// Size and margins of a plot over time, px.
const W: f64 = 300.0;
const H: f64 = 170.0;
const LEFT: f64 = 58.0;
const RIGHT: f64 = 8.0;
const TOP: f64 = 24.0;
const BOTTOM: f64 = 26.0;

/// Colours of the sequences' lines, in turn.
const COLOURS: [&str; 6] = [
    "#b2182b", "#2155a8", "#1b7837", "#c05a00", "#762a83", "#01665e",
];

/// The frame of a plot: `(t0, t1)` seconds and `(y0, y1)`; maps to pixels.
struct Frame {
    t: (f64, f64),
    y: (f64, f64),
}

impl Frame {
    fn new(times: impl Iterator<Item = f64> + Clone, values: impl Iterator<Item = f64>) -> Frame {
        let t0 = times.clone().fold(f64::INFINITY, f64::min);
        let t1 = times.fold(f64::NEG_INFINITY, f64::max);
        let (lo, hi) = values
            .filter(|v| v.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
        let (lo, hi) = if lo.is_finite() { (lo, hi) } else { (0.0, 0.0) };
        let pad = ((hi - lo) * 0.08).max(1e-6);
        Frame {
            t: if t1 > t0 { (t0, t1) } else { (t0, t0 + 1.0) },
            y: (lo - pad, hi + pad),
        }
    }

    fn x(&self, t: f64) -> f64 {
        LEFT + (t - self.t.0) / (self.t.1 - self.t.0) * (W - LEFT - RIGHT)
    }

    fn y(&self, v: f64) -> f64 {
        TOP + (self.y.1 - v) / (self.y.1 - self.y.0) * (H - TOP - BOTTOM)
    }

    /// `points` as an SVG polyline's points.
    fn line(&self, points: impl Iterator<Item = (f64, f64)>) -> String {
        points
            .map(|(t, v)| format!("{:.2},{:.2}", self.x(t), self.y(v)))
            .collect::<Vec<_>>()
            .join(" ")
    }
}

/// The opening of a plot: the svg element, its accessible title, the title row, the plot area,
/// the y range's labels and the time axis's.
fn open(title: &str, unit: &str, frame: &Frame) -> String {
    let mut s = String::new();
    let _ = write!(
        s,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{W}\" height=\"{H}\" viewBox=\"0 0 {W} {H}\" role=\"img\" font-family=\"sans-serif\" font-size=\"10\"><title>{}</title>",
        esc(&format!("{title} ({unit}) against time"))
    );
    let _ = write!(
        s,
        "<text x=\"{:.2}\" y=\"14\" text-anchor=\"middle\" font-weight=\"bold\">{}</text>",
        W / 2.0,
        esc(&format!("{title} ({unit})"))
    );
    let _ = write!(
        s,
        "<rect x=\"{LEFT:.2}\" y=\"{TOP:.2}\" width=\"{:.2}\" height=\"{:.2}\" fill=\"none\" stroke=\"#999999\"/>",
        W - LEFT - RIGHT,
        H - TOP - BOTTOM
    );
    // Enough decimals that the two ends differ: two significant digits of the span.
    let span = frame.y.1 - frame.y.0;
    let decimals = (1.0 - span.log10().floor()).clamp(0.0, 9.0) as usize;
    for v in [frame.y.0, frame.y.1] {
        let _ = write!(
            s,
            "<text x=\"{:.2}\" y=\"{:.2}\" text-anchor=\"end\">{}</text>",
            LEFT - 4.0,
            frame.y(v) + 3.5,
            esc(&unicode_minus(&trimmed(v, decimals)))
        );
    }
    for (t, anchor) in [(frame.t.0, "start"), (frame.t.1, "end")] {
        let _ = write!(
            s,
            "<text x=\"{:.2}\" y=\"{:.2}\" text-anchor=\"{anchor}\">{} s</text>",
            frame.x(t),
            H - BOTTOM + 13.0,
            format_number(t)
        );
    }
    s
}

/// Truth and measured values of `d` over time, one line each per sequence.
fn values_plot(entity: &str, d: &Dof) -> String {
    let points = || d.series.iter().flat_map(|s| &s.points);
    let frame = Frame::new(
        points().map(|p| p.time_s),
        points().flat_map(|p| [p.truth, p.measured]),
    );
    let mut s = open(&format!("{entity} {}", d.label), &d.unit, &frame);
    for (k, series) in d.series.iter().enumerate() {
        let _ = write!(
            s,
            "<polyline fill=\"none\" stroke=\"#999999\" stroke-width=\"2.5\" points=\"{}\"/>",
            frame.line(series.points.iter().map(|p| (p.time_s, p.truth)))
        );
        let _ = write!(
            s,
            "<polyline fill=\"none\" stroke=\"{}\" stroke-width=\"1\" points=\"{}\"><title>{}</title></polyline>",
            COLOURS[k % COLOURS.len()],
            frame.line(series.points.iter().map(|p| (p.time_s, p.measured))),
            esc(&format!("sequence {} measured", series.sequence))
        );
    }
    s.push_str("</svg>\n");
    s
}

/// The error of `d` over time per sequence, with the per-frame trueness.
fn error_plot(entity: &str, d: &Dof) -> String {
    let points = || d.series.iter().flat_map(|s| &s.points);
    let frame = Frame::new(
        points().map(|p| p.time_s),
        points().map(|p| p.error).chain([0.0]),
    );
    let mut s = open(&format!("{entity} {} error", d.label), &d.unit, &frame);
    let _ = write!(
        s,
        "<line x1=\"{LEFT:.2}\" y1=\"{0:.2}\" x2=\"{1:.2}\" y2=\"{0:.2}\" stroke=\"#bbbbbb\" stroke-dasharray=\"4 3\"/>",
        frame.y(0.0),
        W - RIGHT
    );
    for (k, series) in d.series.iter().enumerate() {
        let _ = write!(
            s,
            "<polyline fill=\"none\" stroke=\"{}\" stroke-width=\"0.8\" points=\"{}\"><title>{}</title></polyline>",
            COLOURS[k % COLOURS.len()],
            frame.line(series.points.iter().map(|p| (p.time_s, p.error))),
            esc(&format!("sequence {} error", series.sequence))
        );
    }
    let _ = write!(
        s,
        "<polyline fill=\"none\" stroke=\"#222222\" stroke-width=\"1.8\" points=\"{}\"><title>per-frame trueness</title></polyline>",
        frame.line(per_frame_trueness(d).into_iter())
    );
    s.push_str("</svg>\n");
    s
}

/// `(time, mean error over the sequences)` per frame number, in frame order.
fn per_frame_trueness(d: &Dof) -> Vec<(f64, f64)> {
    let mut by_frame: std::collections::BTreeMap<u32, (f64, f64, usize)> = Default::default();
    for p in d.series.iter().flat_map(|s| &s.points) {
        let e = by_frame.entry(p.frame).or_insert((p.time_s, 0.0, 0));
        e.1 += p.error;
        e.2 += 1;
    }
    by_frame
        .into_values()
        .map(|(t, sum, n)| (t, sum / n as f64))
        .collect()
}

/// Header of [`frames_csv`].
pub(crate) const FRAMES_HEADER: [&str; 13] = [
    "noise_level",
    "exposure_factor",
    "sequence",
    "frame",
    "run",
    "time_s",
    "entity",
    "kind",
    "dof",
    "unit",
    "truth",
    "measured",
    "error",
];

/// Every measured frame's value of every degree of freedom at full precision (Rust's shortest
/// round-trip formatting), one row each: level, sequence, frame, run, time, entity, degree of
/// freedom, truth, measured, error.
pub fn frames_csv(q: &SequenceSection) -> String {
    let mut w = super::csv::writer();
    w.write_record(FRAMES_HEADER).expect("write to memory");
    for l in &q.levels {
        for e in &l.entities {
            for d in &e.dofs {
                for series in &d.series {
                    for p in &series.points {
                        w.write_record([
                            l.noise_level.to_string(),
                            l.exposure_factor
                                .map_or_else(String::new, |f| f.to_string()),
                            series.sequence.clone(),
                            p.frame.to_string(),
                            p.run.clone(),
                            p.time_s.to_string(),
                            e.id.clone(),
                            e.kind.clone(),
                            d.label.clone(),
                            d.unit.clone(),
                            p.truth.to_string(),
                            p.measured.to_string(),
                            p.error.to_string(),
                        ])
                        .expect("write to memory");
                    }
                }
            }
        }
    }
    super::csv::finish(w)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_value_labels_of_a_narrow_range_far_from_zero_differ() {
        // −50.2 … −50.3 mm (a joint translation): two significant digits would print −50 twice.
        let frame = Frame::new([0.0, 1.0].into_iter(), [-50.2, -50.3].into_iter());
        let svg = open("q3", "mm", &frame);
        let labels: Vec<&str> = svg
            .split("text-anchor=\"end\">")
            .skip(1)
            .map(|r| r.split('<').next().unwrap())
            .collect();
        assert_eq!(labels.len(), 3, "{svg}");
        assert_ne!(labels[0], labels[1], "{labels:?}");
        assert!(labels[0].starts_with("\u{2212}50.3"), "{labels:?}");
    }
}

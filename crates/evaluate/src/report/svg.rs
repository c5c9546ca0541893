//! Hand-written inline SVG plots of trueness ± precision against noise level. Deterministic:
//! coordinates are printed with two decimals, nothing depends on time or randomness.

use std::fmt::Write;

use super::unicode_minus;
use crate::output::html_text::escape as esc;
use crate::stats::{Cell, Significance};

const W: f64 = 330.0;
const H: f64 = 230.0;
const LEFT: f64 = 66.0;
const RIGHT: f64 = 14.0;
const TOP: f64 = 28.0;
const BOTTOM: f64 = 48.0;

/// Colours of significant points and bars (the paper's red and blue, darkened for lines).
const RED: &str = "#b2182b";
const BLUE: &str = "#2155a8";
const BLACK: &str = "#222222";

/// What the x axis of a plot shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Axis {
    /// Binary mode: noise levels, % of I_max.
    Noise,
    /// Attenuation mode: exposure levels, factors on the exposure.
    Exposure,
}

impl Axis {
    /// The axis in a sentence: "noise level" or "exposure level".
    pub(crate) fn noun(self) -> &'static str {
        match self {
            Axis::Noise => "noise level",
            Axis::Exposure => "exposure level",
        }
    }

    /// The x axis of a plot against these levels.
    pub(crate) fn x_axis(self) -> XAxis<'static> {
        XAxis {
            title_html: self.title_html(),
            noun: self.noun(),
        }
    }

    fn title_html(self) -> &'static str {
        match self {
            Axis::Noise => {
                "Noise level (% of I<tspan baseline-shift=\"sub\" font-size=\"8\">max</tspan>)"
            }
            Axis::Exposure => "Exposure level (factor on the exposure)",
        }
    }
}

/// Colour of a threshold line (MTPM).
const ORANGE: &str = "#c05a00";

/// What the x axis of a plot shows, for any quantity: its title (HTML-escaped, may hold
/// `<tspan>`) and its noun for the plot's accessible title.
pub(crate) struct XAxis<'a> {
    /// The axis title as SVG text content (escaped).
    pub title_html: &'a str,
    /// The quantity in a sentence, e.g. "noise level".
    pub noun: &'a str,
}

/// A plot of one parameter: points at (`levels[i]`, T) against `axis` (noise level, exposure
/// level or a swept parameter) with error bars ±P, a dashed zero line, `labels[i]` under the x
/// axis, tick labels on the y axis, axis titles with `unit`. Positive cells are red
/// up-triangles, negative cells blue down-triangles, others black circles; N = 1 cells have no
/// bar.
/// With `threshold` (a magnitude such as MTPM, never tested against zero) every point is a black
/// circle and an orange dashed line marks the threshold, inside the y range.
pub(crate) fn plot(
    title: &str,
    unit: &str,
    levels: &[f64],
    labels: &[String],
    axis: &XAxis,
    cells: &[Option<&Cell>],
    threshold: Option<f64>,
) -> String {
    let points: Vec<(f64, &Cell)> = levels
        .iter()
        .zip(cells)
        .filter_map(|(&x, c)| c.map(|c| (x, c)))
        .collect();
    let (x0, x1) = x_domain(levels);
    let (ticks, y0, y1) = y_ticks(&points, threshold);
    let px = |x: f64| LEFT + (x - x0) / (x1 - x0) * (W - LEFT - RIGHT);
    let py = |y: f64| TOP + (y1 - y) / (y1 - y0) * (H - TOP - BOTTOM);
    let mut s = String::new();
    let _ = write!(
        s,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{W}\" height=\"{H}\" viewBox=\"0 0 {W} {H}\" \
role=\"img\" font-family=\"sans-serif\" font-size=\"11\"><title>{}</title>",
        esc(&format!(
            "{title}: trueness ± precision ({unit}) against {}",
            axis.noun
        ))
    );
    let _ = write!(
        s,
        "<text x=\"{:.2}\" y=\"16\" text-anchor=\"middle\" font-weight=\"bold\">{}</text>",
        W / 2.0,
        esc(title)
    );
    let _ = write!(
        s,
        "<rect x=\"{LEFT:.2}\" y=\"{TOP:.2}\" width=\"{:.2}\" height=\"{:.2}\" fill=\"none\" stroke=\"#999999\"/>",
        W - LEFT - RIGHT,
        H - TOP - BOTTOM
    );
    for (value, label) in &ticks {
        let y = py(*value);
        let _ = write!(
            s,
            "<line x1=\"{:.2}\" y1=\"{y:.2}\" x2=\"{LEFT:.2}\" y2=\"{y:.2}\" stroke=\"#999999\"/>",
            LEFT - 4.0
        );
        let _ = write!(
            s,
            "<text x=\"{:.2}\" y=\"{:.2}\" text-anchor=\"end\">{}</text>",
            LEFT - 6.0,
            y + 4.0,
            esc(label)
        );
    }
    let mut seen: Vec<f64> = Vec::new();
    for (&level, label) in levels.iter().zip(labels) {
        if seen.contains(&level) {
            continue;
        }
        seen.push(level);
        let x = px(level);
        let base = H - BOTTOM;
        let _ = write!(
            s,
            "<line x1=\"{x:.2}\" y1=\"{base:.2}\" x2=\"{x:.2}\" y2=\"{:.2}\" stroke=\"#999999\"/>",
            base + 4.0
        );
        let _ = write!(
            s,
            "<text x=\"{x:.2}\" y=\"{:.2}\" text-anchor=\"middle\">{}</text>",
            base + 16.0,
            esc(label)
        );
    }
    let zero = py(0.0);
    let _ = write!(
        s,
        "<line x1=\"{LEFT:.2}\" y1=\"{zero:.2}\" x2=\"{:.2}\" y2=\"{zero:.2}\" stroke=\"#555555\" stroke-dasharray=\"4 3\"/>",
        W - RIGHT
    );
    if let Some(t) = threshold {
        let y = py(t);
        let _ = write!(
            s,
            "<line x1=\"{LEFT:.2}\" y1=\"{y:.2}\" x2=\"{:.2}\" y2=\"{y:.2}\" stroke=\"{ORANGE}\" stroke-width=\"1.5\" stroke-dasharray=\"6 3\"/>",
            W - RIGHT
        );
        let _ = write!(
            s,
            "<text x=\"{:.2}\" y=\"{:.2}\" text-anchor=\"end\" fill=\"{ORANGE}\">threshold {}</text>",
            W - RIGHT - 3.0,
            y - 3.0,
            esc(&super::number::trimmed(t, 6))
        );
    }
    for (level, c) in &points {
        let significance = match threshold {
            Some(_) => Significance::None,
            None => c.significance,
        };
        point(&mut s, px(*level), c, significance, &py);
    }
    let _ = write!(
        s,
        "<text x=\"{:.2}\" y=\"{:.2}\" text-anchor=\"middle\">{}</text>",
        LEFT + (W - LEFT - RIGHT) / 2.0,
        H - 10.0,
        axis.title_html
    );
    let (cx, cy) = (14.0, TOP + (H - TOP - BOTTOM) / 2.0);
    let _ = write!(
        s,
        "<text x=\"{cx:.2}\" y=\"{cy:.2}\" text-anchor=\"middle\" transform=\"rotate(-90 {cx:.2} {cy:.2})\">T ± P ({})</text>",
        esc(unit)
    );
    s.push_str("</svg>");
    s
}

/// One point with its error bar, drawn as `significance` says.
fn point(s: &mut String, x: f64, c: &Cell, significance: Significance, py: &dyn Fn(f64) -> f64) {
    let color = match significance {
        Significance::Positive => RED,
        Significance::Negative => BLUE,
        Significance::None => BLACK,
    };
    if c.precision.is_finite() {
        let (lo, hi) = (py(c.trueness - c.precision), py(c.trueness + c.precision));
        let _ = write!(
            s,
            "<line x1=\"{x:.2}\" y1=\"{lo:.2}\" x2=\"{x:.2}\" y2=\"{hi:.2}\" stroke=\"{color}\" stroke-width=\"1.5\"/>"
        );
        for y in [lo, hi] {
            let _ = write!(
                s,
                "<line x1=\"{:.2}\" y1=\"{y:.2}\" x2=\"{:.2}\" y2=\"{y:.2}\" stroke=\"{color}\" stroke-width=\"1.5\"/>",
                x - 5.0,
                x + 5.0
            );
        }
    }
    let y = py(c.trueness);
    let shape = match significance {
        Significance::Positive => format!(
            "<path d=\"M{x:.2} {:.2}L{:.2} {:.2}L{:.2} {:.2}Z\"",
            y - 5.0,
            x + 5.0,
            y + 4.0,
            x - 5.0,
            y + 4.0
        ),
        Significance::Negative => format!(
            "<path d=\"M{x:.2} {:.2}L{:.2} {:.2}L{:.2} {:.2}Z\"",
            y + 5.0,
            x + 5.0,
            y - 4.0,
            x - 5.0,
            y - 4.0
        ),
        Significance::None => format!("<circle cx=\"{x:.2}\" cy=\"{y:.2}\" r=\"3.5\""),
    };
    let _ = write!(
        s,
        "{shape} fill=\"{color}\"><title>{}</title></",
        esc(&tooltip(c))
    );
    s.push_str(if significance == Significance::None {
        "circle>"
    } else {
        "path>"
    });
}

/// The hover text of a point: "T ± P (N=k)".
fn tooltip(c: &Cell) -> String {
    unicode_minus(&format!(
        "{} (N={})",
        super::trueness_precision(c, " ± "),
        c.n
    ))
}

/// The x range: the noise levels, padded by 8 % (±0.1 around a single level).
fn x_domain(levels: &[f64]) -> (f64, f64) {
    let lo = levels.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = levels.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !lo.is_finite() || !hi.is_finite() {
        return (0.0, 1.0);
    }
    let pad = if hi > lo { 0.08 * (hi - lo) } else { 0.1 };
    (lo - pad, hi + pad)
}

/// "Nice" y ticks (steps of 1, 2 or 5 × 10^k) covering zero, every T ± P and the threshold;
/// returns the ticks with their labels and the axis range.
fn y_ticks(points: &[(f64, &Cell)], threshold: Option<f64>) -> (Vec<(f64, String)>, f64, f64) {
    let mut lo: f64 = 0.0;
    let mut hi: f64 = threshold.filter(|t| t.is_finite()).unwrap_or(0.0).max(0.0);
    for (_, c) in points {
        let p = if c.precision.is_finite() {
            c.precision
        } else {
            0.0
        };
        for v in [c.trueness - p, c.trueness + p] {
            if v.is_finite() {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
    }
    if hi - lo <= 0.0 {
        (lo, hi) = (-1.0, 1.0);
    }
    // Headroom, so that no point or bar end sits on the frame.
    let pad = 0.05 * (hi - lo);
    (lo, hi) = (lo - pad, hi + pad);
    let raw = (hi - lo) / 4.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * mag)
        .find(|&s| s >= raw)
        .unwrap_or(10.0 * mag);
    let (i0, i1) = ((lo / step).floor() as i64, (hi / step).ceil() as i64);
    let decimals = (-step.log10().floor()).max(0.0) as usize;
    let ticks = (i0..=i1)
        .map(|i| {
            let v = i as f64 * step;
            let label = if i == 0 {
                "0".to_string()
            } else {
                unicode_minus(&format!("{v:.decimals$}"))
            };
            (v, label)
        })
        .collect();
    (ticks, i0 as f64 * step, i1 as f64 * step)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stats::Confidence;

    #[test]
    fn ticks_are_nice_and_cover_the_bars() {
        let c = Cell::from_residuals(&[-0.5, -0.6, -0.4], &Confidence::default());
        let (ticks, lo, hi) = y_ticks(&[(0.0, &c)], None);
        assert!(lo <= c.trueness - c.precision && hi >= 0.0);
        let labels: Vec<&str> = ticks.iter().map(|(_, l)| l.as_str()).collect();
        assert_eq!(labels, ["−0.8", "−0.6", "−0.4", "−0.2", "0", "0.2"]);
    }

    fn labels() -> Vec<String> {
        [0.0, 0.225, 0.45].map(super::super::format_noise).to_vec()
    }

    #[test]
    fn a_plot_is_deterministic_and_marks_significance() {
        let pos = Cell::from_residuals(&[1.0, 1.1, 0.9], &Confidence::default());
        let one = Cell::from_residuals(&[0.2], &Confidence::default());
        let svg = plot(
            "tube1 · x_r",
            "mm",
            &[0.0, 0.225, 0.45],
            &labels(),
            &Axis::Noise.x_axis(),
            &[Some(&pos), None, Some(&one)],
            None,
        );
        assert_eq!(
            svg,
            plot(
                "tube1 · x_r",
                "mm",
                &[0.0, 0.225, 0.45],
                &labels(),
                &Axis::Noise.x_axis(),
                &[Some(&pos), None, Some(&one)],
                None
            )
        );
        assert_eq!(svg.matches("<path").count(), 1);
        assert_eq!(svg.matches("<circle").count(), 1);
        assert!(svg.contains(">22.5%</text>") && svg.contains("T ± P (mm)"));
        assert!(!svg.contains("threshold"));
    }

    #[test]
    fn a_magnitude_is_plotted_against_its_threshold_not_as_bias() {
        // An MTPM-like magnitude far from zero: T ± P excludes zero, yet no bias mark.
        let mtpm = Cell::from_residuals(&[0.05, 0.06, 0.04], &Confidence::default());
        assert_eq!(mtpm.significance, Significance::Positive);
        let svg = plot(
            "femur · MTPM",
            "mm",
            &[0.0],
            &labels()[..1],
            &Axis::Noise.x_axis(),
            &[Some(&mtpm)],
            Some(0.2),
        );
        assert_eq!(svg.matches("<path").count(), 0);
        assert_eq!(svg.matches("<circle").count(), 1);
        assert!(svg.contains(">threshold 0.2</text>") && svg.contains(ORANGE));
        // The y range reaches the threshold: a tick at 0.2 or above.
        let (ticks, _, hi) = y_ticks(&[(0.0, &mtpm)], Some(0.2));
        assert!(hi >= 0.2 && ticks.iter().any(|(v, _)| *v >= 0.2));
    }
}

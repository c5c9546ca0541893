//! The SVG plot of `rsasim spectrum`: photons per bin against energy before and after the
//! tube's filtration, the absorption edges of the materials in the beam as dashed lines, and the
//! energies of the bins traced for the images as ticks under the axis. Deterministic:
//! coordinates are printed with two decimals; nothing depends on time.

use std::fmt::Write;

use rsasim::attenuation::beamline::Beamline;
use rsasim::output::html_text::escape;

/// The first bytes of every plot this command writes: how an earlier one is recognised before
/// it is replaced.
pub const MARK: &str = "<!-- rsasim spectrum -->";

const W: f64 = 720.0;
const H: f64 = 420.0;
const LEFT: f64 = 84.0;
const RIGHT: f64 = 20.0;
const TOP: f64 = 40.0;
const BOTTOM: f64 = 70.0;

/// The plot as a standalone SVG document.
pub fn svg(title: &str, beam: &Beamline) -> String {
    let energies = &beam.filtered.energies_kev;
    let e_max = energies.last().copied().unwrap_or(1.0).max(1.0);
    let x_max = (e_max / 10.0).ceil() * 10.0;
    // Scaled to the filtered spectrum; the unfiltered one (whose low-energy lines can be a
    // hundred times higher) is clipped to the plot.
    let y_max = beam
        .filtered
        .photons
        .iter()
        .copied()
        .fold(0.0_f64, f64::max);
    let y_max = if y_max > 0.0 { y_max * 1.05 } else { 1.0 };
    let x = |e: f64| LEFT + e / x_max * (W - LEFT - RIGHT);
    let y = |n: f64| H - BOTTOM - n / y_max * (H - TOP - BOTTOM);
    let mut s = String::new();
    let _ = writeln!(s, "{MARK}");
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(
        s,
        r#"<text x="{LEFT}" y="18" font-size="13">{}</text>"#,
        escape(title)
    );
    let _ = writeln!(
        s,
        r#"<clipPath id="plot"><rect x="{LEFT}" y="{TOP}" width="{:.2}" height="{:.2}"/></clipPath>"#,
        W - LEFT - RIGHT,
        H - TOP - BOTTOM
    );
    // Axes with ticks every 10 keV and at fifths of the photon range.
    let (x0, y0) = (x(0.0), y(0.0));
    let _ = writeln!(
        s,
        r##"<path d="M{x0:.2},{:.2} V{y0:.2} H{:.2}" fill="none" stroke="#222"/>"##,
        TOP,
        W - RIGHT
    );
    let mut e = 0.0;
    while e <= x_max + 1e-9 {
        let _ = writeln!(
            s,
            r##"<line x1="{0:.2}" y1="{1:.2}" x2="{0:.2}" y2="{2:.2}" stroke="#222"/><text x="{0:.2}" y="{3:.2}" text-anchor="middle">{4}</text>"##,
            x(e),
            y0,
            y0 + 5.0,
            y0 + 18.0,
            e
        );
        e += 10.0;
    }
    for k in 0..=5 {
        let n = y_max / 1.05 * f64::from(k) / 5.0;
        let _ = writeln!(
            s,
            r##"<line x1="{0:.2}" y1="{1:.2}" x2="{2:.2}" y2="{1:.2}" stroke="#222"/><text x="{3:.2}" y="{4:.2}" text-anchor="end">{5:.3e}</text>"##,
            x0 - 5.0,
            y(n),
            x0,
            x0 - 8.0,
            y(n) + 4.0,
            n
        );
    }
    let _ = writeln!(
        s,
        r#"<text x="{:.2}" y="{:.2}" text-anchor="middle">energy (keV); ticks below: the {} bins traced for the images</text>"#,
        (LEFT + W - RIGHT) / 2.0,
        H - 16.0,
        beam.traced_bins.len()
    );
    let unit = if beam.absolute {
        "photons per bin per mm² per mAs at 1000 mm"
    } else {
        "relative photons per bin"
    };
    let _ = writeln!(
        s,
        r#"<text transform="translate(16 {:.2}) rotate(-90)" text-anchor="middle">{unit}</text>"#,
        (TOP + H - BOTTOM) / 2.0
    );
    // Edges, then the spectra, then the traced bins.
    for (k, edge) in beam.edges.iter().enumerate() {
        let ex = x(edge.energy_kev);
        let label_y = TOP + 10.0 + 12.0 * (k % 3) as f64;
        let _ = writeln!(
            s,
            r##"<line x1="{ex:.2}" y1="{TOP:.2}" x2="{ex:.2}" y2="{y0:.2}" stroke="#c05a00" stroke-dasharray="4 3"/><text x="{:.2}" y="{:.2}" fill="#c05a00" font-size="10">{} {}</text>"##,
            ex + 2.0,
            label_y,
            escape(edge.element),
            escape(edge.shell)
        );
    }
    for (photons, colour, name) in [
        (&beam.unfiltered.photons, "#9a9a9a", "before filtration"),
        (&beam.filtered.photons, "#2155a8", "after filtration"),
    ] {
        let mut d = String::new();
        for (i, (&e, &n)) in energies.iter().zip(photons.iter()).enumerate() {
            let _ = write!(
                d,
                "{}{:.2},{:.2} ",
                if i == 0 { "M" } else { "L" },
                x(e),
                y(n)
            );
        }
        let _ = writeln!(
            s,
            r#"<path d="{}" fill="none" stroke="{colour}" stroke-width="1.5" clip-path="url(#plot)"><title>{name}</title></path>"#,
            d.trim_end()
        );
    }
    for [e, _] in &beam.traced_bins {
        let _ = writeln!(
            s,
            r##"<line x1="{0:.2}" y1="{1:.2}" x2="{0:.2}" y2="{2:.2}" stroke="#b2182b"/>"##,
            x(*e),
            y0 + 24.0,
            y0 + 32.0
        );
    }
    let _ = writeln!(
        s,
        r##"<text x="{:.2}" y="{:.2}" text-anchor="end"><tspan fill="#9a9a9a">— before filtration</tspan> <tspan fill="#2155a8">— after filtration</tspan> <tspan fill="#c05a00">- - absorption edges</tspan></text>"##,
        W - RIGHT,
        TOP - 6.0
    );
    s += "</svg>\n";
    s
}

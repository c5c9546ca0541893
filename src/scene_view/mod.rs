//! `rsasim scene`: one self-contained HTML page that shows a scenario before it is run — the
//! sources, detectors, calibration box, meshes and beads of the first run in 3D (drag to turn,
//! wheel to zoom), the envelope each object sweeps over the runs of the protocol (its random
//! ranges) as a shaded box, each beamline's beam cone, the first run's images as thumbnails and
//! the scenario check's warnings placed at the objects they concern.
//!
//! The page needs no network: the viewer ([`VIEWER_JS`], a small canvas renderer) and its style
//! are inline, the scene is inline JSON, the thumbnails are PNG data URLs. It depends only on the
//! scenario and the program version (byte-identical re-renders). The scenario is read by the
//! scenario loader under its confinement rules ([`crate::phantom::confine`]); nothing else is
//! opened.

pub mod decimate;
pub mod scene;
pub mod thumbnails;

use std::fmt::Write;
use std::path::Path;

use crate::diagnostic::Diagnostic;
use crate::output::html_text::escape as esc;
use crate::simulate::Checked;

pub use scene::{Scene, build};

/// The viewer: draws the scene JSON on a canvas (painter's algorithm, orthographic view).
pub const VIEWER_JS: &str = include_str!("viewer.js");

/// The page's stylesheet.
pub const VIEWER_CSS: &str = include_str!("viewer.css");

/// The `generator` of every scene page: how an earlier page is recognised before it is
/// replaced.
pub const GENERATOR: &str = "rsasim scene";

/// The scene of a checked scenario, with the first run's thumbnails unless `images` is false
/// (they need a simulation of that run). Consumes `checked`: the thumbnails' simulation takes
/// its phantoms.
pub fn scene_of(checked: Checked, images: bool) -> std::io::Result<Scene> {
    let mut scene = build(
        &checked.loaded.scenario,
        &checked.models,
        &checked.warnings,
        &|_| Vec::new(),
    );
    if images {
        let thumbs = thumbnails::first_run_thumbnails(checked)?;
        for (d, t) in scene.detectors.iter_mut().zip(thumbs) {
            d.images = t;
        }
    }
    Ok(scene)
}

/// The page of `scene`.
pub fn page(scene: &Scene) -> String {
    let json = serde_json::to_string(scene)
        .unwrap_or_else(|_| "{}".into())
        // Inside <script>, "</" could end the element: JSON allows "<\/" for it.
        .replace("</", "<\\/");
    let title = format!("rsasim scene: {}", scene.name);
    let mut s = String::new();
    let _ = write!(
        s,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\"/>\n\
<meta name=\"generator\" content=\"{GENERATOR} {}\"/>\n<title>{}</title>\n<style>{VIEWER_CSS}</style>\n</head>\n<body>\n",
        env!("CARGO_PKG_VERSION"),
        esc(&title)
    );
    let _ = writeln!(
        s,
        "<header><h1>{}</h1><p>Scanner frame, mm. Run <code>{}</code> drawn; shaded boxes: what each object sweeps over {} of {} runs (its random ranges). Drag to turn, wheel to zoom, double-click to reset.</p></header>",
        esc(&title),
        esc(&scene.run),
        scene.envelope_runs,
        scene.total_runs
    );
    s.push_str(
        "<main><div id=\"stage\"><canvas id=\"view\" width=\"900\" height=\"640\"></canvas>\
<div id=\"controls\"><label><input type=\"checkbox\" id=\"show-cones\" checked/> beam cones</label> \
<label><input type=\"checkbox\" id=\"show-envelopes\" checked/> random ranges</label> \
<label><input type=\"checkbox\" id=\"show-labels\" checked/> labels</label> \
<button id=\"reset\" type=\"button\">Reset view</button></div></div>\n<aside>\n",
    );
    warnings_list(&mut s, scene);
    thumbnails_list(&mut s, scene);
    legend(&mut s, scene);
    s.push_str("</aside></main>\n");
    let _ = write!(
        s,
        "<script type=\"application/json\" id=\"scene-data\">{json}</script>\n<script>{VIEWER_JS}</script>\n</body>\n</html>\n"
    );
    s
}

/// The warnings, numbered as on the scene.
fn warnings_list(s: &mut String, scene: &Scene) {
    let _ = writeln!(s, "<h2>Warnings ({})</h2>", scene.warnings.len());
    if scene.warnings.is_empty() {
        s.push_str("<p>None.</p>\n");
        return;
    }
    s.push_str("<ol id=\"warnings\">\n");
    for w in &scene.warnings {
        let key = w
            .key
            .as_ref()
            .map_or(String::new(), |k| format!("<code>{}</code>: ", esc(k)));
        let place = if w.at.is_some() {
            ""
        } else {
            " <em>(not placed: about no one object)</em>"
        };
        let _ = writeln!(s, "<li>{key}{}{place}</li>", esc(&w.text));
    }
    s.push_str("</ol>\n");
}

/// The first run's images, per detector.
fn thumbnails_list(s: &mut String, scene: &Scene) {
    let _ = writeln!(s, "<h2>Images of run <code>{}</code></h2>", esc(&scene.run));
    if scene.detectors.iter().all(|d| d.images.is_empty()) {
        s.push_str("<p>Not made (<code>--no-images</code>).</p>\n");
        return;
    }
    s.push_str("<div class=\"thumbs\">\n");
    for d in &scene.detectors {
        for im in &d.images {
            let _ = writeln!(
                s,
                "<figure><img src=\"{}\" alt=\"exposure {} on detector {}\"/><figcaption>{} · {}</figcaption></figure>",
                esc(&im.src),
                esc(&im.exposure),
                esc(&d.id),
                esc(&im.exposure),
                esc(&d.id)
            );
        }
    }
    s.push_str("</div>\n<p class=\"note\">Windowed 8-bit previews, never evidence.</p>\n");
}

/// What the colours mean, and how big the meshes are.
fn legend(s: &mut String, scene: &Scene) {
    s.push_str("<h2>Legend</h2>\n<ul class=\"legend\">\n<li><span class=\"sw src\"></span> source (focus)</li>\n<li><span class=\"sw det\"></span> detector (active area; the r axis marked from pixel (0, 0))</li>\n<li><span class=\"sw cone\"></span> beam cone: source to its detector's corners</li>\n<li><span class=\"sw env\"></span> random range: bounds over the runs</li>\n<li><span class=\"sw bead\"></span> bead</li>\n<li><span class=\"sw mesh\"></span> mesh, box plate, cylinder</li>\n<li><span class=\"sw warn\"></span> warning (numbered as in the list)</li>\n</ul>\n");
    for p in &scene.phantoms {
        if let Some(m) = &p.mesh {
            let shown = m.triangles.len() / 3;
            if shown < m.full_triangles {
                let _ = writeln!(
                    s,
                    "<p class=\"note\">Mesh {}: {shown} of its {} triangles drawn (decimated for the page; the simulation uses them all).</p>",
                    esc(&p.id),
                    m.full_triangles
                );
            }
        }
    }
}

/// Why `rsasim scene` would not write the page file.
pub fn check_page_target(path: &Path) -> Result<(), Box<Diagnostic>> {
    let meta = match std::fs::symlink_metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => {
            return Err(Box::new(Diagnostic::file_error(
                path,
                format!("cannot check the page file: {e}"),
            )));
        }
    };
    let refuse = |why: &str| {
        Box::new(
            Diagnostic::file_error(path, format!("{why}; it is left as it is"))
                .with_help("give another file with --out"),
        )
    };
    if !meta.is_file() {
        return Err(refuse("is not a regular file (a folder or a link)"));
    }
    let mut head = vec![0u8; 512];
    let n = std::fs::File::open(path)
        .and_then(|mut f| std::io::Read::read(&mut f, &mut head))
        .unwrap_or(0);
    let head = String::from_utf8_lossy(&head[..n]);
    if !head.contains(&format!("<meta name=\"generator\" content=\"{GENERATOR} ")) {
        return Err(refuse("exists and is not a page rsasim scene wrote"));
    }
    Ok(())
}

#[cfg(test)]
mod tests;

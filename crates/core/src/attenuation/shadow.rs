//! Every part's shadow on a detector (its path lengths over the rectangle it covers) and what
//! the response takes of the shadows: one layer of material per shadow (and, for a nested part,
//! one taken from the material it displaces), and the scene of one image. Shared by the image
//! ([`super::image`]) and its sampled expectation ([`super::sampled`]).

use glam::DVec3;
use rayon::prelude::*;

use crate::geometry::DetectorFrame;
use crate::response::{self, Fluence, Layer, Scene};
use crate::trace::{PathLengths, path_lengths};

use super::scene::Part;
use super::setup::Setup;

/// Every part's path lengths on `frame` from `source_mm` (parts in parallel; a mesh is
/// scan-converted on one thread), in part order.
pub(super) fn shadows_of(
    parts: &[Part],
    frame: &DetectorFrame,
    source_mm: DVec3,
) -> Vec<Option<PathLengths>> {
    parts
        .par_iter()
        .map(|part| path_lengths(frame, source_mm, &part.object))
        .collect()
}

/// What the response needs of one image on `frame`: the materials' attenuation, the path-length
/// `layers`, and a point source's `fluence` on the frame's pixel centres.
pub(super) fn scene_of<'a>(
    setup: &'a Setup,
    frame: &DetectorFrame,
    layers: &'a [Layer<'a>],
    fluence: &'a response::PointSourceFluence,
) -> Scene<'a> {
    let [w, h] = frame.pixels.map(|n| n as usize);
    Scene {
        width: w,
        height: h,
        mu_per_mm: &setup.mu_per_mm,
        layers,
        fluence: Fluence::PointSource(fluence),
    }
}

/// The layers of the parts' shadows: each part's lengths added to its material and, for a
/// nested part, taken from the material it displaces (parts in order).
pub(super) fn layers_of<'a>(parts: &[Part], shadows: &'a [Option<PathLengths>]) -> Vec<Layer<'a>> {
    let mut layers = Vec::with_capacity(2 * parts.len());
    for (part, shadow) in parts.iter().zip(shadows) {
        let Some(pl) = shadow else { continue };
        layers.push(layer(part.material, 1.0, pl));
        if let Some(p) = part.parent {
            layers.push(layer(parts[p].material, -1.0, pl));
        }
    }
    layers
}

/// The layer of `pl` added to (`sign` +1) or taken from (−1) material `material`.
fn layer(material: usize, sign: f64, pl: &PathLengths) -> Layer<'_> {
    Layer {
        material,
        sign,
        columns: pl.columns.start as usize..pl.columns.end as usize,
        rows: pl.rows.start as usize..pl.rows.end as usize,
        length_mm: &pl.length_mm,
    }
}

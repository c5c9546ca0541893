//! One attenuation-mode image: the exact path length of every part on every pixel, summed per
//! material net of nesting (a part's length is added to its material and taken from the
//! material it displaces), then the detector response with quantum noise.

use glam::DVec3;

use crate::geometry::DetectorFrame;
use crate::noise::NoiseKey;
use crate::response::{self, Scene};
use crate::trace::{Object, path_lengths};

use super::scene::Part;
use super::setup::Setup;

/// Net path lengths below this (mm) are rounding; below its negative a nested solid pokes out
/// of the solid it was declared `inside`.
const NEST_TOLERANCE_MM: f64 = 1e-6;

/// A bead's visibility on one image.
#[derive(Debug, Clone, PartialEq)]
pub struct BeadVisibility {
    /// Index of the bead's phantom in the run.
    pub phantom: usize,
    /// Index of the bead among its phantom's markers.
    pub bead: usize,
    /// Whether the pixel under the bead's projected centre sees metal besides beads (a volume
    /// of density ≥ 4 g/cm³) along its ray.
    pub occluded: bool,
    /// Fraction of the bead's shadow pixels (pixels whose ray crosses the bead) whose ray also
    /// crosses metal; 0 when the bead casts no shadow on the detector.
    pub metal_fraction: f64,
}

/// The image and what the truth needs of it.
pub struct AttenuationImage {
    /// Detector values, row-major.
    pub pixels: Vec<u16>,
    /// Pixels clamped at I_max.
    pub saturated: usize,
    /// Visibility of every bead in the beam, in part order.
    pub beads: Vec<BeadVisibility>,
    /// Net path length per material (row-major, mm), when asked for.
    pub lengths_mm: Option<Vec<Vec<f64>>>,
}

/// Renders the parts of one exposure on one detector at exposure factor `factor`.
#[allow(clippy::too_many_arguments)]
pub fn render(
    setup: &Setup,
    parts: &[Part],
    frame: &DetectorFrame,
    source_mm: DVec3,
    factor: f64,
    i_max: u16,
    key: &NoiseKey,
    keep_lengths: bool,
) -> Result<AttenuationImage, String> {
    let [w, h] = frame.pixels.map(|n| n as usize);
    let n = w * h;
    let materials = setup.materials.len();
    let mut lengths: Vec<Vec<f64>> = vec![Vec::new(); materials];
    let mut metal: Vec<f64> = Vec::new();
    let mut shadows = Vec::with_capacity(parts.len());
    for part in parts {
        let Some(pl) = path_lengths(frame, source_mm, &part.object) else {
            shadows.push(None);
            continue;
        };
        let targets = [(part.material, 1.0)]
            .into_iter()
            .chain(part.parent.map(|p| (parts[p].material, -1.0)));
        for (m, sign) in targets {
            let image = &mut lengths[m];
            if image.is_empty() {
                image.resize(n, 0.0);
            }
            add_rect(image, w, &pl, sign);
        }
        if part.bead.is_none() && setup.is_metal(part.material) {
            if metal.is_empty() {
                metal.resize(n, 0.0);
            }
            add_rect(&mut metal, w, &pl, 1.0);
        }
        shadows.push(if part.bead.is_some() { Some(pl) } else { None });
    }
    for (m, image) in lengths.iter_mut().enumerate() {
        for (p, l) in image.iter_mut().enumerate() {
            if *l < 0.0 {
                if *l < -NEST_TOLERANCE_MM {
                    let nested: Vec<&str> = parts
                        .iter()
                        .filter(|x| x.parent.is_some_and(|q| parts[q].material == m))
                        .map(|x| x.label.as_str())
                        .collect();
                    return Err(format!(
                        "at pixel ({}, {}) the ray crosses {:.4} mm more of the solids placed inside {} material than of the {} itself: {} not wholly inside the solid it is declared `inside`",
                        p % w,
                        p / w,
                        -*l,
                        setup.names[m],
                        setup.names[m],
                        nested.join(", ")
                    ));
                }
                *l = 0.0;
            }
        }
    }
    let fluence = response::point_source_fluence(frame, source_mm);
    let beam = setup.beam(frame, source_mm, factor);
    let nominal = setup.beam(frame, source_mm, 1.0);
    let detector = setup.detector(&nominal, i_max);
    let scene = Scene {
        width: w,
        height: h,
        mu_per_mm: &setup.mu_per_mm,
        lengths_mm: &lengths,
        fluence: &fluence,
    };
    let rendered = response::render(&beam, &detector, &scene, key);
    let beads = parts
        .iter()
        .zip(&shadows)
        .filter_map(|(part, shadow)| {
            let bead = part.bead?;
            let (mut covered, mut over_metal) = (0usize, 0usize);
            if let Some(pl) = shadow {
                for (k, &l) in pl.length_mm.iter().enumerate() {
                    if l > 0.0 {
                        covered += 1;
                        let cols = (pl.columns.end - pl.columns.start) as usize;
                        let (i, j) = (
                            pl.columns.start as usize + k % cols,
                            pl.rows.start as usize + k / cols,
                        );
                        if metal.get(j * w + i).is_some_and(|&x| x > 0.0) {
                            over_metal += 1;
                        }
                    }
                }
            }
            let occluded = match &part.object {
                Object::Sphere { centre_mm, .. } => frame
                    .project(source_mm, *centre_mm)
                    .filter(|uv| frame.contains_pixel(*uv))
                    .is_some_and(|uv| {
                        let (i, j) = (uv.x.floor() as usize, uv.y.floor() as usize);
                        metal.get(j * w + i).is_some_and(|&x| x > 0.0)
                    }),
                _ => false,
            };
            Some(BeadVisibility {
                phantom: part.phantom,
                bead,
                occluded,
                metal_fraction: if covered == 0 {
                    0.0
                } else {
                    over_metal as f64 / covered as f64
                },
            })
        })
        .collect();
    Ok(AttenuationImage {
        pixels: rendered.pixels,
        saturated: rendered.saturated,
        beads,
        lengths_mm: keep_lengths.then(|| {
            lengths
                .into_iter()
                .map(|l| if l.is_empty() { vec![0.0; n] } else { l })
                .collect()
        }),
    })
}

/// Adds `sign ×` a rectangle of path lengths into a full image of width `w`.
fn add_rect(image: &mut [f64], w: usize, pl: &crate::trace::PathLengths, sign: f64) {
    let cols = (pl.columns.end - pl.columns.start) as usize;
    if cols == 0 {
        return;
    }
    for (r, row) in pl.length_mm.chunks(cols).enumerate() {
        let j = pl.rows.start as usize + r;
        let start = j * w + pl.columns.start as usize;
        for (dst, &l) in image[start..start + cols].iter_mut().zip(row) {
            *dst += sign * l;
        }
    }
}

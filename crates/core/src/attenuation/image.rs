//! One attenuation-mode image: the exact path length of every part on every pixel, summed per
//! material net of nesting (a part's length is added to its material and taken from the
//! material it displaces), then the detector response with quantum noise.

use crate::noise::NoiseKey;
use rayon::prelude::*;

use crate::response::{self, Layer, Unsharpness};
use crate::sampling::Sampling;
use crate::trace::Object;

use super::scene::{Exposure, Part};
use super::setup::Setup;
use super::shadow::{layers_of, scene_of, shadows_of};

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

/// How an image is formed beyond one ray per pixel centre and quantum noise.
#[derive(Clone, Copy)]
pub struct Formation<'a> {
    /// Pixel samples, focal spot, heel effect.
    pub sampling: &'a Sampling,
    /// Scatter, detector blur and electronic noise.
    pub unsharp: &'a Unsharpness,
    /// The electronic noise's key (`NoiseKey::derive_electronic`).
    pub electronic_key: &'a NoiseKey,
    /// A frame of a sequence whose parts move during its pulse: the parts at each of the pulse's
    /// poses (in time order, equal weights); the expected image is the mean of theirs. Empty
    /// otherwise.
    pub pulse: &'a [Vec<Part<'a>>],
}

impl Formation<'_> {
    /// One ray to each pixel centre from a point source, nothing beyond quantum noise, no
    /// motion: the sharp image, rendered in one pass.
    fn is_sharp(&self) -> bool {
        self.sampling.is_point() && *self.unsharp == Unsharpness::default() && self.pulse.is_empty()
    }
}

/// Renders the parts of one exposure on one detector at exposure factor `factor`.
///
/// Every part's path lengths over its shadow's rectangle become one layer of its material and,
/// for a nested part, one negative layer of the material it displaces (parts in order); the
/// response sums them per material row by row, so no W×H image per material is held unless
/// `keep_lengths` asks for them. Bead visibility, the nesting check and the path-length layers
/// come from the rays to the pixel centres from the spot's centre; with area sampling or a focal
/// spot the image itself is the average over the pixel samples and sub-sources
/// ([`super::sampled`]), and with scatter, blur or electronic noise the detector applies them
/// ([`response::render_expected`]).
pub fn render(
    exposure: &Exposure,
    factor: f64,
    i_max: u16,
    key: &NoiseKey,
    keep_lengths: bool,
    formation: Formation,
) -> Result<AttenuationImage, String> {
    let Exposure {
        setup,
        parts,
        frame,
        source_mm,
    } = *exposure;
    let [w, h] = frame.pixels.map(|n| n as usize);
    // Parts in parallel (a mesh is scan-converted on one thread), each part's lengths its own.
    let shadows = shadows_of(parts, frame, source_mm);
    let layers = layers_of(parts, &shadows);
    check_nesting(setup, parts, &layers, w)?;
    let fluence = response::PointSourceFluence::new(frame, source_mm);
    let beam = setup.beam(frame, source_mm, factor);
    let nominal = setup.beam(frame, source_mm, 1.0);
    let detector = setup.detector(&nominal, i_max);
    let scene = scene_of(setup, frame, &layers, &fluence);
    let rendered = if formation.is_sharp() {
        response::render(&beam, &detector, &scene, key)
    } else if !formation.pulse.is_empty() {
        // Motion blur: the mean of the expected images at the pulse's poses, in pose order.
        let mut sum: Option<response::Expected> = None;
        for pose_parts in formation.pulse {
            let at = Exposure {
                parts: pose_parts,
                ..*exposure
            };
            let e = expected_of(&at, &beam, &detector, formation.sampling);
            match &mut sum {
                None => sum = Some(e),
                Some(total) => {
                    for (a, b) in [
                        (&mut total.quanta, &e.quanta),
                        (&mut total.energy_kev, &e.energy_kev),
                        (&mut total.open_signal, &e.open_signal),
                    ] {
                        a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
                    }
                }
            }
        }
        let mut mean = sum.expect("a pulse has poses");
        let k = formation.pulse.len() as f64;
        for image in [
            &mut mean.quanta,
            &mut mean.energy_kev,
            &mut mean.open_signal,
        ] {
            image.iter_mut().for_each(|x| *x /= k);
        }
        response::render_expected(
            &detector,
            &mean,
            formation.unsharp,
            key,
            formation.electronic_key,
        )
    } else {
        let expected = if formation.sampling.is_point() {
            response::expected(&beam, &detector, &scene)
        } else if formation.sampling.adaptive {
            super::sampled::expected_adaptive(
                exposure,
                &shadows,
                &beam,
                &detector,
                formation.sampling,
                response::expected(&beam, &detector, &scene),
            )
        } else {
            super::sampled::expected(exposure, &beam, &detector, formation.sampling)
        };
        response::render_expected(
            &detector,
            &expected,
            formation.unsharp,
            key,
            formation.electronic_key,
        )
    };
    // Metal besides beads at a pixel: some metal volume's path length there is positive.
    let metal_at = |i: u32, j: u32| {
        parts.iter().zip(&shadows).any(|(part, shadow)| {
            part.bead.is_none()
                && setup.is_metal(part.material)
                && shadow.as_ref().is_some_and(|pl| pl.at(i, j) > 0.0)
        })
    };
    let beads = parts
        .iter()
        .zip(&shadows)
        .filter_map(|(part, shadow)| {
            let bead = part.bead?;
            let (mut covered, mut over_metal) = (0usize, 0usize);
            if let Some(pl) = shadow {
                let cols = (pl.columns.end - pl.columns.start) as usize;
                for (k, &l) in pl.length_mm.iter().enumerate() {
                    if l > 0.0 {
                        covered += 1;
                        let (i, j) = (
                            pl.columns.start + (k % cols) as u32,
                            pl.rows.start + (k / cols) as u32,
                        );
                        if metal_at(i, j) {
                            over_metal += 1;
                        }
                    }
                }
            }
            let occluded = match &part.object {
                Object::Sphere { centre_mm, .. } => frame
                    .project(source_mm, *centre_mm)
                    .filter(|uv| frame.contains_pixel(*uv))
                    .is_some_and(|uv| metal_at(uv.x.floor() as u32, uv.y.floor() as u32)),
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
    let lengths_mm = keep_lengths.then(|| {
        (0..setup.materials.len())
            .map(|m| net_lengths(&layers, m, w, h))
            .collect()
    });
    Ok(AttenuationImage {
        pixels: rendered.pixels,
        saturated: rendered.saturated,
        beads,
        lengths_mm,
    })
}

/// Material `m`'s net path length on every pixel (W×H, row-major, mm): its layers summed, a
/// negative sum (rounding) set to 0: the lengths the response uses.
fn net_lengths(layers: &[Layer], m: usize, w: usize, h: usize) -> Vec<f64> {
    let mut image = vec![0.0; w * h];
    if w == 0 || !layers.iter().any(|l| l.material == m) {
        return image;
    }
    image.par_chunks_mut(w).enumerate().for_each(|(j, row)| {
        response::net_material_row(layers, m, j, row);
    });
    image
}

/// Fails when some pixel's net length of a material is below −[`NEST_TOLERANCE_MM`]: the solids
/// declared inside it cross more of it than it has there. Looks only at the rows of the negative
/// layers; reports the first such pixel by material, then row, then column.
/// The expected image of `exposure` as `sampling` says (one ray per pixel centre, adaptive or
/// full sampling), before the detector's noise.
fn expected_of(
    exposure: &Exposure,
    beam: &response::Beam,
    detector: &response::DetectorModel,
    sampling: &Sampling,
) -> response::Expected {
    if sampling.is_point() {
        super::sampled::expected_sharp(exposure, beam, detector).1
    } else if sampling.adaptive {
        super::sampled::expected_adaptive_of(exposure, beam, detector, sampling)
    } else {
        super::sampled::expected(exposure, beam, detector, sampling)
    }
}

fn check_nesting(setup: &Setup, parts: &[Part], layers: &[Layer], w: usize) -> Result<(), String> {
    for m in 0..setup.materials.len() {
        let Some(rows) = layers
            .iter()
            .filter(|l| l.material == m && l.sign < 0.0)
            .map(|l| l.rows.clone())
            .reduce(|a, b| a.start.min(b.start)..a.end.max(b.end))
        else {
            continue;
        };
        let found = rows.into_par_iter().find_map_first(|j| {
            let mut row = vec![0.0; w];
            let span = response::material_row(layers, m, j, &mut row);
            row[span.clone()]
                .iter()
                .position(|&l| l < -NEST_TOLERANCE_MM)
                .map(|k| (span.start + k, j, row[span.start + k]))
        });
        if let Some((i, j, l)) = found {
            let nested: Vec<&str> = parts
                .iter()
                .filter(|x| x.parent.is_some_and(|q| parts[q].material == m))
                .map(|x| x.label.as_str())
                .collect();
            return Err(format!(
                "at pixel ({i}, {j}) the ray crosses {:.4} mm more of the solids placed inside {} material than of the {} itself: {} not wholly inside the solid it is declared `inside`",
                -l,
                setup.names[m],
                setup.names[m],
                nested.join(", ")
            ));
        }
    }
    Ok(())
}

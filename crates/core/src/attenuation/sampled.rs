//! The expected image of one exposure with area sampling, a focal spot and the heel effect:
//! per sub-source and per strip of pixel rows, the exact path lengths of every part at the
//! pixel samples (`crate::sampling::strip`), their expected quanta, energy and open-field signal
//! (`crate::response::expected`, photons per *pixel* of the detector: each sample stands for its
//! whole pixel), averaged into the detector's pixels with the sub-source's weight and 1/s² per
//! sample (sub-sources in order, then samples row by row: a fixed order). The heel factor of
//! each pixel centre multiplies all three. What the detector does with it is
//! `crate::response::render_expected`.

use glam::DVec3;
use rayon::prelude::*;

use crate::geometry::DetectorFrame;
use crate::response::{
    self, Beam, DetectorModel, Expected, PixelMean, PointSourceFluence, RayMean, RayScratch,
};
use crate::sampling::strip::{STRIP_SAMPLES, add_blocks, strips, window};
use crate::sampling::{Sampling, adaptive};
use crate::trace::{Object, PathLengths, Projected};

use super::scene::{Exposure, Part};
use super::shadow::{layers_of, scene_of, shadows_of};

/// The expected image of `parts` on `frame` from the spot centred at `source_mm`, for the
/// detector's photons `beam` (per pixel of `frame`) and `detector`.
pub fn expected(
    exposure: &Exposure,
    beam: &Beam,
    detector: &DetectorModel,
    sampling: &Sampling,
) -> Expected {
    let Exposure {
        setup,
        parts,
        frame,
        source_mm,
    } = *exposure;
    let [w, h] = frame.pixels.map(|n| n as usize);
    let s = sampling.samples_per_side.max(1) as usize;
    let mut out = Expected {
        width: w,
        height: h,
        quanta: vec![0.0; w * h],
        energy_kev: vec![0.0; w * h],
        open_signal: vec![0.0; w * h],
    };
    let per_sample = 1.0 / (s * s) as f64;
    let strips = strips(frame, s as u32, STRIP_SAMPLES);
    for (src, weight) in sampling.sources(frame, source_mm) {
        for st in &strips {
            let shadows = shadows_of(parts, &st.frame, src);
            let layers = layers_of(parts, &shadows);
            let fluence = PointSourceFluence::new(&st.frame, src);
            let scene = scene_of(setup, &st.frame, &layers, &fluence);
            let fine = response::expected(beam, detector, &scene);
            let rows = st.first_row as usize * w..(st.first_row + st.rows) as usize * w;
            let k = weight * per_sample;
            add_blocks(&fine.quanta, w, s, k, &mut out.quanta[rows.clone()]);
            add_blocks(&fine.energy_kev, w, s, k, &mut out.energy_kev[rows.clone()]);
            add_blocks(&fine.open_signal, w, s, k, &mut out.open_signal[rows]);
        }
    }
    if let Some(heel) = &sampling.heel {
        let factor = heel.image(frame);
        for image in [&mut out.quanta, &mut out.energy_kev, &mut out.open_signal] {
            for (v, f) in image.iter_mut().zip(&factor) {
                *v *= f;
            }
        }
    }
    out
}

/// [`expected_adaptive`] from the parts alone: the sharp image first (one ray per pixel centre
/// from the spot's centre), then the refined pixels; what `super::render` does with the sharp
/// path lengths it already has.
pub fn expected_adaptive_of(
    exposure: &Exposure,
    beam: &Beam,
    detector: &DetectorModel,
    sampling: &Sampling,
) -> Expected {
    let (shadows, sharp) = expected_sharp(exposure, beam, detector);
    expected_adaptive(exposure, &shadows, beam, detector, sampling, sharp)
}

/// The sharp expected image (one ray per pixel centre from the spot's centre) of the parts, and
/// every part's path lengths on those rays (in part order).
pub fn expected_sharp(
    exposure: &Exposure,
    beam: &Beam,
    detector: &DetectorModel,
) -> (Vec<Option<PathLengths>>, Expected) {
    let Exposure {
        setup,
        parts,
        frame,
        source_mm,
    } = *exposure;
    let shadows = shadows_of(parts, frame, source_mm);
    let layers = layers_of(parts, &shadows);
    let fluence = PointSourceFluence::new(frame, source_mm);
    let scene = scene_of(setup, frame, &layers, &fluence);
    let sharp = response::expected(beam, detector, &scene);
    (shadows, sharp)
}

/// The same image by adaptive sampling (`crate::sampling::adaptive`): `sharp` is the expected
/// image of one ray per pixel centre from the spot's centre (`shadows`: every part's path
/// lengths on those rays, in part order). The pixels the refine mask marks get the mean over all
/// their rays, traced in tiles of [`adaptive::TILE_PX`] pixels (rays by sub-source in order,
/// then samples row by row) and summed over the spectrum by [`RayMean::pixel`]: a third-order
/// expansion about the rays' mean path lengths where its bound is within
/// [`adaptive::TOLERANCE_NOISE_SD`], else every ray's exact sum. Every other pixel keeps its
/// sharp value. The heel factor then multiplies all three images, as in [`expected`].
pub fn expected_adaptive(
    exposure: &Exposure,
    shadows: &[Option<PathLengths>],
    beam: &Beam,
    detector: &DetectorModel,
    sampling: &Sampling,
    sharp: Expected,
) -> Expected {
    let Exposure {
        parts,
        frame,
        source_mm,
        ..
    } = *exposure;
    let [w, h] = frame.pixels.map(|n| n as usize);
    let s = sampling.samples_per_side.max(1);
    let footprint = footprint(parts, frame, source_mm, sampling);
    let edges = edges(parts, shadows, frame, source_mm, w, h);
    let mask = adaptive::refine_mask(
        w,
        h,
        &edges,
        &sharp.quanta,
        &sharp.energy_kev,
        &footprint,
        adaptive::TOLERANCE_NOISE_SD,
    );
    let tiles = adaptive::tiles(&mask, w, h);
    let mut out = sharp;
    if !tiles.is_empty() {
        let fine = window(frame, 0, 0, w as u32, h as u32, s);
        let sources = sampling.sources(frame, source_mm);
        let cell = adaptive::TILE_PX * s;
        // Every part projected once per sub-source, all held: a tile takes all its rays at once.
        let projected: Vec<Vec<Projected>> = sources
            .iter()
            .map(|&(src, _)| {
                parts
                    .par_iter()
                    .map(|p| Projected::new(&fine, src, &p.object, cell))
                    .collect()
            })
            .collect();
        let seen: Vec<Seen> = sources
            .iter()
            .zip(&projected)
            .map(|(&(source_mm, weight), projected)| Seen {
                source_mm,
                weight,
                projected,
            })
            .collect();
        let rays = RayMean::new(beam, detector, &exposure.setup.mu_per_mm);
        let open = response::open_signal_per_fluence(detector, beam);
        let refined: Vec<Vec<(usize, PixelMean)>> = tiles
            .par_iter()
            .map_init(TileScratch::default, |scratch, &(i0, j0)| {
                let tile = Tile { i0, j0, s };
                refine_tile(exposure, &seen, &mask, tile, &rays, scratch)
            })
            .collect();
        for (p, mean) in refined.into_iter().flatten() {
            out.quanta[p] = mean.quanta;
            out.energy_kev[p] = mean.energy_kev;
            out.open_signal[p] = mean.weight * open;
        }
    }
    if let Some(heel) = &sampling.heel {
        let factor = heel.image(frame);
        for image in [&mut out.quanta, &mut out.energy_kev, &mut out.open_signal] {
            for (v, f) in image.iter_mut().zip(&factor) {
                *v *= f;
            }
        }
    }
    out
}

/// One sub-source: its position, its weight, and every part projected from it.
struct Seen<'a> {
    source_mm: DVec3,
    weight: f64,
    projected: &'a [Projected<'a>],
}

/// One tile of [`adaptive::TILE_PX`] pixels: its first pixel (`i0`, `j0`) and the samples per
/// side of a pixel `s`.
#[derive(Clone, Copy)]
struct Tile {
    i0: u32,
    j0: u32,
    s: u32,
}

/// Buffers of one worker, reused from tile to tile.
#[derive(Default)]
struct TileScratch {
    /// One sub-source's rays over the tile's samples: lengths `[sample][material]`, fluence.
    lengths: Vec<f64>,
    fluence: Vec<f64>,
    /// Every ray of every pixel of the tile: `[pixel][ray][material]` and `[pixel][ray]`, rays
    /// by sub-source, then sample row by row.
    pixel_lengths: Vec<f64>,
    pixel_weights: Vec<f64>,
    rays: RayScratch,
}

/// The mean over all rays of every pixel of `tile` that `mask` marks, as (pixel index in the
/// image, its [`PixelMean`]); rays by sub-source in order, then samples row by row. Only marked
/// pixels are traced.
fn refine_tile(
    exposure: &Exposure,
    seen: &[Seen],
    mask: &[bool],
    tile: Tile,
    rays: &RayMean,
    scratch: &mut TileScratch,
) -> Vec<(usize, PixelMean)> {
    let Exposure {
        setup,
        parts,
        frame,
        ..
    } = *exposure;
    let Tile { i0, j0, s } = tile;
    let [w, h] = frame.pixels;
    let t = adaptive::TILE_PX;
    let (tw, th) = (t.min(w - i0), t.min(h - j0));
    let (columns, rows) = (i0 * s..(i0 + tw) * s, j0 * s..(j0 + th) * s);
    let wanted = |fi: u32, fj: u32| mask[(fj / s) as usize * w as usize + (fi / s) as usize];
    let m_all = rays.materials();
    let (s, tw_u, th_u) = (s as usize, tw as usize, th as usize);
    let per_pixel = s * s * seen.len();
    let pixels = tw_u * th_u;
    let TileScratch {
        lengths,
        fluence,
        pixel_lengths,
        pixel_weights,
        rays: ray_scratch,
    } = scratch;
    // Every slot is written below (each sample of each sub-source once): no clearing needed.
    pixel_lengths.resize(pixels * per_pixel * m_all, 0.0);
    pixel_weights.resize(pixels * per_pixel, 0.0);
    let tile_frame = window(frame, i0, j0, tw, th, s as u32);
    for (k, one) in seen.iter().enumerate() {
        // The parts' lengths over the tile's samples, in the tile's own pixel coordinates.
        let shadows: Vec<Option<PathLengths>> = one
            .projected
            .iter()
            .map(|p| {
                p.window(columns.clone(), rows.clone(), &wanted)
                    .map(|pl| PathLengths {
                        columns: 0..tw * s as u32,
                        rows: 0..th * s as u32,
                        length_mm: pl.length_mm,
                    })
            })
            .collect();
        let layers = layers_of(parts, &shadows);
        let point = PointSourceFluence::new(&tile_frame, one.source_mm);
        let scene = scene_of(setup, &tile_frame, &layers, &point);
        response::rays_of(&scene, lengths, fluence);
        let share = one.weight / (s * s) as f64;
        let fw = tw_u * s;
        for (q, &f) in fluence.iter().enumerate() {
            let (fi, fj) = (q % fw, q / fw);
            let pixel = (fj / s) * tw_u + fi / s;
            let ray = k * s * s + (fj % s) * s + fi % s;
            let r = pixel * per_pixel + ray;
            pixel_weights[r] = share * f;
            pixel_lengths[r * m_all..(r + 1) * m_all]
                .copy_from_slice(&lengths[q * m_all..(q + 1) * m_all]);
        }
    }
    let mut out = Vec::new();
    for pixel in 0..pixels {
        let (i, j) = (i0 as usize + pixel % tw_u, j0 as usize + pixel / tw_u);
        let p = j * w as usize + i;
        if !mask[p] {
            continue;
        }
        let mean = rays.pixel(
            &pixel_lengths[pixel * per_pixel * m_all..(pixel + 1) * per_pixel * m_all],
            &pixel_weights[pixel * per_pixel..(pixel + 1) * per_pixel],
            adaptive::TOLERANCE_NOISE_SD,
            ray_scratch,
        );
        out.push((p, mean));
    }
    out
}

/// The footprint of the rays of a pixel ([`adaptive::Footprint`]) for the parts' depths: the
/// largest `(D − z)/z` over the corners of every part's bounding box, z the corner's distance
/// from the spot's plane and D the detector's.
fn footprint(
    parts: &[Part],
    frame: &DetectorFrame,
    source_mm: DVec3,
    sampling: &Sampling,
) -> adaptive::Footprint {
    let d = frame.pose.to_local(source_mm).z;
    let ratio = parts
        .iter()
        .flat_map(|p| p.object.bounding_corners_mm())
        .map(|c| {
            let height = frame.pose.to_local(c).z;
            // A corner at or behind the spot's plane: no bound from it but the detector's size.
            if height >= d {
                f64::INFINITY
            } else {
                height / (d - height)
            }
        })
        .fold(0.0, f64::max)
        .min(MAX_DEPTH_RATIO);
    let offsets: Vec<[f64; 2]> = sampling.sub_sources.iter().map(|s| s.offset_mm).collect();
    let weights: Vec<f64> = sampling.sub_sources.iter().map(|s| s.weight).collect();
    adaptive::Footprint::new(
        sampling.samples_per_side,
        &offsets,
        &weights,
        frame.pixel_pitch_mm,
        ratio,
    )
}

/// The largest depth ratio the footprint takes: a part reaching the spot's plane would blur
/// over the whole detector; beyond this every pixel near an edge is refined far out anyway.
const MAX_DEPTH_RATIO: f64 = 1e3;

/// The pixels (W×H) where some part's shadow starts or ends on the rays to the pixel centres
/// (both sides of the boundary), and every pixel within a bead's projected radius plus one pixel
/// of its projected centre: a bead may be too small for the pixel centres to see.
fn edges(
    parts: &[Part],
    shadows: &[Option<PathLengths>],
    frame: &DetectorFrame,
    source_mm: DVec3,
    w: usize,
    h: usize,
) -> Vec<bool> {
    let mut edges = vec![false; w * h];
    for (part, shadow) in parts.iter().zip(shadows) {
        if let Object::Sphere {
            centre_mm,
            radius_mm,
        } = &part.object
        {
            let rim = *centre_mm + frame.pose.rotation.x_axis * *radius_mm;
            if let (Some(c), Some(r)) = (
                frame.project(source_mm, *centre_mm),
                frame.project(source_mm, rim),
            ) {
                let reach = (r - c).length() + 1.0;
                let (lo, hi) = (c - reach, c + reach);
                let clip = |v: f64, n: usize| v.floor().clamp(0.0, n as f64) as usize;
                for j in clip(lo.y, h)..clip(hi.y + 1.0, h) {
                    edges[j * w + clip(lo.x, w)..j * w + clip(hi.x + 1.0, w)].fill(true);
                }
            }
            continue;
        }
        let Some(pl) = shadow else { continue };
        let inside = |i: i64, j: i64| {
            i >= 0 && j >= 0 && i < w as i64 && j < h as i64 && pl.at(i as u32, j as u32) > 0.0
        };
        for j in pl.rows.clone() {
            for i in pl.columns.clone() {
                let (i, j) = (i64::from(i), i64::from(j));
                if !inside(i, j) {
                    continue;
                }
                for (di, dj) in [(-1, 0), (1, 0), (0, -1), (0, 1)] {
                    let (ni, nj) = (i + di, j + dj);
                    if !inside(ni, nj) {
                        edges[j as usize * w + i as usize] = true;
                        if ni >= 0 && nj >= 0 && ni < w as i64 && nj < h as i64 {
                            edges[nj as usize * w + ni as usize] = true;
                        }
                    }
                }
            }
        }
    }
    edges
}

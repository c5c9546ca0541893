//! Model-based RSA (Kaptein et al. 2003): a model's pose from its outlines in the calibrated
//! views, without beads.
//!
//! Two stages, both over all views at once:
//!
//! 1. **Coarse search**, from the nominal pose. The views are rendered at a quarter of their
//!    resolution. The translation comes from the shadows' centroids: each view's observed and
//!    predicted centroids are back-projected and triangulated, and the pose moves by the
//!    difference (three times). The rotation comes from a search about the three world axes
//!    through the model's centre: first every combination of −12°, −6°, 0, 6° and 12° about each
//!    axis (124 candidates), then steps of 3° and 1.5° about one axis at a time, scored by the
//!    area of disagreement between observed and predicted shadows once their centroids are
//!    aligned. A start 10° and 10 mm off lands within a few pixels.
//!    The best twelve grid poses, each polished by the finer steps, are the starts of stage 2,
//!    tried in order until a fit is good ([`GOOD_FIT_PX`], [`MIN_OUTLINE_AGREEMENT`]; the best
//!    fit is kept otherwise): the disagreement score alone picked a wrong local minimum in 2 of
//!    100 biplanar runs, and on a blurred attenuation image (`biplanar_realistic_blurred`, ×0.25)
//!    the best four all led to the same wrong minimum 7° off.
//!
//!    A fit is good when its mean edge distance is small *and* the outline it projects agrees
//!    with the shadow found in the images ([`outline_agreement`]). On graded images each fit is
//!    refined on edge points measured along its own outline, so its mean distance judges it by
//!    points it chose itself: a pose 6° off can pair the half of its outline that meets some
//!    edge and look as good as the truth by that measure alone (run n2-r19 of
//!    `biplanar_realistic_blurred` at ×0.5 did, and was kept 2.4 mm and 6.2° off).
//! 2. **Refinement**: an iterative closest point fit of the model's projected outer outline
//!    ([`OutlineModel::outline`]) to the detected edge points ([`super::contour`]) in every view.
//!    Each detected point is paired with the nearest outline segment within a search radius that
//!    shrinks from 12 to 2.5 pixels; the point-to-segment-line distances, Huber-weighted at a
//!    threshold that shrinks with the radius to [`HUBER_PX`] (a quarter of a pixel), are
//!    minimised by Gauss–Newton over the six pose parameters (a rotation about the model's
//!    centre and a translation), with analytic derivatives of the central projection.
//!
//! The fit residual is the mean distance in pixels between the detected edge points and the
//! projected outline, over the points paired at the end: about a quarter of a pixel for an exact
//! model, since binary pixels put each edge point up to half a pixel from the true edge.

use glam::{DMat3, DVec2, DVec3};
use nalgebra::{SMatrix, SVector};

use super::contour::Outline;
use super::model_outline::{OutlineModel, OutlineSegment};
use crate::geometry::{DetectorFrame, Pose};
use crate::trace::{Object, render_binary};

/// Coarse rendering: one coarse pixel per `COARSE × COARSE` pixels.
const COARSE: u32 = 4;
/// Coarse rotation steps, degrees.
const ROTATION_STEPS_DEG: [f64; 3] = [6.0, 3.0, 1.5];
/// Search radius of the first refinement pairing, pixels.
const FIRST_RADIUS_PX: f64 = 12.0;
/// Final search radius, pixels.
const LAST_RADIUS_PX: f64 = 2.5;
/// Huber threshold of the refinement at its last search radius, pixels; while the radius
/// shrinks from [`FIRST_RADIUS_PX`], the threshold shrinks with it (from 1.2 px), so a start a
/// few pixels off in one view still pulls that view in (run n0-r15 of the blurred scenario lost
/// its lateral view, 0.9 mm off, at a fixed 0.25 px). On graded images each round re-measures
/// its edge points along the outline it has fitted, and whether a normal gives a clean step
/// depends on where that outline lies: a pose turned slightly about the axis perpendicular to
/// both beams admitted points that, at a final threshold of 1 px, held the fit there, up to 0.2°
/// off (issue 32, item 5; docs/src/results/biases.md). Those points lie a few tenths of a pixel
/// off the outline, so at 0.25 px their pull is capped near that of a well-fitting point.
pub const HUBER_PX: f64 = 0.25;
/// Refinement iterations at most.
const MAX_ITERATIONS: usize = 60;
/// Starts the refinement tries at most: the best poses of the coarse grid, in order, until one
/// gives a good fit ([`GOOD_FIT_PX`]).
const STARTS: usize = 12;
/// A fit whose mean edge distance is at most this (pixels) is taken without trying the other
/// starts; binary pixels alone give about 0.25 px, a wrong local minimum well over 0.5 px.
pub const GOOD_FIT_PX: f64 = 0.35;
/// A fit is taken without trying the other starts only if at least this share of the edge
/// points found by segmenting the images (pose-independent, [`SilhouetteView::outline`]) lies
/// within [`LAST_RADIUS_PX`] of its projected outline in every view
/// ([`least_view_agreement`]); among the fits tried, one that is close ([`GOOD_FIT_PX`]) with
/// this share over all views ([`outline_agreement`]) beats one that is not. On
/// `biplanar_realistic_blurred` the right minima had 0.82–1.0 over all views and the wrong ones
/// 0.50–0.62 (binary images: about 1), so a share below this marks a fit that found only part
/// of the model's outline.
pub const MIN_OUTLINE_AGREEMENT: f64 = 0.75;

/// The share of the views' segmented edge points ([`SilhouetteView::outline`], found without
/// the model) that lie within [`LAST_RADIUS_PX`] of the model's projected outline at `pose`:
/// a check of a fit that does not depend on the points it was refined on.
pub fn outline_agreement(model: &OutlineModel, views: &[SilhouetteView], pose: &Pose) -> f64 {
    share_over_views(&view_agreements(model, views, pose))
}

/// [`outline_agreement`] in the view where it is least. A fit that lost one view's outline (its
/// pose a millimetre off across that view) can still pair most points of all views together
/// (run n0-r15 of the blurred scenario: 84 % of them at 0.2 px, 0.9 mm off), so only a fit that
/// agrees in every view ends the search early. It is no ranking: a right fit can agree less in
/// one view whose segmented outline holds edges of the bone (runs n2-r08 and n3-r10: 59 % and
/// 69 % in one view at 0.07 to 0.09 px, beside wrong minima agreeing more at 0.4 px).
pub fn least_view_agreement(model: &OutlineModel, views: &[SilhouetteView], pose: &Pose) -> f64 {
    least_share(&view_agreements(model, views, pose))
}

/// The share of all views' points near the outline, from [`view_agreements`]' counts.
fn share_over_views(counts: &[(usize, usize)]) -> f64 {
    let near: usize = counts.iter().map(|c| c.0).sum();
    let points: usize = counts.iter().map(|c| c.1).sum();
    near as f64 / points.max(1) as f64
}

/// The least view's share of its points near the outline, from [`view_agreements`]' counts.
fn least_share(counts: &[(usize, usize)]) -> f64 {
    counts
        .iter()
        .map(|&(near, points)| near as f64 / points.max(1) as f64)
        .fold(1.0, f64::min)
}

/// Per view, its segmented edge points within [`LAST_RADIUS_PX`] of the outline at `pose`, and
/// all of them.
fn view_agreements(
    model: &OutlineModel,
    views: &[SilhouetteView],
    pose: &Pose,
) -> Vec<(usize, usize)> {
    views
        .iter()
        .map(|view| {
            let segments = model.outline(pose, view.source_mm, &view.frame);
            let grid = SegmentGrid::new(&segments, 4.0);
            let near = (view.outline.edge_points.iter())
                .filter(|&&e| grid.nearest(e, LAST_RADIUS_PX).is_some())
                .count();
            (near, view.outline.edge_points.len())
        })
        .collect()
}

/// One calibrated view of the model: the beamline and the outline detected in its image.
pub struct SilhouetteView<'a> {
    /// The calibrated detector frame.
    pub frame: DetectorFrame,
    /// The calibrated source position, mm.
    pub source_mm: DVec3,
    /// The model's detected shadow and edge points.
    pub outline: &'a Outline,
}

/// The result of a model-based fit.
#[derive(Debug, Clone, PartialEq)]
pub struct SilhouetteFit {
    /// The model's pose (local → box frame).
    pub pose: Pose,
    /// Mean distance between the detected edge points and the projected outline, pixels.
    pub mean_distance_px: f64,
    /// Edge points paired with the outline in the last iteration (all views).
    pub points_used: usize,
    /// Refinement iterations.
    pub iterations: usize,
}

/// Measures view `k`'s edge points again near the outline (its segments) of the model at a
/// pose: for graded images, `super::edge::edge_points_along_outline`.
pub type Remeasure<'r> = &'r dyn Fn(usize, &Pose, &[OutlineSegment]) -> Vec<DVec2>;

/// Rounds of edge points measured again along the fitted outline ([`Remeasure`]), each followed
/// by a refinement.
pub const REMEASURE_ROUNDS: usize = 2;

/// Finds the model's pose from its outlines, starting at `start` (the nominal pose). With
/// `remeasure`, every start's refined fit is refined again on edge points measured along its
/// outline ([`REMEASURE_ROUNDS`] times) before it is judged.
pub fn fit_silhouette(
    model: &OutlineModel,
    views: &[SilhouetteView],
    start: Pose,
    remeasure: Option<Remeasure>,
) -> Result<SilhouetteFit, String> {
    if views.len() < 2 {
        return Err(format!(
            "model-based RSA needs the model in at least two calibrated views, got {}",
            views.len()
        ));
    }
    let coarse = CoarseSearch::new(model, views)?;
    // The best fit so far, with whether it is good (close, and agreeing with the segmented
    // outline over all views): a good fit beats any that is not, then the smaller mean distance
    // wins.
    let mut best: Option<(bool, SilhouetteFit)> = None;
    for (score, pose) in coarse.grid(start) {
        let refined = refine(model, views, coarse.polish(pose, score));
        let refined = match (refined, remeasure) {
            (Ok(fit), Some(r)) => refine_remeasured(model, views, fit, r, REMEASURE_ROUNDS),
            (other, _) => other,
        };
        let fit = match refined {
            Ok(fit) => fit,
            Err(e) if best.is_none() => return Err(e),
            Err(_) => continue,
        };
        // Both checks from one projection of the outline per view, and only for a close fit.
        let (good, done) = if fit.mean_distance_px <= GOOD_FIT_PX {
            let counts = view_agreements(model, views, &fit.pose);
            (
                share_over_views(&counts) >= MIN_OUTLINE_AGREEMENT,
                least_share(&counts) >= MIN_OUTLINE_AGREEMENT,
            )
        } else {
            (false, false)
        };
        if best.as_ref().is_none_or(|(b_good, b)| {
            (good, -fit.mean_distance_px) > (*b_good, -b.mean_distance_px)
        }) {
            best = Some((good, fit));
        }
        if done {
            break;
        }
    }
    best.map(|(_, fit)| fit)
        .ok_or_else(|| "no start converged".into())
}

/// A view at coarse resolution: the frame and the observed shadow sampled on its pixel centres.
struct CoarseView<'a> {
    view: &'a SilhouetteView<'a>,
    frame: DetectorFrame,
    observed: Vec<bool>,
    observed_area: usize,
}

impl<'a> CoarseView<'a> {
    fn new(view: &'a SilhouetteView<'a>) -> CoarseView<'a> {
        let [w, h] = view.frame.pixels;
        let [cw, ch] = [w.div_ceil(COARSE), h.div_ceil(COARSE)];
        let frame = DetectorFrame {
            pixels: [cw, ch],
            pixel_pitch_mm: view.frame.pixel_pitch_mm.map(|p| p * f64::from(COARSE)),
            ..view.frame
        };
        let mut observed = vec![false; (cw * ch) as usize];
        for j in 0..ch {
            for i in 0..cw {
                let uv = to_full(
                    &frame,
                    &view.frame,
                    DVec2::new(i as f64 + 0.5, j as f64 + 0.5),
                );
                observed[(j * cw + i) as usize] = view
                    .outline
                    .covered(uv.x.floor() as i64, uv.y.floor() as i64);
            }
        }
        let observed_area = observed.iter().filter(|&&c| c).count();
        CoarseView {
            view,
            frame,
            observed,
            observed_area,
        }
    }

    /// The predicted shadow at `pose`: covered coarse pixels and their centroid (full-resolution
    /// pixel coordinates).
    fn predict(&self, model: &OutlineModel, pose: Pose) -> (Vec<(u32, u32)>, Option<DVec2>) {
        // Filled from the contour generator, as `render_binary` renders it (`model_shadow`);
        // rendered where a contour vertex does not project.
        let covered = model
            .shadow_pixels(&pose, self.view.source_mm, &self.frame)
            .unwrap_or_else(|| {
                let image = render_binary(
                    &self.frame,
                    self.view.source_mm,
                    &[Object::Mesh {
                        bvh: model.bvh(),
                        pose,
                    }],
                    1,
                );
                let w = self.frame.pixels[0];
                (image.iter().enumerate())
                    .filter(|(_, v)| **v != 0)
                    .map(|(k, _)| (k as u32 % w, k as u32 / w))
                    .collect()
            });
        let centroid = (!covered.is_empty()).then(|| {
            let sum = covered.iter().fold(DVec2::ZERO, |a, &(i, j)| {
                a + DVec2::new(i as f64 + 0.5, j as f64 + 0.5)
            });
            to_full(&self.frame, &self.view.frame, sum / covered.len() as f64)
        });
        (covered, centroid)
    }

    /// Area of disagreement between the observed shadow and the predicted one moved so that the
    /// centroids coincide, as a fraction of the observed area.
    fn disagreement(&self, model: &OutlineModel, pose: Pose) -> f64 {
        let (covered, centroid) = self.predict(model, pose);
        let Some(centroid) = centroid else {
            return 1.0;
        };
        let shift = (self.view.outline.centroid - centroid) / f64::from(COARSE);
        let (di, dj) = (shift.x.round() as i64, shift.y.round() as i64);
        let [cw, ch] = self.frame.pixels.map(i64::from);
        let both = covered
            .iter()
            .filter(|&&(i, j)| {
                let (x, y) = (i as i64 + di, j as i64 + dj);
                x >= 0 && y >= 0 && x < cw && y < ch && self.observed[(y * cw + x) as usize]
            })
            .count();
        (self.observed_area + covered.len() - 2 * both) as f64 / self.observed_area.max(1) as f64
    }
}

/// Full-resolution pixel coordinates of coarse pixel coordinates `uv` (same detector plane).
fn to_full(coarse: &DetectorFrame, full: &DetectorFrame, uv: DVec2) -> DVec2 {
    full.local_to_pixel(coarse.pixel_local(uv.x, uv.y))
}

/// The point closest, in the least-squares sense, to the rays from each source through its
/// detector point `uv`; `None` when the rays are (nearly) parallel.
fn triangulate(rays: &[(&DetectorFrame, DVec3, DVec2)]) -> Option<DVec3> {
    let mut a = DMat3::ZERO;
    let mut b = DVec3::ZERO;
    for &(frame, source, uv) in rays {
        let d = (frame.pose.to_world(frame.pixel_local(uv.x, uv.y)) - source).normalize();
        let m = DMat3::IDENTITY - DMat3::from_cols(d * d.x, d * d.y, d * d.z);
        a += m;
        b += m * source;
    }
    (a.determinant().abs() > 1e-9).then(|| a.inverse() * b)
}

/// Moves `pose` so that the triangulated centroids of the predicted shadows meet those of the
/// observed ones.
fn align_centroids(model: &OutlineModel, views: &[CoarseView], mut pose: Pose) -> Pose {
    let observed: Vec<_> = views
        .iter()
        .map(|v| (&v.view.frame, v.view.source_mm, v.view.outline.centroid))
        .collect();
    let Some(target) = triangulate(&observed) else {
        return pose;
    };
    for _ in 0..3 {
        let predicted: Option<Vec<_>> = views
            .iter()
            .map(|v| {
                v.predict(model, pose)
                    .1
                    .map(|c| (&v.view.frame, v.view.source_mm, c))
            })
            .collect();
        let Some(now) = predicted.as_deref().and_then(triangulate) else {
            return pose;
        };
        pose.position_mm += target - now;
    }
    pose
}

/// `pose` turned by `angle_rad` about the world `axis` through the model's centre.
fn turned(model: &OutlineModel, pose: Pose, axis: DVec3, angle_rad: f64) -> Pose {
    let centre = pose.to_world(model.centre_mm);
    let r = DMat3::from_axis_angle(axis, angle_rad);
    Pose {
        position_mm: r * (pose.position_mm - centre) + centre,
        rotation: r * pose.rotation,
    }
}

/// Stage 1 over every view (module docs).
struct CoarseSearch<'a> {
    model: &'a OutlineModel,
    views: Vec<CoarseView<'a>>,
}

impl<'a> CoarseSearch<'a> {
    fn new(model: &'a OutlineModel, views: &'a [SilhouetteView<'a>]) -> Result<Self, String> {
        let views: Vec<CoarseView> = views.iter().map(CoarseView::new).collect();
        if views.iter().any(|c| c.observed_area == 0) {
            return Err("the model's shadow is too small to fit at coarse resolution".into());
        }
        Ok(CoarseSearch { model, views })
    }

    fn score(&self, pose: Pose) -> f64 {
        self.views
            .iter()
            .map(|c| c.disagreement(self.model, pose))
            .sum()
    }

    /// Centroid alignment from `start`, then every combination of up to two first-round steps
    /// about each axis: the best [`STARTS`] poses with their scores, best first.
    fn grid(&self, start: Pose) -> Vec<(f64, Pose)> {
        let around = align_centroids(self.model, &self.views, start);
        let first = ROTATION_STEPS_DEG[0].to_radians();
        let mut grid = Vec::with_capacity(125);
        for mx in -2..=2 {
            for my in -2..=2 {
                for mz in -2..=2 {
                    let mut candidate = around;
                    for (axis, m) in [(DVec3::X, mx), (DVec3::Y, my), (DVec3::Z, mz)] {
                        candidate = turned(self.model, candidate, axis, f64::from(m) * first);
                    }
                    grid.push((self.score(candidate), candidate));
                }
            }
        }
        grid.sort_by(|a, b| a.0.total_cmp(&b.0));
        grid.truncate(STARTS);
        grid
    }

    /// Steps of the later rounds about one axis at a time while the score improves, then
    /// centroid alignment.
    fn polish(&self, mut pose: Pose, mut best: f64) -> Pose {
        for step_deg in &ROTATION_STEPS_DEG[1..] {
            for _pass in 0..2 {
                let mut improved = false;
                for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
                    for m in [-1.0, 1.0] {
                        let candidate = turned(self.model, pose, axis, (m * step_deg).to_radians());
                        let s = self.score(candidate);
                        if s < best {
                            best = s;
                            pose = candidate;
                            improved = true;
                        }
                    }
                }
                if !improved {
                    break;
                }
            }
        }
        align_centroids(self.model, &self.views, pose)
    }
}

/// Outline segments binned on a square grid for nearest-segment queries.
struct SegmentGrid<'s> {
    segments: &'s [OutlineSegment],
    origin: DVec2,
    cell_px: f64,
    columns: usize,
    rows: usize,
    cells: Vec<Vec<u32>>,
}

impl<'s> SegmentGrid<'s> {
    fn new(segments: &'s [OutlineSegment], cell_px: f64) -> SegmentGrid<'s> {
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for s in segments {
            for p in s.uv {
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        if segments.is_empty() {
            (lo, hi) = (DVec2::ZERO, DVec2::ZERO);
        }
        let columns = ((hi.x - lo.x) / cell_px) as usize + 1;
        let rows = ((hi.y - lo.y) / cell_px) as usize + 1;
        let mut grid = SegmentGrid {
            segments,
            origin: lo,
            cell_px,
            columns,
            rows,
            cells: vec![Vec::new(); columns * rows],
        };
        for (k, s) in segments.iter().enumerate() {
            let (a, b) = (
                grid.cell(s.uv[0].min(s.uv[1])),
                grid.cell(s.uv[0].max(s.uv[1])),
            );
            for j in a.1..=b.1 {
                for i in a.0..=b.0 {
                    grid.cells[j * columns + i].push(k as u32);
                }
            }
        }
        grid
    }

    fn cell(&self, p: DVec2) -> (usize, usize) {
        let c = ((p - self.origin) / self.cell_px).floor();
        (
            (c.x.max(0.0) as usize).min(self.columns - 1),
            (c.y.max(0.0) as usize).min(self.rows - 1),
        )
    }

    /// The nearest segment to `p` within `radius_px`: its index and the closest point's
    /// parameter along it (0 at `uv[0]`, 1 at `uv[1]`).
    fn nearest(&self, p: DVec2, radius_px: f64) -> Option<(usize, f64, f64)> {
        let reach = DVec2::splat(radius_px);
        let lo = ((p - reach - self.origin) / self.cell_px).floor();
        let hi = ((p + reach - self.origin) / self.cell_px).floor();
        if hi.x < 0.0 || hi.y < 0.0 || lo.x >= self.columns as f64 || lo.y >= self.rows as f64 {
            return None;
        }
        let (i0, j0) = (lo.x.max(0.0) as usize, lo.y.max(0.0) as usize);
        let (i1, j1) = (
            (hi.x as usize).min(self.columns - 1),
            (hi.y as usize).min(self.rows - 1),
        );
        let mut best: Option<(usize, f64, f64)> = None;
        for j in j0..=j1 {
            for i in i0..=i1 {
                for &k in &self.cells[j * self.columns + i] {
                    let s = &self.segments[k as usize];
                    let d = s.uv[1] - s.uv[0];
                    let lambda = ((p - s.uv[0]).dot(d) / d.length_squared()).clamp(0.0, 1.0);
                    let dist = (s.uv[0] + d * lambda - p).length();
                    if dist <= radius_px && best.is_none_or(|b| dist < b.2) {
                        best = Some((k as usize, lambda, dist));
                    }
                }
            }
        }
        best
    }
}

/// `rounds` refinements from `fit`, each on edge points measured again along the outline at
/// the pose before it.
pub fn refine_remeasured(
    model: &OutlineModel,
    views: &[SilhouetteView],
    mut fit: SilhouetteFit,
    remeasure: Remeasure,
    rounds: usize,
) -> Result<SilhouetteFit, String> {
    for _ in 0..rounds {
        let outlines: Vec<Outline> = views
            .iter()
            .enumerate()
            .map(|(k, v)| Outline {
                edge_points: remeasure(
                    k,
                    &fit.pose,
                    &model.outline(&fit.pose, v.source_mm, &v.frame),
                ),
                ..v.outline.clone()
            })
            .collect();
        let again: Vec<SilhouetteView> = views
            .iter()
            .zip(&outlines)
            .map(|(v, outline)| SilhouetteView {
                frame: v.frame,
                source_mm: v.source_mm,
                outline,
            })
            .collect();
        fit = refine(model, &again, fit.pose)?;
    }
    Ok(fit)
}

/// Stage 2: iterative closest points with Gauss–Newton steps (module docs), from `pose`.
fn refine(
    model: &OutlineModel,
    views: &[SilhouetteView],
    mut pose: Pose,
) -> Result<SilhouetteFit, String> {
    let mut radius = FIRST_RADIUS_PX;
    let mut last = (0.0, 0);
    let mut iterations = 0;
    while iterations < MAX_ITERATIONS {
        iterations += 1;
        let centre = pose.to_world(model.centre_mm);
        let huber_px = HUBER_PX * radius / LAST_RADIUS_PX;
        let mut h = SMatrix::<f64, 6, 6>::zeros();
        let mut g = SVector::<f64, 6>::zeros();
        let (mut distance_sum, mut paired) = (0.0, 0usize);
        for view in views {
            let segments = model.outline(&pose, view.source_mm, &view.frame);
            let grid = SegmentGrid::new(&segments, 4.0);
            for &e in &view.outline.edge_points {
                let Some((k, lambda, dist)) = grid.nearest(e, radius) else {
                    continue;
                };
                let s = &segments[k];
                let along = (s.uv[1] - s.uv[0]).normalize();
                let normal = DVec2::new(-along.y, along.x);
                let q = s.uv[0] + (s.uv[1] - s.uv[0]) * lambda;
                let residual = normal.dot(q - e);
                let point = s.world_mm[0] + (s.world_mm[1] - s.world_mm[0]) * lambda;
                let Some([gu, gv]) = view.frame.project_gradient(view.source_mm, point) else {
                    continue;
                };
                let grad = gu * normal.x + gv * normal.y;
                let arm = point - centre;
                let rot = arm.cross(grad);
                let j = SVector::<f64, 6>::from([rot.x, rot.y, rot.z, grad.x, grad.y, grad.z]);
                let weight = if residual.abs() <= huber_px {
                    1.0
                } else {
                    huber_px / residual.abs()
                };
                h += j * j.transpose() * weight;
                g += j * (weight * residual);
                distance_sum += dist;
                paired += 1;
            }
        }
        if paired < 12 {
            return Err(format!(
                "only {paired} detected edge points lie near the model's projected outline"
            ));
        }
        last = (distance_sum / paired as f64, paired);
        let damping = 1e-9 * h.trace();
        for k in 0..6 {
            h[(k, k)] += damping;
        }
        let step = h
            .cholesky()
            .ok_or("the outline does not constrain the model's pose")?
            .solve(&(-g));
        let omega = DVec3::new(step[0], step[1], step[2]);
        let delta = DVec3::new(step[3], step[4], step[5]);
        if omega.length() > 0.0 {
            pose = turned(model, pose, omega.normalize(), omega.length());
        }
        pose.position_mm += delta;
        let settled = radius <= LAST_RADIUS_PX && delta.length() < 1e-5 && omega.length() < 1e-7;
        if settled {
            break;
        }
        radius = (radius * 0.7).max(LAST_RADIUS_PX);
    }
    Ok(SilhouetteFit {
        pose,
        mean_distance_px: last.0,
        points_used: last.1,
        iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contour::outline;
    use crate::geometry::{euler_xyz_deg, rotation_xyz_deg};

    /// The knee component, as the biplanar scenario places it.
    fn femur() -> OutlineModel {
        crate::model_outline::tests::femoral_component()
    }

    /// Two orthogonal beamlines (as in biplanar.toml, detectors cut to 600² pixels of 0.3 mm)
    /// and the model's shadow in each at `truth`.
    fn scene(model: &OutlineModel, truth: Pose) -> Vec<(DetectorFrame, DVec3, Outline)> {
        let beamlines = [
            (
                Pose::from_position_euler_deg([1.0, -2.0, -500.0], [0.5, -0.3, 0.2]),
                DVec3::new(3.0, -4.0, 1300.0),
            ),
            (
                Pose::from_position_euler_deg([-500.0, 2.0, 1.0], [0.2, 90.4, -0.5]),
                DVec3::new(1300.0, 5.0, -3.0),
            ),
        ];
        beamlines
            .into_iter()
            .map(|(pose, source)| {
                let frame = DetectorFrame {
                    pose,
                    pixels: [600, 600],
                    pixel_pitch_mm: [0.3, 0.3],
                };
                let image = render_binary(
                    &frame,
                    source,
                    &[Object::Mesh {
                        bvh: model.bvh(),
                        pose: truth,
                    }],
                    7,
                );
                (frame, source, outline(&image, 600, 7).unwrap())
            })
            .collect()
    }

    fn errors(found: &Pose, truth: &Pose) -> (f64, f64) {
        let position = (found.position_mm - truth.position_mm).abs().max_element();
        let angles = euler_xyz_deg(&(truth.rotation.transpose() * found.rotation));
        (
            position,
            angles.map(f64::abs).into_iter().fold(0.0, f64::max),
        )
    }

    #[test]
    fn converges_from_starts_ten_degrees_and_ten_millimetres_off() {
        let model = femur();
        let truth = Pose::from_position_euler_deg([2.0, -3.0, 1.5], [4.0, -6.0, 3.0]);
        let scene = scene(&model, truth);
        let views: Vec<SilhouetteView> = scene
            .iter()
            .map(|(frame, source, outline)| SilhouetteView {
                frame: *frame,
                source_mm: *source,
                outline,
            })
            .collect();
        for (dp, dr) in [
            ([10.0, -10.0, 10.0], [10.0, -10.0, 10.0]),
            ([-10.0, 8.0, -6.0], [-10.0, 10.0, -8.0]),
            ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0]),
        ] {
            let start = Pose {
                position_mm: truth.position_mm + DVec3::from_array(dp),
                rotation: truth.rotation * rotation_xyz_deg(dr),
            };
            let t0 = std::time::Instant::now();
            let fit = fit_silhouette(&model, &views, start, None).unwrap();
            let (dx, da) = errors(&fit.pose, &truth);
            eprintln!(
                "start off by {dp:?} mm, {dr:?}°: error {dx:.4} mm, {da:.4}°, residual {:.3} px over {} points, {} iterations, {:.2} s",
                fit.mean_distance_px,
                fit.points_used,
                fit.iterations,
                t0.elapsed().as_secs_f64()
            );
            assert!(dx < 0.05 && da < 0.05, "{dx} mm, {da}°");
            assert!(fit.mean_distance_px < 0.35, "{}", fit.mean_distance_px);
        }
    }
}

//! Scan conversion: the binary projection of meshes and beads computed row by row over the pixel
//! centres, instead of one traced ray per pixel. It produces the image of the ray tracer
//! ([`super::render_binary_traced`]) up to pixel centres that lie within rounding distance of a
//! projected silhouette edge (the tracer works in f32, this in f64).
//!
//! **Meshes.** A point source projects a mesh onto the detector as the union of its projected
//! triangles (a ray to a pixel centre crosses the mesh exactly when the pixel centre lies in the
//! projection of a triangle it crosses). Every vertex is moved once into the detector frame and
//! projected centrally to continuous pixel coordinates (u, v), with the centre of pixel (i, j) at
//! (i + 0.5, j + 0.5) (docs/src/reference/conventions.md, "Pixels"; [`DetectorFrame::project`]). Each triangle is then filled row by
//! row: for each row of its bounding box, each of its three edges bounds the row's span of pixel
//! centres on one side; the bound is found from the edge's crossing with the row and settled with
//! the edge function itself, so no pixel outside the span is tested (a triangle at most four
//! columns wide, the common sliver of a fine mesh, just tests those columns, without branches).
//! Cost: O(vertices + triangles + filled pixels).
//!
//! Edge functions are evaluated in f64 in a canonical form that depends only on the edge's two
//! endpoints, not on the triangle, so the two triangles that share an edge see exactly opposite
//! values at every pixel centre; a centre exactly on an edge (value zero) belongs to the triangle
//! on a fixed side of it (the top-left rule of rasterisers: the side a centre moved by an
//! infinitesimal step along +u, then +v, would fall on). So a pixel centre on a shared edge or
//! vertex is filled by exactly one of the triangles around it: no gap, no double count.
//!
//! Only the triangles that face the source are filled for a closed mesh; see [`Faces`].
//!
//! A mesh with a vertex at or behind the source's plane (parallel to the detector), or at or
//! beyond the detector plane, is not projected: the caller traces it instead (the segment from
//! the source to a pixel centre ends on the detector, and a projection through the source's plane
//! is not a triangle).
//!
//! **Beads.** The rays that pass within `r` of a sphere's centre form a cone, which meets a row of
//! pixel centres in one interval: the roots of a quadratic in u. Each row's candidates are that
//! interval widened by a pixel on each side (a bead at most 16 columns wide keeps all the columns
//! of its bounds); each candidate is then decided by the tracer's exact predicate
//! ([`super::sphere_blocks`]) over the tracer's pixel bounds, so bead pixels are the tracer's,
//! byte for byte.

use glam::{DVec2, DVec3};

use super::MeshBvh;
use crate::geometry::{DetectorFrame, Pose};

/// Which projected triangles of a mesh scan conversion fills.
///
/// For a closed, consistently wound mesh, the triangles that face the source are enough. The
/// source is outside the solid (every vertex lies strictly in front of the source's plane, so the
/// source is outside the convex hull). Follow a ray from the source to a pixel centre that crosses
/// the surface: at the first surface point along the ray, the ray passes from outside to inside,
/// so the outward normal of the triangle it enters through points back towards the source (where
/// the ray enters through an edge or a vertex, at least one of the triangles there does: if all
/// faced away, the ray would leave or graze the solid there, not enter). Hence every covered pixel
/// centre lies in the projection of a front face, and back faces only cover pixels that front faces
/// already cover (a grazing ray along a silhouette edge is the rounding case that the module docs
/// describe). Front faces are told by the sign of their projected area: central projection keeps
/// orientation for points in front of the source, and an outward triangle seen from outside
/// winds counter-clockwise, i.e. positive area in (u, v) (both pixel axes follow the detector's
/// right-handed r, c axes, with s towards the source).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Faces {
    /// Closed, wound counter-clockwise seen from outside: fill positive projected area only.
    Outward,
    /// Closed, wound clockwise seen from outside: fill negative projected area only.
    Inward,
    /// Not known to be closed: fill every triangle, whichever way it faces.
    All,
}

/// Projected coordinates beyond this many pixels (a vertex next to the source's plane) make the
/// caller trace the mesh instead, keeping every edge function well inside f64's exact range.
const MAX_PROJECTED_PX: f64 = 1e9;

/// Fills with `value` every pixel of `image` (row-major, `frame.pixels`) whose centre lies in the
/// shadow of `mesh` at `pose` seen from `source_mm`. Returns `false`, touching nothing, when the
/// mesh cannot be scan-converted (see the module docs); the caller then traces it.
pub(super) fn fill_mesh(
    image: &mut [u16],
    frame: &DetectorFrame,
    source_mm: DVec3,
    mesh: &MeshBvh,
    pose: Pose,
    value: u16,
) -> bool {
    let Some(uv_px) = project_vertices(frame, source_mm, &mesh.vertices_mm, pose) else {
        return false;
    };
    let [w, h] = frame.pixels;
    let width = w as usize;
    for t in &mesh.faces {
        let [a, b, c] = t.map(|k| uv_px[k as usize]);
        let area = (b - a).perp_dot(c - a);
        let (b, c) = match mesh.facing {
            Faces::Outward | Faces::All if area > 0.0 => (b, c),
            Faces::Inward | Faces::All if area < 0.0 => (c, b),
            _ => continue,
        };
        scan_triangle(w, h, a, b, c, |row, first, end| {
            image[row * width + first..row * width + end].fill(value);
        });
    }
    true
}

/// Continuous pixel coordinates (u, v) of every vertex (local frame, mm) of a mesh at `pose`,
/// projected from `source_mm`; `None` when a vertex is not strictly between the source's plane
/// and the detector plane, or projects absurdly far out.
pub(super) fn project_vertices(
    frame: &DetectorFrame,
    source_mm: DVec3,
    vertices_mm: &[DVec3],
    pose: Pose,
) -> Option<Vec<DVec2>> {
    // Local → detector frame in one step; the source in the detector frame.
    let to_detector = frame.pose.inverse().compose(&pose);
    let s = frame.pose.to_local(source_mm);
    if !s.z.is_finite() || s.z <= 0.0 {
        return None;
    }
    let [w, h] = frame.pixels;
    let [pitch_x_mm, pitch_y_mm] = frame.pixel_pitch_mm;
    let (half_w_px, half_h_px) = (w as f64 / 2.0, h as f64 / 2.0);
    vertices_mm
        .iter()
        .map(|&v| {
            let p = to_detector.to_world(v);
            if !(p.z > 0.0 && p.z < s.z) {
                return None;
            }
            // As DetectorFrame::project: the ray from s through p meets z = 0 at t = s.z / (s.z − p.z).
            let t = s.z / (s.z - p.z);
            let hit = s + (p - s) * t;
            let uv = DVec2::new(
                hit.x / pitch_x_mm + half_w_px,
                hit.y / pitch_y_mm + half_h_px,
            );
            (uv.x.abs() < MAX_PROJECTED_PX && uv.y.abs() < MAX_PROJECTED_PX).then_some(uv)
        })
        .collect()
}

/// One edge of a triangle, prepared for scan conversion.
///
/// Its edge function at a pixel centre (x, y) is `sign·((q.x − p.x)(y − p.y) − (q.y − p.y)(x − p.x))`,
/// computed from the canonical endpoints only, so the triangle across the edge gets the exact
/// negation. Along a row it is monotonic in x even in floating point (each operation rounds
/// monotonically), so the centres inside an edge on a row form one run.
struct Edge {
    /// The endpoint that comes first in the canonical order (by v, then u).
    p: DVec2,
    /// `q − p`, with q the other endpoint (so `dy ≥ 0`).
    d: DVec2,
    /// +1 when the triangle runs the edge p → q, −1 when q → p.
    sign: f64,
    /// Whether a pixel centre exactly on the edge belongs to this triangle.
    owns_ties: bool,
}

impl Edge {
    /// The edge `from → to` of a triangle wound counter-clockwise in (u, v) (positive area), so
    /// that the triangle's inside is where the edge function is positive.
    fn new(from: DVec2, to: DVec2) -> Edge {
        let forward = from.y < to.y || (from.y == to.y && from.x < to.x);
        let (p, q) = if forward { (from, to) } else { (to, from) };
        let d = q - p;
        Edge {
            p,
            d,
            sign: if forward { 1.0 } else { -1.0 },
            // A centre on the edge goes to the side that a step along +u (then +v) enters: the
            // gradient of the edge function, (from.y − to.y, to.x − from.x), points there.
            owns_ties: to.y < from.y || (to.y == from.y && to.x > from.x),
        }
    }

    /// The part of the edge function that is constant along the row of centres at `y_px`.
    fn row_term(&self, y_px: f64) -> f64 {
        self.d.x * (y_px - self.p.y)
    }

    /// Whether the centre of column `i` is inside this edge, on the row of `row_term`.
    fn inside(&self, row_term: f64, i: i64) -> bool {
        let e = self.sign * (row_term - self.d.y * ((i as f64 + 0.5) - self.p.x));
        (e > 0.0) | ((e == 0.0) & self.owns_ties)
    }

    /// Narrows the half-open run `[first, end)` of columns on a row of centres (given by its
    /// `row_term` from [`Edge::row_term`]) to the centres inside this edge; returns whether the
    /// run is still non-empty. The run's end is found by walking from the analytic crossing.
    fn clip_row(&self, row_term: f64, first: &mut i64, end: &mut i64) -> bool {
        if self.d.y == 0.0 {
            // A horizontal edge: the same answer for the whole row.
            return self.inside(row_term, *first);
        }
        // The first centre at or right of the crossing with the row, give or take one (the walk
        // below settles it): ⌈x − 0.5⌉ ≈ ⌊x + 0.5⌋, by a cast after clamping (NaN goes to 0).
        let crossing = self.p.x + row_term / self.d.y;
        let guess = (crossing + 0.5).clamp(*first as f64, *end as f64) as i64;
        if self.sign < 0.0 {
            // The edge function grows along the row: the inside run starts here.
            *first = first_true(*first, *end, guess, |i| self.inside(row_term, i));
        } else {
            *end = first_true(*first, *end, guess, |i| !self.inside(row_term, i));
        }
        *first < *end
    }
}

/// The first `i` in `[lo, hi)` with `f(i)` (or `hi`), for `f` false then true along the range,
/// walking from `guess`.
fn first_true(lo: i64, hi: i64, guess: i64, f: impl Fn(i64) -> bool) -> i64 {
    let mut i = guess.clamp(lo, hi);
    if i == hi || f(i) {
        while i > lo && f(i - 1) {
            i -= 1;
        }
    } else {
        while i < hi && !f(i) {
            i += 1;
        }
    }
    i
}

/// The half-open range of pixel indices whose centres `k + 0.5` lie in `[lo, hi]`, clipped to
/// `[0, n)`; `None` when empty. (Rounding `lo − 0.5` is monotonic, so a centre exactly at `lo`
/// or `hi` is kept.) Written with casts rather than `ceil`/`floor`, which are calls into the
/// math library on baseline x86-64 and the hottest part of a triangle's set-up.
pub(super) fn centre_range(lo: f64, hi: f64, n: u32) -> Option<(i64, i64)> {
    let (lo, hi) = (lo - 0.5, hi - 0.5);
    if !(hi >= 0.0 && lo < n as f64) {
        return None;
    }
    // Both now lie below n (or are clamped to 0 ≤ · ≤ n), so the casts are exact truncations
    // of non-negative numbers, i.e. floors.
    let lo = lo.max(0.0);
    let floor_lo = lo as i64;
    let first = floor_lo + i64::from((floor_lo as f64) < lo);
    let end = (hi.min(n as f64) as i64 + 1).min(n as i64);
    (first < end).then_some((first, end))
}

/// Triangles at most this many pixel columns wide are filled by testing each column of their
/// bounding box; wider ones by walking each edge's crossing with the row. Both use the same edge
/// functions, so they fill the same pixels; only the speed differs.
const NARROW_COLUMNS: i64 = 4;

/// Calls `span(row, first, end)` for every row of the `w × h` grid with the half-open run of
/// columns whose pixel centres lie inside the triangle `a, b, c` (continuous pixel coordinates,
/// counter-clockwise in (u, v): positive area).
pub(super) fn scan_triangle(
    w: u32,
    h: u32,
    a: DVec2,
    b: DVec2,
    c: DVec2,
    mut span: impl FnMut(usize, usize, usize),
) {
    let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
    let Some((j0, j1)) = centre_range(lo.y, hi.y, h) else {
        return;
    };
    let Some((i0, i1)) = centre_range(lo.x, hi.x, w) else {
        return;
    };
    let edges = [Edge::new(a, b), Edge::new(b, c), Edge::new(c, a)];
    for j in j0..j1 {
        let y_px = j as f64 + 0.5;
        let terms = edges.each_ref().map(|e| e.row_term(y_px));
        let (mut first, mut end) = (i0, i1);
        if i1 - i0 <= NARROW_COLUMNS {
            // A narrow triangle (most of a fine mesh): test its few columns at once, without
            // branches (the inside columns form one run: bits first..end of the mask).
            let mut mask = 0u32;
            for k in 0..NARROW_COLUMNS {
                let i = i0 + k;
                let inside = edges[0].inside(terms[0], i)
                    & edges[1].inside(terms[1], i)
                    & edges[2].inside(terms[2], i);
                mask |= u32::from(inside) << k;
            }
            mask &= (1u32 << (i1 - i0)) - 1;
            if mask != 0 {
                first = i0 + i64::from(mask.trailing_zeros());
                end = i0 + 32 - i64::from(mask.leading_zeros());
                span(j as usize, first as usize, end as usize);
            }
        } else if (0..3).all(|k| edges[k].clip_row(terms[k], &mut first, &mut end)) {
            span(j as usize, first as usize, end as usize);
        }
    }
}

/// Beads whose pixel bounds are at most this many columns wide are not bounded per row.
const NARROW_BEAD_COLUMNS: u32 = 16;

/// Fills with `value` every pixel of `image` in the column and row ranges `[i0, i1) × [j0, j1)`
/// whose ray from `source_mm` passes within `radius_mm` of `centre_mm`, deciding each candidate
/// with the tracer's predicate [`super::sphere_blocks`] (so the result is the tracer's over the
/// same ranges, bit for bit).
pub(super) fn fill_sphere(
    image: &mut [u16],
    frame: &DetectorFrame,
    source_mm: DVec3,
    centre_mm: DVec3,
    radius_mm: f64,
    (i0, i1, j0, j1): (u32, u32, u32, u32),
    value: u16,
) {
    let [w, h] = frame.pixels;
    let [pitch_x_mm, pitch_y_mm] = frame.pixel_pitch_mm;
    let rot = frame.pose.rotation;
    // The ray to the centre at u on row j runs along d(u) = d0 + u·step (mm); it passes within r
    // of the centre (w_mm from the source) when |w × d|² − r²|d|² ≤ 0, a quadratic a·u² + b·u + c.
    let w_mm = centre_mm - source_mm;
    let step_mm = rot.x_axis * pitch_x_mm;
    let r2 = radius_mm * radius_mm;
    let w_step = w_mm.cross(step_mm);
    let a = w_step.length_squared() - r2 * step_mm.length_squared();
    // A cone that meets the rows in bounded intervals, and is not so near the limit that the
    // coefficient `a` has lost its digits; otherwise every column of the range is a candidate.
    // So is every column of a narrow range (a small bead), where bounding costs more than it saves.
    let bounded = a > 1e-6 * w_step.length_squared() && i1 - i0 > NARROW_BEAD_COLUMNS;
    for j in j0..j1 {
        let (first, end) = if bounded {
            let row_mm = DVec3::new(
                -(w as f64) / 2.0 * pitch_x_mm,
                (j as f64 + 0.5 - h as f64 / 2.0) * pitch_y_mm,
                0.0,
            );
            let d0_mm = rot * row_mm + frame.pose.position_mm - source_mm;
            let w_d0 = w_mm.cross(d0_mm);
            let b = 2.0 * (w_step.dot(w_d0) - r2 * step_mm.dot(d0_mm));
            let c = w_d0.length_squared() - r2 * d0_mm.length_squared();
            let mid_px = -b / (2.0 * a);
            let disc = b * b - 4.0 * a * c;
            let half_px = if disc > 0.0 {
                disc.sqrt() / (2.0 * a)
            } else {
                0.0
            };
            // Centres u = i + 0.5 within a pixel of the roots [mid − half, mid + half].
            let first = ((mid_px - half_px) - 1.5).floor().max(i0 as f64);
            let end = (((mid_px + half_px) + 0.5).floor() + 1.0).min(i1 as f64);
            // (`max`/`min` have replaced a NaN bound by the range's own.)
            if first >= end {
                continue;
            }
            (first as u32, end as u32)
        } else {
            (i0, i1)
        };
        for i in first..end {
            if super::sphere_blocks(
                centre_mm,
                radius_mm,
                source_mm,
                frame.pixel_centre_world(i, j),
            ) {
                image[j as usize * w as usize + i as usize] = value;
            }
        }
    }
}

#[cfg(test)]
pub(super) mod tests;

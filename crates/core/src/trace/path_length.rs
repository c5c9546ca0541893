//! Exact path lengths: per pixel, the length (mm) of the segment from the source to the pixel
//! centre that lies inside one object (attenuation mode, docs/src/reference/conventions.md, "Image formation").
//!
//! **Analytic solids** (spheres, cuboids, elliptic cylinders): the line's interval inside the
//! solid (`shapes.rs`) clipped to the segment, for every pixel of the object's projected bounds.
//!
//! **Closed meshes** are scan-converted like binary mode (`raster.rs`), but front *and* back faces,
//! with depth. In the detector frame, with the source at `s` and the ray to the centre `p` of a
//! pixel running along `d = p − s`, the ray meets the plane `n·(x − A) = 0` of a triangle at
//! `τ = n·(A − s) / n·d` (one division per covered pixel: `n·d` is linear along the row). Every
//! covered pixel accumulates `Σ_back τ − Σ_front τ`; times `|d|` this is the length inside. Each
//! crossing is counted by exactly one triangle because the projected triangles are filled by the
//! same edge functions and tie rule as binary mode ([`super::raster`]'s `scan_triangle`), so the
//! pixels with a positive length are the pixels binary mode fills (up to pixel centres on a
//! silhouette, whose length is zero or a rounding residue, clamped at zero). Cost:
//! O(vertices + triangles + covered pixels).
//!
//! The source lies outside a mesh that projects (every vertex strictly between the source's plane
//! and the detector plane), and so does every pixel centre; so the signed sum is the length inside
//! for a closed, consistently wound mesh, nested shells included. A mesh that does not project,
//! and one that is not closed, is ray cast instead ([`path_lengths_traced`]).
//!
//! **The reference** ([`path_lengths_traced`]) casts the ray's whole line through the mesh in f64
//! (`crossings.rs`: BVH candidates, a watertight f64 line–triangle test with the same kind of tie
//! rule), sorts the crossings, and sums the inside intervals (by parity from the line's far end)
//! clipped to the segment. It needs no winding; for a mesh that is not closed its parity is
//! whatever the surface gives (attenuation mode refuses such meshes: [`MeshBvh::is_closed`]).

use std::ops::Range;

use glam::{DVec2, DVec3};
use rayon::prelude::*;

use super::raster::{self, centre_range, scan_triangle};
use super::{Chords, MeshBvh, Object, pixel_bounds, shapes};
use crate::geometry::{DetectorFrame, Pose};

/// Per-pixel path length of one object over a rectangle of pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct PathLengths {
    /// Columns of the rectangle (pixel column indices, half-open).
    pub columns: Range<u32>,
    /// Rows of the rectangle (pixel row indices, half-open).
    pub rows: Range<u32>,
    /// Length inside the object, mm, row-major over the rectangle; never negative.
    pub length_mm: Vec<f64>,
}

impl PathLengths {
    /// The path length (mm) at pixel (column `i`, row `j`); 0 outside the rectangle.
    pub fn at(&self, i: u32, j: u32) -> f64 {
        if !(self.columns.contains(&i) && self.rows.contains(&j)) {
            return 0.0;
        }
        let width = (self.columns.end - self.columns.start) as usize;
        let k = (j - self.rows.start) as usize * width + (i - self.columns.start) as usize;
        self.length_mm.get(k).copied().unwrap_or(0.0)
    }
}

/// Length (mm) of the segment from `source_mm` to each pixel centre that lies inside `object`.
/// `None` when the object's shadow misses the detector. Analytic solids by their chords, closed
/// meshes by scan conversion with depth; a mesh that cannot be projected (a vertex at or behind
/// the source's plane, or at or beyond the detector plane) or that is not closed by
/// [`path_lengths_traced`]. See the module docs.
pub fn path_lengths(
    frame: &DetectorFrame,
    source_mm: DVec3,
    object: &Object,
) -> Option<PathLengths> {
    if let Object::Mesh { bvh, pose } = object
        && bvh.is_closed()
        && let Some(uv_px) = raster::project_vertices(frame, source_mm, &bvh.vertices_mm, *pose)
    {
        return scan_mesh(frame, source_mm, bvh, *pose, &uv_px);
    }
    path_lengths_traced(frame, source_mm, object)
}

/// The same by ray casting in f64 with every hit along the ray (meshes: BVH for candidates, an
/// f64 line–triangle test; analytic solids: their chords), over the object's projected bounds:
/// the cross-check of [`path_lengths`], and its fallback for a mesh that cannot be projected.
pub fn path_lengths_traced(
    frame: &DetectorFrame,
    source_mm: DVec3,
    object: &Object,
) -> Option<PathLengths> {
    let (lo, hi) = object.local_bounds();
    let (i0, i1, j0, j1) = pixel_bounds(frame, source_mm, object.pose(), lo, hi)?;
    let width = (i1 - i0) as usize;
    let mut length_mm = vec![0.0; width * (j1 - j0) as usize];
    if width > 0 {
        // Rows in parallel: every pixel's value is its own, so the result does not depend on
        // the number of threads.
        let chords = object.chords_from(source_mm);
        length_mm
            .par_chunks_mut(width)
            .zip(j0..j1)
            .for_each_init(Vec::new, |targets, (row, j)| {
                targets.clear();
                targets.extend((i0..i1).map(|i| frame.pixel_centre_world(i, j)));
                lengths_to_targets_mm(object, chords.as_ref(), source_mm, targets, row);
            });
    }
    Some(PathLengths {
        columns: i0..i1,
        rows: j0..j1,
        length_mm,
    })
}

/// The lengths (mm) of the segments `source → target` inside `object` for each of `targets`, into
/// `out`: by an analytic solid's row kernels (`chords`, its `chords_from(source)`: bit for bit
/// its per-target chords), else by [`traced_length_mm`] per target.
pub(super) fn lengths_to_targets_mm(
    object: &Object,
    chords: Option<&Chords>,
    source: DVec3,
    targets: &[DVec3],
    out: &mut [f64],
) {
    match chords {
        Some(c) => c.lengths_mm(targets, out),
        None => {
            for (l, &target) in out.iter_mut().zip(targets) {
                *l = traced_length_mm(object, source, target);
            }
        }
    }
}

/// The length (mm) of the segment `source → target` inside `object`, by ray casting (meshes) or
/// the chord (analytic solids): one pixel of [`path_lengths_traced`].
pub(super) fn traced_length_mm(object: &Object, source: DVec3, target: DVec3) -> f64 {
    match object {
        Object::Mesh { bvh, pose } => traced_mesh_length_mm(bvh, *pose, source, target),
        _ => object.chord_mm(source, target).unwrap_or(0.0),
    }
}

/// The length of the segment `source → target` inside `mesh` at `pose`, from the sorted crossings
/// of its line: inside between the 1st and 2nd crossing, the 3rd and 4th, ….
fn traced_mesh_length_mm(mesh: &MeshBvh, pose: Pose, source: DVec3, target: DVec3) -> f64 {
    let d = pose.rotation.transpose() * (target - source);
    let ts = mesh.line_crossings(pose.to_local(source), d);
    ts.chunks_exact(2)
        .map(|pair| shapes::segment_length_mm((pair[0], pair[1]), d))
        .sum()
}

/// Scan conversion with depth of a closed mesh whose vertices project to `uv_px` (see the module
/// docs). `None` when no pixel centre lies in the projection's bounding box.
fn scan_mesh(
    frame: &DetectorFrame,
    source_mm: DVec3,
    mesh: &MeshBvh,
    pose: Pose,
    uv_px: &[DVec2],
) -> Option<PathLengths> {
    let [w, h] = frame.pixels;
    let lo = uv_px.iter().fold(DVec2::INFINITY, |m, &p| m.min(p));
    let hi = uv_px.iter().fold(DVec2::NEG_INFINITY, |m, &p| m.max(p));
    // Every triangle's bounding box lies in this one, so `scan_triangle` (which clips by the same
    // `centre_range`) only visits pixels of the rectangle.
    let (i0, i1) = centre_range(lo.x, hi.x, w)?;
    let (j0, j1) = centre_range(lo.y, hi.y, h)?;
    let depth = MeshDepth::new(frame, source_mm, mesh, pose, uv_px);
    let (columns, rows) = (i0 as usize..i1 as usize, j0 as usize..j1 as usize);
    let length_mm = depth.lengths(
        mesh.faces.iter(),
        DVec2::ZERO,
        [w, h],
        columns.clone(),
        rows.clone(),
    );
    Some(PathLengths {
        columns: columns.start as u32..columns.end as u32,
        rows: rows.start as u32..rows.end as u32,
        length_mm,
    })
}

/// A closed mesh in a detector's frame, its vertices projected: what scan conversion with depth
/// needs, for the whole frame ([`scan_mesh`]) or for windows of it (`super::window`).
pub(super) struct MeshDepth<'a> {
    frame: &'a DetectorFrame,
    mesh: &'a MeshBvh,
    /// The source in the detector frame.
    s: DVec3,
    /// The vertices in the detector frame.
    vertices: std::borrow::Cow<'a, [DVec3]>,
    /// The vertices' continuous pixel coordinates.
    uv_px: &'a [DVec2],
}

impl<'a> MeshDepth<'a> {
    /// The mesh at `pose` seen from `source_mm` on `frame`, its vertices projected to `uv_px`
    /// ([`raster::project_vertices`]).
    pub(super) fn new(
        frame: &'a DetectorFrame,
        source_mm: DVec3,
        mesh: &'a MeshBvh,
        pose: Pose,
        uv_px: &'a [DVec2],
    ) -> Self {
        let to_detector = frame.pose.inverse().compose(&pose);
        MeshDepth {
            frame,
            mesh,
            s: frame.pose.to_local(source_mm),
            vertices: mesh
                .vertices_mm
                .iter()
                .map(|&v| to_detector.to_world(v))
                .collect::<Vec<_>>()
                .into(),
            uv_px,
        }
    }

    /// The vertices in the detector frame (mm), for [`MeshDepth::with_vertices`].
    pub(super) fn into_vertices(self) -> Vec<DVec3> {
        self.vertices.into_owned()
    }

    /// The same mesh again, its vertices already in the detector frame (from
    /// [`MeshDepth::into_vertices`] of the same frame, source and pose).
    pub(super) fn with_vertices(
        frame: &'a DetectorFrame,
        source_mm: DVec3,
        mesh: &'a MeshBvh,
        vertices: &'a [DVec3],
        uv_px: &'a [DVec2],
    ) -> Self {
        MeshDepth {
            frame,
            mesh,
            s: frame.pose.to_local(source_mm),
            vertices: vertices.into(),
            uv_px,
        }
    }

    /// The path lengths (mm, row-major) of the frame's pixels `columns × rows` through `faces`:
    /// per pixel `Σ_back τ − Σ_front τ` times the ray's length, clamped at 0 (see the module
    /// docs). The faces are scan-converted on a grid of `grid` pixels whose pixel (0, 0) is the
    /// frame's pixel `offset` (the vertices' coordinates are shifted by it), and only rows and
    /// columns of the rectangle (in grid coordinates: shifted by `offset` too) are visited.
    pub(super) fn lengths<'f>(
        &self,
        faces: impl Iterator<Item = &'f [u32; 3]>,
        offset: DVec2,
        grid: [u32; 2],
        columns: Range<usize>,
        rows: Range<usize>,
    ) -> Vec<f64> {
        let (ox, oy) = (offset.x as usize, offset.y as usize);
        let s = self.s;
        // The ray offsets d = p − s of the pixel centres per column (x) and row (y); d.z = −s.z.
        let dx: Vec<f64> = columns
            .clone()
            .map(|i| self.frame.pixel_local((i + ox) as f64 + 0.5, 0.0).x - s.x)
            .collect();
        let dy: Vec<f64> = rows
            .clone()
            .map(|j| self.frame.pixel_local(0.0, (j + oy) as f64 + 0.5).y - s.y)
            .collect();
        let (i0, j0, width) = (columns.start, rows.start, columns.len());
        let outward = self.mesh.facing == raster::Faces::Outward;
        // Σ_back τ − Σ_front τ per pixel of the rectangle.
        let mut depth = vec![0.0f64; width * dy.len()];
        for face in faces {
            let [a, b, c] = face.map(|k| self.uv_px[k as usize] - offset);
            let area = (b - a).perp_dot(c - a);
            if area == 0.0 {
                continue;
            }
            // Front faces (facing the source) are entries: positive projected area when the mesh
            // is wound outward (raster.rs, `Faces`).
            let weight = if (area > 0.0) == outward { -1.0 } else { 1.0 };
            let (b, c) = if area > 0.0 { (b, c) } else { (c, b) };
            let [pa, pb, pc] = face.map(|k| self.vertices[k as usize]);
            let n = (pb - pa).cross(pc - pa);
            let numerator = weight * n.dot(pa - s);
            scan_triangle(grid[0], grid[1], a, b, c, |row, first, end| {
                if !rows.contains(&row) {
                    return;
                }
                let (first, end) = (first.max(i0), end.min(columns.end));
                if first >= end {
                    return;
                }
                let r = row - j0;
                let row_term = n.y * dy[r] - n.z * s.z;
                let line = &mut depth[r * width..(r + 1) * width];
                for (acc, &x) in line[first - i0..end - i0]
                    .iter_mut()
                    .zip(&dx[first - i0..end - i0])
                {
                    *acc += numerator / (n.x * x + row_term);
                }
            });
        }
        for (r, line) in depth.chunks_exact_mut(width.max(1)).enumerate() {
            let yz = dy[r] * dy[r] + s.z * s.z;
            for (acc, &x) in line.iter_mut().zip(&dx) {
                if *acc != 0.0 {
                    *acc = (*acc * (x * x + yz).sqrt()).max(0.0);
                }
            }
        }
        depth
    }
}

#[cfg(test)]
mod tests;

//! Path lengths over many small windows of one frame: each object is projected onto the frame
//! once ([`Projected::new`]), then a window of pixels costs only what lies in it
//! ([`Projected::window`]). This is what adaptive sampling needs: the few pixels near edges get
//! all their rays, traced as small windows of a fine frame, thousands per image.
//!
//! * **Closed meshes** that project: the vertices are projected once, and every face is filed
//!   under each square cell of `cell_px` pixels its bounding box touches. A window scan-converts
//!   only the faces filed under its cells, each face once (under the first of its cells, in
//!   row-major order, that the window covers), with the same depth accumulation as the whole frame (`path_length::MeshDepth`), on
//!   the window's own grid (the vertices' coordinates shifted by the window's corner, an exact
//!   shift by whole pixels). The values equal the whole-frame scan's up to rounding.
//! * **Everything else** (analytic solids, meshes that are traced): the exact length of each
//!   wanted pixel of the window, as [`super::path_lengths_traced`] computes it.
//!
//! A window only computes the pixels its caller wants: the others are 0.

use std::ops::Range;

use glam::{DVec2, DVec3};

use super::path_length::{MeshDepth, lengths_to_targets_mm};
use super::raster::{self, centre_range};
use super::{MeshBvh, Object, PathLengths, pixel_bounds};
use crate::geometry::DetectorFrame;

/// One object projected onto one frame from one source, ready for windows of that frame.
pub struct Projected<'a> {
    frame: &'a DetectorFrame,
    source_mm: DVec3,
    object: &'a Object<'a>,
    /// The pixel rectangle `[i0, i1) × [j0, j1)` of the object's shadow; `None` when it misses.
    bounds: Option<(u32, u32, u32, u32)>,
    /// The scan conversion of a closed mesh that projects.
    mesh: Option<FiledMesh>,
}

/// A projected mesh's faces filed by square cells of pixels.
struct FiledMesh {
    /// The vertices' continuous pixel coordinates.
    uv_px: Vec<DVec2>,
    /// The vertices in the detector frame, mm.
    vertices: Vec<DVec3>,
    /// Pixels per side of a cell.
    cell_px: u32,
    /// Cells per row and per column of the frame.
    cells_per_row: u32,
    cells_per_column: u32,
    /// Per cell (row-major), the faces whose bounding box touches it (indices into the mesh's
    /// faces).
    cells: Vec<Vec<u32>>,
    /// Per face, the first cell (column, row) it is filed under.
    first_cell: Vec<[u32; 2]>,
}

impl<'a> Projected<'a> {
    /// `object` seen from `source_mm` on `frame`; a mesh's faces filed by cells of `cell_px` ×
    /// `cell_px` pixels (≥ 1: the size of the windows to come makes a good cell).
    pub fn new(
        frame: &'a DetectorFrame,
        source_mm: DVec3,
        object: &'a Object<'a>,
        cell_px: u32,
    ) -> Projected<'a> {
        let cell_px = cell_px.max(1);
        let [w, h] = frame.pixels;
        let mut mesh = None;
        let mut bounds = None;
        if let Object::Mesh { bvh, pose } = object
            && bvh.is_closed()
            && let Some(uv_px) = raster::project_vertices(frame, source_mm, &bvh.vertices_mm, *pose)
        {
            let lo = uv_px.iter().fold(DVec2::INFINITY, |m, &p| m.min(p));
            let hi = uv_px.iter().fold(DVec2::NEG_INFINITY, |m, &p| m.max(p));
            if let (Some((i0, i1)), Some((j0, j1))) =
                (centre_range(lo.x, hi.x, w), centre_range(lo.y, hi.y, h))
            {
                bounds = Some((i0 as u32, i1 as u32, j0 as u32, j1 as u32));
                let mut filed = file_faces(bvh, &uv_px, [w, h], cell_px);
                filed.vertices =
                    MeshDepth::new(frame, source_mm, bvh, *pose, &uv_px).into_vertices();
                filed.uv_px = uv_px;
                mesh = Some(filed);
            }
            return Projected {
                frame,
                source_mm,
                object,
                bounds,
                mesh,
            };
        }
        let (lo, hi) = object.local_bounds();
        bounds = pixel_bounds(frame, source_mm, object.pose(), lo, hi);
        Projected {
            frame,
            source_mm,
            object,
            bounds,
            mesh,
        }
    }

    /// The object's path lengths over the frame's pixels `columns × rows`, computed where
    /// `wanted(i, j)` (frame pixel indices) holds and 0 elsewhere; `None` when the object's
    /// shadow misses the window. The rectangle of the result is the window itself.
    pub fn window(
        &self,
        columns: Range<u32>,
        rows: Range<u32>,
        wanted: &(dyn Fn(u32, u32) -> bool + Sync),
    ) -> Option<PathLengths> {
        let (i0, i1, j0, j1) = self.bounds?;
        if columns.end <= i0 || columns.start >= i1 || rows.end <= j0 || rows.start >= j1 {
            return None;
        }
        let width = (columns.end - columns.start) as usize;
        let height = (rows.end - rows.start) as usize;
        let length_mm = match &self.mesh {
            Some(filed) => {
                let Object::Mesh { bvh, .. } = self.object else {
                    return None;
                };
                let mut lengths = self.mesh_window(filed, bvh, &columns, &rows);
                for (k, l) in lengths.iter_mut().enumerate() {
                    let (i, j) = (
                        columns.start + (k % width) as u32,
                        rows.start + (k / width) as u32,
                    );
                    if *l != 0.0 && !wanted(i, j) {
                        *l = 0.0;
                    }
                }
                lengths
            }
            None => {
                // The wanted pixels' centres, then their lengths in one call: an analytic
                // solid's row kernels (bit for bit its per-pixel chords) or the tracer.
                let mut at = Vec::new();
                let mut targets = Vec::new();
                for j in rows.start.max(j0)..rows.end.min(j1) {
                    for i in columns.start.max(i0)..columns.end.min(i1) {
                        if wanted(i, j) {
                            at.push(
                                (j - rows.start) as usize * width + (i - columns.start) as usize,
                            );
                            targets.push(self.frame.pixel_centre_world(i, j));
                        }
                    }
                }
                let mut found = vec![0.0; targets.len()];
                let chords = self.object.chords_from(self.source_mm);
                lengths_to_targets_mm(
                    self.object,
                    chords.as_ref(),
                    self.source_mm,
                    &targets,
                    &mut found,
                );
                let mut lengths = vec![0.0; width * height];
                for (&k, &l) in at.iter().zip(&found) {
                    lengths[k] = l;
                }
                lengths
            }
        };
        length_mm.iter().any(|&l| l != 0.0).then_some(PathLengths {
            columns,
            rows,
            length_mm,
        })
    }

    /// A filed mesh's lengths over a window (see the module docs).
    fn mesh_window(
        &self,
        filed: &FiledMesh,
        bvh: &MeshBvh,
        columns: &Range<u32>,
        rows: &Range<u32>,
    ) -> Vec<f64> {
        let depth = MeshDepth::with_vertices(
            self.frame,
            self.source_mm,
            bvh,
            &filed.vertices,
            &filed.uv_px,
        );
        let n = filed.cell_px;
        let (cx0, cy0) = (columns.start / n, rows.start / n);
        let cx1 = ((columns.end - 1) / n).min(filed.cells_per_row - 1);
        let cy1 = ((rows.end - 1) / n).min(filed.cells_per_column - 1);
        // Each face once: in the window's first cell (row-major) that it is filed under.
        let faces = (cy0..=cy1)
            .flat_map(|cy| (cx0..=cx1).map(move |cx| (cx, cy)))
            .flat_map(|(cx, cy)| {
                filed.cells[(cy * filed.cells_per_row + cx) as usize]
                    .iter()
                    .filter(move |&&f| {
                        let [fx, fy] = filed.first_cell[f as usize];
                        fx.max(cx0) == cx && fy.max(cy0) == cy
                    })
                    .map(|&f| &bvh.faces[f as usize])
            });
        let (w, h) = (columns.end - columns.start, rows.end - rows.start);
        depth.lengths(
            faces,
            DVec2::new(columns.start as f64, rows.start as f64),
            [w, h],
            0..w as usize,
            0..h as usize,
        )
    }
}

/// Files every face of `bvh` (vertices at `uv_px`) under the cells of `cell_px` × `cell_px`
/// pixels of a `frame_px` frame that its bounding box's pixel centres touch.
fn file_faces(bvh: &MeshBvh, uv_px: &[DVec2], frame_px: [u32; 2], cell_px: u32) -> FiledMesh {
    let [w, h] = frame_px;
    let (per_row, per_column) = (w.div_ceil(cell_px).max(1), h.div_ceil(cell_px).max(1));
    let mut cells = vec![Vec::new(); (per_row * per_column) as usize];
    let mut first_cell = vec![[u32::MAX; 2]; bvh.faces.len()];
    for (f, face) in bvh.faces.iter().enumerate() {
        let [a, b, c] = face.map(|k| uv_px[k as usize]);
        let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
        let (Some((i0, i1)), Some((j0, j1))) =
            (centre_range(lo.x, hi.x, w), centre_range(lo.y, hi.y, h))
        else {
            continue;
        };
        let (x0, x1) = (i0 as u32 / cell_px, (i1 as u32 - 1) / cell_px);
        let (y0, y1) = (j0 as u32 / cell_px, (j1 as u32 - 1) / cell_px);
        first_cell[f] = [x0, y0];
        for y in y0..=y1 {
            for x in x0..=x1 {
                cells[(y * per_row + x) as usize].push(f as u32);
            }
        }
    }
    FiledMesh {
        uv_px: Vec::new(),
        vertices: Vec::new(),
        cell_px,
        cells_per_row: per_row,
        cells_per_column: per_column,
        cells,
        first_cell,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Pose;
    use crate::phantom::mesh::TriMesh;
    use crate::trace::path_lengths;

    /// A frame of `w × h` pixels of pitch 0.5 mm at z = −400, facing +z.
    fn frame(w: u32, h: u32) -> DetectorFrame {
        DetectorFrame {
            pose: Pose::from_position_euler_deg([1.0, -2.0, -400.0], [3.0, -2.0, 10.0]),
            pixels: [w, h],
            pixel_pitch_mm: [0.5, 0.5],
        }
    }

    /// Every window of a tiling equals the whole frame's path lengths (to rounding for a mesh,
    /// bit for bit for a sphere, a cuboid and a cylinder); unwanted pixels are 0.
    #[test]
    fn tiled_windows_equal_the_whole_frame() {
        let mesh = TriMesh::uv_sphere(30.0, 24, 16);
        let bvh = MeshBvh::new(&mesh);
        let pose = Pose::from_position_euler_deg([5.0, 3.0, 20.0], [10.0, 20.0, 30.0]);
        let objects = [
            Object::Mesh { bvh: &bvh, pose },
            Object::Sphere {
                centre_mm: DVec3::new(-20.0, 10.0, 0.0),
                radius_mm: 6.0,
            },
            Object::Cuboid {
                pose: Pose::from_position_euler_deg([10.0, -15.0, -10.0], [5.0, 0.0, 20.0]),
                half_size_mm: DVec3::new(20.0, 10.0, 4.0),
            },
            Object::EllipticCylinder {
                pose: Pose::from_position_euler_deg([0.0, 0.0, 0.0], [90.0, 0.0, 0.0]),
                radii_mm: [40.0, 30.0],
                half_length_mm: 60.0,
            },
        ];
        let f = frame(160, 150);
        let source = DVec3::new(3.0, 1.0, 900.0);
        let wanted = |i: u32, j: u32| (i * 7 + j * 3) % 5 != 0;
        for object in &objects {
            let whole = path_lengths(&f, source, object).expect("in the beam");
            let projected = Projected::new(&f, source, object, 16);
            for tj in (0..150).step_by(16) {
                for ti in (0..160).step_by(24) {
                    let (cols, rows) = (ti..(ti + 24).min(160), tj..(tj + 16).min(150));
                    let win = projected.window(cols.clone(), rows.clone(), &wanted);
                    for j in rows.clone() {
                        for i in cols.clone() {
                            let got = win.as_ref().map_or(0.0, |w| w.at(i, j));
                            let want = if wanted(i, j) { whole.at(i, j) } else { 0.0 };
                            assert!(
                                (got - want).abs() < 1e-9,
                                "pixel ({i}, {j}): window {got}, whole frame {want}"
                            );
                            // An analytic solid's window is the same chords, bit for bit.
                            if !matches!(object, Object::Mesh { .. }) {
                                assert_eq!(got.to_bits(), want.to_bits(), "pixel ({i}, {j})");
                            }
                        }
                    }
                }
            }
        }
    }

    /// A window spanning several cells counts each face once.
    #[test]
    fn tall_windows_count_each_face_once() {
        let mesh = TriMesh::uv_sphere(30.0, 24, 16);
        let bvh = MeshBvh::new(&mesh);
        let object = Object::Mesh {
            bvh: &bvh,
            pose: Pose::from_position_euler_deg([0.0, 0.0, 0.0], [0.0, 0.0, 0.0]),
        };
        let f = frame(140, 140);
        let source = DVec3::new(0.0, 0.0, 900.0);
        let whole = path_lengths(&f, source, &object).expect("in the beam");
        let projected = Projected::new(&f, source, &object, 8);
        let win = projected
            .window(30..110, 5..135, &|_, _| true)
            .expect("in the beam");
        for j in 5..135 {
            for i in 30..110 {
                assert!((win.at(i, j) - whole.at(i, j)).abs() < 1e-9, "({i}, {j})");
            }
        }
    }
}

//! The shadow of a model's closed mesh on a detector's pixel centres, filled from its contour
//! generator: what `rsasim_core::trace::render_binary` gives for the mesh alone, at a fraction
//! of the cost for a fine mesh on coarse pixels (the silhouette fit's coarse search renders the
//! model some hundred times per view, and the femoral component has 87 000 faces, most smaller
//! than a coarse pixel).
//!
//! Every face that faces the source covers its projection once, and the shadow is where at
//! least one does. The faces that face the source form regions whose boundary is the contour
//! generator: the edges between a face that faces the source and one that does not. Each
//! such edge, run as the facing face runs it, is part of the regions' boundary, all with the
//! same turning sense once projected (the projection keeps the orientation of every facing
//! face alike), so the winding number of the projected contour edges about a point counts the
//! facing faces over it: the shadow is where it is not zero. Rows are filled from the edges'
//! crossings with each row of pixel centres. A pixel centre exactly on a projected edge may be
//! decided otherwise than by `render_binary`'s tie rule; elsewhere the two agree (tested on
//! the shipped femoral component).

use glam::DVec3;

use super::model_outline::OutlineModel;
use crate::geometry::{DetectorFrame, Pose};

impl OutlineModel {
    /// The pixels (column, row), row by row, whose centres the model's shadow at `pose` covers,
    /// seen from `source_mm` on `frame` (module docs). `None` when a vertex of the contour
    /// generator does not project onto the detector's plane (at or behind the source's plane,
    /// or beyond the detector's).
    pub fn shadow_pixels(
        &self,
        pose: &Pose,
        source_mm: DVec3,
        frame: &DetectorFrame,
    ) -> Option<Vec<(u32, u32)>> {
        let source_local = pose.rotation.transpose() * (source_mm - pose.position_mm);
        let facing = self.facing(source_local);
        let project = frame.projector(source_mm, pose);
        let [w, h] = frame.pixels;
        // (row, x, ±1) for every crossing of a contour edge with a row of pixel centres: the
        // rows j whose centre y = j + ½ lies in [min y, max y) of the edge.
        let mut crossings: Vec<(u32, f64, i32)> = Vec::new();
        for e in self.contour(&facing) {
            let (from, to) = if e.runs_forward(&facing) {
                (e.a, e.b)
            } else {
                (e.b, e.a)
            };
            let p = project(self.vertices[from as usize])?;
            let q = project(self.vertices[to as usize])?;
            if p.y == q.y {
                continue;
            }
            let (lo, hi) = (p.y.min(q.y), p.y.max(q.y));
            let first = (lo - 0.5).ceil().max(0.0);
            let end = (hi - 0.5).ceil().min(f64::from(h));
            let direction = if q.y > p.y { 1 } else { -1 };
            let slope = (q.x - p.x) / (q.y - p.y);
            let mut j = first;
            while j < end {
                crossings.push((j as u32, p.x + (j + 0.5 - p.y) * slope, direction));
                j += 1.0;
            }
        }
        crossings.sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
        // Along each row, the pixels whose centres x = i + ½ lie in [x_k, x_k+1) take the
        // winding number of the crossings up to k.
        let mut covered = Vec::new();
        for row in crossings.chunk_by(|a, b| a.0 == b.0) {
            let mut winding = 0;
            for pair in row.windows(2) {
                winding += pair[0].2;
                if winding == 0 {
                    continue;
                }
                let first = (pair[0].1 - 0.5).ceil().max(0.0);
                let end = (pair[1].1 - 0.5).ceil().min(f64::from(w));
                let mut i = first;
                while i < end {
                    covered.push((i as u32, row[0].0));
                    i += 1.0;
                }
            }
        }
        Some(covered)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model_outline::tests::{femoral_component, turned};
    use crate::trace::{Object, render_binary};

    #[test]
    fn the_shadow_from_the_contour_is_the_rendered_shadow() {
        // The shipped femoral component (87 000 faces; folds, a box and pegs) in 40 poses,
        // seen on a quarter-resolution and a full-resolution detector: every pixel as
        // `render_binary` (front faces scan-converted, tested against a ray tracer) gives it.
        let model = femoral_component();
        let source = DVec3::new(3.0, -5.0, 1300.0);
        let mut pixels_seen = 0;
        for k in 0..40 {
            let pose = turned(k);
            let f = f64::from(k);
            for (pixels, pitch) in [(360, 1.2), (1440, 0.3)] {
                let frame = DetectorFrame {
                    pose: Pose {
                        position_mm: DVec3::new(1.0, -2.0, -500.0),
                        rotation: crate::geometry::rotation_xyz_deg([1.0, -2.0, 0.5 * f]),
                    },
                    pixels: [pixels, pixels],
                    pixel_pitch_mm: [pitch, pitch],
                };
                let image = render_binary(
                    &frame,
                    source,
                    &[Object::Mesh {
                        bvh: model.bvh(),
                        pose,
                    }],
                    1,
                );
                let rendered: Vec<(u32, u32)> = (image.iter().enumerate())
                    .filter(|(_, v)| **v != 0)
                    .map(|(i, _)| (i as u32 % pixels, i as u32 / pixels))
                    .collect();
                let filled = model.shadow_pixels(&pose, source, &frame).unwrap();
                assert_eq!(filled, rendered, "pose {k}, {pixels} px");
                pixels_seen += rendered.len();
            }
        }
        assert!(pixels_seen > 1_000_000, "{pixels_seen}");
    }
}

//! The tracing stage: rays from a point source to every pixel centre of a detector, tested
//! against the phantoms of one exposure. The paper's binary mode: a pixel whose ray crosses any
//! object gets I_max, every other pixel 0.
//!
//! Only pixels inside an object's projected bounds are traced: each object's bounding box is
//! projected onto the detector (the projection of a convex hull is the convex hull of the
//! projections, so the corners' pixel rectangle bounds the object's shadow).

mod mesh_bvh;
mod watertight;

pub use mesh_bvh::MeshBvh;

use glam::DVec3;

use crate::geometry::{DetectorFrame, Pose};

/// An object in the beam, placed in the world (box) frame.
pub enum Object<'a> {
    /// An exact sphere (a bead).
    Sphere {
        /// Centre, mm.
        centre_mm: DVec3,
        /// Radius, mm.
        radius_mm: f64,
    },
    /// A closed mesh at a pose.
    Mesh {
        /// The mesh in its local frame.
        bvh: &'a MeshBvh,
        /// Local → world.
        pose: Pose,
    },
}

/// A binary projection image, row-major, `W × H` detector counts.
pub fn render_binary(
    frame: &DetectorFrame,
    source_mm: DVec3,
    objects: &[Object],
    i_max: u16,
) -> Vec<u16> {
    let [w, h] = frame.pixels;
    let mut image = vec![0u16; w as usize * h as usize];
    for object in objects {
        let (lo, hi) = object.local_bounds();
        let Some((i0, i1, j0, j1)) = pixel_bounds(frame, source_mm, object.pose(), lo, hi) else {
            continue;
        };
        for j in j0..j1 {
            for i in i0..i1 {
                let px = &mut image[j as usize * w as usize + i as usize];
                if *px == 0 && object.blocks(source_mm, frame.pixel_centre_world(i, j)) {
                    *px = i_max;
                }
            }
        }
    }
    image
}

impl Object<'_> {
    fn pose(&self) -> Pose {
        match self {
            Object::Sphere { centre_mm, .. } => Pose {
                position_mm: *centre_mm,
                rotation: glam::DMat3::IDENTITY,
            },
            Object::Mesh { pose, .. } => *pose,
        }
    }

    fn local_bounds(&self) -> (DVec3, DVec3) {
        match self {
            Object::Sphere { radius_mm, .. } => {
                (DVec3::splat(-radius_mm), DVec3::splat(*radius_mm))
            }
            Object::Mesh { bvh, .. } => bvh.bounds_mm,
        }
    }

    /// Whether the segment from the source to `target` crosses the object.
    fn blocks(&self, source: DVec3, target: DVec3) -> bool {
        match self {
            Object::Sphere {
                centre_mm,
                radius_mm,
            } => {
                let d = target - source;
                let w = *centre_mm - source;
                // Distance from the centre to the ray's line, via the cross product (no cancellation).
                w.cross(d).length_squared() <= radius_mm * radius_mm * d.length_squared()
            }
            Object::Mesh { bvh, pose } => bvh.segment_hits(
                pose.to_local(source),
                pose.rotation.transpose() * (target - source),
            ),
        }
    }
}

/// The half-open pixel rectangle `[i0, i1) × [j0, j1)` that contains the projection of the local
/// box `lo..hi` at `pose`, clipped to the detector; `None` when it is empty. Falls back to the
/// whole detector if a corner does not project (it would then be at or behind the source).
fn pixel_bounds(
    frame: &DetectorFrame,
    source: DVec3,
    pose: Pose,
    lo: DVec3,
    hi: DVec3,
) -> Option<(u32, u32, u32, u32)> {
    let [w, h] = frame.pixels;
    let (mut umin, mut vmin, mut umax, mut vmax) = (
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    );
    for k in 0..8 {
        let corner = DVec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        );
        let Some(uv) = frame.project(source, pose.to_world(corner)) else {
            return Some((0, w, 0, h));
        };
        umin = umin.min(uv.x);
        vmin = vmin.min(uv.y);
        umax = umax.max(uv.x);
        vmax = vmax.max(uv.y);
    }
    // Pixel i's centre is at u = i + 0.5: include every centre in [umin, umax].
    let clip = |a: f64, n: u32| a.clamp(0.0, n as f64) as u32;
    let (i0, i1) = (
        clip((umin - 0.5).ceil(), w),
        clip((umax - 0.5).floor() + 1.0, w),
    );
    let (j0, j1) = (
        clip((vmin - 0.5).ceil(), h),
        clip((vmax - 0.5).floor() + 1.0, h),
    );
    (i0 < i1 && j0 < j1).then_some((i0, i1, j0, j1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phantom::TriMesh;

    fn frame(n: u32, pitch: f64) -> DetectorFrame {
        DetectorFrame {
            pose: Pose::IDENTITY,
            pixels: [n, n],
            pixel_pitch_mm: [pitch, pitch],
        }
    }

    #[test]
    fn a_centred_sphere_casts_a_disc_of_the_magnified_radius() {
        // Source 1000 mm above the detector, sphere of radius 5 mm at 500 mm: shadow radius is
        // r·D/sqrt(d² − r²)·... ≈ 10.0 mm for small r; the pixel count matches the disc area.
        let f = frame(200, 0.25);
        let source = DVec3::new(0.0, 0.0, 1000.0);
        let objects = [Object::Sphere {
            centre_mm: DVec3::new(0.0, 0.0, 500.0),
            radius_mm: 5.0,
        }];
        let img = render_binary(&f, source, &objects, 255);
        let covered = img.iter().filter(|&&p| p == 255).count() as f64 * 0.0625;
        // Exact shadow of a sphere seen from distance d = 500: a cone of half-angle asin(r/d),
        // cut by the plane at 1000 mm: radius 1000·tan(asin(0.01)).
        let radius = 1000.0 * (0.01f64).asin().tan();
        let exact = std::f64::consts::PI * radius * radius;
        assert!((covered / exact - 1.0).abs() < 0.01, "{covered} vs {exact}");
        assert!(img.iter().all(|&p| p == 0 || p == 255));
    }

    #[test]
    fn a_sphere_mesh_and_an_exact_sphere_cast_nearly_the_same_shadow() {
        let f = frame(160, 0.25);
        let source = DVec3::new(3.0, -2.0, 1000.0);
        let centre = DVec3::new(1.0, 2.0, 400.0);
        let bvh = MeshBvh::new(&TriMesh::uv_sphere(6.0, 96, 192));
        let exact = render_binary(
            &f,
            source,
            &[Object::Sphere {
                centre_mm: centre,
                radius_mm: 6.0,
            }],
            1,
        );
        let pose = Pose {
            position_mm: centre,
            rotation: crate::geometry::rotation_xyz_deg([10.0, 20.0, 30.0]),
        };
        let mesh = render_binary(&f, source, &[Object::Mesh { bvh: &bvh, pose }], 1);
        let differ = exact.iter().zip(&mesh).filter(|(a, b)| a != b).count();
        let area = exact.iter().filter(|&&p| p == 1).count();
        // Only silhouette pixels may differ (the facets lie inside the sphere).
        assert!(area > 5000 && differ * 50 < area, "{differ} of {area}");
    }

    #[test]
    fn bounds_never_cut_the_shadow() {
        // Tracing with bounds equals tracing every pixel.
        let f = frame(64, 0.5);
        let source = DVec3::new(5.0, 5.0, 900.0);
        let objects = [Object::Sphere {
            centre_mm: DVec3::new(-3.0, 4.0, 300.0),
            radius_mm: 2.0,
        }];
        let fast = render_binary(&f, source, &objects, 9);
        for j in 0..64 {
            for i in 0..64 {
                let slow = objects[0].blocks(source, f.pixel_centre_world(i, j));
                assert_eq!(fast[(j * 64 + i) as usize] == 9, slow);
            }
        }
    }
}

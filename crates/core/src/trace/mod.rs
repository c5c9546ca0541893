//! The tracing stage: the paper's binary mode. A ray from the point source to every pixel centre
//! of a detector is tested against the phantoms of one exposure; a pixel whose ray crosses any
//! object gets I_max, every other pixel 0.
//!
//! Two projectors compute that image. [`render_binary`], the default, scan-converts (`raster.rs`):
//! each mesh's projected front-facing triangles are filled row by row over the pixel centres, and
//! each bead's candidate pixels are bounded per row by its projected ellipse, then decided by the
//! exact sphere predicate. [`render_binary_traced`] traces one ray per pixel centre: meshes through
//! a BVH with a watertight triangle test (`mesh_bvh.rs`, `watertight.rs`), beads by the same exact
//! predicate. The two agree on every bead pixel, and on every mesh pixel except those whose centre
//! lies within rounding distance of a projected silhouette edge (the tracer works in f32). A mesh
//! that cannot be projected (a vertex at or behind the source's plane or beyond the detector plane)
//! is traced by `render_binary` too.
//!
//! Cuboids and elliptic cylinders (analytic solids, `shapes.rs`) are decided by the same exact
//! predicate in both projectors: the segment from the source to the pixel centre runs inside the
//! solid for a positive length. [`path_lengths`] gives that length per pixel (`path_length.rs`).
//!
//! Both only look at pixels inside an object's projected bounds: each object's bounding box is
//! projected onto the detector (the projection of a convex hull is the convex hull of the
//! projections, so the corners' pixel rectangle bounds the object's shadow).

mod chord_row;
pub(crate) mod columns;
mod crossings;
mod fan;
mod mesh_bvh;
mod path_length;
mod raster;
mod shapes;
mod watertight;
mod window;

pub use mesh_bvh::MeshBvh;
pub use path_length::{PathLengths, path_lengths, path_lengths_traced};
pub use window::Projected;

use glam::DVec3;

use chord_row::{Posed, RowSolid};

use crate::geometry::{DetectorFrame, Pose};

/// An object in the beam, placed in the world (box) frame.
#[derive(Clone)]
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
    /// A solid box centred on its local origin, edges along the local axes (e.g. an acrylic
    /// calibration plate). Its faces belong to it (a ray along a face runs inside).
    Cuboid {
        /// Local → world.
        pose: Pose,
        /// Half the edge lengths along local x, y, z, mm.
        half_size_mm: DVec3,
    },
    /// A solid elliptic cylinder centred on its local origin, axis along local z, flat caps
    /// (e.g. a soft-tissue envelope). Its surface belongs to it.
    EllipticCylinder {
        /// Local → world.
        pose: Pose,
        /// Semi-axes of the cross-section along local x and y, mm.
        radii_mm: [f64; 2],
        /// Half the length along local z (caps at z = ±half_length_mm), mm.
        half_length_mm: f64,
    },
}

/// A binary projection image, row-major, `W × H` detector counts: `i_max` where the ray from
/// `source_mm` to the pixel centre crosses an object, 0 elsewhere. Scan conversion (see the
/// module docs); the same image as [`render_binary_traced`] up to pixels whose centre lies within
/// rounding distance of a mesh's projected silhouette.
pub fn render_binary(
    frame: &DetectorFrame,
    source_mm: DVec3,
    objects: &[Object],
    i_max: u16,
) -> Vec<u16> {
    let [w, h] = frame.pixels;
    let mut image = vec![0u16; w as usize * h as usize];
    for object in objects {
        match object {
            Object::Sphere {
                centre_mm,
                radius_mm,
            } => {
                let (lo, hi) = object.local_bounds();
                if let Some(bounds) = pixel_bounds(frame, source_mm, object.pose(), lo, hi) {
                    raster::fill_sphere(
                        &mut image, frame, source_mm, *centre_mm, *radius_mm, bounds, i_max,
                    );
                }
            }
            Object::Mesh { bvh, pose } => {
                if !raster::fill_mesh(&mut image, frame, source_mm, bvh, *pose, i_max) {
                    trace_object(&mut image, frame, source_mm, object, i_max);
                }
            }
            // The exact predicate over the projected bounds: the tracer's image, bit for bit.
            Object::Cuboid { .. } | Object::EllipticCylinder { .. } => {
                trace_object(&mut image, frame, source_mm, object, i_max);
            }
        }
    }
    image
}

/// The same image as [`render_binary`], by tracing one ray per pixel centre inside each
/// object's projected bounds (meshes through their BVH with the watertight triangle test).
pub fn render_binary_traced(
    frame: &DetectorFrame,
    source_mm: DVec3,
    objects: &[Object],
    i_max: u16,
) -> Vec<u16> {
    let [w, h] = frame.pixels;
    let mut image = vec![0u16; w as usize * h as usize];
    for object in objects {
        trace_object(&mut image, frame, source_mm, object, i_max);
    }
    image
}

/// Binary mode's occlusion of a bead: whether its shadow overlaps another object's. That is,
/// whether some pixel centre whose ray from `source_mm` crosses the bead (the exact sphere
/// predicate of the projectors) is also crossed by one of `occluders` (traced as
/// [`render_binary_traced`] does). In a binary image such a bead's disc merges with that
/// object's shadow: both are at I_max.
pub fn bead_occluded(
    frame: &DetectorFrame,
    source_mm: DVec3,
    centre_mm: DVec3,
    radius_mm: f64,
    occluders: &[&Object],
) -> bool {
    if occluders.is_empty() {
        return false;
    }
    let bead = Object::Sphere {
        centre_mm,
        radius_mm,
    };
    let (lo, hi) = bead.local_bounds();
    let Some((i0, i1, j0, j1)) = pixel_bounds(frame, source_mm, bead.pose(), lo, hi) else {
        return false;
    };
    (j0..j1).any(|j| {
        (i0..i1).any(|i| {
            let target = frame.pixel_centre_world(i, j);
            sphere_blocks(centre_mm, radius_mm, source_mm, target)
                && occluders.iter().any(|o| o.blocks(source_mm, target))
        })
    })
}

/// Traces `object` over its projected bounds, setting `i_max` where its rays are blocked.
fn trace_object(
    image: &mut [u16],
    frame: &DetectorFrame,
    source_mm: DVec3,
    object: &Object,
    i_max: u16,
) {
    let w = frame.pixels[0];
    let (lo, hi) = object.local_bounds();
    let Some((i0, i1, j0, j1)) = pixel_bounds(frame, source_mm, object.pose(), lo, hi) else {
        return;
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

/// The exact bead predicate: whether the line from `source` through `target` passes within
/// `radius_mm` of `centre_mm`.
fn sphere_blocks(centre_mm: DVec3, radius_mm: f64, source: DVec3, target: DVec3) -> bool {
    let d = target - source;
    let w = centre_mm - source;
    // Distance from the centre to the ray's line, via the cross product (no cancellation).
    w.cross(d).length_squared() <= radius_mm * radius_mm * d.length_squared()
}

impl Object<'_> {
    fn pose(&self) -> Pose {
        match self {
            Object::Sphere { centre_mm, .. } => Pose {
                position_mm: *centre_mm,
                rotation: glam::DMat3::IDENTITY,
            },
            Object::Mesh { pose, .. }
            | Object::Cuboid { pose, .. }
            | Object::EllipticCylinder { pose, .. } => *pose,
        }
    }

    /// The eight corners (world, mm) of the object's bounding box at its pose: the object lies
    /// inside their convex hull.
    pub fn bounding_corners_mm(&self) -> [DVec3; 8] {
        let (lo, hi) = self.local_bounds();
        let pose = self.pose();
        std::array::from_fn(|k| {
            pose.to_world(DVec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            ))
        })
    }

    fn local_bounds(&self) -> (DVec3, DVec3) {
        match self {
            Object::Sphere { radius_mm, .. } => {
                (DVec3::splat(-radius_mm), DVec3::splat(*radius_mm))
            }
            Object::Mesh { bvh, .. } => bvh.bounds_mm,
            Object::Cuboid { half_size_mm, .. } => (-*half_size_mm, *half_size_mm),
            Object::EllipticCylinder {
                radii_mm,
                half_length_mm,
                ..
            } => {
                let half = DVec3::new(radii_mm[0], radii_mm[1], *half_length_mm);
                (-half, half)
            }
        }
    }

    /// Whether the segment from the source to `target` crosses the object.
    fn blocks(&self, source: DVec3, target: DVec3) -> bool {
        match self {
            Object::Sphere {
                centre_mm,
                radius_mm,
            } => sphere_blocks(*centre_mm, *radius_mm, source, target),
            Object::Mesh { bvh, pose } => bvh.segment_hits(
                pose.to_local(source),
                pose.rotation.transpose() * (target - source),
            ),
            Object::Cuboid { .. } | Object::EllipticCylinder { .. } => {
                self.chord_mm(source, target).is_some_and(|l| l > 0.0)
            }
        }
    }

    /// The length (mm) of the segment from `source` to `target` inside an analytic solid
    /// (sphere, cuboid, elliptic cylinder); `None` for a mesh.
    fn chord_mm(&self, source: DVec3, target: DVec3) -> Option<f64> {
        Some(self.chords_from(source)?.length_mm(target))
    }

    /// An analytic solid seen from `source`, for the chords to many targets; `None` for a mesh.
    fn chords_from(&self, source: DVec3) -> Option<Chords> {
        let posed = |pose: &Pose| Posed {
            source,
            source_local: pose.to_local(source),
            to_local: pose.rotation.transpose(),
        };
        let solid = match self {
            Object::Sphere {
                centre_mm,
                radius_mm,
            } => Solid::Sphere {
                centre_mm: *centre_mm,
                radius_mm: *radius_mm,
            },
            Object::Cuboid { pose, half_size_mm } => Solid::Posed(
                posed(pose),
                RowSolid::Cuboid {
                    half_size_mm: *half_size_mm,
                },
            ),
            Object::EllipticCylinder {
                pose,
                radii_mm,
                half_length_mm,
            } => Solid::Posed(
                posed(pose),
                RowSolid::EllipticCylinder {
                    radii_mm: *radii_mm,
                    half_length_mm: *half_length_mm,
                },
            ),
            Object::Mesh { .. } => return None,
        };
        Some(Chords { source, solid })
    }
}

/// An analytic solid seen from one source: the source and, for a posed solid, the source in the
/// solid's frame and the rotation into it, computed once for the chords to every pixel (the same
/// operations, so the same bits, as computing them per pixel).
struct Chords {
    source: DVec3,
    solid: Solid,
}

enum Solid {
    Sphere {
        centre_mm: DVec3,
        radius_mm: f64,
    },
    /// A cuboid or an elliptic cylinder at a pose.
    Posed(Posed, RowSolid),
}

impl Chords {
    /// The length (mm) of the segment from the source to `target` inside the solid.
    #[inline]
    fn length_mm(&self, target: DVec3) -> f64 {
        let d = target - self.source;
        let interval = match &self.solid {
            Solid::Sphere {
                centre_mm,
                radius_mm,
            } => shapes::sphere_interval(*centre_mm, *radius_mm, self.source, d),
            Solid::Posed(p, RowSolid::Cuboid { half_size_mm }) => {
                shapes::cuboid_interval(*half_size_mm, p.source_local, p.to_local * d)
            }
            Solid::Posed(
                p,
                RowSolid::EllipticCylinder {
                    radii_mm,
                    half_length_mm,
                },
            ) => shapes::cylinder_interval(
                *radii_mm,
                *half_length_mm,
                p.source_local,
                p.to_local * d,
            ),
        };
        interval.map_or(0.0, |t| shapes::segment_length_mm(t, d))
    }

    /// [`Chords::length_mm`] for each of `targets`, into `out`: bit for bit the same values, a
    /// posed solid's row by the branch-free kernels of `chord_row`.
    fn lengths_mm(&self, targets: &[DVec3], out: &mut [f64]) {
        match &self.solid {
            Solid::Sphere { .. } => {
                for (o, &t) in out.iter_mut().zip(targets) {
                    *o = self.length_mm(t);
                }
            }
            Solid::Posed(p, solid) => chord_row::lengths(p, *solid, targets, out),
        }
    }
}

/// The half-open pixel rectangle `[i0, i1) × [j0, j1)` whose pixel centres can see `object` from
/// `source` (the projection of its bounding box, clipped to the detector); `None` when it is
/// empty.
pub fn shadow_bounds(
    frame: &DetectorFrame,
    source: DVec3,
    object: &Object,
) -> Option<(u32, u32, u32, u32)> {
    let (lo, hi) = object.local_bounds();
    pixel_bounds(frame, source, object.pose(), lo, hi)
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
    fn a_bead_is_occluded_exactly_when_its_disc_shares_a_pixel_with_another_shadow() {
        // The bead's own image and the slab's image, traced separately: occluded ⇔ some pixel
        // is set in both. The slab slides across the bead's shadow from far left to far right.
        let f = frame(120, 0.25);
        let source = DVec3::new(0.5, -0.3, 1000.0);
        let (centre, radius) = (DVec3::new(0.2, 0.1, 500.0), 0.5);
        let bead = [Object::Sphere {
            centre_mm: centre,
            radius_mm: radius,
        }];
        let disc = render_binary_traced(&f, source, &bead, 1);
        let mut seen = [false; 2];
        for step in 0..41 {
            let x = -12.0 + 0.6 * step as f64;
            let slab = Object::Cuboid {
                pose: Pose {
                    position_mm: DVec3::new(x, 0.0, 300.0),
                    rotation: crate::geometry::rotation_xyz_deg([0.0, 0.0, 7.0]),
                },
                half_size_mm: DVec3::new(5.0, 20.0, 1.0),
            };
            let shadow = render_binary_traced(&f, source, std::slice::from_ref(&slab), 1);
            let overlap = disc.iter().zip(&shadow).any(|(&a, &b)| a == 1 && b == 1);
            assert_eq!(
                bead_occluded(&f, source, centre, radius, &[&slab]),
                overlap,
                "slab at x = {x}"
            );
            seen[usize::from(overlap)] = true;
        }
        assert_eq!(seen, [true, true]);
        assert!(!bead_occluded(&f, source, centre, radius, &[]));
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

//! A model mesh as the CT-like volume Autoscoper tracks, and the frame Autoscoper gives it.
//!
//! # The volume file
//!
//! One multi-page 16-bit TIFF (`Volume::Volume` in Autoscoper's `libautoscoper/src/Volume.cpp`
//! reads page k as slice k, scanline r as row r, column c as column c; one sample per pixel,
//! unsigned). A voxel holds `round(μ(E) · 6553.5)`, clamped to 65535: the linear attenuation
//! coefficient of the phantom's material at the reference energy in units of 1/(6553.5 mm), so
//! that full scale is μ = 10 /mm; voxels outside the mesh hold exactly 0, as Autoscoper's DRR mask
//! needs (its cost is computed over non-zero DRR pixels). A voxel is inside when its centre is
//! (even-odd rule along the voxel column, a ray along +z through the closed mesh).
//!
//! # The volume frame (what a `.tra` pose moves)
//!
//! Autoscoper places the centre of TIFF voxel (c, r, p) of a W × H × D volume with voxel sizes
//! (sx, sy, sz) and `VolumeFlip fx fy fz` at
//! `(sx·(c′ + ½), sy·(H − ½ − r′), −sz·(p′ + ½))` with `c′ = fx ? W−1−c : c` and so on
//! (`VolumeDescription::VolumeDescription`, `RayCaster::setInvModelView` and the ray-casting
//! kernels; the crop to the non-zero bounding box does not move this origin). rsasim writes
//! `VolumeFlip 0 1 1`, which makes the volume frame a translation of the phantom's own frame:
//! the voxel centre is at `(sx·(c + ½), sy·(r + ½), sz·(p + ½) − sz·D)`, and rsasim lays the grid
//! so that this is `local − a` with
//!
//! `a = (x_min − m, y_min − m, z_max + m)`
//!
//! where `(x_min, y_min, z_min)`–`(x_max, y_max, z_max)` are the mesh's bounds in its phantom's
//! frame and `m` = [`MARGIN_MM`]: columns start at `x_min − m`, rows at `y_min − m`, and the
//! last page ends at `z_max + m` (pages run towards −z from there, the grid reaching at least to
//! `z_min − m`). The offset depends on the mesh only, not on the voxel size, so a pose read back
//! from Autoscoper is a phantom pose once `a` is known: world ← phantom =
//! (world ← volume) · translate(−a).
//!
//! The mesh Autoscoper pairs with the volume (`MeshFile`, the same pose) is written in the
//! volume frame: every vertex minus `a`.

use glam::DVec3;

use crate::geometry::Pose;
use crate::phantom::mesh::TriMesh;
use rsasim_core::trace::MeshBvh;

/// Empty space around the mesh on every side of the grid, mm.
pub const MARGIN_MM: f64 = 2.0;

/// Full scale of a voxel value: μ = 10 /mm is 65535.
pub const VALUE_PER_MU_MM: f64 = 6553.5;

/// The most voxels a volume may hold (2^28, 512 MiB of 16-bit samples before compression).
pub const MAX_VOXELS: u64 = 1 << 28;

/// The voxel grid of a mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    /// Columns, rows, pages (W, H, D).
    pub dims: [u32; 3],
    /// Voxel size, mm (isotropic).
    pub voxel_mm: f64,
    /// The volume frame's origin in the phantom's frame, `a` of the module docs, mm.
    pub offset_mm: DVec3,
}

/// The offset `a` of the module docs: the volume frame's origin in the phantom's frame.
pub fn frame_offset_mm(mesh: &TriMesh) -> DVec3 {
    let (lo, hi) = mesh.bounds_mm();
    DVec3::new(lo.x - MARGIN_MM, lo.y - MARGIN_MM, hi.z + MARGIN_MM)
}

impl Grid {
    /// The grid of `mesh` at `voxel_mm`; errors when the mesh is empty, the voxel size not
    /// positive and finite, or the grid larger than [`MAX_VOXELS`].
    pub fn of_mesh(mesh: &TriMesh, voxel_mm: f64) -> Result<Grid, String> {
        if !(voxel_mm.is_finite() && voxel_mm > 0.0) {
            return Err(format!(
                "the voxel size {voxel_mm} mm is not positive and finite"
            ));
        }
        if mesh.vertices.is_empty() {
            return Err("the mesh has no vertices".into());
        }
        let (lo, hi) = mesh.bounds_mm();
        let extent = hi - lo + DVec3::splat(2.0 * MARGIN_MM);
        let n = |e: f64| (e / voxel_mm).ceil().max(1.0);
        let dims_f = [n(extent.x), n(extent.y), n(extent.z)];
        let total = dims_f.iter().product::<f64>();
        if !(total <= MAX_VOXELS as f64) {
            return Err(format!(
                "the volume would hold {total:.3e} voxels of {voxel_mm} mm ({:.1} × {:.1} × {:.1} mm), more than {MAX_VOXELS}",
                extent.x, extent.y, extent.z
            ));
        }
        Ok(Grid {
            dims: dims_f.map(|d| d as u32),
            voxel_mm,
            offset_mm: frame_offset_mm(mesh),
        })
    }

    /// The centre of voxel (c, r, p) in the phantom's frame, mm.
    pub fn voxel_centre_mm(&self, c: u32, r: u32, p: u32) -> DVec3 {
        let s = self.voxel_mm;
        self.offset_mm
            + DVec3::new(
                s * (f64::from(c) + 0.5),
                s * (f64::from(r) + 0.5),
                s * (f64::from(p) + 0.5) - s * f64::from(self.dims[2]),
            )
    }
}

/// Which voxel centres lie inside the closed mesh, indexed `(p·H + r)·W + c`.
pub fn inside(mesh: &TriMesh, grid: &Grid) -> Vec<bool> {
    let [w, h, d] = grid.dims;
    let bvh = MeshBvh::new(mesh);
    let mut out = vec![false; w as usize * h as usize * d as usize];
    // One line per voxel column along +z (the f64 crossings with the tie rule that counts a
    // crossing through a shared edge or vertex once); a voxel centre is inside when an odd
    // number of crossings lie before it.
    for r in 0..h {
        for c in 0..w {
            let start = grid.voxel_centre_mm(c, r, 0);
            let crossings: Vec<f64> = bvh
                .line_crossings(start, DVec3::Z)
                .into_iter()
                .map(|t| t + start.z)
                .collect();
            if crossings.is_empty() {
                continue;
            }
            let mut before = 0;
            for p in 0..d {
                let z = grid.voxel_centre_mm(c, r, p).z;
                while before < crossings.len() && crossings[before] < z {
                    before += 1;
                }
                if before % 2 == 1 {
                    out[((p * h + r) * w + c) as usize] = true;
                }
            }
        }
    }
    out
}

/// A voxel value for a linear attenuation coefficient, per the module docs.
pub fn voxel_value(mu_per_mm: f64) -> u16 {
    (mu_per_mm * VALUE_PER_MU_MM).round().clamp(1.0, 65535.0) as u16
}

/// The pose Autoscoper's `.tra` holds for a phantom at `pose` (world ← phantom): world ← volume
/// = pose · translate(a), as a row-major 4×4 matrix (Autoscoper's "matrix, row" layout:
/// translation at 1-based positions 4, 8 and 12).
pub fn tra_matrix(pose: &Pose, offset_mm: DVec3) -> [f64; 16] {
    let r = pose.rotation;
    let t = pose.position_mm + r * offset_mm;
    let (x, y, z) = (r.x_axis, r.y_axis, r.z_axis);
    [
        x.x, y.x, z.x, t.x, //
        x.y, y.y, z.y, t.y, //
        x.z, y.z, z.z, t.z, //
        0.0, 0.0, 0.0, 1.0,
    ]
}

/// The phantom pose (world ← phantom) of a `.tra` row-major matrix (world ← volume): the
/// inverse of [`tra_matrix`].
pub fn pose_of_tra(m: &[f64; 16], offset_mm: DVec3) -> Pose {
    let rotation = glam::DMat3::from_cols(
        DVec3::new(m[0], m[4], m[8]),
        DVec3::new(m[1], m[5], m[9]),
        DVec3::new(m[2], m[6], m[10]),
    );
    let t = DVec3::new(m[3], m[7], m[11]);
    Pose {
        position_mm: t - rotation * offset_mm,
        rotation,
    }
}

/// The mesh in the volume frame (every vertex minus `a`).
pub fn mesh_in_volume_frame(mesh: &TriMesh, offset_mm: DVec3) -> TriMesh {
    TriMesh {
        vertices: mesh
            .vertices
            .iter()
            .map(|v| {
                (DVec3::from_array(v.map(f64::from)) - offset_mm)
                    .as_vec3()
                    .to_array()
            })
            .collect(),
        triangles: mesh.triangles.clone(),
    }
}

/// One line of a `.tra` file: 16 comma-separated values, each the shortest decimal that reads
/// back as the same 64-bit float.
pub fn tra_line(m: &[f64; 16]) -> String {
    let v: Vec<String> = m.iter().map(|x| format!("{x}")).collect();
    v.join(",") + "\n"
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The voxel centre of the module docs, computed the way Autoscoper's reader does for
    /// `VolumeFlip 0 1 1` (its formula, written out here), in the volume frame.
    fn autoscoper_volume_frame(g: &Grid, c: u32, r: u32, p: u32) -> DVec3 {
        let [w, h, d] = g.dims;
        let (cf, rf, pf) = (c, h - 1 - r, d - 1 - p);
        let _ = w;
        let s = g.voxel_mm;
        DVec3::new(
            s * (f64::from(cf) + 0.5),
            s * (f64::from(h) - 0.5 - f64::from(rf)),
            -s * (f64::from(pf) + 0.5),
        )
    }

    #[test]
    fn a_sphere_fills_the_voxels_within_its_radius_and_autoscoper_places_them_back() {
        let mesh = TriMesh::uv_sphere(5.0, 48, 96);
        let g = Grid::of_mesh(&mesh, 0.5).unwrap();
        // Bounds ±5 mm, margin 2 mm: 14 mm = 28 voxels each way; a = (−7, −7, 7).
        assert_eq!(g.dims, [28, 28, 28]);
        assert_eq!(g.offset_mm, DVec3::new(-7.0, -7.0, 7.0));
        let inside = inside(&mesh, &g);
        let [w, h, d] = g.dims;
        let mut wrong = 0;
        for p in 0..d {
            for r in 0..h {
                for c in 0..w {
                    let local = g.voxel_centre_mm(c, r, p);
                    // Autoscoper's voxel centre, in the phantom frame: + a.
                    let back = autoscoper_volume_frame(&g, c, r, p) + g.offset_mm;
                    assert!((back - local).length() < 1e-12, "{c} {r} {p}");
                    // The uv sphere's facets lie within 5·(1 − cos(π/96))… of the sphere.
                    let radius = local.length();
                    let got = inside[((p * h + r) * w + c) as usize];
                    if (radius - 5.0).abs() > 0.02 && got != (radius < 5.0) {
                        wrong += 1;
                    }
                }
            }
        }
        assert_eq!(wrong, 0);
        assert!(inside.iter().filter(|&&v| v).count() > 3000); // 4/3·π·5³/0.125 ≈ 4189
    }

    #[test]
    fn tra_matrix_and_its_inverse() {
        let pose = Pose::from_position_euler_deg([10.0, -20.0, 30.0], [15.0, -40.0, 70.0]);
        let a = DVec3::new(-7.0, 3.0, 12.5);
        let m = tra_matrix(&pose, a);
        // A point given in the volume frame lands where the phantom pose puts its local point.
        let local = DVec3::new(1.0, 2.0, 3.0);
        let vol = local - a;
        let world_tra = DVec3::new(
            m[0] * vol.x + m[1] * vol.y + m[2] * vol.z + m[3],
            m[4] * vol.x + m[5] * vol.y + m[6] * vol.z + m[7],
            m[8] * vol.x + m[9] * vol.y + m[10] * vol.z + m[11],
        );
        assert!((world_tra - pose.to_world(local)).length() < 1e-12);
        let back = pose_of_tra(&m, a);
        assert!((back.position_mm - pose.position_mm).length() < 1e-12);
        assert!(back.rotation.abs_diff_eq(pose.rotation, 1e-15));
        assert_eq!(&m[12..], &[0.0, 0.0, 0.0, 1.0]);
    }

    #[test]
    fn voxel_values_are_scaled_and_clamped() {
        assert_eq!(voxel_value(0.05), 328); // 0.05 · 6553.5 = 327.675
        assert_eq!(voxel_value(10.0), 65535);
        assert_eq!(voxel_value(100.0), 65535);
        assert_eq!(voxel_value(0.0), 1); // inside is never 0 (0 is Autoscoper's outside)
    }
}

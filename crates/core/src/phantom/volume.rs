//! The volumes of a phantom: the solids whose material attenuates (attenuation mode) — its mesh,
//! an elliptic cylinder, the plates of a calibration box — each in the phantom's local frame.
//! Beads are not volumes: they are markers, with the phantom's bead material.

use glam::DVec3;

use crate::geometry::Pose;
use crate::scenario::{CalibrationBox, EllipticCylinder};

/// The shape of a volume, in the phantom's local frame (mm).
#[derive(Debug, Clone, PartialEq)]
pub enum VolumeShape {
    /// The phantom's closed mesh ([`super::PhantomModel::mesh`]).
    Mesh,
    /// A box of half-sizes `half_size_mm` along its own axes, placed by `pose` in the phantom.
    Cuboid {
        /// Box frame → phantom frame.
        pose: Pose,
        /// Half the edge lengths along the box's x, y, z, mm.
        half_size_mm: DVec3,
    },
    /// An elliptic cylinder on the phantom's z axis, centred on its origin, flat caps.
    EllipticCylinder {
        /// Semi-axes along x and y, mm.
        radii_mm: [f64; 2],
        /// Half the length along z, mm.
        half_length_mm: f64,
    },
}

/// One solid of a phantom with the material filling it.
#[derive(Debug, Clone, PartialEq)]
pub struct Volume {
    /// For messages and truth: the phantom id, and `/<plate>` for a box plate.
    pub label: String,
    /// Its shape.
    pub shape: VolumeShape,
    /// Material name (library or user); `None` in binary mode where none was given.
    pub material: Option<String>,
}

/// The volume of an elliptic-cylinder phantom.
pub fn cylinder(id: &str, c: &EllipticCylinder, material: Option<&String>) -> Volume {
    Volume {
        label: id.to_string(),
        shape: VolumeShape::EllipticCylinder {
            radii_mm: c.radii_mm,
            half_length_mm: c.length_mm / 2.0,
        },
        material: material.cloned(),
    }
}

/// The plates of a calibration box that have a thickness: slabs of `size_mm × thickness_mm`
/// centred on their bead plane, in the plate's material (default PMMA).
pub fn plates(id: &str, b: &CalibrationBox) -> Vec<Volume> {
    b.plates
        .iter()
        .filter_map(|p| {
            let t = p.thickness_mm?;
            Some(Volume {
                label: format!("{id}/{}", p.id),
                shape: VolumeShape::Cuboid {
                    pose: Pose::from_position_euler_deg(p.center_mm, p.rotation_deg),
                    half_size_mm: DVec3::new(p.size_mm[0] / 2.0, p.size_mm[1] / 2.0, t / 2.0),
                },
                material: Some(p.material.clone().unwrap_or_else(|| "pmma".into())),
            })
        })
        .collect()
}

impl Volume {
    /// Corners of the volume's bounding box in the phantom frame (none for a mesh, whose
    /// vertices bound it).
    pub fn corners(&self) -> Vec<DVec3> {
        let (pose, h) = match &self.shape {
            VolumeShape::Mesh => return Vec::new(),
            VolumeShape::Cuboid { pose, half_size_mm } => (*pose, *half_size_mm),
            VolumeShape::EllipticCylinder {
                radii_mm,
                half_length_mm,
            } => (
                Pose::IDENTITY,
                DVec3::new(radii_mm[0], radii_mm[1], *half_length_mm),
            ),
        };
        (0..8)
            .map(|k| {
                let s = |bit: u32| if k & (1 << bit) == 0 { -1.0 } else { 1.0 };
                pose.to_world(DVec3::new(s(0) * h.x, s(1) * h.y, s(2) * h.z))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::{Plate, PlateRole};

    #[test]
    fn a_plate_with_a_thickness_is_a_pmma_slab_centred_on_its_beads() {
        let mut plate = Plate {
            id: "F".into(),
            role: PlateRole::Fiducial,
            center_mm: [0.0, 0.0, -100.0],
            rotation_deg: [0.0, 0.0, 0.0],
            size_mm: [100.0, 80.0],
            grid: [2, 2],
            spacing_mm: [10.0, 10.0],
            bead_diameter_mm: 1.0,
            omit: vec![],
            thickness_mm: None,
            material: None,
        };
        let b = CalibrationBox {
            plates: vec![plate.clone()],
        };
        assert!(plates("box", &b).is_empty());
        plate.thickness_mm = Some(8.0);
        let v = plates(
            "box",
            &CalibrationBox {
                plates: vec![plate],
            },
        );
        assert_eq!(v.len(), 1);
        assert_eq!(v[0].label, "box/F");
        assert_eq!(v[0].material.as_deref(), Some("pmma"));
        let c = v[0].corners();
        let zs: Vec<f64> = c.iter().map(|p| p.z).collect();
        assert!(zs.iter().all(|&z| z == -104.0 || z == -96.0), "{zs:?}");
        assert!(c.iter().all(|p| p.x.abs() == 50.0 && p.y.abs() == 40.0));
    }
}

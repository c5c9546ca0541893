//! Rigid poses and the X-Y-Z Euler convention of the paper (M = Mx(α)·My(β)·Mz(γ)).

use glam::{DMat3, DVec3};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// A rigid pose: `world = rotation · local + position_mm`.
///
/// Serialised as `position_mm` (3 numbers) and `rotation` (three rows of three numbers), the form
/// every JSON file of rsasim uses.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Pose {
    /// Origin of the local frame in world coordinates, mm.
    #[serde(with = "vec3_serde")]
    #[schemars(with = "[f64; 3]")]
    pub position_mm: DVec3,
    /// Rotation matrix as three rows; its columns are the local axes in world coordinates.
    #[serde(with = "mat3_rows_serde")]
    #[schemars(with = "[[f64; 3]; 3]")]
    pub rotation: DMat3,
}

impl Pose {
    /// The identity pose (local frame = world frame).
    pub const IDENTITY: Pose = Pose {
        position_mm: DVec3::ZERO,
        rotation: DMat3::IDENTITY,
    };

    /// A pose from a position in mm and X-Y-Z Euler angles in degrees (see [`rotation_xyz_deg`]).
    pub fn from_position_euler_deg(position_mm: [f64; 3], rotation_deg: [f64; 3]) -> Pose {
        Pose {
            position_mm: DVec3::from_array(position_mm),
            rotation: rotation_xyz_deg(rotation_deg),
        }
    }

    /// Maps a point given in the local frame to the world frame.
    pub fn to_world(&self, local: DVec3) -> DVec3 {
        self.rotation * local + self.position_mm
    }

    /// Maps a point given in the world frame to the local frame.
    pub fn to_local(&self, world: DVec3) -> DVec3 {
        self.rotation.transpose() * (world - self.position_mm)
    }

    /// The pose that undoes this one: `self.inverse().to_world(self.to_world(p)) == p`.
    pub fn inverse(&self) -> Pose {
        let rt = self.rotation.transpose();
        Pose {
            position_mm: -(rt * self.position_mm),
            rotation: rt,
        }
    }

    /// Composition `self ∘ inner`: first `inner`, then `self` (`self.to_world(inner.to_world(p))`).
    pub fn compose(&self, inner: &Pose) -> Pose {
        Pose {
            position_mm: self.to_world(inner.position_mm),
            rotation: self.rotation * inner.rotation,
        }
    }
}

/// Rotation matrix `Rx(α)·Ry(β)·Rz(γ)` from `[α, β, γ]` in degrees.
///
/// This is the decomposition the paper uses for orientation residuals (M = Mx(α)·My(β)·Mz(γ)),
/// so a scenario's `rotation_deg` and a report's angles speak the same language. Each factor is a
/// right-handed (counter-clockwise, seen from the positive axis) rotation about a fixed axis.
pub fn rotation_xyz_deg(angles_deg: [f64; 3]) -> DMat3 {
    let [a, b, c] = angles_deg.map(f64::to_radians);
    let (sa, ca) = (libm::sin(a), libm::cos(a));
    let (sb, cb) = (libm::sin(b), libm::cos(b));
    let (sc, cc) = (libm::sin(c), libm::cos(c));
    let rx = DMat3::from_cols(DVec3::X, DVec3::new(0.0, ca, sa), DVec3::new(0.0, -sa, ca));
    let ry = DMat3::from_cols(DVec3::new(cb, 0.0, -sb), DVec3::Y, DVec3::new(sb, 0.0, cb));
    let rz = DMat3::from_cols(DVec3::new(cc, sc, 0.0), DVec3::new(-sc, cc, 0.0), DVec3::Z);
    rx * ry * rz
}

/// The angles `[α, β, γ]` in degrees with `m = Rx(α)·Ry(β)·Rz(γ)`, β in [−90°, 90°].
///
/// The inverse of [`rotation_xyz_deg`] away from gimbal lock (|β| = 90°), where α + γ is
/// returned as α and γ = 0.
pub fn euler_xyz_deg(m: &DMat3) -> [f64; 3] {
    // Rx·Ry·Rz has row 0 = (cb·cc, −cb·sc, sb), column 2 = (sb, −sa·cb, ca·cb).
    let sb = m.z_axis.x.clamp(-1.0, 1.0);
    let b = libm::asin(sb);
    let (a, c) = if sb.abs() < 1.0 - 1e-12 {
        (
            libm::atan2(-m.z_axis.y, m.z_axis.z),
            libm::atan2(-m.y_axis.x, m.x_axis.x),
        )
    } else {
        (libm::atan2(m.y_axis.z, m.y_axis.y), 0.0)
    };
    [a.to_degrees(), b.to_degrees(), c.to_degrees()]
}

/// A rotation matrix as three rows, the form every JSON file of rsasim uses.
pub fn rotation_rows(m: &DMat3) -> [[f64; 3]; 3] {
    let t = m.transpose();
    [
        t.x_axis.to_array(),
        t.y_axis.to_array(),
        t.z_axis.to_array(),
    ]
}

/// The matrix whose rows are `rows` (the inverse of [`rotation_rows`]).
pub fn rotation_from_rows(rows: [[f64; 3]; 3]) -> DMat3 {
    DMat3::from_cols(
        DVec3::from_array(rows[0]),
        DVec3::from_array(rows[1]),
        DVec3::from_array(rows[2]),
    )
    .transpose()
}

/// Serde for a `DVec3` as a plain `[x, y, z]` array.
pub(crate) mod vec3_serde {
    use glam::DVec3;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(v: &DVec3, s: S) -> Result<S::Ok, S::Error> {
        v.to_array().serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<DVec3, D::Error> {
        <[f64; 3]>::deserialize(d).map(DVec3::from_array)
    }
}

/// Serde for a `DMat3` as three rows.
pub(crate) mod mat3_rows_serde {
    use glam::DMat3;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(m: &DMat3, s: S) -> Result<S::Ok, S::Error> {
        super::rotation_rows(m).serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<DMat3, D::Error> {
        <[[f64; 3]; 3]>::deserialize(d).map(super::rotation_from_rows)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: DVec3, b: DVec3) -> bool {
        (a - b).length() < 1e-12
    }

    #[test]
    fn rotations_are_right_handed_about_each_axis() {
        // +90° about z takes x to y; about x takes y to z; about y takes z to x.
        assert!(close(
            rotation_xyz_deg([0.0, 0.0, 90.0]) * DVec3::X,
            DVec3::Y
        ));
        assert!(close(
            rotation_xyz_deg([90.0, 0.0, 0.0]) * DVec3::Y,
            DVec3::Z
        ));
        assert!(close(
            rotation_xyz_deg([0.0, 90.0, 0.0]) * DVec3::Z,
            DVec3::X
        ));
    }

    #[test]
    fn euler_round_trip_matches_the_factor_order() {
        for angles in [
            [10.0, -20.0, 30.0],
            [-170.0, 45.0, 5.0],
            [0.3, 0.0, -0.7],
            [120.0, -80.0, 179.0],
        ] {
            let m = rotation_xyz_deg(angles);
            let back = euler_xyz_deg(&m);
            for k in 0..3 {
                assert!((back[k] - angles[k]).abs() < 1e-9, "{angles:?} -> {back:?}");
            }
            let rx = rotation_xyz_deg([angles[0], 0.0, 0.0]);
            let ry = rotation_xyz_deg([0.0, angles[1], 0.0]);
            let rz = rotation_xyz_deg([0.0, 0.0, angles[2]]);
            assert!((rx * ry * rz - m).abs_diff_eq(DMat3::ZERO, 1e-12));
        }
    }

    #[test]
    fn pose_inverse_and_compose() {
        let a = Pose::from_position_euler_deg([1.0, -2.0, 30.0], [5.0, 10.0, -15.0]);
        let b = Pose::from_position_euler_deg([-7.0, 0.5, 2.0], [-40.0, 3.0, 60.0]);
        let p = DVec3::new(3.0, 4.0, -5.0);
        assert!(close(a.inverse().to_world(a.to_world(p)), p));
        assert!(close(a.compose(&b).to_world(p), a.to_world(b.to_world(p))));
        assert!(close(a.to_local(a.to_world(p)), p));
    }

    #[test]
    fn pose_json_has_rotation_as_rows() {
        let pose = Pose::from_position_euler_deg([1.0, 2.0, 3.0], [0.0, 0.0, 90.0]);
        let v: serde_json::Value = serde_json::to_value(pose).unwrap();
        // Row 0 of Rz(90°) is (cos, −sin, 0) = (0, −1, 0).
        let row0: Vec<f64> = v["rotation"][0]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        assert!((row0[0]).abs() < 1e-15 && (row0[1] + 1.0).abs() < 1e-15 && row0[2] == 0.0);
        let back: Pose = serde_json::from_value(v).unwrap();
        assert_eq!(back, pose);
    }
}

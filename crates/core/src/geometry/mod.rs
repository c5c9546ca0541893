//! Geometry shared by every stage: rigid poses, Euler angles, the detector's pixel frame, the
//! distance from a point to a triangle, and the triangulation and rigid-body fits of markers.
//!
//! Conventions (docs/src/reference/conventions.md, "Units" and "Frames"): lengths in millimetres, angles in degrees at every
//! boundary a person sees, radians only inside. A [`Pose`] maps local to world coordinates as
//! `world = rotation · local + position`; the columns of `rotation` are the local axes in world
//! coordinates. All trigonometry goes through the pure-Rust `libm` crate, never the platform's,
//! so poses are bit-identical on every machine.

mod detector;
mod distance;
pub mod joint;
mod pose;
mod rigid;
pub mod trajectory;

pub use detector::DetectorFrame;
pub use distance::point_triangle_distance;
pub use glam::{DMat3, DVec3};
pub use pose::{Pose, euler_xyz_deg, rotation_from_rows, rotation_rows, rotation_xyz_deg};
pub(crate) use pose::{mat3_rows_serde, vec3_serde};
pub use rigid::{RigidFit, condition_number, fit_rigid, triangulate};

//! The detector's pixel frame and the central projection of a point source onto it.
//!
//! Detector frame (docs/src/reference/conventions.md, "Frames"): origin at the centre of the active area; local x = r along a row
//! (increasing column index), local y = c along a column (increasing row index), local z = s, the
//! normal pointing from the detector towards its source. Continuous pixel coordinates (u, v) put
//! the centre of pixel (column i, row j) at (i + 0.5, j + 0.5).

use glam::{DVec2, DVec3};

use super::Pose;

/// A flat detector placed in the world: its pose and its pixel grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectorFrame {
    /// Pose of the detector frame (r, c, s axes) in world coordinates.
    pub pose: Pose,
    /// Pixel counts `[W, H]` (columns, rows).
    pub pixels: [u32; 2],
    /// Pixel pitch `[x, y]` in mm.
    pub pixel_pitch_mm: [f64; 2],
}

impl DetectorFrame {
    /// World position of the centre of pixel (column `i`, row `j`).
    pub fn pixel_centre_world(&self, i: u32, j: u32) -> DVec3 {
        self.pose
            .to_world(self.pixel_local(i as f64 + 0.5, j as f64 + 0.5))
    }

    /// Detector-frame position (z = 0) of continuous pixel coordinates (u, v).
    pub fn pixel_local(&self, u: f64, v: f64) -> DVec3 {
        let [w, h] = self.pixels;
        DVec3::new(
            (u - w as f64 / 2.0) * self.pixel_pitch_mm[0],
            (v - h as f64 / 2.0) * self.pixel_pitch_mm[1],
            0.0,
        )
    }

    /// Continuous pixel coordinates (u, v) of a detector-frame point's (x, y).
    pub fn local_to_pixel(&self, local: DVec3) -> DVec2 {
        let [w, h] = self.pixels;
        DVec2::new(
            local.x / self.pixel_pitch_mm[0] + w as f64 / 2.0,
            local.y / self.pixel_pitch_mm[1] + h as f64 / 2.0,
        )
    }

    /// Central projection of `point` from `source` onto the detector plane, in continuous pixel
    /// coordinates. `None` when the ray from the source through the point never reaches the plane
    /// (the point is not strictly between the source's side and the detector).
    pub fn project(&self, source: DVec3, point: DVec3) -> Option<DVec2> {
        let s = self.pose.to_local(source);
        let p = self.pose.to_local(point);
        let dz = s.z - p.z;
        if s.z <= 0.0 || dz <= 0.0 {
            return None;
        }
        let t = s.z / dz;
        let hit = s + (p - s) * t;
        Some(self.local_to_pixel(hit))
    }

    /// The derivatives of [`project`](Self::project)'s (u, v) with respect to the world position
    /// of `point`: `[∇u, ∇v]`, pixels per mm. `None` where `project` gives `None`.
    pub fn project_gradient(&self, source: DVec3, point: DVec3) -> Option<[DVec3; 2]> {
        let s = self.pose.to_local(source);
        let p = self.pose.to_local(point);
        let dz = s.z - p.z;
        if s.z <= 0.0 || dz <= 0.0 {
            return None;
        }
        // hit = s + (p − s)·t with t = s.z / dz: ∂hit_x/∂p = (t, 0, (p_x − s_x)·s.z/dz²).
        let t = s.z / dz;
        let k = s.z / (dz * dz);
        let du = DVec3::new(t, 0.0, (p.x - s.x) * k) / self.pixel_pitch_mm[0];
        let dv = DVec3::new(0.0, t, (p.y - s.y) * k) / self.pixel_pitch_mm[1];
        // Local = Rᵀ·(world − position), so a local gradient g is R·g in the world.
        Some([self.pose.rotation * du, self.pose.rotation * dv])
    }

    /// [`project`](Self::project) of points given in the local frame of `pose`, with the two
    /// frames' transforms composed once: `projector(source, pose)(v)` is
    /// `project(source, pose.to_world(v))` up to rounding. For projecting many vertices of one
    /// posed mesh.
    pub fn projector(&self, source: DVec3, pose: &Pose) -> impl Fn(DVec3) -> Option<DVec2> {
        let to_detector = self.pose.rotation.transpose();
        let (m, offset) = (
            to_detector * pose.rotation,
            to_detector * (pose.position_mm - self.pose.position_mm),
        );
        let s = self.pose.to_local(source);
        let frame = *self;
        move |v: DVec3| {
            let p = m * v + offset;
            let dz = s.z - p.z;
            if !(s.z > 0.0 && dz > 0.0) {
                return None;
            }
            Some(frame.local_to_pixel(s + (p - s) * (s.z / dz)))
        }
    }

    /// Width and height of the active area in mm.
    pub fn size_mm(&self) -> [f64; 2] {
        [
            self.pixels[0] as f64 * self.pixel_pitch_mm[0],
            self.pixels[1] as f64 * self.pixel_pitch_mm[1],
        ]
    }

    /// Whether continuous pixel coordinates fall on the active area.
    pub fn contains_pixel(&self, uv: DVec2) -> bool {
        uv.x >= 0.0 && uv.y >= 0.0 && uv.x <= self.pixels[0] as f64 && uv.y <= self.pixels[1] as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame() -> DetectorFrame {
        DetectorFrame {
            pose: Pose::from_position_euler_deg([0.0, 0.0, -500.0], [0.0, 0.0, 0.0]),
            pixels: [4, 2],
            pixel_pitch_mm: [0.5, 0.25],
        }
    }

    #[test]
    fn pixel_centres_follow_design_md() {
        let d = frame();
        // Pixel (0, 0): x = (0.5 − 2)·0.5 = −0.75, y = (0.5 − 1)·0.25 = −0.125.
        assert_eq!(
            d.pixel_centre_world(0, 0),
            DVec3::new(-0.75, -0.125, -500.0)
        );
        assert_eq!(d.pixel_centre_world(3, 1), DVec3::new(0.75, 0.125, -500.0));
    }

    #[test]
    fn the_projector_of_a_pose_projects_as_project_does() {
        let mut d = frame();
        d.pose = Pose::from_position_euler_deg([3.0, -2.0, -480.0], [2.0, 91.0, -5.0]);
        let source = d.pose.to_world(DVec3::new(10.0, -20.0, 1800.0));
        let pose = Pose::from_position_euler_deg([5.0, 7.0, -30.0], [20.0, -35.0, 60.0]);
        let projector = d.projector(source, &pose);
        for k in 0..50 {
            let f = f64::from(k);
            let v = DVec3::new(f.sin() * 40.0, (1.7 * f).cos() * 30.0, f - 25.0);
            let (a, b) = (
                projector(v).unwrap(),
                d.project(source, pose.to_world(v)).unwrap(),
            );
            assert!((a - b).length() < 1e-9, "{a} against {b}");
        }
        // A point at or behind the source's plane does not project, by either.
        let behind = pose.to_local(source + (source - d.pose.position_mm));
        assert_eq!(projector(behind), None);
        assert_eq!(d.project(source, pose.to_world(behind)), None);
    }

    #[test]
    fn projection_lands_on_the_pixel_centre_it_came_from() {
        let mut d = frame();
        d.pose = Pose::from_position_euler_deg([3.0, -2.0, -480.0], [2.0, 91.0, -5.0]);
        let source = d.pose.to_world(DVec3::new(10.0, -20.0, 1800.0));
        for (i, j) in [(0, 0), (3, 1), (2, 0)] {
            let c = d.pixel_centre_world(i, j);
            // Any point on the segment source→pixel centre projects to that centre.
            let p = source + (c - source) * 0.6;
            let uv = d.project(source, p).unwrap();
            assert!((uv - DVec2::new(i as f64 + 0.5, j as f64 + 0.5)).length() < 1e-9);
        }
        // The gradient matches central differences.
        let p = source + (d.pixel_centre_world(2, 1) - source) * 0.7 + DVec3::new(3.0, -1.0, 2.0);
        let [gu, gv] = d.project_gradient(source, p).unwrap();
        for (axis, e) in [DVec3::X, DVec3::Y, DVec3::Z].into_iter().enumerate() {
            let h = 1e-4;
            let fd = (d.project(source, p + e * h).unwrap()
                - d.project(source, p - e * h).unwrap())
                / (2.0 * h);
            assert!((fd.x - gu[axis]).abs() < 1e-6, "u/{axis}: {fd} vs {gu}");
            assert!((fd.y - gv[axis]).abs() < 1e-6, "v/{axis}: {fd} vs {gv}");
        }
        // A point behind the source does not project.
        assert!(
            d.project(source, source + (source - d.pose.position_mm))
                .is_none()
        );
    }
}

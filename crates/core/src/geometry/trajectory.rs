//! A rigid body's pose over time from keyframes: the one place that says what a `[phantoms.motion]`
//! means between its keyframes.
//!
//! Keyframe `i` gives a time `t_i` (strictly increasing) and a pose `M_i = (R_i, p_i)`. At time `t`
//! with `t_i ≤ t ≤ t_{i+1}` and `u = (t − t_i)/(t_{i+1} − t_i)`:
//!
//! * **Position**: the cubic Hermite curve through `p_i` and `p_{i+1}` with Catmull–Rom tangents
//!   for uneven times, `m_i = (p_{i+1} − p_{i−1})/(t_{i+1} − t_{i−1})` inside and the chord's slope
//!   `(p_1 − p_0)/(t_1 − t_0)` and `(p_n − p_{n−1})/(t_n − t_{n−1})` at the ends: continuous
//!   velocity, and with two keyframes a straight line at constant speed.
//! * **Rotation**: `R(t) = R_i · rot(a, u·θ)`, where `rot(a, θ) = R_iᵀ·R_{i+1}` is the relative
//!   rotation with `0 ≤ θ < 180°` (spherical linear interpolation: the shortest arc at constant
//!   angular speed). A step that turns 180° or more, or in which one of the written Euler angles
//!   changes by 180° or more (170° → −170° might mean 20° or 340°), is refused when the scenario
//!   is checked ([`Trajectory::new`]): give a keyframe between them.
//! * Before `t_0` the pose is `M_0`, after `t_n` it is `M_n` (held).
//!
//! All trigonometry goes through `libm` (via glam's `libm` feature and [`rotation_xyz_deg`]), so
//! poses are the same bits on every machine.

use glam::{DMat3, DQuat, DVec3};

use super::{Pose, rotation_xyz_deg};

/// One keyframe: time in seconds, position in mm, rotation as X-Y-Z Euler angles in degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Key {
    /// Time, s.
    pub time_s: f64,
    /// Position, mm.
    pub position_mm: [f64; 3],
    /// Rotation, X-Y-Z Euler angles, degrees.
    pub rotation_deg: [f64; 3],
}

/// A pose over time: keyframes ready to be interpolated.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    times_s: Vec<f64>,
    positions_mm: Vec<DVec3>,
    /// Velocity at each keyframe, mm/s (the Catmull–Rom tangents).
    velocities_mm_s: Vec<DVec3>,
    rotations: Vec<DMat3>,
    /// Per interval, the axis and angle (rad) of `R_iᵀ·R_{i+1}`.
    turns: Vec<(DVec3, f64)>,
}

/// Why keyframes cannot make a trajectory.
#[derive(Debug, Clone, PartialEq)]
pub enum TrajectoryError {
    /// Fewer than two keyframes.
    TooFew,
    /// Keyframe `index` is not later than the one before it (or its time is not finite).
    NotIncreasing { index: usize },
    /// From keyframe `index − 1` to `index` the body turns, or one written Euler angle changes,
    /// by `angle_deg` ≥ 180°: the way between them is not unique.
    HalfTurn { index: usize, angle_deg: f64 },
}

impl Trajectory {
    /// The trajectory through `keys`; see [`TrajectoryError`] for what is refused.
    pub fn new(keys: &[Key]) -> Result<Trajectory, TrajectoryError> {
        if keys.len() < 2 {
            return Err(TrajectoryError::TooFew);
        }
        for (i, pair) in keys.windows(2).enumerate() {
            if !(pair[0].time_s.is_finite() && pair[1].time_s.is_finite())
                || pair[1].time_s <= pair[0].time_s
            {
                return Err(TrajectoryError::NotIncreasing { index: i + 1 });
            }
        }
        let times_s: Vec<f64> = keys.iter().map(|k| k.time_s).collect();
        let positions_mm: Vec<DVec3> = keys
            .iter()
            .map(|k| DVec3::from_array(k.position_mm))
            .collect();
        let n = keys.len();
        let velocities_mm_s = (0..n)
            .map(|i| {
                let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
                (positions_mm[b] - positions_mm[a]) / (times_s[b] - times_s[a])
            })
            .collect();
        let rotations: Vec<DMat3> = keys
            .iter()
            .map(|k| rotation_xyz_deg(k.rotation_deg))
            .collect();
        let mut turns = Vec::with_capacity(n - 1);
        for (i, pair) in rotations.windows(2).enumerate() {
            let (axis, angle) = axis_angle(pair[0].transpose() * pair[1]);
            let written = (0..3)
                .map(|a| (keys[i + 1].rotation_deg[a] - keys[i].rotation_deg[a]).abs())
                .fold(0.0, f64::max);
            let angle_deg = angle.to_degrees().max(written);
            // Within a few units of rounding of 180° the axis is not defined either.
            if !(angle_deg < 180.0 - 1e-9) {
                return Err(TrajectoryError::HalfTurn {
                    index: i + 1,
                    angle_deg,
                });
            }
            turns.push((axis, angle));
        }
        Ok(Trajectory {
            times_s,
            positions_mm,
            velocities_mm_s,
            rotations,
            turns,
        })
    }

    /// The pose at `time_s` (held before the first keyframe and after the last).
    pub fn pose_at(&self, time_s: f64) -> Pose {
        let n = self.times_s.len();
        if !(time_s > self.times_s[0]) {
            return self.key_pose(0);
        }
        if time_s >= self.times_s[n - 1] {
            return self.key_pose(n - 1);
        }
        // The interval [t_i, t_{i+1}) holding time_s.
        let i = self.times_s.partition_point(|&t| t <= time_s) - 1;
        let (t0, t1) = (self.times_s[i], self.times_s[i + 1]);
        let h = t1 - t0;
        let u = (time_s - t0) / h;
        let (u2, u3) = (u * u, u * u * u);
        let position = self.positions_mm[i] * (2.0 * u3 - 3.0 * u2 + 1.0)
            + self.velocities_mm_s[i] * (h * (u3 - 2.0 * u2 + u))
            + self.positions_mm[i + 1] * (-2.0 * u3 + 3.0 * u2)
            + self.velocities_mm_s[i + 1] * (h * (u3 - u2));
        let (axis, angle) = self.turns[i];
        Pose {
            position_mm: position,
            rotation: self.rotations[i] * DMat3::from_axis_angle(axis, u * angle),
        }
    }

    /// The last keyframe's time, s.
    pub fn end_s(&self) -> f64 {
        self.times_s[self.times_s.len() - 1]
    }

    fn key_pose(&self, i: usize) -> Pose {
        Pose {
            position_mm: self.positions_mm[i],
            rotation: self.rotations[i],
        }
    }
}

/// The unit axis and the angle in [0, π] (rad) of a rotation matrix; the x axis for no turn.
fn axis_angle(m: DMat3) -> (DVec3, f64) {
    let mut q = DQuat::from_mat3(&m).normalize();
    if q.w < 0.0 {
        q = -q;
    }
    let v = DVec3::new(q.x, q.y, q.z);
    let s = v.length();
    if s == 0.0 {
        return (DVec3::X, 0.0);
    }
    (v / s, 2.0 * libm::atan2(s, q.w))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::euler_xyz_deg;

    fn key(time_s: f64, position_mm: [f64; 3], rotation_deg: [f64; 3]) -> Key {
        Key {
            time_s,
            position_mm,
            rotation_deg,
        }
    }

    fn angle_between_deg(a: DMat3, b: DMat3) -> f64 {
        // By hand: the angle of AᵀB from its trace, cos θ = (tr − 1)/2.
        let t = (a.transpose() * b).to_cols_array();
        let trace = t[0] + t[4] + t[8];
        ((trace - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees()
    }

    #[test]
    fn two_keyframes_move_in_a_straight_line_at_constant_speed() {
        let t = Trajectory::new(&[
            key(0.5, [0.0, 0.0, 0.0], [0.0; 3]),
            key(1.5, [10.0, -4.0, 2.0], [0.0; 3]),
        ])
        .unwrap();
        for (time, f) in [(0.75, 0.25), (1.0, 0.5), (1.25, 0.75)] {
            let p = t.pose_at(time).position_mm;
            let want = DVec3::new(10.0, -4.0, 2.0) * f;
            assert!((p - want).length() < 1e-12, "{time}: {p} vs {want}");
        }
    }

    #[test]
    fn three_keyframes_pass_through_every_keyframe_with_the_catmull_rom_slope() {
        // x: 0 at t=0, 10 at t=1, 0 at t=3. At t=1 the tangent is (0 − 0)/(3 − 0) = 0, so the
        // curve peaks there; on [0, 1] with m0 = 10 mm/s and m1 = 0 the Hermite form at u = ½
        // gives x = ½·0 + ⅛·10 + ½·10 − ⅛·0 = 6.25 mm (by hand).
        let t = Trajectory::new(&[
            key(0.0, [0.0; 3], [0.0; 3]),
            key(1.0, [10.0, 0.0, 0.0], [0.0; 3]),
            key(3.0, [0.0; 3], [0.0; 3]),
        ])
        .unwrap();
        assert_eq!(t.pose_at(1.0).position_mm, DVec3::new(10.0, 0.0, 0.0));
        assert!((t.pose_at(0.5).position_mm.x - 6.25).abs() < 1e-12);
        let slope =
            (t.pose_at(1.0 + 1e-6).position_mm.x - t.pose_at(1.0 - 1e-6).position_mm.x) / 2e-6;
        assert!(slope.abs() < 1e-4, "velocity at the peak keyframe: {slope}");
    }

    #[test]
    fn rotation_follows_the_shortest_arc_at_constant_angular_speed() {
        let t = Trajectory::new(&[
            key(0.0, [0.0; 3], [10.0, 0.0, 0.0]),
            key(2.0, [0.0; 3], [70.0, 0.0, 0.0]),
        ])
        .unwrap();
        for (time, want) in [(0.5, 25.0), (1.0, 40.0), (1.5, 55.0)] {
            let r = t.pose_at(time).rotation;
            let angles = euler_xyz_deg(&r);
            assert!((angles[0] - want).abs() < 1e-9, "{angles:?}");
            assert!(angles[1].abs() < 1e-9 && angles[2].abs() < 1e-9);
        }
        // About a general axis: the angle from the start grows linearly, to the end falls.
        let t = Trajectory::new(&[
            key(0.0, [0.0; 3], [20.0, -30.0, 5.0]),
            key(1.0, [0.0; 3], [-40.0, 35.0, 60.0]),
        ])
        .unwrap();
        let (r0, r1) = (t.pose_at(0.0).rotation, t.pose_at(1.0).rotation);
        let total = angle_between_deg(r0, r1);
        for u in [0.1, 0.3, 0.5, 0.9] {
            let r = t.pose_at(u).rotation;
            assert!((angle_between_deg(r0, r) - u * total).abs() < 1e-7);
            assert!((angle_between_deg(r, r1) - (1.0 - u) * total).abs() < 1e-7);
        }
        // The short way round: 100° → 190° about x (written within 180° of each other) passes
        // 145°, and 190° is the same rotation as −170°.
        let t = Trajectory::new(&[
            key(0.0, [0.0; 3], [100.0, 0.0, 0.0]),
            key(1.0, [0.0; 3], [190.0, 0.0, 0.0]),
        ])
        .unwrap();
        let mid = euler_xyz_deg(&t.pose_at(0.5).rotation)[0];
        assert!((mid - 145.0).abs() < 1e-9, "{mid}");
        let end = euler_xyz_deg(&t.pose_at(1.0).rotation)[0];
        assert!((end + 170.0).abs() < 1e-9, "{end}");
    }

    #[test]
    fn poses_are_held_outside_the_keyframes() {
        let t = Trajectory::new(&[
            key(1.0, [1.0, 2.0, 3.0], [5.0, 0.0, 0.0]),
            key(2.0, [4.0, 5.0, 6.0], [0.0, 5.0, 0.0]),
        ])
        .unwrap();
        assert_eq!(t.pose_at(0.0), t.pose_at(1.0));
        assert_eq!(t.pose_at(-1e9), t.pose_at(1.0));
        assert_eq!(t.pose_at(7.0), t.pose_at(2.0));
        assert_eq!(t.pose_at(2.0).position_mm, DVec3::new(4.0, 5.0, 6.0));
        assert_eq!(t.end_s(), 2.0);
    }

    #[test]
    fn bad_keyframes_are_refused() {
        assert_eq!(
            Trajectory::new(&[key(0.0, [0.0; 3], [0.0; 3])]),
            Err(TrajectoryError::TooFew)
        );
        assert_eq!(
            Trajectory::new(&[
                key(0.0, [0.0; 3], [0.0; 3]),
                key(1.0, [0.0; 3], [0.0; 3]),
                key(1.0, [0.0; 3], [0.0; 3])
            ]),
            Err(TrajectoryError::NotIncreasing { index: 2 })
        );
        assert_eq!(
            Trajectory::new(&[
                key(f64::NAN, [0.0; 3], [0.0; 3]),
                key(1.0, [0.0; 3], [0.0; 3])
            ]),
            Err(TrajectoryError::NotIncreasing { index: 1 })
        );
        match Trajectory::new(&[
            key(0.0, [0.0; 3], [0.0; 3]),
            key(1.0, [0.0; 3], [0.0, 0.0, 180.0]),
        ]) {
            Err(TrajectoryError::HalfTurn {
                index: 1,
                angle_deg,
            }) => {
                assert!((angle_deg - 180.0).abs() < 1e-6)
            }
            other => panic!("{other:?}"),
        }
        assert!(
            Trajectory::new(&[
                key(0.0, [0.0; 3], [0.0; 3]),
                key(1.0, [0.0; 3], [0.0, 0.0, 179.0])
            ])
            .is_ok()
        );
        // 170° → −170° is 20° one way and 340° the other: refused, whatever was meant.
        assert_eq!(
            Trajectory::new(&[
                key(0.0, [0.0; 3], [170.0, 0.0, 0.0]),
                key(1.0, [0.0; 3], [-170.0, 0.0, 0.0])
            ]),
            Err(TrajectoryError::HalfTurn {
                index: 1,
                angle_deg: 340.0
            })
        );
    }
}

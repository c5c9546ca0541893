//! The chords of a row of pixels through one cuboid or elliptic cylinder, written without
//! branches so the compiler vectorizes them (with AVX2 where the CPU has it): bit for bit the
//! per-pixel [`super::Chords::length_mm`], because every value is computed by the same IEEE
//! operations in the same order (glam's `DMat3 * DVec3`, `dot`, `perp_dot`, `length` spelled
//! out), and `min`, `max` and selects are exact. A branch of the scalar code (a zero direction
//! component, a miss) becomes a select between both outcomes. Test
//! `rows_equal_the_scalar_chords_bit_for_bit`.

use glam::{DMat3, DVec2, DVec3};

/// A posed solid as its row kernels read it: the source in the world and in the solid's frame,
/// and the rotation into that frame.
#[derive(Clone, Copy)]
pub(super) struct Posed {
    pub source: DVec3,
    pub source_local: DVec3,
    pub to_local: DMat3,
}

impl Posed {
    /// The direction `target − source` in the world and in the solid's frame
    /// (`to_local * d`, glam's order: `x_axis·d.x + y_axis·d.y + z_axis·d.z`).
    #[inline(always)]
    fn directions(&self, target: DVec3) -> (DVec3, DVec3) {
        let d = target - self.source;
        let m = &self.to_local;
        let local = DVec3::new(
            m.x_axis.x * d.x + m.y_axis.x * d.y + m.z_axis.x * d.z,
            m.x_axis.y * d.x + m.y_axis.y * d.y + m.z_axis.y * d.z,
            m.x_axis.z * d.x + m.y_axis.z * d.y + m.z_axis.z * d.z,
        );
        (d, local)
    }
}

/// The interval `(t0, t1)` narrowed by the slab `|s + t·d| ≤ half` and whether the line missed:
/// `shapes::slab` without branches.
#[inline(always)]
fn slab(t: (f64, f64), half: f64, s: f64, d: f64) -> ((f64, f64), bool) {
    let a = (-half - s) / d;
    let b = (half - s) / d;
    let zero = d == 0.0;
    let nan = a.is_nan() | b.is_nan();
    // d = 0: inside for every t when |s| ≤ half (the interval is unchanged), else a miss.
    let t0 = if zero { t.0 } else { t.0.max(a.min(b)) };
    let t1 = if zero { t.1 } else { t.1.min(a.max(b)) };
    let miss = if zero { !(s.abs() <= half) } else { nan };
    ((t0, t1), miss | !(t0 <= t1))
}

/// The length on the segment `0 ≤ t ≤ 1` of the interval, 0 on a miss or an empty interval
/// (`shapes::segment_length_mm` after `(t0 < t1).then_some(t)`).
#[inline(always)]
fn length(t: (f64, f64), miss: bool, d: DVec3) -> f64 {
    let span = t.1.min(1.0) - t.0.max(0.0);
    let len = span * ((d.x * d.x) + (d.y * d.y) + (d.z * d.z)).sqrt();
    if miss | !(t.0 < t.1) | !(span > 0.0) {
        0.0
    } else {
        len
    }
}

/// One pixel of a cuboid of half sizes `half_mm` (`shapes::cuboid_interval`).
#[inline(always)]
fn cuboid(p: &Posed, half_mm: DVec3, target: DVec3) -> f64 {
    let (d, l) = p.directions(target);
    let s = p.source_local;
    let t = (f64::NEG_INFINITY, f64::INFINITY);
    let (t, mx) = slab(t, half_mm.x, s.x, l.x);
    let (t, my) = slab(t, half_mm.y, s.y, l.y);
    let (t, mz) = slab(t, half_mm.z, s.z, l.z);
    length(t, mx | my | mz, d)
}

/// One pixel of an elliptic cylinder (`shapes::cylinder_interval`).
#[inline(always)]
fn cylinder(p: &Posed, radii_mm: [f64; 2], half_length_mm: f64, target: DVec3) -> f64 {
    let (d, l) = p.directions(target);
    let s = p.source_local;
    let scale = DVec2::new(1.0 / radii_mm[0], 1.0 / radii_mm[1]);
    let pp = DVec2::new(s.x * scale.x, s.y * scale.y);
    let q = DVec2::new(l.x * scale.x, l.y * scale.y);
    let qq = (q.x * q.x) + (q.y * q.y);
    let cross = (pp.x * q.y) - (pp.y * q.x);
    let disc = qq - cross * cross;
    let mid = -((pp.x * q.x) + (pp.y * q.y)) / qq;
    let half = disc.sqrt() / qq;
    let parallel = qq == 0.0;
    // Parallel to the axis: inside for every t or for none.
    let side = if parallel {
        (f64::NEG_INFINITY, f64::INFINITY)
    } else {
        (mid - half, mid + half)
    };
    let side_miss = if parallel {
        !((pp.x * pp.x) + (pp.y * pp.y) <= 1.0)
    } else {
        !(disc >= 0.0)
    };
    let (t, mz) = slab(side, half_length_mm, s.z, l.z);
    length(t, side_miss | mz, d)
}

/// Which solid a row is cut through.
#[derive(Clone, Copy)]
pub(super) enum RowSolid {
    Cuboid {
        half_size_mm: DVec3,
    },
    EllipticCylinder {
        radii_mm: [f64; 2],
        half_length_mm: f64,
    },
}

/// The lengths (mm) inside `solid` of the segments from the source to each of `targets`.
///
/// # Panics
/// When the slices differ in length.
pub(super) fn lengths(p: &Posed, solid: RowSolid, targets: &[DVec3], out: &mut [f64]) {
    assert_eq!(targets.len(), out.len(), "one length per target");
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked just above).
        unsafe { lengths_avx2(p, solid, targets, out) };
        return;
    }
    lengths_portable(p, solid, targets, out);
}

/// [`lengths`] compiled for AVX2; the same operations, so the same bits.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn lengths_avx2(p: &Posed, solid: RowSolid, targets: &[DVec3], out: &mut [f64]) {
    lengths_portable(p, solid, targets, out);
}

#[inline(always)]
fn lengths_portable(p: &Posed, solid: RowSolid, targets: &[DVec3], out: &mut [f64]) {
    match solid {
        RowSolid::Cuboid { half_size_mm } => {
            for (o, &t) in out.iter_mut().zip(targets) {
                *o = cuboid(p, half_size_mm, t);
            }
        }
        RowSolid::EllipticCylinder {
            radii_mm,
            half_length_mm,
        } => {
            for (o, &t) in out.iter_mut().zip(targets) {
                *o = cylinder(p, radii_mm, half_length_mm, t);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Pose;
    use crate::trace::Object;

    /// A small deterministic generator (SplitMix64) of doubles in [−1, 1).
    struct Mix(u64);
    impl Mix {
        fn next(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^= z >> 31;
            (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        }
    }

    /// Every target's row length against the scalar chord, bit for bit, through both the AVX2
    /// (where the CPU has it) and the portable kernel.
    fn check(object: &Object, source: DVec3, targets: &[DVec3]) -> usize {
        let chords = object.chords_from(source).expect("an analytic solid");
        let mut row = vec![f64::NAN; targets.len()];
        chords.lengths_mm(targets, &mut row);
        let mut portable = vec![f64::NAN; targets.len()];
        if let Solid::Posed(p, solid) = &chords.solid {
            lengths_portable(p, *solid, targets, &mut portable);
        }
        let mut inside = 0;
        for (k, &t) in targets.iter().enumerate() {
            let want = chords.length_mm(t);
            assert_eq!(
                row[k].to_bits(),
                want.to_bits(),
                "target {t}: {} vs {want}",
                row[k]
            );
            assert_eq!(
                portable[k].to_bits(),
                want.to_bits(),
                "portable, target {t}"
            );
            inside += usize::from(want > 0.0);
        }
        inside
    }

    use super::super::Solid;

    #[test]
    fn rows_equal_the_scalar_chords_bit_for_bit() {
        let mut r = Mix(12);
        let mut inside = 0;
        let mut total = 0;
        for case in 0..60 {
            // Axis-aligned solids (direction components exactly 0, rays along faces) and turned ones.
            let rotation = if case % 3 == 0 {
                glam::DMat3::IDENTITY
            } else {
                glam::DMat3::from_euler(
                    glam::EulerRot::XYZ,
                    3.0 * r.next(),
                    3.0 * r.next(),
                    3.0 * r.next(),
                )
            };
            let pose = Pose {
                position_mm: DVec3::new(30.0 * r.next(), 30.0 * r.next(), 30.0 * r.next()),
                rotation,
            };
            let half = DVec3::new(
                60.0 + 40.0 * r.next(),
                60.0 + 40.0 * r.next(),
                4.0 + 3.0 * r.next(),
            );
            let source = DVec3::new(20.0 * r.next(), 20.0 * r.next(), 1000.0 + 300.0 * r.next());
            // Targets on a plane below, covering the shadow and beyond, plus special rays: along
            // the local axes through the source, and grazing a face.
            let mut targets: Vec<DVec3> = (0..400)
                .map(|_| DVec3::new(250.0 * r.next(), 250.0 * r.next(), -500.0 + 50.0 * r.next()))
                .collect();
            let s_local = pose.to_local(source);
            for local in [
                DVec3::new(s_local.x, s_local.y, -3000.0),
                DVec3::new(half.x, s_local.y, -3000.0),
                DVec3::new(half.x, half.y, -half.z),
                DVec3::new(-half.x, 0.0, half.z),
                DVec3::new(s_local.x, half.y, 0.0),
            ] {
                targets.push(pose.to_world(local));
            }
            // The source inside the solid, and a target inside it.
            targets.push(pose.to_world(DVec3::ZERO));
            let cuboid = Object::Cuboid {
                pose,
                half_size_mm: half,
            };
            inside += check(&cuboid, source, &targets);
            inside += check(&cuboid, pose.to_world(DVec3::new(1.0, -2.0, 0.5)), &targets);
            let cylinder = Object::EllipticCylinder {
                pose,
                radii_mm: [half.x, 0.8 * half.y],
                half_length_mm: 10.0 * half.z,
            };
            inside += check(&cylinder, source, &targets);
            inside += check(
                &cylinder,
                pose.to_world(DVec3::new(1.0, -2.0, 0.5)),
                &targets,
            );
            total += 4 * targets.len();
        }
        // Both outcomes are exercised in earnest.
        assert!(
            inside > total / 10 && inside < total * 9 / 10,
            "{inside} of {total}"
        );
    }
}

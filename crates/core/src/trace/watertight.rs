//! The watertight ray/triangle test of Woop, Benthin and Wald (JCGT 2013).
//!
//! A ray that passes exactly through an edge or a vertex shared by several triangles hits at
//! least one of them, so no ray leaks through a closed mesh (obvhs' built-in Möller–Trumbore test
//! lets a few through where a ray meets a shared edge exactly). Edge functions that come out exactly zero
//! in f32 are recomputed in f64, as the paper prescribes.

use glam::Vec3A;

/// A ray prepared for the watertight test: the shear that maps its direction onto +z.
#[derive(Debug, Clone, Copy)]
pub struct ShearedRay {
    origin: Vec3A,
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f32,
    sy: f32,
    sz: f32,
}

impl ShearedRay {
    /// Prepares `origin + t·direction` (direction need not be normalised).
    pub fn new(origin: Vec3A, direction: Vec3A) -> Self {
        let kz = dominant_axis(direction.abs().as_dvec3());
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if direction[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        ShearedRay {
            origin,
            kx,
            ky,
            kz,
            sx: direction[kx] / direction[kz],
            sy: direction[ky] / direction[kz],
            sz: 1.0 / direction[kz],
        }
    }

    /// The ray parameter `t` of the hit with triangle (v0, v1, v2) if `t_min < t < t_max`,
    /// else `f32::INFINITY`. Both faces count.
    pub fn intersect(&self, v0: Vec3A, v1: Vec3A, v2: Vec3A, t_min: f32, t_max: f32) -> f32 {
        let (kx, ky, kz) = (self.kx, self.ky, self.kz);
        let a = v0 - self.origin;
        let b = v1 - self.origin;
        let c = v2 - self.origin;
        let ax = a[kx] - self.sx * a[kz];
        let ay = a[ky] - self.sy * a[kz];
        let bx = b[kx] - self.sx * b[kz];
        let by = b[ky] - self.sy * b[kz];
        let cx = c[kx] - self.sx * c[kz];
        let cy = c[ky] - self.sy * c[kz];
        let mut u = cx * by - cy * bx;
        let mut v = ax * cy - ay * cx;
        let mut w = bx * ay - by * ax;
        if u == 0.0 || v == 0.0 || w == 0.0 {
            let f =
                |p: f32, q: f32, r: f32, s: f32| (p as f64 * q as f64 - r as f64 * s as f64) as f32;
            u = f(cx, by, cy, bx);
            v = f(ax, cy, ay, cx);
            w = f(bx, ay, by, ax);
        }
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return f32::INFINITY;
        }
        let det = u + v + w;
        if det == 0.0 {
            return f32::INFINITY;
        }
        let az = self.sz * a[kz];
        let bz = self.sz * b[kz];
        let cz = self.sz * c[kz];
        let t_scaled = u * az + v * bz + w * cz;
        let (t_scaled, det) = if det < 0.0 {
            (-t_scaled, -det)
        } else {
            (t_scaled, det)
        };
        if t_scaled <= t_min * det || t_scaled >= t_max * det {
            return f32::INFINITY;
        }
        t_scaled / det
    }
}

/// The axis along which `magnitudes` (absolute values of a direction) is largest, the first on a tie.
pub(super) fn dominant_axis(magnitudes: glam::DVec3) -> usize {
    let a = magnitudes;
    if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::vec3a;

    #[test]
    fn hits_inside_misses_outside_and_reports_t() {
        let (v0, v1, v2) = (
            vec3a(0.0, 0.0, 5.0),
            vec3a(1.0, 0.0, 5.0),
            vec3a(0.0, 1.0, 5.0),
        );
        let r = ShearedRay::new(vec3a(0.2, 0.2, 0.0), vec3a(0.0, 0.0, 2.0));
        assert!((r.intersect(v0, v1, v2, 0.0, 10.0) - 2.5).abs() < 1e-6);
        // Beyond t_max, and a ray beside the triangle, miss.
        assert_eq!(r.intersect(v0, v1, v2, 0.0, 2.0), f32::INFINITY);
        let r = ShearedRay::new(vec3a(0.8, 0.8, 0.0), vec3a(0.0, 0.0, 1.0));
        assert_eq!(r.intersect(v0, v1, v2, 0.0, 10.0), f32::INFINITY);
    }

    #[test]
    fn a_ray_through_a_shared_edge_hits_one_of_the_two_triangles() {
        // Two triangles sharing the diagonal of the unit square; rays exactly on the diagonal.
        let (a, b, c, d) = (
            vec3a(0.0, 0.0, 1.0),
            vec3a(1.0, 0.0, 1.0),
            vec3a(1.0, 1.0, 1.0),
            vec3a(0.0, 1.0, 1.0),
        );
        for k in 1..100 {
            let x = k as f32 / 100.0;
            let r = ShearedRay::new(vec3a(x, x, 0.0), vec3a(0.0, 0.0, 1.0));
            let hits = [
                r.intersect(a, b, c, 0.0, 2.0),
                r.intersect(a, c, d, 0.0, 2.0),
            ];
            assert!(hits.iter().any(|t| t.is_finite()), "ray at {x} leaked");
        }
    }
}

//! Building blocks of the procedural models (the femoral component, the distal femur, the
//! proximal tibia and the tibial components): implicit solids given by a function that is
//! negative inside, combined with rounded intersections, lofted through superelliptic
//! cross-sections, and polygonised by [`marching_tetrahedra`] into a mesh in a model's local
//! frame. Only arithmetic, `sqrt` and `libm` are used, so the meshes are the same bytes on every
//! platform.

use glam::DVec3;

use super::TriMesh;
use super::isosurface::{Grid, marching_tetrahedra, sample};

/// Rounded intersection of two solids given by distances `a`, `b` (negative inside): convex
/// edges are rounded with radius `r`. The result is never below `max(a, b)`, so the rounded
/// solid lies inside the sharp intersection.
pub(crate) fn round_intersection(a: f64, b: f64, r: f64) -> f64 {
    let (u, v) = ((r + a).max(0.0), (r + b).max(0.0));
    (-r).min(a.max(b)) + (u * u + v * v).sqrt()
}

/// Cubic smooth step from 0 at `e0` to 1 at `e1`.
pub(crate) fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// A value going smoothly (a cubic smooth step) from `values[0]` at height `heights[0]` to
/// `values[1]` at `heights[1]`, constant beyond them: e.g. a cortex thickening from the
/// metaphysis to the diaphysis.
pub(crate) fn blend(values: [f64; 2], heights: [f64; 2], y: f64) -> f64 {
    values[0] + (values[1] - values[0]) * smoothstep(heights[0], heights[1], y)
}

/// A superelliptic cross-section of a lofted bone in the x–z plane (x medio-lateral, z
/// anterior, mm): `|x / a|^n + |(z − z_c) / b|^n = 1` with `a` the half-width, `b` and `z_c`
/// half the extent and the centre of `z_post ..= z_ant`, `n` the exponent (2 an ellipse, larger
/// boxier).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Superellipse {
    /// Half the medio-lateral width, mm.
    pub half_width: f64,
    /// Anterior extent, mm.
    pub z_ant: f64,
    /// Posterior extent, mm.
    pub z_post: f64,
    /// Exponent.
    pub exponent: f64,
}

impl Superellipse {
    /// The section `from + (to − from)·t`, parameter by parameter, with its own `t` for the
    /// posterior extent (the two ends of a loft at the fractions of the way along).
    pub fn mix(from: [f64; 4], to: [f64; 4], t: f64, t_post: f64) -> Superellipse {
        let mix = |i: usize, t: f64| from[i] + (to[i] - from[i]) * t;
        Superellipse {
            half_width: mix(0, t),
            z_ant: mix(1, t),
            z_post: mix(2, t_post),
            exponent: mix(3, t),
        }
    }

    /// The section shrunk by `wall` mm on every side (same exponent).
    pub fn inset(&self, wall: f64) -> Superellipse {
        Superellipse {
            half_width: self.half_width - wall,
            z_ant: self.z_ant - wall,
            z_post: self.z_post + wall,
            exponent: self.exponent,
        }
    }

    /// An approximate signed distance to the superellipse in the cross-section plane (negative
    /// inside; never more than the true distance along the minor axis).
    pub fn distance(&self, x: f64, z: f64) -> f64 {
        let a = self.half_width;
        let b = 0.5 * (self.z_ant - self.z_post);
        let zc = 0.5 * (self.z_ant + self.z_post);
        let n = self.exponent;
        let sum = libm::pow((x / a).abs(), n) + libm::pow(((z - zc) / b).abs(), n);
        (libm::pow(sum, 1.0 / n) - 1.0) * a.min(b)
    }
}

/// Where and how finely a solid is polygonised: the box `lo ..= hi` that encloses it (design
/// frame, mm), the grid spacing along x, y, z, and the fractions of a step by which the nodes are
/// shifted off round numbers (so that no node falls on a flat face of the solid).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Sampling {
    /// Lower corner of the box enclosing the solid, mm.
    pub lo: DVec3,
    /// Upper corner, mm.
    pub hi: DVec3,
    /// Grid spacing, mm.
    pub step: DVec3,
    /// Node offsets as fractions of a step, each in (0, 1).
    pub offset: DVec3,
}

/// Polygonises `{f < 0}` over a grid enclosing `sampling`'s box with a margin of two steps and
/// moves it to a local frame (subtracting `origin` from every vertex). `what` names the solid in
/// the panic message should it reach the grid's boundary (a programming error: the box must
/// enclose the solid).
pub(crate) fn polygonise(
    f: impl Fn(DVec3) -> f64,
    sampling: &Sampling,
    origin: DVec3,
    what: &str,
) -> TriMesh {
    let Sampling {
        lo,
        hi,
        step: h,
        offset,
    } = *sampling;
    let grid_origin = lo - (DVec3::splat(2.0) - offset) * h;
    let count = |extent: f64, h: f64| (extent / h).ceil() as usize + 5;
    let size = hi - lo;
    let grid = Grid {
        origin: grid_origin,
        step: h,
        n: [count(size.x, h.x), count(size.y, h.y), count(size.z, h.z)],
    };
    let values = sample(&grid, f);
    // The grid encloses the solid with a margin of two steps, so the surface always closes.
    let surface =
        marching_tetrahedra(&grid, &values).unwrap_or_else(|e| panic!("{what} grid: {e}"));
    TriMesh {
        vertices: surface
            .vertices
            .iter()
            .map(|v| (*v - origin).as_vec3().to_array())
            .collect(),
        triangles: surface.triangles,
    }
}

//! A mesh's triangles binned by their projection along one fixed direction ([`DIRECTION`]): the
//! triangles a ray from a point along that direction may cross, and those that may come within a
//! distance of a point, without looking at the others. Whether a bead lies inside a mesh
//! (`crate::attenuation::containment`) asks both questions for every bead of every run; over all
//! triangles that was 15 % of the realistic protocol's time.
//!
//! Each triangle's projection onto the plane across [`DIRECTION`] is bounded by a rectangle,
//! widened by a margin far above the rounding of the projection and of any exact test done later
//! in 3D; the rectangle is entered in every cell of a square grid it overlaps. A ray from `p`
//! along the direction meets a triangle only where the triangle's projection holds `p`'s, so only
//! the triangles of `p`'s cell can be crossed, each listed once. A point within `r` of a triangle
//! projects within `r` of the triangle's projection (projection does not lengthen), so only the
//! cells meeting the square of half-side `r` around `p`'s projection hold triangles that can be
//! that near. The answers are supersets: the caller's exact tests decide, so results are those of
//! testing every triangle.

use glam::DVec3;

/// The direction containment casts its rays along: fixed and irrational, so that a ray misses the
/// edges and vertices of any practical mesh.
pub const DIRECTION: DVec3 = DVec3::new(
    0.577_215_664_901_532_9,
    std::f64::consts::LOG10_2,
    0.759_134_453_1,
);

/// Triangles binned by the cells of their projected rectangle.
#[derive(Debug, Clone)]
pub struct Columns {
    /// Unit direction and two unit axes across it.
    axes: [DVec3; 3],
    /// Lower corner of the grid on the plane (coordinates along the two cross axes), mm.
    origin_mm: [f64; 2],
    /// Side of a cell, mm.
    cell_mm: f64,
    /// Cells per axis.
    n: [usize; 2],
    /// `items[start[c]..start[c + 1]]` are the triangles of cell `c` (row-major), ascending.
    start: Vec<u32>,
    items: Vec<u32>,
}

impl Columns {
    /// The triangles `faces` (indices into `vertices_mm`) binned along [`DIRECTION`].
    pub fn new(vertices_mm: &[DVec3], faces: &[[u32; 3]]) -> Columns {
        let d = DIRECTION.normalize();
        let u = d.any_orthonormal_vector();
        let axes = [u, d.cross(u), d];
        let project = |p: DVec3| [p.dot(axes[0]), p.dot(axes[1])];
        let rects: Vec<[[f64; 2]; 2]> = faces
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|i| project(vertices_mm[i as usize]));
                let mut lo = [a[0].min(b[0]).min(c[0]), a[1].min(b[1]).min(c[1])];
                let mut hi = [a[0].max(b[0]).max(c[0]), a[1].max(b[1]).max(c[1])];
                for k in 0..2 {
                    let margin = MARGIN_REL * (lo[k].abs() + hi[k].abs()) + MARGIN_MM;
                    lo[k] -= margin;
                    hi[k] += margin;
                }
                [lo, hi]
            })
            .collect();
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for r in &rects {
            for k in 0..2 {
                lo[k] = lo[k].min(r[0][k]);
                hi[k] = hi[k].max(r[1][k]);
            }
        }
        if rects.is_empty() {
            lo = [0.0; 2];
            hi = [0.0; 2];
        }
        // About one triangle per cell on a closed surface's two sheets, at most 1024² cells. A
        // mesh of large overlapping triangles (each over many cells) gets a coarser grid, so that
        // the entries stay within `MAX_ENTRIES_PER_TRIANGLE` per triangle: counted per
        // rectangle without visiting its cells, so no mesh makes this slow or large.
        let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(MARGIN_MM);
        let mut side = ((rects.len() as f64).sqrt().ceil() as usize).clamp(1, 1024);
        let budget = MAX_ENTRIES_PER_TRIANGLE * rects.len() as u64 + 4096;
        let mut out = loop {
            let cell_mm = extent / side as f64;
            let n = [0, 1].map(|k| (((hi[k] - lo[k]) / cell_mm).floor() as usize + 1).min(side));
            let grid = Columns {
                axes,
                origin_mm: lo,
                cell_mm,
                n,
                start: Vec::new(),
                items: Vec::new(),
            };
            let entries: u64 = rects
                .iter()
                .map(|r| {
                    let span =
                        |k: usize| (grid.cell(k, r[1][k]) - grid.cell(k, r[0][k]) + 1) as u64;
                    span(0) * span(1)
                })
                .sum();
            if entries <= budget || side == 1 {
                break grid;
            }
            side = side.div_ceil(2);
        };
        let n = out.n;
        let mut counts = vec![0u32; n[0] * n[1] + 1];
        for r in &rects {
            out.for_cells(r[0], r[1], |c| counts[c] += 1);
        }
        let mut start = Vec::with_capacity(counts.len());
        let mut total = 0u32;
        for c in &counts {
            start.push(total);
            total += c;
        }
        let mut fill = start.clone();
        let mut items = vec![0u32; total as usize];
        for (t, r) in rects.iter().enumerate() {
            out.for_cells(r[0], r[1], |c| {
                items[fill[c] as usize] = t as u32;
                fill[c] += 1;
            });
        }
        out.start = start;
        out.items = items;
        out
    }

    /// The cell index along axis `k` of plane coordinate `x`, clamped to the grid.
    fn cell(&self, k: usize, x: f64) -> usize {
        let i = ((x - self.origin_mm[k]) / self.cell_mm).floor();
        if i.is_nan() || i < 0.0 {
            0
        } else {
            (i as usize).min(self.n[k] - 1)
        }
    }

    /// Calls `f` with every cell the rectangle `lo`–`hi` overlaps.
    fn for_cells(&self, lo: [f64; 2], hi: [f64; 2], mut f: impl FnMut(usize)) {
        for j in self.cell(1, lo[1])..=self.cell(1, hi[1]) {
            for i in self.cell(0, lo[0])..=self.cell(0, hi[0]) {
                f(j * self.n[0] + i);
            }
        }
    }

    /// Whether the plane point `q` lies inside the grid (every rectangle does).
    fn holds(&self, q: [f64; 2]) -> bool {
        (0..2).all(|k| {
            q[k] >= self.origin_mm[k] && q[k] <= self.origin_mm[k] + self.n[k] as f64 * self.cell_mm
        })
    }

    fn project(&self, p: DVec3) -> [f64; 2] {
        [p.dot(self.axes[0]), p.dot(self.axes[1])]
    }

    /// The triangles a ray from `p` along [`DIRECTION`] can cross, each once, ascending.
    pub fn along(&self, p: DVec3) -> &[u32] {
        let q = self.project(p);
        if !self.holds(q) {
            return &[];
        }
        let c = self.cell(1, q[1]) * self.n[0] + self.cell(0, q[0]);
        &self.items[self.start[c] as usize..self.start[c + 1] as usize]
    }

    /// Calls `f` with every triangle that can come within `r_mm` of `p` (some more than once).
    pub fn near(&self, p: DVec3, r_mm: f64, mut f: impl FnMut(u32)) {
        let q = self.project(p);
        let reach = r_mm * (1.0 + MARGIN_REL) + MARGIN_MM;
        let (lo, hi) = ([q[0] - reach, q[1] - reach], [q[0] + reach, q[1] + reach]);
        let grid_hi = [0, 1].map(|k| self.origin_mm[k] + self.n[k] as f64 * self.cell_mm);
        if (0..2).any(|k| hi[k] < self.origin_mm[k] || lo[k] > grid_hi[k]) {
            return;
        }
        self.for_cells(lo, hi, |c| {
            for &t in &self.items[self.start[c] as usize..self.start[c + 1] as usize] {
                f(t);
            }
        });
    }
}

/// The most cell entries per triangle, on average, before the grid is made coarser (a closed
/// mesh's small triangles take 1–4 each).
const MAX_ENTRIES_PER_TRIANGLE: u64 = 16;

/// Relative widening of every rectangle and query: far above the rounding of a projection
/// (a few units of 10⁻¹⁶ of the coordinates).
const MARGIN_REL: f64 = 1e-9;
/// Absolute widening, mm.
const MARGIN_MM: f64 = 1e-9;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phantom::TriMesh;

    #[test]
    fn every_triangle_a_ray_crosses_is_in_its_column() {
        let m = TriMesh::uv_sphere(10.0, 12, 24);
        let v: Vec<DVec3> = m
            .vertices
            .iter()
            .map(|p| DVec3::from_array(p.map(f64::from)))
            .collect();
        let cols = Columns::new(&v, &m.triangles);
        let d = DIRECTION.normalize();
        let mut crossed = 0;
        for i in 0..3000u32 {
            let p = DVec3::new(
                -12.0 + 0.008 * f64::from(i),
                -11.0 + 0.0071 * f64::from(i % 3001),
                -3.0 + 0.002 * f64::from(i),
            );
            let listed = cols.along(p);
            for (t, f) in m.triangles.iter().enumerate() {
                let [a, b, c] = f.map(|k| v[k as usize]);
                // The projection of the crossing point is p's: inside the triangle's projection.
                let n = (b - a).cross(c - a);
                let den = n.dot(d);
                if den.abs() < 1e-12 {
                    continue;
                }
                let s = n.dot(a - p) / den;
                let x = p + d * s;
                let inside = [(a, b), (b, c), (c, a)]
                    .iter()
                    .all(|&(e0, e1)| (e1 - e0).cross(x - e0).dot(n) >= 0.0);
                if s > 0.0 && inside {
                    crossed += 1;
                    assert!(listed.contains(&(t as u32)), "triangle {t} missing at {p}");
                }
            }
        }
        assert!(crossed > 1000, "{crossed}");
    }

    /// A hostile mesh: many large triangles over one another, each across the whole grid a
    /// closed mesh of that many triangles would get. The grid coarsens, the entries stay within
    /// their budget, and every triangle a ray crosses is still listed.
    #[test]
    fn overlapping_large_triangles_coarsen_the_grid() {
        let n = 20_000u32;
        let mut v = Vec::new();
        let mut faces = Vec::new();
        for t in 0..n {
            let z = f64::from(t) * 0.001;
            let k = v.len() as u32;
            v.extend([
                DVec3::new(-100.0, -100.0, z),
                DVec3::new(100.0, -100.0, z),
                DVec3::new(0.0, 100.0, z),
            ]);
            faces.push([k, k + 1, k + 2]);
        }
        let start = std::time::Instant::now();
        let cols = Columns::new(&v, &faces);
        assert!(
            cols.items.len() as u64 <= MAX_ENTRIES_PER_TRIANGLE * u64::from(n) + 4096,
            "{} entries",
            cols.items.len()
        );
        assert!(start.elapsed().as_secs() < 10, "{:?}", start.elapsed());
        // A point below every sheet: its ray (z component > 0) crosses them all.
        assert_eq!(cols.along(DVec3::new(0.0, 0.0, -1.0)).len(), n as usize);
    }
}

//! Helpers of the procedural models' tests (the distal femur, the proximal tibia, the tibial
//! component): points inside a closed mesh, distances to a mesh, cross-section extents, the
//! shipped model files.

use glam::DVec3;
use sha2::{Digest, Sha256};

use super::TriMesh;
use crate::geometry::point_triangle_distance;
use crate::trace::MeshBvh;

/// The vertices of `m` as f64, mm.
pub(crate) fn vertices(m: &TriMesh) -> impl Iterator<Item = DVec3> + '_ {
    m.vertices
        .iter()
        .map(|v| DVec3::from_array(v.map(f64::from)))
}

/// Whether `p` is inside the closed mesh of `bvh`: the parity of the crossings of a ray from
/// `p` in a direction no grid axis or diagonal shares, counted by the f64 reference, which
/// counts a crossing through a shared edge or vertex once.
pub(crate) fn inside(bvh: &MeshBvh, p: DVec3) -> bool {
    let dir = DVec3::new(0.3127, 0.8311, 0.4597);
    let ahead = bvh
        .line_crossings(p, dir)
        .iter()
        .filter(|&&t| t > 0.0)
        .count();
    ahead % 2 == 1
}

/// Triangles bucketed in a uniform grid, for distances up to a small radius.
pub(crate) struct Nearby {
    corners: Vec<[DVec3; 3]>,
    lo: DVec3,
    cell_mm: f64,
    dims: [usize; 3],
    buckets: Vec<Vec<u32>>,
}

impl Nearby {
    pub(crate) fn new(m: &TriMesh, cell_mm: f64) -> Nearby {
        let (lo, hi) = m.bounds_mm();
        let lo = lo - DVec3::splat(cell_mm);
        let dims = ((hi - lo) / cell_mm)
            .ceil()
            .as_uvec3()
            .to_array()
            .map(|d| d as usize + 2);
        let mut buckets = vec![Vec::new(); dims[0] * dims[1] * dims[2]];
        let corners: Vec<[DVec3; 3]> = m
            .triangles
            .iter()
            .map(|t| t.map(|i| DVec3::from_array(m.vertices[i as usize].map(f64::from))))
            .collect();
        let cell = |p: DVec3| {
            ((p - lo) / cell_mm)
                .floor()
                .as_uvec3()
                .to_array()
                .map(|c| c as usize)
        };
        for (t, c) in corners.iter().enumerate() {
            let (a, b) = (
                cell(c[0].min(c[1]).min(c[2])),
                cell(c[0].max(c[1]).max(c[2])),
            );
            for k in a[2]..=b[2] {
                for j in a[1]..=b[1] {
                    for i in a[0]..=b[0] {
                        buckets[i + dims[0] * (j + dims[1] * k)].push(t as u32);
                    }
                }
            }
        }
        Nearby {
            corners,
            lo,
            cell_mm,
            dims,
            buckets,
        }
    }

    /// Distance from `p` to the nearest triangle, or `radius` if none is closer.
    pub(crate) fn distance_within(&self, p: DVec3, radius: f64) -> f64 {
        let cell = |p: DVec3, d: usize| {
            let c = ((p - self.lo) / self.cell_mm).floor();
            (c.to_array()[d].max(0.0) as usize).min(self.dims[d] - 1)
        };
        let (a, b) = (p - DVec3::splat(radius), p + DVec3::splat(radius));
        let mut best = radius;
        for k in cell(a, 2)..=cell(b, 2) {
            for j in cell(a, 1)..=cell(b, 1) {
                for i in cell(a, 0)..=cell(b, 0) {
                    for &t in &self.buckets[i + self.dims[0] * (j + self.dims[1] * k)] {
                        let [u, v, w] = self.corners[t as usize];
                        best = best.min(point_triangle_distance(p, u, v, w));
                    }
                }
            }
        }
        best
    }
}

/// V − E + F of a closed triangle surface (E = 3F/2): 2 for one closed genus-0 surface.
pub(crate) fn euler_characteristic(m: &TriMesh) -> i64 {
    m.vertices.len() as i64 - (3 * m.triangles.len() / 2) as i64 + m.triangles.len() as i64
}

/// Asserts that `m` is one closed, 2-manifold, outward-wound genus-0 surface of at least
/// `min_volume_mm3` in at most `max_triangles` triangles, and prints its size.
pub(crate) fn assert_closed_genus_zero(
    name: &str,
    m: &TriMesh,
    min_volume_mm3: f64,
    max_triangles: usize,
) {
    m.check_closed().unwrap_or_else(|e| panic!("{name}: {e}"));
    let volume = m.signed_volume_mm3();
    eprintln!(
        "{name}: {} triangles, {} vertices, volume {volume:.0} mm³",
        m.triangles.len(),
        m.vertices.len()
    );
    assert!(volume >= min_volume_mm3, "{name}: volume {volume} mm³");
    assert_eq!(
        euler_characteristic(m),
        2,
        "{name}: one closed genus-0 surface"
    );
    assert!(
        m.triangles.len() <= max_triangles,
        "{name}: {} triangles",
        m.triangles.len()
    );
}

/// The vertices of `m` and the centroids of its triangles, mm.
fn vertices_and_centroids(m: &TriMesh) -> impl Iterator<Item = DVec3> + '_ {
    let centroids = m.triangles.iter().map(|t| {
        let [a, b, c] = t.map(|i| DVec3::from_array(m.vertices[i as usize].map(f64::from)));
        (a + b + c) / 3.0
    });
    vertices(m).chain(centroids)
}

/// Asserts that no vertex or triangle centroid of either of two closed meshes lies inside the
/// other, and returns the smallest distance (up to `radius`) from a vertex or centroid of `a` to
/// the surface of `b`, and where.
pub(crate) fn closest_approach(a: &TriMesh, b: &TriMesh, radius: f64) -> (f64, DVec3) {
    let (bvh_a, bvh_b) = (MeshBvh::new(a), MeshBvh::new(b));
    let near_b = Nearby::new(b, 2.0);
    let mut closest = (radius, DVec3::ZERO);
    for p in vertices_and_centroids(a) {
        assert!(
            !inside(&bvh_b, p),
            "point {p} of the first mesh lies in the second"
        );
        let d = near_b.distance_within(p, radius);
        if d < closest.0 {
            closest = (d, p);
        }
    }
    for p in vertices_and_centroids(b) {
        assert!(
            !inside(&bvh_a, p),
            "point {p} of the second mesh lies in the first"
        );
    }
    closest
}

/// Asserts that every vertex of `inner` lies inside `outer`, and returns the thinnest wall
/// between the two surfaces (up to 1 mm: the smallest distance from a vertex of either to the
/// other) and where.
pub(crate) fn thinnest_wall(outer: &TriMesh, inner: &TriMesh) -> (f64, DVec3) {
    let outer_bvh = MeshBvh::new(outer);
    let (near_outer, near_inner) = (Nearby::new(outer, 2.0), Nearby::new(inner, 2.0));
    let mut thinnest = (f64::INFINITY, DVec3::ZERO);
    for p in vertices(inner) {
        assert!(
            inside(&outer_bvh, p),
            "inner vertex {p} is outside the outer surface"
        );
        let d = near_outer.distance_within(p, 1.0);
        if d < thinnest.0 {
            thinnest = (d, p);
        }
    }
    for p in vertices(outer) {
        let d = near_inner.distance_within(p, 1.0);
        if d < thinnest.0 {
            thinnest = (d, p);
        }
    }
    eprintln!("thinnest wall: {:.3} mm at {}", thinnest.0, thinnest.1);
    thinnest
}

/// The cortex at height `y` between the outer surface `outer` and the inner one `inner`, from
/// the extents of their vertices within 1 mm of that height: on the −x, +x, −z and +z sides, mm.
pub(crate) fn cortex_mm(outer: &TriMesh, inner: &TriMesh, y: f64) -> [f64; 4] {
    let (o_lo, o_hi) = slab_extent(outer, y);
    let (i_lo, i_hi) = slab_extent(inner, y);
    [
        i_lo.x - o_lo.x,
        o_hi.x - i_hi.x,
        i_lo.z - o_lo.z,
        o_hi.z - i_hi.z,
    ]
}

/// Extents (x, z) of the vertices of `m` within 1 mm of height `y` (local frame).
pub(crate) fn slab_extent(m: &TriMesh, y: f64) -> (DVec3, DVec3) {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for p in vertices(m).filter(|p| (p.y - y).abs() < 1.0) {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    (lo, hi)
}

fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Asserts that the shipped model `file` (relative to the repository root) is byte for byte the
/// binary glTF of `mesh`, and that it loads back as a closed mesh with the same triangles;
/// `example` names the example that regenerates it.
pub(crate) fn assert_shipped(file: &str, mesh: &TriMesh, example: &str) {
    let root = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    let path = root.join(file);
    let expected = super::mesh_io::glb_bytes(mesh).unwrap();
    let shipped = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(
        sha256_hex(&shipped),
        sha256_hex(&expected),
        "{file} is out of date: run `cargo run --release --example {example} -- scenarios/models`"
    );
    let loaded = super::mesh_io::load_mesh(&path, 1000.0).unwrap();
    loaded.check_closed().unwrap();
    assert_eq!(&loaded.triangles, &mesh.triangles);
}

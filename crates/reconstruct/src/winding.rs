//! Whether a model's shadow covers a point of the detector, from the projected contour
//! generator: the winding number of the contour edges about the point (see
//! [`super::model_shadow`] for why it counts the faces over the point that face the source).
//! The outline's visibility test reads it ([`super::model_outline`]).

use glam::DVec2;

/// Height of the bands of [`Winding`]'s index, pixels.
const BAND_PX: f64 = 2.0;

/// The projected contour edges of a model at one pose, oriented as their facing faces run
/// them and filed by bands of rows: whether the shadow covers a point, as the winding number
/// of the edges about it (module docs).
pub struct Winding {
    edges: Vec<[DVec2; 2]>,
    /// The top of band 0, pixels.
    top: f64,
    /// The edges (indices) whose rows reach into each band.
    bands: Vec<Vec<u32>>,
}

impl Winding {
    /// From the contour edges, each projected from its facing face's first vertex to its second.
    pub fn new(edges: Vec<[DVec2; 2]>) -> Winding {
        let (top, bottom) = (edges.iter().flatten())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(t, b), p| {
                (t.min(p.y), b.max(p.y))
            });
        let count = if top <= bottom {
            ((bottom - top) / BAND_PX).floor() as usize + 1
        } else {
            0
        };
        let mut bands = vec![Vec::new(); count];
        for (k, [p, q]) in edges.iter().enumerate() {
            let first = ((p.y.min(q.y) - top) / BAND_PX).floor() as usize;
            let last = ((p.y.max(q.y) - top) / BAND_PX).floor() as usize;
            for band in &mut bands[first..=last.min(count - 1)] {
                band.push(k as u32);
            }
        }
        Winding { edges, top, bands }
    }

    /// Whether the winding number of the edges about `point` is not zero: an edge from p to q
    /// counts ±1 where `p.y ≤ y < q.y` (or the reverse) and it crosses that row right of
    /// `point`.
    pub fn covers(&self, point: DVec2) -> bool {
        let band = (point.y - self.top) / BAND_PX;
        let Some(edges) = (band >= 0.0)
            .then(|| self.bands.get(band as usize))
            .flatten()
        else {
            return false;
        };
        let mut winding = 0i32;
        for &k in edges {
            let [p, q] = self.edges[k as usize];
            let up = p.y <= point.y && point.y < q.y;
            let down = q.y <= point.y && point.y < p.y;
            if !(up || down) {
                continue;
            }
            let x = p.x + (point.y - p.y) * (q.x - p.x) / (q.y - p.y);
            if x > point.x {
                winding += if up { 1 } else { -1 };
            }
        }
        winding != 0
    }
}

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
    /// An edge with a coordinate that is not finite (a pose that is not) is left out.
    pub fn new(mut edges: Vec<[DVec2; 2]>) -> Winding {
        edges.retain(|[p, q]| p.is_finite() && q.is_finite());
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
            for band in bands.iter_mut().take(last + 1).skip(first) {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_square_covers_its_inside_and_an_edge_that_is_not_finite_is_left_out() {
        // A 10 × 6 px square run counter-clockwise, and a second copy inside it run the same
        // way (winding 2 there); by hand, a point is covered exactly when it lies inside.
        let square = |x0: f64, y0: f64, x1: f64, y1: f64| {
            let c = [
                DVec2::new(x0, y0),
                DVec2::new(x1, y0),
                DVec2::new(x1, y1),
                DVec2::new(x0, y1),
            ];
            (0..4).map(move |k| [c[k], c[(k + 1) % 4]])
        };
        let mut edges: Vec<[DVec2; 2]> = square(2.0, 3.0, 12.0, 9.0)
            .chain(square(4.0, 4.0, 6.0, 5.0))
            .collect();
        edges.push([DVec2::new(f64::NAN, 1.0), DVec2::new(3.0, 40.0)]);
        let w = Winding::new(edges);
        for (p, inside) in [
            (DVec2::new(7.0, 6.0), true),
            (DVec2::new(5.0, 4.5), true),
            (DVec2::new(11.9, 8.9), true),
            (DVec2::new(1.9, 6.0), false),
            (DVec2::new(7.0, 9.1), false),
            (DVec2::new(7.0, 30.0), false),
            (DVec2::new(f64::NAN, 6.0), false),
        ] {
            assert_eq!(w.covers(p), inside, "{p}");
        }
        assert!(!Winding::new(Vec::new()).covers(DVec2::new(0.0, 0.0)));
        // Only edges that are not finite (a pose gone to NaN): nothing is covered, no panic.
        let nan = DVec2::splat(f64::NAN);
        assert!(!Winding::new(vec![[nan, nan]; 3]).covers(DVec2::new(0.0, 0.0)));
    }
}

//! The detected outline of a model in one image: its shadow segmented from the background, and
//! the sub-pixel points where the shadow's edge crosses the lines between pixel centres.
//!
//! In the paper's binary images a covered pixel holds I_max and a background pixel a Poisson
//! count of mean level·I_max clamped to I_max, so at every paper noise level (even 90 %, where
//! I_max is some 27 standard deviations above the background mean at 16 bpp) the shadow is the set
//! of pixels at I_max. The model is the largest 8-connected component of them; beads, and the
//! rare background pixel that reaches I_max, are separate, smaller components and are left out.
//!
//! A pixel is covered when its centre is inside the shadow, so wherever two neighbouring pixels
//! differ the true edge crosses the segment between their centres somewhere, uniformly likely
//! along it: the midpoint is the unbiased estimate. Those midpoints are the edge points.

use glam::DVec2;

use super::detect::components;

/// A model's shadow and outline in one image.
#[derive(Debug, Clone)]
pub struct Outline {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// The shadow mask, row-major, `width × height`.
    pub mask: Vec<bool>,
    /// Number of shadow pixels.
    pub area: usize,
    /// Centroid of the shadow, continuous pixel coordinates (pixel (i, j)'s centre is
    /// (i + 0.5, j + 0.5)).
    pub centroid: DVec2,
    /// Edge points, continuous pixel coordinates: midpoints between horizontally or vertically
    /// neighbouring pixel centres of which exactly one is in the shadow.
    pub edge_points: Vec<DVec2>,
}

impl Outline {
    /// Whether pixel (column `i`, row `j`) is in the shadow; `false` outside the image.
    pub fn covered(&self, i: i64, j: i64) -> bool {
        i >= 0
            && j >= 0
            && (i as usize) < self.width
            && (j as usize) < self.height
            && self.mask[j as usize * self.width + i as usize]
    }
}

/// Segments the model's shadow (the largest component of pixels equal to `on`) in a `width`-wide
/// row-major image and extracts its outline. `None` when no pixel equals `on`.
pub fn outline(pixels: &[u16], width: usize, on: u16) -> Option<Outline> {
    let height = pixels.len() / width;
    let (labels, blobs) = components(pixels, width, on);
    let (index, largest) = blobs.iter().enumerate().max_by_key(|(_, b)| b.area)?;
    let id = index as u32 + 1;
    let mask: Vec<bool> = labels.iter().map(|&l| l == id).collect();
    let [i0, j0, i1, j1] = largest.bbox.map(|v| v as usize);
    let mut edge_points = Vec::new();
    // Every neighbouring pair with one pixel in the bounding box (extended by one pixel) is seen.
    for j in j0.saturating_sub(1)..=(j1 + 1).min(height - 1) {
        for i in i0.saturating_sub(1)..=(i1 + 1).min(width - 1) {
            let here = mask[j * width + i];
            if i + 1 < width && here != mask[j * width + i + 1] {
                edge_points.push(DVec2::new(i as f64 + 1.0, j as f64 + 0.5));
            }
            if j + 1 < height && here != mask[(j + 1) * width + i] {
                edge_points.push(DVec2::new(i as f64 + 0.5, j as f64 + 1.0));
            }
        }
    }
    Some(Outline {
        width,
        height,
        mask,
        area: largest.area,
        centroid: largest.centroid,
        edge_points,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_largest_component_is_kept_and_its_edges_lie_between_pixel_centres() {
        // A 4×3 rectangle (columns 3..7, rows 2..5) and a single bead pixel far away.
        let (w, h) = (12, 9);
        let mut img = vec![5u16; w * h];
        for j in 2..5 {
            for i in 3..7 {
                img[j * w + i] = 100;
            }
        }
        img[8 * w + 11] = 100;
        let o = outline(&img, w, 100).unwrap();
        assert_eq!(o.area, 12);
        assert_eq!(o.centroid, DVec2::new(5.0, 3.5));
        assert!(!o.covered(11, 8), "the bead is not part of the model");
        // Perimeter: 2·(4 + 3) = 14 unit edges, each giving one midpoint.
        assert_eq!(o.edge_points.len(), 14);
        // Left edge between columns 2 and 3: u = 3.0; right edge between 6 and 7: u = 7.0;
        // top edge between rows 1 and 2: v = 2.0; bottom between 4 and 5: v = 5.0.
        for p in &o.edge_points {
            let on_side = (p.x == 3.0 || p.x == 7.0) && p.y > 2.0 && p.y < 5.0
                || (p.y == 2.0 || p.y == 5.0) && p.x > 3.0 && p.x < 7.0;
            assert!(on_side, "{p}");
        }
        assert!(outline(&img, w, 101).is_none());
    }

    #[test]
    fn a_disc_outline_is_unbiased() {
        // Pixel centres inside a circle of radius 40.3 px: the edge points' mean distance from the
        // centre is the radius to well under a tenth of a pixel.
        let (w, h) = (120, 110);
        let c = DVec2::new(60.2, 54.7);
        let img: Vec<u16> = (0..w * h)
            .map(|k| {
                let p = DVec2::new((k % w) as f64 + 0.5, (k / w) as f64 + 0.5);
                if (p - c).length() <= 40.3 { 1 } else { 0 }
            })
            .collect();
        let o = outline(&img, w, 1).unwrap();
        let mean = o.edge_points.iter().map(|p| (*p - c).length()).sum::<f64>()
            / o.edge_points.len() as f64;
        assert!((mean - 40.3).abs() < 0.05, "{mean}");
    }
}

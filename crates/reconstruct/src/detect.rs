//! Finding blobs in a binary-mode image: 8-connected components of pixels at I_max, with their
//! sub-pixel centroids.
//!
//! The paper's images put I_max where an object covers the pixel and Poisson noise (mean
//! level·I_max, clamped to I_max) everywhere else, so a noisy background pixel reaches I_max only
//! by chance. Such pixels form tiny components; [`Blob::area`] lets the caller keep only blobs of
//! a bead's expected size, which is what keeps detection right at every noise level. Two touching
//! beads make one blob; [`super::split::bead_blobs`] gives each its own.

use glam::DVec2;

/// A connected component of covered pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct Blob {
    /// Centroid in continuous pixel coordinates (pixel (i, j)'s centre is (i + 0.5, j + 0.5)).
    pub centroid: DVec2,
    /// Number of pixels.
    pub area: usize,
    /// Bounding box `[i_min, j_min, i_max, j_max]`, inclusive.
    pub bbox: [u32; 4],
}

/// The area (pixels) of a bead image of `radius_px`.
pub fn bead_area_px(radius_px: f64) -> f64 {
    std::f64::consts::PI * radius_px * radius_px
}

/// The smallest and the largest pixel count of one bead's blob when a bead's image is expected
/// to cover `expected_px` pixels: the pixel-centre sampling of a small disc, a magnification a
/// few per cent off and motion blur all change the count.
pub fn one_bead_area_range_px(expected_px: f64) -> (f64, f64) {
    (0.45 * expected_px, 1.6 * expected_px + 2.0)
}

/// Whether a blob of `area_px` pixels fits one bead expected to cover `expected_px` pixels
/// ([`one_bead_area_range_px`]): not a merged pair, not a noise speck, not a mesh shadow.
pub fn fits_one_bead(area_px: usize, expected_px: f64) -> bool {
    let (min, max) = one_bead_area_range_px(expected_px);
    (min..=max).contains(&(area_px as f64))
}

/// Every 8-connected component of pixels equal to `on` in a `width`-wide row-major image.
pub fn blobs(pixels: &[u16], width: usize, on: u16) -> Vec<Blob> {
    components(pixels, width, on).1
}

/// [`blobs`] with the label image: `labels[k]` is 1 + the index of pixel `k`'s blob, or 0 for a
/// pixel that is not `on`.
pub fn components(pixels: &[u16], width: usize, on: u16) -> (Vec<u32>, Vec<Blob>) {
    components_where(pixels, width, |v| v == on)
}

/// [`components`] of the pixels at `min` or above.
pub fn components_at_least(pixels: &[u16], width: usize, min: u16) -> (Vec<u32>, Vec<Blob>) {
    components_where(pixels, width, |v| v >= min)
}

/// The 8-connected components of the pixels whose value `on` accepts, with the label image.
fn components_where(
    pixels: &[u16],
    width: usize,
    on: impl Fn(u16) -> bool,
) -> (Vec<u32>, Vec<Blob>) {
    if width == 0 {
        return (vec![0; pixels.len()], Vec::new());
    }
    let height = pixels.len() / width;
    let mut label = vec![0u32; pixels.len()];
    let mut out = Vec::new();
    let mut stack = Vec::new();
    for start in 0..pixels.len() {
        if !on(pixels[start]) || label[start] != 0 {
            continue;
        }
        let id = out.len() as u32 + 1;
        label[start] = id;
        stack.push(start);
        let (mut su, mut sv, mut n) = (0.0f64, 0.0f64, 0usize);
        let mut bbox = [u32::MAX, u32::MAX, 0, 0];
        while let Some(k) = stack.pop() {
            let (i, j) = (k % width, k / width);
            su += i as f64 + 0.5;
            sv += j as f64 + 0.5;
            n += 1;
            bbox = [
                bbox[0].min(i as u32),
                bbox[1].min(j as u32),
                bbox[2].max(i as u32),
                bbox[3].max(j as u32),
            ];
            for dj in -1i64..=1 {
                for di in -1i64..=1 {
                    let (x, y) = (i as i64 + di, j as i64 + dj);
                    if x < 0 || y < 0 || x >= width as i64 || y >= height as i64 {
                        continue;
                    }
                    let q = y as usize * width + x as usize;
                    if on(pixels[q]) && label[q] == 0 {
                        label[q] = id;
                        stack.push(q);
                    }
                }
            }
        }
        out.push(Blob {
            centroid: DVec2::new(su / n as f64, sv / n as f64),
            area: n,
            bbox,
        });
    }
    (label, out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn components_centroids_and_areas() {
        // A 3×3 square at columns 2..4, rows 1..3, and a diagonal pair touching by a corner.
        let (w, h) = (10, 8);
        let mut img = vec![0u16; w * h];
        for j in 1..4 {
            for i in 2..5 {
                img[j * w + i] = 7;
            }
        }
        img[6 * w + 7] = 7;
        img[7 * w + 8] = 7;
        img[0] = 6; // not `on`
        let b = blobs(&img, w, 7);
        assert_eq!(b.len(), 2);
        assert_eq!(b[0].area, 9);
        assert_eq!(b[0].centroid, DVec2::new(3.5, 2.5));
        assert_eq!(b[0].bbox, [2, 1, 4, 3]);
        assert_eq!(b[1].area, 2);
        assert_eq!(b[1].centroid, DVec2::new(8.0, 7.0));
    }
}

//! Path lengths as the renderer receives them: one layer per solid and material, each over the
//! rectangle of pixels the solid's shadow covers, summed per material one row at a time (no W×H
//! image per material is ever held).

use std::ops::Range;

/// One solid's path lengths (mm) over a rectangle of pixels, added to (`sign` +1) or taken from
/// (`sign` −1, a solid nested in another displaces the outer one's material) one material.
#[derive(Debug, Clone)]
pub struct Layer<'a> {
    /// Index of the material (into [`super::Scene::mu_per_mm`]).
    pub material: usize,
    /// +1 or −1.
    pub sign: f64,
    /// Pixel columns of the rectangle (half-open).
    pub columns: Range<usize>,
    /// Pixel rows of the rectangle (half-open).
    pub rows: Range<usize>,
    /// Path lengths over the rectangle, row-major, mm (≥ 0).
    pub length_mm: &'a [f64],
}

impl<'a> Layer<'a> {
    /// A layer over the whole `width × height` image: `length_mm` row-major (`width·height`
    /// values), added to `material`.
    pub fn image(material: usize, width: usize, height: usize, length_mm: &'a [f64]) -> Self {
        Layer {
            material,
            sign: 1.0,
            columns: 0..width,
            rows: 0..height,
            length_mm,
        }
    }

    /// One layer per non-empty image of `images` (material `m` = its index), each `width ×
    /// height`: the layers of per-material length images.
    pub fn images(width: usize, height: usize, images: &'a [Vec<f64>]) -> Vec<Self> {
        images
            .iter()
            .enumerate()
            .filter(|(_, l)| !l.is_empty())
            .map(|(m, l)| Layer::image(m, width, height, l))
            .collect()
    }

    /// Whether the rectangle's size matches `length_mm` and lies within `width × height`.
    pub(crate) fn fits(&self, width: usize, height: usize) -> bool {
        self.columns.start <= self.columns.end
            && self.rows.start <= self.rows.end
            && self.columns.end <= width
            && self.rows.end <= height
            && self.columns.len().checked_mul(self.rows.len()) == Some(self.length_mm.len())
    }
}

/// Row `j` of material `material`'s summed path length (mm), unclamped: `out` (W long) is set to
/// 0, then every layer of that material covering row `j` adds `sign × length`, layers in slice
/// order. Every pixel's sum therefore runs over the layers in a fixed order from 0, the same
/// bits as adding the layers into a zeroed W×H image one after the other. A negative result
/// means nested solids cross more than their container (see `attenuation`).
///
/// Returns the columns touched by some layer (empty range when none).
pub fn material_row(layers: &[Layer], material: usize, j: usize, out: &mut [f64]) -> Range<usize> {
    out.fill(0.0);
    let (mut lo, mut hi) = (usize::MAX, 0);
    for l in layers {
        if l.material != material || !l.rows.contains(&j) || l.columns.is_empty() {
            continue;
        }
        let cols = l.columns.len();
        let k = (j - l.rows.start) * cols;
        for (dst, &v) in out[l.columns.clone()]
            .iter_mut()
            .zip(&l.length_mm[k..k + cols])
        {
            *dst += l.sign * v;
        }
        lo = lo.min(l.columns.start);
        hi = hi.max(l.columns.end);
    }
    if lo < hi { lo..hi } else { 0..0 }
}

/// [`material_row`] with a negative sum (rounding of nested solids) set to 0: material
/// `material`'s net path length on row `j`, as the response uses it. Returns the columns
/// touched by some layer.
pub fn net_material_row(
    layers: &[Layer],
    material: usize,
    j: usize,
    out: &mut [f64],
) -> Range<usize> {
    let span = material_row(layers, material, j, out);
    for l in &mut out[span.clone()] {
        if *l < 0.0 {
            *l = 0.0;
        }
    }
    span
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_sum_layers_in_order_with_signs() {
        // 6 × 3 image; material 0: a 3 × 2 rectangle at (1, 1) minus a 1 × 1 at (2, 2);
        // material 1: the whole image.
        let outer = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let inner = [0.5];
        let full: Vec<f64> = (0..18).map(|p| p as f64 * 0.25).collect();
        let layers = [
            Layer {
                material: 0,
                sign: 1.0,
                columns: 1..4,
                rows: 1..3,
                length_mm: &outer,
            },
            Layer {
                material: 0,
                sign: -1.0,
                columns: 2..3,
                rows: 2..3,
                length_mm: &inner,
            },
            Layer::image(1, 6, 3, &full),
        ];
        assert!(layers.iter().all(|l| l.fits(6, 3)));
        let mut row = [9.0; 6];
        assert_eq!(material_row(&layers, 0, 0, &mut row), 0..0);
        assert_eq!(row, [0.0; 6]);
        assert_eq!(material_row(&layers, 0, 1, &mut row), 1..4);
        assert_eq!(row, [0.0, 1.0, 2.0, 3.0, 0.0, 0.0]);
        assert_eq!(material_row(&layers, 0, 2, &mut row), 1..4);
        assert_eq!(row, [0.0, 4.0, 4.5, 6.0, 0.0, 0.0]);
        assert_eq!(material_row(&layers, 1, 2, &mut row), 0..6);
        assert_eq!(row, [3.0, 3.25, 3.5, 3.75, 4.0, 4.25]);
        // A nested layer larger than its container: the raw sum goes negative, the net one is 0.
        let big = [9.0];
        let mut over = layers.to_vec();
        over.push(Layer {
            material: 0,
            sign: -1.0,
            columns: 3..4,
            rows: 1..2,
            length_mm: &big,
        });
        material_row(&over, 0, 1, &mut row);
        assert_eq!(row, [0.0, 1.0, 2.0, -6.0, 0.0, 0.0]);
        assert_eq!(net_material_row(&over, 0, 1, &mut row), 1..4);
        assert_eq!(row, [0.0, 1.0, 2.0, 0.0, 0.0, 0.0]);
        let bad = Layer {
            material: 0,
            sign: 1.0,
            columns: 4..7,
            rows: 0..1,
            length_mm: &inner,
        };
        assert!(!bad.fits(6, 3));
    }
}

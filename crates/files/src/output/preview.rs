//! 8-bit grayscale PNG previews of detector images, for people (the manual's figures, a quick look):
//! never evidence. The TIFF and EXR files are the images; a preview is windowed and scaled.
//!
//! - **Window.** From the 0.5th to the 99.5th percentile of the image's pixel values (nearest
//!   rank: the values at sorted positions ⌊0.005·(n − 1)⌋ and ⌈0.995·(n − 1)⌉): values at or
//!   below the low one are black (0), at or above the high one white (255), linear in between.
//!   When both are equal (a flat image, or one value in more than 99 % of the pixels) that value
//!   is mid-grey (128), lower values black and higher ones white.
//! - **Scale.** Area averaging (each output pixel the mean of the windowed input over its
//!   footprint, fractional pixels weighted by their covered fraction), down so that the longer
//!   side is at most `max_side_px`; the shorter side keeps the aspect ratio (rounded, at least
//!   1 px). Images are never scaled up.
//! - **Bytes.** The pinned `png` crate with fixed settings ([`COMPRESSION`], [`FILTER`], no
//!   metadata chunks) and arithmetic only (no libm): the same image gives the same bytes on
//!   every platform.

use png::{BitDepth, ColorType, Compression, Encoder, Filter};

/// Compression of every preview.
pub const COMPRESSION: Compression = Compression::Balanced;
/// Row filter of every preview.
pub const FILTER: Filter = Filter::Adaptive;
/// Gap between the images of [`side_by_side`], px (white).
pub const GAP_PX: u32 = 8;

/// The grey of a flat image.
const MID_GREY: u8 = 128;

/// An 8-bit grayscale PNG of a detector image for people (never evidence): window from the 0.5th
/// to the 99.5th percentile of the pixel values (a flat image maps to mid-grey), area-averaged
/// down so the longer side is at most `max_side_px`, deterministic bytes (pinned `png` crate,
/// fixed settings). See the module documentation for the exact rules.
///
/// `pixels` holds `width × height` values row by row (row 0 first). Pixels beyond that are
/// ignored and missing ones count as 0; an image without pixels gives a 1 × 1 mid-grey PNG.
/// `max_side_px` 0 counts as 1.
pub fn preview_png(pixels: &[u16], width: u32, height: u32, max_side_px: u32) -> Vec<u8> {
    let gray = windowed_and_scaled(pixels, width, height, max_side_px);
    encode(&gray.values, gray.width, gray.height)
}

/// Several previews side by side with a small gap (for the manual's figures), each already windowed.
/// Each image `(pixels, width, height)` is windowed on its own percentiles and scaled as by
/// [`preview_png`]; they stand left to right in the given order, centred vertically, [`GAP_PX`]
/// apart on white. No images give a 1 × 1 mid-grey PNG.
pub fn side_by_side(images: &[(&[u16], u32, u32)], max_side_px: u32) -> Vec<u8> {
    let parts: Vec<Gray> = images
        .iter()
        .map(|&(pixels, w, h)| windowed_and_scaled(pixels, w, h, max_side_px))
        .collect();
    if parts.is_empty() {
        return encode(&[MID_GREY], 1, 1);
    }
    let height = parts.iter().map(|g| g.height).max().unwrap_or(1);
    let width = parts.iter().map(|g| g.width).sum::<u32>() + GAP_PX * (parts.len() as u32 - 1);
    let mut canvas = vec![255u8; width as usize * height as usize];
    let mut left = 0usize;
    for g in &parts {
        let top = ((height - g.height) / 2) as usize;
        for row in 0..g.height as usize {
            let src = &g.values[row * g.width as usize..(row + 1) * g.width as usize];
            let start = (top + row) * width as usize + left;
            canvas[start..start + src.len()].copy_from_slice(src);
        }
        left += (g.width + GAP_PX) as usize;
    }
    encode(&canvas, width, height)
}

/// An 8-bit grayscale picture, row by row.
#[derive(Debug, Clone, PartialEq)]
struct Gray {
    values: Vec<u8>,
    width: u32,
    height: u32,
}

/// The low and high window values (see the module documentation), or `None` without pixels.
fn window(pixels: &[u16]) -> Option<(u16, u16)> {
    if pixels.is_empty() {
        return None;
    }
    // A histogram gives exact order statistics in O(n) for 16-bit values.
    let mut histogram = vec![0u64; 1 << 16];
    for &p in pixels {
        histogram[usize::from(p)] += 1;
    }
    let last = pixels.len() as u64 - 1;
    let rank_lo = last * 5 / 1000;
    let rank_hi = (last * 995).div_ceil(1000);
    let value_at = |rank: u64| {
        let mut seen = 0u64;
        for (value, &count) in histogram.iter().enumerate() {
            seen += count;
            if seen > rank {
                return value as u16;
            }
        }
        u16::MAX
    };
    Some((value_at(rank_lo), value_at(rank_hi)))
}

/// Maps a pixel value through the window `[lo, hi]` to a grey level in [0, 255] (not yet
/// rounded); a degenerate window (`lo == hi`) puts that value at mid-grey.
fn windowed(value: u16, lo: u16, hi: u16) -> f64 {
    if value < lo || (value == lo && lo < hi) {
        0.0
    } else if value > hi || (value == hi && lo < hi) {
        255.0
    } else if lo == hi {
        f64::from(MID_GREY)
    } else {
        255.0 * f64::from(value - lo) / f64::from(hi - lo)
    }
}

/// For each output index along one axis of `n_in` input pixels scaled to `n_out`: the input
/// pixels it covers and their weights (covered fractions, summing to `n_in / n_out`).
fn footprints(n_in: u32, n_out: u32) -> Vec<Vec<(usize, f64)>> {
    let scale = f64::from(n_in) / f64::from(n_out);
    (0..n_out)
        .map(|o| {
            let (a, b) = (f64::from(o) * scale, f64::from(o + 1) * scale);
            let first = a.floor() as usize;
            let last = (b.ceil() as usize).min(n_in as usize);
            (first..last)
                .filter_map(|i| {
                    let overlap = b.min(i as f64 + 1.0) - a.max(i as f64);
                    (overlap > 0.0).then_some((i, overlap))
                })
                .collect()
        })
        .collect()
}

/// The output size: longer side at most `max_side` (never enlarged), aspect ratio kept.
fn output_size(width: u32, height: u32, max_side: u32) -> (u32, u32) {
    let long = width.max(height);
    let target = long.min(max_side.max(1));
    let short = |side: u32| {
        let scaled =
            (u64::from(side) * u64::from(target) * 2 + u64::from(long)) / (2 * u64::from(long));
        (scaled as u32).clamp(1, side)
    };
    if width >= height {
        (target, short(height))
    } else {
        (short(width), target)
    }
}

fn windowed_and_scaled(pixels: &[u16], width: u32, height: u32, max_side_px: u32) -> Gray {
    let n = width as usize * height as usize;
    // Missing pixels count as 0 (the window included).
    let pixels: std::borrow::Cow<[u16]> = if pixels.len() >= n {
        std::borrow::Cow::Borrowed(&pixels[..n])
    } else {
        let mut padded = pixels.to_vec();
        padded.resize(n, 0);
        std::borrow::Cow::Owned(padded)
    };
    let Some((lo, hi)) = window(&pixels).filter(|_| width > 0 && height > 0) else {
        return Gray {
            values: vec![MID_GREY],
            width: 1,
            height: 1,
        };
    };
    let (out_w, out_h) = output_size(width, height, max_side_px);
    let (fx, fy) = (footprints(width, out_w), footprints(height, out_h));
    let value = |i: usize, j: usize| windowed(pixels[j * width as usize + i], lo, hi);
    // Horizontal pass per input row, then vertical pass: each a weighted mean over the footprint.
    let area_x = f64::from(width) / f64::from(out_w);
    let rows: Vec<Vec<f64>> = (0..height as usize)
        .map(|j| {
            fx.iter()
                .map(|fp| fp.iter().map(|&(i, w)| w * value(i, j)).sum::<f64>() / area_x)
                .collect()
        })
        .collect();
    let area_y = f64::from(height) / f64::from(out_h);
    let mut values = Vec::with_capacity(out_w as usize * out_h as usize);
    for fp in &fy {
        for o in 0..out_w as usize {
            let mean = fp.iter().map(|&(j, w)| w * rows[j][o]).sum::<f64>() / area_y;
            values.push((mean + 0.5).floor().clamp(0.0, 255.0) as u8);
        }
    }
    Gray {
        values,
        width: out_w,
        height: out_h,
    }
}

/// Encodes an 8-bit grayscale image (`width`, `height` ≥ 1, `values.len() == width · height`).
fn encode(values: &[u8], width: u32, height: u32) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut encoder = Encoder::new(&mut bytes, width, height);
    encoder.set_color(ColorType::Grayscale);
    encoder.set_depth(BitDepth::Eight);
    encoder.set_compression(COMPRESSION);
    encoder.set_filter(FILTER);
    // Writing to memory fails only for an inconsistent size, which the callers rule out.
    let written = encoder.write_header().and_then(|mut writer| {
        writer.write_image_data(values)?;
        writer.finish()
    });
    match written {
        Ok(()) => bytes,
        Err(e) => unreachable!(
            "PNG of {width} × {height} from {} values: {e}",
            values.len()
        ),
    }
}

#[cfg(test)]
mod tests;

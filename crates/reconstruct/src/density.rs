//! From an attenuation-mode image's stored values to what the realistic detectors work on: the
//! attenuation line integral `ln(S_open / S)` of every pixel (dense matter high, whatever the
//! stored polarity) and the transmission `S / S_open`, in which blur is linear.
//!
//! The program reads only the nominal imaging settings an operator knows from the detector's
//! set-up: the polarity, `radiograph_range` and `offset` (`[imaging.detector]`).
//!
//! * `radiograph` polarity stores `I_max · clamp(ln(S_open/S) / range, 0, 1)`: the attenuation is
//!   `value · range / I_max`; a value at `I_max` is clipped (at least `range`).
//! * `raw` polarity stores `offset + gain · S`: the attenuation is `ln(S_ref / (value − offset))`
//!   with `S_ref` the image's open-field level, estimated as its 99.9th percentile above the
//!   offset (the constant does not matter to the detectors, which subtract local backgrounds).
//!   A pixel attenuating more than the default radiograph range (7, a transmission below
//!   e⁻⁷ ≈ 0.09 % of the open field) counts as clipped, as radiograph polarity would show it.

use crate::scenario::{Imaging, PolarityOption};

/// The smallest signal above the offset (DN) that `raw` polarity takes the logarithm of: values at
/// or below the offset read as this.
const RAW_FLOOR_DN: f64 = 0.5;

/// Default `radiograph_range` (the attenuation shown as I_max), as the simulator's.
const DEFAULT_RADIOGRAPH_RANGE: f64 = 7.0;

/// How the stored values of an attenuation-mode image map to attenuation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Reading {
    /// Dense bright: attenuation = `value · range / i_max`.
    Radiograph {
        /// The attenuation shown as I_max.
        range: f64,
        /// I_max = 2^bpp − 1.
        i_max: u16,
    },
    /// Dense dark: `value = offset + gain · S`.
    Raw {
        /// Dark offset, DN.
        offset: f64,
        /// I_max = 2^bpp − 1.
        i_max: u16,
    },
}

impl Reading {
    /// The reading of a detector of `i_max` under the scenario's nominal `imaging` settings.
    pub fn of(imaging: &Imaging, i_max: u16) -> Reading {
        match imaging.detector.polarity {
            PolarityOption::Radiograph => Reading::Radiograph {
                range: imaging
                    .detector
                    .radiograph_range
                    .unwrap_or(DEFAULT_RADIOGRAPH_RANGE),
                i_max,
            },
            PolarityOption::Raw => Reading::Raw {
                offset: imaging.detector.offset.unwrap_or(0.0),
                i_max,
            },
        }
    }
}

/// An image as attenuation.
#[derive(Debug, Clone)]
pub struct Density {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Attenuation `ln(S_open / S)` per pixel (up to an image-wide constant in `raw` polarity),
    /// row-major.
    pub values: Vec<f64>,
    /// Whether the pixel is clipped: white in `radiograph` polarity (its attenuation is a lower
    /// bound only), attenuating more than the default radiograph range in `raw` polarity.
    pub clipped: Vec<bool>,
}

impl Density {
    /// The attenuation at pixel (column `i`, row `j`), which must be inside the image.
    pub fn at(&self, i: usize, j: usize) -> f64 {
        self.values[j * self.width + i]
    }

    /// The transmission `S / S_open` at pixel (`i`, `j`) (up to a constant factor in `raw`).
    pub fn transmission(&self, i: usize, j: usize) -> f64 {
        libm::exp(-self.at(i, j))
    }

    /// The image blurred by a separable Gaussian of `sigma_px` (> 0) in transmission, where a
    /// detector's blur acts, the image clamped at its borders; the clipped flags are kept. For
    /// tests and studies of the detectors under blur (the program itself never blurs).
    pub fn blurred(&self, sigma_px: f64) -> Density {
        let (w, h) = (self.width, self.height);
        let t: Vec<f64> = self.values.iter().map(|v| libm::exp(-v)).collect();
        let half = (4.0 * sigma_px).ceil().max(0.0) as i64;
        let kernel: Vec<f64> = (-half..=half)
            .map(|x| libm::exp(-((x * x) as f64) / (2.0 * sigma_px * sigma_px)))
            .collect();
        let norm: f64 = kernel.iter().sum();
        let pass = |src: &[f64], horizontal: bool| -> Vec<f64> {
            let mut out = vec![0.0; w * h];
            for j in 0..h {
                for i in 0..w {
                    let mut acc = 0.0;
                    for (n, k) in kernel.iter().enumerate() {
                        let d = n as i64 - half;
                        let (x, y) = if horizontal {
                            ((i as i64 + d).clamp(0, w as i64 - 1), j as i64)
                        } else {
                            (i as i64, (j as i64 + d).clamp(0, h as i64 - 1))
                        };
                        acc += k * src[y as usize * w + x as usize];
                    }
                    out[j * w + i] = acc / norm;
                }
            }
            out
        };
        let blurred = pass(&pass(&t, true), false);
        Density {
            width: w,
            height: h,
            values: blurred.iter().map(|v| -libm::log(*v)).collect(),
            clipped: self.clipped.clone(),
        }
    }
}

/// Converts a `width`-wide row-major image read as `reading`.
pub fn density(pixels: &[u16], width: usize, reading: Reading) -> Density {
    let height = pixels.len().checked_div(width).unwrap_or(0);
    let (values, clipped) = match reading {
        Reading::Radiograph { range, i_max } => {
            let scale = range / f64::from(i_max.max(1));
            (
                pixels.iter().map(|&v| f64::from(v) * scale).collect(),
                pixels.iter().map(|&v| v >= i_max).collect(),
            )
        }
        Reading::Raw { offset, i_max: _ } => {
            let reference = open_level(pixels, offset);
            let ln_ref = libm::log(reference);
            // One logarithm per possible value, not per pixel (the same bits).
            let attenuation: Vec<f64> = (0..=u16::MAX)
                .map(|v| ln_ref - libm::log((f64::from(v) - offset).max(RAW_FLOOR_DN)))
                .collect();
            let of = |v: u16| attenuation[usize::from(v)];
            (
                pixels.iter().map(|&v| of(v)).collect(),
                pixels
                    .iter()
                    .map(|&v| of(v) >= DEFAULT_RADIOGRAPH_RANGE)
                    .collect(),
            )
        }
    };
    Density {
        width,
        height,
        values,
        clipped,
    }
}

/// The open-field level of a raw image above `offset`: its 99.9th percentile (at least
/// [`RAW_FLOOR_DN`]).
fn open_level(pixels: &[u16], offset: f64) -> f64 {
    if pixels.is_empty() {
        return 1.0;
    }
    let mut counts = vec![0usize; 65536];
    for &v in pixels {
        counts[usize::from(v)] += 1;
    }
    let wanted = pixels.len() - pixels.len() / 1000;
    let mut seen = 0;
    let mut level = 0usize;
    for (v, &n) in counts.iter().enumerate() {
        seen += n;
        if seen >= wanted.max(1) {
            level = v;
            break;
        }
    }
    (level as f64 - offset).max(RAW_FLOOR_DN)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radiograph_and_raw_read_the_same_attenuation() {
        // Open field 1000 DN (raw), an object of attenuation 2 and a clipped one.
        let i_max = 4095u16;
        let range = 7.0;
        let open = 1000.0;
        let att = [0.0, 2.0, 9.0];
        let raw: Vec<u16> = att
            .iter()
            .cycle()
            .take(3000)
            .enumerate()
            .map(|(k, a)| {
                if k < 2990 {
                    open as u16
                } else {
                    (open * libm::exp(-a)).round() as u16
                }
            })
            .collect();
        let rad: Vec<u16> = att
            .iter()
            .map(|a| ((f64::from(i_max) * (a / range)).min(f64::from(i_max))).round() as u16)
            .collect();
        let d = density(&rad, 3, Reading::Radiograph { range, i_max });
        assert!((d.values[1] - 2.0).abs() < 2e-3);
        assert_eq!(d.clipped, vec![false, false, true]);
        let r = density(&raw, 3000, Reading::Raw { offset: 0.0, i_max });
        assert_eq!(r.values[0], 0.0);
        // The last ten pixels cycle through the attenuations: 2990 % 3 = 2 → 9.0 (rounds to 0 DN,
        // clipped), then 0, 2, …
        assert!(r.clipped[2990]);
        assert!((r.values[2992] - 2.0).abs() < 5e-3, "{}", r.values[2992]);
        assert!((d.transmission(1, 0) - libm::exp(-2.0)).abs() < 1e-3);
    }
}

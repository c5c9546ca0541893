//! The options of [`super::render_expected`]: the detector's unsharpness and extra noise, all
//! off by default.

use super::{Psf, Scatter};

/// What [`super::render_expected`] adds to the quantum noise of an expected image. The default
/// adds nothing (the output is then [`super::render`]'s, bit for bit).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Unsharpness {
    /// Scatter added to the expected image before the quantum noise (an approximation: one
    /// scatter-to-primary ratio and one broad kernel for the whole image; see [`Scatter`]).
    pub scatter: Option<Scatter>,
    /// The detector's point-spread function (scintillator light spread), applied to the noisy
    /// signal after the quantum noise, so it correlates the noise; also to the flat field of a
    /// radiograph. See [`Psf`].
    pub psf: Option<Psf>,
    /// SD of the additive Gaussian electronic (read-out) noise, in DN (≥ 0, finite; 0 = none).
    /// Added to `offset + gain · S` before rounding and clipping; in a radiograph the signal
    /// becomes `S + noise/gain`.
    pub electronic_noise_dn: f64,
}

impl Unsharpness {
    /// Checks the plain numbers (the kernels check themselves when built): the message names
    /// the field and what would be valid.
    pub fn check(&self) -> Result<(), String> {
        let e = self.electronic_noise_dn;
        if !(e >= 0.0 && e.is_finite()) {
            return Err(format!(
                "electronic_noise_dn = {e} is not valid (must be finite and ≥ 0 DN)"
            ));
        }
        Ok(())
    }

    /// The electronic noise SD when some is to be drawn (positive and finite).
    pub(crate) fn electronic_sd_dn(&self) -> Option<f64> {
        let e = self.electronic_noise_dn;
        (e > 0.0 && e.is_finite()).then_some(e)
    }
}

//! The noise-free expected image as a whole ([`Expected`]): what [`super::render`] draws from,
//! held for every pixel so that a caller can average several of them (sub-pixel samples,
//! focal-spot sub-sources) and [`super::render_expected`] can blur and noise the result.

use rayon::prelude::*;

use super::bins::Bins;
use super::{Beam, DetectorModel, Prepared, RenderScratch, Scene, open_signal};

/// The noise-free expected values of every pixel of an image or of a strip of one.
///
/// All three images are `width × height`, row-major (row 0 the first stored row). A caller may
/// fill one itself, e.g. as a weighted mean of several [`expected`] results (weights summing to
/// 1 keep the open field's meaning); [`super::render_expected`] takes any non-negative finite
/// values.
#[derive(Debug, Clone, PartialEq)]
pub struct Expected {
    /// Pixels per row (W).
    pub width: usize,
    /// Rows (H).
    pub height: usize,
    /// Expected detected quanta Q per pixel (the Poisson mean), row-major.
    pub quanta: Vec<f64>,
    /// Expected detected energy E per pixel, keV (always filled, also for photon counting).
    pub energy_kev: Vec<f64>,
    /// Expected open-field signal per pixel `S_open = f_p · S_ref` (counts for photon counting,
    /// keV for energy integrating, as `det.response`): what a radiograph divides by. See
    /// [`open_signal_per_fluence`] for `S_ref`.
    pub open_signal: Vec<f64>,
}

impl Expected {
    /// Whether the three images each hold `width × height` values.
    pub fn is_consistent(&self) -> bool {
        let n = self.width.checked_mul(self.height);
        n == Some(self.quanta.len())
            && n == Some(self.energy_kev.len())
            && n == Some(self.open_signal.len())
    }
}

/// The expected open-field signal at unit fluence, `S_ref`: `Σ_b N_b·η_b` counts (photon
/// counting) or `Σ_b N_b·η_b·e_b` keV (energy integrating), bins ascending from 0. A pixel of
/// relative fluence `f` has `S_open = f · S_ref` ([`Expected::open_signal`]).
///
/// # Panics
/// When `beam.energies_kev`, `beam.photons_per_pixel` and `det.efficiency` differ in length.
pub fn open_signal_per_fluence(det: &DetectorModel, beam: &Beam) -> f64 {
    open_signal(det.response, &Bins::new(beam, &det.efficiency))
}

/// The expected image of `scene`: bit for bit the values [`super::render`] draws from
/// (`quanta`), scales by (`energy_kev`, here filled for either response) and divides by
/// (`open_signal`), so `render_expected(det, &expected(beam, det, scene),
/// &Unsharpness::default(), key, ek)` is `render(beam, det, scene, key)`.
///
/// # Panics
/// When the shapes disagree (see [`super::check_inputs`]).
pub fn expected(beam: &Beam, det: &DetectorModel, scene: &Scene) -> Expected {
    let prep = Prepared::new(beam, det, scene);
    let (w, h) = (scene.width, scene.height);
    let open = open_signal(det.response, &prep.bins);
    let mut quanta = vec![0.0; w * h];
    let mut energy_kev = vec![0.0; w * h];
    let mut open_signal = vec![0.0; w * h];
    if w > 0 {
        quanta
            .par_chunks_mut(w)
            .zip(energy_kev.par_chunks_mut(w))
            .zip(open_signal.par_chunks_mut(w))
            .enumerate()
            .for_each_init(RenderScratch::default, |s, (j, ((q, e), o))| {
                prep.row(scene, j, &mut s.fluence, &mut s.rows, q, Some(e));
                for (o, &f) in o.iter_mut().zip(&s.fluence) {
                    *o = f * open;
                }
            });
    }
    Expected {
        width: w,
        height: h,
        quanta,
        energy_kev,
        open_signal,
    }
}

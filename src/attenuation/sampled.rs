//! The expected image of one exposure with area sampling, a focal spot and the heel effect:
//! per sub-source and per strip of pixel rows, the exact path lengths of every part at the
//! pixel samples (`crate::sampling::strip`), their expected quanta, energy and open-field signal
//! (`crate::response::expected`, photons per *pixel* of the detector: each sample stands for its
//! whole pixel), averaged into the detector's pixels with the sub-source's weight and 1/s² per
//! sample (sub-sources in order, then samples row by row: a fixed order). The heel factor of
//! each pixel centre multiplies all three. What the detector does with it is
//! `crate::response::render_expected`.

use glam::DVec3;

use crate::geometry::DetectorFrame;
use crate::response::{self, Beam, DetectorModel, Expected, Fluence, PointSourceFluence, Scene};
use crate::sampling::Sampling;
use crate::sampling::strip::{STRIP_SAMPLES, add_blocks, strips};

use super::image::{layers_of, shadows_of};
use super::scene::Part;
use super::setup::Setup;

/// The expected image of `parts` on `frame` from the spot centred at `source_mm`, for the
/// detector's photons `beam` (per pixel of `frame`) and `detector`.
pub fn expected(
    setup: &Setup,
    parts: &[Part],
    frame: &DetectorFrame,
    source_mm: DVec3,
    beam: &Beam,
    detector: &DetectorModel,
    sampling: &Sampling,
) -> Expected {
    let [w, h] = frame.pixels.map(|n| n as usize);
    let s = sampling.samples_per_side.max(1) as usize;
    let mut out = Expected {
        width: w,
        height: h,
        quanta: vec![0.0; w * h],
        energy_kev: vec![0.0; w * h],
        open_signal: vec![0.0; w * h],
    };
    let per_sample = 1.0 / (s * s) as f64;
    let strips = strips(frame, s as u32, STRIP_SAMPLES);
    for (src, weight) in sampling.sources(frame, source_mm) {
        for st in &strips {
            let shadows = shadows_of(parts, &st.frame, src);
            let layers = layers_of(parts, &shadows);
            let fluence = PointSourceFluence::new(&st.frame, src);
            let [fw, fh] = st.frame.pixels.map(|n| n as usize);
            let scene = Scene {
                width: fw,
                height: fh,
                mu_per_mm: &setup.mu_per_mm,
                layers: &layers,
                fluence: Fluence::PointSource(&fluence),
            };
            let fine = response::expected(beam, detector, &scene);
            let rows = st.first_row as usize * w..(st.first_row + st.rows) as usize * w;
            let k = weight * per_sample;
            add_blocks(&fine.quanta, w, s, k, &mut out.quanta[rows.clone()]);
            add_blocks(&fine.energy_kev, w, s, k, &mut out.energy_kev[rows.clone()]);
            add_blocks(&fine.open_signal, w, s, k, &mut out.open_signal[rows]);
        }
    }
    if let Some(heel) = &sampling.heel {
        let factor = heel.image(frame);
        for image in [&mut out.quanta, &mut out.energy_kev, &mut out.open_signal] {
            for (v, f) in image.iter_mut().zip(&factor) {
                *v *= f;
            }
        }
    }
    out
}

//! Expected detected quanta and energy per pixel (Beer–Lambert over energy bins), one image row
//! at a time.
//!
//! For pixel p: `Q_p = f_p · Σ_b w_b · exp(−Σ_m μ_{m,b} · L_{m,p})` and
//! `E_p = f_p · Σ_b w_b · e_b · exp(−Σ_m μ_{m,b} · L_{m,p})` with `w_b = N_b · η_b`.
//! Every sum runs in a fixed order (bins ascending, materials ascending, each starting from 0),
//! so a value does not depend on how rows are split across threads.
//!
//! **Open field shared.** A pixel whose path lengths are all 0 has `exp(−0) = 1` in every bin,
//! so its sums are the open-field sums `Σ_b w_b` and `Σ_b w_b·e_b`, computed once: the same bits
//! as the per-pixel loop would give ([`super::exp::exp`] of −0 is exactly 1). Only the other
//! pixels are gathered into contiguous buffers and run through the bin loop, which loops over
//! pixels innermost (one multiply-add per material, one [`super::exp::exp`], two multiply-adds
//! per bin and pixel) so that it auto-vectorises.

use super::exp::exp_neg_into;
use super::{Beam, Scene};

/// The per-bin weights of a beam on a detector, and their open-field sums.
#[derive(Debug, Clone)]
pub(crate) struct Bins {
    /// `w_b = N_b · η_b`: expected detected photons per pixel in bin b, open field, `f = 1`.
    pub quanta: Vec<f64>,
    /// `w_b · e_b`: expected detected energy (keV) per pixel in bin b, open field, `f = 1`.
    pub energy_kev: Vec<f64>,
    /// `Σ_b w_b` (bins ascending, from 0).
    pub open_quanta: f64,
    /// `Σ_b w_b · e_b` (bins ascending, from 0).
    pub open_energy_kev: f64,
}

impl Bins {
    /// The weights of `beam` on a detector of absorption efficiency `efficiency` (per bin).
    ///
    /// # Panics
    /// When `beam.energies_kev`, `beam.photons_per_pixel` and `efficiency` differ in length.
    pub fn new(beam: &Beam, efficiency: &[f64]) -> Bins {
        let n = beam.energies_kev.len();
        assert!(
            beam.photons_per_pixel.len() == n && efficiency.len() == n,
            "beam and efficiency differ in bin count: {} energies, {} photon counts, {} efficiencies",
            n,
            beam.photons_per_pixel.len(),
            efficiency.len()
        );
        let quanta: Vec<f64> = beam
            .photons_per_pixel
            .iter()
            .zip(efficiency)
            .map(|(&n, &eta)| n * eta)
            .collect();
        let energy_kev: Vec<f64> = quanta
            .iter()
            .zip(&beam.energies_kev)
            .map(|(&w, &e)| w * e)
            .collect();
        Bins {
            open_quanta: quanta.iter().fold(0.0, |s, &w| s + w),
            open_energy_kev: energy_kev.iter().fold(0.0, |s, &w| s + w),
            quanta,
            energy_kev,
        }
    }
}

/// Scratch buffers of one worker, reused from row to row.
#[derive(Debug, Default)]
pub(crate) struct RowScratch {
    covered: Vec<usize>,
    lengths: Vec<f64>,
    exponent: Vec<f64>,
    transmission: Vec<f64>,
    quanta: Vec<f64>,
    energy: Vec<f64>,
}

/// The expected quanta `Q` (and, with `energy` given, the expected energy `E` in keV) of every
/// pixel of row `j`, fluence included, written into `quanta` (and `energy`), each `W` long.
///
/// `active` lists the materials whose length image is not empty.
pub(crate) fn row_expected(
    bins: &Bins,
    scene: &Scene,
    active: &[usize],
    j: usize,
    quanta: &mut [f64],
    mut energy: Option<&mut [f64]>,
    s: &mut RowScratch,
) {
    let w = scene.width;
    let start = j * w;
    let fluence = &scene.fluence[start..start + w];
    // Open field everywhere first.
    for (q, &f) in quanta.iter_mut().zip(fluence) {
        *q = f * bins.open_quanta;
    }
    if let Some(e) = energy.as_deref_mut() {
        for (e, &f) in e.iter_mut().zip(fluence) {
            *e = f * bins.open_energy_kev;
        }
    }
    // The pixels with some material on their ray, and their lengths, gathered.
    s.covered.clear();
    for i in 0..w {
        if active
            .iter()
            .any(|&m| scene.lengths_mm[m][start + i] != 0.0)
        {
            s.covered.push(i);
        }
    }
    let n = s.covered.len();
    if n == 0 {
        return;
    }
    s.lengths.clear();
    for &m in active {
        let row = &scene.lengths_mm[m][start..start + w];
        s.lengths.extend(s.covered.iter().map(|&i| row[i]));
    }
    for buf in [
        &mut s.exponent,
        &mut s.transmission,
        &mut s.quanta,
        &mut s.energy,
    ] {
        buf.clear();
        buf.resize(n, 0.0);
    }
    for b in 0..bins.quanta.len() {
        s.exponent.fill(0.0);
        for (slot, &m) in active.iter().enumerate() {
            let mu = scene.mu_per_mm[m][b];
            let lengths = &s.lengths[slot * n..(slot + 1) * n];
            for (a, &l) in s.exponent.iter_mut().zip(lengths) {
                *a += mu * l;
            }
        }
        exp_neg_into(&s.exponent, &mut s.transmission);
        let wq = bins.quanta[b];
        for (q, &t) in s.quanta.iter_mut().zip(&s.transmission) {
            *q += wq * t;
        }
        if energy.is_some() {
            let we = bins.energy_kev[b];
            for (e, &t) in s.energy.iter_mut().zip(&s.transmission) {
                *e += we * t;
            }
        }
    }
    for (k, &i) in s.covered.iter().enumerate() {
        quanta[i] = fluence[i] * s.quanta[k];
    }
    if let Some(e) = energy {
        for (k, &i) in s.covered.iter().enumerate() {
            e[i] = fluence[i] * s.energy[k];
        }
    }
}

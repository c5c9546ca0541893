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
//! pixels are gathered, in blocks of [`LANES`] pixels, and each block runs through the bin loop
//! with its sums held in registers (per bin and pixel: one multiply-add per material, one
//! [`super::exp::exp`], one or two multiply-adds), the pixels of a block innermost so that it
//! vectorises on baseline x86-64 (SSE2). The blocks change no value: every pixel's sums are the
//! same operations in the same order as a plain per-pixel loop.

use super::exp::exp;
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

/// Pixels per block of the bin loop: the bins run innermost over a block of this many pixels
/// held in registers (four SSE2 vectors of two lanes), so the exponent, the exponential and both
/// sums of a block never leave the registers, and the independent lanes hide the latency of the
/// exponential's polynomial.
const LANES: usize = 8;

/// Scratch buffers of one worker, reused from row to row.
#[derive(Debug, Default)]
pub(crate) struct RowScratch {
    /// Columns of the pixels with some material on their ray.
    covered: Vec<usize>,
    /// Their lengths by block: `[block][slot][lane]`, the last block padded with zeros.
    lengths: Vec<f64>,
    /// `μ` by bin then active material: `[b][slot]`.
    mu: Vec<f64>,
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
        for (x, &f) in e.iter_mut().zip(fluence) {
            *x = f * bins.open_energy_kev;
        }
    }
    // The pixels with some material on their ray, and their lengths, gathered by block.
    s.covered.clear();
    for i in 0..w {
        if active
            .iter()
            .any(|&m| scene.lengths_mm[m][start + i] != 0.0)
        {
            s.covered.push(i);
        }
    }
    if s.covered.is_empty() {
        return;
    }
    let slots = active.len();
    s.lengths.clear();
    for block in s.covered.chunks(LANES) {
        for &m in active {
            let row = &scene.lengths_mm[m][start..start + w];
            s.lengths.extend(block.iter().map(|&i| row[i]));
            s.lengths
                .extend(std::iter::repeat_n(0.0, LANES - block.len()));
        }
    }
    s.mu.clear();
    for b in 0..bins.quanta.len() {
        s.mu.extend(active.iter().map(|&m| scene.mu_per_mm[m][b]));
    }
    match energy {
        None => {
            for (block, lengths) in s
                .covered
                .chunks(LANES)
                .zip(s.lengths.chunks_exact(slots * LANES))
            {
                let (q, _) = block_sums::<false>(bins, &s.mu, lengths);
                for (k, &i) in block.iter().enumerate() {
                    quanta[i] = fluence[i] * q[k];
                }
            }
        }
        Some(e) => {
            for (block, lengths) in s
                .covered
                .chunks(LANES)
                .zip(s.lengths.chunks_exact(slots * LANES))
            {
                let (q, en) = block_sums::<true>(bins, &s.mu, lengths);
                for (k, &i) in block.iter().enumerate() {
                    quanta[i] = fluence[i] * q[k];
                    e[i] = fluence[i] * en[k];
                }
            }
        }
    }
}

/// `Σ_b w_b · exp(−Σ_m μ_{m,b} · L_m)` (and, with `ENERGY`, `Σ_b w_b · e_b · exp(…)`) for the
/// [`LANES`] pixels of one block: `mu` is `[b][slot]`, `lengths` `[slot][lane]`. Every sum runs
/// in the documented order (bins ascending, materials ascending, each from 0).
#[inline(always)]
fn block_sums<const ENERGY: bool>(
    bins: &Bins,
    mu: &[f64],
    lengths: &[f64],
) -> ([f64; LANES], [f64; LANES]) {
    let slots = lengths.len() / LANES;
    let mut q = [0.0; LANES];
    let mut e = [0.0; LANES];
    for (b, mu_b) in mu.chunks_exact(slots).enumerate() {
        let mut a = [0.0; LANES];
        for (&mu, l) in mu_b.iter().zip(lengths.chunks_exact(LANES)) {
            for k in 0..LANES {
                a[k] += mu * l[k];
            }
        }
        let wq = bins.quanta[b];
        let we = bins.energy_kev[b];
        for k in 0..LANES {
            let t = exp(-a[k]);
            q[k] += wq * t;
            if ENERGY {
                e[k] += we * t;
            }
        }
    }
    (q, e)
}

//! Expected detected quanta and energy per pixel (Beer–Lambert over energy bins), one image row
//! at a time: each material's row of path lengths is summed from its layers
//! ([`super::material_row`]), then the bins run over the pixels that have some material.
//!
//! For pixel p: `Q_p = f_p · Σ_b w_b · exp(−Σ_m μ_{m,b} · L_{m,p})` and
//! `E_p = f_p · Σ_b w_b · e_b · exp(−Σ_m μ_{m,b} · L_{m,p})` with `w_b = N_b · η_b`.
//! Every sum runs in a fixed order (bins ascending, materials ascending, each starting from 0),
//! so a value does not depend on how rows are split across threads.
//!
//! **Open field shared.** A pixel whose path lengths are all 0 has `exp(−0) = 1` in every bin,
//! so its sums are the open-field sums `Σ_b w_b` and `Σ_b w_b·e_b`, computed once: the same bits
//! as the per-pixel loop would give ([`super::exp::exp`] of −0 is exactly 1).
//!
//! **One material, one table.** A pixel whose only non-zero length is that of a material with a
//! transmission table ([`super::transmission`]) takes `f·T_Q(L)` and `f·T_E(L)` from it: within
//! 10⁻¹⁰ (relative) of the sums, at a cubic instead of one exponential per bin.
//!
//! Only the other pixels are gathered, in blocks of [`LANES`] pixels, and each block runs through the bin loop
//! with its sums held in registers (per bin and pixel: one multiply-add per material, one
//! [`super::exp::exp`], one or two multiply-adds), the pixels of a block innermost. The blocks
//! change no value: every pixel's sums are the same operations in the same order as a plain
//! per-pixel loop.
//!
//! **AVX2.** The compiler keeps that loop scalar (the exponential's selects and bit operations
//! defeat its vectoriser), so on x86-64 CPUs with AVX2 (checked at run time) a block runs as two
//! 4-lane vectors with intrinsics (`covered_sums_avx2`, [`super::exp::exp_avx2`]): the same
//! IEEE operations in the same order, multiplies and adds never fused, so the values are bit for
//! bit those of the scalar loop (tests `avx2_sums_equal_scalar`, `avx2_lanes_equal_scalar`);
//! measured 2× faster on the realistic knee image. It also skips, per block, the materials none
//! of its pixels crosses (adding μ·0 = +0 to a sum ≥ +0 changes no bit). Other CPUs run the
//! scalar loop.

use super::Scene;
use super::bins::Bins;
use super::exp::exp;

/// Pixels per block of the bin loop: the bins run innermost over a block of this many pixels
/// held in registers (two AVX2 vectors of four lanes), so the exponent, the exponential and both
/// sums of a block never leave the registers, and the independent lanes hide the latency of the
/// exponential's polynomial.
pub(super) const LANES: usize = 8;

/// Scratch buffers of one worker, reused from row to row.
#[derive(Debug, Default)]
pub(crate) struct RowScratch {
    /// The row's length per active material: `[slot][column]`.
    rows: Vec<f64>,
    /// Columns of the pixels with some material on their ray.
    covered: Vec<usize>,
    /// Their lengths by block: `[block][slot][lane]`, the last block padded with zeros.
    lengths: Vec<f64>,
    /// `μ` by bin then active material: `[b][slot]`.
    mu: Vec<f64>,
}

/// The expected quanta `Q` (and, with `energy` given, the expected energy `E` in keV) of every
/// pixel of row `j`, with the row's fluence `fluence`, written into `quanta` (and `energy`),
/// each `W` long.
///
/// `prep` holds the spectrum's bins, the materials with layers (`active`, ascending) and their
/// transmission tables (a pixel crossing one material with a table takes its values from it;
/// module [`super::transmission`]). A material's length at a pixel is the sum of its layers
/// ([`super::material_row`]), a negative sum counting as 0.
pub(super) fn row_expected(
    prep: &super::Prepared,
    scene: &Scene,
    j: usize,
    fluence: &[f64],
    quanta: &mut [f64],
    mut energy: Option<&mut [f64]>,
    s: &mut RowScratch,
) {
    let (bins, active, tables) = (&prep.bins, &prep.active[..], &prep.tables[..]);
    let w = scene.width;
    // Open field everywhere first.
    for (q, &f) in quanta.iter_mut().zip(fluence) {
        *q = f * bins.open_quanta;
    }
    if let Some(e) = energy.as_deref_mut() {
        for (x, &f) in e.iter_mut().zip(fluence) {
            *x = f * bins.open_energy_kev;
        }
    }
    // Each active material's lengths on this row, and the columns any layer touches.
    s.rows.resize(active.len() * w, 0.0);
    let (mut lo, mut hi) = (w, 0);
    for (&m, row) in active.iter().zip(s.rows.chunks_exact_mut(w.max(1))) {
        let span = super::net_material_row(scene.layers, m, j, row);
        if !span.is_empty() {
            lo = lo.min(span.start);
            hi = hi.max(span.end);
        }
    }
    // The pixels with some material on their ray: those crossing one material with a table
    // take its values; the others, and their lengths, are gathered by block.
    let slots = active.len();
    s.covered.clear();
    for i in lo..hi {
        let (mut crossed, mut slot) = (0usize, 0usize);
        for k in 0..slots {
            if s.rows[k * w + i] != 0.0 {
                crossed += 1;
                slot = k;
            }
        }
        if crossed == 0 {
            continue;
        }
        if crossed == 1
            && let Some(table) = &tables[slot]
            && let Some((q, e)) = table.at(s.rows[slot * w + i])
        {
            quanta[i] = fluence[i] * q;
            if let Some(en) = energy.as_deref_mut() {
                en[i] = fluence[i] * e;
            }
            continue;
        }
        s.covered.push(i);
    }
    if s.covered.is_empty() {
        return;
    }
    s.lengths.clear();
    for block in s.covered.chunks(LANES) {
        for row in s.rows.chunks_exact(w) {
            s.lengths.extend(block.iter().map(|&i| row[i]));
            s.lengths
                .extend(std::iter::repeat_n(0.0, LANES - block.len()));
        }
    }
    s.mu.clear();
    for b in 0..bins.quanta.len() {
        s.mu.extend(active.iter().map(|&m| scene.mu_per_mm[m][b]));
    }
    let e = energy.unwrap_or(&mut []);
    let with_energy = !e.is_empty();
    let args = Covered {
        bins,
        mu: &s.mu,
        covered: &s.covered,
        lengths: &s.lengths,
        slots,
        fluence,
    };
    args.sums(with_energy, quanta, e);
}

/// `v_i · Σ_b w_b · exp(−Σ_m μ_{m,b} · L_{m,i})` and `v_i · Σ_b w_b · e_b · exp(…)` of every
/// ray i (`weights[i]` = v_i) into `quanta[i]` and `energy[i]`: the per-pixel sums of
/// [`row_expected`] (same operations, same order, AVX2 where the CPU has it) over rays instead of
/// a row's pixels. `mu` is `[b][slot]`, `lengths` `[block][slot][lane]` as [`row_expected`]
/// gathers them, the last block padded with zeros.
pub(super) fn ray_sums(
    bins: &Bins,
    mu: &[f64],
    slots: usize,
    lengths: &[f64],
    weights: &[f64],
    quanta: &mut [f64],
    energy: &mut [f64],
) {
    let covered: Vec<usize> = (0..weights.len()).collect();
    let args = Covered {
        bins,
        mu,
        covered: &covered,
        lengths,
        slots,
        fluence: weights,
    };
    args.sums(true, quanta, energy);
}

/// The covered pixels of one row, gathered by block (see [`row_expected`]).
struct Covered<'a> {
    bins: &'a Bins,
    /// `μ` by bin then active material: `[b][slot]`.
    mu: &'a [f64],
    /// Columns of the covered pixels.
    covered: &'a [usize],
    /// Their lengths by block: `[block][slot][lane]`.
    lengths: &'a [f64],
    /// Active materials.
    slots: usize,
    /// The row's fluence.
    fluence: &'a [f64],
}

impl Covered<'_> {
    /// `Q` (and with `with_energy`, `E`) of every covered pixel: [`covered_sums_avx2`] on CPUs
    /// with AVX2 (checked at run time), else [`covered_sums`]; the same bits either way.
    fn sums(&self, with_energy: bool, quanta: &mut [f64], e: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above).
            unsafe {
                if with_energy {
                    covered_sums_avx2::<true>(self, quanta, e);
                } else {
                    covered_sums_avx2::<false>(self, quanta, e);
                }
            }
            return;
        }
        if with_energy {
            covered_sums::<true>(self, quanta, e);
        } else {
            covered_sums::<false>(self, quanta, e);
        }
    }
}

/// [`covered_sums`] with AVX2 intrinsics: a block's [`LANES`] pixels are two vectors of four,
/// the bin loop and the sums the same operations in the same order (separate multiplies and adds,
/// never fused; [`super::exp::exp_avx2`] has the bits of the scalar `exp`), so the values are bit
/// for bit those of [`covered_sums`]: only the speed differs (test `avx2_sums_equal_scalar`).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn covered_sums_avx2<const ENERGY: bool>(c: &Covered, quanta: &mut [f64], e: &mut [f64]) {
    use std::arch::x86_64::*;
    const _: () = assert!(LANES == 8, "two AVX2 vectors per block");
    let slots = c.slots;
    let mut used = Vec::with_capacity(slots);
    for (block, lengths) in c
        .covered
        .chunks(LANES)
        .zip(c.lengths.chunks_exact(slots * LANES))
    {
        // The materials with a length in some lane of the block. A zero length adds μ·0 = +0 to
        // a sum that is ≥ +0, which changes no bit, so the others are skipped.
        used.clear();
        for (k, l) in lengths.chunks_exact(LANES).enumerate() {
            if l.iter().any(|&v| v != 0.0) {
                used.push(k);
            }
        }
        let zero = _mm256_setzero_pd();
        let (mut q0, mut q1, mut e0, mut e1) = (zero, zero, zero, zero);
        for (b, mu_b) in c.mu.chunks_exact(slots).enumerate() {
            let (mut a0, mut a1) = (zero, zero);
            for &k in &used {
                let (mu, l) = (mu_b[k], &lengths[k * LANES..(k + 1) * LANES]);
                let m = _mm256_set1_pd(mu);
                // SAFETY: `l` holds LANES = 8 values: two unaligned loads of four.
                let (l0, l1) = unsafe {
                    (
                        _mm256_loadu_pd(l.as_ptr()),
                        _mm256_loadu_pd(l.as_ptr().add(4)),
                    )
                };
                a0 = _mm256_add_pd(a0, _mm256_mul_pd(m, l0));
                a1 = _mm256_add_pd(a1, _mm256_mul_pd(m, l1));
            }
            // −a: flip the sign bit, exactly as the scalar negation.
            let neg = _mm256_set1_pd(-0.0);
            // SAFETY: AVX2 is enabled in this function.
            let (t0, t1) = unsafe {
                (
                    super::exp::exp_avx2(_mm256_xor_pd(a0, neg)),
                    super::exp::exp_avx2(_mm256_xor_pd(a1, neg)),
                )
            };
            let wq = _mm256_set1_pd(c.bins.quanta[b]);
            q0 = _mm256_add_pd(q0, _mm256_mul_pd(wq, t0));
            q1 = _mm256_add_pd(q1, _mm256_mul_pd(wq, t1));
            if ENERGY {
                let we = _mm256_set1_pd(c.bins.energy_kev[b]);
                e0 = _mm256_add_pd(e0, _mm256_mul_pd(we, t0));
                e1 = _mm256_add_pd(e1, _mm256_mul_pd(we, t1));
            }
        }
        let (mut q, mut en) = ([0.0f64; LANES], [0.0f64; LANES]);
        // SAFETY: stores of four f64 into arrays of eight, at 0 and 4.
        unsafe {
            _mm256_storeu_pd(q.as_mut_ptr(), q0);
            _mm256_storeu_pd(q.as_mut_ptr().add(4), q1);
            _mm256_storeu_pd(en.as_mut_ptr(), e0);
            _mm256_storeu_pd(en.as_mut_ptr().add(4), e1);
        }
        for (k, &i) in block.iter().enumerate() {
            quanta[i] = c.fluence[i] * q[k];
            if ENERGY {
                e[i] = c.fluence[i] * en[k];
            }
        }
    }
}

/// `Q` (and with `ENERGY`, `E`) of the covered pixels of a row, block by block.
fn covered_sums<const ENERGY: bool>(c: &Covered, quanta: &mut [f64], e: &mut [f64]) {
    for (block, lengths) in c
        .covered
        .chunks(LANES)
        .zip(c.lengths.chunks_exact(c.slots * LANES))
    {
        let (q, en) = block_sums::<ENERGY>(c.bins, c.mu, lengths);
        for (k, &i) in block.iter().enumerate() {
            quanta[i] = c.fluence[i] * q[k];
            if ENERGY {
                e[i] = c.fluence[i] * en[k];
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

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_sums_equal_scalar() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            println!("no AVX2 on this CPU: the AVX2 path is never taken here");
            return;
        }
        // 3 materials, 40 bins, 61 covered pixels (7 full blocks and a padded one), lengths
        // from 0 to ~300 mm (exponents from 0 to beyond X_MIN), both sums.
        let (slots, nbins, n) = (3usize, 40usize, 61usize);
        let quanta: Vec<f64> = (0..nbins).map(|b| 1e3 + 37.0 * b as f64).collect();
        let energy_kev: Vec<f64> = quanta
            .iter()
            .enumerate()
            .map(|(b, w)| w * (20.0 + b as f64))
            .collect();
        let bins = Bins {
            open_quanta: quanta.iter().sum(),
            open_energy_kev: energy_kev.iter().sum(),
            quanta,
            energy_kev,
        };
        let mu: Vec<f64> = (0..nbins * slots)
            .map(|k| 0.01 + 2.5 * ((k * 2654435761) % 1000) as f64 / 1000.0)
            .collect();
        let covered: Vec<usize> = (0..n).map(|i| 2 * i + 1).collect();
        let mut lengths = Vec::new();
        for (blk, block) in covered.chunks(LANES).enumerate() {
            for slot in 0..slots {
                for k in 0..LANES {
                    // Some blocks cross no length of a material at all (the AVX2 loop skips it).
                    let absent = (slot == 1 && blk % 2 == 0) || (slot == 2 && blk % 3 == 0);
                    let v = if k < block.len() && !absent {
                        ((blk * 31 + slot * 7 + k * 13) % 97) as f64 * 3.1 / (1.0 + slot as f64)
                    } else {
                        0.0
                    };
                    lengths.push(v);
                }
            }
        }
        let fluence: Vec<f64> = (0..2 * n + 2).map(|i| 1.0 - 1e-3 * i as f64).collect();
        let c = Covered {
            bins: &bins,
            mu: &mu,
            covered: &covered,
            lengths: &lengths,
            slots,
            fluence: &fluence,
        };
        let w = fluence.len();
        let (mut q1, mut e1, mut q2, mut e2) =
            (vec![0.0; w], vec![0.0; w], vec![0.0; w], vec![0.0; w]);
        covered_sums::<true>(&c, &mut q1, &mut e1);
        // SAFETY: AVX2 checked above.
        unsafe { covered_sums_avx2::<true>(&c, &mut q2, &mut e2) };
        assert!(q1.iter().any(|&v| v > 0.0) && q1.iter().any(|&v| v > 0.0 && v < 1e-100));
        for i in 0..w {
            assert_eq!(q1[i].to_bits(), q2[i].to_bits(), "Q at {i}");
            assert_eq!(e1[i].to_bits(), e2[i].to_bits(), "E at {i}");
        }
    }
}

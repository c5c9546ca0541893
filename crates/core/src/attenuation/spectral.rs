//! The bins the images are traced with: the filtered spectrum (0.05 keV bins for a tube) grouped
//! into few runs of neighbouring bins, so that a pixel costs few exponentials.
//!
//! **Rules.** A group never crosses an absorption edge of a material in the beam or of the
//! scintillator (a bin belongs to the side of an edge its centre lies on; above the edge the
//! higher μ applies, as in the material tables). A bin holding a characteristic line of the
//! tube with at least [`LINE_SHARE`] of the detected signal is a group of its own, at its own
//! energy. Bins holding less than [`DROP_SHARE`] of the signal are left out.
//!
//! **A group** keeps what the detector sees of its bins: its photons `N = Σ n`, its absorption
//! `η = Σ n·η / N`, its energy `E = Σ n·η·e / Σ n·η` (so `N·η` and `N·η·E`, the photon and
//! energy weights of the response, are the sums over its bins: the open field is exact), and for
//! each material the attenuation `μ_g = −ln(Σ w·e^{−μ t*} / Σ w) / t*` that makes the group's
//! transmission exact at the thickness `t* = t_m/4` (below), with the signal weights `w = n·η`
//! (photon counting) or `n·η·e` (energy integrating). The signal-weighted mean of μ would be
//! exact for thin layers only and errs on one side (it always overstates the attenuation);
//! exact at `t*`, a group errs a little either way around it.
//!
//! **Error bound.** For each material m, let `t_m` be the thickness whose transmission (over
//! every bin, as the detector weighs it) is [`FLOOR`], at most [`MAX_THICKNESS_MM`]. At the
//! thicknesses `t_m·2⁻ᵏ`, k = 0 … [`LADDER`] − 1, each group's error `|Σ w·e^{−μt} − W·e^{−μ̄t}|`
//! is at most `tolerance · (W/W_total) · Σ_all w·e^{−μt}`; summed over the groups, the traced
//! transmission of a single-material layer of those thicknesses is within `tolerance` of the
//! transmission over every bin (relative). Groups are grown left to right while the bound
//! holds, which gives the fewest groups for it. When that is more than `max_energy_bins`, or
//! when no tolerance is asked for, the tolerance is the smallest for which the groups fit
//! (doubled from the one asked, or from 10⁻⁶, then bisected); the tolerance reached is reported.

use crate::material::Material;
use crate::scenario::ResponseKind;
use crate::spectrum::Spectrum;

/// A line bin holding at least this share of the detected signal is traced on its own.
pub const LINE_SHARE: f64 = 1e-4;
/// Bins holding less than this share of the detected signal are not traced.
pub const DROP_SHARE: f64 = 1e-9;
/// The transmission down to which the error is bounded.
pub const FLOOR: f64 = 1e-3;
/// The largest thickness the bound is held at, mm.
pub const MAX_THICKNESS_MM: f64 = 1000.0;
/// Thicknesses per material at which the bound is held (`t_m`, `t_m/2`, …).
pub const LADDER: usize = 6;
/// The rung (`t_m/2^PIVOT`) at which a group's attenuation of a material is exact.
pub const PIVOT: usize = 2;
/// Where the search for the smallest tolerance `max_bins` allows starts (no tolerance asked).
const SMALLEST_TOLERANCE: f64 = 1e-6;

/// What the traced bins are made from.
pub struct Request<'a> {
    /// The spectrum after the tube's filtration.
    pub spectrum: &'a Spectrum,
    /// Energies of the spectrum's bins that hold a characteristic line (bin centres).
    pub lines_kev: &'a [f64],
    /// The materials the images trace, in the setup's order.
    pub materials: &'a [Material],
    /// The scintillator and its thickness (mm), if any.
    pub scintillator: Option<(&'a Material, f64)>,
    /// Energy integrating or photon counting.
    pub response: ResponseKind,
    /// The relative error to hold (see the module); `None`: the smallest that `max_bins` allows.
    pub tolerance: Option<f64>,
    /// The most groups.
    pub max_bins: usize,
}

/// The traced bins.
#[derive(Debug, Clone, PartialEq)]
pub struct Traced {
    /// Per group: the detected-photon-weighted mean energy, keV.
    pub energies_kev: Vec<f64>,
    /// Per group: photons, in the spectrum's unit.
    pub photons: Vec<f64>,
    /// Per group: the detector's absorption.
    pub efficiency: Vec<f64>,
    /// `[material][group]`: signal-weighted mean linear attenuation, 1/mm.
    pub mu_per_mm: Vec<Vec<f64>>,
    /// Per group: the centres of its first and last bin, keV.
    pub bounds_kev: Vec<[f64; 2]>,
    /// The tolerance the groups hold (the one asked for, or the larger one `max_bins` forced);
    /// infinite when even one group per edge interval and line was more than `max_bins`.
    pub tolerance: f64,
}

/// One bin of the spectrum as the grouping sees it.
struct Bin {
    energy_kev: f64,
    photons: f64,
    efficiency: f64,
    /// The signal weight w.
    weight: f64,
    /// The number of edges at or below the bin's centre.
    side: usize,
    /// A line bin traced on its own.
    line: bool,
}

/// The fraction of the photons of energy `e_kev` the detector absorbs: `1 − exp(−μ(E)·t)` for a
/// scintillator of thickness t (mm), 1 without one (an ideal absorber).
pub fn detector_absorption(scintillator: Option<(&Material, f64)>, e_kev: f64) -> f64 {
    match scintillator {
        Some((m, t)) => 1.0 - libm::exp(-m.linear_attenuation_per_mm(e_kev) * t),
        None => 1.0,
    }
}

/// Groups `request.spectrum` (see the module).
pub fn traced(request: &Request) -> Traced {
    let s = request.spectrum;
    let efficiency_at = |e: f64| detector_absorption(request.scintillator, e);
    let mut walls: Vec<f64> = request
        .materials
        .iter()
        .chain(request.scintillator.map(|(m, _)| m))
        .flat_map(|m| m.edges())
        .map(|e| e.energy_kev)
        .collect();
    walls.sort_by(f64::total_cmp);
    walls.dedup();
    let all: Vec<(f64, f64, f64, f64)> = s
        .energies_kev
        .iter()
        .zip(&s.photons)
        .map(|(&e, &n)| {
            let eta = efficiency_at(e);
            let w = match request.response {
                ResponseKind::PhotonCounting => n * eta,
                ResponseKind::EnergyIntegrating => n * eta * e,
            };
            (e, n, eta, w)
        })
        .collect();
    let total: f64 = all.iter().map(|b| b.3).filter(|w| *w > 0.0).sum();
    let bins: Vec<Bin> = all
        .into_iter()
        .filter(|&(_, n, _, w)| n > 0.0 && w > DROP_SHARE * total)
        .map(|(e, n, eta, w)| Bin {
            energy_kev: e,
            photons: n,
            efficiency: eta,
            weight: w,
            side: walls.partition_point(|&x| x <= e),
            line: w >= LINE_SHARE * total
                && request.lines_kev.iter().any(|&l| (l - e).abs() < 1e-9),
        })
        .collect();
    let mu: Vec<Vec<f64>> = request
        .materials
        .iter()
        .map(|m| {
            bins.iter()
                .map(|b| m.linear_attenuation_per_mm(b.energy_kev))
                .collect()
        })
        .collect();
    let ladder = Ladder::new(&bins, &mu);
    let mut tolerance = request.tolerance.unwrap_or(SMALLEST_TOLERANCE);
    let mut groups = ladder.groups(&bins, tolerance);
    let max_bins = request.max_bins.max(1);
    let mut doublings = 0;
    while groups.len() > max_bins && doublings < 200 {
        tolerance *= 2.0;
        doublings += 1;
        groups = ladder.groups(&bins, tolerance);
    }
    if doublings > 0 && groups.len() <= max_bins {
        // The smallest tolerance that fits, between the last that did not and the first that
        // did (bisection of the logarithm, 12 steps: within 0.02 % of it).
        let (mut lo, mut hi) = (tolerance / 2.0, tolerance);
        for _ in 0..12 {
            let mid = libm::sqrt(lo * hi);
            let g = ladder.groups(&bins, mid);
            if g.len() <= max_bins {
                hi = mid;
                groups = g;
            } else {
                lo = mid;
            }
        }
        tolerance = hi;
    }
    if groups.len() > max_bins {
        // Even one group per edge interval and line is too many: equal runs of bins.
        tolerance = f64::INFINITY;
        groups = equal_runs(bins.len(), max_bins);
    }
    let mut out = Traced {
        energies_kev: Vec::with_capacity(groups.len()),
        photons: Vec::with_capacity(groups.len()),
        efficiency: Vec::with_capacity(groups.len()),
        mu_per_mm: vec![Vec::with_capacity(groups.len()); request.materials.len()],
        bounds_kev: Vec::with_capacity(groups.len()),
        tolerance,
    };
    for g in groups {
        let part = &bins[g.clone()];
        let n: f64 = part.iter().map(|b| b.photons).sum();
        let q: f64 = part.iter().map(|b| b.photons * b.efficiency).sum();
        let qe: f64 = part
            .iter()
            .map(|b| b.photons * b.efficiency * b.energy_kev)
            .sum();
        let w: f64 = part.iter().map(|b| b.weight).sum();
        out.photons.push(n);
        out.efficiency.push(q / n);
        out.bounds_kev
            .push([part[0].energy_kev, part[part.len() - 1].energy_kev]);
        out.energies_kev
            .push(if let [b] = part { b.energy_kev } else { qe / q });
        for (m, mu_m) in mu.iter().enumerate() {
            let wm: f64 = part
                .iter()
                .zip(&mu_m[g.clone()])
                .map(|(b, &x)| b.weight * x)
                .sum();
            let pivot = m * LADDER + PIVOT;
            let at_pivot: f64 = ladder.attenuated[pivot][g.clone()].iter().sum();
            let t = ladder.thickness_mm[pivot];
            out.mu_per_mm[m].push(if let [_] = part {
                mu_m[g.start]
            } else {
                ladder.effective_mu(w, wm, at_pivot, t)
            });
        }
    }
    out
}

/// The thicknesses of the bound and each bin's attenuated weight there.
struct Ladder {
    /// `[m·LADDER + k]`: the thickness, mm.
    thickness_mm: Vec<f64>,
    /// `[m·LADDER + k][bin]`: `w·e^{−μ t}`.
    attenuated: Vec<Vec<f64>>,
    /// `[m·LADDER + k]`: the sum over every bin.
    total: Vec<f64>,
    /// `[m][bin]`: μ.
    mu: Vec<Vec<f64>>,
    /// Σ w over every bin.
    weight: f64,
    /// Each bin's w.
    weights: Vec<f64>,
}

impl Ladder {
    fn new(bins: &[Bin], mu: &[Vec<f64>]) -> Ladder {
        let weight: f64 = bins.iter().map(|b| b.weight).sum();
        let transmission = |mu_m: &[f64], t: f64| -> f64 {
            bins.iter()
                .zip(mu_m)
                .map(|(b, &x)| b.weight * libm::exp(-x * t))
                .sum::<f64>()
                / weight
        };
        let mut thickness_mm = Vec::new();
        let mut attenuated = Vec::new();
        let mut total = Vec::new();
        for mu_m in mu {
            // The thickness leaving FLOOR (bisection to 1e-6 relative), at most MAX_THICKNESS_MM.
            let t_m = if transmission(mu_m, MAX_THICKNESS_MM) >= FLOOR {
                MAX_THICKNESS_MM
            } else {
                let (mut lo, mut hi) = (0.0, MAX_THICKNESS_MM);
                while hi - lo > 1e-6 * hi {
                    let mid = 0.5 * (lo + hi);
                    if transmission(mu_m, mid) > FLOOR {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                hi
            };
            for k in 0..LADDER {
                let t = t_m / f64::from(1u32 << k);
                let a: Vec<f64> = bins
                    .iter()
                    .zip(mu_m)
                    .map(|(b, &x)| b.weight * libm::exp(-x * t))
                    .collect();
                total.push(a.iter().sum());
                attenuated.push(a);
                thickness_mm.push(t);
            }
        }
        Ladder {
            thickness_mm,
            attenuated,
            total,
            mu: mu.to_vec(),
            weight,
            weights: bins.iter().map(|b| b.weight).collect(),
        }
    }

    /// The groups (ranges of `bins`) for `tolerance`, grown left to right.
    fn groups(&self, bins: &[Bin], tolerance: f64) -> Vec<std::ops::Range<usize>> {
        let rungs = self.thickness_mm.len();
        let mut groups = Vec::new();
        let mut start = 0;
        // The open group's sums: Σ w, Σ w·μ per material, Σ w·e^{−μt} per rung.
        let mut w = 0.0;
        let mut wmu = vec![0.0; self.mu.len()];
        let mut att = vec![0.0; rungs];
        for (i, b) in bins.iter().enumerate() {
            let alone = b.line || (i > start && bins[i - 1].line);
            let joins = i > start
                && !alone
                && b.side == bins[start].side
                && self.fits(i, w, &wmu, &att, tolerance);
            if i > start && !joins {
                groups.push(start..i);
                start = i;
                w = 0.0;
                wmu.iter_mut().for_each(|x| *x = 0.0);
                att.iter_mut().for_each(|x| *x = 0.0);
            }
            w += b.weight;
            for (m, x) in wmu.iter_mut().enumerate() {
                *x += b.weight * self.mu[m][i];
            }
            for (r, x) in att.iter_mut().enumerate() {
                *x += self.attenuated[r][i];
            }
        }
        if start < bins.len() {
            groups.push(start..bins.len());
        }
        groups
    }

    /// Whether the open group with bin `i` added still holds the bound at every rung.
    fn fits(&self, i: usize, w: f64, wmu: &[f64], att: &[f64], tolerance: f64) -> bool {
        let weight = w + self.weight_of(i);
        (0..self.thickness_mm.len()).all(|r| {
            let m = r / LADDER;
            let pivot = m * LADDER + PIVOT;
            let mu = self.effective_mu(
                weight,
                wmu[m] + self.weight_of(i) * self.mu[m][i],
                att[pivot] + self.attenuated[pivot][i],
                self.thickness_mm[pivot],
            );
            let exact = att[r] + self.attenuated[r][i];
            let approx = weight * libm::exp(-mu * self.thickness_mm[r]);
            (exact - approx).abs() <= tolerance * (weight / self.weight) * self.total[r]
        })
    }

    /// A group's attenuation for one material: the one that gives its transmission exactly at
    /// the pivot thickness `t` (from `attenuated = Σ w·e^{−μt}` and `weight = Σ w`), or the
    /// signal-weighted mean `wmu / weight` where that cannot be told (nothing left at `t`).
    fn effective_mu(&self, weight: f64, wmu: f64, attenuated: f64, t: f64) -> f64 {
        if attenuated > 0.0 && t > 0.0 {
            -libm::log(attenuated / weight) / t
        } else {
            wmu / weight
        }
    }

    fn weight_of(&self, i: usize) -> f64 {
        self.weights[i]
    }
}

/// `count` bins in `groups` contiguous runs of equal length (the larger first).
fn equal_runs(count: usize, groups: usize) -> Vec<std::ops::Range<usize>> {
    let groups = groups.min(count).max(1);
    let (base, extra) = (count / groups, count % groups);
    let mut out = Vec::with_capacity(groups);
    let mut start = 0;
    for g in 0..groups {
        let end = start + base + usize::from(g < extra);
        out.push(start..end);
        start = end;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::by_name;

    /// A smooth spectrum in 0.05 keV bins from 20 to 90 keV, with a "line" at 59.325 keV.
    fn spectrum() -> Spectrum {
        let energies_kev: Vec<f64> = (0..1400).map(|j| 20.025 + 0.05 * j as f64).collect();
        let photons = energies_kev
            .iter()
            .map(|&e| {
                let continuum = (90.0 - e) * e;
                if (e - 59.325).abs() < 1e-9 {
                    continuum * 40.0
                } else {
                    continuum
                }
            })
            .collect();
        Spectrum {
            energies_kev,
            photons,
            absolute: true,
        }
    }

    fn request<'a>(
        s: &'a Spectrum,
        materials: &'a [Material],
        tolerance: Option<f64>,
        max_bins: usize,
    ) -> Request<'a> {
        Request {
            spectrum: s,
            lines_kev: &[59.325],
            materials,
            scintillator: None,
            response: ResponseKind::EnergyIntegrating,
            tolerance,
            max_bins,
        }
    }

    /// Σ w·e^{−μt} / Σ w over `(energies, photons, efficiency, mu)` as the response weighs it.
    fn transmission(e: &[f64], n: &[f64], eta: &[f64], mu: &[f64], t: f64) -> f64 {
        let w: Vec<f64> = (0..e.len()).map(|i| n[i] * eta[i] * e[i]).collect();
        let behind: f64 = (0..e.len()).map(|i| w[i] * libm::exp(-mu[i] * t)).sum();
        behind / w.iter().sum::<f64>()
    }

    #[test]
    fn groups_keep_the_detected_photons_and_energy() {
        let s = spectrum();
        let ta = [by_name("tantalum").unwrap().clone()];
        let t = traced(&request(&s, &ta, None, 40));
        let photons: f64 = s.photons.iter().sum();
        let energy: f64 = s
            .energies_kev
            .iter()
            .zip(&s.photons)
            .map(|(e, n)| e * n)
            .sum();
        let got_photons: f64 = t.photons.iter().sum();
        let got_energy: f64 = (0..t.photons.len())
            .map(|g| t.photons[g] * t.efficiency[g] * t.energies_kev[g])
            .sum();
        assert!((got_photons / photons - 1.0).abs() < 1e-12);
        assert!((got_energy / energy - 1.0).abs() < 1e-12);
        assert!(t.efficiency.iter().all(|&x| x == 1.0));
    }

    #[test]
    fn no_group_crosses_an_edge_and_a_strong_line_stands_alone() {
        let s = spectrum();
        let ta = [by_name("tantalum").unwrap().clone()];
        let k_edge = 67.4164;
        for max_bins in [4, 12, 40, 1000] {
            let t = traced(&request(&s, &ta, None, max_bins));
            assert!(t.energies_kev.len() <= max_bins.max(3));
            for [lo, hi] in &t.bounds_kev {
                assert!(
                    !(*lo < k_edge && *hi >= k_edge),
                    "{lo}–{hi} keV crosses the K edge"
                );
            }
            assert!(
                t.bounds_kev.contains(&[59.325, 59.325]),
                "{max_bins}: the line is not alone: {:?}",
                t.bounds_kev
            );
        }
    }

    #[test]
    fn the_tolerance_holds_at_every_rung_and_a_finer_one_takes_more_bins() {
        let s = spectrum();
        let m = [
            by_name("tantalum").unwrap().clone(),
            by_name("soft_tissue").unwrap().clone(),
        ];
        let mu_all: Vec<Vec<f64>> = m
            .iter()
            .map(|m| {
                s.energies_kev
                    .iter()
                    .map(|&e| m.linear_attenuation_per_mm(e))
                    .collect()
            })
            .collect();
        let ones = vec![1.0; s.photons.len()];
        let mut counts = Vec::new();
        for tolerance in [1e-2, 1e-3, 1e-4] {
            let t = traced(&request(&s, &m, Some(tolerance), 1000));
            assert_eq!(t.tolerance, tolerance);
            counts.push(t.energies_kev.len());
            for (k, mu) in mu_all.iter().enumerate() {
                // Thicknesses from thin to the 0.1 % one (the bound's rungs lie in between).
                for thickness in [0.01, 0.1, 0.3, 1.0, 3.0, 30.0, 100.0, 300.0] {
                    let exact = transmission(&s.energies_kev, &s.photons, &ones, mu, thickness);
                    if exact < FLOOR || (k == 0 && thickness > 3.0) {
                        continue;
                    }
                    let ours = transmission(
                        &t.energies_kev,
                        &t.photons,
                        &t.efficiency,
                        &t.mu_per_mm[k],
                        thickness,
                    );
                    // Between the rungs and below the thinnest, allow twice the tolerance.
                    assert!(
                        (ours / exact - 1.0).abs() <= 2.0 * tolerance,
                        "{} {thickness} mm at {tolerance}: {ours} vs {exact}",
                        m[k].name
                    );
                }
            }
        }
        assert!(counts[0] < counts[1] && counts[1] < counts[2], "{counts:?}");
    }

    #[test]
    fn too_few_bins_widen_the_tolerance_to_the_smallest_that_fits() {
        let s = spectrum();
        let m = [by_name("tantalum").unwrap().clone()];
        let wide = traced(&request(&s, &m, Some(1e-4), 10));
        assert!(wide.energies_kev.len() <= 10);
        assert!(wide.tolerance > 1e-4);
        // Within 0.05 % of the smallest: a slightly smaller one takes more than 10 bins.
        let tighter = traced(&request(&s, &m, Some(wide.tolerance * 0.999), 1000));
        assert!(
            tighter.energies_kev.len() > 10,
            "{}",
            tighter.energies_kev.len()
        );
        let unasked = traced(&request(&s, &m, None, 10));
        assert!(unasked.energies_kev.len() <= 10);
        assert!((unasked.tolerance / wide.tolerance - 1.0).abs() < 2e-3);
    }

    #[test]
    fn one_energy_is_one_bin_with_its_own_attenuation() {
        let s = Spectrum::monochromatic(60.0);
        let m = [by_name("tantalum").unwrap().clone()];
        let t = traced(&request(&s, &m, None, 40));
        assert_eq!(t.energies_kev, vec![60.0]);
        assert_eq!(t.mu_per_mm[0], vec![m[0].linear_attenuation_per_mm(60.0)]);
        let none = traced(&request(&s, &[], None, 40));
        assert_eq!(none.photons, vec![1.0]);
    }
}

//! Detector response in attenuation mode: from per-pixel path lengths per material to stored
//! detector values with quantum noise (docs/src/reference/conventions.md, "Image formation").
//!
//! The module takes plain numbers (energies, photon counts, attenuation coefficients, path
//! lengths, fluence), so it depends neither on the material tables nor on the spectrum model nor
//! on the tracer.
//!
//! # Model
//!
//! Per pixel p, with the beam binned in energy (bin b: energy `e_b` in keV, `N_b` photons per
//! pixel at the reference point with no object, detector absorption efficiency `η_b`), materials
//! m (linear attenuation `μ_{m,b}` per mm, path length `L_{m,p}` in mm, already net of nesting)
//! and the pixel's relative fluence `f_p` (see [`point_source_fluence`]):
//!
//! * expected detected quanta `Q = f · Σ_b N_b · η_b · exp(−Σ_m μ_{m,b} · L_m)`;
//! * expected detected energy `E = f · Σ_b N_b · η_b · e_b · exp(−Σ_m μ_{m,b} · L_m)` (keV);
//! * quantum noise on **every** pixel: `n ~ Poisson(Q)`;
//! * signal `S`: photon counting `S = n` (counts); energy integrating `S = n · E/Q` (keV: each
//!   detected photon deposits the pixel's mean detected energy; the spread of deposited energy,
//!   the Swank factor, is not modelled, so the noise of an energy-integrating pixel is that of its
//!   photon count scaled by `E/Q`);
//! * [`Polarity::Raw`]: stored value `round(offset + gain · S)` clipped to `0..=i_max` (metal
//!   dark, air bright); `gain` in DN per count (photon counting) or per keV (energy
//!   integrating), `offset` in DN;
//! * [`Polarity::Radiograph`]: the flat-field corrected log image, dense matter bright:
//!   `i_max · clamp(ln(S_open / S) / range, 0, 1)` rounded, `S_open = f · Σ_b N_b · η_b` (photon
//!   counting) or `f · Σ_b N_b · η_b · e_b` (energy integrating) the pixel's expected open-field
//!   signal, `range` the attenuation (natural log) shown white, [`DEFAULT_RADIOGRAPH_RANGE`] = 7
//!   by default (0.09 % transmission). `S = 0` is white. This is an ideal flat-field correction:
//!   it uses the signal before gain, offset and clipping, so it does not depend on them.
//!
//! Values are rounded half up. [`render`] does all of this in one pass per row (the sharp
//! image). Not modelled there: scatter, blur (focal spot, detector PSF), the Swank factor,
//! electronic (read-out) noise, dark current, gain non-uniformity and the heel effect.
//!
//! # Unsharpness and extra noise (issue 12)
//!
//! [`expected`] gives the noise-free image as a whole ([`Expected`]: `Q`, `E` and `S_open` of
//! every pixel, bit for bit what [`render`] draws from); a caller may average several (sub-pixel
//! samples, focal-spot sub-sources). [`render_expected`] then renders it in the order of the
//! physics, each step optional ([`Unsharpness`], all off by default, then bit for bit
//! [`render`]): [`Scatter`] added to `Q` and `E` (an approximation: one scatter-to-primary ratio
//! and a broad almost-Gaussian kernel), quantum noise as above, the detector [`Psf`] on the
//! noisy signal `S` (so the noise becomes correlated, its power spectrum ∝ MTF², as in an
//! indirect flat panel) and on the flat field `S_open` of a radiograph, Gaussian electronic noise
//! added to the raw value (`S + e/gain` in a radiograph) on streams of its own
//! ([`NoiseKey::derive_electronic`]), then the digitisation above.
//!
//! # Noise draws (the documented order)
//!
//! Row `j` (row 0 is the first stored row) draws from `key.row_rng(j)` (the stream derivation of
//! [`crate::noise::stream`]); its pixels draw left to right, one Poisson sample each, with the
//! pixel's own mean λ = Q ([`crate::noise::Poisson::sample_with_mean`], the same values as
//! `Poisson::new(Q).sample`). A sample consumes a variable number of `u64`s (none for λ = 0), so
//! unlike binary mode a pixel's noise depends on the means of the pixels before it in its row.
//! Means outside `[0, LAMBDA_MAX]` (only from invalid inputs; see [`check_inputs`]) are replaced by
//! 0 (negative or NaN) or [`LAMBDA_MAX`]. Rows are independent and run in parallel (rayon): the
//! output is the same on any number of threads.
//!
//! # Determinism and speed
//!
//! The Beer–Lambert factor uses this module's own [`exp`] (pure IEEE arithmetic, within 2 ulp of
//! `libm::exp`), the radiograph logarithm `libm::log` (a stored value far from a step is decided
//! with one multiplication instead of the formula's division, bit for bit the formula's value),
//! the sampler the project's own, its per-pixel constants computed for blocks of pixels. Path
//! lengths arrive as [`Layer`]s (one solid's rectangle of lengths, added to or taken from one
//! material) and the fluence as a [`PointSourceFluence`]; both are turned into values one row at
//! a time inside the row loop, so no W×H image per material is held. Pixels whose lengths are
//! all 0 share one precomputed open-field sum (times their fluence); those crossing a single
//! material take its per-image transmission table (within 10⁻¹⁰ of the sum; `transmission`);
//! the others run through a bin loop over blocks of pixels, with AVX2 intrinsics where the CPU has them (bit for bit the
//! scalar values; see `expected`).

mod bins;
mod convolve;
mod digitise;
pub mod exp;
mod expected;
mod fluence;
mod image;
mod layer;
mod pipeline;
pub mod psf;
mod ray_mean;
pub mod scatter;
#[cfg(test)]
mod tests;
mod transmission;
mod unsharp;

pub use fluence::{PointSourceFluence, point_source_fluence};
pub use image::{Expected, expected, open_signal_per_fluence};
pub use layer::{Layer, material_row, net_material_row};
pub use pipeline::render_expected;
pub use psf::{Psf, PsfShape};
pub use ray_mean::{PixelMean, RayMean, RayScratch, rays_of};
pub use scatter::Scatter;
pub use unsharp::Unsharpness;

use rayon::prelude::*;

use crate::noise::NoiseKey;
use bins::Bins;
use expected::{RowScratch, row_expected};
use transmission::Transmission;

/// The attenuation (natural log of open-field over object signal) shown white in a radiograph
/// when the scenario does not say: 7, i.e. 0.09 % transmission.
pub const DEFAULT_RADIOGRAPH_RANGE: f64 = 7.0;

/// The largest Poisson mean drawn (10¹⁵ quanta per pixel, far beyond any detector); a larger
/// expected count (only from invalid inputs) is drawn at this mean.
pub const LAMBDA_MAX: f64 = 1e15;

/// How the detector turns absorbed photons into a signal.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Response {
    /// The signal is the absorbed energy (keV): `S = n · E/Q` (flat-panel scintillator detectors).
    EnergyIntegrating,
    /// The signal is the number of absorbed photons: `S = n`.
    PhotonCounting,
}

/// What a stored value means.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Polarity {
    /// The detector's digital value `round(offset + gain · S)`, clipped to `0..=i_max`: metal
    /// dark, air bright.
    Raw,
    /// The flat-field corrected log image, dense matter bright:
    /// `i_max · clamp(ln(S_open/S) / range, 0, 1)`, rounded.
    Radiograph {
        /// The attenuation `ln(S_open/S)` shown white (> 0; [`DEFAULT_RADIOGRAPH_RANGE`]).
        range: f64,
    },
}

/// The X-ray beam at the reference point (the foot of the perpendicular from the source to the
/// detector, where the fluence factor is 1), with no object in it, binned in energy.
#[derive(Debug, Clone, PartialEq)]
pub struct Beam {
    /// Energy of each bin, keV (> 0).
    pub energies_kev: Vec<f64>,
    /// Photons per pixel in each bin reaching the detector at the reference point (≥ 0).
    pub photons_per_pixel: Vec<f64>,
}

/// The detector: response, absorption efficiency, gain, offset, bit depth and output polarity.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectorModel {
    /// Energy integrating or photon counting.
    pub response: Response,
    /// Absorption efficiency `η_b` in `[0, 1]`, one per beam bin.
    pub efficiency: Vec<f64>,
    /// DN per count (photon counting) or per keV (energy integrating); see
    /// [`DetectorModel::auto_gain`].
    pub gain: f64,
    /// DN added to every raw value.
    pub offset: f64,
    /// The largest stored value, `2^bpp − 1`.
    pub i_max: u16,
    /// Raw values or a radiograph.
    pub polarity: Polarity,
    /// Whether each pixel's count is a Poisson draw of mean `Q` (`true`, a real detector) or
    /// `Q` itself (the expected image).
    pub quantum_noise: bool,
}

impl DetectorModel {
    /// Gain that maps the expected open-field signal at the reference point to
    /// `fraction · i_max` (after offset): `(fraction · i_max − offset) / S_ref` with
    /// `S_ref = Σ_b N_b·η_b` (photon counting) or `Σ_b N_b·η_b·e_b` (energy integrating).
    /// 0 when the beam gives no signal (`S_ref` not positive and finite) or the result would
    /// be negative.
    ///
    /// # Panics
    /// When `beam.energies_kev`, `beam.photons_per_pixel` and `efficiency` differ in length.
    pub fn auto_gain(
        response: &Response,
        beam: &Beam,
        efficiency: &[f64],
        offset: f64,
        fraction: f64,
        i_max: u16,
    ) -> f64 {
        let bins = Bins::new(beam, efficiency);
        let reference = open_signal(*response, &bins);
        let gain = (fraction * f64::from(i_max) - offset) / reference;
        if reference > 0.0 && reference.is_finite() && gain > 0.0 && gain.is_finite() {
            gain
        } else {
            0.0
        }
    }
}

/// One image's geometry-dependent inputs: path lengths per material and relative fluence.
#[derive(Debug, Clone, Copy)]
pub struct Scene<'a> {
    /// Pixels per row (W).
    pub width: usize,
    /// Rows (H).
    pub height: usize,
    /// `mu_per_mm[m][b]`: linear attenuation of material m at bin b, per mm (≥ 0).
    pub mu_per_mm: &'a [Vec<f64>],
    /// The path-length layers: material m's length at a pixel is the sum of its layers there
    /// ([`material_row`]), a negative sum (rounding of nested solids) counting as 0. A material
    /// without layers is absent.
    pub layers: &'a [Layer<'a>],
    /// The relative fluence of every pixel.
    pub fluence: Fluence<'a>,
}

/// The relative fluence `f_p` of every pixel.
#[derive(Debug, Clone, Copy)]
pub enum Fluence<'a> {
    /// W×H values, row-major.
    Image(&'a [f64]),
    /// A point source's `(D/r)³`, computed row by row.
    PointSource(&'a PointSourceFluence),
}

impl Fluence<'_> {
    /// Row `j` (W values) into `out`.
    fn row(&self, j: usize, out: &mut [f64]) {
        match self {
            Fluence::Image(v) => {
                let w = out.len();
                out.copy_from_slice(&v[j * w..(j + 1) * w]);
            }
            Fluence::PointSource(f) => f.row(j, out),
        }
    }
}

/// A rendered image and what a caller reports about it.
#[derive(Debug, Clone, PartialEq)]
pub struct Rendered {
    /// W×H stored values, row-major.
    pub pixels: Vec<u16>,
    /// Pixels whose raw value `round(offset + gain · S)` exceeded `i_max` and was clipped
    /// (counted in both polarities: a radiograph is computed before clipping, but the detector
    /// would have saturated there).
    pub saturated: usize,
    /// The largest expected open-field raw value over the image, in DN before clipping:
    /// `offset + gain · max_p(f_p) · S_ref` (compare with `i_max` to see whether air saturates).
    pub expected_open_max: f64,
}

/// The expected open-field signal per unit fluence: counts or keV.
fn open_signal(response: Response, bins: &Bins) -> f64 {
    match response {
        Response::PhotonCounting => bins.open_quanta,
        Response::EnergyIntegrating => bins.open_energy_kev,
    }
}

/// Checks the inputs of [`render`] and [`expected_quanta`]: the shapes (which those functions
/// assert) and the values (which they would otherwise sanitise). The message names the field,
/// the index and what would be valid.
pub fn check_inputs(beam: &Beam, det: &DetectorModel, scene: &Scene) -> Result<(), String> {
    let bins = beam.energies_kev.len();
    if beam.photons_per_pixel.len() != bins || det.efficiency.len() != bins {
        return Err(format!(
            "beam and detector differ in bin count: {bins} energies, {} photon counts, {} \
             efficiencies (need one of each per bin)",
            beam.photons_per_pixel.len(),
            det.efficiency.len()
        ));
    }
    let bad = |what: &str, i: usize, v: f64, valid: &str| {
        Err(format!("{what}[{i}] = {v} is not valid (must be {valid})"))
    };
    for (i, &e) in beam.energies_kev.iter().enumerate() {
        if !(e > 0.0 && e.is_finite()) {
            return bad("energies_kev", i, e, "finite and > 0 keV");
        }
    }
    for (i, &n) in beam.photons_per_pixel.iter().enumerate() {
        if !(n >= 0.0 && n <= LAMBDA_MAX) {
            return bad("photons_per_pixel", i, n, "between 0 and 1e15");
        }
    }
    for (i, &eta) in det.efficiency.iter().enumerate() {
        if !(0.0..=1.0).contains(&eta) {
            return bad("efficiency", i, eta, "between 0 and 1");
        }
    }
    for (what, v) in [("gain", det.gain), ("offset", det.offset)] {
        if !v.is_finite() {
            return Err(format!("{what} = {v} is not valid (must be finite)"));
        }
    }
    if let Polarity::Radiograph { range } = det.polarity
        && !(range > 0.0 && range.is_finite())
    {
        return Err(format!(
            "radiograph range = {range} is not valid (must be finite and > 0)"
        ));
    }
    check_scene(scene, bins)
}

/// The scene half of [`check_inputs`].
fn check_scene(scene: &Scene, bins: usize) -> Result<(), String> {
    let (w, h) = (scene.width, scene.height);
    match scene.fluence {
        Fluence::Image(v) => {
            if w.checked_mul(h).is_none_or(|p| v.len() != p) {
                return Err(format!(
                    "fluence has {} values for a {w}×{h} image",
                    v.len()
                ));
            }
            if let Some((p, v)) = v
                .iter()
                .enumerate()
                .find(|(_, v)| !(**v >= 0.0 && v.is_finite()))
            {
                return Err(format!(
                    "fluence[{p}] = {v} is not valid (must be finite and ≥ 0)"
                ));
            }
        }
        Fluence::PointSource(f) => {
            if (f.width(), f.height()) != (w, h) {
                return Err(format!(
                    "the fluence is {}×{} for a {w}×{h} image",
                    f.width(),
                    f.height()
                ));
            }
        }
    }
    for (m, mu) in scene.mu_per_mm.iter().enumerate() {
        if mu.len() != bins {
            return Err(format!(
                "mu_per_mm[{m}] has {} values for {bins} bins",
                mu.len()
            ));
        }
        if let Some((b, v)) = mu
            .iter()
            .enumerate()
            .find(|(_, v)| !(**v >= 0.0 && v.is_finite()))
        {
            return Err(format!(
                "mu_per_mm[{m}][{b}] = {v} is not valid (must be finite and ≥ 0 per mm)"
            ));
        }
    }
    for (k, layer) in scene.layers.iter().enumerate() {
        if layer.material >= scene.mu_per_mm.len() {
            return Err(format!(
                "layer {k} has material {} of {} (need one attenuation row per material)",
                layer.material,
                scene.mu_per_mm.len()
            ));
        }
        if !layer.fits(w, h) {
            return Err(format!(
                "layer {k} covers columns {:?} and rows {:?} with {} values (must lie within \
                 the {w}×{h} image, one value per pixel)",
                layer.columns,
                layer.rows,
                layer.length_mm.len()
            ));
        }
        if layer.sign != 1.0 && layer.sign != -1.0 {
            return Err(format!(
                "layer {k} has sign {} (must be +1 or −1)",
                layer.sign
            ));
        }
        if let Some((p, v)) = layer
            .length_mm
            .iter()
            .enumerate()
            .find(|(_, v)| !(**v >= 0.0 && v.is_finite()))
        {
            return Err(format!(
                "layer {k} length_mm[{p}] = {v} is not valid (must be finite and ≥ 0 mm)"
            ));
        }
    }
    Ok(())
}

/// The prepared inputs shared by every row.
struct Prepared {
    bins: Bins,
    /// Materials with at least one layer, ascending.
    active: Vec<usize>,
    /// Per active material, the table of its transmission for pixels that cross it alone.
    tables: Vec<Option<Transmission>>,
}

impl Prepared {
    /// # Panics
    /// When the shapes disagree (see [`check_inputs`]).
    fn new(beam: &Beam, det: &DetectorModel, scene: &Scene) -> Prepared {
        let bins = Bins::new(beam, &det.efficiency);
        let (w, h) = (scene.width, scene.height);
        match scene.fluence {
            Fluence::Image(v) => assert_eq!(Some(v.len()), w.checked_mul(h), "fluence is not W×H"),
            Fluence::PointSource(f) => {
                assert_eq!((f.width(), f.height()), (w, h), "fluence is not W×H")
            }
        }
        for (m, mu) in scene.mu_per_mm.iter().enumerate() {
            assert_eq!(
                mu.len(),
                bins.quanta.len(),
                "mu_per_mm[{m}]: one value per bin"
            );
        }
        let mut active = Vec::new();
        for (k, layer) in scene.layers.iter().enumerate() {
            assert!(
                layer.material < scene.mu_per_mm.len(),
                "layer {k}: no attenuation row for its material"
            );
            assert!(layer.fits(w, h), "layer {k} does not fit the image");
            active.push(layer.material);
        }
        active.sort_unstable();
        active.dedup();
        assert!(
            scene.height as u64 <= 1u64 << 32,
            "more than 2³² rows (noise streams are numbered by u32)"
        );
        let tables = active
            .iter()
            .map(|&m| {
                // An upper bound of the material's net length: its positive layers' maxima.
                let max_mm = scene
                    .layers
                    .iter()
                    .filter(|l| l.material == m && l.sign > 0.0)
                    .map(|l| l.length_mm.iter().fold(0.0f64, |a, &v| a.max(v)))
                    .fold(0.0, |a, v| a + v);
                Transmission::new(&bins, &scene.mu_per_mm[m], max_mm, w * h)
            })
            .collect();
        Prepared {
            bins,
            active,
            tables,
        }
    }

    /// Row `j`'s fluence (into `fluence`, resized to W) and its expected quanta (and, with
    /// `energy`, expected energy) by [`row_expected`].
    #[inline]
    fn row(
        &self,
        scene: &Scene,
        j: usize,
        fluence: &mut Vec<f64>,
        rows: &mut RowScratch,
        quanta: &mut [f64],
        energy: Option<&mut [f64]>,
    ) {
        fluence.resize(scene.width, 0.0);
        scene.fluence.row(j, fluence);
        row_expected(self, scene, j, fluence, quanta, energy, rows);
    }
}

/// The expected detected quanta `Q` of every pixel (W×H, row-major, fluence and efficiency
/// included): the Poisson means [`render`] draws from, bit for bit.
///
/// # Panics
/// When the shapes disagree (see [`check_inputs`]).
pub fn expected_quanta(beam: &Beam, det: &DetectorModel, scene: &Scene) -> Vec<f64> {
    let prep = Prepared::new(beam, det, scene);
    let w = scene.width;
    let mut out = vec![0.0; w * scene.height];
    if w == 0 {
        return out;
    }
    out.par_chunks_mut(w)
        .enumerate()
        .for_each_init(RenderScratch::default, |s, (j, row)| {
            prep.row(scene, j, &mut s.fluence, &mut s.rows, row, None);
        });
    out
}

/// Per-worker buffers of [`render`].
#[derive(Default)]
struct RenderScratch {
    rows: RowScratch,
    fluence: Vec<f64>,
    quanta: Vec<f64>,
    energy_kev: Vec<f64>,
    /// The noisy signal `S` of a row.
    signal: Vec<f64>,
    /// The expected open-field signal of a row.
    open: Vec<f64>,
}

/// Renders one attenuation image: expected quanta, Poisson noise on every pixel, signal, then
/// raw values or a radiograph (module documentation, with the draw order).
///
/// Never panics on values (invalid ones are sanitised as documented; [`check_inputs`] reports
/// them).
///
/// # Panics
/// When the shapes disagree (see [`check_inputs`]).
pub fn render(beam: &Beam, det: &DetectorModel, scene: &Scene, key: &NoiseKey) -> Rendered {
    let prep = Prepared::new(beam, det, scene);
    let w = scene.width;
    let open = open_signal(det.response, &prep.bins);
    let mut pixels = vec![0u16; w * scene.height];
    if w == 0 {
        return Rendered {
            pixels,
            saturated: 0,
            expected_open_max: det.offset,
        };
    }
    let digitiser = digitise::Digitiser::new(det);
    let integrating = digitiser.integrating();
    let (saturated, f_max) = pixels
        .par_chunks_mut(w)
        .enumerate()
        .map_init(RenderScratch::default, |s, (j, row)| {
            s.quanta.resize(w, 0.0);
            s.energy_kev.resize(w, 0.0);
            let energy = integrating.then_some(&mut s.energy_kev[..]);
            prep.row(scene, j, &mut s.fluence, &mut s.rows, &mut s.quanta, energy);
            let fluence = &s.fluence;
            let f_max = fluence.iter().fold(0.0f64, |m, &f| m.max(f));
            let mut rng = key.row_rng(j as u32);
            s.signal.resize(w, 0.0);
            digitiser.detect_row(&s.quanta, &s.energy_kev, &mut rng, &mut s.signal);
            s.open.clear();
            s.open.extend(fluence.iter().map(|&f| f * open));
            let saturated = digitiser.store_row(&s.signal, &s.open, row);
            (saturated, f_max)
        })
        .reduce(|| (0, 0.0), |a, b| (a.0 + b.0, a.1.max(b.1)));
    let expected_open_max = det.offset + det.gain * (f_max * open);
    Rendered {
        pixels,
        saturated,
        expected_open_max,
    }
}

//! The scenario stage: the TOML file the user wrote, read into plain records and checked.
//!
//! Nothing here knows about rays or pixels: this stage turns text into [`Scenario`] records and
//! [`Diagnostic`](crate::diagnostic::Diagnostic)s. Checks that need the mesh files or the
//! geometry of every run happen in the later stages, which report through the same locator.

mod dicom;
mod imaging;
mod imaging_check;
mod lengths;
mod load;
mod magnitudes;
mod model;
mod sequence;
mod sequence_check;
mod study;
mod study_check;
mod validate;

pub use load::{LoadedScenario, MAX_SCENARIO_BYTES, from_text, hex, load};
pub use magnitudes::MAX_ABS;
pub use model::*;
pub use validate::{MAX_ID_BYTES, MIN_PIXEL_PITCH_MM, id_problem};

/// Every message `s.toml` with `text` gives: its errors, or its warnings (prefixed `warning: `)
/// when it loads, each with its `file:line:column` (the checks' tests read them).
#[cfg(test)]
pub(crate) fn messages_of(text: &str) -> Vec<String> {
    match from_text(
        text,
        std::path::Path::new("s.toml"),
        std::path::Path::new("."),
    ) {
        Ok(l) => l.warnings.iter().map(|d| format!("warning: {d}")).collect(),
        Err(e) => e.iter().map(|d| d.to_string()).collect(),
    }
}

/// One level of the protocol: the binary mode's noise level, or attenuation mode's exposure
/// factor (then the noise level is 0: noise follows from the photons).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Level {
    /// Background noise as a fraction of I_max (binary mode).
    pub noise_level: f64,
    /// Factor on the imaging exposure (attenuation mode).
    pub exposure_factor: Option<f64>,
}

impl Scenario {
    /// Whether the material `name` (a user material of `[materials]` or a shipped one) counts as
    /// metal: density at least [`crate::material::METAL_DENSITY_G_CM3`]. Unknown names do not.
    pub fn is_metal(&self, name: &str) -> bool {
        let density = match self.materials.get(name) {
            Some(user) => user.density_g_cm3,
            None => crate::material::by_name(name).map_or(0.0, |m| m.density_g_cm3),
        };
        density >= crate::material::METAL_DENSITY_G_CM3
    }

    /// Number of runs: levels × runs per level for the protocol (× frames with a sequence: each
    /// frame is a run), patients × exams for a study.
    pub fn run_count(&self) -> u64 {
        match &self.study {
            Some(d) => u64::from(d.patients) * d.exams.len() as u64,
            None => {
                self.levels().len() as u64
                    * u64::from(self.protocol.runs_per_level)
                    * u64::from(self.frames_per_run())
            }
        }
    }

    /// Frames per run of the protocol: the sequence's frames, 1 without a sequence.
    pub fn frames_per_run(&self) -> u32 {
        self.sequence.as_ref().map_or(1, |q| q.frames.max(1))
    }

    /// The one level of every exam of a study: `study.noise_level` in binary mode,
    /// `study.exposure_factor` (default 1) in attenuation mode.
    pub fn study_level(&self, d: &StudyDesign) -> Level {
        if self.imaging.is_attenuation() {
            Level {
                noise_level: 0.0,
                exposure_factor: Some(d.exposure_factor.unwrap_or(1.0)),
            }
        } else {
            Level {
                noise_level: d.noise_level,
                exposure_factor: None,
            }
        }
    }

    /// The protocol's levels in order: `noise_levels` in binary mode, `exposure_levels`
    /// (default `[1.0]`) in attenuation mode.
    pub fn levels(&self) -> Vec<Level> {
        if self.imaging.is_attenuation() {
            self.protocol
                .exposure_levels
                .clone()
                .unwrap_or_else(|| vec![1.0])
                .into_iter()
                .map(|f| Level {
                    noise_level: 0.0,
                    exposure_factor: Some(f),
                })
                .collect()
        } else {
            self.protocol
                .noise_levels
                .iter()
                .map(|&noise_level| Level {
                    noise_level,
                    exposure_factor: None,
                })
                .collect()
        }
    }
}

/// JSON Schema of the scenario file (draft 2020-12), generated from the records above.
pub fn json_schema() -> serde_json::Value {
    let schema = schemars::schema_for!(Scenario);
    schema.as_value().clone()
}

impl Detector {
    /// Pixel pitch `[x, y]` in mm, from `pixel_pitch_mm` or `size_mm / pixels`.
    pub fn resolved_pixel_pitch_mm(&self) -> [f64; 2] {
        match (self.pixel_pitch_mm, self.size_mm) {
            (Some(p), _) => p,
            (None, Some(s)) => [s[0] / self.pixels[0] as f64, s[1] / self.pixels[1] as f64],
            (None, None) => [f64::NAN; 2],
        }
    }

    /// I_max = 2^bpp − 1, the value of a covered pixel.
    pub fn i_max(&self) -> u16 {
        ((1u32 << self.bpp) - 1) as u16
    }
}

/// The shape of a phantom, once validation has ensured exactly one is given.
pub enum PhantomShape<'a> {
    /// A free bead set.
    Beads(&'a [Bead]),
    /// A calibration box.
    CalibrationBox(&'a CalibrationBox),
    /// A mesh with optional beads.
    Mesh(&'a MeshPhantom),
    /// An elliptic cylinder (a soft-tissue envelope).
    EllipticCylinder(&'a EllipticCylinder),
}

impl Phantom {
    /// The phantom's shape. Validation guarantees exactly one of the three keys is set.
    pub fn shape(&self) -> PhantomShape<'_> {
        match (
            &self.beads,
            &self.calibration_box,
            &self.mesh,
            &self.elliptic_cylinder,
        ) {
            (Some(b), None, None, None) => PhantomShape::Beads(b),
            (None, Some(c), None, None) => PhantomShape::CalibrationBox(c),
            (None, None, Some(m), None) => PhantomShape::Mesh(m),
            (None, None, None, Some(e)) => PhantomShape::EllipticCylinder(e),
            _ => panic!(
                "phantom `{}` was not validated: it needs exactly one shape",
                self.id
            ),
        }
    }

    /// The kind as written in truth files: `beads`, `calibration_box`, `mesh` or
    /// `elliptic_cylinder`.
    pub fn kind(&self) -> &'static str {
        match self.shape() {
            PhantomShape::Beads(_) => "beads",
            PhantomShape::CalibrationBox(_) => "calibration_box",
            PhantomShape::Mesh(_) => "mesh",
            PhantomShape::EllipticCylinder(_) => "elliptic_cylinder",
        }
    }
}

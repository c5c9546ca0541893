//! What a DICOM file says about one image of a run: its identity (UIDs, numbers, synthetic
//! patient), its pixels' meaning, and the set-up's distances and exposure.
//!
//! The distances and directions are the **nominal** set-up's (the scenario's positions without
//! the random offsets of the run), as a real X-ray unit records its nominal source–image
//! distance: the exact geometry of a run is the truth, and a blind images folder must not carry
//! it.
//!
//! Patient Orientation takes the box frame as the patient's, with the RSA convention of
//! clinical studies: x transverse towards the patient's left (`L`), y longitudinal towards the
//! head (`H`), z sagittal towards the front (`A`) (right-handed: L × H = A). The row direction
//! is the detector's r axis and the column direction its c axis; each is written as the letters
//! of its non-zero components (above 10⁻⁶), largest first (e.g. `L`, `FA` for an oblique axis).

use glam::DVec3;

use super::{DicomIntent, DxImage, PixelMeaning, uid};
use crate::expand::{self, Run};
use crate::phantom::PhantomModel;
use crate::scenario::{PolarityOption, Scenario};

/// The nominal distances and directions of one exposure and detector.
#[derive(Debug, Clone, PartialEq)]
pub struct NominalView {
    /// Exposure id.
    pub exposure: String,
    /// Detector id.
    pub detector: String,
    /// Source to detector centre, mm.
    pub sid_mm: f64,
    /// Source to the exposure's phantoms along the central ray, mm: the distance from the source
    /// to the mean of the phantoms' positions, projected onto the line from the source to the
    /// detector centre. `None` unless it lies strictly between the source and the detector.
    pub sod_mm: Option<f64>,
    /// Patient Orientation: the patient directions of the rows (r) and columns (c).
    pub patient_orientation: [String; 2],
}

/// The DICOM patient-direction letters of a unit vector in the box frame, largest component
/// first (box x, y, z = patient left, head, anterior).
pub fn patient_direction(v: DVec3) -> String {
    let mut parts: Vec<(f64, char)> = [(v.x, ['L', 'R']), (v.y, ['H', 'F']), (v.z, ['A', 'P'])]
        .into_iter()
        .filter(|(c, _)| c.abs() > 1e-6)
        .map(|(c, [plus, minus])| (c.abs(), if c > 0.0 { plus } else { minus }))
        .collect();
    parts.sort_by(|a, b| b.0.total_cmp(&a.0));
    parts.into_iter().map(|(_, letter)| letter).collect()
}

/// The nominal distances and directions of every exposure and detector of `s`
/// (exposure-major).
pub fn nominal_views(s: &Scenario, models: &[PhantomModel]) -> Vec<NominalView> {
    let run = expand::nominal_run(s, models);
    let mut out = Vec::new();
    for exposure in &run.exposures {
        let in_beam = exposure.phantom_indices(models);
        let centre = in_beam
            .iter()
            .map(|&i| run.phantoms[i].position_mm)
            .fold(DVec3::ZERO, |a, b| a + b)
            / in_beam.len().max(1) as f64;
        for det in &run.detectors {
            let source = run.source_of(det);
            let axis = det.position_mm - source;
            let sid_mm = axis.length();
            let sod = (centre - source).dot(axis / sid_mm);
            out.push(NominalView {
                exposure: exposure.id.clone(),
                detector: det.id.clone(),
                sid_mm,
                sod_mm: (sod > 0.0 && sod < sid_mm).then_some(sod),
                patient_orientation: [
                    patient_direction(det.rotation.x_axis),
                    patient_direction(det.rotation.y_axis),
                ],
            });
        }
    }
    out
}

/// One image to describe: where it sits in the scenario and the run.
pub struct ImageRef<'a> {
    /// The scenario as run.
    pub scenario: &'a Scenario,
    /// SHA-256 of the scenario file (lowercase hex).
    pub scenario_sha256: &'a str,
    /// The run.
    pub run: &'a Run,
    /// Index of the exposure in the scenario.
    pub exposure_index: usize,
    /// Index of the detector in the scenario.
    pub detector_index: usize,
    /// The intent of the file.
    pub intent: DicomIntent,
}

/// The DICOM description of one image with its `pixels`; `views` from [`nominal_views`].
pub fn describe<'a>(image: &ImageRef, views: &[NominalView], pixels: &'a [u16]) -> DxImage<'a> {
    let s = image.scenario;
    let run = image.run;
    let exposure = &s.exposures[image.exposure_index];
    let det = &run.detectors[image.detector_index];
    let intent = image.intent;
    let nominal = views
        .iter()
        .find(|d| d.exposure == exposure.id && d.detector == det.id);
    let attenuation = s.imaging.is_attenuation();
    let meaning = match (attenuation, s.imaging.detector.polarity) {
        (false, _) => PixelMeaning::Silhouette,
        (true, PolarityOption::Raw) => PixelMeaning::Linear,
        (true, PolarityOption::Radiograph) => PixelMeaning::Log,
    };
    let factor = run.exposure_factor.unwrap_or(1.0);
    let intents = &s.output.dicom.intents;
    let intent_index = intents.iter().position(|&i| i == intent).unwrap_or(0);
    let level = match run.exposure_factor {
        Some(f) => format!("exposure factor {f}"),
        None => format!("noise level {}", run.noise_level),
    };
    let sha = image.scenario_sha256;
    DxImage {
        intent,
        width: det.pixels[0],
        height: det.pixels[1],
        pixels,
        bits_stored: det.bpp,
        meaning,
        pixel_pitch_mm: det.pixel_pitch_mm,
        sid_mm: nominal.map(|n| n.sid_mm),
        sod_mm: nominal.and_then(|n| n.sod_mm),
        patient_orientation: nominal.map(|n| n.patient_orientation.clone()),
        kvp: s
            .imaging
            .tube
            .as_ref()
            .filter(|_| attenuation)
            .map(|t| t.kvp),
        mas: s.imaging.mas.filter(|_| attenuation).map(|m| m * factor),
        focal_spot_mm: s.imaging.focal_spot.as_ref().map(|f| f.size_mm),
        detector_type: if attenuation && s.imaging.detector.scintillator.is_some() {
            "SCINTILLATOR"
        } else {
            ""
        },
        date: s
            .output
            .dicom
            .dicom_date()
            .unwrap_or_else(|| "20000101".into()),
        study_uid: uid::study_uid(sha, &run.id),
        series_uid: uid::series_uid(sha, &run.id, &exposure.id, intent.name()),
        instance_uid: uid::instance_uid(sha, &run.id, &exposure.id, &det.id, intent.name()),
        series_number: (image.exposure_index * intents.len() + intent_index + 1) as u32,
        instance_number: (image.detector_index + 1) as u32,
        patient_id: s.name.clone(),
        study_id: run.id.clone(),
        study_description: format!("rsasim run {}", run.id),
        series_description: format!("{} {}", exposure.id, intent.name()),
        detector_id: det.id.clone(),
        comments: format!(
            "Synthetic image simulated by {}: scenario {}, run {}, {level}, exposure {} \
             (phantoms {}), detector {}, {} bits per pixel (I_max {}), for {}. Distances are the \
             nominal set-up's; the exact geometry is in the run's ground truth.",
            crate::output::program(),
            s.name,
            run.id,
            exposure.id,
            exposure.phantoms.join(", "),
            det.id,
            det.bpp,
            det.i_max(),
            intent.name()
        ),
        software: crate::output::program(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patient_directions_follow_the_box_axes() {
        assert_eq!(patient_direction(DVec3::X), "L");
        assert_eq!(patient_direction(-DVec3::X), "R");
        assert_eq!(patient_direction(DVec3::Y), "H");
        assert_eq!(patient_direction(-DVec3::Y), "F");
        assert_eq!(patient_direction(DVec3::Z), "A");
        assert_eq!(patient_direction(-DVec3::Z), "P");
        // An oblique axis: the largest component first; rounding dust is ignored.
        assert_eq!(patient_direction(DVec3::new(0.6, -0.8, 1e-17)), "FL");
        assert_eq!(patient_direction(DVec3::new(-0.5, 0.3, 0.81)), "ARH");
    }
}

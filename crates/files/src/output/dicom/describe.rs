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
    let intent_number = |series: usize| (series * intents.len() + intent_index + 1) as u32;
    // A static run is one study with a series per exposure and an instance per detector; a
    // sequence is one study with a series per exposure and detector (one camera's cine) and an
    // instance per frame, acquired at the frame's time.
    let (study, series_uid, series_number, instance_number, time, frame_words) = match &run.frame {
        None => (
            run.id.as_str(),
            uid::series_uid(sha, &run.id, &exposure.id, intent.name()),
            intent_number(image.exposure_index),
            (image.detector_index + 1) as u32,
            "000000".to_string(),
            String::new(),
        ),
        Some(f) => (
            f.sequence.as_str(),
            uid::camera_series_uid(sha, &f.sequence, &exposure.id, &det.id, intent.name()),
            intent_number(image.exposure_index * run.detectors.len() + image.detector_index),
            f.index + 1,
            tm(f.time_s),
            format!(
                ", frame {} of {} of sequence {} at {} s from the first (the middle of its pulse)",
                f.index + 1,
                f.count,
                f.sequence,
                f.time_s
            ),
        ),
    };
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
        study_uid: uid::study_uid(sha, study),
        series_uid,
        instance_uid: uid::instance_uid(sha, &run.id, &exposure.id, &det.id, intent.name()),
        series_number,
        instance_number,
        acquisition_time: time,
        patient_id: s.name.clone(),
        study_id: study.to_string(),
        study_description: match &run.frame {
            None => format!("rsasim run {}", run.id),
            Some(_) => format!("rsasim sequence {study}"),
        },
        series_description: format!("{} {}", exposure.id, intent.name()),
        detector_id: det.id.clone(),
        comments: format!(
            "Synthetic image simulated by {}: scenario {}, run {}{frame_words}, {level}, exposure {} \
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

/// A DICOM Time (TM, `HHMMSS.FFFFFF`) `seconds` after midnight, to the microsecond (at most
/// 23:59:59.999999).
pub fn tm(seconds: f64) -> String {
    let us = (seconds.max(0.0) * 1e6).round().min(86_399_999_999.0) as u64;
    let (s, frac) = (us / 1_000_000, us % 1_000_000);
    format!("{:02}{:02}{:02}.{frac:06}", s / 3600, s / 60 % 60, s % 60)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_are_hours_minutes_seconds_and_microseconds() {
        assert_eq!(tm(0.0), "000000.000000");
        assert_eq!(tm(0.37), "000000.370000");
        assert_eq!(tm(3725.0000004), "010205.000000");
        assert_eq!(tm(1e9), "235959.999999");
    }

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

//! DICOM Digital X-Ray (DX) image encoder (dicom-rs, pinned), writing to memory.
//!
//! One file per image: a DX Image Storage instance "for presentation" or "for processing"
//! (Explicit VR Little Endian, native 16-bit pixels, MONOCHROME1 or MONOCHROME2) with the
//! attributes RSA software reads: Imager Pixel Spacing and Pixel Spacing (the detector pitch,
//! row spacing first), Distance Source to Detector, Distance Source to Patient, Estimated
//! Radiographic Magnification Factor, Bits Stored, the pixel intensity relationship, kVp and
//! exposure where the scenario has them, a synthetic patient and study, and deterministic UIDs
//! ([`uid`]). Every value comes from [`DxImage`]; nothing reads the clock, so the bytes depend
//! only on the inputs. [`describe`] builds a [`DxImage`] from a run.

pub mod describe;
pub mod uid;

use dicom_core::value::{C, DataSetSequence, PrimitiveValue};
use dicom_core::{DataElement, Tag, VR};
use dicom_dictionary_std::{tags, uids};
use dicom_object::InMemDicomObject;
use dicom_object::meta::FileMetaTableBuilder;

pub use crate::scenario::DicomIntent;

/// The Patient's Name of every file: no real person.
pub const PATIENT_NAME: &str = "SYNTHETIC^PHANTOM";
/// The Patient Comments of every file.
pub const PATIENT_COMMENTS: &str =
    "Synthetic image simulated by rsasim: no real person was imaged or identified.";

/// What the stored pixel values mean (DICOM Pixel Intensity Relationship and its sign), and so
/// which way a viewer shows them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PixelMeaning {
    /// Attenuation mode, raw polarity: values rise linearly with the detected X-ray intensity
    /// (`LIN`, sign +1); metal is dark, so the image is shown MONOCHROME1 (low values white).
    Linear,
    /// Attenuation mode, radiograph polarity: values rise with `ln(S_open / S)`, i.e. fall with
    /// the intensity (`LOG`, sign −1); shown MONOCHROME2.
    Log,
    /// Binary mode (the paper): objects' shadows are I_max, the beam's background carries the
    /// noise (`LIN`, sign −1: the nearest DICOM description of a silhouette); shown MONOCHROME2.
    Silhouette,
}

impl PixelMeaning {
    fn relationship(self) -> &'static str {
        match self {
            PixelMeaning::Linear | PixelMeaning::Silhouette => "LIN",
            PixelMeaning::Log => "LOG",
        }
    }

    fn sign(self) -> i16 {
        match self {
            PixelMeaning::Linear => 1,
            PixelMeaning::Log | PixelMeaning::Silhouette => -1,
        }
    }

    /// Photometric Interpretation and Presentation LUT Shape: dense matter displays bright.
    fn photometric(self) -> (&'static str, &'static str) {
        match self {
            PixelMeaning::Linear => ("MONOCHROME1", "INVERSE"),
            PixelMeaning::Log | PixelMeaning::Silhouette => ("MONOCHROME2", "IDENTITY"),
        }
    }
}

/// Everything one DICOM DX file states.
#[derive(Debug, Clone)]
pub struct DxImage<'a> {
    /// For presentation or for processing.
    pub intent: DicomIntent,
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Row-major detector counts, `width · height` of them, each ≤ 2^bits_stored − 1.
    pub pixels: &'a [u16],
    /// The detector's bits per pixel (6 to 16).
    pub bits_stored: u8,
    /// What the values mean.
    pub meaning: PixelMeaning,
    /// Pixel pitch `[x, y]` (along a row, along a column), mm, at the detector face.
    pub pixel_pitch_mm: [f64; 2],
    /// Source to detector centre, mm.
    pub sid_mm: Option<f64>,
    /// Source to the imaged object's centre along the central ray, mm, when it lies between
    /// the source and the detector.
    pub sod_mm: Option<f64>,
    /// Patient Orientation: the patient directions of the rows and the columns (e.g. `L`,
    /// `F`), when known.
    pub patient_orientation: Option<[String; 2]>,
    /// Peak tube voltage, kV (attenuation mode with a tube).
    pub kvp: Option<f64>,
    /// Tube current-time product, mAs (attenuation mode with `mas`, times the exposure level).
    pub mas: Option<f64>,
    /// Focal spot size, mm (with `[imaging.focal_spot]`).
    pub focal_spot_mm: Option<f64>,
    /// Detector type (`SCINTILLATOR` with a scintillator; empty when unknown).
    pub detector_type: &'static str,
    /// Study, Series, Content and Acquisition Date, `YYYYMMDD`.
    pub date: String,
    /// Study Instance UID.
    pub study_uid: String,
    /// Series Instance UID.
    pub series_uid: String,
    /// SOP Instance UID.
    pub instance_uid: String,
    /// Series Number.
    pub series_number: u32,
    /// Instance Number.
    pub instance_number: u32,
    /// Content and Acquisition Time (TM): `000000` for a static run, a dynamic exam's frame's
    /// time from its first frame.
    pub acquisition_time: String,
    /// Patient ID (the scenario name).
    pub patient_id: String,
    /// Study ID (the run id).
    pub study_id: String,
    /// Study Description.
    pub study_description: String,
    /// Series Description.
    pub series_description: String,
    /// Detector ID.
    pub detector_id: String,
    /// Image Comments: the ids and levels of the image, in words.
    pub comments: String,
    /// Software Versions (`rsasim <version>`).
    pub software: String,
}

/// A DICOM Decimal String of `v`: the shortest decimal that fits the 16 characters DS allows
/// (trailing zeros dropped).
pub fn ds(v: f64) -> String {
    let shortest = format!("{v}");
    if shortest.len() <= 16 {
        return shortest;
    }
    for decimals in (0..=15).rev() {
        let s = format!("{v:.decimals$}");
        let s = if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        };
        if s.len() <= 16 {
            return s;
        }
    }
    format!("{v:.3e}")
}

/// `s` cut to at most `max` characters (the length a DICOM value representation allows).
fn fit(s: &str, max: usize) -> String {
    s.chars().take(max).collect()
}

fn text(tag: Tag, vr: VR, value: &str) -> DataElement<InMemDicomObject> {
    DataElement::new(tag, vr, value)
}

fn strs(tag: Tag, vr: VR, values: &[String]) -> DataElement<InMemDicomObject> {
    DataElement::new(tag, vr, PrimitiveValue::Strs(C::from_vec(values.to_vec())))
}

fn us(tag: Tag, value: u16) -> DataElement<InMemDicomObject> {
    DataElement::new(tag, VR::US, PrimitiveValue::U16(C::from_elem(value, 1)))
}

fn empty(tag: Tag, vr: VR) -> DataElement<InMemDicomObject> {
    DataElement::new(tag, vr, PrimitiveValue::Empty)
}

/// Encodes `img` as a DICOM file (preamble, `DICM`, file meta group, data set) in memory.
///
/// Errors: a pixel count that is not `width · height`, a size beyond DICOM's 16-bit rows and
/// columns, bits stored outside 6..=16, or an encoder failure.
pub fn encode_dx(img: &DxImage) -> Result<Vec<u8>, String> {
    let (w, h) = (img.width, img.height);
    if w == 0 || h == 0 || w > u32::from(u16::MAX) || h > u32::from(u16::MAX) {
        return Err(format!("a DICOM image cannot be {w}×{h} pixels"));
    }
    if img.pixels.len() as u64 != u64::from(w) * u64::from(h) {
        return Err(format!(
            "DICOM image is {w}×{h} but {} pixels were given",
            img.pixels.len()
        ));
    }
    let bits = img.bits_stored;
    if !(crate::scenario::DX_MIN_BITS_STORED..=16).contains(&bits) {
        return Err(format!("a DICOM DX image stores 6 to 16 bits, not {bits}"));
    }
    let i_max = ((1u32 << bits) - 1) as u16;
    let (sop_class, intent_type) = match img.intent {
        DicomIntent::Presentation => (
            uids::DIGITAL_X_RAY_IMAGE_STORAGE_FOR_PRESENTATION,
            "FOR PRESENTATION",
        ),
        DicomIntent::Processing => (
            uids::DIGITAL_X_RAY_IMAGE_STORAGE_FOR_PROCESSING,
            "FOR PROCESSING",
        ),
    };
    let (photometric, lut_shape) = img.meaning.photometric();
    // DICOM spacing is row spacing (between rows: the y pitch), then column spacing.
    let spacing = [ds(img.pixel_pitch_mm[1]), ds(img.pixel_pitch_mm[0])];
    let date = img.date.as_str();
    let mut obj = InMemDicomObject::from_element_iter([
        // SOP Common
        text(tags::SOP_CLASS_UID, VR::UI, sop_class),
        text(tags::SOP_INSTANCE_UID, VR::UI, &img.instance_uid),
        // Patient: synthetic, never a real person
        text(tags::PATIENT_NAME, VR::PN, PATIENT_NAME),
        text(tags::PATIENT_ID, VR::LO, &fit(&img.patient_id, 64)),
        empty(tags::PATIENT_BIRTH_DATE, VR::DA),
        text(tags::PATIENT_SEX, VR::CS, "O"),
        text(tags::PATIENT_COMMENTS, VR::LT, PATIENT_COMMENTS),
        // General Study
        text(tags::STUDY_INSTANCE_UID, VR::UI, &img.study_uid),
        text(tags::STUDY_DATE, VR::DA, date),
        text(tags::STUDY_TIME, VR::TM, "000000"),
        empty(tags::REFERRING_PHYSICIAN_NAME, VR::PN),
        text(tags::STUDY_ID, VR::SH, &fit(&img.study_id, 16)),
        empty(tags::ACCESSION_NUMBER, VR::SH),
        text(
            tags::STUDY_DESCRIPTION,
            VR::LO,
            &fit(&img.study_description, 64),
        ),
        // General Series, DX Series
        text(tags::MODALITY, VR::CS, "DX"),
        text(tags::SERIES_INSTANCE_UID, VR::UI, &img.series_uid),
        text(tags::SERIES_NUMBER, VR::IS, &img.series_number.to_string()),
        text(tags::SERIES_DATE, VR::DA, date),
        text(tags::SERIES_TIME, VR::TM, "000000"),
        text(
            tags::SERIES_DESCRIPTION,
            VR::LO,
            &fit(&img.series_description, 64),
        ),
        text(tags::PRESENTATION_INTENT_TYPE, VR::CS, intent_type),
        // General Equipment
        text(tags::MANUFACTURER, VR::LO, "rsasim"),
        text(tags::MANUFACTURER_MODEL_NAME, VR::LO, "rsasim simulator"),
        text(tags::SOFTWARE_VERSIONS, VR::LO, &fit(&img.software, 64)),
        // General Image, DX Image, DX Anatomy Imaged
        text(
            tags::INSTANCE_NUMBER,
            VR::IS,
            &img.instance_number.to_string(),
        ),
        text(tags::CONTENT_DATE, VR::DA, date),
        text(tags::CONTENT_TIME, VR::TM, &img.acquisition_time),
        text(tags::ACQUISITION_DATE, VR::DA, date),
        text(tags::ACQUISITION_TIME, VR::TM, &img.acquisition_time),
        strs(
            tags::IMAGE_TYPE,
            VR::CS,
            &["ORIGINAL".into(), "PRIMARY".into()],
        ),
        text(tags::IMAGE_COMMENTS, VR::LT, &fit(&img.comments, 10240)),
        text(tags::BURNED_IN_ANNOTATION, VR::CS, "NO"),
        text(tags::LOSSY_IMAGE_COMPRESSION, VR::CS, "00"),
        text(tags::IMAGE_LATERALITY, VR::CS, "U"),
        empty(tags::BODY_PART_EXAMINED, VR::CS),
        DataElement::new(
            tags::ANATOMIC_REGION_SEQUENCE,
            VR::SQ,
            DataSetSequence::<InMemDicomObject>::empty(),
        ),
        text(
            tags::PIXEL_INTENSITY_RELATIONSHIP,
            VR::CS,
            img.meaning.relationship(),
        ),
        DataElement::new(
            tags::PIXEL_INTENSITY_RELATIONSHIP_SIGN,
            VR::SS,
            PrimitiveValue::I16(C::from_elem(img.meaning.sign(), 1)),
        ),
        text(tags::RESCALE_INTERCEPT, VR::DS, "0"),
        text(tags::RESCALE_SLOPE, VR::DS, "1"),
        text(tags::RESCALE_TYPE, VR::LO, "US"),
        text(tags::PRESENTATION_LUT_SHAPE, VR::CS, lut_shape),
        // Image Pixel
        us(tags::SAMPLES_PER_PIXEL, 1),
        text(tags::PHOTOMETRIC_INTERPRETATION, VR::CS, photometric),
        us(tags::ROWS, h as u16),
        us(tags::COLUMNS, w as u16),
        us(tags::BITS_ALLOCATED, 16),
        us(tags::BITS_STORED, u16::from(bits)),
        us(tags::HIGH_BIT, u16::from(bits) - 1),
        us(tags::PIXEL_REPRESENTATION, 0),
        // DX Detector
        text(tags::DETECTOR_TYPE, VR::CS, img.detector_type),
        text(tags::DETECTOR_ID, VR::SH, &fit(&img.detector_id, 16)),
        strs(tags::IMAGER_PIXEL_SPACING, VR::DS, &spacing),
        strs(tags::PIXEL_SPACING, VR::DS, &spacing),
        strs(tags::DETECTOR_ELEMENT_SPACING, VR::DS, &spacing),
        text(tags::DETECTOR_ACTIVE_SHAPE, VR::CS, "RECTANGLE"),
        strs(
            tags::DETECTOR_ACTIVE_DIMENSIONS,
            VR::DS,
            &[
                ds(img.pixel_pitch_mm[0] * f64::from(w)),
                ds(img.pixel_pitch_mm[1] * f64::from(h)),
            ],
        ),
        // DX Positioning
        empty(tags::POSITIONER_TYPE, VR::CS),
        // Acquisition Context
        DataElement::new(
            tags::ACQUISITION_CONTEXT_SEQUENCE,
            VR::SQ,
            DataSetSequence::<InMemDicomObject>::empty(),
        ),
        // The pixels
        DataElement::new(
            tags::PIXEL_DATA,
            VR::OW,
            PrimitiveValue::U16(C::from_slice(img.pixels)),
        ),
    ]);
    if let Some(sid) = img.sid_mm {
        obj.put(text(tags::DISTANCE_SOURCE_TO_DETECTOR, VR::DS, &ds(sid)));
        if let Some(sod) = img.sod_mm {
            obj.put(text(tags::DISTANCE_SOURCE_TO_PATIENT, VR::DS, &ds(sod)));
            obj.put(text(
                tags::ESTIMATED_RADIOGRAPHIC_MAGNIFICATION_FACTOR,
                VR::DS,
                &ds(sid / sod),
            ));
        }
    }
    if let Some(orientation) = &img.patient_orientation {
        obj.put(strs(tags::PATIENT_ORIENTATION, VR::CS, orientation));
    }
    if img.intent == DicomIntent::Presentation {
        // A linear window over the whole stored range 0..=I_max.
        let width = f64::from(i_max) + 1.0;
        obj.put(text(tags::WINDOW_CENTER, VR::DS, &ds(width / 2.0)));
        obj.put(text(tags::WINDOW_WIDTH, VR::DS, &ds(width)));
    }
    if let Some(kvp) = img.kvp {
        obj.put(text(tags::KVP, VR::DS, &ds(kvp)));
    }
    if let Some(mas) = img.mas {
        // Exposure (IS) in whole mAs, Exposure in µAs (IS) to the nearest µAs.
        obj.put(text(tags::EXPOSURE, VR::IS, &format!("{:.0}", mas)));
        obj.put(text(
            tags::EXPOSURE_INU_AS,
            VR::IS,
            &format!("{:.0}", mas * 1000.0),
        ));
    }
    if let Some(spot) = img.focal_spot_mm {
        obj.put(text(tags::FOCAL_SPOTS, VR::DS, &ds(spot)));
    }
    let file = obj
        .with_meta(
            FileMetaTableBuilder::new()
                .transfer_syntax(uids::EXPLICIT_VR_LITTLE_ENDIAN)
                .implementation_class_uid(uid::implementation_class_uid())
                .implementation_version_name(fit(
                    &format!("RSASIM_{}", env!("CARGO_PKG_VERSION")),
                    16,
                )),
        )
        .map_err(|e| format!("DICOM file meta group: {e}"))?;
    let mut out = Vec::with_capacity(img.pixels.len() * 2 + 8192);
    file.write_all(&mut out)
        .map_err(|e| format!("DICOM encoding failed: {e}"))?;
    Ok(out)
}

#[cfg(test)]
mod tests;

//! The `[output.dicom]` table: which DICOM Digital X-Ray images to write and the date they
//! carry, and the checks of those keys (and of the detectors a DICOM DX image can describe).

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::{ImageFormat, Scenario};
use crate::diagnostic::{Diagnostic, KeyPath, Locator, cut};

/// The date every DICOM file carries when `study_date` is not given: a fixed, documented date
/// (never the clock), so the files stay byte-identical.
pub const DEFAULT_STUDY_DATE: &str = "2000-01-01";

/// Fewest bits stored a DICOM Digital X-Ray image allows (the DX Image module's Bits Stored is
/// 6 to 16).
pub const DX_MIN_BITS_STORED: u8 = 6;

/// The intent of a DICOM Digital X-Ray image (its SOP class and Presentation Intent Type).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize, JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum DicomIntent {
    /// "For presentation" (`<exposure>-<detector>.dcm`): what a clinic's archive holds and a
    /// clinical RSA program imports. The detector counts as stored, with a Presentation LUT
    /// Shape and a window over 0..I_max so that dense matter displays bright.
    Presentation,
    /// "For processing" (`<exposure>-<detector>-processing.dcm`): the detector counts as
    /// stored, described by Pixel Intensity Relationship and its sign, for image-processing
    /// software.
    Processing,
}

impl DicomIntent {
    /// The end of the file name after `<exposure>-<detector>`.
    pub fn file_suffix(self) -> &'static str {
        match self {
            DicomIntent::Presentation => ".dcm",
            DicomIntent::Processing => "-processing.dcm",
        }
    }

    /// The word used in the UID labels and reports: `presentation` or `processing`.
    pub fn name(self) -> &'static str {
        match self {
            DicomIntent::Presentation => "presentation",
            DicomIntent::Processing => "processing",
        }
    }
}

/// DICOM output options (used when `formats` lists `"dicom"`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DicomOptions {
    /// Which Digital X-Ray images to write per exposure and detector: `"presentation"`
    /// (`<exposure>-<detector>.dcm`), `"processing"` (`<exposure>-<detector>-processing.dcm`) or
    /// both. Default `["presentation"]`.
    #[serde(default = "DicomOptions::default_intents")]
    pub intents: Vec<DicomIntent>,
    /// The Study, Series, Acquisition and Content Date of every DICOM file, `YYYY-MM-DD`
    /// (times are 00:00:00). Default `"2000-01-01"`: a fixed date, never the clock, so the files
    /// stay byte-identical.
    #[serde(default = "DicomOptions::default_study_date")]
    pub study_date: String,
}

impl DicomOptions {
    fn default_intents() -> Vec<DicomIntent> {
        vec![DicomIntent::Presentation]
    }

    fn default_study_date() -> String {
        DEFAULT_STUDY_DATE.into()
    }

    /// Whether nothing was set (then the table is not written back).
    pub fn is_default(&self) -> bool {
        *self == DicomOptions::default()
    }

    /// The study date as DICOM writes it (`YYYYMMDD`), if `study_date` is a valid date.
    pub fn dicom_date(&self) -> Option<String> {
        parse_date(&self.study_date).map(|(y, m, d)| format!("{y:04}{m:02}{d:02}"))
    }
}

impl Default for DicomOptions {
    fn default() -> Self {
        DicomOptions {
            intents: Self::default_intents(),
            study_date: Self::default_study_date(),
        }
    }
}

/// `YYYY-MM-DD` as (year, month, day) if it is a date of the Gregorian calendar, years 1 to
/// 9999.
fn parse_date(text: &str) -> Option<(u32, u32, u32)> {
    let b = text.as_bytes();
    let digits = |r: std::ops::Range<usize>| {
        b[r.clone()]
            .iter()
            .all(u8::is_ascii_digit)
            .then(|| text[r].parse::<u32>().ok())
            .flatten()
    };
    if b.len() != 10 || b[4] != b'-' || b[7] != b'-' {
        return None;
    }
    let (y, m, d) = (digits(0..4)?, digits(5..7)?, digits(8..10)?);
    let leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
    let days = match m {
        1 | 3 | 5 | 7 | 8 | 10 | 12 => 31,
        4 | 6 | 9 | 11 => 30,
        2 if leap => 29,
        2 => 28,
        _ => return None,
    };
    (y >= 1 && (1..=days).contains(&d)).then_some((y, m, d))
}

/// Findings on `[output.dicom]` and on what DICOM output needs of the detectors.
pub fn check(s: &Scenario, loc: &Locator) -> Vec<Diagnostic> {
    let mut out = Vec::new();
    let key = KeyPath::root().key("output").key("dicom");
    let o = &s.output.dicom;
    let writes_dicom = s.output.formats.contains(&ImageFormat::Dicom);
    if !writes_dicom && !o.is_default() {
        out.push(
            loc.warning(
                key.clone(),
                "`[output.dicom]` has no effect: `formats` does not list \"dicom\"",
            )
            .with_help("add \"dicom\" to `[output] formats` or remove the table"),
        );
    }
    if o.intents.is_empty() {
        out.push(
            loc.error(key.key("intents"), "no DICOM image intent is selected")
                .with_help("list \"presentation\", \"processing\" or both"),
        );
    }
    for (i, intent) in o.intents.iter().enumerate() {
        if o.intents[..i].contains(intent) {
            out.push(
                loc.error(
                    key.key("intents").index(i),
                    format!("\"{}\" is listed twice", intent.name()),
                )
                .with_help("list each intent once"),
            );
        }
    }
    if parse_date(&o.study_date).is_none() {
        out.push(
            loc.error(
                key.key("study_date"),
                format!(
                    "`{}` is not a date of the form YYYY-MM-DD",
                    cut(&o.study_date)
                ),
            )
            .with_help(format!(
                "give a calendar date such as \"{DEFAULT_STUDY_DATE}\" (the default)"
            )),
        );
    }
    if writes_dicom {
        for (i, d) in s.detectors.iter().enumerate() {
            if d.bpp < DX_MIN_BITS_STORED {
                out.push(
                    loc.error(
                        KeyPath::root().key("detectors").index(i).key("bpp"),
                        format!(
                            "detector `{}` has {} bits per pixel, but a DICOM Digital X-Ray image stores {DX_MIN_BITS_STORED} to 16",
                            cut(&d.id),
                            d.bpp
                        ),
                    )
                    .with_help(format!(
                        "use bpp = {DX_MIN_BITS_STORED} to 16, or leave \"dicom\" out of `[output] formats`"
                    )),
                );
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates_are_checked_against_the_calendar() {
        assert_eq!(parse_date("2000-01-01"), Some((2000, 1, 1)));
        assert_eq!(parse_date("2024-02-29"), Some((2024, 2, 29)));
        assert_eq!(parse_date("2000-02-29"), Some((2000, 2, 29)));
        for bad in [
            "1900-02-29",
            "2023-02-29",
            "2023-04-31",
            "2023-13-01",
            "2023-00-10",
            "0000-01-01",
            "2023-1-01",
            "20230101",
            "2023-01-01T00:00",
            "+023-01-01",
            "２０２３-01-01",
        ] {
            assert_eq!(parse_date(bad), None, "{bad}");
        }
        let o = DicomOptions {
            study_date: "2024-02-29".into(),
            ..DicomOptions::default()
        };
        assert_eq!(o.dicom_date().as_deref(), Some("20240229"));
    }

    #[test]
    fn file_suffixes_and_names() {
        assert_eq!(DicomIntent::Presentation.file_suffix(), ".dcm");
        assert_eq!(DicomIntent::Processing.file_suffix(), "-processing.dcm");
        assert_eq!(
            serde_json::to_string(&DicomIntent::Processing).unwrap(),
            "\"processing\""
        );
        assert_eq!(DicomOptions::default().intents, [DicomIntent::Presentation]);
        assert_eq!(
            DicomOptions::default().dicom_date().as_deref(),
            Some("20000101")
        );
    }
}

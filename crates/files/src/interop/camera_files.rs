//! What `rsasim camera` writes for each beamline: the camera in three forms, printed or as a new
//! folder.
//!
//! - `<detector>_MayaCam.txt`: MayaCam 2.0 ([`PinholeCamera::mayacam_text`]), as `rsasim export`
//!   writes it, for XMALab and Autoscoper.
//! - `dlt11.csv`: DLT-11 coefficients L1…L11 (L12 = 1), 11 rows, one column per detector, in
//!   XMALab's and DLTdv's convention: 1-based pixels, origin bottom-left ([`PinholeCamera::dlt`]).
//! - `<detector>_opencv.json`: the OpenCV pinhole model, `x ∝ K·(R·X + t)` with pixels 0-based
//!   from the top-left of the image (no distortion): `image_size_px` (width, height), `K`, `R`
//!   (world → camera rows), `t_mm`, `dist_coeffs` (all zero), with the beamline it was made
//!   from (`source_mm`, `corners_mm` in the order of [`super::detector_corners`],
//!   `pixel_pitch_mm`).
//!
//! Every form describes the image flipped top to bottom against rsasim's (see
//! [`super::camera`]), the image `rsasim export` writes.

use std::path::{Path, PathBuf};

use glam::DVec3;

use super::camera::PinholeCamera;
use super::detector_corners::corners_of;
use super::failure::Error;
use crate::expand::DetectorState;
use crate::output::atomic::write_staged;
use crate::output::commit::{FolderKind, OutputTarget};

/// Format tag of `<detector>_opencv.json`.
pub const OPENCV_FORMAT: &str = "rsasim-opencv-camera/1";

/// A beamline's camera with what it was made from.
#[derive(Debug, Clone, PartialEq)]
pub struct NamedCamera {
    /// The detector's id: the files' names.
    pub detector: String,
    /// Focus position, mm.
    pub source_mm: DVec3,
    /// The image's corners ([`super::detector_corners`]), mm.
    pub corners_mm: [DVec3; 4],
    /// Pixel pitch `[x, y]`, mm.
    pub pixel_pitch_mm: [f64; 2],
    /// The camera.
    pub camera: PinholeCamera,
    /// DLT-11 coefficients L1…L11.
    pub dlt: [f64; 11],
}

impl NamedCamera {
    /// The camera of a source and its detector (box frame), made by
    /// [`PinholeCamera::of_beamline`]; an error says why it has no DLT-11.
    pub fn new(
        source_mm: DVec3,
        detector: &DetectorState,
        camera: PinholeCamera,
    ) -> Result<Self, String> {
        let dlt = camera
            .dlt()
            .map_err(|e| format!("detector `{}`: {e}", crate::diagnostic::cut(&detector.id)))?;
        Ok(NamedCamera {
            detector: detector.id.clone(),
            source_mm,
            corners_mm: corners_of(detector),
            pixel_pitch_mm: detector.pixel_pitch_mm,
            camera,
            dlt,
        })
    }

    /// `<detector>_MayaCam.txt`.
    pub fn mayacam_name(&self) -> String {
        format!("{}_MayaCam.txt", self.detector)
    }

    /// `<detector>_opencv.json`.
    pub fn opencv_name(&self) -> String {
        format!("{}_opencv.json", self.detector)
    }

    /// The OpenCV JSON (see the module docs), one field per line, a matrix on one line.
    pub fn opencv_json(&self) -> String {
        let c = &self.camera;
        let fields: [(&str, String); 11] = [
            ("format", compact(&OPENCV_FORMAT)),
            ("detector", compact(&self.detector.as_str())),
            ("convention", compact(&CONVENTION)),
            ("image_size_px", compact(&c.size)),
            ("K", compact(&c.k)),
            ("R", compact(&c.r)),
            ("t_mm", compact(&c.t)),
            ("dist_coeffs", compact(&[0.0; 5])),
            ("source_mm", compact(&self.source_mm.to_array())),
            (
                "corners_mm",
                compact(&self.corners_mm.map(|c| c.to_array())),
            ),
            ("pixel_pitch_mm", compact(&self.pixel_pitch_mm)),
        ];
        let lines: Vec<String> = fields
            .iter()
            .map(|(k, v)| format!("  \"{k}\": {v}"))
            .collect();
        format!("{{\n{}\n}}\n", lines.join(",\n"))
    }
}

/// What `convention` says in `<detector>_opencv.json`.
const CONVENTION: &str = "x ∝ K·(R·X + t): X in mm (box frame), pixels 0-based from the top-left corner of the image flipped top to bottom against rsasim's (the image rsasim export writes); no distortion";

/// Compact JSON text of a plain value.
fn compact<T: serde::Serialize + ?Sized>(value: &T) -> String {
    serde_json::to_string(value).expect("plain numbers and strings")
}

/// `dlt11.csv`: row i holds coefficient L(i+1) of every camera, in order.
pub fn dlt11_csv(coefficients: &[[f64; 11]]) -> String {
    let mut text = String::new();
    for i in 0..11 {
        let row: Vec<String> = coefficients.iter().map(|l| l[i].to_string()).collect();
        text += &row.join(",");
        text.push('\n');
    }
    text
}

/// Every camera as labelled blocks for a terminal: per camera its MayaCam text, its DLT-11
/// column and its OpenCV JSON, each under a `# <detector>: …` line.
pub fn printed(cameras: &[NamedCamera]) -> String {
    let mut s = String::new();
    for c in cameras {
        s += &format!("# {}: MayaCam 2.0 ({})\n", c.detector, c.mayacam_name());
        s += &c.camera.mayacam_text();
        s += &format!(
            "\n# {}: DLT-11, L1 to L11 (XMALab and DLTdv: 1-based pixels, origin bottom-left; a column of dlt11.csv)\n",
            c.detector
        );
        s += &dlt11_csv(&[c.dlt]);
        s += &format!("\n# {}: OpenCV ({})\n", c.detector, c.opencv_name());
        s += &c.opencv_json();
        s.push('\n');
    }
    s
}

/// What [`write_folder`] wrote.
#[derive(Debug)]
pub struct Written {
    /// The folder, as given.
    pub dir: PathBuf,
    /// The files' names in it.
    pub files: Vec<String>,
    /// What the claim and the commit did, for the user.
    pub notes: Vec<String>,
}

/// Writes the new folder `dest` with every camera's files (see the module docs): claimed,
/// staged and swapped in whole, or not at all.
pub fn write_folder(dest: &Path, cameras: &[NamedCamera]) -> Result<Written, Error> {
    let target =
        OutputTarget::claim(dest, FolderKind::Camera).map_err(|d| Error::Input(vec![*d]))?;
    let mut notes = target.notes.clone();
    let staged = target.stage().map_err(|e| Error::Write(e.to_string()))?;
    let mut files: Vec<(String, String)> = Vec::new();
    for c in cameras {
        files.push((c.mayacam_name(), c.camera.mayacam_text()));
        files.push((c.opencv_name(), c.opencv_json()));
    }
    let dlts: Vec<[f64; 11]> = cameras.iter().map(|c| c.dlt).collect();
    files.push(("dlt11.csv".into(), dlt11_csv(&dlts)));
    for (name, text) in &files {
        write_staged(&staged.path().join(name), text.as_bytes())
            .map_err(|e| Error::Write(format!("{name}: {e}")))?;
    }
    let committed = staged.commit().map_err(|e| Error::Write(e.to_string()))?;
    notes.extend(committed.notes);
    Ok(Written {
        dir: committed.path,
        files: files.into_iter().map(|(n, _)| n).collect(),
        notes,
    })
}

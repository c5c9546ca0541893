//! A beamline given as Autoscoper users measure one (Autoscoper issue 320): the source position
//! and the four outer corners of the image, turned into rsasim's detector (and so into a
//! [`super::camera::PinholeCamera`]), and back.
//!
//! # The order of the corners
//!
//! The corners are those of the image the camera describes: the exported image, flipped top to
//! bottom against rsasim's (see [`super::camera`]), with row 0 at the top as XMALab and
//! Autoscoper show it:
//!
//! 1. the outer corner of the first pixel (the top-left corner of row 0),
//! 2. the end of row 0 (top-right),
//! 3. the end of the last row (bottom-right),
//! 4. the start of the last row (bottom-left).
//!
//! In rsasim's detector frame (u along r, v along c, pixel centres at i + 0.5; row j of the
//! exported image is row H − 1 − j of rsasim's) they are the points (u, v) = (0, H), (W, H),
//! (W, 0), (0, 0): corner 1 → 2 runs along r, corner 1 → 4 along −c. The camera's x axis runs
//! from corner 1 to corner 2, its y axis from corner 1 to corner 4, and it looks along x × y,
//! so the source must lie on the side of the image that x × y points away from. The pixel pitch
//! is each side's length over its pixel count.

use std::path::Path;

use glam::{DMat3, DVec3};

use crate::diagnostic::{Diagnostic, cut};
use crate::expand::DetectorState;

/// The largest relative departure from a rectangle accepted: corner 3's distance from where a
/// rectangle puts it, and the cosine of the angle at corner 1, each over the diagonal's length.
pub const RECTANGLE_TOLERANCE: f64 = 1e-6;

/// The corners of a detector in the order of the module docs, box frame, mm.
pub fn corners_of(detector: &DetectorState) -> [DVec3; 4] {
    let frame = detector.frame();
    let [w, h] = detector.pixels.map(f64::from);
    [(0.0, h), (w, h), (w, 0.0), (0.0, 0.0)]
        .map(|(u, v)| frame.pose.to_world(frame.pixel_local(u, v)))
}

/// A beamline as given on the command line: source, corners and pixel counts.
#[derive(Debug, Clone, PartialEq)]
pub struct CornerBeamline {
    /// The detector's name (file names of `rsasim camera --dir`).
    pub id: String,
    /// Focus position, mm.
    pub source_mm: DVec3,
    /// The four corners, in the order of the module docs, mm.
    pub corners_mm: [DVec3; 4],
    /// Columns, rows.
    pub pixels: [u32; 2],
}

fn refuse(field: &str, message: String, help: &str) -> Box<Diagnostic> {
    Box::new(Diagnostic::file_error(Path::new(field), message).with_help(help))
}

const SOURCE_HELP: &str = "give the focus position as X,Y,Z in mm, e.g. --source-mm 0,0,1000";
const CORNERS_HELP: &str = "give the four outer corners of the image as x,y,z;x,y,z;x,y,z;x,y,z in mm: the top-left corner of row 0, the end of row 0, the end of the last row, the start of the last row";
const PIXELS_HELP: &str = "give the image's columns and rows as W,H, e.g. --pixels 1000,800";

/// Finite numbers within the scene's bounds, separated by commas; `count` of them.
fn numbers(
    field: &str,
    what: &str,
    text: &str,
    count: usize,
    help: &str,
) -> Result<Vec<f64>, Box<Diagnostic>> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != count {
        return Err(refuse(
            field,
            format!(
                "{what} `{}` has {} number(s), not {count}",
                cut(text),
                parts.len()
            ),
            help,
        ));
    }
    parts
        .iter()
        .map(|p| {
            p.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite() && x.abs() <= crate::scenario::MAX_ABS)
                .ok_or_else(|| {
                    refuse(
                        field,
                        format!(
                            "{what}: `{}` is not a number within ±{:e} mm",
                            cut(p),
                            crate::scenario::MAX_ABS
                        ),
                        help,
                    )
                })
        })
        .collect()
}

impl CornerBeamline {
    /// Reads `--source-mm X,Y,Z`, `--corners-mm "x,y,z;…"` (four corners) and `--pixels W,H`;
    /// an error names the option and what would be valid.
    pub fn parse(
        id: &str,
        source: &str,
        corners: &str,
        pixels: &str,
    ) -> Result<Self, Box<Diagnostic>> {
        if let Some(why) = crate::output::received::name_problem(id) {
            return Err(refuse(
                "--detector",
                format!("`{}` cannot name a camera's files: {why}", cut(id)),
                "give a plain name, e.g. --detector det1",
            ));
        }
        let source = numbers("--source-mm", "the source", source, 3, SOURCE_HELP)?;
        let parts: Vec<&str> = corners.split(';').collect();
        if parts.len() != 4 {
            return Err(refuse(
                "--corners-mm",
                format!("{} corner(s) given, not 4", parts.len()),
                CORNERS_HELP,
            ));
        }
        let mut corners_mm = [DVec3::ZERO; 4];
        for (k, (part, c)) in parts.iter().zip(&mut corners_mm).enumerate() {
            let v = numbers(
                "--corners-mm",
                &format!("corner {}", k + 1),
                part,
                3,
                CORNERS_HELP,
            )?;
            *c = DVec3::new(v[0], v[1], v[2]);
        }
        let n: Vec<&str> = pixels.split(',').map(str::trim).collect();
        let count = |t: &str| t.parse::<u32>().ok().filter(|&n| n >= 1);
        let [Some(w), Some(h)] = [n.first(), n.get(1)].map(|t| t.and_then(|t| count(t))) else {
            return Err(refuse(
                "--pixels",
                format!("`{}` is not two whole numbers of pixels ≥ 1", cut(pixels)),
                PIXELS_HELP,
            ));
        };
        if n.len() != 2 {
            return Err(refuse(
                "--pixels",
                format!("`{}` has {} numbers, not 2", cut(pixels), n.len()),
                PIXELS_HELP,
            ));
        }
        Ok(CornerBeamline {
            id: id.to_string(),
            source_mm: DVec3::new(source[0], source[1], source[2]),
            corners_mm,
            pixels: [w, h],
        })
    }

    /// rsasim's detector of these corners (see the module docs): refused when the corners are
    /// no rectangle within [`RECTANGLE_TOLERANCE`], or the source does not lie in front of it.
    pub fn detector(&self) -> Result<DetectorState, Box<Diagnostic>> {
        let [p1, p2, p3, p4] = self.corners_mm;
        let (along_row, down) = (p2 - p1, p4 - p1);
        let scale = (p3 - p1).length();
        for (k, side) in [(2, along_row), (4, down)] {
            if side.length() <= RECTANGLE_TOLERANCE * scale || scale == 0.0 {
                return Err(refuse(
                    "--corners-mm",
                    format!("corner {k} coincides with corner 1: the image has no extent"),
                    CORNERS_HELP,
                ));
            }
        }
        let off = (p3 - (p2 + p4 - p1)).length();
        if off > RECTANGLE_TOLERANCE * scale {
            return Err(refuse(
                "--corners-mm",
                format!(
                    "corner 3 lies {off:.3e} mm from where a rectangle puts it (corner 2 + corner 4 − corner 1), more than {RECTANGLE_TOLERANCE:e} of the diagonal"
                ),
                CORNERS_HELP,
            ));
        }
        let cos = along_row.normalize().dot(down.normalize());
        if cos.abs() > RECTANGLE_TOLERANCE {
            return Err(refuse(
                "--corners-mm",
                format!(
                    "the angle at corner 1 (between corners 2 and 4) is {:.6}°, not 90°",
                    cos.clamp(-1.0, 1.0).acos().to_degrees()
                ),
                CORNERS_HELP,
            ));
        }
        let r = along_row.normalize();
        let c = -(down - down.dot(r) * r).normalize();
        let s = r.cross(c);
        let [w, h] = self.pixels.map(f64::from);
        let detector = DetectorState {
            id: self.id.clone(),
            source: "source".into(),
            position_mm: (p1 + p2 + p3 + p4) / 4.0,
            rotation: DMat3::from_cols(r, c, s),
            pixels: self.pixels,
            pixel_pitch_mm: [along_row.length() / w, down.length() / h],
            bpp: 16,
        };
        let distance = (self.source_mm - detector.position_mm).dot(s);
        if distance.is_nan() || distance <= 0.0 {
            return Err(refuse(
                "--source-mm",
                format!(
                    "the source lies {distance:.3} mm in front of the image plane as the corners order the image (the camera looks along (corner 2 − corner 1) × (corner 4 − corner 1)); it must lie in front, more than 0 mm"
                ),
                "the corners of an image seen from the source run clockwise 1 → 2 → 3 → 4; if the image is the mirror image of that view, flip its rows and give the corners in the order 4, 3, 2, 1",
            ));
        }
        Ok(detector)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::rotation_xyz_deg;

    #[test]
    fn corners_of_a_detector_give_it_back() {
        let det = DetectorState {
            id: "det1".into(),
            source: "tube1".into(),
            position_mm: DVec3::new(12.0, -7.0, -480.0),
            rotation: rotation_xyz_deg([3.0, -8.0, 21.0]),
            pixels: [640, 480],
            pixel_pitch_mm: [0.25, 0.2],
            bpp: 16,
        };
        let beamline = CornerBeamline {
            id: "det1".into(),
            source_mm: DVec3::new(-20.0, 15.0, 1290.0),
            corners_mm: corners_of(&det),
            pixels: det.pixels,
        };
        let back = beamline.detector().unwrap();
        assert!((back.position_mm - det.position_mm).length() < 1e-9);
        assert!(back.rotation.abs_diff_eq(det.rotation, 1e-12));
        assert!((back.pixel_pitch_mm[0] - 0.25).abs() < 1e-12);
        assert!((back.pixel_pitch_mm[1] - 0.2).abs() < 1e-12);
    }

    #[test]
    fn bad_text_names_the_option() {
        let ok = "0,0,0;1,0,0;1,1,0;0,1,0";
        let e = CornerBeamline::parse("det1", "0,0", ok, "2,2").unwrap_err();
        assert!(e.to_string().contains("--source-mm") && e.message.contains("not 3"));
        let e = CornerBeamline::parse("det1", "0,0,nan", ok, "2,2").unwrap_err();
        assert!(e.message.contains("`nan` is not a number"), "{e}");
        let e = CornerBeamline::parse("det1", "0,0,1", "0,0,0;1,0,0", "2,2").unwrap_err();
        assert!(e.to_string().contains("--corners-mm") && e.message.contains("2 corner(s)"));
        let e = CornerBeamline::parse("det1", "0,0,1", ok, "2,0").unwrap_err();
        assert!(e.to_string().contains("--pixels"), "{e}");
        let e = CornerBeamline::parse("det1", "0,0,1", ok, "2,2,2").unwrap_err();
        assert!(e.message.contains("not 2"), "{e}");
        let e = CornerBeamline::parse("../x", "0,0,1", ok, "2,2").unwrap_err();
        assert!(e.to_string().contains("--detector"), "{e}");
    }
}

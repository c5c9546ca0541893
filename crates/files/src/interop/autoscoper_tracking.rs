//! Autoscoper's tracking results (`.tra`) read back as poses, for `rsasim evaluate`.
//!
//! What Autoscoper writes (`AutoscoperMainWindow::save_tracking_results`, autoscoper/src/ui/
//! AutoscoperMainWindow.cpp: a loop over the trial's frames, one line each): one line per frame,
//! values separated by a comma or a space, no header; per volume either a 4×4 matrix (16 values,
//! "row" order: translation at 1-based positions 4, 8 and 12; or "column" order: at 13, 14 and 15)
//! or `x, y, z, yaw, pitch, roll` (mm and degrees, R = Rz(yaw)·Ry(pitch)·Rx(roll),
//! `CoordFrame::from_xyzypr`); with "all volumes" the volumes follow each other on the line, in the
//! trial's order. An untracked frame is `NaN` in every value. The pose is world ← volume frame
//! (see [`super::volume`]), turned here into the phantom's pose with the volume frame's offset.
//!
//! A run's trial has one frame, so its file one line; a sequence's trial (exported as one, see
//! [`super::trials`]) has its frames, so its file one line per frame, line k for frame k.
//!
//! Which volumes a file holds is told by its name, as rsasim's export names the trials: `<exposure>_<phantom>.tra`
//! (Autoscoper's own name for one volume's tracking of trial `<exposure>.cfg`) holds that phantom;
//! `<exposure>.tra` holds every volume of that trial in its order. The matrix order is told by the
//! values: a row-order matrix ends in 0, 0, 0, 1; a column-order one has 0 at positions 4, 8
//! and 12. A matrix with a zero translation fits both and is read in row order (Autoscoper's
//! default).

use std::path::Path;

use glam::{DMat3, DVec3};

use super::volume;
use crate::diagnostic::{Diagnostic, cut};
use crate::geometry::rotation_rows;
use crate::output::measured::MeasuredPose;
use crate::output::{MEASURED_FORMAT, Measured, Truth};

/// The phantoms (ids, in the trial's order) a `.tra` file named `file_name` holds for `truth`'s
/// run, given the phantoms that have a volume; or why the name fits no trial.
fn volumes_named<'a>(
    file_name: &str,
    truth: &'a Truth,
    has_volume: &dyn Fn(&str) -> bool,
) -> Result<Vec<&'a str>, String> {
    let stem = file_name
        .strip_suffix(".tra")
        .or_else(|| file_name.strip_suffix(".TRA"))
        .unwrap_or(file_name);
    let mut names = Vec::new();
    for exposure in &truth.run.exposures {
        let trial: Vec<&str> = exposure
            .phantoms
            .iter()
            .map(String::as_str)
            .filter(|p| has_volume(p))
            .collect();
        if trial.is_empty() {
            continue;
        }
        if stem == exposure.id {
            return Ok(trial);
        }
        for p in &trial {
            if stem == format!("{}_{p}", exposure.id) {
                return Ok(vec![p]);
            }
            names.push(format!("{}_{p}.tra", exposure.id));
        }
        names.push(format!("{}.tra", exposure.id));
    }
    Err(format!(
        "the name `{}` names no trial of {}: give {}",
        cut(file_name),
        super::trials::trial_label(&truth.run),
        names.join(" or ")
    ))
}

/// The world ← volume matrix (row order) of one volume's values, or `None` when untracked.
fn matrix(v: &[f64]) -> Option<[f64; 16]> {
    if v.iter().all(|x| x.is_nan()) {
        return None;
    }
    Some(match v.len() {
        16 => {
            let m: [f64; 16] = v.try_into().ok()?;
            let row = m[12] == 0.0 && m[13] == 0.0 && m[14] == 0.0 && m[15] == 1.0;
            if row {
                m
            } else {
                // Column order: transpose.
                std::array::from_fn(|k| m[(k % 4) * 4 + k / 4])
            }
        }
        _ => {
            let [x, y, z, yaw, pitch, roll] = v.try_into().ok()?;
            let r = DMat3::from_rotation_z(yaw.to_radians())
                * DMat3::from_rotation_y(pitch.to_radians())
                * DMat3::from_rotation_x(roll.to_radians());
            let (c0, c1, c2) = (r.x_axis, r.y_axis, r.z_axis);
            [
                c0.x, c1.x, c2.x, x, //
                c0.y, c1.y, c2.y, y, //
                c0.z, c1.z, c2.z, z, //
                0.0, 0.0, 0.0, 1.0,
            ]
        }
    })
}

/// Reads an Autoscoper tracking result of one run (see the module docs). `offset_mm` gives the
/// volume frame's offset of each phantom with a volume ([`volume::frame_offset_mm`]).
pub fn read_tracking(
    file: &Path,
    truth: &Truth,
    offset_mm: &dyn Fn(&str) -> Option<DVec3>,
) -> Result<Measured, Vec<Diagnostic>> {
    let mut frames = read_tracking_frames(file, &[truth], offset_mm)?;
    Ok(frames.remove(0))
}

/// Reads an Autoscoper tracking result of one trial ([`super::trials`]): `frames` are the
/// trial's runs in frame order (one for a run without a frame), and line k of the file (blank
/// lines aside) is the pose of frame k, as `AutoscoperMainWindow::save_tracking_results` writes
/// one line per frame of the trial, frame 0 first. A file with another number of lines is an
/// error naming its first line too many, or the line after its last. Returns one result per
/// frame, in the same order.
pub fn read_tracking_frames(
    file: &Path,
    frames: &[&Truth],
    offset_mm: &dyn Fn(&str) -> Option<DVec3>,
) -> Result<Vec<Measured>, Vec<Diagnostic>> {
    let Some(first) = frames.first() else {
        return Ok(Vec::new());
    };
    let bytes =
        crate::output::received::read_in_folder(file, crate::output::received::MAX_TABLE_BYTES)
            .map_err(|d| vec![d])?;
    let text = std::str::from_utf8(&bytes).map_err(|e| {
        vec![
            Diagnostic::file_error(file, format!("not UTF-8 text: {e}"))
                .with_help("give the .tra file Autoscoper saved"),
        ]
    })?;
    let name = file.file_name().unwrap_or_default().to_string_lossy();
    let phantoms = volumes_named(&name, first, &|p| offset_mm(p).is_some()).map_err(|why| {
        vec![Diagnostic::file_error(file, why).with_help(
            "save the tracking of trial <exposure>.cfg as <exposure>_<phantom>.tra (one volume) or <exposure>.tra (all volumes)",
        )]
    })?;
    let lines: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty())
        .collect();
    let runs: Vec<&crate::expand::Run> = frames.iter().map(|t| &t.run).collect();
    if let Some(problem) = super::trials::frame_count_problem(lines.len(), &runs, "line") {
        let line = match lines.get(frames.len()) {
            Some(surplus) => surplus.0,
            None => lines.last().map_or(1, |l| l.0 + 1),
        };
        return Err(line_error(
            file,
            line,
            problem,
            if first.run.frame.is_some() {
                "save the tracking of the sequence's trial (every frame, as Autoscoper saves it) into the sequence's folder"
            } else {
                "save the tracking of each run's trial into that run's folder (one line per file)"
            },
        ));
    }
    lines
        .iter()
        .zip(frames)
        .map(|(&(line, row), truth)| pose_line(file, line, row, &phantoms, truth, &name, offset_mm))
        .collect()
}

/// An error at the start of `line` of `file`.
fn line_error(file: &Path, line: usize, message: String, help: &str) -> Vec<Diagnostic> {
    let mut d = Diagnostic::file_error(file, message).with_help(help);
    d.line_col = Some((line, 1));
    vec![d]
}

/// The poses of one line `row` (line `line` of `file`, named `name`): the volumes `phantoms`
/// of the frame `truth`.
fn pose_line(
    file: &Path,
    line: usize,
    row: &str,
    phantoms: &[&str],
    truth: &Truth,
    name: &str,
    offset_mm: &dyn Fn(&str) -> Option<DVec3>,
) -> Result<Measured, Vec<Diagnostic>> {
    let at = |message: String, help: &str| line_error(file, line, message, help);
    let mut values = Vec::new();
    for token in row.split([',', ' ', '\t']).filter(|t| !t.is_empty()) {
        // C++ streams print NaN as `nan`, `-nan` or `NaN`.
        let v = if token
            .trim_start_matches(['-', '+'])
            .eq_ignore_ascii_case("nan")
        {
            f64::NAN
        } else {
            match token.parse::<f64>() {
                Ok(v) if v.is_finite() && v.abs() <= crate::scenario::MAX_ABS => v,
                _ => {
                    return Err(at(
                        format!("`{}` is not a finite number", cut(token)),
                        "Autoscoper writes decimal numbers or NaN",
                    ));
                }
            }
        };
        values.push(v);
    }
    let n = phantoms.len();
    let per = match values.len() {
        l if l == 16 * n => 16,
        l if l == 6 * n => 6,
        l => {
            return Err(at(
                format!(
                    "{l} values for {n} volume(s) ({}): Autoscoper writes 16 per volume (a matrix) or 6 (x, y, z, yaw, pitch, roll)",
                    phantoms.join(", ")
                ),
                "save the tracking as a matrix or as xyzypr, the volumes of this trial only",
            ));
        }
    };
    let mut measured = Measured {
        format: MEASURED_FORMAT.into(),
        run: truth.run.id.clone(),
        software: format!("Autoscoper ({})", cut(name)),
        methods: None,
        sources: Vec::new(),
        detectors: Vec::new(),
        phantoms: Vec::new(),
    };
    for (k, phantom) in phantoms.iter().enumerate() {
        let v = &values[k * per..(k + 1) * per];
        if v.iter().any(|x| x.is_nan()) && !v.iter().all(|x| x.is_nan()) {
            return Err(at(
                format!("volume `{phantom}` is NaN in some values but not all"),
                "an untracked frame is NaN in every value",
            ));
        }
        let Some(m) = matrix(v) else {
            continue;
        };
        let bottom = [m[12], m[13], m[14], m[15]];
        if bottom != [0.0, 0.0, 0.0, 1.0] {
            return Err(at(
                format!(
                    "volume `{phantom}`: the matrix's last row (row order) or column (column order) is {bottom:?}, not 0, 0, 0, 1"
                ),
                "give the file as Autoscoper wrote it",
            ));
        }
        let Some(offset) = offset_mm(phantom) else {
            continue;
        };
        let pose = volume::pose_of_tra(&m, offset);
        measured.phantoms.push(MeasuredPose {
            id: phantom.to_string(),
            position_mm: pose.position_mm.to_array(),
            rotation: Some(rotation_rows(&pose.rotation)),
            markers: Vec::new(),
            quality: None,
        });
    }
    Ok(measured)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn xyzypr_is_z_then_y_then_x() {
        // yaw 90°: x → y. pitch 90° then: x → −z first, then yaw leaves z. By hand:
        // Rz(90)·Ry(90)·Rx(0) maps x = (1,0,0) → Ry: (0,0,−1) → Rz: (0,0,−1).
        let m = matrix(&[1.0, 2.0, 3.0, 90.0, 90.0, 0.0]).unwrap();
        let x_image = [m[0], m[4], m[8]];
        assert!((x_image[0]).abs() < 1e-15 && x_image[1].abs() < 1e-15);
        assert!((x_image[2] + 1.0).abs() < 1e-15);
        // Rz(90)·Ry(0)·Rx(90) maps y → z (Rx) → z (Rz).
        let m = matrix(&[0.0, 0.0, 0.0, 90.0, 0.0, 90.0]).unwrap();
        assert!((m[9] - 1.0).abs() < 1e-15, "{m:?}");
        assert_eq!([m[3], m[7], m[11]], [0.0, 0.0, 0.0]);
    }

    #[test]
    fn column_order_is_transposed_and_nan_is_untracked() {
        let row = [
            0.0, -1.0, 0.0, 10.0, 1.0, 0.0, 0.0, 20.0, 0.0, 0.0, 1.0, 30.0, 0.0, 0.0, 0.0, 1.0,
        ];
        let col: Vec<f64> = (0..16).map(|k| row[(k % 4) * 4 + k / 4]).collect();
        assert_eq!(matrix(&col).unwrap(), row);
        assert_eq!(matrix(&row).unwrap(), row);
        assert_eq!(matrix(&[f64::NAN; 16]), None);
    }
}

//! XMALab's files: what `rsasim export --to xmalab` writes for it (the calibration object's
//! frame specification and references, the model markers' reference coordinates) and what it
//! exports that `rsasim evaluate` reads back (rigid-body transformations, 3-D points).
//!
//! Layouts, from XMALab's public code (`CalibrationObject::loadCoords`, `Trial::loadMarkersFromCSV`,
//! `Trial::saveRigidBodyTransformations`, `Trial::save3dPoints`, `RigidBody::getTransformationMatrix`):
//!
//! - **Frame specification**: a header line, then one bead per line `x,y,z` (mm, box frame).
//! - **References**: lines `<1-based index> <name>` (name: letters, digits and spaces, at most 20).
//! - **Marker reference coordinates** ("Import CSV" in the Points window): line 1
//!   `<name>_x,<name>_y,<name>_z,…`, line 2 the coordinates, mm, in the model's own frame.
//! - **Rigid-body transformations** (one file): optional `Frame` column, then per body 16 columns
//!   `<body>_R11,_R12,_R13,_01,_R21,_R22,_R23,_02,_R31,_R32,_R33,_03,_TX,_TY,_TZ,_1` (a filtered
//!   export adds `_<cutoff>Hz` to every name); one row per frame; `NaN` for an untracked frame.
//!   The 3×3 block R (read row by row) is XMALab's world → body rotation, so the body's axes in the
//!   world (the columns of rsasim's rotation) are the rows of R; (TX, TY, TZ) is the body origin
//!   in the world, mm.
//! - **3-D points** (one file): optional `Frame` column, then per marker `<name>_X,_Y,_Z`, mm,
//!   world frame; `NaN` for an untracked marker.
//! - **2-D points** (one file): optional `Frame` column, or XMALab's offset columns, then per
//!   marker `<name>_cam<j>_X,<name>_cam<j>_Y` for cameras j = 1… (marker-major); pixels of the
//!   exported (flipped) images, 0-based and y down unless the user states XMALab's other
//!   options ([`super::xmalab_points2d`]). They are triangulated with the exported true cameras.
//!
//! A run's trial has one frame, so its export one data row; a sequence's trial ([`super::trials`])
//! one data row per frame, row k for frame k ([`read_export_frames`]).

use std::path::Path;

use glam::DVec3;

use crate::diagnostic::{Diagnostic, cut};
use crate::geometry::{fit_rigid, rotation_rows, triangulate};
use crate::output::measured::{FitQuality, MeasuredPoint, MeasuredPose};
use crate::output::{MEASURED_FORMAT, Measured, Truth};

use super::xmalab_points2d::{PixelOptions, offset_columns};

/// The frame specification of a calibration object: a header line, then `x,y,z` per bead.
/// XMALab's blob detection looks for dark beads unless the header holds `white`
/// (`CalibrationObject::loadCoords`); `white_beads` writes the header XMALab itself writes then
/// (`CalibrationObject::saveCoords`).
pub fn frame_specification(beads_mm: &[DVec3], white_beads: bool) -> String {
    let mut s = String::from(if white_beads { "white\n" } else { "x,y,z\n" });
    for b in beads_mm {
        s += &format!("{},{},{}\n", b.x, b.y, b.z);
    }
    s
}

/// A name XMALab's references reader accepts: letters and digits of `id` (others dropped), at
/// most 20 characters, or `bead<index>` when nothing is left.
fn reference_name(id: &str, index: usize) -> String {
    let n: String = id
        .chars()
        .filter(char::is_ascii_alphanumeric)
        .take(20)
        .collect();
    if n.is_empty() {
        format!("bead{index}")
    } else {
        n
    }
}

/// The references file: `<1-based index> <name>` for each chosen bead.
pub fn references(ids: &[String], chosen: &[usize]) -> String {
    chosen
        .iter()
        .map(|&i| format!("{} {}\n", i + 1, reference_name(&ids[i], i + 1)))
        .collect()
}

/// The marker reference coordinates XMALab imports with "Import CSV": names and local
/// coordinates of a model's beads, on two lines.
pub fn marker_reference_csv(beads: &[(String, DVec3)]) -> String {
    let names: Vec<String> = beads
        .iter()
        .map(|(id, _)| format!("{id}_x,{id}_y,{id}_z"))
        .collect();
    let coords: Vec<String> = beads
        .iter()
        .map(|(_, p)| format!("{},{},{}", p.x, p.y, p.z))
        .collect();
    format!("{}\n{}\n", names.join(","), coords.join(","))
}

/// The 16 column suffixes of one rigid body, in XMALab's order.
const BODY_COLUMNS: [&str; 16] = [
    "R11", "R12", "R13", "01", "R21", "R22", "R23", "02", "R31", "R32", "R33", "03", "TX", "TY",
    "TZ", "1",
];

/// One cell of a CSV line with its 1-based character column.
struct Cell<'a> {
    text: &'a str,
    column: usize,
}

fn cells(line: &str) -> Vec<Cell<'_>> {
    cells_from(line, 1)
}

/// [`cells`] of a line's tail that starts at character column `column`.
fn cells_from(line: &str, mut column: usize) -> Vec<Cell<'_>> {
    let mut out = Vec::new();
    for part in line.split(',') {
        let lead = part.chars().count() - part.trim_start().chars().count();
        out.push(Cell {
            text: part.trim(),
            column: column + lead,
        });
        column += part.chars().count() + 1;
    }
    out
}

/// A name without XMALab's filter suffix `_<cutoff>Hz`.
fn without_filter_suffix(name: &str) -> &str {
    if let Some(stem) = name.strip_suffix("Hz")
        && let Some(at) = stem.rfind('_')
        && stem[at + 1..].parse::<f64>().is_ok()
    {
        return &name[..at];
    }
    name
}

/// Reads an XMALab export for one run: rigid-body transformations, 3-D points or 2-D points,
/// told apart by the header. `truth` gives the run id, the phantoms (ids, beads) names are
/// matched against and the cameras; `pixels` how the 2-D points were exported.
pub fn read_export(
    file: &Path,
    truth: &Truth,
    pixels: PixelOptions,
) -> Result<Measured, Vec<Diagnostic>> {
    let mut frames = read_export_frames(file, &[truth], pixels)?;
    Ok(frames.remove(0))
}

/// Reads an XMALab export of one trial ([`super::trials`]): `frames` are the trial's runs in
/// frame order (one for a run without a frame). XMALab writes one data row per frame of its
/// trial, frame 1 first (`Trial::saveRigidBodyTransformations`, `Trial::save3dPoints`,
/// `Trial::save2dPoints`, src/core/Trial.cpp), so row k is frame k; a `Frame` column, XMALab's
/// 1-based frame number in the trial, is honoured in a sequence: row `Frame = k` is the trial's
/// k-th frame, each frame once, and the frames no row names (XMALab's "from"/"to" export of part
/// of a trial, which it writes only with the `Frame` column) are untracked, as a row of NaN.
/// Without the column, a file with another number of data rows is an error naming its first row
/// too many, or the line after its last. Returns one result per frame, in the same order.
pub fn read_export_frames(
    file: &Path,
    frames: &[&Truth],
    pixels: PixelOptions,
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
                .with_help("give the CSV file XMALab exported"),
        ]
    })?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let lines: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim_end_matches('\r')))
        .filter(|(_, l)| !l.trim().is_empty())
        .collect();
    let at = |line: usize, column: usize, message: String, help: &str| {
        let mut d = Diagnostic::file_error(file, message).with_help(help);
        d.line_col = Some((line, column));
        vec![d]
    };
    let Some(&(header_line, header)) = lines.first() else {
        return Err(vec![
            Diagnostic::file_error(file, "the file is empty").with_help(
                "export from XMALab with the header row: File → Export → Rigid body transformations (or 3D points)",
            ),
        ]);
    };
    let layout = Layout::of_header(header, first, pixels)
        .map_err(|(column, message, help)| at(header_line, column, message, &help))?;
    let data: Vec<(usize, &str)> = lines[1..].to_vec();
    let runs: Vec<&crate::expand::Run> = frames.iter().map(|t| &t.run).collect();
    // With its `Frame` column XMALab exports the frames from..to the user picked
    // (`Trial::saveRigidBodyTransformations` and `Trial::save3dPoints` take start and stop only
    // when `saveColumn` is set, src/core/Trial.cpp): each row names its frame, and the frames
    // not given are untracked. Without it, every frame of the trial, in order.
    let named_frames = layout.frame_column && first.run.frame.is_some();
    let count_problem = if named_frames && (1..=frames.len()).contains(&data.len()) {
        None
    } else {
        super::trials::frame_count_problem(data.len(), &runs, "data row")
    };
    if let Some(problem) = count_problem {
        let line = data
            .get(frames.len())
            .map_or_else(|| data.last().map_or(header_line, |l| l.0 + 1), |r| r.0);
        return Err(at(
            line,
            1,
            problem,
            if first.run.frame.is_some() {
                "export every frame of the sequence's trial (XMALab's export dialog: from 1 to the last frame; NaN where untracked) into the sequence's folder, all bodies (or markers) in one file"
            } else {
                "save the export of each run's trial into that run's folder (one data row per file)"
            },
        ));
    }
    let mut out: Vec<Option<Measured>> = vec![None; frames.len()];
    for (k, &(row_line, row)) in data.iter().enumerate() {
        let values = cells(row);
        if values.len() != layout.lead + layout.names.len() {
            return Err(at(
                row_line,
                values.last().map_or(1, |c| c.column),
                format!(
                    "the row has {} values but the header {} columns{}",
                    values.len(),
                    layout.lead + layout.names.len(),
                    if layout.offsets {
                        format!(
                            " ({} offset columns and {})",
                            layout.lead,
                            layout.names.len()
                        )
                    } else {
                        String::new()
                    }
                ),
                "every row needs as many values as the header",
            ));
        }
        let index = if named_frames {
            frame_of_row(&values[0], frames.len(), &out)
                .map_err(|(message, help)| at(row_line, values[0].column, message, &help))?
        } else {
            k
        };
        let truth = frames[index];
        let measured = layout
            .measured(file, truth, &values, pixels)
            .map_err(|(column, message, help)| at(row_line, column, message, help))?;
        out[index] = Some(measured);
    }
    // A frame outside the exported range: untracked, as a row of NaN.
    let untracked: Vec<Cell<'_>> = (0..layout.lead + layout.names.len())
        .map(|k| Cell {
            text: "NaN",
            column: k + 1,
        })
        .collect();
    let mut all = Vec::with_capacity(frames.len());
    for (slot, truth) in out.into_iter().zip(frames) {
        all.push(match slot {
            Some(m) => m,
            None => layout
                .measured(file, truth, &untracked, pixels)
                .map_err(|(column, message, help)| at(header_line, column, message, help))?,
        });
    }
    Ok(all)
}

/// The position in the trial (0-based) of the frame a row's `Frame` cell names: XMALab's 1-based
/// frame number in the trial, within its `count` frames (a shard's trial holds the frames the
/// shard holds, in order) and not yet given (`done`); otherwise a message and a help.
fn frame_of_row(
    cell: &Cell<'_>,
    count: usize,
    done: &[Option<Measured>],
) -> Result<usize, (String, String)> {
    let frame = cell
        .text
        .parse::<usize>()
        .ok()
        .filter(|f| (1..=count).contains(f));
    let Some(f) = frame else {
        return Err((
            format!(
                "`Frame` is `{}`, not a frame of the trial (1 to {count})",
                cut(cell.text)
            ),
            "XMALab numbers the frames of a trial from 1".into(),
        ));
    };
    if done.get(f - 1).is_some_and(Option::is_some) {
        return Err((
            format!("frame {f} appears twice"),
            "XMALab writes each frame once".into(),
        ));
    }
    Ok(f - 1)
}

/// What a header of XMALab's exports says: the leading cells that name no value (`Frame`, the
/// offset columns), the value columns and which export it is.
struct Layout<'a> {
    /// Cells every row starts with that name no value.
    lead: usize,
    /// Whether those are XMALab's 2-D offset columns.
    offsets: bool,
    /// Whether the first cell is `Frame`.
    frame_column: bool,
    /// The value columns.
    names: Vec<Cell<'a>>,
    /// Which export.
    kind: Kind,
}

/// The three exports of XMALab that `evaluate` reads.
enum Kind {
    /// Rigid-body transformations: the phantom id of each body, in the header's order.
    Rigid(Vec<String>),
    /// 3-D points (or 2-D points, `planar`): the (phantom, bead) indices of each marker, with
    /// its columns per marker.
    Points {
        planar: bool,
        per_marker: usize,
        markers: Vec<(usize, usize)>,
    },
}

/// A refusal at a 1-based character column of a line: the column, the message and a help.
type ColumnError = (usize, String, String);

impl<'a> Layout<'a> {
    /// Reads the header: its leading cells and which export it is, every column name checked
    /// against `truth`'s phantoms and beads.
    fn of_header(
        header: &'a str,
        truth: &Truth,
        pixels: PixelOptions,
    ) -> Result<Self, ColumnError> {
        // `lead`: the cells every row starts with that name no value (`Frame`, the offset columns).
        let offsets = offset_columns(header, truth.run.detectors.len())?;
        let (lead, frame_column, names) = match offsets {
            Some(o) => {
                let skipped = header[..o.bytes].chars().count();
                (o.count, false, cells_from(&header[o.bytes..], skipped + 1))
            }
            None => {
                let mut head = cells(header);
                let frame_column = head.first().is_some_and(|c| c.text == "Frame");
                let lead = usize::from(frame_column);
                (lead, frame_column, head.split_off(lead))
            }
        };
        let first_name = names.first().map(|c| without_filter_suffix(c.text));
        let rigid = first_name.is_some_and(|n| n.ends_with("_R11"));
        let planar = first_name.is_some_and(|n| n.ends_with("_cam1_X"));
        let points = first_name.is_some_and(|n| n.ends_with("_X"));
        let first_column = names.first().map_or(1, |c| c.column);
        if (offsets.is_some() || pixels != PixelOptions::default()) && !planar {
            return Err((
                first_column,
                format!(
                    "{} XMALab's 2D points, but the header `{}` is not `<marker>_cam1_X,…`",
                    if offsets.is_some() {
                        "offset columns belong to".to_string()
                    } else {
                        format!("{} are options of", pixels.flags())
                    },
                    cut(header)
                ),
                "give XMALab's 2D points export, or leave out the --xmalab-2d options for its other exports".into(),
            ));
        }
        let kind = if rigid {
            Kind::Rigid(rigid_bodies(&names, truth)?)
        } else if points {
            let per_marker = if planar {
                2 * truth.run.detectors.len()
            } else {
                3
            };
            Kind::Points {
                planar,
                per_marker,
                markers: point_markers(&names, truth, planar, per_marker)?,
            }
        } else {
            return Err((
                first_column,
                format!(
                    "the header `{}` is none of XMALab's rigid-body transformations (`<body>_R11,…`), 3D points (`<marker>_X,…`) or 2D points (`<marker>_cam1_X,…`)",
                    cut(header)
                ),
                "export from XMALab with \"header row\" checked, all bodies (or markers) in one file".into(),
            ));
        };
        Ok(Layout {
            lead,
            offsets: offsets.is_some(),
            frame_column,
            names,
            kind,
        })
    }

    /// The export's name in XMALab's menu, for the results' software field.
    fn export_name(&self) -> &'static str {
        match &self.kind {
            Kind::Rigid(_) => "rigid-body transformations",
            Kind::Points { planar: true, .. } => "2D points",
            Kind::Points { .. } => "3D points",
        }
    }

    /// One frame's results from one data row's `values` (as many as the header's columns).
    fn measured(
        &self,
        file: &Path,
        truth: &Truth,
        values: &[Cell<'_>],
        pixels: PixelOptions,
    ) -> Result<Measured, (usize, String, &'static str)> {
        if self.offsets
            && let Some(c) = values[..self.lead]
                .iter()
                .find(|c| c.text.parse::<f64>().is_err())
        {
            return Err((
                c.column,
                format!("offset column `{}` is not a number", cut(c.text)),
                "XMALab writes 0 in every offset column",
            ));
        }
        let mut numbers = Vec::with_capacity(self.names.len());
        for c in &values[self.lead..] {
            let x = if c.text.eq_ignore_ascii_case("nan") {
                f64::NAN
            } else {
                c.text
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| {
                        (
                            c.column,
                            format!("`{}` is not a number", cut(c.text)),
                            "XMALab writes decimal numbers or NaN",
                        )
                    })?
            };
            numbers.push(x);
        }
        let mut measured = Measured {
            format: MEASURED_FORMAT.into(),
            run: truth.run.id.clone(),
            software: format!(
                "XMALab ({} {})",
                self.export_name(),
                file.file_name().unwrap_or_default().to_string_lossy()
            ),
            methods: None,
            sources: Vec::new(),
            detectors: Vec::new(),
            phantoms: Vec::new(),
        };
        measured.phantoms = match &self.kind {
            Kind::Rigid(bodies) => rigid_poses(bodies, &numbers, &values[self.lead..])?,
            Kind::Points {
                planar,
                per_marker,
                markers,
            } => {
                let cameras = if *planar {
                    super::camera::run_cameras(&truth.run).map_err(|e| {
                        (
                            1,
                            e,
                            "2D points are triangulated with the run's true cameras",
                        )
                    })?
                } else {
                    Vec::new()
                };
                let found = markers
                    .iter()
                    .zip(numbers.chunks(*per_marker))
                    .filter_map(|(&(pi, mi), v)| {
                        let point = if *planar {
                            triangulated(&cameras, v, pixels)
                        } else {
                            DVec3::new(v[0], v[1], v[2])
                        };
                        point.is_finite().then_some((pi, mi, point))
                    })
                    .collect::<Vec<_>>();
                fit_phantoms(truth, &found)
            }
        };
        Ok(measured)
    }
}

/// Refuses value columns `names` that do not come in groups of `per` (`what` columns), at the
/// last column.
fn check_groups(names: &[Cell<'_>], per: usize, what: &str, help: &str) -> Result<(), ColumnError> {
    if per > 0 && names.len().is_multiple_of(per) {
        return Ok(());
    }
    Err((
        names.last().map_or(1, |c| c.column),
        format!("{} {what} columns is not a multiple of {per}", names.len()),
        help.to_string(),
    ))
}

/// The phantom id of each rigid body of a header's value columns `names`: 16 columns a body, in
/// XMALab's order, each body a phantom of `truth`.
fn rigid_bodies(names: &[Cell<'_>], truth: &Truth) -> Result<Vec<String>, ColumnError> {
    let phantom_ids: Vec<&str> = truth.run.phantoms.iter().map(|p| p.id.as_str()).collect();
    let layout_help =
        "each rigid body has 16 columns: _R11,_R12,_R13,_01,…,_TX,_TY,_TZ,_1".to_string();
    check_groups(names, 16, "transformation", &layout_help)?;
    let mut bodies = Vec::new();
    for group in names.chunks(16) {
        let first = without_filter_suffix(group[0].text);
        let Some(body) = first.strip_suffix("_R11") else {
            return Err((
                group[0].column,
                format!("column `{}` should be `<body>_R11`", cut(group[0].text)),
                layout_help,
            ));
        };
        for (c, suffix) in group.iter().zip(BODY_COLUMNS) {
            if without_filter_suffix(c.text) != format!("{body}_{suffix}") {
                return Err((
                    c.column,
                    format!("column `{}` should be `{body}_{suffix}`", cut(c.text)),
                    "the 16 columns of a body are _R11,_R12,_R13,_01,_R21,_R22,_R23,_02,_R31,_R32,_R33,_03,_TX,_TY,_TZ,_1".into(),
                ));
            }
        }
        if !phantom_ids.contains(&body) {
            return Err((
                group[0].column,
                format!(
                    "rigid body `{}` is not a phantom of run {}",
                    cut(body),
                    truth.run.id
                ),
                format!(
                    "name each rigid body in XMALab after its phantom: {}",
                    phantom_ids.join(", ")
                ),
            ));
        }
        bodies.push(body.to_string());
    }
    Ok(bodies)
}

/// The poses of one row's rigid bodies from its `numbers` (16 a body; `values`, the row's value
/// cells, locate errors). A body with a `NaN` was not tracked in this frame.
fn rigid_poses(
    bodies: &[String],
    numbers: &[f64],
    values: &[Cell<'_>],
) -> Result<Vec<MeasuredPose>, (usize, String, &'static str)> {
    let mut out = Vec::new();
    for (b, body) in bodies.iter().enumerate() {
        let m = &numbers[b * 16..b * 16 + 16];
        if m.iter().any(|x| x.is_nan()) {
            continue; // not tracked in this frame
        }
        let bottom = [m[3], m[7], m[11], m[15]];
        if (bottom[0].abs() + bottom[1].abs() + bottom[2].abs() + (bottom[3] - 1.0).abs()) > 1e-6 {
            return Err((
                values[b * 16 + 3].column,
                format!("body `{body}`: _01, _02, _03 must be 0 and _1 must be 1, not {bottom:?}"),
                "give the file as XMALab wrote it",
            ));
        }
        // R (rows) maps world to body; rsasim's rotation has the body axes as columns,
        // which are R's rows: rotation = Rᵀ.
        let world_to_body = [[m[0], m[1], m[2]], [m[4], m[5], m[6]], [m[8], m[9], m[10]]];
        let rotation = [0, 1, 2].map(|i| [0, 1, 2].map(|j| world_to_body[j][i]));
        out.push(MeasuredPose {
            id: body.clone(),
            position_mm: [m[12], m[13], m[14]],
            rotation: Some(rotation),
            markers: Vec::new(),
            quality: None,
        });
    }
    Ok(out)
}

/// The (phantom, bead) indices of each marker of a header's point columns `names`
/// (`per_marker` columns a marker: `_X,_Y,_Z`, or `_cam<j>_X,_cam<j>_Y` per camera when
/// `planar`), each a bead of `truth` named once.
fn point_markers(
    names: &[Cell<'_>],
    truth: &Truth,
    planar: bool,
    per_marker: usize,
) -> Result<Vec<(usize, usize)>, ColumnError> {
    let suffixes: Vec<String> = if planar {
        (1..=per_marker / 2)
            .flat_map(|j| [format!("_cam{j}_X"), format!("_cam{j}_Y")])
            .collect()
    } else {
        vec!["_X".into(), "_Y".into(), "_Z".into()]
    };
    let layout_help = format!(
        "each marker has {per_marker} columns: <name>{}",
        suffixes.join(",<name>")
    );
    check_groups(names, per_marker, "point", &layout_help)?;
    let mut seen: Vec<(usize, usize)> = Vec::new();
    for group in names.chunks(per_marker) {
        let first = without_filter_suffix(group[0].text);
        let Some(name) = first.strip_suffix(suffixes[0].as_str()) else {
            return Err((
                group[0].column,
                format!(
                    "column `{}` should be `<marker>{}`",
                    cut(group[0].text),
                    suffixes[0]
                ),
                layout_help,
            ));
        };
        for (c, suffix) in group.iter().zip(&suffixes) {
            if without_filter_suffix(c.text) != format!("{name}{suffix}") {
                return Err((
                    c.column,
                    format!("column `{}` should be `{name}{suffix}`", cut(c.text)),
                    layout_help,
                ));
            }
        }
        let (pi, mi) =
            match_bead(truth, name).map_err(|(message, help)| (group[0].column, message, help))?;
        if let Some(before) = seen.iter().position(|s| *s == (pi, mi)) {
            return Err((
                group[0].column,
                format!(
                    "marker `{}` names the same bead as marker {} of the header",
                    cut(name),
                    before + 1
                ),
                "export each bead once".into(),
            ));
        }
        seen.push((pi, mi));
    }
    Ok(seen)
}

/// A bead's 2-D points `v` (x, y per camera; NaN where not seen) triangulated with the true
/// `cameras`; NaN (or infinite) when fewer than two see it.
fn triangulated(
    cameras: &[(DVec3, super::camera::PinholeCamera)],
    v: &[f64],
    pixels: PixelOptions,
) -> DVec3 {
    let rays: Vec<(DVec3, DVec3)> = cameras
        .iter()
        .zip(v.chunks(2))
        .filter(|(_, xy)| !xy[0].is_nan() && !xy[1].is_nan())
        .map(|((source, cam), xy)| {
            let xy = pixels.to_xmalab([xy[0], xy[1]], cam.size[1]);
            (*source, cam.ray_direction(xy))
        })
        .collect();
    triangulate(&rays).0
}

/// The (phantom, bead) indices a marker name designates: a bead id unique over the run's
/// phantoms, or `<phantom>_<bead>`; otherwise a message and a help.
fn match_bead(truth: &Truth, name: &str) -> Result<(usize, usize), (String, String)> {
    let matches: Vec<(usize, usize)> = truth
        .run
        .phantoms
        .iter()
        .enumerate()
        .flat_map(|(pi, p)| {
            p.markers.iter().enumerate().filter_map(move |(mi, m)| {
                (m.id == name || format!("{}_{}", p.id, m.id) == name).then_some((pi, mi))
            })
        })
        .collect();
    match matches.as_slice() {
        [one] => Ok(*one),
        [] => Err((
            format!(
                "marker `{}` is not a bead of run {}",
                cut(name),
                truth.run.id
            ),
            format!(
                "name each marker after its bead (e.g. {}), or <phantom>_<bead> when bead ids repeat",
                truth
                    .run
                    .phantoms
                    .iter()
                    .flat_map(|p| p.markers.iter().map(|m| m.id.as_str()))
                    .take(3)
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )),
        _ => Err((
            format!("marker `{}` names a bead of several phantoms", cut(name)),
            "name it <phantom>_<bead>".into(),
        )),
    }
}

/// The pose of every phantom with at least three measured beads: the least-squares rigid fit of
/// its bead table (local frame) to the measured points, with the points and the fit's quality.
fn fit_phantoms(truth: &Truth, found: &[(usize, usize, DVec3)]) -> Vec<MeasuredPose> {
    let mut out = Vec::new();
    for (pi, phantom) in truth.run.phantoms.iter().enumerate() {
        let mine: Vec<&(usize, usize, DVec3)> = found.iter().filter(|f| f.0 == pi).collect();
        if mine.len() < 3 {
            continue;
        }
        let pose = phantom.pose();
        let local: Vec<DVec3> = mine
            .iter()
            .map(|f| pose.to_local(phantom.markers[f.1].position_mm))
            .collect();
        let world: Vec<DVec3> = mine.iter().map(|f| f.2).collect();
        let Ok(fit) = fit_rigid(&local, &world) else {
            continue;
        };
        out.push(MeasuredPose {
            id: phantom.id.clone(),
            position_mm: fit.pose.position_mm.to_array(),
            rotation: Some(rotation_rows(&fit.pose.rotation)),
            markers: mine
                .iter()
                .map(|f| MeasuredPoint {
                    id: phantom.markers[f.1].id.clone(),
                    position_mm: f.2.to_array(),
                    quality: None,
                })
                .collect(),
            quality: Some(FitQuality {
                beads_used: Some(mine.len()),
                mean_error_mm: Some(fit.mean_error_mm),
                condition_number: Some(fit.condition_number),
                ..Default::default()
            }),
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_names_are_what_xmalabs_reader_takes() {
        // `CalibrationObject::loadCoords` reads `%i %20[0-9a-zA-Z ]s`.
        assert_eq!(
            references(
                &[
                    "F1-00-01".into(),
                    "x".into(),
                    "F1-00-03".into(),
                    "-".into(),
                    "C1".into()
                ],
                &[0, 2, 3]
            ),
            "1 F10001\n3 F10003\n4 bead4\n"
        );
    }

    #[test]
    fn filter_suffixes_are_removed() {
        assert_eq!(without_filter_suffix("femur_R11_25Hz"), "femur_R11");
        assert_eq!(without_filter_suffix("femur_R11_2.5Hz"), "femur_R11");
        assert_eq!(without_filter_suffix("femur_R11"), "femur_R11");
        assert_eq!(without_filter_suffix("a_bHz"), "a_bHz");
    }

    #[test]
    fn marker_reference_csv_has_two_lines() {
        let s = marker_reference_csv(&[
            ("K1".into(), DVec3::new(1.0, 2.5, -3.0)),
            ("K2".into(), DVec3::new(0.0, 0.0, 4.0)),
        ]);
        assert_eq!(s, "K1_x,K1_y,K1_z,K2_x,K2_y,K2_z\n1,2.5,-3,0,0,4\n");
    }

    #[test]
    fn a_second_body_without_its_r11_column_is_an_error_not_a_panic() {
        let tmp = tempfile::tempdir().unwrap();
        let file = tmp.path().join("x.csv");
        let names = [
            "R11", "R12", "R13", "01", "R21", "R22", "R23", "02", "R31", "R32", "R33", "03", "TX",
            "TY", "TZ", "1",
        ];
        let mut header: Vec<String> = names.iter().map(|n| format!("a_{n}")).collect();
        header.extend((0..16).map(|_| "é".to_string()));
        let row = vec!["0"; 32].join(",");
        std::fs::write(&file, format!("{}\n{row}\n", header.join(","))).unwrap();
        let truth: Truth = serde_json::from_str(
            r#"{"format": "rsasim-truth/1", "program": "rsasim test", "scenario": "t",
                "id": "n0-r00", "noise_level_index": 0, "noise_level": 0.0, "run_index": 0,
                "geometry_stream": "g",
                "box_pose_in_scanner": {"position_mm": [0, 0, 0],
                                        "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]},
                "sources": [], "detectors": [], "exposures": [], "images": [],
                "phantoms": [{"id": "a", "kind": "beads", "position_mm": [0, 0, 0],
                              "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
                              "markers": [{"id": "K1", "position_mm": [0, 0, 0], "diameter_mm": 1}]}]}"#,
        )
        .unwrap();
        let e = read_export(&file, &truth, PixelOptions::default()).unwrap_err();
        assert_eq!(e[0].line_col.map(|l| l.0), Some(1));
        assert!(
            e[0].message.contains("should be `<body>_R11`"),
            "{}",
            e[0].message
        );
        std::fs::write(&file, "K1_X,K1_Y,K1_Z,é,b,c\n1,2,3,4,5,6\n").unwrap();
        let e = read_export(&file, &truth, PixelOptions::default()).unwrap_err();
        assert!(
            e[0].message.contains("should be `<marker>_X`"),
            "{}",
            e[0].message
        );
    }

    #[test]
    fn cells_know_their_columns() {
        let c = cells("Frame, a_R11,b");
        assert_eq!(
            c.iter().map(|c| (c.text, c.column)).collect::<Vec<_>>(),
            vec![("Frame", 1), ("a_R11", 8), ("b", 14)]
        );
    }
}

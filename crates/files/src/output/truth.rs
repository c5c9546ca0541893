//! `truth.json`: the exact ground truth of one run, in the calibration box frame.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::expand::Run;

/// The format tag of truth files written by this version.
pub const TRUTH_FORMAT: &str = "rsasim-truth/1";

/// Ground truth of one run: every pose drawn (the fields of [`Run`] at top level), and for each
/// image the files and the projected centre of every bead.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Truth {
    /// Always `rsasim-truth/1` for this layout.
    pub format: String,
    /// The program that wrote the file, `rsasim <version>`.
    pub program: String,
    /// The scenario's name.
    pub scenario: String,
    /// The run: id, noise level, sources, detectors, phantoms with their beads, exposures.
    #[serde(flatten)]
    pub run: Run,
    /// One entry per exposure and detector.
    pub images: Vec<ImageTruth>,
}

/// One image (an exposure seen by a detector) and where each bead of its phantoms lands.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ImageTruth {
    /// Exposure id.
    pub exposure: String,
    /// Detector id.
    pub detector: String,
    /// The image files, one per format, relative to the run folder.
    pub files: Vec<FileRef>,
    /// Every bead of the exposure's phantoms, projected.
    pub markers: Vec<ProjectedMarker>,
    /// Attenuation mode: pixels clamped at I_max (over-exposure).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub saturated_pixels: Option<u64>,
    /// Attenuation mode with `path_length_layers`: the EXR holding, per material, the path
    /// length (mm) of every pixel's ray (channels `pathlength_mm.<material>`), beside truth.json.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path_lengths: Option<FileRef>,
}

/// A file and its SHA-256.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FileRef {
    /// Path relative to the folder of the JSON file that lists it, with `/` separators.
    pub path: String,
    /// SHA-256 of the file's bytes, lowercase hex.
    pub sha256: String,
}

/// The central projection of a bead's centre onto a detector.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ProjectedMarker {
    /// Id of the phantom the bead belongs to.
    pub phantom: String,
    /// Bead id within its phantom.
    pub id: String,
    /// Continuous pixel coordinates `[u, v]` of the projected centre: pixel (column i, row j)
    /// spans [i, i+1) × [j, j+1), its centre is (i + 0.5, j + 0.5).
    pub pixel: [f64; 2],
    /// Whether the projected centre falls on the active area.
    pub inside: bool,
    /// Whether the bead is hidden by an implant. Attenuation mode: the ray to the pixel under the
    /// projected centre crosses metal (a volume of density ≥ 4 g/cm³, beads aside), i.e. the bead
    /// is seen over the implant. Binary mode: the bead's disc shares a pixel with the shadow of a
    /// solid of the exposure (a mesh or cylinder): some pixel centre whose ray crosses the bead
    /// also crosses that solid, so the bead merges with its shadow.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub occluded: Option<bool>,
    /// Attenuation mode: the fraction of the bead's shadow pixels whose ray also crosses metal.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metal_fraction: Option<f64>,
    /// A frame of a sequence with a pulse (`[sequence] pulse_ms`): the length of the path, px,
    /// its projected centre travels during the pulse (through its places at the start, at each
    /// of the pulse's poses and at the end): the extent of its motion blur. 0 for a bead that
    /// does not move.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub blur_px: Option<f64>,
}

/// Reads `runs/<run>/truth.json` of a received folder through the gate (a regular file within the
/// size cap, matching the manifest's hash where the manifest lists it) and checks what a sender
/// could have forged before anything uses it: the format tag, the run id equal to its folder's
/// name, and every id that names a file or folder (sources, detectors, phantoms, exposures and
/// the images' exposure and detector) a plain name, each at most once.
pub fn read_run_truth(
    folder: &super::received::ReceivedFolder,
    run: &str,
) -> Result<Truth, crate::diagnostic::Diagnostic> {
    use crate::diagnostic::Diagnostic;
    let rel = format!("runs/{run}/truth.json");
    let file = folder.path(&rel);
    let bytes = folder.read(&rel, super::received::MAX_JSON_BYTES)?;
    let text = String::from_utf8_lossy(&bytes);
    let truth: Truth = serde_json::from_str(text.strip_prefix('\u{feff}').unwrap_or(&text))
        .map_err(|e| {
            let mut d = Diagnostic::file_error(
                &file,
                format!("invalid JSON: {}", crate::diagnostic::cut(&e.to_string())),
            )
            .with_help("the file must follow schemas/truth.schema.json");
            if e.line() > 0 {
                d.line_col = Some((e.line(), e.column()));
            }
            d
        })?;
    check_truth_names(&file, run, &truth)?;
    Ok(truth)
}

/// The checks of [`read_run_truth`] on a parsed truth.
pub fn check_truth_names(
    file: &std::path::Path,
    run: &str,
    truth: &Truth,
) -> Result<(), crate::diagnostic::Diagnostic> {
    use super::received::check_name;
    use crate::diagnostic::{Diagnostic, cut};
    if truth.format != TRUTH_FORMAT {
        return Err(Diagnostic::file_error(
            file,
            format!(
                "`format` is {:?}; this rsasim reads {TRUTH_FORMAT:?}",
                cut(&truth.format)
            ),
        ));
    }
    check_name(file, "id", &truth.run.id)?;
    if truth.run.id != run {
        return Err(Diagnostic::file_error(
            file,
            format!(
                "`id` is {:?}, but the file lies in the run folder `{run}`",
                cut(&truth.run.id)
            ),
        )
        .with_help(
            "rsasim names every run folder after its run id: this truth was moved or edited",
        ));
    }
    if let Some(frame) = &truth.run.frame {
        check_frame(file, &truth.run.id, frame).map_err(|d| *d)?;
    }
    let groups: [(&str, Vec<&str>); 4] = [
        (
            "sources[].id",
            truth.run.sources.iter().map(|s| s.id.as_str()).collect(),
        ),
        (
            "detectors[].id",
            truth.run.detectors.iter().map(|d| d.id.as_str()).collect(),
        ),
        (
            "phantoms[].id",
            truth.run.phantoms.iter().map(|p| p.id.as_str()).collect(),
        ),
        (
            "exposures[].id",
            truth.run.exposures.iter().map(|e| e.id.as_str()).collect(),
        ),
    ];
    for (field, ids) in &groups {
        let mut seen = std::collections::HashSet::with_capacity(ids.len());
        for id in ids {
            check_name(file, field, id)?;
            if !seen.insert(*id) {
                return Err(Diagnostic::file_error(
                    file,
                    format!("`{field}` {:?} appears twice", cut(id)),
                )
                .with_help("ids are unique within a run"));
            }
        }
    }
    check_truth_magnitudes(file, truth)?;
    let mut images = std::collections::HashSet::with_capacity(truth.images.len());
    for image in &truth.images {
        check_name(file, "images[].exposure", &image.exposure)?;
        check_name(file, "images[].detector", &image.detector)?;
        if !images.insert((image.exposure.as_str(), image.detector.as_str())) {
            return Err(Diagnostic::file_error(
                file,
                format!(
                    "`images[]` lists exposure {:?} with detector {:?} twice",
                    cut(&image.exposure),
                    cut(&image.detector)
                ),
            ));
        }
    }
    Ok(())
}

/// A frame's place in its sequence, checked: the sequence id a plain name (it names the
/// sequence's folder in an export), the index below the count, and the run id the one rsasim
/// gives that frame (`crate::expand::sequence::frame_run_id`), so that no two run folders claim
/// one frame of a sequence.
fn check_frame(
    file: &std::path::Path,
    run_id: &str,
    frame: &crate::expand::FrameState,
) -> Result<(), Box<crate::diagnostic::Diagnostic>> {
    use crate::diagnostic::{Diagnostic, cut};
    super::received::check_name(file, "frame.sequence", &frame.sequence).map_err(Box::new)?;
    if frame.index >= frame.count {
        return Err(Box::new(Diagnostic::file_error(
            file,
            format!(
                "`frame.index` is {}, but `frame.count` is {}: frames are numbered from 0",
                frame.index, frame.count
            ),
        )));
    }
    let id = crate::expand::sequence::frame_run_id(&frame.sequence, frame.index, frame.count);
    if id != run_id {
        return Err(Box::new(
            Diagnostic::file_error(
                file,
                format!(
                    "`id` is {:?}, but frame {} of sequence {:?} ({} frames) is run {id:?}",
                    cut(run_id),
                    frame.index,
                    cut(&frame.sequence),
                    frame.count
                ),
            )
            .with_help("rsasim names a frame's run <sequence>-f<index>: this truth was edited"),
        ));
    }
    Ok(())
}

/// The numbers of a truth that later stages divide by, shift by or project with, checked for
/// physical sense: positions finite and within ±[`crate::scenario::MAX_ABS`] mm,
/// rotations finite, detectors with 1 to 65,535 pixels a side, a pitch of at least
/// [`crate::scenario::MIN_PIXEL_PITCH_MM`] and 1 to 16 bits, every detector's source
/// one of the run's. A truth rsasim wrote always passes; a forged one is refused here, so no NaN
/// or infinity reaches an exported file.
fn check_truth_magnitudes(
    file: &std::path::Path,
    truth: &Truth,
) -> Result<(), crate::diagnostic::Diagnostic> {
    use crate::diagnostic::{Diagnostic, cut};
    use crate::scenario::MAX_ABS;
    use crate::scenario::MIN_PIXEL_PITCH_MM;
    let bad = |field: String, what: String| {
        Diagnostic::file_error(file, format!("`{field}` {what}"))
            .with_help("a truth rsasim wrote holds finite positions within ±1e6 mm, detectors of 1–65535 pixels a side, a pitch of at least 0.001 mm and 1–16 bits: this one was not written by rsasim as it is")
    };
    let position = |field: String, p: glam::DVec3| {
        if p.to_array()
            .iter()
            .all(|x| x.is_finite() && x.abs() <= MAX_ABS)
        {
            Ok(())
        } else {
            Err(bad(
                field,
                format!(
                    "is {:?} mm, not finite within ±{MAX_ABS:e} mm",
                    p.to_array()
                ),
            ))
        }
    };
    let rotation = |field: String, r: glam::DMat3| {
        if r.to_cols_array()
            .iter()
            .all(|x| x.is_finite() && x.abs() <= 2.0)
        {
            Ok(())
        } else {
            Err(bad(
                field,
                "is not a rotation (entries finite, within ±1)".into(),
            ))
        }
    };
    let run = &truth.run;
    for s in &run.sources {
        position(
            format!("sources[{}].position_mm", cut(&s.id)),
            s.position_mm,
        )?;
    }
    for d in &run.detectors {
        let id = cut(&d.id);
        position(format!("detectors[{id}].position_mm"), d.position_mm)?;
        rotation(format!("detectors[{id}].rotation"), d.rotation)?;
        if d.pixels.iter().any(|&n| n == 0 || n > 65_535) {
            return Err(bad(
                format!("detectors[{id}].pixels"),
                format!("is {:?}, not 1–65535 a side", d.pixels),
            ));
        }
        if !d
            .pixel_pitch_mm
            .iter()
            .all(|&x| x.is_finite() && (MIN_PIXEL_PITCH_MM..=MAX_ABS).contains(&x))
        {
            return Err(bad(
                format!("detectors[{id}].pixel_pitch_mm"),
                format!(
                    "is {:?}, not {MIN_PIXEL_PITCH_MM}–{MAX_ABS:e} mm",
                    d.pixel_pitch_mm
                ),
            ));
        }
        if !(1..=16).contains(&d.bpp) {
            return Err(bad(
                format!("detectors[{id}].bpp"),
                format!("is {}, not 1–16", d.bpp),
            ));
        }
        if !run.sources.iter().any(|s| s.id == d.source) {
            return Err(bad(
                format!("detectors[{id}].source"),
                format!(
                    "names {:?}, which is not a source of the run",
                    cut(&d.source)
                ),
            ));
        }
    }
    for p in &run.phantoms {
        let id = cut(&p.id);
        position(format!("phantoms[{id}].position_mm"), p.position_mm)?;
        rotation(format!("phantoms[{id}].rotation"), p.rotation)?;
        for m in &p.markers {
            position(
                format!("phantoms[{id}].markers[{}].position_mm", cut(&m.id)),
                m.position_mm,
            )?;
        }
    }
    Ok(())
}

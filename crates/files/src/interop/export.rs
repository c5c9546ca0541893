//! `rsasim export OUT --to xmalab|autoscoper --dir DEST`: an rsasim output folder as the files
//! XMALab or Autoscoper open, with the exam's known (true) calibration, or the calibration a
//! software measured.
//!
//! Layout of DEST (one folder per run, since every run has its own geometry):
//!
//! ```text
//! DEST/README.md
//! DEST/<run>/calibration/<detector>_MayaCam.txt   MayaCam 2.0, one per detector (both programs)
//! DEST/<run>/calibration/dlt11.csv                 DLT-11: 11 rows, one column per detector (xmalab)
//! DEST/<run>/calibration/frame_specification.csv   the box beads, box frame (xmalab)
//! DEST/<run>/calibration/references.txt            four reference beads (xmalab)
//! DEST/<run>/images/<exposure>-<detector>/<exposure>-<detector>.0001.tif
//! DEST/<run>/models/<phantom>_markers.csv          bead names and local coordinates (xmalab)
//! DEST/<run>/models/<phantom>.obj | .stl           the model mesh, local frame, mm
//! DEST/<run>/<exposure>.cfg                        Autoscoper trial (autoscoper)
//! ```

use std::path::{Path, PathBuf};

use glam::DVec3;

use super::camera::PinholeCamera;
use super::{autoscoper, xmalab};
use crate::diagnostic::Diagnostic;
use crate::expand::{DetectorState, Run};
use crate::geometry::rotation_from_rows;
use crate::output::atomic::write_staged;
use crate::output::commit::{FolderKind, OutputTarget};
use crate::output::decode::read_image;
use crate::output::exam::{Setup, load_setup};
use crate::output::received::ReceivedFolder;
use crate::output::tiff::{TiffCompression, TiffFacts, encode_tiff};
use crate::output::{Measured, Truth};

/// The program the export is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// XMALab: MayaCam 2.0 per camera, DLT-11, calibration object, marker reference CSV, OBJ.
    Xmalab,
    /// Autoscoper: MayaCam 2.0 per camera, a `.cfg` per exposure with models, STL.
    Autoscoper,
}

impl Target {
    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Target::Xmalab => "xmalab",
            Target::Autoscoper => "autoscoper",
        }
    }
}

/// Options of `rsasim export`.
#[derive(Debug, Clone)]
pub struct Options {
    /// The program.
    pub target: Target,
    /// Run ids to export; empty: every run.
    pub runs: Vec<String>,
    /// Write `I_max − value` (beads and implants dark on a bright background).
    pub invert: bool,
    /// Take each beamline's source and detector pose from this results file of every run folder
    /// (e.g. `measured-rsasim-dlt-markers.json`) instead of the truth.
    pub calibration_from: Option<String>,
}

/// What an export wrote.
#[derive(Debug)]
pub struct Summary {
    /// Runs exported.
    pub runs: usize,
    /// Files written.
    pub files: usize,
    /// The export folder as given.
    pub dir: PathBuf,
    /// What the user should know.
    pub notes: Vec<String>,
}

/// Why an export failed: bad input (exit 2, nothing written) or a write error (exit 1).
#[derive(Debug)]
pub enum Error {
    /// Refused before writing.
    Input(Vec<Diagnostic>),
    /// Writing failed; nothing was committed.
    Write(String),
}

impl From<Vec<Diagnostic>> for Error {
    fn from(d: Vec<Diagnostic>) -> Self {
        Error::Input(d)
    }
}

impl From<Diagnostic> for Error {
    fn from(d: Diagnostic) -> Self {
        Error::Input(vec![d])
    }
}

/// One run, read and checked, ready to be written.
struct RunExport {
    truth: Truth,
    dir: PathBuf,
    cameras: Vec<(String, PinholeCamera)>,
}

/// Exports `out` into the new folder `dest` (see the module docs). With `truth_dir` (the blind
/// layout) `out` is the images folder and `truth_dir` its truth folder, bound to it by the SHA-256
/// of its manifest.
///
/// `out` (and `truth_dir`) are received folders: the truth (every `truth.json` and
/// `scenario.toml`) is verified against the manifest before it is parsed, every id that becomes
/// part of an exported path is a plain name, and each run folder is named after its run id, so
/// nothing is written outside `dest` and no run replaces another.
pub fn export(
    out: &Path,
    truth_dir: Option<&Path>,
    dest: &Path,
    options: &Options,
) -> Result<Summary, Error> {
    crate::output::check_output_folder(out)?;
    if let Some(t) = truth_dir {
        crate::output::check_output_folder(t)?;
    }
    let truth_root = truth_dir.unwrap_or(out);
    let manifest = crate::output::truth_check::verify_truth(truth_root, truth_dir.map(|_| out))?;
    let truth_folder = ReceivedFolder::listed(truth_root, &manifest);
    let images_folder = match truth_dir {
        None => truth_folder.clone(),
        Some(_) => {
            let (images_manifest, _) = crate::output::verify::read_manifest(out)
                .map_err(|f| vec![Diagnostic::file_error(&out.join(&f.path), f.problem)])?;
            ReceivedFolder::listed(out, &images_manifest)
        }
    };
    let setup = load_setup(truth_root)?;
    for name in &options.runs {
        if let Some(why) = crate::output::received::name_problem(name) {
            return Err(Error::Input(vec![
                Diagnostic::file_error(
                    &out.join("runs"),
                    format!(
                        "--runs {:?} is not a run id: {why}",
                        crate::diagnostic::cut(name)
                    ),
                )
                .with_help("give run ids as the folders of OUT/runs are named (e.g. n0-r00)"),
            ]));
        }
    }
    let mut runs = Vec::new();
    for id in truth_folder.sub_folders("runs")? {
        if !options.runs.is_empty() && !options.runs.contains(&id) {
            continue;
        }
        if !truth_folder.exists(&format!("runs/{id}/truth.json")) {
            continue;
        }
        let truth = crate::output::truth::read_run_truth(&truth_folder, &id)?;
        let dir = images_folder.sub_folder(&format!("runs/{id}"))?;
        let calibration = match &options.calibration_from {
            None => None,
            Some(name) => {
                crate::output::received::check_name(
                    Path::new("--calibration-from"),
                    "--calibration-from",
                    name,
                )?;
                let rel = format!("runs/{id}/{name}");
                let file = images_folder.path(&rel);
                let bytes = images_folder
                    .read(&rel, crate::output::received::MAX_JSON_BYTES)
                    .map_err(|d| {
                        vec![d.with_help("give a results file every run folder holds, e.g. measured-rsasim-dlt-markers.json")]
                    })?;
                Some(parse_json::<Measured>(
                    &file,
                    &bytes,
                    "schemas/measured.schema.json",
                )?)
            }
        };
        let cameras = cameras(&truth.run, calibration.as_ref(), &dir, options)?;
        runs.push(RunExport {
            truth,
            dir,
            cameras,
        });
    }
    let missing: Vec<&String> = options
        .runs
        .iter()
        .filter(|r| !runs.iter().any(|x| &x.truth.run.id == *r))
        .collect();
    if !missing.is_empty() || runs.is_empty() {
        let what = if missing.is_empty() {
            "no run folder with a truth.json".to_string()
        } else {
            format!(
                "no run {} in this output",
                missing
                    .iter()
                    .map(|m| format!("`{}`", crate::diagnostic::cut(m)))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        };
        return Err(Error::Input(vec![
            Diagnostic::file_error(&truth_root.join("runs"), what).with_help(
                "give run ids as the folders of OUT/runs are named (e.g. n0-r00); an export needs the truth: give the ordinary output folder, or a blind images folder with --truth TRUTH_DIR",
            ),
        ]));
    }
    if let Some(t) = truth_dir {
        refuse_inside(t, dest)?;
    }
    check_images(&runs)?;
    refuse_inside(out, dest)?;
    let target =
        OutputTarget::claim(dest, FolderKind::Export).map_err(|d| Error::Input(vec![*d]))?;
    let mut notes = target.notes.clone();
    let staged = target.stage().map_err(|e| Error::Write(e.to_string()))?;
    let root = staged.path().to_path_buf();
    let mut files = 0usize;
    let mut write = |rel: &str, bytes: &[u8]| -> Result<(), Error> {
        let path = root.join(rel);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(|e| Error::Write(format!("{rel}: {e}")))?;
        }
        write_staged(&path, bytes).map_err(|e| Error::Write(format!("{rel}: {e}")))?;
        files += 1;
        Ok(())
    };
    write("README.md", readme(out, options, &runs).as_bytes())?;
    for run in &runs {
        write_run(run, &setup, options, &mut write)?;
    }
    let committed = staged.commit().map_err(|e| Error::Write(e.to_string()))?;
    notes.extend(committed.notes);
    Ok(Summary {
        runs: runs.len(),
        files,
        dir: committed.path,
        notes,
    })
}

/// Decodes every image of every run once before anything is written, so that an unreadable
/// image, or one whose size is not its detector's, is an input error (exit 2) with nothing
/// written, not even the export folder's lock. The pixels are decoded again when written: the
/// export is not worth holding every image in memory.
fn check_images(runs: &[RunExport]) -> Result<(), Error> {
    for run in runs {
        for image in &run.truth.images {
            let stem = format!("{}-{}", image.exposure, image.detector);
            let (det, (w, h, _)) = run_image(run, image, &stem)?;
            if [w, h] != det.pixels {
                return Err(Error::Input(vec![Diagnostic::file_error(
                    &run.dir,
                    format!(
                        "image `{stem}` is {w} × {h} pixels, but truth.json gives detector `{}` {} × {}",
                        image.detector, det.pixels[0], det.pixels[1]
                    ),
                )]));
            }
        }
    }
    Ok(())
}

/// An image of a run, decoded, with the detector that took it.
fn run_image<'a>(
    run: &'a RunExport,
    image: &crate::output::ImageTruth,
    stem: &str,
) -> Result<(&'a DetectorState, (u32, u32, Vec<u16>)), Error> {
    let det = run
        .truth
        .run
        .detectors
        .iter()
        .find(|d| d.id == image.detector)
        .ok_or_else(|| {
            Error::Input(vec![Diagnostic::file_error(
                &run.dir.join("truth.json"),
                format!("image `{stem}` names an unknown detector"),
            )])
        })?;
    let decoded = read_image(&run.dir, stem).map_err(|e| {
        Error::Input(vec![Diagnostic::file_error(&run.dir, format!("cannot read the image: {e}"))
            .with_help("export reads the TIFF (or EXR) images of every run; give a folder written with them")])
    })?;
    Ok((det, decoded))
}

/// Refuses an export folder inside the output folder (it would add files the manifest does not
/// list).
fn refuse_inside(out: &Path, dest: &Path) -> Result<(), Error> {
    let abs = |p: &Path| {
        std::path::absolute(p)
            .unwrap_or_else(|_| p.to_path_buf())
            .components()
            .collect::<PathBuf>()
    };
    let out_real = out.canonicalize().unwrap_or_else(|_| abs(out));
    let mut existing = abs(dest);
    let mut rest = Vec::new();
    while !existing.exists() {
        match (
            existing.file_name().map(|n| n.to_os_string()),
            existing.parent(),
        ) {
            (Some(n), Some(p)) => {
                rest.push(n);
                existing = p.to_path_buf();
            }
            _ => break,
        }
    }
    let mut dest_real = existing.canonicalize().unwrap_or(existing);
    dest_real.extend(rest.iter().rev());
    if dest_real.starts_with(&out_real) {
        return Err(Error::Input(vec![
            Diagnostic::file_error(
                dest,
                format!(
                    "the export folder lies inside the output folder {}",
                    out.display()
                ),
            )
            .with_help("write the export beside it, e.g. --dir xmalab/<name>; files in the output folder must be those its manifest lists"),
        ]));
    }
    Ok(())
}

fn parse_json<T: serde::de::DeserializeOwned>(
    file: &Path,
    bytes: &[u8],
    schema: &str,
) -> Result<T, Error> {
    let text = String::from_utf8_lossy(bytes);
    serde_json::from_str(text.strip_prefix('\u{feff}').unwrap_or(&text)).map_err(|e| {
        let mut d = Diagnostic::file_error(
            file,
            format!("invalid JSON: {}", crate::diagnostic::cut(&e.to_string())),
        )
        .with_help(format!("the file must follow {schema}"));
        if e.line() > 0 {
            d.line_col = Some((e.line(), e.column()));
        }
        Error::Input(vec![d])
    })
}

/// The camera of every detector, from the truth or from a results file.
fn cameras(
    run: &Run,
    measured: Option<&Measured>,
    dir: &Path,
    options: &Options,
) -> Result<Vec<(String, PinholeCamera)>, Error> {
    let mut out = Vec::new();
    for det in &run.detectors {
        let (source, det) = match measured {
            None => {
                let source = run
                    .sources
                    .iter()
                    .find(|s| s.id == det.source)
                    .ok_or_else(|| {
                        Error::Input(vec![Diagnostic::file_error(
                            &dir.join("truth.json"),
                            format!("detector `{}` names no source of the run", det.id),
                        )])
                    })?;
                (source.position_mm, det.clone())
            }
            Some(m) => {
                let file = dir.join(options.calibration_from.as_deref().unwrap_or_default());
                let lacks = |what: &str| {
                    Error::Input(vec![Diagnostic::file_error(
                        &file,
                        format!("it has no measured {what}, which the exported calibration needs"),
                    )
                    .with_help("give a results file with the calibration (sources and detectors with rotation), e.g. measured-rsasim-dlt-markers.json, or export the true calibration")])
                };
                let s = m
                    .sources
                    .iter()
                    .find(|s| s.id == det.source)
                    .ok_or_else(|| lacks(&format!("source `{}`", det.source)))?;
                let d = m
                    .detectors
                    .iter()
                    .find(|d| d.id == det.id)
                    .ok_or_else(|| lacks(&format!("detector `{}`", det.id)))?;
                let rotation = d
                    .rotation
                    .ok_or_else(|| lacks(&format!("rotation of detector `{}`", det.id)))?;
                // The results are the sender's: positions and rotations checked for physical sense
                // here, so that the error names this file, not the cameras made from it.
                let implausible = |field: String| {
                    Error::Input(vec![Diagnostic::file_error(
                        &file,
                        format!("`{field}` is not finite within ±{:e} mm (or a rotation's entries within ±1)", crate::scenario::MAX_ABS),
                    )
                    .with_help("give a results file with a plausible calibration (mm, box frame), or export the true calibration")])
                };
                let plausible = |v: &[f64]| {
                    v.iter()
                        .all(|x| x.is_finite() && x.abs() <= crate::scenario::MAX_ABS)
                };
                if !plausible(&s.position_mm) {
                    return Err(implausible(format!(
                        "sources[{}].position_mm",
                        crate::diagnostic::cut(&s.id)
                    )));
                }
                if !plausible(&d.position_mm) {
                    return Err(implausible(format!(
                        "detectors[{}].position_mm",
                        crate::diagnostic::cut(&d.id)
                    )));
                }
                if !rotation
                    .iter()
                    .flatten()
                    .all(|x| x.is_finite() && x.abs() <= 1.0 + 1e-6)
                {
                    return Err(implausible(format!(
                        "detectors[{}].rotation",
                        crate::diagnostic::cut(&d.id)
                    )));
                }
                let posed = DetectorState {
                    position_mm: DVec3::from_array(d.position_mm),
                    rotation: rotation_from_rows(rotation),
                    ..det.clone()
                };
                (DVec3::from_array(s.position_mm), posed)
            }
        };
        let cam = PinholeCamera::of_beamline(source, &det)
            .map_err(|e| Error::Input(vec![Diagnostic::file_error(&dir.join("truth.json"), e)]))?;
        out.push((det.id.clone(), cam));
    }
    Ok(out)
}

/// An image for the other program: rows flipped (see [`super::camera`]), optionally inverted,
/// scaled to the full 16-bit range: `round(value · 65535 / I_max)`.
pub fn export_pixels(pixels: &[u16], width: u32, i_max: u16, invert: bool) -> Vec<u16> {
    let w = width as usize;
    let max = u64::from(i_max.max(1));
    let mut out = Vec::with_capacity(pixels.len());
    for row in pixels.chunks(w).rev() {
        out.extend(row.iter().map(|&v| {
            let v = u64::from(v).min(max);
            let v = if invert { max - v } else { v };
            ((v * 65535 + max / 2) / max) as u16
        }));
    }
    out
}

fn write_run(
    run: &RunExport,
    setup: &Setup,
    options: &Options,
    write: &mut dyn FnMut(&str, &[u8]) -> Result<(), Error>,
) -> Result<(), Error> {
    let id = &run.truth.run.id;
    let xmalab = options.target == Target::Xmalab;
    for (det, cam) in &run.cameras {
        write(
            &format!("{id}/calibration/{det}_MayaCam.txt"),
            cam.mayacam_text().as_bytes(),
        )?;
    }
    if xmalab {
        let dlts: Vec<[f64; 11]> = run
            .cameras
            .iter()
            .map(|(det, c)| {
                c.dlt().map_err(|e| {
                    Error::Input(vec![Diagnostic::file_error(
                        &run.dir.join("truth.json"),
                        format!("detector `{det}`: {e}"),
                    )])
                })
            })
            .collect::<Result<_, _>>()?;
        let text = super::camera_files::dlt11_csv(&dlts);
        write(&format!("{id}/calibration/dlt11.csv"), text.as_bytes())?;
        if let Some(cal) = run
            .truth
            .run
            .phantoms
            .iter()
            .find(|p| p.kind == "calibration_box")
        {
            let beads: Vec<DVec3> = cal.markers.iter().map(|m| m.position_mm).collect();
            let ids: Vec<String> = cal.markers.iter().map(|m| m.id.clone()).collect();
            write(
                &format!("{id}/calibration/frame_specification.csv"),
                xmalab::frame_specification(&beads).as_bytes(),
            )?;
            write(
                &format!("{id}/calibration/references.txt"),
                xmalab::references(&ids, &xmalab::reference_beads(&beads)).as_bytes(),
            )?;
        }
    }
    // Images.
    for image in &run.truth.images {
        let stem = format!("{}-{}", image.exposure, image.detector);
        let (det, (w, h, pixels)) = run_image(run, image, &stem)?;
        let converted = export_pixels(&pixels, w, det.i_max(), options.invert);
        let description = format!(
            "rsasim export: run {id}, image {stem}, rows flipped (bottom row first), {}scaled to 0..65535 from 0..{}",
            if options.invert { "inverted and " } else { "" },
            det.i_max()
        );
        let bytes = encode_tiff(
            w,
            h,
            &converted,
            TiffCompression::Lzw,
            &TiffFacts {
                description: &description,
                software: &crate::output::program(),
                pixel_pitch_mm: det.frame().pixel_pitch_mm,
                i_max: u16::MAX,
            },
        )
        .map_err(Error::Write)?;
        write(&format!("{id}/images/{stem}/{stem}.0001.tif"), &bytes)?;
    }
    // Models: every phantom with a mesh or beads, other than the calibration box.
    for phantom in run
        .truth
        .run
        .phantoms
        .iter()
        .filter(|p| p.kind != "calibration_box")
    {
        if xmalab {
            let beads: Vec<(String, DVec3)> = phantom
                .markers
                .iter()
                .map(|m| (m.id.clone(), phantom.pose().to_local(m.position_mm)))
                .collect();
            if !beads.is_empty() {
                write(
                    &format!("{id}/models/{}_markers.csv", phantom.id),
                    xmalab::marker_reference_csv(&beads).as_bytes(),
                )?;
            }
        }
        if let Some(mesh) = setup.meshes.get(&phantom.id) {
            if xmalab {
                write(
                    &format!("{id}/models/{}.obj", phantom.id),
                    super::mesh_text::obj(mesh).as_bytes(),
                )?;
            } else {
                let mut bytes = Vec::new();
                crate::phantom::mesh_io::write_stl(mesh, &mut bytes).map_err(Error::Write)?;
                write(&format!("{id}/models/{}.stl", phantom.id), &bytes)?;
            }
        }
    }
    if !xmalab {
        for exposure in &run.truth.run.exposures {
            let models: Vec<&str> = exposure
                .phantoms
                .iter()
                .filter(|p| setup.meshes.contains_key(*p))
                .map(String::as_str)
                .collect();
            let text = autoscoper::trial_cfg(
                &run.cameras
                    .iter()
                    .map(|(d, _)| d.as_str())
                    .collect::<Vec<_>>(),
                &exposure.id,
                &models,
            );
            write(&format!("{id}/{}.cfg", exposure.id), text.as_bytes())?;
        }
    }
    Ok(())
}

fn readme(out: &Path, options: &Options, runs: &[RunExport]) -> String {
    let calibration = match &options.calibration_from {
        None => "the TRUE calibration (the exact source and detector poses of truth.json): the \
                 exam's known calibration"
            .to_string(),
        Some(name) => format!("the calibration measured in each run's `{name}`"),
    };
    format!(
        "# rsasim export for {program}\n\n\
         Written by {version} from the output folder `{out}` ({n} run(s)).\n\n\
         - Cameras (MayaCam 2.0{dlt}) hold {calibration}.\n\
         - Images are the run's TIFFs with their rows flipped (bottom row first), {inv}scaled to \
         the full 16-bit range. The flip makes each beamline a standard pinhole camera; pixel \
         coordinates in these images are not rsasim's.\n\
         - Units: mm; world frame: the calibration box frame of truth.json.\n\
         - One folder per run, since every run has its own geometry. See rsasim's README, \
         \"XMALab and Autoscoper\", for the steps in {program} and how to score its results with \
         `rsasim evaluate`.\n",
        program = match options.target {
            Target::Xmalab => "XMALab",
            Target::Autoscoper => "Autoscoper",
        },
        version = crate::output::program(),
        out = out.display(),
        n = runs.len(),
        dlt = if options.target == Target::Xmalab {
            " and DLT-11"
        } else {
            ""
        },
        inv = if options.invert {
            "inverted (I_max − value) and "
        } else {
            ""
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixels_are_flipped_and_scaled_by_hand() {
        // 2 × 2 image of a 12-bit detector: rows [0, 4095], [2048, 1].
        let p = export_pixels(&[0, 4095, 2048, 1], 2, 4095, false);
        // Rows swapped; 2048·65535/4095 = 32775.99… → 32776; 1·65535/4095 = 16.0037 → 16.
        assert_eq!(p, vec![32776, 16, 0, 65535]);
        let inv = export_pixels(&[0, 4095, 2048, 1], 2, 4095, true);
        assert_eq!(inv, vec![32759, 65519, 65535, 0]);
    }
}

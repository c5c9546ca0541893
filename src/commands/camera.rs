//! `rsasim camera`: a beamline's pinhole camera as MayaCam 2.0, DLT-11 and OpenCV JSON
//! ([`rsasim::interop::camera_files`]), from a source and four detector corners, a scenario's
//! nominal set-up or a run's truth ([`rsasim::interop::camera_input`]); printed, or a new folder.

use std::path::Path;

use rsasim::diagnostic::Diagnostic;
use rsasim::interop::camera_files::{self, NamedCamera};
use rsasim::interop::camera_input::{corner_camera, output_run_cameras, scenario_cameras};
use rsasim::interop::detector_corners::CornerBeamline;

use super::Outcome;
use super::shared::{print_stdout, report_errors, report_folder_error};
use crate::cli::CameraArgs;

/// Prints or writes the cameras (bad input: exit 2, nothing written; a failure while writing:
/// exit 1).
pub fn execute(args: CameraArgs) -> Outcome {
    let cameras = cameras(&args).map_err(|e| report_errors(&e))?;
    let Some(dir) = &args.dir else {
        return print_stdout(&camera_files::printed(&cameras));
    };
    let written =
        camera_files::write_folder(dir, &cameras).map_err(|e| report_folder_error(e, dir))?;
    written.notes.iter().for_each(|n| eprintln!("rsasim: {n}"));
    eprintln!(
        "rsasim camera: {} camera(s), {} files -> {}",
        cameras.len(),
        written.files.len(),
        written.dir.display()
    );
    Ok(())
}

/// The cameras the arguments name.
fn cameras(args: &CameraArgs) -> Result<Vec<NamedCamera>, Vec<Diagnostic>> {
    let refuse = |field: &str, message: &str, help: &str| {
        vec![Diagnostic::file_error(Path::new(field), message).with_help(help)]
    };
    match (&args.input, &args.source_mm) {
        (Some(out), _) if out.is_dir() => match &args.run {
            Some(run) => output_run_cameras(out, run),
            None => Err(refuse(
                &out.display().to_string(),
                "an output folder holds one geometry per run",
                "name the run whose true cameras you want, e.g. --run n0-r00",
            )),
        },
        (Some(scenario), _) => match &args.run {
            Some(_) => Err(refuse(
                "--run",
                "a scenario has no runs yet; its cameras are those of its nominal set-up",
                "drop --run, or give the output folder the scenario was run into",
            )),
            None => scenario_cameras(scenario, &args.allow_dir),
        },
        (None, Some(source)) => {
            let beamline = CornerBeamline::parse(
                args.detector.as_deref().unwrap_or("det1"),
                source,
                args.corners_mm.as_deref().unwrap_or_default(),
                args.pixels.as_deref().unwrap_or_default(),
            )
            .map_err(|d| vec![*d])?;
            corner_camera(&beamline)
                .map(|c| vec![c])
                .map_err(|d| vec![*d])
        }
        (None, None) => Err(refuse(
            "rsasim camera",
            "no beamline given",
            "give a scenario, an output folder with --run, or --source-mm with --corners-mm and --pixels",
        )),
    }
}

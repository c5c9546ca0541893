//! Where `rsasim camera` takes its beamlines from: a source and four detector corners
//! ([`super::detector_corners`]), a scenario's nominal set-up (every pose without its random
//! draw, [`crate::expand::nominal_run`]), or the truth of one run of an output folder, verified
//! against its manifest before it is parsed.

use std::path::{Path, PathBuf};

use super::camera::{PinholeCamera, run_cameras};
use super::camera_files::NamedCamera;
use super::detector_corners::CornerBeamline;
use crate::diagnostic::{Diagnostic, cut};
use crate::expand::Run;
use crate::output::received::ReceivedFolder;

/// The camera of a beamline given by its corners.
pub fn corner_camera(beamline: &CornerBeamline) -> Result<NamedCamera, Box<Diagnostic>> {
    let detector = beamline.detector()?;
    let field = |e: String| {
        Box::new(
            Diagnostic::file_error(Path::new("--source-mm"), e)
                .with_help("give a source in front of the image, at a finite distance"),
        )
    };
    let camera = PinholeCamera::of_beamline(beamline.source_mm, &detector).map_err(field)?;
    NamedCamera::new(beamline.source_mm, &detector, camera).map_err(field)
}

/// The camera of every detector of a scenario's nominal set-up; `allowed_dirs` are the folders
/// besides the scenario's own that its mesh files may be read from.
pub fn scenario_cameras(
    path: &Path,
    allowed_dirs: &[PathBuf],
) -> Result<Vec<NamedCamera>, Vec<Diagnostic>> {
    let mut loaded = crate::scenario::load(path)?;
    loaded.allowed_dirs = allowed_dirs.to_vec();
    let models = crate::phantom::build(&loaded)?;
    let nominal = crate::expand::nominal_run(&loaded.scenario, &models);
    cameras_of(&nominal, path)
}

/// The camera of every detector of run `run` of the output folder `out`, from its truth.
pub fn output_run_cameras(out: &Path, run: &str) -> Result<Vec<NamedCamera>, Vec<Diagnostic>> {
    crate::output::check_output_folder(out)?;
    let runs_dir = out.join("runs");
    if let Some(why) = crate::output::received::name_problem(run) {
        return Err(vec![
            Diagnostic::file_error(
                &runs_dir,
                format!("--run `{}` is not a run id: {why}", cut(run)),
            )
            .with_help("give a run id as the folders of OUT/runs are named, e.g. --run n0-r00"),
        ]);
    }
    let manifest = crate::output::truth_check::verify_truth(out, None)?;
    let folder = ReceivedFolder::listed(out, &manifest);
    let truth_file = format!("runs/{run}/truth.json");
    if !folder.exists(&truth_file) {
        let runs = folder.sub_folders("runs").map_err(|d| vec![d])?;
        return Err(vec![
            Diagnostic::file_error(
                &runs_dir,
                format!("no run `{}` with a truth.json", cut(run)),
            )
            .with_help(format!(
                "give one of the runs of this output: {}",
                runs.iter().take(10).cloned().collect::<Vec<_>>().join(", ")
            )),
        ]);
    }
    let truth = crate::output::truth::read_run_truth(&folder, run).map_err(|d| vec![d])?;
    cameras_of(&truth.run, &folder.path(&truth_file))
}

/// The camera of every detector of `run`, read from `file`.
fn cameras_of(run: &Run, file: &Path) -> Result<Vec<NamedCamera>, Vec<Diagnostic>> {
    let to_diagnostic = |e: String| vec![Diagnostic::file_error(file, e)];
    let cameras = run_cameras(run).map_err(to_diagnostic)?;
    cameras
        .into_iter()
        .zip(&run.detectors)
        .map(|((source, camera), detector)| {
            NamedCamera::new(source, detector, camera).map_err(to_diagnostic)
        })
        .collect()
}

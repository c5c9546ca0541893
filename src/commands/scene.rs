//! `rsasim scene`: one HTML page showing the scenario in 3D before it is run.

use std::path::Path;

use rsasim::scene_view;

use super::Outcome;
use super::shared::{check, report_errors};
use crate::cli::SceneArgs;

/// Checks the scenario (errors: exit 2, nothing written), then writes its page.
pub fn execute(args: SceneArgs) -> Outcome {
    let checked = check(&args.scenario, &args.allow.into())?;
    let out = args.out.unwrap_or_else(|| {
        Path::new("out").join(format!("{}-scene.html", checked.loaded.scenario.name))
    });
    scene_view::check_page_target(&out).map_err(|d| report_errors(&[*d]))?;
    let scene = scene_view::scene_of(checked, !args.no_images).map_err(|e| {
        eprintln!("error: making the thumbnails of the first run failed: {e}");
        1
    })?;
    let page = scene_view::page(&scene);
    let written = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .map_or(Ok(()), std::fs::create_dir_all)
        .and_then(|()| rsasim::output::atomic::write_atomic(&out, page.as_bytes()));
    written.map_err(|e| {
        eprintln!("error: writing {} failed: {e}", out.display());
        1
    })?;
    eprintln!(
        "rsasim scene: {} warning(s), {} KiB -> {}",
        scene.warnings.len(),
        page.len().div_ceil(1024),
        out.display()
    );
    Ok(())
}

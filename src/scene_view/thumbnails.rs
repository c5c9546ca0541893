//! Thumbnails of the first run's images: that run is simulated exactly as `rsasim SCENARIO`
//! would (same stages, same seeds) into a private temporary folder, as uncompressed TIFF only,
//! and each image is turned into a small PNG by the preview writer
//! ([`crate::output::preview::preview_png`]). The temporary folder is removed afterwards.

use base64::Engine;

use super::scene::ImageView;
use crate::output::preview::preview_png;
use crate::scenario::{ImageFormat, TiffCompression};
use crate::simulate::{self, Checked, Plan};

/// Longer side of a thumbnail, pixels.
pub const THUMBNAIL_MAX_SIDE_PX: u32 = 160;

/// The first run's images of every detector, as thumbnails: `[detector][exposure]`, in scenario
/// order. Takes the checked scenario (its meshes are already in memory: nothing more is read).
pub fn first_run_thumbnails(checked: Checked) -> std::io::Result<Vec<Vec<ImageView>>> {
    let mut loaded = checked.loaded;
    loaded.scenario.output.formats = vec![ImageFormat::Tiff];
    loaded.scenario.output.tiff_compression = TiffCompression::None;
    let Some(first) = crate::expand::runs(&loaded.scenario, &checked.models).next() else {
        return Ok(Vec::new());
    };
    let plan = Plan {
        loaded,
        models: checked.models,
        bvhs: checked.bvhs,
        setup: checked.setup,
        previews: false,
        runs: vec![first],
        shard: None,
        warnings: Vec::new(),
        cost: checked.cost,
        // Thumbnails come from the TIFFs alone.
        dicom_views: Vec::new(),
    };
    let work = tempfile::Builder::new().prefix("rsasim-scene-").tempdir()?;
    let out = work.path().join("first-run");
    let target = simulate::claim_output(&plan, &out, false).map_err(|d| {
        std::io::Error::other(
            d.into_iter()
                .map(|d| d.message)
                .collect::<Vec<_>>()
                .join("; "),
        )
    })?;
    let summary = simulate::simulate(&plan, target, None, &|| {})?;
    let run = &plan.runs[0];
    let dir = summary.out_dir.join("runs").join(&run.id);
    run.detectors
        .iter()
        .map(|d| {
            run.exposures
                .iter()
                .map(|e| {
                    let (w, h, pixels) =
                        crate::output::decode::read_image(&dir, &format!("{}-{}", e.id, d.id))
                            .map_err(std::io::Error::other)?;
                    let png = preview_png(&pixels, w, h, THUMBNAIL_MAX_SIDE_PX);
                    Ok(ImageView {
                        exposure: e.id.clone(),
                        src: format!(
                            "data:image/png;base64,{}",
                            base64::engine::general_purpose::STANDARD.encode(png)
                        ),
                    })
                })
                .collect()
        })
        .collect()
}

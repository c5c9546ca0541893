//! The output stage: image files, `truth.json`, `manifest.json`, the phantom files a real RSA
//! user has, and the schemas of the JSON files (docs/src/reference/conventions.md, "Files").

pub mod atomic;
pub mod commit;
pub mod decode;
pub mod dicom;
pub mod exam;
pub mod exr;
pub mod exr_deflate;
pub mod folder_readme;
pub mod html_text;
pub mod manifest;
pub mod measured;
pub mod merge;
pub mod migration_measured;
pub mod preview;
pub mod received;
pub mod study;
pub mod tiff;
pub mod truth;
pub mod truth_check;
pub mod verify;

pub use manifest::{
    Build, ImagesBinding, Layout, MANIFEST_FORMAT, Manifest, ManifestFile, OUTPUT_FORMAT,
    ShardRecord,
};
pub use measured::{MEASURED_FORMAT, Measured};
pub use truth::{FileRef, ImageTruth, ProjectedMarker, TRUTH_FORMAT, Truth};

/// Checks that `out` is a folder written by `rsasim SCENARIO.toml` (it holds `scenario.toml`,
/// `manifest.json` and `runs/`), so commands that read one say so instead of failing on a file.
pub fn check_output_folder(
    out: &std::path::Path,
) -> Result<(), Vec<crate::diagnostic::Diagnostic>> {
    let missing: Vec<&str> = ["scenario.toml", "manifest.json", "runs"]
        .into_iter()
        .filter(|name| !out.join(name).exists())
        .collect();
    if missing.is_empty() {
        return Ok(());
    }
    Err(vec![crate::diagnostic::Diagnostic::file_error(
        out,
        format!("not an rsasim output folder: {} missing", missing.join(", ")),
    )
    .with_help("give the folder that `rsasim SCENARIO.toml --out DIR` wrote (by default out/<scenario name>)")])
}

/// `rsasim <version>`, as written into every file. Image files and `truth.json` carry only this
/// (not the commit), so that their bytes change only when the version does; the manifest carries
/// the exact build (`rsasim::build_info::build`, recorded where the binary is built).
pub fn program() -> String {
    format!("rsasim {}", env!("CARGO_PKG_VERSION"))
}

/// The JSON Schemas rsasim publishes, by name: `scenario`, `truth`, `measured`, `manifest`,
/// `study`, `migration_measured`.
pub fn schemas() -> Vec<(&'static str, serde_json::Value)> {
    vec![
        ("scenario", crate::scenario::json_schema()),
        ("truth", schemars::schema_for!(Truth).as_value().clone()),
        (
            "measured",
            schemars::schema_for!(Measured).as_value().clone(),
        ),
        (
            "manifest",
            schemars::schema_for!(Manifest).as_value().clone(),
        ),
        (
            "study",
            schemars::schema_for!(study::Study).as_value().clone(),
        ),
        (
            "migration_measured",
            schemars::schema_for!(migration_measured::MigrationMeasured)
                .as_value()
                .clone(),
        ),
    ]
}

/// Synthetic images for the encoders' tests.
#[cfg(test)]
pub(crate) mod test_image {
    use crate::noise::{NoiseKey, add_noise};

    /// A binary-mode image: a disc at `i_max` (diameter 0.4·w) on Poisson background noise.
    pub fn noisy_disc(w: usize, h: usize, level: f64, i_max: u16, key: &NoiseKey) -> Vec<u16> {
        let mut v = vec![0u16; w * h];
        for j in 0..h {
            for i in 0..w {
                let (x, y) = (i as f64 - w as f64 / 2.0, j as f64 - h as f64 / 2.0);
                if x * x + y * y < (w as f64 / 5.0).powi(2) {
                    v[j * w + i] = i_max;
                }
            }
        }
        add_noise(&mut v, w, level, i_max, key);
        v
    }
}

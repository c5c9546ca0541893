//! The output stage: image files, `truth.json`, `manifest.json`, the phantom files a real RSA
//! user has, and the schemas of the JSON files (DESIGN.md, "Output layout").

pub mod atomic;
pub mod exr;
pub mod manifest;
pub mod measured;
pub mod tiff;
pub mod truth;

pub use manifest::{MANIFEST_FORMAT, Manifest, ManifestFile};
pub use measured::{MEASURED_FORMAT, Measured};
pub use truth::{FileRef, ImageTruth, ProjectedMarker, TRUTH_FORMAT, Truth};

/// `rsasim <version>`, as written into every file.
pub fn program() -> String {
    format!("rsasim {}", env!("CARGO_PKG_VERSION"))
}

/// The JSON Schemas rsasim publishes, by name: `scenario`, `truth`, `measured`, `manifest`.
pub fn schemas() -> Vec<(&'static str, serde_json::Value)> {
    vec![
        ("scenario", crate::scenario::json_schema()),
        ("truth", schemars::schema_for!(Truth).as_value().clone()),
        ("measured", schemars::schema_for!(Measured).as_value().clone()),
        ("manifest", schemars::schema_for!(Manifest).as_value().clone()),
    ]
}

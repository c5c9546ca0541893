//! `manifest.json`: what was run and every file written, with its SHA-256.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// The format tag of manifests.
pub const MANIFEST_FORMAT: &str = "rsasim-manifest/1";

/// The index of an output folder. It holds no clock time or host name, so the same scenario,
/// seed and version give a byte-identical manifest anywhere.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Always `rsasim-manifest/1`.
    pub format: String,
    /// `rsasim <version>`.
    pub program: String,
    /// The scenario's name.
    pub scenario: String,
    /// SHA-256 of the scenario file as given, lowercase hex.
    pub scenario_sha256: String,
    /// The scenario's master seed.
    pub seed: u64,
    /// Number of runs.
    pub runs: usize,
    /// Every file of the folder but this one, sorted by path.
    pub files: Vec<ManifestFile>,
}

/// A file of the output folder.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ManifestFile {
    /// Path relative to the output folder, `/` separators.
    pub path: String,
    /// SHA-256 of the bytes, lowercase hex.
    pub sha256: String,
    /// Size in bytes.
    pub bytes: u64,
}

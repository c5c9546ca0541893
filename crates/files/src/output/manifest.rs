//! `manifest.json`: what was run, by which build, and every file written, with its SHA-256.
//!
//! # The manifest's own hash
//!
//! `manifest_sha256` is the SHA-256 of the manifest file's exact bytes with that field's value
//! replaced by the empty string. A reviewer recomputes it with standard tools:
//!
//! ```text
//! sed 's/"manifest_sha256": "[0-9a-f]*"/"manifest_sha256": ""/' manifest.json | sha256sum
//! ```
//!
//! It detects accidental corruption of the manifest (a damaged copy, an edited line). It does not
//! protect against deliberate forgery: whoever edits the manifest can recompute the hash. For that,
//! record the SHA-256 of `manifest.json` itself somewhere the data set's recipient trusts (a
//! dossier, a signed message); the truth folder of a blind layout does exactly that for its images
//! folder.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::scenario::hex;

/// The format tag of manifests.
pub const MANIFEST_FORMAT: &str = "rsasim-manifest/1";

/// The version of the output folder layout (which files exist where). Raised whenever a folder
/// of one version could be misread by a program written for another.
pub const OUTPUT_FORMAT: u32 = 2;

/// The index of an output folder. It holds no clock time or host name, so the same scenario,
/// seed and build give a byte-identical manifest anywhere.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Always `rsasim-manifest/1`.
    pub format: String,
    /// SHA-256 of this file with this field's value empty (see the module documentation); empty
    /// in manifests of rsasim 0.1, which had no such field.
    #[serde(default)]
    pub manifest_sha256: String,
    /// `rsasim <version>`.
    pub program: String,
    /// The exact build that wrote the folder (absent in manifests of rsasim 0.1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub build: Option<Build>,
    /// The version of the folder layout ([`OUTPUT_FORMAT`]); 1 when absent (rsasim 0.1).
    #[serde(default = "Manifest::first_output_format")]
    pub output_format: u32,
    /// What the folder holds: absent for an ordinary output (images and truth together),
    /// `images` for the blind folder given to a software under test, `truth` for its truth.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub layout: Option<Layout>,
    /// The scenario's name.
    pub scenario: String,
    /// SHA-256 of the scenario file as given, lowercase hex (absent in a blind images folder:
    /// with the nominal set-up it would help to guess the seed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scenario_sha256: Option<String>,
    /// The scenario's master seed (absent in a blind images folder).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// Number of runs (in a shard folder: the runs it holds).
    pub runs: usize,
    /// In a truth folder: the images folder it belongs to.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub images: Option<ImagesBinding>,
    /// In a shard folder (`rsasim SCENARIO --shard K/N`): which shard it is and which runs it
    /// holds; absent in every other folder, a merged one included.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard: Option<ShardRecord>,
    /// Every file of the folder but this one, sorted by path.
    pub files: Vec<ManifestFile>,
}

/// Which build of rsasim wrote a folder.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Build {
    /// The crate version, e.g. `0.2.0`.
    pub version: String,
    /// The git commit it was built from (40 hex digits), or `unknown` (built without git).
    pub commit: String,
    /// Whether the sources differed from that commit: `true`, `false` or `unknown`.
    pub dirty: String,
}

/// The kind of folder a manifest describes (blind layout).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Layout {
    /// The folder for the software under test: images, phantoms, the nominal set-up; no truth.
    Images,
    /// The truth of an images folder: every `truth.json` and the full scenario as run.
    Truth,
}

/// How a truth folder names its images folder.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ImagesBinding {
    /// SHA-256 of the images folder's `manifest.json` file, lowercase hex.
    pub manifest_sha256: String,
    /// The images folder's name when it was written (where `rsasim verify` looks for it, beside
    /// the truth folder, unless given `--images`).
    pub folder: String,
}

/// What a shard folder holds of its protocol (see [`crate::shard`] for the split).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ShardRecord {
    /// The shard's index K, from 0 to `count` − 1.
    pub index: usize,
    /// The number of shards N the protocol was split into.
    pub count: usize,
    /// The ids of the runs this folder holds, in protocol order.
    pub runs: Vec<String>,
    /// The ids of every run of the protocol, in order: what the N shards hold together.
    pub protocol_runs: Vec<String>,
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

impl Manifest {
    fn first_output_format() -> u32 {
        1
    }

    /// The manifest's file bytes: pretty JSON with a final newline, `manifest_sha256` filled in.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut m = self.clone();
        m.manifest_sha256.clear();
        let unsealed = pretty(&m);
        m.manifest_sha256 = hex(&Sha256::digest(&unsealed));
        pretty(&m)
    }
}

/// Pretty JSON with a final newline.
fn pretty(m: &Manifest) -> Vec<u8> {
    let mut v = serde_json::to_vec_pretty(m).expect("manifests serialise");
    v.push(b'\n');
    v
}

/// The key and the text that precede the self-hash's value in the file.
const SELF_HASH_KEY: &[u8] = b"\"manifest_sha256\": \"";

/// Recomputes the self-hash of a manifest file's bytes: the SHA-256 of the bytes with the value of
/// the first `"manifest_sha256": "…"` emptied. Returns `(recorded, recomputed)`, or `None` when the
/// field is missing or malformed.
pub fn self_hash(bytes: &[u8]) -> Option<(String, String)> {
    let start = bytes
        .windows(SELF_HASH_KEY.len())
        .position(|w| w == SELF_HASH_KEY)?
        + SELF_HASH_KEY.len();
    let len = bytes[start..].iter().position(|&b| b == b'"')?;
    let recorded = std::str::from_utf8(&bytes[start..start + len])
        .ok()?
        .to_string();
    let mut hasher = Sha256::new();
    hasher.update(&bytes[..start]);
    hasher.update(&bytes[start + len..]);
    Some((recorded, hex(&hasher.finalize())))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Manifest {
        Manifest {
            format: MANIFEST_FORMAT.into(),
            manifest_sha256: String::new(),
            program: "rsasim 0.0.0".into(),
            build: Some(Build {
                version: "0.0.0".into(),
                commit: "unknown".into(),
                dirty: "unknown".into(),
            }),
            output_format: OUTPUT_FORMAT,
            layout: None,
            scenario: "s".into(),
            scenario_sha256: Some("00".repeat(32)),
            seed: Some(7),
            runs: 1,
            images: None,
            shard: None,
            files: vec![ManifestFile {
                path: "a".into(),
                sha256: "11".repeat(32),
                bytes: 3,
            }],
        }
    }

    #[test]
    fn the_self_hash_verifies_and_catches_an_edit() {
        let bytes = sample().to_bytes();
        let (recorded, recomputed) = self_hash(&bytes).unwrap();
        assert_eq!(recorded.len(), 64);
        assert_eq!(recorded, recomputed);
        let parsed: Manifest = serde_json::from_slice(&bytes).unwrap();
        assert_eq!(parsed.manifest_sha256, recorded);
        let edited = String::from_utf8(bytes)
            .unwrap()
            .replace("\"bytes\": 3", "\"bytes\": 4");
        let (recorded, recomputed) = self_hash(edited.as_bytes()).unwrap();
        assert_ne!(recorded, recomputed);
    }

    #[test]
    fn the_documented_recipe_is_the_self_hash() {
        // sed 's/"manifest_sha256": "[0-9a-f]*"/"manifest_sha256": ""/' manifest.json | sha256sum
        let bytes = sample().to_bytes();
        let text = String::from_utf8(bytes).unwrap();
        let parsed: Manifest = serde_json::from_str(&text).unwrap();
        let emptied = text.replace(
            &format!("\"manifest_sha256\": \"{}\"", parsed.manifest_sha256),
            "\"manifest_sha256\": \"\"",
        );
        assert_eq!(
            hex(&Sha256::digest(emptied.as_bytes())),
            parsed.manifest_sha256
        );
    }

    #[test]
    fn a_manifest_of_rsasim_0_1_still_reads() {
        let old = r#"{"format":"rsasim-manifest/1","program":"rsasim 0.1.0","scenario":"s",
            "scenario_sha256":"00","seed":1,"runs":0,"files":[]}"#;
        let m: Manifest = serde_json::from_str(old).unwrap();
        assert_eq!((m.output_format, m.build, m.seed), (1, None, Some(1)));
        assert!(self_hash(old.as_bytes()).is_none());
    }
}

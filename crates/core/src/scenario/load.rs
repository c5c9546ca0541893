//! Reading a scenario file: TOML parse errors located by line, column and key path.

use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use super::Scenario;
use super::lengths::check_lengths;
use super::magnitudes::check_magnitudes;
use super::validate::validate;
use crate::diagnostic::{Diagnostic, Locator};

/// A scenario read from disk, with what later stages need to report on it.
pub struct LoadedScenario {
    /// The records as the user wrote them (defaults filled in by serde).
    pub scenario: Scenario,
    /// The file it came from.
    pub path: PathBuf,
    /// The folder relative paths in the scenario (mesh files) are resolved against.
    pub base_dir: PathBuf,
    /// Folders besides `base_dir` that files the scenario pulls in (meshes, glTF buffers and
    /// images) may be read from (`--allow-dir`); empty after loading. Library callers push
    /// their folders here before building phantoms (see `phantom::confine`).
    pub allowed_dirs: Vec<PathBuf>,
    /// SHA-256 of the file's bytes, lowercase hex.
    pub sha256: String,
    /// Key path → line/column index of the file, for diagnostics of later stages.
    pub locator: Locator,
    /// Warnings found so far (errors stop loading).
    pub warnings: Vec<Diagnostic>,
}

/// Largest scenario (or sweep) file read: 2 MiB. The shipped ones are a few kB, and a phantom
/// listing 20,000 beads inline stays below; a scenario is parsed several times (located,
/// deserialised, its magnitudes walked), at a few MB per second, so a received folder's
/// `scenario.toml` at the cap is refused or read in well under a second (a 19 MB one took 3.4 s).
pub const MAX_SCENARIO_BYTES: u64 = 2 * 1024 * 1024;

/// Reads, parses and validates a scenario file. On failure every error found is returned
/// (a parse error stops at the first; semantic checks report them all).
pub fn load(path: &Path) -> Result<LoadedScenario, Vec<Diagnostic>> {
    let bytes = crate::input_file::read_named(path, MAX_SCENARIO_BYTES).map_err(|d| {
        vec![d.with_help("give the path of a scenario .toml file, e.g. scenarios/biplanar.toml")]
    })?;
    let text = String::from_utf8(bytes).map_err(|e| {
        vec![
            Diagnostic::file_error(
                path,
                format!(
                    "the file is not UTF-8 text (byte {})",
                    e.utf8_error().valid_up_to()
                ),
            )
            .with_help("scenario files are TOML, which must be UTF-8"),
        ]
    })?;
    let base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    from_text(&text, path, &base_dir)
}

/// Parses and validates scenario text. `path` names it in diagnostics; mesh paths resolve
/// against `base_dir`. Used by [`load`] and by tests that build scenarios in memory.
pub fn from_text(
    text: &str,
    path: &Path,
    base_dir: &Path,
) -> Result<LoadedScenario, Vec<Diagnostic>> {
    let locator = Locator::new(path, text);
    let length_errors = check_lengths(&locator);
    if !length_errors.is_empty() {
        return Err(length_errors);
    }
    let scenario: Scenario = toml::from_str(text).map_err(|e| {
        let message = e.message().trim_end().to_string();
        let mut d = locator.error_at_span(e.span(), message.clone());
        if let Some(help) = parse_help(&message) {
            d = d.with_help(help);
        }
        vec![d]
    })?;
    let magnitude_errors = check_magnitudes(&scenario, &locator);
    if !magnitude_errors.is_empty() {
        return Err(magnitude_errors);
    }
    let mut diagnostics = validate(&scenario, &locator);
    diagnostics.extend(super::imaging_check::check(&scenario, &locator));
    diagnostics.extend(super::dicom::check(&scenario, &locator));
    let (errors, warnings): (Vec<_>, Vec<_>) =
        diagnostics.into_iter().partition(Diagnostic::is_error);
    if !errors.is_empty() {
        return Err(errors);
    }
    Ok(LoadedScenario {
        scenario,
        path: path.to_path_buf(),
        base_dir: base_dir.to_path_buf(),
        allowed_dirs: Vec::new(),
        sha256: hex(&Sha256::digest(text.as_bytes())),
        locator,
        warnings,
    })
}

/// Lowercase hex of bytes (sha2 0.11 digests do not implement `LowerHex`).
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// A hint for the common parse errors.
fn parse_help(message: &str) -> Option<String> {
    if message.contains("unknown field") {
        Some("remove or rename the key; the valid keys are listed above and in schemas/scenario.schema.json".into())
    } else if message.contains("missing field") {
        Some("add the key; docs/src/reference/scenario.md says what it means".into())
    } else if message.contains("invalid type") {
        Some("check the value's type: numbers without quotes, ids and paths in quotes, vectors as [x, y, z]".into())
    } else if message.contains("unknown variant") {
        Some("use one of the values listed above".into())
    } else {
        None
    }
}

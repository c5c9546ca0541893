//! Ctrl-C and SIGTERM: say what an interrupted run leaves behind, and exit 130.
//!
//! rsasim does not delete the unfinished staging folder itself: writer threads may still be
//! creating files in it at that instant, and a removal racing them could leave a folder without
//! its staging marker, which no later run would dare to remove. The folder carries the marker, and
//! the next run into the same output removes it and says so.

use std::path::PathBuf;
use std::sync::Mutex;

use super::durable::{human_bytes, tree_bytes};

/// Staging folders being written now, with the output each is for.
static ACTIVE: Mutex<Vec<(PathBuf, PathBuf)>> = Mutex::new(Vec::new());

/// Records that `staging` is being written for the output `shown`.
pub(crate) fn register(staging: &std::path::Path, shown: &std::path::Path) {
    if let Ok(mut active) = ACTIVE.lock() {
        active.push((staging.to_path_buf(), shown.to_path_buf()));
    }
}

/// Forgets `staging` (committed or removed).
pub(crate) fn unregister(staging: &std::path::Path) {
    if let Ok(mut active) = ACTIVE.lock() {
        active.retain(|(s, _)| s != staging);
    }
}

/// What an interrupted process tells its user: one line per unfinished staging folder.
pub fn interrupted_message() -> String {
    let active = ACTIVE.lock().map(|a| a.clone()).unwrap_or_default();
    let mut text = String::from("rsasim: interrupted; nothing was committed");
    for (staging, shown) in active.iter().filter(|(s, _)| s.exists()) {
        text += &format!(
            "\n  = left {} ({} written so far); the next run into {} removes it",
            staging.display(),
            human_bytes(tree_bytes(staging)),
            shown.display()
        );
    }
    text
}

/// Installs the handler of Ctrl-C (SIGINT) and SIGTERM: print [`interrupted_message`], exit 130.
/// The output lock is released by the operating system as the process ends. Installed once per
/// process: later calls (a sweep runs several outputs) return the first call's result.
pub fn install() -> Result<(), String> {
    static INSTALLED: std::sync::OnceLock<Result<(), String>> = std::sync::OnceLock::new();
    INSTALLED
        .get_or_init(|| {
            ctrlc::set_handler(|| {
                eprintln!("\n{}", interrupted_message());
                std::process::exit(130);
            })
            .map_err(|e| e.to_string())
        })
        .clone()
}

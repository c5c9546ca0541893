//! Records which build this is: the git commit the binary was built from and whether the files
//! that go into the build differed from it (`dirty`). Built outside a git checkout of this crate
//! (a crates.io package, a tarball, or a checkout without git installed) both are "unknown".
//!
//! Sets, for `env!` in the crate: `RSASIM_BUILD_COMMIT` (40 hex digits or `unknown`),
//! `RSASIM_BUILD_DIRTY` (`true`, `false` or `unknown`) and `RSASIM_VERSION_LINE` (what
//! `rsasim --version` prints after the name, e.g. `0.2.0 (abc1234)`).

use std::path::{Path, PathBuf};
use std::process::Command;

/// The files whose changes make a build differ from its commit.
/// Every crate of the workspace goes into the binary, so its folder is among them.
const BUILD_INPUTS: &[&str] = &["src", "crates", "Cargo.toml", "Cargo.lock", "build.rs"];

fn git(dir: &Path, args: &[&str]) -> Option<String> {
    let out = Command::new("git")
        .args(args)
        .current_dir(dir)
        .output()
        .ok()?;
    if !out.status.success() {
        return None;
    }
    Some(String::from_utf8_lossy(&out.stdout).trim_end().to_string())
}

fn main() {
    let manifest_dir = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").unwrap_or_default());
    for input in BUILD_INPUTS {
        println!("cargo:rerun-if-changed={input}");
    }
    let (commit, dirty) = commit_and_dirty(&manifest_dir);
    let short: String = commit.chars().take(7).collect();
    let line = match (commit.as_str(), dirty.as_str()) {
        ("unknown", _) => format!("{} (unknown build)", env_version()),
        (_, "true") => format!("{} ({short}, dirty)", env_version()),
        _ => format!("{} ({short})", env_version()),
    };
    println!("cargo:rustc-env=RSASIM_BUILD_COMMIT={commit}");
    println!("cargo:rustc-env=RSASIM_BUILD_DIRTY={dirty}");
    println!("cargo:rustc-env=RSASIM_VERSION_LINE={line}");
}

fn env_version() -> String {
    std::env::var("CARGO_PKG_VERSION").unwrap_or_default()
}

/// The commit of the checkout holding this crate, and whether its build inputs are modified.
/// A git repository that merely contains the crate's folder (a tarball unpacked inside another
/// project) is not this crate's checkout: the top level must be the crate's own folder.
fn commit_and_dirty(dir: &Path) -> (String, String) {
    let unknown = || ("unknown".to_string(), "unknown".to_string());
    let Some(top) = git(dir, &["rev-parse", "--show-toplevel"]) else {
        return unknown();
    };
    let same = |a: &Path, b: &Path| match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    if !same(Path::new(&top), dir) {
        return unknown();
    }
    let Some(commit) = git(dir, &["rev-parse", "HEAD"]) else {
        return unknown();
    };
    if commit.len() != 40 || !commit.bytes().all(|b| b.is_ascii_hexdigit()) {
        return unknown();
    }
    // Rebuild when HEAD moves (a commit, a checkout, a reset). Cargo treats a watched path that
    // does not exist as changed on every build, so only paths that exist are watched: HEAD, the
    // folder holding the branch's loose ref (a commit creates or rewrites the file in it, which
    // changes the folder's newest modification time) and `packed-refs` where there is one. The
    // index is not watched: `git status` refreshes it without changing what is committed, and a
    // staged change is dirty as much as an unstaged one, which the watched sources already cover.
    let mut watched = Vec::new();
    if let Some(p) = git(dir, &["rev-parse", "--git-path", "HEAD"]) {
        watched.push(dir.join(p));
    }
    if let Some(p) = git(dir, &["rev-parse", "--git-path", "packed-refs"]) {
        watched.push(dir.join(p));
    }
    if let Some(head_ref) = git(dir, &["symbolic-ref", "-q", "HEAD"])
        && let Some(p) = git(dir, &["rev-parse", "--git-path", &head_ref])
    {
        let loose = dir.join(p);
        if let Some(folder) = loose.parent() {
            watched.push(folder.to_path_buf());
        }
        watched.push(loose);
    }
    for path in watched.iter().filter(|p| p.exists()) {
        println!("cargo:rerun-if-changed={}", path.display());
    }
    let mut args = vec!["status", "--porcelain", "--"];
    args.extend(BUILD_INPUTS);
    let dirty = match git(dir, &args) {
        Some(s) => (!s.is_empty()).to_string(),
        None => "unknown".to_string(),
    };
    (commit.to_lowercase(), dirty)
}

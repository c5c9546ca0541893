//! Which build this is, as recorded by `build.rs`: the crate version, the git commit and whether
//! the sources differed from it. It lives in the binary's crate, at the top of the house, so that
//! a commit recompiles only this crate and nothing below it.

use rsasim_files::output::Build;

/// The exact build of this program: crate version, git commit (or `unknown` when built without
/// git) and whether the sources differed from that commit (recorded by `build.rs`).
pub fn build() -> Build {
    Build {
        version: env!("CARGO_PKG_VERSION").into(),
        commit: env!("RSASIM_BUILD_COMMIT").into(),
        dirty: env!("RSASIM_BUILD_DIRTY").into(),
    }
}

/// What `rsasim --version` prints after the name: `<version> (<short commit>[, dirty])`, or
/// `<version> (unknown build)` without git.
pub const VERSION_LINE: &str = env!("RSASIM_VERSION_LINE");

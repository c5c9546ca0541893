//! Parameter sweeps: one base scenario, some of its values varied (grid or zip), one standalone
//! scenario per point, each run by the main command's own entry points into its own output
//! folder, and a summary of every point's evaluation against the varied parameter.
//!
//! The flow: [`prepare`] reads the sweep file and the base scenario and builds and checks every
//! point (nothing written; errors name the sweep file's line); [`claim`] takes the sweep folder
//! (new, or the same sweep resumed); [`SweepFolder::write_points`] writes the point scenarios;
//! the caller runs each pending point as `rsasim POINT.toml --out DIR/<id>` would; after
//! `reconstruct` and `evaluate` per point, [`summary::summary`] and [`summary::write`] make the
//! summary. A point is a scenario file plus an output folder, so running one point can be split
//! further (sharded) without the sweep knowing.
//!
//! On a cluster (`--shard K/N`): every task of an array job [`join`]s the sweep folder (no lock
//! on it; the sweep's own files written once by whichever task comes first) and writes one shard
//! of every point ([`split`]) into `DIR/shards/<id>/shard-j-of-N/`, as `rsasim POINT.toml --shard
//! j/N` would. `--merge` then checks every point's shards ([`merge::check`]) and joins them into
//! `DIR/<id>/`, the bytes an unsharded sweep writes.

pub mod file;
pub mod folder;
pub mod merge;
pub mod points;
pub mod prepare;
pub mod split;
pub mod summary;

pub use folder::{Index, SweepFolder, WriteError, claim, is_sweep_folder, join, read_index};
pub use prepare::{Sweep, prepare};

//! The files rsasim reads and writes: the image codecs, `truth.json`, manifests and measured
//! records, folder transactions (staging, locks, the final swap), `verify` and `merge`, and the
//! exports for XMALab and Autoscoper (`interop`).
//!
//! It sees the core (what a scenario is) and nothing above it: no simulation driver, no reference
//! program, no evaluation, no command line.

// The core's modules under the names the code of this crate uses (`crate::scenario`, ...).
#[cfg(test)]
use rsasim_core::noise;
use rsasim_core::{
    attenuation, cost, diagnostic, expand, geometry, input_file, phantom, scenario, shard,
};

pub mod interop;
pub mod output;

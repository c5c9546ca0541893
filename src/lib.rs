//! rsasim: a Radio Stereometric Analysis simulator.
//!
//! The core (what a scenario is and how an image forms) is the crate `rsasim-core`, re-exported
//! here under the same names; this crate adds the files rsasim reads and writes, the simulation
//! driver, the reference RSA program, evaluation, sweeps and the command line.

pub use rsasim_core::{
    attenuation, cost, diagnostic, expand, geometry, input_file, material, noise, phantom, random,
    response, sampling, scenario, shard, spectrum, trace,
};
pub mod evaluate;
pub mod interop;
pub mod migration;
pub mod output;
pub mod reconstruct;
pub mod scene_view;
pub mod simulate;
pub mod sweep;

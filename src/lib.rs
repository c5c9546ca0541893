//! rsasim: a Radio Stereometric Analysis simulator.
//!
//! The core (what a scenario is and how an image forms) is the crate `rsasim-core`, re-exported
//! here under the same names, as are the files rsasim reads and writes (`rsasim-files`: codecs,
//! records, folder transactions, verify, merge, interop); this crate adds the simulation driver,
//! the reference RSA program, evaluation, sweeps and the command line.

pub use rsasim_core::{
    attenuation, binary, cost, diagnostic, expand, geometry, input_file, material, noise, phantom,
    random, response, sampling, scenario, shard, spectrum, trace,
};
pub use rsasim_evaluate as evaluate;
pub use rsasim_files::{interop, output};
pub use rsasim_migration as migration;
pub use rsasim_reconstruct as reconstruct;
pub mod build_info;
pub mod scene_view;
pub mod simulate;
pub mod sweep;

//! The core of rsasim: what a scenario is and how an image forms. The scenario's records, their
//! parsing and validation; materials and spectra; phantoms and the meshes they read; the
//! expansion of a scenario into plain runs; geometry (poses, projection, rigid fits); tracing and
//! sampling; binary-mode images; the detector's response and quantum noise; what a scenario will
//! cost and how its runs are sharded. It sees no image file format, no output folder, no command
//! line, no reconstruction and no evaluation: those crates sit above it.

pub mod attenuation;
pub mod binary;
pub mod cost;
pub mod diagnostic;
pub mod expand;
pub mod geometry;
pub mod input_file;
pub mod material;
pub mod noise;
pub mod phantom;
pub mod random;
pub mod response;
pub mod sampling;
pub mod scenario;
pub mod shard;
pub mod spectrum;
pub mod trace;

//! Attenuation mode (beyond the paper): radiographs by physics. The scenario's `[imaging]` is
//! resolved once ([`Setup`]); each exposure of a run becomes a list of solids with materials and
//! nesting ([`scene::parts`]); each image is the exact path length of every solid on every pixel
//! (`crate::trace::path_lengths`), summed per material, attenuated over the spectrum and turned
//! into detector values with quantum noise (`crate::response`). See docs/src/reference/conventions.md, "Image formation".

pub mod beamline;
pub mod check;
pub mod containment;
pub mod image;
pub mod sampled;
pub mod scene;
pub mod setup;
mod shadow;
pub mod spectral;

pub use image::{AttenuationImage, BeadVisibility, Formation, render};
pub use scene::{Exposure, Part, parts};
pub use setup::Setup;

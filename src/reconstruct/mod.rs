//! The reference RSA program: what a real RSA software does, from the images alone.
//!
//! It sees only what an operator has: the images, the nominal set-up (the scenario without its
//! random draws), the box bead table and the model files in `OUT/phantoms/`. It never reads the
//! ground truth: nothing in this module refers to the truth records or their files.
pub mod calibrate;
pub mod correspond;
pub mod detect;
pub mod exam;
pub mod rigid;

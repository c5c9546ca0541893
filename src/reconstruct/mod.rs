//! The reference RSA program: what a real RSA software does, from the images alone.
//!
//! It sees only what an operator has: the images, the nominal set-up (the scenario without its
//! random draws), the box bead table and the model files in `OUT/phantoms/`. It never reads
//! `truth.json`: nothing in this module refers to the truth records.
pub mod calibrate;
pub mod rigid;

//! Interoperability with the programs XROMM and RSA labs use, after `output` and `reconstruct`
//! in the flow: `rsasim export` writes an output folder as XMALab or Autoscoper open it (cameras
//! with the known calibration, images, calibration object, models), and `rsasim evaluate` reads
//! XMALab's exports back ([`xmalab::read_export`]).

pub mod autoscoper;
pub mod camera;
pub mod export;
pub mod mesh_text;
pub mod reference_beads;
pub mod volume;
pub mod xmalab;

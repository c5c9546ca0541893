//! Interoperability with the programs XROMM and RSA labs use, after `output` and `reconstruct`
//! in the flow: `rsasim export` writes an output folder as XMALab or Autoscoper open it (cameras
//! with the known calibration, images, calibration object, models), and `rsasim evaluate` reads
//! XMALab's exports back ([`xmalab::read_export`]); `rsasim camera` writes one beamline's camera
//! in MayaCam, DLT-11 and OpenCV form ([`camera_input`], [`camera_files`]). The export's
//! Autoscoper volumes and `.tra` truth are [`volume`]'s, and Autoscoper's tracking results are read
//! back by [`autoscoper_tracking`]; XMALab's reference beads are chosen by
//! [`reference_beads`]. A sequence's frames are one trial of each ([`trials`]).

pub mod autoscoper;
pub mod autoscoper_tracking;
pub mod camera;
pub mod camera_files;
pub mod camera_input;
pub mod detector_corners;
pub mod export;
pub mod failure;
pub mod mesh_text;
pub mod reference_beads;
pub mod trials;
pub mod volume;
pub mod xmalab;
pub mod xmalab_points2d;

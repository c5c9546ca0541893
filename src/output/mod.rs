//! Image writers: byte-stable TIFF and EXR encoders that write to memory.

pub mod exr;
pub mod tiff;

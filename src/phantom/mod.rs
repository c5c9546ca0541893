//! Phantoms in their own local frames: bead sets, calibration boxes, meshes with beads.
pub mod femoral;
pub mod isosurface;
pub mod mesh;
pub mod mesh_io;

pub use mesh::TriMesh;

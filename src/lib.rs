//! rsasim: a Radio Stereometric Analysis simulator.
pub mod diagnostic;
pub mod geometry;
pub mod noise;
pub mod output;
pub mod phantom;

//! rsasim: a Radio Stereometric Analysis simulator.
pub mod diagnostic;
pub mod geometry;
pub mod scenario;
pub mod phantom;
pub mod random;
pub mod expand;
pub mod trace;
pub mod noise;
pub mod output;
pub mod evaluate;
pub mod reconstruct;
pub mod simulate;

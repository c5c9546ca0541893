//! rsasim: a Radio Stereometric Analysis simulator.
pub mod attenuation;
pub mod cost;
pub mod diagnostic;
pub mod evaluate;
pub mod expand;
pub mod geometry;
pub mod material;
pub mod noise;
pub mod output;
pub mod phantom;
pub mod random;
pub mod reconstruct;
pub mod response;
pub mod scenario;
pub mod simulate;
pub mod spectrum;
pub mod trace;

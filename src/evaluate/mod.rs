//! The evaluation stage: score what a software under test reconstructed against the
//! simulator's truth, by ISO 5725 trueness and precision (DESIGN.md, "Accuracy").
pub mod iso5725;
pub mod stats;
pub mod table;
pub mod report;

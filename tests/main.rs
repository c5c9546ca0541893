//! The whole-program tests, one binary: each module is one subject (its file says what it checks
//! and against what), run against the real `rsasim` binary or the library. One binary links the
//! library once, where one binary per file linked it once per file.
//!
//! Run one subject with `cargo test --test integration <module>::`, e.g.
//! `cargo test --test integration hostile_sender::`.

mod common;

mod attenuation;
mod bad_scenarios;
mod blind;
mod camera;
mod conformance;
mod conventions;
mod deploy;
mod detection;
mod dicom;
mod evaluate;
mod exr_encoder;
mod geometry;
mod golden;
mod hostile_meshes;
mod hostile_sender;
mod house;
mod interop;
mod knee_joint;
mod limits;
mod manual;
mod mesh_formats;
mod migration;
mod mutation;
mod output_safety;
mod physics;
mod reconstruct;
mod reconstruct_realistic;
mod sampling;
mod scene;
mod schemas;
mod sequence;
mod shards;
mod silhouette_bias;
mod study;
mod study_pipeline;
mod sweep;
mod sweep_shards;
mod verify;

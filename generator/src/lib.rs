//! vtgen: synthetic visuotactile training data for in-hand 6D object pose estimation.
//!
//! Data flows one way, and the modules follow it (ARCHITECTURE.md has the page-long tour):
//!
//! config -> plan -> assets -> scene (camera, appearance) -> physics (grasp loop, arm moves)
//! -> render (main camera, the pad views) -> sensors (tactile cloud, RGB-D noise)
//! -> annotate (occlusion) -> sample (assembles one sample) -> output (shards, manifest).
//!
//! `cli` holds the subcommands that read, check or convert datasets. Each stage is a module that
//! can be used and tested alone; physics and rendering sit behind the `HandPhysics` and
//! `Renderer` traits.

pub mod annotate;
pub mod assets;
pub mod cli;
pub mod config;
pub mod cpu_clock;
pub mod output;
pub mod physics;
pub mod plan;
pub mod render;
pub mod sample;
pub mod scene;
pub mod sensors;

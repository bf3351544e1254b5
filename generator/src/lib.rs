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
//! `Renderer` traits. A module imports only the modules before it in that flow: a unit test
//! (`module_order.rs`) checks it.

// The modules in the order data flows, each importing only those before it (`module_order.rs`
// checks it); one per group so that rustfmt keeps that order.
pub mod cpu_clock;

pub mod config;

pub mod plan;

pub mod assets;

pub mod scene;

pub mod physics;

pub mod render;

pub mod sensors;

pub mod annotate;

pub mod sample;

pub mod output;

pub mod cli;

#[cfg(test)]
mod module_order;

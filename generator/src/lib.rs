//! vtgen: synthetic visuotactile training data for in-hand 6D object pose estimation.
//!
//! Data flows one way: config -> plan -> sampled scene -> render -> sample -> shard writer.
//! Each stage is a module that can be used and tested alone.

pub mod assets;
pub mod bench;
pub mod config;
pub mod dump;
pub mod export;
pub mod grasp;
pub mod grasp_check;
pub mod inspect;
pub mod occlusion;
pub mod physics;
pub mod pipeline;
pub mod plan;
pub mod preview;
pub mod render;
pub mod sample;
pub mod scene;
pub mod sensor_noise;
pub mod stats;
pub mod tactile;
pub mod validate;
pub mod writer_thread;

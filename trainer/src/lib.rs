//! vt-trainer: train and evaluate visuotactile 6D pose networks on vtgen datasets (binary
//! `vtpose`).
//!
//! The networks are the paper's Tactile-Channel network, the vision-only DenseFusion baseline and
//! the paper's ablations ([`model`]), trained with DenseFusion's confidence-weighted model-point
//! loss ([`loss`]) on batches the [`data`] pipeline prepares from the shards on a background thread,
//! and scored with the paper's position and angle errors plus ADD/ADD-S ([`metrics`], [`eval`]).
//!
//! Built on burn 0.22: tensors carry their backend in their `Device`, so every model is
//! backend-generic by construction; the CPU (ndarray) backend is always built, CUDA is the cargo
//! feature `cuda` ([`device`]).
//!
//! ```no_run
//! use vt_trainer::{config::TrainConfig, train::{train, TrainOptions}, device};
//! let cfg = TrainConfig::load("trainer/configs/tiny-hand.yaml".as_ref())?;
//! let opts = TrainOptions { out: "runs/tactile".into(), resume: false, overwrite: false, device: device::cpu(), quiet: false };
//! let summary = train(&cfg, &opts)?;
//! # anyhow::Ok(())
//! ```

pub mod bench;
pub mod compare;
pub mod config;
pub mod data;
pub mod device;
pub mod encoder;
pub mod eval;
pub mod geometry;
pub mod loss;
pub mod metrics;
pub mod model;
pub mod plots;
pub mod run;
pub mod sweep;
pub mod train;

//! vt-trainer: train and evaluate visuotactile 6D pose networks on vtgen datasets (binary
//! `vtpose`).
//!
//! The modules follow the data as it flows:
//!
//! - [`data`]: batches prepared from the shards on a background thread;
//! - [`model`]: the networks, the paper's Tactile-Channel network, the vision-only DenseFusion
//!   baseline and the paper's ablations, with their colour encoders ([`model::encoder`]);
//! - [`loss`]: DenseFusion's confidence-weighted model-point loss;
//! - [`train`]: the training loop, checkpoints and `--resume`, into a run directory ([`run`]);
//! - [`eval`]: the trained networks scored with the paper's position and angle errors plus
//!   ADD/ADD-S ([`eval::metrics`]), summarised, and compared per grasp ([`eval::compare`]);
//! - [`report`]: `report.md`, `results.json`, per-sample CSV and SVG charts of those results.
//!
//! The commands on top: [`sweep`] (train and evaluate one network per tactile point count) and
//! [`bench`] (inference timing). Shared by every stage: [`config`] (the YAML of a run, which names
//! the model's variants and encoders), [`device`] and [`geometry`].
//!
//! A stage imports only the stages before it, with two exceptions: [`data`] builds the network's
//! input type ([`model::PoseInput`], the model's interface), and [`train`] scores the network on
//! held-out samples with [`eval::evaluate`] every `train.eval_every` epochs. Neither makes a cycle:
//! [`model`] does not import [`data`], nor [`eval`] [`train`].
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

pub mod config;
pub mod device;
pub mod geometry;
pub mod host;

// The stages in the order the data flows, one per group so that rustfmt keeps that order.
pub mod data;

pub mod model;

pub mod loss;

pub mod run;
pub mod train;

pub mod eval;

pub mod report;

pub mod bench;
pub mod sweep;

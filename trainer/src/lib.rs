//! vt-trainer: train and evaluate visuotactile 6D pose networks on vtgen datasets (binary
//! `vtpose`).
//!
//! The modules, in the order they import one another: each imports only modules above it in
//! this list, so the imports have no cycle.
//!
//! - [`device`], [`geometry`], [`host`]: the burn devices, rotations and symmetries, and the
//!   process's CPU time and allocator settings; they import no other module (the geometry tests
//!   use [`device`]).
//! - [`model`]: the networks, the paper's Tactile-Channel network, the vision-only DenseFusion
//!   baseline and the paper's ablations, with their colour encoders ([`model::encoder`]); it
//!   owns the network's input and output types and the config's `model:` section
//!   ([`model::ModelConfig`]).
//! - [`data`]: batches prepared from the shards on a background thread, as [`model::PoseInput`];
//!   it owns the `objects:`, `data:` and `augment:` sections.
//! - [`synthetic`]: deterministic inputs with a config's shapes, for `vtpose bench` and the tests.
//! - [`refine`]: the geometric pose refiner: the object's mesh registered to the depth points,
//!   the tactile points and the depth image's free space (global search, then Gauss-Newton).
//! - [`loss`]: DenseFusion's confidence-weighted model-point loss.
//! - [`optim`]: the `train:` section (learning rate and schedule, the loss's weights, epochs).
//! - [`config`]: the YAML of a run, the sections above composed into [`config::TrainConfig`],
//!   loaded and validated.
//! - [`run`]: a run directory's files (state, weights, `metrics.csv` read back).
//! - [`eval`]: the trained networks scored with the paper's position and angle errors plus
//!   ADD/ADD-S ([`eval::metrics`]), summarised, and compared per grasp ([`eval::compare`]).
//! - [`train`]: the training loop, checkpoints, `--resume` and `metrics.csv`, into a run
//!   directory; it scores the network on held-out samples with [`eval::evaluate`] every
//!   `train.eval_every` epochs.
//! - [`report`]: `report.md`, `results.json`, per-sample CSV and SVG charts of those results.
//! - [`track`]: the tracking benchmark, per-frame networks over the test episodes of an episode
//!   dataset, scored as sequences, with a constant-velocity filter and the touch control; its
//!   report (charts through [`report::plots`]).
//! - [`bench`](mod@bench) (inference and training-step timing) and [`sweep`] (train and evaluate one network
//!   per tactile point count): the commands on top.
//!
//! The order is checked, not only written down: a unit test (`module_order.rs`) reads every
//! source file, collects the modules each names through `crate::` paths (tests included, comments
//! not), and fails when one names a module that does not come before it.
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

// The modules in import order (see above), one per group so that rustfmt keeps that order.
pub mod device;
pub mod geometry;
pub mod host;

pub mod model;

pub mod data;

pub mod synthetic;

pub mod refine;

pub mod loss;

pub mod optim;

pub mod config;

pub mod run;

pub mod eval;

pub mod train;

pub mod report;

pub mod track;

pub mod bench;
pub mod sweep;

#[cfg(test)]
mod module_order;

//! The `train:` section of a training config: Adam's learning rate and its schedule, the loss's
//! weights, the batch size and epochs, and what a run does along the way (checkpoints, held-out
//! evaluations, threads per step).
//!
//! It sits below [`crate::config`], which composes it with the other sections, and
//! [`crate::train`] reads it with the rest of the config.

use serde::{Deserialize, Serialize};
use vt_check::{Check, Checks, excl, incl, key};

use crate::loss::LossWeights;

/// Optimisation (the paper: Adam, lr 2e-4, batch 16, w = 0.015).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OptimConfig {
    pub epochs: usize,
    pub batch_size: usize,
    pub lr: f64,
    /// The learning rate over the run: `constant` (the paper's) or `cosine` (from `lr` down to 0
    /// at the last step, half a cosine; a deviation from the paper, see docs/training.md).
    pub lr_schedule: LrSchedule,
    /// The confidence regulariser `w` of the loss.
    pub w: f64,
    /// Metres of distance per unit of chordal rotation error added to each estimate's model-point
    /// distance in the loss (0: the paper's loss; see `loss::pose_loss`).
    pub rotation_loss: f64,
    /// Seeds the weights, the sample order and every random choice of the data pipeline.
    pub seed: u64,
    /// Objects (ids) trained with the closest-point loss (DenseFusion's ADD-S variant): a pose
    /// that differs from the truth by a symmetry of the object's *shape* costs nothing. The paper
    /// trains every object with plain ADD (eq. 1): texture breaks the shape's symmetries, and its
    /// angle metric counts a symmetric twin as an error. List an object only when it really
    /// looks the same under its symmetry (models_info.json), e.g. an untextured can.
    pub symmetric_loss: Vec<String>,
    /// Keep a copy of the weights every this many epochs in `checkpoints/` (the last epoch
    /// always; `model.bpk` always holds the latest).
    pub checkpoint_every: usize,
    /// Evaluate on the test split every this many epochs (0: never during training).
    pub eval_every: usize,
    /// At most this many test samples in those evaluations (0: all).
    pub eval_samples: usize,
    /// Train on at most this many samples of the train split (0: all), e.g. to overfit a few.
    pub max_train_samples: usize,
    /// Threads a training step splits its batch over (data parallel, gradients summed):
    /// 0 = the machine's cores on the CPU backends, 1 on a GPU.
    pub step_threads: usize,
}

/// See [`OptimConfig::lr_schedule`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LrSchedule {
    #[default]
    Constant,
    Cosine,
}

impl Default for OptimConfig {
    fn default() -> Self {
        OptimConfig {
            epochs: 20,
            batch_size: 16,
            lr: 2e-4,
            lr_schedule: LrSchedule::Constant,
            w: 0.015,
            rotation_loss: 0.0,
            seed: 0,
            symmetric_loss: Vec::new(),
            checkpoint_every: 10,
            eval_every: 5,
            eval_samples: 0,
            max_train_samples: 0,
            step_threads: 0,
        }
    }
}

impl OptimConfig {
    /// The loss's weights.
    pub fn loss_weights(&self) -> LossWeights {
        LossWeights { w: self.w, rotation: self.rotation_loss }
    }

    /// The learning rate of the step after `steps_done` of `total_steps`.
    pub fn lr_at(&self, steps_done: u64, total_steps: u64) -> f64 {
        match self.lr_schedule {
            LrSchedule::Constant => self.lr,
            LrSchedule::Cosine => {
                let progress = (steps_done as f64 / total_steps.max(1) as f64).clamp(0.0, 1.0);
                0.5 * self.lr * (1.0 + (std::f64::consts::PI * progress).cos())
            }
        }
    }
}

/// The range checks the type system does not make (NaN fails them too).
impl Check for OptimConfig {
    fn check(&self, c: &mut Checks) {
        c.key(key!(self.epochs)).bounded(self.epochs as f64, incl(1.0), None, "");
        c.key(key!(self.batch_size)).bounded(self.batch_size as f64, incl(1.0), None, "");
        c.key(key!(self.lr)).bounded(self.lr, excl(0.0), None, "");
        c.key(key!(self.w)).bounded(self.w, incl(0.0), None, "");
        c.key(key!(self.rotation_loss)).bounded(self.rotation_loss, incl(0.0), None, "");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cosine_schedule_falls_from_lr_to_zero() {
        let mut t = OptimConfig { lr: 1e-3, ..Default::default() };
        assert_eq!(t.lr_at(50, 100), 1e-3);
        t.lr_schedule = LrSchedule::Cosine;
        assert_eq!(t.lr_at(0, 100), 1e-3);
        assert!((t.lr_at(50, 100) - 5e-4).abs() < 1e-12);
        assert!(t.lr_at(100, 100).abs() < 1e-12 && t.lr_at(150, 100).abs() < 1e-12);
    }
}

//! The epoch loop: every batch of the background loader through a training step, and at each
//! epoch's end its record, the held-out evaluation when due, the saved weights and a
//! `metrics.csv` row.

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use anyhow::{Result, bail};
use burn::module::Module;
use burn::optim::ModuleOptimizer;
use burn::prelude::*;
use indicatif::ProgressBar;

use super::step::train_step;
use super::{TrainOptions, metrics_csv};
use crate::config::TrainConfig;
use crate::data::{Batch, Loaded, Loader, SplitSource};
use crate::eval::{self, Summary};
use crate::model::PoseNet;
use crate::run::{RunDir, RunState};

/// One row of `metrics.csv` ([`metrics_csv::COLUMNS`]).
#[derive(Debug, Clone, PartialEq)]
pub struct EpochRecord {
    pub epoch: usize,
    pub steps: u64,
    pub samples: usize,
    /// Samples skipped because the object is not visible.
    pub skipped: usize,
    /// Mean training loss over the epoch's batches.
    pub loss: f64,
    /// Mean distance `L_i` (eq. 1) of the most confident estimate, cm.
    pub distance_cm: f64,
    pub seconds: f64,
    /// Test-split metrics when evaluated this epoch.
    pub eval: Option<Summary>,
}

impl EpochRecord {
    /// The line printed after the epoch.
    fn report_line(&self) -> String {
        let ev = self.eval.as_ref().map_or(String::new(), |e| {
            format!(
                ", test: position {:.2} cm, angle {:.1}° (median {:.1}°), ADD-S AUC {:.1}",
                e.position_cm.mean, e.angle_deg.mean, e.angle_median_deg, e.adds_auc
            )
        });
        format!("epoch {}: loss {:.5}, chosen-estimate distance {:.2} cm{ev}", self.epoch, self.loss, self.distance_cm)
    }
}

/// The running sums of the epoch in progress.
pub(super) struct EpochSums {
    loss: f64,
    distance: f64,
    batches: usize,
    samples: usize,
    started: Instant,
}

impl EpochSums {
    pub fn new() -> Self {
        EpochSums { loss: 0.0, distance: 0.0, batches: 0, samples: 0, started: Instant::now() }
    }
}

/// The epoch loop: what stays the same over the epochs, and what each one appends.
pub(super) struct Epochs<'a> {
    pub cfg: &'a TrainConfig,
    pub opts: &'a TrainOptions,
    pub run: &'a RunDir,
    pub slots: Vec<Option<usize>>,
    /// The held-out samples evaluated during training (handed back after each evaluation).
    pub test_source: Option<SplitSource>,
    pub bar: ProgressBar,
    /// `metrics.csv`, open for appending.
    pub csv: std::fs::File,
    pub records: Vec<EpochRecord>,
    pub sums: EpochSums,
    /// Threads each training step splits its batch over ([`super::step_threads`]).
    pub step_threads: usize,
    /// Steps of the whole run (the learning-rate schedule's progress).
    pub total_steps: u64,
}

impl Epochs<'_> {
    /// Trains on every batch of the loader, closing each epoch at its end of pass; returns the
    /// records of the epochs done and the run's state after the last.
    pub fn run(
        mut self,
        loader: Loader,
        mut model: PoseNet,
        mut optim: ModuleOptimizer,
        mut state: RunState,
        device: &Device,
    ) -> Result<(Vec<EpochRecord>, RunState)> {
        while let Some(msg) = loader.recv() {
            match msg? {
                Loaded::Batch { epoch, batch } => {
                    model = self.step(model, &mut optim, epoch, state.steps, &batch, device)?;
                    state.steps += 1;
                }
                Loaded::EndOfPass { epoch, skipped } => {
                    state.epochs_done = epoch as usize;
                    self.end_epoch(&model, &optim, &state, skipped.len())?;
                }
            }
        }
        loader.finish();
        self.bar.finish_and_clear();
        Ok((self.records, state))
    }

    /// One optimizer step on `batch`, after `steps_done` steps of the run; returns the updated
    /// network.
    fn step(
        &mut self,
        model: PoseNet,
        optim: &mut ModuleOptimizer,
        epoch: u64,
        steps_done: u64,
        batch: &Batch,
        device: &Device,
    ) -> Result<PoseNet> {
        let train = &self.cfg.train;
        let lr = train.lr_at(steps_done, self.total_steps);
        let (model, done) = train_step(model, optim, batch, train.loss_weights(), lr, self.step_threads, device, &mut |_| {});
        if !done.loss.is_finite() {
            bail!("epoch {epoch}: the loss is {} (diverged); try a lower train.lr", done.loss);
        }
        let sums = &mut self.sums;
        sums.distance += done.best_distance_m * batch.len() as f64;
        sums.loss += done.loss;
        sums.batches += 1;
        sums.samples += batch.len();
        self.bar.set_message(format!("{epoch}/{} loss {:.4}", train.epochs, sums.loss / sums.batches as f64));
        self.bar.inc(1);
        Ok(model)
    }

    /// Closes the epoch `state.epochs_done`: its record (with test metrics when due), the saved
    /// weights, a `metrics.csv` row and the printed line.
    fn end_epoch(&mut self, model: &PoseNet, optim: &ModuleOptimizer, state: &RunState, skipped: usize) -> Result<()> {
        let (train, epoch, sums) = (&self.cfg.train, state.epochs_done, &self.sums);
        let mut rec = EpochRecord {
            epoch,
            steps: state.steps,
            samples: sums.samples,
            skipped,
            loss: sums.loss / sums.batches.max(1) as f64,
            distance_cm: 100.0 * sums.distance / sums.samples.max(1) as f64,
            seconds: sums.started.elapsed().as_secs_f64(),
            eval: None,
        };
        let last = epoch == train.epochs;
        if train.eval_every > 0 && (epoch.is_multiple_of(train.eval_every) || last) {
            rec.eval = evaluate_during_training(&model.valid(), &mut self.test_source, self.cfg, &self.slots, &self.opts.device)?;
        }
        let checkpoint = last || epoch.is_multiple_of(train.checkpoint_every.max(1));
        save_epoch(self.run, model, optim, state, checkpoint)?;
        writeln!(self.csv, "{}", metrics_csv::row(&rec))?;
        self.csv.flush()?;
        if !self.opts.quiet {
            let line = rec.report_line();
            // indicatif swallows println on a hidden bar (stderr not a terminal).
            if self.bar.is_hidden() { eprintln!("{line}") } else { self.bar.println(line) }
        }
        self.records.push(rec);
        self.sums = EpochSums::new();
        Ok(())
    }
}

/// Weights, optimizer state and (`checkpoint`) a copy of the weights for the epoch just done,
/// then the run state that points at them: an interrupted save leaves the previous state valid.
fn save_epoch(run: &RunDir, model: &PoseNet, optim: &ModuleOptimizer, state: &RunState, checkpoint: bool) -> Result<()> {
    save_model(model, &run.model())?;
    optim.save(run.optimizer()).map_err(|e| anyhow::anyhow!("cannot write {}: {e}", run.optimizer().display()))?;
    if checkpoint {
        save_model(model, &run.checkpoint(state.epochs_done))?;
    }
    run.save_state(state)
}

fn save_model(model: &PoseNet, path: &Path) -> Result<()> {
    model.clone().save_file(path).map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))
}

/// The test metrics of `model` on the held-out samples (None when there are none); the source
/// is handed back for the next evaluation.
fn evaluate_during_training(
    model: &PoseNet,
    test_source: &mut Option<SplitSource>,
    cfg: &TrainConfig,
    slots: &[Option<usize>],
    device: &Device,
) -> Result<Option<Summary>> {
    let Some(src) = test_source.take() else { return Ok(None) };
    let eval_opts = eval::EvalOptions::for_config(cfg, slots, None).on(device);
    let (results, _, src) = eval::evaluate(model, src, &eval_opts)?;
    *test_source = Some(src);
    Ok(Some(Summary::of(&results)))
}

//! Training (`vtpose train`): Adam on the pose loss, a background loader, a progress bar,
//! checkpoints, `--resume`, and `metrics.csv`.
//!
//! A run directory holds everything needed to continue or evaluate a run:
//!
//! ```text
//! RUN/
//!   config.yaml          the config the run trains with (dataset path absolute)
//!   state.json           epochs done, steps, the objects of the head slots, the variant
//!   model.bpk            the latest weights (burn record, burnpack)
//!   optimizer.bpk        the Adam state of those weights
//!   checkpoints/epoch-NNNN.bpk   weights after epoch NNNN (every `checkpoint_every` epochs)
//!   metrics.csv          one row per epoch: loss, distance of the chosen estimates, test metrics
//! ```
//!
//! Resuming reloads weights and optimizer state and continues with the next epoch; the sample
//! order and every random choice of epoch `k` depend only on the seed and `k`, so a resumed run
//! sees the same data as an uninterrupted one.
//!
//! This file sets a run up (a fresh or resumed run directory, the network, the loader);
//! `step.rs` is one optimizer step ([`train_step`]), `epochs.rs` the loop over the epochs, and
//! [`metrics_csv`] the columns of `metrics.csv`.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use burn::module::Module;
use burn::optim::ModuleOptimizer;
use burn::prelude::*;
use indicatif::{ProgressBar, ProgressStyle};

use crate::config::TrainConfig;
use crate::data::{Loader, ObjectModel, Pass, PrepareOptions, SplitSource, load_models, select_objects, shuffled};
use crate::model::PoseNet;
pub use crate::run::{RunDir, RunState, slot_table};

mod epochs;
pub mod metrics_csv;
mod step;

pub use epochs::EpochRecord;
use epochs::{EpochSums, Epochs};
pub use step::{StepDone, StepStage, adam, best_distance, step_threads, train_step};

/// How to run [`train`].
#[derive(Debug, Clone)]
pub struct TrainOptions {
    pub out: PathBuf,
    /// Continue the run in `out` (its config must match, except `train.epochs`).
    pub resume: bool,
    /// Replace a run in `out`.
    pub overwrite: bool,
    /// The device to train on (autodiff is added).
    pub device: Device,
    pub quiet: bool,
}

/// What a training run did.
#[derive(Debug, Clone)]
pub struct TrainSummary {
    pub run: PathBuf,
    pub epochs: Vec<EpochRecord>,
    pub state: RunState,
}

/// Trains `cfg` into the run directory `opts.out` (see the module docs).
pub fn train(cfg: &TrainConfig, opts: &TrainOptions) -> Result<TrainSummary> {
    cfg.validate()?;
    let run = RunDir(opts.out.clone());
    let mut cfg = cfg.clone();
    cfg.dataset = std::path::absolute(&cfg.dataset).with_context(|| format!("dataset path {}", cfg.dataset.display()))?;
    let models = load_models(&cfg.dataset)?;
    let objects = select_objects(&models, &cfg.objects)?;

    let resumed = open_run(&run, &cfg, &objects, opts)?;
    std::fs::create_dir_all(run.0.join("checkpoints")).with_context(|| format!("cannot create {}", run.0.display()))?;
    cfg.save(&run.config())?;

    let device = opts.device.clone().autodiff();
    let (model, optim, state) = init_network(&cfg, &run, &objects, resumed, &device)?;
    if state.epochs_done >= cfg.train.epochs {
        if !opts.quiet {
            eprintln!("{}: already trained for {} epochs", run.0.display(), state.epochs_done);
        }
        return Ok(TrainSummary { run: run.0, epochs: Vec::new(), state });
    }

    let (source, test_source) = open_sources(&cfg, &objects)?;
    let n_train = source.len();
    let slots = slot_table(&models, &objects);
    let loader = spawn_loader(&cfg, &models, &slots, source, state.epochs_done)?;
    let bar = progress_bar(opts.quiet, (cfg.train.epochs - state.epochs_done) * n_train.div_ceil(cfg.train.batch_size));
    if !opts.quiet {
        eprintln!(
            "vtpose: training {} on {} ({} train samples of {}), {} params, device {:?}, {} thread(s) per step",
            cfg.model.variant.label(),
            cfg.dataset.display(),
            n_train,
            objects.join(", "),
            model.num_params(),
            opts.device,
            step_threads(&cfg.train, &opts.device)
        );
    }
    let csv = metrics_csv::open(&run.metrics(), state.epochs_done == 0)?;
    let epochs = Epochs {
        cfg: &cfg,
        opts,
        run: &run,
        slots,
        test_source,
        bar,
        csv,
        records: Vec::new(),
        sums: EpochSums::new(),
        step_threads: step_threads(&cfg.train, &opts.device),
        total_steps: (cfg.train.epochs * n_train.div_ceil(cfg.train.batch_size)) as u64,
    };
    let (records, state) = epochs.run(loader, model, optim, state, &device)?;
    Ok(TrainSummary { run: run.0, epochs: records, state })
}

/// The network (seeded by `train.seed`), its Adam optimizer and the run state: fresh, or
/// reloaded from `run` when it is resumed.
fn init_network(
    cfg: &TrainConfig,
    run: &RunDir,
    objects: &[String],
    resumed: Option<RunState>,
    device: &Device,
) -> Result<(PoseNet, ModuleOptimizer, RunState)> {
    device.seed(cfg.train.seed);
    let mut model = cfg.model.init(objects.len(), device);
    let mut optim = adam();
    let mut state = RunState {
        epochs_done: 0,
        steps: 0,
        objects: objects.to_vec(),
        variant: cfg.model.variant,
        trainer: format!("vtpose {}", env!("CARGO_PKG_VERSION")),
    };
    if let Some(saved) = resumed {
        model = model.try_load_file(run.model()).map_err(|e| anyhow::anyhow!("cannot load {}: {e}", run.model().display()))?;
        optim = optim.load(run.optimizer()).map_err(|e| anyhow::anyhow!("cannot load {}: {e}", run.optimizer().display()))?;
        state = saved;
    }
    Ok((model, optim, state))
}

/// The background loader over the epochs still to train (each epoch's order from the seed).
fn spawn_loader(
    cfg: &TrainConfig,
    models: &[ObjectModel],
    slots: &[Option<usize>],
    source: SplitSource,
    epochs_done: usize,
) -> Result<Loader> {
    let n_train = source.len();
    let prep = PrepareOptions {
        data: cfg.data.clone(),
        augment: cfg.augment.clone(),
        seed: cfg.train.seed,
        split: "train".into(),
        slots: slots.to_vec(),
        closest_point: closest_point_table(models, &cfg.train.symmetric_loss)?,
    };
    let passes: Vec<Pass> = (epochs_done + 1..=cfg.train.epochs)
        .map(|e| Pass { epoch: e as u64, order: shuffled(n_train, cfg.train.seed, e as u64) })
        .collect();
    Ok(Loader::spawn(source, passes, prep, cfg.train.batch_size, cfg.data.prefetch))
}

/// A fresh run, or the state of the one in `run` to continue (`--resume`: the config may differ
/// only in `train.epochs`); `--overwrite` clears a previous run's files first.
fn open_run(run: &RunDir, cfg: &TrainConfig, objects: &[String], opts: &TrainOptions) -> Result<Option<RunState>> {
    if !run.state().exists() || opts.overwrite {
        if opts.overwrite && run.0.exists() {
            for f in [run.state(), run.model(), run.optimizer(), run.metrics(), run.config()] {
                let _ = std::fs::remove_file(f);
            }
            let _ = std::fs::remove_dir_all(run.0.join("checkpoints"));
        }
        return Ok(None);
    }
    if !opts.resume {
        bail!("{} already holds a run: use --resume to continue it or --overwrite to replace it", run.0.display());
    }
    let state = run.load_state()?;
    let saved = TrainConfig::load(&run.config())?;
    let mut comparable = cfg.clone();
    comparable.train.epochs = saved.train.epochs;
    if comparable != saved {
        bail!("--resume: the config differs from the run's {} (only train.epochs may change)", run.config().display());
    }
    if state.objects != objects {
        bail!("--resume: the run was trained on {:?}, the config selects {:?}", state.objects, objects);
    }
    Ok(Some(state))
}

/// The train split (truncated as the config says) and, when the run evaluates during training,
/// the evenly spread test samples it evaluates on.
fn open_sources(cfg: &TrainConfig, objects: &[String]) -> Result<(SplitSource, Option<SplitSource>)> {
    let mut source = SplitSource::open(&cfg.dataset, "train", objects, cfg.data.depth, cfg.data.cache)?;
    if cfg.train.max_train_samples > 0 {
        source.truncate(cfg.train.max_train_samples);
    }
    if source.is_empty() {
        bail!("{}: the train split has no samples of {:?}", cfg.dataset.display(), objects);
    }
    let test_source = if cfg.train.eval_every > 0 {
        let mut s = SplitSource::open(&cfg.dataset, "test", objects, cfg.data.depth, cfg.data.cache)?;
        s.spread(cfg.train.eval_samples);
        Some(s).filter(|s| !s.is_empty())
    } else {
        None
    };
    Ok((source, test_source))
}

fn progress_bar(quiet: bool, batches: usize) -> ProgressBar {
    let bar = if quiet { ProgressBar::hidden() } else { ProgressBar::new(batches as u64) };
    bar.set_style(
        ProgressStyle::with_template("{spinner} epoch {msg} [{bar:30}] {pos}/{len} batches, {per_sec}, ETA {eta}")
            .expect("template")
            .progress_chars("=> "),
    );
    bar
}

/// Per dataset object: trained with the closest-point loss (`train.symmetric_loss` lists its id).
pub fn closest_point_table(models: &[ObjectModel], ids: &[String]) -> Result<Vec<bool>> {
    for id in ids {
        if !models.iter().any(|m| &m.id == id) {
            bail!("train.symmetric_loss: '{id}' is not an object of the dataset");
        }
    }
    Ok(models.iter().map(|m| ids.contains(&m.id)).collect())
}

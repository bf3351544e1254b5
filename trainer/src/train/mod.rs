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

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use burn::module::Module;
use burn::optim::{AdamConfig, GradientsAccumulator, GradientsParams, ModuleOptimizer};
use burn::prelude::*;
use indicatif::{ProgressBar, ProgressStyle};

use crate::config::{AugmentConfig, OptimConfig, TrainConfig};
use crate::data::{Batch, Loaded, Loader, ObjectModel, Pass, PrepareOptions, SplitSource, load_models, select_objects, shuffled};
use crate::eval::{self, Summary};
use crate::loss::{LossWeights, pose_loss};
use crate::model::PoseNet;
pub use crate::run::{RunDir, RunState, slot_table};

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

/// One row of `metrics.csv`.
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

const CSV_HEADER: &str = "epoch,steps,samples,skipped,loss,distance_cm,seconds,eval_n,eval_position_cm,eval_angle_deg,eval_add_auc,eval_adds_auc,eval_position_median_cm,eval_angle_median_deg";

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

    fn csv(&self) -> String {
        let e = self.eval.as_ref();
        let f = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6}"));
        format!(
            "{},{},{},{},{:.6},{:.4},{:.2},{},{},{},{},{},{},{}",
            self.epoch,
            self.steps,
            self.samples,
            self.skipped,
            self.loss,
            self.distance_cm,
            self.seconds,
            e.map_or(String::new(), |e| e.n.to_string()),
            f(e.map(|e| e.position_cm.mean)),
            f(e.map(|e| e.angle_deg.mean)),
            f(e.map(|e| e.add_auc)),
            f(e.map(|e| e.adds_auc)),
            f(e.map(|e| e.position_median_cm)),
            f(e.map(|e| e.angle_median_deg)),
        )
    }
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
    let csv = open_csv(&run.metrics(), state.epochs_done == 0)?;
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
    let mut model = cfg.model.net(objects.len()).init(device);
    let mut optim = AdamConfig::new().with_epsilon(1e-8).init(); // PyTorch's Adam, as the paper
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

/// The running sums of the epoch in progress.
struct EpochSums {
    loss: f64,
    distance: f64,
    batches: usize,
    samples: usize,
    started: Instant,
}

impl EpochSums {
    fn new() -> Self {
        EpochSums { loss: 0.0, distance: 0.0, batches: 0, samples: 0, started: Instant::now() }
    }
}

/// The epoch loop: what stays the same over the epochs, and what each one appends.
struct Epochs<'a> {
    cfg: &'a TrainConfig,
    opts: &'a TrainOptions,
    run: &'a RunDir,
    slots: Vec<Option<usize>>,
    /// The held-out samples evaluated during training (handed back after each evaluation).
    test_source: Option<SplitSource>,
    bar: ProgressBar,
    csv: std::fs::File,
    records: Vec<EpochRecord>,
    sums: EpochSums,
    /// Threads each training step splits its batch over ([`step_threads`]).
    step_threads: usize,
    /// Steps of the whole run (the learning-rate schedule's progress).
    total_steps: u64,
}

impl Epochs<'_> {
    /// Trains on every batch of the loader, closing each epoch at its end of pass.
    fn run(
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
        writeln!(self.csv, "{}", rec.csv())?;
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

/// The stages of a training step, in order (`vtpose bench` times each).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepStage {
    /// The prepared samples to tensors on the device.
    Inputs,
    Forward,
    Loss,
    Backward,
    /// The optimizer's update of the weights.
    Optimizer,
}

impl StepStage {
    pub const ALL: [StepStage; 5] = [StepStage::Inputs, StepStage::Forward, StepStage::Loss, StepStage::Backward, StepStage::Optimizer];

    pub fn name(self) -> &'static str {
        match self {
            StepStage::Inputs => "inputs",
            StepStage::Forward => "forward",
            StepStage::Loss => "loss",
            StepStage::Backward => "backward",
            StepStage::Optimizer => "optimizer",
        }
    }
}

/// What a training step reports.
#[derive(Debug, Clone, Copy)]
pub struct StepDone {
    /// The batch's loss (eq. 2–3, the mean over its samples).
    pub loss: f64,
    /// Mean over the batch of the distance `L_i` of each sample's most confident estimate, m.
    pub best_distance_m: f64,
}

/// The number of threads a training step splits its batch over: `train.step_threads`, or with 0
/// the machine's cores on burn's CPU backends and 1 on a GPU (one device queue gains nothing from
/// more threads).
pub fn step_threads(train: &OptimConfig, device: &Device) -> usize {
    crate::device::batch_threads(train.step_threads, device)
}

/// One optimizer step of `model` on `batch`. With `threads` > 1 the batch is split into that many
/// shards (at most one per sample), each shard's forward and backward pass runs on its own thread
/// on its own autodiff copy of the weights, and the shards' gradients, each weighted by its share
/// of the batch, are summed before the optimizer's update: the gradient of the batch's mean loss, as one
/// pass computes it, up to float summation order. This is what puts a CPU's cores to work: burn's
/// CPU kernels parallelise only large tensors, and most of this network's are small. (A network
/// with batch norm, the `resnet_psp` encoder, would see per-shard batch statistics: its steps
/// run in one pass.) `lap` is called at the end of each stage of a one-pass step only: a threaded
/// step's stages overlap.
#[allow(clippy::too_many_arguments)]
pub fn train_step(
    model: PoseNet,
    optim: &mut ModuleOptimizer,
    batch: &Batch,
    weights: LossWeights,
    lr: f64,
    threads: usize,
    device: &Device,
    lap: &mut dyn FnMut(StepStage),
) -> (PoseNet, StepDone) {
    let shards = if model.has_batch_norm() { 1 } else { threads.clamp(1, batch.len().max(1)) };
    if shards == 1 {
        let input = batch.inputs(device);
        let targets = batch.targets(device);
        lap(StepStage::Inputs);
        let out = model.forward(&input);
        lap(StepStage::Forward);
        let l = pose_loss(&out, &targets, weights);
        let loss: f64 = l.loss.clone().into_scalar::<f32>() as f64;
        let best_distance_m = best_distance(&out, &l.distance);
        lap(StepStage::Loss);
        let grads = GradientsParams::from_grads(l.loss.backward(), &model);
        lap(StepStage::Backward);
        let model = optim.step(lr, model, grads);
        lap(StepStage::Optimizer);
        return (model, StepDone { loss, best_distance_m });
    }
    let parts = batch.split(shards);
    let total = batch.len() as f64;
    let results: Vec<(GradientsParams, f64, f64)> = std::thread::scope(|scope| {
        let handles: Vec<_> = parts
            .iter()
            .map(|part| {
                // Fresh autodiff leaves with the same parameter ids: each shard's graph is its own.
                let copy = model.valid().train();
                scope.spawn(move || {
                    let share = part.len() as f64 / total;
                    let out = copy.forward(&part.inputs(device));
                    let l = pose_loss(&out, &part.targets(device), weights);
                    let loss = l.loss.clone().into_scalar::<f32>() as f64;
                    let best = best_distance(&out, &l.distance);
                    let grads = GradientsParams::from_grads(l.loss.mul_scalar(share).backward(), &copy);
                    (grads, loss * share, best * share)
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().expect("a training shard panicked")).collect()
    });
    let mut accumulator = GradientsAccumulator::<PoseNet>::new();
    let (mut loss, mut best_distance_m) = (0.0, 0.0);
    for (grads, l, d) in results {
        accumulator.accumulate(&model, grads);
        loss += l;
        best_distance_m += d;
    }
    let model = optim.step(lr, model, accumulator.grads());
    (model, StepDone { loss, best_distance_m })
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

/// Per dataset object: trained with the closest-point loss (`train.symmetric_loss` lists its id).
pub fn closest_point_table(models: &[ObjectModel], ids: &[String]) -> Result<Vec<bool>> {
    for id in ids {
        if !models.iter().any(|m| &m.id == id) {
            bail!("train.symmetric_loss: '{id}' is not an object of the dataset");
        }
    }
    Ok(models.iter().map(|m| ids.contains(&m.id)).collect())
}

fn save_model(model: &PoseNet, path: &Path) -> Result<()> {
    model.clone().save_file(path).map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))
}

fn open_csv(path: &Path, fresh: bool) -> Result<std::fs::File> {
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(!fresh)
        .write(true)
        .truncate(fresh)
        .open(path)
        .with_context(|| format!("cannot write {}", path.display()))?;
    if fresh {
        writeln!(f, "{CSV_HEADER}")?;
    }
    Ok(f)
}

/// Mean over the batch of the distance `L_i` of each sample's most confident valid estimate.
pub fn best_distance(out: &crate::model::PoseOutput, distance: &Tensor<2>) -> f64 {
    let [b, e] = distance.dims();
    let conf: Vec<f32> =
        (out.confidence.clone().detach() * out.valid.clone() + (out.valid.clone() - 1.0)).into_data().iter::<f32>().collect();
    let dist: Vec<f32> = distance.clone().into_data().iter::<f32>().collect();
    (0..b)
        .map(|s| {
            let row = &conf[s * e..(s + 1) * e];
            let i = (0..e).max_by(|&a, &c| row[a].total_cmp(&row[c])).unwrap_or(0);
            dist[s * e + i] as f64
        })
        .sum::<f64>()
        / b.max(1) as f64
}

/// Augmentation off: what evaluation and benchmarks use.
pub fn no_augmentation() -> AugmentConfig {
    AugmentConfig::NONE
}

#[cfg(test)]
mod tests {
    use burn::optim::SgdConfig;

    use super::*;
    use crate::bench::{synthetic_batch, synthetic_input};
    use crate::config::{DataConfig, ModelConfig};
    use crate::device::cpu;

    fn values<const D: usize>(t: Tensor<D>) -> Vec<f32> {
        t.into_data().iter::<f32>().collect()
    }

    #[test]
    fn a_step_split_over_threads_takes_the_gradient_of_the_whole_batch() {
        let data = DataConfig { n_points: 32, n_tactile: 8, n_model_points: 16, crop_size: 16, ..Default::default() };
        let device = cpu().autodiff();
        device.seed(3);
        let model = ModelConfig::default().net(1).init(&device);
        // Five samples: shards of 3 and 2, so the shares differ.
        let batch = synthetic_batch(&data, 5, data.n_model_points);
        let probe = synthetic_input(&data, &cpu());
        let before = model.valid().forward(&probe);
        let mut outcomes = Vec::new();
        for threads in [1, 2] {
            // Plain SGD: the update is the gradient itself (Adam's first step is its sign only).
            let mut optim = SgdConfig::new().init();
            let (stepped, done) =
                train_step(model.clone(), &mut optim, &batch, LossWeights::paper(0.015), 1.0, threads, &device, &mut |_| {});
            outcomes.push((stepped.valid().forward(&probe), done));
        }
        let (one, split) = (&outcomes[0], &outcomes[1]);
        assert!((one.1.loss - split.1.loss).abs() < 1e-6 * one.1.loss.abs().max(1.0), "{} vs {}", one.1.loss, split.1.loss);
        assert!((one.1.best_distance_m - split.1.best_distance_m).abs() < 1e-6);
        let moved = |a: &Tensor<3>, b: &Tensor<3>| {
            values(a.clone()).iter().zip(values(b.clone())).map(|(x, y)| (x - y).abs()).fold(0.0f32, f32::max)
        };
        // The step changes the network, and both ways change it the same.
        let step = moved(&before.translation, &one.0.translation);
        assert!(step > 1e-4, "the step moved the translations by {step}");
        let differ = moved(&one.0.translation, &split.0.translation).max(moved(&one.0.rotation, &split.0.rotation));
        assert!(differ < 1e-3 * step, "one pass vs shards: {differ} (the step: {step})");
    }

    #[test]
    fn the_cosine_schedule_falls_from_lr_to_zero() {
        let mut t = OptimConfig { lr: 1e-3, ..Default::default() };
        assert_eq!(t.lr_at(50, 100), 1e-3);
        t.lr_schedule = crate::config::LrSchedule::Cosine;
        assert_eq!(t.lr_at(0, 100), 1e-3);
        assert!((t.lr_at(50, 100) - 5e-4).abs() < 1e-12);
        assert!(t.lr_at(100, 100).abs() < 1e-12 && t.lr_at(150, 100).abs() < 1e-12);
    }
}

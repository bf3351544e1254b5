//! Timing (`vtpose bench`).
//!
//! - Inference: milliseconds per frame of the network alone (one sample, forward pass and the
//!   choice of the most confident estimate read back to the host), on the current backend. Data
//!   loading and the segmentation the paper's pipeline adds are not timed (the paper: 10.1 ms
//!   network alone).
//! - Training (`--train`): training steps per second on a batch of `train.batch_size` (forward,
//!   loss, backward, Adam: [`train_step`]) with one thread and with the step's threads, the
//!   process's CPU share while stepping, and the per-stage time of a one-thread step.
//!
//! Inputs are synthetic with the config's shapes ([`crate::synthetic`]): the same tensors on every
//! call and device.

use std::time::Instant;

use burn::prelude::*;
use serde::Serialize;

use crate::config::TrainConfig;
use crate::data::DataConfig;
use crate::eval::metrics::MeanSe;
use crate::host::process_cpu_seconds;
use crate::model::{PoseNet, Variant};
use crate::synthetic;
use crate::train::{StepStage, adam, train_step};

/// One benchmarked network.
#[derive(Debug, Clone, Serialize)]
pub struct BenchRow {
    pub name: String,
    pub variant: Variant,
    pub params: usize,
    pub n_points: usize,
    pub n_tactile: usize,
    pub crop_size: usize,
    /// Per-frame latency over `iters` timed runs.
    pub ms_per_frame: MeanSe,
    pub iters: usize,
}

/// Times `model` (already on `device`, without autodiff) over `iters` runs after `warmup`.
pub fn bench_model(name: &str, model: &PoseNet, data: &DataConfig, device: &Device, iters: usize, warmup: usize) -> BenchRow {
    let input = synthetic::input(data, device);
    for _ in 0..warmup {
        let _ = model.forward(&input).best();
    }
    let mut ms = Vec::with_capacity(iters);
    for _ in 0..iters {
        let t = Instant::now();
        let best = model.forward(&input).best();
        std::hint::black_box(best);
        ms.push(t.elapsed().as_secs_f64() * 1e3);
    }
    BenchRow {
        name: name.to_string(),
        variant: model.variant(),
        params: model.num_params(),
        n_points: data.n_points,
        n_tactile: data.n_tactile,
        crop_size: data.crop_size,
        ms_per_frame: MeanSe::of(&ms),
        iters,
    }
}

/// A Markdown table of benchmark rows.
pub fn table(rows: &[BenchRow], device: &str) -> String {
    let mut s = format!(
        "Inference, network alone, batch 1, device `{device}`:\n\n| network | model | parameters | n | n_t | crop | ms / frame |\n|---|---|---|---|---|---|---|\n"
    );
    for r in rows {
        s += &format!(
            "| {} | {} | {} | {} | {} | {} | {:.2} |\n",
            r.name,
            r.variant.label(),
            r.params,
            r.n_points,
            r.n_tactile,
            r.crop_size,
            r.ms_per_frame
        );
    }
    s
}

/// One benchmarked training setup.
#[derive(Debug, Clone, Serialize)]
pub struct TrainBenchRow {
    pub name: String,
    pub variant: Variant,
    pub batch_size: usize,
    /// Threads the step splits its batch over.
    pub threads: usize,
    pub ms_per_step: MeanSe,
    pub steps_per_s: f64,
    /// Process CPU time over wall time while stepping (1.0: one core busy); `None` where the
    /// platform does not report it.
    pub cpu_share: Option<f64>,
    /// Per stage of a one-thread step (`StepStage` order; the device synchronised at each
    /// stage's end): milliseconds. Empty for a threaded step, whose shards overlap.
    pub stages_ms: Vec<(String, MeanSe)>,
    pub iters: usize,
}

/// Times training steps of `cfg`'s network (fresh weights, seeded by `train.seed`) on `device`
/// with `threads` threads per step: `iters` timed steps after `warmup`.
pub fn bench_training(name: &str, cfg: &TrainConfig, device: &Device, threads: usize, iters: usize, warmup: usize) -> TrainBenchRow {
    let device = device.clone().autodiff();
    device.seed(cfg.train.seed);
    let mut model = cfg.model.init(1, &device);
    let mut optim = adam();
    let batch = synthetic::batch(&cfg.data, cfg.train.batch_size, cfg.data.n_model_points);
    for _ in 0..warmup {
        model = train_step(model, &mut optim, &batch, cfg.train.loss_weights(), cfg.train.lr, threads, &device, &mut |_| {}).0;
    }
    let mut stage_ms: Vec<Vec<f64>> = vec![Vec::new(); StepStage::ALL.len()];
    let mut ms = Vec::with_capacity(iters);
    let cpu_start = process_cpu_seconds();
    let wall = Instant::now();
    for _ in 0..iters {
        let start = Instant::now();
        let mut last = start;
        let mut lap = |stage: StepStage| {
            if threads == 1 {
                let _ = device.sync();
                let now = Instant::now();
                let i = StepStage::ALL.iter().position(|s| *s == stage).expect("a stage");
                stage_ms[i].push((now - last).as_secs_f64() * 1e3);
                last = now;
            }
        };
        model = train_step(model, &mut optim, &batch, cfg.train.loss_weights(), cfg.train.lr, threads, &device, &mut lap).0;
        let _ = device.sync();
        ms.push(start.elapsed().as_secs_f64() * 1e3);
    }
    let wall = wall.elapsed().as_secs_f64();
    let cpu_share = cpu_start.zip(process_cpu_seconds()).map(|(a, b)| (b - a) / wall.max(1e-9));
    TrainBenchRow {
        name: name.to_string(),
        variant: cfg.model.variant,
        batch_size: cfg.train.batch_size,
        threads,
        steps_per_s: iters as f64 / wall.max(1e-9),
        ms_per_step: MeanSe::of(&ms),
        cpu_share,
        stages_ms: StepStage::ALL
            .iter()
            .zip(stage_ms)
            .filter(|(_, v)| !v.is_empty())
            .map(|(s, v)| (s.name().to_string(), MeanSe::of(&v)))
            .collect(),
        iters,
    }
}

/// A Markdown table of training benchmark rows, then each one-thread row's stages.
pub fn training_table(rows: &[TrainBenchRow], device: &str) -> String {
    let mut s = format!(
        "Training steps, device `{device}`:\n\n| network | model | batch | threads | ms / step | steps / s | CPU share |\n|---|---|---|---|---|---|---|\n"
    );
    for r in rows {
        let cpu = r.cpu_share.map_or("–".to_string(), |c| format!("{:.0} %", 100.0 * c));
        s += &format!(
            "| {} | {} | {} | {} | {:.1} | {:.2} | {cpu} |\n",
            r.name,
            r.variant.label(),
            r.batch_size,
            r.threads,
            r.ms_per_step,
            r.steps_per_s
        );
    }
    for r in rows.iter().filter(|r| !r.stages_ms.is_empty()) {
        let total: f64 = r.stages_ms.iter().map(|(_, m)| m.mean).sum();
        s += &format!("\nOne-thread step of {} by stage:\n\n| stage | ms | share |\n|---|---|---|\n", r.name);
        for (stage, m) in &r.stages_ms {
            s += &format!("| {stage} | {m:.1} | {:.0} % |\n", 100.0 * m.mean / total.max(1e-12));
        }
    }
    s
}

/// The refiner's time on real samples (`vtpose bench --refine DATASET`): per estimator, the time
/// per sample on one core, and the samples per second with one thread and with every core.
#[derive(Debug, Clone, Serialize)]
pub struct RefineBenchRow {
    pub estimator: String,
    pub samples: usize,
    /// One refinement on one core, mean over the samples (ms).
    pub ms_per_sample_one_core: f64,
    /// Wall time per sample of every estimator together, with one thread and with `threads`.
    pub wall_ms_per_sample_one_thread: f64,
    pub wall_ms_per_sample_all: f64,
    pub threads: usize,
}

/// Times the refiner on `samples` evenly spread test samples of `dataset`, with one thread and
/// with every core ([`crate::eval::refined::evaluate_refined`], without the touch control).
pub fn bench_refiner(
    dataset: &std::path::Path,
    samples: usize,
    config: crate::refine::RefineConfig,
) -> anyhow::Result<Vec<RefineBenchRow>> {
    use crate::eval::refined::{RefineCommand, evaluate_refined};
    let cmd = RefineCommand {
        dataset: dataset.to_path_buf(),
        split: "test".into(),
        max_samples: samples,
        runs: Vec::new(),
        config,
        touch_control: false,
        device: crate::device::cpu(),
        quiet: true,
    };
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?.install(|| evaluate_refined(&cmd))?;
    let all = evaluate_refined(&cmd)?;
    let per = |e: &crate::eval::refined::RefineEval| 1000.0 * e.wall_s / e.samples.max(1) as f64;
    Ok(one
        .estimators
        .iter()
        .map(|e| RefineBenchRow {
            estimator: e.label.clone(),
            samples: e.results.len(),
            ms_per_sample_one_core: e.ms_per_sample,
            wall_ms_per_sample_one_thread: per(&one),
            wall_ms_per_sample_all: per(&all),
            threads: all.threads,
        })
        .collect())
}

/// The Markdown table of [`bench_refiner`].
pub fn refine_table(rows: &[RefineBenchRow]) -> String {
    let mut s = String::from(
        "| estimator | samples | ms per sample, one core | all estimators: wall ms per sample, 1 thread | all estimators: wall ms per sample, all threads |\n|---|---|---|---|---|\n",
    );
    for r in rows {
        s += &format!(
            "| {} | {} | {:.1} | {:.1} | {:.1} ({} threads) |\n",
            r.estimator, r.samples, r.ms_per_sample_one_core, r.wall_ms_per_sample_one_thread, r.wall_ms_per_sample_all, r.threads
        );
    }
    s
}

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
//! Inputs are synthetic with the config's shapes: the same tensors on every call and device.

use std::time::Instant;

use burn::optim::AdamConfig;
use burn::prelude::*;
use burn::tensor::Int;
use glam::{DQuat, DVec3};
use serde::Serialize;

use crate::config::{DataConfig, TrainConfig};
use crate::data::{Batch, Prepared};
use crate::eval::metrics::MeanSe;
use crate::host::process_cpu_seconds;
use crate::model::{PoseInput, PoseNet, Variant};
use crate::train::{StepStage, train_step};

/// A fixed low-discrepancy sequence in [-0.5, 0.5).
fn wave(k: usize, salt: usize) -> f32 {
    ((k * 2654435761 + salt * 40503) % 1_000_003) as f32 / 1_000_003.0 - 0.5
}

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

/// A synthetic batch of one sample with the shapes of `data`: points around 0.7 m in front of
/// the camera, a pseudo-random normalised crop, spread pixels. Deterministic: the same tensors on
/// every call and device.
pub fn synthetic_input(data: &DataConfig, device: &Device) -> PoseInput {
    let (n, nt, s) = (data.n_points, data.n_tactile, data.crop_size);
    let around = |k: usize, salt: usize| {
        let v: Vec<f32> = (0..k * 3).map(|i| if i % 3 == 2 { 0.7 } else { 0.0 } + 0.1 * wave(i, salt)).collect();
        Tensor::<3>::from_data(TensorData::new(v, [1, k, 3]), device)
    };
    PoseInput {
        img: Tensor::from_data(TensorData::new((0..3 * s * s).map(|i| 2.0 * wave(i, 7)).collect::<Vec<f32>>(), [1, 3, s, s]), device),
        choose: Tensor::<2, Int>::from_data(
            TensorData::new((0..n).map(|i| ((i * 7919) % (s * s)) as i64).collect::<Vec<_>>(), [1, n]),
            device,
        ),
        cloud: around(n, 1),
        tactile: around(nt, 2),
        has_touch: Tensor::ones([1, 1], device),
        object: Tensor::<1, Int>::zeros([1], device),
    }
}

/// Times `model` (already on `device`, without autodiff) over `iters` runs after `warmup`.
pub fn bench_model(name: &str, model: &PoseNet, data: &DataConfig, device: &Device, iters: usize, warmup: usize) -> BenchRow {
    let input = synthetic_input(data, device);
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

/// A synthetic batch of `batch_size` prepared samples with the shapes of `data` and `m` model
/// points: points around 0.7 m in front of the camera, every sample touched, poses near identity.
pub fn synthetic_batch(data: &DataConfig, batch_size: usize, m: usize) -> Batch {
    let (n, nt, s) = (data.n_points, data.n_tactile, data.crop_size);
    let points = |k: usize, salt: usize, z: f32| -> Vec<f32> {
        (0..k * 3).map(|i| if i % 3 == 2 { z } else { 0.0 } + 0.1 * wave(i, salt)).collect()
    };
    let samples = (0..batch_size)
        .map(|b| Prepared {
            index: b as u64,
            object: 0,
            slot: 0,
            symmetric: false,
            occlusion: 0.5,
            trajectory: b as u32,
            instance: 0,
            cloud: points(n, 10 + b, 0.7),
            choose: (0..n).map(|i| (((i + b) * 7919) % (s * s)) as i64).collect(),
            img: (0..3 * s * s).map(|i| 2.0 * wave(i, 100 + b)).collect(),
            cloud_count: n,
            tactile: points(nt, 200 + b, 0.7),
            tactile_count: nt,
            model_points: points(m, 300 + b, 0.0),
            rotation: DQuat::from_rotation_y(0.1 * b as f64),
            translation: DVec3::new(0.0, 0.0, 0.7),
        })
        .collect();
    Batch { samples }
}

/// Times training steps of `cfg`'s network (fresh weights, seeded by `train.seed`) on `device`
/// with `threads` threads per step: `iters` timed steps after `warmup`.
pub fn bench_training(name: &str, cfg: &TrainConfig, device: &Device, threads: usize, iters: usize, warmup: usize) -> TrainBenchRow {
    let device = device.clone().autodiff();
    device.seed(cfg.train.seed);
    let mut model = cfg.model.net(1).init(&device);
    let mut optim = AdamConfig::new().with_epsilon(1e-8).init();
    let batch = synthetic_batch(&cfg.data, cfg.train.batch_size, cfg.data.n_model_points);
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

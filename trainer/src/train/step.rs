//! One optimizer step: forward, loss, backward and Adam on a batch, on one thread or split over
//! several ([`train_step`]); `vtpose bench --train` times the same function stage by stage.

use burn::optim::{AdamConfig, GradientsAccumulator, GradientsParams, ModuleOptimizer};
use burn::prelude::*;

use crate::data::Batch;
use crate::loss::{LossWeights, pose_loss};
use crate::model::{PoseNet, PoseOutput};
use crate::optim::OptimConfig;

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

/// The optimizer of a run: PyTorch's Adam, as the paper.
pub fn adam() -> ModuleOptimizer {
    AdamConfig::new().with_epsilon(1e-8).init()
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
        one_pass_step(model, optim, batch, weights, lr, device, lap)
    } else {
        sharded_step(model, optim, batch, weights, lr, shards, device)
    }
}

/// [`train_step`] in one pass, calling `lap` at the end of each stage.
fn one_pass_step(
    model: PoseNet,
    optim: &mut ModuleOptimizer,
    batch: &Batch,
    weights: LossWeights,
    lr: f64,
    device: &Device,
    lap: &mut dyn FnMut(StepStage),
) -> (PoseNet, StepDone) {
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
    (model, StepDone { loss, best_distance_m })
}

/// [`train_step`] with the batch split into `shards`, one thread each, the gradients weighted by
/// each shard's share of the batch and summed.
fn sharded_step(
    model: PoseNet,
    optim: &mut ModuleOptimizer,
    batch: &Batch,
    weights: LossWeights,
    lr: f64,
    shards: usize,
    device: &Device,
) -> (PoseNet, StepDone) {
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

/// Mean over the batch of the distance `L_i` of each sample's most confident valid estimate.
pub fn best_distance(out: &PoseOutput, distance: &Tensor<2>) -> f64 {
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

#[cfg(test)]
mod tests {
    use burn::optim::SgdConfig;

    use super::*;
    use crate::data::DataConfig;
    use crate::device::cpu;
    use crate::model::ModelConfig;
    use crate::synthetic;

    fn values<const D: usize>(t: Tensor<D>) -> Vec<f32> {
        t.into_data().iter::<f32>().collect()
    }

    #[test]
    fn a_step_split_over_threads_takes_the_gradient_of_the_whole_batch() {
        let data = DataConfig { n_points: 32, n_tactile: 8, n_model_points: 16, crop_size: 16, ..Default::default() };
        let device = cpu().autodiff();
        device.seed(3);
        let model = ModelConfig::default().init(1, &device);
        // Five samples: shards of 3 and 2, so the shares differ.
        let batch = synthetic::batch(&data, 5, data.n_model_points);
        let probe = synthetic::input(&data, &cpu());
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
}

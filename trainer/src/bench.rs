//! Inference timing (`vtpose bench`): milliseconds per frame of the network alone (one sample,
//! forward pass and the choice of the most confident estimate read back to the host), on the
//! current backend. Inputs are synthetic with the config's shapes: data loading and the
//! segmentation the paper's pipeline adds are not timed (the paper: 10.1 ms network alone).

use std::time::Instant;

use burn::prelude::*;
use burn::tensor::Int;
use serde::Serialize;

use crate::config::DataConfig;
use crate::eval::metrics::MeanSe;
use crate::model::{PoseInput, PoseNet, Variant};

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
    // A fixed low-discrepancy sequence in [-0.5, 0.5).
    let wave = |k: usize, salt: usize| ((k * 2654435761 + salt * 40503) % 1_000_003) as f32 / 1_000_003.0 - 0.5;
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

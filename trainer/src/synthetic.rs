//! Synthetic inputs with a config's shapes: what `vtpose bench` times, and the fixture the tests
//! share (a step, a loss, a resumed run compared on one probe input). Deterministic: the same
//! values on every call and device, with no dataset to read.
//!
//! Not test-only: the benchmark feeds the network these in a release build.

use burn::prelude::*;
use burn::tensor::Int;
use glam::{DQuat, DVec3};

use crate::data::{Batch, DataConfig, Prepared};
use crate::model::PoseInput;

/// A fixed low-discrepancy sequence in [-0.5, 0.5).
fn wave(k: usize, salt: usize) -> f32 {
    ((k * 2654435761 + salt * 40503) % 1_000_003) as f32 / 1_000_003.0 - 0.5
}

/// Network inputs of one sample with the shapes of `data`: points around 0.7 m in front of the
/// camera, a pseudo-random normalised crop, spread pixels.
pub fn input(data: &DataConfig, device: &Device) -> PoseInput {
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

/// A batch of `batch_size` prepared samples with the shapes of `data` and `m` model points: points
/// around 0.7 m in front of the camera, every sample touched, poses near identity.
pub fn batch(data: &DataConfig, batch_size: usize, m: usize) -> Batch {
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
            time_s: f64::NAN,
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

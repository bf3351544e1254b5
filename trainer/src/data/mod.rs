//! The data pipeline: vtgen shards (via `vt-dataset`) to fixed-size network inputs, on a
//! background thread.
//!
//! Per sample it follows the recipe of the Python `vtdata.DenseFusionView` (`datasets/python/
//! vtdata/densefusion.py`), the same steps, sizes and normalisation, so both sides of the project
//! feed a network the same kind of input:
//!
//! - `cloud`: `n` random pixels of the object's mask (the sample's `mask_id`, 1) with depth > 0,
//!   back-projected to camera-frame points (OpenCV pinhole); without replacement when the mask has
//!   `n` such pixels, else every pixel once and the rest drawn with replacement;
//! - `img`: the RGB crop by the mask's bounding box, resized bilinearly (half-pixel centres) to
//!   `S × S`, scaled to [0, 1] and normalised with the ImageNet mean and standard deviation;
//!   `choose`: each point's pixel in the resized crop (`row · S + col`, the resized pixel whose area
//!   holds the original pixel's centre);
//! - `tactile`: `n_t` points of the sample's tactile point cloud, resampled like `cloud`; zeros
//!   and `tactile_count = 0` when the sample has none;
//! - `model_points`: `M` points spread uniformly over the model's surface (area-weighted triangles,
//!   from `models/<id>.ply`), object frame; the loss moves them by the true and estimated poses.
//!
//! The depth points, tactile points, model points and augmentation draw from independent ChaCha8
//! streams seeded by (seed, epoch, split, sample index) only: the same inputs whatever the order
//! of access. The Python view draws from numpy's generators instead: for one sample the two sides
//! give arrays of the same kind, not the same arrays. Training adds seeded augmentation
//! ([`AugmentConfig`]).
//!
//! The config sections this module reads (`data:`, `augment:`, `objects:`) live here too
//! ([`DataConfig`], [`AugmentConfig`], [`ObjectSelection`]).
//!
//! A [`SplitSource`] reads one split; with `cache` it keeps each decoded [`ObjectView`] (the crop,
//! the object's pixels and points, the touch and the pose: tens of KB instead of 640×480 images).
//! A [`Loader`] prepares batches on its own thread and hands them over a bounded channel.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;

use anyhow::{Context, Result, anyhow, bail};
use burn::prelude::*;
use burn::tensor::Int;
use glam::{DQuat, DVec3};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use vt_dataset::{DatasetReader, ModelsInfo, ShardReader};

use crate::geometry::matrix_rows;
use crate::model::PoseInput;

/// Per-channel mean and standard deviation of the crop normalisation (ImageNet, as torchvision's
/// models and the Python view with `normalize=True`).
pub const IMAGENET_MEAN: [f32; 3] = [0.485, 0.456, 0.406];
pub const IMAGENET_STD: [f32; 3] = [0.229, 0.224, 0.225];
/// Model points per object for the metrics (ADD, ADD-S): fixed, seeded by the object.
pub const EVAL_MODEL_POINTS: usize = 2000;

mod batch;
mod config;
mod loader;
mod models;
mod sampling;
mod source;
mod view;

pub use batch::*;
pub use config::*;
pub use loader::*;
pub use models::*;
pub use sampling::*;
pub use source::*;
pub use view::*;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draw_covers_every_index_when_short() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let v = draw(&mut rng, 5, 12);
        assert_eq!(v.len(), 12);
        for i in 0..5 {
            assert!(v.contains(&i));
        }
        let v = draw(&mut rng, 100, 10);
        let mut u = v.clone();
        u.sort();
        u.dedup();
        assert_eq!(u.len(), 10, "no repeats when there are enough");
    }

    #[test]
    fn resize_and_cells_follow_the_python_view() {
        // A 2×2 image upsampled to 4×4: corners keep their values, the half-pixel rule blends.
        let src = [0u8, 0, 0, 100, 100, 100, 200, 200, 200, 255, 255, 255];
        let out = resize_bilinear(&src, 2, 2, 4);
        assert_eq!(out[0], 0.0);
        assert_eq!(out[(3 * 4 + 3) * 3], 255.0);
        // Output column 1 samples x = 0.25: 0.75 * 0 + 0.25 * 100 on row 0.
        assert!((out[3] - 25.0).abs() < 1e-4);
        // Identity size: unchanged.
        assert_eq!(resize_bilinear(&src, 2, 2, 2), src.iter().map(|&v| v as f32).collect::<Vec<_>>());
        // Pixel centres: 3 pixels onto 6 cells -> cells 1, 3, 5; 6 onto 3 -> 0,0,1,1,2,2.
        assert_eq!((0..3).map(|i| resized_cell(i, 3, 6)).collect::<Vec<_>>(), [1, 3, 5]);
        assert_eq!((0..6).map(|i| resized_cell(i, 6, 3)).collect::<Vec<_>>(), [0, 0, 1, 1, 2, 2]);
    }

    #[test]
    fn surface_samples_lie_on_the_mesh() {
        // The unit square z = 0 as two triangles.
        let m = ObjectModel::from_mesh(
            "sq",
            0,
            "none",
            1.4,
            &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
            &[[0, 1, 2], [0, 2, 3]],
        );
        let pts = m.sample_surface(2000, &mut ChaCha8Rng::seed_from_u64(3));
        assert!(pts.iter().all(|p| (0.0..=1.0).contains(&p[0]) && (0.0..=1.0).contains(&p[1]) && p[2] == 0.0));
        let mean_x = pts.iter().map(|p| p[0] as f64).sum::<f64>() / 2000.0;
        assert!((mean_x - 0.5).abs() < 0.03, "uniform over the square: mean x {mean_x}");
        assert_eq!(m.eval_points.len(), EVAL_MODEL_POINTS);
    }
}

//! The data pipeline: vtgen shards (via `vt-dataset`) to fixed-size network inputs, on a
//! background thread.
//!
//! Per sample it does what the Python `vtdata.DenseFusionView` does (`datasets/python/vtdata/
//! densefusion.py`), so both sides of the project feed a network the same thing:
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
//! of access. Training adds seeded augmentation ([`AugmentConfig`]).
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

use crate::config::{AugmentConfig, DataConfig, DepthSource, ObjectSelection};
use crate::geometry::matrix_rows;
use crate::model::PoseInput;

/// Per-channel mean and standard deviation of the crop normalisation (ImageNet, as torchvision's
/// models and the Python view with `normalize=True`).
pub const IMAGENET_MEAN: [f32; 3] = [0.485, 0.456, 0.406];
pub const IMAGENET_STD: [f32; 3] = [0.229, 0.224, 0.225];
/// Model points per object for the metrics (ADD, ADD-S): fixed, seeded by the object.
pub const EVAL_MODEL_POINTS: usize = 2000;
/// The mask id of the target object when `/sample/info` does not say (FORMAT.md).
const TARGET_MASK_ID: u8 = 1;

// --------------------------------------------------------------------------------------------
// Object models
// --------------------------------------------------------------------------------------------

/// One object of `models/`: its mesh, symmetry and fixed metric points.
#[derive(Debug, Clone)]
pub struct ObjectModel {
    pub id: String,
    /// The object's `object_index` in the dataset.
    pub dataset_index: usize,
    /// `none`, `continuous_z` or `discrete` (models_info.json).
    pub symmetry: String,
    /// The symmetries the "angle up to symmetry" forgives (mesh-verified when the dataset has them).
    pub symmetries: crate::metrics::Symmetries,
    /// Largest vertex distance, metres.
    pub diameter: f64,
    vertices: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    /// Cumulative triangle areas, normalised to end at 1 (empty: sample vertices instead).
    cdf: Vec<f64>,
    /// `EVAL_MODEL_POINTS` surface points (object frame) the metrics use.
    pub eval_points: Vec<[f32; 3]>,
}

impl ObjectModel {
    pub fn from_mesh(
        id: &str,
        dataset_index: usize,
        symmetry: &str,
        diameter: f64,
        positions: &[[f32; 3]],
        triangles: &[[u32; 3]],
    ) -> Self {
        let vertices: Vec<DVec3> = positions.iter().map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)).collect();
        let mut cdf = Vec::with_capacity(triangles.len());
        let mut total = 0.0;
        for t in triangles {
            let [a, b, c] = t.map(|i| vertices[i as usize]);
            total += 0.5 * (b - a).cross(c - a).length();
            cdf.push(total);
        }
        if total > 0.0 {
            cdf.iter_mut().for_each(|x| *x /= total);
        } else {
            cdf.clear();
        }
        let mut m = ObjectModel {
            id: id.to_string(),
            dataset_index,
            symmetry: symmetry.to_string(),
            symmetries: crate::metrics::Symmetries::of_kind(symmetry),
            diameter,
            vertices,
            triangles: triangles.to_vec(),
            cdf,
            eval_points: Vec::new(),
        };
        let mut rng = ChaCha8Rng::seed_from_u64(0x5eed_0000 + dataset_index as u64);
        m.eval_points = m.sample_surface(EVAL_MODEL_POINTS, &mut rng);
        m
    }

    /// Symmetric objects use the closest-point loss and ADD-S.
    pub fn symmetric(&self) -> bool {
        self.symmetry != "none"
    }

    /// `n` points uniformly distributed over the surface (object frame), as the Python
    /// `sample_surface`: triangles chosen by area, points uniform inside them. A mesh without
    /// (non-degenerate) faces falls back to its vertices.
    pub fn sample_surface(&self, n: usize, rng: &mut impl Rng) -> Vec<[f32; 3]> {
        if self.cdf.is_empty() {
            return draw(rng, self.vertices.len(), n).into_iter().map(|i| self.vertices[i].as_vec3().to_array()).collect();
        }
        (0..n)
            .map(|_| {
                let u: f64 = rng.random();
                let k = self.cdf.partition_point(|&c| c < u).min(self.triangles.len() - 1);
                let [a, b, c] = self.triangles[k].map(|i| self.vertices[i as usize]);
                let (mut r1, mut r2): (f64, f64) = (rng.random(), rng.random());
                if r1 + r2 > 1.0 {
                    (r1, r2) = (1.0 - r1, 1.0 - r2);
                }
                (a + r1 * (b - a) + r2 * (c - a)).as_vec3().to_array()
            })
            .collect()
    }
}

/// Every object of a dataset's `models/`, by `object_index`.
pub fn load_models(root: &Path) -> Result<Vec<ObjectModel>> {
    let dir = root.join("models");
    let path = dir.join("models_info.json");
    let text = std::fs::read_to_string(&path).with_context(|| format!("cannot read {}", path.display()))?;
    let info: ModelsInfo = serde_json::from_str(&text).with_context(|| format!("{} is not a valid models_info.json", path.display()))?;
    let mut models: Vec<ObjectModel> = info
        .objects
        .iter()
        .map(|o| {
            let mesh = vt_dataset::read_ply(&dir.join(&o.file))?;
            let mut m = ObjectModel::from_mesh(&o.id, o.object_index as usize, &o.symmetry, o.diameter, &mesh.positions, &mesh.triangles);
            m.symmetries = crate::metrics::Symmetries::from_models_info(&o.symmetry, &o.symmetries_discrete, &o.symmetries_continuous);
            Ok(m)
        })
        .collect::<Result<_>>()?;
    models.sort_by_key(|m| m.dataset_index);
    if models.iter().enumerate().any(|(i, m)| m.dataset_index != i) {
        bail!("{}: object_index values are not 0..{}", path.display(), models.len());
    }
    Ok(models)
}

/// The objects a run trains on, in head-slot order (slot `k` = `objects[k]`).
pub fn select_objects(models: &[ObjectModel], selection: &ObjectSelection) -> Result<Vec<String>> {
    match selection {
        ObjectSelection::All => Ok(models.iter().map(|m| m.id.clone()).collect()),
        ObjectSelection::List(ids) => {
            for id in ids {
                if !models.iter().any(|m| &m.id == id) {
                    bail!(
                        "objects: '{id}' is not in the dataset (it has: {})",
                        models.iter().map(|m| m.id.as_str()).collect::<Vec<_>>().join(", ")
                    );
                }
            }
            Ok(ids.clone())
        }
    }
}

// --------------------------------------------------------------------------------------------
// Sampling helpers (mirroring densefusion.py)
// --------------------------------------------------------------------------------------------

/// `n` indices into `0..count` (`count >= 1`) in random order: no repeats when `count >= n`,
/// else every index once and the other `n - count` drawn with replacement.
pub fn draw(rng: &mut impl Rng, count: usize, n: usize) -> Vec<usize> {
    assert!(count >= 1, "draw from an empty set");
    if count >= n {
        // Partial Fisher-Yates: the first n of a random permutation.
        let mut all: Vec<usize> = (0..count).collect();
        for i in 0..n {
            let j = rng.random_range(i..count);
            all.swap(i, j);
        }
        all.truncate(n);
        all
    } else {
        let mut v: Vec<usize> = (0..count).chain((0..n - count).map(|_| rng.random_range(0..count))).collect();
        v.shuffle(rng);
        v
    }
}

/// Resizes `h × w × 3` bytes to `size × size × 3` floats (0..255), bilinear with half-pixel
/// centres: output pixel `r` samples the input at `(r + 0.5) · h / size − 0.5`, clamped (the
/// convention of torch's `interpolate(align_corners=False)` and of the Python view).
pub fn resize_bilinear(src: &[u8], h: usize, w: usize, size: usize) -> Vec<f32> {
    let axis = |n_in: usize| -> Vec<(usize, usize, f32)> {
        (0..size)
            .map(|r| {
                let x = ((r as f64 + 0.5) * n_in as f64 / size as f64 - 0.5).clamp(0.0, (n_in - 1) as f64);
                let i0 = x.floor() as usize;
                (i0, (i0 + 1).min(n_in - 1), (x - i0 as f64) as f32)
            })
            .collect()
    };
    let (ys, xs) = (axis(h), axis(w));
    let px = |r: usize, c: usize, k: usize| src[(r * w + c) * 3 + k] as f32;
    let mut out = vec![0.0; size * size * 3];
    for (r, &(y0, y1, wy)) in ys.iter().enumerate() {
        for (c, &(x0, x1, wx)) in xs.iter().enumerate() {
            for k in 0..3 {
                let top = px(y0, x0, k) * (1.0 - wx) + px(y0, x1, k) * wx;
                let bottom = px(y1, x0, k) * (1.0 - wx) + px(y1, x1, k) * wx;
                out[(r * size + c) * 3 + k] = top * (1.0 - wy) + bottom * wy;
            }
        }
    }
    out
}

/// The resized-crop cell holding the centre of crop pixel `i` along an axis of `n` pixels.
pub fn resized_cell(i: usize, n: usize, size: usize) -> usize {
    ((2 * i + 1) * size / (2 * n)).min(size - 1)
}

/// A small, deterministic mixing of integers into one seed (splitmix64 steps).
pub fn mix_seed(parts: &[u64]) -> u64 {
    let mut h: u64 = 0x243f_6a88_85a3_08d3;
    for &p in parts {
        h ^= p;
        h = h.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = h;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        h = z ^ (z >> 31);
    }
    h
}

/// A stable integer for a split name.
fn split_key(split: &str) -> u64 {
    split.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ b as u64).wrapping_mul(0x1000_0000_01b3))
}

// --------------------------------------------------------------------------------------------
// Decoded samples
// --------------------------------------------------------------------------------------------

/// What the pipeline keeps of a decoded sample: the object's crop, pixels, points, touch, pose.
#[derive(Debug, Clone)]
pub struct ObjectView {
    /// The sample's index in its split.
    pub index: u64,
    /// Its object's `object_index`.
    pub object: usize,
    /// Bounding box of the mask, `[row_min, row_max, col_min, col_max)`; zeros when not visible.
    pub bbox: [usize; 4],
    /// The RGB crop by `bbox`, row-major bytes.
    pub crop: Vec<u8>,
    /// Object pixels with depth, `(row, col)` in the full image, row-major order.
    pub pixels: Vec<(u32, u32)>,
    /// Their camera-frame points.
    pub points: Vec<[f32; 3]>,
    /// The tactile point cloud (camera frame); empty without touch.
    pub tactile: Vec<[f32; 3]>,
    pub rotation: DQuat,
    pub translation: DVec3,
    /// The paper's occlusion level (NaN when the dataset has none).
    pub occlusion: f32,
    /// The grasp (trajectory) and the arm pose (instance) of the sample, from `/sample/info`
    /// (`u32::MAX` when absent): samples of one trajectory share a grasp.
    pub trajectory: u32,
    pub instance: u32,
}

impl ObjectView {
    /// Extracts the view of a full sample.
    pub fn from_sample(s: &vt_dataset::Sample, object: usize, depth: DepthSource) -> Result<Self> {
        let (w, h) = (s.width as usize, s.height as usize);
        let mask_id = s.info.get("mask_id").and_then(|v| v.as_u64()).map_or(TARGET_MASK_ID, |v| v as u8);
        let depth_img = match depth {
            DepthSource::Exact => &s.depth,
            DepthSource::Noisy => s
                .depth_noisy
                .as_ref()
                .ok_or_else(|| anyhow!("sample {}: data.depth is `noisy` but the dataset has no /camera/depth_noisy", s.index))?,
        };
        let (fx, fy, cx, cy) = (s.fx(), s.fy(), s.cx(), s.cy());
        let (mut rmin, mut rmax, mut cmin, mut cmax) = (usize::MAX, 0, usize::MAX, 0);
        let mut pixels = Vec::new();
        let mut points = Vec::new();
        for r in 0..h {
            for c in 0..w {
                let i = r * w + c;
                if s.mask[i] != mask_id {
                    continue;
                }
                (rmin, rmax, cmin, cmax) = (rmin.min(r), rmax.max(r + 1), cmin.min(c), cmax.max(c + 1));
                let z = depth_img[i] as f64;
                if z > 0.0 {
                    pixels.push((r as u32, c as u32));
                    points.push([((c as f64 - cx) * z / fx) as f32, ((r as f64 - cy) * z / fy) as f32, z as f32]);
                }
            }
        }
        let (bbox, crop) = if pixels.is_empty() {
            ([0; 4], Vec::new())
        } else {
            let crop = (rmin..rmax).flat_map(|r| s.rgb[(r * w + cmin) * 3..(r * w + cmax) * 3].iter().copied()).collect();
            ([rmin, rmax, cmin, cmax], crop)
        };
        let tactile = s.tactile.as_ref().map(|t| t.points.iter().map(|p| p.position).collect()).unwrap_or_default();
        let occlusion = s.info.pointer("/occlusion/level").and_then(|v| v.as_f64()).map_or(f32::NAN, |v| v as f32);
        let id = |key: &str| s.info.get(key).and_then(|v| v.as_u64()).map_or(u32::MAX, |v| v as u32);
        Ok(ObjectView {
            index: s.index,
            object,
            bbox,
            crop,
            pixels,
            points,
            tactile,
            rotation: s.t_camera_object.rotation(),
            translation: s.t_camera_object.translation(),
            occlusion,
            trajectory: id("trajectory"),
            instance: id("instance"),
        })
    }

    pub fn visible(&self) -> bool {
        !self.pixels.is_empty()
    }
}

/// One sample as the network and the loss take it (fixed shapes).
#[derive(Debug, Clone)]
pub struct Prepared {
    pub index: u64,
    /// Dataset `object_index` and head slot.
    pub object: usize,
    pub slot: usize,
    /// Closest-point (ADD-S) loss for this sample.
    pub symmetric: bool,
    pub occlusion: f32,
    pub trajectory: u32,
    pub instance: u32,
    /// `(n, 3)` camera-frame points; zeros when `cloud_count == 0`.
    pub cloud: Vec<f32>,
    /// `(n,)` pixel of each point in the flattened `S × S` crop.
    pub choose: Vec<i64>,
    /// `(3, S, S)` normalised crop, channel-first.
    pub img: Vec<f32>,
    /// Object pixels with depth the points were drawn from (0: not visible).
    pub cloud_count: usize,
    /// `(n_t, 3)` tactile points; zeros when `tactile_count == 0`.
    pub tactile: Vec<f32>,
    pub tactile_count: usize,
    /// `(M, 3)` model points, object frame.
    pub model_points: Vec<f32>,
    /// Ground truth `T_camera_object` (translation noise included in training).
    pub rotation: DQuat,
    pub translation: DVec3,
}

/// What [`prepare`] needs besides the sample.
#[derive(Debug, Clone)]
pub struct PrepareOptions {
    pub data: DataConfig,
    pub augment: AugmentConfig,
    pub seed: u64,
    pub split: String,
    /// Head slot per dataset object index (`None`: not trained on).
    pub slots: Vec<Option<usize>>,
    /// Per dataset object index: trained with the closest-point loss (`train.symmetric_loss`).
    pub closest_point: Vec<bool>,
}

impl PrepareOptions {
    /// The random streams of sample `index` in `epoch` (0: depth points, 1: tactile, 2: model
    /// points, 3: augmentation).
    fn rng(&self, epoch: u64, index: u64, stream: u64) -> ChaCha8Rng {
        let mut rng = ChaCha8Rng::seed_from_u64(mix_seed(&[self.seed, epoch, split_key(&self.split), index]));
        rng.set_stream(stream);
        rng
    }
}

/// Maps a decoded sample to the network's inputs (see the module docs).
pub fn prepare(view: &ObjectView, model: &ObjectModel, opts: &PrepareOptions, epoch: u64) -> Prepared {
    let d = &opts.data;
    let epoch = if d.resample { epoch } else { 0 };
    let (n, s) = (d.n_points, d.crop_size);
    let mut rng_cloud = opts.rng(epoch, view.index, 0);
    let mut cloud = vec![0.0f32; n * 3];
    let mut choose = vec![0i64; n];
    let mut img = vec![0.0f32; 3 * s * s];
    if view.visible() {
        let [rmin, rmax, cmin, cmax] = view.bbox;
        let (h, w) = (rmax - rmin, cmax - cmin);
        for (k, i) in draw(&mut rng_cloud, view.pixels.len(), n).into_iter().enumerate() {
            cloud[k * 3..k * 3 + 3].copy_from_slice(&view.points[i]);
            let (r, c) = view.pixels[i];
            choose[k] = (resized_cell(r as usize - rmin, h, s) * s + resized_cell(c as usize - cmin, w, s)) as i64;
        }
        let mut crop = resize_bilinear(&view.crop, h, w, s);
        if opts.augment.color_jitter > 0.0 {
            color_jitter(&mut crop, opts.augment.color_jitter, &mut opts.rng(epoch, view.index, 3));
        }
        // HWC bytes-as-float -> CHW normalised.
        for p in 0..s * s {
            for k in 0..3 {
                img[k * s * s + p] = (crop[p * 3 + k] / 255.0 - IMAGENET_MEAN[k]) / IMAGENET_STD[k];
            }
        }
    }
    let nt = d.n_tactile;
    let mut tactile = vec![0.0f32; nt * 3];
    if !view.tactile.is_empty() {
        let mut rng = opts.rng(epoch, view.index, 1);
        for (k, i) in draw(&mut rng, view.tactile.len(), nt).into_iter().enumerate() {
            tactile[k * 3..k * 3 + 3].copy_from_slice(&view.tactile[i]);
        }
    }
    let model_points = model.sample_surface(d.n_model_points, &mut opts.rng(epoch, view.index, 2)).concat();
    let mut translation = view.translation;
    let noise = opts.augment.translation_noise_m;
    if noise > 0.0 {
        // One offset for the whole sample: the scene moved, the inputs and the truth alike.
        let mut rng = opts.rng(epoch, view.index, 4);
        let off: [f32; 3] = std::array::from_fn(|_| rng.random_range(-noise..=noise));
        translation += DVec3::from_array(off.map(f64::from));
        for (k, v) in cloud.iter_mut().enumerate().take(if view.visible() { n * 3 } else { 0 }) {
            *v += off[k % 3];
        }
        for (k, v) in tactile.iter_mut().enumerate().take(if view.tactile.is_empty() { 0 } else { nt * 3 }) {
            *v += off[k % 3];
        }
    }
    Prepared {
        index: view.index,
        object: view.object,
        slot: opts.slots[view.object].unwrap_or(0),
        symmetric: opts.closest_point.get(view.object).copied().unwrap_or(false),
        occlusion: view.occlusion,
        trajectory: view.trajectory,
        instance: view.instance,
        cloud,
        choose,
        img,
        cloud_count: view.pixels.len(),
        tactile,
        tactile_count: view.tactile.len(),
        model_points,
        rotation: view.rotation,
        translation,
    }
}

/// Brightness, contrast and saturation jitter in place (values 0..255, HWC), factors `1 ± j`.
fn color_jitter(img: &mut [f32], j: f32, rng: &mut impl Rng) {
    let mut factor = || rng.random_range(1.0 - j..=1.0 + j);
    let (brightness, contrast, saturation) = (factor(), factor(), factor());
    let mean = img.iter().sum::<f32>() / img.len() as f32;
    for px in img.chunks_exact_mut(3) {
        let grey = 0.299 * px[0] + 0.587 * px[1] + 0.114 * px[2];
        for v in px.iter_mut() {
            let sat = grey + (*v - grey) * saturation;
            *v = ((mean + (sat - mean) * contrast) * brightness).clamp(0.0, 255.0);
        }
    }
}

// --------------------------------------------------------------------------------------------
// Batches
// --------------------------------------------------------------------------------------------

/// Prepared samples of one batch, turned into tensors on demand.
#[derive(Debug, Clone, Default)]
pub struct Batch {
    pub samples: Vec<Prepared>,
}

/// The ground truth of a batch, as the loss takes it.
#[derive(Debug, Clone)]
pub struct Targets {
    /// `(B, M, 3)` model points, object frame.
    pub model_points: Tensor<3>,
    /// `(B, 3, 3)` true rotations.
    pub rotation: Tensor<3>,
    /// `(B, 3)` true translations.
    pub translation: Tensor<2>,
    /// Per sample: closest-point (symmetric) loss.
    pub symmetric: Vec<bool>,
    /// The same model points on the host, for the closest-point search.
    pub host_points: Vec<Vec<[f32; 3]>>,
    pub host_rotation: Vec<[f32; 9]>,
    pub host_translation: Vec<[f32; 3]>,
}

impl Batch {
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// The network inputs on `device`.
    pub fn inputs(&self, device: &Device) -> PoseInput {
        let b = self.samples.len();
        let first = &self.samples[0];
        let n = first.choose.len();
        let nt = first.tactile.len() / 3;
        let s = ((first.img.len() / 3) as f64).sqrt() as usize;
        let cat = |f: &dyn Fn(&Prepared) -> &[f32]| self.samples.iter().flat_map(|p| f(p).iter().copied()).collect::<Vec<f32>>();
        PoseInput {
            img: Tensor::from_data(TensorData::new(cat(&|p| &p.img), [b, 3, s, s]), device),
            choose: Tensor::from_data(
                TensorData::new(self.samples.iter().flat_map(|p| p.choose.iter().copied()).collect::<Vec<i64>>(), [b, n]),
                device,
            ),
            cloud: Tensor::from_data(TensorData::new(cat(&|p| &p.cloud), [b, n, 3]), device),
            tactile: Tensor::from_data(TensorData::new(cat(&|p| &p.tactile), [b, nt, 3]), device),
            has_touch: Tensor::from_data(
                TensorData::new(self.samples.iter().map(|p| f32::from(u8::from(p.tactile_count > 0))).collect::<Vec<f32>>(), [b, 1]),
                device,
            ),
            object: Tensor::<1, Int>::from_data(
                TensorData::new(self.samples.iter().map(|p| p.slot as i64).collect::<Vec<i64>>(), [b]),
                device,
            ),
        }
    }

    /// The loss targets on `device`.
    pub fn targets(&self, device: &Device) -> Targets {
        let b = self.samples.len();
        let m = self.samples[0].model_points.len() / 3;
        let host_rotation: Vec<[f32; 9]> = self.samples.iter().map(|p| matrix_rows(p.rotation)).collect();
        let host_translation: Vec<[f32; 3]> = self.samples.iter().map(|p| p.translation.as_vec3().to_array()).collect();
        Targets {
            model_points: Tensor::from_data(
                TensorData::new(self.samples.iter().flat_map(|p| p.model_points.iter().copied()).collect::<Vec<f32>>(), [b, m, 3]),
                device,
            ),
            rotation: Tensor::from_data(TensorData::new(host_rotation.concat(), [b, 3, 3]), device),
            translation: Tensor::from_data(TensorData::new(host_translation.concat(), [b, 3]), device),
            symmetric: self.samples.iter().map(|p| p.symmetric).collect(),
            host_points: self.samples.iter().map(|p| p.model_points.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()).collect(),
            host_rotation,
            host_translation,
        }
    }
}

// --------------------------------------------------------------------------------------------
// Reading a split
// --------------------------------------------------------------------------------------------

/// One split of a dataset, restricted to the selected objects, with an optional view cache.
pub struct SplitSource {
    pub root: PathBuf,
    pub split: String,
    shards: Vec<ShardReader>,
    /// Selected samples: (shard, split index, object index).
    entries: Vec<(usize, u64, usize)>,
    pub models: Arc<Vec<ObjectModel>>,
    depth: DepthSource,
    cache: Option<HashMap<usize, Arc<ObjectView>>>,
}

impl SplitSource {
    /// Opens `split` of the dataset at `root`, keeping the samples of `objects` (ids).
    pub fn open(root: &Path, split: &str, objects: &[String], depth: DepthSource, cache: bool) -> Result<Self> {
        let reader = DatasetReader::open(root)?;
        let models = load_models(root)?;
        let shards = reader.shards(split)?;
        let object_of = sample_objects(root, split, models.len())?;
        let wanted: Vec<bool> = models.iter().map(|m| objects.contains(&m.id)).collect();
        let mut entries = Vec::new();
        for (k, sh) in shards.iter().enumerate() {
            for i in sh.indices() {
                let o = object_of(i)?;
                if wanted[o] {
                    entries.push((k, i, o));
                }
            }
        }
        Ok(SplitSource {
            root: root.to_path_buf(),
            split: split.to_string(),
            shards,
            entries,
            models: Arc::new(models),
            depth,
            cache: cache.then(HashMap::new),
        })
    }

    /// Selected samples.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Keeps only the first `n` selected samples.
    pub fn truncate(&mut self, n: usize) {
        self.entries.truncate(n);
    }

    /// Keeps every `k`-th selected sample so that at most `n` remain (an even spread).
    pub fn spread(&mut self, n: usize) {
        if n > 0 && self.entries.len() > n {
            let len = self.entries.len();
            self.entries = (0..n).map(|i| self.entries[i * len / n]).collect();
        }
    }

    /// The decoded view of selected sample `i` (0-based among the selected).
    pub fn view(&mut self, i: usize) -> Result<Arc<ObjectView>> {
        if let Some(v) = self.cache.as_ref().and_then(|c| c.get(&i)) {
            return Ok(v.clone());
        }
        let (shard, index, object) = self.entries[i];
        let sample = self.shards[shard].read(index)?;
        let id = sample.sample_info()?.object_id;
        if id != self.models[object].id {
            bail!("{} sample {index}: object '{id}', expected '{}' from the dataset's config.json", self.split, self.models[object].id);
        }
        let view = Arc::new(ObjectView::from_sample(&sample, object, self.depth)?);
        if let Some(c) = self.cache.as_mut() {
            c.insert(i, view.clone());
        }
        Ok(view)
    }
}

/// The object of every split index, from the dataset's `config.json` (FORMAT.md: objects in
/// config order, trajectories ascending, instances ascending; trajectory `t` is a test trajectory
/// iff `t mod (train + test) >= train`), so no sample has to be decoded to be selected.
fn sample_objects(root: &Path, split: &str, num_objects: usize) -> Result<impl Fn(u64) -> Result<usize> + use<>> {
    let path = root.join("config.json");
    let text = std::fs::read_to_string(&path).with_context(|| format!("cannot read {}", path.display()))?;
    let cfg: serde_json::Value = serde_json::from_str(&text).with_context(|| format!("{} is not JSON", path.display()))?;
    let num = |p: &str| cfg.pointer(p).and_then(|v| v.as_u64()).ok_or_else(|| anyhow!("{}: no {p}", path.display()));
    let (trajectories, instances) = (num("/sampling/trajectories_per_object")?, num("/sampling/instances_per_trajectory")?);
    let (a, b) = (num("/sampling/split/train")?, num("/sampling/split/test")?);
    let in_split = (0..trajectories).filter(|t| (t % (a + b) >= a) == (split == "test")).count() as u64;
    let per_object = in_split * instances;
    let objects = cfg.pointer("/objects").and_then(|v| v.as_array()).map_or(0, |v| v.len());
    if objects != num_objects {
        bail!("{}: {objects} objects, but models/ has {num_objects}", path.display());
    }
    let split = split.to_string();
    Ok(move |index: u64| {
        let o = index.checked_div(per_object).unwrap_or(u64::MAX) as usize;
        if o >= num_objects {
            bail!("{split} sample {index} is beyond the dataset's {} samples", per_object * num_objects as u64);
        }
        Ok(o)
    })
}

// --------------------------------------------------------------------------------------------
// The background loader
// --------------------------------------------------------------------------------------------

/// One pass over (some of) a split: its epoch number (seeds the sampling) and the order.
#[derive(Debug, Clone)]
pub struct Pass {
    pub epoch: u64,
    pub order: Vec<usize>,
}

/// A message of the loader: a batch of `epoch`, or the pass's end with the samples it skipped
/// (not visible: no object pixel with depth).
#[derive(Debug)]
pub enum Loaded {
    Batch { epoch: u64, batch: Batch },
    EndOfPass { epoch: u64, skipped: Vec<u64> },
}

/// Prepares batches on a background thread, `prefetch` ahead, over a bounded channel.
pub struct Loader {
    rx: Option<Receiver<Result<Loaded>>>,
    handle: Option<JoinHandle<SplitSource>>,
}

impl Loader {
    /// Starts the thread; it owns `source` until [`Loader::finish`] hands it back.
    pub fn spawn(mut source: SplitSource, passes: Vec<Pass>, opts: PrepareOptions, batch_size: usize, prefetch: usize) -> Loader {
        let (tx, rx) = sync_channel::<Result<Loaded>>(prefetch.max(1));
        let handle = std::thread::Builder::new()
            .name(format!("vtpose-loader-{}", source.split))
            .spawn(move || {
                // A send fails only when the receiver is gone: stop quietly then.
                let _ = run_passes(&mut source, &passes, &opts, batch_size, &tx);
                source
            })
            .expect("cannot start the loader thread");
        Loader { rx: Some(rx), handle: Some(handle) }
    }

    /// The next message; `None` when every pass is done.
    pub fn recv(&self) -> Option<Result<Loaded>> {
        self.rx.as_ref()?.recv().ok()
    }

    /// Stops the thread (if still running) and returns the source with its cache.
    pub fn finish(mut self) -> SplitSource {
        self.rx = None;
        self.handle.take().expect("finish once").join().expect("the loader thread panicked")
    }
}

fn run_passes(
    source: &mut SplitSource,
    passes: &[Pass],
    opts: &PrepareOptions,
    batch_size: usize,
    tx: &SyncSender<Result<Loaded>>,
) -> Result<(), ()> {
    let models = source.models.clone();
    for pass in passes {
        let mut batch = Batch::default();
        let mut skipped = Vec::new();
        for &i in &pass.order {
            let view = match source.view(i) {
                Ok(v) => v,
                Err(e) => {
                    tx.send(Err(e)).map_err(|_| ())?;
                    return Err(());
                }
            };
            if !view.visible() {
                skipped.push(view.index);
                continue;
            }
            batch.samples.push(prepare(&view, &models[view.object], opts, pass.epoch));
            if batch.len() == batch_size {
                tx.send(Ok(Loaded::Batch { epoch: pass.epoch, batch: std::mem::take(&mut batch) })).map_err(|_| ())?;
            }
        }
        if !batch.is_empty() {
            tx.send(Ok(Loaded::Batch { epoch: pass.epoch, batch })).map_err(|_| ())?;
        }
        tx.send(Ok(Loaded::EndOfPass { epoch: pass.epoch, skipped })).map_err(|_| ())?;
    }
    Ok(())
}

/// A seeded shuffle of `0..n` for `epoch`.
pub fn shuffled(n: usize, seed: u64, epoch: u64) -> Vec<usize> {
    let mut order: Vec<usize> = (0..n).collect();
    order.shuffle(&mut ChaCha8Rng::seed_from_u64(mix_seed(&[seed, epoch, 0x5_4ff1e])));
    order
}

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

//! The training config (`vtpose train CONFIG`): one YAML file naming the dataset, the network, the
//! data pipeline and the optimisation. Unknown keys are errors, and every error names the field.
//!
//! ```yaml
//! dataset: ../out/tiny-hand          # relative to this file
//! objects: all                       # or a list of object ids: per-object or multi-object training
//! model:
//!   variant: tactile_channel         # tactile_channel | vision_only | non_siamese | no_global | tactile_only
//!   encoder: small                   # small | resnet_psp (DenseFusion's PSPNet on a dilated ResNet-18)
//!   resnet_width: 64                 # resnet_psp: first-stage width (64 = ResNet-18)
//!   cnn_channels: [16, 32]           # small: widths at full and half resolution
//!   color_dim: 32                    # per-pixel colour embedding
//!   point_dims: [32, 64]             # the two point-wise stages (depth, colour, tactile)
//!   global_dims: [128, 256]          # global feature MLP; the last is the global feature's width
//!   head_dims: [128, 64]             # hidden widths of the pose heads
//!   rotation: quaternion             # quaternion (the paper's) | rot6d (continuous 6D, Zhou et al. 2019)
//! data:
//!   n_points: 1000                   # depth points (and estimates per channel)
//!   n_tactile: 240                   # tactile points, 4 ..= 1000
//!   n_model_points: 500              # model points of the loss
//!   crop_size: 64                    # side of the resized RGB crop
//!   depth: exact                     # exact | noisy (/camera/depth_noisy when the dataset has it)
//!   resample: true                   # new random points every epoch (false: the same every epoch)
//! augment: {color_jitter: 0.2, translation_noise_m: 0.03}
//! train: {epochs: 20, batch_size: 16, lr: 0.0002, w: 0.015, seed: 0}   # lr_schedule: constant | cosine; rotation_loss: 0
//! # symmetric_loss: [005_tomato_soup_can]   # objects trained with the closest-point (ADD-S) loss; the paper: none
//! ```

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};

use crate::model::encoder::EncoderKind;
use crate::model::{PoseNetConfig, RotationKind, Variant};

/// Tactile point counts of the paper's sweep (Fig. "Effect of number of tactile points").
pub const TACTILE_SWEEP: [usize; 5] = [4, 12, 36, 60, 240];
/// Allowed tactile point counts (inclusive), as the Python `DenseFusionView`.
pub const N_TACTILE_RANGE: (usize, usize) = (4, 1000);

/// The whole config file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrainConfig {
    /// The dataset directory (a `vtgen generate` output); relative paths are relative to the
    /// config file. `vtpose train --dataset` overrides it.
    pub dataset: PathBuf,
    /// Which objects to train on: `all`, or a list of object ids. Each selected object gets its
    /// own output slot in the pose heads (DenseFusion's per-class heads).
    #[serde(default)]
    pub objects: ObjectSelection,
    #[serde(default)]
    pub model: ModelConfig,
    #[serde(default)]
    pub data: DataConfig,
    #[serde(default)]
    pub augment: AugmentConfig,
    #[serde(default)]
    pub train: OptimConfig,
}

/// `objects: all` or `objects: [id, ...]`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ObjectSelection {
    #[default]
    #[serde(with = "all_keyword")]
    All,
    List(Vec<String>),
}

/// Serde for the unit variant `All` as the string `all`.
mod all_keyword {
    use serde::{Deserialize, Deserializer, Serializer, de::Error};

    pub fn serialize<S: Serializer>(s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str("all")
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<(), D::Error> {
        let s = String::deserialize(d)?;
        if s == "all" { Ok(()) } else { Err(D::Error::custom(format!("expected `all` or a list of object ids, found `{s}`"))) }
    }
}

/// The network (see [`crate::model`]). Defaults are small enough to train on a CPU.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ModelConfig {
    pub variant: Variant,
    /// The colour encoder: `small` (tests, quick CPU runs) or `resnet_psp` (the paper's).
    pub encoder: EncoderKind,
    /// `resnet_psp`: the first stage's width (64 = ResNet-18; smaller for CPU runs).
    pub resnet_width: usize,
    /// `small`: widths at full and half resolution.
    pub cnn_channels: [usize; 2],
    pub color_dim: usize,
    pub point_dims: [usize; 2],
    pub global_dims: Vec<usize>,
    pub head_dims: Vec<usize>,
    /// How the rotation heads express a rotation: `quaternion` (the paper's) or `rot6d`.
    pub rotation: RotationKind,
}

impl Default for ModelConfig {
    fn default() -> Self {
        ModelConfig {
            variant: Variant::TactileChannel,
            encoder: EncoderKind::Small,
            resnet_width: 64,
            cnn_channels: [16, 32],
            color_dim: 32,
            point_dims: [32, 64],
            global_dims: vec![128, 256],
            head_dims: vec![128, 64],
            rotation: RotationKind::Quaternion,
        }
    }
}

impl ModelConfig {
    /// The burn config of the network, for `num_objects` output slots.
    pub fn net(&self, num_objects: usize) -> PoseNetConfig {
        PoseNetConfig::new(self.variant, num_objects)
            .with_encoder(self.encoder)
            .with_resnet_width(self.resnet_width)
            .with_cnn_channels(self.cnn_channels.to_vec())
            .with_color_dim(self.color_dim)
            .with_point_dims(self.point_dims.to_vec())
            .with_global_dims(self.global_dims.clone())
            .with_head_dims(self.head_dims.clone())
            .with_rotation(self.rotation)
    }
}

/// Which depth image the points come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DepthSource {
    /// `/camera/depth`, the exact z-depth (what the Python `DenseFusionView` uses).
    #[default]
    Exact,
    /// `/camera/depth_noisy`, the RGB-D sensor model, when the dataset has one (else an error).
    Noisy,
}

/// Per-sample inputs (mirrors `vtdata.DenseFusionView`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DataConfig {
    pub n_points: usize,
    pub n_tactile: usize,
    pub n_model_points: usize,
    pub crop_size: usize,
    pub depth: DepthSource,
    /// Draw new points (and augmentation) for every sample in every epoch; `false`: the same
    /// draw in every epoch (what the Python view does with a fixed seed), e.g. to overfit.
    pub resample: bool,
    /// Keep each sample's decoded object view in memory after its first read (a few tens of KB
    /// per sample instead of re-decoding 640×480 images every epoch).
    pub cache: bool,
    /// Batches the background loader may prepare ahead of the training loop.
    pub prefetch: usize,
}

impl Default for DataConfig {
    fn default() -> Self {
        DataConfig {
            n_points: 1000,
            n_tactile: 240,
            n_model_points: 500,
            crop_size: 64,
            depth: DepthSource::Exact,
            resample: true,
            cache: true,
            prefetch: 4,
        }
    }
}

/// Training-time augmentation (seeded; never applied in evaluation).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AugmentConfig {
    /// Brightness, contrast and saturation jitter of the crop: factors in `1 ± color_jitter`.
    pub color_jitter: f32,
    /// Uniform translation noise per axis (metres) added to the depth points, the tactile points
    /// and the ground-truth translation alike (DenseFusion's `noise_trans`).
    pub translation_noise_m: f32,
}

impl Default for AugmentConfig {
    fn default() -> Self {
        AugmentConfig { color_jitter: 0.2, translation_noise_m: 0.03 }
    }
}

impl AugmentConfig {
    pub const NONE: AugmentConfig = AugmentConfig { color_jitter: 0.0, translation_noise_m: 0.0 };
}

/// Optimisation (the paper: Adam, lr 2e-4, batch 16, w = 0.015).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OptimConfig {
    pub epochs: usize,
    pub batch_size: usize,
    pub lr: f64,
    /// The learning rate over the run: `constant` (the paper's) or `cosine` (from `lr` down to 0
    /// at the last step, half a cosine; a deviation from the paper, see docs/training.md).
    pub lr_schedule: LrSchedule,
    /// The confidence regulariser `w` of the loss.
    pub w: f64,
    /// Metres of distance per unit of chordal rotation error added to each estimate's model-point
    /// distance in the loss (0: the paper's loss; see `loss::pose_loss`).
    pub rotation_loss: f64,
    /// Seeds the weights, the sample order and every random choice of the data pipeline.
    pub seed: u64,
    /// Objects (ids) trained with the closest-point loss (DenseFusion's ADD-S variant): a pose
    /// that differs from the truth by a symmetry of the object's *shape* costs nothing. The paper
    /// trains every object with plain ADD (eq. 1): texture breaks the shape's symmetries, and its
    /// angle metric counts a symmetric twin as an error. List an object only when it really
    /// looks the same under its symmetry (models_info.json), e.g. an untextured can.
    pub symmetric_loss: Vec<String>,
    /// Keep a copy of the weights every this many epochs in `checkpoints/` (the last epoch
    /// always; `model.bpk` always holds the latest).
    pub checkpoint_every: usize,
    /// Evaluate on the test split every this many epochs (0: never during training).
    pub eval_every: usize,
    /// At most this many test samples in those evaluations (0: all).
    pub eval_samples: usize,
    /// Train on at most this many samples of the train split (0: all), e.g. to overfit a few.
    pub max_train_samples: usize,
    /// Threads a training step splits its batch over (data parallel, gradients summed):
    /// 0 = the machine's cores on the CPU backends, 1 on a GPU.
    pub step_threads: usize,
}

/// See [`OptimConfig::lr_schedule`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LrSchedule {
    #[default]
    Constant,
    Cosine,
}

impl OptimConfig {
    /// The loss's weights.
    pub fn loss_weights(&self) -> crate::loss::LossWeights {
        crate::loss::LossWeights { w: self.w, rotation: self.rotation_loss }
    }

    /// The learning rate of the step after `steps_done` of `total_steps`.
    pub fn lr_at(&self, steps_done: u64, total_steps: u64) -> f64 {
        match self.lr_schedule {
            LrSchedule::Constant => self.lr,
            LrSchedule::Cosine => {
                let progress = (steps_done as f64 / total_steps.max(1) as f64).clamp(0.0, 1.0);
                0.5 * self.lr * (1.0 + (std::f64::consts::PI * progress).cos())
            }
        }
    }
}

impl Default for OptimConfig {
    fn default() -> Self {
        OptimConfig {
            epochs: 20,
            batch_size: 16,
            lr: 2e-4,
            lr_schedule: LrSchedule::Constant,
            w: 0.015,
            rotation_loss: 0.0,
            seed: 0,
            symmetric_loss: Vec::new(),
            checkpoint_every: 10,
            eval_every: 5,
            eval_samples: 0,
            max_train_samples: 0,
            step_threads: 0,
        }
    }
}

impl TrainConfig {
    /// A config for `dataset` with every other value at its default.
    pub fn new(dataset: impl Into<PathBuf>) -> Self {
        TrainConfig {
            dataset: dataset.into(),
            objects: ObjectSelection::All,
            model: ModelConfig::default(),
            data: DataConfig::default(),
            augment: AugmentConfig::default(),
            train: OptimConfig::default(),
        }
    }

    /// Parses YAML; errors name the field (`train.batch_size: invalid type ...`).
    pub fn parse(text: &str, origin: &Path) -> Result<Self> {
        let de = serde_yaml::Deserializer::from_str(text);
        let cfg: TrainConfig = serde_path_to_error::deserialize(de).map_err(|e| {
            let path = e.path().to_string();
            let inner = e.into_inner();
            let at = inner.location().map(|l| format!(":{}:{}", l.line(), l.column())).unwrap_or_default();
            anyhow::anyhow!("{}{at}: {}: {inner}", origin.display(), if path == "." { "config".into() } else { path })
        })?;
        cfg.validate().with_context(|| format!("{}", origin.display()))?;
        Ok(cfg)
    }

    /// Reads a config file; a relative `dataset` is resolved against the file's directory.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("cannot read config {}", path.display()))?;
        let mut cfg = Self::parse(&text, path)?;
        if cfg.dataset.is_relative() {
            cfg.dataset = path.parent().unwrap_or(Path::new(".")).join(&cfg.dataset);
        }
        Ok(cfg)
    }

    pub fn save(&self, path: &Path) -> Result<()> {
        let text = serde_yaml::to_string(self)?;
        std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
    }

    /// Range checks the type system does not make.
    pub fn validate(&self) -> Result<()> {
        let d = &self.data;
        let (lo, hi) = N_TACTILE_RANGE;
        if !(lo..=hi).contains(&d.n_tactile) {
            bail!("data.n_tactile must be in {lo}..={hi}, got {}", d.n_tactile);
        }
        if d.n_points == 0 || d.n_model_points == 0 {
            bail!("data.n_points and data.n_model_points must be >= 1");
        }
        let multiple = self.model.encoder.crop_multiple();
        if d.crop_size < 4 || !d.crop_size.is_multiple_of(multiple) {
            bail!(
                "data.crop_size must be >= 4 and a multiple of {multiple} (the {:?} colour encoder's stride), got {}",
                self.model.encoder,
                d.crop_size
            );
        }
        let m = &self.model;
        if m.cnn_channels.contains(&0) || m.resnet_width == 0 || m.color_dim == 0 || m.point_dims.contains(&0) {
            bail!("model widths must be >= 1");
        }
        if m.global_dims.is_empty() || m.global_dims.contains(&0) || m.head_dims.contains(&0) {
            bail!("model.global_dims needs >= 1 width, and no width may be 0");
        }
        let t = &self.train;
        // (written so that NaN fails too)
        if t.batch_size == 0
            || t.epochs == 0
            || t.lr.is_nan()
            || t.lr <= 0.0
            || t.w.is_nan()
            || t.w < 0.0
            || t.rotation_loss.is_nan()
            || t.rotation_loss < 0.0
        {
            bail!("train.batch_size and train.epochs must be >= 1, train.lr > 0, train.w >= 0, train.rotation_loss >= 0");
        }
        if self.augment.color_jitter < 0.0 || self.augment.color_jitter >= 1.0 || self.augment.translation_noise_m < 0.0 {
            bail!("augment.color_jitter must be in [0, 1) and augment.translation_noise_m >= 0");
        }
        if let ObjectSelection::List(ids) = &self.objects
            && ids.is_empty()
        {
            bail!("objects: the list is empty (use `all`)");
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_defaults_and_names_bad_fields() {
        let c = TrainConfig::parse("dataset: d\n", Path::new("c.yaml")).unwrap();
        assert_eq!(c.objects, ObjectSelection::All);
        assert_eq!(c.train.batch_size, 16);
        assert_eq!(c.train.lr, 2e-4);
        let c = TrainConfig::parse("dataset: d\nobjects: [a, b]\nmodel: {variant: vision_only}\n", Path::new("c.yaml")).unwrap();
        assert_eq!(c.objects, ObjectSelection::List(vec!["a".into(), "b".into()]));
        assert_eq!(c.model.variant, Variant::VisionOnly);
        assert_eq!(TrainConfig::parse("dataset: d\nobjects: all\n", Path::new("c.yaml")).unwrap().objects, ObjectSelection::All);
        assert!(TrainConfig::parse("dataset: d\nobjects: some\n", Path::new("c.yaml")).is_err());
        assert!(serde_yaml::to_string(&TrainConfig::new("d")).unwrap().contains("objects: all"));
        let e = TrainConfig::parse("dataset: d\ntrain: {batch_size: x}\n", Path::new("c.yaml")).unwrap_err().to_string();
        assert!(e.contains("train.batch_size"), "{e}");
        let e = TrainConfig::parse("dataset: d\ntrain: {bogus: 1}\n", Path::new("c.yaml")).unwrap_err().to_string();
        assert!(e.contains("bogus"), "{e}");
        let e = TrainConfig::parse("dataset: d\ndata: {n_tactile: 2}\n", Path::new("c.yaml")).unwrap_err();
        assert!(format!("{e:#}").contains("n_tactile"), "{e:#}");
        // Round trip through YAML (the run directory keeps the config it was trained with).
        let text = serde_yaml::to_string(&c_full()).unwrap();
        assert_eq!(TrainConfig::parse(&text, Path::new("c.yaml")).unwrap(), c_full());
    }

    fn c_full() -> TrainConfig {
        let mut c = TrainConfig::new("x");
        c.objects = ObjectSelection::List(vec!["005_tomato_soup_can".into()]);
        c.model.variant = Variant::NonSiamese;
        c
    }
}

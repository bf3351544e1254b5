//! The training config (`vtpose train CONFIG`): one YAML file naming the dataset, the network, the
//! data pipeline and the optimisation. Unknown keys are errors, and every error names the field.
//!
//! Each section belongs to the module that reads it: `model:` is [`crate::model::ModelConfig`],
//! `objects:`, `data:` and `augment:` are [`crate::data`]'s, `train:` is
//! [`crate::optim::OptimConfig`]. This module only composes them into [`TrainConfig`], loads and
//! saves it, and checks what spans two sections (the crop size against the colour encoder); the
//! section types are re-exported here for code that builds a config.
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
use vt_check::{Check, Checks, field, key};

pub use crate::data::{AugmentConfig, DataConfig, DepthSource, ObjectSelection};
pub use crate::model::ModelConfig;
pub use crate::optim::{LrSchedule, OptimConfig};

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
        // Every problem on a line of its own, each with the line of its field.
        let problems: Vec<String> = vt_check::problems(&cfg)
            .iter()
            .map(|p| {
                let at = vt_check::locate::locate(text, &p.path).map(|(l, c)| format!(":{l}:{c}")).unwrap_or_default();
                format!("{}{at}: {p}", origin.display())
            })
            .collect();
        if !problems.is_empty() {
            bail!("{}", problems.join("\n"));
        }
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

    /// The config's problems as one error (each on a line of its own), for configs built in code.
    pub fn validate(&self) -> Result<()> {
        let problems = vt_check::problems(self);
        if !problems.is_empty() {
            bail!("{}", problems.iter().map(|p| p.to_string()).collect::<Vec<_>>().join("\n"));
        }
        Ok(())
    }
}

/// Range checks the type system does not make: each section's own, and the one that spans two
/// sections, the crop size against the colour encoder's stride.
impl Check for TrainConfig {
    fn check(&self, c: &mut Checks) {
        c.section(field!(self.objects));
        c.section(field!(self.model));
        c.section(field!(self.data));
        c.section(field!(self.augment));
        c.section(field!(self.train));
        let multiple = self.model.encoder.crop_multiple();
        let data = &self.data;
        if data.crop_size < 4 || !data.crop_size.is_multiple_of(multiple) {
            c.key(key!(self.data)).key(key!(data.crop_size)).fail(format!(
                "must be >= 4 and a multiple of {multiple} (the {:?} colour encoder's stride), got {}",
                self.model.encoder, data.crop_size
            ));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Variant;

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
        assert!(format!("{e:#}").starts_with("c.yaml:2:8: data.n_tactile: 2 is out of range"), "{e:#}");
        // Every bad field is named on a line of its own, with its line and column.
        let text = "dataset: d\ntrain:\n  epochs: 0\n  batch_size: 0\n  lr: .nan\n  w: -1\n  rotation_loss: -1\nmodel: {global_dims: [], head_dims: [0]}\naugment: {color_jitter: 1}\nobjects: []\n";
        let e = TrainConfig::parse(text, Path::new("c.yaml")).unwrap_err().to_string();
        let lines: Vec<&str> = e.lines().collect();
        for (want, line) in [
            ("objects", 10),
            ("model.head_dims[0]", 8),
            ("model.global_dims", 8),
            ("augment.color_jitter", 9),
            ("train.epochs", 3),
            ("train.batch_size", 4),
            ("train.lr", 5),
            ("train.w", 6),
            ("train.rotation_loss", 7),
        ] {
            assert!(lines.iter().any(|l| l.starts_with(&format!("c.yaml:{line}:")) && l.contains(&format!(": {want}: "))), "{want}: {e}");
        }
        assert_eq!(lines.len(), 9, "{e}");
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

    /// The configs users run (trainer/configs, the touch experiment's training files) load with
    /// the keys they are written with.
    #[test]
    fn the_shipped_training_configs_load() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("workspace root");
        let mut files: Vec<PathBuf> = Vec::new();
        for (dir, prefix) in [("trainer/configs", ""), ("experiments/touch", "train-")] {
            for entry in std::fs::read_dir(root.join(dir)).unwrap().flatten() {
                let name = entry.file_name().to_string_lossy().into_owned();
                if name.starts_with(prefix) && name.ends_with(".yaml") {
                    files.push(entry.path());
                }
            }
        }
        assert!(files.len() >= 5, "{files:?}");
        for f in files {
            TrainConfig::load(&f).unwrap_or_else(|e| panic!("{e:#}"));
        }
    }
}

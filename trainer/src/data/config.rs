//! The `data:`, `augment:` and `objects:` sections of a training config: what the pipeline draws
//! per sample, how training perturbs it, and which objects it reads.

use serde::{Deserialize, Serialize};
use vt_check::{Check, Checks, excl, field, incl, key};

/// Tactile point counts of the paper's sweep (Fig. "Effect of number of tactile points").
pub const TACTILE_SWEEP: [usize; 5] = [4, 12, 36, 60, 240];
/// Allowed tactile point counts (inclusive), as the Python `DenseFusionView`.
pub const N_TACTILE_RANGE: (usize, usize) = (4, 1000);

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

/// What serde cannot check: a list names at least one object.
impl Check for ObjectSelection {
    fn check(&self, c: &mut Checks) {
        if let ObjectSelection::List(ids) = self
            && ids.is_empty()
        {
            c.fail("the list is empty (use `all`)");
        }
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

/// Per-sample inputs (the sizes of `vtdata.DenseFusionView`).
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

/// The range checks the type system does not make. The crop size also has to suit the colour
/// encoder's stride, which the model section decides: [`crate::config::TrainConfig`] checks that.
impl Check for DataConfig {
    fn check(&self, c: &mut Checks) {
        let (lo, hi) = N_TACTILE_RANGE;
        c.range(field!(self.n_tactile), lo, hi);
        c.key(key!(self.n_points)).bounded(self.n_points as f64, incl(1.0), None, "points");
        c.key(key!(self.n_model_points)).bounded(self.n_model_points as f64, incl(1.0), None, "points");
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
    /// Augmentation off: what evaluation and benchmarks use.
    pub const NONE: AugmentConfig = AugmentConfig { color_jitter: 0.0, translation_noise_m: 0.0 };
}

impl Check for AugmentConfig {
    fn check(&self, c: &mut Checks) {
        c.key(key!(self.color_jitter)).bounded(self.color_jitter.into(), incl(0.0), excl(1.0), "");
        c.key(key!(self.translation_noise_m)).bounded(self.translation_noise_m.into(), incl(0.0), None, "metres");
    }
}

//! The pose networks: the paper's **Tactile-Channel** network, the vision-only **DenseFusion**
//! baseline (without refinement) and the paper's ablations, as one configurable [`PoseNet`].
//!
//! Per sample the inputs are `n` camera-frame depth points of the object, the RGB crop of the
//! object's bounding box with each point's pixel in it (`choose`), and `n_t` tactile points
//! (see [`crate::data`]). The network fuses them in two channels:
//!
//! - **visual channel**: a colour encoder ([`encoder`]: DenseFusion's PSPNet on a dilated
//!   ResNet-18, or a small CNN for tests) maps the crop to a per-pixel colour embedding, gathered at
//!   the points' pixels; colour and depth points each go through a two-stage point-wise MLP, and the
//!   stages are concatenated per point (DenseFusion's pixel-wise dense fusion);
//! - **tactile channel**: the tactile points go through their own two-stage point-wise MLP and are
//!   fused point-wise with the depth embedding. The channel has one entry per depth point, like the
//!   visual one (the paper: "each output 1000 pose estimates"): entry `i` pairs depth point `i`
//!   with tactile point `i mod n_t`, so any `n_t` (4 … 1000) feeds the same network;
//! - **global feature**: the second-stage colour, depth and tactile embeddings of each point go
//!   through an MLP and are averaged over the points, then appended to every point's features.
//!
//! The pose estimator (§III-B) predicts, per point of each channel, a rotation (unit quaternion, (w, x, y,
//! z)), a translation (an offset from the point's anchor: the depth point in the visual channel,
//! the tactile point in the tactile channel) and a confidence. The rotation head is **Siamese**:
//! one set of weights for both channels. Every head has one output slot per object (DenseFusion's
//! per-class heads) and the sample's object picks its slot. `2 × n` estimates come out; the most
//! confident is the network's answer ([`PoseOutput::best`]). As in the paper, the rotation and
//! confidence heads of a channel see that channel's point features and the global feature, while
//! both channels' **translation heads see the RGB-depth and the tactile-depth features** and the
//! global feature: a visual estimate of the position can use where the fingers touch the object.
//!
//! Variants ([`Variant`]): `vision_only` drops the tactile channel (DenseFusion without refinement);
//! `non_siamese` gives the tactile channel its own rotation head; `no_global` drops the global
//! feature; `tactile_only` drops the colour input and the visual channel (depth + touch remain).
//!
//! The widths are configurable ([`ModelConfig`]); the defaults are small enough for a CPU.

pub mod encoder;

use std::str::FromStr;
use vt_check::{Check, Checks, incl, key};

use burn::nn::{Linear, LinearConfig};
use burn::prelude::*;
use burn::tensor::Int;
use burn::tensor::activation::{relu, sigmoid};
use burn::tensor::module::linear;
use serde::{Deserialize, Serialize};

use crate::geometry::{normalize_quat, quat_to_matrix, rot6d_to_matrix, rows_to_wxyz};
use encoder::{ColorEncoder, ColorEncoderConfig, EncoderKind};

/// Point coordinates enter the network in decimetres (relative to the depth cloud's centroid)
/// and the translation heads answer in decimetres: object-sized inputs and outputs of order 1,
/// which the default initialisation and Adam's step size suit (metres train several times slower).
pub const POINT_SCALE: f32 = 10.0;

/// How the rotation heads express a rotation. The network's estimates are rotation matrices
/// either way ([`PoseOutput::rotation`]); the loss and the metrics do not change.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RotationKind {
    /// The paper's (DenseFusion's): 4 outputs, normalised to a unit quaternion.
    #[default]
    Quaternion,
    /// Zhou et al. 2019's continuous 6D representation: 6 outputs, two columns made orthonormal
    /// (a deviation from the paper; see docs/training.md).
    Rot6d,
}

impl RotationKind {
    /// Outputs per object slot.
    pub fn outputs(self) -> usize {
        match self {
            RotationKind::Quaternion => 4,
            RotationKind::Rot6d => 6,
        }
    }

    /// The heads' raw outputs `(B, N, outputs)` as row-major rotation matrices `(B, N, 9)`.
    pub fn to_matrix(self, raw: Tensor<3>) -> Tensor<3> {
        match self {
            RotationKind::Quaternion => quat_to_matrix(normalize_quat(raw)),
            RotationKind::Rot6d => rot6d_to_matrix(raw),
        }
    }
}

/// Which network to build.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Variant {
    /// The paper's network: visual + tactile channel, global feature, Siamese rotation head.
    TactileChannel,
    /// The baseline: DenseFusion (visual channel only), no refinement.
    VisionOnly,
    /// Ablation: separate rotation heads for the two channels.
    NonSiamese,
    /// Ablation: no global feature.
    NoGlobal,
    /// Ablation: no colour; the tactile channel (depth + tactile points) alone.
    TactileOnly,
}

impl Variant {
    pub const ALL: [Variant; 5] =
        [Variant::TactileChannel, Variant::VisionOnly, Variant::NonSiamese, Variant::NoGlobal, Variant::TactileOnly];

    /// The config name (`tactile_channel`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Variant::TactileChannel => "tactile_channel",
            Variant::VisionOnly => "vision_only",
            Variant::NonSiamese => "non_siamese",
            Variant::NoGlobal => "no_global",
            Variant::TactileOnly => "tactile_only",
        }
    }

    /// The name in reports (the paper's).
    pub fn label(self) -> &'static str {
        match self {
            Variant::TactileChannel => "Tactile-Channel (Siamese)",
            Variant::VisionOnly => "Vision-only baseline (DenseFusion)",
            Variant::NonSiamese => "Non-Siamese",
            Variant::NoGlobal => "No global feature",
            Variant::TactileOnly => "Tactile-only",
        }
    }

    pub fn uses_color(self) -> bool {
        self != Variant::TactileOnly
    }

    pub fn uses_tactile(self) -> bool {
        self != Variant::VisionOnly
    }

    pub fn global_feature(self) -> bool {
        self != Variant::NoGlobal
    }

    /// Estimates per depth point: 2 with both channels, else 1.
    pub fn channels(self) -> usize {
        usize::from(self.uses_color()) + usize::from(self.uses_tactile())
    }
}

impl FromStr for Variant {
    type Err = anyhow::Error;
    fn from_str(s: &str) -> anyhow::Result<Self> {
        Variant::ALL
            .into_iter()
            .find(|v| v.name() == s)
            .ok_or_else(|| anyhow::anyhow!("unknown model variant '{s}' (expected one of: {})", Variant::ALL.map(|v| v.name()).join(", ")))
    }
}

impl std::fmt::Display for Variant {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

// --------------------------------------------------------------------------------------------
// Building blocks
// --------------------------------------------------------------------------------------------

/// Two point-wise layers (DenseFusion's `conv1`/`conv2` 1×1 convolutions), returning both stages.
#[derive(Config, Debug)]
pub struct TwoStageConfig {
    pub d_input: usize,
    pub dims: [usize; 2],
}

#[derive(Module, Debug)]
pub struct TwoStage {
    stage1: Linear,
    stage2: Linear,
}

impl TwoStageConfig {
    pub fn init(&self, device: &Device) -> TwoStage {
        TwoStage {
            stage1: LinearConfig::new(self.d_input, self.dims[0]).init(device),
            stage2: LinearConfig::new(self.dims[0], self.dims[1]).init(device),
        }
    }
}

impl TwoStage {
    /// `(B, N, d_input)` → the stage-1 `(B, N, dims[0])` and stage-2 `(B, N, dims[1])` features.
    pub fn forward(&self, x: Tensor<3>) -> (Tensor<3>, Tensor<3>) {
        let f1 = relu(self.stage1.forward(x));
        let f2 = relu(self.stage2.forward(f1.clone()));
        (f1, f2)
    }
}

/// A point-wise MLP: Linear + ReLU per width in `dims`, and with `d_output` a last Linear without
/// activation (a head).
#[derive(Config, Debug)]
pub struct MlpConfig {
    pub d_input: usize,
    pub dims: Vec<usize>,
    pub d_output: Option<usize>,
}

#[derive(Module, Debug)]
pub struct Mlp {
    hidden: Vec<Linear>,
    output: Option<Linear>,
}

impl MlpConfig {
    pub fn init(&self, device: &Device) -> Mlp {
        let mut d = self.d_input;
        let hidden = self
            .dims
            .iter()
            .map(|&w| {
                let l = LinearConfig::new(d, w).init(device);
                d = w;
                l
            })
            .collect();
        Mlp { hidden, output: self.d_output.map(|o| LinearConfig::new(d, o).init(device)) }
    }
}

impl Mlp {
    pub fn forward(&self, x: Tensor<3>) -> Tensor<3> {
        self.forward_with_shared(x, None)
    }

    /// [`Mlp::forward`] of the features `[x, shared]`, where `shared` `(B, 1, d_s)` is the same
    /// for every point of a sample (the global feature): the first layer's product with it is
    /// computed once per sample instead of once per point, and the `(B, N, d_s)` copy is never
    /// made. The same parameters and, up to float summation order, the same result as `forward`
    /// of the concatenation: the heads' first layers are most of a training step's arithmetic.
    pub fn forward_with_shared(&self, x: Tensor<3>, shared: Option<&Tensor<3>>) -> Tensor<3> {
        let mut layers = self.hidden.iter().map(|l| (l, true)).chain(self.output.iter().map(|l| (l, false)));
        let Some((first, activate)) = layers.next() else { return x };
        let mut x = match shared {
            None => first.forward(x),
            Some(g) => {
                let [b, n, d] = x.dims();
                let w = first.weight.val();
                let [d_in, d_out] = w.dims();
                let per_point = linear(x, w.clone().slice([0..d, 0..d_out]), first.bias.as_ref().map(|b| b.val()));
                let per_sample = linear(g.clone(), w.slice([d..d_in, 0..d_out]), None);
                per_point + per_sample.expand([b, n, d_out])
            }
        };
        if activate {
            x = relu(x);
        }
        for (l, activate) in layers {
            x = l.forward(x);
            if activate {
                x = relu(x);
            }
        }
        x
    }
}

/// The pose heads of one channel: rotation (absent when the channel borrows the Siamese one),
/// translation and confidence, each with one output slot per object.
#[derive(Module, Debug)]
pub struct Heads {
    rotation: Option<Mlp>,
    translation: Mlp,
    confidence: Mlp,
}

/// `d_own`: the channel's own point features plus the global feature (rotation, confidence);
/// `d_translation`: what the translation head sees (the paper: both channels' features and the
/// global feature).
/// `rotation`: the rotation head's outputs per object (`None`: no own rotation head).
fn heads(d_own: usize, d_translation: usize, hidden: &[usize], objects: usize, rotation: Option<usize>, device: &Device) -> Heads {
    let head = |d_input: usize, k: usize| MlpConfig::new(d_input, hidden.to_vec()).with_d_output(Some(objects * k)).init(device);
    Heads { rotation: rotation.map(|k| head(d_own, k)), translation: head(d_translation, 3), confidence: head(d_own, 1) }
}

/// Picks each sample's object slot: `(B, N, O·k)` → `(B, N, k)`.
fn select_object(out: Tensor<3>, object: &Tensor<1, Int>, k: usize) -> Tensor<3> {
    let [b, n, ok] = out.dims();
    let o = ok / k;
    let idx = object.clone().reshape([b, 1, 1, 1]).expand([b, n, 1, k]);
    out.reshape([b, n, o, k]).gather(2, idx).reshape([b, n, k])
}

// --------------------------------------------------------------------------------------------
// The network
// --------------------------------------------------------------------------------------------

/// The network's hyper-parameters, the `model:` section of a training config (see the module
/// docs). The number of objects, which sets the heads' output slots, comes from the dataset, not
/// from the file: [`ModelConfig::init`] takes it. Defaults are small enough to train on a CPU.
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
    /// Per-pixel colour embedding.
    pub color_dim: usize,
    /// The two point-wise stages (depth, colour, tactile).
    pub point_dims: [usize; 2],
    /// The global feature MLP; the last is the global feature's width.
    pub global_dims: Vec<usize>,
    /// Hidden widths of the pose heads.
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

/// See the module docs.
#[derive(Module, Debug)]
pub struct PoseNet {
    color_cnn: Option<ColorEncoder>,
    color_mlp: Option<TwoStage>,
    depth_mlp: TwoStage,
    tactile_mlp: Option<TwoStage>,
    global: Option<Mlp>,
    visual: Option<Heads>,
    tactile: Option<Heads>,
    #[module(skip)]
    variant: Variant,
    #[module(skip)]
    rotation: RotationKind,
}

/// The range checks the type system does not make: every width at least 1, and a global feature.
impl Check for ModelConfig {
    fn check(&self, c: &mut Checks) {
        let width = |c: &mut Checks, w: usize| c.bounded(w as f64, incl(1.0), None, "channels");
        width(&mut c.key(key!(self.resnet_width)), self.resnet_width);
        width(&mut c.key(key!(self.color_dim)), self.color_dim);
        let lists: [(&'static str, &[usize]); 4] = [
            (key!(self.cnn_channels), &self.cnn_channels),
            (key!(self.point_dims), &self.point_dims),
            (key!(self.global_dims), &self.global_dims),
            (key!(self.head_dims), &self.head_dims),
        ];
        for (key, widths) in lists {
            for (i, &w) in widths.iter().enumerate() {
                width(&mut c.key(key).index(i), w);
            }
        }
        if self.global_dims.is_empty() {
            c.key(key!(self.global_dims)).fail("needs at least one width (the last is the global feature's)");
        }
    }
}

impl ModelConfig {
    /// A network with fresh weights and `num_objects` output slots per head, on `device`.
    pub fn init(&self, num_objects: usize, device: &Device) -> PoseNet {
        let v = self.variant;
        let [p1, p2] = self.point_dims;
        let two_stage = |d_input| TwoStageConfig::new(d_input, [p1, p2]).init(device);
        let global_dim = if v.global_feature() { *self.global_dims.last().expect("validated: >= 1 global width") } else { 0 };
        // Every channel's point features: [depth stage 1, other stage 1, depth stage 2, other stage 2],
        // then the global feature. The translation heads see both channels' features (§III-B).
        let channel_dim = 2 * p1 + 2 * p2;
        let own_dim = channel_dim + global_dim;
        let translation_dim = channel_dim * v.channels() + global_dim;
        let global_in = p2 * (1 + v.channels());
        let o = num_objects;
        let siamese = v != Variant::NonSiamese;
        let k_rot = self.rotation.outputs();
        PoseNet {
            color_cnn: v
                .uses_color()
                .then(|| ColorEncoderConfig::new(self.encoder, self.cnn_channels, self.resnet_width, self.color_dim).init(device)),
            color_mlp: v.uses_color().then(|| two_stage(self.color_dim)),
            depth_mlp: two_stage(3),
            tactile_mlp: v.uses_tactile().then(|| two_stage(3)),
            global: v.global_feature().then(|| MlpConfig::new(global_in, self.global_dims.clone()).init(device)),
            visual: v.uses_color().then(|| heads(own_dim, translation_dim, &self.head_dims, o, Some(k_rot), device)),
            // The tactile channel has its own rotation head unless it shares the visual one.
            tactile: v
                .uses_tactile()
                .then(|| heads(own_dim, translation_dim, &self.head_dims, o, (!(siamese && v.uses_color())).then_some(k_rot), device)),
            variant: v,
            rotation: self.rotation,
        }
    }
}

/// One batch of network inputs (see [`crate::data::Batch::inputs`]).
#[derive(Debug, Clone)]
pub struct PoseInput {
    /// `(B, 3, S, S)`: the normalised RGB crops.
    pub img: Tensor<4>,
    /// `(B, N)`: each depth point's pixel in the flattened crop.
    pub choose: Tensor<2, Int>,
    /// `(B, N, 3)`: camera-frame depth points, metres.
    pub cloud: Tensor<3>,
    /// `(B, N_t, 3)`: camera-frame tactile points (zeros without touch).
    pub tactile: Tensor<3>,
    /// `(B, 1)`: 1 when the sample has tactile points, else 0 (its tactile estimates are void).
    pub has_touch: Tensor<2>,
    /// `(B,)`: the head slot of each sample's object.
    pub object: Tensor<1, Int>,
}

/// The `E` pose estimates per sample (visual channel first, then tactile).
#[derive(Debug, Clone)]
pub struct PoseOutput {
    /// `(B, E, 9)`: rotation matrices, row-major.
    pub rotation: Tensor<3>,
    /// `(B, E, 3)`: translations, metres.
    pub translation: Tensor<3>,
    /// `(B, E)`: confidences in (0, 1).
    pub confidence: Tensor<2>,
    /// `(B, E)`: 1 for a real estimate, 0 for the tactile channel of a sample without touch.
    pub valid: Tensor<2>,
}

/// The pose a network picks for one sample: its most confident valid estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// (w, x, y, z).
    pub rotation: [f32; 4],
    pub translation: [f32; 3],
    pub confidence: f32,
    /// Which estimate: `< n` visual channel (or tactile for `tactile_only`), else tactile.
    pub index: usize,
}

impl PoseOutput {
    /// The most confident valid estimate of every sample (read back to the host).
    pub fn best(&self) -> Vec<Estimate> {
        let [b, e, _] = self.rotation.dims();
        // Void estimates get confidence −1, below any real one.
        let score = self.confidence.clone() * self.valid.clone() + (self.valid.clone() - 1.0);
        let idx: Vec<i64> = score.argmax(1).into_data().iter::<i64>().collect();
        let rot: Vec<f32> = self.rotation.clone().into_data().iter::<f32>().collect();
        let tra: Vec<f32> = self.translation.clone().into_data().iter::<f32>().collect();
        let conf: Vec<f32> = self.confidence.clone().into_data().iter::<f32>().collect();
        (0..b)
            .map(|s| {
                let i = idx[s] as usize;
                let k = s * e + i;
                Estimate {
                    rotation: rows_to_wxyz(&std::array::from_fn(|c| rot[k * 9 + c])),
                    translation: std::array::from_fn(|c| tra[k * 3 + c]),
                    confidence: conf[k],
                    index: i,
                }
            })
            .collect()
    }
}

impl PoseNet {
    /// Whether a forward pass normalises by batch statistics: its batch cannot be split into
    /// shards without changing what it computes.
    pub fn has_batch_norm(&self) -> bool {
        self.color_cnn.as_ref().is_some_and(ColorEncoder::has_batch_norm)
    }

    pub fn variant(&self) -> Variant {
        self.variant
    }

    /// The paper's Fig. 2 top to bottom: the depth embedding, the visual and tactile channels'
    /// point-wise fusion, the global feature, then the heads' estimates.
    pub fn forward(&self, input: &PoseInput) -> PoseOutput {
        let [b, n, _] = input.cloud.dims();
        // The point-wise MLPs see coordinates relative to the depth cloud's centroid, in
        // decimetres (the anchors of the translations stay absolute): centimetre detail is hard to
        // resolve in absolute metres ~0.7 m from the camera, and the pose does not depend on where
        // it is seen.
        let centroid = input.cloud.clone().mean_dim(1); // (B, 1, 3)
        let (d1, d2) = self.depth_mlp.forward((input.cloud.clone() - centroid.clone().expand([b, n, 3])).mul_scalar(POINT_SCALE));
        let visual = self.visual_embedding(input);
        let tactile = self.tactile_embedding(input, &centroid);
        let global = self.global_feature(&d2, visual.as_ref(), tactile.as_ref());
        // Each channel's point features without the global feature: [depth 1, own 1, depth 2, own 2].
        let visual_feats = visual.map(|(c1, c2)| Tensor::cat(vec![d1.clone(), c1, d2.clone(), c2], 2));
        let tactile_parts = tactile.map(|(t1, t2, anchor)| (Tensor::cat(vec![d1.clone(), t1, d2.clone(), t2], 2), anchor));
        self.estimates(input, visual_feats, tactile_parts, global)
    }

    /// Visual channel: the colour embedding gathered at the points' pixels, through the colour
    /// MLP: stage-1 and stage-2 features `(B, N, p1)`, `(B, N, p2)`; `None` without colour.
    fn visual_embedding(&self, input: &PoseInput) -> Option<(Tensor<3>, Tensor<3>)> {
        let (Some(cnn), Some(mlp)) = (&self.color_cnn, &self.color_mlp) else { return None };
        let [b, n, _] = input.cloud.dims();
        let emb = cnn.forward(input.img.clone());
        let [_, c, h, w] = emb.dims();
        let choose = input.choose.clone().reshape([b, 1, n]).expand([b, c, n]);
        let per_point = emb.reshape([b, c, h * w]).gather(2, choose).swap_dims(1, 2); // (B, N, C)
        Some(mlp.forward(per_point))
    }

    /// Tactile channel: the tactile embeddings with entry `i` paired with depth point `i`
    /// (tactile point `i mod n_t`): stage-1 `(B, N, p1)`, stage-2 `(B, N, p2)` and the paired
    /// tactile points `(B, N, 3)` (the anchors of its translations); `None` without touch input.
    fn tactile_embedding(&self, input: &PoseInput, centroid: &Tensor<3>) -> Option<(Tensor<3>, Tensor<3>, Tensor<3>)> {
        let mlp = self.tactile_mlp.as_ref()?;
        let [b, n, _] = input.cloud.dims();
        let [_, nt, _] = input.tactile.dims();
        // Samples without touch contribute no tactile embedding (their tactile estimates are void).
        let touch = input.has_touch.clone().reshape([b, 1, 1]);
        let (t1, t2) = mlp.forward((input.tactile.clone() - centroid.clone().expand([b, nt, 3])).mul_scalar(POINT_SCALE));
        let mask = |t: Tensor<3>| {
            let dims = t.dims();
            t * touch.clone().expand(dims)
        };
        let (t1, t2) = (mask(t1), mask(t2));
        let pairing: Vec<i64> = (0..n).map(|i| (i % nt) as i64).collect();
        let pairing = Tensor::<1, Int>::from_data(TensorData::new(pairing, [n]), &input.cloud.device());
        let pick = |t: Tensor<3>| t.select(1, pairing.clone());
        Some((pick(t1), pick(t2), pick(input.tactile.clone())))
    }

    /// Global feature: the colour, depth and tactile stage-2 embeddings through the global MLP,
    /// averaged over the points: `(B, 1, G)`, the same for every point; `None` for `no_global`.
    fn global_feature(
        &self,
        d2: &Tensor<3>,
        visual: Option<&(Tensor<3>, Tensor<3>)>,
        tactile: Option<&(Tensor<3>, Tensor<3>, Tensor<3>)>,
    ) -> Option<Tensor<3>> {
        let mlp = self.global.as_ref()?;
        let mut parts = vec![d2.clone()];
        if let Some((_, c2)) = visual {
            parts.push(c2.clone());
        }
        if let Some((_, t2, _)) = tactile {
            parts.push(t2.clone());
        }
        Some(mlp.forward(Tensor::cat(parts, 2)).mean_dim(1))
    }

    /// The heads of each channel on its point features (`visual`; `tactile` with its anchors)
    /// and the global feature: the visual estimates, then the tactile ones.
    fn estimates(
        &self,
        input: &PoseInput,
        visual: Option<Tensor<3>>,
        tactile: Option<(Tensor<3>, Tensor<3>)>,
        global: Option<Tensor<3>>,
    ) -> PoseOutput {
        let [b, n, _] = input.cloud.dims();
        let device = input.cloud.device();
        // The paper's translation heads see the RGB-depth, the tactile-depth and the global
        // features; rotation and confidence see their own channel and the global feature. Each
        // head's input is its point features followed by the global feature (`shared`).
        let shared = global.as_ref();
        let translation_in = Tensor::cat(visual.iter().cloned().chain(tactile.as_ref().map(|(f, _)| f.clone())).collect::<Vec<_>>(), 2);

        let mut rotation = Vec::new();
        let mut translation = Vec::new();
        let mut confidence = Vec::new();
        let mut valid = Vec::new();
        let mut run = |heads: &Heads, shared_rotation: Option<&Mlp>, own: Tensor<3>, anchor: Tensor<3>, ok: Tensor<2>| {
            let rot_head = heads.rotation.as_ref().or(shared_rotation).expect("a rotation head");
            let r = select_object(rot_head.forward_with_shared(own.clone(), shared), &input.object, self.rotation.outputs());
            let t = select_object(heads.translation.forward_with_shared(translation_in.clone(), shared), &input.object, 3);
            let c = select_object(heads.confidence.forward_with_shared(own, shared), &input.object, 1);
            rotation.push(self.rotation.to_matrix(r));
            translation.push(anchor + t.div_scalar(POINT_SCALE));
            confidence.push(sigmoid(c).reshape([b, n]));
            valid.push(ok.expand([b, n]));
        };
        if let (Some(heads), Some(f)) = (&self.visual, visual) {
            run(heads, None, f, input.cloud.clone(), Tensor::ones([b, 1], &device));
        }
        if let (Some(heads), Some((f, anchor))) = (&self.tactile, tactile) {
            let shared_rotation = self.visual.as_ref().and_then(|v| v.rotation.as_ref());
            run(heads, shared_rotation, f, anchor, input.has_touch.clone());
        }
        PoseOutput {
            rotation: Tensor::cat(rotation, 1),
            translation: Tensor::cat(translation, 1),
            confidence: Tensor::cat(confidence, 1),
            valid: Tensor::cat(valid, 1),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::cpu;
    use burn::tensor::Distribution;

    fn input(b: usize, n: usize, nt: usize, s: usize, device: &Device) -> PoseInput {
        PoseInput {
            img: Tensor::random([b, 3, s, s], Distribution::Normal(0.0, 1.0), device),
            choose: Tensor::<1, Int>::arange(0..(b * n) as i64, device).reshape([b, n]).remainder_scalar((s * s) as i64),
            cloud: Tensor::random([b, n, 3], Distribution::Uniform(0.25, 0.35), device),
            tactile: Tensor::random([b, nt, 3], Distribution::Uniform(0.25, 0.35), device),
            has_touch: Tensor::ones([b, 1], device),
            object: Tensor::<1, Int>::zeros([b], device),
        }
    }

    #[test]
    fn a_shared_input_through_the_first_layer_once_equals_the_concatenation() {
        let device = cpu();
        let (b, n, d, g) = (3, 7, 5, 4);
        for (dims, out) in [(vec![6, 3], Some(2)), (vec![], Some(2)), (vec![6], None)] {
            let mlp = MlpConfig::new(d + g, dims).with_d_output(out).init(&device);
            let x = Tensor::<3>::random([b, n, d], Distribution::Normal(0.0, 1.0), &device);
            let shared = Tensor::<3>::random([b, 1, g], Distribution::Normal(0.0, 1.0), &device);
            let whole = mlp.forward(Tensor::cat(vec![x.clone(), shared.clone().expand([b, n, g])], 2));
            let split = mlp.forward_with_shared(x, Some(&shared));
            assert_eq!(whole.dims(), split.dims());
            for (a, c) in values(whole).iter().zip(values(split)) {
                assert!((a - c).abs() < 1e-5, "{a} vs {c}");
            }
        }
    }

    fn values<const D: usize>(t: Tensor<D>) -> Vec<f32> {
        t.into_data().iter::<f32>().collect()
    }

    /// The paper's heads: a visual estimate's translation sees the tactile features, its rotation
    /// and confidence do not (without the global feature, which mixes every channel in).
    #[test]
    fn visual_translation_sees_touch_visual_rotation_does_not() {
        let device = cpu();
        let (b, n, nt, s) = (2, 16, 8, 16);
        let net = ModelConfig { variant: Variant::NoGlobal, cnn_channels: [4, 8], color_dim: 8, ..ModelConfig::default() }.init(1, &device);
        let a = input(b, n, nt, s, &device);
        let mut moved = a.clone();
        moved.tactile = moved.tactile.add_scalar(0.02);
        let (oa, ob) = (net.forward(&a), net.forward(&moved));
        let visual = |t: Tensor<3>| t.narrow(1, 0, n);
        let dr = values((visual(oa.rotation.clone()) - visual(ob.rotation.clone())).abs()).into_iter().fold(0.0, f32::max);
        let dc =
            values((oa.confidence.clone().narrow(1, 0, n) - ob.confidence.clone().narrow(1, 0, n)).abs()).into_iter().fold(0.0, f32::max);
        let dt = values((visual(oa.translation.clone()) - visual(ob.translation.clone())).abs()).into_iter().fold(0.0, f32::max);
        assert!(dr < 1e-6 && dc < 1e-6, "visual rotation/confidence moved by {dr}/{dc}");
        assert!(dt > 1e-6, "the visual translation ignores touch");
        // Shapes: both channels, n estimates each.
        assert_eq!(oa.rotation.dims(), [b, 2 * n, 9]);
        assert_eq!(oa.translation.dims(), [b, 2 * n, 3]);
    }
}

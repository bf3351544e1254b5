//! The colour encoders: map the RGB crop `(B, 3, S, S)` to a per-pixel embedding `(B, D, S, S)`
//! that the visual channel gathers at its points' pixels.
//!
//! - [`EncoderKind::ResnetPsp`] (the paper configs' default): DenseFusion's colour network, a
//!   **PSPNet on a dilated ResNet-18**. The ResNet keeps 1/8 of the resolution (layers 3 and 4
//!   dilated instead of strided), a pyramid pooling module pools its features over 1×1, 2×2,
//!   3×3 and 6×6 bins (global context: every output pixel sees the whole crop), and three
//!   ×2 upsampling stages bring the features back to `S × S`. The widths scale with
//!   `resnet_width` (64 = DenseFusion's ResNet-18). Differences from DenseFusion's code: ReLU for
//!   its PReLU, no dropout, no log-softmax on the embedding, and no pretrained weights (none can
//!   be downloaded here: the encoder trains from scratch);
//! - [`EncoderKind::Small`]: a two-level encoder-decoder of four 3×3 convolutions (receptive field
//!   about 11 px, no global context), fast enough for CPU tests.

use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::pool::{MaxPool2d, MaxPool2dConfig};
use burn::nn::{BatchNorm, BatchNormConfig, PaddingConfig2d};
use burn::prelude::*;
use burn::tensor::activation::relu;
use burn::tensor::module::adaptive_avg_pool2d;
use serde::{Deserialize, Serialize};

/// Which colour encoder a network uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EncoderKind {
    /// Four 3×3 convolutions at full and half resolution (tests, quick CPU runs).
    #[default]
    Small,
    /// DenseFusion's PSPNet on a dilated ResNet-18.
    ResnetPsp,
}

impl EncoderKind {
    /// The crop side must be a multiple of this.
    pub fn crop_multiple(self) -> usize {
        match self {
            EncoderKind::Small => 2,
            EncoderKind::ResnetPsp => 8,
        }
    }
}

fn conv(c_in: usize, c_out: usize, k: usize, stride: usize, dilation: usize, bias: bool, device: &Device) -> Conv2d {
    let pad = dilation * (k - 1) / 2;
    Conv2dConfig::new([c_in, c_out], [k, k])
        .with_stride([stride, stride])
        .with_dilation([dilation, dilation])
        .with_padding(PaddingConfig2d::Explicit(pad, pad, pad, pad))
        .with_bias(bias)
        .init(device)
}

/// Bilinear resizing to `size` (torch's `align_corners=False` convention), written as two matrix
/// products so that it differentiates on every backend: burn's own bilinear interpolation has no
/// backward pass on its GPU backends (wgpu, CUDA), where the paper-size network would not train.
fn resize(x: Tensor<4>, size: [usize; 2]) -> Tensor<4> {
    let [b, c, h, w] = x.dims();
    let [oh, ow] = size;
    let device = x.device();
    // Along the rows of each image, then (transposed) along its columns.
    let cols = x.reshape([b * c * h, w]).matmul(linear_taps(w, ow, &device));
    let rows = cols.reshape([b * c, h, ow]).swap_dims(1, 2).reshape([b * c * ow, h]).matmul(linear_taps(h, oh, &device));
    rows.reshape([b * c, ow, oh]).swap_dims(1, 2).reshape([b, c, oh, ow])
}

/// Linear interpolation from `n_in` to `n_out` samples with half-pixel centres (torch's
/// `interpolate(align_corners=False)`, and the Python view's crop): output `j` reads the input at
/// `(j + 0.5) n_in / n_out - 0.5`, clamped to the first and last sample, as `(i0, i1, t)`: the
/// two inputs and the weight of `i1`.
pub fn bilinear_taps(n_in: usize, n_out: usize) -> Vec<(usize, usize, f32)> {
    (0..n_out)
        .map(|j| {
            let x = ((j as f64 + 0.5) * n_in as f64 / n_out as f64 - 0.5).clamp(0.0, (n_in - 1) as f64);
            let i0 = x.floor() as usize;
            (i0, (i0 + 1).min(n_in - 1), (x - i0 as f64) as f32)
        })
        .collect()
}

/// [`bilinear_taps`] as an `(n_in, n_out)` matrix: column `j` holds output `j`'s two weights.
fn linear_taps(n_in: usize, n_out: usize, device: &Device) -> Tensor<2> {
    let mut m = vec![0.0f32; n_in * n_out];
    for (j, (i0, i1, t)) in bilinear_taps(n_in, n_out).into_iter().enumerate() {
        m[i0 * n_out + j] += 1.0 - t;
        m[i1 * n_out + j] += t;
    }
    Tensor::from_data(TensorData::new(m, [n_in, n_out]), device)
}

// --------------------------------------------------------------------------------------------
// Small encoder
// --------------------------------------------------------------------------------------------

/// The small encoder-decoder (see the module docs).
#[derive(Module, Debug)]
pub struct SmallCnn {
    conv1: Conv2d,
    down: Conv2d,
    conv2: Conv2d,
    out: Conv2d,
}

impl SmallCnn {
    pub fn new(channels: [usize; 2], out: usize, device: &Device) -> Self {
        let [c1, c2] = channels;
        SmallCnn {
            conv1: conv(3, c1, 3, 1, 1, true, device),
            down: conv(c1, c2, 3, 2, 1, true, device),
            conv2: conv(c2, c2, 3, 1, 1, true, device),
            out: conv(c2 + c1, out, 3, 1, 1, true, device),
        }
    }

    /// `(B, 3, S, S)` → `(B, out, S, S)`; `S` even.
    pub fn forward(&self, img: Tensor<4>) -> Tensor<4> {
        let e1 = relu(self.conv1.forward(img));
        let e2 = relu(self.conv2.forward(relu(self.down.forward(e1.clone()))));
        let up = upsample2(e2);
        self.out.forward(Tensor::cat(vec![up, e1], 1))
    }
}

/// Nearest-neighbour ×2 upsampling by reshape and broadcast (differentiable on every backend).
fn upsample2(x: Tensor<4>) -> Tensor<4> {
    let [b, c, h, w] = x.dims();
    x.reshape([b, c, h, 1, w, 1]).expand([b, c, h, 2, w, 2]).reshape([b, c, 2 * h, 2 * w])
}

// --------------------------------------------------------------------------------------------
// Dilated ResNet-18 + pyramid pooling
// --------------------------------------------------------------------------------------------

/// ResNet's basic block: two 3×3 convolutions with batch norm and a (projected) shortcut.
#[derive(Module, Debug)]
pub struct BasicBlock {
    conv1: Conv2d,
    bn1: BatchNorm,
    conv2: Conv2d,
    bn2: BatchNorm,
    shortcut: Option<(Conv2d, BatchNorm)>,
}

impl BasicBlock {
    fn new(c_in: usize, c_out: usize, stride: usize, dilation: usize, device: &Device) -> Self {
        let bn = |c| BatchNormConfig::new(c).init(device);
        BasicBlock {
            conv1: conv(c_in, c_out, 3, stride, dilation, false, device),
            bn1: bn(c_out),
            conv2: conv(c_out, c_out, 3, 1, dilation, false, device),
            bn2: bn(c_out),
            shortcut: (stride != 1 || c_in != c_out).then(|| (conv(c_in, c_out, 1, stride, 1, false, device), bn(c_out))),
        }
    }

    fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let y = relu(self.bn1.forward(self.conv1.forward(x.clone())));
        let y = self.bn2.forward(self.conv2.forward(y));
        let skip = match &self.shortcut {
            Some((c, b)) => b.forward(c.forward(x)),
            None => x,
        };
        relu(y + skip)
    }
}

/// DenseFusion's PSPNet on a dilated ResNet-18 (see the module docs).
#[derive(Module, Debug)]
pub struct ResnetPsp {
    stem: Conv2d,
    stem_bn: BatchNorm,
    pool: MaxPool2d,
    blocks: Vec<BasicBlock>,
    /// One 1×1 convolution per pyramid level.
    pyramid: Vec<Conv2d>,
    bottleneck: Conv2d,
    up: Vec<Conv2d>,
    out: Conv2d,
}

/// The pyramid pooling bins of PSPNet.
pub const PSP_BINS: [usize; 4] = [1, 2, 3, 6];

impl ResnetPsp {
    /// `width`: the first stage's channels (64 in ResNet-18); `out`: the embedding width.
    pub fn new(width: usize, out: usize, device: &Device) -> Self {
        let w = width;
        let mut blocks = Vec::new();
        // (channels, stride, dilation) of the four stages, two blocks each; output stride 8.
        let mut c_in = w;
        for (c, stride, dilation) in [(w, 1, 1), (2 * w, 2, 1), (4 * w, 1, 2), (8 * w, 1, 4)] {
            blocks.push(BasicBlock::new(c_in, c, stride, dilation, device));
            blocks.push(BasicBlock::new(c, c, 1, dilation, device));
            c_in = c;
        }
        let feats = 8 * w;
        ResnetPsp {
            stem: conv(3, w, 7, 2, 1, false, device),
            stem_bn: BatchNormConfig::new(w).init(device),
            pool: MaxPool2dConfig::new([3, 3]).with_strides([2, 2]).with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1)).init(),
            blocks,
            pyramid: PSP_BINS.iter().map(|_| conv(feats, feats, 1, 1, 1, false, device)).collect(),
            bottleneck: conv(feats * (PSP_BINS.len() + 1), 16 * w, 1, 1, 1, true, device),
            up: vec![conv(16 * w, 4 * w, 3, 1, 1, true, device), conv(4 * w, w, 3, 1, 1, true, device), conv(w, w, 3, 1, 1, true, device)],
            out: conv(w, out, 1, 1, 1, true, device),
        }
    }

    /// `(B, 3, S, S)` → `(B, out, S, S)`; `S` a multiple of 8.
    pub fn forward(&self, img: Tensor<4>) -> Tensor<4> {
        let [_, _, h, w] = img.dims();
        let mut x = self.pool.forward(relu(self.stem_bn.forward(self.stem.forward(img))));
        for b in &self.blocks {
            x = b.forward(x);
        }
        let [_, _, fh, fw] = x.dims();
        // Pyramid pooling: every level pooled, projected and brought back to the feature size.
        let mut levels: Vec<Tensor<4>> = PSP_BINS
            .iter()
            .zip(&self.pyramid)
            .map(|(&bins, c)| resize(c.forward(adaptive_avg_pool2d(x.clone(), [bins, bins])), [fh, fw]))
            .collect();
        levels.push(x);
        let mut y = relu(self.bottleneck.forward(Tensor::cat(levels, 1)));
        // Three ×2 stages back to the crop's resolution (the last one lands exactly on S × S).
        let n = self.up.len();
        for (k, c) in self.up.iter().enumerate() {
            let [_, _, yh, yw] = y.dims();
            let size = if k + 1 == n { [h, w] } else { [2 * yh, 2 * yw] };
            y = relu(c.forward(resize(y, size)));
        }
        self.out.forward(y)
    }
}

// --------------------------------------------------------------------------------------------
// Either encoder
// --------------------------------------------------------------------------------------------

/// The encoder's hyper-parameters.
#[derive(Config, Debug)]
pub struct ColorEncoderConfig {
    pub kind: EncoderKind,
    /// Widths of the small encoder at full and half resolution.
    pub small_channels: [usize; 2],
    /// First-stage width of the ResNet (64 = ResNet-18).
    pub resnet_width: usize,
    /// Width of the per-pixel embedding.
    pub out: usize,
}

/// One of the encoders (the other field is empty).
#[derive(Module, Debug)]
pub struct ColorEncoder {
    small: Option<SmallCnn>,
    resnet: Option<ResnetPsp>,
}

impl ColorEncoderConfig {
    pub fn init(&self, device: &Device) -> ColorEncoder {
        match self.kind {
            EncoderKind::Small => ColorEncoder { small: Some(SmallCnn::new(self.small_channels, self.out, device)), resnet: None },
            EncoderKind::ResnetPsp => ColorEncoder { small: None, resnet: Some(ResnetPsp::new(self.resnet_width, self.out, device)) },
        }
    }
}

impl ColorEncoder {
    /// Whether the encoder normalises by batch statistics (the ResNet's batch norm).
    pub fn has_batch_norm(&self) -> bool {
        self.resnet.is_some()
    }

    pub fn forward(&self, img: Tensor<4>) -> Tensor<4> {
        match (&self.small, &self.resnet) {
            (Some(s), _) => s.forward(img),
            (None, Some(r)) => r.forward(img),
            (None, None) => unreachable!("a colour encoder has one of its two networks"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::cpu;

    fn max_abs_diff(a: Tensor<4>, b: Tensor<4>) -> Vec<f32> {
        // Per output pixel: the largest change over the channels.
        let [_, c, h, w] = a.dims();
        let d: Vec<f32> = (a - b).abs().into_data().iter::<f32>().collect();
        (0..h * w).map(|p| (0..c).map(|k| d[k * h * w + p]).fold(0.0, f32::max)).collect()
    }

    /// Output shape, and the receptive field measured by perturbing one input corner: the
    /// ResNet-PSP's output changes everywhere (pyramid pooling gives every pixel global context),
    /// the small encoder's only within a few pixels of the perturbation.
    #[test]
    fn encoders_keep_the_crop_size_and_differ_in_receptive_field() {
        let device = cpu();
        let s = 32;
        // A fixed image (tests run in parallel: no shared random stream).
        let pixels: Vec<f32> = (0..3 * s * s).map(|i| ((i * 7919 % 1000) as f32 / 500.0) - 1.0).collect();
        let img = Tensor::<4>::from_data(TensorData::new(pixels.clone(), [1, 3, s, s]), &device);
        let mut poked = pixels;
        for k in 0..3 {
            poked[k * s * s] += 5.0; // pixel (0, 0) of every channel
        }
        let poked = Tensor::<4>::from_data(TensorData::new(poked, [1, 3, s, s]), &device);
        for kind in [EncoderKind::Small, EncoderKind::ResnetPsp] {
            device.seed(3);
            let enc = ColorEncoderConfig::new(kind, [8, 16], 8, 12).init(&device);
            let (a, b) = (enc.forward(img.clone()), enc.forward(poked.clone()));
            assert_eq!(a.dims(), [1, 12, s, s], "{kind:?}");
            let diff = max_abs_diff(a, b);
            let changed = |r: usize, c: usize| diff[r * s + c] > 0.0;
            // The farthest pixel (row + col) the poke reached.
            let reach = (0..s * s).filter(|&p| changed(p / s, p % s)).map(|p| p / s + p % s).max().unwrap_or(0);
            match kind {
                // Four 3×3 convolutions, one at half resolution: the small encoder sees ~11 px.
                EncoderKind::Small => assert!((3..=12).contains(&reach), "small encoder reach {reach}"),
                EncoderKind::ResnetPsp => {
                    assert!(changed(s - 1, s - 1), "the opposite corner must see the poke");
                    assert!(reach >= s, "resnet reach {reach}");
                }
            }
        }
    }

    /// The matrix-product resizing is burn's bilinear interpolation (`align_corners = false`):
    /// up from each pyramid level and by ×2, and to an odd size.
    #[test]
    fn resizing_by_matrix_products_is_bilinear_interpolation() {
        use burn::nn::interpolate::{Interpolate2dConfig, InterpolateMode};
        let device = cpu();
        for (from, to) in [
            ([1, 1], [8, 8]),
            ([2, 2], [8, 8]),
            ([3, 3], [8, 8]),
            ([6, 6], [8, 8]),
            ([8, 4], [16, 8]),
            ([5, 7], [7, 5]),
            ([16, 16], [32, 32]),
        ] {
            let n = 2 * 3 * from[0] * from[1];
            let x = Tensor::<4>::from_data(
                TensorData::new((0..n).map(|i| ((i * 37 % 101) as f32 / 50.0) - 1.0).collect::<Vec<_>>(), [2, 3, from[0], from[1]]),
                &device,
            );
            let ours: Vec<f32> = resize(x.clone(), to).into_data().iter::<f32>().collect();
            let burns: Vec<f32> = Interpolate2dConfig::new()
                .with_output_size(Some(to))
                .with_mode(InterpolateMode::Linear)
                .with_align_corners(false)
                .init()
                .forward(x)
                .into_data()
                .iter::<f32>()
                .collect();
            assert_eq!(ours.len(), 2 * 3 * to[0] * to[1]);
            let worst = ours.iter().zip(&burns).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
            assert!(worst < 1e-5, "{from:?} -> {to:?}: off by {worst}");
        }
    }

    /// The ResNet-PSP trains on burn's GPU backend too (here on a CPU Vulkan driver such as
    /// lavapipe, as CI has): the backward pass gives the first convolution the gradient the CPU
    /// backend computes for the same weights and image.
    #[test]
    fn resnet_psp_backpropagates_on_wgpu() {
        let (cpu, gpu) = (cpu().autodiff(), crate::device::parse("wgpu:cpu").unwrap().autodiff());
        cpu.seed(11);
        let enc = ColorEncoderConfig::new(EncoderKind::ResnetPsp, [8, 16], 8, 12).init(&cpu);
        // A fixed image (tests run in parallel: no shared random stream).
        let pixels: Vec<f32> = (0..2 * 3 * 16 * 16).map(|i| ((i * 7919 % 1000) as f32 / 500.0) - 1.0).collect();
        let stem_grad = |enc: &ColorEncoder, device: &Device| -> Vec<f32> {
            let img = Tensor::<4>::from_data(TensorData::new(pixels.clone(), [2, 3, 16, 16]), device);
            let grads = enc.forward(img).square().mean().backward();
            let stem = enc.resnet.as_ref().unwrap().stem.weight.val().grad(&grads).expect("the stem gets a gradient");
            stem.into_data().iter::<f32>().collect()
        };
        let on_cpu = stem_grad(&enc, &cpu);
        let on_gpu = stem_grad(&enc.clone().fork(&gpu), &gpu);
        let scale = on_cpu.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        assert!(scale > 0.0 && on_gpu.iter().all(|v| v.is_finite()));
        let worst = on_cpu.iter().zip(&on_gpu).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
        assert!(worst <= 1e-3 * scale, "wgpu's gradient is off by {worst} (largest {scale})");
    }

    /// The ResNet-PSP trains: a backward pass through batch norm, pooling and bilinear resizing
    /// gives finite gradients that reach the first convolution.
    #[test]
    fn resnet_psp_backpropagates() {
        let device = cpu().autodiff();
        let enc = ColorEncoderConfig::new(EncoderKind::ResnetPsp, [8, 16], 8, 12).init(&device);
        let img = Tensor::<4>::random([2, 3, 16, 16], burn::tensor::Distribution::Normal(0.0, 1.0), &device);
        let loss = enc.forward(img).square().mean();
        let grads = loss.backward();
        let stem = enc.resnet.as_ref().unwrap().stem.weight.val().grad(&grads).expect("the stem gets a gradient");
        let g: Vec<f32> = stem.into_data().iter::<f32>().collect();
        assert!(g.iter().all(|v| v.is_finite()) && g.iter().any(|v| *v != 0.0));
    }
}

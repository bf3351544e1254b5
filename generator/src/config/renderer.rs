//! `renderer:` the rasterizer's backend, shadows, tone mapping and anti-aliasing.

use serde::{Deserialize, Serialize};
use vt_check::{Check, Checks, field, key};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RendererConfig {
    #[serde(default)]
    pub backend: Backend,
    /// Pick the adapter whose name contains this text (e.g. "llvmpipe", "H100").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub adapter: Option<String>,
    /// Side of the spotlight's shadow map in texels (256–8192).
    pub shadow_map_size: u32,
    /// Shadow-map comparisons per shaded pixel (percentage-closer filtering, each a bilinear 2x2
    /// comparison): 4 (default) or 9, the 3x3 kernel of earlier versions. 4 draws the main view
    /// about 8% faster on lavapipe with the same shadows to within a few levels at their edges
    /// (docs/rendering.md).
    #[serde(skip_serializing_if = "is_default_shadow_taps")]
    pub shadow_taps: u32,
    /// Tone mapping of the linear colour before sRGB encoding: `none` (clamp) or `aces` (filmic).
    #[serde(default)]
    pub tonemapping: ToneMapping,
    /// Multisample anti-aliasing of the colour image: 1 (off) or 4. Depth and mask stay exact
    /// (one sample per pixel centre) either way.
    pub msaa: u32,
}

impl Default for RendererConfig {
    fn default() -> Self {
        RendererConfig {
            backend: Backend::Auto,
            adapter: None,
            shadow_map_size: 1024,
            shadow_taps: DEFAULT_SHADOW_TAPS,
            tonemapping: ToneMapping::None,
            msaa: 1,
        }
    }
}

const DEFAULT_SHADOW_TAPS: u32 = 4;

fn is_default_shadow_taps(taps: &u32) -> bool {
    *taps == DEFAULT_SHADOW_TAPS
}

impl Check for RendererConfig {
    /// Shadow map size and filter, anti-aliasing.
    fn check(&self, c: &mut Checks) {
        c.range(field!(self.shadow_map_size), 256, 8192);
        if ![1, 4].contains(&self.msaa) {
            c.key(key!(self.msaa)).fail(format!("{} is not supported: use 1 (off) or 4", self.msaa));
        }
        if ![4, 9].contains(&self.shadow_taps) {
            c.key(key!(self.shadow_taps)).fail(format!("{} is not supported: use 4 or 9", self.shadow_taps));
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ToneMapping {
    #[default]
    None,
    Aces,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Backend {
    /// The best adapter found: a GPU if there is one, else a CPU rasterizer (Mesa lavapipe).
    #[default]
    Auto,
    Vulkan,
    Gl,
    Metal,
    Dx12,
}

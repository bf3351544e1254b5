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
    /// Tone mapping of the linear colour before sRGB encoding: `none` (clamp) or `aces` (filmic).
    #[serde(default)]
    pub tonemapping: ToneMapping,
    /// Multisample anti-aliasing of the colour image: 1 (off) or 4. Depth and mask stay exact
    /// (one sample per pixel centre) either way.
    pub msaa: u32,
}

impl Default for RendererConfig {
    fn default() -> Self {
        RendererConfig { backend: Backend::Auto, adapter: None, shadow_map_size: 1024, tonemapping: ToneMapping::None, msaa: 1 }
    }
}

impl Check for RendererConfig {
    /// Shadow map size, anti-aliasing.
    fn check(&self, c: &mut Checks) {
        c.range(field!(self.shadow_map_size), 256, 8192);
        if ![1, 4].contains(&self.msaa) {
            c.key(key!(self.msaa)).fail(format!("{} is not supported: use 1 (off) or 4", self.msaa));
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

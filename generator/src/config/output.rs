//! `output:` where the shards go, how many samples each holds and how they are compressed.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use vt_check::{Check, Checks, field};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutputConfig {
    /// Dataset directory, relative to the current directory (overridable with `--out`); default
    /// `out/<config file name without .yaml>`.
    #[serde(default)]
    pub dir: PathBuf,
    pub samples_per_shard: u32,
    #[serde(default)]
    pub compression: CompressionKind,
    pub zstd_level: i32,
    /// How the main camera's depth (and its noisy reading) is stored: `exact` (the rasterizer's
    /// float), or rounded to multiples of 2^-bits m (`14`: 0.061 mm steps, at most 0.031 mm off),
    /// which zstd packs ~8x tighter in the same `32FC1` metres. `auto` (default): 14 bits in
    /// episodes (`sampling.record`), exact in snapshots. Left out of the config when `auto`.
    #[serde(skip_serializing_if = "DepthGrid::is_auto")]
    pub depth_grid: DepthGrid,
}

/// `output.depth_grid`: `auto`, `exact`, or a number of bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DepthGrid {
    #[default]
    Auto,
    Exact,
    /// Depth rounded to multiples of 2^-bits m (8 ..= 20).
    Bits(u32),
}

impl Serialize for DepthGrid {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            DepthGrid::Auto => s.serialize_str("auto"),
            DepthGrid::Exact => s.serialize_str("exact"),
            DepthGrid::Bits(b) => s.serialize_u32(*b),
        }
    }
}

impl<'de> Deserialize<'de> for DepthGrid {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Grid;
        impl serde::de::Visitor<'_> for Grid {
            type Value = DepthGrid;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("auto, exact or a number of bits (8 ..= 20: a grid of 2^-bits m)")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<DepthGrid, E> {
                match v {
                    "auto" => Ok(DepthGrid::Auto),
                    "exact" => Ok(DepthGrid::Exact),
                    _ => Err(E::invalid_value(serde::de::Unexpected::Str(v), &self)),
                }
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<DepthGrid, E> {
                u32::try_from(v).map(DepthGrid::Bits).map_err(|_| E::invalid_value(serde::de::Unexpected::Unsigned(v), &self))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<DepthGrid, E> {
                u32::try_from(v).map(DepthGrid::Bits).map_err(|_| E::invalid_value(serde::de::Unexpected::Signed(v), &self))
            }
        }
        d.deserialize_any(Grid)
    }
}

/// The grid episodes store their depth on unless the config says otherwise: chosen by measurement
/// (docs/episodes.md, "Bytes").
pub const EPISODE_DEPTH_GRID_BITS: u32 = 14;

impl DepthGrid {
    fn is_auto(&self) -> bool {
        *self == DepthGrid::Auto
    }

    /// The grid's bits for a run that records episodes (`episodes`) or snapshots; None: exact.
    pub fn bits(&self, episodes: bool) -> Option<u32> {
        match self {
            DepthGrid::Auto => episodes.then_some(EPISODE_DEPTH_GRID_BITS),
            DepthGrid::Exact => None,
            DepthGrid::Bits(b) => Some(*b),
        }
    }
}

/// Rounds every finite, positive depth to a multiple of 2^-bits m (exact in f32 below 2^(24 -
/// bits) m: 1024 m at 14 bits); 0 (no surface) stays 0.
pub fn snap_depth_to_grid(depth: &mut [f32], bits: u32) {
    let scale = (1u64 << bits) as f64;
    for d in depth.iter_mut().filter(|d| d.is_finite() && **d > 0.0) {
        *d = ((*d as f64 * scale).round() / scale) as f32;
    }
}

impl OutputConfig {
    /// The shard writer's compression for this output section.
    pub fn shard_compression(&self) -> vt_dataset::Compression {
        match self.compression {
            CompressionKind::Zstd => vt_dataset::Compression::Zstd { level: self.zstd_level as u32 },
            CompressionKind::None => vt_dataset::Compression::None,
        }
    }
}

impl Default for OutputConfig {
    fn default() -> Self {
        OutputConfig {
            dir: PathBuf::new(),
            samples_per_shard: 500,
            compression: CompressionKind::default(),
            zstd_level: 3,
            depth_grid: DepthGrid::default(),
        }
    }
}

impl Check for OutputConfig {
    /// Shard size, compression.
    fn check(&self, c: &mut Checks) {
        c.range(field!(self.samples_per_shard), 1, 1_000_000);
        c.range(field!(self.zstd_level), 1, 19);
        if let DepthGrid::Bits(bits) = self.depth_grid {
            c.range(("depth_grid", &bits), 8, 20);
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CompressionKind {
    #[default]
    Zstd,
    None,
}

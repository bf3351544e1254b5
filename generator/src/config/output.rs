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
        OutputConfig { dir: PathBuf::new(), samples_per_shard: 500, compression: CompressionKind::default(), zstd_level: 3 }
    }
}

impl Check for OutputConfig {
    /// Shard size, compression.
    fn check(&self, c: &mut Checks) {
        c.range(field!(self.samples_per_shard), 1, 1_000_000);
        c.range(field!(self.zstd_level), 1, 19);
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CompressionKind {
    #[default]
    Zstd,
    None,
}

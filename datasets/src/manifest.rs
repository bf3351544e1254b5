use std::collections::BTreeMap;
use std::io::Read;
use std::path::Path;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

/// `manifest.json` (FORMAT.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub format: String,
    pub format_version: u32,
    pub generator: String,
    pub seed: u64,
    pub config_sha256: String,
    pub complete: bool,
    pub splits: BTreeMap<String, SplitManifest>,
    /// Grasp-loop figures summed over the complete shards (when a robot is in the scene).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grasp: Option<serde_json::Value>,
    /// Occlusion-level histogram over the paper's bins, summed over the complete shards.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub occlusion: Option<serde_json::Value>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SplitManifest {
    pub samples: u64,
    pub samples_per_shard: u64,
    pub shards: Vec<ShardEntry>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShardEntry {
    pub file: String,
    pub shard_index: u32,
    pub first_sample: u64,
    pub samples: u64,
    pub bytes: Option<u64>,
    pub sha256: Option<String>,
}

impl Manifest {
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
        serde_json::from_str(&text).with_context(|| format!("{} is not a valid vtgen manifest", path.display()))
    }

    /// Writes atomically, so a reader never sees half a manifest.
    pub fn save(&self, path: &Path) -> Result<()> {
        let mut text = serde_json::to_string_pretty(self)?;
        text.push('\n');
        write_atomic(path, text.as_bytes())
    }
}

/// `models/models_info.json` (FORMAT.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelsInfo {
    pub objects: Vec<ModelInfo>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelInfo {
    pub id: String,
    pub object_index: u32,
    pub mask_id: u8,
    pub symmetry: String,
    pub mass: f64,
    pub extents: [f64; 3],
    pub diameter: f64,
    pub source: String,
    pub file: String,
}

/// Size and SHA-256 (hex) of a file.
pub fn sha256_file(path: &Path) -> Result<(u64, String)> {
    let mut f = std::fs::File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut n = 0u64;
    loop {
        let k = f.read(&mut buf)?;
        if k == 0 {
            break;
        }
        h.update(&buf[..k]);
        n += k as u64;
    }
    Ok((n, h.finalize().iter().map(|b| format!("{b:02x}")).collect()))
}

/// Writes a file through a temporary file of this process and a rename: readers see the old or the
/// new content, never a mix, even with several `--shard` processes writing the same directory.
pub fn write_atomic(path: &Path, data: &[u8]) -> Result<()> {
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("file");
    let tmp = path.with_file_name(format!(".{name}.{}.tmp", std::process::id()));
    std::fs::write(&tmp, data).with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("cannot write {}", path.display()))
}

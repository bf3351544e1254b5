use std::collections::BTreeMap;
use std::io::Read;
use std::path::Path;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::OcclusionBin;

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
    #[serde(default, skip_serializing_if = "Option::is_none", serialize_with = "keys_sorted")]
    pub grasp: Option<GraspStats>,
    /// Occlusion-level histogram over the paper's bins, summed over the complete shards.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub occlusion: Option<OcclusionHistogram>,
}

/// The manifest writes its records with their keys in alphabetical order (a shard's
/// `grasp_stats` keeps the struct's order): the bytes datasets have always had.
fn keys_sorted<T: Serialize, S: serde::Serializer>(value: &Option<T>, s: S) -> Result<S::Ok, S::Error> {
    serde_json::to_value(value).map_err(serde::ser::Error::custom)?.serialize(s)
}

/// The grasp loop's figures (FORMAT.md, "Grasp statistics"): a shard's `grasp_stats` (of the
/// trajectories that start in it) and the manifest's `grasp` (summed over the complete shards).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GraspStats {
    pub trajectories: u64,
    pub attempts: u64,
    /// Failed attempts by outcome name.
    pub failures: BTreeMap<String, u64>,
    pub max_slip_mm: f64,
    pub max_penetration_mm: f64,
}

impl GraspStats {
    pub fn merge(&mut self, o: &GraspStats) {
        self.trajectories += o.trajectories;
        self.attempts += o.attempts;
        for (k, v) in &o.failures {
            *self.failures.entry(k.clone()).or_default() += v;
        }
        self.max_slip_mm = self.max_slip_mm.max(o.max_slip_mm);
        self.max_penetration_mm = self.max_penetration_mm.max(o.max_penetration_mm);
    }
}

/// One line of JSON, keys in alphabetical order, as the manifest holds the figures.
impl std::fmt::Display for GraspStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", serde_json::to_value(self).map_err(|_| std::fmt::Error)?)
    }
}

/// The manifest's `occlusion`: samples per occlusion bin ([`OcclusionBin::ALL`] order), summed
/// over the complete shards; a shard's `occlusion_histogram` holds its `counts` alone.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OcclusionHistogram {
    /// The bins' keys ([`OcclusionBin::key`]).
    pub bins: Vec<String>,
    pub counts: [u64; 3],
}

impl OcclusionHistogram {
    pub fn new(counts: [u64; 3]) -> Self {
        OcclusionHistogram { bins: OcclusionBin::ALL.map(|b| b.key().to_string()).to_vec(), counts }
    }
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
    /// The kind of symmetry that holds on the mesh: `none`, `continuous_z` or `discrete` (the
    /// catalogue's kind, or `none` when none of its symmetries passed the check on the mesh).
    pub symmetry: String,
    pub mass: f64,
    pub extents: [f64; 3],
    pub diameter: f64,
    pub source: String,
    pub file: String,
    /// The 180° flips that map the mesh onto itself, verified on it: 4×4 rigid transforms in the
    /// model frame, row-major (BOP's layout), translation in metres. Empty (and absent from the
    /// file) for other kinds and in datasets written before they were measured.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub symmetries_discrete: Vec<[f64; 16]>,
    /// The revolution axis that maps the mesh onto itself, verified on it (at most one).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub symmetries_continuous: Vec<ContinuousSymmetry>,
}

/// A continuous symmetry: revolution about the line through `offset` along `axis` (model frame;
/// `axis` a unit vector, `offset` a point of the line in metres), as BOP's `symmetries_continuous`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ContinuousSymmetry {
    pub axis: [f64; 3],
    pub offset: [f64; 3],
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn models_info_symmetry_transforms_are_optional() {
        // A dataset written before the transforms were measured still reads.
        let old = r#"{"objects": [{"id": "009_gelatin_box", "object_index": 0, "mask_id": 1, "symmetry": "discrete",
            "mass": 0.097, "extents": [0.09, 0.1, 0.03], "diameter": 0.114, "source": "mesh", "file": "009_gelatin_box.ply"}]}"#;
        let info: ModelsInfo = serde_json::from_str(old).unwrap();
        assert!(info.objects[0].symmetries_discrete.is_empty() && info.objects[0].symmetries_continuous.is_empty());
        // Empty lists are left out; filled ones round-trip.
        let text = serde_json::to_string(&info).unwrap();
        assert!(!text.contains("symmetries_"), "{text}");
        let mut o = info.objects[0].clone();
        let flip_z = [-1.0, 0.0, 0.0, 0.001, 0.0, -1.0, 0.0, -0.002, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
        o.symmetries_discrete = vec![flip_z];
        o.symmetries_continuous = vec![ContinuousSymmetry { axis: [0.0, 0.0, 1.0], offset: [0.001, 0.0, 0.0] }];
        let text = serde_json::to_string(&o).unwrap();
        assert!(text.contains(r#""symmetries_continuous":[{"axis":[0.0,0.0,1.0],"offset":[0.001,0.0,0.0]}]"#), "{text}");
        assert_eq!(serde_json::from_str::<ModelInfo>(&text).unwrap(), o);
    }
}

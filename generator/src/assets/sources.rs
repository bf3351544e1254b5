//! Where a run's meshes came from, by the content that was loaded: part of a dataset's identity,
//! beside its config. Two runs whose objects or robot were loaded from different bytes (real YCB
//! scans on one node, procedural stand-ins on another; another robot mesh download) make
//! different data, so `generate` refuses to add one's shards to the other's dataset.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::assets::{LoadedObject, MeshSource};
use crate::config::LoadedConfig;

/// The mesh sources of a dataset: `sources.json` in its directory (FORMAT.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MeshSources {
    /// Per object id: its mesh as loaded.
    pub objects: BTreeMap<String, Source>,
    /// The robot's URDF and meshes as loaded; absent without a robot.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<Source>,
}

/// One source: what it was read from (for people; no directory, so that the same download in
/// another place writes the same bytes) and the SHA-256 of what was loaded (the identity).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Source {
    pub from: String,
    pub sha256: String,
}

impl std::fmt::Display for Source {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} (sha256 {})", self.from, &self.sha256[..12.min(self.sha256.len())])
    }
}

impl MeshSources {
    /// The sources of `objects` (as `load_objects` loaded them) and of the config's robot.
    pub fn of(cfg: &LoadedConfig, objects: &[LoadedObject]) -> Result<Self> {
        let objects = objects
            .iter()
            .map(|o| {
                let from = match &o.source {
                    MeshSource::Procedural => "procedural stand-in".to_string(),
                    MeshSource::File(p) => format!("mesh {}", tail(p, 3)),
                };
                (o.id.clone(), Source { from, sha256: mesh_sha256(o) })
            })
            .collect();
        let robot = cfg.config.robot.as_ref().map(|r| robot_source(cfg, r)).transpose()?;
        Ok(MeshSources { objects, robot })
    }

    /// The first difference from `other` (the dataset's), as "what: dataset's vs this run's";
    /// None when both name the same bytes.
    pub fn difference(&self, dataset: &MeshSources) -> Option<String> {
        let mut diffs = Vec::new();
        let ids: std::collections::BTreeSet<&String> = self.objects.keys().chain(dataset.objects.keys()).collect();
        for id in ids {
            match (dataset.objects.get(id), self.objects.get(id)) {
                (Some(a), Some(b)) if a.sha256 == b.sha256 => {}
                (a, b) => diffs.push(format!("{id}: dataset {} vs this run {}", shown(a), shown(b))),
            }
        }
        if dataset.robot.as_ref().map(|s| &s.sha256) != self.robot.as_ref().map(|s| &s.sha256) {
            diffs.push(format!("robot: dataset {} vs this run {}", shown(dataset.robot.as_ref()), shown(self.robot.as_ref())));
        }
        let first = diffs.first()?.clone();
        Some(if diffs.len() > 1 { format!("{first} (and {} more)", diffs.len() - 1) } else { first })
    }
}

/// The last `n` components of a path, '/'-separated (a YCB object's `<id>/google_16k/textured.obj`).
fn tail(p: &Path, n: usize) -> String {
    let parts: Vec<String> = p.components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
    parts[parts.len().saturating_sub(n)..].join("/")
}

fn shown(s: Option<&Source>) -> String {
    s.map_or_else(|| "none".to_string(), ToString::to_string)
}

/// SHA-256 of the mesh as it is drawn and simulated: vertices, normals, uvs, triangles, texture.
fn mesh_sha256(o: &LoadedObject) -> String {
    let m = &o.mesh;
    let mut h = Sha256::new();
    h.update(bytemuck::cast_slice::<[f32; 3], u8>(&m.positions));
    h.update(bytemuck::cast_slice::<[f32; 3], u8>(&m.normals));
    h.update(bytemuck::cast_slice::<[f32; 2], u8>(&m.uvs));
    h.update(bytemuck::cast_slice::<u32, u8>(&m.indices));
    h.update(m.texture.width.to_le_bytes());
    h.update(m.texture.height.to_le_bytes());
    h.update(&m.texture.rgba);
    hex(h)
}

/// The robot: its URDF text (and its description's, but for the default robot, whose identity
/// earlier datasets carry as its URDF's alone) and every mesh file its URDF names that the run
/// reads.
fn robot_source(cfg: &LoadedConfig, rc: &crate::config::RobotConfig) -> Result<Source> {
    let mut h = Sha256::new();
    let mut from = Vec::new();
    let name = cfg.robot.as_ref().map_or(vt_robot::DEFAULT_ROBOT, |r| r.name.as_str());
    let read = |p: &Path| {
        let path = cfg.resolve(p);
        std::fs::read(&path).with_context(|| format!("cannot read {}", path.display())).map(|b| (b, path))
    };
    if let Some(d) = &rc.description {
        let (bytes, path) = read(d)?;
        h.update(bytes);
        from.push(format!("description {}", tail(&path, 1)));
    }
    match (&rc.urdf, &rc.description) {
        (Some(p), _) => {
            let (bytes, path) = read(p)?;
            h.update(bytes);
            from.push(format!("URDF {}", tail(&path, 1)));
        }
        (None, Some(_)) => {
            let robot = cfg.robot.as_ref().context("a robot description is loaded with the config")?;
            h.update(robot.urdf_text.as_bytes());
            from.push("the description's URDF".to_string());
        }
        (None, None) if name == vt_robot::DEFAULT_ROBOT => {
            let robot = cfg.robot.as_ref().context("a built-in robot is loaded with the config")?;
            h.update(robot.urdf_text.as_bytes());
            from.push("built-in URDF".to_string());
        }
        (None, None) => {
            let robot = cfg.robot.as_ref().context("a built-in robot is loaded with the config")?;
            h.update(robot.urdf_text.as_bytes());
            h.update(vt_robot::builtin_description(name).unwrap_or_default().as_bytes());
            from.push(format!("built-in {name}"));
        }
    }
    // The mesh files a URDF names (the robot's own geometry), by content.
    if let Some(robot) = cfg.robot.as_ref().filter(|r| !r.model.mesh_files.is_empty()) {
        for (file, m) in robot.model.mesh_files.iter().zip(robot_mesh_files(robot, None)?) {
            h.update(tail(file, 1).as_bytes());
            h.update(m.bytes.to_le_bytes());
            h.update(m.sha256.as_bytes());
        }
        from.push(format!("{} URDF mesh files", robot.model.mesh_files.len()));
    }
    // A robot drawn from its primitives where its optional meshes are not there.
    if cfg.robot.as_ref().is_some_and(|r| !r.model.visual_meshes_left_out.is_empty()) {
        from.push("primitives".to_string());
    }
    Ok(Source { from: from.join(", "), sha256: hex(h) })
}

/// The mesh files a robot's URDF names, each with its size and SHA-256 (`robot/meshes.json`); a
/// file in the robot assets folder `assets` by its path there (the same assets in another folder
/// give the same dataset), any other where it was read.
pub fn robot_mesh_files(robot: &vt_robot::Robot, assets: Option<&Path>) -> Result<Vec<vt_dataset::RobotMeshFile>> {
    let assets = assets.map(|a| std::fs::canonicalize(a).unwrap_or_else(|_| a.to_path_buf()));
    robot
        .model
        .mesh_files
        .iter()
        .map(|f| {
            let bytes = std::fs::read(f).with_context(|| format!("cannot read {}", f.display()))?;
            let mut h = Sha256::new();
            h.update(&bytes);
            let file = assets.as_deref().and_then(|a| f.strip_prefix(a).ok()).unwrap_or(f);
            Ok(vt_dataset::RobotMeshFile { file: file.display().to_string(), bytes: bytes.len() as u64, sha256: hex(h) })
        })
        .collect()
}

fn hex(h: Sha256) -> String {
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sources(sha: &str, robot: Option<&str>) -> MeshSources {
        MeshSources {
            objects: [("005_tomato_soup_can".to_string(), Source { from: "x".into(), sha256: sha.into() })].into(),
            robot: robot.map(|r| Source { from: "primitives".into(), sha256: r.into() }),
        }
    }

    #[test]
    fn sources_differ_by_content_not_by_path() {
        let a = sources("aa", Some("rr"));
        let mut b = a.clone();
        b.objects.get_mut("005_tomato_soup_can").unwrap().from = "/elsewhere/textured.obj".into();
        assert_eq!(b.difference(&a), None, "the same bytes from another directory");
        let c = sources("bb", Some("rr"));
        let d = c.difference(&a).unwrap();
        assert!(d.starts_with("005_tomato_soup_can: dataset x (sha256 aa) vs this run x (sha256 bb)"), "{d}");
        let e = sources("aa", None).difference(&a).unwrap();
        assert!(e.contains("robot: dataset primitives (sha256 rr) vs this run none"), "{e}");
    }
}

//! Resolves the config's objects to meshes: a YCB download, a custom mesh file, or the built-in
//! procedural stand-in.

pub mod robot;
pub mod sources;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use vt_objects::{Catalog, CatalogEntry, Surface, Symmetry, TexturedMesh, find_ycb_mesh, load_mesh, procedural_mesh};

use crate::config::{LoadedConfig, ObjectSpec};

/// An object ready to render.
#[derive(Debug, Clone)]
pub struct LoadedObject {
    pub id: String,
    pub index: u32,
    pub mass: f64,
    pub symmetry: Symmetry,
    pub mesh: TexturedMesh,
    pub source: MeshSource,
    /// What the surface is made of (the catalogue's; matte for custom objects).
    pub surface: Surface,
}

/// Where an object's mesh came from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum MeshSource {
    /// The catalogue's built-in stand-in (no YCB directory given).
    Procedural,
    /// A mesh file: a YCB download or a custom object's mesh.
    File(PathBuf),
}

impl std::fmt::Display for MeshSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MeshSource::Procedural => f.write_str("procedural"),
            MeshSource::File(p) => write!(f, "{}", p.display()),
        }
    }
}

/// A catalogue object's mesh: the YCB download's in `ycb_dir`, else the catalogue's procedural
/// stand-in.
pub fn catalog_mesh(id: &str, entry: &CatalogEntry, ycb_dir: Option<&Path>) -> Result<(TexturedMesh, MeshSource)> {
    Ok(match ycb_dir {
        Some(dir) => {
            let path = find_ycb_mesh(dir, id).map_err(|tried| {
                let tried: Vec<String> = tried.iter().map(|p| p.display().to_string()).collect();
                anyhow::anyhow!("no mesh for '{id}' in the YCB directory; looked for: {}", tried.join(", "))
            })?;
            (load_mesh(&path)?, MeshSource::File(path))
        }
        None => (procedural_mesh(entry), MeshSource::Procedural),
    })
}

/// Loads every object of the config. `ycb_dir` (from `--ycb-dir` or the config) selects real meshes
/// for catalogue objects; without it, catalogue objects are procedural.
pub fn load_objects(cfg: &LoadedConfig, ycb_dir: Option<&PathBuf>) -> Result<Vec<LoadedObject>> {
    let catalog = Catalog::builtin();
    let ycb_dir = ycb_dir.cloned().or_else(|| cfg.config.ycb_dir.as_ref().map(|p| cfg.resolve(p)));
    if let Some(d) = &ycb_dir
        && !d.is_dir()
    {
        bail!("YCB directory {} does not exist", d.display());
    }
    let mut out = Vec::new();
    for (i, spec) in cfg.config.objects.iter().enumerate() {
        let obj = match spec {
            ObjectSpec::Catalog(id) => {
                let entry = catalog.get(id).with_context(|| format!("unknown object id '{id}'"))?;
                let (mesh, source) = catalog_mesh(id, entry, ycb_dir.as_deref())?;
                LoadedObject {
                    id: id.clone(),
                    index: i as u32,
                    mass: entry.mass,
                    symmetry: entry.symmetry,
                    mesh,
                    source,
                    surface: entry.surface,
                }
            }
            ObjectSpec::Custom(c) => {
                let path = cfg.resolve(&c.mesh);
                let mesh = load_mesh(&path)?;
                LoadedObject {
                    id: c.id.clone(),
                    index: i as u32,
                    mass: c.mass,
                    symmetry: c.symmetry,
                    mesh,
                    source: MeshSource::File(path),
                    surface: Surface::default(),
                }
            }
        };
        let ext = obj.mesh.extents();
        if ext.max_element() > 2.0 || ext.min_element() < 1e-4 {
            bail!("mesh of '{}' ({}) is {:.3} x {:.3} x {:.3}: meshes must be in metres", obj.id, obj.source, ext.x, ext.y, ext.z);
        }
        out.push(obj);
    }
    Ok(out)
}

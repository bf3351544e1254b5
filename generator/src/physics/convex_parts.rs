//! Convex decomposition of a robot's collision meshes (the description's `convex_decomposition`):
//! a concave link (a palm with a recess, a hook) collides as several convex parts instead of one
//! hull. parry's V-HACD voxelizes the mesh and splits it; it draws no random numbers, so the same
//! mesh and parameters give the same parts. They are computed once per mesh and parameters and
//! kept on disk under their content hash (`vtgen-convex-v1/<sha256>.json` in the cache folder).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Context, Result};
use glam::{DVec3, Vec3};
use rapier3d::parry::transformation::vhacd::{VHACD, VHACDParameters};
use sha2::{Digest, Sha256};
use vt_robot::{Geometry, Robot, Shape, TriangleMesh};

/// The folder the parts are cached in, below a cache root (`LoadedConfig::cache_dir`).
pub const CACHE_FOLDER: &str = "vtgen-convex-v1";

/// `robot` with the collision meshes of its `decomposition` links replaced by their convex parts
/// (each a hull shape at the mesh's origin). Unchanged without a decomposition.
pub fn with_convex_parts(robot: &Robot, cache_root: Option<&Path>) -> Result<Robot> {
    let Some(d) = &robot.decomposition else { return Ok(robot.clone()) };
    let mut out = robot.clone();
    for &link in &d.links {
        let mut shapes = Vec::new();
        for s in &robot.model.links[link].collisions {
            match &s.geometry {
                Geometry::Mesh { mesh } => {
                    let parts = convex_parts(mesh, d.max_hulls, d.resolution, cache_root).with_context(|| {
                        format!("link '{}': convex decomposition of {}", robot.model.links[link].name, mesh.file.display())
                    })?;
                    shapes.extend(parts.into_iter().map(|points| Shape {
                        geometry: Geometry::ConvexHull { points: Arc::new(points) },
                        origin: s.origin,
                        rgba: s.rgba,
                    }));
                }
                _ => shapes.push(s.clone()),
            }
        }
        out.model.links[link].collisions = shapes;
    }
    Ok(out)
}

/// The convex parts of `mesh` (each the points of one hull, mesh frame), from the cache when it
/// has them.
pub fn convex_parts(mesh: &TriangleMesh, max_hulls: u32, resolution: u32, cache_root: Option<&Path>) -> Result<Vec<Vec<DVec3>>> {
    let key = content_key(mesh, max_hulls, resolution);
    let cached: Option<PathBuf> = cache_root.map(|r| r.join(CACHE_FOLDER).join(format!("{key}.json")));
    if let Some(path) = &cached
        && let Ok(text) = std::fs::read_to_string(path)
        && let Ok(parts) = serde_json::from_str::<Vec<Vec<[f64; 3]>>>(&text)
    {
        return Ok(parts.into_iter().map(|p| p.into_iter().map(DVec3::from_array).collect()).collect());
    }
    let points: Vec<Vec3> = mesh.positions.iter().map(|p| p.as_vec3()).collect();
    let params = VHACDParameters { resolution, max_convex_hulls: max_hulls, ..Default::default() };
    let parts: Vec<Vec<DVec3>> = VHACD::decompose(&params, &points, &mesh.triangles, false)
        .compute_convex_hulls(params.convex_hull_downsampling)
        .into_iter()
        .filter(|(p, _)| p.len() >= 4)
        .map(|(p, _)| p.into_iter().map(|v| v.as_dvec3()).collect())
        .collect();
    anyhow::ensure!(!parts.is_empty(), "no convex part with volume (is the mesh closed?)");
    if let Some(path) = &cached {
        let text = serde_json::to_string(&parts.iter().map(|p| p.iter().map(|v| v.to_array()).collect::<Vec<_>>()).collect::<Vec<_>>())?;
        // A cache that cannot be written only costs the next run the computation again.
        if std::fs::create_dir_all(path.parent().expect("a file in a folder")).is_ok() {
            let _ = vt_dataset::write_atomic(path, text.as_bytes());
        }
    }
    Ok(parts)
}

/// SHA-256 of the mesh's vertices and triangles and the parameters.
fn content_key(mesh: &TriangleMesh, max_hulls: u32, resolution: u32) -> String {
    let mut h = Sha256::new();
    for p in &mesh.positions {
        for c in p.to_array() {
            h.update(c.to_le_bytes());
        }
    }
    for t in &mesh.triangles {
        for i in t {
            h.update(i.to_le_bytes());
        }
    }
    h.update(max_hulls.to_le_bytes());
    h.update(resolution.to_le_bytes());
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An L-shaped block (two boxes joined, closed and concave) as a triangle mesh.
    fn l_block() -> TriangleMesh {
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        // The L's outline in x-y, extruded along z by 0.02.
        let outline = [[0.0, 0.0], [0.1, 0.0], [0.1, 0.02], [0.02, 0.02], [0.02, 0.1], [0.0, 0.1]];
        let n = outline.len() as u32;
        for z in [0.0, 0.02] {
            positions.extend(outline.iter().map(|p| DVec3::new(p[0], p[1], z)));
        }
        // Caps as fans from the concave corner (vertex 3), which sees every other vertex.
        for (a, b) in [(4, 5), (5, 0), (0, 1), (1, 2)] {
            triangles.push([3, b, a]);
            triangles.push([n + 3, n + a, n + b]);
        }
        for i in 0..n {
            let j = (i + 1) % n;
            triangles.push([i, j, n + j]);
            triangles.push([i, n + j, n + i]);
        }
        TriangleMesh::new(positions, triangles, vec![None; 20], PathBuf::from("l.obj"))
    }

    #[test]
    fn an_l_block_splits_into_parts_that_leave_its_corner_empty_and_come_back_from_the_cache() {
        let mesh = l_block();
        let dir = tempfile::tempdir().unwrap();
        let parts = convex_parts(&mesh, 8, 64, Some(dir.path())).unwrap();
        assert!(parts.len() >= 2, "{} parts", parts.len());
        // The L's empty corner (0.06, 0.06) lies in no part's bounding box, which one hull covers.
        let corner = DVec3::new(0.06, 0.06, 0.01);
        for p in &parts {
            let (lo, hi) = p.iter().fold((DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)), |(a, b), v| (a.min(*v), b.max(*v)));
            assert!(!(corner.cmpge(lo).all() && corner.cmple(hi).all()), "a part covers the empty corner: {lo} {hi}");
        }
        // Every vertex of the parts lies within the L's bounds (voxels: within one voxel).
        assert!(parts.iter().flatten().all(|v| v.x > -0.003 && v.x < 0.103 && v.y > -0.003 && v.y < 0.103));
        // The same mesh again: the cached parts, exactly.
        let files: Vec<_> = std::fs::read_dir(dir.path().join(CACHE_FOLDER)).unwrap().collect();
        assert_eq!(files.len(), 1);
        assert_eq!(convex_parts(&mesh, 8, 64, Some(dir.path())).unwrap(), parts);
        // And computed anew (no cache): the same parts, deterministic.
        assert_eq!(convex_parts(&mesh, 8, 64, None).unwrap(), parts);
    }
}

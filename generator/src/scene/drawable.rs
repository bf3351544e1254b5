//! A robot link's triangles as the renderer draws them: vertices welded, simplified within a
//! bound on the surface's error (meshoptimizer), creased normals, its colours in a palette.

use std::collections::HashMap;

use glam::Vec3;
use vt_objects::{Texture, TexturedMesh, linear_to_srgb8};

/// The simplifier's error bound, relative to a mesh's extent: 0.2 % of the upper arm's 0.5 m is
/// 1 mm, under a pixel of the paper camera at the arm's distance (about 1.6 mm at 1 m).
const MAX_SIMPLIFY_ERROR: f32 = 0.002;
/// Faces whose normals differ by more than this keep a hard edge between them (CAD meshes have
/// sharp edges that averaged normals would round off).
const CREASE_DEG: f32 = 40.0;

/// Triangles per drawn link with meshes: a robot link is a background occluder seen at a few
/// hundred pixels (the UR5e's meshes have 126 000 triangles in all); the simplifier stops
/// earlier where the error bound says so.
pub const TRIANGLES_PER_LINK: usize = 3000;

/// Triangles of one mesh file in its own frame, with a colour per triangle (linear RGB).
pub struct RawMesh {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub colours: Vec<[f64; 3]>,
}

/// A link's triangles (link frame) as the renderer draws them: vertices welded, simplified to
/// about `max_triangles` within `MAX_SIMPLIFY_ERROR` of the extent, creased normals, a palette.
pub fn drawable_link(raw: RawMesh, max_triangles: usize) -> TexturedMesh {
    let raw = simplify(weld(raw), max_triangles);
    drawable(&raw.positions, &raw.triangles, &raw.colours)
}

/// Merges vertices at the same position (STL repeats them per facet; OBJ per normal), so that
/// simplification and normals see the surface as connected.
fn weld(raw: RawMesh) -> RawMesh {
    let mut index: HashMap<[u32; 3], u32> = HashMap::new();
    let mut positions = Vec::new();
    let remap: Vec<u32> = raw
        .positions
        .iter()
        .map(|p| {
            *index.entry(p.to_array().map(f32::to_bits)).or_insert_with(|| {
                positions.push(*p);
                positions.len() as u32 - 1
            })
        })
        .collect();
    let mut triangles = Vec::with_capacity(raw.triangles.len());
    let mut colours = Vec::with_capacity(raw.triangles.len());
    for (t, c) in raw.triangles.iter().zip(&raw.colours) {
        let t = t.map(|i| remap[i as usize]);
        if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
            triangles.push(t);
            colours.push(*c);
        }
    }
    RawMesh { positions, triangles, colours }
}

/// Simplifies each colour's triangles separately (so that colour borders stay where they are)
/// to about `max_triangles` in all, with meshoptimizer's edge-collapse simplifier.
fn simplify(raw: RawMesh, max_triangles: usize) -> RawMesh {
    if raw.triangles.len() <= max_triangles {
        return raw;
    }
    let vertices: Vec<[f32; 3]> = raw.positions.iter().map(|p| p.to_array()).collect();
    let adapter = meshopt::VertexDataAdapter::new(bytemuck::cast_slice(&vertices), 12, 0).expect("tightly packed f32x3");
    let mut groups: Vec<([f64; 3], Vec<u32>)> = Vec::new();
    for (t, c) in raw.triangles.iter().zip(&raw.colours) {
        match groups.iter_mut().find(|(gc, _)| gc == c) {
            Some((_, idx)) => idx.extend_from_slice(t),
            None => groups.push((*c, t.to_vec())),
        }
    }
    let ratio = max_triangles as f64 / raw.triangles.len() as f64;
    let mut triangles = Vec::new();
    let mut colours = Vec::new();
    for (c, idx) in groups {
        let target = ((idx.len() as f64 * ratio) as usize / 3).max(1) * 3;
        // Stops at the target count or when the next collapse would move the surface by more than
        // `MAX_SIMPLIFY_ERROR` of the mesh's extent, whichever comes first.
        let kept = meshopt::simplify(&idx, &adapter, target, MAX_SIMPLIFY_ERROR, meshopt::SimplifyOptions::LockBorder, None);
        for t in kept.chunks_exact(3) {
            triangles.push([t[0], t[1], t[2]]);
            colours.push(c);
        }
    }
    RawMesh { positions: raw.positions, triangles, colours }
}

/// The mesh the renderer draws: every triangle with its own three vertices (positions shared
/// only through the normals), normals averaged over the faces around a vertex within
/// `CREASE_DEG` of the triangle's own, and texture coordinates into a palette of the colours.
fn drawable(positions: &[Vec3], triangles: &[[u32; 3]], colours: &[[f64; 3]]) -> TexturedMesh {
    let mut palette: Vec<[f64; 3]> = Vec::new();
    for c in colours {
        if !palette.contains(c) {
            palette.push(*c);
        }
    }
    let face_normal = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        (b - a).cross(c - a)
    };
    let normals: Vec<Vec3> = triangles.iter().map(face_normal).collect();
    let mut around: Vec<Vec<u32>> = vec![Vec::new(); positions.len()];
    for (f, t) in triangles.iter().enumerate() {
        for &v in t {
            around[v as usize].push(f as u32);
        }
    }
    let cos_crease = CREASE_DEG.to_radians().cos();
    let mut mesh = TexturedMesh {
        positions: Vec::with_capacity(triangles.len() * 3),
        normals: Vec::with_capacity(triangles.len() * 3),
        uvs: Vec::with_capacity(triangles.len() * 3),
        indices: (0..triangles.len() as u32 * 3).collect(),
        texture: Texture {
            width: palette.len() as u32,
            height: 1,
            rgba: palette.iter().flat_map(|c| [c[0], c[1], c[2], 1.0].map(linear_to_srgb8)).collect(),
        },
    };
    for (f, t) in triangles.iter().enumerate() {
        let own = normals[f].normalize_or_zero();
        let k = palette.iter().position(|c| c == &colours[f]).expect("in the palette");
        let uv = [(k as f32 + 0.5) / palette.len() as f32, 0.5];
        for &v in t {
            let n: Vec3 =
                around[v as usize].iter().map(|&g| normals[g as usize]).filter(|n| n.normalize_or_zero().dot(own) >= cos_crease).sum();
            mesh.positions.push(positions[v as usize].to_array());
            mesh.normals.push(n.normalize_or(own).to_array());
            mesh.uvs.push(uv);
        }
    }
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn creased_normals_keep_a_cube_flat_and_the_palette_holds_each_colour_once() {
        let p = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.], [0., 0., 1.], [1., 0., 1.], [1., 1., 1.], [0., 1., 1.]]
            .map(Vec3::from_array);
        let tris = [
            [0, 2, 1],
            [0, 3, 2],
            [4, 5, 6],
            [4, 6, 7],
            [0, 1, 5],
            [0, 5, 4],
            [2, 3, 7],
            [2, 7, 6],
            [1, 2, 6],
            [1, 6, 5],
            [0, 4, 7],
            [0, 7, 3],
        ];
        let colours: Vec<[f64; 3]> = (0..12).map(|i| if i < 2 { [0.9, 0.9, 0.9] } else { [0.2, 0.2, 0.2] }).collect();
        let m = drawable(&p, &tris, &colours);
        assert_eq!((m.positions.len(), m.texture.width), (36, 2));
        for (t, tri) in m.indices.chunks_exact(3).zip(&tris) {
            let face = (p[tri[1] as usize] - p[tri[0] as usize]).cross(p[tri[2] as usize] - p[tri[0] as usize]).normalize();
            for &i in t {
                assert!(Vec3::from(m.normals[i as usize]).dot(face) > 0.9999, "a cube's faces stay flat");
            }
        }
        assert!(m.uvs[0][0] < 0.5 && m.uvs[35][0] > 0.5, "white on the first faces, black on the rest");
    }
}

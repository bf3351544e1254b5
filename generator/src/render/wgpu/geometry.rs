//! What the GPU reads: vertices, the frame and instance uniforms, uploaded meshes, and the
//! triangle clusters that let small views draw only what they see.

use super::*;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct Vertex {
    pub(super) position: [f32; 3],
    pub(super) normal: [f32; 3],
    pub(super) uv: [f32; 2],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct FrameUniform {
    pub(super) view: [[f32; 4]; 4],
    pub(super) proj: [[f32; 4]; 4],
    pub(super) light_pos: [f32; 4],
    pub(super) light_color: [f32; 4],
    pub(super) ambient: [f32; 4],
    pub(super) light_dir: [f32; 4],
    pub(super) spot: [f32; 4],
    pub(super) up: [f32; 4],
    pub(super) shadow_vp: [[f32; 4]; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct InstanceUniform {
    pub(super) model_view: [[f32; 4]; 4],
    pub(super) normal_mat: [[f32; 4]; 4],
    pub(super) mask_id: [u32; 4],
}

pub(super) struct GpuMesh {
    pub(super) vertices: wgpu::Buffer,
    pub(super) indices: wgpu::Buffer,
    pub(super) index_count: u32,
    pub(super) material: wgpu::BindGroup,
    /// Roughness, metallic and UV scale (uniform of the material bind group).
    pub(super) factors: wgpu::Buffer,
    pub(super) pbr: Material,
    /// The texture repeats per UV unit (`set_texture`), kept for `set_material`.
    pub(super) uv_scale: f32,
    pub(super) texture: wgpu::Texture,
    /// Model-frame bounding box (min, max), to skip draws a view cannot see.
    pub(super) bounds: (glam::DVec3, glam::DVec3),
    /// The mesh simplified for the shadow pass (`shadow_lod`), indexing the same vertices.
    pub(super) shadow_indices: wgpu::Buffer,
    pub(super) shadow_index_count: u32,
    /// Triangles grouped into spatial clusters (index range, model-frame bounding box), so that
    /// small views draw only the part of a mesh they can see.
    pub(super) clusters: Vec<Cluster>,
}

/// A range of a mesh's reordered indices and the bounding box (min, max) of its triangles.
pub(super) type Cluster = (std::ops::Range<u32>, glam::DVec3, glam::DVec3);

/// Reorders triangles into the cells of an 8x8x8 grid over the mesh's bounding box and returns the
/// new indices with each non-empty cell's index range and bounding box.
pub(super) fn cluster_triangles(mesh: &TexturedMesh) -> (Vec<u32>, Vec<Cluster>) {
    const N: usize = 8;
    let (lo, hi) = mesh.aabb();
    let (lo, size) = (lo.as_dvec3(), (hi - lo).as_dvec3().max(glam::DVec3::splat(1e-9)));
    let p = |i: u32| glam::Vec3::from(mesh.positions[i as usize]).as_dvec3();
    let mut cells: Vec<Vec<[u32; 3]>> = vec![Vec::new(); N * N * N];
    for t in mesh.indices.chunks_exact(3) {
        let c = (p(t[0]) + p(t[1]) + p(t[2])) / 3.0;
        let g = ((c - lo) / size * N as f64).floor().clamp(glam::DVec3::ZERO, glam::DVec3::splat((N - 1) as f64));
        cells[(g.x as usize * N + g.y as usize) * N + g.z as usize].push([t[0], t[1], t[2]]);
    }
    let mut indices = Vec::with_capacity(mesh.indices.len());
    let mut clusters = Vec::new();
    for cell in cells.into_iter().filter(|c| !c.is_empty()) {
        let start = indices.len() as u32;
        let (mut a, mut b) = (glam::DVec3::splat(f64::MAX), glam::DVec3::splat(f64::MIN));
        for t in cell {
            for i in t {
                a = a.min(p(i));
                b = b.max(p(i));
                indices.push(i);
            }
        }
        clusters.push((start..indices.len() as u32, a, b));
    }
    (indices, clusters)
}

/// How far (m) the shadow pass's simplified meshes may stray from the drawn ones: a quarter of a
/// shadow-map texel at 1 m from the light (2.1 mm for the canonical 45° cone and a 1024² map), so
/// the shadows do not change while the pass, which is all triangle setup on a CPU rasterizer (its
/// cost does not depend on the map's size), draws a fraction of the triangles.
pub(super) const SHADOW_LOD_ERROR: f32 = 5e-4;

/// Indices of `mesh` simplified for the shadow pass, within `SHADOW_LOD_ERROR`: positions are
/// welded first (texture seams split a scanned mesh's vertices, and the simplifier cannot
/// collapse across a seam), and the result indexes the mesh's own vertex buffer.
pub(super) fn shadow_lod(mesh: &TexturedMesh) -> Vec<u32> {
    let mut first: std::collections::HashMap<[u32; 3], u32> = std::collections::HashMap::new();
    let welded: Vec<u32> = mesh.indices.iter().map(|&i| *first.entry(mesh.positions[i as usize].map(f32::to_bits)).or_insert(i)).collect();
    let Ok(adapter) = meshopt::VertexDataAdapter::new(bytemuck::cast_slice(&mesh.positions), 12, 0) else {
        return mesh.indices.clone();
    };
    let lod = meshopt::simplify(&welded, &adapter, 0, SHADOW_LOD_ERROR, meshopt::SimplifyOptions::ErrorAbsolute, None);
    if lod.is_empty() { mesh.indices.clone() } else { lod }
}

/// Is the box `[lo, hi]` (model frame) wholly outside the clip volume of `model_view_proj` (wgpu:
/// -w <= x, y <= w, 0 <= z <= w)? Exact for culling: true only when all eight corners lie beyond
/// one clip plane, so a skipped draw could not have produced a fragment (corners behind the
/// camera included: the planes are tested in homogeneous coordinates).
pub(super) fn box_outside_clip(model_view_proj: &DMat4, lo: glam::DVec3, hi: glam::DVec3) -> bool {
    let corners: [glam::DVec4; 8] = std::array::from_fn(|k| {
        let c = glam::DVec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        );
        *model_view_proj * c.extend(1.0)
    });
    let all = |f: &dyn Fn(&glam::DVec4) -> bool| corners.iter().all(f);
    all(&|c| c.x > c.w) || all(&|c| c.x < -c.w) || all(&|c| c.y > c.w) || all(&|c| c.y < -c.w) || all(&|c| c.z > c.w) || all(&|c| c.z < 0.0)
}

/// Does the box `[lo, hi]` (model frame), seen through `model_view`, overlap the view volume
/// `[-hx, hx] x [-hy, hy] x [near, far]` (camera frame)?
pub(super) fn box_overlaps_view(model_view: &DMat4, lo: glam::DVec3, hi: glam::DVec3, cull: [f64; 4]) -> bool {
    let [hx, hy, near, far] = cull;
    let (mut a, mut b) = (glam::DVec3::splat(f64::MAX), glam::DVec3::splat(f64::MIN));
    for k in 0..8 {
        let c = glam::DVec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        );
        let q = model_view.transform_point3(c);
        a = a.min(q);
        b = b.max(q);
    }
    a.x <= hx && b.x >= -hx && a.y <= hy && b.y >= -hy && a.z <= far && b.z >= near
}

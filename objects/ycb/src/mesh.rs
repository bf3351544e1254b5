use glam::Vec3;

/// A linear colour channel (0..1, as in MTL `Kd`, glTF factors and URDF colours) as an sRGB byte
/// (gamma 2.2).
pub fn linear_to_srgb8(x: f64) -> u8 {
    (x.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0).round() as u8
}

/// An RGBA8 texture, sRGB-encoded, row 0 at the top (v = 0).
#[derive(Debug, Clone, PartialEq)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<u8>,
}

impl Texture {
    pub fn solid(rgb: [u8; 3]) -> Self {
        Texture { width: 1, height: 1, rgba: vec![rgb[0], rgb[1], rgb[2], 255] }
    }

    /// The texel under `uv` (repeating, as the renderer's sampler), sRGB RGBA.
    pub fn texel(&self, uv: [f32; 2]) -> [u8; 4] {
        let wrap = |x: f32, n: u32| ((x.rem_euclid(1.0) * n as f32) as u32).min(n - 1) as usize;
        let i = 4 * (wrap(uv[1], self.height) * self.width as usize + wrap(uv[0], self.width));
        [self.rgba[i], self.rgba[i + 1], self.rgba[i + 2], self.rgba[i + 3]]
    }
}

/// A triangle mesh with one base-colour texture, in metres.
#[derive(Debug, Clone, PartialEq)]
pub struct TexturedMesh {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub uvs: Vec<[f32; 2]>,
    /// Triangles, counter-clockwise seen from outside.
    pub indices: Vec<u32>,
    pub texture: Texture,
}

impl TexturedMesh {
    /// No triangles yet, drawn with `texture`.
    pub fn empty(texture: Texture) -> Self {
        TexturedMesh { positions: Vec::new(), normals: Vec::new(), uvs: Vec::new(), indices: Vec::new(), texture }
    }

    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Axis-aligned bounding box (min, max).
    pub fn aabb(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for p in &self.positions {
            let p = Vec3::from(*p);
            lo = lo.min(p);
            hi = hi.max(p);
        }
        (lo, hi)
    }

    /// Per-vertex colours (sRGB RGBA) from the texture: for viewers that take vertex colours
    /// (e.g. the meshes embedded in shards for Foxglove) instead of a multi-megabyte texture.
    pub fn vertex_colors(&self) -> Vec<[u8; 4]> {
        self.uvs.iter().map(|uv| self.texture.texel(*uv)).collect()
    }

    /// Extents of the bounding box.
    pub fn extents(&self) -> Vec3 {
        let (lo, hi) = self.aabb();
        hi - lo
    }

    /// Moves the mesh into the model frame: origin at the bounding-box centre, axes unchanged.
    pub fn center_on_aabb(&mut self) {
        let (lo, hi) = self.aabb();
        let c = (lo + hi) * 0.5;
        for p in &mut self.positions {
            *p = (Vec3::from(*p) - c).into();
        }
    }

    /// Largest distance between two vertices (the BOP "diameter"), metres: see [`diameter_of`].
    pub fn diameter(&self) -> f64 {
        diameter_of(&self.positions)
    }

    /// Recomputes smooth per-vertex normals from the triangles (area-weighted).
    pub fn compute_normals(&mut self) {
        let mut n = vec![Vec3::ZERO; self.positions.len()];
        for t in self.indices.chunks_exact(3) {
            let [a, b, c] = [t[0] as usize, t[1] as usize, t[2] as usize];
            let pa = Vec3::from(self.positions[a]);
            let fn_ = (Vec3::from(self.positions[b]) - pa).cross(Vec3::from(self.positions[c]) - pa);
            n[a] += fn_;
            n[b] += fn_;
            n[c] += fn_;
        }
        self.normals = n.into_iter().map(|v| v.normalize_or(Vec3::Z).into()).collect();
    }
}

/// Largest distance between two vertices (the BOP "diameter", as `bop_toolkit`'s
/// `calc_pts_diameter` computes it), metres, exact for any number of vertices. A pair's distance is
/// at most the sum of its points' distances from the bounding box's centre, so with the points
/// sorted by that distance only the pairs whose bound beats the best pair so far are measured:
/// on scanned meshes a small fraction of all pairs.
pub fn diameter_of(positions: &[[f32; 3]]) -> f64 {
    let pts: Vec<glam::DVec3> = positions.iter().map(|p| Vec3::from(*p).as_dvec3()).collect();
    let Some(first) = pts.first() else { return 0.0 };
    let (lo, hi) = pts.iter().fold((*first, *first), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let centre = 0.5 * (lo + hi);
    let mut by_reach: Vec<(f64, glam::DVec3)> = pts.iter().map(|p| (p.distance(centre), *p)).collect();
    by_reach.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut best = 0.0f64;
    for (i, &(ri, pi)) in by_reach.iter().enumerate() {
        if ri + by_reach[0].0 <= best {
            break;
        }
        for &(rj, pj) in &by_reach[..i] {
            if ri + rj <= best {
                break;
            }
            best = best.max(pi.distance(pj));
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute_force(positions: &[[f32; 3]]) -> f64 {
        let pts: Vec<glam::DVec3> = positions.iter().map(|p| Vec3::from(*p).as_dvec3()).collect();
        pts.iter().enumerate().flat_map(|(i, a)| pts[i + 1..].iter().map(move |b| a.distance(*b))).fold(0.0, f64::max)
    }

    /// Exact on clouds past the size where an estimate used to take over (3000 vertices): a
    /// flattened blob, a long rod with a bump and a sphere shell, from a fixed LCG.
    #[test]
    fn the_diameter_is_the_farthest_vertex_pair_exactly() {
        let mut state = 12345u64;
        let mut next = move || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
        };
        let shapes: [&dyn Fn([f32; 3]) -> [f32; 3]; 3] = [
            &|[x, y, z]| [0.06 * x, 0.04 * y, 0.01 * z],
            &|[x, y, z]| [0.2 * x, 0.01 * y + if x > 0.9 { 0.03 } else { 0.0 }, 0.01 * z],
            &|[x, y, z]| {
                let n = (x * x + y * y + z * z).sqrt().max(1e-6);
                [0.05 * x / n, 0.05 * y / n, 0.05 * z / n]
            },
        ];
        for shape in shapes {
            let positions: Vec<[f32; 3]> = (0..4000).map(|_| shape([next(), next(), next()])).collect();
            assert_eq!(diameter_of(&positions), brute_force(&positions));
        }
        assert_eq!(diameter_of(&[]), 0.0);
        assert_eq!(diameter_of(&[[1.0, 2.0, 3.0]]), 0.0);
    }
}

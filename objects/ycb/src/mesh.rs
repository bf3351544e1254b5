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

/// Largest distance between two vertices (the BOP "diameter"), metres. Exact for meshes up to
/// a few thousand vertices; for larger meshes it is computed on the convex-hull candidates
/// (the extreme vertices along 64 directions), which is exact for practical scans to < 0.1 mm.
pub fn diameter_of(positions: &[[f32; 3]]) -> f64 {
    let pts: Vec<Vec3> = if positions.len() <= 3000 {
        positions.iter().map(|p| Vec3::from(*p)).collect()
    } else {
        let mut idx = std::collections::BTreeSet::new();
        let n = 16;
        for i in 0..n {
            for j in 0..n {
                let th = std::f32::consts::PI * (i as f32 + 0.5) / n as f32;
                let ph = 2.0 * std::f32::consts::PI * j as f32 / n as f32;
                let d = Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
                let (mut best_hi, mut best_lo) = (0usize, 0usize);
                let (mut vhi, mut vlo) = (f32::NEG_INFINITY, f32::INFINITY);
                for (k, p) in positions.iter().enumerate() {
                    let v = d.dot(Vec3::from(*p));
                    if v > vhi {
                        vhi = v;
                        best_hi = k;
                    }
                    if v < vlo {
                        vlo = v;
                        best_lo = k;
                    }
                }
                idx.insert(best_hi);
                idx.insert(best_lo);
            }
        }
        idx.into_iter().map(|k| Vec3::from(positions[k])).collect()
    };
    let mut best = 0.0f64;
    for (i, a) in pts.iter().enumerate() {
        for b in &pts[i + 1..] {
            best = best.max(a.distance(*b) as f64);
        }
    }
    best
}

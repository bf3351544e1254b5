//! Procedural stand-ins for the catalogue objects: the right size (the scan's bounding box exactly),
//! the rough shape (box, can, bottle, mug, banana, drill, flat tools) and a procedural label texture,
//! so that the default job runs without downloading the YCB meshes.

use glam::{Vec2, Vec3};

use crate::catalog::{CatalogEntry, Shape};
use crate::mesh::{Texture, TexturedMesh};

/// Which half of the texture atlas a part samples: the printed label or the plain secondary colour.
#[derive(Clone, Copy)]
enum Region {
    Label,
    Plain,
}

impl Region {
    fn map(self, uv: Vec2) -> [f32; 2] {
        let (u0, u1) = match self {
            Region::Label => (0.01, 0.49),
            Region::Plain => (0.51, 0.99),
        };
        [u0 + (u1 - u0) * uv.x.clamp(0.0, 1.0), 0.01 + 0.98 * uv.y.clamp(0.0, 1.0)]
    }
}

/// The 6 faces of an axis-aligned box as (outward normal, u, v) with `u x v = normal`: corners
/// `normal ± u ± v` (scaled by the half extents) in the order (-,-), (+,-), (+,+), (-,+) are wound
/// counter-clockwise seen from outside.
pub const BOX_FACES: [(Vec3, Vec3, Vec3); 6] = [
    (Vec3::X, Vec3::Y, Vec3::Z),
    (Vec3::NEG_X, Vec3::NEG_Y, Vec3::Z),
    (Vec3::Y, Vec3::NEG_X, Vec3::Z),
    (Vec3::NEG_Y, Vec3::X, Vec3::Z),
    (Vec3::Z, Vec3::X, Vec3::Y),
    (Vec3::NEG_Z, Vec3::X, Vec3::NEG_Y),
];

#[derive(Default)]
struct Builder {
    positions: Vec<Vec3>,
    uvs: Vec<[f32; 2]>,
    indices: Vec<u32>,
}

impl Builder {
    fn vertex(&mut self, p: Vec3, uv: [f32; 2]) -> u32 {
        self.positions.push(p);
        self.uvs.push(uv);
        (self.positions.len() - 1) as u32
    }

    /// Axis-aligned box; faces wound counter-clockwise seen from outside.
    fn cuboid(&mut self, center: Vec3, half: Vec3, region: Region) {
        for (n, u, v) in BOX_FACES {
            let c = center + n * half;
            let (hu, hv) = (u * half, v * half);
            let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
            let base = self.positions.len() as u32;
            for (a, b) in corners {
                let uv = Vec2::new((a + 1.0) * 0.5, 1.0 - (b + 1.0) * 0.5);
                self.vertex(c + hu * a + hv * b, region.map(uv));
            }
            self.indices.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
        }
    }

    /// Surface of revolution about the z axis through `center`. `profile` is (radius, z), traversed
    /// counter-clockwise in the (r, z) half-plane (bottom centre, outwards, up, inwards) so faces point
    /// out of the solid; repeat a point to make a crease. `squareness` 2 gives circles, larger values
    /// give rounded rectangles (a superellipse cross-section).
    fn lathe(&mut self, center: Vec3, profile: &[(f32, f32)], segments: u32, squareness: f32, region: Region) {
        let mut len = vec![0.0f32];
        for w in profile.windows(2) {
            let d = Vec2::new(w[1].0 - w[0].0, w[1].1 - w[0].1).length();
            len.push(len.last().unwrap() + d);
        }
        let total = len.last().copied().unwrap_or(1.0).max(1e-9);
        let base = self.positions.len() as u32;
        let ring = segments + 1;
        for (i, &(r, z)) in profile.iter().enumerate() {
            for j in 0..ring {
                let th = std::f32::consts::TAU * j as f32 / segments as f32;
                let (s, c) = th.sin_cos();
                let e = 2.0 / squareness;
                let x = c.signum() * c.abs().powf(e);
                let y = s.signum() * s.abs().powf(e);
                let uv = Vec2::new(j as f32 / segments as f32, 1.0 - len[i] / total);
                self.vertex(center + Vec3::new(r * x, r * y, z), region.map(uv));
            }
        }
        for i in 0..profile.len() as u32 - 1 {
            for j in 0..segments {
                let a = base + i * ring + j;
                let b = a + 1;
                let d = a + ring;
                let c = d + 1;
                self.indices.extend([a, b, c, a, c, d]);
            }
        }
    }

    /// A tube of varying radius swept along `path`, with closed ends.
    fn tube(&mut self, path: &[Vec3], radii: &[f32], segments: u32, region: Region) {
        let n = path.len();
        let tangent = |k: usize| (path[(k + 1).min(n - 1)] - path[k.saturating_sub(1)]).normalize();
        // Parallel-transported frame (t, nrm, bin) with bin = t x nrm: right-handed, so faces point out.
        let mut prev = tangent(0);
        let mut nrm = prev.any_orthonormal_vector();
        let base = self.positions.len() as u32;
        let ring = segments + 1;
        let mut frames = Vec::with_capacity(n);
        for k in 0..n {
            // Rotate the normal with the tangent (parallel transport): it never twists or flips.
            let t = tangent(k);
            nrm = (glam::Quat::from_rotation_arc(prev, t) * nrm).normalize();
            prev = t;
            frames.push((t, nrm, t.cross(nrm)));
        }
        for k in 0..n {
            let (_, nn, bb) = frames[k];
            for j in 0..ring {
                let ph = std::f32::consts::TAU * j as f32 / segments as f32;
                let (s, c) = ph.sin_cos();
                let uv = Vec2::new(j as f32 / segments as f32, k as f32 / (n - 1) as f32);
                self.vertex(path[k] + (nn * c + bb * s) * radii[k], region.map(uv));
            }
        }
        for k in 0..n as u32 - 1 {
            for j in 0..segments {
                let a = base + k * ring + j;
                let b = a + 1;
                let d = a + ring;
                let c = d + 1;
                self.indices.extend([a, b, c, a, c, d]);
            }
        }
        // End caps as fans.
        let c0 = self.vertex(path[0], region.map(Vec2::new(0.5, 0.0)));
        let c1 = self.vertex(path[n - 1], region.map(Vec2::new(0.5, 1.0)));
        let last = base + (n as u32 - 1) * ring;
        for j in 0..segments {
            self.indices.extend([c0, base + j + 1, base + j]);
            self.indices.extend([c1, last + j, last + j + 1]);
        }
    }

    fn finish(self, extents: [f64; 3], texture: Texture) -> TexturedMesh {
        let mut mesh = TexturedMesh {
            positions: self.positions.iter().map(|p| (*p).into()).collect(),
            normals: Vec::new(),
            uvs: self.uvs,
            indices: self.indices,
            texture,
        };
        // Scale to the scan's bounding box exactly, then centre.
        let ext = mesh.extents();
        let s = Vec3::new(extents[0] as f32, extents[1] as f32, extents[2] as f32) / ext.max(Vec3::splat(1e-9));
        for p in &mut mesh.positions {
            *p = (Vec3::from(*p) * s).into();
        }
        mesh.center_on_aabb();
        mesh.compute_normals();
        mesh
    }
}

fn arc(center: Vec3, radius: f32, from: f32, to: f32, n: usize, plane: (Vec3, Vec3)) -> Vec<Vec3> {
    (0..n)
        .map(|k| {
            let a = from + (to - from) * k as f32 / (n - 1) as f32;
            center + (plane.0 * a.cos() + plane.1 * a.sin()) * radius
        })
        .collect()
}

/// Builds the procedural stand-in of a catalogue object, in the model frame, scaled to its extents.
// Long on purpose: one arm per object shape in the catalogue, each a few primitives.
pub fn procedural_mesh(entry: &CatalogEntry) -> TexturedMesh {
    let mut b = Builder::default();
    let seg = 48;
    match entry.shape {
        Shape::Box => b.cuboid(Vec3::ZERO, Vec3::splat(0.5), Region::Label),
        Shape::RoundedBox => {
            b.lathe(Vec3::ZERO, &[(0.0, 0.0), (0.9, 0.0), (1.0, 0.04), (1.0, 0.96), (0.9, 1.0), (0.0, 1.0)], seg, 5.0, Region::Label)
        }
        Shape::Can => b.lathe(
            Vec3::ZERO,
            &[(0.0, 0.02), (0.93, 0.02), (0.97, 0.0), (1.0, 0.03), (1.0, 0.97), (0.97, 1.0), (0.93, 0.98), (0.0, 0.98)],
            seg,
            2.0,
            Region::Label,
        ),
        Shape::Bottle => {
            b.lathe(
                Vec3::ZERO,
                &[(0.0, 0.0), (0.95, 0.0), (1.0, 0.05), (1.0, 0.62), (0.85, 0.72), (0.45, 0.8), (0.3, 0.82), (0.0, 0.82)],
                seg,
                3.0,
                Region::Label,
            );
            // Cap and the off-centre spout that breaks the symmetry, as on the real bottle.
            b.lathe(Vec3::new(0.0, 0.0, 0.8), &[(0.0, 0.0), (0.32, 0.0), (0.32, 0.1), (0.0, 0.1)], seg, 2.0, Region::Plain);
            b.tube(&[Vec3::new(0.1, 0.0, 0.88), Vec3::new(0.22, 0.0, 1.0)], &[0.08, 0.03], 16, Region::Plain);
        }
        Shape::Banana => {
            let path = arc(Vec3::new(-1.0, 0.0, 0.0), 1.0, -0.9, 0.9, 24, (Vec3::X, Vec3::Y));
            let radii: Vec<f32> = (0..path.len())
                .map(|k| {
                    let s = k as f32 / (path.len() - 1) as f32;
                    0.02 + 0.16 * (std::f32::consts::PI * s).sin().max(0.0).powf(0.6)
                })
                .collect();
            b.tube(&path, &radii, 24, Region::Label);
        }
        Shape::Mug => {
            b.lathe(
                Vec3::ZERO,
                &[
                    (0.0, 0.0),
                    (0.5, 0.0),
                    (0.5, 0.0),
                    (0.5, 1.0),
                    (0.5, 1.0),
                    (0.45, 1.0),
                    (0.45, 1.0),
                    (0.45, 0.08),
                    (0.45, 0.08),
                    (0.0, 0.08),
                ],
                seg,
                2.0,
                Region::Label,
            );
            let handle = arc(Vec3::new(0.5, 0.0, 0.5), 0.3, -1.5, 1.5, 20, (Vec3::Z, Vec3::X));
            b.tube(&handle, &vec![0.06; handle.len()], 16, Region::Plain);
        }
        Shape::Drill => {
            // Lies flat like the scan: barrel along x, grip along -y, battery at the grip's end.
            b.tube(&[Vec3::new(-0.5, 0.25, 0.0), Vec3::new(0.2, 0.25, 0.0)], &[0.15, 0.15], 32, Region::Label);
            b.tube(&[Vec3::new(0.2, 0.25, 0.0), Vec3::new(0.5, 0.25, 0.0)], &[0.07, 0.05], 24, Region::Plain);
            b.cuboid(Vec3::new(-0.3, -0.05, 0.0), Vec3::new(0.09, 0.3, 0.12), Region::Label);
            b.cuboid(Vec3::new(-0.3, -0.45, 0.0), Vec3::new(0.2, 0.1, 0.15), Region::Plain);
        }
        Shape::Scissors => {
            b.cuboid(Vec3::new(-0.05, 0.25, 0.0), Vec3::new(0.06, 0.5, 0.03), Region::Plain);
            b.cuboid(Vec3::new(0.07, 0.25, 0.0), Vec3::new(0.05, 0.48, 0.03), Region::Plain);
            for x in [-0.25, 0.25] {
                let ring = arc(Vec3::new(x, -0.45, 0.0), 0.18, 0.0, std::f32::consts::TAU, 24, (Vec3::X, Vec3::Y));
                b.tube(&ring, &vec![0.06; ring.len()], 12, Region::Label);
            }
        }
        Shape::Wrench => {
            b.cuboid(Vec3::new(0.0, -0.2, 0.0), Vec3::new(0.12, 0.6, 0.05), Region::Label);
            let head = arc(Vec3::new(0.0, 0.55, 0.0), 0.3, -1.2, 4.3, 28, (Vec3::X, Vec3::Y));
            b.tube(&head, &vec![0.12; head.len()], 12, Region::Plain);
        }
    }
    b.finish(entry.extents, label_texture(entry))
}

/// A deterministic label-like texture: the left half is the printed label (primary colour, bands of
/// the secondary colour, dark and light "text" blocks), the right half the plain secondary colour.
fn label_texture(entry: &CatalogEntry) -> Texture {
    let (w, h) = (512u32, 256u32);
    let [p, s] = entry.colors;
    // FNV-1a of the id: a stable per-object pattern.
    let mut hash = entry.id.bytes().fold(0xcbf29ce484222325u64, |h, b| (h ^ b as u64).wrapping_mul(0x100000001b3));
    let mut next = || {
        hash ^= hash << 13;
        hash ^= hash >> 7;
        hash ^= hash << 17;
        hash
    };
    let blocks: Vec<(u32, u32, u32, u32, [u8; 3])> = (0..14)
        .map(|k| {
            let bw = 20 + (next() % 90) as u32;
            let bh = 6 + (next() % 22) as u32;
            let x = 8 + (next() % (240 - bw as u64)) as u32;
            let y = 8 + (next() % (240 - bh as u64)) as u32;
            let c = if k % 3 == 0 {
                [245, 245, 240]
            } else if k % 3 == 1 {
                [25, 25, 30]
            } else {
                s
            };
            (x, y, bw, bh, c)
        })
        .collect();
    let band_a = 40 + (next() % 40) as u32;
    let band_b = 170 + (next() % 40) as u32;
    let mut rgba = Vec::with_capacity((w * h * 4) as usize);
    for y in 0..h {
        for x in 0..w {
            let c = if x < w / 2 {
                let mut c = p;
                if (band_a..band_a + 18).contains(&y) || (band_b..band_b + 12).contains(&y) {
                    c = s;
                }
                for &(bx, by, bw, bh, bc) in &blocks {
                    if (bx..bx + bw).contains(&x) && (by..by + bh).contains(&y) && ((x / 3 + y / 2) % 4 != 0) {
                        c = bc;
                    }
                }
                c
            } else {
                let shade = if (x / 8 + y / 8) % 2 == 0 { 0 } else { 12 };
                [s[0].saturating_sub(shade), s[1].saturating_sub(shade), s[2].saturating_sub(shade)]
            };
            rgba.extend([c[0], c[1], c[2], 255]);
        }
    }
    Texture { width: w, height: h, rgba }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::catalog::Catalog;

    /// Signed volume by the divergence theorem: positive when faces point outwards.
    fn signed_volume(m: &TexturedMesh) -> f64 {
        m.indices
            .chunks_exact(3)
            .map(|t| {
                let [a, b, c] = [t[0], t[1], t[2]].map(|i| Vec3::from(m.positions[i as usize]).as_dvec3());
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    #[test]
    fn stand_ins_match_the_catalogue_extents_and_face_outwards() {
        for e in Catalog::builtin().entries() {
            let m = procedural_mesh(e);
            let ext = m.extents();
            for k in 0..3 {
                assert!((ext[k] as f64 - e.extents[k]).abs() < 1e-5, "{} axis {k}: {} vs {}", e.id, ext[k], e.extents[k]);
            }
            let (lo, hi) = m.aabb();
            assert!((lo + hi).length() < 1e-5, "{} is centred", e.id);
            let box_volume = e.extents.iter().product::<f64>();
            let v = signed_volume(&m);
            assert!(v > 0.03 * box_volume && v < 1.01 * box_volume, "{}: volume {v} vs box {box_volume}", e.id);
            assert_eq!(m.normals.len(), m.positions.len());
            assert!(m.texture.rgba.len() == (m.texture.width * m.texture.height * 4) as usize);
        }
    }
}

//! The occlusion level of a sample, as the paper computes it: the object's model points moved by
//! the ground-truth pose; a point is visible when the main camera's depth point cloud has a point
//! within ε of it (searched in the image window that can hold one); occlusion = share of model
//! points not visible.
//! Self-occlusion counts: the far side of an object is never visible.

use glam::DVec3;
use vt_objects::{SurfaceSampler, TexturedMesh};

use crate::config::Intrinsics;

/// `n` points spread over the mesh surface by area (a fixed, seed-free sequence: the same model
/// always gives the same points).
pub fn model_points(mesh: &TexturedMesh, n: usize) -> Vec<DVec3> {
    let surface = SurfaceSampler::from_mesh(&mesh.positions, mesh.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]));
    if surface.is_empty() {
        return Vec::new();
    }
    // A low-discrepancy (R2) sequence: even coverage without a random generator.
    let (a1, a2, a3) = (0.819_172_513_396_164_4, 0.671_043_606_703_789_2, 0.549_730_125_185_948_4);
    (0..n)
        .map(|i| {
            let i = i as f64 + 0.5;
            surface.sample((a1 * i).fract(), (a2 * i).fract(), (a3 * i).fract())
        })
        .collect()
}

/// Whether some depth pixel back-projects to within ε of `p` (camera frame). A point `p + δ` with
/// |δ| ≤ ε projects within `f ε (z + |x|) / (z (z − ε))` pixels of `p`'s projection along each
/// image axis, so only the depth pixels in that window (plus one for rounding) can be close
/// enough: the answer is exact, as a nearest-neighbour search over the whole cloud would give.
fn has_depth_point_near(p: DVec3, depth: &[f32], width: u32, height: u32, k: &Intrinsics, epsilon: f64) -> bool {
    let (w, h) = (width as i64, height as i64);
    let (u_range, v_range) = if p.z > epsilon * 1.001 {
        let u = k.fx * p.x / p.z + k.cx;
        let v = k.fy * p.y / p.z + k.cy;
        let ru = k.fx * epsilon * (p.z + p.x.abs()) / (p.z * (p.z - epsilon)) + 1.0;
        let rv = k.fy * epsilon * (p.z + p.y.abs()) / (p.z * (p.z - epsilon)) + 1.0;
        let clamp = |lo: f64, hi: f64, n: i64| ((lo.floor() as i64).max(0), (hi.ceil() as i64).min(n - 1));
        (clamp(u - ru, u + ru, w), clamp(v - rv, v + rv, h))
    } else {
        // Closer to the camera than ε: no useful bound, look everywhere.
        ((0, w - 1), (0, h - 1))
    };
    let eps2 = epsilon * epsilon;
    for v in v_range.0..=v_range.1 {
        for u in u_range.0..=u_range.1 {
            let d = depth[(v * w + u) as usize] as f64;
            if d > 0.0 && d.is_finite() {
                let c = DVec3::new((u as f64 - k.cx) * d / k.fx, (v as f64 - k.cy) * d / k.fy, d);
                if c.distance_squared(p) <= eps2 {
                    return true;
                }
            }
        }
    }
    false
}

/// Occlusion level (0…1) and the number of visible points, for model points in the camera frame.
pub fn occlusion_level(points: &[DVec3], depth: &[f32], width: u32, height: u32, k: &Intrinsics, epsilon: f64) -> (f64, usize) {
    if points.is_empty() {
        return (1.0, 0);
    }
    let visible = points.iter().filter(|p| has_depth_point_near(**p, depth, width, height, k, epsilon)).count();
    (1.0 - visible as f64 / points.len() as f64, visible)
}

/// The same by comparing every model point with every depth point (for tests).
pub fn occlusion_level_brute_force(points: &[DVec3], depth: &[f32], width: u32, height: u32, k: &Intrinsics, epsilon: f64) -> (f64, usize) {
    // Every depth pixel back-projected.
    let cloud: Vec<DVec3> = (0..height as usize)
        .flat_map(|v| (0..width as usize).map(move |u| (u, v)))
        .filter_map(|(u, v)| {
            let d = depth[v * width as usize + u] as f64;
            (d > 0.0 && d.is_finite()).then(|| DVec3::new((u as f64 - k.cx) * d / k.fx, (v as f64 - k.cy) * d / k.fy, d))
        })
        .collect();
    let visible = points.iter().filter(|p| cloud.iter().any(|c| c.distance(**p) <= epsilon)).count();
    (1.0 - visible as f64 / points.len().max(1) as f64, visible)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 64x48 depth image of a wall facing the camera at `wall` m.
    fn wall(wall: f32) -> (Vec<f32>, Intrinsics) {
        (vec![wall; 64 * 48], Intrinsics { fx: 60.0, fy: 60.0, cx: 31.5, cy: 23.5 })
    }

    #[test]
    fn points_on_the_seen_surface_are_visible_and_points_behind_it_are_not() {
        let (depth, k) = wall(1.0);
        // A grid of points on the wall, and the same grid 5 cm behind it.
        let on: Vec<DVec3> = (0..40).map(|i| DVec3::new(-0.2 + 0.01 * i as f64, 0.1 - 0.005 * i as f64, 1.0)).collect();
        let behind: Vec<DVec3> = on.iter().map(|p| *p * 1.05).collect();
        // Pixels are 1.7 cm apart on the wall: every point is within 1.2 cm of one.
        assert_eq!(occlusion_level(&on, &depth, 64, 48, &k, 0.02), (0.0, 40));
        assert_eq!(occlusion_level(&behind, &depth, 64, 48, &k, 0.02), (1.0, 0));
        let half: Vec<DVec3> = on.iter().take(10).chain(behind.iter().take(30)).copied().collect();
        let (level, visible) = occlusion_level(&half, &depth, 64, 48, &k, 0.02);
        assert_eq!((level, visible), (0.75, 10));
        assert_eq!(vt_dataset::OcclusionBin::of(level), Some(vt_dataset::OcclusionBin::Below80));
        // The windowed search answers as the search over the whole cloud does.
        for eps in [0.002, 0.01, 0.03, 0.06] {
            assert_eq!(occlusion_level(&half, &depth, 64, 48, &k, eps), occlusion_level_brute_force(&half, &depth, 64, 48, &k, eps));
        }
        // Nothing seen: no depth anywhere.
        assert_eq!(occlusion_level(&on, &vec![0.0; 64 * 48], 64, 48, &k, 0.02), (1.0, 0));
    }

    #[test]
    fn model_points_lie_on_the_mesh_and_spread_by_area() {
        // Two triangles: a unit square at z = 0 (area 1) and a small one at z = 1 (area 0.125).
        let mesh = TexturedMesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
                [0.5, 0.0, 1.0],
                [0.0, 0.5, 1.0],
            ],
            normals: vec![[0.0, 0.0, 1.0]; 7],
            uvs: vec![[0.0, 0.0]; 7],
            indices: vec![0, 1, 2, 0, 2, 3, 4, 5, 6],
            texture: vt_objects::Texture::solid([128, 128, 128]),
        };
        let pts = model_points(&mesh, 900);
        assert_eq!(pts, model_points(&mesh, 900));
        let high = pts.iter().filter(|p| p.z == 1.0).count();
        assert!(pts.iter().all(|p| p.z == 0.0 || p.z == 1.0));
        assert!(pts.iter().filter(|p| p.z == 0.0).all(|p| (0.0..=1.0).contains(&p.x) && (0.0..=1.0).contains(&p.y)));
        assert!(pts.iter().filter(|p| p.z == 1.0).all(|p| p.x + p.y <= 0.5 + 1e-12));
        // 1/9 of the area: 100 of 900 points, within a low-discrepancy sequence's few.
        assert!((90..=110).contains(&high), "{high}");
    }
}

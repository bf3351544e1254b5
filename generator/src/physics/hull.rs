//! Convex collision hulls with few vertices. A scanned YCB mesh's hull has 240 to 3 400 vertices and
//! an Allegro fingertip's 600, most of them on rounded edges a tenth of a millimetre apart. rapier
//! pays for every vertex at every step (the moving hull's bounding box is recomputed from all of
//! them, and each support query scans them), so the hulls are reduced once, at load, to the
//! vertices that keep the shape within a tolerance.
//!
//! The reduced hull is the hull of a subset of the exact hull's vertices, so it lies inside the
//! exact hull (never a contact the exact shape would not make), and every exact vertex lies within
//! `tolerance` of the reduced hull's face planes (tested below).

use glam::Vec3;
use rapier3d::parry::transformation::convex_hull;

/// How far (m) an exact hull vertex may lie outside the reduced hull's face planes: a tenth of the
/// recorded penetration's 1 mm limit, and a fraction of a pixel of the paper camera.
pub const HULL_TOLERANCE: f32 = 1e-4;

/// Below this many vertices a hull is kept whole: the reduction would not pay.
const KEEP_WHOLE: usize = 48;

/// Exact hull vertices added per refinement round (the farthest outside the current hull first).
const ADD_PER_ROUND: usize = 8;

/// The vertices of a convex hull of `points` with few vertices, within `tolerance` of the exact
/// hull (see the module comment). Degenerate input (fewer than four points off a plane) comes
/// back as the exact hull's vertices, for the caller's hull builder to refuse.
pub fn reduced_hull(points: &[Vec3], tolerance: f32) -> Vec<Vec3> {
    if points.len() < 4 {
        return points.to_vec();
    }
    let (exact, _) = convex_hull(points);
    if exact.len() <= KEEP_WHOLE {
        return exact;
    }
    // Start from the extreme vertices along 26 directions (the axes, the face and the corner
    // diagonals of a cube): a box-like object is then nearly done.
    let mut chosen: Vec<usize> = Vec::new();
    for x in -1..=1 {
        for y in -1..=1 {
            for z in -1..=1 {
                if (x, y, z) == (0, 0, 0) {
                    continue;
                }
                let d = Vec3::new(x as f32, y as f32, z as f32);
                let best = (0..exact.len()).max_by(|&a, &b| exact[a].dot(d).total_cmp(&exact[b].dot(d))).expect("non-empty");
                if !chosen.contains(&best) {
                    chosen.push(best);
                }
            }
        }
    }
    loop {
        let subset: Vec<Vec3> = chosen.iter().map(|&i| exact[i]).collect();
        let planes = face_planes(&subset);
        if planes.len() < 4 {
            return exact;
        }
        let mut outside: Vec<(f32, usize)> = (0..exact.len())
            .filter(|i| !chosen.contains(i))
            .map(|i| (planes.iter().map(|(n, d)| n.dot(exact[i]) - d).fold(f32::MIN, f32::max), i))
            .filter(|(dist, _)| *dist > tolerance)
            .collect();
        if outside.is_empty() {
            return subset;
        }
        outside.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        chosen.extend(outside.iter().take(ADD_PER_ROUND).map(|&(_, i)| i));
    }
}

/// Outward unit normals and offsets (`n · p = d` on the plane) of the faces of the hull of
/// `points`; faces of no area are skipped.
fn face_planes(points: &[Vec3]) -> Vec<(Vec3, f32)> {
    let (v, faces) = convex_hull(points);
    if v.is_empty() {
        return Vec::new();
    }
    let centroid = v.iter().copied().sum::<Vec3>() / v.len() as f32;
    faces
        .iter()
        .filter_map(|f| {
            let (a, b, c) = (v[f[0] as usize], v[f[1] as usize], v[f[2] as usize]);
            let n = (b - a).cross(c - a).try_normalize()?;
            // Oriented away from the centroid, whatever the winding.
            let n = if n.dot(centroid - a) > 0.0 { -n } else { n };
            Some((n, n.dot(a)))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rounded box: the kind of hull (many vertices on rounded edges) the reduction is for.
    fn rounded_box() -> Vec<Vec3> {
        let mut pts = Vec::new();
        let (half, r) = (Vec3::new(0.08, 0.03, 0.1), 0.004);
        for i in 0..40 {
            for j in 0..20 {
                let (th, ph) = (i as f32 / 40.0 * std::f32::consts::TAU, (j as f32 / 19.0 - 0.5) * std::f32::consts::PI);
                let n = Vec3::new(ph.cos() * th.cos(), ph.cos() * th.sin(), ph.sin());
                for corner in [Vec3::ONE, Vec3::new(-1.0, 1.0, 1.0), Vec3::new(1.0, -1.0, 1.0), Vec3::new(1.0, 1.0, -1.0)] {
                    for s in [1.0, -1.0] {
                        pts.push(half * corner * s + n * r);
                    }
                }
            }
        }
        pts
    }

    #[test]
    fn a_reduced_hull_has_far_fewer_vertices_and_every_exact_vertex_within_tolerance() {
        let pts = rounded_box();
        let (exact, _) = convex_hull(&pts);
        let reduced = reduced_hull(&pts, HULL_TOLERANCE);
        assert!(exact.len() > 400, "the test shape has {} hull vertices", exact.len());
        assert!(reduced.len() * 2 < exact.len(), "{} of {} vertices kept", reduced.len(), exact.len());
        // Every reduced vertex is an exact one (so the reduced hull lies inside the exact hull)…
        assert!(reduced.iter().all(|p| exact.contains(p)));
        // …and every exact vertex lies within the tolerance of the reduced hull's planes.
        let planes = face_planes(&reduced);
        let worst = exact.iter().map(|p| planes.iter().map(|(n, d)| n.dot(*p) - d).fold(f32::MIN, f32::max)).fold(f32::MIN, f32::max);
        assert!(worst <= HULL_TOLERANCE, "an exact vertex lies {worst} m outside");
    }

    #[test]
    fn small_hulls_are_kept_whole() {
        let cube: Vec<Vec3> = (0..8).map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32)).collect();
        assert_eq!(reduced_hull(&cube, HULL_TOLERANCE).len(), 8);
    }
}

//! Exact closest points on a triangle mesh: a bounding-volume hierarchy over the triangles and the
//! closest point of one triangle.

use glam::DVec3;

/// A bounding-volume hierarchy over triangles for exact closest-point distances.
pub(super) struct Bvh {
    tris: Vec<[DVec3; 3]>,
    /// Unit normals of `tris`.
    normals: Vec<DVec3>,
    nodes: Vec<BvhNode>,
}

struct BvhNode {
    lo: DVec3,
    hi: DVec3,
    /// Leaf: `tris[start..end]`; inner: children `start` and `end`.
    start: usize,
    end: usize,
    leaf: bool,
}

const LEAF_SIZE: usize = 4;

impl Bvh {
    pub(super) fn new(mut tris: Vec<[DVec3; 3]>) -> Self {
        let mut nodes = Vec::with_capacity(2 * tris.len() / LEAF_SIZE + 2);
        if !tris.is_empty() {
            let n = tris.len();
            Self::build(&mut nodes, &mut tris, 0, n);
        }
        let normals = tris.iter().map(|[a, b, c]| (*b - *a).cross(*c - *a).normalize()).collect();
        Bvh { tris, normals, nodes }
    }

    /// Builds the node over `tris[start..end]` (median split along the widest centroid extent);
    /// returns its index.
    fn build(nodes: &mut Vec<BvhNode>, tris: &mut [[DVec3; 3]], start: usize, end: usize) -> usize {
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        let (mut clo, mut chi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for t in &tris[start..end] {
            for p in t {
                lo = lo.min(*p);
                hi = hi.max(*p);
            }
            let c = (t[0] + t[1] + t[2]) / 3.0;
            clo = clo.min(c);
            chi = chi.max(c);
        }
        let index = nodes.len();
        nodes.push(BvhNode { lo, hi, start, end, leaf: true });
        if end - start > LEAF_SIZE {
            let ext = chi - clo;
            let axis = if ext.x >= ext.y && ext.x >= ext.z {
                0
            } else if ext.y >= ext.z {
                1
            } else {
                2
            };
            let mid = (start + end) / 2;
            let key = |t: &[DVec3; 3]| t[0][axis] + t[1][axis] + t[2][axis];
            tris[start..end].select_nth_unstable_by(mid - start, |a, b| key(a).total_cmp(&key(b)));
            let left = Self::build(nodes, tris, start, mid);
            let right = Self::build(nodes, tris, mid, end);
            nodes[index] = BvhNode { lo, hi, start: left, end: right, leaf: false };
        }
        index
    }

    fn box_distance_sq(n: &BvhNode, p: DVec3) -> f64 {
        let d = (n.lo - p).max(p - n.hi).max(DVec3::ZERO);
        d.length_squared()
    }

    /// Squared distance from `p` to the closest point of the surface.
    pub(super) fn distance_sq(&self, p: DVec3, stack: &mut Vec<usize>) -> f64 {
        self.closest(p, f64::INFINITY, stack).map_or(f64::INFINITY, |c| c.0)
    }

    /// The closest point of the surface to `p` if it is nearer than √`cap_sq`: squared distance,
    /// point, and the normal of its triangle.
    pub(super) fn closest(&self, p: DVec3, cap_sq: f64, stack: &mut Vec<usize>) -> Option<(f64, DVec3, DVec3)> {
        let mut best = cap_sq;
        let mut found = None;
        if self.nodes.is_empty() {
            return None;
        }
        stack.clear();
        stack.push(0);
        while let Some(i) = stack.pop() {
            let n = &self.nodes[i];
            if Self::box_distance_sq(n, p) >= best {
                continue;
            }
            if n.leaf {
                for k in n.start..n.end {
                    let q = closest_point_on_triangle(p, &self.tris[k]);
                    let d = (q - p).length_squared();
                    if d < best {
                        best = d;
                        found = Some((q, k));
                    }
                }
            } else {
                // Nearer child last, so it is searched first.
                let (dl, dr) = (Self::box_distance_sq(&self.nodes[n.start], p), Self::box_distance_sq(&self.nodes[n.end], p));
                if dl < dr {
                    stack.extend([n.end, n.start]);
                } else {
                    stack.extend([n.start, n.end]);
                }
            }
        }
        found.map(|(q, k)| (best, q, self.normals[k]))
    }
}

/// The closest point of triangle `t` to `p` (Ericson, *Real-Time Collision Detection*, 5.1.5).
pub fn closest_point_on_triangle(p: DVec3, t: &[DVec3; 3]) -> DVec3 {
    let [a, b, c] = *t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

#[cfg(test)]
mod tests {
    use glam::DMat4;

    use super::*;
    use crate::catalog::Catalog;
    use crate::procedural::procedural_mesh;
    use crate::symmetry::measure::{SplitMix64, SymmetryChecker};

    #[test]
    fn closest_points_are_exact() {
        let m = procedural_mesh(Catalog::builtin().get("025_mug").unwrap());
        let c = SymmetryChecker::new(&m.positions, &m.indices);
        let tris: Vec<[DVec3; 3]> =
            m.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]].map(|i| Vec3f(m.positions[i as usize]).d())).collect();
        let mut rng = SplitMix64(3);
        for _ in 0..300 {
            let p = DVec3::new(rng.next_f64() - 0.5, rng.next_f64() - 0.5, rng.next_f64() - 0.5) * 0.2;
            let brute = tris.iter().map(|t| (closest_point_on_triangle(p, t) - p).length()).fold(f64::INFINITY, f64::min);
            assert!((c.distance(p) - brute).abs() < 1e-12, "{} vs {brute}", c.distance(p));
        }
        // Samples lie on the surface; the identity moves nothing.
        assert!(c.samples().iter().all(|p| c.distance(*p) < 1e-9));
        assert_eq!(c.displacement(&DMat4::IDENTITY).max, c.samples().iter().map(|p| c.distance(*p)).fold(0.0, f64::max));
        // A point on a face of a triangle, off it along the normal.
        let t = [DVec3::ZERO, DVec3::X, DVec3::Y];
        assert!(closest_point_on_triangle(DVec3::new(0.2, 0.2, 1.0), &t).abs_diff_eq(DVec3::new(0.2, 0.2, 0.0), 1e-15));
        assert_eq!(closest_point_on_triangle(DVec3::new(2.0, -1.0, 0.0), &t), DVec3::X);
        assert_eq!(closest_point_on_triangle(DVec3::new(1.0, 1.0, 0.0), &t), DVec3::new(0.5, 0.5, 0.0));
    }

    struct Vec3f([f32; 3]);
    impl Vec3f {
        fn d(&self) -> DVec3 {
            DVec3::new(self.0[0] as f64, self.0[1] as f64, self.0[2] as f64)
        }
    }
}

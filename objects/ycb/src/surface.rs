//! Points spread over a triangle mesh's surface by area: the one sampler behind the occlusion
//! level's model points, `vtgen validate`'s reprojection points, the symmetry measurements'
//! surface samples and the trainer's model points.
//!
//! A sampler holds the triangles (f64) and a running sum of their areas. A point takes three
//! uniform numbers from the caller: one picks a triangle by binary search over the running sum,
//! two place the point in it. The callers draw from their own streams (a low-discrepancy
//! sequence, an LCG, SplitMix64, ChaCha8), and their points are written to datasets or checked by
//! tests bit for bit, so the few ways they differ in arithmetic are kept as choices here: the
//! comparison of the binary search ([`SurfaceSampler::pick_by`]), and the folded or the
//! square-root placement in the triangle ([`SurfaceSampler::point`], [`SurfaceSampler::point_sqrt`]).

use glam::{DVec3, Vec3};

/// A triangle mesh's surface, ready to draw area-weighted points from.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceSampler {
    triangles: Vec<[DVec3; 3]>,
    areas: Vec<f64>,
    /// `running[k]`: the sum of `areas[..=k]`.
    running: Vec<f64>,
    total: f64,
}

impl SurfaceSampler {
    /// The surface of `triangles` (model frame, f64).
    pub fn new(triangles: Vec<[DVec3; 3]>) -> Self {
        let areas: Vec<f64> = triangles.iter().map(|&[a, b, c]| 0.5 * (b - a).cross(c - a).length()).collect();
        let mut running = Vec::with_capacity(areas.len());
        let mut acc = 0.0;
        for a in &areas {
            acc += a;
            running.push(acc);
        }
        SurfaceSampler { triangles, areas, running, total: acc }
    }

    /// The surface of an indexed mesh: f32 positions (widened exactly to f64) and index triples.
    /// A triangle with an index outside `positions` is left out.
    pub fn from_mesh(positions: &[[f32; 3]], triangles: impl IntoIterator<Item = [u32; 3]>) -> Self {
        let vertex = |i: u32| positions.get(i as usize).map(|p| Vec3::from(*p).as_dvec3());
        let tris = triangles
            .into_iter()
            .filter_map(|t| {
                let [a, b, c] = t.map(vertex);
                Some([a?, b?, c?])
            })
            .collect();
        Self::new(tris)
    }

    pub fn triangles(&self) -> &[[DVec3; 3]] {
        &self.triangles
    }

    /// The area of each triangle.
    pub fn areas(&self) -> &[f64] {
        &self.areas
    }

    /// The sum of the triangle areas, in order.
    pub fn total_area(&self) -> f64 {
        self.total
    }

    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// The triangle `u` (uniform in [0, 1)) falls in: the first whose running sum reaches `u`
    /// times the total area. Needs a triangle.
    pub fn pick(&self, u: f64) -> usize {
        self.pick_by(|&running| running < u * self.total)
    }

    /// The first triangle whose running sum `below` rejects (the binary search of
    /// `partition_point`: `below` must hold for a prefix of the running sums), the last one when
    /// `below` holds for all. For callers that compare in their own way; needs a triangle.
    pub fn pick_by(&self, below: impl FnMut(&f64) -> bool) -> usize {
        self.running.partition_point(below).min(self.triangles.len() - 1)
    }

    /// The point of triangle `k` at (`u1`, `u2`), both uniform in [0, 1): the pair is folded into
    /// the triangle (`u1 + u2 > 1` maps to `1 − u1`, `1 − u2`), `a + (b − a) u1 + (c − a) u2`.
    pub fn point(&self, k: usize, u1: f64, u2: f64) -> DVec3 {
        let (mut u, mut v) = (u1, u2);
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let [a, b, c] = self.triangles[k];
        a + (b - a) * u + (c - a) * v
    }

    /// The point of triangle `k` at (`r1`, `r2`), both uniform in [0, 1), by the square-root
    /// mapping (Osada et al., *Shape distributions*): `a (1 − √r1) + b √r1 (1 − r2) + c √r1 r2`.
    pub fn point_sqrt(&self, k: usize, r1: f64, r2: f64) -> DVec3 {
        let [a, b, c] = self.triangles[k];
        let s = r1.sqrt();
        a * (1.0 - s) + b * (s * (1.0 - r2)) + c * (s * r2)
    }

    /// The unit normal of triangle `k` (counter-clockwise seen from its front).
    pub fn face_normal(&self, k: usize) -> DVec3 {
        let [a, b, c] = self.triangles[k];
        (b - a).cross(c - a).normalize()
    }

    /// A point uniformly distributed over the surface: the triangle by `u_tri`
    /// ([`pick`](Self::pick)), the point in it by `u1`, `u2` ([`point`](Self::point)); all three
    /// uniform in [0, 1). Needs a triangle.
    pub fn sample(&self, u_tri: f64, u1: f64, u2: f64) -> DVec3 {
        self.point(self.pick(u_tri), u1, u2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Uniform numbers in [0, 1) from a 64-bit LCG (the test needs no particular stream).
    fn uniform(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// Two triangles in the z = 0 plane, of areas 1 and 3, and a degenerate one between them.
    fn one_and_three() -> SurfaceSampler {
        let small = [DVec3::ZERO, DVec3::new(2.0, 0.0, 0.0), DVec3::new(0.0, 1.0, 0.0)];
        let line = [DVec3::ZERO, DVec3::X, DVec3::new(2.0, 0.0, 0.0)];
        let large = [DVec3::new(5.0, 0.0, 0.0), DVec3::new(8.0, 0.0, 0.0), DVec3::new(5.0, 2.0, 0.0)];
        SurfaceSampler::new(vec![small, line, large])
    }

    /// Barycentric coordinates of `p` in the z = 0 triangle `t`.
    fn barycentric(p: DVec3, [a, b, c]: [DVec3; 3]) -> [f64; 3] {
        let (v0, v1, v2) = (b - a, c - a, p - a);
        let d = v0.x * v1.y - v1.x * v0.y;
        let l1 = (v2.x * v1.y - v1.x * v2.y) / d;
        let l2 = (v0.x * v2.y - v2.x * v0.y) / d;
        [1.0 - l1 - l2, l1, l2]
    }

    #[test]
    fn points_spread_by_area_and_lie_on_their_triangle() {
        let s = one_and_three();
        assert_eq!(s.areas(), &[1.0, 0.0, 3.0]);
        assert_eq!(s.total_area(), 4.0);
        let mut rnd = uniform(7);
        let n = 40_000;
        let mut counts = [0usize; 3];
        for _ in 0..n {
            let k = s.pick(rnd());
            let (u1, u2) = (rnd(), rnd());
            counts[k] += 1;
            for p in [s.point(k, u1, u2), s.point_sqrt(k, u1, u2)] {
                assert_eq!(p.z, 0.0);
                let l = barycentric(p, s.triangles()[k]);
                assert!(l.iter().all(|&x| x >= -1e-12), "{p} outside triangle {k}: {l:?}");
            }
        }
        // The degenerate triangle has no area and gets no point; the others 1 : 3.
        assert_eq!(counts[1], 0);
        let share = counts[0] as f64 / n as f64;
        assert!((share - 0.25).abs() < 0.01, "{counts:?}");
        assert_eq!(s.face_normal(2), DVec3::Z);
    }

    #[test]
    fn points_are_uniform_inside_a_triangle() {
        // The unit right triangle split by the line x = 0.5: the part left of it holds 3/4 of
        // the area, for both placements.
        let s = SurfaceSampler::new(vec![[DVec3::ZERO, DVec3::X, DVec3::Y]]);
        let mut rnd = uniform(11);
        let n = 40_000;
        let (mut folded, mut sqrt) = (0, 0);
        for _ in 0..n {
            let (u1, u2) = (rnd(), rnd());
            folded += (s.point(0, u1, u2).x < 0.5) as usize;
            sqrt += (s.point_sqrt(0, u1, u2).x < 0.5) as usize;
        }
        for c in [folded, sqrt] {
            assert!((c as f64 / n as f64 - 0.75).abs() < 0.01, "{folded} {sqrt}");
        }
    }

    #[test]
    fn running_sums_and_picks() {
        let areas = SurfaceSampler::from_mesh(
            &[[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 3.0, 0.0]],
            [[0, 1, 2], [0, 1, 3], [0, 1, 9]],
        );
        // The triangle with index 9 is left out.
        assert_eq!(areas.triangles().len(), 2);
        assert_eq!(areas.running, [1.0, 4.0]);
        let s = &areas;
        assert_eq!([s.pick(0.0), s.pick(0.2499), s.pick(0.25), s.pick(0.2501), s.pick(0.9999)], [0, 0, 0, 1, 1]);
        // The search's own comparison: `<=` moves a draw on a boundary to the next triangle.
        assert_eq!(s.pick_by(|&r| r <= 0.25 * s.total), 1);
        assert_eq!(s.pick_by(|_| true), 1);
        assert_eq!(areas.sample(0.1, 0.5, 0.25), DVec3::new(1.0, 0.25, 0.0));
        assert!(SurfaceSampler::from_mesh(&[], [[0, 1, 2]]).is_empty());
    }
}

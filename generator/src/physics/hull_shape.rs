//! A convex-hull collider for rapier whose world bounding box and support points are found by
//! walking the hull's surface instead of scanning every vertex, with the values parry's
//! `ConvexPolyhedron` gives, bit for bit.
//!
//! Why: rapier recomputes every moving hull's bounding box from all its vertices at every step
//! (the YCB hulls have 244–3 354 vertices, the Allegro links up to ~600), and GJK scans all of them
//! for every support point: ~5.5 % of a generate run's CPU. Fewer vertices would be cheaper, but
//! the creep test showed that any change of the hulls (even the order of their vertices) changes
//! which grasps hold still (README, Throughput). So the hull stays exactly as parry builds it and
//! only the *search* changes.
//!
//! The search: on a convex polytope, every vertex that does not maximise a linear function has a
//! neighbour along a hull edge with a larger value, so the vertices whose value is at least `c`
//! are connected through hull edges to the maximum for every `c`. A greedy walk from the last
//! answer (which is almost always still the answer one step later) finds a local maximum; a flood
//! from it over the vertices within `slack` of the best value found then reaches every vertex
//! whose *computed* f32 value could be the largest (`slack` covers twice the rounding of a value,
//! and parry's hulls' tolerance-sized dents). The walk and the flood rank vertices by a cheap key
//! (for a bounding box, a row of the rotation matrix dotted with the vertex, within a rounding of
//! parry's transformed coordinate); the answer is the maximum over the flood's region of the same
//! f32 expressions parry evaluates, ties to the lowest vertex index as parry's linear scan, so it is
//! parry's answer; the warm start only changes how many vertices are visited. Unit tests compare
//! both over many poses and directions.

use std::cell::RefCell;
use std::sync::atomic::{AtomicU32, Ordering};

use glam::{Mat3, Vec3};
use rapier3d::parry::bounding_volume::{Aabb, BoundingSphere};
use rapier3d::parry::mass_properties::MassProperties;
use rapier3d::parry::math::{Pose, Real};
use rapier3d::parry::query::{PointProjection, PointQuery, Ray, RayCast, RayIntersection};
use rapier3d::parry::shape::{
    ConvexPolyhedron, FeatureId, PolygonalFeature, PolygonalFeatureMap, Shape, ShapeType, SubShapeId, SupportMap, TypedShape,
};

/// Hulls with fewer vertices are scanned as parry does (a walk would visit most of them anyway).
const MIN_WALKED: usize = 48;

/// How far below the best value (m, per metre of scale) the flood still follows the surface: well
/// above f32 rounding (~1e-7 relative) and quickhull's tolerance, well below a vertex spacing.
const SLACK: f32 = 2e-5;

/// parry's `ConvexPolyhedron` and its vertex adjacency for the bounding-box and support-point
/// searches; every other query is the polyhedron's own.
#[derive(Debug)]
pub struct WalkedHull {
    hull: ConvexPolyhedron,
    /// Neighbours of vertex `i` along the hull's triangles: `adjacency[offsets[i]..offsets[i + 1]]`.
    offsets: Vec<u32>,
    adjacency: Vec<u32>,
    /// Vertices on no hull triangle (none in practice): visited by every search.
    loose: Vec<u32>,
    /// The largest vertex distance from the origin, for the slack of a support search.
    radius: f32,
    /// Where the last search in each direction ended (bounding box +x, −x, +y, −y, +z, −z, then
    /// support points): the next one starts there. Answers do not depend on it.
    hints: [AtomicU32; 7],
}

impl Clone for WalkedHull {
    fn clone(&self) -> Self {
        WalkedHull {
            hull: self.hull.clone(),
            offsets: self.offsets.clone(),
            adjacency: self.adjacency.clone(),
            loose: self.loose.clone(),
            radius: self.radius,
            hints: std::array::from_fn(|k| AtomicU32::new(self.hints[k].load(Ordering::Relaxed))),
        }
    }
}

/// Per-thread work space of the searches, stamped instead of cleared: a vertex belongs to the
/// current search's region when its stamp is the current one. Sized to the largest hull searched
/// on the thread.
#[derive(Default)]
struct Scratch {
    /// The flood's region: `region[i] == search`.
    region: Vec<u32>,
    search: u32,
    /// The region's vertices, in the order reached.
    members: Vec<u32>,
    stack: Vec<u32>,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::default();
}

/// The next stamp of a stamped buffer of `n` entries (cleared on wrap-around).
fn next_stamp(stamp: &mut u32, marks: &mut Vec<u32>, n: usize) -> u32 {
    if marks.len() < n {
        marks.resize(n, 0);
    }
    *stamp = stamp.wrapping_add(1);
    if *stamp == 0 {
        marks.fill(0);
        *stamp = 1;
    }
    *stamp
}

impl WalkedHull {
    /// The convex hull of `points`, as `ConvexPolyhedron::from_convex_hull` builds it (the same
    /// two steps), with the adjacency of its triangles. None: degenerate points.
    pub fn from_points(points: &[Vec3]) -> Option<Self> {
        let (vertices, triangles) = rapier3d::parry::transformation::try_convex_hull(points).ok()?;
        let hull = ConvexPolyhedron::from_convex_mesh(vertices, &triangles)?;
        let n = hull.points().len();
        let mut pairs: Vec<(u32, u32)> = triangles
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .flat_map(|(a, b)| [(a, b), (b, a)])
            .filter(|&(a, b)| (a as usize) < n && (b as usize) < n)
            .collect();
        pairs.sort_unstable();
        pairs.dedup();
        let mut offsets = vec![0u32; n + 1];
        for &(a, _) in &pairs {
            offsets[a as usize + 1] += 1;
        }
        for i in 0..n {
            offsets[i + 1] += offsets[i];
        }
        let adjacency = pairs.iter().map(|&(_, b)| b).collect();
        let loose = (0..n as u32).filter(|&i| offsets[i as usize] == offsets[i as usize + 1]).collect();
        let radius = hull.points().iter().map(|p| p.length()).fold(0.0, f32::max);
        Some(WalkedHull { hull, offsets, adjacency, loose, radius, hints: std::array::from_fn(|_| AtomicU32::new(0)) })
    }

    fn neighbours(&self, i: u32) -> &[u32] {
        &self.adjacency[self.offsets[i as usize] as usize..self.offsets[i as usize + 1] as usize]
    }

    /// The largest `exact(i)` over the vertices and the lowest index that has it. The walk and the
    /// flood (see the module comment) follow `key`, a cheaper value within a rounding of `exact`
    /// (`slack` covers both); `exact` is then evaluated on the flood's region only, which holds
    /// every vertex whose key is within `slack` of the largest, so every vertex that can hold the
    /// largest `exact`.
    fn extreme(&self, hint: &AtomicU32, slack: f32, key: impl Fn(u32) -> f32, exact: impl Fn(u32) -> f32) -> (f32, u32) {
        let n = self.hull.points().len();
        // Greedy walk uphill from the last answer.
        let mut at = hint.load(Ordering::Relaxed).min(n as u32 - 1);
        let mut at_key = key(at);
        loop {
            let mut next = None;
            for &j in self.neighbours(at) {
                let k = key(j);
                if k > at_key {
                    (at_key, next) = (k, Some(j));
                }
            }
            match next {
                Some(j) => at = j,
                None => break,
            }
        }
        hint.store(at, Ordering::Relaxed);
        SCRATCH.with_borrow_mut(|s| {
            // Flood over every vertex within `slack` of the best key found.
            let search = next_stamp(&mut s.search, &mut s.region, n);
            let mut best_key = at_key;
            s.region[at as usize] = search;
            s.members.clear();
            s.members.push(at);
            s.stack.clear();
            s.stack.push(at);
            while let Some(i) = s.stack.pop() {
                for &j in self.neighbours(i) {
                    if s.region[j as usize] == search {
                        continue;
                    }
                    let k = key(j);
                    if k >= best_key - slack {
                        s.region[j as usize] = search;
                        s.members.push(j);
                        s.stack.push(j);
                        best_key = best_key.max(k);
                    }
                }
            }
            // The exact values, on the region and the vertices no walk reaches.
            let (mut best, mut best_id) = (f32::NEG_INFINITY, u32::MAX);
            for &i in s.members.iter().chain(&self.loose) {
                let v = exact(i);
                if v > best || (v == best && i < best_id) {
                    (best, best_id) = (v, i);
                }
            }
            (best, best_id)
        })
    }

    /// parry's `point_cloud_aabb`: the min and max of `pos * p` over the vertices.
    fn world_aabb(&self, pos: &Pose) -> Aabb {
        let n = self.hull.points().len();
        if n < MIN_WALKED || !pos.translation.is_finite() || !pos.rotation.is_finite() {
            return self.hull.aabb(pos);
        }
        let slack = SLACK * (1.0 + self.radius + pos.translation.abs().max_element());
        let points = self.hull.points();
        // The search key along axis a: row a of the rotation times p (the translation adds the
        // same to every vertex); the exact value is parry's `(pos * p)[a]`.
        let rows = Mat3::from_quat(pos.rotation).transpose();
        let mut lo = [0.0f32; 3];
        let mut hi = [0.0f32; 3];
        for axis in 0..3 {
            let row = rows.col(axis);
            let key = |i: u32| row.dot(points[i as usize]);
            let exact = |i: u32| (pos * points[i as usize])[axis];
            hi[axis] = self.extreme(&self.hints[2 * axis], slack, key, exact).0;
            lo[axis] = -self.extreme(&self.hints[2 * axis + 1], slack, |i| -key(i), |i| -exact(i)).0;
        }
        Aabb::new(Vec3::from_array(lo), Vec3::from_array(hi))
    }

    /// parry's `point_cloud_support_point`: the vertex with the largest `p · dir`, the lowest index
    /// among equals.
    fn support(&self, dir: Vec3) -> Vec3 {
        let points = self.hull.points();
        if points.len() < MIN_WALKED || !dir.is_finite() {
            return self.hull.local_support_point(dir);
        }
        let slack = SLACK * (1.0 + self.radius) * dir.length();
        let dot = |i: u32| points[i as usize].dot(dir);
        let (_, i) = self.extreme(&self.hints[6], slack, dot, dot);
        points[i as usize]
    }
}

impl SupportMap for WalkedHull {
    fn local_support_point(&self, dir: Vec3) -> Vec3 {
        self.support(dir)
    }
}

impl PolygonalFeatureMap for WalkedHull {
    fn local_support_feature(&self, dir: Vec3, out_feature: &mut PolygonalFeature) {
        self.hull.local_support_feature(dir, out_feature)
    }

    fn is_convex_polyhedron(&self) -> bool {
        true
    }
}

impl PointQuery for WalkedHull {
    fn project_local_point(&self, point: Vec3, solid: bool) -> PointProjection {
        self.hull.project_local_point(point, solid)
    }

    fn project_local_point_and_get_feature(&self, point: Vec3) -> (PointProjection, FeatureId) {
        self.hull.project_local_point_and_get_feature(point)
    }
}

impl RayCast for WalkedHull {
    fn cast_local_ray_and_get_normal(&self, ray: &Ray, max_time_of_impact: Real, solid: bool) -> Option<RayIntersection> {
        self.hull.cast_local_ray_and_get_normal(ray, max_time_of_impact, solid)
    }
}

impl Shape for WalkedHull {
    fn compute_local_aabb(&self) -> Aabb {
        self.hull.local_aabb()
    }

    fn compute_local_bounding_sphere(&self) -> BoundingSphere {
        self.hull.local_bounding_sphere()
    }

    fn clone_dyn(&self) -> Box<dyn Shape> {
        Box::new(self.clone())
    }

    fn scale_dyn(&self, scale: Vec3, num_subdivisions: u32) -> Option<Box<dyn Shape>> {
        // A scaled hull is a new hull: parry's own (nothing here scales colliders).
        self.hull.scale_dyn(scale, num_subdivisions)
    }

    fn compute_aabb(&self, position: &Pose) -> Aabb {
        self.world_aabb(position)
    }

    fn mass_properties(&self, density: Real) -> MassProperties {
        Shape::mass_properties(&self.hull, density)
    }

    fn is_convex(&self) -> bool {
        true
    }

    // The polyhedron's type, so that every query that dispatches on it (rapier's continuous
    // collision detection sweeps a hull as its point cloud) treats this shape as the hull it is.
    // Nothing downcasts a `ShapeType::ConvexPolyhedron` to the concrete type.
    fn shape_type(&self) -> ShapeType {
        ShapeType::ConvexPolyhedron
    }

    fn as_typed_shape(&self) -> TypedShape<'_> {
        TypedShape::ConvexPolyhedron(&self.hull)
    }

    fn ccd_thickness(&self) -> Real {
        self.hull.ccd_thickness()
    }

    fn ccd_angular_thickness(&self) -> Real {
        self.hull.ccd_angular_thickness()
    }

    fn as_support_map(&self) -> Option<&dyn SupportMap> {
        Some(self as &dyn SupportMap)
    }

    fn as_polygonal_feature_map(&self) -> Option<(&dyn PolygonalFeatureMap, Real)> {
        Some((self as &dyn PolygonalFeatureMap, 0.0))
    }

    fn feature_normal_at_point(&self, subshape: SubShapeId, feature: FeatureId, point: Vec3) -> Option<Vec3> {
        self.hull.feature_normal_at_point(subshape, feature, point)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Point clouds like the simulated hulls': a scanned-looking rounded box (many nearly coplanar
    /// vertices), a CAD-like cylinder (exactly equal coordinates, flat faces), a noisy blob, and
    /// the real meshes' when `YCB_DIR` is set.
    fn clouds() -> Vec<Vec<Vec3>> {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut clouds: Vec<Vec<Vec3>> = vec![
            (0..3000)
                .map(|_| {
                    let p = Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
                    let q = p / p.abs().max_element();
                    q * Vec3::new(0.08, 0.03, 0.11) + Vec3::splat(0.0005) * q.normalize()
                })
                .collect(),
            (0..64)
                .flat_map(|k| {
                    let a = k as f32 * std::f32::consts::TAU / 64.0;
                    [Vec3::new(0.014 * a.cos(), 0.014 * a.sin(), 0.0), Vec3::new(0.014 * a.cos(), 0.014 * a.sin(), 0.027)]
                })
                .collect(),
            (0..800)
                .map(|_| {
                    let d = Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)).normalize();
                    d * rng.random_range(0.04..0.05) + Vec3::new(0.01, -0.02, 0.1)
                })
                .collect(),
        ];
        if let Some(dir) = std::env::var_os("YCB_DIR") {
            for id in ["003_cracker_box", "011_banana", "037_scissors"] {
                let path = vt_objects::find_ycb_mesh(std::path::Path::new(&dir), id).expect("YCB mesh");
                clouds.push(vt_objects::load_mesh(&path).expect("mesh").positions.iter().map(|p| Vec3::from_array(*p)).collect());
            }
        }
        clouds
    }

    #[test]
    fn bounding_boxes_and_support_points_are_parrys_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for cloud in clouds() {
            let walked = WalkedHull::from_points(&cloud).expect("hull");
            let hull = ConvexPolyhedron::from_convex_hull(&cloud).expect("hull");
            assert_eq!(walked.hull.points(), hull.points(), "the same hull as parry's from_convex_hull");
            assert!(walked.loose.is_empty());
            // A slowly moving pose (the warm start of a simulation) and jumps (cold starts).
            let mut axis = Vec3::X;
            let mut angle = 0.0f32;
            for k in 0..3000 {
                if k % 10 == 0 {
                    axis = Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0))
                        .normalize_or(Vec3::X);
                    angle = rng.random_range(0.0..6.3);
                } else {
                    angle += 0.003;
                }
                let t = Vec3::new(rng.random_range(-0.4..0.4), rng.random_range(-0.4..0.4), rng.random_range(-0.4..0.4));
                let pos = Pose::from_parts(t, Quat::from_axis_angle(axis, angle));
                let (a, b) = (walked.compute_aabb(&pos), hull.aabb(&pos));
                assert_eq!((a.mins.to_array(), a.maxs.to_array()), (b.mins.to_array(), b.maxs.to_array()), "pose {pos:?}");
                // Random directions, and axis-aligned ones (ties between equal coordinates).
                let dir = if k % 3 == 0 { Vec3::X * rng.random_range(-2.0..2.0) } else { axis * 3.0 };
                assert_eq!(walked.local_support_point(dir).to_array(), hull.local_support_point(dir).to_array(), "direction {dir}");
            }
        }
    }

    #[test]
    fn queries_other_than_the_searches_are_the_hulls() {
        let cloud = clouds().remove(2);
        let walked = WalkedHull::from_points(&cloud).unwrap();
        let hull = ConvexPolyhedron::from_convex_hull(&cloud).unwrap();
        let (a, b) = (Shape::mass_properties(&walked, 1000.0), Shape::mass_properties(&hull, 1000.0));
        assert_eq!((a.mass(), a.local_com), (b.mass(), b.local_com));
        assert_eq!(walked.compute_local_aabb(), hull.local_aabb());
        assert_eq!(walked.ccd_thickness(), hull.ccd_thickness());
        assert!(matches!(walked.as_typed_shape(), TypedShape::ConvexPolyhedron(_)));
        let p = Vec3::new(0.2, 0.1, -0.3);
        assert_eq!(walked.project_local_point(p, true).point, hull.project_local_point(p, true).point);
    }
}

//! What the refiner knows of an object, computed once per object: a distance field of its mesh
//! (for scoring thousands of pose hypotheses), dense surface points with normals in a k-d tree
//! (for point-to-plane correspondences), and, per viewing direction, the centroid of the surface
//! that faces the camera (for a hypothesis' first translation).

use glam::{DVec3, Vec3};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use parry3d::query::PointQuery;
use parry3d::shape::TriMesh;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::data::ObjectModel;

/// The distance field's padding around the mesh's bounding box (m): farther points cost the
/// robust kernel's ceiling anyway.
const FIELD_PAD_M: f64 = 0.03;
/// At most this many cells along the field's longest side, and no cell smaller than this (m).
const FIELD_MAX_CELLS: usize = 64;
const FIELD_MIN_CELL_M: f64 = 0.002;
/// Surface points with normals for the correspondences: spacing about √(area / n).
const SURFACE_POINTS: usize = 6000;
/// Viewing directions, an octahedral grid of this many cells a side, each with its facing
/// surface's centroid (looked up in constant time).
const VIEW_GRID: usize = 24;
/// Surface points checked against free space per pose (a fixed, spread subset).
const FREE_SPACE_POINTS: usize = 400;

/// The unsigned distance to the mesh on a regular grid (object frame), trilinearly interpolated.
#[derive(Debug, Clone)]
pub struct DistanceField {
    origin: Vec3,
    cell: f32,
    dims: [usize; 3],
    values: Vec<f32>,
}

impl DistanceField {
    /// The exact distance (parry's projection onto the triangle mesh) at every grid node, the
    /// z-slices computed in parallel.
    fn of_mesh(mesh: &TriMesh, lo: DVec3, hi: DVec3) -> Self {
        let (lo, hi) = (lo - DVec3::splat(FIELD_PAD_M), hi + DVec3::splat(FIELD_PAD_M));
        let extent = hi - lo;
        let cell = (extent.max_element() / (FIELD_MAX_CELLS - 1) as f64).max(FIELD_MIN_CELL_M);
        let dims = [0, 1, 2].map(|k| (extent[k] / cell).ceil() as usize + 1);
        let origin = lo.as_vec3();
        let cell = cell as f32;
        let values: Vec<f32> = (0..dims[2])
            .into_par_iter()
            .flat_map_iter(|z| {
                (0..dims[1]).flat_map(move |y| {
                    (0..dims[0]).map(move |x| {
                        let p = origin + Vec3::new(x as f32, y as f32, z as f32) * cell;
                        let proj = mesh.project_local_point(p, false);
                        (proj.point - p).length()
                    })
                })
            })
            .collect();
        DistanceField { origin, cell, dims, values }
    }

    fn at(&self, x: usize, y: usize, z: usize) -> f32 {
        self.values[(z * self.dims[1] + y) * self.dims[0] + x]
    }

    /// The distance at `p` (object frame) and its gradient. Outside the grid: the distance at the
    /// nearest grid point plus the way there, the gradient pointing away from the grid.
    pub fn sample(&self, p: Vec3) -> (f32, Vec3) {
        let g = (p - self.origin) / self.cell;
        let max = Vec3::new((self.dims[0] - 1) as f32, (self.dims[1] - 1) as f32, (self.dims[2] - 1) as f32);
        let gc = g.clamp(Vec3::ZERO, max);
        let outside = (g - gc) * self.cell;
        let i = gc.floor().min(max - Vec3::ONE).max(Vec3::ZERO);
        let f = gc - i;
        let (x, y, z) = (i.x as usize, i.y as usize, i.z as usize);
        let c = |dx: usize, dy: usize, dz: usize| self.at(x + dx, y + dy, z + dz);
        let (c000, c100, c010, c110) = (c(0, 0, 0), c(1, 0, 0), c(0, 1, 0), c(1, 1, 0));
        let (c001, c101, c011, c111) = (c(0, 0, 1), c(1, 0, 1), c(0, 1, 1), c(1, 1, 1));
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let (x00, x10) = (lerp(c000, c100, f.x), lerp(c010, c110, f.x));
        let (x01, x11) = (lerp(c001, c101, f.x), lerp(c011, c111, f.x));
        let (y0, y1) = (lerp(x00, x10, f.y), lerp(x01, x11, f.y));
        let d = lerp(y0, y1, f.z);
        let dx = lerp(lerp(c100 - c000, c110 - c010, f.y), lerp(c101 - c001, c111 - c011, f.y), f.z);
        let dy = lerp(lerp(c010 - c000, c110 - c100, f.x), lerp(c011 - c001, c111 - c101, f.x), f.z);
        let dz = y1 - y0;
        let grad = Vec3::new(dx, dy, dz) / self.cell;
        let out = outside.length();
        if out > 0.0 { (d + out, outside / out) } else { (d, grad) }
    }
}

/// One object as the refiner sees it (object frame throughout).
#[derive(Debug)]
pub struct ObjectShape {
    pub field: DistanceField,
    /// Surface points and their outward unit normals.
    pub points: Vec<DVec3>,
    pub normals: Vec<DVec3>,
    tree: ImmutableKdTree<f64, 3>,
    /// Per cell of the octahedral grid of viewing directions, the centroid of the surface points
    /// facing its central direction `d` (`n · d < 0`).
    facing_centroid: Vec<DVec3>,
    /// Indices into `points` checked against free space.
    pub free_space: Vec<usize>,
}

impl ObjectShape {
    /// Builds the shape of `model` (deterministic: seeded by the object's index). An error when
    /// the mesh has no triangle.
    pub fn of(model: &ObjectModel) -> anyhow::Result<Self> {
        let (vertices, triangles) = model.mesh();
        let area = model.surface().total_area();
        if triangles.is_empty() || area.is_nan() || area <= 0.0 {
            anyhow::bail!("object '{}': its mesh has no triangle with an area; the refiner needs a surface", model.id);
        }
        let mesh = TriMesh::new(vertices.iter().map(|v| v.as_vec3()).collect(), triangles.to_vec())
            .map_err(|e| anyhow::anyhow!("object '{}': its mesh is not a triangle mesh parry accepts: {e:?}", model.id))?;
        let lo = vertices.iter().fold(DVec3::splat(f64::INFINITY), |a, v| a.min(*v));
        let hi = vertices.iter().fold(DVec3::splat(f64::NEG_INFINITY), |a, v| a.max(*v));
        let field = DistanceField::of_mesh(&mesh, lo, hi);
        // Outward normals: the winding's orientation, flipped as a whole when the mesh's signed
        // volume says it is wound inward.
        let surface = model.surface();
        let volume: f64 = surface.triangles().iter().map(|[a, b, c]| a.dot(b.cross(*c))).sum();
        let sign = if volume < 0.0 { -1.0 } else { 1.0 };
        let mut rng = ChaCha8Rng::seed_from_u64(0x7e_f17e + model.dataset_index as u64);
        let (mut points, mut normals) = (Vec::with_capacity(SURFACE_POINTS), Vec::with_capacity(SURFACE_POINTS));
        while points.len() < SURFACE_POINTS {
            let k = surface.pick(rng.random());
            let [a, b, c] = surface.triangles()[k];
            let n = (b - a).cross(c - a);
            let p = surface.point(k, rng.random(), rng.random());
            if n.length_squared() > 0.0 {
                points.push(p);
                normals.push(sign * n.normalize());
            }
        }
        let tree = ImmutableKdTree::new_from_slice(&points.iter().map(|p| p.to_array()).collect::<Vec<_>>());
        let centroid = points.iter().sum::<DVec3>() / points.len() as f64;
        let facing_centroid = (0..VIEW_GRID * VIEW_GRID)
            .map(octahedral_direction)
            .map(|d| {
                let (sum, n) = points
                    .iter()
                    .zip(&normals)
                    .filter(|(_, n)| n.dot(d) < 0.0)
                    .fold((DVec3::ZERO, 0usize), |(s, k), (p, _)| (s + *p, k + 1));
                if n == 0 { centroid } else { sum / n as f64 }
            })
            .collect();
        let stride = (SURFACE_POINTS / FREE_SPACE_POINTS).max(1);
        let free_space = (0..SURFACE_POINTS).step_by(stride).collect();
        Ok(ObjectShape { field, points, normals, tree, facing_centroid, free_space })
    }

    /// The nearest surface point to `p` (object frame): its index.
    pub fn nearest(&self, p: DVec3) -> usize {
        self.tree.nearest_one::<SquaredEuclidean>(&p.to_array()).item as usize
    }

    /// The centroid of the surface a camera looking along `direction` (object frame, unit) sees
    /// when nothing hides it: the first translation of a hypothesis.
    pub fn facing_centroid(&self, direction: DVec3) -> DVec3 {
        self.facing_centroid[octahedral_cell(direction)]
    }
}

/// The cell of the octahedral map (Meyer et al. 2010: the sphere folded onto a square) that a
/// unit direction falls in.
fn octahedral_cell(d: DVec3) -> usize {
    let p = d / (d.x.abs() + d.y.abs() + d.z.abs()).max(1e-12);
    let (mut x, mut y) = (p.x, p.y);
    if p.z < 0.0 {
        (x, y) = ((1.0 - p.y.abs()) * p.x.signum(), (1.0 - p.x.abs()) * p.y.signum());
    }
    let cell = |v: f64| (((v * 0.5 + 0.5) * VIEW_GRID as f64) as usize).min(VIEW_GRID - 1);
    cell(y) * VIEW_GRID + cell(x)
}

/// The unit direction at the centre of an octahedral cell.
fn octahedral_direction(cell: usize) -> DVec3 {
    let centre = |k: usize| (k as f64 + 0.5) / VIEW_GRID as f64 * 2.0 - 1.0;
    let (x, y) = (centre(cell % VIEW_GRID), centre(cell / VIEW_GRID));
    let z = 1.0 - x.abs() - y.abs();
    let (x, y) = if z < 0.0 { ((1.0 - y.abs()) * x.signum(), (1.0 - x.abs()) * y.signum()) } else { (x, y) };
    DVec3::new(x, y, z).normalize()
}

/// Meshes for the refiner's tests.
#[cfg(test)]
pub(crate) mod tests_support {
    use crate::data::ObjectModel;

    /// A closed axis-aligned box about the origin, wound outward.
    pub fn box_model(half: [f32; 3]) -> ObjectModel {
        let [a, b, c] = half;
        let v: Vec<[f32; 3]> =
            (0..8).map(|i| [if i & 1 == 0 { -a } else { a }, if i & 2 == 0 { -b } else { b }, if i & 4 == 0 { -c } else { c }]).collect();
        let t = [
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
        ];
        let d = 2.0 * (a * a + b * b + c * c).sqrt() as f64;
        ObjectModel::from_mesh("box", 0, "none", d, &v, &t)
    }
}

#[cfg(test)]
mod tests {
    use super::tests_support::box_model;
    use super::*;

    #[test]
    fn the_field_is_the_distance_to_the_box() {
        let shape = ObjectShape::of(&box_model([0.05, 0.03, 0.02])).unwrap();
        // On a face, off a face, at a corner's diagonal, far outside the grid.
        let cases = [
            (Vec3::new(0.05, 0.0, 0.0), 0.0),
            (Vec3::new(0.0, 0.04, 0.0), 0.01),
            (Vec3::new(0.0, 0.0, 0.0), 0.02),
            (Vec3::new(0.06, 0.04, 0.03), (3.0f32 * 0.01 * 0.01).sqrt()),
            (Vec3::new(0.3, 0.0, 0.0), 0.25),
        ];
        for (p, want) in cases {
            let (d, _) = shape.field.sample(p);
            assert!((d - want).abs() < 0.0015, "at {p}: {d} vs {want}");
        }
        let (_, g) = shape.field.sample(Vec3::new(0.0, 0.045, 0.0));
        assert!(g.normalize().dot(Vec3::Y) > 0.95, "gradient {g}");
        // Outward normals: every surface point's normal points away from the centre.
        assert!(shape.points.iter().zip(&shape.normals).all(|(p, n)| p.dot(*n) > 0.0));
        // The surface facing a camera lies on the camera's side of the box, as far as the box
        // allows: looking along +y, the −y face (at y = −3 cm) and whatever side faces tilt in.
        for d in [DVec3::Y, DVec3::new(0.3, 1.0, 0.2).normalize(), DVec3::new(-1.0, 0.1, -0.4).normalize()] {
            let c = shape.facing_centroid(d);
            assert!(c.dot(d) < -0.01, "looking along {d}: centroid {c}");
        }
        assert!(shape.facing_centroid(DVec3::Y).y < -0.015);
        // The octahedral cells: every direction falls in the cell whose centre is nearest-ish.
        for k in 0..VIEW_GRID * VIEW_GRID {
            assert_eq!(octahedral_cell(octahedral_direction(k)), k);
        }
    }
}

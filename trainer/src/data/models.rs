//! One object of a dataset's `models/`: its mesh, symmetry and fixed metric points; the objects a
//! run trains on.

use vt_objects::SurfaceSampler;

use super::*;

/// One object of `models/`: its mesh, symmetry and fixed metric points.
#[derive(Debug, Clone)]
pub struct ObjectModel {
    pub id: String,
    /// The object's `object_index` in the dataset.
    pub dataset_index: usize,
    /// `none`, `continuous_z` or `discrete` (models_info.json).
    pub symmetry: String,
    /// The symmetries the "angle up to symmetry" forgives (mesh-verified when the dataset has them).
    pub symmetries: crate::geometry::Symmetries,
    /// Largest vertex distance, metres.
    pub diameter: f64,
    vertices: Vec<DVec3>,
    /// The mesh's index triples (into `vertices`).
    triangles: Vec<[u32; 3]>,
    /// The triangles and their running areas (no area: sample vertices instead).
    surface: SurfaceSampler,
    /// `EVAL_MODEL_POINTS` surface points (object frame) the metrics use.
    pub eval_points: Vec<[f32; 3]>,
}

impl ObjectModel {
    pub fn from_mesh(
        id: &str,
        dataset_index: usize,
        symmetry: &str,
        diameter: f64,
        positions: &[[f32; 3]],
        triangles: &[[u32; 3]],
    ) -> Self {
        let vertices: Vec<DVec3> = positions.iter().map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)).collect();
        let surface = SurfaceSampler::from_mesh(positions, triangles.iter().copied());
        let mut m = ObjectModel {
            id: id.to_string(),
            dataset_index,
            symmetry: symmetry.to_string(),
            symmetries: crate::geometry::Symmetries::of_kind(symmetry),
            diameter,
            vertices,
            triangles: triangles.to_vec(),
            surface,
            eval_points: Vec::new(),
        };
        let mut rng = ChaCha8Rng::seed_from_u64(0x5eed_0000 + dataset_index as u64);
        m.eval_points = m.sample_surface(EVAL_MODEL_POINTS, &mut rng);
        m
    }

    /// The mesh's vertices (object frame) and index triples, as `models/<id>.ply` has them.
    pub fn mesh(&self) -> (&[DVec3], &[[u32; 3]]) {
        (&self.vertices, &self.triangles)
    }

    /// The area-weighted surface sampler of the mesh.
    pub fn surface(&self) -> &SurfaceSampler {
        &self.surface
    }

    /// Symmetric objects use the closest-point loss and ADD-S.
    pub fn symmetric(&self) -> bool {
        self.symmetry != "none"
    }

    /// `n` points uniformly distributed over the surface (object frame), as the Python
    /// `sample_surface`: triangles chosen by area, points uniform inside them. A mesh without
    /// (non-degenerate) faces falls back to its vertices.
    // `!(total > 0.0)` on purpose: a NaN area falls back to the vertices too.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    pub fn sample_surface(&self, n: usize, rng: &mut impl Rng) -> Vec<[f32; 3]> {
        let total = self.surface.total_area();
        if !(total > 0.0) {
            return draw(rng, self.vertices.len(), n).into_iter().map(|i| self.vertices[i].as_vec3().to_array()).collect();
        }
        (0..n)
            .map(|_| {
                let u: f64 = rng.random();
                // Each running area over the total, compared with `u`: the division is this
                // sampler's since its first points (the generator's `c < u · total` differs in
                // the last bits), and the trainer's tests and runs keep their points.
                let k = self.surface.pick_by(|&c| c / total < u);
                let (r1, r2): (f64, f64) = (rng.random(), rng.random());
                self.surface.point(k, r1, r2).as_vec3().to_array()
            })
            .collect()
    }
}

/// Every object of a dataset's `models/`, by `object_index`.
pub fn load_models(root: &Path) -> Result<Vec<ObjectModel>> {
    let dir = root.join("models");
    let path = dir.join("models_info.json");
    let text = std::fs::read_to_string(&path).with_context(|| format!("cannot read {}", path.display()))?;
    let info: ModelsInfo = serde_json::from_str(&text).with_context(|| format!("{} is not a valid models_info.json", path.display()))?;
    let mut models: Vec<ObjectModel> = info
        .objects
        .iter()
        .map(|o| {
            let mesh = vt_dataset::read_ply(&dir.join(&o.file))?;
            let mut m = ObjectModel::from_mesh(&o.id, o.object_index as usize, &o.symmetry, o.diameter, &mesh.positions, &mesh.triangles);
            m.symmetries = crate::geometry::Symmetries::from_models_info(&o.symmetry, &o.symmetries_discrete, &o.symmetries_continuous);
            Ok(m)
        })
        .collect::<Result<_>>()?;
    models.sort_by_key(|m| m.dataset_index);
    if models.iter().enumerate().any(|(i, m)| m.dataset_index != i) {
        bail!("{}: object_index values are not 0..{}", path.display(), models.len());
    }
    Ok(models)
}

/// The objects a run trains on, in head-slot order (slot `k` = `objects[k]`).
pub fn select_objects(models: &[ObjectModel], selection: &ObjectSelection) -> Result<Vec<String>> {
    match selection {
        ObjectSelection::All => Ok(models.iter().map(|m| m.id.clone()).collect()),
        ObjectSelection::List(ids) => {
            for id in ids {
                if !models.iter().any(|m| &m.id == id) {
                    bail!(
                        "objects: '{id}' is not in the dataset (it has: {})",
                        models.iter().map(|m| m.id.as_str()).collect::<Vec<_>>().join(", ")
                    );
                }
            }
            Ok(ids.clone())
        }
    }
}

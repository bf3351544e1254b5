//! Objects: the catalogue of the paper's 11 YCB objects, mesh loading into the dataset's model frame,
//! procedural stand-ins so the default job needs no download, the objects' symmetries measured on
//! the mesh (`symmetry`), and the area-weighted surface sampler every mesh-sampling caller shares
//! (`surface`).
//!
//! The model frame (see `datasets/FORMAT.md`) keeps the axes of the YCB scan and puts the origin at
//! the centre of the mesh's axis-aligned bounding box.

mod catalog;
mod load;
mod mesh;
mod procedural;
mod surface;
mod symmetry;

pub use catalog::{Catalog, CatalogEntry, Shape, Surface, Symmetry};
pub use load::{MeshError, find_ycb_mesh, load_mesh, load_obj_file};
pub use mesh::{Texture, TexturedMesh, diameter_of, linear_to_srgb8};
pub use procedural::{BOX_FACES, procedural_mesh};
pub use surface::SurfaceSampler;
pub use symmetry::{
    ContinuousAxis, DerivedSymmetries, Displacement, SAMPLE_SEED, SURFACE_SAMPLES, SymmetryCheck, SymmetryChecker, axis_aligned_transforms,
    closest_point_on_triangle, derive_symmetries, revolution_turns, row_major4, tolerance,
};

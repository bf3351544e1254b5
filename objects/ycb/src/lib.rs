//! Objects: the catalogue of the paper's 11 YCB objects, mesh loading into the dataset's model frame,
//! and procedural stand-ins so the default job needs no download.
//!
//! The model frame (see `datasets/FORMAT.md`) keeps the axes of the YCB scan and puts the origin at
//! the centre of the mesh's axis-aligned bounding box.

mod catalog;
mod load;
mod mesh;
mod procedural;

pub use catalog::{Catalog, CatalogEntry, Shape, Symmetry};
pub use load::{MeshError, find_ycb_mesh, load_mesh};
pub use mesh::{Texture, TexturedMesh, linear_to_srgb8};
pub use procedural::{BOX_FACES, procedural_mesh};

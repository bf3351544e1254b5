//! Symmetries measured on the mesh itself.
//!
//! The catalogue declares a *kind* of symmetry per object (`discrete`: a box-like object with 180°
//! flips; `continuous_z`: a body of revolution about the model z axis). The model frame keeps the
//! axes of the scan, and real scans are not aligned with their faces (the YCB gelatin box is turned
//! about 13° about z), so the axis-aligned transforms the kind names can move the surface by
//! centimetres. This module
//!
//! - **measures** how far a rigid transform moves a mesh's surface off itself: area-weighted,
//!   seeded surface samples are moved by the transform, and each one's exact distance to the closest
//!   point of the surface (point-to-triangle, through a bounding-volume hierarchy) is taken;
//!   [`Displacement`] reports the maximum and the 99th and 95th percentiles;
//! - **derives** the symmetries of a declared kind from the mesh: the box frame (principal axes of
//!   the area-weighted surface covariance, centred on the bounding box in that frame, and the model
//!   axes as a second start) refined by a small pattern search, its three 180° flips for `discrete`;
//!   the revolution axis (the principal axis nearest model z) refined the same way and verified at
//!   every 30° for `continuous_z`; a symmetry is kept only when it passes [`tolerance`].
//!
//! Everything is deterministic (a fixed seed, no threads, only `+ − × ÷ √` in the search), so the
//! same mesh gives the same bytes in `models_info.json` on every run. Nothing is logged: the result
//! carries every measurement ([`DerivedSymmetries::checks`]) for the caller to report.
//!
//! The parts: `derive` (the public result types and the derivation of each kind), `measure` (the
//! surface samples and what a transform does to them), `search` (the candidate transforms about a
//! frame and the refinement of the frame), `linalg` (the small dense algebra the search needs) and
//! `closest` (the bounding-volume hierarchy for exact closest points).

mod closest;
mod derive;
mod linalg;
mod measure;
mod search;

pub use closest::closest_point_on_triangle;
pub use derive::{
    ContinuousAxis, DerivedSymmetries, SymmetryCheck, axis_aligned_transforms, derive_symmetries, revolution_turns, row_major4,
};
pub use measure::{Displacement, SAMPLE_SEED, SURFACE_SAMPLES, SymmetryChecker, tolerance};

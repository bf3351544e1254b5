//! Randomizers: pure, seeded functions from a sample's random stream to scene parameters and
//! procedural textures. Nothing here renders; the generator turns these parameters into pixels.

mod appearance;
mod stream;
mod texture;

pub use appearance::{Appearance, Light};
pub use stream::{SampleKey, SampleStream};
pub use texture::{ProceduralTexture, checker_texture};

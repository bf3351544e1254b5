//! Randomizers: pure, seeded functions from (config, sample key) to scene appearance parameters
//! and procedural textures. Nothing here renders; the generator turns these parameters into
//! pixels. The only I/O is [`ImageLibrary::load`] (user images for the `image` texture kind).
//!
//! - [`SampleStream`]: counter-based ChaCha8 streams keyed by (seed, object, trajectory, instance,
//!   purpose), so any sample can be made alone, anywhere, with the same numbers.
//! - [`RandomizationConfig`]: the `randomization:` config section (ranges, texture kinds, shares)
//!   and its checks (a [`vt_check::Check`]: every problem names its field).
//! - [`sample_appearance`]: a sample's [`Appearance`]: spotlight (position, target, colour from a
//!   blackbody temperature times a random tint, intensity, cone), ambient level, floor and
//!   backdrop textures ([`TextureSpec`] rendered to [`ProceduralTexture`]), distractors, main-camera
//!   pose jitter, and whether the sample is randomized at all. [`sample_appearance_info`] gives the
//!   same parameters without rendering textures ([`AppearanceInfo`], serializable metadata).
//! - [`is_unrandomized`]: the unrandomized share (canonical appearance, [`Appearance::canonical`]),
//!   decided by a low-discrepancy sequence so that any 1000 consecutive samples of an object
//!   hold the configured share within ±1%.
//!
//! - [`sample_sensor_variation`]: one optical tactile sensor unit's deviation from its design
//!   (`randomization.tactile_sensors`), per pad and sample.
//!
//! Same (config, key, context) → identical parameters and texture bytes. See the crate's
//! `README.md` for every parameter and its default.

mod appearance;
mod color;
mod config;
mod images;
mod raster;
mod rotation;
mod stream;
mod tactile;
mod texture;

pub use appearance::{
    Appearance, AppearanceContext, AppearanceInfo, CANONICAL_TEXTURE_SIZE, Distractor, RobotLook, Spotlight, is_unrandomized,
    sample_appearance, sample_appearance_info,
};
pub use color::{blackbody_rgb, hsv};
pub use config::{
    COLOR_TEMPERATURE_RANGE_K, CameraJitter, LightRandomization, RandomizationConfig, RobotMaterialRandomization, TextureKind,
    TextureRandomization,
};
pub use images::ImageLibrary;
pub use rotation::uniform_rotation;
pub use stream::{SampleKey, SampleStream};
pub use tactile::{SensorVariation, TactileSensorRandomization, sample_sensor_variation};
pub use texture::{ProceduralTexture, TextureSpec, checker_texture};

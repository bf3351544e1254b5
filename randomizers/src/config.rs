//! The `randomization:` section of a scene config: which appearance parameters vary, and over
//! which ranges. Every field has a default, unknown keys are errors, and its [`Check`]
//! names each bad field by its path under `randomization`.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use vt_check::{Check, Checks, excl, field, incl, key};

/// Domain randomization of a sample's appearance (YAML section `randomization:`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RandomizationConfig {
    /// Off by default: then every sample has the canonical appearance.
    pub enabled: bool,
    /// Share of samples kept unrandomized (canonical appearance, `randomized: false` in the
    /// metadata), 0..=1. Decided by a low-discrepancy sequence, so any 1000 consecutive samples of
    /// an object hold this share within ±1%.
    pub unrandomized_share: f64,
    /// The floor texture.
    pub floor: TextureRandomization,
    /// The backdrop (background) texture.
    pub backdrop: TextureRandomization,
    /// The spotlight.
    pub light: LightRandomization,
    /// Linear ambient level range (the largest component of the ambient colour).
    pub ambient: [f32; 2],
    /// Number of distractor objects, inclusive range.
    pub distractors: [u32; 2],
    /// Random offset of the main camera's pose; zero (the default) is off.
    pub camera_jitter: CameraJitter,
    /// Side of the square procedural textures in pixels (images from a folder are always
    /// [`ImageLibrary::SIZE`](crate::ImageLibrary::SIZE)). Default 256.
    pub texture_size: u32,
    /// The robot's materials (hand and arm): off unless the key is given (`robot_materials: {}`
    /// takes the defaults). Left out of the config when off, so other datasets keep their hash.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub robot_materials: Option<RobotMaterialRandomization>,
    /// Sensor-to-sensor variation of the optical tactile sensors: off unless the key is given
    /// (`tactile_sensors: {}` takes the defaults); left out of the config when off.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tactile_sensors: Option<crate::tactile::TactileSensorRandomization>,
}

/// Per-sample variation of the robot's materials: roughness and metallic drawn from their ranges,
/// the base colour scaled per channel by a factor in `1 ± tint`. Geometry, masks and depth are
/// unchanged; canonical samples keep the assets' materials.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RobotMaterialRandomization {
    pub roughness: [f64; 2],
    pub metallic: [f64; 2],
    pub tint: f64,
}

impl Default for RobotMaterialRandomization {
    fn default() -> Self {
        RobotMaterialRandomization { roughness: [0.3, 0.9], metallic: [0.0, 0.5], tint: 0.25 }
    }
}

impl Default for RandomizationConfig {
    fn default() -> Self {
        RandomizationConfig {
            enabled: false,
            unrandomized_share: 0.2,
            floor: TextureRandomization::default(),
            backdrop: TextureRandomization::default(),
            light: LightRandomization::default(),
            ambient: [0.05, 0.45],
            distractors: [0, 0],
            camera_jitter: CameraJitter::default(),
            texture_size: 256,
            robot_materials: None,
            tactile_sensors: None,
        }
    }
}

/// Kinds of surface textures. In YAML: `noise`, `stripes`, `checker`, `gradient`, `tiles`, `image`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TextureKind {
    /// Fractal value noise (2–4 octaves) between two random colours.
    Noise,
    /// Stripes at a random angle and width in 2–3 colours.
    Stripes,
    /// A checkerboard of a random (even) cell count in two colours.
    Checker,
    /// A linear (mirrored) or radial gradient between two colours.
    Gradient,
    /// Tiles with grout lines, per-tile colour jitter, optionally in running bond.
    Tiles,
    /// A random image of the `image_dir` folder.
    Image,
}

impl TextureKind {
    /// The procedural kinds (all but [`TextureKind::Image`]): the default of `kinds`.
    pub const PROCEDURAL: [TextureKind; 5] =
        [TextureKind::Noise, TextureKind::Stripes, TextureKind::Checker, TextureKind::Gradient, TextureKind::Tiles];

    /// The YAML name.
    pub fn name(self) -> &'static str {
        match self {
            TextureKind::Noise => "noise",
            TextureKind::Stripes => "stripes",
            TextureKind::Checker => "checker",
            TextureKind::Gradient => "gradient",
            TextureKind::Tiles => "tiles",
            TextureKind::Image => "image",
        }
    }
}

/// Randomization of one textured surface (the floor or the backdrop).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TextureRandomization {
    /// Kinds to draw from with equal weight (a kind listed twice has twice the weight). Default:
    /// all procedural kinds. `image` needs `image_dir`.
    pub kinds: Vec<TextureKind>,
    /// Folder of `.png`/`.jpg`/`.jpeg` images for the `image` kind (e.g. a photo set).
    pub image_dir: Option<PathBuf>,
    /// Range of the size of one texture repeat on the surface, metres. Default [0.2, 1.0].
    pub tile_m: [f64; 2],
}

impl Default for TextureRandomization {
    fn default() -> Self {
        TextureRandomization { kinds: TextureKind::PROCEDURAL.to_vec(), image_dir: None, tile_m: [0.2, 1.0] }
    }
}

/// Randomization of the spotlight.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LightRandomization {
    /// World-frame box (z up, metres) the spotlight position is drawn from, uniformly.
    pub position_min: [f64; 3],
    pub position_max: [f64; 3],
    /// The spot aims at a point uniformly within a ball of this radius around the workspace centre.
    pub target_radius_m: f64,
    /// Blackbody colour temperature range in kelvin (drawn uniformly).
    pub color_temperature_k: [f64; 2],
    /// The blackbody colour is multiplied by a tint of random hue and a saturation up to this (0..=1).
    pub tint: f32,
    /// Intensity range (1 = the canonical light).
    pub intensity: [f32; 2],
    /// Outer half-angle range of the cone, degrees.
    pub cone_deg: [f64; 2],
    /// Range of the inner/outer cone ratio of the falloff (0 = soft from the axis, 1 = hard edge).
    pub softness: [f64; 2],
}

impl Default for LightRandomization {
    fn default() -> Self {
        LightRandomization {
            position_min: [-0.8, -1.2, 0.8],
            position_max: [0.8, 0.2, 1.8],
            target_radius_m: 0.15,
            color_temperature_k: [2700.0, 9000.0],
            tint: 0.3,
            intensity: [0.6, 1.6],
            cone_deg: [25.0, 50.0],
            softness: [0.6, 0.9],
        }
    }
}

/// Largest random offsets of the main camera pose (uniform in a ball / over rotation angles).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraJitter {
    /// Largest translation, metres (the offset is uniform in a ball of this radius).
    pub translation_m: f64,
    /// Largest rotation angle, degrees (random axis, angle uniform in [0, rotation_deg]).
    pub rotation_deg: f64,
}

/// Blackbody temperatures the colour approximation covers (Kim et al.'s Planckian locus fit).
pub const COLOR_TEMPERATURE_RANGE_K: [f64; 2] = [1667.0, 25000.0];

/// An f32 as the f64 it prints as (0.1f32 -> 0.1, not 0.10000000149011612), for messages.
fn wide(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(f64::NAN)
}

/// Every problem of the config under its field path (below `randomization`), each message naming
/// the allowed range. Checked whether or not `enabled` is set.
impl Check for RandomizationConfig {
    fn check(&self, c: &mut Checks) {
        c.key(key!(self.unrandomized_share)).bounded(self.unrandomized_share, incl(0.0), incl(1.0), "");
        c.section(field!(self.floor));
        c.section(field!(self.backdrop));
        c.section(field!(self.light));
        c.key(key!(self.ambient)).bounded_range(self.ambient.map(wide), incl(0.0), None, "linear");
        c.key(key!(self.distractors)).bounded_range(self.distractors.map(f64::from), incl(0.0), incl(64.0), "objects");
        c.section(field!(self.camera_jitter));
        c.key(key!(self.texture_size)).bounded(self.texture_size as f64, incl(8.0), incl(4096.0), "pixels");
        c.section(field!(self.robot_materials));
        c.section(field!(self.tactile_sensors));
    }
}

impl Check for TextureRandomization {
    fn check(&self, c: &mut Checks) {
        if self.kinds.is_empty() {
            c.key(key!(self.kinds)).fail("must list at least one of noise, stripes, checker, gradient, tiles, image");
        }
        if self.kinds.contains(&TextureKind::Image) && self.image_dir.is_none() {
            c.key(key!(self.image_dir)).fail("is required when kinds contains image");
        }
        c.key(key!(self.tile_m)).bounded_range(self.tile_m, excl(0.0), None, "metres");
    }
}

impl Check for LightRandomization {
    fn check(&self, c: &mut Checks) {
        let finite = self.position_min.iter().chain(&self.position_max).all(|v| v.is_finite());
        if !finite || (0..3).any(|i| self.position_min[i] > self.position_max[i]) {
            c.key(key!(self.position_max)).fail(format!(
                "must be >= position_min in every axis (finite metres), got min {:?} max {:?}",
                self.position_min, self.position_max
            ));
        }
        c.key(key!(self.position_min)).index(2).bounded(self.position_min[2], excl(0.0), None, "metres, above the floor");
        c.key(key!(self.target_radius_m)).bounded(self.target_radius_m, incl(0.0), None, "metres");
        let [tmin, tmax] = COLOR_TEMPERATURE_RANGE_K;
        c.key(key!(self.color_temperature_k)).bounded_range(self.color_temperature_k, incl(tmin), incl(tmax), "kelvin");
        c.key(key!(self.tint)).bounded(wide(self.tint), incl(0.0), incl(1.0), "");
        c.key(key!(self.intensity)).bounded_range(self.intensity.map(wide), incl(0.0), None, "");
        c.key(key!(self.cone_deg)).bounded_range(self.cone_deg, excl(0.0), excl(90.0), "degrees");
        c.key(key!(self.softness)).bounded_range(self.softness, incl(0.0), incl(1.0), "");
    }
}

impl Check for CameraJitter {
    fn check(&self, c: &mut Checks) {
        c.key(key!(self.translation_m)).bounded(self.translation_m, incl(0.0), incl(1.0), "metres");
        c.key(key!(self.rotation_deg)).bounded(self.rotation_deg, incl(0.0), incl(90.0), "degrees");
    }
}

impl Check for RobotMaterialRandomization {
    fn check(&self, c: &mut Checks) {
        c.key(key!(self.roughness)).bounded_range(self.roughness, incl(0.0), incl(1.0), "");
        c.key(key!(self.metallic)).bounded_range(self.metallic, incl(0.0), incl(1.0), "");
        c.key(key!(self.tint)).bounded(self.tint, incl(0.0), incl(1.0), "");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paths(c: &RandomizationConfig) -> Vec<String> {
        vt_check::problems(c).iter().map(|p| p.field()).collect()
    }

    #[test]
    fn defaults_are_valid_and_documented_values() {
        let c = RandomizationConfig::default();
        assert!(vt_check::problems(&c).is_empty(), "{:?}", vt_check::problems(&c));
        assert!(!c.enabled);
        assert_eq!(c.unrandomized_share, 0.2);
        assert_eq!(c.ambient, [0.05, 0.45]);
        assert_eq!(c.floor.kinds, TextureKind::PROCEDURAL.to_vec());
        assert_eq!(c.light.position_min, [-0.8, -1.2, 0.8]);
        assert_eq!(c.camera_jitter, CameraJitter { translation_m: 0.0, rotation_deg: 0.0 });
    }

    #[test]
    fn bad_ranges_are_named_with_their_allowed_range() {
        let mut c = RandomizationConfig { unrandomized_share: 1.5, ambient: [0.5, 0.1], distractors: [3, 1], ..Default::default() };
        c.light.intensity = [1.6, 0.6];
        c.light.cone_deg = [10.0, 95.0];
        c.light.color_temperature_k = [1000.0, 5000.0];
        c.light.tint = -0.1;
        c.light.target_radius_m = f64::NAN;
        c.light.position_min = [0.0, 0.0, 2.0];
        c.light.position_max = [1.0, 1.0, 1.0];
        c.floor.kinds = vec![];
        c.floor.tile_m = [0.0, 1.0];
        c.backdrop.kinds = vec![TextureKind::Image];
        c.camera_jitter.translation_m = -0.01;
        c.texture_size = 4;
        c.robot_materials = Some(RobotMaterialRandomization { roughness: [0.9, 0.2], metallic: [0.0, 1.5], tint: 2.0 });
        let errs = vt_check::problems(&c);
        let msg = |p: &str| {
            errs.iter().find(|q| q.field() == p).map(|q| q.message.clone()).unwrap_or_else(|| panic!("no error for {p}: {errs:?}"))
        };
        assert_eq!(msg("unrandomized_share"), "must be 0 <= x <= 1, got 1.5");
        assert_eq!(msg("light.intensity"), "must be [lo, hi] with 0 <= lo <= hi, got [1.6, 0.6]");
        assert_eq!(msg("light.cone_deg"), "must be [lo, hi] with 0 < lo <= hi < 90 (degrees), got [10, 95]");
        assert_eq!(msg("light.color_temperature_k"), "must be [lo, hi] with 1667 <= lo <= hi <= 25000 (kelvin), got [1000, 5000]");
        assert_eq!(msg("light.tint"), "must be 0 <= x <= 1, got -0.1");
        assert!(msg("light.target_radius_m").contains("got NaN"));
        assert!(msg("light.position_max").contains("position_min"));
        assert!(msg("ambient").contains("0 <= lo <= hi"));
        assert!(msg("distractors").contains("got [3, 1]"));
        assert!(msg("floor.kinds").contains("at least one"));
        assert!(msg("floor.tile_m").contains("0 < lo <= hi"));
        assert_eq!(msg("backdrop.image_dir"), "is required when kinds contains image");
        assert!(msg("camera_jitter.translation_m").contains("0 <= x"));
        assert!(msg("texture_size").contains("8 <= x <= 4096"));
        assert!(msg("robot_materials.roughness").contains("got [0.9, 0.2]"));
        assert!(msg("robot_materials.metallic").contains("got [0, 1.5]"));
        assert_eq!(msg("robot_materials.tint"), "must be 0 <= x <= 1, got 2");
        assert_eq!(errs.len(), 17, "{errs:?}");
        // A valid config stays valid with the image kind once a folder is named.
        let mut ok = RandomizationConfig::default();
        ok.floor.kinds.push(TextureKind::Image);
        assert_eq!(paths(&ok), vec!["floor.image_dir"]);
        ok.floor.image_dir = Some("photos".into());
        assert!(paths(&ok).is_empty());
    }

    #[test]
    fn yaml_round_trip_defaults_and_unknown_keys() {
        let yaml = "enabled: true\nunrandomized_share: 0.1\nfloor: {kinds: [noise, image], image_dir: photos}\nlight: {intensity: [0.5, 2.0]}\ndistractors: [1, 3]\ncamera_jitter: {rotation_deg: 2}\n";
        let c: RandomizationConfig = serde_yaml::from_str(yaml).unwrap();
        assert!(c.enabled);
        assert_eq!(c.floor.kinds, vec![TextureKind::Noise, TextureKind::Image]);
        assert_eq!(c.floor.image_dir.as_deref(), Some(std::path::Path::new("photos")));
        assert_eq!(c.floor.tile_m, [0.2, 1.0]);
        assert_eq!(c.light.intensity, [0.5, 2.0]);
        assert_eq!(c.light.cone_deg, [25.0, 50.0]);
        assert_eq!(c.camera_jitter, CameraJitter { translation_m: 0.0, rotation_deg: 2.0 });
        assert_eq!(c.backdrop, TextureRandomization::default());
        let back: RandomizationConfig = serde_yaml::from_str(&serde_yaml::to_string(&c).unwrap()).unwrap();
        assert_eq!(back, c);
        let empty: RandomizationConfig = serde_yaml::from_str("{}").unwrap();
        assert_eq!(empty, RandomizationConfig::default());
        for bad in ["enabeld: true", "light: {colour: [1, 1, 1]}", "floor: {kinds: [marble]}", "camera_jitter: {x: 1}"] {
            assert!(serde_yaml::from_str::<RandomizationConfig>(bad).is_err(), "{bad}");
        }
    }
}

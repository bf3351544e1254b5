//! The `randomization:` section of a scene config: which appearance parameters vary, and over
//! which ranges. Every field has a default, unknown keys are errors, and [`RandomizationConfig::validate`]
//! names each bad field by its dotted path under `randomization`.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

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

/// Bound of an allowed range: (value, inclusive).
type Bound = Option<(f64, bool)>;

fn describe(min: Bound, max: Bound, what: &str, unit: &str) -> String {
    let mut s = String::new();
    if let Some((m, incl)) = min {
        s += &format!("{m} {} ", if incl { "<=" } else { "<" });
    }
    s += what;
    if let Some((m, incl)) = max {
        s += &format!(" {} {m}", if incl { "<=" } else { "<" });
    }
    if !unit.is_empty() {
        s += &format!(" ({unit})");
    }
    s
}

fn within(x: f64, min: Bound, max: Bound) -> bool {
    x.is_finite()
        && min.is_none_or(|(m, incl)| if incl { x >= m } else { x > m })
        && max.is_none_or(|(m, incl)| if incl { x <= m } else { x < m })
}

/// An f32 as the f64 it prints as (0.1f32 -> 0.1, not 0.10000000149011612), for messages.
fn wide(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(f64::NAN)
}

struct Errors(Vec<(String, String)>);

impl Errors {
    fn range(&mut self, path: &str, r: [f64; 2], min: Bound, max: Bound, unit: &str) {
        if !(within(r[0], min, max) && within(r[1], min, max) && r[0] <= r[1]) {
            let rule = describe(min, max, "lo <= hi", unit);
            self.0.push((path.into(), format!("must be [lo, hi] with {rule}, got [{}, {}]", r[0], r[1])));
        }
    }

    fn scalar(&mut self, path: &str, x: f64, min: Bound, max: Bound, unit: &str) {
        if !within(x, min, max) {
            self.0.push((path.into(), format!("must be {}, got {x}", describe(min, max, "x", unit))));
        }
    }

    fn texture(&mut self, path: &str, t: &TextureRandomization) {
        if t.kinds.is_empty() {
            self.0.push((format!("{path}.kinds"), "must list at least one of noise, stripes, checker, gradient, tiles, image".into()));
        }
        if t.kinds.contains(&TextureKind::Image) && t.image_dir.is_none() {
            self.0.push((format!("{path}.image_dir"), format!("is required when {path}.kinds contains image")));
        }
        self.range(&format!("{path}.tile_m"), t.tile_m, Some((0.0, false)), None, "metres");
    }
}

impl RandomizationConfig {
    /// Every problem of the config as (dotted field path under `randomization`, message naming the
    /// allowed range). Empty when the config is valid. Checked whether or not `enabled` is set.
    pub fn validate(&self) -> Vec<(String, String)> {
        const ZERO: Bound = Some((0.0, true));
        let mut e = Errors(Vec::new());
        e.scalar("unrandomized_share", self.unrandomized_share, ZERO, Some((1.0, true)), "");
        e.texture("floor", &self.floor);
        e.texture("backdrop", &self.backdrop);
        let l = &self.light;
        let finite = l.position_min.iter().chain(&l.position_max).all(|v| v.is_finite());
        if !finite || (0..3).any(|i| l.position_min[i] > l.position_max[i]) {
            e.0.push((
                "light.position_max".into(),
                format!(
                    "must be >= light.position_min in every axis (finite metres), got min {:?} max {:?}",
                    l.position_min, l.position_max
                ),
            ));
        }
        e.scalar("light.position_min[2]", l.position_min[2], Some((0.0, false)), None, "metres, above the floor");
        e.scalar("light.target_radius_m", l.target_radius_m, ZERO, None, "metres");
        let [tmin, tmax] = COLOR_TEMPERATURE_RANGE_K;
        e.range("light.color_temperature_k", l.color_temperature_k, Some((tmin, true)), Some((tmax, true)), "kelvin");
        e.scalar("light.tint", wide(l.tint), ZERO, Some((1.0, true)), "");
        e.range("light.intensity", l.intensity.map(wide), ZERO, None, "");
        e.range("light.cone_deg", l.cone_deg, Some((0.0, false)), Some((90.0, false)), "degrees");
        e.range("light.softness", l.softness, ZERO, Some((1.0, true)), "");
        e.range("ambient", self.ambient.map(wide), ZERO, None, "linear");
        e.range("distractors", self.distractors.map(f64::from), ZERO, Some((64.0, true)), "objects");
        e.scalar("camera_jitter.translation_m", self.camera_jitter.translation_m, ZERO, Some((1.0, true)), "metres");
        e.scalar("camera_jitter.rotation_deg", self.camera_jitter.rotation_deg, ZERO, Some((90.0, true)), "degrees");
        e.scalar("texture_size", self.texture_size as f64, Some((8.0, true)), Some((4096.0, true)), "pixels");
        if let Some(r) = &self.robot_materials {
            e.range("robot_materials.roughness", r.roughness, ZERO, Some((1.0, true)), "");
            e.range("robot_materials.metallic", r.metallic, ZERO, Some((1.0, true)), "");
            e.scalar("robot_materials.tint", r.tint, ZERO, Some((1.0, true)), "");
        }
        if let Some(t) = &self.tactile_sensors {
            e.0.extend(t.problems().into_iter().map(|(path, message)| (format!("tactile_sensors.{path}"), message)));
        }
        e.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paths(c: &RandomizationConfig) -> Vec<String> {
        c.validate().into_iter().map(|(p, _)| p).collect()
    }

    #[test]
    fn defaults_are_valid_and_documented_values() {
        let c = RandomizationConfig::default();
        assert!(c.validate().is_empty(), "{:?}", c.validate());
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
        let errs = c.validate();
        let msg =
            |p: &str| errs.iter().find(|(q, _)| q == p).map(|(_, m)| m.clone()).unwrap_or_else(|| panic!("no error for {p}: {errs:?}"));
        assert_eq!(msg("unrandomized_share"), "must be 0 <= x <= 1, got 1.5");
        assert_eq!(msg("light.intensity"), "must be [lo, hi] with 0 <= lo <= hi, got [1.6, 0.6]");
        assert_eq!(msg("light.cone_deg"), "must be [lo, hi] with 0 < lo <= hi < 90 (degrees), got [10, 95]");
        assert_eq!(msg("light.color_temperature_k"), "must be [lo, hi] with 1667 <= lo <= hi <= 25000 (kelvin), got [1000, 5000]");
        assert_eq!(msg("light.tint"), "must be 0 <= x <= 1, got -0.1");
        assert!(msg("light.target_radius_m").contains("got NaN"));
        assert!(msg("light.position_max").contains("light.position_min"));
        assert!(msg("ambient").contains("0 <= lo <= hi"));
        assert!(msg("distractors").contains("got [3, 1]"));
        assert!(msg("floor.kinds").contains("at least one"));
        assert!(msg("floor.tile_m").contains("0 < lo <= hi"));
        assert_eq!(msg("backdrop.image_dir"), "is required when backdrop.kinds contains image");
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

//! Scene appearance: the spotlight, the ambient light, the floor and backdrop textures, the main
//! camera's pose jitter and the distractors. [`sample_appearance`] draws them from a sample's key;
//! unrandomized samples (and every sample when randomization is off) get
//! [`Appearance::canonical`].

use std::f64::consts::TAU;
use std::sync::OnceLock;

use glam::DVec3;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::color::{blackbody_rgb, hsv, normalize_max};
use crate::config::{RandomizationConfig, TextureKind, TextureRandomization};
use crate::images::ImageLibrary;
use crate::stream::{SampleKey, SampleStream};
use crate::texture::{ProceduralTexture, TextureSpec, random_spec};

/// A spotlight (world frame, metres), colour linear RGB.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Spotlight {
    pub position: DVec3,
    /// The point the cone's axis passes through.
    pub target: DVec3,
    /// Linear RGB, largest component 1.
    pub color: [f32; 3],
    /// Scale of the colour (1 = the canonical light).
    pub intensity: f32,
    /// Outer half-angle of the cone, degrees: no light outside it.
    pub cone_deg: f64,
    /// Inner/outer half-angle ratio (0..=1): full light inside `softness·cone_deg`, a smooth
    /// falloff to zero at `cone_deg`.
    pub softness: f64,
}

impl Spotlight {
    /// Unit vector from the light towards its target (zero if they coincide).
    pub fn direction(&self) -> DVec3 {
        (self.target - self.position).normalize_or_zero()
    }

    /// Inner half-angle of the cone in degrees: `softness · cone_deg`.
    pub fn inner_cone_deg(&self) -> f64 {
        self.softness * self.cone_deg
    }
}

/// A distractor object standing on the floor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Distractor {
    /// Index into the generator's distractor candidates ([`AppearanceContext::distractor_candidates`]).
    pub candidate: usize,
    /// World x, y of its position on the floor (metres).
    pub position_xy: [f64; 2],
    /// Rotation about the world z axis, radians in [0, 2π).
    pub yaw: f64,
}

/// The robot's materials in one sample (`randomization.robot_materials`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RobotLook {
    pub roughness: f32,
    pub metallic: f32,
    /// Factors on the base colour's sRGB channels.
    pub tint: [f32; 3],
}

/// Everything about a sample's look that is not the object or the robot's geometry.
#[derive(Debug, Clone, PartialEq)]
pub struct Appearance {
    pub light: Spotlight,
    /// Ambient light, linear RGB.
    pub ambient: [f32; 3],
    pub floor: ProceduralTexture,
    /// Size of one floor texture repeat in metres.
    pub floor_tile: f64,
    pub backdrop: ProceduralTexture,
    /// Size of one backdrop texture repeat in metres.
    pub backdrop_tile: f64,
    /// Offset of the main camera: (translation in metres, rotation vector in radians), both in the
    /// camera frame, applied as `T_world_camera · T(translation) · R(rotation)`. Zero = none.
    pub camera_offset: (DVec3, DVec3),
    pub distractors: Vec<Distractor>,
    /// False for the canonical appearance (the unrandomized share, or randomization off).
    pub randomized: bool,
    /// What `floor` was rendered from (for the metadata).
    pub floor_pattern: TextureSpec,
    /// What `backdrop` was rendered from.
    pub backdrop_pattern: TextureSpec,
    /// The robot's materials, when randomized (None: the assets' own).
    pub robot: Option<RobotLook>,
}

/// An [`Appearance`] without pixels: every sampled number and the texture specs. Small, and
/// serializable for the sample metadata; [`AppearanceInfo::render`] makes the [`Appearance`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AppearanceInfo {
    pub randomized: bool,
    pub light: Spotlight,
    pub ambient: [f32; 3],
    pub floor: TextureSpec,
    pub floor_tile: f64,
    pub backdrop: TextureSpec,
    pub backdrop_tile: f64,
    /// Camera offset translation (metres, camera frame).
    pub camera_translation: DVec3,
    /// Camera offset rotation vector (radians, camera frame).
    pub camera_rotation: DVec3,
    pub distractors: Vec<Distractor>,
    /// The robot's materials, when `randomization.robot_materials` is on and the sample randomized.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<RobotLook>,
}

/// What the sampler needs to know about the scene.
#[derive(Debug, Clone, Copy)]
pub struct AppearanceContext<'a> {
    /// Centre of the object workspace (world): the canonical light aims here, random ones near it.
    pub workspace_center: DVec3,
    /// Half sizes in x and y of the floor area (around the centre's x, y) distractors stand in.
    pub workspace_half_extent: [f64; 2],
    /// Number of distractor objects the generator can place (0: no distractors).
    pub distractor_candidates: usize,
    /// Images for the `image` texture kind.
    pub images: &'a ImageLibrary,
}

/// Side of the canonical textures in pixels.
pub const CANONICAL_TEXTURE_SIZE: u32 = 256;

impl AppearanceInfo {
    /// The canonical appearance, aimed at (0, 0, 0.15).
    pub fn canonical() -> Self {
        AppearanceInfo {
            randomized: false,
            light: Spotlight {
                position: DVec3::new(0.4, -0.6, 1.4),
                target: DVec3::new(0.0, 0.0, 0.15),
                color: [1.0, 0.97, 0.92],
                intensity: 1.0,
                cone_deg: 45.0,
                softness: 0.8,
            },
            ambient: [0.28, 0.28, 0.3],
            floor: TextureSpec::Checker { colors: [[150, 150, 145], [110, 110, 108]], cells: 8 },
            floor_tile: 0.4,
            backdrop: TextureSpec::Plain { color: [196, 198, 200], grain: 3 },
            backdrop_tile: 1.0,
            camera_translation: DVec3::ZERO,
            camera_rotation: DVec3::ZERO,
            distractors: Vec::new(),
            robot: None,
        }
    }

    /// Renders the textures: procedural ones at `texture_size`², images at the library's size.
    pub fn render(&self, texture_size: u32, images: &ImageLibrary) -> Appearance {
        Appearance {
            light: self.light,
            ambient: self.ambient,
            floor: self.floor.render(texture_size, images),
            floor_tile: self.floor_tile,
            backdrop: self.backdrop.render(texture_size, images),
            backdrop_tile: self.backdrop_tile,
            camera_offset: (self.camera_translation, self.camera_rotation),
            distractors: self.distractors.clone(),
            randomized: self.randomized,
            floor_pattern: self.floor.clone(),
            backdrop_pattern: self.backdrop.clone(),
            robot: self.robot,
        }
    }
}

impl Appearance {
    /// The canonical appearance: a warm-white spotlight above and in front of the workspace aimed at
    /// (0, 0, 0.15), a grey checker floor, a plain light-grey backdrop with a subtle grain, no
    /// camera jitter, no distractors. Rendered once, then cloned.
    pub fn canonical() -> Self {
        static CANONICAL: OnceLock<Appearance> = OnceLock::new();
        CANONICAL.get_or_init(|| AppearanceInfo::canonical().render(CANONICAL_TEXTURE_SIZE, &ImageLibrary::empty())).clone()
    }

    /// The appearance without its pixels (for the sample metadata).
    pub fn info(&self) -> AppearanceInfo {
        AppearanceInfo {
            randomized: self.randomized,
            light: self.light,
            ambient: self.ambient,
            floor: self.floor_pattern.clone(),
            floor_tile: self.floor_tile,
            backdrop: self.backdrop_pattern.clone(),
            backdrop_tile: self.backdrop_tile,
            camera_translation: self.camera_offset.0,
            camera_rotation: self.camera_offset.1,
            distractors: self.distractors.clone(),
            robot: self.robot,
        }
    }
}

/// 1/φ: the golden-ratio rotation that spreads the per-trajectory phases.
const GOLDEN: f64 = 0.618_033_988_749_894_9;

/// Whether sample `key` is unrandomized: always when randomization is off, otherwise for a share
/// `cfg.unrandomized_share` of the samples.
///
/// Not a coin flip but a low-discrepancy sequence, so that the share holds within ±1% over any
/// 1000 consecutive samples whatever the number of instances per trajectory. The sample's phase is
/// `u = frac(c + t/φ + s·i)` (`c` a random offset per seed and object, `t` the trajectory, `i`
/// the instance, `s` the share); it is unrandomized iff `u < s`. Within a trajectory that is a
/// Sturmian sequence (exactly ⌊s·n⌋ or ⌈s·n⌉ unrandomized among any n consecutive instances),
/// and the golden-ratio rotation of the trajectory offsets makes the rounding errors of
/// successive trajectories cancel instead of adding up.
pub fn is_unrandomized(cfg: &RandomizationConfig, key: &SampleKey) -> bool {
    !cfg.enabled || unrandomized_phase(key, cfg.unrandomized_share) < cfg.unrandomized_share
}

/// The phase `u` in [0, 1) of [`is_unrandomized`].
fn unrandomized_phase(key: &SampleKey, share: f64) -> f64 {
    let c: f64 = SampleStream::trajectory(key.seed, key.object_id, 0, "appearance/unrandomized").random();
    let trajectory_phase = (c + GOLDEN * key.trajectory as f64).fract();
    (trajectory_phase + (share * key.instance as f64).fract()).fract()
}

/// The appearance of sample `key`: [`sample_appearance_info`] with its textures rendered
/// (procedural ones at `cfg.texture_size`², canonical ones at [`CANONICAL_TEXTURE_SIZE`]²).
pub fn sample_appearance(cfg: &RandomizationConfig, key: &SampleKey, ctx: &AppearanceContext) -> Appearance {
    let info = sample_appearance_info(cfg, key, ctx);
    if !info.randomized {
        let mut a = Appearance::canonical();
        a.light = info.light;
        return a;
    }
    info.render(cfg.texture_size, ctx.images)
}

/// The appearance parameters of sample `key` without rendering textures (cheap). Unrandomized
/// samples get the canonical appearance with the light aimed at the workspace centre.
///
/// Each group of parameters has its own stream (`appearance/light`, `appearance/ambient`,
/// `appearance/floor`, `appearance/backdrop`, `appearance/distractors`, `appearance/camera`,
/// `appearance/robot`), so
/// changing one range never shifts the numbers of another.
pub fn sample_appearance_info(cfg: &RandomizationConfig, key: &SampleKey, ctx: &AppearanceContext) -> AppearanceInfo {
    if is_unrandomized(cfg, key) {
        let mut info = AppearanceInfo::canonical();
        info.light.target = ctx.workspace_center;
        return info;
    }
    let stream = |purpose: &str| SampleStream::sample(key, &format!("appearance/{purpose}"));

    let l = &cfg.light;
    let mut rng = stream("light");
    let position = DVec3::from_array(std::array::from_fn(|i| uniform(&mut rng, [l.position_min[i], l.position_max[i]])));
    let target = ctx.workspace_center + in_ball(&mut rng, l.target_radius_m);
    // A blackbody colour times a tint uniform over the disc of hues and saturations up to `tint`.
    let kelvin = uniform(&mut rng, l.color_temperature_k);
    let tint = hsv(rng.random(), l.tint * rng.random::<f32>().sqrt(), 1.0);
    let bb = blackbody_rgb(kelvin);
    let color = normalize_max([0, 1, 2].map(|i| bb[i] * tint[i]));
    let light = Spotlight {
        position,
        target,
        color,
        intensity: uniform(&mut rng, l.intensity.map(f64::from)) as f32,
        cone_deg: uniform(&mut rng, l.cone_deg),
        softness: uniform(&mut rng, l.softness),
    };

    let mut rng = stream("ambient");
    let level = uniform(&mut rng, cfg.ambient.map(f64::from)) as f32;
    let ambient_tint = hsv(rng.random(), l.tint / 3.0 * rng.random::<f32>(), 1.0);
    let ambient = normalize_max(ambient_tint).map(|v| v * level);

    let (floor, floor_tile) = surface(&mut stream("floor"), &cfg.floor, ctx.images, AppearanceInfo::canonical().floor);
    let (backdrop, backdrop_tile) = surface(&mut stream("backdrop"), &cfg.backdrop, ctx.images, AppearanceInfo::canonical().backdrop);

    let mut rng = stream("distractors");
    let [lo, hi] = cfg.distractors;
    let count = if ctx.distractor_candidates == 0 { 0 } else { lo + rng.random_range(0..=hi.saturating_sub(lo)) };
    let c = ctx.workspace_center;
    let [hx, hy] = ctx.workspace_half_extent;
    let distractors = (0..count)
        .map(|_| Distractor {
            candidate: rng.random_range(0..ctx.distractor_candidates),
            position_xy: [uniform(&mut rng, [c.x - hx, c.x + hx]), uniform(&mut rng, [c.y - hy, c.y + hy])],
            yaw: TAU * rng.random::<f64>(),
        })
        .collect();

    let mut rng = stream("camera");
    let j = &cfg.camera_jitter;
    let camera_translation = in_ball(&mut rng, j.translation_m);
    let angle = j.rotation_deg.to_radians() * rng.random::<f64>();
    let camera_rotation = if angle > 0.0 { unit_vector(&mut rng) * angle } else { DVec3::ZERO };

    let robot = cfg.robot_materials.map(|r| {
        let mut rng = stream("robot");
        RobotLook {
            roughness: uniform(&mut rng, r.roughness) as f32,
            metallic: uniform(&mut rng, r.metallic) as f32,
            tint: [0; 3].map(|_| uniform(&mut rng, [1.0 - r.tint, 1.0 + r.tint]) as f32),
        }
    });

    AppearanceInfo {
        randomized: true,
        light,
        ambient,
        floor,
        floor_tile,
        backdrop,
        backdrop_tile,
        camera_translation,
        camera_rotation,
        distractors,
        robot,
    }
}

/// A texture spec and tile size for one surface. The kind is drawn uniformly from `kinds`
/// (`image` left out when the library has no image for the surface).
fn surface(rng: &mut ChaCha8Rng, t: &TextureRandomization, images: &ImageLibrary, fallback: TextureSpec) -> (TextureSpec, f64) {
    let tile = uniform(rng, t.tile_m);
    let dir = t.image_dir.as_deref();
    let has_images = images.count_for(dir) > 0;
    let kinds: Vec<TextureKind> = t.kinds.iter().copied().filter(|&k| k != TextureKind::Image || has_images).collect();
    if kinds.is_empty() {
        return (fallback, tile);
    }
    let kind = kinds[rng.random_range(0..kinds.len())];
    (random_spec(rng, kind, images, dir), tile)
}

/// Uniform in [lo, hi] (lo when the range is empty or reversed).
fn uniform(rng: &mut impl Rng, [lo, hi]: [f64; 2]) -> f64 {
    let u: f64 = rng.random();
    if hi > lo { lo + (hi - lo) * u } else { lo }
}

/// A uniformly random unit vector.
fn unit_vector(rng: &mut impl Rng) -> DVec3 {
    let z: f64 = 2.0 * rng.random::<f64>() - 1.0;
    let phi = TAU * rng.random::<f64>();
    let r = (1.0 - z * z).max(0.0).sqrt();
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Uniform in the ball of `radius` (exactly zero for radius 0).
fn in_ball(rng: &mut impl Rng, radius: f64) -> DVec3 {
    let dir = unit_vector(rng);
    let r = radius * rng.random::<f64>().cbrt();
    if radius > 0.0 { dir * r } else { DVec3::ZERO }
}

#[cfg(test)]
mod tests;

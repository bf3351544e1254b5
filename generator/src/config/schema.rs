//! The config schema. Sections for the robot, physics, tactile sensing and randomization slot in
//! here as new optional sections; unknown keys are rejected everywhere.
//!
//! Each section's default, allowed ranges and checks sit together: the struct, its `Default`, and
//! its [`Check`] impl (paths derived from the field names, see `check.rs`).

use std::path::PathBuf;

use std::f64::consts::{PI, TAU};

use serde::{Deserialize, Serialize};

use vt_check::{Check, Checks, field, key};

/// Every section but `objects` has a default (the paper's camera, 200 x 100 samples per object,
/// split 4:1, …), so `objects: [...]` alone is a config; `vtgen config FILE` prints it resolved.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// Root of all randomness: the same seed and config give byte-identical datasets.
    #[serde(default)]
    pub seed: u64,
    /// Catalogue ids (`003_cracker_box`, …) or custom objects `{id, mesh, …}`.
    pub objects: Vec<ObjectSpec>,
    /// A YCB download (`<dir>/<id>/google_16k/textured.obj`); when absent, procedural stand-ins.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ycb_dir: Option<PathBuf>,
    #[serde(default)]
    pub sampling: Sampling,
    #[serde(default)]
    pub camera: Camera,
    #[serde(default)]
    pub scene: SceneConfig,
    #[serde(default)]
    pub renderer: RendererConfig,
    /// Domain randomization (`randomizers/README.md`); off by default.
    #[serde(default, skip_serializing_if = "is_default")]
    pub randomization: vt_randomizers::RandomizationConfig,
    /// The arm and hand and the grasp loop. Without it, the object floats in front of the camera.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<RobotConfig>,
    #[serde(default)]
    pub output: Output,
}

/// Every problem of a parsed config, section by section (the loader reports the first).
impl Check for Config {
    fn check(&self, c: &mut Checks) {
        self.check_objects(c);
        c.section(field!(self.sampling));
        c.section(field!(self.camera));
        c.section(field!(self.renderer));
        c.section(field!(self.randomization));
        c.section(field!(self.scene));
        c.section(field!(self.output));
        c.section(field!(self.robot));
        self.check_record(c);
    }
}

impl Config {
    /// Episodes need the grasp loop, and their rates fit its physics step.
    fn check_record(&self, c: &mut Checks) {
        let Some(record) = &self.sampling.record else { return };
        let sampling_config = &self.sampling;
        let mut sampling = c.key(key!(self.sampling));
        let mut at = sampling.key(key!(sampling_config.record));
        match &self.robot {
            None => at.fail("episodes record a grasp: the config needs a robot section"),
            Some(robot) => record.check_rates(robot.physics.timestep, &mut at),
        }
        at.section(field!(record.finger_motion));
    }

    /// Object ids known or well-formed, custom masses in range, no object twice.
    fn check_objects(&self, c: &mut Checks) {
        let mut objects = c.key(key!(self.objects));
        if self.objects.is_empty() {
            objects.fail("at least one object is required");
        }
        let catalog = vt_objects::Catalog::builtin();
        let mut seen = std::collections::BTreeSet::new();
        for (i, o) in self.objects.iter().enumerate() {
            let mut item = objects.index(i);
            let id = o.id();
            if let ObjectSpec::Catalog(id) = o
                && catalog.get(id).is_none()
            {
                let known: Vec<&str> = catalog.ids().collect();
                item.fail(format!("unknown object id '{id}'; the catalogue has: {}", known.join(", ")));
            }
            if let ObjectSpec::Custom(custom) = o {
                custom.check(&mut item);
            }
            if !seen.insert(id.to_string()) {
                item.fail(format!("object '{id}' is listed twice"));
            }
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotConfig {
    /// A built-in robot by name (`vt_robot::BUILTIN_ROBOTS`); default: `ur5e_allegro`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<String>,
    /// A robot description file (docs/robots.md) for a robot of one's own, instead of `model`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<PathBuf>,
    /// A URDF: replaces the one the description names (with no description: a URDF with the
    /// built-in robot's joint and link names).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub urdf: Option<PathBuf>,
    /// The real robot meshes to draw (`scripts/robot-assets`; `--robot-assets` overrides it);
    /// without them, the URDF's primitives are drawn.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub assets: Option<PathBuf>,
    /// Folders where the robot's `package://NAME/...` mesh files are found (a package's root, or a
    /// folder holding package roots), besides the folders above its URDF and the robot assets.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub package_dirs: Vec<PathBuf>,
    /// Robot base position (world) and rotation about world z.
    #[serde(default = "default_base_position")]
    pub base_position: [f64; 3],
    #[serde(default = "default_base_yaw")]
    pub base_yaw_deg: f64,
    #[serde(default)]
    pub physics: PhysicsConfig,
    #[serde(default)]
    pub grasp: GraspConfig,
    #[serde(default)]
    pub tactile: TactileConfig,
}

impl Check for RobotConfig {
    fn check(&self, c: &mut Checks) {
        c.section(field!(self.tactile));
        c.section(field!(self.physics));
        c.section(field!(self.grasp));
        let (base, position) = field!(self.base_position);
        for (i, v) in position.iter().enumerate() {
            c.key(base).index(i).within(*v, -100.0, 100.0);
        }
        c.range(field!(self.base_yaw_deg), -360.0, 360.0);
    }
}

/// The phalanx depth cameras (FORMAT.md, `/tactile/*`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TactileConfig {
    /// Pixels per side of each phalanx camera (the paper: 32).
    pub resolution: u32,
    /// A pixel is in contact when the object surface is at most this far from the pad (mm).
    pub contact_threshold_mm: f64,
    /// Depth range of the cameras from the pad plane (mm); near < 0 keeps surfaces pressed into
    /// the pad.
    pub near_mm: f64,
    pub far_mm: f64,
    /// The sensor model of each phalanx group. All give object-surface points (the paper's
    /// sensor-invariant representation); they differ in where they sample the contact.
    pub sensors: SensorGroups,
    /// `orthographic` (default: each pixel looks straight out of the pad) or `perspective` (a
    /// pinhole `perspective_standoff_mm` behind the pad whose view covers the pad).
    pub projection: PadProjection,
    pub perspective_standoff_mm: f64,
    /// The optical sensor of the pads whose model is `optical` (default: the `gelsight_mini`
    /// preset). Left out of the config when not given, so other datasets keep their hash.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub optical: Option<super::optical::OpticalConfig>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PadProjection {
    #[default]
    Orthographic,
    Perspective,
}

impl Default for TactileConfig {
    fn default() -> Self {
        TactileConfig {
            resolution: 32,
            contact_threshold_mm: 2.0,
            near_mm: -5.0,
            far_mm: 30.0,
            sensors: SensorGroups::default(),
            projection: PadProjection::Orthographic,
            perspective_standoff_mm: 10.0,
            optical: None,
        }
    }
}

impl Check for TactileConfig {
    // `!(a < b)` on purpose: a NaN in the YAML must fail the checks too.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    fn check(&self, c: &mut Checks) {
        c.range(field!(self.resolution), 4, 256);
        c.range(field!(self.contact_threshold_mm), 0.0, 50.0);
        if !(self.near_mm < self.far_mm) {
            c.key(key!(self.far_mm)).fail(format!("{} must be above near_mm ({})", self.far_mm, self.near_mm));
        }
        let groups = &self.sensors;
        let mut sensors = c.key(key!(self.sensors));
        for (group, m) in [field!(groups.proximal), field!(groups.medial), field!(groups.distal)] {
            match *m {
                SensorModel::TaxelArray { rows, cols } if rows == 0 || cols == 0 || rows > self.resolution || cols > self.resolution => {
                    sensors
                        .key(group)
                        .fail(format!("taxel grid {rows}x{cols} is out of range: 1 ..= resolution ({}) per side", self.resolution))
                }
                SensorModel::Gelsight { gel_thickness_mm } if !(gel_thickness_mm > 0.0 && gel_thickness_mm <= 20.0) => {
                    sensors.key(group).fail(format!("gel_thickness_mm {gel_thickness_mm} is out of range: 0 < t <= 20"))
                }
                _ => {}
            }
        }
        c.range(field!(self.near_mm), -100.0, 100.0);
        c.range(field!(self.far_mm), -100.0, 1000.0);
        c.positive(field!(self.perspective_standoff_mm), 100.0, "mm");
        c.section(field!(self.optical));
    }
}

impl TactileConfig {
    /// Whether any pad group has the `optical` model.
    pub fn has_optical(&self) -> bool {
        let s = &self.sensors;
        [s.proximal, s.medial, s.distal].contains(&SensorModel::Optical)
    }

    /// The optical sensor's resolved parameters (the `gelsight_mini` preset unless configured).
    pub fn optical_sensor(&self) -> super::optical::OpticalSensor {
        self.optical.clone().unwrap_or_default().resolve()
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SensorGroups {
    pub proximal: SensorModel,
    pub medial: SensorModel,
    pub distal: SensorModel,
}

impl SensorGroups {
    /// The model of a pad in `group` (the robot description's `pads[*].group`).
    pub fn of(&self, group: vt_robot::PadGroup) -> SensorModel {
        match group {
            vt_robot::PadGroup::Proximal => self.proximal,
            vt_robot::PadGroup::Medial => self.medial,
            vt_robot::PadGroup::Distal => self.distal,
        }
    }
}

impl Default for SensorGroups {
    fn default() -> Self {
        SensorGroups { proximal: SensorModel::DepthCamera, medial: SensorModel::DepthCamera, distal: SensorModel::DepthCamera }
    }
}

/// A tactile sensor model on a phalanx pad.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "model", deny_unknown_fields)]
pub enum SensorModel {
    /// Every depth-camera pixel within the contact threshold is a point (the paper's sensor).
    DepthCamera,
    /// A grid of taxels (e.g. 224 over the hand): a taxel fires when any surface under it is within
    /// the threshold and reports the surface point at its closest pixel.
    TaxelArray { rows: u32, cols: u32 },
    /// An optical gel pad: the surface indents a gel of this thickness; every indented pixel is a
    /// point (a height map of the indentation).
    Gelsight { gel_thickness_mm: f64 },
    /// An optical gel sensor (`robot.tactile.optical`): the `gelsight` rule with the sensor's gel
    /// thickness for the points, and the RGB image its camera sees (`/tactile/<pad>/image`).
    Optical,
}

fn default_base_position() -> [f64; 3] {
    [0.0, 0.5, 0.0]
}
fn default_base_yaw() -> f64 {
    180.0
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PhysicsBackend {
    #[default]
    Rapier,
    Mujoco,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PhysicsConfig {
    pub backend: PhysicsBackend,
    /// Simulation step (s).
    pub timestep: f64,
    /// Coulomb friction of hand and object surfaces.
    pub friction: f64,
    /// Finger joint PD gains (N·m/rad, N·m·s/rad) and torque limit (N·m).
    pub stiffness: f64,
    pub damping: f64,
    pub max_torque: f64,
}

impl Default for PhysicsConfig {
    fn default() -> Self {
        PhysicsConfig {
            backend: PhysicsBackend::Rapier,
            timestep: 1.0 / 240.0,
            friction: 1.5,
            stiffness: 5.0,
            damping: 0.2,
            max_torque: 0.7,
        }
    }
}

impl Check for PhysicsConfig {
    fn check(&self, c: &mut Checks) {
        c.range(field!(self.timestep), 1e-4, 0.02);
        c.range(field!(self.friction), 0.0, 10.0);
        c.positive(field!(self.stiffness), 1e4, "N·m/rad");
        c.range(field!(self.damping), 0.0, 1e3);
        c.positive(field!(self.max_torque), 1e3, "N·m");
    }
}

/// The grasp loop's parameters. Joint arrays are in the robot description's order (`arm`, `hand`);
/// left out (or empty), they are the description's (`LoadedConfig` fills them in).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GraspConfig {
    /// Arm joints the IK starts from (rad; the description's `arm.home`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub home_arm: Vec<f64>,
    /// Box (world) the palm is moved to, and how far its palmar normal may tilt from straight up.
    pub palm_workspace: Workspace,
    pub max_tilt_deg: f64,
    /// Rotation of the palm about its normal, either way from "fingers towards the camera side".
    pub max_roll_deg: f64,
    /// Share of the arm moves (instances) that turn the back of the hand to the camera: the palm
    /// normal tilts from straight up *away from the camera* by an angle drawn from
    /// `back_to_camera_tilt_deg`, so palm and fingers stand between the camera and the object.
    /// This is what reaches the paper's heavy-occlusion regime (> 85% of the model unseen); the
    /// other moves keep the `max_tilt_deg` cone. 0 (the default) draws nothing extra: configs
    /// without it give the same data as before the knob existed.
    #[serde(skip_serializing_if = "is_zero")]
    pub back_to_camera_share: f64,
    #[serde(skip_serializing_if = "is_default_back_tilt")]
    pub back_to_camera_tilt_deg: (f64, f64),
    /// Random preshape: a range per hand joint (rad; the description's `hand[*].preshape`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub preshape: Vec<(f64, f64)>,
    /// Closing targets per hand joint; null keeps the preshape value (ab/adduction).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub close: Vec<Option<f64>>,
    /// Object centre range in the palm frame (y, z used; x puts the object against the palm).
    pub object_offset: Workspace,
    /// Palmar surface of the palm (palm frame x, m).
    pub palm_surface_x: f64,
    /// Object orientations deeper than this in front of the palm (m) are redrawn: the fingers
    /// cannot wrap around them.
    pub max_grasp_depth: f64,
    pub close_seconds: f64,
    /// After closing: the palm turns from facing up to its sampled orientation over the first
    /// half, and the object must stay put over the second.
    pub settle_seconds: f64,
    /// Duration of the arm's move between instances (smoothstep in joint space). Faster moves
    /// shake heavy objects (the drill, the cracker box) out of the hand more often; a move that
    /// drops the object is undone and another drawn (both backends), so 0.5 s costs fewer simulated
    /// steps per recorded instance than 1 s.
    pub move_seconds: f64,
    /// Stillness after each move before the instance is checked and recorded.
    pub hold_seconds: f64,
    /// Grasp attempts per trajectory (each with fresh randomness) before `generate` gives up
    /// with an error naming the trajectory. Large objects need many: on the cracker box about 1
    /// attempt in 29 keeps the object through 100 arm moves.
    pub max_attempts: u32,
    /// Largest accepted penetration of a hand link into the object (m).
    pub max_penetration: f64,
}

/// Palm-normal tilt (from straight up, away from the camera) of the back-to-camera moves: from
/// nearly horizontal to 30 deg past it, palm turned a little down. Measured with `vtgen bench` on
/// `scenes/paper.yaml` (550 samples, 11 objects, share 0.5): (80, 120) puts 36% of the samples
/// above 85% occlusion, (60, 100) 27%; the `max_tilt_deg` cone alone 9%.
const DEFAULT_BACK_TILT_DEG: (f64, f64) = (80.0, 120.0);

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

fn is_default_back_tilt(v: &(f64, f64)) -> bool {
    *v == DEFAULT_BACK_TILT_DEG
}

impl Default for GraspConfig {
    fn default() -> Self {
        GraspConfig {
            home_arm: Vec::new(),
            palm_workspace: Workspace { min: [-0.08, -0.05, 0.22], max: [0.08, 0.05, 0.32] },
            max_tilt_deg: 50.0,
            max_roll_deg: 45.0,
            back_to_camera_share: 0.0,
            back_to_camera_tilt_deg: DEFAULT_BACK_TILT_DEG,
            preshape: Vec::new(),
            close: Vec::new(),
            object_offset: Workspace { min: [0.0, -0.02, 0.0], max: [0.0, 0.02, 0.05] },
            palm_surface_x: 0.0111,
            max_grasp_depth: 0.08,
            close_seconds: 0.6,
            settle_seconds: 0.4,
            move_seconds: 0.5,
            hold_seconds: 0.2,
            max_attempts: 200,
            max_penetration: 0.001,
        }
    }
}

impl GraspConfig {
    /// This config with the joint arrays it leaves out taken from the robot's description.
    pub fn with_robot_defaults(mut self, robot: &vt_robot::Robot) -> Self {
        if self.home_arm.is_empty() {
            self.home_arm = robot.home.clone();
        }
        if self.preshape.is_empty() {
            self.preshape = robot.hand.iter().map(|h| h.preshape).collect();
        }
        if self.close.is_empty() {
            self.close = robot.hand.iter().map(|h| h.close).collect();
        }
        self
    }

    /// Which joint array does not fit the robot: (field, message).
    pub fn mismatch(&self, robot: &vt_robot::Robot) -> Option<(&'static str, String)> {
        let (arm, hand) = (robot.arm_dofs.len(), robot.hand.len());
        let name = &robot.name;
        [
            (field!(self.home_arm).0, self.home_arm.len(), arm, "arm joints"),
            (field!(self.preshape).0, self.preshape.len(), hand, "hand joints"),
            (field!(self.close).0, self.close.len(), hand, "hand joints"),
        ]
        .into_iter()
        .find(|(_, n, want, _)| n != want)
        .map(|(key, n, want, what)| (key, format!("{n} values for the {want} {what} of robot '{name}'")))
    }
}

impl Check for GraspConfig {
    fn check(&self, c: &mut Checks) {
        c.range(field!(self.max_attempts), 1, 10_000);
        c.range(field!(self.max_tilt_deg), 0.0, 180.0);
        c.range(field!(self.max_roll_deg), 0.0, 180.0);
        c.range(field!(self.back_to_camera_share), 0.0, 1.0);
        c.key(key!(self.back_to_camera_tilt_deg)).ordered_pair(self.back_to_camera_tilt_deg, 0.0, 180.0);
        // Joint angles (rad): within a turn either way for the arm (the UR5e's limits), half a
        // turn for the hand. The preshape and the boxes are drawn from: a reversed range would
        // make the draw panic.
        let (home, arm) = field!(self.home_arm);
        for (i, q) in arm.iter().enumerate() {
            c.key(home).index(i).within(*q, -TAU, TAU);
        }
        let (preshape, ranges) = field!(self.preshape);
        for (i, range) in ranges.iter().enumerate() {
            c.key(preshape).index(i).ordered_pair(*range, -PI, PI);
        }
        let (close, targets) = field!(self.close);
        for (i, q) in targets.iter().enumerate() {
            if let Some(q) = q {
                c.key(close).index(i).within(*q, -PI, PI);
            }
        }
        c.section(field!(self.palm_workspace));
        c.section(field!(self.object_offset));
        c.range(field!(self.palm_surface_x), -0.1, 0.1);
        c.positive(field!(self.max_grasp_depth), 1.0, "m");
        // Durations (s): a phase of 0 s would still simulate one step, so zero is refused rather
        // than silently lengthened.
        for duration in [field!(self.close_seconds), field!(self.settle_seconds), field!(self.move_seconds), field!(self.hold_seconds)] {
            c.positive(duration, 60.0, "s");
        }
        c.range(field!(self.max_penetration), 0.0, 0.1);
    }
}

/// A catalogue id, or a custom object with its own mesh.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum ObjectSpec {
    Catalog(String),
    Custom(CustomObject),
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CustomObject {
    pub id: String,
    /// OBJ (+MTL), glTF or GLB, relative to the config file.
    pub mesh: PathBuf,
    #[serde(default = "default_mass")]
    pub mass: f64,
    #[serde(default)]
    pub symmetry: vt_objects::Symmetry,
}

fn default_mass() -> f64 {
    0.2
}

impl Check for CustomObject {
    fn check(&self, c: &mut Checks) {
        c.positive(field!(self.mass), 100.0, "kg");
        if self.id.is_empty() || !self.id.chars().all(|ch| ch.is_ascii_alphanumeric() || ch == '_' || ch == '-') {
            c.key(key!(self.id)).fail(format!("'{}' is not a valid id: use letters, digits, '_' and '-'", self.id));
        }
    }
}

impl ObjectSpec {
    pub fn id(&self) -> &str {
        match self {
            ObjectSpec::Catalog(id) => id,
            ObjectSpec::Custom(c) => &c.id,
        }
    }
}

impl<'de> Deserialize<'de> for ObjectSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = ObjectSpec;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a catalogue object id (e.g. 003_cracker_box) or a custom object {id, mesh, mass, symmetry}")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<ObjectSpec, E> {
                Ok(ObjectSpec::Catalog(v.to_string()))
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(self, map: A) -> Result<ObjectSpec, A::Error> {
                CustomObject::deserialize(serde::de::value::MapAccessDeserializer::new(map)).map(ObjectSpec::Custom)
            }
        }
        d.deserialize_any(V)
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Sampling {
    /// Random trajectories per object (the paper: 200).
    pub trajectories_per_object: u32,
    /// Recorded instances per trajectory (the paper: 100).
    pub instances_per_trajectory: u32,
    #[serde(default)]
    pub split: Split,
    /// Episodes instead of snapshots: each trajectory becomes one episode, every stream at its own
    /// rate (FORMAT.md, "Episodes"). Left out of the config when off.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub record: Option<RecordConfig>,
}

/// `sampling.record`: the rates of an episode's streams. Each is a whole number of physics steps,
/// the touch and state rates whole multiples of the camera's and the state's of the touch's, so
/// every camera frame has the touch and the state of its own instant, and every touch its state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RecordConfig {
    /// The main camera: RGB, depth, mask (Hz).
    pub camera_hz: f64,
    /// The tactile pads: depth views, the point cloud, optical images (Hz).
    pub tactile_hz: f64,
    /// Joint states and the object's pose and twist (Hz); none: every physics step.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub state_hz: Option<f64>,
    /// Scripted finger motion after each arm move (off unless given).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub finger_motion: Option<FingerMotion>,
}

impl Default for RecordConfig {
    fn default() -> Self {
        RecordConfig { camera_hz: 30.0, tactile_hz: 60.0, state_hz: None, finger_motion: None }
    }
}

/// `sampling.record.finger_motion`: after each arm move's hold, the listed hand joints swing about
/// where they stand against the object, `q + amplitude · (sin(2π t / period + phase) − sin phase)`,
/// for `cycles` periods, then squeeze again, while the arm stands still and the other joints keep
/// squeezing: a finger gait that works the object in the hand. Each arm move then takes
/// `cycles · period` longer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FingerMotion {
    #[serde(default = "default_gait_period")]
    pub period_s: f64,
    #[serde(default = "default_gait_cycles")]
    pub cycles: u32,
    pub joints: Vec<FingerJointMotion>,
}

fn default_gait_period() -> f64 {
    0.5
}
fn default_gait_cycles() -> u32 {
    2
}

/// One hand joint of a finger motion.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FingerJointMotion {
    /// A hand joint of the robot's description (`hand[].joint`).
    pub joint: String,
    pub amplitude_deg: f64,
    #[serde(default)]
    pub phase_deg: f64,
}

impl Check for FingerMotion {
    fn check(&self, c: &mut Checks) {
        c.positive(field!(self.period_s), 60.0, "s");
        c.range(field!(self.cycles), 1, 1000);
        let joints_key = key!(self.joints);
        if self.joints.is_empty() {
            c.key(joints_key).fail("list at least one hand joint");
        }
        for (i, j) in self.joints.iter().enumerate() {
            let mut joints = c.key(joints_key);
            let mut at = joints.index(i);
            at.range(field!(j.amplitude_deg), -90.0, 90.0);
            at.range(field!(j.phase_deg), -360.0, 360.0);
        }
    }
}

impl FingerMotion {
    /// Physics steps of the motion at `timestep`.
    pub fn steps(&self, timestep: f64) -> usize {
        (self.cycles as f64 * self.period_s / timestep).round() as usize
    }
}

/// Physics steps between two messages of each stream of an episode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StreamPeriods {
    pub camera: u64,
    pub tactile: u64,
    pub state: u64,
}

impl RecordConfig {
    /// Each stream's period in physics steps of `timestep` seconds (the nearest whole number).
    pub fn periods(&self, timestep: f64) -> StreamPeriods {
        let steps = |hz: f64| (1.0 / (hz * timestep)).round().max(1.0) as u64;
        StreamPeriods { camera: steps(self.camera_hz), tactile: steps(self.tactile_hz), state: self.state_hz.map_or(1, steps) }
    }

    /// The rates against the physics step: each a whole number of steps (within 1 %), touch and
    /// state whole multiples of the camera.
    fn check_rates(&self, timestep: f64, c: &mut Checks) {
        let p = self.periods(timestep);
        let rates = [(key!(self.camera_hz), self.camera_hz, p.camera), (key!(self.tactile_hz), self.tactile_hz, p.tactile)]
            .into_iter()
            .chain(self.state_hz.map(|hz| (key!(self.state_hz), hz, p.state)));
        for (key, hz, steps) in rates {
            if !(hz > 0.0 && hz <= 1.0 / timestep * 1.0001) {
                c.key(key).fail(format!("{hz} Hz is out of range: allowed 0 < rate <= the physics rate ({:.1} Hz)", 1.0 / timestep));
            } else if ((steps as f64) * hz * timestep - 1.0).abs() > 0.01 {
                c.key(key).fail(format!(
                    "{hz} Hz is not a whole number of physics steps ({timestep} s each): {:.1} Hz ({steps} steps) is",
                    1.0 / (steps as f64 * timestep)
                ));
            } else if key != key!(self.camera_hz) && !p.camera.is_multiple_of(steps) {
                c.key(key).fail(format!("{hz} Hz must be a whole multiple of camera_hz ({} Hz)", self.camera_hz));
            } else if key == key!(self.state_hz) && !p.tactile.is_multiple_of(steps) {
                c.key(key).fail(format!("{hz} Hz must be a whole multiple of tactile_hz ({} Hz)", self.tactile_hz));
            }
        }
    }
}

impl Default for Sampling {
    fn default() -> Self {
        Sampling { trajectories_per_object: 200, instances_per_trajectory: 100, split: Split::default(), record: None }
    }
}

impl Check for Sampling {
    fn check(&self, c: &mut Checks) {
        c.range(field!(self.trajectories_per_object), 1, 1_000_000);
        c.range(field!(self.instances_per_trajectory), 1, 100_000);
        c.section(field!(self.split));
    }
}

/// Train/test ratio, decided per trajectory (FORMAT.md).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Split {
    pub train: u32,
    pub test: u32,
}

impl Default for Split {
    fn default() -> Self {
        Split { train: 4, test: 1 }
    }
}

impl Check for Split {
    /// Both in range, and a split that keeps something.
    fn check(&self, c: &mut Checks) {
        c.range(field!(self.train), 0, 1000);
        c.range(field!(self.test), 0, 1000);
        if self.train == 0 && self.test == 0 {
            c.fail("train + test must be at least 1");
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Camera {
    pub width: u32,
    pub height: u32,
    /// Pinhole intrinsics in pixels (FORMAT.md pixel-centre convention) …
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub intrinsics: Option<Intrinsics>,
    /// … or a vertical field of view in degrees (square pixels, centred principal point). With
    /// neither, the paper camera's: a 615 px focal length at 480 rows, scaled with `height`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fov_y_deg: Option<f64>,
    /// Camera position in the world frame (metres).
    pub position: [f64; 3],
    /// World point the optical axis goes through.
    pub look_at: [f64; 3],
    pub near: f64,
    pub far: f64,
    /// RGB-D sensor noise (off by default): the noisy depth goes to `/camera/depth_noisy`, the
    /// clean one stays the ground truth.
    #[serde(default, skip_serializing_if = "is_default")]
    pub noise: super::noise::SensorNoise,
}

fn is_default<T: Default + PartialEq>(v: &T) -> bool {
    *v == T::default()
}

/// The paper camera's focal length (pixels) at 480 rows.
const PAPER_FOCAL_PX_AT_480: f64 = 615.0;

impl Default for Camera {
    fn default() -> Self {
        Camera {
            width: 640,
            height: 480,
            intrinsics: None,
            fov_y_deg: None,
            // The paper camera: 0.75 m in front of the robot's workspace, looking down at it.
            position: [0.0, -0.75, 0.55],
            look_at: [0.0, 0.0, 0.28],
            near: 0.05,
            far: 10.0,
            noise: Default::default(),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

impl Camera {
    /// The intrinsics, from `intrinsics`, derived from `fov_y_deg`, or the paper camera's focal
    /// length scaled to the image (615 px at 640 x 480: the paper's intrinsics exactly).
    pub fn k(&self) -> Intrinsics {
        let f = match (self.intrinsics, self.fov_y_deg) {
            (Some(k), _) => return k,
            (None, Some(fov)) => 0.5 * self.height as f64 / (0.5 * fov.to_radians()).tan(),
            (None, None) => PAPER_FOCAL_PX_AT_480 * self.height as f64 / 480.0,
        };
        Intrinsics { fx: f, fy: f, cx: (self.width as f64 - 1.0) / 2.0, cy: (self.height as f64 - 1.0) / 2.0 }
    }
}

impl Check for Camera {
    /// Image size, intrinsics or field of view, clip planes, noise models, the camera's aim.
    // `!(a <= b)` on purpose: a NaN in the YAML must fail the checks too.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    fn check(&self, c: &mut Checks) {
        c.range(field!(self.width), 8, 8192);
        c.range(field!(self.height), 8, 8192);
        match (&self.intrinsics, self.fov_y_deg) {
            (Some(_), Some(_)) => c.key(key!(self.fov_y_deg)).fail("give either intrinsics or fov_y_deg, not both"),
            (None, None) => {}
            (None, Some(f)) => c.key(key!(self.fov_y_deg)).within(f, 1.0, 170.0),
            (Some(k), None) => {
                let mut intrinsics = c.key(key!(self.intrinsics));
                intrinsics.range(field!(k.fx), 1.0, 1e6);
                intrinsics.range(field!(k.fy), 1.0, 1e6);
                intrinsics.range(field!(k.cx), -0.5, self.width as f64 - 0.5);
                intrinsics.range(field!(k.cy), -0.5, self.height as f64 - 0.5);
            }
        }
        c.range(field!(self.near), 1e-4, 100.0);
        c.section(field!(self.noise));
        if !(self.far > self.near && self.far <= 1000.0) {
            c.key(key!(self.far)).fail(format!("{} is out of range: allowed near ({}) < far <= 1000", self.far, self.near));
        }
        let d: f64 = (0..3).map(|i| (self.look_at[i] - self.position[i]).powi(2)).sum::<f64>().sqrt();
        if !(d > 1e-6) {
            c.key(key!(self.look_at)).fail("look_at must differ from position");
        } else if ((self.look_at[0] - self.position[0]).abs() + (self.look_at[1] - self.position[1]).abs()) < 1e-9 {
            c.key(key!(self.look_at)).fail("the camera must not look straight up or down (world z is the up direction)");
        }
        for (key, point) in [field!(self.position), field!(self.look_at)] {
            for (i, v) in point.iter().enumerate() {
                c.key(key).index(i).within(*v, -100.0, 100.0);
            }
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SceneConfig {
    /// Box (world frame) in which the object's centre is placed.
    #[serde(default)]
    pub workspace: Workspace,
    /// Background colour (sRGB) where nothing is drawn.
    pub background: [u8; 3],
    /// Occlusion level: model points per object, and how close (mm) a depth point must be for a
    /// model point to count as visible.
    pub occlusion_points: u32,
    pub occlusion_epsilon_mm: f64,
}

impl Default for SceneConfig {
    fn default() -> Self {
        SceneConfig { workspace: Workspace::default(), background: [70, 78, 92], occlusion_points: 2000, occlusion_epsilon_mm: 3.0 }
    }
}

impl Check for SceneConfig {
    /// A workspace above the floor, occlusion sampling.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    fn check(&self, c: &mut Checks) {
        let w = &self.workspace;
        let mut workspace = c.key(key!(self.workspace));
        w.check(&mut workspace);
        if !(w.min[2] > 0.0) {
            workspace.key(key!(w.min)).fail(format!("min z = {} must be above the floor (z > 0)", w.min[2]));
        }
        c.range(field!(self.occlusion_points), 10, 1_000_000);
        c.range(field!(self.occlusion_epsilon_mm), 0.01, 100.0);
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Workspace {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

impl Default for Workspace {
    fn default() -> Self {
        Workspace { min: [-0.08, -0.08, 0.18], max: [0.08, 0.08, 0.32] }
    }
}

impl Check for Workspace {
    /// A box: `max >= min` on every axis, every corner within 100 m of the origin.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    fn check(&self, c: &mut Checks) {
        for i in 0..3 {
            if !(self.min[i] <= self.max[i]) {
                c.key(key!(self.max)).fail(format!("max[{i}] = {} must be >= min[{i}] = {}", self.max[i], self.min[i]));
            }
        }
        for (key, corner) in [field!(self.min), field!(self.max)] {
            for (i, v) in corner.iter().enumerate() {
                c.key(key).index(i).within(*v, -100.0, 100.0);
            }
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RendererConfig {
    #[serde(default)]
    pub backend: Backend,
    /// Pick the adapter whose name contains this text (e.g. "llvmpipe", "H100").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub adapter: Option<String>,
    /// Side of the spotlight's shadow map in texels (256–8192).
    pub shadow_map_size: u32,
    /// Tone mapping of the linear colour before sRGB encoding: `none` (clamp) or `aces` (filmic).
    #[serde(default)]
    pub tonemapping: ToneMapping,
    /// Multisample anti-aliasing of the colour image: 1 (off) or 4. Depth and mask stay exact
    /// (one sample per pixel centre) either way.
    pub msaa: u32,
}

impl Default for RendererConfig {
    fn default() -> Self {
        RendererConfig { backend: Backend::Auto, adapter: None, shadow_map_size: 1024, tonemapping: ToneMapping::None, msaa: 1 }
    }
}

impl Check for RendererConfig {
    /// Shadow map size, anti-aliasing.
    fn check(&self, c: &mut Checks) {
        c.range(field!(self.shadow_map_size), 256, 8192);
        if ![1, 4].contains(&self.msaa) {
            c.key(key!(self.msaa)).fail(format!("{} is not supported: use 1 (off) or 4", self.msaa));
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ToneMapping {
    #[default]
    None,
    Aces,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Backend {
    /// The best adapter found: a GPU if there is one, else a CPU rasterizer (Mesa lavapipe).
    #[default]
    Auto,
    Vulkan,
    Gl,
    Metal,
    Dx12,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Output {
    /// Dataset directory, relative to the current directory (overridable with `--out`); default
    /// `out/<config file name without .yaml>`.
    #[serde(default)]
    pub dir: PathBuf,
    pub samples_per_shard: u32,
    #[serde(default)]
    pub compression: CompressionKind,
    pub zstd_level: i32,
}

impl Output {
    /// The shard writer's compression for this output section.
    pub fn shard_compression(&self) -> vt_dataset::Compression {
        match self.compression {
            CompressionKind::Zstd => vt_dataset::Compression::Zstd { level: self.zstd_level as u32 },
            CompressionKind::None => vt_dataset::Compression::None,
        }
    }
}

impl Default for Output {
    fn default() -> Self {
        Output { dir: PathBuf::new(), samples_per_shard: 500, compression: CompressionKind::default(), zstd_level: 3 }
    }
}

impl Check for Output {
    /// Shard size, compression.
    fn check(&self, c: &mut Checks) {
        c.range(field!(self.samples_per_shard), 1, 1_000_000);
        c.range(field!(self.zstd_level), 1, 19);
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CompressionKind {
    #[default]
    Zstd,
    None,
}

impl Config {
    /// Canonical JSON of the dataset's definition: what `config_sha256` hashes. Locations that do
    /// not change the data (output directory, YCB directory) are left out, so the same dataset
    /// generated on machines with different paths carries the same hash and bytes.
    pub fn canonical_json(&self) -> String {
        let mut c = self.clone();
        c.output.dir = PathBuf::new();
        c.ycb_dir = None;
        if let Some(r) = c.robot.as_mut() {
            r.assets = None;
        }
        serde_json::to_string(&c).expect("config serializes")
    }
}

//! The robot description: the short YAML file beside a URDF that names what the URDF cannot say
//! (docs/robots.md): the arm's chain and home, the grasp frame and the kind of grasp, the hand's
//! joints with their preshape ranges and closing targets, and the tactile pads. [`Robot`] is a
//! URDF model checked against its description, with every name resolved to an index once.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::{DAffine3, DVec3};
use serde::Deserialize;

use crate::mesh::MeshPaths;
use crate::model::{Geometry, JointKind, RobotError, RobotModel, VisualMeshes, xyz_rpy};

/// How the grasp loop takes hold of an object.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GraspKind {
    /// The object is placed on the open palm (the grasp frame's +x is the palmar normal), the hand
    /// takes a random preshape and closes around it: the multi-finger hands.
    Palm,
    /// The object is put between the open jaws at an antipodal pair of its surface points (on the
    /// line between the first two pads), the jaws close: the parallel grippers.
    ParallelJaw,
}

/// The description file as written (see `robots/ur5e_allegro/robot.yaml`).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Description {
    /// The robot's name, as datasets record it.
    pub name: String,
    /// The URDF, relative to the description file or `package://NAME/...` (a config's
    /// `robot.urdf` overrides it). With `hand_urdf`: the arm's URDF.
    #[serde(default)]
    pub urdf: Option<String>,
    /// The hand's or gripper's own URDF, mounted on the arm's link `mount.parent` (labs keep the
    /// two apart). Its links and joints join the arm's tree; names must not clash.
    #[serde(default)]
    pub hand_urdf: Option<String>,
    /// Where `hand_urdf`'s root link sits on the arm (required with `hand_urdf`).
    #[serde(default)]
    pub mount: Option<MountSpec>,
    /// Folders (relative to the description) holding the `package://` roots its URDFs name,
    /// looked in before the folders above each URDF.
    #[serde(default)]
    pub package_dirs: Vec<PathBuf>,
    pub arm: ArmSpec,
    pub grasp: GraspSpec,
    /// The hand's or gripper's joints that move on their own, in the order joint arrays use.
    /// Joints that `<mimic>` one of them follow it and are not listed.
    pub hand: Vec<HandJointSpec>,
    pub pads: Vec<PadSpec>,
    /// Links whose contact with the object counts as touching (default: the pads' links).
    #[serde(default)]
    pub touch_links: Option<Vec<String>>,
    /// Collision meshes that collide as several convex parts instead of one hull.
    #[serde(default)]
    pub convex_decomposition: Option<DecompositionSpec>,
    /// `optional`: the URDF's visual meshes are drawn when their files are there (the robot
    /// assets), else its primitive visuals (default `required`).
    #[serde(default)]
    pub drawn_meshes: VisualMeshes,
    /// `mesh_hulls`: the hand's links collide as the convex hulls of their visual meshes when
    /// those are drawn, and the pads move onto their surfaces (default `urdf`: as the URDF's
    /// collision shapes).
    #[serde(default)]
    pub hand_collision: HandCollision,
    /// The pads' sensors when a config names none for them: rules as `robot.tactile.sensors`
    /// takes them (docs/tactile.md), read by the generator (this crate knows no sensor).
    #[serde(default)]
    pub sensors: Option<serde_yaml::Value>,
    /// Joints whose URDF type or limits are corrected, by name (upstream files with `fixed` finger
    /// joints that move on the real robot): the simulated URDF is the corrected one, the upstream
    /// text is kept beside it.
    #[serde(default)]
    pub joints: BTreeMap<String, JointOverride>,
}

/// A URDF joint's type and limits as the description corrects them (`joints:`); fields not given
/// keep the URDF's values.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointOverride {
    #[serde(default, rename = "type")]
    pub kind: Option<JointType>,
    /// Limits (rad, or m for a prismatic joint), effort (N·m or N) and velocity.
    #[serde(default)]
    pub lower: Option<f64>,
    #[serde(default)]
    pub upper: Option<f64>,
    #[serde(default)]
    pub effort: Option<f64>,
    #[serde(default)]
    pub velocity: Option<f64>,
}

/// A URDF joint type a description may set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum JointType {
    Revolute,
    Continuous,
    Prismatic,
    Fixed,
}

/// How the hand collides (`hand_collision` in a description).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HandCollision {
    /// As the URDF's collision shapes.
    #[default]
    Urdf,
    /// Each hand link with visual meshes as their convex hull (the real surface the picture
    /// shows), its pads moved onto that surface; the URDF's shapes where the meshes are not there.
    MeshHulls,
}

/// Which links' collision meshes are decomposed into convex parts (V-HACD) and how finely.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DecompositionSpec {
    /// Link names, or `[all]` for every link with a collision mesh.
    pub links: Vec<String>,
    /// At most this many parts per mesh.
    #[serde(default = "default_max_hulls")]
    pub max_hulls: u32,
    /// Voxels along the mesh's longest side.
    #[serde(default = "default_resolution")]
    pub resolution: u32,
}

fn default_max_hulls() -> u32 {
    16
}

fn default_resolution() -> u32 {
    64
}

/// The collision meshes to decompose, resolved: link indices and the decomposition's parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct Decomposition {
    pub links: Vec<usize>,
    pub max_hulls: u32,
    pub resolution: u32,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MountSpec {
    /// The arm link the hand is mounted on (usually the flange).
    pub parent: String,
    /// The hand's root link in `parent`'s frame (default: at its origin).
    #[serde(default)]
    pub origin: Option<OriginSpec>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmSpec {
    /// The chain's first link (the robot's base) and last (the flange the hand is mounted on).
    pub base: String,
    pub flange: String,
    /// Arm joint values (rad or m, base to flange) the inverse kinematics starts from.
    pub home: Vec<f64>,
    /// Where the grasp frame lies, seen from above, relative to the first arm joint's angle
    /// (rad): the inverse kinematics' retries turn that joint towards a target's azimuth with it.
    /// Default: measured from the model at `home`.
    #[serde(default)]
    pub azimuth_offset: Option<f64>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GraspSpec {
    /// The link the grasp is planned in and the physics simulates the hand in (the palm; for a
    /// gripper, a frame between its jaws): +x towards the object, the arm's moves keep it within
    /// `max_tilt_deg` of straight up.
    pub frame: String,
    /// The grasp frame in `frame`'s frame, when it is not a link of its own (e.g. a gripper's
    /// tool point with +x out of the jaws): vtgen adds a link `<frame>_grasp` there.
    #[serde(default)]
    pub origin: Option<OriginSpec>,
    pub kind: GraspKind,
    /// The link the simulated hand starts from: it and everything below it (default: `frame`).
    /// The grasp frame must be fixed to it.
    #[serde(default)]
    pub hand_root: Option<String>,
    /// A grasp holds, and a pose is recorded, only with at least this many touch links touching.
    pub min_touching: usize,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HandJointSpec {
    pub joint: String,
    /// The random preshape's range (rad, or m for a prismatic joint).
    pub preshape: (f64, f64),
    /// The closing target; null keeps the preshape value (e.g. ab/adduction).
    pub close: Option<f64>,
    /// Torque (N·m) or force (N) limit of the joint's drive (default: `robot.physics.max_torque`).
    #[serde(default)]
    pub effort: Option<f64>,
    /// PD gains of the joint's drive (N·m/rad and N·m·s/rad, or N/m and N·s/m; default:
    /// `robot.physics.stiffness` and `damping`).
    #[serde(default)]
    pub stiffness: Option<f64>,
    #[serde(default)]
    pub damping: Option<f64>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PadSpec {
    /// The pad's name: its topics are `/tactile/<name>/...`.
    pub name: String,
    /// The link the pad is on (it moves with it; its contacts gate the pad's points).
    pub link: String,
    /// The pad frame (FORMAT.md, `/tactile/*`): a URDF link fixed to `link`, or an `origin`
    /// in `link`'s frame. One of the two.
    #[serde(default)]
    pub frame: Option<String>,
    #[serde(default)]
    pub origin: Option<OriginSpec>,
    /// Sensing area (length along the pad's x, width along its y; m). Default: from the link's
    /// collision geometry.
    #[serde(default)]
    pub size: Option<[f64; 2]>,
    /// Names a sensor rule may select the pad by besides its own (e.g. `proximal`, `tip`).
    #[serde(default)]
    pub labels: Vec<String>,
    /// One label (the key older descriptions used for it).
    #[serde(default)]
    pub group: Option<String>,
    /// What the pad's skin is (default: `PadContact::default()`, a soft elastomer).
    #[serde(default)]
    pub contact: Option<PadContact>,
}

/// A pad's skin as its contacts see it: what sets the size of a contact patch under a load
/// (Hertz: radius `(3 N R / 4 E*)^(1/3)`). Physics backends whose contacts are single points give
/// each pad's contacts the torsional friction of that patch; a rigid link's patch is a point.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PadContact {
    /// Effective modulus `E* = E / (1 - ν²)` of the skin against a rigid object (MPa).
    pub modulus_mpa: f64,
    /// Radius of curvature of the skin's surface where it touches (mm).
    pub crown_radius_mm: f64,
}

impl Default for PadContact {
    /// A soft silicone skin, as on gel-based sensors (E about 0.3 MPa, ν about 0.5), domed with
    /// a 20 mm radius.
    fn default() -> Self {
        PadContact { modulus_mpa: 0.4, crown_radius_mm: 20.0 }
    }
}

impl PadContact {
    /// The radius (m) of the patch a normal force `normal` (N) presses, at most `max_radius` (the
    /// pad's half width, where it is known).
    pub fn patch_radius(&self, normal: f64, max_radius: Option<f64>) -> f64 {
        let a = (3.0 * normal.max(0.0) * self.crown_radius_mm * 1e-3 / (4.0 * self.modulus_mpa * 1e6)).cbrt();
        max_radius.map_or(a, |m| a.min(m))
    }
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OriginSpec {
    pub xyz: [f64; 3],
    #[serde(default)]
    pub rpy: [f64; 3],
}

/// A prismatic finger's default drive pushes with its whole effort at this position error (m).
pub const PRISMATIC_FULL_FORCE_ERROR: f64 = 0.005;
/// A prismatic finger's default damping: its stiffness times this (s).
pub const PRISMATIC_DAMPING_TIME: f64 = 0.02;

/// A hand joint that moves on its own.
#[derive(Debug, Clone, PartialEq)]
pub struct HandJoint {
    pub name: String,
    /// Index in `model.joints`, and in the joint-value vector.
    pub joint: usize,
    pub dof: usize,
    pub preshape: (f64, f64),
    pub close: Option<f64>,
    pub effort: Option<f64>,
    pub stiffness: Option<f64>,
    pub damping: Option<f64>,
}

impl HandJoint {
    /// The sign of the joint's opening: from its closing target towards its preshape (the middle
    /// of the preshape's range). None for a joint that does not close (it keeps its preshape).
    pub fn opening_sign(&self) -> Option<f64> {
        Some((0.5 * (self.preshape.0 + self.preshape.1) - self.close?).signum())
    }
}

/// A tactile pad.
#[derive(Debug, Clone, PartialEq)]
pub struct Pad {
    pub name: String,
    /// The link it is on, and its frame (a link fixed to it).
    pub link: usize,
    pub frame: usize,
    pub size: Option<(f64, f64)>,
    /// The description's labels of the pad (sensor rules select pads by name or label).
    pub labels: Vec<String>,
    pub contact: PadContact,
}

impl Pad {
    /// Whether a sensor rule's `pattern` selects this pad: a glob (`*` any run of characters, `?`
    /// one) over its name, or one of its labels exactly.
    pub fn matches(&self, pattern: &str) -> bool {
        self.labels.iter().any(|l| l == pattern) || glob_match(pattern.as_bytes(), self.name.as_bytes())
    }
}

/// `*` and `?` glob matching (no classes, no escapes: pad names are plain words).
fn glob_match(pattern: &[u8], name: &[u8]) -> bool {
    match (pattern.first(), name.first()) {
        (None, None) => true,
        (Some(b'*'), _) => glob_match(&pattern[1..], name) || (!name.is_empty() && glob_match(pattern, &name[1..])),
        (Some(b'?'), Some(_)) => glob_match(&pattern[1..], &name[1..]),
        (Some(p), Some(n)) if p == n => glob_match(&pattern[1..], &name[1..]),
        _ => false,
    }
}

/// A URDF model with its description, every name resolved.
#[derive(Debug, Clone)]
pub struct Robot {
    pub name: String,
    pub model: RobotModel,
    /// The URDF's text as simulated (a dataset's identity names it; an arm and a hand: the two
    /// joined; the description's `joints:` corrections applied).
    pub urdf_text: String,
    /// The URDF's text before the description's `joints:` corrections (None: it has none).
    pub upstream_urdf_text: Option<String>,
    /// The description's text, as written (a dataset carries it beside the URDF).
    pub description_text: String,
    /// Moving joints from the base to the flange, and their entries in the joint-value vector.
    pub arm_joints: Vec<usize>,
    pub arm_dofs: Vec<usize>,
    pub base: usize,
    pub flange: usize,
    pub home: Vec<f64>,
    pub azimuth_offset: f64,
    pub grasp_frame: usize,
    /// The simulated hand's root link (the grasp frame is fixed to it).
    pub hand_root: usize,
    pub kind: GraspKind,
    pub min_touching: usize,
    pub hand: Vec<HandJoint>,
    /// The joints below the grasp frame that mimic a hand joint (they follow it).
    pub followers: Vec<usize>,
    pub pads: Vec<Pad>,
    pub touch_links: Vec<usize>,
    /// The links whose collision meshes collide as convex parts (None: each mesh as its hull).
    pub decomposition: Option<Decomposition>,
    /// The description's default sensor rules (`sensors:`), as written.
    pub sensors: Option<serde_yaml::Value>,
    pub hand_collision: HandCollision,
}

// The robots vtgen carries, chosen by name (`robot.model`): one folder each under `robots/`
// (`build.rs` finds them).
include!(concat!(env!("OUT_DIR"), "/builtin_robots.rs"));

/// A built-in robot's texts: its (arm's) URDF (None: its description names an upstream URDF, read
/// from the robot assets), its hand's URDF when the description mounts one, its description.
struct BuiltinTexts {
    urdf: Option<&'static str>,
    hand: Option<&'static str>,
    description: &'static str,
}

fn builtin_texts(name: &str) -> Option<BuiltinTexts> {
    BUILTIN_TEXTS.iter().find(|r| r.0 == name).map(|r| BuiltinTexts { urdf: r.1, hand: r.2, description: r.3 })
}

/// A built-in robot's description text.
pub fn builtin_description(name: &str) -> Option<&'static str> {
    builtin_texts(name).map(|t| t.description)
}

/// A built-in robot's URDF text when its folder carries it: its arm's with its hand's mounted as
/// the description says (one tree, as datasets store it).
pub fn builtin_urdf(name: &str) -> Option<String> {
    let t = builtin_texts(name)?;
    let desc = parse(t.description, name).ok()?;
    builtin_urdf_text(name, &t, &desc).ok()
}

/// The URDF text of a built-in robot that carries its URDFs: the arm's, with the hand's mounted on
/// it when the description has a `hand_urdf` (its `package://` meshes left as named).
fn builtin_urdf_text(name: &str, t: &BuiltinTexts, desc: &Description) -> Result<String, RobotError> {
    let urdf = t.urdf.expect("called for a robot that carries its URDF");
    match (t.hand, &desc.mount) {
        (Some(hand), Some(mount)) => {
            let origin = mount.origin.map_or(DAffine3::IDENTITY, |o| xyz_rpy(o.xyz, o.rpy));
            let hand_name = PathBuf::from(format!("built-in {name} hand_urdf"));
            compose_urdf(urdf, &format!("built-in {name} urdf"), hand, &hand_name, &MeshPaths::default(), &mount.parent, origin)
        }
        _ => Ok(urdf.to_string()),
    }
}

/// The file a description's `urdf` or `hand_urdf` names: `package://NAME/...` through the package
/// folders, else relative to the description's folder.
fn urdf_file(
    field: &str,
    named: &str,
    description_dir: Option<&Path>,
    package_dirs: &[PathBuf],
    source_name: &str,
) -> Result<PathBuf, RobotError> {
    let paths = MeshPaths { urdf_dir: description_dir.map(Path::to_path_buf), package_dirs: package_dirs.to_vec() };
    paths.resolve(named).map_err(|e| RobotError {
        source_name: source_name.to_string(),
        message: if description_dir.is_none() {
            format!(
                "{field}: '{named}': {e}. This robot is built from its upstream files: fetch them with `scripts/robot-assets` and \
                 pass `--robot-assets DIR` (or set robot.assets)"
            )
        } else {
            format!("{field}: '{named}': {e}")
        },
    })
}

fn read_text(p: &Path) -> Result<String, RobotError> {
    std::fs::read_to_string(p).map_err(|e| RobotError { source_name: p.display().to_string(), message: format!("cannot read: {e}") })
}

impl Robot {
    /// A built-in robot by name (`BUILTIN_ROBOTS`) whose URDF it carries.
    pub fn builtin(name: &str) -> Result<Self, RobotError> {
        Robot::builtin_with(name, &[])
    }

    /// A built-in robot by name; one built from its upstream files finds them (`package://`) in
    /// `package_dirs` (the robot assets folder of `scripts/robot-assets`).
    pub fn builtin_with(name: &str, package_dirs: &[PathBuf]) -> Result<Self, RobotError> {
        let description_name = format!("built-in {name}.yaml");
        match builtin_texts(name) {
            Some(t) if t.urdf.is_some() => {
                let desc = parse(t.description, &description_name)?;
                let urdf = builtin_urdf_text(name, &t, &desc)?;
                let paths = MeshPaths { urdf_dir: None, package_dirs: package_dirs.to_vec() };
                Robot::build(urdf, &format!("built-in {name}.urdf"), &paths, desc, t.description, &description_name)
            }
            Some(t) => {
                let desc = parse(t.description, &description_name)?;
                Robot::from_description(desc, t.description, None, None, package_dirs, &description_name)
            }
            None => Err(RobotError {
                source_name: "robot.model".into(),
                message: format!("no built-in robot '{name}' (built in: {})", BUILTIN_ROBOTS.join(", ")),
            }),
        }
    }

    /// A built-in robot's description with a URDF of one's own (its links and joints named as the
    /// built-in one's); its meshes are found beside it and in `package_dirs`.
    pub fn builtin_with_urdf(name: &str, urdf: &Path, package_dirs: &[PathBuf]) -> Result<Self, RobotError> {
        let Some(t) = builtin_texts(name) else {
            return Robot::builtin_with(name, package_dirs);
        };
        let source_name = format!("built-in {name}.yaml with {}", urdf.display());
        let mut desc = parse(t.description, &source_name)?;
        // The URDF given is the whole robot: no hand is mounted on it.
        (desc.hand_urdf, desc.mount) = (None, None);
        Robot::from_description(desc, t.description, None, Some(urdf), package_dirs, &source_name)
    }

    /// The default robot ([`crate::DEFAULT_ROBOT`]: the paper's UR5e with the Allegro hand).
    pub fn default_robot() -> Self {
        Robot::builtin(crate::DEFAULT_ROBOT).expect("the built-in robot is valid (unit-tested)")
    }

    /// Reads a description file and its URDF (`urdf`, or the one the description names relative
    /// to itself).
    /// Mesh files are found beside each URDF, in the description's `package_dirs` and in
    /// `package_dirs` (the config's, then the robot assets folder).
    pub fn from_files(description: &Path, urdf: Option<&Path>, package_dirs: &[PathBuf]) -> Result<Self, RobotError> {
        let text = read_text(description)?;
        let source_name = description.display().to_string();
        let desc = parse(&text, &source_name)?;
        let dir = description.parent().unwrap_or(Path::new("."));
        Robot::from_description(desc, &text, Some(dir), urdf, package_dirs, &source_name)
    }

    /// A parsed description with its URDF (or arm and hand URDFs) read from files.
    fn from_description(
        desc: Description,
        description_text: &str,
        dir: Option<&Path>,
        urdf: Option<&Path>,
        package_dirs: &[PathBuf],
        source_name: &str,
    ) -> Result<Self, RobotError> {
        let mut packages: Vec<PathBuf> = desc.package_dirs.iter().map(|p| dir.map_or(p.clone(), |d| d.join(p))).collect();
        packages.extend(package_dirs.iter().cloned());
        let urdf_path = match (urdf, &desc.urdf) {
            (Some(u), _) => u.to_path_buf(),
            (None, Some(u)) => urdf_file("urdf", u, dir, &packages, source_name)?,
            (None, None) => {
                return Err(RobotError {
                    source_name: source_name.to_string(),
                    message: "urdf: no URDF named (here or in the config's robot.urdf)".into(),
                });
            }
        };
        let paths = |urdf: &Path| MeshPaths { package_dirs: packages.clone(), ..MeshPaths::beside(urdf) };
        let mut urdf_text = read_text(&urdf_path)?;
        let mut urdf_name = urdf_path.display().to_string();
        match (&desc.hand_urdf, &desc.mount) {
            (Some(hand), Some(mount)) => {
                let hand_path = urdf_file("hand_urdf", hand, dir, &packages, source_name)?;
                let hand_text = read_text(&hand_path)?;
                let origin = mount.origin.map_or(DAffine3::IDENTITY, |o| xyz_rpy(o.xyz, o.rpy));
                urdf_text = compose_urdf(&urdf_text, &urdf_name, &hand_text, &hand_path, &paths(&hand_path), &mount.parent, origin)?;
                urdf_name = format!("{} + {}", urdf_path.display(), hand_path.display());
            }
            (Some(_), None) => {
                return Err(RobotError {
                    source_name: source_name.to_string(),
                    message: "mount: hand_urdf needs a mount (parent link and origin)".into(),
                });
            }
            (None, Some(_)) => {
                return Err(RobotError { source_name: source_name.to_string(), message: "mount: given without a hand_urdf".into() });
            }
            (None, None) => {}
        }
        Robot::build(urdf_text, &urdf_name, &paths(&urdf_path), desc, description_text, source_name)
    }

    /// The robot from its URDF text (the description's joint corrections applied first) and its
    /// parsed description.
    fn build(
        urdf_text: String,
        urdf_name: &str,
        paths: &MeshPaths,
        desc: Description,
        description_text: &str,
        source_name: &str,
    ) -> Result<Self, RobotError> {
        let (urdf_text, upstream) = match corrected_urdf(&urdf_text, urdf_name, &desc.joints, description_text, source_name)? {
            Some(corrected) => (corrected, Some(urdf_text)),
            None => (urdf_text, None),
        };
        let model = RobotModel::from_urdf_with(&urdf_text, urdf_name, paths, desc.drawn_meshes)?;
        let mut robot = Robot::resolve(model, urdf_text, desc, description_text, source_name)?;
        robot.upstream_urdf_text = upstream;
        Ok(robot)
    }

    /// A URDF and a description given as text (names are for errors).
    pub fn from_texts(urdf: &str, urdf_name: &str, description: &str, description_name: &str) -> Result<Self, RobotError> {
        let desc = parse(description, description_name)?;
        Robot::build(urdf.to_string(), urdf_name, &MeshPaths::default(), desc, description, description_name)
    }

    /// The grasp frame's azimuth minus the first arm joint's angle, at home.
    pub(crate) fn measured_azimuth_offset(&self) -> f64 {
        let q = self.home_q();
        let p = self.grasp_frame_pose(&q).translation;
        p.y.atan2(p.x) - q[self.arm_dofs[0]]
    }

    /// Joint values at zero (within limits) with the arm at home.
    fn home_q(&self) -> Vec<f64> {
        let mut q = self.model.zero();
        for (&d, &v) in self.arm_dofs.iter().zip(&self.home) {
            q[d] = v;
        }
        q
    }

    /// Pose of the grasp frame (the palm) in the robot base frame.
    pub fn grasp_frame_pose(&self, q: &[f64]) -> DAffine3 {
        self.model.relative_pose(q, self.model.root, self.grasp_frame)
    }

    /// Sensing area of each pad: (length along the pad's x, width along its y), metres. The
    /// description's size when it gives one; else, from the pad link's collision geometry. With
    /// primitives: the (last) collision box's extent along the pad's axes, plus the radius of a
    /// sphere on the link (a rounded tip). With a hull or a mesh: from the link's origin to its
    /// child revolute joint, or to the hull's end when it has none, by the hull's width.
    pub fn pad_sizes(&self) -> Vec<(f64, f64)> {
        let model = &self.model;
        self.pads
            .iter()
            .map(|pad| {
                if let Some(size) = pad.size {
                    return size;
                }
                let id = pad.link;
                let (mut len, mut wid) = (0.02, 0.02);
                // The pad's own x and y axes in the link frame (components below 1e-6 are zero, so
                // that a right angle written to 8 digits, as URDFs do, gives exactly the box's side).
                let t_link_pad = model.relative_pose(&model.zero(), id, pad.frame);
                let axis = |v: DVec3| {
                    let a = t_link_pad.transform_vector3(v);
                    DVec3::new(snap(a.x), snap(a.y), snap(a.z))
                };
                let (pad_x, pad_y) = (axis(DVec3::X), axis(DVec3::Y));
                for s in &model.links[id].collisions {
                    match &s.geometry {
                        // The box's extent along the pad's axes (the last box on the link: a
                        // finger's tip).
                        Geometry::Box { size } => {
                            let along = |u: DVec3| (0..3).map(|i| (s.origin.matrix3.col(i).dot(u)).abs() * size[i]).sum::<f64>();
                            (len, wid) = (along(pad_x), along(pad_y));
                        }
                        Geometry::Sphere { radius } => len += radius,
                        Geometry::Cylinder { .. } => {}
                        g @ (Geometry::ConvexHull { .. } | Geometry::Mesh { .. }) => {
                            let points = g.hull_points().expect("a hull or a mesh");
                            let next = model.joints.iter().find(|j| j.parent == id && j.kind == JointKind::Revolute);
                            let (ylo, yhi, zhi) =
                                points.iter().fold((f64::MAX, f64::MIN, f64::MIN), |(a, b, c), p| (a.min(p.y), b.max(p.y), c.max(p.z)));
                            (len, wid) = (next.map_or(zhi, |j| j.origin.translation.z), yhi - ylo);
                        }
                    }
                }
                (len, wid)
            })
            .collect()
    }

    pub fn pad_names(&self) -> Vec<String> {
        self.pads.iter().map(|p| p.name.clone()).collect()
    }

    pub fn touch_link_names(&self) -> Vec<String> {
        self.touch_links.iter().map(|&l| self.model.links[l].name.clone()).collect()
    }

    /// Writes the hand's joint values (`hand` order) into a whole joint-value vector.
    pub fn set_hand(&self, q: &mut [f64], hand: &[f64]) {
        for (h, v) in self.hand.iter().zip(hand) {
            q[h.dof] = *v;
        }
    }
}

/// An arm URDF and a hand URDF as one tree: the hand's root link fixed to the arm's `parent` at
/// `origin`, the hand's relative and `package://` mesh names turned into its files' paths (they
/// are found from the hand URDF's folder).
fn compose_urdf(
    arm: &str,
    arm_name: &str,
    hand: &str,
    hand_path: &Path,
    hand_paths: &MeshPaths,
    parent: &str,
    origin: DAffine3,
) -> Result<String, RobotError> {
    let err = |source: &str, message: String| RobotError { source_name: source.to_string(), message };
    let hand_name = hand_path.display().to_string();
    let mut robot = urdf_rs::read_from_string(arm).map_err(|e| err(arm_name, format!("not valid URDF: {e}")))?;
    let mut hand = urdf_rs::read_from_string(hand).map_err(|e| err(&hand_name, format!("not valid URDF: {e}")))?;
    if !robot.links.iter().any(|l| l.name == parent) {
        return Err(err(arm_name, format!("mount.parent: no link '{parent}' in the arm's URDF")));
    }
    let children: std::collections::HashSet<&str> = hand.joints.iter().map(|j| j.child.link.as_str()).collect();
    let roots: Vec<String> = hand.links.iter().filter(|l| !children.contains(l.name.as_str())).map(|l| l.name.clone()).collect();
    let [root] = &roots[..] else {
        return Err(err(&hand_name, format!("the hand's URDF must have one root link, it has {}: {}", roots.len(), roots.join(", "))));
    };
    for l in &hand.links {
        if robot.links.iter().any(|a| a.name == l.name) {
            return Err(err(&hand_name, format!("link '{}' is in the arm's URDF too: rename one", l.name)));
        }
    }
    for j in &hand.joints {
        if robot.joints.iter().any(|a| a.name == j.name) {
            return Err(err(&hand_name, format!("joint '{}' is in the arm's URDF too: rename one", j.name)));
        }
    }
    for link in &mut hand.links {
        let geometries = link.visual.iter_mut().map(|v| &mut v.geometry).chain(link.collision.iter_mut().map(|c| &mut c.geometry));
        for g in geometries {
            if let urdf_rs::Geometry::Mesh { filename, .. } = g
                && let Ok(p) = hand_paths.resolve(filename)
            {
                *filename = p.display().to_string();
            }
        }
    }
    let (_, rot, xyz) = origin.to_scale_rotation_translation();
    let (yaw, pitch, roll) = rot.to_euler(glam::EulerRot::ZYX);
    robot.joints.push(urdf_rs::Joint {
        name: format!("{root}_mount"),
        joint_type: urdf_rs::JointType::Fixed,
        origin: urdf_rs::Pose { xyz: urdf_rs::Vec3(xyz.to_array()), rpy: urdf_rs::Vec3([roll, pitch, yaw]) },
        parent: urdf_rs::LinkName { link: parent.to_string() },
        child: urdf_rs::LinkName { link: root.clone() },
        axis: Default::default(),
        limit: Default::default(),
        calibration: None,
        dynamics: None,
        mimic: None,
        safety_controller: None,
    });
    let arm_materials: Vec<String> = robot.materials.iter().map(|m| m.name.clone()).collect();
    robot.materials.extend(hand.materials.into_iter().filter(|m| !arm_materials.contains(&m.name)));
    robot.links.extend(hand.links);
    robot.joints.extend(hand.joints);
    urdf_rs::write_to_string(&robot).map_err(|e| err(&hand_name, format!("cannot join the arm and the hand: {e}")))
}

/// The URDF with the description's `joints:` corrections applied (None when it has none): each
/// named joint's type, limits, effort and velocity as given. Errors name the description's line.
fn corrected_urdf(
    urdf: &str,
    urdf_name: &str,
    joints: &BTreeMap<String, JointOverride>,
    description_text: &str,
    source_name: &str,
) -> Result<Option<String>, RobotError> {
    if joints.is_empty() {
        return Ok(None);
    }
    let mut robot = urdf_rs::read_from_string(urdf)
        .map_err(|e| RobotError { source_name: urdf_name.to_string(), message: format!("not valid URDF: {e}") })?;
    let problem = |name: &str, field: Option<&'static str>, message: String| {
        let mut path = vec![vt_check::Seg::key("joints"), vt_check::Seg::key(name.to_string())];
        path.extend(field.map(vt_check::Seg::key));
        let line = vt_check::locate::locate(description_text, &path).map(|(l, _)| format!("line {l}: ")).unwrap_or_default();
        let field = field.map_or(String::new(), |f| format!(".{f}"));
        RobotError { source_name: source_name.to_string(), message: format!("{line}joints.{name}{field}: {message}") }
    };
    for (name, o) in joints {
        let Some(j) = robot.joints.iter_mut().find(|j| &j.name == name) else {
            return Err(problem(name, None, format!("no joint '{name}' in the URDF")));
        };
        if let Some(kind) = o.kind {
            j.joint_type = match kind {
                JointType::Revolute => urdf_rs::JointType::Revolute,
                JointType::Continuous => urdf_rs::JointType::Continuous,
                JointType::Prismatic => urdf_rs::JointType::Prismatic,
                JointType::Fixed => urdf_rs::JointType::Fixed,
            };
        }
        for (field, value, slot) in [
            ("lower", o.lower, &mut j.limit.lower),
            ("upper", o.upper, &mut j.limit.upper),
            ("effort", o.effort, &mut j.limit.effort),
            ("velocity", o.velocity, &mut j.limit.velocity),
        ] {
            if let Some(v) = value {
                if !v.is_finite() || (matches!(field, "effort" | "velocity") && v < 0.0) {
                    return Err(problem(
                        name,
                        Some(field),
                        format!("{v} is not a finite{} number", if field == "lower" || field == "upper" { "" } else { ", non-negative" }),
                    ));
                }
                *slot = v;
            }
        }
        let moves = !matches!(j.joint_type, urdf_rs::JointType::Fixed);
        let limited = matches!(j.joint_type, urdf_rs::JointType::Revolute | urdf_rs::JointType::Prismatic);
        if limited && j.limit.lower >= j.limit.upper {
            return Err(problem(
                name,
                None,
                format!("moves between {} and {}: give a range (lower below upper) for a joint that moves", j.limit.lower, j.limit.upper),
            ));
        }
        if moves && j.axis.xyz.0.iter().all(|a| *a == 0.0) {
            return Err(problem(name, Some("type"), "the URDF gives this joint no axis to move about".into()));
        }
    }
    urdf_rs::write_to_string(&robot)
        .map(Some)
        .map_err(|e| RobotError { source_name: urdf_name.to_string(), message: format!("cannot write the corrected URDF: {e}") })
}

/// `x`, or 0 when it is a rounding error's size (cos(1.57079633) is 3e-9).
fn snap(x: f64) -> f64 {
    if x.abs() < 1e-6 { 0.0 } else { x }
}

/// The description's YAML; errors name the file, line and field (serde's path).
fn parse(text: &str, source_name: &str) -> Result<Description, RobotError> {
    serde_yaml::from_str(text).map_err(|e| {
        let at = e.location().map(|l| format!("line {}: ", l.line())).unwrap_or_default();
        RobotError { source_name: source_name.to_string(), message: format!("{at}{e}") }
    })
}

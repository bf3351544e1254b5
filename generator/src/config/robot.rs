//! `robot:` the robot (built in or a lab's own), where it stands, and its physics, grasp and
//! tactile sections.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use vt_check::{Check, Checks, field, key};

use super::{GraspConfig, PhysicsConfig, TactileConfig};

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
        if self.tactile.force_field.is_some() && self.physics.backend == super::PhysicsBackend::Rapier {
            c.key(key!(self.tactile)).key("force_field").fail(
                "needs the contact forces of the physics, which rapier does not give reliably (docs/tactile.md, \"Force fields\"): \
                 set robot.physics.backend: mujoco",
            );
        }
    }
}

fn default_base_position() -> [f64; 3] {
    [0.0, 0.5, 0.0]
}

fn default_base_yaw() -> f64 {
    180.0
}

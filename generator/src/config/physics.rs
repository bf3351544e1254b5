//! `robot.physics:` the physics backend and the hand's contact and drive parameters.

use serde::{Deserialize, Serialize};
use vt_check::{Check, Checks, field};

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

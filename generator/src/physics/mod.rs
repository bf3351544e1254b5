//! Physics behind a small trait. The hand is simulated in its grasp frame (the palm): a fixed-base
//! articulated hand or gripper (its description's joints PD-controlled, `<mimic>` joints following
//! them) and one free object. The arm's motion enters as the apparent
//! gravity in the palm frame, `R_palmᵀ (g − a_palm)`, which is what makes an object slip or turn in
//! the hand when the arm reorients or accelerates. (Rotational fictitious forces, below 1% of g for
//! the arm's speeds, are neglected.) This keeps the grasp stable and identical for every backend.

pub mod antipodal;
pub mod convex_parts;
#[cfg(test)]
pub(crate) mod fake;
pub mod grasp;
pub mod hand_assembly;
mod hull_shape;
#[cfg(feature = "mujoco")]
mod mujoco_backend;
mod rapier_backend;
pub mod robot;

use glam::{DAffine3, DVec3};

#[cfg(feature = "mujoco")]
pub use mujoco_backend::MujocoHand;
pub use rapier_backend::RapierHand;

/// What the physics needs of an object: a convex collision shape and a mass.
#[derive(Debug, Clone)]
pub struct PhysicsObject {
    /// Vertices (model frame); the backend uses their convex hull.
    pub points: Vec<[f32; 3]>,
    pub mass: f64,
}

/// One contact point between a hand link and the object, in the grasp (palm) frame, with the force
/// the backend's solver applied there in its last step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandContact {
    /// The hand link (`RobotModel::links` index).
    pub link: usize,
    /// The contact point (m).
    pub point: DVec3,
    /// Unit contact normal, out of the link towards the object.
    pub normal: DVec3,
    /// The force the object exerts on the link there (N): its part along `-normal` is the
    /// pressure, the rest is friction.
    pub force: DVec3,
}

/// Per-step settings shared by backends.
#[derive(Debug, Clone, Copy)]
pub struct PhysicsSettings {
    pub timestep: f64,
    pub friction: f64,
    /// PD gains of the hand joints (N·m/rad, N·m·s/rad; N/m, N·s/m for prismatic ones) and the
    /// effort limit of joints whose description gives none (N·m or N).
    pub stiffness: f64,
    pub damping: f64,
    pub max_torque: f64,
}

impl From<&crate::config::PhysicsConfig> for PhysicsSettings {
    fn from(pc: &crate::config::PhysicsConfig) -> Self {
        PhysicsSettings {
            timestep: pc.timestep,
            friction: pc.friction,
            stiffness: pc.stiffness,
            damping: pc.damping,
            max_torque: pc.max_torque,
        }
    }
}

/// The simulated hand in the grasp frame.
pub trait HandPhysics {
    fn backend_name(&self) -> &'static str;
    /// A new grasp: hand joints at `q` (one value per hand joint, `Robot::hand` order), the object
    /// at `object_pose` (grasp frame), at rest.
    fn reset(&mut self, object: &PhysicsObject, object_pose: DAffine3, q: &[f64]) -> anyhow::Result<()>;
    /// PD targets of the hand joints (`Robot::hand` order); mimic joints follow theirs.
    fn set_targets(&mut self, targets: &[f64]);
    /// Apparent gravity in the palm frame (m/s²).
    fn set_gravity(&mut self, g: DVec3);
    /// Extra damping of the object's motion, e.g. while the fingers close around it.
    fn set_object_damping(&mut self, linear: f64, angular: f64);
    fn step(&mut self);
    /// Steps taken since the backend was made (for `vtgen bench`'s cost per step).
    fn steps_taken(&self) -> u64;
    fn object_pose(&self) -> DAffine3;
    /// The hand joints' positions (`Robot::hand` order).
    fn joint_positions(&self) -> Vec<f64>;
    /// For each touch link (`Robot::touch_links` order): the signed distance of its closest
    /// contact with the object (negative = penetration), None when not touching.
    fn touch_contacts(&self) -> Vec<Option<f64>>;
    /// Every contact of a hand link with the object and the force on the link there (an empty list
    /// when nothing touches). At rest the forces on the links sum to the object's weight in the
    /// apparent gravity (the balance `tests/contact_forces.rs` checks). None: the backend cannot
    /// give forces that balance. rapier cannot: the impulses its solver keeps per contact, summed
    /// over a settled Allegro hold, miss the weight by 3.6 and 33 times its size on 2 of 3 test
    /// holds, so force fields need MuJoCo (docs/tactile.md).
    fn hand_contacts(&self) -> Option<Vec<HandContact>>;
    /// Deepest penetration (m, >= 0) of any hand link into the object.
    fn max_penetration(&self) -> f64;
    /// The hand link (`RobotModel::links` index) that reaches deepest into the object, and how
    /// deep (m, >= 0); None when no link touches it. Errors name it (an `InitialOverlap`).
    fn deepest_link(&self) -> Option<(usize, f64)>;
    /// The whole simulation state, so that `restore` can undo what follows (an arm move that
    /// dropped the object or ended in a pose that cannot be recorded, the hold screen's probes).
    /// Every backend must: the grasp loop's redo of a move depends on it, and so do the data's
    /// bytes. Valid until the next `reset`.
    fn save(&self) -> SavedState;
    /// Back to a state `save` returned since the last `reset`.
    fn restore(&mut self, state: &SavedState);
}

/// A backend's whole simulation state (`HandPhysics::save`): opaque to the grasp loop, which
/// only hands it back to the backend that made it.
pub struct SavedState(Box<dyn std::any::Any + Send>);

impl SavedState {
    pub fn new<T: std::any::Any + Send>(state: T) -> Self {
        SavedState(Box::new(state))
    }

    /// The backend's own state; a state from another backend is a bug in the grasp loop.
    pub fn get<T: std::any::Any>(&self) -> &T {
        self.0.downcast_ref().expect("a state saved by this backend")
    }
}

//! The robot as data: a URDF (arm and hand or gripper) and the short description beside it that
//! names what the URDF cannot say (the arm chain, the grasp frame and kind, the hand's joints and
//! the tactile pads). Each built-in robot is a folder of data under `robots/` (`robot.yaml`, and
//! `robot.urdf` unless the description names its upstream URDF), found by `build.rs`.
//!
//! This crate turns them into a checked kinematic model: forward kinematics of every link
//! (revolute, prismatic and `<mimic>` joints), inverse kinematics of the grasp frame over the arm
//! chain, and the primitive geometry (boxes, cylinders, spheres) that physics and rendering use.

mod description;
mod ik;
pub mod mesh;
mod model;
mod resolve;

pub use description::{
    BUILTIN_ROBOTS, Decomposition, DecompositionSpec, Description, GraspKind, HandCollision, HandJoint, PRISMATIC_DAMPING_TIME,
    PRISMATIC_FULL_FORCE_ERROR, Pad, PadContact, Robot, builtin_description, builtin_urdf,
};
pub use ik::IkOptions;
pub use mesh::{MeshPaths, TriangleMesh};
pub use model::{Geometry, Joint, JointKind, Link, Mimic, NO_RGBA, RobotError, RobotModel, Shape, VisualMeshes, xyz_rpy};

/// The robot a config without `robot.model` gets: the paper's.
pub const DEFAULT_ROBOT: &str = "ur5e_allegro";

#[cfg(test)]
mod tests;

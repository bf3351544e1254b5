//! The hand as a physics engine builds it, worked out once for every backend: its rigid bodies
//! (each moving link with the links fixed to it, their masses lumped), their colliders, the
//! simulated joints with their drives, and the `<mimic>` couplings. The rapier and MuJoCo backends
//! translate this assembly into their own terms; neither re-derives it from the robot.

use anyhow::{Result, bail};
use glam::{DAffine3, DVec3};
use vt_robot::{JointKind, Robot};

use super::PhysicsSettings;

/// A moving body lighter than this (kg) is simulated at this mass: a massless link (a URDF that
/// gives none) has no inertia to integrate.
const MIN_BODY_MASS: f64 = 0.005;
/// Side (m) of the cube whose inertia every body gets about its centre of mass: the URDFs' own
/// inertia tensors are often placeholders, and a small cube keeps the fingers stable.
const INERTIA_CUBE_SIDE: f64 = 0.02;

/// A rigid body of the hand: the frame of `link`, and every link fixed below it that has mass or
/// collision geometry.
#[derive(Debug, Clone)]
pub struct Body {
    pub link: usize,
    /// The lumped mass (kg, at least [`MIN_BODY_MASS`]; the root's is not used: it is fixed).
    pub mass: f64,
    /// The lumped centre of mass, in the body's frame.
    pub com: DVec3,
}

impl Body {
    /// The diagonal of the body's inertia tensor about its centre of mass (kg·m²): a cube of
    /// [`INERTIA_CUBE_SIDE`]'s of the body's mass.
    pub fn inertia(&self) -> f64 {
        self.mass * INERTIA_CUBE_SIDE * INERTIA_CUBE_SIDE / 6.0
    }

    /// [`Body::inertia`] computed in single precision, for an engine that works in it.
    pub fn inertia_f32(&self) -> f32 {
        let side = INERTIA_CUBE_SIDE as f32;
        self.mass as f32 * side * side / 6.0
    }
}

/// A collision shape on a body: shape `shape` of `link`'s collisions, at `pose` in the body frame.
#[derive(Debug, Clone)]
pub struct Collider {
    pub body: usize,
    pub link: usize,
    pub shape: usize,
    pub pose: DAffine3,
}

/// A hand joint's PD gains and effort limit: the description's, or the config's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Drive {
    pub stiffness: f64,
    pub damping: f64,
    pub effort: f64,
}

impl Drive {
    pub fn of(h: &vt_robot::HandJoint, s: &PhysicsSettings) -> Self {
        Drive {
            stiffness: h.stiffness.unwrap_or(s.stiffness),
            damping: h.damping.unwrap_or(s.damping),
            effort: h.effort.unwrap_or(s.max_torque),
        }
    }
}

/// A simulated joint: a hand joint, or a follower (`<mimic>`) of one.
#[derive(Debug, Clone)]
pub struct SimJoint {
    /// The joint (`RobotModel::joints` index) and the bodies it joins ([`HandAssembly::bodies`]).
    pub joint: usize,
    pub parent: usize,
    pub child: usize,
    /// The joint's frame in the parent body's frame (the child body's frame at joint value 0).
    pub origin: DAffine3,
    pub axis: DVec3,
    pub prismatic: bool,
    pub lower: f64,
    pub upper: f64,
    /// The hand joint that drives it (`Robot::hand` index), and the joint's value as
    /// `multiplier · value + offset` of the driving joint's (1 and 0 for a hand joint itself).
    pub hand: usize,
    pub multiplier: f64,
    pub offset: f64,
    /// A mimic joint: its value follows its leader's.
    pub follower: bool,
    /// The driving hand joint's gains.
    pub drive: Drive,
}

/// The hand below its root, fixed in the grasp frame.
#[derive(Debug, Clone)]
pub struct HandAssembly {
    /// The root's pose in the grasp frame; None: the root is the grasp frame.
    pub t_grasp_root: Option<DAffine3>,
    /// The root body first; the others in the order of their first link with mass or geometry.
    pub bodies: Vec<Body>,
    /// Every collider, in link order.
    pub colliders: Vec<Collider>,
    /// The hand's joints (`Robot::hand` order), then their followers (in tree order).
    pub joints: Vec<SimJoint>,
}

impl HandAssembly {
    /// A pose in the root's frame, in the grasp frame.
    pub fn in_grasp_frame(&self, t: DAffine3) -> DAffine3 {
        self.t_grasp_root.map_or(t, |g| g * t)
    }

    pub fn new(robot: &Robot, settings: &PhysicsSettings) -> Result<Self> {
        let m = &robot.model;
        let root = robot.hand_root;
        // Only fixed joints lie between the root and the grasp frame, and between a body's link
        // and the links fixed to it: these poses do not depend on the joint values.
        let q = m.zero();
        let t_grasp_root = (root != robot.grasp_frame).then(|| m.relative_pose(&q, root, robot.grasp_frame).inverse());
        // Each link below the root moves with a body: its own when a joint moves it, else its
        // parent's (links fixed to another, e.g. sensor pads or a finger's outer shell).
        let mut body_link = vec![usize::MAX; m.links.len()];
        for (li, link) in m.links.iter().enumerate() {
            if !m.is_below(li, root) {
                continue;
            }
            body_link[li] = match link.parent_joint {
                _ if li == root => li,
                Some(j) if m.joints[j].moves() => li,
                Some(j) => body_link[m.joints[j].parent],
                None => li,
            };
        }
        // A body for the root and for every body link with a link of mass or geometry.
        let mut body_of_link = vec![None; m.links.len()];
        let mut bodies: Vec<Body> = Vec::new();
        let mut colliders = Vec::new();
        for (li, link) in m.links.iter().enumerate() {
            let b = body_link[li];
            if b == usize::MAX || (li != root && link.mass <= 0.0 && link.collisions.is_empty()) {
                continue;
            }
            let body = *body_of_link[b].get_or_insert_with(|| {
                bodies.push(lumped(robot, &q, &body_link, b));
                bodies.len() - 1
            });
            let t_body_link = if b == li { DAffine3::IDENTITY } else { m.relative_pose(&q, b, li) };
            for (shape, s) in link.collisions.iter().enumerate() {
                colliders.push(Collider { body, link: li, shape, pose: t_body_link * s.origin });
            }
        }
        let mut drives: Vec<(usize, usize, f64, f64)> = robot.hand.iter().enumerate().map(|(k, h)| (h.joint, k, 1.0, 0.0)).collect();
        for &f in &robot.followers {
            let mimic = m.joints[f].mimic.expect("a follower mimics");
            let k = robot.hand.iter().position(|h| h.joint == mimic.leader).expect("a follower's leader is a hand joint");
            drives.push((f, k, mimic.multiplier, mimic.offset));
        }
        let mut joints = Vec::new();
        for (ji, hand, multiplier, offset) in drives {
            let j = &m.joints[ji];
            let pb = body_link[j.parent];
            let (Some(parent), Some(child)) = (body_of_link[pb], body_of_link[j.child]) else {
                bail!("joint {} links bodies without geometry", j.name)
            };
            joints.push(SimJoint {
                joint: ji,
                parent,
                child,
                origin: if pb == j.parent { j.origin } else { m.relative_pose(&q, pb, j.parent) * j.origin },
                axis: j.axis,
                prismatic: j.kind == JointKind::Prismatic,
                lower: j.lower,
                upper: j.upper,
                hand,
                multiplier,
                offset,
                follower: j.mimic.is_some(),
                drive: Drive::of(&robot.hand[hand], settings),
            });
        }
        Ok(HandAssembly { t_grasp_root, bodies, colliders, joints })
    }
}

/// Body `b`'s mass and centre of mass: its link's, with the links fixed to it that have mass
/// (positions in `b`'s frame), the mass at least [`MIN_BODY_MASS`].
fn lumped(robot: &Robot, q: &[f64], body_link: &[usize], b: usize) -> Body {
    let m = &robot.model;
    let parts: Vec<usize> = (0..m.links.len()).filter(|&l| body_link[l] == b && m.links[l].mass > 0.0).collect();
    let (mass, com) = match parts[..] {
        [] => (0.0, m.links[b].com),
        [only] if only == b => (m.links[b].mass, m.links[b].com),
        _ => {
            let total: f64 = parts.iter().map(|&l| m.links[l].mass).sum();
            let moment =
                parts.iter().fold(DVec3::ZERO, |acc, &l| acc + m.relative_pose(q, b, l).transform_point3(m.links[l].com) * m.links[l].mass);
            (total, moment / total)
        }
    };
    Body { link: b, mass: mass.max(MIN_BODY_MASS), com }
}

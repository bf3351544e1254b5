//! rapier3d backend: the hand as fixed-root multibodies (reduced coordinates, so long finger chains
//! stay stiff), joint motors as PD controllers (a `<mimic>` joint's motor tracks its leader's
//! target), the object as a convex hull.

use anyhow::{Context, Result};
use glam::{DAffine3, DQuat, DVec3, Vec3};
use rapier3d::prelude::*;
use vt_robot::{Geometry, Robot};

use super::hand_assembly::{Drive, HandAssembly, SimJoint};
use super::hull_shape::WalkedHull;
use super::{HandPhysics, PhysicsObject, PhysicsSettings, SavedState};

const HAND_GROUP: Group = Group::GROUP_1;
const OBJECT_GROUP: Group = Group::GROUP_2;

fn to_pose(t: &DAffine3) -> Pose {
    let q = DQuat::from_mat3(&t.matrix3).normalize();
    Pose::from_parts(t.translation.as_vec3(), q.as_quat())
}

fn from_pose(p: &Pose) -> DAffine3 {
    DAffine3::from_rotation_translation(p.rotation.as_dquat(), p.translation.as_dvec3())
}

/// A simulated joint of the assembly, with its bodies and its joint in the world.
struct HandJoint {
    body: RigidBodyHandle,
    parent: RigidBodyHandle,
    joint: MultibodyJointHandle,
    assembly: SimJoint,
}

/// A mimic joint stands for a rigid linkage (the 2F-85's four-bar): its drive tracks the leader's
/// position with this many times the hand's PD gains and effort, so that the coupling holds under
/// the grip's load.
const FOLLOWER_GAIN: f64 = 20.0;

/// A link's collision shape (a mesh link's: the exact hull of its points, `hull_shape`). None: a degenerate mesh.
fn collision_shape(g: &Geometry) -> Option<SharedShape> {
    Some(match g {
        Geometry::Box { size } => SharedShape::cuboid(size.x as f32 / 2.0, size.y as f32 / 2.0, size.z as f32 / 2.0),
        Geometry::Sphere { radius } => SharedShape::ball(*radius as f32),
        Geometry::Cylinder { radius, length } => SharedShape::cylinder(*length as f32 / 2.0, *radius as f32),
        hull @ (Geometry::ConvexHull { .. } | Geometry::Mesh { .. }) => {
            let pts: Vec<Vec3> = hull.hull_points()?.iter().map(|p| p.as_vec3()).collect();
            hull_shape(&pts)?
        }
    })
}

/// The exact convex hull of `points` (parry's), as a collider shape whose bounding box and support
/// points are found by walking its surface (`hull_shape.rs`: the same values, a few dozen vertices
/// visited instead of all). None: degenerate points.
fn hull_shape(points: &[Vec3]) -> Option<SharedShape> {
    Some(SharedShape::new(WalkedHull::from_points(points)?))
}

/// An empty world with the hand's solver parameters.
fn hand_world(settings: &PhysicsSettings) -> PhysicsWorld {
    let mut world = PhysicsWorld::new();
    world.integration_parameters.dt = settings.timestep as f32;
    // Tighter than the default so resting contacts penetrate well under a millimetre.
    world.integration_parameters.normalized_allowed_linear_error = 0.0002;
    world.integration_parameters.num_solver_iterations = 4;
    // Four Gauss-Seidel sweeps per solver iteration instead of one: with one, the friction of
    // a held object's 5 to 7 contacts did not converge, and objects crept 1 to 5 mm and up to
    // 3.5° in 10 s with the arm still (7 of 12 test grasps still); with four and the stiffer
    // contacts below, 12 of 12 stay within 0.5 mm and 0.6° (tests/grasping.rs) at the same
    // physics time per sample, measured with `vtgen bench`. More substeps (16 solver
    // iterations) or friction in the bias pass did not help.
    world.integration_parameters.num_internal_pgs_iterations = 4;
    // Every step finds the contacts anew. Rapier's contact recycling reuses a pair's contact
    // points until the pair has moved 5 cm (its default), which here let held objects sink 2 to
    // 15 mm into the palm during arm moves, unseen by the solver (the moves then failed the
    // penetration check and were redone; `tests/grasping.rs`). Off, the CPU per step stayed
    // within `vtgen bench`'s run-to-run noise, and far fewer grasps are lost (docs/grasp-loop.md).
    world.integration_parameters.contact_recycling = false;
    // Stiff contacts: fingers squeeze with up to 0.7 N·m, which soft contacts turn into
    // millimetres of overlap.
    let nf = 1000.0;
    world.integration_parameters.contact_softness = SpringCoefficients::new(nf, 5.0);
    world.integration_parameters.static_contact_softness = SpringCoefficients::new(2.0 * nf, 5.0);
    world
}

/// A simulated joint as rapier's: a generic joint whose free axis (AngX for a revolute joint,
/// LinX for a prismatic one) is the URDF axis, its motor at `value` with the drive's gains (times
/// [`FOLLOWER_GAIN`] for a follower).
fn multibody_joint(sj: &SimJoint, value: f64) -> GenericJoint {
    let to_axis = DQuat::from_rotation_arc(DVec3::X, sj.axis);
    let origin_rot = DQuat::from_mat3(&sj.origin.matrix3);
    let frame1 = DAffine3::from_rotation_translation(origin_rot * to_axis, sj.origin.translation);
    let frame2 = DAffine3::from_quat(to_axis);
    let (locked, axis) = if sj.prismatic {
        (JointAxesMask::LOCKED_PRISMATIC_AXES, JointAxis::LinX)
    } else {
        (JointAxesMask::LOCKED_REVOLUTE_AXES, JointAxis::AngX)
    };
    let gain = if sj.follower { FOLLOWER_GAIN } else { 1.0 };
    let Drive { stiffness, damping, effort } = sj.drive;
    GenericJointBuilder::new(locked)
        .local_frame1(to_pose(&frame1))
        .local_frame2(to_pose(&frame2))
        .limits(axis, [sj.lower as f32, sj.upper as f32])
        .motor_model(axis, MotorModel::ForceBased)
        .motor_position(axis, value as f32, (stiffness * gain) as f32, (damping * gain) as f32)
        .motor_max_force(axis, (effort * gain) as f32)
        .build()
}

/// Each multibody's (one per finger) links where its joint coordinates put them.
fn place_multibodies(world: &mut PhysicsWorld, joints: &[HandJoint]) {
    let mut multibodies = Vec::new();
    for link in joints.iter().filter_map(|j| world.multibody_joints.rigid_body_link(j.body)) {
        if !multibodies.contains(&link.multibody) {
            multibodies.push(link.multibody);
        }
    }
    for index in multibodies {
        if let Some(mb) = world.multibody_joints.get_multibody_mut(index) {
            mb.forward_kinematics(&world.bodies, true);
            mb.update_rigid_bodies(&mut world.bodies, false);
        }
    }
}

/// rapier's simulation state: what its snapshots serialize (the pipelines are only workspaces).
#[derive(Clone)]
struct WorldState {
    gravity: Vector,
    islands: IslandManager,
    broad_phase: BroadPhaseBvh,
    narrow_phase: NarrowPhase,
    bodies: RigidBodySet,
    colliders: ColliderSet,
    impulse_joints: ImpulseJointSet,
    multibody_joints: MultibodyJointSet,
}

pub struct RapierHand {
    robot: Robot,
    settings: PhysicsSettings,
    /// The hand's bodies, colliders and joints (the same at every rebuild).
    assembly: HandAssembly,
    world: PhysicsWorld,
    joints: Vec<HandJoint>,
    /// Each link's collision shapes (`model.links[i].collisions` order), made once: every grasp
    /// attempt rebuilds the hand, and a mesh link's hull costs more to compute than to simulate.
    link_shapes: Vec<Vec<SharedShape>>,
    /// Collider handles per touch link and all hand colliders.
    touch_colliders: Vec<Vec<ColliderHandle>>,
    hand_colliders: Vec<ColliderHandle>,
    /// The link of each of `hand_colliders`.
    hand_collider_links: Vec<usize>,
    object: Option<(RigidBodyHandle, ColliderHandle)>,
    /// The convex hull of the last object reset with, keyed by its points: computing the hull of
    /// a scanned mesh's ~8 000 vertices costs more than a grasp attempt's first steps, and every
    /// attempt of a trajectory resets with the same object.
    hull: Option<(Vec<[f32; 3]>, SharedShape)>,
    steps: u64,
}

impl RapierHand {
    pub fn new(robot: &Robot, settings: PhysicsSettings) -> Result<Self> {
        let link_shapes = robot
            .model
            .links
            .iter()
            .map(|link| {
                link.collisions
                    .iter()
                    .map(|s| collision_shape(&s.geometry).with_context(|| format!("link {}: no convex hull of its mesh", link.name)))
                    .collect::<Result<Vec<_>>>()
            })
            .collect::<Result<Vec<_>>>()?;
        let mut h = RapierHand {
            robot: robot.clone(),
            assembly: HandAssembly::new(robot, &settings)?,
            settings,
            world: PhysicsWorld::new(),
            joints: Vec::new(),
            link_shapes,
            touch_colliders: Vec::new(),
            hand_colliders: Vec::new(),
            hand_collider_links: Vec::new(),
            object: None,
            hull: None,
            steps: 0,
        };
        h.build(&vec![0.0; robot.hand.len()])?;
        Ok(h)
    }

    /// Builds the hand at hand joint values `q` in a fresh world.
    fn build(&mut self, q: &[f64]) -> Result<()> {
        let robot = &self.robot;
        let m = &robot.model;
        let mut world = hand_world(&self.settings);
        // The hand's root (the palm, or a gripper's base), its bodies, colliders and joints.
        let palm = robot.hand_root;
        let assembly = &self.assembly;
        let mut full_q = m.zero();
        robot.set_hand(&mut full_q, q);
        let groups = InteractionGroups::new(HAND_GROUP, OBJECT_GROUP, InteractionTestMode::And);
        let bodies: Vec<RigidBodyHandle> = assembly
            .bodies
            .iter()
            .map(|body| {
                let pose = to_pose(&assembly.in_grasp_frame(m.relative_pose(&full_q, palm, body.link)));
                let rb = if body.link == palm { RigidBodyBuilder::fixed() } else { RigidBodyBuilder::dynamic() };
                world.insert_body(rb.pose(pose).can_sleep(false))
            })
            .collect();
        let mut hand_colliders = Vec::new();
        let mut hand_collider_links = Vec::new();
        let mut link_colliders: Vec<Vec<ColliderHandle>> = vec![Vec::new(); m.links.len()];
        for c in &assembly.colliders {
            // Colliders have no mass: the body's is the assembly's (below).
            let collider = ColliderBuilder::new(self.link_shapes[c.link][c.shape].clone())
                .position(to_pose(&c.pose))
                .friction(self.settings.friction as f32)
                .density(0.0)
                .collision_groups(groups);
            let ch = world.insert_collider(collider, Some(bodies[c.body]));
            hand_colliders.push(ch);
            hand_collider_links.push(c.link);
            link_colliders[c.link].push(ch);
        }
        for (body, &handle) in assembly.bodies.iter().zip(&bodies).filter(|(b, _)| b.link != palm) {
            if let Some(rb) = world.bodies.get_mut(handle) {
                let props = MassProperties::new(body.com.as_vec3(), body.mass as f32, Vec3::splat(body.inertia_f32()));
                rb.set_additional_mass_properties(props, true);
            }
        }
        let mut joints = Vec::new();
        for sj in &assembly.joints {
            let name = &m.joints[sj.joint].name;
            let (mut parent, child) = (bodies[sj.parent], bodies[sj.child]);
            if assembly.bodies[sj.parent].link == palm {
                // One multibody per finger, each on its own fixed root at the palm: contact
                // constraints then solve against 4x4 instead of 16x16 mass matrices.
                parent = world.insert_body(RigidBodyBuilder::fixed().pose(to_pose(&assembly.in_grasp_frame(DAffine3::IDENTITY))));
            }
            let value = m.joint_value(sj.joint, &full_q).expect("a simulated joint moves");
            let joint = multibody_joint(sj, value);
            let handle =
                world.insert_multibody_joint(parent, child, joint).with_context(|| format!("cannot add joint {name} to the hand"))?;
            // A multibody joint starts at coordinate 0 (the URDF's zero, e.g. a Panda's closed
            // fingers): start it at `value`, the preshape, as the bodies were placed.
            if let Some((mb, link)) = world.multibody_joints.get_mut(handle)
                && let Some(l) = mb.link_mut(link)
            {
                l.joint.apply_displacement(&[value as f32]);
            }
            joints.push(HandJoint { body: child, parent, joint: handle, assembly: sj.clone() });
        }
        place_multibodies(&mut world, &joints);
        let touch_colliders = robot.touch_links.iter().map(|&l| link_colliders[l].clone()).collect();
        self.world = world;
        self.joints = joints;
        self.hand_colliders = hand_colliders;
        self.hand_collider_links = hand_collider_links;
        self.touch_colliders = touch_colliders;
        self.object = None;
        Ok(())
    }

    /// Drives simulated joint `k` towards its drive's `value` (mapped by its multiplier and offset)
    /// with the hand's PD gains times `gain`.
    fn set_motor(&mut self, k: usize, value: f64, gain: f64) {
        let (handle, sj) = (self.joints[k].joint, &self.joints[k].assembly);
        let t = (sj.multiplier * value + sj.offset).clamp(sj.lower, sj.upper) as f32;
        let axis = if sj.prismatic { JointAxis::LinX } else { JointAxis::AngX };
        let (stiffness, damping) = ((sj.drive.stiffness * gain) as f32, (sj.drive.damping * gain) as f32);
        if let Some((mb, link)) = self.world.multibody_joints.get_mut(handle)
            && let Some(l) = mb.link_mut(link)
        {
            l.joint.data.set_motor_position(axis, t, stiffness, damping);
        }
    }

    /// The value of simulated joint `k` from its bodies' poses.
    fn joint_value(&self, k: usize) -> f64 {
        let hj = &self.joints[k];
        let sj = &hj.assembly;
        let p = from_pose(self.world.bodies[hj.parent].position());
        let c = from_pose(self.world.bodies[hj.body].position());
        let rel = p.inverse() * c;
        if sj.prismatic {
            // The child's offset from the joint origin, along the axis.
            return (sj.origin.inverse() * rel).translation.dot(sj.axis);
        }
        let q = DQuat::from_mat3(&sj.origin.matrix3).inverse() * DQuat::from_mat3(&rel.matrix3);
        2.0 * DVec3::new(q.x, q.y, q.z).dot(sj.axis).atan2(q.w)
    }

    /// Signed distance (negative = penetration) between a hand collider and the object at their
    /// current poses, computed by parry; None when farther apart than 1 mm. (The narrow phase's
    /// manifolds date from before the last solver pass and over-state penetration.)
    fn contact_distance(&self, c: ColliderHandle) -> Option<f64> {
        let (_, oc) = self.object?;
        let (a, b) = (&self.world.colliders[c], &self.world.colliders[oc]);
        let contact = rapier3d::parry::query::contact(a.position(), a.shape(), b.position(), b.shape(), 1e-3).ok()??;
        Some(contact.dist as f64)
    }
}

impl HandPhysics for RapierHand {
    fn backend_name(&self) -> &'static str {
        "rapier"
    }

    fn reset(&mut self, object: &PhysicsObject, object_pose: DAffine3, q: &[f64]) -> Result<()> {
        // `new` built the hand joints first: their limits clamp the requested values.
        let q: Vec<f64> = q.iter().zip(&self.joints).map(|(v, j)| v.clamp(j.assembly.lower, j.assembly.upper)).collect();
        self.build(&q)?;
        if self.hull.as_ref().is_none_or(|(pts, _)| *pts != object.points) {
            let pts: Vec<Vec3> = object.points.iter().map(|p| Vec3::from_array(*p)).collect();
            let shape = hull_shape(&pts).context("the object's points have no convex hull (degenerate mesh)")?;
            self.hull = Some((object.points.clone(), shape));
        }
        let shape = self.hull.as_ref().expect("set above").1.clone();
        let collider = ColliderBuilder::new(shape)
            .mass(object.mass as f32)
            .friction(self.settings.friction as f32)
            .restitution(0.0)
            .collision_groups(InteractionGroups::new(OBJECT_GROUP, HAND_GROUP, InteractionTestMode::And));
        let body = self.world.insert_body(RigidBodyBuilder::dynamic().pose(to_pose(&object_pose)).can_sleep(false).ccd_enabled(true));
        let ch = self.world.insert_collider(collider, Some(body));
        self.object = Some((body, ch));
        Ok(())
    }

    fn set_targets(&mut self, targets: &[f64]) {
        for k in 0..self.joints.len() {
            if !self.joints[k].assembly.follower {
                self.set_motor(k, targets[self.joints[k].assembly.hand], 1.0);
            }
        }
    }

    fn set_gravity(&mut self, g: DVec3) {
        self.world.gravity = g.as_vec3();
    }

    fn set_object_damping(&mut self, linear: f64, angular: f64) {
        if let Some((b, _)) = self.object
            && let Some(body) = self.world.bodies.get_mut(b)
        {
            body.set_linear_damping(linear as f32);
            body.set_angular_damping(angular as f32);
        }
    }

    fn step(&mut self) {
        // Mimic joints follow where their leader is.
        for k in 0..self.joints.len() {
            if self.joints[k].assembly.follower {
                let leader = self.joint_value(self.joints[k].assembly.hand);
                self.set_motor(k, leader, FOLLOWER_GAIN);
            }
        }
        self.world.step();
        self.steps += 1;
    }

    fn steps_taken(&self) -> u64 {
        self.steps
    }

    fn object_pose(&self) -> DAffine3 {
        let (b, _) = self.object.expect("reset() places the object");
        from_pose(self.world.bodies[b].position())
    }

    fn joint_positions(&self) -> Vec<f64> {
        (0..self.robot.hand.len()).map(|k| self.joint_value(k)).collect()
    }

    fn touch_contacts(&self) -> Vec<Option<f64>> {
        self.touch_colliders.iter().map(|cs| cs.iter().filter_map(|&c| self.contact_distance(c)).min_by(f64::total_cmp)).collect()
    }

    fn hand_contacts(&self) -> Option<Vec<super::HandContact>> {
        // The impulses rapier's solver keeps per contact (`ContactData`) do not balance a settled
        // hold's weight (HandPhysics::hand_contacts): no forces rather than wrong ones.
        None
    }

    fn max_penetration(&self) -> f64 {
        self.hand_colliders.iter().filter_map(|&c| self.contact_distance(c)).map(|d| (-d).max(0.0)).fold(0.0, f64::max)
    }

    fn deepest_link(&self) -> Option<(usize, f64)> {
        self.hand_colliders
            .iter()
            .zip(&self.hand_collider_links)
            .filter_map(|(&c, &l)| self.contact_distance(c).map(|d| (l, (-d).max(0.0))))
            .max_by(|a, b| a.1.total_cmp(&b.1))
    }

    fn save(&self) -> SavedState {
        let w = &self.world;
        SavedState::new(WorldState {
            gravity: w.gravity,
            islands: w.islands.clone(),
            broad_phase: w.broad_phase.clone(),
            narrow_phase: w.narrow_phase.clone(),
            bodies: w.bodies.clone(),
            colliders: w.colliders.clone(),
            impulse_joints: w.impulse_joints.clone(),
            multibody_joints: w.multibody_joints.clone(),
        })
    }

    fn restore(&mut self, state: &SavedState) {
        let s = state.get::<WorldState>().clone();
        let w = &mut self.world;
        w.gravity = s.gravity;
        w.islands = s.islands;
        w.broad_phase = s.broad_phase;
        w.narrow_phase = s.narrow_phase;
        w.bodies = s.bodies;
        w.colliders = s.colliders;
        w.impulse_joints = s.impulse_joints;
        w.multibody_joints = s.multibody_joints;
    }
}

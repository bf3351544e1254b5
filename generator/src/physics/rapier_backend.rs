//! rapier3d backend: the hand as a fixed-root multibody (reduced coordinates, so long finger chains
//! stay stiff), joint motors as PD controllers, the object as a convex hull.

use anyhow::{Context, Result, bail};
use glam::{DAffine3, DQuat, DVec3, Vec3};
use rapier3d::prelude::*;
use vt_robot::{Geometry, RobotModel, hand_joint_names, phalanx_names};

use super::hull_shape::WalkedHull;
use super::{HandPhysics, PhysicsObject, PhysicsSettings};

const HAND_GROUP: Group = Group::GROUP_1;
const OBJECT_GROUP: Group = Group::GROUP_2;

fn to_pose(t: &DAffine3) -> Pose {
    let q = DQuat::from_mat3(&t.matrix3).normalize();
    Pose::from_parts(t.translation.as_vec3(), q.as_quat())
}

fn from_pose(p: &Pose) -> DAffine3 {
    DAffine3::from_rotation_translation(p.rotation.as_dquat(), p.translation.as_dvec3())
}

struct HandJoint {
    body: RigidBodyHandle,
    parent: RigidBodyHandle,
    joint: MultibodyJointHandle,
    /// URDF joint origin rotation and axis, to read the angle back from body poses.
    origin_rot: DQuat,
    axis: DVec3,
    lower: f64,
    upper: f64,
}

/// A link's collision shape (a mesh link's: the exact hull of its points, `hull_shape`). None: a degenerate mesh.
fn collision_shape(g: &Geometry) -> Option<SharedShape> {
    Some(match g {
        Geometry::Box { size } => SharedShape::cuboid(size.x as f32 / 2.0, size.y as f32 / 2.0, size.z as f32 / 2.0),
        Geometry::Sphere { radius } => SharedShape::ball(*radius as f32),
        Geometry::Cylinder { radius, length } => SharedShape::cylinder(*length as f32 / 2.0, *radius as f32),
        Geometry::ConvexHull { points } => {
            let pts: Vec<Vec3> = points.iter().map(|p| p.as_vec3()).collect();
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
    model: RobotModel,
    settings: PhysicsSettings,
    world: PhysicsWorld,
    joints: Vec<HandJoint>,
    /// Each link's collision shapes (`model.links[i].collisions` order), made once: every grasp
    /// attempt rebuilds the hand, and a mesh link's hull costs more to compute than to simulate.
    link_shapes: Vec<Vec<SharedShape>>,
    /// Collider handles per phalanx (12) and all hand colliders.
    phalanx_colliders: Vec<Vec<ColliderHandle>>,
    hand_colliders: Vec<ColliderHandle>,
    object: Option<(RigidBodyHandle, ColliderHandle)>,
    /// The convex hull of the last object reset with, keyed by its points: computing the hull of
    /// a scanned mesh's ~8 000 vertices costs more than a grasp attempt's first steps, and every
    /// attempt of a trajectory resets with the same object.
    hull: Option<(Vec<[f32; 3]>, SharedShape)>,
    saved: Option<WorldState>,
    steps: u64,
}

impl RapierHand {
    pub fn new(model: &RobotModel, settings: PhysicsSettings) -> Result<Self> {
        let link_shapes = model
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
            model: model.clone(),
            settings,
            world: PhysicsWorld::new(),
            joints: Vec::new(),
            link_shapes,
            phalanx_colliders: Vec::new(),
            hand_colliders: Vec::new(),
            object: None,
            hull: None,
            saved: None,
            steps: 0,
        };
        h.build(&[0.0; 16])?;
        Ok(h)
    }

    /// Builds the hand at joint values `q` in a fresh world.
    // Long on purpose: one multibody built link by link (colliders, joints, motors), in one place.
    fn build(&mut self, q: &[f64; 16]) -> Result<()> {
        let m = &self.model;
        let mut world = PhysicsWorld::new();
        world.integration_parameters.dt = self.settings.timestep as f32;
        // Tighter than the default so resting contacts penetrate well under a millimetre.
        world.integration_parameters.normalized_allowed_linear_error = 0.0002;
        world.integration_parameters.num_solver_iterations = 4;
        // Four Gauss-Seidel sweeps per solver iteration instead of one: with one, the friction of
        // a held object's 5 to 7 contacts did not converge, and objects crept 1 to 5 mm and up to
        // 3.5° in 10 s with the arm still (7 of 12 test grasps still); with four and the stiffer
        // contacts below, 12 of 12 stay within 0.5 mm and 0.6° (tests/grasping.rs) at the same
        // physics time per sample, measured with `vtgen bench`. More substeps (16 solver
        // iterations), no contact recycling or friction in the bias pass did not help.
        world.integration_parameters.num_internal_pgs_iterations = 4;
        // Stiff contacts: fingers squeeze with up to 0.7 N·m, which soft contacts turn into
        // millimetres of overlap.
        let nf = 1000.0;
        world.integration_parameters.contact_softness = SpringCoefficients::new(nf, 5.0);
        world.integration_parameters.static_contact_softness = SpringCoefficients::new(2.0 * nf, 5.0);
        let palm = m.link_id(vt_robot::PALM).context("palm")?;
        let names = hand_joint_names();
        let mut full_q = m.zero();
        for (k, n) in names.iter().enumerate() {
            full_q[m.dof(n).context("hand joint")?] = q[k];
        }
        let groups = InteractionGroups::new(HAND_GROUP, OBJECT_GROUP, InteractionTestMode::And);
        let mut bodies = vec![None; m.links.len()];
        let mut hand_colliders = Vec::new();
        let mut link_colliders: Vec<Vec<ColliderHandle>> = vec![Vec::new(); m.links.len()];
        // Bodies for the palm and every link below it that has mass or collision geometry.
        for (li, link) in m.links.iter().enumerate() {
            if !m.is_below(li, palm) || (li != palm && link.mass <= 0.0 && link.collisions.is_empty()) {
                continue;
            }
            let pose = to_pose(&m.relative_pose(&full_q, palm, li));
            let rb = if li == palm { RigidBodyBuilder::fixed() } else { RigidBodyBuilder::dynamic() };
            let handle = world.insert_body(rb.pose(pose).can_sleep(false));
            bodies[li] = Some(handle);
            for (s, shape) in link.collisions.iter().zip(&self.link_shapes[li]) {
                // Colliders share the link's mass; their density is set so the link mass is exact.
                let c = ColliderBuilder::new(shape.clone())
                    .position(to_pose(&s.origin))
                    .friction(self.settings.friction as f32)
                    .density(0.0)
                    .collision_groups(groups);
                let ch = world.insert_collider(c, Some(handle));
                hand_colliders.push(ch);
                link_colliders[li].push(ch);
            }
            if li != palm {
                // Mass properties from the URDF (a small box inertia about the centre of mass).
                let mass = link.mass.max(0.005) as f32;
                let i = mass * 0.02 * 0.02 / 6.0;
                if let Some(b) = world.bodies.get_mut(handle) {
                    b.set_additional_mass_properties(MassProperties::new(link.com.as_vec3(), mass, Vec3::splat(i)), true);
                }
            }
        }
        let mut joints = Vec::new();
        for name in &names {
            let ji = m.joints.iter().position(|j| &j.name == name).context("hand joint")?;
            let j = &m.joints[ji];
            let (Some(mut parent), Some(child)) = (bodies[j.parent], bodies[j.child]) else {
                bail!("joint {name} links bodies without geometry")
            };
            if j.parent == palm {
                // One multibody per finger, each on its own fixed root at the palm: contact
                // constraints then solve against 4x4 instead of 16x16 mass matrices.
                parent = world.insert_body(RigidBodyBuilder::fixed().pose(to_pose(&DAffine3::IDENTITY)));
            }
            // Joint frames whose x axis is the URDF axis: rapier's free revolute axis is AngX.
            let to_axis = DQuat::from_rotation_arc(DVec3::X, j.axis);
            let origin_rot = DQuat::from_mat3(&j.origin.matrix3);
            let frame1 = DAffine3::from_rotation_translation(origin_rot * to_axis, j.origin.translation);
            let frame2 = DAffine3::from_quat(to_axis);
            let k = full_q[j.dof.expect("revolute")];
            let joint = GenericJointBuilder::new(JointAxesMask::LOCKED_REVOLUTE_AXES)
                .local_frame1(to_pose(&frame1))
                .local_frame2(to_pose(&frame2))
                .limits(JointAxis::AngX, [j.lower as f32, j.upper as f32])
                .motor_model(JointAxis::AngX, MotorModel::ForceBased)
                .motor_position(JointAxis::AngX, k as f32, self.settings.stiffness as f32, self.settings.damping as f32)
                .motor_max_force(JointAxis::AngX, self.settings.max_torque as f32)
                .build();
            let handle =
                world.insert_multibody_joint(parent, child, joint).with_context(|| format!("cannot add joint {name} to the hand"))?;
            joints.push(HandJoint { body: child, parent, joint: handle, origin_rot, axis: j.axis, lower: j.lower, upper: j.upper });
        }
        let phalanx_colliders = phalanx_names().iter().map(|p| link_colliders[m.link_id(p).expect("validated")].clone()).collect();
        self.world = world;
        self.joints = joints;
        self.hand_colliders = hand_colliders;
        self.phalanx_colliders = phalanx_colliders;
        self.object = None;
        self.saved = None;
        Ok(())
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

    fn reset(&mut self, object: &PhysicsObject, object_pose: DAffine3, q: &[f64; 16]) -> Result<()> {
        // `new` built the 16 joints: their limits clamp the requested values.
        let q: [f64; 16] = std::array::from_fn(|k| q[k].clamp(self.joints[k].lower, self.joints[k].upper));
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

    fn set_targets(&mut self, targets: &[f64; 16]) {
        let (stiffness, damping) = (self.settings.stiffness as f32, self.settings.damping as f32);
        for (k, hj) in self.joints.iter().enumerate() {
            let t = targets[k].clamp(hj.lower, hj.upper) as f32;
            if let Some((mb, link)) = self.world.multibody_joints.get_mut(hj.joint)
                && let Some(l) = mb.link_mut(link)
            {
                l.joint.data.set_motor_position(JointAxis::AngX, t, stiffness, damping);
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

    fn joint_positions(&self) -> [f64; 16] {
        std::array::from_fn(|k| {
            let hj = &self.joints[k];
            let p = from_pose(self.world.bodies[hj.parent].position());
            let c = from_pose(self.world.bodies[hj.body].position());
            let rel = DQuat::from_mat3(&(p.inverse() * c).matrix3);
            let q = hj.origin_rot.inverse() * rel;
            let s = DVec3::new(q.x, q.y, q.z).dot(hj.axis);
            2.0 * s.atan2(q.w)
        })
    }

    fn phalanx_contacts(&self) -> [Option<f64>; 12] {
        std::array::from_fn(|p| self.phalanx_colliders[p].iter().filter_map(|&c| self.contact_distance(c)).min_by(f64::total_cmp))
    }

    fn max_penetration(&self) -> f64 {
        self.hand_colliders.iter().filter_map(|&c| self.contact_distance(c)).map(|d| (-d).max(0.0)).fold(0.0, f64::max)
    }

    fn save(&mut self) {
        let w = &self.world;
        self.saved = Some(WorldState {
            gravity: w.gravity,
            islands: w.islands.clone(),
            broad_phase: w.broad_phase.clone(),
            narrow_phase: w.narrow_phase.clone(),
            bodies: w.bodies.clone(),
            colliders: w.colliders.clone(),
            impulse_joints: w.impulse_joints.clone(),
            multibody_joints: w.multibody_joints.clone(),
        });
    }

    fn restore(&mut self) {
        if let Some(s) = self.saved.clone() {
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
}

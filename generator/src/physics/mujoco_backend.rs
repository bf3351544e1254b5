//! MuJoCo backend (cargo feature `mujoco`): the same hand-frame simulation as the rapier backend,
//! as an MJCF model translated from the hand's assembly (`hand_assembly.rs`): the hand's root
//! fixed in the world, its bodies with their lumped inertia, the hand joints with position
//! actuators (PD gains and effort limits from the config and the description), `<mimic>` joints
//! as joint equality constraints, and the object as a free body whose collision shape MuJoCo takes
//! as its mesh's convex hull.

use std::fmt::Write as _;

use anyhow::{Context, Result, anyhow};
use glam::{DAffine3, DQuat, DVec3};
use mujoco_rs::prelude::*;
use vt_robot::{Geometry, PadContact, Robot, RobotModel};

use super::hand_assembly::{Drive, HandAssembly, SimJoint};
use super::{HandContact, HandPhysics, PhysicsObject, PhysicsSettings, SavedState};

struct Sim {
    data: MjData<Box<MjModel>>,
    /// Which object the model was built for (its points' count and first point).
    object_key: (usize, [u32; 3]),
    hand_qpos: Vec<usize>,
    hand_actuators: Vec<usize>,
    /// Mimic joints: qpos address, the hand joint they follow (`Robot::hand` index), multiplier
    /// and offset, to start them where their constraint holds.
    follower_qpos: Vec<(usize, usize, f64, f64)>,
    object_body: usize,
    /// The object's free joint: its qpos address (position, wxyz quaternion) and dof address.
    object_qpos: usize,
    object_dof: usize,
    object_geom: usize,
    touch_geoms: Vec<Vec<usize>>,
    hand_geoms: Vec<usize>,
    /// Each hand link with collision geometry and its geoms.
    link_geoms: Vec<(usize, Vec<usize>)>,
    /// Every hand geom with the skin its contacts have (`hand_skins`).
    skins: Vec<GeomSkin>,
}

/// A hand geom's skin: what sizes the patch of its contacts, so their torsional friction.
struct GeomSkin {
    geom: usize,
    skin: PadContact,
    /// Half the narrower side of the pad's sensing area, on a pad's link (m).
    max_radius: Option<f64>,
}

pub struct MujocoHand {
    robot: Robot,
    settings: PhysicsSettings,
    /// The hand's bodies, colliders and joints, as the MJCF writes them.
    assembly: HandAssembly,
    sim: Option<Sim>,
    damping: (f64, f64),
    mass: f64,
    steps: u64,
}

/// Everything `mj_step` integrates from, as `mj_getState` packs it.
const FULL_STATE: u32 = MjtState::mjSTATE_INTEGRATION as u32;

fn quat_wxyz(t: &DAffine3) -> [f64; 4] {
    let q = DQuat::from_mat3(&t.matrix3).normalize();
    [q.w, q.x, q.y, q.z]
}

/// A pose as MJCF's `pos` and `quat` attributes.
fn pos_quat(t: &DAffine3) -> String {
    let (p, q) = (t.translation, quat_wxyz(t));
    format!(r#"pos="{} {} {}" quat="{} {} {} {}""#, p.x, p.y, p.z, q[0], q[1], q[2], q[3])
}

/// MuJoCo's soft contacts let a held object creep under a steady load (measured with the arm
/// still: 1 of 12 grasps within 1 mm and 1° over 10 s, the rest 1 to 7 mm). Its noslip solver pass
/// removes it: 10 iterations left 8 of 12 still, 50 all 12 with torsional friction 0.02 for every
/// contact, and 11 of 12 (the twelfth 1.6 mm, 1.2°) with each pad's patch (`tests/grasping.rs`),
/// for 3–5 % more physics time (`vtgen bench`).
const NOSLIP_ITERATIONS: u32 = 50;

/// The armature of a hand joint (kg·m² or kg) unless its drive needs more (`write_children`).
const DEFAULT_ARMATURE: f64 = 0.0005;

/// The skin of a hand link that is no pad: rigid plastic or metal (E about 2 GPa), whose contact
/// patch is a fraction of a millimetre.
const RIGID_SKIN: PadContact = PadContact { modulus_mpa: 2000.0, crown_radius_mm: 20.0 };

/// A contact's torsional friction (MuJoCo's spin coefficient, m: the largest torque about the
/// normal is it times the normal force) for a Hertzian patch of radius `a` under Coulomb friction
/// `mu`: the integral of `mu·p(r)·r` over the patch under Hertz's pressure, `3π/16 · mu · a`. MuJoCo's contacts are points, so without it nothing resists an object's
/// spin between two opposed pads; with one constant it is the same for a soft pad eased to 1 N
/// as for a rigid link pressing 30 N.
fn torsional_friction(mu: f64, a: f64) -> f64 {
    3.0 * std::f64::consts::PI / 16.0 * mu * a
}

/// The skin of each hand link's geoms: the description's pad's on a pad's link (the first pad on
/// it, whose half width bounds the patch), rigid on the others.
fn hand_skins(robot: &Robot, link_geoms: &[(usize, Vec<usize>)]) -> Vec<GeomSkin> {
    let sizes = robot.pad_sizes();
    let mut skins = Vec::new();
    for (link, geoms) in link_geoms {
        let (skin, max_radius) = match robot.pads.iter().position(|p| p.link == *link) {
            Some(i) => (robot.pads[i].contact, Some(sizes[i].0.min(sizes[i].1) / 2.0)),
            None => (RIGID_SKIN, None),
        };
        skins.extend(geoms.iter().map(|&geom| GeomSkin { geom, skin, max_radius }));
    }
    skins
}

/// The real hand's links collide as the convex hulls of their meshes: one `<mesh>` asset per hull
/// shape, named `<link>_<shape index>` (MuJoCo takes the hull of a mesh's vertices for collision).
fn write_hull_meshes(x: &mut String, m: &RobotModel) {
    for link in &m.links {
        for (i, sh) in link.collisions.iter().enumerate() {
            if let Some(points) = sh.geometry.hull_points() {
                let _ = write!(x, r#"<mesh name="{}_{i}" vertex=""#, link.name);
                for p in points.iter() {
                    let _ = write!(x, "{} {} {} ", p.x, p.y, p.z);
                }
                x.push_str("\"/>");
            }
        }
    }
}

impl MujocoHand {
    pub fn new(robot: &Robot, settings: PhysicsSettings) -> Result<Self> {
        Ok(MujocoHand {
            robot: robot.clone(),
            assembly: HandAssembly::new(robot, &settings)?,
            settings,
            sim: None,
            damping: (0.0, 0.0),
            mass: 1.0,
            steps: 0,
        })
    }

    /// MJCF of the hand below its root (the assembly's bodies, colliders, joints and drives) and
    /// one free object.
    fn mjcf(&self, object: &PhysicsObject) -> String {
        let (robot, a, s) = (&self.robot, &self.assembly, &self.settings);
        let mut x = String::new();
        let _ = write!(
            x,
            r#"<mujoco model="vtgen-hand"><compiler angle="radian" autolimits="true"/>
<option timestep="{}" gravity="0 0 0" integrator="implicitfast" cone="elliptic" impratio="10" noslip_iterations="{}"/>
<default><geom friction="{} 0 0.0001" condim="4" solref="0.01 1" solimp="0.99 0.999 0.0005"/></default>
<asset><mesh name="object" vertex=""#,
            s.timestep, NOSLIP_ITERATIONS, s.friction
        );
        for p in &object.points {
            let _ = write!(x, "{} {} {} ", p[0], p[1], p[2]);
        }
        x.push_str("\"/>");
        write_hull_meshes(&mut x, &robot.model);
        x.push_str("</asset><worldbody>");
        match a.t_grasp_root {
            None => x.push_str(r#"<body name="palm">"#),
            Some(t) => {
                let _ = write!(x, r#"<body name="palm" {}>"#, pos_quat(&t));
            }
        }
        self.write_geoms(&mut x, 0);
        self.write_children(&mut x, 0);
        x.push_str("</body>");
        let _ = write!(
            x,
            r#"<body name="object"><freejoint name="object"/><geom name="object" type="mesh" mesh="object" mass="{}" contype="2" conaffinity="1"/></body></worldbody>"#,
            object.mass
        );
        // A mimic joint follows its leader: q = offset + multiplier * q_leader.
        let followers: Vec<&SimJoint> = a.joints.iter().filter(|j| j.follower).collect();
        if !followers.is_empty() {
            x.push_str("<equality>");
            for j in followers {
                let (name, leader) = (&robot.model.joints[j.joint].name, &robot.hand[j.hand].name);
                let _ = write!(x, r#"<joint joint1="{name}" joint2="{leader}" polycoef="{} {} 0 0 0"/>"#, j.offset, j.multiplier);
            }
            x.push_str("</equality>");
        }
        x.push_str("<actuator>");
        for j in a.joints.iter().filter(|j| !j.follower) {
            let name = &robot.hand[j.hand].name;
            let Drive { stiffness: kp, damping: kv, effort } = j.drive;
            let _ = write!(
                x,
                r#"<position name="{name}" joint="{name}" kp="{kp}" kv="{kv}" ctrlrange="{} {}" forcerange="{} {}"/>"#,
                j.lower, j.upper, -effort, effort
            );
        }
        x.push_str("</actuator></mujoco>");
        x
    }

    /// The geoms of body `b`'s colliders. Hand geoms collide with the object only (contype 1 /
    /// conaffinity 2, the object 2 / 1), and have no mass: the body's is the assembly's. Their
    /// priority makes a contact take the hand geom's friction, whose torsional part `step` sets
    /// from the geom's skin and load.
    fn write_geoms(&self, x: &mut String, b: usize) {
        let m = &self.robot.model;
        for c in self.assembly.colliders.iter().filter(|c| c.body == b) {
            let name = format!("{}_{}", m.links[c.link].name, c.shape);
            let (kind, size) = match &m.links[c.link].collisions[c.shape].geometry {
                Geometry::Box { size } => ("box", format!(r#"size="{} {} {}""#, size.x / 2.0, size.y / 2.0, size.z / 2.0)),
                Geometry::Sphere { radius } => ("sphere", format!(r#"size="{radius}""#)),
                Geometry::Cylinder { radius, length } => ("cylinder", format!(r#"size="{radius} {}""#, length / 2.0)),
                Geometry::ConvexHull { .. } | Geometry::Mesh { .. } => ("mesh", format!(r#"mesh="{name}""#)),
            };
            let _ = write!(
                x,
                r#"<geom name="{name}" type="{kind}" {size} {} contype="1" conaffinity="2" priority="1" mass="0"/>"#,
                pos_quat(&c.pose)
            );
        }
    }

    /// The bodies the joints of body `b` move, each with its lumped inertia, its joint and geoms,
    /// depth first.
    fn write_children(&self, x: &mut String, b: usize) {
        let (a, m, s) = (&self.assembly, &self.robot.model, &self.settings);
        for j in a.joints.iter().filter(|j| j.parent == b) {
            let body = &a.bodies[j.child];
            let (c, i) = (body.com, body.inertia());
            let kind = if j.prismatic { "slide" } else { "hinge" };
            // A drive's stiffness is explicit in MuJoCo's integrator (implicitfast takes only the
            // damping implicitly): a stiff drive on a light link (the Panda's 15 g fingers at
            // 14 000 N/m) would ring. Each driven joint (and its mimics) gets at least the
            // armature that keeps `kp·dt²/armature` at 1; the Allegro's and the 2F-85's keep the
            // default.
            let armature = DEFAULT_ARMATURE.max(j.drive.stiffness * s.timestep * s.timestep);
            let _ = write!(
                x,
                r#"<body name="{}" {}><inertial pos="{} {} {}" mass="{}" diaginertia="{i} {i} {i}"/><joint name="{}" type="{kind}" axis="{} {} {}" range="{} {}" damping="0.01" armature="{armature}"/>"#,
                m.links[body.link].name,
                pos_quat(&j.origin),
                c.x,
                c.y,
                c.z,
                body.mass,
                m.joints[j.joint].name,
                j.axis.x,
                j.axis.y,
                j.axis.z,
                j.lower,
                j.upper,
            );
            self.write_geoms(x, j.child);
            self.write_children(x, j.child);
            x.push_str("</body>");
        }
    }

    fn build(&mut self, object: &PhysicsObject) -> Result<()> {
        let key = (object.points.len(), object.points.first().map_or([0; 3], |p| p.map(f32::to_bits)));
        if self.sim.as_ref().is_some_and(|s| s.object_key == key) {
            let sim = self.sim.as_mut().expect("checked");
            sim.data.reset();
            return Ok(());
        }
        let xml = self.mjcf(object);
        let model = MjModel::from_xml_string(&xml).map_err(|e| anyhow!("MuJoCo rejected the generated hand model: {e:?}"))?;
        let id = |t: MjtObjBase, n: &str| model.name_to_id(t, n).with_context(|| format!("MuJoCo model lacks {n}"));
        let mut hand_qpos = Vec::new();
        let mut hand_actuators = Vec::new();
        for h in &self.robot.hand {
            let j = id(MjtObjBase::mjOBJ_JOINT, &h.name)?;
            hand_qpos.push(model.jnt_qposadr()[j] as usize);
            hand_actuators.push(id(MjtObjBase::mjOBJ_ACTUATOR, &h.name)?);
        }
        let mut follower_qpos = Vec::new();
        for &f in &self.robot.followers {
            let joint = &self.robot.model.joints[f];
            let mimic = joint.mimic.expect("a follower mimics");
            let leader = self.robot.hand.iter().position(|h| h.joint == mimic.leader).expect("a follower's leader is a hand joint");
            let j = id(MjtObjBase::mjOBJ_JOINT, &joint.name)?;
            follower_qpos.push((model.jnt_qposadr()[j] as usize, leader, mimic.multiplier, mimic.offset));
        }
        let object_body = id(MjtObjBase::mjOBJ_BODY, "object")?;
        let object_joint = id(MjtObjBase::mjOBJ_JOINT, "object")?;
        let object_qpos = model.jnt_qposadr()[object_joint] as usize;
        let object_dof = model.jnt_dofadr()[object_joint] as usize;
        let object_geom = id(MjtObjBase::mjOBJ_GEOM, "object")?;
        let geom_of_link = |link: &str| -> Vec<usize> {
            (0..16).filter_map(|i| model.name_to_id(MjtObjBase::mjOBJ_GEOM, &format!("{link}_{i}"))).collect()
        };
        let touch_geoms = self.robot.touch_link_names().iter().map(|l| geom_of_link(l)).collect();
        let hand_geoms = (0..model.ngeom() as usize).filter(|&g| g != object_geom).collect();
        let link_geoms = (0..self.robot.model.links.len())
            .map(|l| (l, geom_of_link(&self.robot.model.links[l].name)))
            .filter(|(_, g)| !g.is_empty())
            .collect::<Vec<_>>();
        let skins = hand_skins(&self.robot, &link_geoms);
        let data = MjData::new(Box::new(model));
        self.sim = Some(Sim {
            data,
            object_key: key,
            hand_qpos,
            hand_actuators,
            follower_qpos,
            object_body,
            object_qpos,
            object_dof,
            object_geom,
            touch_geoms,
            hand_geoms,
            link_geoms,
            skins,
        });
        Ok(())
    }

    fn sim(&self) -> &Sim {
        self.sim.as_ref().expect("reset() builds the model")
    }

    /// Signed distances of current contacts between the object and `geoms`.
    fn contact_dists<'a>(&'a self, geoms: &'a [usize]) -> impl Iterator<Item = f64> + 'a {
        let sim = self.sim();
        sim.data.contact().iter().filter_map(move |c| {
            let (a, b) = (c.geom[0] as usize, c.geom[1] as usize);
            let hit = (a == sim.object_geom && geoms.contains(&b)) || (b == sim.object_geom && geoms.contains(&a));
            (hit && c.dist < 1e-3).then_some(c.dist)
        })
    }
}

impl Sim {
    /// The torsional friction each hand geom's contacts have in the next step: its skin's patch
    /// under the normal force the object put on it in this one (all its contacts together, so
    /// their torsional torques add up to the patch's).
    fn size_patches(&mut self, mu: f64) {
        let mut normal = vec![0.0; self.skins.len()];
        for (i, c) in self.data.contact().iter().enumerate() {
            let (a, b) = (c.geom[0] as usize, c.geom[1] as usize);
            let hand_geom = if a == self.object_geom {
                b
            } else if b == self.object_geom {
                a
            } else {
                continue;
            };
            if let Some(k) = self.skins.iter().position(|s| s.geom == hand_geom) {
                normal[k] += self.data.contact_force(i)[0].max(0.0);
            }
        }
        let spin: Vec<f64> =
            self.skins.iter().zip(&normal).map(|(s, &n)| torsional_friction(mu, s.skin.patch_radius(n, s.max_radius))).collect();
        self.set_spin(&spin);
    }

    /// Each hand geom's torsional friction coefficient, in `skins` order.
    fn spin(&self) -> Vec<f64> {
        let friction = self.data.model().geom_friction();
        self.skins.iter().map(|s| friction[s.geom][1]).collect()
    }

    fn set_spin(&mut self, spin: &[f64]) {
        // Only values of existing geoms change: no size, index or address of the model.
        let friction = unsafe { self.data.model_mut() }.geom_friction_mut();
        for (s, &v) in self.skins.iter().zip(spin) {
            friction[s.geom][1] = v;
        }
    }
}

impl HandPhysics for MujocoHand {
    fn backend_name(&self) -> &'static str {
        "mujoco"
    }

    fn reset(&mut self, object: &PhysicsObject, object_pose: DAffine3, q: &[f64]) -> Result<()> {
        self.build(object)?;
        self.mass = object.mass;
        let sim = self.sim.as_mut().expect("built");
        let qp = sim.data.qpos_mut();
        for (&a, &v) in sim.hand_qpos.iter().zip(q) {
            qp[a] = v;
        }
        for &(a, leader, multiplier, offset) in &sim.follower_qpos {
            qp[a] = offset + multiplier * q[leader];
        }
        let oq = quat_wxyz(&object_pose);
        let t = object_pose.translation;
        let base = sim.object_qpos;
        let qp = sim.data.qpos_mut();
        qp[base..base + 7].copy_from_slice(&[t.x, t.y, t.z, oq[0], oq[1], oq[2], oq[3]]);
        let ctrl = sim.data.ctrl_mut();
        for (&a, &v) in sim.hand_actuators.iter().zip(q) {
            ctrl[a] = v;
        }
        // No load yet: the patches are points until the first step sizes them.
        sim.set_spin(&vec![0.0; sim.skins.len()]);
        sim.data.forward();
        Ok(())
    }

    fn set_targets(&mut self, targets: &[f64]) {
        let sim = self.sim.as_mut().expect("built");
        let ctrl = sim.data.ctrl_mut();
        for (&a, &v) in sim.hand_actuators.iter().zip(targets) {
            ctrl[a] = v;
        }
    }

    fn set_gravity(&mut self, g: DVec3) {
        let sim = self.sim.as_mut().expect("built");
        sim.data.model_opt_mut().gravity = g.to_array();
    }

    fn set_object_damping(&mut self, linear: f64, angular: f64) {
        self.damping = (linear, angular);
    }

    fn step(&mut self) {
        let (lin, ang, mass) = (self.damping.0, self.damping.1, self.mass);
        let sim = self.sim.as_mut().expect("built");
        let d = sim.object_dof;
        let v: Vec<f64> = sim.data.qvel()[d..d + 6].to_vec();
        // Damping of the object's motion as applied generalized forces (like rapier's).
        let f = sim.data.qfrc_applied_mut();
        for i in 0..3 {
            f[d + i] = -lin * mass * v[i];
            f[d + 3 + i] = -ang * mass * 0.0025 * v[3 + i];
        }
        sim.data.step();
        sim.size_patches(self.settings.friction);
        self.steps += 1;
    }

    fn steps_taken(&self) -> u64 {
        self.steps
    }

    fn object_pose(&self) -> DAffine3 {
        let sim = self.sim();
        let p = sim.data.xpos()[sim.object_body];
        let q = sim.data.xquat()[sim.object_body];
        DAffine3::from_rotation_translation(DQuat::from_xyzw(q[1], q[2], q[3], q[0]).normalize(), DVec3::from_array(p))
    }

    fn joint_positions(&self) -> Vec<f64> {
        let sim = self.sim();
        sim.hand_qpos.iter().map(|&a| sim.data.qpos()[a]).collect()
    }

    fn touch_contacts(&self) -> Vec<Option<f64>> {
        self.sim().touch_geoms.iter().map(|g| self.contact_dists(g).min_by(f64::total_cmp)).collect()
    }

    fn hand_contacts(&self) -> Option<Vec<HandContact>> {
        let sim = self.sim();
        let mut out = Vec::new();
        for (i, c) in sim.data.contact().iter().enumerate() {
            let (a, b) = (c.geom[0] as usize, c.geom[1] as usize);
            let (link_geom, link_first) = match (a == sim.object_geom, b == sim.object_geom) {
                (false, true) => (a, true),
                (true, false) => (b, false),
                _ => continue,
            };
            let Some(&(link, _)) = sim.link_geoms.iter().find(|(_, g)| g.contains(&link_geom)) else { continue };
            // mj_contactForce: the force in the contact frame (normal, then the two tangents; the
            // frame's rows), exerted by the first geom on the second; the normal points from the
            // first to the second.
            let f = sim.data.contact_force(i);
            if f[0] <= 0.0 {
                continue;
            }
            let row = |r: usize| DVec3::new(c.frame[3 * r], c.frame[3 * r + 1], c.frame[3 * r + 2]);
            let on_second = row(0) * f[0] + row(1) * f[1] + row(2) * f[2];
            let sign = if link_first { -1.0 } else { 1.0 };
            out.push(HandContact { link, point: DVec3::from_array(c.pos), normal: -sign * row(0), force: sign * on_second });
        }
        Some(out)
    }

    fn max_penetration(&self) -> f64 {
        self.contact_dists(&self.sim().hand_geoms).map(|d| (-d).max(0.0)).fold(0.0, f64::max)
    }

    fn deepest_link(&self) -> Option<(usize, f64)> {
        self.sim()
            .link_geoms
            .iter()
            .filter_map(|(l, g)| self.contact_dists(g).map(|d| (-d).max(0.0)).reduce(f64::max).map(|d| (*l, d)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// MuJoCo's integration state (time, qpos, qvel, act, controls, warm start, applied forces),
    /// the gravity and the hand geoms' torsional friction (sized by the last step's loads).
    fn save(&self) -> SavedState {
        let sim = self.sim();
        SavedState::new((sim.data.state(FULL_STATE), sim.data.model_opt().gravity, sim.spin()))
    }

    fn restore(&mut self, state: &SavedState) {
        let (state, gravity, spin) = state.get::<(Box<[f64]>, [f64; 3], Vec<f64>)>();
        let sim = self.sim.as_mut().expect("built");
        sim.set_spin(spin);
        // The buffer came from `save` on this model (the grasp loop saves again after each
        // reset), so it has the size mj_setState expects.
        sim.data.set_state(state, FULL_STATE).expect("a state saved from the same model");
        sim.data.model_opt_mut().gravity = *gravity;
        // Positions, contacts and the other derived quantities the checks read, for that state.
        sim.data.forward();
    }
}

//! The robot in the scene: the grasp loop's recorded states turned into world poses, and the
//! arm and hand links as renderable meshes with their mask ids (FORMAT.md).

use std::collections::BTreeMap;

use anyhow::{Context, Result};
use glam::{DAffine3, DQuat, DVec3, Vec3};
use vt_dataset::mask_ids;
use vt_objects::{Texture, TexturedMesh};
use vt_robot::{Geometry, Robot, RobotModel};

use crate::assets::robot::{ROBOTS_WITH_MESHES, load_hand_meshes, robot_assets_dir, with_real_hand};
use crate::config::{LoadedConfig, RobotConfig};
use crate::physics::grasp::{
    GraspContext, GraspEvent, MIN_REACHABLE_SHARE, REACH_SAMPLES, Trajectory, TrajectoryKey, reachable_share, simulate_trajectory,
};
use crate::physics::{HandPhysics, PhysicsObject, PhysicsSettings, RapierHand};

/// Mask id of a robot link (`vt_dataset::mask_ids`): the base and the arm link moved by arm joint
/// k, the hand's body (the links fixed between flange and grasp frame), the hand link moved by
/// hand joint k (then by each mimic joint), a link fixed below a hand link with that link's id.
/// None: not drawn (e.g. the flange and links fixed to arm links).
pub fn mask_id(robot: &Robot, link: usize) -> Option<u8> {
    let model = &robot.model;
    if link == robot.base {
        return Some(*mask_ids::ARM_LINKS.start());
    }
    if link != robot.flange && model.is_below(link, robot.flange) && !moves_below(model, robot.flange, link) {
        return Some(mask_ids::PALM);
    }
    let j = model.links[link].parent_joint?;
    if let Some(k) = robot.arm_joints.iter().position(|&a| a == j) {
        return mask_ids::arm_link(k);
    }
    if let Some(k) = robot.hand.iter().position(|h| h.joint == j) {
        return mask_ids::nth(&mask_ids::HAND_LINKS, k);
    }
    if let Some(k) = robot.followers.iter().position(|&f| f == j) {
        return mask_ids::nth(&mask_ids::HAND_LINKS, robot.hand.len() + k);
    }
    let joint = &model.joints[j];
    if !joint.moves() && model.is_below(link, robot.hand_root) { mask_id(robot, joint.parent) } else { None }
}

/// Whether a moving joint lies between `top` and `link` (below it).
fn moves_below(model: &RobotModel, top: usize, link: usize) -> bool {
    let mut l = link;
    while l != top {
        let Some(j) = model.links[l].parent_joint else { return false };
        if model.joints[j].moves() {
            return true;
        }
        l = model.joints[j].parent;
    }
    false
}

/// A link's visual shapes as one mesh (its colours in a small texture, one texel per shape).
pub fn link_mesh(model: &RobotModel, link: usize) -> Option<TexturedMesh> {
    let shapes = &model.links[link].visuals;
    if shapes.is_empty() {
        return None;
    }
    let n = shapes.len();
    let mut mesh = TexturedMesh {
        positions: Vec::new(),
        normals: Vec::new(),
        uvs: Vec::new(),
        indices: Vec::new(),
        texture: Texture {
            width: n as u32,
            height: 1,
            rgba: shapes.iter().flat_map(|s| s.rgba.map(vt_objects::linear_to_srgb8)).collect(),
        },
    };
    for (i, s) in shapes.iter().enumerate() {
        let uv = [(i as f32 + 0.5) / n as f32, 0.5];
        let (pos, nrm, idx) = primitive(&s.geometry);
        let base = mesh.positions.len() as u32;
        let m = s.origin;
        let r = m.matrix3;
        mesh.positions.extend(pos.iter().map(|p| m.transform_point3(p.as_dvec3()).as_vec3().to_array()));
        mesh.normals.extend(nrm.iter().map(|v| (r * v.as_dvec3()).normalize().as_vec3().to_array()));
        mesh.uvs.extend(std::iter::repeat_n(uv, pos.len()));
        mesh.indices.extend(idx.iter().map(|i| i + base));
    }
    Some(mesh)
}

/// Box, cylinder (along z) or sphere as positions, normals and triangles.
fn primitive(g: &Geometry) -> (Vec<Vec3>, Vec<Vec3>, Vec<u32>) {
    let (mut p, mut n, mut t) = (Vec::new(), Vec::new(), Vec::new());
    match *g {
        Geometry::Box { size } => {
            let h = size.as_vec3() * 0.5;
            for (nn, u, v) in vt_objects::BOX_FACES {
                let b = p.len() as u32;
                for (a, c) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                    p.push((nn + u * a + v * c) * h);
                    n.push(nn);
                }
                t.extend([b, b + 1, b + 2, b, b + 2, b + 3]);
            }
        }
        Geometry::Cylinder { radius, length } => {
            let (r, hl, seg) = (radius as f32, length as f32 / 2.0, 24u32);
            for j in 0..=seg {
                let a = std::f32::consts::TAU * j as f32 / seg as f32;
                let d = Vec3::new(a.cos(), a.sin(), 0.0);
                p.extend([d * r - Vec3::Z * hl, d * r + Vec3::Z * hl]);
                n.extend([d, d]);
            }
            for j in 0..seg {
                let b = 2 * j;
                t.extend([b, b + 2, b + 3, b, b + 3, b + 1]);
            }
            for (z, nz) in [(-hl, Vec3::NEG_Z), (hl, Vec3::Z)] {
                let c = p.len() as u32;
                p.push(Vec3::Z * z);
                n.push(nz);
                for j in 0..=seg {
                    let a = std::f32::consts::TAU * j as f32 / seg as f32;
                    p.push(Vec3::new(a.cos() * r, a.sin() * r, z));
                    n.push(nz);
                }
                for j in 0..seg {
                    if z < 0.0 { t.extend([c, c + 2 + j, c + 1 + j]) } else { t.extend([c, c + 1 + j, c + 2 + j]) }
                }
            }
        }
        // Visual shapes come from the URDF, which has no hulls (real meshes are drawn whole).
        Geometry::ConvexHull { .. } => {}
        Geometry::Sphere { radius } => {
            let (r, st, sl) = (radius as f32, 12u32, 24u32);
            for i in 0..=st {
                let th = std::f32::consts::PI * i as f32 / st as f32;
                for j in 0..=sl {
                    let ph = std::f32::consts::TAU * j as f32 / sl as f32;
                    let d = Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
                    p.push(d * r);
                    n.push(d);
                }
            }
            for i in 0..st {
                for j in 0..sl {
                    let a = i * (sl + 1) + j;
                    let b = a + sl + 1;
                    t.extend([a, b, b + 1, a, b + 1, a + 1]);
                }
            }
        }
    }
    (p, n, t)
}

/// Counts for the run's summary.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GraspStats {
    pub trajectories: u64,
    pub attempts: u64,
    pub failures: BTreeMap<String, u64>,
    pub max_slip_mm: f64,
    pub max_penetration_mm: f64,
}

impl GraspStats {
    pub fn merge(&mut self, o: &GraspStats) {
        self.trajectories += o.trajectories;
        self.attempts += o.attempts;
        for (k, v) in &o.failures {
            *self.failures.entry(k.clone()).or_default() += v;
        }
        self.max_slip_mm = self.max_slip_mm.max(o.max_slip_mm);
        self.max_penetration_mm = self.max_penetration_mm.max(o.max_penetration_mm);
    }
}

/// A simulated trajectory and the grasp loop's figures for it.
pub struct Simulated {
    pub trajectory: Result<Trajectory>,
    pub stats: GraspStats,
}

/// The robot half of a worker: model and physics. The trajectory being recorded is the sample
/// stage's (`SampleFactory`), which simulates it when its first sample is made.
pub struct RobotScene {
    pub robot: Robot,
    pub config: RobotConfig,
    pub t_world_base: DAffine3,
    /// The real hand meshes (link frames) when the run has robot assets: the model's hand then
    /// collides as their convex hulls and its pads sit on their surfaces.
    pub hand_meshes: Option<std::collections::HashMap<usize, TexturedMesh>>,
    physics: Box<dyn HandPhysics>,
    objects: Vec<PhysicsObject>,
    /// The main camera's position (world), for the back-to-camera arm moves.
    camera_position: DVec3,
}

impl RobotScene {
    pub fn new(cfg: &LoadedConfig, robot: &RobotConfig, objects: &[crate::assets::LoadedObject]) -> Result<Self> {
        let mut model = cfg.robot.clone().context("a config with a robot section has its robot loaded")?;
        if cfg.robot_assets.is_some() && !ROBOTS_WITH_MESHES.contains(&model.name.as_str()) {
            anyhow::bail!(
                "robot meshes (--robot-assets or robot.assets) are those of the built-in robots ({}); robot '{}' is drawn \
                 from its URDF's shapes: leave them out",
                ROBOTS_WITH_MESHES.join(", "),
                model.name
            );
        }
        // The Allegro hand collides as its real meshes' hulls, its pads on their surfaces; the
        // 2F-85 collides as its URDF's boxes (its meshes are drawn).
        let hand_meshes = match robot_assets_dir(cfg) {
            Some(dir) if model.name == "ur5e_allegro" => Some(load_hand_meshes(&dir, &model.model, None)?),
            _ => None,
        };
        if let Some(hand) = &hand_meshes {
            model.model = with_real_hand(&model, hand)?;
        }
        let pc = &robot.physics;
        let settings = PhysicsSettings::from(pc);
        let physics: Box<dyn HandPhysics> = match pc.backend {
            crate::config::PhysicsBackend::Rapier => Box::new(RapierHand::new(&model, settings)?),
            #[cfg(feature = "mujoco")]
            crate::config::PhysicsBackend::Mujoco => Box::new(crate::physics::MujocoHand::new(&model, settings)?),
            #[cfg(not(feature = "mujoco"))]
            crate::config::PhysicsBackend::Mujoco => {
                anyhow::bail!(
                    "physics backend 'mujoco' is not built into this vtgen: build with `--features mujoco` (see scripts/mujoco-setup)"
                )
            }
        };
        let t_world_base = DAffine3::from_rotation_translation(
            DQuat::from_rotation_z(robot.base_yaw_deg.to_radians()),
            DVec3::from_array(robot.base_position),
        );
        // A workspace the arm cannot reach would fail every grasp as Unreachable: said up front.
        let ctx = GraspContext {
            robot: &model,
            t_world_base,
            config: &robot.grasp,
            timestep: robot.physics.timestep,
            camera_position: DVec3::from_array(cfg.config.camera.position),
        };
        let share = reachable_share(&ctx, REACH_SAMPLES);
        if share < MIN_REACHABLE_SHARE {
            anyhow::bail!(
                "{}: robot.grasp.palm_workspace: the arm of robot '{}' reaches {:.0}% of {REACH_SAMPLES} grasp-frame poses drawn from it \
                 (at least {:.0}% needed): move the workspace or robot.base_position, or widen the joint limits",
                cfg.path.display(),
                model.name,
                100.0 * share,
                100.0 * MIN_REACHABLE_SHARE
            );
        }
        let objects = objects.iter().map(|o| PhysicsObject { points: o.mesh.positions.clone(), mass: o.mass }).collect();
        Ok(RobotScene {
            robot: model,
            config: robot.clone(),
            t_world_base,
            hand_meshes,
            physics,
            objects,
            camera_position: DVec3::from_array(cfg.config.camera.position),
        })
    }

    pub fn backend_name(&self) -> &'static str {
        self.physics.backend_name()
    }

    /// Physics steps taken by this worker so far.
    pub fn physics_steps(&self) -> u64 {
        self.physics.steps_taken()
    }

    /// Simulates trajectory `trajectory` of object `object_index` (every attempt until a grasp
    /// holds through all instances) and returns it with the grasp loop's figures, which a lost
    /// trajectory keeps too (`vtgen grasps` reports them).
    pub fn simulate(&mut self, seed: u64, object_index: u32, object_id: &str, trajectory: u32, instances: u32) -> Simulated {
        let ctx = GraspContext {
            robot: &self.robot,
            t_world_base: self.t_world_base,
            config: &self.config.grasp,
            timestep: self.config.physics.timestep,
            camera_position: self.camera_position,
        };
        let mut events: Vec<GraspEvent> = Vec::new();
        let result = simulate_trajectory(
            &ctx,
            self.physics.as_mut(),
            &self.objects[object_index as usize],
            TrajectoryKey { seed, object_id, trajectory, instances },
            &mut events,
        );
        let attempts = result.as_ref().map_or(self.config.grasp.max_attempts, |t| t.attempts);
        let mut stats = GraspStats { trajectories: 1, attempts: attempts as u64, ..Default::default() };
        for e in events {
            *stats.failures.entry(e.name().to_string()).or_default() += 1;
        }
        for s in result.iter().flat_map(|t| &t.instances) {
            stats.max_slip_mm = stats.max_slip_mm.max(s.slip_translation * 1e3);
            stats.max_penetration_mm = stats.max_penetration_mm.max(s.penetration * 1e3);
        }
        Simulated { trajectory: result.with_context(|| format!("grasping {object_id}")), stats }
    }
}

//! The robot half of a worker: the robot (with its real hand's collision hulls when the run draws
//! the real meshes), its physics backend and the objects' physics shapes; it simulates whole
//! trajectories (`grasp.rs`) and counts the grasp loop's figures.

use anyhow::{Context, Result};
use glam::{DAffine3, DQuat, DVec3};
use vt_dataset::GraspStats;
use vt_objects::TexturedMesh;
use vt_robot::Robot;

use crate::assets::robot::{hand_surface_meshes, with_real_hand};
use crate::config::{LoadedConfig, RobotConfig};
use crate::physics::grasp::{
    Approach, FingerGait, GraspContext, GraspLog, HoldScreen, MIN_REACHABLE_SHARE, PivotControl, REACH_SAMPLES, RollControl, StepLedger,
    Trajectory, TrajectoryKey, reachable_share, simulate_trajectory,
};
use crate::physics::{HandPhysics, PhysicsObject, PhysicsSettings, RapierHand};

/// A simulated trajectory and the grasp loop's figures for it.
pub struct Simulated {
    pub trajectory: Result<Trajectory>,
    pub stats: GraspStats,
    /// Where its physics steps went.
    pub steps: StepLedger,
    /// Its in-hand windows by how their turning ended (`GraspLog::in_hand_ends`).
    pub in_hand_ends: std::collections::BTreeMap<&'static str, u64>,
    /// Pads its pivoting placed again (`GraspLog::repinches`).
    pub repinches: u64,
}

/// The robot's base in the world (`robot.base_position`, `robot.base_yaw_deg`).
pub fn t_world_base(rc: &RobotConfig) -> DAffine3 {
    DAffine3::from_rotation_translation(DQuat::from_rotation_z(rc.base_yaw_deg.to_radians()), DVec3::from_array(rc.base_position))
}

/// What the grasp loop needs of a worker's robot besides its physics.
pub fn grasp_context<'a>(
    robot: &'a Robot,
    t_world_base: DAffine3,
    rc: &'a RobotConfig,
    camera_position: DVec3,
    record: Option<&crate::config::RecordConfig>,
) -> GraspContext<'a> {
    let finger_gait = record.and_then(|r| r.finger_motion.as_ref()).map(|m| FingerGait::of(m, robot, rc.physics.timestep));
    let pivot = record.and_then(|r| r.pivot.as_ref()).map(|p| PivotControl::of(p, robot, rc.physics.timestep));
    let finger_roll = record.and_then(|r| r.finger_roll.as_ref()).map(|r| RollControl::of(r, robot, rc.physics.timestep));
    let record_steps = record.is_some();
    let record_contact_forces = rc.tactile.force_field.is_some();
    GraspContext {
        record_steps,
        recorded_grasp_steps: record.map_or(0, |r| r.grasp_steps(&rc.grasp, rc.physics.timestep) as usize),
        finger_gait,
        pivot,
        finger_roll,
        turn_target_deg: record.and_then(|r| r.turn_target_deg),
        record_contact_forces,
        approach: record.and_then(|r| {
            let approach = r.approach.as_ref().filter(|_| r.grasp)?;
            Some(Approach { steps: approach.steps(rc.physics.timestep), distance: approach.distance_mm * 1e-3 })
        }),
        ..GraspContext::new(robot, t_world_base, &rc.grasp, rc.physics.timestep, camera_position)
    }
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
    /// Episodes: trajectories record every physics step (`Trajectory::steps`), with the
    /// recording's finger motion.
    record: Option<crate::config::RecordConfig>,
    /// The hold screen's mode when not the config's (`vtgen grasps --judge-screen`).
    pub hold_screen: Option<HoldScreen>,
}

impl RobotScene {
    pub fn new(cfg: &LoadedConfig, robot: &RobotConfig, objects: &[crate::assets::LoadedObject]) -> Result<Self> {
        let mut model = cfg.robot.clone().context("a config with a robot section has its robot loaded")?;
        // A hand that collides as its meshes' hulls (`hand_collision: mesh_hulls`, when they are
        // drawn), its pads on their surfaces.
        let hand_meshes = hand_surface_meshes(&model);
        if let Some(hand) = &hand_meshes {
            model.model = with_real_hand(&model, hand)?;
        }
        // Links the description decomposes collide as their convex parts.
        let model = crate::physics::convex_parts::with_convex_parts(&model, cfg.cache_dir().as_deref())?;
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
        let t_world_base = t_world_base(robot);
        // A workspace the arm cannot reach would fail every grasp as Unreachable: said up front.
        let camera_position = DVec3::from_array(cfg.config.camera.position);
        let share = reachable_share(&grasp_context(&model, t_world_base, robot, camera_position, None), REACH_SAMPLES);
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
            camera_position,
            record: cfg.config.sampling.record.clone(),
            hold_screen: None,
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
        let mut ctx = grasp_context(&self.robot, self.t_world_base, &self.config, self.camera_position, self.record.as_ref());
        if let Some(mode) = self.hold_screen {
            ctx.hold_screen = mode;
        }
        let mut log = GraspLog::default();
        let result = simulate_trajectory(
            &ctx,
            self.physics.as_mut(),
            &self.objects[object_index as usize],
            TrajectoryKey { seed, object_id, trajectory, instances },
            &mut log,
        );
        let attempts = result.as_ref().map_or(self.config.grasp.max_attempts, |t| t.attempts);
        let mut stats = GraspStats { trajectories: 1, attempts: attempts as u64, ..Default::default() };
        for e in log.events {
            *stats.failures.entry(e.name().to_string()).or_default() += 1;
        }
        for s in result.iter().flat_map(|t| &t.instances) {
            stats.max_slip_mm = stats.max_slip_mm.max(s.slip_translation * 1e3);
            stats.max_penetration_mm = stats.max_penetration_mm.max(s.penetration * 1e3);
        }
        Simulated {
            trajectory: result.with_context(|| format!("grasping {object_id}")),
            stats,
            steps: log.steps,
            in_hand_ends: log.in_hand_ends,
            repinches: log.repinches,
        }
    }
}

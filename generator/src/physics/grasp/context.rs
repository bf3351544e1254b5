//! What the grasp loop knows besides the physics: the robot, its base, the grasp config and the
//! camera; the grasp-frame and arm-move samplers; reachability.

use glam::{DAffine3, DMat3, DQuat, DVec3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use vt_randomizers::SampleStream;
use vt_robot::{IkOptions, Robot};

use super::finger_roll::RollControl;
use super::palm_up;
use super::pivot::PivotControl;
use super::screen::HoldScreen;
use crate::config::GraspConfig;

/// Everything the loop needs besides the physics.
pub struct GraspContext<'a> {
    pub robot: &'a Robot,
    pub t_world_base: DAffine3,
    pub config: &'a GraspConfig,
    pub timestep: f64,
    /// The main camera's position (world): back-to-camera moves turn the palm away from it.
    pub camera_position: DVec3,
    /// Record the state after every physics step from the settled grasp on (`Trajectory::steps`,
    /// for episodes). Each arm move then also waits out its whole settle window, so that every
    /// move takes [`GraspContext::move_steps`] steps.
    pub record_steps: bool,
    /// Episodes with `sampling.record.grasp`: the states kept from before the settled grasp
    /// (`RecordConfig::grasp_steps`; 0: none recorded). The arm then holds the palm up while the
    /// object is put in and the fingers close, and turns to the grasp pose during the settle.
    pub recorded_grasp_steps: usize,
    /// A scripted finger motion after each arm move's hold (episodes).
    pub finger_gait: Option<FingerGait>,
    /// Gravity pivoting after each arm move's hold and finger motion (episodes; a gripper's jaws or
    /// a hand's pinch).
    pub pivot: Option<PivotControl>,
    /// A closed-loop finger roll after each arm move's hold and finger motion (episodes, hands).
    pub finger_roll: Option<RollControl>,
    /// The range (degrees) each episode's turn target is drawn from (`sampling.record.turn_target_deg`).
    pub turn_target_deg: Option<(f64, f64)>,
    /// Record the hand's contact forces with every state (`InstanceState::hand_contacts`, for
    /// the force fields).
    pub record_contact_forces: bool,
    /// The hold screen between the settled grasp and the first arm move.
    pub hold_screen: HoldScreen,
    /// Recording the grasp with `sampling.record.approach`: the open hand's approach to the
    /// object first.
    pub approach: Option<Approach>,
}

/// The recorded grasp's approach: the palm starts `distance` (m) back from its palm-up grasp pose
/// along its normal and the arm's smooth path takes it there in `steps` physics steps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Approach {
    pub steps: usize,
    pub distance: f64,
}

/// `sampling.record.finger_motion` resolved to hand joints: after each arm move's hold, hand joint
/// `j` (`Robot::hand` order) targets `q_j + a (sin(2π t / period + φ) − sin φ)` for `steps`
/// physics steps, `q_j` its position when the motion starts (against the object: the grasp's
/// targets lie beyond it, where a swing would not move the finger), then its grasp target again.
/// The other hand joints keep squeezing.
#[derive(Debug, Clone, PartialEq)]
pub struct FingerGait {
    pub period: f64,
    pub steps: usize,
    /// (hand joint index, amplitude, phase), radians.
    pub joints: Vec<(usize, f64, f64)>,
}

impl FingerGait {
    /// The configured motion for `robot` at `timestep` (its joints are checked at load).
    pub fn of(motion: &crate::config::FingerMotionConfig, robot: &Robot, timestep: f64) -> Self {
        let joints = motion
            .joints
            .iter()
            .filter_map(|j| {
                let k = robot.hand.iter().position(|h| h.name == j.joint)?;
                Some((k, j.amplitude_deg.to_radians(), j.phase_deg.to_radians()))
            })
            .collect();
        FingerGait { period: motion.period_s, steps: motion.steps(timestep), joints }
    }

    /// The hand's targets `t` seconds into the motion, from the grasp's targets and the hand's
    /// joint positions when it started.
    pub(super) fn targets(&self, grasp: &[f64], start: &[f64], t: f64) -> Vec<f64> {
        let mut out = grasp.to_vec();
        for &(k, a, phase) in &self.joints {
            out[k] = start[k] + a * ((std::f64::consts::TAU * t / self.period + phase).sin() - phase.sin());
        }
        out
    }
}

impl<'a> GraspContext<'a> {
    /// The context of snapshot trajectories (no step recording, no finger motion).
    pub fn new(robot: &'a Robot, t_world_base: DAffine3, config: &'a GraspConfig, timestep: f64, camera_position: DVec3) -> Self {
        GraspContext {
            robot,
            t_world_base,
            config,
            timestep,
            camera_position,
            record_steps: false,
            recorded_grasp_steps: 0,
            finger_gait: None,
            pivot: None,
            finger_roll: None,
            turn_target_deg: None,
            record_contact_forces: false,
            hold_screen: if config.hold_screen { HoldScreen::On } else { HoldScreen::Off },
            approach: None,
        }
    }

    /// The turn target (degrees, as the config gives it) of trajectory `key`'s episode: every
    /// attempt at it aims at the same turn, drawn from its own stream.
    pub fn turn_target_deg(&self, key: &TrajectoryKey) -> Option<f64> {
        let (lo, hi) = self.turn_target_deg?;
        Some(SampleStream::trajectory(key.seed, key.object_id, key.trajectory, "turn_target").random_range(lo..=hi))
    }

    /// The arm's home: elbow up, palm facing up over the workspace.
    pub fn home(&self) -> Vec<f64> {
        let mut q = self.robot.model.zero();
        for (&d, &v) in self.robot.arm_dofs.iter().zip(&self.config.home_arm) {
            q[d] = v;
        }
        q
    }

    /// A random palm pose (world): position in the palm workspace, palmar normal within
    /// `max_tilt` of straight up, any roll about it.
    pub fn sample_palm(&self, rng: &mut ChaCha8Rng) -> DAffine3 {
        let w = &self.config.palm_workspace;
        let p =
            DVec3::new(rng.random_range(w.min[0]..=w.max[0]), rng.random_range(w.min[1]..=w.max[1]), rng.random_range(w.min[2]..=w.max[2]));
        let roll = self.draw_roll(rng);
        let tilt_axis = DVec3::new(0.0, rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)).normalize_or(DVec3::Y);
        let cos_max = self.config.max_tilt_deg.to_radians().cos();
        let tilt = (rng.random_range(cos_max..=1.0f64)).acos();
        DAffine3::from_rotation_translation(cone_palm(roll, tilt_axis, tilt), p)
    }

    /// A random roll about the palm normal (palm x), within `max_roll_deg` either way.
    fn draw_roll(&self, rng: &mut ChaCha8Rng) -> DQuat {
        let max_roll = self.config.max_roll_deg.to_radians();
        DQuat::from_rotation_x(rng.random_range(-max_roll..=max_roll))
    }

    /// Which sampler an arm move's palm pose comes from: with probability `back_to_camera_share`
    /// the back of the hand faces the camera, otherwise `sample_palm`'s cone. Drawn once per
    /// move, so that redrawing a pose the arm cannot reach keeps the share.
    pub(super) fn draw_move_kind(&self, rng: &mut ChaCha8Rng) -> MoveKind {
        let share = self.config.back_to_camera_share;
        // No extra draw without the knob: the data of configs that do not use it stays the same.
        if share <= 0.0 || rng.random_range(0.0..1.0) >= share { MoveKind::Cone } else { MoveKind::BackToCamera }
    }

    /// The palm pose of an arm move of `kind`: the back of the hand facing the camera (the palm
    /// normal tilted away from it by `back_to_camera_tilt_deg` from straight up, rolled about the
    /// normal as usual), or `sample_palm`'s cone.
    pub(super) fn sample_move_palm(&self, kind: MoveKind, rng: &mut ChaCha8Rng) -> DAffine3 {
        if kind == MoveKind::Cone {
            return self.sample_palm(rng);
        }
        // The position (and draws) of the plain sampler; its cone tilt is replaced by a world
        // rotation that takes the normal (world z) towards the horizontal direction from the
        // camera to the palm workspace's centre.
        let mut t = self.sample_palm(rng);
        let away = self.away_from_camera();
        let (lo, hi) = self.config.back_to_camera_tilt_deg;
        let tilt = rng.random_range(lo..=hi).to_radians();
        t.matrix3 = DMat3::from_quat(back_to_camera_palm(away, tilt, self.draw_roll(rng)));
        t
    }

    /// The horizontal direction (world) from the camera to the palm workspace's centre: the
    /// back-to-camera moves tilt the palm normal along it.
    pub(super) fn away_from_camera(&self) -> DVec3 {
        let w = &self.config.palm_workspace;
        let centre = DVec3::from_array(w.min).lerp(DVec3::from_array(w.max), 0.5);
        (centre - self.camera_position).with_z(0.0).normalize_or(DVec3::Y)
    }

    /// Simulation steps in `seconds` (at least one).
    pub(super) fn steps(&self, seconds: f64) -> usize {
        crate::config::physics_steps(seconds, self.timestep)
    }

    /// Physics steps of one recorded arm move: the move, the hold, and (when recording steps) the
    /// whole settle window of `PENETRATION_WAITS` waits.
    pub fn move_steps(&self) -> usize {
        self.config.move_steps(self.timestep)
            + self.finger_gait.as_ref().map_or(0, |g| g.steps)
            + self.pivot.as_ref().map_or(0, |p| p.steps)
            + self.finger_roll.as_ref().map_or(0, |r| r.steps)
    }

    /// IK for a world palm pose, from `q`.
    pub fn reach(&self, t_world_palm: &DAffine3, q: &[f64]) -> Option<Vec<f64>> {
        let target = self.t_world_base.inverse() * *t_world_palm;
        self.robot.solve_grasp_ik(&target, q, &IkOptions::default())
    }
}

/// The sampler of an arm move's palm pose (`GraspContext::draw_move_kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum MoveKind {
    /// Within the tilt cone about palm up.
    Cone,
    /// The back of the hand towards the camera.
    BackToCamera,
}

/// A palm orientation (world) of the arm moves' cone: `palm_up` rolled about the palm normal by
/// `roll`, then tilted by `tilt` (rad) about `tilt_axis` (palm frame, across the normal).
pub(super) fn cone_palm(roll: DQuat, tilt_axis: DVec3, tilt: f64) -> DQuat {
    palm_up() * roll * DQuat::from_axis_angle(tilt_axis, tilt)
}

/// A back-to-camera palm orientation (world): the palm normal tilted from straight up by `tilt`
/// (rad) towards `away` (horizontal, world), after a `roll` about it.
pub(super) fn back_to_camera_palm(away: DVec3, tilt: f64, roll: DQuat) -> DQuat {
    DQuat::from_axis_angle(DVec3::Z.cross(away).normalize(), tilt) * palm_up() * roll
}

/// Grasp-frame poses drawn by `reachable_share`, and the share of them the arm must reach.
pub const REACH_SAMPLES: usize = 48;
pub const MIN_REACHABLE_SHARE: f64 = 0.5;

/// The share of `n` grasp-frame poses drawn from the workspace (as grasps draw them, from a stream
/// of their own: the data's draws stay untouched) that the inverse kinematics reaches from home.
pub fn reachable_share(ctx: &GraspContext, n: usize) -> f64 {
    let reached = reach_samples(ctx, n).iter().filter(|q| q.is_some()).count();
    reached as f64 / n.max(1) as f64
}

/// `n` grasp-frame poses drawn from the workspace (from the stream of `reachable_share`) and the
/// arm's joint values reaching each from home (None: unreachable).
pub fn reach_samples(ctx: &GraspContext, n: usize) -> Vec<Option<Vec<f64>>> {
    use rand::SeedableRng;
    let mut rng = ChaCha8Rng::seed_from_u64(0x0072_6561_6368); // "reach"
    let home = ctx.home();
    (0..n).map(|_| ctx.reach(&ctx.sample_palm(&mut rng), &home)).collect()
}

/// Which trajectory of which object, and how many instances it records: the keys of its random
/// streams (`grasp/<attempt>` per trajectory, `arm/<attempt>…` per instance).
#[derive(Debug, Clone, Copy)]
pub struct TrajectoryKey<'a> {
    pub seed: u64,
    pub object_id: &'a str,
    pub trajectory: u32,
    pub instances: u32,
}

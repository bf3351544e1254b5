//! The paper's grasp loop (Algorithm 1), one trajectory at a time: place the object against the
//! palm at a random orientation, random preshape, close the fingers under PD control, check the
//! grasp holds, then move the arm to a new random palm pose for every instance (a simulated
//! joint-space path, so the object may slip or turn), let it settle and record. A failed attempt
//! (dropped object, fewer touch links in contact than the robot's `min_touching`, object lost
//! during motion) is retried with
//! fresh randomness from the same trajectory stream; attempts are counted.

use anyhow::{Result, bail};
use glam::{DAffine3, DMat3, DQuat, DVec3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use vt_randomizers::{SampleKey, SampleStream, uniform_rotation};
use vt_robot::{GraspKind, IkOptions, Robot};

use crate::config::GraspConfig;
use crate::physics::antipodal::{Hull, Jaws, antipodal_pose};
use crate::physics::{HandPhysics, PhysicsObject};

/// The state recorded at one instance.
#[derive(Debug, Clone)]
pub struct InstanceState {
    /// All robot joint values (`RobotModel::dof_names` order).
    pub q: Vec<f64>,
    /// Palm pose in the robot base frame.
    pub t_base_palm: DAffine3,
    /// Object pose in the palm frame.
    pub t_palm_object: DAffine3,
    /// Per touch link (`Robot::touch_links` order): contact distance when touching.
    pub contacts: Vec<Option<f64>>,
    /// Object motion relative to the palm since the grasp settled: metres and radians.
    pub slip_translation: f64,
    pub slip_rotation: f64,
    pub penetration: f64,
}

/// What a held attempt recorded: its instances and (episodes) its steps.
type Recorded = (Vec<InstanceState>, Vec<InstanceState>);

#[derive(Debug, Clone)]
pub struct Trajectory {
    pub instances: Vec<InstanceState>,
    /// Attempts it took (1 = the first grasp held through every instance).
    pub attempts: u32,
    /// With `GraspContext::record_steps`: the state at the settled grasp, then after every
    /// physics step of the recorded arm moves (`1 + instances * move_steps` states); else empty.
    pub steps: Vec<InstanceState>,
}

/// Why an attempt at a trajectory ended without it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Failure {
    InitialOverlap,
    GraspNotHeld,
    LostDuringMotion,
    TooFewContacts,
    Penetration,
    TouchesFloor,
    Unreachable,
    /// No antipodal pair of the object's hull fits between the open jaws (a parallel-jaw grasp).
    NoAntipodalPair,
}

/// An arm move undone and redrawn from the last recorded state: not a failure, the attempt goes
/// on. A move that drops the object, or ends with a hand link more than `max_penetration` into
/// the object, fewer touch links touching than `min_touching` or the object on the floor, cannot
/// be recorded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Redo {
    Drop,
    Penetration,
    Contacts,
    Floor,
}

/// What the grasp loop counts for the run's statistics: failed attempts and redone moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GraspEvent {
    Failed(Failure),
    Redone(Redo),
}

impl GraspEvent {
    /// The name statistics count it under (`grasp_stats.failures` in shards and the manifest,
    /// `vtgen grasps`): stable, the names earlier datasets carry.
    pub fn name(self) -> &'static str {
        match self {
            GraspEvent::Failed(f) => match f {
                Failure::InitialOverlap => "InitialOverlap",
                Failure::GraspNotHeld => "GraspNotHeld",
                Failure::LostDuringMotion => "LostDuringMotion",
                Failure::TooFewContacts => "TooFewContacts",
                Failure::Penetration => "Penetration",
                Failure::TouchesFloor => "TouchesFloor",
                Failure::Unreachable => "Unreachable",
                Failure::NoAntipodalPair => "NoAntipodalPair",
            },
            GraspEvent::Redone(r) => match r {
                Redo::Penetration => "MoveRedoneForPenetration",
                Redo::Contacts => "MoveRedoneForContacts",
                Redo::Floor => "MoveRedoneForFloor",
                Redo::Drop => "MoveRedoneForDrop",
            },
        }
    }
}

/// Arm moves tried for one instance (each from the last recorded state, when the backend can
/// undo) before the attempt is given up. A grasp whose four moves all drop the object or press a
/// finger in is seldom saved by more: 4 tries made the grasp loop 10% faster than 8, and 16 20%
/// slower, over 4 trajectories of every object with the same kept share.
const MAX_MOVES_PER_INSTANCE: u32 = 4;

const GRAVITY: DVec3 = DVec3::new(0.0, 0.0, -9.81);
/// Gravity in the palm frame while the palm faces straight up (its normal is +x).
const PALM_UP_GRAVITY: DVec3 = DVec3::new(-9.81, 0.0, 0.0);

/// The neutral palm orientation (world). Palm frame: +x palmar normal, +z along the fingers.
/// Neutral: palm up (x -> world z), fingers towards the camera side (z -> world -y), so the arm
/// stays behind the hand.
fn palm_up() -> DQuat {
    DQuat::from_mat3(&DMat3::from_cols(DVec3::Z, DVec3::NEG_X, DVec3::NEG_Y))
}

fn rot(t: &DAffine3) -> DQuat {
    DQuat::from_mat3(&t.matrix3).normalize()
}

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
    /// A scripted finger motion after each arm move's hold (episodes).
    pub finger_gait: Option<FingerGait>,
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
    pub fn of(motion: &crate::config::FingerMotion, robot: &Robot, timestep: f64) -> Self {
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
    fn targets(&self, grasp: &[f64], start: &[f64], t: f64) -> Vec<f64> {
        let mut out = grasp.to_vec();
        for &(k, a, phase) in &self.joints {
            out[k] = start[k] + a * ((std::f64::consts::TAU * t / self.period + phase).sin() - phase.sin());
        }
        out
    }
}

impl GraspContext<'_> {
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
        DAffine3::from_rotation_translation(palm_up() * roll * DQuat::from_axis_angle(tilt_axis, tilt), p)
    }

    /// A random roll about the palm normal (palm x), within `max_roll_deg` either way.
    fn draw_roll(&self, rng: &mut ChaCha8Rng) -> DQuat {
        let max_roll = self.config.max_roll_deg.to_radians();
        DQuat::from_rotation_x(rng.random_range(-max_roll..=max_roll))
    }

    /// The palm pose of an arm move: with probability `back_to_camera_share` the back of the hand
    /// faces the camera (the palm normal tilted away from it by `back_to_camera_tilt_deg` from
    /// straight up, rolled about the normal as usual), otherwise `sample_palm`'s cone.
    fn sample_move_palm(&self, rng: &mut ChaCha8Rng) -> DAffine3 {
        let share = self.config.back_to_camera_share;
        // No extra draw without the knob: the data of configs that do not use it stays the same.
        if share <= 0.0 || rng.random_range(0.0..1.0) >= share {
            return self.sample_palm(rng);
        }
        // The position (and draws) of the plain sampler; its cone tilt is replaced by a world
        // rotation that takes the normal (world z) towards the horizontal direction from the
        // camera to the palm workspace's centre.
        let mut t = self.sample_palm(rng);
        let w = &self.config.palm_workspace;
        let centre = DVec3::from_array(w.min).lerp(DVec3::from_array(w.max), 0.5);
        let away = (centre - self.camera_position).with_z(0.0).normalize_or(DVec3::Y);
        let (lo, hi) = self.config.back_to_camera_tilt_deg;
        let tilt = rng.random_range(lo..=hi).to_radians();
        let turn = DQuat::from_axis_angle(DVec3::Z.cross(away).normalize(), tilt);
        t.matrix3 = DMat3::from_quat(turn * palm_up() * self.draw_roll(rng));
        t
    }

    /// Simulation steps in `seconds` (at least one).
    fn steps(&self, seconds: f64) -> usize {
        (seconds / self.timestep).round().max(1.0) as usize
    }

    /// Physics steps of one recorded arm move: the move, the hold, and (when recording steps) the
    /// whole settle window of `PENETRATION_WAITS` waits.
    pub fn move_steps(&self) -> usize {
        move_steps(self.config, self.timestep) + self.finger_gait.as_ref().map_or(0, |g| g.steps)
    }

    /// IK for a world palm pose, from `q`.
    pub fn reach(&self, t_world_palm: &DAffine3, q: &[f64]) -> Option<Vec<f64>> {
        let target = self.t_world_base.inverse() * *t_world_palm;
        self.robot.solve_grasp_ik(&target, q, &IkOptions::default())
    }
}

/// Physics steps of one recorded arm move of an episode, without a finger motion
/// (`GraspContext::move_steps`).
pub fn move_steps(config: &GraspConfig, timestep: f64) -> usize {
    let steps = |seconds: f64| (seconds / timestep).round().max(1.0) as usize;
    steps(config.move_seconds) + steps(config.hold_seconds) + PENETRATION_WAITS * steps(PENETRATION_WAIT_SECONDS)
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

/// Object orientations drawn before falling back to the thin-axis placement of large objects.
const ORIENTATION_DRAWS: u32 = 20;
/// Largest tilt (rad) of a large object's thin axis off the palm normal: more makes them deeper
/// than the fingers reach.
const LARGE_OBJECT_MAX_TILT: f64 = 0.05;
/// Gap (m) between the palm surface and the object's back at placement.
const PLACEMENT_GAP: f64 = 0.003;
/// Placement retries, each this much further out along the palm normal (m), while the object
/// overlaps a link by more than `PLACEMENT_MAX_OVERLAP` (m).
const PLACEMENT_RETRIES: u32 = 6;
const PLACEMENT_STEP: f64 = 0.01;
const PLACEMENT_MAX_OVERLAP: f64 = 0.0015;
/// The object rests on the open palm this long (s) before the fingers close.
const REST_SECONDS: f64 = 0.15;
/// Object damping (linear = angular) while resting, while closing, and from the settle on.
const REST_DAMPING: f64 = 20.0;
const CLOSE_DAMPING: f64 = 2.0;
const HELD_DAMPING: f64 = 0.05;
/// A settled grasp may not let the object drift more than this (m) while still (and must touch it
/// with at least the robot's `min_touching` touch links).
const MAX_SETTLE_DRIFT: f64 = 0.02;

/// Simulates a trajectory and returns its recorded instances: attempts with fresh randomness
/// until one grasp holds through every instance, or `max_attempts` is spent.
pub fn simulate_trajectory(
    ctx: &GraspContext,
    physics: &mut dyn HandPhysics,
    object: &PhysicsObject,
    key: TrajectoryKey,
    events: &mut Vec<GraspEvent>,
) -> Result<Trajectory> {
    let cfg = ctx.config;
    let mut last = None;
    for attempt in 0..cfg.max_attempts {
        match attempt_trajectory(ctx, physics, object, key, attempt, events)? {
            Ok((instances, steps)) => return Ok(Trajectory { instances, attempts: attempt + 1, steps }),
            Err(f) => {
                events.push(GraspEvent::Failed(f));
                last = Some(f);
            }
        }
    }
    // The last placement is still in the physics: an overlap names the link it is with.
    let why = match last {
        Some(Failure::InitialOverlap) => match physics.deepest_link() {
            Some((link, depth)) => format!(
                "InitialOverlap: the object overlaps link '{}' by {:.1} mm wherever it is put",
                ctx.robot.model.links[link].name,
                1000.0 * depth
            ),
            None => "InitialOverlap".to_string(),
        },
        Some(f) => GraspEvent::Failed(f).name().to_string(),
        None => "no attempt".to_string(),
    };
    bail!("{} trajectory {}: no grasp held in {} attempts ({why})", key.object_id, key.trajectory, cfg.max_attempts)
}

/// One attempt, in its phases: reach the grasp pose, place the object on the open palm, close the
/// fingers, settle while the palm turns to its pose, then record the instances (arm moves).
fn attempt_trajectory(
    ctx: &GraspContext,
    physics: &mut dyn HandPhysics,
    object: &PhysicsObject,
    key: TrajectoryKey,
    attempt: u32,
    events: &mut Vec<GraspEvent>,
) -> Result<std::result::Result<Recorded, Failure>> {
    let cfg = ctx.config;
    let rng = &mut SampleStream::trajectory(key.seed, key.object_id, key.trajectory, &format!("grasp/{attempt}"));
    let t_world_palm = ctx.sample_palm(rng);
    let Some(q) = ctx.reach(&t_world_palm, &ctx.home()) else {
        return Ok(Err(Failure::Unreachable));
    };
    let pre: Vec<f64> = cfg.preshape.iter().map(|&(lo, hi)| rng.random_range(lo..=hi)).collect();
    let placed = match ctx.robot.kind {
        GraspKind::Palm => place_object(ctx, physics, object, rng, &pre)?.then_some(()).ok_or(Failure::InitialOverlap),
        GraspKind::ParallelJaw => place_between_jaws(ctx, physics, object, rng, &pre)?,
    };
    if let Err(f) = placed {
        return Ok(Err(f));
    }
    let grasp_targets = close_hand(ctx, physics, &pre);
    let grasped = match settle(ctx, physics, &t_world_palm) {
        Ok(pose) => pose,
        Err(f) => return Ok(Err(f)),
    };
    record_instances(ctx, physics, object, key, attempt, q, (grasped, &grasp_targets), events)
}

/// How far `object` reaches along the palm normal (palm x) turned by `r`: (depth, how far behind
/// its origin its back is).
fn depth_along(object: &PhysicsObject, r: DQuat) -> (f64, f64) {
    let xs = object.points.iter().map(|p| (r * DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)).x);
    let (lo, hi) = xs.fold((f64::MAX, f64::MIN), |(lo, hi), x| (lo.min(x), hi.max(x)));
    (hi - lo, -lo)
}

/// The object's orientation in the palm: uniformly random, redrawn (no physics needed) while the
/// object is deeper in front of the palm than the fingers can wrap around.
fn sample_object_orientation(cfg: &GraspConfig, object: &PhysicsObject, rng: &mut ChaCha8Rng) -> DQuat {
    let mut r_obj = uniform_rotation(rng);
    for _ in 0..ORIENTATION_DRAWS {
        if depth_along(object, r_obj).0 <= cfg.max_grasp_depth {
            break;
        }
        r_obj = uniform_rotation(rng);
    }
    if depth_along(object, r_obj).0 <= cfg.max_grasp_depth {
        return r_obj;
    }
    // Large objects (boxes, the drill) fit the hand in few orientations: turn the model's thinnest
    // axis onto the palm normal, then spin about it, flip, and tilt a little.
    let (lo, hi) = object.points.iter().fold((DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)), |(lo, hi), p| {
        let v = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
        (lo.min(v), hi.max(v))
    });
    let ext = hi - lo;
    let thin = if ext.x <= ext.y && ext.x <= ext.z {
        DVec3::X
    } else if ext.y <= ext.z {
        DVec3::Y
    } else {
        DVec3::Z
    };
    let flip = if rng.random_bool(0.5) { -1.0 } else { 1.0 };
    let align = DQuat::from_rotation_arc(thin * flip, DVec3::X);
    let spin = DQuat::from_rotation_x(rng.random_range(0.0..std::f64::consts::TAU));
    let tilt_axis = DVec3::new(0.0, rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)).normalize_or(DVec3::Y);
    let tilt = DQuat::from_axis_angle(tilt_axis, rng.random_range(0.0..LARGE_OBJECT_MAX_TILT));
    tilt * spin * align
}

/// Phase 1: the object on the open palm (preshape, palm up) at a random orientation and offset,
/// resting under gravity. False when it overlaps a link wherever it is put.
fn place_object(
    ctx: &GraspContext,
    physics: &mut dyn HandPhysics,
    object: &PhysicsObject,
    rng: &mut ChaCha8Rng,
    pre: &[f64],
) -> Result<bool> {
    let cfg = ctx.config;
    let r_obj = sample_object_orientation(cfg, object, rng);
    let back = depth_along(object, r_obj).1;
    let o = &cfg.object_offset;
    let pos =
        DVec3::new(cfg.palm_surface_x + PLACEMENT_GAP + back, rng.random_range(o.min[1]..=o.max[1]), rng.random_range(o.min[2]..=o.max[2]));
    // An object spawned inside a link (large objects reach the thumb, which sits in front of the
    // palm) would be launched by the solver: one step finds the overlap, and the object is moved
    // out along the palm normal until it is clear.
    for shift in 0..PLACEMENT_RETRIES {
        let p = pos + DVec3::X * (PLACEMENT_STEP * shift as f64);
        physics.reset(object, DAffine3::from_rotation_translation(r_obj, p), pre)?;
        // Open hand at the preshape, palm facing up: the object rests on the palm under gravity
        // (along the palm normal, -x in the palm frame), held still by damping. Closing without
        // gravity lets the first finger to touch push the weightless object out of the hand.
        physics.set_targets(pre);
        physics.set_gravity(PALM_UP_GRAVITY);
        physics.set_object_damping(REST_DAMPING, REST_DAMPING);
        physics.step();
        if physics.max_penetration() <= PLACEMENT_MAX_OVERLAP {
            for _ in 0..ctx.steps(REST_SECONDS) {
                physics.step();
            }
            return Ok(true);
        }
    }
    Ok(false)
}

/// Phase 1 of a parallel-jaw grasp: the object weightless between the open jaws at an antipodal
/// pair of its hull ([`antipodal_pose`]), held still by damping. Fails when no pair fits the jaws,
/// or every pose tried overlaps the gripper.
fn place_between_jaws(
    ctx: &GraspContext,
    physics: &mut dyn HandPhysics,
    object: &PhysicsObject,
    rng: &mut ChaCha8Rng,
    pre: &[f64],
) -> Result<std::result::Result<(), Failure>> {
    let Some(hull) = Hull::of(&object.points) else { bail!("the object's points have no convex hull (degenerate mesh)") };
    let jaws = Jaws::of(ctx.robot, pre);
    for _ in 0..PLACEMENT_RETRIES {
        let Some(pose) = antipodal_pose(&hull, &jaws, rng) else { return Ok(Err(Failure::NoAntipodalPair)) };
        physics.reset(object, pose, pre)?;
        physics.set_targets(pre);
        physics.set_gravity(DVec3::ZERO);
        physics.set_object_damping(REST_DAMPING, REST_DAMPING);
        physics.step();
        if physics.max_penetration() <= PLACEMENT_MAX_OVERLAP {
            return Ok(Ok(()));
        }
    }
    Ok(Err(Failure::InitialOverlap))
}

/// Phase 2: every flexion joint towards its closed target, ab/adduction kept.
fn close_hand(ctx: &GraspContext, physics: &mut dyn HandPhysics, pre: &[f64]) -> Vec<f64> {
    let mut close = pre.to_vec();
    for (c, t) in close.iter_mut().zip(&ctx.config.close) {
        if let Some(t) = t {
            *c = *t;
        }
    }
    physics.set_targets(&close);
    physics.set_object_damping(CLOSE_DAMPING, CLOSE_DAMPING);
    for _ in 0..ctx.steps(ctx.config.close_seconds) {
        physics.step();
    }
    close
}

/// Phase 3: the palm turns from facing up to its sampled orientation over the first half (gravity
/// turns with it in the palm frame, as a wrist rotation would), then holds still for the second
/// half. The grasp must hold the object by friction: it may not drift more than
/// `MAX_SETTLE_DRIFT` while still. Drift during the turn is the object seating itself in the hand,
/// not a lost grasp. Returns the held object pose (palm frame).
fn settle(ctx: &GraspContext, physics: &mut dyn HandPhysics, t_world_palm: &DAffine3) -> std::result::Result<DAffine3, Failure> {
    physics.set_object_damping(HELD_DAMPING, HELD_DAMPING);
    let gravity_in_palm = rot(t_world_palm).inverse() * GRAVITY;
    let turn = DQuat::from_rotation_arc(PALM_UP_GRAVITY.normalize(), gravity_in_palm.normalize());
    let n_settle = ctx.steps(ctx.config.settle_seconds);
    let n_turn = (n_settle / 2).max(1);
    let gravity_at = |k: usize| DQuat::IDENTITY.slerp(turn, k as f64 / n_turn as f64) * PALM_UP_GRAVITY;
    // A lost object can only fall further (nothing but the hand is simulated): the grasp has
    // failed, and the rest of the settle would simulate the fall.
    for k in 1..n_turn {
        physics.set_gravity(gravity_at(k));
        physics.step();
        if lost(physics) {
            return Err(Failure::GraspNotHeld);
        }
    }
    physics.set_gravity(gravity_at(n_turn));
    let before = physics.object_pose();
    for _ in n_turn - 1..n_settle {
        physics.step();
        if lost(physics) {
            return Err(Failure::GraspNotHeld);
        }
    }
    let held = physics.object_pose();
    let touching = physics.touch_contacts().iter().filter(|c| c.is_some()).count();
    if (held.translation - before.translation).length() > MAX_SETTLE_DRIFT || touching < ctx.robot.min_touching {
        return Err(Failure::GraspNotHeld);
    }
    Ok(held)
}

/// Phase 4: one arm move per instance from the settled grasp at joint values `q`; a move that
/// cannot stand is undone and redrawn, up to `MAX_MOVES_PER_INSTANCE` times.
#[allow(clippy::too_many_arguments)] // the attempt's state, passed in and out (no hidden fields)
fn record_instances(
    ctx: &GraspContext,
    physics: &mut dyn HandPhysics,
    object: &PhysicsObject,
    key: TrajectoryKey,
    attempt: u32,
    mut q: Vec<f64>,
    (grasped, grasp_targets): (DAffine3, &[f64]),
    events: &mut Vec<GraspEvent>,
) -> Result<std::result::Result<Recorded, Failure>> {
    let mut out = Vec::with_capacity(key.instances as usize);
    let mut steps = Vec::new();
    let mut log = ctx.record_steps.then_some(StepLog { steps: &mut steps, grasped });
    if let Some(log) = log.as_mut() {
        log.push(ctx, physics, &q);
    }
    for instance in 0..key.instances {
        let sample_key = SampleKey { seed: key.seed, object_id: key.object_id, trajectory: key.trajectory, instance };
        let mut moved = 0;
        let (obj, contacts, penetration) = loop {
            // The first move of an instance draws from `arm/<attempt>`, later ones (after a pose
            // that could not be recorded) from `arm/<attempt>/<move>`.
            let stream = if moved == 0 { format!("arm/{attempt}") } else { format!("arm/{attempt}/{moved}") };
            let mut arm_rng = SampleStream::sample(&sample_key, &stream);
            moved += 1;
            // A move that drops the object or ends in a pose that cannot be recorded is undone
            // (the arm then only takes moves that keep a recordable grasp): redoing one move costs
            // far less than a fresh grasp and every instance before it.
            physics.save();
            let q_before = q.clone();
            let logged = log.as_ref().map_or(0, |l| l.steps.len());
            // Why this move cannot stand: the attempt's failure if it was the last try, and the
            // redo counted otherwise.
            let (failure, redo) = match move_and_settle(ctx, physics, object, &mut q, &mut arm_rng, grasp_targets, log.as_mut())? {
                MoveOutcome::Recordable(obj, contacts, penetration) => break (obj, contacts, penetration),
                MoveOutcome::Failed(Failure::LostDuringMotion) => (Failure::LostDuringMotion, Redo::Drop),
                MoveOutcome::Failed(f) => return Ok(Err(f)),
                MoveOutcome::NotRecordable(f @ Failure::Penetration) => (f, Redo::Penetration),
                MoveOutcome::NotRecordable(f @ Failure::TouchesFloor) => (f, Redo::Floor),
                MoveOutcome::NotRecordable(f) => (f, Redo::Contacts),
            };
            if moved >= MAX_MOVES_PER_INSTANCE {
                return Ok(Err(failure));
            }
            events.push(GraspEvent::Redone(redo));
            physics.restore();
            q = q_before;
            if let Some(log) = log.as_mut() {
                log.steps.truncate(logged);
            }
        };
        out.push(instance_state(ctx, physics, &q, obj, grasped, contacts, penetration));
    }
    Ok(Ok((out, steps)))
}

/// The state of the grasp with the arm at `q` (its hand joints read from the physics).
fn instance_state(
    ctx: &GraspContext,
    physics: &dyn HandPhysics,
    q: &[f64],
    obj: DAffine3,
    grasped: DAffine3,
    contacts: Vec<Option<f64>>,
    penetration: f64,
) -> InstanceState {
    let mut qr = q.to_vec();
    ctx.robot.set_hand(&mut qr, &physics.joint_positions());
    let rel = grasped.inverse() * obj;
    InstanceState {
        t_base_palm: ctx.robot.grasp_frame_pose(&qr),
        q: qr,
        t_palm_object: obj,
        contacts,
        slip_translation: rel.translation.length(),
        slip_rotation: rot(&rel).angle_between(DQuat::IDENTITY),
        penetration,
    }
}

/// The states of the recorded arm moves, one per physics step (episodes).
struct StepLog<'a> {
    steps: &'a mut Vec<InstanceState>,
    grasped: DAffine3,
}

impl StepLog<'_> {
    /// The state now, with the arm at `q`.
    fn push(&mut self, ctx: &GraspContext, physics: &dyn HandPhysics, q: &[f64]) {
        let state =
            instance_state(ctx, physics, q, physics.object_pose(), self.grasped, physics.touch_contacts(), physics.max_penetration());
        self.steps.push(state);
    }
}

/// How one arm move of an instance ended.
// One value per arm move, moved once: boxing the recordable pose would buy nothing.
#[allow(clippy::large_enum_variant)]
enum MoveOutcome {
    /// Object pose in the palm, touch-link contacts, deepest penetration: a recordable instance.
    Recordable(DAffine3, Vec<Option<f64>>, f64),
    /// The pose cannot be recorded (penetration, too few contacts, the object on the floor), but
    /// the grasp still holds: another move may give a recordable one.
    NotRecordable(Failure),
    /// The grasp is lost (or the target unreachable): the attempt ends.
    Failed(Failure),
}

/// Moves the arm from `q` to a random reachable palm pose along a simulated smooth joint-space
/// path (the palm's motion enters as apparent gravity), lets the object settle, and checks the
/// instance. `q` becomes the target.
// Long on purpose: the move's phases in order (draw a reachable pose, follow the path and hold,
// settle, check the instance), each stepping the same physics and reading the same state.
fn move_and_settle(
    ctx: &GraspContext,
    physics: &mut dyn HandPhysics,
    object: &PhysicsObject,
    q: &mut Vec<f64>,
    arm_rng: &mut ChaCha8Rng,
    grasp_targets: &[f64],
    mut log: Option<&mut StepLog>,
) -> Result<MoveOutcome> {
    let cfg = ctx.config;
    let robot = ctx.robot;
    let steps = |s: f64| ctx.steps(s);
    let mut target = None;
    for _ in 0..20 {
        let t = ctx.sample_move_palm(arm_rng);
        // A pose that puts a link under the floor is drawn again before any physics is spent on
        // it (the check after the move stays, for the hand's links).
        if let Some(qt) = ctx.reach(&t, q)
            && robot_floor_clearance(robot, &ctx.t_world_base, &qt).is_none_or(|(_, z)| z >= 0.0)
        {
            target = Some(qt);
            break;
        }
    }
    let Some(q_target) = target else {
        return Ok(MoveOutcome::Failed(Failure::Unreachable));
    };
    let n = steps(cfg.move_seconds);
    let q_from = q.clone();
    let palm_at = |s: f64| -> DAffine3 {
        let w = s * s * (3.0 - 2.0 * s);
        let qs: Vec<f64> = q_from.iter().zip(&q_target).map(|(a, b)| a + (b - a) * w).collect();
        ctx.t_world_base * robot.grasp_frame_pose(&qs)
    };
    let dt = ctx.timestep;
    let ds = 1.0 / n as f64;
    for k in 1..=n + steps(cfg.hold_seconds) {
        let s = (k as f64 * ds).min(1.0);
        let p = palm_at(s);
        let acc = if k <= n {
            let (a, b) = (palm_at((s - ds).max(0.0)).translation, palm_at((s + ds).min(1.0)).translation);
            (b - 2.0 * p.translation + a) / (dt * dt)
        } else {
            DVec3::ZERO
        };
        physics.set_gravity(rot(&p).inverse() * (GRAVITY - acc));
        physics.step();
        if let Some(log) = log.as_deref_mut() {
            let w = s * s * (3.0 - 2.0 * s);
            let qs: Vec<f64> = q_from.iter().zip(&q_target).map(|(a, b)| a + (b - a) * w).collect();
            log.push(ctx, physics, &qs);
        }
        // An object this far from the palm has fallen out of the hand and cannot come back: the
        // move's outcome is known, and the rest of it (up to 0.7 s) would simulate the fall.
        // (Same outcome, same bytes: the failed move is undone and the next draws from its own
        // random stream.)
        if lost(physics) {
            return Ok(MoveOutcome::Failed(Failure::LostDuringMotion));
        }
    }
    // The scripted finger motion, the arm still (apparent gravity as in the hold).
    if let Some(gait) = &ctx.finger_gait {
        let start = physics.joint_positions();
        for k in 1..=gait.steps {
            physics.set_targets(&gait.targets(grasp_targets, &start, k as f64 * dt));
            physics.step();
            if let Some(log) = log.as_deref_mut() {
                log.push(ctx, physics, &q_target);
            }
            if lost(physics) {
                physics.set_targets(grasp_targets);
                return Ok(MoveOutcome::Failed(Failure::LostDuringMotion));
            }
        }
        physics.set_targets(grasp_targets);
    }
    *q = q_target;
    let touching = physics.touch_contacts().iter().filter(|c| c.is_some()).count();
    if lost(physics) || touching == 0 {
        return Ok(MoveOutcome::Failed(Failure::LostDuringMotion));
    }
    if touching < robot.min_touching {
        return Ok(MoveOutcome::NotRecordable(Failure::TooFewContacts));
    }
    // Squeezing transients settle within a few tens of milliseconds: wait for them (an episode
    // waits out the whole window, so that every move takes the same time).
    let mut penetration = physics.max_penetration();
    for _ in 0..PENETRATION_WAITS {
        if penetration <= cfg.max_penetration && log.is_none() {
            break;
        }
        for _ in 0..steps(PENETRATION_WAIT_SECONDS) {
            physics.step();
            if let Some(log) = log.as_deref_mut() {
                log.push(ctx, physics, q);
            }
        }
        penetration = physics.max_penetration();
    }
    if penetration > cfg.max_penetration {
        return Ok(MoveOutcome::NotRecordable(Failure::Penetration));
    }
    let obj = physics.object_pose();
    let contacts = physics.touch_contacts();
    if contacts.iter().filter(|c| c.is_some()).count() < robot.min_touching {
        return Ok(MoveOutcome::NotRecordable(Failure::TooFewContacts));
    }
    // The object must hang free: its lowest point above the floor (z = 0); and no link of the
    // robot may be under the floor (a real arm would have hit it).
    if floor_clearance(&object.points, &(ctx.t_world_base * robot.grasp_frame_pose(q) * obj)) < MIN_FLOOR_CLEARANCE {
        return Ok(MoveOutcome::NotRecordable(Failure::TouchesFloor));
    }
    let mut q_now = q.clone();
    robot.set_hand(&mut q_now, &physics.joint_positions());
    if robot_floor_clearance(robot, &ctx.t_world_base, &q_now).is_some_and(|(_, z)| z < 0.0) {
        return Ok(MoveOutcome::NotRecordable(Failure::TouchesFloor));
    }
    Ok(MoveOutcome::Recordable(obj, contacts, penetration))
}

/// After a move, up to this many waits of `PENETRATION_WAIT_SECONDS` for squeezing transients.
const PENETRATION_WAITS: usize = 10;
const PENETRATION_WAIT_SECONDS: f64 = 0.025;

/// Distance (m) from the palm at which an object is lost from the hand (a move's end check; the
/// settle and the moves stop as soon as the object is this far).
const LOST_DISTANCE: f64 = 0.25;

/// Whether the object has fallen `LOST_DISTANCE` from the palm (out of the hand for good).
fn lost(physics: &dyn HandPhysics) -> bool {
    physics.object_pose().translation.length() > LOST_DISTANCE
}

/// Smallest height (m) of the object above the floor a recorded instance may have.
const MIN_FLOOR_CLEARANCE: f64 = 0.005;

/// The lowest link of the robot at joint values `q` (its base at `t_world_base`) that an arm joint
/// moves, and the height of its lowest collision point above the floor (world z = 0); None: no
/// such link has collision geometry.
pub fn robot_floor_clearance(robot: &Robot, t_world_base: &DAffine3, q: &[f64]) -> Option<(usize, f64)> {
    let model = &robot.model;
    let first_moved = model.joints[*robot.arm_joints.first()?].child;
    let poses = model.forward_kinematics(q);
    let mut lowest: Option<(usize, f64)> = None;
    for (id, link) in model.links.iter().enumerate() {
        if !model.is_below(id, first_moved) {
            continue;
        }
        let t_world_link = *t_world_base * poses[id];
        for s in &link.collisions {
            let t = t_world_link * s.origin;
            let z = match &s.geometry {
                vt_robot::Geometry::Box { size } => {
                    let h = *size * 0.5;
                    (0..8)
                        .map(|c| {
                            let corner = DVec3::new(
                                if c & 1 == 0 { -h.x } else { h.x },
                                if c & 2 == 0 { -h.y } else { h.y },
                                if c & 4 == 0 { -h.z } else { h.z },
                            );
                            t.transform_point3(corner).z
                        })
                        .fold(f64::MAX, f64::min)
                }
                vt_robot::Geometry::Sphere { radius } => t.translation.z - radius,
                vt_robot::Geometry::Cylinder { radius, length } => {
                    let uz = t.transform_vector3(DVec3::Z).normalize().z;
                    t.translation.z - uz.abs() * length / 2.0 - radius * (1.0 - uz * uz).max(0.0).sqrt()
                }
                g => g.hull_points().unwrap_or(&[]).iter().map(|p| t.transform_point3(*p).z).fold(f64::MAX, f64::min),
            };
            if lowest.is_none_or(|(_, l)| z < l) {
                lowest = Some((id, z));
            }
        }
    }
    lowest
}

/// Height above the floor (world z = 0) of the lowest of `points` (model frame) posed by
/// `t_world_object`.
pub fn floor_clearance(points: &[[f32; 3]], t_world_object: &DAffine3) -> f64 {
    points.iter().map(|p| t_world_object.transform_point3(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)).z).fold(f64::MAX, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{GraspConfig, PhysicsConfig};
    use crate::physics::{PhysicsSettings, RapierHand};
    use rand::SeedableRng;

    /// The object's physics shape: the real mesh when `YCB_DIR` is set, else the procedural one.
    pub fn physics_object(id: &str) -> PhysicsObject {
        let e = vt_objects::Catalog::builtin().get(id).unwrap().clone();
        let m = match std::env::var_os("YCB_DIR") {
            Some(d) => vt_objects::load_mesh(&vt_objects::find_ycb_mesh(std::path::Path::new(&d), id).unwrap()).unwrap(),
            None => vt_objects::procedural_mesh(&e),
        };
        PhysicsObject { points: m.positions.clone(), mass: e.mass }
    }

    /// The grasp config's defaults with the Allegro hand's joint arrays.
    fn allegro_grasp() -> GraspConfig {
        GraspConfig::default().with_robot_defaults(&Robot::allegro())
    }

    /// The robot base and the camera of `scenes/paper.yaml`.
    fn paper_context() -> (DAffine3, DVec3) {
        (
            DAffine3::from_rotation_translation(DQuat::from_rotation_z(std::f64::consts::PI), DVec3::new(0.0, 0.5, 0.0)),
            DVec3::new(0.0, -0.75, 0.55),
        )
    }

    /// The palm's normal (world) of `n` arm moves drawn with `cfg`.
    fn move_normals(cfg: &GraspConfig, n: u64) -> Vec<(DVec3, DVec3)> {
        let robot = Robot::allegro();
        let (t_world_base, camera_position) = paper_context();
        let ctx = GraspContext {
            robot: &robot,
            t_world_base,
            config: cfg,
            timestep: 1.0 / 240.0,
            camera_position,
            record_steps: false,
            finger_gait: None,
        };
        (0..n)
            .map(|k| {
                let mut rng = ChaCha8Rng::seed_from_u64(k);
                let t = ctx.sample_move_palm(&mut rng);
                (t.matrix3 * DVec3::X, t.translation)
            })
            .collect()
    }

    #[test]
    fn back_to_camera_moves_turn_the_palm_away_from_the_camera() {
        let mut cfg = GraspConfig { back_to_camera_share: 0.5, ..allegro_grasp() };
        let camera = DVec3::new(0.0, -0.75, 0.55);
        let normals = move_normals(&cfg, 400);
        let (lo, hi) = cfg.back_to_camera_tilt_deg;
        let mut back = 0;
        for (n, p) in &normals {
            assert!((n.length() - 1.0).abs() < 1e-9);
            let tilt = n.z.clamp(-1.0, 1.0).acos().to_degrees();
            if tilt <= cfg.max_tilt_deg + 1e-9 {
                continue;
            }
            // Outside the cone: a back-to-camera move, tilted within its range, away from the
            // camera (the normal's horizontal part points from the camera past the palm).
            back += 1;
            assert!(tilt >= lo - 1e-9 && tilt <= hi + 1e-9, "tilt {tilt}");
            let away = (*p - camera).with_z(0.0).normalize();
            let horizontal = n.with_z(0.0).normalize();
            assert!(horizontal.dot(away) > 0.99, "normal {n} is not turned away from the camera");
            // The camera looks at the back of the hand: the palm normal points along its view.
            assert!(n.dot((*p - camera).normalize()) > 0.0);
        }
        // About half of the moves (binomial, 400 draws: 5 standard deviations either way).
        assert!((150..=250).contains(&back), "{back} of 400 back-to-camera moves");
        // Without the knob no move leaves the cone, and the draws are those of the plain sampler.
        cfg.back_to_camera_share = 0.0;
        let robot = Robot::allegro();
        let (t_world_base, camera_position) = paper_context();
        let ctx = GraspContext {
            robot: &robot,
            t_world_base,
            config: &cfg,
            timestep: 1.0 / 240.0,
            camera_position,
            record_steps: false,
            finger_gait: None,
        };
        for k in 0..50 {
            let a = ctx.sample_move_palm(&mut ChaCha8Rng::seed_from_u64(k));
            let b = ctx.sample_palm(&mut ChaCha8Rng::seed_from_u64(k));
            assert_eq!(a, b);
            assert!((a.matrix3 * DVec3::X).z >= cfg.max_tilt_deg.to_radians().cos() - 1e-9);
        }
    }

    /// The grasp loop over the scripted hand: `cfg` with the paper's robot and camera.
    fn run_fake(hand: &mut crate::physics::fake::FakeHand, cfg: &GraspConfig, instances: u32) -> (Result<Trajectory>, Vec<GraspEvent>) {
        let robot = Robot::allegro();
        let (t_world_base, camera_position) = paper_context();
        let ctx = GraspContext {
            robot: &robot,
            t_world_base,
            config: cfg,
            timestep: 1.0 / 240.0,
            camera_position,
            record_steps: false,
            finger_gait: None,
        };
        let object = PhysicsObject {
            points: vt_objects::procedural_mesh(vt_objects::Catalog::builtin().get("005_tomato_soup_can").unwrap()).positions,
            mass: 0.35,
        };
        let mut failures = Vec::new();
        let key = TrajectoryKey { seed: 3, object_id: "005_tomato_soup_can", trajectory: 0, instances };
        (simulate_trajectory(&ctx, hand, &object, key, &mut failures), failures)
    }

    #[test]
    fn a_held_object_gives_every_instance_without_slip_and_the_same_key_the_same_trajectory() {
        let cfg = allegro_grasp();
        let robot = Robot::allegro();
        let mut hand = crate::physics::fake::FakeHand::holding(3);
        let (t, failures) = run_fake(&mut hand, &cfg, 4);
        let t = t.unwrap();
        assert_eq!((t.instances.len(), t.attempts), (4, 1), "{failures:?}");
        let grasped = t.instances[0].t_palm_object;
        for i in &t.instances {
            assert_eq!(i.t_palm_object, grasped);
            assert_eq!((i.slip_translation, i.slip_rotation), (0.0, 0.0));
            assert_eq!(i.contacts.iter().filter(|c| c.is_some()).count(), 3);
            // The recorded hand joints are the physics' (the fake reaches the closing targets).
            for (k, h) in robot.hand.iter().enumerate() {
                if let Some(target) = cfg.close[k] {
                    assert_eq!(i.q[h.dof], target, "{}", h.name);
                }
            }
        }
        // Arm moves differ from instance to instance; the same key gives the same trajectory.
        assert_ne!(t.instances[0].t_base_palm, t.instances[1].t_base_palm);
        let (again, _) = run_fake(&mut crate::physics::fake::FakeHand::holding(3), &cfg, 4);
        let again = again.unwrap();
        assert!(t.instances.iter().zip(&again.instances).all(|(a, b)| a.q == b.q && a.t_palm_object == b.t_palm_object));
    }

    #[test]
    fn grasps_that_do_not_hold_fail_each_attempt_and_the_trajectory_names_the_cause() {
        let cfg = GraspConfig { max_attempts: 3, ..allegro_grasp() };
        // The object slides 1 mm per step: more than 2 cm while the hand holds still.
        let mut sliding = crate::physics::fake::FakeHand::holding(3);
        sliding.drift_per_step = DVec3::new(0.0, 0.0, 0.001);
        let (t, failures) = run_fake(&mut sliding, &cfg, 2);
        let e = t.unwrap_err().to_string();
        assert!(e.contains("005_tomato_soup_can trajectory 0: no grasp held in 3 attempts"), "{e}");
        assert!(failures.iter().all(|f| matches!(f, GraspEvent::Failed(Failure::GraspNotHeld | Failure::Unreachable))), "{failures:?}");
        assert!(failures.contains(&GraspEvent::Failed(Failure::GraspNotHeld)));
        // One phalanx alone does not hold an object either.
        let (t, failures) = run_fake(&mut crate::physics::fake::FakeHand::holding(1), &cfg, 2);
        assert!(t.is_err());
        assert!(failures.contains(&GraspEvent::Failed(Failure::GraspNotHeld)), "{failures:?}");
        // A hand that presses into the object never records an instance (1.2 mm: placed, since
        // placement tolerates 1.5 mm, but over the 1 mm a recorded instance may have).
        let mut pressing = crate::physics::fake::FakeHand::holding(3);
        pressing.penetration = 1.2 * cfg.max_penetration;
        let (t, failures) = run_fake(&mut pressing, &cfg, 2);
        assert!(t.is_err());
        assert!(
            failures.contains(&GraspEvent::Redone(Redo::Penetration)) && failures.contains(&GraspEvent::Failed(Failure::Penetration)),
            "{failures:?}"
        );
    }

    #[test]
    fn a_move_that_drops_the_object_is_undone_and_redrawn() {
        let cfg = allegro_grasp();
        // Steps of placing, resting, closing and settling, then well into the first arm move.
        let settle_steps = (0.15f64 + cfg.close_seconds + cfg.settle_seconds) * 240.0;
        let mut hand = crate::physics::fake::FakeHand::holding(3);
        hand.drop_at_step = Some(settle_steps as u64 + 60);
        let (t, failures) = run_fake(&mut hand, &cfg, 3);
        let t = t.unwrap();
        assert_eq!((t.instances.len(), t.attempts), (3, 1));
        assert_eq!(failures, vec![GraspEvent::Redone(Redo::Drop)]);
        // The redone move starts from the state saved before the drop: the object is back in the hand.
        assert!(t.instances.iter().all(|i| i.slip_translation == 0.0));
    }

    #[test]
    fn both_built_in_robots_reach_the_paper_workspace() {
        // The robots the binary carries (the Panda, built from its upstream files, has its own
        // tests where they are fetched: tests/panda.rs).
        for name in vt_robot::BUILTIN_ROBOTS.into_iter().filter(|&n| vt_robot::Robot::builtin(n).is_ok()) {
            let robot = Robot::builtin(name).unwrap();
            let cfg = GraspConfig::default().with_robot_defaults(&robot);
            let (t_world_base, camera_position) = paper_context();
            let ctx = GraspContext {
                robot: &robot,
                t_world_base,
                config: &cfg,
                timestep: 1.0 / 240.0,
                camera_position,
                record_steps: false,
                finger_gait: None,
            };
            let share = reachable_share(&ctx, REACH_SAMPLES);
            eprintln!("{name}: {:.0}% of {REACH_SAMPLES} workspace poses reached", 100.0 * share);
            assert!(share >= 0.9, "{name}: {share}");
        }
    }

    #[test]
    fn the_simulated_hand_starts_at_its_preshape_not_at_the_urdfs_zero() {
        let robot = Robot::allegro();
        let settings = PhysicsSettings::from(&PhysicsConfig::default());
        let mut hand = RapierHand::new(&robot, settings).unwrap();
        let pre: Vec<f64> = robot.hand.iter().map(|h| 0.5 * (h.preshape.0 + h.preshape.1) + 0.1).collect();
        // The object far away: nothing touches the hand.
        hand.reset(&physics_object("009_gelatin_box"), DAffine3::from_translation(DVec3::new(1.0, 0.0, 0.0)), &pre).unwrap();
        hand.set_targets(&pre);
        hand.set_gravity(DVec3::ZERO);
        // Where the joints are before and after the first step: at the preshape, not at 0.
        for _ in 0..2 {
            for ((got, want), h) in hand.joint_positions().iter().zip(&pre).zip(&robot.hand) {
                let want = want.clamp(robot.model.joints[h.joint].lower, robot.model.joints[h.joint].upper);
                assert!((got - want).abs() < 0.02, "{}: {got} vs the preshape {want}", h.name);
            }
            hand.step();
        }
    }

    #[test]
    fn a_link_under_the_floor_is_found_and_named() {
        let robot = Robot::allegro();
        let mut q = robot.model.zero();
        for (&d, &v) in robot.arm_dofs.iter().zip(&robot.home) {
            q[d] = v;
        }
        let (link, z) = robot_floor_clearance(&robot, &DAffine3::IDENTITY, &q).unwrap();
        // Lowered by 2 m, the same link is 2 m lower: under the floor.
        let (low, zl) = robot_floor_clearance(&robot, &DAffine3::from_translation(DVec3::new(0.0, 0.0, -2.0)), &q).unwrap();
        assert_eq!(link, low);
        assert!((z - 2.0 - zl).abs() < 1e-9 && zl < 0.0, "{z} {zl}");
        // The base, fixed to the floor, does not count: the lowest link is one the arm moves.
        assert!(robot.model.is_below(link, robot.model.joints[robot.arm_joints[0]].child), "{}", robot.model.links[link].name);
    }

    #[test]
    fn event_names_are_the_ones_earlier_datasets_count_under() {
        use Failure::*;
        let failed =
            [InitialOverlap, GraspNotHeld, LostDuringMotion, TooFewContacts, Penetration, TouchesFloor, Unreachable, NoAntipodalPair];
        for f in failed {
            assert_eq!(GraspEvent::Failed(f).name(), format!("{f:?}"));
        }
        for r in [Redo::Penetration, Redo::Contacts, Redo::Floor, Redo::Drop] {
            assert_eq!(GraspEvent::Redone(r).name(), format!("MoveRedoneFor{r:?}"));
        }
    }

    #[test]
    #[ignore]
    fn experiment() {
        let robot = Robot::allegro();
        let pc = PhysicsConfig::default();
        let env = |k: &str, d: f64| std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d);
        let settings =
            PhysicsSettings { friction: env("F", pc.friction), max_torque: env("T", pc.max_torque), ..PhysicsSettings::from(&pc) };
        let mut cfg = allegro_grasp();
        cfg.max_tilt_deg = env("TILT", cfg.max_tilt_deg);
        cfg.move_seconds = env("MOVE", cfg.move_seconds);
        cfg.max_attempts = env("MAXATT", cfg.max_attempts as f64) as u32;
        let only = std::env::var("OBJ").unwrap_or_default();
        let ctx = GraspContext {
            robot: &robot,
            t_world_base: DAffine3::from_rotation_translation(DQuat::from_rotation_z(std::f64::consts::PI), DVec3::new(0.0, 0.5, 0.0)),
            config: &cfg,
            timestep: pc.timestep,
            camera_position: DVec3::new(0.0, -0.75, 0.55),
            record_steps: false,
            finger_gait: None,
        };
        // PHYS=mujoco (with --features mujoco) measures the MuJoCo backend instead.
        let mut hand: Box<dyn HandPhysics> = match std::env::var("PHYS").as_deref() {
            #[cfg(feature = "mujoco")]
            Ok("mujoco") => Box::new(crate::physics::MujocoHand::new(&robot, settings).unwrap()),
            _ => Box::new(RapierHand::new(&robot, settings).unwrap()),
        };
        let n: u32 = std::env::var("TRAJ").ok().and_then(|s| s.parse().ok()).unwrap_or(3);
        let inst: u32 = std::env::var("INST").ok().and_then(|s| s.parse().ok()).unwrap_or(10);
        for e in vt_objects::Catalog::builtin().entries().iter().filter(|e| e.id.contains(&only)) {
            let obj = physics_object(&e.id);
            let mut failures = Vec::new();
            let t0 = std::time::Instant::now();
            let mut ok = 0;
            let mut attempts = 0;
            let mut max_slip: f64 = 0.0;
            let mut max_pen: f64 = 0.0;
            for t in 0..n {
                match simulate_trajectory(
                    &ctx,
                    hand.as_mut(),
                    &obj,
                    TrajectoryKey { seed: 1, object_id: &e.id, trajectory: t, instances: inst },
                    &mut failures,
                ) {
                    Ok(tr) => {
                        ok += 1;
                        attempts += tr.attempts;
                        for s in &tr.instances {
                            max_slip = max_slip.max(s.slip_translation);
                            max_pen = max_pen.max(s.penetration);
                        }
                    }
                    Err(e) => eprintln!("{e}"),
                }
            }
            let mut counts = std::collections::BTreeMap::new();
            for f in &failures {
                *counts.entry(f.name()).or_insert(0) += 1;
            }
            eprintln!(
                "{:24} ok {ok}/{n} attempts {attempts} slip {:.1}mm pen {:.2}mm {:.1}s {:?}",
                e.id,
                max_slip * 1e3,
                max_pen * 1e3,
                t0.elapsed().as_secs_f64(),
                counts
            );
        }
    }
}

//! Phase 4 of an attempt: the instances. Each is one arm move from the last recorded state to a
//! random reachable palm pose, along a simulated smooth joint-space path (the palm's motion
//! enters as apparent gravity), then the hold, the scripted finger motion (episodes), the wait for
//! squeezing transients and the instance's checks. A move that cannot stand is undone and
//! redrawn, up to `MAX_MOVES_PER_INSTANCE` times.

use anyhow::Result;
use glam::{DAffine3, DVec3};
use rand_chacha::ChaCha8Rng;
use vt_randomizers::{SampleKey, SampleStream};

use super::floor::{MIN_FLOOR_CLEARANCE, floor_clearance, robot_floor_clearance};
use super::pivot::Pivoted;
use super::{
    Attempt, Failure, GRAVITY, GraspContext, GraspEvent, Held, InstanceState, Phase, Recorded, Redo, Stop, lost, rot, turn_left_to,
};
use crate::physics::HandPhysics;

/// Arm moves tried for one instance (each from the last recorded state, when the backend can
/// undo) before the attempt is given up. A grasp whose four moves all drop the object or press a
/// finger in is seldom saved by more: 4 tries made the grasp loop 10% faster than 8, and 16 20%
/// slower, over 4 trajectories of every object with the same kept share.
const MAX_MOVES_PER_INSTANCE: u32 = 4;

/// Palm poses drawn for one arm move before it counts as unreachable.
const MOVE_TARGET_DRAWS: usize = 20;

/// A snapshot's hold ends once the object has stopped in the hand: it moved less than
/// `STILL_TRANSLATION` (m) and turned less than `STILL_ROTATION` (rad) in the palm over the last
/// `STILL_WINDOW_SECONDS`, and the hold lasted `MIN_HOLD_SECONDS`. That is 1 mm/s and 1°/s,
/// twenty times the creep of a held object with the arm still (docs/grasp-loop.md#creep).
const STILL_WINDOW_SECONDS: f64 = 0.05;
const STILL_TRANSLATION: f64 = 0.00005;
const STILL_ROTATION: f64 = 0.05 * std::f64::consts::PI / 180.0;
const MIN_HOLD_SECONDS: f64 = 0.05;

use crate::config::{PENETRATION_WAIT_SECONDS, PENETRATION_WAITS};

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

/// The states of the recorded arm moves, one per physics step (episodes).
pub(super) struct StepLog<'a> {
    steps: &'a mut Vec<InstanceState>,
    grasped: DAffine3,
}

impl StepLog<'_> {
    /// The state now, with the arm at `q`.
    pub(super) fn push(&mut self, ctx: &GraspContext, physics: &dyn HandPhysics, q: &[f64]) {
        let state =
            instance_state(ctx, physics, q, physics.object_pose(), self.grasped, physics.touch_contacts(), physics.max_penetration());
        self.steps.push(state);
    }
}

/// The state of the grasp with the arm at `q` (its hand joints read from the physics).
pub(super) fn instance_state(
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
    let mut state = InstanceState {
        t_base_palm: ctx.robot.grasp_frame_pose(&qr),
        q: qr,
        t_palm_object: obj,
        contacts,
        slip_translation: 0.0,
        slip_rotation: 0.0,
        penetration,
        hand_contacts: if ctx.record_contact_forces { physics.hand_contacts() } else { None },
    };
    state.count_slip_from(&grasped);
    state
}

/// Whether the object has stopped in the hand during a hold: its palm-frame poses over the last
/// `STILL_WINDOW_SECONDS`.
struct StillWatch {
    window: std::collections::VecDeque<DAffine3>,
    len: usize,
    min_steps: usize,
}

impl StillWatch {
    fn new(ctx: &GraspContext) -> Self {
        let len = ctx.steps(STILL_WINDOW_SECONDS);
        StillWatch { window: std::collections::VecDeque::with_capacity(len + 1), len, min_steps: ctx.steps(MIN_HOLD_SECONDS) }
    }

    /// The object at `pose` after the hold's `held`-th step: true once it has stopped.
    fn stopped(&mut self, pose: DAffine3, held: usize) -> bool {
        self.window.push_back(pose);
        if self.window.len() <= self.len {
            return false;
        }
        let then = self.window.pop_front().expect("a full window");
        let moved = (pose.translation - then.translation).length();
        let turned = rot(&then).angle_between(rot(&pose));
        held >= self.min_steps && moved < STILL_TRANSLATION && turned < STILL_ROTATION
    }
}

/// The smooth path's peak speed (at its middle) in units of its mean speed: smoothstep's slope.
pub(super) const SMOOTH_PATH_PEAK_SPEED: f64 = 1.5;

/// The joint values a fraction `s` ∈ [0, 1] along the smooth (smoothstep) path from `from` to `to`.
pub(super) fn along_path(from: &[f64], to: &[f64], s: f64) -> Vec<f64> {
    let w = s * s * (3.0 - 2.0 * s);
    from.iter().zip(to).map(|(a, b)| a + (b - a) * w).collect()
}

impl GraspContext<'_> {
    /// The apparent gravity in the palm's frame with the arm a fraction `s` along the smooth path
    /// from `from` to `to`: gravity less the palm's acceleration while the arm moves at `ds` of
    /// the path per physics step (None: standing still).
    pub(super) fn gravity_on_path(&self, from: &[f64], to: &[f64], s: f64, ds: Option<f64>) -> DVec3 {
        let palm_at = |s: f64| -> DAffine3 { self.t_world_base * self.robot.grasp_frame_pose(&along_path(from, to, s)) };
        let p = palm_at(s);
        let acc = match ds {
            Some(ds) => {
                let (a, b) = (palm_at((s - ds).max(0.0)).translation, palm_at((s + ds).min(1.0)).translation);
                let dt = self.timestep;
                (b - 2.0 * p.translation + a) / (dt * dt)
            }
            None => DVec3::ZERO,
        };
        rot(&p).inverse() * (GRAVITY - acc)
    }

    /// The shortest time (s) the smooth path from `from` to `to` takes with every arm joint within
    /// its speed limit (the description's `velocity`; a joint without one is not limited).
    pub(super) fn path_seconds_at_speed_limits(&self, from: &[f64], to: &[f64]) -> f64 {
        let robot = self.robot;
        robot
            .arm_joints
            .iter()
            .zip(&robot.arm_dofs)
            .map(|(&j, &d)| {
                let limit = robot.model.joints[j].velocity;
                if limit > 0.0 { SMOOTH_PATH_PEAK_SPEED * (to[d] - from[d]).abs() / limit } else { 0.0 }
            })
            .fold(0.0, f64::max)
    }

    /// Physics steps of the arm's path from `from` to `to`: `move_seconds`, or, with
    /// `arm_speed_limits`, as many more as keep every joint within its speed limit (snapshots;
    /// an episode's moves keep one length).
    pub(super) fn path_steps(&self, from: &[f64], to: &[f64]) -> usize {
        if self.record_steps { self.steps(self.config.move_seconds) } else { self.stretched_path_steps(from, to) }
    }

    /// An arm move's end: the arm's joints (`move_end`) at a palm pose drawn for the move that
    /// puts no link under the floor, nor the held object (at `t_palm_object`, its `points`) —
    /// drawn again before any physics is spent on it; the checks after the move stay, for the
    /// hand's links and for an object that slipped on the way. Where every draw puts the object
    /// on the floor, the first that keeps the arm above it (the move may still stand: the object
    /// can turn in the hand). None when no draw keeps the arm above the floor.
    ///
    /// The inverse kinematics starts from `q`, so that the arm takes the nearest solution. Where
    /// no draw is usable from there, the arm has wandered into a branch of its solutions (the
    /// shoulder turned under, the elbow below it) where most poses put a link under the floor
    /// (82 % of the moves drawn from such a pose of `scenes/paper.yaml`, 3 % from home): the
    /// draws are made again from the arm's home, and the move brings the arm back to the branch
    /// the workspace is drawn for, instead of ending a grasp that holds.
    pub(super) fn draw_move_target(
        &self,
        q: &[f64],
        t_palm_object: &DAffine3,
        points: &[[f32; 3]],
        arm_rng: &mut ChaCha8Rng,
    ) -> Option<Vec<f64>> {
        self.draw_move_target_from(q, q, t_palm_object, points, arm_rng).or_else(|| {
            // Home's arm joints, the hand's where they are (the floor checks see the hand).
            let mut home = q.to_vec();
            for (&d, &v) in self.robot.arm_dofs.iter().zip(&self.config.home_arm) {
                home[d] = v;
            }
            self.draw_move_target_from(q, &home, t_palm_object, points, arm_rng)
        })
    }

    /// `draw_move_target` with the inverse kinematics started from `seed`.
    pub(super) fn draw_move_target_from(
        &self,
        q: &[f64],
        seed: &[f64],
        t_palm_object: &DAffine3,
        points: &[[f32; 3]],
        arm_rng: &mut ChaCha8Rng,
    ) -> Option<Vec<f64>> {
        let kind = self.draw_move_kind(arm_rng);
        let mut arm_clear = None;
        for _ in 0..MOVE_TARGET_DRAWS {
            let t = self.sample_move_palm(kind, arm_rng);
            let Some(qt) = self.reach(&t, seed).map(|qt| self.move_end(q, &qt)) else { continue };
            if robot_floor_clearance(self.robot, &self.t_world_base, &qt).is_some_and(|(_, z)| z < 0.0) {
                continue;
            }
            let t_world_object = self.t_world_base * self.robot.grasp_frame_pose(&qt) * *t_palm_object;
            if floor_clearance(points, &t_world_object) >= MIN_FLOOR_CLEARANCE {
                return Some(qt);
            }
            arm_clear.get_or_insert(qt);
        }
        arm_clear
    }

    /// Physics steps of the arm's path from `from` to `to` stretched to the joints' speed limits:
    /// `move_seconds`, or, with `arm_speed_limits`, as many more as keep every joint within its
    /// limit (a snapshot's move, and an episode's wrist turn within its pivoting window).
    pub(super) fn stretched_path_steps(&self, from: &[f64], to: &[f64]) -> usize {
        let steps = self.steps(self.config.move_seconds);
        if !self.config.arm_speed_limits {
            return steps;
        }
        // Rounded up: the steps' time is at least the limits' time.
        steps.max((self.path_seconds_at_speed_limits(from, to) / self.timestep).ceil() as usize)
    }

    /// Where the arm's move from `from` towards `to` ends: at `to`, or, in an episode with
    /// `arm_speed_limits` (whose moves all take `move_seconds`: its timeline is fixed), as far
    /// along the straight joint-space line to it as every joint's speed limit allows in that time
    /// (`reach_within`): an episode's arm turns no joint faster than the real arm can and reaches
    /// a far pose over several moves.
    pub(super) fn move_end(&self, from: &[f64], to: &[f64]) -> Vec<f64> {
        if !self.config.arm_speed_limits || !self.record_steps {
            return to.to_vec();
        }
        self.reach_within(from, to, self.steps(self.config.move_seconds))
    }

    /// How far along the straight joint-space line from `from` to `to` the arm's smooth path gets
    /// in `steps` physics steps with every joint within its speed limit: `to` when it gets there.
    pub(super) fn reach_within(&self, from: &[f64], to: &[f64], steps: usize) -> Vec<f64> {
        let allowed = steps as f64 * self.timestep;
        let needed = self.path_seconds_at_speed_limits(from, to);
        if needed <= allowed {
            return to.to_vec();
        }
        let share = allowed / needed;
        from.iter().zip(to).map(|(a, b)| a + (b - a) * share).collect()
    }
}

impl Attempt<'_> {
    /// Phase 4: one arm move per instance from the settled grasp at joint values `q`.
    pub(super) fn record_instances(&mut self, mut q: Vec<f64>, held: Held) -> Result<Recorded, Stop> {
        let key = self.key;
        let mut steps = self.take_grasp_states(&held.t_palm_object);
        let mut log = self.ctx.record_steps.then_some(StepLog { steps: &mut steps, grasped: held.t_palm_object });
        // The hand's full grasp; a re-placed pad keeps its new place until a move is undone.
        let mut grasp_targets = held.targets.to_vec();
        self.turn_goal = self.turn_target_deg.map(|target| (rot(&self.physics.object_pose()), target.to_radians()));
        if let Some(log) = log.as_mut() {
            log.push(self.ctx, &*self.physics, &q);
        }
        for instance in self.first_instance..key.instances {
            let sample_key = SampleKey { seed: key.seed, object_id: key.object_id, trajectory: key.trajectory, instance };
            let mut moved = 0;
            let (obj, contacts, penetration) = loop {
                // The first move of an instance draws from `arm/<attempt>`, later ones (after a
                // pose that could not be recorded) from `arm/<attempt>/<move>`.
                let stream = if moved == 0 { format!("arm/{}", self.number) } else { format!("arm/{}/{moved}", self.number) };
                let mut arm_rng = SampleStream::sample(&sample_key, &stream);
                moved += 1;
                // A move that drops the object or ends in a pose that cannot be recorded is undone
                // (the arm then only takes moves that keep a recordable grasp): redoing one move
                // costs far less than a fresh grasp and every instance before it.
                let before = self.physics.save();
                let move_start = self.physics.steps_taken();
                let (q_before, targets_before) = (q.clone(), grasp_targets.clone());
                let logged = log.as_ref().map_or(0, |l| l.steps.len());
                // Why this move cannot stand: the attempt's failure if it was the last try, and
                // the redo counted otherwise.
                let (failure, redo) = match self.move_and_settle(&mut q, &mut arm_rng, &mut grasp_targets, log.as_mut())? {
                    MoveOutcome::Recordable(obj, contacts, penetration) => break (obj, contacts, penetration),
                    MoveOutcome::Failed(Failure::LostDuringMotion) => (Failure::LostDuringMotion, Redo::Drop),
                    MoveOutcome::Failed(f) => return Err(f.into()),
                    MoveOutcome::NotRecordable(f @ Failure::Penetration) => (f, Redo::Penetration),
                    MoveOutcome::NotRecordable(f @ Failure::TouchesFloor) => (f, Redo::Floor),
                    MoveOutcome::NotRecordable(f) => (f, Redo::Contacts),
                };
                if moved >= MAX_MOVES_PER_INSTANCE {
                    return Err(failure.into());
                }
                self.log.events.push(GraspEvent::Redone(redo));
                self.redone_steps += self.physics.steps_taken() - move_start;
                self.physics.restore(&before);
                q = q_before;
                grasp_targets = targets_before;
                if let Some(log) = log.as_mut() {
                    log.steps.truncate(logged);
                }
            };
            self.instances.push(instance_state(self.ctx, &*self.physics, &q, obj, held.t_palm_object, contacts, penetration));
            self.recorded_at = (self.physics.steps_taken(), self.redone_steps);
        }
        Ok((std::mem::take(&mut self.instances), steps))
    }

    /// One arm move from `q`, in its steps: draw a reachable palm pose, follow the path and hold,
    /// the finger motion, wait out the squeeze, check the instance. `q` becomes the target.
    fn move_and_settle(
        &mut self,
        q: &mut Vec<f64>,
        arm_rng: &mut ChaCha8Rng,
        grasp_targets: &mut Vec<f64>,
        mut log: Option<&mut StepLog>,
    ) -> Result<MoveOutcome> {
        let Some(mut q_target) = self.draw_move_target(q, arm_rng) else {
            return Ok(MoveOutcome::Failed(Failure::Unreachable));
        };
        // The path's steps up to its end count as the move, the rest as the hold.
        let path_steps = self.ctx.path_steps(q, &q_target) as u64;
        let start = self.physics.steps_taken();
        let followed = self.follow_path(q, &q_target, log.as_deref_mut());
        let steps = self.physics.steps_taken() - start;
        self.log.steps.add(Phase::ArmMove, steps.min(path_steps));
        self.log.steps.add(Phase::Hold, steps - steps.min(path_steps));
        if !followed {
            return Ok(MoveOutcome::Failed(Failure::LostDuringMotion));
        }
        let in_hand = self.counted(Phase::InHand, |a| {
            if a.swing_fingers(&q_target, grasp_targets, log.as_deref_mut())
                && a.roll_fingers(&q_target, grasp_targets, arm_rng, log.as_deref_mut())
            {
                a.pivot(&mut q_target, grasp_targets, arm_rng, log.as_deref_mut())
            } else {
                Pivoted::Dropped
            }
        });
        match in_hand {
            Pivoted::Held => {}
            Pivoted::Dropped => return Ok(MoveOutcome::Failed(Failure::LostDuringMotion)),
            Pivoted::NoPinch => return Ok(MoveOutcome::Failed(Failure::NoPinch)),
        }
        *q = q_target;
        let touching = self.physics.touch_contacts().iter().filter(|c| c.is_some()).count();
        if lost(&*self.physics) || touching == 0 {
            return Ok(MoveOutcome::Failed(Failure::LostDuringMotion));
        }
        if touching < self.ctx.robot.min_touching {
            return Ok(MoveOutcome::NotRecordable(Failure::TooFewContacts));
        }
        let penetration = self.counted(Phase::Squeeze, |a| a.wait_out_squeeze(q, log));
        Ok(self.check_instance(q, penetration))
    }

    /// A palm pose the arm reaches from `q` without putting a link under the floor, nor the held
    /// object where it lies in the palm now (`GraspContext::draw_move_target`).
    fn draw_move_target(&self, q: &[f64], arm_rng: &mut ChaCha8Rng) -> Option<Vec<f64>> {
        self.ctx.draw_move_target(q, &self.physics.object_pose(), &self.object.points, arm_rng)
    }

    /// The move along the smooth joint-space path from `q_from` to `q_target`, then the hold: the
    /// palm's acceleration enters as apparent gravity. The hold lasts `hold_seconds`, or (snapshots,
    /// `grasp.hold_until_still`) until the object has stopped in the hand. False when the object
    /// falls out of the hand.
    pub(super) fn follow_path(&mut self, q_from: &[f64], q_target: &[f64], log: Option<&mut StepLog>) -> bool {
        let n = self.ctx.path_steps(q_from, q_target);
        self.follow_path_to_goal(q_from, q_target, n, false, log).is_some()
    }

    /// `follow_path` over `n` steps of path; with `stop_at_goal`, the arm stops where it is on the
    /// path once the object has turned the episode's turn target in the hand, and holds there for
    /// the rest of the move's steps. The arm's joints where it stopped (`q_target` when it did
    /// not); None when the object falls out of the hand.
    pub(super) fn follow_path_to_goal(
        &mut self,
        q_from: &[f64],
        q_target: &[f64],
        n: usize,
        stop_at_goal: bool,
        mut log: Option<&mut StepLog>,
    ) -> Option<Vec<f64>> {
        let goal = self.turn_goal.filter(|_| stop_at_goal);
        let (ctx, physics) = (self.ctx, &mut *self.physics);
        let ds = 1.0 / n as f64;
        // Episodes keep every hold whole: each move takes the same steps.
        let mut still = (ctx.config.hold_until_still && !ctx.record_steps).then(|| StillWatch::new(ctx));
        let mut stopped_at = None;
        for k in 1..=n + ctx.steps(ctx.config.hold_seconds) {
            let s = stopped_at.unwrap_or((k as f64 * ds).min(1.0));
            physics.set_gravity(ctx.gravity_on_path(q_from, q_target, s, (k <= n && stopped_at.is_none()).then_some(ds)));
            physics.step();
            if let Some(log) = log.as_deref_mut() {
                log.push(ctx, &*physics, &along_path(q_from, q_target, s));
            }
            // An object this far from the palm has fallen out of the hand and cannot come back:
            // the move's outcome is known, and the rest of it (up to 0.7 s) would simulate the
            // fall. (Same outcome, same bytes: the failed move is undone and the next draws from
            // its own random stream.)
            if lost(&*physics) {
                return None;
            }
            if stopped_at.is_none() && goal.is_some_and(|g| turn_left_to(g, &physics.object_pose()) <= 0.0) {
                stopped_at = Some(s);
            }
            if k > n
                && let Some(watch) = still.as_mut()
                && watch.stopped(physics.object_pose(), k - n)
            {
                break;
            }
        }
        Some(stopped_at.map_or_else(|| q_target.to_vec(), |s| along_path(q_from, q_target, s)))
    }

    /// The scripted finger motion (episodes), the arm still at `q` (apparent gravity as in the
    /// hold), then the grasp's targets again. False when the object falls out of the hand.
    fn swing_fingers(&mut self, q: &[f64], grasp_targets: &[f64], mut log: Option<&mut StepLog>) -> bool {
        let (ctx, physics) = (self.ctx, &mut *self.physics);
        let Some(gait) = &ctx.finger_gait else { return true };
        let start = physics.joint_positions();
        for k in 1..=gait.steps {
            let targets = gait.targets(grasp_targets, &start, k as f64 * ctx.timestep);
            if !self.step_hand(&targets, grasp_targets, q, log.as_deref_mut()) {
                return false;
            }
        }
        self.physics.set_targets(grasp_targets);
        true
    }

    /// One physics step of the in-hand motions (episodes), the arm still at `q` and the hand's
    /// joints at `targets`, logged. False when the object falls out of the hand: the hand's
    /// targets are then the grasp's again.
    pub(super) fn step_hand(&mut self, targets: &[f64], grasp_targets: &[f64], q: &[f64], log: Option<&mut StepLog>) -> bool {
        let physics = &mut *self.physics;
        physics.set_targets(targets);
        physics.step();
        if let Some(log) = log {
            log.push(self.ctx, &*physics, q);
        }
        if lost(&*physics) {
            physics.set_targets(grasp_targets);
            return false;
        }
        true
    }

    /// Squeezing transients settle within a few tens of milliseconds: waits for them (an episode
    /// waits out the whole window, so that every move takes the same time). The deepest
    /// penetration after the wait.
    fn wait_out_squeeze(&mut self, q: &[f64], mut log: Option<&mut StepLog>) -> f64 {
        let (ctx, physics) = (self.ctx, &mut *self.physics);
        let mut penetration = physics.max_penetration();
        for _ in 0..PENETRATION_WAITS {
            if penetration <= ctx.config.max_penetration && log.is_none() {
                break;
            }
            for _ in 0..ctx.steps(PENETRATION_WAIT_SECONDS) {
                physics.step();
                if let Some(log) = log.as_deref_mut() {
                    log.push(ctx, &*physics, q);
                }
            }
            penetration = physics.max_penetration();
        }
        penetration
    }

    /// Whether the grasp at `q` (after the wait) is a recordable instance: shallow enough, touched
    /// by enough touch links, the object hanging free above the floor and no link under it.
    fn check_instance(&self, q: &[f64], penetration: f64) -> MoveOutcome {
        let (ctx, physics) = (self.ctx, &*self.physics);
        let robot = ctx.robot;
        if penetration > ctx.config.max_penetration {
            return MoveOutcome::NotRecordable(Failure::Penetration);
        }
        let obj = physics.object_pose();
        let contacts = physics.touch_contacts();
        if contacts.iter().filter(|c| c.is_some()).count() < robot.min_touching {
            return MoveOutcome::NotRecordable(Failure::TooFewContacts);
        }
        // The object must hang free: its lowest point above the floor (z = 0); and no link of the
        // robot may be under the floor (a real arm would have hit it).
        if floor_clearance(&self.object.points, &(ctx.t_world_base * robot.grasp_frame_pose(q) * obj)) < MIN_FLOOR_CLEARANCE {
            return MoveOutcome::NotRecordable(Failure::TouchesFloor);
        }
        let mut q_now = q.to_vec();
        robot.set_hand(&mut q_now, &physics.joint_positions());
        if robot_floor_clearance(robot, &ctx.t_world_base, &q_now).is_some_and(|(_, z)| z < 0.0) {
            return MoveOutcome::NotRecordable(Failure::TouchesFloor);
        }
        MoveOutcome::Recordable(obj, contacts, penetration)
    }
}

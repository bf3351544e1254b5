//! The paper's grasp loop (Algorithm 1), one trajectory at a time: place the object against the
//! palm at a random orientation, random preshape, close the fingers under PD control, check the
//! grasp holds, then move the arm to a new random palm pose for every instance (a simulated
//! joint-space path, so the object may slip or turn), let it settle and record. A failed attempt
//! (dropped object, fewer touch links in contact than the robot's `min_touching`, object lost
//! during motion) is retried with
//! fresh randomness from the same trajectory stream; attempts are counted.
//!
//! One file per step: [`context`] (what the loop knows besides the physics, and the grasp-frame
//! samplers), [`placement`] (the object into the open hand, one way per grasp kind), [`phases`]
//! (close the hand, settle the grasp), [`screen`] (the optional hold screen of a settled grasp),
//! [`arm_move`] (the instances: one arm move each, undone and redrawn when it cannot be recorded),
//! [`floor`] (heights above the floor), [`outcome`] (what the loop counts) and [`ledger`] (where
//! its physics steps go).

mod approach;
mod arm_move;
mod context;
mod finger_roll;
mod floor;
mod ledger;
mod outcome;
mod phases;
mod pivot;
mod placement;
mod repinch;
mod screen;
#[cfg(test)]
mod tests;

use anyhow::Result;
use glam::{DAffine3, DMat3, DQuat, DVec3};
use rand::Rng;
use vt_randomizers::SampleStream;

pub use context::{Approach, FingerGait, GraspContext, MIN_REACHABLE_SHARE, REACH_SAMPLES, TrajectoryKey, reach_samples, reachable_share};
pub use finger_roll::RollControl;
pub use floor::{floor_clearance, robot_floor_clearance};
pub use ledger::{GraspLog, Phase, ScreenJudged, StepLedger};
pub use outcome::{Failure, GraspEvent, InHandEnd, Redo};
pub use pivot::PivotControl;
pub use screen::HoldScreen;

use crate::physics::{HandPhysics, PhysicsObject};
use placement::Placement;

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
    /// With `GraspContext::record_contact_forces`: the hand's contacts with the object and their
    /// forces (palm frame), where the backend gives them (`HandPhysics::hand_contacts`).
    pub hand_contacts: Option<Vec<crate::physics::HandContact>>,
}

impl InstanceState {
    /// Sets the slip: the object's motion in the palm since the grasp settled at `grasped`.
    fn count_slip_from(&mut self, grasped: &DAffine3) {
        let rel = grasped.inverse() * self.t_palm_object;
        self.slip_translation = rel.translation.length();
        self.slip_rotation = rot(&rel).angle_between(DQuat::IDENTITY);
    }
}

/// What a held attempt recorded: its instances and (episodes) its steps.
type Recorded = (Vec<InstanceState>, Vec<InstanceState>);

#[derive(Debug, Clone)]
pub struct Trajectory {
    pub instances: Vec<InstanceState>,
    /// Attempts it took (1 = the first grasp held through every instance).
    pub attempts: u32,
    /// Per instance, the attempt (1-based) whose grasp recorded it: all `attempts` unless
    /// `grasp.regrasp_on_loss` kept the instances of grasps lost before.
    pub instance_grasps: Vec<u32>,
    /// With `GraspContext::record_steps`: the state at the settled grasp, then after every
    /// physics step of the recorded arm moves (`1 + instances * GraspContext::move_steps` states),
    /// after the `settled_step` states of the grasp itself before it (`sampling.record.grasp`); else empty.
    pub steps: Vec<InstanceState>,
    /// The index in `steps` of the settled grasp (`GraspContext::recorded_grasp_steps`).
    pub settled_step: usize,
    /// The episode's turn target (degrees), with `sampling.record.turn_target_deg`.
    pub turn_target_deg: Option<f64>,
}

const GRAVITY: DVec3 = DVec3::new(0.0, 0.0, -9.81);
/// Gravity in the palm frame while the palm faces straight up (its normal is +x).
const PALM_UP_GRAVITY: DVec3 = DVec3::new(-9.81, 0.0, 0.0);

/// The neutral palm orientation (world). Palm frame: +x palmar normal, +z along the fingers.
/// Neutral: palm up (x -> world z), fingers towards the camera side (z -> world -y), so the arm
/// stays behind the hand.
pub fn palm_up() -> DQuat {
    DQuat::from_mat3(&DMat3::from_cols(DVec3::Z, DVec3::NEG_X, DVec3::NEG_Y))
}

fn rot(t: &DAffine3) -> DQuat {
    DQuat::from_mat3(&t.matrix3).normalize()
}

/// The turn (rad) left to a turn goal (the orientation it counts from, the target) with the object
/// at `pose` (palm frame); at most 0 once reached.
fn turn_left_to((from, target): (DQuat, f64), pose: &DAffine3) -> f64 {
    target - from.angle_between(rot(pose))
}

/// Distance (m) from the palm at which an object is lost from the hand (a move's end check; the
/// settle and the moves stop as soon as the object is this far).
const LOST_DISTANCE: f64 = 0.25;

/// Whether the object has fallen `LOST_DISTANCE` from the palm (out of the hand for good).
fn lost(physics: &dyn HandPhysics) -> bool {
    physics.object_pose().translation.length() > LOST_DISTANCE
}

/// Why an attempt stopped short of a trajectory: the grasp failed (the loop tries again with
/// fresh randomness) or the run cannot go on (an error, returned as is).
enum Stop {
    Failed(Failure),
    Error(anyhow::Error),
}

impl From<Failure> for Stop {
    fn from(f: Failure) -> Self {
        Stop::Failed(f)
    }
}

impl From<anyhow::Error> for Stop {
    fn from(e: anyhow::Error) -> Self {
        Stop::Error(e)
    }
}

/// One attempt at a trajectory: what its phases read, and the physics they step.
struct Attempt<'a> {
    ctx: &'a GraspContext<'a>,
    physics: &'a mut dyn HandPhysics,
    object: &'a PhysicsObject,
    key: TrajectoryKey<'a>,
    /// 0 for the first attempt: names its random streams (`grasp/<n>`, `arm/<n>…`).
    number: u32,
    /// Where the events and the physics steps are counted.
    log: &'a mut GraspLog,
    /// This attempt's steps in moves it undid, and in the hold screen's probes.
    redone_steps: u64,
    screen_steps: u64,
    /// The trajectory's instance this attempt records first: 0, or (`grasp.regrasp_on_loss`)
    /// the instances lost grasps recorded before it.
    first_instance: u32,
    /// The instances this attempt recorded so far, and the physics' step count and this
    /// attempt's redone steps when it recorded the last of them.
    instances: Vec<InstanceState>,
    recorded_at: (u64, u64),
    /// The hold screen's verdict, when it ran as a judge.
    screen_verdict: Option<bool>,
    /// The episode's turn target (degrees, `sampling.record.turn_target_deg`), drawn once per
    /// trajectory.
    turn_target_deg: Option<f64>,
    /// The object's orientation in the palm at the settled grasp and the turn target (rad) from
    /// it, once the arm moves begin.
    turn_goal: Option<(DQuat, f64)>,
    /// Recording the grasp (`GraspContext::recorded_grasp_steps`): the arm's joints holding the
    /// palm up over the grasp's position, and the states since the object was put in the hand.
    grasp_recording: Option<GraspRecording>,
}

/// The grasp as an episode records it, while it is made.
struct GraspRecording {
    q_palm_up: Vec<f64>,
    /// With an approach: the arm's joints where it starts, the palm back along its normal.
    q_approach: Option<Vec<f64>>,
    states: Vec<InstanceState>,
}

/// A trajectory whose grasp never held: the object's fault, not the run's, so `generate` finishes
/// the other shards before it reports it.
#[derive(Debug)]
pub struct NoGraspHeld(pub String);

impl std::fmt::Display for NoGraspHeld {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for NoGraspHeld {}

/// Simulates a trajectory and returns its recorded instances: attempts with fresh randomness
/// until one grasp holds through every instance, or `max_attempts` is spent.
pub fn simulate_trajectory(
    ctx: &GraspContext,
    physics: &mut dyn HandPhysics,
    object: &PhysicsObject,
    key: TrajectoryKey,
    log: &mut GraspLog,
) -> Result<Trajectory> {
    let cfg = ctx.config;
    let placement = Placement::of(ctx.robot.kind, object)?;
    let mut last = None;
    let mut no_pinch = 0u32;
    let turn_target_deg = ctx.turn_target_deg(&key);
    // The instances of lost grasps kept (`regrasp_on_loss`), and per instance its grasp.
    let (mut kept, mut instance_grasps) = (Vec::new(), Vec::new());
    for number in 0..cfg.max_attempts {
        let start = physics.steps_taken();
        let mut attempt = Attempt {
            ctx,
            physics: &mut *physics,
            object,
            key,
            number,
            log: &mut *log,
            redone_steps: 0,
            screen_steps: 0,
            first_instance: kept.len() as u32,
            instances: Vec::new(),
            recorded_at: (start, 0),
            screen_verdict: None,
            turn_target_deg,
            turn_goal: None,
            grasp_recording: None,
        };
        let outcome = attempt.run(&placement);
        let (redone, screened) = (attempt.redone_steps, attempt.screen_steps);
        let (recorded, (recorded_at, redone_then)) = (std::mem::take(&mut attempt.instances), attempt.recorded_at);
        if let Some(passed) = attempt.screen_verdict {
            log.steps.screen_judged.count(passed, outcome.is_ok());
        }
        let spent = physics.steps_taken() - start;
        match outcome {
            Ok((instances, steps)) => {
                log.steps.redone_moves += redone;
                log.steps.kept += spent - redone - screened;
                instance_grasps.resize(instance_grasps.len() + instances.len(), number + 1);
                kept.extend(instances);
                let settled_step = ctx.recorded_grasp_steps;
                return Ok(Trajectory { instances: kept, attempts: number + 1, instance_grasps, steps, settled_step, turn_target_deg });
            }
            Err(Stop::Failed(f)) => {
                log.steps.instances_before_failure += recorded.len() as u64;
                // A lost grasp's instances stay, with the steps that made them, when asked.
                let made = if cfg.regrasp_on_loss && !recorded.is_empty() { recorded_at - start } else { 0 };
                if made > 0 {
                    log.steps.redone_moves += redone_then;
                    log.steps.kept += made - redone_then - screened;
                    instance_grasps.resize(instance_grasps.len() + recorded.len(), number + 1);
                    kept.extend(recorded);
                }
                log.steps.failed_attempts += spent - made;
                log.events.push(GraspEvent::Failed(f));
                last = Some(f);
                no_pinch += u32::from(f == Failure::NoPinch);
            }
            Err(Stop::Error(e)) => return Err(e),
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
    // Grasps given up for want of a pinch are held grasps: say how to keep them.
    let why = if no_pinch > 0 {
        format!(
            "{why}; {no_pinch} held but had no pinch to pivot from: sampling.record.pivot.require_pinch: false keeps such \
             episodes unturned"
        )
    } else {
        why
    };
    Err(NoGraspHeld(format!(
        "{} trajectory {}: no grasp held in {} attempts ({why}). `vtgen grasps CONFIG` shows per object how often grasps hold; \
         leave the object out of `objects`, widen robot.grasp (preshape, workspace) or raise robot.grasp.max_attempts, then rerun \
         with --resume: the complete shards are kept",
        key.object_id, key.trajectory, cfg.max_attempts
    ))
    .into())
}

impl Attempt<'_> {
    /// The attempt, in its phases: reach the grasp pose, put the object in the open hand, close
    /// the fingers, settle while the palm turns to its pose, then record the instances (arm moves).
    fn run(&mut self, placement: &Placement) -> Result<Recorded, Stop> {
        let (ctx, key) = (self.ctx, self.key);
        let rng = &mut SampleStream::trajectory(key.seed, key.object_id, key.trajectory, &format!("grasp/{}", self.number));
        let t_world_palm = ctx.sample_palm(rng);
        let q = ctx.reach(&t_world_palm, &ctx.home()).ok_or(Failure::Unreachable)?;
        let pre: Vec<f64> = ctx.config.preshape.iter().map(|&(lo, hi)| rng.random_range(lo..=hi)).collect();
        if ctx.recorded_grasp_steps > 0 {
            // Recorded, the grasp is made as a robot would make it: the palm up over the grasp's
            // position while the object is put in and the fingers close, then the wrist turning to
            // the grasp pose (the palm's orientation turned by the least rotation to face up).
            let r = rot(&t_world_palm);
            let up = DAffine3::from_rotation_translation(DQuat::from_rotation_arc(r * DVec3::X, DVec3::Z) * r, t_world_palm.translation);
            let q_palm_up = ctx.reach(&up, &q).ok_or(Failure::Unreachable)?;
            let q_approach = ctx.approach.map(|a| ctx.approach_start(&up, &q_palm_up, a).ok_or(Failure::Unreachable)).transpose()?;
            self.grasp_recording = Some(GraspRecording { q_palm_up, q_approach, states: Vec::new() });
        }
        self.counted(Phase::Place, |a| a.place(placement, rng, &pre))?;
        let grasp_targets = self.counted(Phase::Close, |a| a.close_hand(&pre));
        let (grasped, q_settled) = self.counted(Phase::Settle, |a| a.settle(&t_world_palm, &q))?;
        // A recorded grasp's wrist turn may stop short of the drawn pose (speed limits).
        let t_world_palm = if q_settled == q { t_world_palm } else { ctx.t_world_base * ctx.robot.grasp_frame_pose(&q_settled) };
        let q = q_settled;
        let held = Held { t_palm_object: grasped, targets: &grasp_targets };
        self.screen(&held, &t_world_palm)?;
        self.record_instances(q, held)
    }

    /// One physics step of the grasp before it settled; recording the grasp, the state after it
    /// is logged with the arm's joints at `q_arm` (None: holding the palm up).
    fn grasp_step(&mut self, q_arm: Option<&[f64]>) {
        self.physics.step();
        self.log_grasp_state(q_arm);
    }

    /// Recording the grasp: logs the state now with the arm's joints at `q_arm` (None: holding the
    /// palm up).
    fn log_grasp_state(&mut self, q_arm: Option<&[f64]>) {
        let Some(rec) = self.grasp_recording.as_mut() else { return };
        let physics = &*self.physics;
        let q = q_arm.unwrap_or(&rec.q_palm_up);
        let state = arm_move::instance_state(
            self.ctx,
            physics,
            q,
            physics.object_pose(),
            DAffine3::IDENTITY,
            physics.touch_contacts(),
            physics.max_penetration(),
        );
        rec.states.push(state);
    }

    /// Recording the grasp: its states once it has settled at `held` (palm frame), the settled
    /// state itself left out (the arm moves' log starts with it), the earliest ones dropped so
    /// that `GraspContext::recorded_grasp_steps` remain, their slip counted from `held`.
    fn take_grasp_states(&mut self, held: &DAffine3) -> Vec<InstanceState> {
        let Some(rec) = self.grasp_recording.take() else { return Vec::new() };
        let mut states = rec.states;
        states.pop();
        let keep = self.ctx.recorded_grasp_steps;
        debug_assert!(states.len() >= keep, "{} grasp states, {keep} to keep", states.len());
        let mut states = states.split_off(states.len().saturating_sub(keep));
        for st in &mut states {
            st.count_slip_from(held);
        }
        states
    }

    /// The turn (rad) left to the episode's target: None without one, at most 0 once reached.
    fn turn_left(&self) -> Option<f64> {
        Some(turn_left_to(self.turn_goal?, &self.physics.object_pose()))
    }

    /// Runs `f`, counting the physics steps it takes under `phase`.
    fn counted<T>(&mut self, phase: Phase, f: impl FnOnce(&mut Self) -> T) -> T {
        let start = self.physics.steps_taken();
        let out = f(self);
        let steps = self.physics.steps_taken() - start;
        self.log.steps.add(phase, steps);
        out
    }
}

/// The settled grasp the arm moves start from: the object's pose in the palm and the hand's
/// joint targets.
#[derive(Clone, Copy)]
struct Held<'a> {
    t_palm_object: DAffine3,
    targets: &'a [f64],
}

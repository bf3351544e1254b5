//! Gravity pivoting (episodes): after an arm move, the arm stands still while the grip eases until
//! the object turns under its own weight about the line between two pads, and tightens again when
//! the turn reaches a drawn target: a closed loop on the simulated rotation, repeated while the
//! window lasts (`sampling.record.pivot`). A gripper pivots between its jaws; a hand between a
//! pinch chosen before each pivot, its other fingers lifted off and placed again after it.

use glam::{DAffine3, DQuat, DVec3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::arm_move::StepLog;
use super::floor::robot_floor_clearance;
use super::{Attempt, InHandEnd, repinch, rot};
use crate::physics::antipodal::{Hull, Jaws};

/// A pivot tightens this long (s) before its target at the current turning speed: the grip takes
/// about as long to stop the turn once its targets are full again.
const TIGHTEN_LEAD_SECONDS: f64 = 0.04;
/// The jaws' targets ease from the full squeeze (1) through where they stand (0) to this much of
/// the squeeze's travel open (-) over `ease_seconds`: PD targets at the jaws' own position still
/// press the object as hard as it is deep in the pads, so the grip only lets go on the open side.
const EASED_GRIP: f64 = -0.3;
/// Faster than this (m/s) along the pads, the object slides: the grip rises. (This and
/// `TURN_SPEED` were chosen on `scenes/tiny-pivot.yaml`'s objects: 1 cm/s and 1.5 rad/s kept the
/// grip too tight to turn in a third more windows.)
const SLIDE_SPEED: f64 = 0.02;
/// Two pads may pinch when their contact normals are at least 90° apart (this cosine). 120° apart
/// found no pinch in half of the Allegro's windows, and turned the objects no further when it
/// found one.
const PINCH_FACING: f64 = 0.0;
/// The time (s) a hand's other fingers take to lift before a pivot, and to close again after it.
const LIFT_SECONDS: f64 = 0.15;
/// Faster than this (rad/s) the turn would overshoot: the grip rises.
const TURN_SPEED: f64 = 2.5;
/// Slower than this (rad/s) with the grip fully eased, the object is not turning (its centre of
/// mass hangs under the pads' line, or lies on it, or rests on the gripper).
const STILL_SPEED: f64 = 0.05;

/// `sampling.record.pivot` in physics steps.
#[derive(Debug, Clone, PartialEq)]
pub struct PivotControl {
    /// The window per arm move.
    pub steps: usize,
    /// Steps over which the grip eases from the full squeeze to `EASED_GRIP`.
    pub ease_steps: usize,
    /// Steps of full grip between two pivots and at the window's end.
    pub hold_steps: usize,
    /// Each pivot's target turn (rad), drawn uniformly from [min, max].
    pub step: (f64, f64),
    /// How far (m) the object may slide along the pads over a window.
    pub max_slide: f64,
    /// The pads the object turns between.
    pub pads: PivotPads,
    /// The grip's rise while the object slides or spins, in multiples of its easing rate.
    pub regrip_rate: f64,
    /// How often a window may place a pad of a hand's pinch again where it has none.
    pub repinches: u32,
    /// Whether a window that finds no pinch before its first pivot fails its attempt.
    pub require_pinch: bool,
}

/// The pads a pivot turns the object between.
#[derive(Debug, Clone, PartialEq)]
pub enum PivotPads {
    /// A gripper's two jaws (`Robot::pads` 0 and 1).
    Jaws,
    /// A hand's pinch, chosen before each pivot: a touching pad of `first` and one of `second` on
    /// another finger (indices in `Robot::pads`). The other fingers' closing joints open by
    /// `lift` (rad) over `lift_steps`.
    Pinch { first: Vec<usize>, second: Vec<usize>, lift: f64, lift_steps: usize },
}

impl PivotControl {
    /// The configured pivoting for `robot` at `timestep` (its pad patterns are checked at load).
    pub fn of(pivot: &crate::config::PivotConfig, robot: &vt_robot::Robot, timestep: f64) -> Self {
        let steps = |s: f64| (s / timestep).round().max(1.0) as usize;
        let matching = |pattern: &str| (0..robot.pads.len()).filter(|&p| robot.pads[p].matches(pattern)).collect();
        let pads = match &pivot.pads {
            None => PivotPads::Jaws,
            Some([a, b]) => PivotPads::Pinch {
                first: matching(a),
                second: matching(b),
                lift: pivot.lift_deg.to_radians(),
                lift_steps: steps(LIFT_SECONDS),
            },
        };
        PivotControl {
            steps: pivot.steps(timestep),
            ease_steps: steps(pivot.ease_seconds),
            hold_steps: steps(pivot.hold_seconds),
            step: (pivot.step_deg.0.to_radians(), pivot.step_deg.1.to_radians()),
            max_slide: pivot.max_slide_mm * 1e-3,
            pads,
            regrip_rate: pivot.regrip_rate,
            repinches: pivot.repinches,
            require_pinch: pivot.require_pinch,
        }
    }

    /// Where a pivot whose drawn step is `step` (rad) tightens the grip: at the step, or, with an
    /// episode's turn target of which `turn_left` (rad) is left, at what is left where that is
    /// more (within the steps' range): a window often has time for one pivot only.
    pub fn pivot_target(&self, step: f64, turn_left: Option<f64>) -> f64 {
        turn_left.map_or(step, |left| step.max(left.min(self.step.1)))
    }
}

/// A pinch: its two pads (indices in `Robot::pads`) and the hand joints lifted off while it holds
/// the object, each with the sign of its opening (towards its preshape).
struct Pinch {
    pads: [usize; 2],
    lifted: Vec<(usize, f64)>,
}

/// Whether hand joint `h` moves the link `link`: the link hangs from the joint's child.
pub(super) fn moves(robot: &vt_robot::Robot, h: usize, link: usize) -> bool {
    robot.model.is_below(link, robot.model.joints[robot.hand[h].joint].child)
}

/// Whether pads `a` and `b` (indices in `Robot::pads`) are on one finger: a hand joint moves both.
pub(super) fn on_one_finger(robot: &vt_robot::Robot, a: usize, b: usize) -> bool {
    (0..robot.hand.len()).any(|h| moves(robot, h, robot.pads[a].link) && moves(robot, h, robot.pads[b].link))
}

/// The pinch of the touching pads (`touching`, per `Robot::pads`) of `first` and `second`, on two
/// fingers (no hand joint moves both), whose contact normals face each other most, at least
/// `PINCH_FACING`; the hand joints at `hand`. A pad's contact normal is the object's surface
/// normal where the pad is (`surface_normal`, grasp frame, outward), turned into the object: on a
/// hand's rounded fingertips the pad's own normal (+z, used without `surface_normal`) is not the
/// contact's, and found no pinch in a third of the Allegro's windows. None when no two touching
/// pads face each other.
fn choose_pinch(
    robot: &vt_robot::Robot,
    hand: &[f64],
    touching: &[bool],
    first: &[usize],
    second: &[usize],
    surface_normal: Option<&dyn Fn(DVec3) -> DVec3>,
) -> Option<Pinch> {
    let m = &robot.model;
    let mut q = m.zero();
    robot.set_hand(&mut q, hand);
    let links = m.forward_kinematics(&q);
    let to_grasp = links[robot.grasp_frame].inverse();
    let normal = |p: usize| -> DVec3 {
        let frame = links[robot.pads[p].frame];
        match surface_normal {
            Some(f) => -f(to_grasp.transform_point3(frame.translation)),
            None => to_grasp.transform_vector3(frame.matrix3.z_axis),
        }
    };
    let (facing, pads) = first
        .iter()
        .flat_map(|&a| second.iter().map(move |&b| [a, b]))
        .filter(|&[a, b]| touching[a] && touching[b] && !on_one_finger(robot, a, b))
        .map(|[a, b]| (normal(a).dot(normal(b)), [a, b]))
        .min_by(|x, y| x.0.total_cmp(&y.0))?;
    if facing > PINCH_FACING {
        return None;
    }
    let lifted = (0..robot.hand.len())
        .filter(|&h| !pads.iter().any(|&p| moves(robot, h, robot.pads[p].link)))
        .filter_map(|h| Some((h, robot.hand[h].opening_sign()?)))
        .collect();
    Some(Pinch { pads, lifted })
}

/// The signed angle (rad, in (-π, π]) of `r`'s turn about the unit `axis` (its twist).
pub(super) fn twist_angle(r: DQuat, axis: DVec3) -> f64 {
    let along = DVec3::new(r.x, r.y, r.z).dot(axis);
    // The quaternion's sign is free: the half angle taken in (-π/2, π/2] gives the turn in (-π, π].
    let (along, w) = if r.w < 0.0 { (-along, -r.w) } else { (along, r.w) };
    2.0 * along.atan2(w)
}

/// The gravity the wrist turn aims at lies this much (rad) beyond the pivot's target turn from the
/// object's centre of mass, so the object is still pulled round when it gets there.
const GRAVITY_LEAD: f64 = 0.5;
/// And this much (rad) further for each pivot in a row that did not turn the object.
const STALL_LEAD: f64 = 0.4;
/// Palm orientations tried per pivot, the gravity's direction rotated about the pads' line by this
/// much (rad) more each time, before the window's pivoting ends (unreachable or under the floor).
const WRIST_TRIES: usize = 6;
const WRIST_TRY_STEP: f64 = 0.25;

/// How a pivoting window left the held object.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Pivoted {
    /// In the hand (turned or not).
    Held,
    /// Fallen out of the hand.
    Dropped,
    /// In the hand, but no pivot could begin: the hand found no pinch and placed no pad to make
    /// one (`require_pinch`). The attempt fails (`Failure::NoPinch`): another arm move from the
    /// same grasp seldom finds one.
    NoPinch,
}

impl Attempt<'_> {
    /// The pivoting window of an arm move, the arm at `q`, the hand's full squeeze at
    /// `grasp_targets`. `q` ends where the last wrist turn left the arm. Says whether the object
    /// stayed in the hand and whether any pivot could begin (`Pivoted`).
    ///
    /// Each pivot: a hand first chooses its pinch and lifts its other fingers off (a gripper's
    /// jaws are its pinch). The arm turns the wrist (a smooth joint-space move and hold, as an arm
    /// move, stretched to the joints' speed limits as a snapshot's, and stopped short where the
    /// window's time left is less) so that gravity in the palm frame lies across the pads' line,
    /// a drawn target turn plus `GRAVITY_LEAD` from the object's centre of mass, on the side away
    /// from the palm. Then the grip `g` (the pinch's targets between where they stood, 0, and the
    /// full squeeze, 1) falls at the configured easing rate, and rises `regrip_rate` times as fast
    /// (default 4) while the object slides along the pads (against where they stand now) or turns
    /// faster than `TURN_SPEED`: it hovers where the object turns but does not slip.
    /// At the target (less the turn the grip takes to stop it) the grip is full again for
    /// `hold_seconds`, a hand's lifted fingers close on the object again, and the next pivot
    /// begins. The episode's turn target, once reached, ends the window's pivoting like its last
    /// pivot's target. A hand with no pinch places a pad of the first pattern again, opposite a
    /// touching pad of the second (`repinches` times per window at most; `repinch`), and chooses
    /// again. An object that does not turn with the grip fully eased, or has slid `max_slide`
    /// along the pads, a wrist that cannot turn, or a hand with no pinch left ends the window's
    /// pivoting; the arm then holds still with the grip full. A hand with no pinch before its first
    /// pivot turns nothing: with `require_pinch` the window ends there (`Pivoted::NoPinch`).
    pub(super) fn pivot(
        &mut self,
        q: &mut Vec<f64>,
        grasp_targets: &mut Vec<f64>,
        rng: &mut ChaCha8Rng,
        mut log: Option<&mut StepLog>,
    ) -> Pivoted {
        let ctx = self.ctx;
        let Some(control) = &ctx.pivot else { return Pivoted::Held };
        let lift_steps = match control.pads {
            PivotPads::Jaws => 0,
            PivotPads::Pinch { lift_steps, .. } => lift_steps,
        };
        let centroid = self.object.points.iter().map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)).sum::<DVec3>()
            / self.object.points.len().max(1) as f64;
        // A wrist turn takes at least an arm move and its hold.
        let hold_steps = ctx.steps(ctx.config.hold_seconds);
        let turn_steps = ctx.steps(ctx.config.move_seconds) + hold_steps;
        let (mut slid, mut stalls) = (0.0, 0);
        // Every pivot of the window turns the same way, so the turns add up.
        let mut sense = None;
        // A gripper's jaws hold from the window's start.
        let window_start_q = self.physics.joint_positions();
        // The object's convex hull, for the contact normals a hand's pinch is chosen by.
        let mut hull: Option<Option<Hull>> = None;
        let mut k = 0;
        let mut ended = InHandEnd::Window;
        let mut repinched = 0;
        while k + turn_steps + control.ease_steps + control.hold_steps + 2 * lift_steps <= control.steps {
            if self.turn_left().is_some_and(|left| left <= 0.0) {
                // The episode's turn is made: the grip holds to the window's end.
                ended = InHandEnd::Target;
                break;
            }
            // The pinch and the full grip: the pinch's fingers squeezing, the others lifted.
            let (pads, full, start_q) = match &control.pads {
                PivotPads::Jaws => ([0, 1], grasp_targets.to_vec(), window_start_q.clone()),
                PivotPads::Pinch { first, second, lift, .. } => {
                    let hand = self.physics.joint_positions();
                    let contacts = self.physics.touch_contacts();
                    let touching: Vec<bool> = ctx
                        .robot
                        .pads
                        .iter()
                        .map(|pad| ctx.robot.touch_links.iter().position(|&l| l == pad.link).is_some_and(|i| contacts[i].is_some()))
                        .collect();
                    // The contact normals: the object's hull's nearest faces to the pads.
                    let hull = hull.get_or_insert_with(|| Hull::of(&self.object.points));
                    let object = self.physics.object_pose();
                    let surface_normal =
                        hull.as_ref().map(|h| move |p: DVec3| rot(&object) * h.normal_near(object.inverse().transform_point3(p)));
                    let surface_normal = surface_normal.as_ref().map(|f| f as &dyn Fn(DVec3) -> DVec3);
                    let Some(pinch) = choose_pinch(ctx.robot, &hand, &touching, first, second, surface_normal) else {
                        // A pad of the first pattern placed again, opposite a touching pad of the
                        // second, where the window has time for it and a pivot after it.
                        let transfer_steps = ctx.steps(repinch::TRANSFER_SECONDS);
                        let holding: Vec<usize> =
                            ctx.robot.touch_links.iter().zip(&contacts).filter(|(_, c)| c.is_some()).map(|(&l, _)| l).collect();
                        let room =
                            k + 2 * lift_steps + transfer_steps + turn_steps + control.ease_steps + control.hold_steps + 2 * lift_steps
                                <= control.steps;
                        let plan = (repinched < control.repinches && room)
                            .then(|| {
                                hull.as_ref().and_then(|h| repinch::plan(ctx.robot, &hand, &touching, &holding, first, second, h, &object))
                            })
                            .flatten();
                        let Some(plan) = plan else {
                            if control.require_pinch && sense.is_none() {
                                // No pivot has begun: the window would turn nothing.
                                self.log.in_hand_ended(InHandEnd::NoPinch);
                                return Pivoted::NoPinch;
                            }
                            ended = InHandEnd::NoPinch;
                            break;
                        };
                        repinched += 1;
                        self.log.repinches += 1;
                        let (mut lifted, mut clear, mut press) = (grasp_targets.clone(), grasp_targets.clone(), grasp_targets.clone());
                        for &h in &plan.chain {
                            lifted[h] = hand[h] + ctx.robot.hand[h].opening_sign().unwrap_or(0.0) * lift;
                            clear[h] = plan.clear[h];
                            press[h] = plan.press[h];
                        }
                        let placed = self.ramp_hand(q, grasp_targets, &lifted, lift_steps, grasp_targets, log.as_deref_mut())
                            && self.ramp_hand(q, &lifted, &clear, transfer_steps, grasp_targets, log.as_deref_mut())
                            && self.ramp_hand(q, &clear, &press, lift_steps, grasp_targets, log.as_deref_mut());
                        if !placed {
                            return Pivoted::Dropped;
                        }
                        k += 2 * lift_steps + transfer_steps;
                        *grasp_targets = press;
                        continue;
                    };
                    let mut full = grasp_targets.to_vec();
                    for &(h, open) in &pinch.lifted {
                        full[h] = hand[h] + open * lift;
                    }
                    if !self.ramp_hand(q, grasp_targets, &full, lift_steps, grasp_targets, log.as_deref_mut()) {
                        return Pivoted::Dropped;
                    }
                    k += lift_steps;
                    let mut start_q = self.physics.joint_positions();
                    for &(h, _) in &pinch.lifted {
                        start_q[h] = full[h];
                    }
                    (pinch.pads, full, start_q)
                }
            };
            // The line between the pads, where they stand now (palm frame).
            let jaws = Jaws::between(ctx.robot, &start_q, pads);
            let pad_reach = ctx.robot.pads[pads[0]].size.map_or(0.0, |(w, h)| 0.5 * w.hypot(h));
            let step = rng.random_range(control.step.0..=control.step.1);
            let lead = GRAVITY_LEAD + STALL_LEAD * stalls as f64;
            // The wrist puts gravity past the drawn step; the grip may hold the turn for longer.
            let target = control.pivot_target(step, self.turn_left());
            let Some(mut q_turned) = self.wrist_turn(q, &jaws, centroid, step + lead, &mut sense) else {
                ended = InHandEnd::NoWristTurn;
                if !self.ramp_hand(q, &full, grasp_targets, lift_steps, grasp_targets, log.as_deref_mut()) {
                    return Pivoted::Dropped;
                }
                k += lift_steps;
                break;
            };
            // The wrist turns within its joints' speed limits (`arm_speed_limits`), taking longer
            // than an arm move where it must, and as far as the window's time left allows (an
            // easing and a hold must follow it).
            let mut path_steps = ctx.stretched_path_steps(q, &q_turned);
            let room = control.steps.saturating_sub(k + hold_steps + control.ease_steps + control.hold_steps + lift_steps);
            if path_steps > room {
                q_turned = ctx.reach_within(q, &q_turned, room);
                path_steps = room;
            }
            let turn_steps = path_steps + hold_steps;
            self.physics.set_targets(&full);
            // The wrist turn itself may turn the object: the arm stops where the episode's turn
            // target is reached.
            let turned = self.follow_path_to_goal(q, &q_turned, path_steps, true, log.as_deref_mut());
            let Some(q_turned) = turned else { return Pivoted::Dropped };
            *q = q_turned;
            k += turn_steps;
            let mut pivot_target = Some(target);
            let used = loop {
                let budget = control.steps - control.hold_steps - lift_steps - k;
                let turned = self.turn_by(q, &start_q, &full, &jaws, pads, pad_reach, pivot_target, budget, &mut slid, log.as_deref_mut());
                let Some(used) = turned else { return Pivoted::Dropped };
                k += used.steps;
                // Full grip between pivots; a hand's lifted fingers then close on the object again.
                for _ in 0..control.hold_steps.min(control.steps - lift_steps - k) {
                    if !self.step_hand(&full, grasp_targets, q, log.as_deref_mut()) {
                        return Pivoted::Dropped;
                    }
                    k += 1;
                }
                // The grip tightens ahead of the episode's turn target by a predicted lead; where
                // it stopped the object short, the grip eases again with the wrist where it is
                // (gravity still pulls the object round), while the window has time for it.
                let short = matches!(used.end, TurnEnd::Reached) && self.turn_left().is_some_and(|left| left > 0.0);
                if !short || k + control.ease_steps + control.hold_steps + lift_steps > control.steps {
                    break used;
                }
                pivot_target = None;
            };
            if !self.ramp_hand(q, &full, grasp_targets, lift_steps, grasp_targets, log.as_deref_mut()) {
                return Pivoted::Dropped;
            }
            k += lift_steps;
            match used.end {
                TurnEnd::Reached => stalls = 0,
                // Held where it is (it rests on the gripper, or its centre of mass hangs near the
                // pads' line): the next wrist turn puts gravity further round.
                TurnEnd::Still | TurnEnd::OutOfTime => stalls += 1,
                TurnEnd::Slid => {
                    ended = InHandEnd::Slid;
                    break;
                }
            }
        }
        while k < control.steps {
            if !self.step_hand(grasp_targets, grasp_targets, q, log.as_deref_mut()) {
                return Pivoted::Dropped;
            }
            k += 1;
        }
        if ended == InHandEnd::Window && self.turn_left().is_some_and(|left| left <= 0.0) {
            ended = InHandEnd::Target;
        }
        self.log.in_hand_ended(ended);
        Pivoted::Held
    }

    /// The hand's targets in a straight line from `from` to `to` over `steps` steps, the arm still
    /// at `q`. False when the object falls out of the hand.
    fn ramp_hand(
        &mut self,
        q: &[f64],
        from: &[f64],
        to: &[f64],
        steps: usize,
        grasp_targets: &[f64],
        mut log: Option<&mut StepLog>,
    ) -> bool {
        for s in 1..=steps {
            let t = s as f64 / steps as f64;
            let targets: Vec<f64> = from.iter().zip(to).map(|(a, b)| a + t * (b - a)).collect();
            if !self.step_hand(&targets, grasp_targets, q, log.as_deref_mut()) {
                return false;
            }
        }
        true
    }

    /// The arm's joints from `q` for a wrist turn that puts gravity (palm frame) across the pads'
    /// line, `swing` from the object's centre of mass (`centroid`, object frame)
    /// about it, turning the way `sense` says (+1 or -1 about the line; chosen on the window's first
    /// pivot as the side where gravity points out of the gripper, +x); the palm stays where it is
    /// and turns as little as that allows. None when no such turn is reachable above the floor.
    fn wrist_turn(&self, q: &[f64], jaws: &Jaws, centroid: DVec3, swing: f64, sense: &mut Option<f64>) -> Option<Vec<f64>> {
        let ctx = self.ctx;
        let com = self.physics.object_pose().transform_point3(centroid) - jaws.centre;
        let across = (com - jaws.axis * com.dot(jaws.axis)).normalize_or_zero();
        if across == DVec3::ZERO {
            return None;
        }
        let t_world_palm = ctx.t_world_base * ctx.robot.grasp_frame_pose(q);
        let out_of_gripper = |a: f64| (DQuat::from_axis_angle(jaws.axis, a) * across).x;
        let sign = *sense.get_or_insert(if out_of_gripper(swing) >= out_of_gripper(-swing) { 1.0 } else { -1.0 });
        for attempt in 0..WRIST_TRIES {
            let angle = sign * (swing + WRIST_TRY_STEP * attempt as f64);
            let gravity_dir = DQuat::from_axis_angle(jaws.axis, angle) * across;
            // The palm turned so that `gravity_dir` (palm frame) points down in the world.
            let down_now = rot(&t_world_palm) * gravity_dir;
            let turn = DQuat::from_rotation_arc(down_now, DVec3::NEG_Z);
            let palm = DAffine3::from_rotation_translation(turn * rot(&t_world_palm), t_world_palm.translation);
            if let Some(qt) = ctx.reach(&palm, q)
                && robot_floor_clearance(ctx.robot, &ctx.t_world_base, &qt).is_none_or(|(_, z)| z >= 0.0)
            {
                return Some(qt);
            }
        }
        None
    }

    /// One pivot with the wrist still at `q`: the grip on `pads` regulated until the object has
    /// turned `target` about the pads' line (None: a finishing turn, until the episode's turn
    /// target), for at most `budget` steps. None when the object is lost.
    #[allow(clippy::too_many_arguments)]
    fn turn_by(
        &mut self,
        q: &[f64],
        start_q: &[f64],
        grasp_targets: &[f64],
        jaws: &Jaws,
        pads: [usize; 2],
        pad_reach: f64,
        target: Option<f64>,
        budget: usize,
        slid: &mut f64,
        mut log: Option<&mut StepLog>,
    ) -> Option<Turned> {
        let ctx = self.ctx;
        let control = ctx.pivot.as_ref().expect("pivoting");
        let ease = (1.0 - EASED_GRIP) / control.ease_steps as f64;
        let start = self.physics.object_pose();
        let held_point = start.inverse().transform_point3(jaws.centre);
        let pads_centre = |physics: &dyn crate::physics::HandPhysics| Jaws::between(ctx.robot, &physics.joint_positions(), pads).centre;
        let (mut grip, mut angle, mut point, mut centre) = (1.0, 0.0, jaws.centre, pads_centre(&*self.physics));
        let mut floor_since = None;
        for k in 0..budget {
            let targets: Vec<f64> = start_q.iter().zip(grasp_targets).map(|(s, g)| s + grip * (g - s)).collect();
            if !self.step_hand(&targets, grasp_targets, q, log.as_deref_mut()) {
                return None;
            }
            let pose = self.physics.object_pose();
            // Unwrapped: the turn may pass half a turn.
            let now = twist_angle(rot(&pose) * rot(&start).inverse(), jaws.axis);
            let step = twist_angle(DQuat::from_axis_angle(jaws.axis, now - angle), jaws.axis);
            angle += step;
            let now_point = pose.transform_point3(held_point);
            let now_centre = pads_centre(&*self.physics);
            let slide = slide_along_pads((point, centre), (now_point, now_centre), jaws.axis, pad_reach, step);
            (point, centre) = (now_point, now_centre);
            *slid += slide;
            let (speed, slide_speed) = (step.abs() / ctx.timestep, slide / ctx.timestep);
            // A finishing turn (no target of its own) starts from rest and turns slowly: it stops at
            // the episode's target, not ahead of it.
            let lead = if target.is_some() { speed * TIGHTEN_LEAD_SECONDS } else { 0.0 };
            let end = if target.is_some_and(|t| angle.abs() + lead >= t) || self.turn_left().is_some_and(|left| left <= lead) {
                Some(TurnEnd::Reached)
            } else if *slid > control.max_slide {
                Some(TurnEnd::Slid)
            } else if floor_since.is_some_and(|f| k - f >= control.ease_steps / 2 && speed < STILL_SPEED) {
                Some(TurnEnd::Still)
            } else {
                None
            };
            if let Some(end) = end {
                return Some(Turned { steps: k + 1, end });
            }
            grip = if slide_speed > SLIDE_SPEED || speed > TURN_SPEED { (grip + control.regrip_rate * ease).min(1.0) } else { grip - ease };
            floor_since = if grip <= EASED_GRIP { floor_since.or(Some(k)) } else { None };
            grip = grip.max(EASED_GRIP);
        }
        Some(Turned { steps: budget, end: TurnEnd::OutOfTime })
    }
}

/// How far (m) the object slid along the pads over a step: its held point's move against the pads'
/// centre (`(point, centre)` before and now), across the pads' line `axis` only (the object shifting
/// between the pads as they ease is no slide), less what a turn of `turn` (rad) about a patch of
/// `pad_reach` explains. Against the pads where they stand now, not in the palm: a hand's fingers
/// give as the grip eases, and the object they carry with them does not slide along them.
fn slide_along_pads(before: (DVec3, DVec3), now: (DVec3, DVec3), axis: DVec3, pad_reach: f64, turn: f64) -> f64 {
    let moved = (now.0 - now.1) - (before.0 - before.1);
    let along_pads = moved - axis * moved.dot(axis);
    (along_pads.length() - pad_reach * turn.abs()).max(0.0)
}

/// How a pivot ended, and the steps it took.
struct Turned {
    steps: usize,
    end: TurnEnd,
}

enum TurnEnd {
    /// The object turned by the target.
    Reached,
    /// It did not turn with the grip fully eased.
    Still,
    /// It slid `max_slide` along the pads over the window.
    Slid,
    /// The window's time ran out.
    OutOfTime,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pivot holds on to what is left of the episode's turn target where that is more than its
    /// drawn step, within the steps' range; without a target it turns its step.
    #[test]
    fn a_pivot_holds_on_to_what_is_left_of_the_episodes_target() {
        let robot = vt_robot::Robot::builtin("ur5e_robotiq_2f85").unwrap();
        let cfg: crate::config::PivotConfig = serde_yaml::from_str("{step_deg: [20, 60]}").unwrap();
        let c = PivotControl::of(&cfg, &robot, 0.005);
        let deg = f64::to_radians;
        let at = |step: f64, left: Option<f64>| c.pivot_target(deg(step), left.map(deg)).to_degrees();
        assert!((at(30.0, None) - 30.0).abs() < 1e-9);
        assert!((at(30.0, Some(45.0)) - 45.0).abs() < 1e-9, "{}", at(30.0, Some(45.0)));
        assert!((at(30.0, Some(10.0)) - 30.0).abs() < 1e-9, "the turn left less than the step: the step");
        assert!((at(30.0, Some(100.0)) - 60.0).abs() < 1e-9, "within the steps' range: {}", at(30.0, Some(100.0)));
        assert!((at(50.0, Some(-5.0)) - 50.0).abs() < 1e-9);
    }

    /// The slide is the object's move against the pads: an object carried by a finger that gives
    /// (the Allegro's thumb opening 10°, its pad's place from the forward kinematics) has not slid,
    /// though it moved millimetres in the palm; one moving along still pads has slid that far, one
    /// shifting between them has not, and a turn about the patch explains its share.
    #[test]
    fn the_slide_is_the_objects_move_against_the_pads_where_they_stand_now() {
        let robot = vt_robot::Robot::builtin("ur5e_allegro").unwrap();
        let pad = |n: &str| robot.pads.iter().position(|p| p.name == n).unwrap();
        let pads = [pad("th_distal"), pad("mf_distal")];
        let closed: Vec<f64> = robot.hand.iter().map(|h| h.close.unwrap_or(0.5 * (h.preshape.0 + h.preshape.1))).collect();
        let mut gave = closed.clone();
        let thumb = robot.hand.iter().position(|h| h.name == "th_joint_3").unwrap();
        gave[thumb] += robot.hand[thumb].opening_sign().unwrap() * 10f64.to_radians();
        let jaws = Jaws::between(&robot, &closed, pads);
        let centre_now = Jaws::between(&robot, &gave, pads).centre;
        // The object's held point carried with the pads.
        let carried = centre_now;
        let in_palm = slide_along_pads((jaws.centre, jaws.centre), (carried, jaws.centre), jaws.axis, 0.0, 0.0);
        assert!(in_palm > 0.002, "the finger's give moves the pads' centre {:.2} mm across their line", in_palm * 1e3);
        let against_pads = slide_along_pads((jaws.centre, jaws.centre), (carried, centre_now), jaws.axis, 0.0, 0.0);
        assert!(against_pads < 1e-12, "{against_pads}");

        let across = jaws.axis.any_orthonormal_vector();
        let still = (jaws.centre, jaws.centre);
        let slid = slide_along_pads(still, (jaws.centre + 0.003 * across, jaws.centre), jaws.axis, 0.0, 0.0);
        assert!((slid - 0.003).abs() < 1e-12, "{slid}");
        let between = slide_along_pads(still, (jaws.centre + 0.003 * jaws.axis, jaws.centre), jaws.axis, 0.0, 0.0);
        assert!(between < 1e-12, "{between}");
        let turned = slide_along_pads(still, (jaws.centre + 0.003 * across, jaws.centre), jaws.axis, 0.01, 0.1);
        assert!((turned - 0.002).abs() < 1e-12, "a 0.1 rad turn about a 10 mm patch explains 1 mm: {turned}");
    }

    /// A hand's pinch: the touching pads of the two patterns on two fingers whose normals face
    /// each other most; the other fingers' closing joints lift, the pinch's fingers do not.
    #[test]
    fn a_pinch_takes_the_facing_touching_pads_of_two_fingers() {
        let robot = vt_robot::Robot::builtin("ur5e_allegro").unwrap();
        let cfg: crate::config::PivotConfig = serde_yaml::from_str("{pads: ['th_*', distal]}").unwrap();
        let c = PivotControl::of(&cfg, &robot, 0.005);
        let pad = |n: &str| robot.pads.iter().position(|p| p.name == n).unwrap();
        let hand = |n: &str| robot.hand.iter().position(|h| h.name == n).unwrap();
        let PivotPads::Pinch { first, second, lift, lift_steps } = &c.pads else { panic!("{:?}", c.pads) };
        assert_eq!(*first, vec![pad("th_proximal"), pad("th_medial"), pad("th_distal")]);
        assert_eq!(*second, vec![pad("ff_distal"), pad("mf_distal"), pad("rf_distal"), pad("th_distal")]);
        assert!((lift - 30f64.to_radians()).abs() < 1e-12 && *lift_steps == 30);
        // The hand closed on an object: the thumb opposes the fingers.
        let closed: Vec<f64> = robot.hand.iter().map(|h| h.close.unwrap_or(0.0) * 0.6).collect();
        let all = vec![true; robot.pads.len()];
        let pinch = choose_pinch(&robot, &closed, &all, first, second, None).expect("a pinch");
        assert_eq!(robot.pads[pinch.pads[0]].name.get(..3), Some("th_"));
        assert_ne!(robot.pads[pinch.pads[1]].name.get(..3), Some("th_"), "the thumb pinches against a finger, not itself");
        let [a, b] = pinch.pads;
        let finger = &robot.pads[b].name[..3];
        for (name, lifted) in
            [("th_joint_1", false), (&format!("{finger}joint_1"), false), ("ff_joint_1", finger != "ff_"), ("rf_joint_3", finger != "rf_")]
        {
            assert_eq!(pinch.lifted.iter().any(|&(h, _)| h == hand(name)), lifted, "{name} with the pinch {a} {b}");
        }
        // Closing joints open towards their preshape: the fingers' flexion the negative way.
        assert!(pinch.lifted.iter().all(|&(_, open)| open == -1.0));
        // Only touching pads pinch; a thumb touching alone has none.
        let thumb_only: Vec<bool> = robot.pads.iter().map(|p| p.name.starts_with("th_")).collect();
        assert!(choose_pinch(&robot, &closed, &thumb_only, first, second, None).is_none());
        // By the object's surface normals: an object between the thumb and the fingers (a
        // sphere about the pads' middle) is pinched, one beside them all is not.
        let links = robot.model.forward_kinematics(&{
            let mut q = robot.model.zero();
            robot.set_hand(&mut q, &closed);
            q
        });
        let to_grasp = links[robot.grasp_frame].inverse();
        let pad_at = |n: &str| to_grasp.transform_point3(links[robot.pads[pad(n)].frame].translation);
        let middle = (pad_at("th_distal") + pad_at("mf_distal")) * 0.5;
        let sphere = |c: DVec3| move |p: DVec3| (p - c).normalize();
        let between = sphere(middle);
        let pinch = choose_pinch(&robot, &closed, &all, first, second, Some(&between)).expect("a pinch across the sphere");
        let [a, b] = pinch.pads.map(|p| pad_at(&robot.pads[p].name));
        assert!((a - middle).normalize().dot((b - middle).normalize()) <= PINCH_FACING, "{a} {b} about {middle}");
        let aside = sphere(middle + (pad_at("th_distal") - middle) * 20.0);
        assert!(choose_pinch(&robot, &closed, &all, first, second, Some(&aside)).is_none());
        // A gripper's pads are its jaws.
        let gripper = vt_robot::Robot::builtin("ur5e_robotiq_2f85").unwrap();
        assert_eq!(PivotControl::of(&crate::config::PivotConfig::default(), &gripper, 0.005).pads, PivotPads::Jaws);
    }

    #[test]
    fn the_twist_angle_is_the_turn_about_the_axis_alone() {
        let axis = DVec3::new(0.0, 1.0, 0.0);
        for deg in [-170.0f64, -45.0, 0.0, 30.0, 120.0] {
            let about = DQuat::from_axis_angle(axis, deg.to_radians());
            assert!((twist_angle(about, axis).to_degrees() - deg).abs() < 1e-9, "{deg}");
            // A swing about a perpendicular axis first leaves the twist alone.
            let swung = DQuat::from_axis_angle(DVec3::X, 0.3) * about;
            assert!((twist_angle(swung, axis).to_degrees() - deg).abs() < 3.0, "{deg} with a swing");
        }
        assert!(twist_angle(DQuat::from_rotation_x(1.0), axis).abs() < 1e-12);
    }
}

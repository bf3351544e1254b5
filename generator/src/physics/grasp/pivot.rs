//! Gravity pivoting (episodes, parallel-jaw grippers): after an arm move, the arm stands still
//! while the grip eases until the object turns under its own weight about the line between the
//! pads, and tightens again when the turn reaches a drawn target: a closed loop on the simulated
//! rotation, repeated while the window lasts (`sampling.record.pivot`).

use glam::{DAffine3, DQuat, DVec3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::arm_move::StepLog;
use super::floor::robot_floor_clearance;
use super::{Attempt, InHandEnd, rot};
use crate::physics::antipodal::Jaws;

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
/// The object may slide this far (m) along the pads in a window: then the grip stays full.
const SLIDE_BUDGET: f64 = 0.015;
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
}

impl PivotControl {
    pub fn of(pivot: &crate::config::PivotConfig, timestep: f64) -> Self {
        let steps = |s: f64| (s / timestep).round().max(1.0) as usize;
        PivotControl {
            steps: pivot.steps(timestep),
            ease_steps: steps(pivot.ease_seconds),
            hold_steps: steps(pivot.hold_seconds),
            step: (pivot.step_deg.0.to_radians(), pivot.step_deg.1.to_radians()),
        }
    }
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

impl Attempt<'_> {
    /// The pivoting window of an arm move, the arm at `q`, the gripper's full squeeze at
    /// `grasp_targets`. `q` ends where the last wrist turn left the arm. False when the object
    /// falls out of the hand.
    ///
    /// Each pivot: the arm turns the wrist (a smooth joint-space move and hold, as an arm move) so
    /// that gravity in the palm frame lies across the pads' line, a drawn target turn plus
    /// `GRAVITY_LEAD` from the object's centre of mass, on the side away from the gripper. Then the
    /// grip `g` (the jaws' targets between where they stood, 0, and the full squeeze, 1) falls at
    /// the configured easing rate, and rises four times as fast while the object slides along the
    /// pads or turns faster than `TURN_SPEED`: it hovers where the object turns but does not slip.
    /// At the target (less the turn the grip takes to stop it) the grip is full again for
    /// `hold_seconds`, and the next pivot begins. The episode's turn target, once reached, ends the
    /// window's pivoting like its last pivot's target. An object that does not turn with the grip fully
    /// eased, or has slid `SLIDE_BUDGET` along the pads, or a wrist that cannot turn, ends the
    /// window's pivoting; the arm then holds still with the grip full.
    pub(super) fn pivot(&mut self, q: &mut Vec<f64>, grasp_targets: &[f64], rng: &mut ChaCha8Rng, mut log: Option<&mut StepLog>) -> bool {
        let ctx = self.ctx;
        let Some(control) = &ctx.pivot else { return true };
        let start_q = self.physics.joint_positions();
        // The line between the pads, where the jaws stand now (palm frame).
        let jaws = Jaws::of(ctx.robot, &start_q);
        let pad_reach = ctx.robot.pads[0].size.map_or(0.0, |(w, h)| 0.5 * w.hypot(h));
        let centroid = self.object.points.iter().map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)).sum::<DVec3>()
            / self.object.points.len().max(1) as f64;
        let turn_steps = ctx.steps(ctx.config.move_seconds) + ctx.steps(ctx.config.hold_seconds);
        let (mut slid, mut stalls) = (0.0, 0);
        // Every pivot of the window turns the same way, so the turns add up.
        let mut sense = None;
        let mut k = 0;
        let mut ended = InHandEnd::Window;
        while k + turn_steps + control.ease_steps + control.hold_steps <= control.steps {
            if self.turn_left().is_some_and(|left| left <= 0.0) {
                // The episode's turn is made: the grip holds to the window's end.
                ended = InHandEnd::Target;
                break;
            }
            let target = rng.random_range(control.step.0..=control.step.1);
            let lead = GRAVITY_LEAD + STALL_LEAD * stalls as f64;
            let Some(q_turned) = self.wrist_turn(q, &jaws, centroid, target + lead, &mut sense) else {
                ended = InHandEnd::NoWristTurn;
                break;
            };
            self.physics.set_targets(grasp_targets);
            // The wrist turn itself may turn the object: the arm stops where the episode's turn
            // target is reached.
            let Some(q_turned) = self.follow_path_to_goal(q, &q_turned, true, log.as_deref_mut()) else { return false };
            *q = q_turned;
            k += turn_steps;
            let budget = control.steps - control.hold_steps - k;
            let turned = self.turn_by(q, &start_q, grasp_targets, &jaws, pad_reach, target, budget, &mut slid, log.as_deref_mut());
            let Some(used) = turned else { return false };
            k += used.steps;
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
            // Full grip between pivots.
            for _ in 0..control.hold_steps.min(control.steps - k) {
                if !self.step_hand(grasp_targets, grasp_targets, q, log.as_deref_mut()) {
                    return false;
                }
                k += 1;
            }
        }
        while k < control.steps {
            if !self.step_hand(grasp_targets, grasp_targets, q, log.as_deref_mut()) {
                return false;
            }
            k += 1;
        }
        if ended == InHandEnd::Window && self.turn_left().is_some_and(|left| left <= 0.0) {
            ended = InHandEnd::Target;
        }
        self.log.in_hand_ended(ended);
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

    /// One pivot with the wrist still at `q`: the grip regulated until the object has turned
    /// `target` about the pads' line, for at most `budget` steps. None when the object is lost.
    #[allow(clippy::too_many_arguments)]
    fn turn_by(
        &mut self,
        q: &[f64],
        start_q: &[f64],
        grasp_targets: &[f64],
        jaws: &Jaws,
        pad_reach: f64,
        target: f64,
        budget: usize,
        slid: &mut f64,
        mut log: Option<&mut StepLog>,
    ) -> Option<Turned> {
        let ctx = self.ctx;
        let control = ctx.pivot.as_ref().expect("pivoting");
        let ease = (1.0 - EASED_GRIP) / control.ease_steps as f64;
        let start = self.physics.object_pose();
        let held_point = start.inverse().transform_point3(jaws.centre);
        let (mut grip, mut angle, mut point) = (1.0, 0.0, jaws.centre);
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
            // Along the pads only: the object shifting between them as the jaws ease is no slide.
            let moved = now_point - point;
            let along_pads = moved - jaws.axis * moved.dot(jaws.axis);
            let slide = (along_pads.length() - pad_reach * step.abs()).max(0.0);
            point = now_point;
            *slid += slide;
            let (speed, slide_speed) = (step.abs() / ctx.timestep, slide / ctx.timestep);
            let lead = speed * TIGHTEN_LEAD_SECONDS;
            let end = if angle.abs() + lead >= target || self.turn_left().is_some_and(|left| left <= lead) {
                Some(TurnEnd::Reached)
            } else if *slid > SLIDE_BUDGET {
                Some(TurnEnd::Slid)
            } else if floor_since.is_some_and(|f| k - f >= control.ease_steps / 2 && speed < STILL_SPEED) {
                Some(TurnEnd::Still)
            } else {
                None
            };
            if let Some(end) = end {
                return Some(Turned { steps: k + 1, end });
            }
            grip = if slide_speed > SLIDE_SPEED || speed > TURN_SPEED { (grip + 4.0 * ease).min(1.0) } else { grip - ease };
            floor_since = if grip <= EASED_GRIP { floor_since.or(Some(k)) } else { None };
            grip = grip.max(EASED_GRIP);
        }
        Some(Turned { steps: budget, end: TurnEnd::OutOfTime })
    }
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
    /// It slid `SLIDE_BUDGET` along the pads over the window.
    Slid,
    /// The window's time ran out.
    OutOfTime,
}

#[cfg(test)]
mod tests {
    use super::*;

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

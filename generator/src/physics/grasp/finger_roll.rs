//! The closed-loop finger roll (episodes, hands): after an arm move, the arm stands still while
//! the listed hand joints move from their grasp targets until the object has turned by a drawn
//! target about a chosen axis, then hold; step after step in the same sense, until a joint has
//! moved its most (`sampling.record.finger_roll`). With `regrasp`, the fingers are then lifted,
//! moved back and placed again one at a time, and the roll goes on: finger gaiting.

use glam::{DAffine3, DQuat, DVec3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::arm_move::StepLog;
use super::pivot::twist_angle;
use super::{Attempt, InHandEnd, rot};

/// A step stops this long (s) before its target at the current turning speed: the fingers' drives
/// take about as long to stop the object.
const STOP_LEAD_SECONDS: f64 = 0.05;
/// A turn the wrong way by this much (rad) reverses the joints' directions (once per window).
const WRONG_WAY: f64 = 0.035;

/// `sampling.record.finger_roll` resolved to hand joints and physics steps.
#[derive(Debug, Clone, PartialEq)]
pub struct RollControl {
    pub steps: usize,
    pub hold_steps: usize,
    pub axis: DVec3,
    /// Each step's target turn (rad), drawn uniformly from [min, max].
    pub step: (f64, f64),
    /// Joint speed (rad/s) and the largest move from the grasp target (rad).
    pub speed: f64,
    pub max: f64,
    /// (hand joint index, direction).
    pub joints: Vec<(usize, f64)>,
    pub regrasp: Option<Regrasp>,
}

/// `finger_roll.regrasp` resolved: how each listed joint's finger is lifted and placed again.
#[derive(Debug, Clone, PartialEq)]
pub struct Regrasp {
    /// How far the finger's other joints open (rad).
    pub lift: f64,
    /// Physics steps of the lift, the listed joint's return and the placing.
    pub phase_steps: [usize; 3],
    /// The object's motion in the palm during a lift that puts the finger back (m, rad).
    pub max_slip: f64,
    pub max_slip_angle: f64,
    /// One per listed joint, in `RollControl::joints` order.
    pub fingers: Vec<Finger>,
}

/// The finger of a listed joint.
#[derive(Debug, Clone, PartialEq)]
pub struct Finger {
    /// The finger's other hand joints that close on the object, each with the sign of its
    /// opening (towards its preshape, away from its closing target).
    pub lifting: Vec<(usize, f64)>,
    /// Its touch links (indices in `Robot::touch_links`).
    pub touch: Vec<usize>,
}

impl Regrasp {
    fn of(r: &crate::config::RegraspConfig, robot: &vt_robot::Robot, joints: &[(usize, f64)], timestep: f64) -> Self {
        let m = &robot.model;
        let child = |h: usize| m.joints[robot.hand[h].joint].child;
        let fingers = joints
            .iter()
            .map(|&(listed, _)| {
                // The finger: the hand joints on the listed joint's chain, above and below it; its
                // links hang from the highest of them.
                let chain: Vec<usize> =
                    (0..robot.hand.len()).filter(|&h| m.is_below(child(h), child(listed)) || m.is_below(child(listed), child(h))).collect();
                let top = chain.iter().copied().find(|&h| chain.iter().all(|&o| m.is_below(child(o), child(h)))).unwrap_or(listed);
                let lifting = chain.iter().filter(|&&h| h != listed).filter_map(|&h| Some((h, robot.hand[h].opening_sign()?))).collect();
                let touch = robot.touch_links.iter().enumerate().filter(|&(_, &l)| m.is_below(l, child(top))).map(|(i, _)| i).collect();
                Finger { lifting, touch }
            })
            .collect();
        Regrasp {
            lift: r.lift_deg.to_radians(),
            phase_steps: r.steps(timestep),
            max_slip: r.max_slip_mm * 1e-3,
            max_slip_angle: r.max_slip_deg.to_radians(),
            fingers,
        }
    }

    /// Physics steps one finger's re-placement takes.
    fn finger_steps(&self) -> usize {
        self.phase_steps.iter().sum()
    }
}

impl RollControl {
    /// The configured roll for `robot` at `timestep` (its joints are checked at load).
    pub fn of(roll: &crate::config::FingerRollConfig, robot: &vt_robot::Robot, timestep: f64) -> Self {
        let joints: Vec<(usize, f64)> =
            roll.joints.iter().filter_map(|j| Some((robot.hand.iter().position(|h| h.name == j.joint)?, j.direction))).collect();
        RollControl {
            steps: roll.steps(timestep),
            hold_steps: (roll.hold_seconds / timestep).round().max(1.0) as usize,
            axis: DVec3::from_array(roll.axis).normalize(),
            step: (roll.step_deg.0.to_radians(), roll.step_deg.1.to_radians()),
            speed: roll.speed_deg_s.to_radians(),
            max: roll.max_deg.to_radians(),
            regrasp: roll.regrasp.as_ref().map(|r| Regrasp::of(r, robot, &joints, timestep)),
            joints,
        }
    }
}

/// A finger's re-placement that did not happen, or was taken back.
#[derive(Debug, PartialEq)]
enum Replaced {
    Done,
    /// Not done (the finger stays, or is put back, where it was), and why the roll ends: no time
    /// left in the window, the other fingers not holding the object, or the object moving while the
    /// finger was lifted.
    Refused(InHandEnd),
    /// The object fell out of the hand.
    Lost,
}

/// The roll window's running state: its step count and the hand's targets.
struct Window<'a> {
    q: &'a [f64],
    grasp_targets: &'a [f64],
    targets: Vec<f64>,
    k: usize,
}

impl Attempt<'_> {
    /// One step of the window at its current targets. False when the object falls out of the hand.
    fn window_step(&mut self, w: &mut Window, log: Option<&mut StepLog>) -> bool {
        w.k += 1;
        self.step_hand(&w.targets, w.grasp_targets, w.q, log)
    }

    /// The finger roll's window, the arm still at `q`. False when the object falls out of the hand.
    /// The joints keep their last targets to the window's end: the turn made is kept. The episode's
    /// turn target, once reached, ends the rolling.
    pub(super) fn roll_fingers(&mut self, q: &[f64], grasp_targets: &[f64], rng: &mut ChaCha8Rng, mut log: Option<&mut StepLog>) -> bool {
        let ctx = self.ctx;
        let Some(control) = &ctx.finger_roll else { return true };
        let draw = |rng: &mut ChaCha8Rng| rng.random_range(control.step.0..=control.step.1);
        let per_step = control.speed * ctx.timestep;
        let mut w = Window { q, grasp_targets, targets: grasp_targets.to_vec(), k: 0 };
        // Each listed joint's move from its grasp target (rad, in its direction and the sense).
        let mut moved = vec![0.0f64; control.joints.len()];
        let (mut sense, mut reversed) = (1.0, false);
        // An episode whose turn target is reached rolls no more.
        let mut rolling = self.turn_left().is_none_or(|left| left > 0.0);
        let mut ended = if rolling { InHandEnd::Window } else { InHandEnd::Target };
        let last = control.steps - control.hold_steps;
        while rolling && w.k < last {
            let (target, step_start) = (draw(rng), rot(&self.physics.object_pose()));
            let mut turned = 0.0f64;
            loop {
                if w.k >= last {
                    break;
                }
                if moved.iter().any(|&m| m >= control.max) {
                    let Some(regrasp) = &control.regrasp else {
                        (rolling, ended) = (false, InHandEnd::JointRange);
                        break;
                    };
                    match self.replace_fingers(regrasp, control, &mut moved, &mut w, last, log.as_deref_mut()) {
                        Replaced::Done => continue,
                        Replaced::Refused(why) => {
                            (rolling, ended) = (false, why);
                            break;
                        }
                        Replaced::Lost => return false,
                    }
                }
                for (m, &(j, direction)) in moved.iter_mut().zip(&control.joints) {
                    *m += per_step;
                    w.targets[j] = grasp_targets[j] + sense * direction * *m;
                }
                if !self.window_step(&mut w, log.as_deref_mut()) {
                    return false;
                }
                let now = twist_angle(rot(&self.physics.object_pose()) * step_start.inverse(), control.axis);
                let speed = (now - turned).abs() / ctx.timestep;
                turned = now;
                if !reversed && now < -WRONG_WAY {
                    // The joints turn the object the other way: every direction reverses, from
                    // where they stand.
                    (sense, reversed) = (-sense, true);
                    for (m, &(j, direction)) in moved.iter_mut().zip(&control.joints) {
                        *m = if direction == 0.0 { 0.0 } else { (w.targets[j] - grasp_targets[j]) / (sense * direction) };
                    }
                    break;
                }
                let lead = speed * STOP_LEAD_SECONDS;
                if self.turn_left().is_some_and(|left| left <= lead) {
                    // The episode's turn is made: the fingers hold from here on.
                    (rolling, ended) = (false, InHandEnd::Target);
                    break;
                }
                if now.abs() + lead >= target {
                    break;
                }
            }
            for _ in 0..control.hold_steps.min(last.saturating_sub(w.k)) {
                if !self.window_step(&mut w, log.as_deref_mut()) {
                    return false;
                }
            }
        }
        while w.k < control.steps {
            if !self.window_step(&mut w, log.as_deref_mut()) {
                return false;
            }
        }
        self.log.in_hand_ended(ended);
        true
    }

    /// Moves the targets of hand joints `joints` in a straight line from where they are to `to`
    /// over `steps` steps of the window. `Some(false)` when `go_on` refuses the object's pose
    /// after a step (the targets stay there), None when the object falls out of the hand.
    fn ramp(
        &mut self,
        w: &mut Window,
        joints: &[usize],
        to: &[f64],
        steps: usize,
        mut log: Option<&mut StepLog>,
        mut go_on: impl FnMut(DAffine3) -> bool,
    ) -> Option<bool> {
        let from: Vec<f64> = joints.iter().map(|&h| w.targets[h]).collect();
        for s in 1..=steps {
            let t = s as f64 / steps as f64;
            for ((&h, a), b) in joints.iter().zip(&from).zip(to) {
                w.targets[h] = a + t * (b - a);
            }
            if !self.window_step(w, log.as_deref_mut()) {
                return None;
            }
            if !go_on(self.physics.object_pose()) {
                return Some(false);
            }
        }
        Some(true)
    }

    /// Finger gaiting: each finger whose joint has moved lifts off (its other joints open by
    /// `lift`), its listed joint returns to the grasp target and it closes again, one finger at a
    /// time. A finger is lifted only while at least `min_touching` touch links of the other
    /// fingers touch the object, and is put back at once when the object moves in the palm during
    /// its lift. Every finger placed again has its move cleared.
    fn replace_fingers(
        &mut self,
        regrasp: &Regrasp,
        control: &RollControl,
        moved: &mut [f64],
        w: &mut Window,
        last: usize,
        mut log: Option<&mut StepLog>,
    ) -> Replaced {
        let ctx = self.ctx;
        let [lift_steps, return_steps, place_steps] = regrasp.phase_steps;
        for (f, finger) in regrasp.fingers.iter().enumerate() {
            if moved[f] <= 0.0 {
                continue;
            }
            if w.k + regrasp.finger_steps() > last {
                return Replaced::Refused(InHandEnd::Window);
            }
            let contacts = self.physics.touch_contacts();
            let others = contacts.iter().enumerate().filter(|(i, c)| c.is_some() && !finger.touch.contains(i)).count();
            if others < ctx.robot.min_touching {
                return Replaced::Refused(InHandEnd::OthersNotHolding);
            }
            let (listed, _) = control.joints[f];
            let start = self.physics.object_pose();
            let joints = self.physics.joint_positions();
            let lifting: Vec<usize> = finger.lifting.iter().map(|&(h, _)| h).collect();
            let lifted: Vec<f64> = finger.lifting.iter().map(|&(h, open)| joints[h] + open * regrasp.lift).collect();
            let slipped = |pose: DAffine3| {
                let d = start.inverse() * pose;
                d.translation.length() > regrasp.max_slip
                    || DQuat::from_mat3(&d.matrix3).angle_between(DQuat::IDENTITY) > regrasp.max_slip_angle
            };
            // Lift, watching the object.
            let Some(held) = self.ramp(w, &lifting, &lifted, lift_steps, log.as_deref_mut(), |pose| !slipped(pose)) else {
                return Replaced::Lost;
            };
            if held {
                // Back to the grasp target, in the air.
                let grasp = [w.grasp_targets[listed]];
                if self.ramp(w, &[listed], &grasp, return_steps, log.as_deref_mut(), |_| true).is_none() {
                    return Replaced::Lost;
                }
                moved[f] = 0.0;
            }
            // Placed again: the lifted joints close to their grasp targets.
            let grasp: Vec<f64> = lifting.iter().map(|&h| w.grasp_targets[h]).collect();
            if self.ramp(w, &lifting, &grasp, place_steps, log.as_deref_mut(), |_| true).is_none() {
                return Replaced::Lost;
            }
            if !held {
                return Replaced::Refused(InHandEnd::FingerPutBack);
            }
        }
        Replaced::Done
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_roll_resolves_its_joints_axis_and_rates() {
        let robot = vt_robot::Robot::builtin("ur5e_allegro").unwrap();
        let cfg: crate::config::FingerRollConfig =
            serde_yaml::from_str("{axis: [2, 0, 0], joints: [{joint: ff_joint_0, direction: -1}, {joint: th_joint_0}]}").unwrap();
        let c = RollControl::of(&cfg, &robot, 0.005);
        assert_eq!(c.steps, 400);
        assert_eq!(c.axis, DVec3::X);
        let ff = robot.hand.iter().position(|h| h.name == "ff_joint_0").unwrap();
        let th = robot.hand.iter().position(|h| h.name == "th_joint_0").unwrap();
        assert_eq!(c.joints, vec![(ff, -1.0), (th, 1.0)]);
        assert!((c.speed - 30f64.to_radians()).abs() < 1e-12);
        assert_eq!(c.regrasp, None);
    }

    /// Each listed joint's finger, from the kinematics alone: the hand joints on its chain that
    /// close (opening towards their preshape) and the touch links hanging from the finger.
    #[test]
    fn a_regrasp_finds_each_listed_joints_finger() {
        let robot = vt_robot::Robot::builtin("ur5e_allegro").unwrap();
        let cfg: crate::config::FingerRollConfig =
            serde_yaml::from_str("{joints: [{joint: ff_joint_0}, {joint: th_joint_1}], regrasp: {lift_seconds: 0.1}}").unwrap();
        let c = RollControl::of(&cfg, &robot, 0.005);
        let r = c.regrasp.expect("configured");
        assert_eq!(r.phase_steps, [20, 40, 30]);
        let hand = |n: &str| robot.hand.iter().position(|h| h.name == n).unwrap();
        let names = |f: &Finger| -> Vec<String> { f.touch.iter().map(|&t| robot.model.links[robot.touch_links[t]].name.clone()).collect() };
        // The index finger: its three flexion joints open the negative way (preshape below close).
        assert_eq!(r.fingers[0].lifting, vec![(hand("ff_joint_1"), -1.0), (hand("ff_joint_2"), -1.0), (hand("ff_joint_3"), -1.0)]);
        assert_eq!(names(&r.fingers[0]), ["ff_proximal", "ff_medial", "ff_distal"]);
        // The thumb: its other three joints, the one above the listed joint included.
        assert_eq!(r.fingers[1].lifting, vec![(hand("th_joint_0"), -1.0), (hand("th_joint_2"), -1.0), (hand("th_joint_3"), -1.0)]);
        assert_eq!(names(&r.fingers[1]), ["th_proximal", "th_medial", "th_distal"]);
    }
}

//! The closed-loop finger roll (episodes, hands): after an arm move, the arm stands still while
//! the listed hand joints move from their grasp targets until the object has turned by a drawn
//! target about a chosen axis, then hold; step after step in the same sense, until a joint has
//! moved its most (`sampling.record.finger_roll`).

use glam::DVec3;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::arm_move::StepLog;
use super::pivot::twist_angle;
use super::{Attempt, rot};

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
}

impl RollControl {
    /// The configured roll for `robot` at `timestep` (its joints are checked at load).
    pub fn of(roll: &crate::config::FingerRollConfig, robot: &vt_robot::Robot, timestep: f64) -> Self {
        let joints = roll.joints.iter().filter_map(|j| Some((robot.hand.iter().position(|h| h.name == j.joint)?, j.direction))).collect();
        RollControl {
            steps: roll.steps(timestep),
            hold_steps: (roll.hold_seconds / timestep).round().max(1.0) as usize,
            axis: DVec3::from_array(roll.axis).normalize(),
            step: (roll.step_deg.0.to_radians(), roll.step_deg.1.to_radians()),
            speed: roll.speed_deg_s.to_radians(),
            max: roll.max_deg.to_radians(),
            joints,
        }
    }
}

impl Attempt<'_> {
    /// The finger roll's window, the arm still at `q`. False when the object falls out of the hand.
    pub(super) fn roll_fingers(&mut self, q: &[f64], grasp_targets: &[f64], rng: &mut ChaCha8Rng, mut log: Option<&mut StepLog>) -> bool {
        let ctx = self.ctx;
        let Some(control) = &ctx.finger_roll else { return true };
        let draw = |rng: &mut ChaCha8Rng| rng.random_range(control.step.0..=control.step.1);
        let per_step = control.speed * ctx.timestep;
        let (mut moved, mut sense, mut reversed) = (0.0f64, 1.0, false);
        let mut step_start = rot(&self.physics.object_pose());
        let (mut target, mut turned, mut hold_until) = (draw(rng), 0.0f64, None::<usize>);
        let mut done = false;
        for k in 0..control.steps {
            let closing = k + control.hold_steps >= control.steps;
            let rolling = !done && !closing && hold_until.is_none_or(|h| k >= h);
            if rolling && hold_until.is_some() {
                // The next step, from here.
                (hold_until, target, turned) = (None, draw(rng), 0.0);
                step_start = rot(&self.physics.object_pose());
            }
            if rolling {
                moved += per_step;
                if moved >= control.max {
                    done = true;
                }
            }
            let mut targets = grasp_targets.to_vec();
            if !closing {
                for &(j, direction) in &control.joints {
                    targets[j] += sense * direction * moved;
                }
            }
            if !self.step_hand(&targets, grasp_targets, q, log.as_deref_mut()) {
                return false;
            }
            if !rolling {
                continue;
            }
            let now = twist_angle(rot(&self.physics.object_pose()) * step_start.inverse(), control.axis);
            let speed = (now - turned).abs() / ctx.timestep;
            turned = now;
            if !reversed && now < -WRONG_WAY {
                // The joints turn the object the other way: every direction reverses, from the
                // grasp targets again.
                (sense, reversed, moved) = (-sense, true, 0.0);
                step_start = rot(&self.physics.object_pose());
                turned = 0.0;
            } else if now.abs() + speed * STOP_LEAD_SECONDS >= target {
                hold_until = Some(k + control.hold_steps);
            }
        }
        self.physics.set_targets(grasp_targets);
        true
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
    }
}

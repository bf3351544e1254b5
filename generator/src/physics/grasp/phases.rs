//! Phases 2 and 3 of an attempt: the fingers close on the object, then the grasp settles while
//! the palm turns to its sampled pose.

use glam::{DAffine3, DQuat, DVec3};

use super::arm_move::along_path;
use super::{Attempt, Failure, GRAVITY, PALM_UP_GRAVITY, lost, rot};

/// Object damping (linear = angular) while resting, while closing, and from the settle on.
pub(super) const REST_DAMPING: f64 = 20.0;
const CLOSE_DAMPING: f64 = 2.0;
const HELD_DAMPING: f64 = 0.05;
/// A settled grasp may not let the object drift more than this (m) while still (and must touch it
/// with at least the robot's `min_touching` touch links).
const MAX_SETTLE_DRIFT: f64 = 0.02;

impl Attempt<'_> {
    /// Phase 2: every flexion joint towards its closed target, ab/adduction kept.
    pub(super) fn close_hand(&mut self, pre: &[f64]) -> Vec<f64> {
        let ctx = self.ctx;
        let mut close = pre.to_vec();
        for (c, t) in close.iter_mut().zip(&ctx.config.close) {
            if let Some(t) = t {
                *c = *t;
            }
        }
        self.physics.set_targets(&close);
        self.physics.set_object_damping(CLOSE_DAMPING, CLOSE_DAMPING);
        for _ in 0..ctx.steps(ctx.config.close_seconds) {
            self.grasp_step(None);
        }
        close
    }

    /// Phase 3: the palm turns from facing up to its sampled orientation over the first half (gravity
    /// turns with it in the palm frame, as a wrist rotation would), then holds still for the second
    /// half. Recording the grasp, the arm turns the wrist: it follows the smooth joint path from
    /// the palm up towards `q` (the grasp pose), with the palm's real orientation and acceleration,
    /// and, with `arm_speed_limits`, only as far as the joints' speed limits let it in that half
    /// (`GraspContext::reach_within`, as an episode's arm move: the recording's length is fixed).
    /// The grasp must hold the object by friction: it may not drift more than `MAX_SETTLE_DRIFT`
    /// while still. Drift during the turn is the object seating itself in the hand, not a lost
    /// grasp. Returns the held object pose (palm frame) and the arm's joints where the turn ended.
    pub(super) fn settle(&mut self, t_world_palm: &DAffine3, q: &[f64]) -> Result<(DAffine3, Vec<f64>), Failure> {
        let ctx = self.ctx;
        self.physics.set_object_damping(HELD_DAMPING, HELD_DAMPING);
        let gravity_in_palm = rot(t_world_palm).inverse() * GRAVITY;
        let turn = DQuat::from_rotation_arc(PALM_UP_GRAVITY.normalize(), gravity_in_palm.normalize());
        let n_settle = ctx.steps(ctx.config.settle_seconds);
        let n_turn = (n_settle / 2).max(1);
        let arm_path = self.grasp_recording.as_ref().map(|rec| {
            let up = rec.q_palm_up.clone();
            let end = if ctx.config.arm_speed_limits { ctx.reach_within(&up, q, n_turn) } else { q.to_vec() };
            (up, end)
        });
        let q_settled = arm_path.as_ref().map_or_else(|| q.to_vec(), |(_, end)| end.clone());
        // The arm's joints and the apparent gravity (palm frame) for step `k` of the settle.
        let gravity_at = |k: usize| -> (Option<Vec<f64>>, DVec3) {
            let s = (k as f64 / n_turn as f64).min(1.0);
            match &arm_path {
                Some((up, end)) => {
                    let moving = (k <= n_turn).then_some(1.0 / n_turn as f64);
                    (Some(along_path(up, end, s)), ctx.gravity_on_path(up, end, s, moving))
                }
                None => (None, DQuat::IDENTITY.slerp(turn, s) * PALM_UP_GRAVITY),
            }
        };
        // A lost object can only fall further (nothing but the hand is simulated): the grasp has
        // failed, and the rest of the settle would simulate the fall.
        let mut before = None;
        for k in 1..=n_settle {
            let (q_arm, gravity) = gravity_at(k);
            if k >= n_turn {
                before.get_or_insert_with(|| self.physics.object_pose());
            }
            self.physics.set_gravity(gravity);
            self.grasp_step(q_arm.as_deref());
            if lost(&*self.physics) {
                return Err(Failure::GraspNotHeld);
            }
        }
        let physics = &*self.physics;
        let before = before.expect("the settle reaches its turn's end");
        let held = physics.object_pose();
        let touching = physics.touch_contacts().iter().filter(|c| c.is_some()).count();
        if (held.translation - before.translation).length() > MAX_SETTLE_DRIFT || touching < ctx.robot.min_touching {
            return Err(Failure::GraspNotHeld);
        }
        Ok((held, q_settled))
    }
}

//! Phases 2 and 3 of an attempt: the fingers close on the object, then the grasp settles while
//! the palm turns to its sampled pose.

use glam::{DAffine3, DQuat};

use super::{Attempt, Failure, GRAVITY, PALM_UP_GRAVITY, lost, rot};

/// The object rests on the open palm this long (s) before the fingers close.
pub(super) const REST_SECONDS: f64 = 0.15;
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
        let (ctx, physics) = (self.ctx, &mut *self.physics);
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
    pub(super) fn settle(&mut self, t_world_palm: &DAffine3) -> Result<DAffine3, Failure> {
        let (ctx, physics) = (self.ctx, &mut *self.physics);
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
}

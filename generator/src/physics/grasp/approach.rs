//! Phase 0 of a recorded grasp (`sampling.record.approach`): the open hand's approach. The object
//! stands still in the world where the grasp finds it (the paper's loop places it in the
//! workspace), and the arm brings the open hand to it along the palm normal, so that an episode
//! shows the hand coming, the first contact, the closing and the wrist's turn.

use glam::{DAffine3, DVec3};

use super::arm_move::{along_path, instance_state};
use super::floor::robot_floor_clearance;
use super::phases::REST_DAMPING;
use super::placement::PLACEMENT_MAX_OVERLAP;
use super::{Approach, Attempt, GraspContext, rot};

impl GraspContext<'_> {
    /// The arm's joints where the approach to the palm-up grasp pose `up` (world; the arm there at
    /// `q_up`) starts: the palm `distance` back along its normal. None when the arm cannot reach
    /// it, a link would be under the floor, or the smooth path from it to `q_up` would turn a joint
    /// faster than its speed limit allows in the approach's time (another branch of the arm).
    pub(super) fn approach_start(&self, up: &DAffine3, q_up: &[f64], approach: Approach) -> Option<Vec<f64>> {
        let normal = rot(up) * DVec3::X;
        let start = DAffine3::from_translation(-normal * approach.distance) * *up;
        let q = self.reach(&start, q_up)?;
        if robot_floor_clearance(self.robot, &self.t_world_base, &q).is_some_and(|(_, z)| z < 0.0) {
            return None;
        }
        let seconds = approach.steps as f64 * self.timestep;
        (self.path_seconds_at_speed_limits(&q, q_up) <= seconds).then_some(q)
    }
}

impl Attempt<'_> {
    /// Recording the grasp with an approach: the states of the open hand (its joints at the
    /// preshape `pre`) on the arm's smooth path from the approach's start to the palm-up pose,
    /// the object still in the world where it is put (`end`: its pose in the grasp frame with the
    /// palm up). Each state's object pose is put into the physics (weightless, one step) to find
    /// its contacts: a link deeper in the object than a placement may be blocks the approach
    /// (false). The object is then put in at `end` again under `gravity`, as the placement left it.
    pub(super) fn approach(&mut self, end: DAffine3, pre: &[f64], gravity: DVec3) -> anyhow::Result<bool> {
        let ctx = self.ctx;
        let Some((q_start, q_up)) = self.grasp_recording.as_ref().and_then(|rec| Some((rec.q_approach.clone()?, rec.q_palm_up.clone())))
        else {
            return Ok(true);
        };
        let steps = ctx.approach.map_or(0, |a| a.steps);
        let palm = |q: &[f64]| ctx.t_world_base * ctx.robot.grasp_frame_pose(q);
        let object_world = palm(&q_up) * end;
        let mut states = Vec::with_capacity(steps);
        for k in 0..steps {
            let q = along_path(&q_start, &q_up, k as f64 / steps as f64);
            let object = palm(&q).inverse() * object_world;
            self.put(object, pre, DVec3::ZERO)?;
            let penetration = self.physics.max_penetration();
            if penetration > PLACEMENT_MAX_OVERLAP {
                return Ok(false);
            }
            let contacts = self.physics.touch_contacts();
            states.push(instance_state(ctx, &*self.physics, &q, object, DAffine3::IDENTITY, contacts, penetration));
        }
        self.put(end, pre, gravity)?;
        if let Some(rec) = self.grasp_recording.as_mut() {
            rec.states.extend(states);
        }
        Ok(true)
    }

    /// The object at `pose` (grasp frame) in the open hand at the preshape `pre`, under `gravity`,
    /// held still by damping, after one physics step (which finds its contacts).
    pub(super) fn put(&mut self, pose: DAffine3, pre: &[f64], gravity: DVec3) -> anyhow::Result<()> {
        let physics = &mut *self.physics;
        physics.reset(self.object, pose, pre)?;
        physics.set_targets(pre);
        physics.set_gravity(gravity);
        physics.set_object_damping(REST_DAMPING, REST_DAMPING);
        physics.step();
        Ok(())
    }
}

//! The hold screen, between the settled grasp and the first arm move: a grasp that lets the object
//! go under the apparent gravities the arm moves will put on it fails one of the many moves of its
//! trajectory sooner or later, and every move before that is physics thrown away. The screen turns
//! gravity (palm frame) from the settled grasp's to each extreme of the moves' orientations (the
//! edge of the `max_tilt_deg` cone; the back-to-camera tilts at their ends, rolled either way) and
//! holds it there; the grasp passes when the object stays within `PROBE_MAX_DRIFT` of its settled
//! pose with enough touch links on it. Every probe starts from the settled state and the last is
//! undone, so a grasp that passes is recorded exactly as without the screen.

use glam::{DAffine3, DQuat, DVec3};

use super::context::{back_to_camera_palm, cone_palm};
use super::{Attempt, Failure, GRAVITY, GraspContext, Held, Phase, lost, rot};

/// Whether the hold screen runs, and what it does with its verdict.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum HoldScreen {
    /// No probes.
    #[default]
    Off,
    /// A grasp that fails the probes fails its attempt before any arm move.
    On,
    /// The probes run and are undone, the attempt goes on whatever they found, and the verdict
    /// is counted against the attempt's outcome (`vtgen grasps --judge-screen`).
    Judge,
}

/// How long (s) gravity takes to turn to a probe's direction, and how long it stays there.
const PROBE_TURN_SECONDS: f64 = 0.2;
const PROBE_HOLD_SECONDS: f64 = 0.1;
/// A probe fails the grasp when the object has moved this far (m) from its settled pose.
const PROBE_MAX_DRIFT: f64 = 0.02;
/// Azimuths probed on the edge of the tilt cone.
const CONE_AZIMUTHS: usize = 4;

impl GraspContext<'_> {
    /// The apparent gravities (palm frame) the hold screen probes: the arm moves' extreme palm
    /// orientations, from the same constructions the move sampler draws from.
    pub fn probe_gravities(&self) -> Vec<DVec3> {
        let cfg = self.config;
        let in_palm = |r: DQuat| r.inverse() * GRAVITY;
        let tilt = cfg.max_tilt_deg.to_radians();
        let mut out: Vec<DVec3> = (0..CONE_AZIMUTHS)
            .map(|k| {
                let azimuth = std::f64::consts::TAU * k as f64 / CONE_AZIMUTHS as f64;
                in_palm(cone_palm(DQuat::IDENTITY, DVec3::new(0.0, azimuth.cos(), azimuth.sin()), tilt))
            })
            .collect();
        if cfg.back_to_camera_share > 0.0 {
            let away = self.away_from_camera();
            let roll = cfg.max_roll_deg.to_radians();
            let (lo, hi) = cfg.back_to_camera_tilt_deg;
            for tilt in [lo.to_radians(), hi.to_radians()] {
                for r in [-roll, roll] {
                    out.push(in_palm(back_to_camera_palm(away, tilt, DQuat::from_rotation_x(r))));
                }
            }
        }
        out
    }
}

impl Attempt<'_> {
    /// The hold screen on the settled grasp (`held`, the palm at the settle's orientation):
    /// fails the attempt when a probe shakes the object loose and the screen is on.
    pub(super) fn screen(&mut self, held: &Held, t_world_palm: &DAffine3) -> Result<(), Failure> {
        let mode = self.ctx.hold_screen;
        if mode == HoldScreen::Off {
            return Ok(());
        }
        let start = self.physics.steps_taken();
        let passed = self.probe(held, t_world_palm);
        let steps = self.physics.steps_taken() - start;
        self.log.steps.add(Phase::Screen, steps);
        self.screen_steps += steps;
        // Judged against the outcome only when the verdict does not decide it.
        if mode == HoldScreen::Judge {
            self.screen_verdict = Some(passed);
        }
        match (mode, passed) {
            (HoldScreen::On, false) => {
                self.log.steps.screened_out += 1;
                Err(Failure::HoldScreen)
            }
            _ => Ok(()),
        }
    }

    /// Whether the grasp holds through every probe; the physics is back at the settled state.
    fn probe(&mut self, held: &Held, t_world_palm: &DAffine3) -> bool {
        let ctx = self.ctx;
        let physics = &mut *self.physics;
        let settled = rot(t_world_palm).inverse() * GRAVITY;
        let (n_turn, n_hold) = (ctx.steps(PROBE_TURN_SECONDS), ctx.steps(PROBE_HOLD_SECONDS));
        let settled_state = physics.save();
        let mut passed = true;
        'probes: for g in ctx.probe_gravities() {
            let turn = DQuat::from_rotation_arc(settled.normalize(), g.normalize());
            for k in 1..=n_turn + n_hold {
                let s = (k as f64 / n_turn as f64).min(1.0);
                physics.set_gravity(DQuat::IDENTITY.slerp(turn, s) * settled);
                physics.step();
                if lost(physics) {
                    passed = false;
                    break 'probes;
                }
            }
            let drift = (physics.object_pose().translation - held.t_palm_object.translation).length();
            let touching = physics.touch_contacts().iter().filter(|c| c.is_some()).count();
            physics.restore(&settled_state);
            if drift > PROBE_MAX_DRIFT || touching < ctx.robot.min_touching {
                passed = false;
                break;
            }
        }
        physics.restore(&settled_state);
        passed
    }
}

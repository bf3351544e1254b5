//! Phase 1: the object into the open hand, one way per grasp kind (chosen once per trajectory):
//! on the palm under gravity (a multi-finger hand), or between the jaws at an antipodal pair of its
//! hull (a parallel-jaw gripper).

use anyhow::{Result, anyhow};
use glam::{DAffine3, DQuat, DVec3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use vt_randomizers::uniform_rotation;
use vt_robot::GraspKind;

use super::{Attempt, Failure, PALM_UP_GRAVITY, Stop};
use crate::config::{GraspConfig, REST_SECONDS};
use crate::physics::PhysicsObject;
use crate::physics::antipodal::{Hull, Jaws, antipodal_pose};

/// Object orientations drawn before falling back to the thin-axis placement of large objects.
const ORIENTATION_DRAWS: u32 = 20;
/// Largest tilt (rad) of a large object's thin axis off the palm normal: more makes them deeper
/// than the fingers reach.
const LARGE_OBJECT_MAX_TILT: f64 = 0.05;
/// Gap (m) between the palm surface and the object's back at placement.
const PLACEMENT_GAP: f64 = 0.003;
/// Placement retries, each this much further out along the palm normal (m), while the object
/// overlaps a link by more than `PLACEMENT_MAX_OVERLAP` (m).
const PLACEMENT_RETRIES: u32 = 6;
const PLACEMENT_STEP: f64 = 0.01;
pub(super) const PLACEMENT_MAX_OVERLAP: f64 = 0.0015;

/// How the object is put into the open hand.
pub(super) enum Placement {
    /// On the palm, at a random orientation and offset, resting under gravity.
    OnPalm,
    /// Between the open jaws at an antipodal pair of the object's hull (computed once).
    BetweenJaws(Hull),
}

impl Placement {
    /// The placement of a robot's grasp kind for `object`.
    pub(super) fn of(kind: GraspKind, object: &PhysicsObject) -> Result<Self> {
        Ok(match kind {
            GraspKind::Palm => Placement::OnPalm,
            GraspKind::ParallelJaw => Placement::BetweenJaws(
                Hull::of(&object.points).ok_or_else(|| anyhow!("the object's points have no convex hull (degenerate mesh)"))?,
            ),
        })
    }
}

/// How far `object` reaches along the palm normal (palm x) turned by `r`: (depth, how far behind
/// its origin its back is).
fn depth_along(object: &PhysicsObject, r: DQuat) -> (f64, f64) {
    let xs = object.points.iter().map(|p| (r * DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)).x);
    let (lo, hi) = xs.fold((f64::MAX, f64::MIN), |(lo, hi), x| (lo.min(x), hi.max(x)));
    (hi - lo, -lo)
}

/// The object's orientation in the palm: uniformly random, redrawn (no physics needed) while the
/// object is deeper in front of the palm than the fingers can wrap around.
fn sample_object_orientation(cfg: &GraspConfig, object: &PhysicsObject, rng: &mut ChaCha8Rng) -> DQuat {
    let mut r_obj = uniform_rotation(rng);
    for _ in 0..ORIENTATION_DRAWS {
        if depth_along(object, r_obj).0 <= cfg.max_grasp_depth {
            break;
        }
        r_obj = uniform_rotation(rng);
    }
    if depth_along(object, r_obj).0 <= cfg.max_grasp_depth {
        return r_obj;
    }
    // Large objects (boxes, the drill) fit the hand in few orientations: turn the model's thinnest
    // axis onto the palm normal, then spin about it, flip, and tilt a little.
    let (lo, hi) = object.points.iter().fold((DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)), |(lo, hi), p| {
        let v = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
        (lo.min(v), hi.max(v))
    });
    let ext = hi - lo;
    let thin = if ext.x <= ext.y && ext.x <= ext.z {
        DVec3::X
    } else if ext.y <= ext.z {
        DVec3::Y
    } else {
        DVec3::Z
    };
    let flip = if rng.random_bool(0.5) { -1.0 } else { 1.0 };
    let align = DQuat::from_rotation_arc(thin * flip, DVec3::X);
    let spin = DQuat::from_rotation_x(rng.random_range(0.0..std::f64::consts::TAU));
    let tilt_axis = DVec3::new(0.0, rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)).normalize_or(DVec3::Y);
    let tilt = DQuat::from_axis_angle(tilt_axis, rng.random_range(0.0..LARGE_OBJECT_MAX_TILT));
    tilt * spin * align
}

impl Attempt<'_> {
    /// The object into the open hand at the preshape `pre`, as `placement` puts it.
    pub(super) fn place(&mut self, placement: &Placement, rng: &mut ChaCha8Rng, pre: &[f64]) -> Result<(), Stop> {
        match placement {
            Placement::OnPalm => self.place_on_palm(rng, pre),
            Placement::BetweenJaws(hull) => self.place_between_jaws(hull, rng, pre),
        }
    }

    /// Phase 1: the object on the open palm (preshape, palm up) at a random orientation and offset,
    /// resting under gravity. Fails when it overlaps a link wherever it is put.
    fn place_on_palm(&mut self, rng: &mut ChaCha8Rng, pre: &[f64]) -> Result<(), Stop> {
        let (ctx, object) = (self.ctx, self.object);
        let cfg = ctx.config;
        let r_obj = sample_object_orientation(cfg, object, rng);
        let back = depth_along(object, r_obj).1;
        let o = &cfg.object_offset;
        let pos = DVec3::new(
            cfg.palm_surface_x + PLACEMENT_GAP + back,
            rng.random_range(o.min[1]..=o.max[1]),
            rng.random_range(o.min[2]..=o.max[2]),
        );
        // An object spawned inside a link (large objects reach the thumb, which sits in front of the
        // palm) would be launched by the solver: one step finds the overlap, and the object is moved
        // out along the palm normal until it is clear (and, recording an approach, until the
        // open hand can come to it).
        let mut failure = Failure::InitialOverlap;
        for shift in 0..PLACEMENT_RETRIES {
            let p = pos + DVec3::X * (PLACEMENT_STEP * shift as f64);
            let pose = DAffine3::from_rotation_translation(r_obj, p);
            // Open hand at the preshape, palm facing up: the object rests on the palm under gravity
            // (along the palm normal, -x in the palm frame), held still by damping. Closing without
            // gravity lets the first finger to touch push the weightless object out of the hand.
            self.put(pose, pre, PALM_UP_GRAVITY)?;
            if self.physics.max_penetration() <= PLACEMENT_MAX_OVERLAP {
                if !self.approach(pose, pre, PALM_UP_GRAVITY)? {
                    failure = Failure::ApproachBlocked;
                    continue;
                }
                self.rest();
                return Ok(());
            }
        }
        Err(failure.into())
    }

    /// The object, just put in the open hand, rests there for `REST_SECONDS`; the grasp's recording
    /// starts with it.
    fn rest(&mut self) {
        self.log_grasp_state(None);
        for _ in 0..self.ctx.steps(REST_SECONDS) {
            self.grasp_step(None);
        }
    }

    /// Phase 1 of a parallel-jaw grasp: the object weightless between the open jaws at an antipodal
    /// pair of its hull (`antipodal_pose`), held still by damping. Fails when no pair fits the jaws,
    /// or every pose tried overlaps the gripper.
    fn place_between_jaws(&mut self, hull: &Hull, rng: &mut ChaCha8Rng, pre: &[f64]) -> Result<(), Stop> {
        let jaws = Jaws::of(self.ctx.robot, pre);
        let mut failure = Failure::InitialOverlap;
        for _ in 0..PLACEMENT_RETRIES {
            let pose = antipodal_pose(hull, &jaws, rng).ok_or(Failure::NoAntipodalPair)?;
            self.put(pose, pre, DVec3::ZERO)?;
            if self.physics.max_penetration() <= PLACEMENT_MAX_OVERLAP {
                if !self.approach(pose, pre, DVec3::ZERO)? {
                    failure = Failure::ApproachBlocked;
                    continue;
                }
                // Recorded, the weightless object floats still between the open jaws as long as
                // it would rest on a palm, so that every grasp records as many steps.
                if self.grasp_recording.is_some() {
                    self.rest();
                }
                return Ok(());
            }
        }
        Err(failure.into())
    }
}

//! `robot.grasp:` the grasp loop's parameters: where the grasp frame goes, how the object is
//! placed and the hand closed, and how long each phase lasts.

use std::f64::consts::{PI, TAU};

use serde::{Deserialize, Serialize};
use vt_check::{Check, Checks, field, key};

use super::Workspace;

/// The grasp loop's parameters. Joint arrays are in the robot description's order (`arm`, `hand`);
/// left out (or empty), they are the description's (`LoadedConfig` fills them in).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GraspConfig {
    /// Arm joints the IK starts from (rad; the description's `arm.home`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub home_arm: Vec<f64>,
    /// Box (world) the palm is moved to, and how far its palmar normal may tilt from straight up.
    pub palm_workspace: Workspace,
    pub max_tilt_deg: f64,
    /// Rotation of the palm about its normal, either way from "fingers towards the camera side".
    pub max_roll_deg: f64,
    /// Share of the arm moves (instances) that turn the back of the hand to the camera: the palm
    /// normal tilts from straight up *away from the camera* by an angle drawn from
    /// `back_to_camera_tilt_deg`, so palm and fingers stand between the camera and the object.
    /// This is what reaches the paper's heavy-occlusion regime (> 85% of the model unseen); the
    /// other moves keep the `max_tilt_deg` cone. 0 (the default) draws nothing extra: configs
    /// without it give the same data as before the knob existed.
    #[serde(skip_serializing_if = "is_zero")]
    pub back_to_camera_share: f64,
    #[serde(skip_serializing_if = "is_default_back_tilt")]
    pub back_to_camera_tilt_deg: (f64, f64),
    /// Random preshape: a range per hand joint (rad; the description's `hand[*].preshape`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub preshape: Vec<(f64, f64)>,
    /// Closing targets per hand joint; null keeps the preshape value (ab/adduction).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub close: Vec<Option<f64>>,
    /// Object centre range in the palm frame (y, z used; x puts the object against the palm).
    pub object_offset: Workspace,
    /// Palmar surface of the palm (palm frame x, m).
    pub palm_surface_x: f64,
    /// Object orientations deeper than this in front of the palm (m) are redrawn: the fingers
    /// cannot wrap around them.
    pub max_grasp_depth: f64,
    pub close_seconds: f64,
    /// After closing: the palm turns from facing up to its sampled orientation over the first
    /// half, and the object must stay put over the second.
    pub settle_seconds: f64,
    /// Duration of the arm's move between instances (smoothstep in joint space). Faster moves
    /// shake heavy objects (the drill, the cracker box) out of the hand more often; a move that
    /// drops the object is undone and another drawn (both backends), so 0.5 s costs fewer simulated
    /// steps per recorded instance than 1 s.
    pub move_seconds: f64,
    /// A snapshot's arm move takes longer than `move_seconds` where the smooth path would turn an
    /// arm joint faster than its description's `velocity` limit at its peak (1.5 times the mean
    /// speed), as the real arm must. On by default: on `scenes/paper.yaml` 23% more physics steps
    /// and 16% fewer grasp attempts (docs/grasp-loop.md). An episode's moves all take
    /// `move_seconds` (its timeline is fixed): one that would pass a limit stops short of its
    /// drawn pose, as does a recorded grasp's wrist turn (half of `settle_seconds`), and its
    /// pivoting's wrist turns are stretched within the window.
    pub arm_speed_limits: bool,
    /// Stillness after each move before the instance is checked and recorded (at most this long
    /// with `hold_until_still`, in snapshots).
    pub hold_seconds: f64,
    /// End a snapshot's hold once the object has stopped in the hand (moved < 0.05 mm and turned
    /// < 0.05° over 50 ms, after at least 50 ms) rather than after the whole `hold_seconds`: the
    /// instance is recorded still, and on `scenes/paper.yaml` the grasp loop takes 18% fewer
    /// physics steps with no more attempts (docs/grasp-loop.md). On by default; episodes always
    /// hold the whole `hold_seconds` (every move takes the same time).
    pub hold_until_still: bool,
    /// Grasp attempts per trajectory (each with fresh randomness) before `generate` gives up
    /// with an error naming the trajectory. Large objects need many: on the cracker box about 1
    /// attempt in 24 keeps the object through 100 arm moves (`scenes/paper.yaml`).
    pub max_attempts: u32,
    /// Largest accepted penetration of a hand link into the object (m).
    pub max_penetration: f64,
    /// Probe the settled grasp with the arm moves' extreme apparent gravities before spending
    /// arm moves on it, and fail the attempt when the object comes loose (docs/grasp-loop.md).
    /// Off by default: on `scenes/paper.yaml` it caught half of the large objects' failing
    /// grasps but turned away a fifth of their holding ones, and cost 8% more physics steps.
    pub hold_screen: bool,
    /// When a grasp is lost after it recorded instances, keep them and record the trajectory's
    /// remaining instances with a new grasp (the next attempt) instead of starting the trajectory
    /// over: no recorded arm move is thrown away (docs/performance.md). A trajectory may then hold
    /// several grasps in turn, and each sample names its own (`/sample/info` `grasp`). Off by
    /// default: a trajectory is one grasp held through every instance, as in the paper. Snapshots
    /// only: an episode is one grasp's time series.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub regrasp_on_loss: bool,
}

/// Palm-normal tilt (from straight up, away from the camera) of the back-to-camera moves: from
/// nearly horizontal to 30 deg past it, palm turned a little down. Measured with `vtgen bench` on
/// `scenes/paper.yaml` (550 samples, 11 objects, share 0.5): (80, 120) puts 36% of the samples
/// above 85% occlusion, (60, 100) 27%; the `max_tilt_deg` cone alone 9%.
const DEFAULT_BACK_TILT_DEG: (f64, f64) = (80.0, 120.0);

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

fn is_default_back_tilt(v: &(f64, f64)) -> bool {
    *v == DEFAULT_BACK_TILT_DEG
}

impl Default for GraspConfig {
    fn default() -> Self {
        GraspConfig {
            home_arm: Vec::new(),
            palm_workspace: Workspace { min: [-0.08, -0.05, 0.22], max: [0.08, 0.05, 0.32] },
            max_tilt_deg: 50.0,
            max_roll_deg: 45.0,
            back_to_camera_share: 0.0,
            back_to_camera_tilt_deg: DEFAULT_BACK_TILT_DEG,
            preshape: Vec::new(),
            close: Vec::new(),
            object_offset: Workspace { min: [0.0, -0.02, 0.0], max: [0.0, 0.02, 0.05] },
            palm_surface_x: 0.0111,
            max_grasp_depth: 0.08,
            close_seconds: 0.6,
            settle_seconds: 0.4,
            move_seconds: 0.5,
            arm_speed_limits: true,
            hold_seconds: 0.2,
            hold_until_still: true,
            max_attempts: 200,
            max_penetration: 0.001,
            hold_screen: false,
            regrasp_on_loss: false,
        }
    }
}

/// After an arm move, up to this many waits of `PENETRATION_WAIT_SECONDS` for squeezing
/// transients (the arm move's schedule: `GraspConfig::move_steps`).
pub const PENETRATION_WAITS: usize = 10;
pub const PENETRATION_WAIT_SECONDS: f64 = 0.025;

/// Physics steps of `timestep` seconds in a phase of `seconds` (at least one): how the grasp loop
/// counts every phase.
pub fn physics_steps(seconds: f64, timestep: f64) -> usize {
    (seconds / timestep).round().max(1.0) as usize
}

/// The object rests on the open palm this long (s) before the fingers close.
pub const REST_SECONDS: f64 = 0.15;

impl GraspConfig {
    /// Physics steps of a grasp from the object resting in the open hand to the settled grasp:
    /// the rest (`REST_SECONDS`), the closing and the settle.
    pub fn grasp_steps(&self, timestep: f64) -> usize {
        let steps = |seconds| physics_steps(seconds, timestep);
        steps(REST_SECONDS) + steps(self.close_seconds) + steps(self.settle_seconds)
    }

    /// Physics steps of one recorded arm move of an episode, without in-hand motion: the move, the
    /// hold, and the whole settle window of `PENETRATION_WAITS` waits.
    pub fn move_steps(&self, timestep: f64) -> usize {
        let steps = |seconds| physics_steps(seconds, timestep);
        steps(self.move_seconds) + steps(self.hold_seconds) + PENETRATION_WAITS * steps(PENETRATION_WAIT_SECONDS)
    }

    /// This config with the joint arrays it leaves out taken from the robot's description.
    pub fn with_robot_defaults(mut self, robot: &vt_robot::Robot) -> Self {
        if self.home_arm.is_empty() {
            self.home_arm = robot.home.clone();
        }
        if self.preshape.is_empty() {
            self.preshape = robot.hand.iter().map(|h| h.preshape).collect();
        }
        if self.close.is_empty() {
            self.close = robot.hand.iter().map(|h| h.close).collect();
        }
        self
    }

    /// Which field does not fit the robot: (field, message). A joint array of another length than
    /// the robot's joints; a palm-only key set for a robot that does not grasp with its palm (its
    /// value would be silently unused).
    pub fn mismatch(&self, robot: &vt_robot::Robot) -> Option<(&'static str, String)> {
        let (arm, hand) = (robot.arm_dofs.len(), robot.hand.len());
        let name = &robot.name;
        let lengths = [
            (field!(self.home_arm).0, self.home_arm.len(), arm, "arm joints"),
            (field!(self.preshape).0, self.preshape.len(), hand, "hand joints"),
            (field!(self.close).0, self.close.len(), hand, "hand joints"),
        ]
        .into_iter()
        .find(|(_, n, want, _)| n != want)
        .map(|(key, n, want, what)| (key, format!("{n} values for the {want} {what} of robot '{name}'")));
        lengths.or_else(|| {
            if robot.kind == vt_robot::GraspKind::Palm {
                return None;
            }
            let default = GraspConfig::default();
            let palm_only = [
                (key!(self.object_offset), self.object_offset != default.object_offset),
                (key!(self.palm_surface_x), self.palm_surface_x != default.palm_surface_x),
                (key!(self.max_grasp_depth), self.max_grasp_depth != default.max_grasp_depth),
            ];
            palm_only
                .into_iter()
                .find(|(_, set)| *set)
                .map(|(key, _)| (key, format!("only palm grasps use it, and robot '{name}' grasps between its jaws: leave the key out")))
        })
    }
}

impl Check for GraspConfig {
    fn check(&self, c: &mut Checks) {
        c.range(field!(self.max_attempts), 1, 10_000);
        c.range(field!(self.max_tilt_deg), 0.0, 180.0);
        c.range(field!(self.max_roll_deg), 0.0, 180.0);
        c.range(field!(self.back_to_camera_share), 0.0, 1.0);
        c.key(key!(self.back_to_camera_tilt_deg)).ordered_pair(self.back_to_camera_tilt_deg, 0.0, 180.0);
        // Joint angles (rad): within a turn either way for the arm (the UR5e's limits), half a
        // turn for the hand. The preshape and the boxes are drawn from: a reversed range would
        // make the draw panic.
        let (home, arm) = field!(self.home_arm);
        for (i, q) in arm.iter().enumerate() {
            c.key(home).index(i).within(*q, -TAU, TAU);
        }
        let (preshape, ranges) = field!(self.preshape);
        for (i, range) in ranges.iter().enumerate() {
            c.key(preshape).index(i).ordered_pair(*range, -PI, PI);
        }
        let (close, targets) = field!(self.close);
        for (i, q) in targets.iter().enumerate() {
            if let Some(q) = q {
                c.key(close).index(i).within(*q, -PI, PI);
            }
        }
        c.section(field!(self.palm_workspace));
        c.section(field!(self.object_offset));
        c.range(field!(self.palm_surface_x), -0.1, 0.1);
        c.positive(field!(self.max_grasp_depth), 1.0, "m");
        // Durations (s): a phase of 0 s would still simulate one step, so zero is refused rather
        // than silently lengthened.
        for duration in [field!(self.close_seconds), field!(self.settle_seconds), field!(self.move_seconds), field!(self.hold_seconds)] {
            c.positive(duration, 60.0, "s");
        }
        c.range(field!(self.max_penetration), 0.0, 0.1);
    }
}

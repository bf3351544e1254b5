//! `sampling:` how many trajectories and instances per object, the train/test split, and the
//! episode streams' rates and finger motion.

use serde::{Deserialize, Serialize};
use vt_check::{Check, Checks, excl, field, incl, key};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SamplingConfig {
    /// Random trajectories per object (the paper: 200).
    pub trajectories_per_object: u32,
    /// Recorded instances per trajectory (the paper: 100).
    pub instances_per_trajectory: u32,
    #[serde(default)]
    pub split: SplitConfig,
    /// Episodes instead of snapshots: each trajectory becomes one episode, every stream at its own
    /// rate (FORMAT.md, "Episodes"). Left out of the config when off.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub record: Option<RecordConfig>,
}

/// `sampling.record`: the rates of an episode's streams. Each is a whole number of physics steps,
/// the touch and state rates whole multiples of the camera's and the state's of the touch's, so
/// every camera frame has the touch and the state of its own instant, and every touch its state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RecordConfig {
    /// The main camera: RGB, depth, mask (Hz).
    pub camera_hz: f64,
    /// The tactile pads: depth views, the point cloud, optical images (Hz).
    pub tactile_hz: f64,
    /// Joint states and the object's pose and twist (Hz); none: every physics step.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub state_hz: Option<f64>,
    /// Scripted finger motion after each arm move (off unless given).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub finger_motion: Option<FingerMotionConfig>,
    /// Gravity pivoting after each arm move, between a gripper's jaws or a hand's pinch (off unless
    /// given).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pivot: Option<PivotConfig>,
    /// A closed-loop finger roll after each arm move, for hands (off unless given).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub finger_roll: Option<FingerRollConfig>,
    /// The object's rotation in the palm each episode aims at (degrees, the angle between its
    /// orientations at the settled grasp and now), drawn uniformly from [min, max] per episode: the
    /// pivoting and the finger roll stop turning once it is reached, and the grasp holds from then
    /// on. None: they turn for as long as their windows last.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub turn_target_deg: Option<(f64, f64)>,
    /// Record the grasp itself before the settled grasp: the object resting in the open hand with
    /// the palm up, the fingers closing on it, and the arm turning the wrist to the grasp pose
    /// (the settle then follows that real arm path instead of tilting gravity in the hand's frame).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub grasp: bool,
    /// With `grasp`: the hand's approach recorded before it, the arm moving the open hand along
    /// the palm normal to the object, which the workspace holds still where the grasp finds it
    /// (as the paper's loop places it), until the hand reaches it (off unless given).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub approach: Option<ApproachConfig>,
}

/// `sampling.record.approach`: the open hand's approach to the object before a recorded grasp.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ApproachConfig {
    /// The approach's time (s).
    pub seconds: f64,
    /// How far back from its grasp pose the palm starts, along its normal (mm). From 100 mm the
    /// UR5e's forearm went under the floor in a third of the grasps of `scenes/tiny-episode.yaml`
    /// (the palm 0.22-0.32 m up), from 50-70 mm in one of 60.
    pub distance_mm: f64,
}

impl Default for ApproachConfig {
    fn default() -> Self {
        ApproachConfig { seconds: 0.5, distance_mm: 60.0 }
    }
}

impl Check for ApproachConfig {
    fn check(&self, c: &mut Checks) {
        c.positive(field!(self.seconds), 60.0, "s");
        c.positive(field!(self.distance_mm), 1000.0, "mm");
    }
}

impl ApproachConfig {
    /// Physics steps of the approach, counted as every phase of the grasp is.
    pub fn steps(&self, timestep: f64) -> usize {
        super::physics_steps(self.seconds, timestep)
    }
}

impl Default for RecordConfig {
    fn default() -> Self {
        RecordConfig {
            camera_hz: 30.0,
            tactile_hz: 60.0,
            state_hz: None,
            finger_motion: None,
            pivot: None,
            finger_roll: None,
            turn_target_deg: None,
            grasp: false,
            approach: None,
        }
    }
}

/// `sampling.record.pivot`: gravity pivoting between a gripper's jaws or a hand's pinch. After
/// each arm move's hold (and finger motion), the arm stands still for `seconds` while a closed
/// loop on the simulated rotation turns the object about the line between the pads: the grip
/// eases until the object turns under its own weight, and tightens when the turn reaches a target
/// drawn from `step_deg`; then it eases again towards the next target, until the window's last
/// `hold_seconds`, when the grip is full again. Each arm move then takes `seconds` longer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PivotConfig {
    /// The window per arm move (s).
    pub seconds: f64,
    /// Each pivot's target turn (degrees), drawn uniformly from [min, max].
    pub step_deg: (f64, f64),
    /// The time the grip takes to ease from full to a hundredth of it (s).
    pub ease_seconds: f64,
    /// The grip is full for the window's last `hold_seconds`, and between two pivots (s).
    pub hold_seconds: f64,
    /// How far the object may slide along the pads over a window (mm) before its pivoting ends.
    pub max_slide_mm: f64,
    /// A hand's pinch: two pad patterns (a name, `*`/`?` globs over names, or a label, as the sensor
    /// rules select pads). Before each pivot, the touching pads of the first and of the second on
    /// another finger that face each other most become the pinch whose line the object turns
    /// about; the other fingers lift off, and close on the object again after the pivot. Without
    /// it, a gripper's two jaws (a hand must give it).
    pub pads: Option<[String; 2]>,
    /// How far the other fingers' closing joints open for a hand's pinch (degrees).
    pub lift_deg: f64,
    /// How fast the grip rises again while the object slides along the pads or spins, in
    /// multiples of its easing rate. Less lets a hand's pinch, whose rounded fingertips the object
    /// rolls and slides along, turn it further, and drops it more often (docs/episodes.md).
    pub regrip_rate: f64,
    /// How often in a window a hand with no pinch places a pad of the first pattern again, on the
    /// object's face opposite a touching pad of the second, before its pivoting ends (0: never).
    pub repinches: u32,
    /// A hand's grasp whose window finds no pinch before its first pivot (and places no pad to
    /// make one) would turn nothing: with this, the attempt fails (`NoPinch`) and the trajectory
    /// draws a new grasp, so that every kept episode pivots; without it, the episode is kept
    /// unturned. Objects the hand seldom pinches cost many more attempts (docs/episodes.md).
    pub require_pinch: bool,
}

impl Default for PivotConfig {
    fn default() -> Self {
        PivotConfig {
            seconds: 2.0,
            step_deg: (20.0, 60.0),
            ease_seconds: 0.6,
            hold_seconds: 0.25,
            max_slide_mm: 15.0,
            pads: None,
            lift_deg: 30.0,
            regrip_rate: 4.0,
            repinches: 0,
            require_pinch: false,
        }
    }
}

impl Check for PivotConfig {
    fn check(&self, c: &mut Checks) {
        c.positive(field!(self.seconds), 60.0, "s");
        c.positive(field!(self.ease_seconds), 60.0, "s");
        c.positive(field!(self.hold_seconds), 60.0, "s");
        c.positive(field!(self.max_slide_mm), 1000.0, "mm");
        c.key(key!(self.lift_deg)).bounded(self.lift_deg, incl(0.0), incl(90.0), "degrees");
        c.positive(field!(self.regrip_rate), 100.0, "easing rates");
        let (lo, hi) = self.step_deg;
        c.key(key!(self.step_deg)).bounded_range([lo, hi], excl(0.0), incl(180.0), "degrees");
        if self.hold_seconds >= self.seconds {
            c.key(key!(self.hold_seconds)).fail(format!("{} s must be shorter than the window ({} s)", self.hold_seconds, self.seconds));
        }
        // A gripper's jaws are always its pinch: these would silently do nothing.
        let hand_only = || "applies to a hand's pinch: give its `pads` (a gripper's jaws are always its pinch)".to_string();
        if self.pads.is_none() {
            if self.repinches > 0 {
                c.key(key!(self.repinches)).fail(hand_only());
            }
            if self.require_pinch {
                c.key(key!(self.require_pinch)).fail(hand_only());
            }
        }
    }
}

impl PivotConfig {
    /// Physics steps of the window at `timestep`.
    pub fn steps(&self, timestep: f64) -> usize {
        (self.seconds / timestep).round() as usize
    }
}

/// `sampling.record.finger_motion`: after each arm move's hold, the listed hand joints swing about
/// where they stand against the object, `q + amplitude · (sin(2π t / period + phase) − sin phase)`,
/// for `cycles` periods, then squeeze again, while the arm stands still and the other joints keep
/// squeezing: a finger gait that works the object in the hand. Each arm move then takes
/// `cycles · period` longer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FingerMotionConfig {
    #[serde(default = "default_gait_period")]
    pub period_s: f64,
    #[serde(default = "default_gait_cycles")]
    pub cycles: u32,
    pub joints: Vec<FingerJointMotion>,
}

fn default_gait_period() -> f64 {
    0.5
}

fn default_gait_cycles() -> u32 {
    2
}

/// One hand joint of a finger motion.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FingerJointMotion {
    /// A hand joint of the robot's description (`hand[].joint`).
    pub joint: String,
    pub amplitude_deg: f64,
    #[serde(default)]
    pub phase_deg: f64,
}

impl Check for FingerMotionConfig {
    fn check(&self, c: &mut Checks) {
        c.positive(field!(self.period_s), 60.0, "s");
        c.range(field!(self.cycles), 1, 1000);
        let joints_key = key!(self.joints);
        if self.joints.is_empty() {
            c.key(joints_key).fail("list at least one hand joint");
        }
        for (i, j) in self.joints.iter().enumerate() {
            let mut joints = c.key(joints_key);
            let mut at = joints.index(i);
            at.range(field!(j.amplitude_deg), -90.0, 90.0);
            at.range(field!(j.phase_deg), -360.0, 360.0);
        }
    }
}

impl FingerMotionConfig {
    /// Physics steps of the motion at `timestep`.
    pub fn steps(&self, timestep: f64) -> usize {
        (self.cycles as f64 * self.period_s / timestep).round() as usize
    }
}

/// `sampling.record.finger_roll`: a closed-loop finger roll. After each arm move's hold, the arm
/// stands still for `seconds` while the listed hand joints move from their grasp targets at
/// `speed_deg_s`, each in its `direction` (+1 or -1), until the object has turned by a target
/// drawn from `step_deg` about `axis` (palm frame); the joints then hold for `hold_seconds` and
/// the next step begins, in the same sense, until a joint has moved `max_deg` or the window's last
/// `hold_seconds`, or, with `regrasp`, re-places the fingers and goes on. An object that turns the
/// other way reverses every joint's direction once. The joints keep their last targets to the
/// window's end (the turn is kept). Each arm move takes `seconds` longer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FingerRollConfig {
    #[serde(default = "default_roll_seconds")]
    pub seconds: f64,
    /// The turn's axis, palm frame (normalized).
    #[serde(default = "default_roll_axis")]
    pub axis: [f64; 3],
    #[serde(default = "default_roll_step")]
    pub step_deg: (f64, f64),
    #[serde(default = "default_roll_speed")]
    pub speed_deg_s: f64,
    #[serde(default = "default_roll_max")]
    pub max_deg: f64,
    #[serde(default = "default_roll_hold")]
    pub hold_seconds: f64,
    pub joints: Vec<FingerRollJoint>,
    /// Finger gaiting: when a joint has moved `max_deg`, each listed joint's finger in turn lifts
    /// off, moves its joint back to the grasp target and is placed again, and the roll goes on.
    /// Left out: the roll ends there.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub regrasp: Option<RegraspConfig>,
}

/// `sampling.record.finger_roll.regrasp`: how a finger is lifted and placed again. A finger (the
/// listed joint and the hand joints above and below it) is lifted only while touch links of other
/// fingers hold the object, and is put back at once when the object moves in the hand during
/// its lift.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegraspConfig {
    /// How far the finger's other joints open from where they stand (degrees).
    #[serde(default = "default_lift_deg")]
    pub lift_deg: f64,
    /// The lift, the listed joint's return and the placing (s each).
    #[serde(default = "default_lift_seconds")]
    pub lift_seconds: f64,
    #[serde(default = "default_return_seconds")]
    pub return_seconds: f64,
    #[serde(default = "default_lift_seconds")]
    pub place_seconds: f64,
    /// The object's motion in the palm during a lift that puts the finger back (mm, degrees).
    #[serde(default = "default_max_slip_mm")]
    pub max_slip_mm: f64,
    #[serde(default = "default_max_slip_deg")]
    pub max_slip_deg: f64,
}

fn default_lift_deg() -> f64 {
    25.0
}
fn default_lift_seconds() -> f64 {
    0.15
}
fn default_return_seconds() -> f64 {
    0.2
}
fn default_max_slip_mm() -> f64 {
    10.0
}
fn default_max_slip_deg() -> f64 {
    10.0
}

impl RegraspConfig {
    /// Physics steps of the lift, the return and the placing at `timestep`.
    pub fn steps(&self, timestep: f64) -> [usize; 3] {
        [self.lift_seconds, self.return_seconds, self.place_seconds].map(|s| (s / timestep).round().max(1.0) as usize)
    }
}

impl Check for RegraspConfig {
    fn check(&self, c: &mut Checks) {
        c.positive(field!(self.lift_deg), 90.0, "degrees");
        c.positive(field!(self.lift_seconds), 10.0, "s");
        c.positive(field!(self.return_seconds), 10.0, "s");
        c.positive(field!(self.place_seconds), 10.0, "s");
        c.positive(field!(self.max_slip_mm), 100.0, "mm");
        c.positive(field!(self.max_slip_deg), 180.0, "degrees");
    }
}

fn default_roll_seconds() -> f64 {
    2.0
}
fn default_roll_axis() -> [f64; 3] {
    [1.0, 0.0, 0.0]
}
fn default_roll_step() -> (f64, f64) {
    (5.0, 15.0)
}
fn default_roll_speed() -> f64 {
    30.0
}
fn default_roll_max() -> f64 {
    30.0
}
fn default_roll_hold() -> f64 {
    0.2
}

/// One hand joint of a finger roll and the way it moves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FingerRollJoint {
    pub joint: String,
    #[serde(default = "default_roll_direction")]
    pub direction: f64,
}

fn default_roll_direction() -> f64 {
    1.0
}

impl Check for FingerRollConfig {
    fn check(&self, c: &mut Checks) {
        c.positive(field!(self.seconds), 60.0, "s");
        c.positive(field!(self.hold_seconds), 60.0, "s");
        c.positive(field!(self.speed_deg_s), 1000.0, "degrees/s");
        c.positive(field!(self.max_deg), 180.0, "degrees");
        let (lo, hi) = self.step_deg;
        c.key(key!(self.step_deg)).bounded_range([lo, hi], excl(0.0), incl(180.0), "degrees");
        let [x, y, z] = self.axis;
        let length = (x * x + y * y + z * z).sqrt();
        if length.is_nan() || length <= 1e-6 {
            c.key(key!(self.axis)).fail(format!("[{x}, {y}, {z}] is not a direction"));
        }
        if self.hold_seconds >= self.seconds {
            c.key(key!(self.hold_seconds)).fail(format!("{} s must be shorter than the window ({} s)", self.hold_seconds, self.seconds));
        }
        let joints_key = key!(self.joints);
        if self.joints.is_empty() {
            c.key(joints_key).fail("list at least one hand joint");
        }
        for (i, j) in self.joints.iter().enumerate() {
            let mut joints = c.key(joints_key);
            joints.index(i).range(field!(j.direction), -1.0, 1.0);
        }
        if let Some(r) = &self.regrasp {
            r.check(&mut c.key(key!(self.regrasp)));
        }
    }
}

impl FingerRollConfig {
    /// Physics steps of the window at `timestep`.
    pub fn steps(&self, timestep: f64) -> usize {
        (self.seconds / timestep).round() as usize
    }
}

impl RecordConfig {
    /// Physics steps each arm move of an episode adds for in-hand motion (the finger motion, the
    /// pivoting and the finger roll windows) at `timestep`.
    pub fn in_hand_steps(&self, timestep: f64) -> usize {
        self.finger_motion.as_ref().map_or(0, |m| m.steps(timestep))
            + self.pivot.as_ref().map_or(0, |p| p.steps(timestep))
            + self.finger_roll.as_ref().map_or(0, |r| r.steps(timestep))
    }
}

/// Physics steps between two messages of each stream of an episode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StreamPeriods {
    pub camera: u64,
    pub tactile: u64,
    pub state: u64,
}

impl RecordConfig {
    /// Physics steps an episode records before its settled grasp (`grasp`; 0 without): the
    /// approach (`approach`), the rest, the closing and the settle (`GraspConfig::grasp_steps`),
    /// less the first few, so that the settled grasp falls on a camera frame.
    pub fn grasp_steps(&self, grasp: &super::GraspConfig, timestep: f64) -> u64 {
        if !self.grasp {
            return 0;
        }
        let all = (grasp.grasp_steps(timestep) + self.approach_steps(timestep)) as u64;
        all - all % self.periods(timestep).camera
    }

    /// Physics steps of the recorded grasp's approach (0 without one).
    pub fn approach_steps(&self, timestep: f64) -> usize {
        self.approach.as_ref().filter(|_| self.grasp).map_or(0, |a| a.steps(timestep))
    }

    /// Each stream's period in physics steps of `timestep` seconds (the nearest whole number).
    pub fn periods(&self, timestep: f64) -> StreamPeriods {
        let steps = |hz: f64| (1.0 / (hz * timestep)).round().max(1.0) as u64;
        StreamPeriods { camera: steps(self.camera_hz), tactile: steps(self.tactile_hz), state: self.state_hz.map_or(1, steps) }
    }

    /// The approach: only before a recorded grasp.
    pub(super) fn check_approach(&self, c: &mut Checks) {
        if self.approach.is_some() && !self.grasp {
            c.key(key!(self.approach)).fail("the approach comes before a recorded grasp: it needs sampling.record.grasp: true");
        }
    }

    /// The turn target: within half a turn (the angle between two orientations), for a controller
    /// that turns the object.
    pub(super) fn check_turn_target(&self, c: &mut Checks) {
        let Some((lo, hi)) = self.turn_target_deg else { return };
        let mut at = c.key(key!(self.turn_target_deg));
        at.bounded_range([lo, hi], excl(0.0), incl(180.0), "degrees");
        if self.pivot.is_none() && self.finger_roll.is_none() {
            at.fail("a turn target needs a controller that turns the object: sampling.record.pivot or sampling.record.finger_roll");
        }
    }

    /// The rates against the physics step: each a whole number of steps (within 1 %), touch and
    /// state whole multiples of the camera.
    pub(super) fn check_rates(&self, timestep: f64, c: &mut Checks) {
        let p = self.periods(timestep);
        let rates = [(key!(self.camera_hz), self.camera_hz, p.camera), (key!(self.tactile_hz), self.tactile_hz, p.tactile)]
            .into_iter()
            .chain(self.state_hz.map(|hz| (key!(self.state_hz), hz, p.state)));
        for (key, hz, steps) in rates {
            if !(hz > 0.0 && hz <= 1.0 / timestep * 1.0001) {
                c.key(key).fail(format!("{hz} Hz is out of range: allowed 0 < rate <= the physics rate ({:.1} Hz)", 1.0 / timestep));
            } else if ((steps as f64) * hz * timestep - 1.0).abs() > 0.01 {
                c.key(key).fail(format!(
                    "{hz} Hz is not a whole number of physics steps ({timestep} s each): {:.1} Hz ({steps} steps) is",
                    1.0 / (steps as f64 * timestep)
                ));
            } else if key != key!(self.camera_hz) && !p.camera.is_multiple_of(steps) {
                c.key(key).fail(format!("{hz} Hz must be a whole multiple of camera_hz ({} Hz)", self.camera_hz));
            } else if key == key!(self.state_hz) && !p.tactile.is_multiple_of(steps) {
                c.key(key).fail(format!("{hz} Hz must be a whole multiple of tactile_hz ({} Hz)", self.tactile_hz));
            }
        }
    }
}

impl Default for SamplingConfig {
    fn default() -> Self {
        SamplingConfig { trajectories_per_object: 200, instances_per_trajectory: 100, split: SplitConfig::default(), record: None }
    }
}

impl Check for SamplingConfig {
    fn check(&self, c: &mut Checks) {
        c.range(field!(self.trajectories_per_object), 1, 1_000_000);
        c.range(field!(self.instances_per_trajectory), 1, 100_000);
        c.section(field!(self.split));
    }
}

/// Train/test ratio, decided per trajectory (FORMAT.md).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SplitConfig {
    pub train: u32,
    pub test: u32,
}

impl Default for SplitConfig {
    fn default() -> Self {
        SplitConfig { train: 4, test: 1 }
    }
}

impl Check for SplitConfig {
    /// Both in range, and a split that keeps something.
    fn check(&self, c: &mut Checks) {
        c.range(field!(self.train), 0, 1000);
        c.range(field!(self.test), 0, 1000);
        if self.train == 0 && self.test == 0 {
            c.fail("train + test must be at least 1");
        }
    }
}

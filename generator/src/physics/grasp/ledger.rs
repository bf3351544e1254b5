//! Where the grasp loop's physics steps go: per phase of an attempt, and how many were thrown
//! away (attempts that failed, arm moves undone and redrawn). `vtgen grasps` and `vtgen bench`
//! report it; every failed attempt is physics that made no sample.

use serde::Serialize;

use super::outcome::{GraspEvent, InHandEnd};

/// A phase of an attempt, as [`StepLedger`] counts its physics steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// The object into the open hand, and its rest on the palm.
    Place,
    /// The fingers closing.
    Close,
    /// The grasp settling while the palm turns to its pose.
    Settle,
    /// The hold screen's probes (undone afterwards).
    Screen,
    /// An arm move's path.
    ArmMove,
    /// The hold at the end of an arm move.
    Hold,
    /// Scripted or closed-loop in-hand motion (episodes).
    InHand,
    /// The waits for squeezing transients after a move.
    Squeeze,
}

/// Physics steps per phase over every attempt (kept, failed and redone), and the share of them
/// thrown away.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct StepLedger {
    pub place: u64,
    pub close: u64,
    pub settle: u64,
    pub screen: u64,
    pub arm_move: u64,
    pub hold: u64,
    pub in_hand: u64,
    pub squeeze: u64,
    /// Steps of attempts that failed (every phase of them).
    pub failed_attempts: u64,
    /// Steps of arm moves undone and redrawn within attempts that were kept.
    pub redone_moves: u64,
    /// Steps that made the kept trajectories' recorded instances: their attempts less the moves
    /// redone and the screen's probes.
    pub kept: u64,
    /// Instances the failed attempts had recorded when they failed (summed over them).
    pub instances_before_failure: u64,
    /// Attempts the hold screen turned away before any arm move.
    pub screened_out: u64,
    /// The hold screen's verdicts against the attempts' outcomes (judged when the screen only
    /// watches, `HoldScreen::Judge`): passed and held, passed and failed later, failed but held,
    /// failed and failed.
    pub screen_judged: ScreenJudged,
}

/// The hold screen's verdicts against the attempts' outcomes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct ScreenJudged {
    pub passed_held: u64,
    pub passed_failed: u64,
    pub failed_held: u64,
    pub failed_failed: u64,
}

impl ScreenJudged {
    pub fn count(&mut self, passed: bool, held: bool) {
        *match (passed, held) {
            (true, true) => &mut self.passed_held,
            (true, false) => &mut self.passed_failed,
            (false, true) => &mut self.failed_held,
            (false, false) => &mut self.failed_failed,
        } += 1;
    }

    fn merge(&mut self, o: &ScreenJudged) {
        self.passed_held += o.passed_held;
        self.passed_failed += o.passed_failed;
        self.failed_held += o.failed_held;
        self.failed_failed += o.failed_failed;
    }
}

impl StepLedger {
    pub fn add(&mut self, phase: Phase, steps: u64) {
        *match phase {
            Phase::Place => &mut self.place,
            Phase::Close => &mut self.close,
            Phase::Settle => &mut self.settle,
            Phase::Screen => &mut self.screen,
            Phase::ArmMove => &mut self.arm_move,
            Phase::Hold => &mut self.hold,
            Phase::InHand => &mut self.in_hand,
            Phase::Squeeze => &mut self.squeeze,
        } += steps;
    }

    /// Every step counted.
    pub fn total(&self) -> u64 {
        self.place + self.close + self.settle + self.screen + self.arm_move + self.hold + self.in_hand + self.squeeze
    }

    /// Steps that made no recorded instance: failed attempts, redone moves, and the screen's
    /// probes.
    pub fn wasted(&self) -> u64 {
        self.total() - self.kept
    }

    pub fn merge(&mut self, o: &StepLedger) {
        let StepLedger {
            place,
            close,
            settle,
            screen,
            arm_move,
            hold,
            in_hand,
            squeeze,
            failed_attempts,
            redone_moves,
            kept,
            instances_before_failure,
            screened_out,
            screen_judged,
        } = *o;
        self.place += place;
        self.close += close;
        self.settle += settle;
        self.screen += screen;
        self.arm_move += arm_move;
        self.hold += hold;
        self.in_hand += in_hand;
        self.squeeze += squeeze;
        self.failed_attempts += failed_attempts;
        self.redone_moves += redone_moves;
        self.kept += kept;
        self.instances_before_failure += instances_before_failure;
        self.screened_out += screened_out;
        self.screen_judged.merge(&screen_judged);
    }
}

/// What the grasp loop reports besides the trajectory: the events statistics count, where its
/// physics steps went and why its in-hand windows stopped turning.
#[derive(Debug, Clone, Default)]
pub struct GraspLog {
    pub events: Vec<GraspEvent>,
    pub steps: StepLedger,
    /// Every in-hand window that kept the object in the hand (undone moves' and failed attempts'
    /// included), by how its turning ended (`InHandEnd::name`).
    pub in_hand_ends: std::collections::BTreeMap<&'static str, u64>,
    /// The pads a hand's pivoting placed again to make a pinch where it had none (the same
    /// windows counted).
    pub repinches: u64,
}

impl GraspLog {
    /// Counts an in-hand window by how its turning ended.
    pub fn in_hand_ended(&mut self, end: InHandEnd) {
        *self.in_hand_ends.entry(end.name()).or_default() += 1;
    }
}

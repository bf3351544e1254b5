//! The grasp loop's outcome vocabulary: why an attempt failed, why a move was redone, why an
//! in-hand window stopped turning, and the stable names statistics count them under.

/// Why an attempt at a trajectory ended without it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Failure {
    InitialOverlap,
    GraspNotHeld,
    LostDuringMotion,
    TooFewContacts,
    Penetration,
    TouchesFloor,
    Unreachable,
    /// No antipodal pair of the object's hull fits between the open jaws (a parallel-jaw grasp).
    NoAntipodalPair,
    /// The settled grasp let the object go under one of the hold screen's probes.
    HoldScreen,
    /// Recording the grasp's approach: a link of the open hand would pass through the object on
    /// the way to it, wherever it was put.
    ApproachBlocked,
    /// A hand's pivoting window could not begin (`sampling.record.pivot.require_pinch`): no two
    /// touching pads of its pinch faced each other and no pad could be placed again to make them.
    NoPinch,
}

/// An arm move undone and redrawn from the last recorded state: not a failure, the attempt goes
/// on. A move that drops the object, or ends with a hand link more than `max_penetration` into
/// the object, fewer touch links touching than `min_touching` or the object on the floor, cannot
/// be recorded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Redo {
    Drop,
    Penetration,
    Contacts,
    Floor,
}

/// What the grasp loop counts for the run's statistics: failed attempts and redone moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GraspEvent {
    Failed(Failure),
    Redone(Redo),
}

impl GraspEvent {
    /// The name statistics count it under (`grasp_stats.failures` in shards and the manifest,
    /// `vtgen grasps`): stable, the names earlier datasets carry.
    pub fn name(self) -> &'static str {
        match self {
            GraspEvent::Failed(f) => match f {
                Failure::InitialOverlap => "InitialOverlap",
                Failure::GraspNotHeld => "GraspNotHeld",
                Failure::LostDuringMotion => "LostDuringMotion",
                Failure::TooFewContacts => "TooFewContacts",
                Failure::Penetration => "Penetration",
                Failure::TouchesFloor => "TouchesFloor",
                Failure::Unreachable => "Unreachable",
                Failure::NoAntipodalPair => "NoAntipodalPair",
                Failure::HoldScreen => "HoldScreen",
                Failure::ApproachBlocked => "ApproachBlocked",
                Failure::NoPinch => "NoPinch",
            },
            GraspEvent::Redone(r) => match r {
                Redo::Penetration => "MoveRedoneForPenetration",
                Redo::Contacts => "MoveRedoneForContacts",
                Redo::Floor => "MoveRedoneForFloor",
                Redo::Drop => "MoveRedoneForDrop",
            },
        }
    }
}

/// Why an in-hand window (the pivoting or the finger roll after an arm move) stopped turning the
/// object before the window's end, or that it turned to the end.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InHandEnd {
    /// The episode's turn target was reached.
    Target,
    /// The window had no time left for another pivot or step.
    Window,
    /// The object slid the pivot's budget along the pads.
    Slid,
    /// No wrist turn for the next pivot is reachable above the floor.
    NoWristTurn,
    /// A rolling joint moved its most, and the roll has no regrasp.
    JointRange,
    /// A finger was not lifted: the other fingers' touch links touching the object were fewer
    /// than the robot's `min_touching`.
    OthersNotHolding,
    /// A lifted finger was put back: the object moved in the palm during its lift.
    FingerPutBack,
    /// A hand's pivoting found no two touching pads of its `pads` that face each other, and placed
    /// none again (`sampling.record.pivot.repinches`).
    NoPinch,
}

impl InHandEnd {
    /// The name `vtgen grasps` counts it under.
    pub fn name(self) -> &'static str {
        match self {
            InHandEnd::Target => "target",
            InHandEnd::Window => "window",
            InHandEnd::Slid => "slid",
            InHandEnd::NoWristTurn => "no_wrist_turn",
            InHandEnd::JointRange => "joint_range",
            InHandEnd::OthersNotHolding => "others_not_holding",
            InHandEnd::FingerPutBack => "finger_put_back",
            InHandEnd::NoPinch => "no_pinch",
        }
    }
}

//! The grasp loop's outcome vocabulary: why an attempt failed, why a move was redone, and the
//! stable names statistics count them under.

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

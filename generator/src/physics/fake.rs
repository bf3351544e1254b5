//! A scripted `HandPhysics` for unit tests of the grasp loop without a physics engine: the object
//! stays where it was put (or drifts, or is dropped once, as the test asks), the joints reach their
//! targets at once, and the contacts are whatever the test sets.

use glam::{DAffine3, DVec3};

use super::{HandPhysics, PhysicsObject};

#[derive(Debug, Clone)]
pub struct FakeHand {
    pub object: DAffine3,
    pub joints: Vec<f64>,
    pub gravity: DVec3,
    /// Added to the object's position at every step (a grasp that does not hold).
    pub drift_per_step: DVec3,
    /// The touch links' contacts the backend reports.
    pub contacts: Vec<Option<f64>>,
    pub penetration: f64,
    /// The object flies out of the hand at this step of the simulation (counted from the start),
    /// once: a restored state does not drop it again.
    pub drop_at_step: Option<u64>,
    /// The object flies out of the hand at every step counted in [first, last): a restored state
    /// drops it again while the count is in it (a grasp lost for good).
    pub drop_between: Option<(u64, u64)>,
    /// Steps taken since it was made (a restore does not take them back: they were spent).
    pub steps: u64,
}

impl FakeHand {
    /// A hand that holds whatever it is given, touching it with `touching` of the default robot's
    /// 12 touch links.
    pub fn holding(touching: usize) -> Self {
        FakeHand {
            object: DAffine3::IDENTITY,
            joints: vec![0.0; 16],
            gravity: DVec3::ZERO,
            drift_per_step: DVec3::ZERO,
            contacts: (0..12).map(|k| (k < touching).then_some(0.0)).collect(),
            penetration: 0.0,
            drop_at_step: None,
            drop_between: None,
            steps: 0,
        }
    }
}

impl HandPhysics for FakeHand {
    fn backend_name(&self) -> &'static str {
        "fake"
    }
    fn reset(&mut self, _object: &PhysicsObject, object_pose: DAffine3, q: &[f64]) -> anyhow::Result<()> {
        self.object = object_pose;
        self.joints = q.to_vec();
        Ok(())
    }
    fn set_targets(&mut self, targets: &[f64]) {
        self.joints = targets.to_vec();
    }
    fn set_gravity(&mut self, g: DVec3) {
        self.gravity = g;
    }
    fn set_object_damping(&mut self, _linear: f64, _angular: f64) {}
    fn steps_taken(&self) -> u64 {
        self.steps
    }
    fn step(&mut self) {
        self.steps += 1;
        self.object.translation += self.drift_per_step;
        if self.drop_at_step == Some(self.steps) {
            self.drop_at_step = None;
            self.object.translation += DVec3::new(-1.0, 0.0, 0.0);
        }
        if self.drop_between.is_some_and(|(first, last)| (first..last).contains(&self.steps)) {
            self.object.translation += DVec3::new(-1.0, 0.0, 0.0);
        }
    }
    fn object_pose(&self) -> DAffine3 {
        self.object
    }
    fn joint_positions(&self) -> Vec<f64> {
        self.joints.clone()
    }
    fn touch_contacts(&self) -> Vec<Option<f64>> {
        // A dropped object touches nothing.
        if self.object.translation.length() > 0.25 { vec![None; self.contacts.len()] } else { self.contacts.clone() }
    }
    fn hand_contacts(&self) -> Option<Vec<super::HandContact>> {
        None
    }
    fn max_penetration(&self) -> f64 {
        self.penetration
    }
    fn deepest_link(&self) -> Option<(usize, f64)> {
        None
    }
    fn save(&self) -> super::SavedState {
        super::SavedState::new((self.object, self.joints.clone(), self.gravity))
    }
    fn restore(&mut self, state: &super::SavedState) {
        let (object, joints, gravity) = state.get::<(DAffine3, Vec<f64>, DVec3)>().clone();
        (self.object, self.joints, self.gravity) = (object, joints, gravity);
    }
}

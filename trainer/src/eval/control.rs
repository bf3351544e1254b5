//! The touch control: a tactile network evaluated again on the same samples with the touch of
//! **another grasp** of the same object, and with **no touch**, next to its true touch. A network
//! that uses touch gets worse with the wrong touch; one whose error does not rise is not using it,
//! whatever its error with the true touch. Paired per grasp with the sign test ([`super::compare`]).

use std::collections::BTreeMap;

use serde::Serialize;

use super::SampleResult;
use super::compare::{Paired, paired};
use crate::data::Prepared;

/// A sample's prepared tactile input: its `(n_t, 3)` points and how many are real.
type Touch = (Vec<f32>, usize);

/// Something recorded per sample of one evaluation pass, by (dataset object, trajectory,
/// instance), lent to the samples of another grasp of the same object.
#[derive(Debug, Clone)]
pub struct GraspBank<T>(BTreeMap<(usize, u32, u32), T>);

impl<T> Default for GraspBank<T> {
    fn default() -> Self {
        GraspBank(BTreeMap::new())
    }
}

impl<T> GraspBank<T> {
    pub fn insert(&mut self, object: usize, trajectory: u32, instance: u32, value: T) {
        self.0.insert((object, trajectory, instance), value);
    }

    /// The value of another grasp of `object`: the next of the object's trajectories after
    /// `trajectory` (in order, wrapping around), at `instance` or else that trajectory's first
    /// recorded one. None when the object has no other trajectory here.
    pub fn other_grasp(&self, object: usize, trajectory: u32, instance: u32) -> Option<&T> {
        let of_object = |t: u32| self.0.range((object, t, 0)..=(object, t, u32::MAX));
        let later = self.0.range((object, trajectory.saturating_add(1), 0)..=(object, u32::MAX, u32::MAX)).next();
        let donor = later.or_else(|| self.0.range((object, 0, 0)..(object, trajectory, 0)).next())?.0.1;
        if donor == trajectory {
            return None;
        }
        self.0.get(&(object, donor, instance)).or_else(|| of_object(donor).next().map(|(_, v)| v))
    }
}

/// The tactile inputs of one evaluation pass.
pub type TouchBank = GraspBank<Touch>;

impl TouchBank {
    pub fn record(&mut self, p: &Prepared) {
        self.insert(p.object, p.trajectory, p.instance, (p.tactile.clone(), p.tactile_count));
    }

    /// The touch of another grasp of `p`'s object ([`GraspBank::other_grasp`]).
    pub fn other_grasp_of(&self, p: &Prepared) -> Option<&Touch> {
        self.other_grasp(p.object, p.trajectory, p.instance)
    }
}

/// The tactile input an evaluation pass gives the network.
#[derive(Debug)]
pub enum TouchInput<'a> {
    /// The sample's own touch.
    True,
    /// The sample's own touch, kept in the bank for a later [`TouchInput::OtherGrasp`] pass.
    Record(&'a mut TouchBank),
    /// The touch of another grasp of the same object (samples without one are not scored).
    OtherGrasp(&'a TouchBank),
    /// No touch at all.
    Without,
}

impl TouchInput<'_> {
    /// Gives `p` the tactile input of this pass; false when the sample has none to get.
    pub fn apply(&mut self, p: &mut Prepared) -> bool {
        match self {
            TouchInput::True => true,
            TouchInput::Record(bank) => {
                bank.record(p);
                true
            }
            TouchInput::OtherGrasp(bank) => match bank.other_grasp_of(p) {
                Some((points, count)) => {
                    (p.tactile, p.tactile_count) = (points.clone(), *count);
                    true
                }
                None => false,
            },
            TouchInput::Without => {
                p.tactile.iter_mut().for_each(|x| *x = 0.0);
                p.tactile_count = 0;
                true
            }
        }
    }
}

/// A tactile network's scores with the wrong touch and with none.
#[derive(Debug, Clone, Serialize)]
pub struct TouchControl {
    pub other_grasp: Vec<SampleResult>,
    pub no_touch: Vec<SampleResult>,
}

/// The true touch against each control, paired per grasp: `better` counts the grasps on which the
/// true touch gives the lower error.
#[derive(Debug, Clone, Serialize)]
pub struct ControlComparison {
    pub other_grasp: Option<Paired>,
    pub no_touch: Option<Paired>,
}

impl ControlComparison {
    pub fn of(true_touch: &[SampleResult], control: &TouchControl) -> Self {
        ControlComparison { other_grasp: paired(true_touch, &control.other_grasp), no_touch: paired(true_touch, &control.no_touch) }
    }

    /// Whether the network's position error rises, with the other grasp's touch, on more grasps
    /// than it falls, at p < 0.05: the sign that it uses touch.
    pub fn uses_touch(&self) -> Option<bool> {
        self.other_grasp.as_ref().map(|p| p.position.better > p.position.worse && p.position.p_value < 0.05)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn prepared(object: usize, trajectory: u32, instance: u32, touch: f32) -> Prepared {
        Prepared { object, trajectory, instance, tactile: vec![touch; 6], tactile_count: 2, ..Prepared::default() }
    }

    #[test]
    fn another_grasp_of_the_same_object_lends_its_touch() {
        let mut bank = TouchBank::default();
        for (o, t, i) in [(0, 0, 0), (0, 0, 1), (0, 3, 0), (0, 3, 1), (0, 5, 1), (1, 2, 0)] {
            bank.record(&prepared(o, t, i, (100 * o + 10 * t as usize + i as usize) as f32));
        }
        let donor = |o, t, i| bank.other_grasp_of(&prepared(o, t, i, -1.0)).map(|(p, _)| p[0]);
        // The next trajectory of the object, same instance; wrapping around to the first.
        assert_eq!(donor(0, 0, 1), Some(31.0));
        assert_eq!(donor(0, 3, 1), Some(51.0));
        assert_eq!(donor(0, 5, 1), Some(1.0));
        // The donor trajectory lacks the instance: its first recorded one.
        assert_eq!(donor(0, 3, 0), Some(51.0));
        // An object with one trajectory has no other grasp.
        assert_eq!(donor(1, 2, 0), None);
        // No touch: zeros, none counted.
        let mut p = prepared(0, 0, 0, 7.0);
        assert!(TouchInput::Without.apply(&mut p));
        assert_eq!((p.tactile_count, p.tactile.iter().all(|&x| x == 0.0)), (0, true));
    }
}

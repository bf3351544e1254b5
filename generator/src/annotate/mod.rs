//! Annotations computed from a rendered sample and its ground truth (not seen by a sensor): the
//! paper's occlusion level.

pub mod occlusion;

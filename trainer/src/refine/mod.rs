//! The pose refiner (`vtpose refine`, and a stage of `vtpose track`): the object's model
//! registered to what the sample shows of it, geometrically, with no training.
//!
//! - **Observations** ([`Observation`]): the depth points of the object's mask, the tactile
//!   points (every one lies on the object's surface, often where the camera sees nothing), and
//!   the free space of the depth image (where the camera saw past a point, no surface can be).
//! - **Global stage** ([`search`]): [`RefineConfig::rotations`] rotations spread evenly over
//!   SO(3), each with the translation that puts its camera-facing surface on the observed
//!   points, a few translation steps and a truncated-quadratic score on a distance field of the
//!   mesh ([`shape`]); the best distinct few go on.
//! - **Local stage** ([`local`]): robust point-to-plane Gauss-Newton on SE(3), depth and tactile
//!   points as point-to-surface terms; each candidate scored with the free-space term added, the
//!   lowest kept.
//!
//! It starts from nothing (the global stage), from a network's estimate or from the previous
//! frame's pose (the local stage alone: [`Start`]). Symmetric objects need nothing special: any
//! of the equivalent poses fits, and the metrics (ADD-S) forgive the choice. Deterministic: the
//! rotations are a fixed spiral and the point subsets are seeded by the sample.

pub mod local;
pub mod observation;
pub mod search;
pub mod shape;

use glam::{DQuat, DVec3};
use serde::{Deserialize, Serialize};

pub use observation::{FreeSpace, Observation};
pub use shape::ObjectShape;

/// A pose `T_camera_object`: rotation, translation (m).
pub type Pose = (DQuat, DVec3);

/// The refiner's settings (`refine:` in a YAML, or the defaults): chosen on the geometry's
/// scales (a millimetre-exact synthetic depth, fingertips of a centimetre), not tuned on the
/// test samples.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RefineConfig {
    /// Rotations the global stage tries (a super-Fibonacci spiral: 4096 leave any rotation
    /// within about 11° of one of them on average).
    pub rotations: usize,
    /// Depth and tactile points the global stage scores each rotation with.
    pub search_depth_points: usize,
    pub search_touch_points: usize,
    /// Rotations kept from the coarse pass (a quarter of the points, one translation step) for
    /// the fine one (all of them, `search_translation_steps` steps).
    pub search_keep: usize,
    /// Translation-only Gauss-Newton steps per rotation of the fine pass.
    pub search_translation_steps: usize,
    /// The global score's truncation (m).
    pub search_tau_m: f64,
    /// Distinct hypotheses kept for the local stage, and what "distinct" means.
    pub candidates: usize,
    pub distinct_deg: f64,
    pub distinct_m: f64,
    /// Depth and tactile points of the local stage (a seeded subset of each).
    pub depth_points: usize,
    pub touch_points: usize,
    /// The tactile points' term against the depth points' (each group's mean, weighted).
    pub touch_weight: f64,
    pub local_iterations: usize,
    /// The Geman-McClure scale: from `start`, times `decay` per iteration, down to `min` (m).
    pub local_sigma_start_m: f64,
    pub local_sigma_decay: f64,
    pub local_sigma_min_m: f64,
    /// The final score's truncation (m).
    pub score_tau_m: f64,
    /// The free-space term's weight, and how far past a surface point the camera must have seen
    /// to call it empty (m).
    pub free_space_weight: f64,
    pub free_space_margin_m: f64,
    /// In tracking, a pose warm-started from the previous frame whose score is above this
    /// length squared (an RMS distance to the surface, m) means the track was lost: the frame
    /// is searched from nothing too.
    pub lost_rms_m: f64,
}

impl Default for RefineConfig {
    fn default() -> Self {
        RefineConfig {
            rotations: 4096,
            search_depth_points: 48,
            search_touch_points: 24,
            search_keep: 128,
            search_translation_steps: 3,
            search_tau_m: 0.01,
            candidates: 6,
            distinct_deg: 20.0,
            distinct_m: 0.02,
            depth_points: 300,
            touch_points: 100,
            touch_weight: 1.0,
            local_iterations: 15,
            local_sigma_start_m: 0.02,
            local_sigma_decay: 0.75,
            local_sigma_min_m: 0.003,
            score_tau_m: 0.01,
            free_space_weight: 1.0,
            free_space_margin_m: 0.005,
            lost_rms_m: 0.004,
        }
    }
}

impl RefineConfig {
    /// Reads a YAML file of these fields (any left out keep their default); an error names the
    /// file, the line and the field.
    pub fn load(path: &std::path::Path) -> anyhow::Result<Self> {
        use anyhow::Context as _;
        let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
        let de = serde_yaml::Deserializer::from_str(&text);
        let cfg: RefineConfig = serde_path_to_error::deserialize(de).map_err(|e| {
            let at = e.inner().location().map_or(String::new(), |l| format!(" line {}", l.line()));
            anyhow::anyhow!("{}{at}: refine.{}: {}", path.display(), e.path(), e.inner())
        })?;
        cfg.validate().with_context(|| format!("{}", path.display()))?;
        Ok(cfg)
    }

    /// Checks the ranges; an error names the field.
    pub fn validate(&self) -> anyhow::Result<()> {
        let positive = [
            ("search_tau_m", self.search_tau_m),
            ("local_sigma_start_m", self.local_sigma_start_m),
            ("local_sigma_min_m", self.local_sigma_min_m),
            ("score_tau_m", self.score_tau_m),
            ("lost_rms_m", self.lost_rms_m),
        ];
        for (name, v) in positive {
            if !(v > 0.0 && v.is_finite()) {
                anyhow::bail!("refine.{name} must be a positive length in metres, got {v}");
            }
        }
        if !(self.local_sigma_decay > 0.0 && self.local_sigma_decay <= 1.0) {
            anyhow::bail!("refine.local_sigma_decay must be in (0, 1], got {}", self.local_sigma_decay);
        }
        for (name, v) in [
            ("touch_weight", self.touch_weight),
            ("free_space_weight", self.free_space_weight),
            ("free_space_margin_m", self.free_space_margin_m),
        ] {
            if !(v >= 0.0 && v.is_finite()) {
                anyhow::bail!("refine.{name} must be zero or positive, got {v}");
            }
        }
        for (name, v) in [
            ("rotations", self.rotations),
            ("search_keep", self.search_keep),
            ("candidates", self.candidates),
            ("depth_points", self.depth_points),
        ] {
            if v == 0 {
                anyhow::bail!("refine.{name} must be at least 1");
            }
        }
        Ok(())
    }
}

/// Where the refiner starts.
#[derive(Debug, Clone)]
pub enum Start {
    /// From nothing: the global stage's hypotheses.
    Search,
    /// From these poses (a network's estimate, the previous frame's): the local stage alone.
    From(Vec<Pose>),
}

/// The refiner's answer for one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refined {
    pub pose: Pose,
    /// Its score ([`local::score`]; lower is better).
    pub score: f64,
}

/// The prepared refiner: its settings and the spiral of rotations its global stage tries.
#[derive(Debug, Clone)]
pub struct Refiner {
    pub config: RefineConfig,
    rotations: Vec<DQuat>,
}

impl Refiner {
    pub fn new(config: RefineConfig) -> anyhow::Result<Self> {
        config.validate()?;
        let rotations = search::super_fibonacci(config.rotations);
        Ok(Refiner { config, rotations })
    }

    /// The observation of a decoded sample, with the config's point counts.
    pub fn observe(&self, sample: &vt_dataset::Sample) -> Observation {
        Observation::from_sample(sample, self.config.depth_points, self.config.touch_points)
    }

    /// The best pose of the object in `obs` (see the module docs); None when the observation
    /// has neither a depth point nor a tactile point.
    pub fn refine(&self, shape: &ObjectShape, obs: &Observation, start: &Start) -> Option<Refined> {
        let seeds = match start {
            Start::Search => search::hypotheses(shape, obs, &self.config, &self.rotations),
            Start::From(poses) => poses.clone(),
        };
        if (obs.depth.is_empty() && obs.touch.is_empty()) || seeds.is_empty() {
            return None;
        }
        seeds
            .into_iter()
            .map(|seed| {
                let pose = local::refine(shape, obs, &self.config, seed);
                Refined { pose, score: local::score(shape, obs, &self.config, pose) }
            })
            .min_by(|a, b| a.score.total_cmp(&b.score))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::ObjectModel;

    /// A box observed from a camera at the origin: its camera-facing faces' points as depth (the
    /// visible share cut to `visible`), points of its hidden faces as touch, and a free-space
    /// image of the whole box at 320 × 240.
    fn observe(model: &ObjectModel, pose: Pose, visible: f64, touch: usize) -> Observation {
        let shape = ObjectShape::of(model).unwrap();
        let (q, t) = pose;
        let mut depth = Vec::new();
        let mut hidden = Vec::new();
        for (p, n) in shape.points.iter().zip(&shape.normals) {
            let (pc, nc) = (q * *p + t, q * *n);
            if nc.dot(pc) < 0.0 { depth.push(pc) } else { hidden.push(pc) }
        }
        // The occluder hides the depth points right of a vertical line.
        depth.sort_by(|a, b| a.x.total_cmp(&b.x));
        depth.truncate(((depth.len() as f64) * visible) as usize);
        let stride = (hidden.len() / touch.max(1)).max(1);
        let touch: Vec<DVec3> = hidden.into_iter().step_by(stride).take(touch).collect();
        Observation { depth: depth.into_iter().step_by(4).collect(), touch, free_space: None }
    }

    #[test]
    fn the_search_finds_a_box_from_nothing_and_touch_fixes_what_a_patch_leaves_open() {
        let model = crate::refine::shape::tests_support::box_model([0.06, 0.035, 0.02]);
        let shape = ObjectShape::of(&model).unwrap();
        let truth = (DQuat::from_euler(glam::EulerRot::XYZ, 0.7, -0.4, 2.1), DVec3::new(0.03, -0.02, 0.55));
        let refiner = Refiner::new(RefineConfig { rotations: 2048, ..RefineConfig::default() }).unwrap();
        let add = |pose: Pose| {
            shape.points.iter().map(|p| (pose.0 * *p + pose.1).distance(truth.0 * *p + truth.1)).sum::<f64>() / shape.points.len() as f64
        };
        // The whole camera side visible: depth alone recovers the pose to a millimetre.
        let full = refiner.refine(&shape, &observe(&model, truth, 1.0, 0), &Start::Search).unwrap();
        assert!(add(full.pose) < 0.002, "ADD {}", add(full.pose));
        // Started at the truth moved by 10° and 1 cm, the local stage comes back.
        let off = (truth.0 * DQuat::from_rotation_y(0.17), truth.1 + DVec3::new(0.01, 0.0, 0.0));
        let local = refiner.refine(&shape, &observe(&model, truth, 1.0, 0), &Start::From(vec![off])).unwrap();
        assert!(add(local.pose) < 0.002, "ADD {}", add(local.pose));
        // A sliver of one face and the touch of the hidden faces: the touch pins the pose.
        let with_touch = refiner.refine(&shape, &observe(&model, truth, 0.15, 60), &Start::Search).unwrap();
        assert!(add(with_touch.pose) < 0.003, "ADD with touch {}", add(with_touch.pose));
        // Deterministic.
        assert_eq!(refiner.refine(&shape, &observe(&model, truth, 0.15, 60), &Start::Search), Some(with_touch));
    }
}

//! `scene:` the workspace box, the background and the occlusion estimate's parameters.

use serde::{Deserialize, Serialize};
use vt_check::{Check, Checks, field, key};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SceneConfig {
    /// Box (world frame) in which the object's centre is placed.
    #[serde(default)]
    pub workspace: Workspace,
    /// Background colour (sRGB) where nothing is drawn.
    pub background: [u8; 3],
    /// Occlusion level: model points per object, and how close (mm) a depth point must be for a
    /// model point to count as visible.
    pub occlusion_points: u32,
    pub occlusion_epsilon_mm: f64,
}

impl Default for SceneConfig {
    fn default() -> Self {
        SceneConfig { workspace: Workspace::default(), background: [70, 78, 92], occlusion_points: 2000, occlusion_epsilon_mm: 3.0 }
    }
}

impl Check for SceneConfig {
    /// A workspace above the floor, occlusion sampling.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    fn check(&self, c: &mut Checks) {
        let w = &self.workspace;
        let mut workspace = c.key(key!(self.workspace));
        w.check(&mut workspace);
        if !(w.min[2] > 0.0) {
            workspace.key(key!(w.min)).fail(format!("min z = {} must be above the floor (z > 0)", w.min[2]));
        }
        c.range(field!(self.occlusion_points), 10, 1_000_000);
        c.range(field!(self.occlusion_epsilon_mm), 0.01, 100.0);
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Workspace {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

impl Default for Workspace {
    fn default() -> Self {
        Workspace { min: [-0.08, -0.08, 0.18], max: [0.08, 0.08, 0.32] }
    }
}

impl Check for Workspace {
    /// A box: `max >= min` on every axis, every corner within 100 m of the origin.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    fn check(&self, c: &mut Checks) {
        for i in 0..3 {
            if !(self.min[i] <= self.max[i]) {
                c.key(key!(self.max)).fail(format!("max[{i}] = {} must be >= min[{i}] = {}", self.max[i], self.min[i]));
            }
        }
        for (key, corner) in [field!(self.min), field!(self.max)] {
            for (i, v) in corner.iter().enumerate() {
                c.key(key).index(i).within(*v, -100.0, 100.0);
            }
        }
    }
}

//! Scene appearance: the light and the floor. The canonical (unrandomized) appearance is what the
//! paper's unrandomized 20% look like; randomized appearance arrives with the randomization config.

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::texture::{ProceduralTexture, checker_texture};

/// A point light (world frame) plus an ambient term, colours linear RGB.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Light {
    pub position: DVec3,
    pub color: [f32; 3],
    pub intensity: f32,
    pub ambient: [f32; 3],
}

/// Everything about a sample's look that is not the object or the robot.
#[derive(Debug, Clone, PartialEq)]
pub struct Appearance {
    pub light: Light,
    pub floor: ProceduralTexture,
    /// Size of one floor texture tile in metres.
    pub floor_tile: f64,
    pub randomized: bool,
}

impl Appearance {
    /// The canonical appearance: a light above and in front of the workspace, a grey checker floor.
    pub fn canonical() -> Self {
        Appearance {
            light: Light { position: DVec3::new(0.4, -0.6, 1.4), color: [1.0, 0.97, 0.92], intensity: 1.0, ambient: [0.28, 0.28, 0.3] },
            floor: checker_texture(256, 8, [150, 150, 145], [110, 110, 108]),
            floor_tile: 0.4,
            randomized: false,
        }
    }
}

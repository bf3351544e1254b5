//! `camera.noise`: the RGB-D noise model's parameters (the model itself: `sensors::rgbd_noise`).

use serde::{Deserialize, Serialize};

use vt_check::{Check, Checks, field};

/// `camera.noise` in the config.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraNoiseConfig {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth: Option<DepthNoise>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub color: Option<ColorNoise>,
}

impl Check for CameraNoiseConfig {
    fn check(&self, c: &mut Checks) {
        c.section(field!(self.depth));
        c.section(field!(self.color));
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DepthNoise {
    /// σ at zero distance, mm.
    pub sigma_mm: f64,
    /// Growth of σ with the squared distance, mm per m².
    pub sigma_quadratic_mm: f64,
    /// Stereo baseline (m) and disparity resolution (steps per pixel) of the quantization; 0 = off.
    pub baseline_m: f64,
    pub subpixel: f64,
    /// A pixel whose depth differs from a 4-neighbour's by more than this (mm, plus 2% of the
    /// depth) is on a depth edge and reads 0.
    pub edge_mm: f64,
    /// Pixels whose surface normal is more than this from the viewing ray read 0.
    pub grazing_deg: f64,
    /// Share of pixels that read 0 at random.
    pub dropout: f64,
}

impl Default for DepthNoise {
    // Roughly a RealSense D435 at 640×480.
    fn default() -> Self {
        DepthNoise {
            sigma_mm: 0.5,
            sigma_quadratic_mm: 2.5,
            baseline_m: 0.05,
            subpixel: 8.0,
            edge_mm: 10.0,
            grazing_deg: 80.0,
            dropout: 0.002,
        }
    }
}

impl Check for DepthNoise {
    fn check(&self, c: &mut Checks) {
        c.range(field!(self.sigma_mm), 0.0, 100.0);
        c.range(field!(self.sigma_quadratic_mm), 0.0, 100.0);
        c.range(field!(self.baseline_m), 0.0, 10.0);
        c.range(field!(self.subpixel), 0.0, 1000.0);
        c.range(field!(self.edge_mm), 0.0, 10000.0);
        c.range(field!(self.grazing_deg), 0.0, 90.0);
        c.range(field!(self.dropout), 0.0, 1.0);
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ColorNoise {
    /// Read noise σ in 8-bit levels.
    pub sigma: f64,
    /// Shot noise: σ grows as √(level · shot).
    pub shot: f64,
}

impl Default for ColorNoise {
    fn default() -> Self {
        ColorNoise { sigma: 1.5, shot: 0.3 }
    }
}

impl Check for ColorNoise {
    fn check(&self, c: &mut Checks) {
        c.range(field!(self.sigma), 0.0, 255.0);
        c.range(field!(self.shot), 0.0, 255.0);
    }
}

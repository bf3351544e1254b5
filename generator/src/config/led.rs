//! An optical tactile sensor's LED, as a config (`robot.tactile.optical.lights`) and a calibration
//! file (`leds`) both give it.

use serde::{Deserialize, Serialize};

/// One LED of the sensor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Led {
    /// From the gel towards the LED, in the pad frame (z out of the pad): the LEDs sit behind
    /// the gel, so z < 0. Normalised on use.
    pub direction: [f64; 3],
    /// Linear RGB intensity on a white gel facing it (0..=4).
    pub color: [f64; 3],
    /// How much brighter the gel is on the LED's side of the image than in its centre, and
    /// darker on the far side: a factor `1 + falloff * s`, `s` in -1..=1 along the LED's azimuth.
    #[serde(default)]
    pub falloff: f64,
}

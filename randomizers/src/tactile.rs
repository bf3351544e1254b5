//! Sensor-to-sensor variation of optical tactile sensors (`randomization.tactile_sensors`): two
//! units of one design differ in their LEDs, gel tint, gel and marker print. A variation is a set
//! of factors drawn per pad and per sample; the generator applies them to the configured sensor.

use rand::Rng;
use serde::{Deserialize, Serialize};
use vt_check::{Bound, Check, Checks, incl, key};

use crate::stream::{SampleKey, SampleStream};

/// The ranges of the variation (YAML `randomization.tactile_sensors`). Factors multiply the
/// configured value; `± x` ranges are `[1 - x, 1 + x]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TactileSensorRandomization {
    /// Each LED's colour, per channel: `1 ± led_color`.
    pub led_color: f64,
    /// Each LED's overall intensity.
    pub led_intensity: [f64; 2],
    /// The gel's tint, per channel: `1 ± background`.
    pub background: f64,
    /// Added to the vignetting (the result kept in 0..=0.95).
    pub vignetting: [f64; 2],
    /// The gel's thickness (also the points' contact depth).
    pub gel_thickness: [f64; 2],
    /// The gel's elastic spread: a softer gel spreads wider.
    pub elastic_spread: [f64; 2],
    /// The marker grid's pitch.
    pub marker_pitch: [f64; 2],
}

impl Default for TactileSensorRandomization {
    fn default() -> Self {
        TactileSensorRandomization {
            led_color: 0.15,
            led_intensity: [0.8, 1.2],
            background: 0.08,
            vignetting: [-0.1, 0.1],
            gel_thickness: [0.8, 1.2],
            elastic_spread: [0.7, 1.4],
            marker_pitch: [0.9, 1.1],
        }
    }
}

impl Check for TactileSensorRandomization {
    fn check(&self, c: &mut Checks) {
        const MAX_SPREAD: Bound = incl(0.9);
        c.key(key!(self.led_color)).bounded(self.led_color, incl(0.0), MAX_SPREAD, "");
        c.key(key!(self.background)).bounded(self.background, incl(0.0), MAX_SPREAD, "");
        c.key(key!(self.led_intensity)).bounded_range(self.led_intensity, incl(0.0), incl(4.0), "");
        c.key(key!(self.vignetting)).bounded_range(self.vignetting, incl(-0.95), incl(0.95), "");
        c.key(key!(self.gel_thickness)).bounded_range(self.gel_thickness, incl(0.1), incl(4.0), "");
        c.key(key!(self.elastic_spread)).bounded_range(self.elastic_spread, incl(0.0), incl(4.0), "");
        c.key(key!(self.marker_pitch)).bounded_range(self.marker_pitch, incl(0.5), incl(2.0), "");
    }
}

/// One sensor unit's deviation from the configured sensor, as factors (offsets for vignetting).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SensorVariation {
    /// Per LED: factors on its colour's channels (the intensity included).
    pub led_color: Vec<[f64; 3]>,
    pub background: [f64; 3],
    pub vignetting: f64,
    pub gel_thickness: f64,
    pub elastic_spread: f64,
    pub marker_pitch: f64,
}

impl SensorVariation {
    /// The configured sensor itself.
    pub fn none(leds: usize) -> Self {
        SensorVariation {
            led_color: vec![[1.0; 3]; leds],
            background: [1.0; 3],
            vignetting: 0.0,
            gel_thickness: 1.0,
            elastic_spread: 1.0,
            marker_pitch: 1.0,
        }
    }
}

/// The variation of the sensor on pad `pad` (with `leds` LEDs) in sample `key`: its own stream,
/// so pads and samples never share numbers and adding a pad shifts no other pad's sensor.
pub fn sample_sensor_variation(cfg: &TactileSensorRandomization, key: &SampleKey, pad: &str, leds: usize) -> SensorVariation {
    let mut rng = SampleStream::sample(key, &format!("tactile_sensor/{pad}"));
    let mut uniform = |[lo, hi]: [f64; 2]| if hi > lo { rng.random_range(lo..=hi) } else { lo };
    let led_color = (0..leds)
        .map(|_| {
            let intensity = uniform(cfg.led_intensity);
            [0; 3].map(|_| intensity * uniform([1.0 - cfg.led_color, 1.0 + cfg.led_color]))
        })
        .collect();
    SensorVariation {
        led_color,
        background: [0; 3].map(|_| uniform([1.0 - cfg.background, 1.0 + cfg.background])),
        vignetting: uniform(cfg.vignetting),
        gel_thickness: uniform(cfg.gel_thickness),
        elastic_spread: uniform(cfg.elastic_spread),
        marker_pitch: uniform(cfg.marker_pitch),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variations_are_seeded_per_pad_and_sample_and_stay_in_their_ranges() {
        let cfg = TactileSensorRandomization::default();
        let key = SampleKey { seed: 3, object_id: "a", trajectory: 1, instance: 2 };
        let a = sample_sensor_variation(&cfg, &key, "left", 3);
        assert_eq!(a, sample_sensor_variation(&cfg, &key, "left", 3));
        assert_ne!(a, sample_sensor_variation(&cfg, &key, "right", 3));
        assert_ne!(a, sample_sensor_variation(&cfg, &SampleKey { instance: 3, ..key }, "left", 3));
        assert_eq!(a.led_color.len(), 3);
        for f in a.led_color.iter().flatten() {
            assert!((0.8 * 0.85..=1.2 * 1.15).contains(f), "{f}");
        }
        assert!((0.8..=1.2).contains(&a.gel_thickness));
        assert!(vt_check::problems(&cfg).is_empty());
    }

    #[test]
    fn bad_ranges_are_named() {
        let cfg = TactileSensorRandomization { led_color: 1.5, gel_thickness: [1.2, 0.8], ..Default::default() };
        let names: Vec<String> = vt_check::problems(&cfg).iter().map(|p| p.field()).collect();
        assert_eq!(names, ["led_color", "gel_thickness"]);
    }
}

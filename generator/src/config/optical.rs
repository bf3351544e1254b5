//! `robot.tactile.optical`: the optical (GelSight/DIGIT-style) tactile sensor's parameters. A
//! preset gives every value; any field given in the config replaces the preset's. The image model
//! itself is `sensors::optical`; its conventions are in FORMAT.md (`/tactile/<pad>/image`).

use std::path::PathBuf;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

pub use super::led::Led;
use super::optical_calibration::{LightModel, LoadedCalibration};
use vt_check::{Check, Checks, field, key};

/// A published sensor the parameters start from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OpticalPreset {
    /// GelSight Mini: 18.6 x 14.3 mm sensing area, read at 320 x 240 (its SDK's image size).
    #[default]
    GelsightMini,
    /// DIGIT (Lambeta et al., RA-L 2020): 19 x 16 mm sensing field, 320 x 240 at 60 Hz.
    Digit,
}

/// Printed markers on the gel, on a square grid centred on the pad.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MarkerConfig {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pitch_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius_mm: Option<f64>,
    /// Lateral displacement per unit slope of the indented gel (the slope capped at 1), in gel
    /// thicknesses: markers move away from a contact as the gel under it is pushed aside.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shift: Option<f64>,
    /// How dark a marker is (1: black).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub opacity: Option<f64>,
}

/// `robot.tactile.optical` in the config: a preset and the values that replace its own.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OpticalConfig {
    #[serde(default)]
    pub preset: OpticalPreset,
    /// Image width and height (pixels), over the sensing area.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image_size: Option<[u32; 2]>,
    /// The gel's sensing area (mm) along the pad's x and y, centred on the pad.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensing_area_mm: Option<[f64; 2]>,
    /// How far in front of the pad plane the gel's free surface lies (mm): an object at the pad
    /// plane indents it fully. Also the contact depth of the point cloud's `optical` model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gel_thickness_mm: Option<f64>,
    /// The gel's elastic spread (mm): the width of the Gaussian by which the indented gel pulls
    /// its surroundings along. Softer gels spread wider; 0 = the gel follows the object only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub elastic_spread_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lights: Option<Vec<Led>>,
    /// Ambient light on the gel (0..=1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ambient: Option<f64>,
    /// The gel's tint (linear RGB reflectance, 0..=1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub background: Option<[f64; 3]>,
    /// Darkening towards the image corners (0: none; 0.3: the corners 30 % darker).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vignetting: Option<f64>,
    /// Printed markers: off unless given (`markers: {}` takes the preset's grid).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub markers: Option<MarkerConfig>,
    /// Gaussian pixel noise, σ in 8-bit levels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_std: Option<f64>,
    /// A light model measured on a real unit (`vtgen tactile calibrate`'s `calibration.yaml`, or
    /// Taxim's `polycalib.npz` with its `bg.png`/`bg.jpg`), relative to the config file: it gives
    /// the image size, the pixel size and the shading in place of the preset's LED model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<PathBuf>,
    /// The calibration, loaded with the config (`LoadedConfig`).
    #[serde(skip)]
    pub loaded_calibration: Option<Arc<LoadedCalibration>>,
}

/// A sensor's measured light model: its file (written into `/sample/info`) and, in the generator,
/// the model itself.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SensorCalibration {
    /// The calibration file as the config names it.
    pub file: String,
    /// `polynomial`, `leds` or `taxim_table`.
    pub model: String,
    #[serde(skip)]
    pub light: Option<Arc<LoadedCalibration>>,
}

impl SensorCalibration {
    /// The measured shading and background, when the calibration replaces the LED model's.
    pub fn shading(&self) -> Option<(&LightModel, &[f64])> {
        let c = self.light.as_deref()?;
        Some((c.light.as_ref()?, c.background.as_deref()?))
    }
}

/// The resolved marker grid.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Markers {
    pub pitch_mm: f64,
    pub radius_mm: f64,
    pub shift: f64,
    pub opacity: f64,
}

/// An optical sensor with every parameter resolved (preset, then the config's values, then a
/// sample's randomized variation). Written per pad into `/sample/info`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OpticalSensor {
    pub image_size: [u32; 2],
    pub sensing_area_mm: [f64; 2],
    pub gel_thickness_mm: f64,
    pub elastic_spread_mm: f64,
    pub lights: Vec<Led>,
    pub ambient: f64,
    pub background: [f64; 3],
    pub vignetting: f64,
    pub markers: Option<Markers>,
    pub noise_std: f64,
    /// A measured light model in place of the LED model (`robot.tactile.optical.calibration`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<SensorCalibration>,
}

/// A preset's file (`generator/presets/optical/<preset>.yaml`): the sensor's parameters, its LEDs
/// by azimuth and elevation, and the marker grid a config's `markers: {}` takes.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct PresetFile {
    image_size: [u32; 2],
    sensing_area_mm: [f64; 2],
    gel_thickness_mm: f64,
    elastic_spread_mm: f64,
    lights: Vec<PresetLed>,
    ambient: f64,
    background: [f64; 3],
    vignetting: f64,
    noise_std: f64,
    markers: Markers,
}

/// An LED `elevation_deg` above the gel plane at `azimuth_deg` about the pad's z.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
struct PresetLed {
    azimuth_deg: f64,
    elevation_deg: f64,
    color: [f64; 3],
    falloff: f64,
}

impl PresetLed {
    fn led(&self) -> Led {
        let (a, e) = (self.azimuth_deg.to_radians(), self.elevation_deg.to_radians());
        Led { direction: [e.cos() * a.cos(), e.cos() * a.sin(), -e.sin()], color: self.color, falloff: self.falloff }
    }
}

impl OpticalPreset {
    /// The preset's file, as built into vtgen.
    fn file(self) -> &'static PresetFile {
        static FILES: std::sync::LazyLock<[PresetFile; 2]> = std::sync::LazyLock::new(|| {
            let parse = |name: &str, text: &str| {
                serde_yaml::from_str(text).unwrap_or_else(|e| panic!("presets/optical/{name}.yaml: {e} (unit-tested)"))
            };
            [
                parse("gelsight_mini", include_str!("../../presets/optical/gelsight_mini.yaml")),
                parse("digit", include_str!("../../presets/optical/digit.yaml")),
            ]
        });
        match self {
            OpticalPreset::GelsightMini => &FILES[0],
            OpticalPreset::Digit => &FILES[1],
        }
    }

    /// The preset's parameters (its file, `generator/presets/optical/`).
    pub fn sensor(self) -> OpticalSensor {
        let f = self.file();
        OpticalSensor {
            image_size: f.image_size,
            sensing_area_mm: f.sensing_area_mm,
            gel_thickness_mm: f.gel_thickness_mm,
            elastic_spread_mm: f.elastic_spread_mm,
            lights: f.lights.iter().map(PresetLed::led).collect(),
            ambient: f.ambient,
            background: f.background,
            vignetting: f.vignetting,
            markers: None,
            noise_std: f.noise_std,
            calibration: None,
        }
    }

    /// The preset's marker grid, used when the config asks for markers.
    pub fn markers(self) -> Markers {
        self.file().markers
    }
}

#[cfg(test)]
#[test]
fn the_preset_files_parse_and_give_the_published_sizes() {
    let mini = OpticalPreset::GelsightMini.sensor();
    let digit = OpticalPreset::Digit.sensor();
    assert_eq!((mini.image_size, mini.sensing_area_mm), ([320, 240], [18.6, 14.3]));
    assert_eq!((digit.image_size, digit.sensing_area_mm), ([320, 240], [19.0, 16.0]));
    for s in [&mini, &digit] {
        assert_eq!(s.lights.len(), 3);
        assert!(s.lights.iter().all(|l| l.direction[2] < 0.0 && (glam::DVec3::from_array(l.direction).length() - 1.0).abs() < 1e-12));
    }
    assert_eq!(OpticalPreset::Digit.markers().pitch_mm, 1.6);
}

impl OpticalConfig {
    /// The preset with the config's values in place of its own.
    pub fn resolve(&self) -> OpticalSensor {
        let mut s = self.preset.sensor();
        let or = |v: &Option<f64>, d: f64| v.unwrap_or(d);
        // A calibration's values come between the preset's and the config's own.
        if let (Some(file), Some(cal)) = (&self.calibration, &self.loaded_calibration) {
            s.image_size = cal.image_size;
            if let Some(pixel) = cal.pixel_size_mm {
                s.sensing_area_mm = cal.image_size.map(|n| n as f64 * pixel);
            }
            s.elastic_spread_mm = cal.elastic_spread_mm.unwrap_or(s.elastic_spread_mm);
            if let Some(leds) = &cal.leds {
                s.lights = leds.lights.clone().unwrap_or(s.lights);
                s.ambient = leds.ambient.unwrap_or(s.ambient);
                s.background = leds.background.unwrap_or(s.background);
                s.vignetting = leds.vignetting.unwrap_or(s.vignetting);
            }
            let model = match (&cal.light, &cal.leds) {
                (Some(LightModel::Table { .. }), _) => "taxim_table",
                (Some(LightModel::Polynomial { .. }), _) => "polynomial",
                _ => "leds",
            };
            s.calibration = Some(SensorCalibration { file: file.display().to_string(), model: model.into(), light: Some(cal.clone()) });
        }
        s.image_size = self.image_size.unwrap_or(s.image_size);
        s.sensing_area_mm = self.sensing_area_mm.unwrap_or(s.sensing_area_mm);
        s.gel_thickness_mm = or(&self.gel_thickness_mm, s.gel_thickness_mm);
        s.elastic_spread_mm = or(&self.elastic_spread_mm, s.elastic_spread_mm);
        s.lights = self.lights.clone().unwrap_or(s.lights);
        s.ambient = or(&self.ambient, s.ambient);
        s.background = self.background.unwrap_or(s.background);
        s.vignetting = or(&self.vignetting, s.vignetting);
        s.noise_std = or(&self.noise_std, s.noise_std);
        s.markers = self.markers.map(|m| {
            let d = self.preset.markers();
            Markers {
                pitch_mm: or(&m.pitch_mm, d.pitch_mm),
                radius_mm: or(&m.radius_mm, d.radius_mm),
                shift: or(&m.shift, d.shift),
                opacity: or(&m.opacity, d.opacity),
            }
        });
        s
    }
}

impl Check for OpticalConfig {
    // `!(a > b)` on purpose: a NaN in the YAML must fail the checks too.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    fn check(&self, c: &mut Checks) {
        // The resolved values are checked (a preset's are valid), named by the config's fields.
        let s = self.resolve();
        let (key, size) = field!(s.image_size);
        for (i, v) in size.iter().enumerate() {
            c.key(key).index(i).within(*v, 1, 2048);
        }
        let (key, area) = field!(s.sensing_area_mm);
        for (i, v) in area.iter().enumerate() {
            if !(*v > 0.0 && *v <= 100.0) {
                c.key(key).index(i).fail(format!("{v} is out of range: allowed 0 < sensing area <= 100 mm"));
            }
        }
        c.positive(field!(s.gel_thickness_mm), 20.0, "mm");
        c.range(field!(s.elastic_spread_mm), 0.0, 10.0);
        c.range(field!(s.ambient), 0.0, 1.0);
        let (key, tint) = field!(s.background);
        for (i, v) in tint.iter().enumerate() {
            c.key(key).index(i).within(*v, 0.0, 1.0);
        }
        c.range(field!(s.vignetting), 0.0, 0.95);
        c.range(field!(s.noise_std), 0.0, 50.0);
        let lights_key = key!(s.lights);
        if s.lights.is_empty() || s.lights.len() > 8 {
            c.key(lights_key).fail(format!("{} LEDs: allowed 1 ..= 8", s.lights.len()));
        }
        for (i, l) in s.lights.iter().enumerate() {
            let mut at = c.key(lights_key);
            let mut at = at.index(i);
            let d = glam::DVec3::from_array(l.direction);
            if !(d.length() > 1e-9) {
                at.key(key!(l.direction)).fail(format!("{:?} has zero length (or is not a number): an LED needs a direction", l.direction));
            } else if !(d.z < -1e-3 * d.length()) {
                at.key(key!(l.direction)).fail(format!("{:?} points out of the pad: LEDs sit behind the gel (z < 0)", l.direction));
            }
            for (k, v) in l.color.iter().enumerate() {
                at.key(key!(l.color)).index(k).within(*v, 0.0, 4.0);
            }
            at.range(field!(l.falloff), 0.0, 1.0);
        }
        if !s.lights.is_empty() && s.lights.iter().all(|l| glam::DVec3::from_array(l.direction).length() > 1e-9) {
            let det = light_matrix(&s.lights, [0.0, 0.0]).determinant();
            if !(det.abs() > 1e-3) {
                c.key(lights_key).fail(
                    "the LEDs' colours and directions cannot tell slopes apart: the three colour channels need three \
                     independent light directions",
                );
            }
        }
        if let Some(m) = s.markers {
            let mut at = c.key(key!(self.markers));
            at.positive(field!(m.pitch_mm), 50.0, "mm");
            if !(m.radius_mm > 0.0 && m.radius_mm < m.pitch_mm / 2.0) {
                at.key(key!(m.radius_mm)).fail(format!("{} is out of range: allowed 0 < radius < pitch / 2", m.radius_mm));
            }
            at.range(field!(m.shift), 0.0, 5.0);
            at.range(field!(m.opacity), 0.0, 1.0);
        }
    }
}

/// The matrix that maps the gel's inner surface normal to the colour it shows (before the gel's
/// tint, vignetting and ambient term) at image position `at` (-1..=1 per axis): row c is
/// `sum_i falloff_i(at) * color_ic * direction_i`. Photometric stereo inverts it.
pub fn light_matrix(lights: &[Led], at: [f64; 2]) -> glam::DMat3 {
    let mut rows = [glam::DVec3::ZERO; 3];
    for l in lights {
        let d = glam::DVec3::from_array(l.direction).normalize_or_zero();
        let scale = led_falloff(l, at);
        for (row, c) in rows.iter_mut().zip(l.color) {
            *row += scale * c * d;
        }
    }
    glam::DMat3::from_cols(rows[0], rows[1], rows[2]).transpose()
}

/// An LED's brightness factor at image position `at` (-1..=1 per axis): `1 + falloff * s`, `s` the
/// position along the LED's azimuth.
pub fn led_falloff(l: &Led, at: [f64; 2]) -> f64 {
    let azimuth = glam::DVec2::new(l.direction[0], l.direction[1]).normalize_or_zero();
    (1.0 + l.falloff * azimuth.dot(glam::DVec2::from_array(at))).max(0.0)
}

//! `robot.tactile:` the pads' sensors: the phalanx depth cameras, taxel arrays and optical
//! sensors, and how contact points are read from them.

use serde::{Deserialize, Serialize};
use vt_check::{Check, Checks, field, key};

/// The phalanx depth cameras (FORMAT.md, `/tactile/*`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TactileConfig {
    /// Pixels per side of each phalanx camera (the paper: 32).
    pub resolution: u32,
    /// A pixel is in contact when the object surface is at most this far from the pad (mm).
    pub contact_threshold_mm: f64,
    /// Depth range of the cameras from the pad plane (mm); near < 0 keeps surfaces pressed into
    /// the pad.
    pub near_mm: f64,
    pub far_mm: f64,
    /// The sensor model of each phalanx group. All give object-surface points (the paper's
    /// sensor-invariant representation); they differ in where they sample the contact.
    pub sensors: TactileSensorsConfig,
    /// `orthographic` (default: each pixel looks straight out of the pad) or `perspective` (a
    /// pinhole `perspective_standoff_mm` behind the pad whose view covers the pad).
    pub projection: PadProjection,
    pub perspective_standoff_mm: f64,
    /// The optical sensor of the pads whose model is `optical` (default: the `gelsight_mini`
    /// preset). Left out of the config when not given, so other datasets keep their hash.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub optical: Option<super::optical::OpticalConfig>,
    /// Each pad's contact force field from the physics (FORMAT.md, `/tactile/<pad>/force`); none
    /// unless given, so other datasets keep their hash. Needs a backend that gives its contact
    /// forces (`robot.physics.backend: mujoco`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub force_field: Option<ForceFieldConfig>,
    /// Where the optical images are shaded: `cpu` (default, the reference model) or `gpu` (in
    /// WGSL, in the submission that renders their depth views; within one 8-bit level of the CPU).
    /// Left out of the config when `cpu`, so other datasets keep their hash.
    #[serde(skip_serializing_if = "OpticalShading::is_cpu")]
    pub optical_shading: OpticalShading,
}

/// `robot.tactile.optical_shading`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum OpticalShading {
    #[default]
    Cpu,
    Gpu,
}

impl OpticalShading {
    fn is_cpu(&self) -> bool {
        *self == OpticalShading::Cpu
    }
}

/// `robot.tactile.force_field:` the grid each pad's contact force is spread over.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ForceFieldConfig {
    /// Cells per side of the pad's grid (at most the pad camera's `resolution`: a cell gathers
    /// its pixels).
    pub resolution: u32,
    /// The optical pads' gel: its shear modulus (kPa), how far its surface and markers move under
    /// the shear (an incompressible elastic half-space; silicone gels: tens of kPa).
    pub gel_shear_modulus_kpa: f64,
}

impl Default for ForceFieldConfig {
    fn default() -> Self {
        ForceFieldConfig { resolution: 16, gel_shear_modulus_kpa: 50.0 }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PadProjection {
    #[default]
    Orthographic,
    Perspective,
}

impl Default for TactileConfig {
    fn default() -> Self {
        TactileConfig {
            resolution: 32,
            contact_threshold_mm: 2.0,
            near_mm: -5.0,
            far_mm: 30.0,
            sensors: TactileSensorsConfig::default(),
            projection: PadProjection::Orthographic,
            perspective_standoff_mm: 10.0,
            optical: None,
            force_field: None,
            optical_shading: OpticalShading::Cpu,
        }
    }
}

impl Check for TactileConfig {
    // `!(a < b)` on purpose: a NaN in the YAML must fail the checks too.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    fn check(&self, c: &mut Checks) {
        c.range(field!(self.resolution), 4, 256);
        c.range(field!(self.contact_threshold_mm), 0.0, 50.0);
        if !(self.near_mm < self.far_mm) {
            c.key(key!(self.far_mm)).fail(format!("{} must be above near_mm ({})", self.far_mm, self.near_mm));
        }
        let groups = &self.sensors;
        let mut sensors = c.key(key!(self.sensors));
        for (group, m) in [field!(groups.proximal), field!(groups.medial), field!(groups.distal)] {
            match *m {
                SensorModel::TaxelArray { rows, cols } if rows == 0 || cols == 0 || rows > self.resolution || cols > self.resolution => {
                    sensors
                        .key(group)
                        .fail(format!("taxel grid {rows}x{cols} is out of range: 1 ..= resolution ({}) per side", self.resolution))
                }
                SensorModel::Gelsight { gel_thickness_mm } if !(gel_thickness_mm > 0.0 && gel_thickness_mm <= 20.0) => {
                    sensors.key(group).fail(format!("gel_thickness_mm {gel_thickness_mm} is out of range: 0 < t <= 20"))
                }
                _ => {}
            }
        }
        c.range(field!(self.near_mm), -100.0, 100.0);
        c.range(field!(self.far_mm), -100.0, 1000.0);
        c.positive(field!(self.perspective_standoff_mm), 100.0, "mm");
        c.section(field!(self.optical));
        if let Some(f) = &self.force_field {
            let mut field = c.key(key!(self.force_field));
            field.range(field!(f.resolution), 1, self.resolution);
            field.range(field!(f.gel_shear_modulus_kpa), 1.0, 100_000.0);
        }
    }
}

impl TactileConfig {
    /// Whether any pad group has the `optical` model.
    pub fn has_optical(&self) -> bool {
        let s = &self.sensors;
        [s.proximal, s.medial, s.distal].contains(&SensorModel::Optical)
    }

    /// The optical sensor's resolved parameters (the `gelsight_mini` preset unless configured).
    pub fn optical_sensor(&self) -> super::optical::OpticalSensor {
        self.optical.clone().unwrap_or_default().resolve()
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TactileSensorsConfig {
    pub proximal: SensorModel,
    pub medial: SensorModel,
    pub distal: SensorModel,
}

impl TactileSensorsConfig {
    /// The model of a pad in `group` (the robot description's `pads[*].group`).
    pub fn of(&self, group: vt_robot::PadGroup) -> SensorModel {
        match group {
            vt_robot::PadGroup::Proximal => self.proximal,
            vt_robot::PadGroup::Medial => self.medial,
            vt_robot::PadGroup::Distal => self.distal,
        }
    }
}

impl Default for TactileSensorsConfig {
    fn default() -> Self {
        TactileSensorsConfig { proximal: SensorModel::DepthCamera, medial: SensorModel::DepthCamera, distal: SensorModel::DepthCamera }
    }
}

/// A tactile sensor model on a phalanx pad.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "model", deny_unknown_fields)]
pub enum SensorModel {
    /// Every depth-camera pixel within the contact threshold is a point (the paper's sensor).
    DepthCamera,
    /// A grid of taxels (e.g. 224 over the hand): a taxel fires when any surface under it is within
    /// the threshold and reports the surface point at its closest pixel.
    TaxelArray { rows: u32, cols: u32 },
    /// An optical gel pad: the surface indents a gel of this thickness; every indented pixel is a
    /// point (a height map of the indentation).
    Gelsight { gel_thickness_mm: f64 },
    /// An optical gel sensor (`robot.tactile.optical`): the `gelsight` rule with the sensor's gel
    /// thickness for the points, and the RGB image its camera sees (`/tactile/<pad>/image`).
    Optical,
}

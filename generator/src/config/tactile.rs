//! `robot.tactile:` the pads' sensors (depth cameras, taxel arrays, gel pads, optical sensors),
//! assigned per pad by rules, and how contact points are read from them.

use serde::{Deserialize, Serialize};
use vt_check::{Check, Checks, field, key};

pub use vt_dataset::SensorModel;

use super::optical::{OpticalConfig, OpticalSensor};

/// The pad cameras and the pads' sensors (FORMAT.md, `/tactile/*`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TactileConfig {
    /// Pixels per side of each pad camera (the paper: 32).
    pub resolution: u32,
    /// A pixel is in contact when the object surface is at most this far from the pad (mm).
    pub contact_threshold_mm: f64,
    /// Depth range of the cameras from the pad plane (mm); near < 0 keeps surfaces pressed into
    /// the pad.
    pub near_mm: f64,
    pub far_mm: f64,
    /// Which sensor each pad has: rules in order, the first whose `pads` selects a pad gives its
    /// sensor; a pad no rule selects takes the robot description's rules (`sensors:` in its
    /// `robot.yaml`), else a depth camera. All give object-surface points (the paper's
    /// sensor-invariant representation); they differ in where they sample the contact.
    #[serde(deserialize_with = "sensor_rules")]
    pub sensors: Vec<SensorRule>,
    /// `orthographic` (default: each pixel looks straight out of the pad) or `perspective` (a
    /// pinhole `perspective_standoff_mm` behind the pad whose view covers the pad).
    pub projection: PadProjection,
    pub perspective_standoff_mm: f64,
    /// The optical sensor of the pads whose model is `optical` and whose rule names none of its
    /// own (default: the `gelsight_mini` preset). Left out of the config when not given.
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
            sensors: Vec::new(),
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
        for (i, rule) in self.sensors.iter().enumerate() {
            rule.check(&mut c.key(key!(self.sensors)).index(i), self.resolution);
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
    /// Each pad's sensor (`robot.pads` order): the config's rules, then the description's, then
    /// a depth camera. A rule that selects no pad of the robot is an error (a misspelt name or
    /// label would otherwise leave pads with another sensor, silently). Errors: (field path,
    /// message).
    pub fn pad_sensors(&self, robot: &vt_robot::Robot) -> Result<Vec<PadSensor>, (Vec<&'static str>, String)> {
        let robot_rules: Vec<SensorRule> = match &robot.sensors {
            Some(v) => serde_yaml::from_value::<Vec<SensorRule>>(v.clone())
                .map_err(|e| (vec!["robot"], format!("robot '{}': its description's sensors: {e}", robot.name)))?,
            None => Vec::new(),
        };
        let names = || robot.pads.iter().map(|p| p.name.as_str()).collect::<Vec<_>>().join(", ");
        for (from, rules) in [("robot.tactile.sensors", &self.sensors), ("the description's sensors", &robot_rules)] {
            for (i, rule) in rules.iter().enumerate() {
                if !robot.pads.iter().any(|p| p.matches(&rule.pads)) {
                    let path = if from == "robot.tactile.sensors" { vec!["robot", "tactile", "sensors"] } else { vec!["robot"] };
                    let message = format!(
                        "{from}[{i}].pads: '{}' selects no pad of robot '{}' (pads: {}; a rule selects by name, with * and ?, or by a label the description gives)",
                        rule.pads,
                        robot.name,
                        names()
                    );
                    return Err((path, message));
                }
            }
        }
        Ok(robot
            .pads
            .iter()
            .map(|pad| {
                let rule = self.sensors.iter().chain(&robot_rules).find(|r| pad.matches(&r.pads));
                let model = rule.map_or(SensorModel::DepthCamera, |r| r.model);
                let optical = (model == SensorModel::Optical)
                    .then(|| rule.and_then(|r| r.optical.clone()).map_or_else(|| self.optical_sensor(), |o| o.resolve()));
                PadSensor { model, optical }
            })
            .collect())
    }

    /// The optical sensor of the pads whose rule names none of its own: `optical`, resolved
    /// (the `gelsight_mini` preset unless configured).
    pub fn optical_sensor(&self) -> OpticalSensor {
        self.optical.clone().unwrap_or_default().resolve()
    }

    /// Every optical config the tactile section and its rules give, with the field it is at (for
    /// loading calibrations).
    pub fn optical_configs_mut(&mut self) -> impl Iterator<Item = (String, &mut OpticalConfig)> {
        let top = self.optical.as_mut().map(|o| ("robot.tactile.optical".to_string(), o));
        let rules = self
            .sensors
            .iter_mut()
            .enumerate()
            .filter_map(|(i, r)| r.optical.as_mut().map(|o| (format!("robot.tactile.sensors[{i}].optical"), o)));
        top.into_iter().chain(rules)
    }
}

/// One pad's sensor, resolved: its model and, for `optical`, its sensor's parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct PadSensor {
    pub model: SensorModel,
    pub optical: Option<OpticalSensor>,
}

/// `robot.tactile.sensors[i]`: the pads a rule selects and the sensor they get, e.g.
/// `{pads: "*_distal", model: optical, optical: {preset: digit}}` or
/// `{pads: medial, model: taxel_array, rows: 4, cols: 4}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "SensorRuleFields", into = "SensorRuleFields")]
pub struct SensorRule {
    /// A glob over pad names (`*`, `?`) or a label of the description's pads.
    pub pads: String,
    pub model: SensorModel,
    /// The optical sensor of the pads this rule gives the `optical` model (default: the tactile
    /// section's `optical`, else the `gelsight_mini` preset).
    pub optical: Option<OpticalConfig>,
}

/// A sensor rule as written: the model's own fields beside `pads` and `optical`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SensorRuleFields {
    pads: String,
    model: ModelName,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    rows: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    cols: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    gel_thickness_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    optical: Option<OpticalConfig>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
enum ModelName {
    DepthCamera,
    TaxelArray,
    Gelsight,
    Optical,
}

impl TryFrom<SensorRuleFields> for SensorRule {
    type Error = String;
    fn try_from(f: SensorRuleFields) -> Result<Self, String> {
        let extra = |what: &str| format!("'{what}' belongs to another model than {:?}", f.model);
        let model = match f.model {
            ModelName::TaxelArray => match (f.rows, f.cols) {
                (Some(rows), Some(cols)) => SensorModel::TaxelArray { rows, cols },
                _ => return Err("a taxel_array needs rows and cols".into()),
            },
            ModelName::Gelsight => {
                SensorModel::Gelsight { gel_thickness_mm: f.gel_thickness_mm.ok_or("a gelsight pad needs gel_thickness_mm")? }
            }
            ModelName::DepthCamera => SensorModel::DepthCamera,
            ModelName::Optical => SensorModel::Optical,
        };
        if !matches!(model, SensorModel::TaxelArray { .. }) && (f.rows.is_some() || f.cols.is_some()) {
            return Err(extra("rows/cols"));
        }
        if !matches!(model, SensorModel::Gelsight { .. }) && f.gel_thickness_mm.is_some() {
            return Err(extra("gel_thickness_mm"));
        }
        if model != SensorModel::Optical && f.optical.is_some() {
            return Err(extra("optical"));
        }
        Ok(SensorRule { pads: f.pads, model, optical: f.optical })
    }
}

impl From<SensorRule> for SensorRuleFields {
    fn from(r: SensorRule) -> Self {
        let (model, rows, cols, gel_thickness_mm) = match r.model {
            SensorModel::DepthCamera => (ModelName::DepthCamera, None, None, None),
            SensorModel::TaxelArray { rows, cols } => (ModelName::TaxelArray, Some(rows), Some(cols), None),
            SensorModel::Gelsight { gel_thickness_mm } => (ModelName::Gelsight, None, None, Some(gel_thickness_mm)),
            SensorModel::Optical => (ModelName::Optical, None, None, None),
        };
        SensorRuleFields { pads: r.pads, model, rows, cols, gel_thickness_mm, optical: r.optical }
    }
}

impl SensorRule {
    // `!(a <= b)` on purpose: a NaN in the YAML must fail the checks too.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    fn check(&self, c: &mut Checks, resolution: u32) {
        match self.model {
            SensorModel::TaxelArray { rows, cols } => {
                for (k, n) in [("rows", rows), ("cols", cols)] {
                    if n == 0 || n > resolution {
                        c.key(k).fail(format!("taxel grid {rows}x{cols} is out of range: 1 ..= resolution ({resolution}) per side"));
                    }
                }
            }
            SensorModel::Gelsight { gel_thickness_mm } if !(gel_thickness_mm > 0.0 && gel_thickness_mm <= 20.0) => {
                c.key("gel_thickness_mm").fail(format!("{gel_thickness_mm} is out of range: 0 < t <= 20"))
            }
            _ => {}
        }
        c.section(field!(self.optical));
    }
}

/// `robot.tactile.sensors`: a list of rules. The map by pad group older configs wrote
/// (`{proximal: ..., medial: ..., distal: ...}`) is refused with the list it now reads as.
fn sensor_rules<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<SensorRule>, D::Error> {
    struct Rules;
    impl<'de> serde::de::Visitor<'de> for Rules {
        type Value = Vec<SensorRule>;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("a list of sensor rules, e.g. [{pads: \"*_distal\", model: optical}, {pads: \"*\", model: depth_camera}]")
        }
        fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
            let mut out = Vec::new();
            while let Some(rule) = seq.next_element()? {
                out.push(rule);
            }
            Ok(out)
        }
        fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<Self::Value, A::Error> {
            let mut keys = Vec::new();
            while let Some((k, _)) = map.next_entry::<String, serde::de::IgnoredAny>()? {
                keys.push(k);
            }
            let example = keys.iter().map(|k| format!("{{pads: {k}, model: ...}}")).collect::<Vec<_>>().join(", ");
            Err(serde::de::Error::custom(format!(
                "sensors are a list of rules now, one per set of pads (a pad name with * and ?, or a label such as proximal): write [{example}]"
            )))
        }
    }
    d.deserialize_any(Rules)
}

//! The YAML config. Parsing rejects unknown keys; every error names the file, line, column and
//! field path, and out-of-range values name the allowed range.

mod camera;
mod grasp;
mod led;
mod noise;
mod objects;
mod optical;
pub mod optical_calibration;
mod output;
mod overrides;
mod physics;
mod renderer;
mod robot;
mod sampling;
mod scene;
mod schema;
mod tactile;

use std::path::{Path, PathBuf};

pub use camera::*;
pub use grasp::*;
pub use noise::{CameraNoiseConfig, ColorNoise, DepthNoise};
pub use objects::*;
pub use optical::{Led, MarkerConfig, Markers, OpticalConfig, OpticalPreset, OpticalSensor, SensorCalibration, led_falloff, light_matrix};
pub use output::*;
pub use overrides::Override;
pub use physics::*;
pub use renderer::*;
pub use robot::*;
pub use sampling::*;
pub use scene::*;
pub use schema::*;
pub use tactile::*;
pub use vt_check::{Check, Checks, Problem};

/// A field left at its default is left out of the serialized config (`config.json`).
fn is_default<T: Default + PartialEq>(v: &T) -> bool {
    *v == T::default()
}

/// A serde_yaml error as a config error at its line and column.
fn yaml_error(e: serde_path_to_error::Error<serde_yaml::Error>, path: &Path) -> ConfigError {
    let field = e.path().to_string();
    let inner = e.into_inner();
    let loc = inner.location();
    let mut message = inner.to_string();
    // serde_yaml appends " at line L column C"; the location is printed up front instead.
    if let Some(pos) = message.find(" at line ") {
        message.truncate(pos);
    }
    ConfigError {
        file: path.to_path_buf(),
        line: loc.as_ref().map(|l| l.line()),
        column: loc.as_ref().map(|l| l.column()),
        message: strip_field(message, &field),
        field,
    }
}

/// serde_yaml starts some messages with the field path, which the error prints already.
fn strip_field(message: String, field: &str) -> String {
    match message.strip_prefix(&format!("{field}: ")) {
        Some(rest) if !field.is_empty() && field != "." => rest.to_string(),
        _ => message,
    }
}

/// A config error, formatted `FILE:LINE:COL: FIELD: message`.
#[derive(Debug, thiserror::Error)]
#[error("{}{}{}", location(.file, .line, .column), field_prefix(.field), .message)]
pub struct ConfigError {
    pub file: PathBuf,
    pub line: Option<usize>,
    pub column: Option<usize>,
    pub field: String,
    pub message: String,
}

fn location(file: &Path, line: &Option<usize>, column: &Option<usize>) -> String {
    match (line, column) {
        (Some(l), Some(c)) => format!("{}:{l}:{c}: ", file.display()),
        (Some(l), None) => format!("{}:{l}: ", file.display()),
        _ => format!("{}: ", file.display()),
    }
}

fn field_prefix(field: &str) -> String {
    if field.is_empty() || field == "." { String::new() } else { format!("{field}: ") }
}

/// A robot that does not fit the config: the config keys to blame, and why.
type RobotProblem = (Vec<&'static str>, String);

/// A parsed and validated config, with the file it came from.
#[derive(Debug, Clone)]
pub struct LoadedConfig {
    pub config: Config,
    pub path: PathBuf,
    /// Directory that relative paths in the config are resolved against.
    pub base_dir: PathBuf,
    /// The real robot meshes to draw: the config's `robot.assets` (resolved), or the directory
    /// `--robot-assets` passes in (`load_with_assets`); None: the URDF's primitives.
    pub robot_assets: Option<PathBuf>,
    /// The robot (`robot.model`, or `robot.description` and `robot.urdf`), checked against its
    /// description; its joint arrays fill in the grasp config's left-out ones.
    pub robot: Option<vt_robot::Robot>,
    /// Each pad's sensor (`robot.pads` order), from `robot.tactile.sensors` and the robot's own
    /// rules ([`TactileConfig::pad_sensors`]); empty without a robot.
    pub pad_sensors: Vec<PadSensor>,
}

impl LoadedConfig {
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        Self::load_with(path, &[])
    }

    /// Loads `path` with `--set KEY=VALUE` overrides applied on top (Hydra-style: any key, the
    /// same validation). An error in an overridden field names the override, not a file line.
    pub fn load_with(path: &Path, overrides: &[Override]) -> Result<Self, ConfigError> {
        Self::load_with_assets(path, overrides, None)
    }

    /// `load_with` with the robot files in `robot_assets` (`--robot-assets`, over the config's
    /// `robot.assets`): the real meshes of the built-in robots and the upstream files of those built
    /// from them.
    pub fn load_with_assets(path: &Path, overrides: &[Override], robot_assets: Option<&Path>) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|e| ConfigError {
            file: path.to_path_buf(),
            line: None,
            column: None,
            field: String::new(),
            message: format!("cannot read config: {e}"),
        })?;
        if overrides.is_empty() {
            Self::parse_assets(&text, path, robot_assets)
        } else {
            Self::parse_with_assets(&text, path, overrides, robot_assets)
        }
    }

    /// Parses config text; `path` is used for messages and to resolve relative paths.
    pub fn parse(text: &str, path: &Path) -> Result<Self, ConfigError> {
        Self::parse_assets(text, path, None)
    }

    fn parse_assets(text: &str, path: &Path, robot_assets: Option<&Path>) -> Result<Self, ConfigError> {
        let de = serde_yaml::Deserializer::from_str(text);
        let config: Config = serde_path_to_error::deserialize(de).map_err(|e| yaml_error(e, path))?;
        let problems = vt_check::problems(&config);
        if let Some(p) = problems.into_iter().next() {
            let (line, column) = vt_check::locate::locate(text, &p.path).map_or((None, None), |(l, c)| (Some(l), Some(c)));
            return Err(ConfigError { file: path.to_path_buf(), line, column, field: vt_check::display_path(&p.path), message: p.message });
        }
        Self::with_path(config, path, robot_assets).map_err(|(keys, message)| {
            let keys: Vec<vt_check::Seg> = keys.into_iter().map(vt_check::Seg::key).collect();
            let (line, column) = vt_check::locate::locate(text, &keys).map_or((None, None), |(l, c)| (Some(l), Some(c)));
            ConfigError { file: path.to_path_buf(), line, column, field: vt_check::display_path(&keys), message }
        })
    }

    /// `parse` with overrides: the file's YAML tree with each override set into it, then the
    /// same deserialization and checks.
    pub fn parse_with(text: &str, path: &Path, overrides: &[Override]) -> Result<Self, ConfigError> {
        Self::parse_with_assets(text, path, overrides, None)
    }

    fn parse_with_assets(text: &str, path: &Path, overrides: &[Override], robot_assets: Option<&Path>) -> Result<Self, ConfigError> {
        let mut tree: serde_yaml::Value =
            serde_path_to_error::deserialize(serde_yaml::Deserializer::from_str(text)).map_err(|e| yaml_error(e, path))?;
        if tree.is_null() {
            tree = serde_yaml::Value::Mapping(Default::default());
        }
        for o in overrides {
            o.apply(&mut tree)?;
        }
        // The override an error falls in, if any; otherwise the file's own error, located.
        let blame = |field: &str, message: String| {
            let field_keys = overrides::keys(field);
            match overrides.iter().rev().find(|o| field_keys.starts_with(&o.keys) || o.keys.starts_with(&field_keys)) {
                Some(o) => o.error(field, message),
                None => Self::parse_assets(text, path, robot_assets).err().unwrap_or(ConfigError {
                    file: path.to_path_buf(),
                    line: None,
                    column: None,
                    field: field.to_string(),
                    message: format!("{message} (with the --set overrides)"),
                }),
            }
        };
        let config: Config = serde_path_to_error::deserialize(tree).map_err(|e| {
            let field = e.path().to_string();
            let message = strip_field(e.into_inner().to_string(), &field);
            blame(&field, message)
        })?;
        if let Some(p) = vt_check::problems(&config).into_iter().next() {
            return Err(blame(&vt_check::display_path(&p.path), p.message));
        }
        Self::with_path(config, path, robot_assets).map_err(|(keys, message)| blame(&keys.join("."), message))
    }

    /// The loaded config: output dir defaulted, robot loaded and its joint arrays filled in.
    /// Errors: (field path, message).
    fn with_path(mut config: Config, path: &Path, robot_assets: Option<&Path>) -> Result<Self, RobotProblem> {
        if config.output.dir.as_os_str().is_empty() {
            let stem = path.file_stem().map_or_else(|| "dataset".into(), |s| s.to_string_lossy().into_owned());
            config.output.dir = PathBuf::from("out").join(stem);
        }
        let base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut loaded =
            LoadedConfig { config, path: path.to_path_buf(), base_dir, robot_assets: None, robot: None, pad_sensors: Vec::new() };
        loaded.robot_assets = match robot_assets {
            Some(dir) => Some(dir.to_path_buf()),
            None => loaded.config.robot.as_ref().and_then(|r| r.assets.as_ref()).map(|p| loaded.resolve(p)),
        };
        loaded.load_optical_calibration()?;
        if let Some(rc) = loaded.config.robot.clone() {
            let robot = loaded.load_robot(&rc)?;
            let grasp = rc.grasp.with_robot_defaults(&robot);
            if let Some((key, message)) = grasp.mismatch(&robot) {
                return Err((vec!["robot", "grasp", key], message));
            }
            let record = loaded.config.sampling.record.as_ref();
            let motion =
                record.and_then(|r| r.finger_motion.as_ref()).into_iter().flat_map(|m| &m.joints).map(|j| ("finger_motion", &j.joint));
            let roll = record.and_then(|r| r.finger_roll.as_ref()).into_iter().flat_map(|m| &m.joints).map(|j| ("finger_roll", &j.joint));
            for (section, joint) in motion.chain(roll) {
                if !robot.hand.iter().any(|h| &h.name == joint) {
                    let hand: Vec<&str> = robot.hand.iter().map(|h| h.name.as_str()).collect();
                    let message = format!("'{joint}' is not a hand joint of robot '{}' ({})", robot.name, hand.join(", "));
                    return Err((vec!["sampling", "record", section, "joints"], message));
                }
            }
            if let Some(pivot) = record.and_then(|r| r.pivot.as_ref()) {
                match &pivot.pads {
                    None if robot.kind != vt_robot::GraspKind::ParallelJaw => {
                        let message = format!(
                            "gravity pivoting turns an object about the line between two pads: robot '{}' is not a parallel-jaw gripper, so give the pads its pinch may use (e.g. [\"th_*\", \"*\"])",
                            robot.name
                        );
                        return Err((vec!["sampling", "record", "pivot", "pads"], message));
                    }
                    None => {}
                    Some(patterns) => {
                        if let Some(none) = patterns.iter().find(|p| !robot.pads.iter().any(|pad| pad.matches(p))) {
                            let names: Vec<&str> = robot.pads.iter().map(|p| p.name.as_str()).collect();
                            let message = format!("'{none}' selects no pad of robot '{}' ({})", robot.name, names.join(", "));
                            return Err((vec!["sampling", "record", "pivot", "pads"], message));
                        }
                    }
                }
            }
            loaded.config.robot.as_mut().expect("cloned above").grasp = grasp;
            loaded.pad_sensors = rc.tactile.pad_sensors(&robot)?;
            // Robot assets given, and none of the robot's meshes in them: a wrong folder, which
            // would otherwise draw the primitive robot.
            if let (Some(dir), Some(first)) = (&loaded.robot_assets, robot.model.visual_meshes_left_out.first()) {
                let message = format!(
                    "robot assets {}: none of the meshes of robot '{}' are there (e.g. {first}, looked for as {}). Fetch them with \
                     `scripts/robot-assets` (it prints the folder), or point --robot-assets at a folder with its layout",
                    dir.display(),
                    robot.name,
                    dir.join(first.strip_prefix("package://").unwrap_or(first)).display()
                );
                return Err((vec!["robot"], message));
            }
            loaded.robot = Some(robot);
        }
        Ok(loaded)
    }

    /// Loads the calibration of every optical sensor the config gives (`robot.tactile.optical`,
    /// `robot.tactile.sensors[i].optical`), each checked against its sensor's configured image
    /// size. Errors: (field path, message).
    fn load_optical_calibration(&mut self) -> Result<(), RobotProblem> {
        let base_dir = self.base_dir.clone();
        let Some(robot) = self.config.robot.as_mut() else { return Ok(()) };
        for (at, optical) in robot.tactile.optical_configs_mut() {
            let Some(file) = &optical.calibration else { continue };
            let keys = if at.contains("sensors") { vec!["robot", "tactile", "sensors"] } else { vec!["robot", "tactile", "optical"] };
            let file = if file.is_absolute() { file.clone() } else { base_dir.join(file) };
            let top = !at.contains("sensors");
            let cal = match optical_calibration::load_calibration(&file) {
                Ok(cal) => cal,
                Err(e) if top => return Err((vec!["robot", "tactile", "optical", "calibration"], e)),
                Err(e) => return Err((keys, format!("{at}.calibration: {e}"))),
            };
            if cal.pixel_size_mm.is_none() && optical.sensing_area_mm.is_none() {
                let keys = if top { vec!["robot", "tactile", "optical", "sensing_area_mm"] } else { keys };
                let message = format!(
                    "the calibration does not give the pixel size (Taxim's files do not): set {at}.sensing_area_mm \
                     to the image's {} x {} pixels times the unit's pixel size (mm)",
                    cal.image_size[0], cal.image_size[1]
                );
                return Err((keys, message));
            }
            if let Some(size) = optical.image_size.filter(|s| cal.background.is_some() && *s != cal.image_size) {
                let keys = if top { vec!["robot", "tactile", "optical", "calibration"] } else { keys };
                let message = format!("the calibration's images are {:?}, {at}.image_size {size:?}: leave image_size out", cal.image_size);
                return Err((keys, message));
            }
            optical.loaded_calibration = Some(std::sync::Arc::new(cal));
        }
        Ok(())
    }

    /// The robot a config's `robot` section names. Errors: (field path, message).
    fn load_robot(&self, rc: &RobotConfig) -> Result<vt_robot::Robot, RobotProblem> {
        let urdf = rc.urdf.as_ref().map(|p| self.resolve(p));
        match (&rc.model, &rc.description) {
            (Some(_), Some(_)) => Err((vec!["robot", "description"], "give either a built-in robot.model or a robot.description".into())),
            (_, Some(d)) => vt_robot::Robot::from_files(&self.resolve(d), urdf.as_deref(), &self.package_dirs(rc))
                .map_err(|e| (vec!["robot", "description"], e.to_string())),
            (model, None) => {
                let name = model.as_deref().unwrap_or(vt_robot::DEFAULT_ROBOT);
                let packages = self.package_dirs(rc);
                match urdf {
                    // A URDF of one's own with the built-in robot's names and description.
                    Some(u) => vt_robot::Robot::builtin_with_urdf(name, &u, &packages).map_err(|e| (vec!["robot", "urdf"], e.to_string())),
                    None => {
                        let field = if rc.model.is_some() { vec!["robot", "model"] } else { vec!["robot"] };
                        vt_robot::Robot::builtin_with(name, &packages).map_err(|e| (field, e.message))
                    }
                }
            }
        }
    }

    /// Where a robot's `package://` files are looked for besides the folders above its URDF: the
    /// config's `robot.package_dirs`, then the robot assets folder (`scripts/robot-assets` unpacks
    /// the upstream packages there).
    fn package_dirs(&self, rc: &RobotConfig) -> Vec<PathBuf> {
        rc.package_dirs.iter().map(|p| self.resolve(p)).chain(self.robot_assets.clone()).collect()
    }

    /// Where vtgen keeps what it computes once and reuses across runs (the robots' convex
    /// decompositions): `$XDG_CACHE_HOME`, else `$HOME/.cache`; None when neither is set.
    pub fn cache_dir(&self) -> Option<PathBuf> {
        std::env::var_os("XDG_CACHE_HOME").map(PathBuf::from).or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
    }

    /// Resolves a path written in the config relative to the config file's directory.
    pub fn resolve(&self, p: &Path) -> PathBuf {
        if p.is_absolute() { p.to_path_buf() } else { self.base_dir.join(p) }
    }
}

#[cfg(test)]
mod tests;

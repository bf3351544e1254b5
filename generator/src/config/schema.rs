//! The root of the config: the sections of every stage composed (each in a file of its own,
//! with its defaults and its checks), the cross-section checks, and the canonical JSON that
//! identifies a dataset.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use vt_check::{Check, Checks, field, key};

use super::{CameraConfig, ObjectSpec, OutputConfig, RendererConfig, RobotConfig, SamplingConfig, SceneConfig};

/// Every section but `objects` has a default (the paper's camera, 200 x 100 samples per object,
/// split 4:1, …), so `objects: [...]` alone is a config; `vtgen config FILE` prints it resolved.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// Root of all randomness: the same seed and config give byte-identical datasets.
    #[serde(default)]
    pub seed: u64,
    /// Catalogue ids (`003_cracker_box`, …) or custom objects `{id, mesh, …}`.
    pub objects: Vec<ObjectSpec>,
    /// A YCB download (`<dir>/<id>/google_16k/textured.obj`); when absent, procedural stand-ins.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ycb_dir: Option<PathBuf>,
    #[serde(default)]
    pub sampling: SamplingConfig,
    #[serde(default)]
    pub camera: CameraConfig,
    #[serde(default)]
    pub scene: SceneConfig,
    #[serde(default)]
    pub renderer: RendererConfig,
    /// Domain randomization (`randomizers/README.md`); off by default.
    #[serde(default, skip_serializing_if = "super::is_default")]
    pub randomization: vt_randomizers::RandomizationConfig,
    /// The arm and hand and the grasp loop. Without it, the object floats in front of the camera.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<RobotConfig>,
    #[serde(default)]
    pub output: OutputConfig,
}

/// Every problem of a parsed config, section by section (the loader reports the first).
impl Check for Config {
    fn check(&self, c: &mut Checks) {
        self.check_objects(c);
        c.section(field!(self.sampling));
        c.section(field!(self.camera));
        c.section(field!(self.renderer));
        c.section(field!(self.randomization));
        c.section(field!(self.scene));
        c.section(field!(self.output));
        c.section(field!(self.robot));
        self.check_record(c);
    }
}

impl Config {
    /// Episodes need the grasp loop, and their rates fit its physics step.
    fn check_record(&self, c: &mut Checks) {
        let Some(record) = &self.sampling.record else { return };
        let sampling_config = &self.sampling;
        let mut sampling = c.key(key!(self.sampling));
        let mut at = sampling.key(key!(sampling_config.record));
        match &self.robot {
            None => at.fail("episodes record a grasp: the config needs a robot section"),
            Some(robot) => {
                record.check_rates(robot.physics.timestep, &mut at);
                if robot.grasp.regrasp_on_loss {
                    at.fail("an episode is one grasp's time series: robot.grasp.regrasp_on_loss works with snapshots only");
                }
            }
        }
        at.section(field!(record.finger_motion));
        at.section(field!(record.pivot));
        at.section(field!(record.finger_roll));
        at.section(field!(record.approach));
        record.check_approach(&mut at);
        record.check_turn_target(&mut at);
    }

    /// Object ids known or well-formed, custom masses in range, no object twice.
    fn check_objects(&self, c: &mut Checks) {
        let mut objects = c.key(key!(self.objects));
        if self.objects.is_empty() {
            objects.fail("at least one object is required");
        }
        let catalog = vt_objects::Catalog::builtin();
        let mut seen = std::collections::BTreeSet::new();
        for (i, o) in self.objects.iter().enumerate() {
            let mut item = objects.index(i);
            let id = o.id();
            if let ObjectSpec::Catalog(id) = o
                && catalog.get(id).is_none()
            {
                let known: Vec<&str> = catalog.ids().collect();
                item.fail(format!("unknown object id '{id}'; the catalogue has: {}", known.join(", ")));
            }
            if let ObjectSpec::Custom(custom) = o {
                custom.check(&mut item);
            }
            if !seen.insert(id.to_string()) {
                item.fail(format!("object '{id}' is listed twice"));
            }
        }
    }
}

impl Config {
    /// Canonical JSON of the dataset's definition: what `config_sha256` hashes. Locations that do
    /// not change the data (output directory, YCB directory) are left out, so the same dataset
    /// generated on machines with different paths carries the same hash and bytes.
    pub fn canonical_json(&self) -> String {
        let mut c = self.clone();
        c.output.dir = PathBuf::new();
        c.ycb_dir = None;
        if let Some(r) = c.robot.as_mut() {
            r.assets = None;
        }
        serde_json::to_string(&c).expect("config serializes")
    }
}

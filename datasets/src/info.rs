//! `/sample/info` as types: what the generator writes and every Rust reader (inspect, stats,
//! export, validate, preview, the trainer) reads, instead of string keys into a JSON value.
//! FORMAT.md ("`/sample/info`") documents each field; `SAMPLE_INFO_SCHEMA` in `writer.rs` is the
//! JSON schema shards carry, and a test holds it to these types.
//!
//! The message stays an open JSON object: readers ignore keys they do not know, and the parts a
//! dataset may lack (the robot's, touch, occlusion in datasets made before it existed) are options.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::Pose;

/// An episode shard's `vtgen.shard` `episode` entry (FORMAT.md, "Episodes"): the episode's object
/// and trajectory, its length and its streams' rates (each also as physics steps per period).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpisodeRecord {
    pub object_id: String,
    pub trajectory: u32,
    /// Camera frames (samples) of the episode.
    pub frames: u64,
    pub duration_s: f64,
    pub physics_hz: f64,
    pub camera_hz: f64,
    pub tactile_hz: f64,
    pub state_hz: f64,
    pub camera_period_steps: u64,
    pub tactile_period_steps: u64,
    pub state_period_steps: u64,
    /// With the grasp recorded: the settled grasp's time in the episode (s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub settled_s: Option<f64>,
}

impl EpisodeRecord {
    /// The record as shards store it: one line of JSON, keys in alphabetical order.
    pub fn to_json(&self) -> String {
        serde_json::to_value(self).expect("plain data serializes").to_string()
    }
}

/// The two splits; trajectories (grasps) are split 4:1, never samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Split {
    Train,
    Test,
}

impl Split {
    pub const ALL: [Split; 2] = [Split::Train, Split::Test];

    pub fn as_str(self) -> &'static str {
        match self {
            Split::Train => "train",
            Split::Test => "test",
        }
    }
}

impl std::fmt::Display for Split {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(self.as_str())
    }
}

impl std::str::FromStr for Split {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "train" => Ok(Split::Train),
            "test" => Ok(Split::Test),
            _ => Err(format!("'{s}' is not a split: train or test")),
        }
    }
}

/// One sample's `/sample/info`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SampleInfo {
    pub split: Split,
    /// Index within the split.
    pub index: u64,
    pub object_id: String,
    /// Position of the object in the config's object list (and in `models_info.json`).
    pub object_index: u32,
    /// The target object's id in `/camera/mask`.
    pub mask_id: u8,
    pub trajectory: u32,
    pub instance: u32,
    /// False for the canonical (unrandomized) look.
    pub randomized: bool,
    /// The randomizer's draw (light, floor, backdrop, camera jitter, candidate distractors): its
    /// record as `vt_randomizers::AppearanceInfo` writes it.
    pub appearance: serde_json::Value,
    /// The other objects placed on the floor.
    #[serde(default)]
    pub distractors: Vec<PlacedDistractor>,
    /// Pixels of the target object in the mask.
    pub visible_pixels: u64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub occlusion: Option<OcclusionInfo>,
    #[serde(rename = "T_world_camera")]
    pub t_world_camera: Pose,
    #[serde(rename = "T_camera_object")]
    pub t_camera_object: Pose,
    /// The robot's part, when the config has a robot.
    #[serde(flatten, default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<RobotInfo>,
    /// In an episode dataset: where the frame is in its episode (`instance` is the frame).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub episode: Option<EpisodeFrameInfo>,
}

/// A camera frame's place in its episode.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EpisodeFrameInfo {
    /// The frame's index in the episode (also `instance`).
    pub frame: u32,
    /// Simulated time since the episode's start (the settled grasp, or the object put in the
    /// open hand when the grasp is recorded), seconds.
    pub time_s: f64,
    /// The arm move under way (0-based); the settled grasp (frame 0 unless the grasp is
    /// recorded) and the frames before it are before move 0.
    pub arm_move: u32,
    /// With the grasp recorded (`sampling.record.grasp`): the settled grasp's time (s); the frames
    /// before it show the object put in the open hand, the fingers closing and the wrist turning.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub settled_s: Option<f64>,
}

/// The state stream of an episode (`/episode/state`): the robot's joints and the object's ground
/// truth at one instant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StateRecord {
    /// Simulated time since the episode's start, seconds.
    pub time_s: f64,
    /// Every joint that moves on its own, by name (as `/sample/info` `joint_positions`).
    pub joint_positions: BTreeMap<String, f64>,
    #[serde(rename = "T_world_object")]
    pub t_world_object: Pose,
    #[serde(rename = "T_camera_object")]
    pub t_camera_object: Pose,
    #[serde(rename = "T_world_palm")]
    pub t_world_palm: Pose,
    /// The object's twist in the world frame: linear (m/s) and angular (rad/s) velocity, from
    /// the previous physics step (zero at the episode's start).
    pub linear_velocity: [f64; 3],
    pub angular_velocity: [f64; 3],
    /// Touch links in contact with the object (wire name `phalanges_in_contact`, format version 1).
    #[serde(rename = "phalanges_in_contact")]
    pub links_in_contact: Vec<String>,
}

/// A distractor object standing on the floor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlacedDistractor {
    pub object_id: String,
    pub mask_id: u8,
    #[serde(rename = "T_world_distractor")]
    pub t_world_distractor: Pose,
}

/// The paper's occlusion level and the silhouette figures.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OcclusionInfo {
    /// Share of the model points (posed by the ground truth) with no depth point within ε.
    pub level: f64,
    pub visible_points: u64,
    pub model_points: u64,
    pub epsilon_mm: f64,
    /// Pixels of the object's silhouette had it been drawn alone, and the share of them visible.
    pub silhouette_pixels: u64,
    pub silhouette_visible_fraction: f64,
}

/// The grasp that holds the object in this sample.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotInfo {
    pub physics_backend: String,
    /// The robot's touch links touching the object (`Robot::touch_links`); wire name
    /// `phalanges_in_contact` (format version 1).
    #[serde(rename = "phalanges_in_contact")]
    pub links_in_contact: Vec<String>,
    /// Object motion in the hand since the grasp settled.
    pub slip_mm: f64,
    pub slip_deg: f64,
    /// Deepest penetration of a hand link into the object.
    pub penetration_mm: f64,
    /// Attempts the trajectory took before a grasp held.
    pub grasp_attempts: u32,
    /// With `robot.grasp.regrasp_on_loss`: the attempt (1-based) whose grasp recorded this
    /// instance; where it changes along a trajectory, a grasp was lost and a new one made.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grasp: Option<u32>,
    /// The episode's turn target (degrees; with `sampling.record.turn_target_deg`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub turn_target_deg: Option<f64>,
    /// Every robot joint (rad), by name.
    pub joint_positions: BTreeMap<String, f64>,
    #[serde(rename = "T_world_palm")]
    pub t_world_palm: Pose,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tactile: Option<TouchInfo>,
}

/// How the tactile point cloud of the sample was made, and its size per pad.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TouchInfo {
    pub contact_threshold_mm: f64,
    /// Each pad's sensor model (the config's `robot.tactile.sensors` rules, then the robot's).
    /// Datasets from before sensors were assigned per pad have one entry per pad group
    /// (`proximal`, `medial`, `distal`) instead.
    pub sensors: BTreeMap<String, SensorModel>,
    pub near_mm: f64,
    pub far_mm: f64,
    /// Sensing area of each pad: (length along the finger, width), metres.
    pub pads: BTreeMap<String, [f64; 2]>,
    /// Tactile points per pad.
    pub points: BTreeMap<String, u64>,
    /// Per pad with an optical sensor: the sensor's parameters in this sample (the configured
    /// sensor, varied per sample when `randomization.tactile_sensors` is on).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub optical: Option<BTreeMap<String, serde_json::Value>>,
    /// With `robot.tactile.force_field`: per pad, the contact forces its field was made from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forces: Option<BTreeMap<String, PadForceInfo>>,
    /// With `robot.tactile.force_field`: the force of every contact of the hand on the object's
    /// side, summed (N, world frame): in a still hold, the object's weight.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hand_force_n: Option<[f64; 3]>,
}

/// A pad's tactile sensor model. Every model gives object-surface points (the paper's
/// sensor-invariant representation); they differ in where they sample the contact.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "model", deny_unknown_fields)]
pub enum SensorModel {
    /// Every depth-camera pixel within the contact threshold is a point (the paper's sensor).
    DepthCamera,
    /// A grid of taxels: a taxel fires when any surface under it is within the threshold and
    /// reports the surface point at its closest pixel.
    TaxelArray { rows: u32, cols: u32 },
    /// An optical gel pad: the surface indents a gel of this thickness; every indented pixel is a
    /// point (a height map of the indentation).
    Gelsight { gel_thickness_mm: f64 },
    /// An optical gel sensor with its camera: the `gelsight` rule with the sensor's gel thickness
    /// for the points, and the RGB image its camera sees (`/tactile/<pad>/image`).
    Optical,
}

/// The physics' contact forces on one pad (FORMAT.md, "Force fields"), in the pad frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PadForceInfo {
    /// The force of the contacts on the pad's sensing area (N): what its field sums to.
    pub force_n: [f64; 3],
    /// The force of every contact on the pad's link, on the sensing area or not (N).
    pub link_force_n: [f64; 3],
    /// The physics' contact points on the sensing area.
    pub contacts: u32,
    /// The friction coefficient of the slip rule.
    pub friction: f64,
}

impl SampleInfo {
    /// The info as the JSON object shards store (keys sorted, as `serde_json` orders a map).
    pub fn to_value(&self) -> serde_json::Value {
        serde_json::to_value(self).expect("plain data serializes")
    }

    /// Tactile points of the sample, all pads together (`None` without touch).
    pub fn tactile_points(&self) -> Option<u64> {
        self.robot.as_ref().and_then(|r| r.tactile.as_ref()).map(|t| t.points.values().sum())
    }

    /// Touch links touching the object (empty without a robot).
    pub fn links_in_contact(&self) -> &[String] {
        self.robot.as_ref().map_or(&[], |r| &r.links_in_contact)
    }
}

/// A sample info with every field filled (with `robot`: the robot's, touch and an episode frame
/// too): the key lists of `format.json` and the tests' fixture.
pub(crate) fn example_info(robot: bool) -> SampleInfo {
    let pose = Pose { position: [0.1, -0.2, 0.7], orientation: [0.0, 0.6, 0.0, 0.8] };
    SampleInfo {
        split: Split::Test,
        index: 42,
        object_id: "037_scissors".into(),
        object_index: 1,
        mask_id: 1,
        trajectory: 9,
        instance: 3,
        randomized: true,
        appearance: serde_json::json!({"randomized": true}),
        distractors: vec![PlacedDistractor { object_id: "011_banana".into(), mask_id: 2, t_world_distractor: pose }],
        visible_pixels: 1234,
        occlusion: Some(OcclusionInfo {
            level: 0.87,
            visible_points: 65,
            model_points: 500,
            epsilon_mm: 5.0,
            silhouette_pixels: 4000,
            silhouette_visible_fraction: 0.31,
        }),
        t_world_camera: pose,
        t_camera_object: pose.inverse(),
        robot: robot.then(|| RobotInfo {
            physics_backend: "rapier".into(),
            links_in_contact: vec!["ff_distal".into(), "th_distal".into()],
            slip_mm: 1.5,
            slip_deg: 2.0,
            penetration_mm: 0.4,
            grasp_attempts: 2,
            // Optional, only with `regrasp_on_loss`.
            grasp: None,
            // Optional, only in episodes with a turn target: not a key every robot sample has.
            turn_target_deg: None,
            joint_positions: [("ff_j0".to_string(), 0.1)].into(),
            t_world_palm: pose,
            tactile: Some(TouchInfo {
                contact_threshold_mm: 2.0,
                sensors: [("ff_distal".to_string(), SensorModel::DepthCamera)].into(),
                near_mm: -5.0,
                far_mm: 30.0,
                pads: [("ff_distal".to_string(), [0.02, 0.015])].into(),
                points: [("ff_distal".to_string(), 40), ("th_distal".to_string(), 12)].into(),
                optical: Some([("th_distal".to_string(), serde_json::json!({"image_size": [320, 240]}))].into()),
                forces: Some(
                    [(
                        "ff_distal".to_string(),
                        PadForceInfo { force_n: [0.1, 0.0, -2.0], link_force_n: [0.1, 0.0, -2.1], contacts: 3, friction: 1.0 },
                    )]
                    .into(),
                ),
                hand_force_n: Some([0.0, 0.0, -3.4]),
            }),
        }),
        episode: robot.then_some(EpisodeFrameInfo { frame: 3, time_s: 0.1, arm_move: 0, settled_s: None }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_the_robot_part_is_flat_and_optional() {
        for robot in [false, true] {
            let info = example_info(robot);
            let v = info.to_value();
            assert_eq!(serde_json::from_value::<SampleInfo>(v.clone()).unwrap(), info);
            // The robot's fields sit at the top level, as FORMAT.md lists them.
            assert_eq!(v.get("physics_backend").is_some(), robot);
            assert_eq!(v["split"], "test");
            assert_eq!(v["T_camera_object"]["orientation"].as_array().unwrap().len(), 4);
        }
        assert_eq!(example_info(true).tactile_points(), Some(52));
        assert_eq!(example_info(false).tactile_points(), None);
    }

    #[test]
    fn older_infos_without_occlusion_or_distractors_still_read_and_unknown_keys_are_ignored() {
        let mut v = example_info(false).to_value();
        let o = v.as_object_mut().unwrap();
        o.remove("occlusion");
        o.remove("distractors");
        o.insert("added_later".into(), serde_json::json!(1));
        let info: SampleInfo = serde_json::from_value(v).unwrap();
        assert!(info.occlusion.is_none() && info.distractors.is_empty());
        // A wrong split is named.
        let mut v = example_info(false).to_value();
        v["split"] = "validation".into();
        let e = serde_json::from_value::<SampleInfo>(v).unwrap_err().to_string();
        assert!(e.contains("validation"), "{e}");
    }

    #[test]
    fn the_schema_shards_carry_lists_the_typed_fields() {
        let schema: serde_json::Value = serde_json::from_str(crate::writer::SAMPLE_INFO_SCHEMA).unwrap();
        let v = example_info(true).to_value();
        for (key, prop) in schema["properties"].as_object().unwrap() {
            let value = v.get(key).unwrap_or_else(|| panic!("the schema's '{key}' is not a SampleInfo field"));
            let ok = match prop["type"].as_str().unwrap() {
                "string" => value.is_string(),
                "integer" => value.is_u64(),
                "boolean" => value.is_boolean(),
                "object" => value.is_object(),
                "number" => value.is_number(),
                "array" => value.is_array(),
                other => panic!("type {other}"),
            };
            assert!(ok, "'{key}' is {value}, the schema says {prop}");
        }
        for key in schema["required"].as_array().unwrap() {
            assert!(v.get(key.as_str().unwrap()).is_some());
        }
    }
}

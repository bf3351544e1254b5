//! The format's facts every reader checks, as one JSON document: `datasets/format.json`, written
//! from this crate's constants and types by the test below, which fails when the checked-in file
//! differs. The Python reader (`vtdata.format`) and the Foxglove reader (`datasets/ts`) keep
//! their own constants and assert them against that file in their tests, so a fact changed here
//! fails every reader that still says otherwise. FORMAT.md explains each fact.

use foxglove::Encode;
use foxglove::schemas::{CameraCalibration, FrameTransforms, PointCloud, PoseInFrame, RawImage, SceneUpdate};
use serde_json::{Value, json};

use crate::info::example_info;
use crate::sample::ShardMeta;
use crate::writer::{SAMPLE_INFO_SCHEMA_NAME, STATE_RECORD_SCHEMA_NAME};
use crate::{
    EPISODE_METADATA_KEY, EpisodeRecord, FORMAT_NAME, FORMAT_VERSION, GRASP_STATS_KEY, GraspStats, MANIFEST_FILE, MODELS_DIR,
    MODELS_INFO_FILE, Manifest, OCCLUSION_HISTOGRAM_KEY, OcclusionBin, OcclusionHistogram, PARTIAL_SUFFIX, ROBOT_DIR, SAMPLE_PERIOD_NS,
    SHARD_METADATA, SOURCES_FILE, StateRecord, encodings, force_cells, frames, marker_points, mask_ids, tactile_points, topics,
};

/// When a topic is in a sample: `always`, with a robot, with a depth noise model, for pads with an
/// optical sensor, in episodes, or where the scene's meshes change.
#[derive(Clone, Copy)]
enum When {
    Always,
    Robot,
    DepthNoise,
    Optical,
    ForceField,
    Episode,
    SceneChange,
}

impl When {
    fn key(self) -> &'static str {
        match self {
            When::Always => "always",
            When::Robot => "robot",
            When::DepthNoise => "depth_noise",
            When::Optical => "optical",
            When::ForceField => "force_field",
            When::Episode => "episode",
            When::SceneChange => "scene_change",
        }
    }
}

/// A packed point layout: its fields (name, offset, type) and stride.
fn packed(fields: &[(&str, u32, bool)], stride: u32) -> Value {
    let field = |&(name, offset, unsigned): &(&str, u32, bool)| json!({"name": name, "offset": offset, "type": if unsigned { "UINT32" } else { "FLOAT32" }});
    json!({"fields": fields.iter().map(field).collect::<Vec<_>>(), "point_stride": stride})
}

/// A protobuf topic: its schema from the Foxglove type the writer encodes.
fn protobuf<T: Encode>(topic: &str, image_encoding: Option<&str>, when: When) -> Value {
    let schema = T::get_schema().expect("Foxglove schemas carry their descriptor");
    let mut t = json!({"topic": topic, "schema": schema.name, "message_encoding": T::get_message_encoding()});
    if let Some(e) = image_encoding {
        t["image_encoding"] = e.into();
    }
    t["when"] = when.key().into();
    t
}

fn json_topic(topic: &str, schema: &str, when: When) -> Value {
    json!({"topic": topic, "schema": schema, "message_encoding": "json", "when": when.key()})
}

/// The keys a record serializes to, in its order.
fn keys_of<T: serde::Serialize>(record: &T) -> Vec<String> {
    match serde_json::to_value(record).expect("plain data serializes") {
        Value::Object(m) => m.keys().cloned().collect(),
        other => panic!("not a record: {other}"),
    }
}

/// `datasets/format.json`.
pub fn description() -> Value {
    use When::*;
    let pose = crate::Pose::IDENTITY;
    let with_robot = example_info(true);
    let robot = with_robot.robot.clone().expect("the example has a robot");
    let grasp = GraspStats::default();
    let manifest = Manifest {
        format: FORMAT_NAME.into(),
        format_version: FORMAT_VERSION,
        generator: String::new(),
        seed: 0,
        config_sha256: String::new(),
        complete: true,
        splits: Default::default(),
        grasp: Some(grasp.clone()),
        occlusion: Some(OcclusionHistogram::new([0; 3])),
    };
    let episode = EpisodeRecord {
        object_id: String::new(),
        trajectory: 0,
        frames: 0,
        duration_s: 0.0,
        physics_hz: 0.0,
        camera_hz: 0.0,
        tactile_hz: 0.0,
        state_hz: 0.0,
        camera_period_steps: 0,
        tactile_period_steps: 0,
        state_period_steps: 0,
        settled_s: None,
    };
    let state = StateRecord {
        time_s: 0.0,
        joint_positions: Default::default(),
        t_world_object: pose,
        t_camera_object: pose,
        t_world_palm: pose,
        linear_velocity: [0.0; 3],
        angular_velocity: [0.0; 3],
        links_in_contact: Vec::new(),
    };
    let image = |topic: &str, encoding: &str, when: When| protobuf::<RawImage>(topic, Some(encoding), when);
    let mut sample_topics = vec![
        image(topics::RGB, encodings::RGB8, Always),
        image(topics::DEPTH, encodings::DEPTH_32FC1, Always),
        image(topics::DEPTH_NOISY, encodings::DEPTH_32FC1, DepthNoise),
        image(topics::MASK, encodings::MASK_MONO8, Always),
        protobuf::<CameraCalibration>(topics::CALIBRATION, None, Always),
        protobuf::<PoseInFrame>(topics::OBJECT_POSE, None, Always),
        protobuf::<FrameTransforms>(topics::TF, None, Always),
        json_topic(topics::SAMPLE_INFO, SAMPLE_INFO_SCHEMA_NAME, Always),
        protobuf::<PointCloud>(topics::TACTILE_POINTS, None, Robot),
        protobuf::<SceneUpdate>(topics::SCENE_MODELS, None, SceneChange),
        json_topic(topics::EPISODE_STATE, STATE_RECORD_SCHEMA_NAME, Episode),
    ];
    for t in &mut sample_topics {
        let required = topics::ALL.contains(&t["topic"].as_str().expect("a name"));
        t.as_object_mut().expect("an object").insert("required".into(), required.into());
    }
    let pad = "{pad}";
    let range = |r: &std::ops::RangeInclusive<u8>| json!([r.start(), r.end()]);
    json!({
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "sample_period_ns": SAMPLE_PERIOD_NS,
        "files": {
            "manifest": MANIFEST_FILE,
            "sources": SOURCES_FILE,
            "robot_dir": ROBOT_DIR,
            "models_dir": MODELS_DIR,
            "models_info": format!("{MODELS_DIR}/{MODELS_INFO_FILE}"),
            "shard": crate::shard_file("{split}", 0).replace("00000", "{index:05}"),
            "partial_suffix": PARTIAL_SUFFIX,
        },
        "shard_metadata": {
            "name": SHARD_METADATA,
            "keys": ShardMeta::KEYS,
            "optional_keys": {
                OCCLUSION_HISTOGRAM_KEY: "the shard's samples per occlusion bin (JSON array, occlusion_bins order)",
                GRASP_STATS_KEY: "grasp statistics of the trajectories that start in the shard (JSON, records.grasp_stats)",
                EPISODE_METADATA_KEY: "present in episode shards only (JSON, records.episode)",
            },
        },
        "topics": sample_topics,
        "pad_topics": [
            image(&topics::tactile_depth(pad), encodings::DEPTH_32FC1, Robot),
            image(&topics::tactile_image(pad), encodings::RGB8, Optical),
            image(&topics::tactile_reference(pad), encodings::RGB8, Optical),
            protobuf::<PointCloud>(&topics::tactile_force(pad), None, ForceField),
            protobuf::<PointCloud>(&topics::tactile_markers(pad), None, ForceField),
        ],
        "image_encodings": encodings::ALL.iter().map(|&(name, channels, bytes)| (name.to_string(), json!({"channels": channels, "bytes_per_channel": bytes}))).collect::<serde_json::Map<_, _>>(),
        "tactile_points": packed(&tactile_points::FIELDS, tactile_points::STRIDE),
        "force_cells": packed(&force_cells::FIELDS, force_cells::STRIDE),
        "marker_points": packed(&marker_points::FIELDS, marker_points::STRIDE),
        "frames": {"world": frames::WORLD, "camera": frames::CAMERA, "object": frames::OBJECT},
        "mask_ids": {
            "background": mask_ids::BACKGROUND,
            "target_object": mask_ids::TARGET_OBJECT,
            "distractors": range(&mask_ids::DISTRACTORS),
            "arm_links": range(&mask_ids::ARM_LINKS),
            "arm_link_seventh": mask_ids::ARM_LINK_SEVENTH,
            "palm": mask_ids::PALM,
            "hand_links": range(&mask_ids::HAND_LINKS),
        },
        "occlusion_bins": {"keys": OcclusionBin::ALL.map(OcclusionBin::key), "bounds": OcclusionBin::BOUNDS},
        "records": {
            "manifest": keys_of(&manifest),
            "grasp_stats": keys_of(&grasp),
            "occlusion_histogram": keys_of(&OcclusionHistogram::new([0; 3])),
            "sample_info": keys_of(&example_info(false)),
            "sample_info_robot": keys_of(&robot),
            "touch_info": keys_of(robot.tactile.as_ref().expect("the example has touch")),
            "pad_force": keys_of(robot.tactile.as_ref().and_then(|t| t.forces.as_ref()).and_then(|f| f.values().next()).expect("the example has forces")),
            "occlusion": keys_of(&with_robot.occlusion.expect("the example has an occlusion level")),
            "episode_frame": keys_of(&with_robot.episode.expect("the example is an episode frame")),
            "episode": keys_of(&episode),
            "state": keys_of(&state),
        },
    })
}

#[cfg(test)]
mod tests {
    /// `datasets/format.json` is this crate's format; `VTGEN_BLESS=1` rewrites it after a change.
    #[test]
    fn format_json_is_current() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("format.json");
        let text = serde_json::to_string_pretty(&super::description()).unwrap() + "\n";
        if std::env::var_os("VTGEN_BLESS").is_some() {
            std::fs::write(&path, &text).unwrap();
        }
        let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
        assert!(
            on_disk == text,
            "{} differs from the format this crate writes: rerun with VTGEN_BLESS=1 and update the Python and TypeScript readers \
             (their tests compare against it)",
            path.display()
        );
    }
}

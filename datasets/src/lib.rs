//! The vtgen dataset format (see `datasets/FORMAT.md`, the contract): sharded MCAP files with
//! Foxglove protobuf schemas, a JSON manifest, and the rendered object models as PLY.
//!
//! One implementation of the format per language: this crate for Rust (the generator writes with
//! it; inspection, validation and the trainer read with it), `datasets/python` for Python.

mod glb;
mod info;
mod manifest;
mod occlusion;
mod ply;
mod reader;
mod sample;
mod writer;

pub use glb::{ColoredMesh, encode_glb, srgb_to_linear};
pub use info::{EpisodeFrameInfo, OcclusionInfo, PlacedDistractor, RobotInfo, SampleInfo, Split, StateRecord, TouchInfo};
pub use manifest::{ContinuousSymmetry, Manifest, ModelInfo, ModelsInfo, ShardEntry, SplitManifest, sha256_file, write_atomic};
pub use occlusion::OcclusionBin;
pub use ply::{LengthUnit, PlyMesh, read_ply, write_ply};
pub use reader::{DatasetReader, ShardReader};
pub use sample::{EpisodeData, OpticalPadImage, Pose, Sample, ShardMeta, TactileData, TactilePointRecord};
pub use writer::{Compression, SceneModel, ShardReceipt, ShardWriter};

/// Version of the on-disk format written by this crate.
pub const FORMAT_VERSION: u32 = 1;
/// Nanoseconds between consecutive samples on the MCAP timeline (10 Hz).
pub const SAMPLE_PERIOD_NS: u64 = 100_000_000;
/// The shard metadata key that marks an episode shard (its value: the episode's JSON record).
pub const EPISODE_METADATA_KEY: &str = "episode";
/// Name of the per-shard MCAP metadata record.
pub const SHARD_METADATA: &str = "vtgen.shard";
/// Suffix of a shard that is still being written.
pub const PARTIAL_SUFFIX: &str = ".partial";
/// The dataset's mesh sources (FORMAT.md, "Directory layout"): with `config.json`, its identity.
pub const SOURCES_FILE: &str = "sources.json";
/// The folder of the robot a dataset was made with (FORMAT.md, "Directory layout"):
/// `robot.urdf`, `robot.yaml` and `meshes.json` ([`RobotFiles`]).
pub const ROBOT_DIR: &str = "robot";

/// `robot/meshes.json`: the robot's name and the mesh files its URDF names.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RobotFiles {
    pub name: String,
    pub meshes: Vec<RobotMeshFile>,
}

/// One mesh file of the robot: where the generating machine read it, its size and its SHA-256.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RobotMeshFile {
    pub file: String,
    pub bytes: u64,
    pub sha256: String,
}

/// Topic names (FORMAT.md, "MCAP shard").
pub mod topics {
    pub const RGB: &str = "/camera/rgb";
    pub const DEPTH: &str = "/camera/depth";
    pub const DEPTH_NOISY: &str = "/camera/depth_noisy";
    pub const MASK: &str = "/camera/mask";
    pub const CALIBRATION: &str = "/camera/calibration";
    pub const OBJECT_POSE: &str = "/object/pose";
    pub const TF: &str = "/tf";
    pub const SAMPLE_INFO: &str = "/sample/info";
    pub const TACTILE_POINTS: &str = "/tactile/points";
    /// Episodes: the state stream (JSON `StateRecord`).
    pub const EPISODE_STATE: &str = "/episode/state";
    /// `foxglove.SceneUpdate`: the meshes for the 3D view, with the first sample of a shard and
    /// whenever the target object changes.
    pub const SCENE_MODELS: &str = "/scene/models";
    /// The depth image topic of a phalanx camera.
    pub fn tactile_depth(phalanx: &str) -> String {
        format!("/tactile/{phalanx}/depth")
    }
    /// The optical image topic of a pad with an optical sensor.
    pub fn tactile_image(pad: &str) -> String {
        format!("/tactile/{pad}/image")
    }
    /// The no-contact reference image of that sensor, beside each image.
    pub fn tactile_reference(pad: &str) -> String {
        format!("/tactile/{pad}/reference")
    }
    /// Every topic a complete sample has, in the order they are written.
    pub const ALL: [&str; 7] = [RGB, DEPTH, MASK, CALIBRATION, OBJECT_POSE, TF, SAMPLE_INFO];
}

/// Frame ids (FORMAT.md, "Conventions").
pub mod frames {
    pub const WORLD: &str = "world";
    pub const CAMERA: &str = "camera";
    pub const OBJECT: &str = "object";
}

/// Mask ids (FORMAT.md, "Instance mask ids"): every id range of the instance mask, named once.
pub mod mask_ids {
    use std::ops::RangeInclusive;

    /// The floor, backdrop and other environment.
    pub const BACKGROUND: u8 = 0;
    /// The object whose pose is the ground truth.
    pub const TARGET_OBJECT: u8 = 1;
    /// Distractors: the k-th placed one (`/sample/info` `distractors`) has `start + k`.
    pub const DISTRACTORS: RangeInclusive<u8> = 2..=9;
    /// Arm links: the one moved by the k-th arm joint (the base with the first) has `start + k`
    /// for the first six; a seventh arm joint's link has `ARM_LINK_SEVENTH` (`arm_link`).
    pub const ARM_LINKS: RangeInclusive<u8> = 10..=15;
    pub const ARM_LINK_SEVENTH: u8 = 81;
    /// The hand's body: the grasp frame (palm) and the links fixed between it and the flange.
    pub const PALM: u8 = 16;
    /// Hand links: the one moved by the k-th hand joint has `start + k`, then those moved by the
    /// hand's mimic joints in the robot's joint order; links fixed to one share its id.
    pub const HAND_LINKS: RangeInclusive<u8> = 17..=80;

    /// The id of the link moved by arm joint `k` (0-based, base to flange).
    pub fn arm_link(k: usize) -> Option<u8> {
        if k == 6 { Some(ARM_LINK_SEVENTH) } else { nth(&ARM_LINKS, k) }
    }

    /// The id of the k-th entry of a range, when the range has one.
    pub fn nth(range: &RangeInclusive<u8>, k: usize) -> Option<u8> {
        let id = *range.start() as usize + k;
        (id <= *range.end() as usize).then_some(id as u8)
    }

    /// Whether a mask id is a part of the robot.
    pub fn is_robot(id: u8) -> bool {
        ARM_LINKS.contains(&id) || id == ARM_LINK_SEVENTH || id == PALM || HAND_LINKS.contains(&id)
    }
}

/// The file name of shard `index` of a split, relative to the dataset root.
pub fn shard_file(split: &str, index: u32) -> String {
    format!("{split}/shard-{index:05}.mcap")
}

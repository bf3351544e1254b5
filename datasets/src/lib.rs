//! The vtgen dataset format (see `datasets/FORMAT.md`, the contract): sharded MCAP files with
//! Foxglove protobuf schemas, a JSON manifest, and the rendered object models as PLY.
//!
//! One implementation of the format per language: this crate for Rust (the generator writes with
//! it; inspection, validation and the trainer read with it), `datasets/python` for Python.

mod format;
mod glb;
mod info;
mod manifest;
mod occlusion;
mod ply;
mod reader;
mod sample;
mod writer;

pub use format::description as format_description;
pub use glb::{ColoredMesh, encode_glb, srgb_to_linear};
pub use info::{
    EpisodeFrameInfo, EpisodeRecord, OcclusionInfo, PadForceInfo, PlacedDistractor, RobotInfo, SampleInfo, SensorModel, Split, StateRecord,
    TouchInfo,
};
pub use manifest::{
    ContinuousSymmetry, GraspStats, Manifest, ModelInfo, ModelsInfo, OcclusionHistogram, ShardEntry, SplitManifest, sha256_file,
    write_atomic,
};
pub use occlusion::OcclusionBin;
pub use ply::{LengthUnit, PlyMesh, read_ply, write_ply};
pub use reader::{DatasetReader, ShardReader};
pub use sample::{
    EpisodeData, ForceCell, OpticalPadImage, PadForceField, PadMarkerFlow, Pose, Sample, ShardMeta, TactileData, TactilePointRecord,
};
pub use writer::{Compression, SceneModel, ShardReceipt, ShardWriter};

/// `manifest.json`'s `format`: what makes a folder a vtgen dataset.
pub const FORMAT_NAME: &str = "vtgen-dataset";
/// Version of the on-disk format written by this crate.
pub const FORMAT_VERSION: u32 = 1;
/// Nanoseconds between consecutive samples on the MCAP timeline (10 Hz).
pub const SAMPLE_PERIOD_NS: u64 = 100_000_000;
/// The shard metadata key that marks an episode shard (its value: the episode's JSON record).
pub const EPISODE_METADATA_KEY: &str = "episode";
/// The dataset's manifest, at its root (FORMAT.md, "Directory layout").
pub const MANIFEST_FILE: &str = "manifest.json";
/// The folder of the object models and their `models_info.json`.
pub const MODELS_DIR: &str = "models";
pub const MODELS_INFO_FILE: &str = "models_info.json";
/// `vtgen.shard` keys of the shard's figures (JSON values): the occlusion histogram's counts
/// ([`OcclusionHistogram::counts`]) and, with a robot, the [`GraspStats`] of the trajectories
/// that start in the shard.
pub const OCCLUSION_HISTOGRAM_KEY: &str = "occlusion_histogram";
pub const GRASP_STATS_KEY: &str = "grasp_stats";
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
    /// The depth image topic of a pad camera.
    pub fn tactile_depth(pad: &str) -> String {
        format!("/tactile/{pad}/depth")
    }
    /// The optical image topic of a pad with an optical sensor.
    pub fn tactile_image(pad: &str) -> String {
        format!("/tactile/{pad}/image")
    }
    /// The no-contact reference image of that sensor, beside each image.
    pub fn tactile_reference(pad: &str) -> String {
        format!("/tactile/{pad}/reference")
    }
    /// A pad's contact force field (`robot.tactile.force_field`).
    pub fn tactile_force(pad: &str) -> String {
        format!("/tactile/{pad}/force")
    }
    /// An optical pad's markers, at rest and moved (with force fields).
    pub fn tactile_markers(pad: &str) -> String {
        format!("/tactile/{pad}/markers")
    }
    /// Every topic a complete sample has, in the order they are written.
    pub const ALL: [&str; 7] = [RGB, DEPTH, MASK, CALIBRATION, OBJECT_POSE, TF, SAMPLE_INFO];
}

/// `foxglove.RawImage` encodings (FORMAT.md, "MCAP shard"): bytes per pixel, little-endian.
pub mod encodings {
    /// Colour (`/camera/rgb`, an optical pad's image and reference): 3 bytes, sRGB.
    pub const RGB8: &str = "rgb8";
    /// z-depth in metres (`/camera/depth`, `/camera/depth_noisy`, a pad's depth): one `f32`.
    pub const DEPTH_32FC1: &str = "32FC1";
    /// Instance ids (`/camera/mask`): one byte.
    pub const MASK_MONO8: &str = "mono8";
    /// (encoding, channels, bytes per channel) of every encoding the format writes.
    pub const ALL: [(&str, u32, u32); 3] = [(RGB8, 3, 1), (MASK_MONO8, 1, 1), (DEPTH_32FC1, 1, 4)];
}

/// `/tactile/points` (FORMAT.md, "Tactile point cloud"): one packed point per contact pixel.
pub mod tactile_points {
    /// A point's fields: name, byte offset and whether it is an unsigned integer (else `f32`).
    pub const FIELDS: [(&str, u32, bool); 5] =
        [("x", 0, false), ("y", 4, false), ("z", 8, false), ("distance", 12, false), ("phalanx", 16, true)];
    /// Bytes per point.
    pub const STRIDE: u32 = 20;
}

/// `/tactile/<pad>/force` (FORMAT.md, "Force fields"): one packed point per cell of a pad's grid,
/// in the pad frame.
pub mod force_cells {
    /// A cell's fields: name, byte offset and whether it is an unsigned integer (else `f32`).
    pub const FIELDS: [(&str, u32, bool); 7] = [
        ("x", 0, false),
        ("y", 4, false),
        ("z", 8, false),
        ("pressure", 12, false),
        ("shear_x", 16, false),
        ("shear_y", 20, false),
        ("slip", 24, true),
    ];
    /// Bytes per cell.
    pub const STRIDE: u32 = 28;
}

/// `/tactile/<pad>/markers` (FORMAT.md, "Force fields"): one packed point per marker, in the pad
/// frame: where it is, then its rest position.
pub mod marker_points {
    /// A marker's fields: name, byte offset and whether it is an unsigned integer (else `f32`).
    pub const FIELDS: [(&str, u32, bool); 5] =
        [("x", 0, false), ("y", 4, false), ("z", 8, false), ("rest_x", 12, false), ("rest_y", 16, false)];
    /// Bytes per marker.
    pub const STRIDE: u32 = 20;
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

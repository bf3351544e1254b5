use glam::{DMat4, DQuat, DVec3};
use serde::{Deserialize, Serialize};

/// A rigid transform `T_A_B` (maps frame-B coordinates into frame A), quaternion (x, y, z, w).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    pub position: [f64; 3],
    pub orientation: [f64; 4],
}

impl Pose {
    pub fn from_rt(rotation: DQuat, translation: DVec3) -> Self {
        let q = rotation.normalize();
        Pose { position: translation.to_array(), orientation: [q.x, q.y, q.z, q.w] }
    }

    pub fn rotation(&self) -> DQuat {
        let [x, y, z, w] = self.orientation;
        DQuat::from_xyzw(x, y, z, w)
    }

    pub fn translation(&self) -> DVec3 {
        DVec3::from_array(self.position)
    }

    pub fn matrix(&self) -> DMat4 {
        DMat4::from_rotation_translation(self.rotation(), self.translation())
    }

    pub fn transform_point(&self, p: DVec3) -> DVec3 {
        self.rotation() * p + self.translation()
    }
}

/// One complete sample as stored in a shard.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// Index of the sample within its split.
    pub index: u64,
    pub width: u32,
    pub height: u32,
    /// `width * height * 3` bytes, sRGB.
    pub rgb: Vec<u8>,
    /// z-depth in metres, 0 = no surface.
    pub depth: Vec<f32>,
    /// The depth as a noisy RGB-D sensor reads it, when the config has a noise model.
    pub depth_noisy: Option<Vec<f32>>,
    /// Instance ids (FORMAT.md).
    pub mask: Vec<u8>,
    /// Row-major 3x3 intrinsics.
    pub k: [f64; 9],
    pub t_camera_object: Pose,
    pub t_world_camera: Pose,
    pub t_world_object: Pose,
    /// Further frames for `/tf` (parent, child, `T_parent_child`): the grasp frame, the drawn
    /// links and the pads when a robot is in the scene.
    pub extra_transforms: Vec<(String, String, Pose)>,
    /// `/sample/info`.
    pub info: crate::SampleInfo,
    /// The pad cameras and the tactile point cloud, when a robot is in the scene.
    pub tactile: Option<TactileData>,
    /// In an episode dataset: the frame's time and the faster streams up to the next frame.
    pub episode: Option<EpisodeData>,
}

/// What an episode's camera frame carries besides the sample at its instant: its time, and the
/// touch and state streams from it up to (not including) the next frame.
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeData {
    /// The frame's simulated time since the episode's start (ns): its MCAP log time.
    pub time_ns: u64,
    /// The touch at the tactile rate after the frame's own (which is `Sample::tactile`).
    pub tactile: Vec<(u64, TactileData)>,
    /// The state stream from the frame's instant (included) on.
    pub states: Vec<(u64, crate::StateRecord)>,
}

/// One tactile point (FORMAT.md `/tactile/points`): camera-frame position, depth from the pad,
/// pad index (the wire field `phalanx` of format version 1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TactilePointRecord {
    pub position: [f32; 3],
    pub distance: f32,
    pub pad: u32,
}

#[derive(Debug, Clone, PartialEq)]
pub struct TactileData {
    /// Pad names in the robot's pad order (what `TactilePointRecord::pad` indexes).
    pub pads: Vec<String>,
    /// Pixels per side of each pad camera.
    pub resolution: u32,
    /// Per pad: row-major z-depths from the pad plane, `+inf` = no surface.
    pub depth: Vec<Vec<f32>>,
    pub points: Vec<TactilePointRecord>,
    /// The optical images of the pads with an optical sensor, in pad order (FORMAT.md,
    /// `/tactile/<pad>/image`); empty without one.
    pub optical: Vec<OpticalPadImage>,
    /// Every pad's force field, in pad order (FORMAT.md, `/tactile/<pad>/force`), when the config
    /// asks for them (`robot.tactile.force_field`); else empty.
    pub forces: Vec<PadForceField>,
    /// With force fields, each optical pad with markers: where its markers are (FORMAT.md,
    /// `/tactile/<pad>/markers`), in pad order; else empty.
    pub marker_flow: Vec<PadMarkerFlow>,
}

/// One optical pad's markers: each one's rest position and where the gel has moved it.
#[derive(Debug, Clone, PartialEq)]
pub struct PadMarkerFlow {
    /// The pad's name (one of `TactileData::pads`).
    pub pad: String,
    /// Per marker (the rest grid's order, row by row): (rest, moved) in the pad frame (x, y; m).
    pub markers: Vec<([f32; 2], [f32; 2])>,
}

/// One pad's contact force field: a `resolution x resolution` grid over its sensing area, rows and
/// columns as its depth image's (FORMAT.md, `/tactile/<pad>/force`).
#[derive(Debug, Clone, PartialEq)]
pub struct PadForceField {
    /// The pad's name (one of `TactileData::pads`).
    pub pad: String,
    pub resolution: u32,
    /// `resolution²` cells, row-major.
    pub cells: Vec<ForceCell>,
}

/// One cell of a force field: what the object exerts on the pad's surface there.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ForceCell {
    /// The cell's centre in the pad frame (x, y; m), on the pad plane.
    pub position: [f32; 2],
    /// Normal pressure (Pa, >= 0), pushing into the pad.
    pub pressure: f32,
    /// Shear traction along the pad's x and y (Pa).
    pub shear: [f32; 2],
    /// Whether the cell slips: its traction is at the friction limit.
    pub slip: bool,
}

/// One pad's optical tactile image and its sensor's no-contact reference image.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OpticalPadImage {
    /// The pad's name (one of `TactileData::pads`).
    pub pad: String,
    pub width: u32,
    pub height: u32,
    /// `width * height * 3` bytes, RGB, linear 8-bit levels.
    pub image: Vec<u8>,
    /// The same sensor with nothing touching it, without noise. An episode writes it once, with
    /// its first frame: the reader fills it in for the others.
    pub reference: Vec<u8>,
}

impl Sample {
    pub fn fx(&self) -> f64 {
        self.k[0]
    }
    pub fn fy(&self) -> f64 {
        self.k[4]
    }
    pub fn cx(&self) -> f64 {
        self.k[2]
    }
    pub fn cy(&self) -> f64 {
        self.k[5]
    }
}

/// The `vtgen.shard` metadata record of a shard.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ShardMeta {
    pub generator: String,
    pub seed: u64,
    pub config_sha256: String,
    pub split: String,
    pub shard_index: u32,
    pub first_sample: u64,
    pub sample_count: u64,
    /// Further string entries (e.g. `grasp_stats`, JSON).
    pub extra: std::collections::BTreeMap<String, String>,
}

impl ShardMeta {
    /// The keys every `vtgen.shard` record has, in this order; [`ShardMeta::extra`] adds others.
    pub const KEYS: [&str; 8] =
        ["format_version", "generator", "seed", "config_sha256", "split", "shard_index", "first_sample", "sample_count"];

    pub fn to_map(&self) -> std::collections::BTreeMap<String, String> {
        let values = [
            crate::FORMAT_VERSION.to_string(),
            self.generator.clone(),
            self.seed.to_string(),
            self.config_sha256.clone(),
            self.split.clone(),
            self.shard_index.to_string(),
            self.first_sample.to_string(),
            self.sample_count.to_string(),
        ];
        Self::KEYS.into_iter().zip(values).map(|(k, v)| (k.to_string(), v)).chain(self.extra.clone()).collect()
    }

    pub fn from_map(m: &std::collections::BTreeMap<String, String>) -> anyhow::Result<Self> {
        let get = |k: &str| m.get(k).ok_or_else(|| anyhow::anyhow!("shard metadata lacks '{k}'"));
        let num = |k: &str| -> anyhow::Result<u64> { get(k)?.parse().map_err(|_| anyhow::anyhow!("shard metadata '{k}' is not a number")) };
        Ok(ShardMeta {
            generator: get("generator")?.clone(),
            seed: num("seed")?,
            config_sha256: get("config_sha256")?.clone(),
            split: get("split")?.clone(),
            shard_index: num("shard_index")? as u32,
            first_sample: num("first_sample")?,
            sample_count: num("sample_count")?,
            extra: m.iter().filter(|(k, _)| !Self::KEYS.contains(&k.as_str())).map(|(k, v)| (k.clone(), v.clone())).collect(),
        })
    }
}

impl Pose {
    pub const IDENTITY: Pose = Pose { position: [0.0; 3], orientation: [0.0, 0.0, 0.0, 1.0] };

    /// `self * other`: with `self = T_A_B` and `other = T_B_C`, gives `T_A_C`.
    pub fn compose(&self, other: &Pose) -> Pose {
        Pose::from_rt(self.rotation() * other.rotation(), self.transform_point(other.translation()))
    }

    /// `T_B_A` from `T_A_B`.
    pub fn inverse(&self) -> Pose {
        let r = self.rotation().inverse();
        Pose::from_rt(r, -(r * self.translation()))
    }

    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({"position": self.position, "orientation": self.orientation})
    }
}

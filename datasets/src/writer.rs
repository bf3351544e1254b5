//! Writes one shard: an MCAP file with one zstd chunk per sample, under a temporary name that is
//! renamed to the final name only once the file is complete and synced.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use foxglove::Encode;
use foxglove::schemas::{
    CameraCalibration, Color, FrameTransform, FrameTransforms, ModelPrimitive, PackedElementField, PointCloud, Pose as FgPose, PoseInFrame,
    Quaternion, RawImage, SceneEntity, SceneUpdate, Timestamp, Vector3,
};
use prost::Message;

use crate::sample::{Pose, Sample, ShardMeta};
use crate::{PARTIAL_SUFFIX, SAMPLE_PERIOD_NS, SHARD_METADATA, encodings, frames, topics};

/// Chunk compression of a shard.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Compression {
    None,
    Zstd { level: u32 },
}

/// A mesh shown in Foxglove's 3D panel (`/scene/models`): a binary glTF drawn in `frame_id`,
/// which `/tf` moves per sample (the object in `object`, each robot link in its link frame).
#[derive(Debug, Clone, PartialEq)]
pub struct SceneModel {
    pub id: String,
    pub frame_id: String,
    /// A GLB ([`crate::encode_glb`]); shared, since every shard of a run carries the same meshes.
    pub glb: std::sync::Arc<Vec<u8>>,
}

/// What a finished shard looks like on disk.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ShardReceipt {
    pub path: PathBuf,
    pub bytes: u64,
    pub sha256: String,
}

struct Channels {
    rgb: u16,
    depth: u16,
    /// `/camera/depth_noisy`, added with the first sample that has one.
    depth_noisy: Option<u16>,
    mask: u16,
    calibration: u16,
    pose: u16,
    tf: u16,
    info: u16,
}

/// JSON schema of `/sample/info` (FORMAT.md). Open for extension: readers ignore unknown keys.
pub(crate) const SAMPLE_INFO_SCHEMA_NAME: &str = "vtgen.SampleInfo";
pub(crate) const SAMPLE_INFO_SCHEMA: &str = r#"{"title":"vtgen.SampleInfo","type":"object","properties":{"split":{"type":"string"},"index":{"type":"integer"},"object_id":{"type":"string"},"object_index":{"type":"integer"},"mask_id":{"type":"integer"},"trajectory":{"type":"integer"},"instance":{"type":"integer"},"randomized":{"type":"boolean"},"visible_pixels":{"type":"integer"},"T_world_camera":{"type":"object"},"T_camera_object":{"type":"object"}},"required":["split","index","object_id","trajectory","instance"]}"#;

/// JSON schema of `/episode/state` (FORMAT.md, "Episodes").
pub(crate) const STATE_RECORD_SCHEMA_NAME: &str = "vtgen.StateRecord";
pub(crate) const STATE_RECORD_SCHEMA: &str = r#"{"title":"vtgen.StateRecord","type":"object","properties":{"time_s":{"type":"number"},"joint_positions":{"type":"object"},"T_world_object":{"type":"object"},"T_camera_object":{"type":"object"},"T_world_palm":{"type":"object"},"linear_velocity":{"type":"array","items":{"type":"number"}},"angular_velocity":{"type":"array","items":{"type":"number"}},"phalanges_in_contact":{"type":"array","items":{"type":"string"}}},"required":["time_s","joint_positions","T_world_object","T_camera_object"]}"#;

pub struct ShardWriter {
    mcap: mcap::Writer<BufWriter<File>>,
    channels: Channels,
    partial_path: PathBuf,
    final_path: PathBuf,
    sequence: u32,
    written: u64,
    meta: ShardMeta,
    /// Tactile channels, added with the first sample that has tactile data.
    tactile_channels: Option<TactileChannels>,
    /// `/episode/state`, added with the first episode frame.
    state_channel: Option<u16>,
    /// `/scene/models`, added with the first scene update.
    scene_channel: Option<u16>,
    /// Models to publish with the next sample.
    pending_scene: Option<Vec<SceneModel>>,
}

fn add<T: Encode>(w: &mut mcap::Writer<BufWriter<File>>, topic: &str) -> Result<u16> {
    let schema = T::get_schema().expect("Foxglove schemas carry their descriptor");
    let sid = w.add_schema(&schema.name, &schema.encoding, &schema.data)?;
    Ok(w.add_channel(sid, topic, &T::get_message_encoding(), &BTreeMap::new())?)
}

fn ts(log_time: u64) -> Option<Timestamp> {
    Some(Timestamp::new((log_time / 1_000_000_000) as u32, (log_time % 1_000_000_000) as u32))
}

fn fg_pose(p: &Pose) -> FgPose {
    FgPose {
        position: Some(Vector3 { x: p.position[0], y: p.position[1], z: p.position[2] }),
        orientation: Some(Quaternion { x: p.orientation[0], y: p.orientation[1], z: p.orientation[2], w: p.orientation[3] }),
    }
}

fn transform(log_time: u64, parent: &str, child: &str, p: &Pose) -> FrameTransform {
    let fp = fg_pose(p);
    FrameTransform {
        timestamp: ts(log_time),
        parent_frame_id: parent.into(),
        child_frame_id: child.into(),
        translation: fp.position,
        rotation: fp.orientation,
    }
}

/// The tactile channels of a shard: the points, each pad's depth view, and per optical pad its
/// name, image and reference channels.
#[derive(Clone)]
struct TactileChannels {
    points: u16,
    depth: Vec<u16>,
    optical: Vec<(String, u16, u16)>,
    forces: Vec<u16>,
    markers: Vec<u16>,
}

impl ShardWriter {
    /// Starts a shard that will end up at `final_path`; nothing exists there until [`finish`].
    pub fn create(final_path: &Path, meta: &ShardMeta, compression: Compression) -> Result<Self> {
        let partial_path = PathBuf::from(format!("{}{PARTIAL_SUFFIX}", final_path.display()));
        if let Some(dir) = final_path.parent() {
            std::fs::create_dir_all(dir).with_context(|| format!("cannot create directory {}", dir.display()))?;
        }
        let file = File::create(&partial_path).with_context(|| format!("cannot create {}", partial_path.display()))?;
        let (comp, level) = match compression {
            Compression::None => (None, 0),
            Compression::Zstd { level } => (Some(mcap::Compression::Zstd), level),
        };
        let opts = mcap::WriteOptions::new()
            .compression(comp)
            .compression_level(level)
            // Single-threaded zstd: the same bytes on every machine; parallelism comes from shards.
            .compression_threads(0)
            // Chunks are closed explicitly after each sample: one chunk per sample.
            .chunk_size(None)
            .library(meta.generator.clone());
        let mut mcap = opts.create(BufWriter::with_capacity(1 << 20, file))?;
        let channels = Channels {
            rgb: add::<RawImage>(&mut mcap, topics::RGB)?,
            depth: add::<RawImage>(&mut mcap, topics::DEPTH)?,
            depth_noisy: None,
            mask: add::<RawImage>(&mut mcap, topics::MASK)?,
            calibration: add::<CameraCalibration>(&mut mcap, topics::CALIBRATION)?,
            pose: add::<PoseInFrame>(&mut mcap, topics::OBJECT_POSE)?,
            tf: add::<FrameTransforms>(&mut mcap, topics::TF)?,
            info: {
                let sid = mcap.add_schema(SAMPLE_INFO_SCHEMA_NAME, "jsonschema", SAMPLE_INFO_SCHEMA.as_bytes())?;
                mcap.add_channel(sid, topics::SAMPLE_INFO, "json", &BTreeMap::new())?
            },
        };
        Ok(ShardWriter {
            mcap,
            channels,
            partial_path,
            final_path: final_path.to_path_buf(),
            sequence: 0,
            written: 0,
            meta: meta.clone(),
            tactile_channels: None,
            state_channel: None,
            scene_channel: None,
            pending_scene: None,
        })
    }

    fn put(&mut self, channel: u16, log_time: u64, data: &[u8]) -> Result<()> {
        let header = mcap::records::MessageHeader { channel_id: channel, sequence: self.sequence, log_time, publish_time: log_time };
        self.sequence += 1;
        self.mcap.write_to_known_channel(&header, data)?;
        Ok(())
    }

    /// Appends one sample as one chunk: at `index * SAMPLE_PERIOD_NS`, or for an episode frame at
    /// its simulated time, followed by its episode's touch and state streams up to the next frame.
    pub fn write_sample(&mut self, s: &Sample) -> Result<()> {
        let t = s.episode.as_ref().map_or(s.index * SAMPLE_PERIOD_NS, |e| e.time_ns);
        let (w, h) = (s.width, s.height);
        anyhow::ensure!(
            s.rgb.len() == (w * h * 3) as usize && s.depth.len() == (w * h) as usize && s.mask.len() == (w * h) as usize,
            "image sizes do not match {w}x{h}"
        );
        let image = |encoding: &str, step: u32, data: &[u8]| RawImage {
            timestamp: ts(t),
            frame_id: frames::CAMERA.into(),
            width: w,
            height: h,
            encoding: encoding.into(),
            step,
            data: prost::bytes::Bytes::copy_from_slice(data),
        };
        let rgb = image(encodings::RGB8, w * 3, &s.rgb).encode_to_vec();
        self.put(self.channels.rgb, t, &rgb)?;
        let depth_bytes: Vec<u8> = s.depth.iter().flat_map(|d| d.to_le_bytes()).collect();
        let depth = image(encodings::DEPTH_32FC1, w * 4, &depth_bytes).encode_to_vec();
        self.put(self.channels.depth, t, &depth)?;
        if let Some(noisy) = &s.depth_noisy {
            anyhow::ensure!(noisy.len() == (w * h) as usize, "noisy depth size does not match {w}x{h}");
            let ch = match self.channels.depth_noisy {
                Some(c) => c,
                None => {
                    let c = add::<RawImage>(&mut self.mcap, topics::DEPTH_NOISY)?;
                    self.channels.depth_noisy = Some(c);
                    c
                }
            };
            let bytes: Vec<u8> = noisy.iter().flat_map(|d| d.to_le_bytes()).collect();
            let msg = image(encodings::DEPTH_32FC1, w * 4, &bytes).encode_to_vec();
            self.put(ch, t, &msg)?;
        }
        let mask = image(encodings::MASK_MONO8, w, &s.mask).encode_to_vec();
        self.put(self.channels.mask, t, &mask)?;
        let k = s.k;
        let calib = CameraCalibration {
            timestamp: ts(t),
            frame_id: frames::CAMERA.into(),
            width: w,
            height: h,
            distortion_model: "plumb_bob".into(),
            d: vec![0.0; 5],
            k: k.to_vec(),
            r: vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            p: vec![k[0], k[1], k[2], 0.0, k[3], k[4], k[5], 0.0, k[6], k[7], k[8], 0.0],
        }
        .encode_to_vec();
        self.put(self.channels.calibration, t, &calib)?;
        let pose =
            PoseInFrame { timestamp: ts(t), frame_id: frames::CAMERA.into(), pose: Some(fg_pose(&s.t_camera_object)) }.encode_to_vec();
        self.put(self.channels.pose, t, &pose)?;
        let mut transforms = vec![
            transform(t, frames::WORLD, frames::CAMERA, &s.t_world_camera),
            transform(t, frames::WORLD, frames::OBJECT, &s.t_world_object),
        ];
        transforms.extend(s.extra_transforms.iter().map(|(parent, child, p)| transform(t, parent, child, p)));
        let tf = FrameTransforms { transforms }.encode_to_vec();
        self.put(self.channels.tf, t, &tf)?;
        // Through a JSON value, whose object keys are sorted: the bytes do not follow field order.
        let info = serde_json::to_vec(&s.info.to_value())?;
        self.put(self.channels.info, t, &info)?;
        if let Some(tac) = &s.tactile {
            self.write_tactile(t, tac)?;
        }
        if let Some(models) = self.pending_scene.take() {
            self.write_scene(t, &models)?;
        }
        if let Some(e) = &s.episode {
            self.write_episode_streams(e)?;
        }
        // Close the chunk: a random read of sample i decompresses exactly one chunk.
        self.mcap.flush()?;
        self.written += 1;
        Ok(())
    }

    /// An episode frame's state and touch streams, in time order (the state first at a tie).
    fn write_episode_streams(&mut self, e: &crate::sample::EpisodeData) -> Result<()> {
        let channel = match self.state_channel {
            Some(c) => c,
            None => {
                let c = self.mcap.add_schema(STATE_RECORD_SCHEMA_NAME, "jsonschema", STATE_RECORD_SCHEMA.as_bytes())?;
                let c = self.mcap.add_channel(c, topics::EPISODE_STATE, "json", &BTreeMap::new())?;
                self.state_channel = Some(c);
                c
            }
        };
        let (mut states, mut touch) = (e.states.iter().peekable(), e.tactile.iter().peekable());
        loop {
            let next_state = states.peek().map(|(t, _)| *t);
            let next_touch = touch.peek().map(|(t, _)| *t);
            let state_first = match (next_state, next_touch) {
                (None, None) => return Ok(()),
                (Some(ts), tt) => tt.is_none_or(|tt| ts <= tt),
                (None, Some(_)) => false,
            };
            if state_first {
                let (t, state) = states.next().expect("peeked");
                self.put(channel, *t, &serde_json::to_vec(&serde_json::to_value(state)?)?)?;
            } else {
                let (t, tac) = touch.next().expect("peeked");
                self.write_tactile(*t, tac)?;
            }
        }
    }

    fn write_tactile(&mut self, t: u64, tac: &crate::sample::TactileData) -> Result<()> {
        if self.tactile_channels.is_none() {
            let points = add::<PointCloud>(&mut self.mcap, topics::TACTILE_POINTS)?;
            let depth = tac.pads.iter().map(|p| add::<RawImage>(&mut self.mcap, &topics::tactile_depth(p))).collect::<Result<_>>()?;
            let optical = tac
                .optical
                .iter()
                .map(|o| {
                    let image = add::<RawImage>(&mut self.mcap, &topics::tactile_image(&o.pad))?;
                    Ok((o.pad.clone(), image, add::<RawImage>(&mut self.mcap, &topics::tactile_reference(&o.pad))?))
                })
                .collect::<Result<_>>()?;
            let forces =
                tac.forces.iter().map(|f| add::<PointCloud>(&mut self.mcap, &topics::tactile_force(&f.pad))).collect::<Result<_>>()?;
            let markers = tac
                .marker_flow
                .iter()
                .map(|f| add::<PointCloud>(&mut self.mcap, &topics::tactile_markers(&f.pad)))
                .collect::<Result<_>>()?;
            self.tactile_channels = Some(TactileChannels { points, depth, optical, forces, markers });
        }
        let TactileChannels { points: points_ch, depth: image_chs, optical, forces, markers } =
            self.tactile_channels.clone().expect("set above");
        anyhow::ensure!(
            optical.len() == tac.optical.len() && optical.iter().zip(&tac.optical).all(|(c, o)| c.0 == o.pad),
            "the optical pads changed within a shard"
        );
        anyhow::ensure!(forces.len() == tac.forces.len(), "the pads with force fields changed within a shard");
        anyhow::ensure!(markers.len() == tac.marker_flow.len(), "the pads with marker flow changed within a shard");
        let cloud = tactile_cloud(t, &tac.points);
        self.put(points_ch, t, &cloud)?;
        let r = tac.resolution;
        for (k, ch) in image_chs.iter().enumerate() {
            let bytes: Vec<u8> = tac.depth[k].iter().flat_map(|d| d.to_le_bytes()).collect();
            let img = RawImage {
                timestamp: ts(t),
                frame_id: format!("{}_pad", tac.pads[k]),
                width: r,
                height: r,
                encoding: encodings::DEPTH_32FC1.into(),
                step: r * 4,
                data: prost::bytes::Bytes::from(bytes),
            }
            .encode_to_vec();
            self.put(*ch, t, &img)?;
        }
        for ((_, image_ch, reference_ch), o) in optical.iter().zip(&tac.optical) {
            anyhow::ensure!(
                o.image.len() == (o.width * o.height * 3) as usize && (o.reference.is_empty() || o.reference.len() == o.image.len()),
                "optical image sizes of pad {} do not match {}x{}",
                o.pad,
                o.width,
                o.height
            );
            // An empty reference is not written (an episode's: once, with its first frame).
            let with_reference = (!o.reference.is_empty()).then_some((reference_ch, &o.reference));
            for (ch, bytes) in [(image_ch, &o.image)].into_iter().chain(with_reference) {
                let img = RawImage {
                    timestamp: ts(t),
                    frame_id: format!("{}_pad", o.pad),
                    width: o.width,
                    height: o.height,
                    encoding: encodings::RGB8.into(),
                    step: o.width * 3,
                    data: prost::bytes::Bytes::copy_from_slice(bytes),
                }
                .encode_to_vec();
                self.put(*ch, t, &img)?;
            }
        }
        for (ch, field) in forces.iter().zip(&tac.forces) {
            anyhow::ensure!(tac.pads.contains(&field.pad), "force field of an unknown pad {}", field.pad);
            self.put(*ch, t, &force_cloud(t, field)?)?;
        }
        for (ch, flow) in markers.iter().zip(&tac.marker_flow) {
            let mut data = Vec::with_capacity(flow.markers.len() * crate::marker_points::STRIDE as usize);
            for (rest, moved) in &flow.markers {
                for v in [moved[0], moved[1], 0.0, rest[0], rest[1]] {
                    data.extend(v.to_le_bytes());
                }
            }
            let cloud = packed_cloud(t, format!("{}_pad", flow.pad), (&crate::marker_points::FIELDS, crate::marker_points::STRIDE), data);
            self.put(*ch, t, &cloud)?;
        }
        Ok(())
    }

    /// Publishes `models` on `/scene/models` with the next sample, replacing what the previous
    /// update showed. Call it before the first sample of a shard and whenever the set changes (the
    /// target object does): each update is complete, so a viewer that seeks shows the right scene
    /// from the latest update alone.
    pub fn set_scene(&mut self, models: Vec<SceneModel>) {
        self.pending_scene = Some(models);
    }

    fn write_scene(&mut self, t: u64, models: &[SceneModel]) -> Result<()> {
        let channel = match self.scene_channel {
            Some(c) => c,
            None => {
                let c = add::<SceneUpdate>(&mut self.mcap, topics::SCENE_MODELS)?;
                self.scene_channel = Some(c);
                c
            }
        };
        let entities = models
            .iter()
            .map(|m| SceneEntity {
                timestamp: ts(t),
                frame_id: m.frame_id.clone(),
                id: m.id.clone(),
                // Lives until replaced, attached to its frame: /tf moves it from sample to sample.
                lifetime: None,
                frame_locked: true,
                models: vec![ModelPrimitive {
                    pose: Some(fg_pose(&Pose::IDENTITY)),
                    scale: Some(Vector3 { x: 1.0, y: 1.0, z: 1.0 }),
                    color: Some(Color { r: 1.0, g: 1.0, b: 1.0, a: 1.0 }),
                    override_color: false,
                    url: String::new(),
                    media_type: "model/gltf-binary".into(),
                    data: prost::bytes::Bytes::copy_from_slice(&m.glb),
                }],
                ..Default::default()
            })
            .collect();
        // Entities of the previous update that this one does not replace are deleted first.
        let deletions = vec![foxglove::schemas::SceneEntityDeletion {
            timestamp: ts(t),
            r#type: foxglove::schemas::scene_entity_deletion::Type::All as i32,
            id: String::new(),
        }];
        let update = SceneUpdate { deletions, entities }.encode_to_vec();
        self.put(channel, t, &update)
    }

    /// Adds an entry to the shard's metadata record (written by [`finish`]).
    pub fn set_metadata(&mut self, key: &str, value: String) {
        self.meta.extra.insert(key.to_string(), value);
    }

    /// Writes the summary, syncs, and renames the shard to its final name. Until this returns, no
    /// file with the final name exists, so an interrupted run never leaves a complete-looking shard.
    pub fn finish(mut self) -> Result<ShardReceipt> {
        anyhow::ensure!(self.written == self.meta.sample_count, "shard has {} samples, expected {}", self.written, self.meta.sample_count);
        // Written after the last sample's chunk was closed: a metadata record in the middle would
        // close a chunk early and leave one without a sample.
        self.mcap.write_metadata(&mcap::records::Metadata { name: SHARD_METADATA.into(), metadata: self.meta.to_map() })?;
        self.mcap.finish()?;
        let file = self.mcap.into_inner().into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        drop(file);
        std::fs::rename(&self.partial_path, &self.final_path)
            .with_context(|| format!("cannot rename {} to {}", self.partial_path.display(), self.final_path.display()))?;
        let (bytes, sha256) = crate::manifest::sha256_file(&self.final_path)?;
        Ok(ShardReceipt { path: self.final_path.clone(), bytes, sha256 })
    }
}

/// A pad's force field as a Foxglove `PointCloud` in the pad frame, one point per cell at its
/// centre on the pad plane, laid out as [`crate::force_cells::FIELDS`] says.
fn force_cloud(t: u64, f: &crate::sample::PadForceField) -> Result<Vec<u8>> {
    let r = f.resolution;
    anyhow::ensure!(f.cells.len() == (r * r) as usize, "pad {}: {} force cells, expected {r}x{r}", f.pad, f.cells.len());
    let mut data = Vec::with_capacity(f.cells.len() * crate::force_cells::STRIDE as usize);
    for c in &f.cells {
        for v in [c.position[0], c.position[1], 0.0, c.pressure, c.shear[0], c.shear[1]] {
            data.extend(v.to_le_bytes());
        }
        data.extend((c.slip as u32).to_le_bytes());
    }
    Ok(packed_cloud(t, format!("{}_pad", f.pad), (&crate::force_cells::FIELDS, crate::force_cells::STRIDE), data))
}

/// The tactile points as a Foxglove `PointCloud` in the camera frame, laid out as
/// [`crate::tactile_points::FIELDS`] says.
fn tactile_cloud(t: u64, points: &[crate::sample::TactilePointRecord]) -> Vec<u8> {
    let mut data = Vec::with_capacity(points.len() * crate::tactile_points::STRIDE as usize);
    for p in points {
        for v in p.position.iter().chain([&p.distance]) {
            data.extend(v.to_le_bytes());
        }
        data.extend(p.pad.to_le_bytes());
    }
    packed_cloud(t, frames::CAMERA.into(), (&crate::tactile_points::FIELDS, crate::tactile_points::STRIDE), data)
}

/// A `PointCloud` of packed points in `frame_id` (identity pose), with the `(name, offset,
/// unsigned)` fields of a layout and its stride.
fn packed_cloud(t: u64, frame_id: String, (fields, stride): (&[(&str, u32, bool)], u32), data: Vec<u8>) -> Vec<u8> {
    use foxglove::schemas::packed_element_field::NumericType;
    let field = |&(name, offset, unsigned): &(&str, u32, bool)| PackedElementField {
        name: name.into(),
        offset,
        r#type: if unsigned { NumericType::Uint32 } else { NumericType::Float32 } as i32,
    };
    PointCloud {
        timestamp: ts(t),
        frame_id,
        pose: Some(fg_pose(&Pose::IDENTITY)),
        point_stride: stride,
        fields: fields.iter().map(field).collect(),
        data: prost::bytes::Bytes::from(data),
    }
    .encode_to_vec()
}

//! Reads shards through their MCAP summary (chunk indexes), so sample i costs one chunk's
//! decompression and no scan of the file.

use std::collections::BTreeMap;
use std::fs::File;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, bail};
use foxglove::schemas::{CameraCalibration, FrameTransforms, PoseInFrame, RawImage};
use prost::Message;

use crate::manifest::Manifest;
use crate::sample::{Pose, Sample, ShardMeta};
use crate::{SAMPLE_PERIOD_NS, SHARD_METADATA, encodings, frames, topics};

pub struct ShardReader {
    path: PathBuf,
    data: memmap2::Mmap,
    summary: mcap::Summary,
    /// Split index of a sample -> position in `summary.chunk_indexes`.
    chunks: BTreeMap<u64, usize>,
    meta: ShardMeta,
    /// An episode shard (`vtgen.shard` has `episode`): its chunks are frames.
    episode: bool,
    /// An episode's reference images (its first frame's), by topic, read once.
    references: std::sync::OnceLock<BTreeMap<String, Vec<u8>>>,
}

/// The largest uncompressed chunk (one sample) a reader accepts: a 640×480 sample with 12 tactile
/// views is about 3 MB; 1 GiB leaves room for 4K images and noisy depth.
pub const MAX_CHUNK_BYTES: u64 = 1 << 30;

/// A cursor over one record's body that checks every length prefix against what is left.
struct Fields<'a> {
    body: &'a [u8],
    at: usize,
}

impl Fields<'_> {
    fn skip(&mut self, n: usize) -> Option<()> {
        self.at = self.at.checked_add(n).filter(|&e| e <= self.body.len())?;
        Some(())
    }
    /// A u32 length prefix and that many bytes (a string, byte array or map).
    fn prefixed(&mut self) -> Option<(usize, usize)> {
        let n = u32::from_le_bytes(self.body.get(self.at..self.at + 4)?.try_into().ok()?) as usize;
        self.skip(4)?;
        let start = self.at;
        self.skip(n)?;
        Some((start, n))
    }
    /// A string map: a u32 byte length, then key and value strings within it.
    fn string_map(&mut self) -> Option<()> {
        let (start, n) = self.prefixed()?;
        let mut inner = Fields { body: &self.body[start..start + n], at: 0 };
        while inner.at < n {
            inner.prefixed()?;
            inner.prefixed()?;
        }
        Some(())
    }
}

/// Checks the length prefixes inside the summary section's records (schemas, channels, chunk
/// and metadata indexes, statistics) against their records before the mcap crate reads them: it
/// reserves what a u32 prefix says before reading (a damaged one asked for 3.4 GB; found by
/// `tests/fuzz`). Records of other kinds are left to the crate.
fn check_summary_lengths(data: &[u8]) -> Result<()> {
    // The file ends with the footer record (opcode 0x02, length 20) and the 8 magic bytes.
    let Some(footer) = data.len().checked_sub(8 + 29) else { return Ok(()) };
    if data[footer] != 0x02 {
        return Ok(()); // no footer where it should be: the crate reports that
    }
    let summary_start = u64::from_le_bytes(data[footer + 9..footer + 17].try_into().expect("8 bytes")) as usize;
    if summary_start == 0 {
        return Ok(());
    }
    anyhow::ensure!(summary_start <= footer, "the footer puts the summary at byte {summary_start}, past the footer itself");
    let mut at = summary_start;
    while at < footer {
        let opcode = data[at];
        let len = data.get(at + 1..at + 9).map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")) as usize);
        let end = len.and_then(|l| (at + 9).checked_add(l)).filter(|&e| e <= footer);
        let Some(end) = end else { bail!("summary record at byte {at} runs past the summary section") };
        let mut f = Fields { body: &data[at + 9..end], at: 0 };
        let ok = match opcode {
            0x03 => f.skip(2).and_then(|_| f.prefixed()).and_then(|_| f.prefixed()).and_then(|_| f.prefixed()).map(|_| ()),
            0x04 => f.skip(4).and_then(|_| f.prefixed()).and_then(|_| f.prefixed()).and_then(|_| f.string_map()),
            0x08 => f.skip(32).and_then(|_| f.prefixed()).and_then(|_| f.skip(8)).and_then(|_| f.prefixed()).map(|_| ()),
            0x0A => f.skip(40).and_then(|_| f.prefixed()).and_then(|_| f.prefixed()).map(|_| ()),
            0x0B => f.skip(8 + 2 + 16 + 16).and_then(|_| f.prefixed()).map(|_| ()),
            0x0D => f.skip(16).and_then(|_| f.prefixed()).map(|_| ()),
            _ => Some(()),
        };
        if ok.is_none() {
            bail!("summary record (opcode {opcode:#04x}) at byte {at}: a length inside it runs past the record (damaged)");
        }
        at = end;
    }
    Ok(())
}

/// The same check for the metadata record a metadata index points at.
fn check_metadata_lengths(data: &[u8], index: &mcap::records::MetadataIndex) -> Result<()> {
    let start = index.offset as usize;
    let end = start.checked_add(index.length as usize).filter(|&e| e <= data.len() && index.length >= 9);
    let Some(end) = end else { bail!("the metadata index points past the end of the file") };
    let mut f = Fields { body: &data[start + 9..end], at: 0 };
    f.prefixed()
        .and_then(|_| f.string_map())
        .ok_or_else(|| anyhow!("metadata record at byte {start}: a length inside it runs past the record (damaged)"))
}

impl ShardReader {
    pub fn open(path: &Path) -> Result<Self> {
        let file = File::open(path).with_context(|| format!("cannot open shard {}", path.display()))?;
        // SAFETY: shards are immutable once renamed to their final name; the map is read-only.
        let data = unsafe { memmap2::Mmap::map(&file) }.with_context(|| format!("cannot map shard {}", path.display()))?;
        check_summary_lengths(&data).with_context(|| format!("shard {}: summary section is unreadable", path.display()))?;
        let summary = mcap::Summary::read(&data)
            .with_context(|| format!("shard {}: summary section is unreadable", path.display()))?
            .ok_or_else(|| anyhow!("shard {}: has no summary section (truncated or unfinished)", path.display()))?;
        let meta_index = summary
            .metadata_indexes
            .iter()
            .find(|m| m.name == SHARD_METADATA)
            .ok_or_else(|| anyhow!("shard {}: no '{SHARD_METADATA}' metadata", path.display()))?;
        check_metadata_lengths(&data, meta_index).with_context(|| format!("shard {}: metadata unreadable", path.display()))?;
        let meta = mcap::read::metadata(&data, meta_index).with_context(|| format!("shard {}: metadata unreadable", path.display()))?;
        let meta = ShardMeta::from_map(&meta.metadata).with_context(|| format!("shard {}", path.display()))?;
        // A snapshot shard's chunk holds one sample at `index * SAMPLE_PERIOD_NS`; an episode
        // shard's chunks are its frames in time order, numbered from the shard's first sample.
        let episode = meta.extra.contains_key(crate::EPISODE_METADATA_KEY);
        let mut chunks = BTreeMap::new();
        let mut frames: Vec<(u64, usize)> = Vec::new();
        for (i, ci) in summary.chunk_indexes.iter().enumerate() {
            if ci.message_index_offsets.is_empty() {
                continue; // schemas/channels only, no sample
            }
            if episode {
                frames.push((ci.message_start_time, i));
                continue;
            }
            if ci.message_start_time % SAMPLE_PERIOD_NS != 0 || ci.message_start_time != ci.message_end_time {
                bail!("shard {}: chunk {i} does not hold exactly one sample", path.display());
            }
            chunks.insert(ci.message_start_time / SAMPLE_PERIOD_NS, i);
        }
        frames.sort();
        for (k, (_, i)) in frames.into_iter().enumerate() {
            chunks.insert(meta.first_sample + k as u64, i);
        }
        Ok(ShardReader { path: path.to_path_buf(), data, summary, chunks, meta, episode, references: Default::default() })
    }

    /// The messages of chunk `ci` as (topic, payload), decoded with every size bounded before it
    /// is used: the chunk lies inside the file, its record's lengths agree with the summary, its
    /// uncompressed size matches the summary and stays under `MAX_CHUNK_BYTES`, it decompresses
    /// to exactly that size with a matching CRC, and the records inside are read with their lengths
    /// limited to the decompressed bytes. (A flipped byte in a chunk header once made the reader
    /// ask for 3 EB and abort; a damaged record length inside a chunk, found by the fuzzer, asked
    /// for 360 PB.)
    fn chunk_messages(&self, ci: usize) -> Result<Vec<(String, u64, Vec<u8>)>> {
        let index = &self.summary.chunk_indexes[ci];
        let start = index.chunk_start_offset as usize;
        let end = start.checked_add(index.chunk_length as usize).filter(|&e| e <= self.data.len());
        let Some(end) = end else {
            bail!("chunk {ci} ({} bytes at offset {start}) runs past the end of the file ({} bytes)", index.chunk_length, self.data.len());
        };
        // Chunk record: opcode (1), record length (8), message start and end time (8 + 8), the
        // uncompressed size (8) and CRC (4), the compression name (u32 length + bytes), the
        // compressed size (8), then the records, little-endian (MCAP spec).
        let chunk = &self.data[start..end];
        let u64_at = |at: usize| chunk.get(at..at + 8).map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")));
        let u32_at = |at: usize| chunk.get(at..at + 4).map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")));
        let damaged = || anyhow!("chunk {ci}: its header disagrees with the summary (the chunk header is damaged)");
        if chunk.first() != Some(&0x06) {
            bail!("chunk {ci}: no chunk record at offset {start}");
        }
        let size = u64_at(25).ok_or_else(damaged)?;
        if size != index.uncompressed_size || size > MAX_CHUNK_BYTES {
            bail!(
                "chunk {ci}: uncompressed size {size} bytes in its header, {} in the summary (at most {MAX_CHUNK_BYTES}): the chunk header is damaged",
                index.uncompressed_size
            );
        }
        if u64_at(1).ok_or_else(damaged)?.checked_add(9) != Some(index.chunk_length) {
            return Err(damaged());
        }
        let crc = u32_at(33).ok_or_else(damaged)?;
        let name_length = u32_at(37).map(|n| n as usize).filter(|&n| n <= 64).ok_or_else(damaged)?;
        let name = chunk.get(41..41 + name_length).ok_or_else(damaged)?;
        let records_at = 41 + name_length + 8;
        if u64_at(41 + name_length).ok_or_else(damaged)?.checked_add(records_at as u64) != Some(index.chunk_length) {
            return Err(damaged());
        }
        let compressed = &chunk[records_at..];
        let records = match name {
            b"zstd" => zstd::bulk::decompress(compressed, size as usize).map_err(|e| anyhow!("chunk {ci}: zstd: {e}"))?,
            b"" => compressed.to_vec(),
            other => bail!("chunk {ci}: compression '{}' is not one vtgen writes", String::from_utf8_lossy(other)),
        };
        if records.len() as u64 != size {
            bail!("chunk {ci}: decompressed to {} bytes, its header says {size}", records.len());
        }
        if crc != 0 && crc32fast::hash(&records) != crc {
            bail!("chunk {ci}: CRC mismatch (the chunk is damaged)");
        }
        let mut messages = Vec::new();
        for record in mcap::read::LinearReader::sans_magic(&records) {
            if let mcap::records::Record::Message { header, data } = record.with_context(|| format!("chunk {ci}"))? {
                let channel = self
                    .summary
                    .channels
                    .get(&header.channel_id)
                    .ok_or_else(|| anyhow!("chunk {ci}: unknown channel {}", header.channel_id))?;
                messages.push((channel.topic.clone(), header.log_time, data.into_owned()));
            }
        }
        Ok(messages)
    }

    /// Every optical image of `tactile` with its reference: a snapshot's are its own; an episode's
    /// come with its first frame (FORMAT.md, "Episodes"). An image without one is an error.
    fn fill_references(&self, mut tactile: Option<crate::sample::TactileData>) -> Result<Option<crate::sample::TactileData>> {
        let Some(tac) = tactile.as_mut() else { return Ok(tactile) };
        if tac.optical.iter().all(|o| !o.reference.is_empty()) {
            return Ok(tactile);
        }
        if self.references.get().is_none() {
            let first = match (self.episode, self.chunks.values().next()) {
                (true, Some(&ci)) => self.chunk_messages(ci)?,
                _ => Vec::new(),
            };
            let references = first.into_iter().filter(|(t, _, _)| t.ends_with("/reference")).map(|(t, _, data)| (t, data)).collect();
            let _ = self.references.set(references);
        }
        let references = self.references.get().expect("set above");
        for o in tac.optical.iter_mut().filter(|o| o.reference.is_empty()) {
            let topic = crate::topics::tactile_reference(&o.pad);
            let raw = references.get(&topic).ok_or_else(|| anyhow!("{topic} is missing"))?;
            let img = RawImage::decode(&raw[..])?;
            if (img.width, img.height, img.encoding.as_str()) != (o.width, o.height, encodings::RGB8) || img.data.len() != o.image.len() {
                bail!("{topic} is not a {}x{} rgb8 image like its pad's images", o.width, o.height);
            }
            o.reference = img.data.to_vec();
        }
        Ok(tactile)
    }

    /// Decodes every chunk of the shard (bounded sizes, each chunk's CRC), without parsing the
    /// samples: whether the file is intact, as far as its own checks can tell.
    pub fn verify_chunks(&self) -> Result<()> {
        for ci in 0..self.summary.chunk_indexes.len() {
            self.chunk_messages(ci).with_context(|| format!("shard {}", self.path.display()))?;
        }
        Ok(())
    }

    pub fn meta(&self) -> &ShardMeta {
        &self.meta
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Split indices of the samples in this shard, ascending.
    pub fn indices(&self) -> impl Iterator<Item = u64> + '_ {
        self.chunks.keys().copied()
    }

    pub fn len(&self) -> usize {
        self.chunks.len()
    }

    pub fn is_empty(&self) -> bool {
        self.chunks.is_empty()
    }

    /// Only the `/sample/info` JSON of sample `index` (no image is decoded).
    pub fn read_info(&self, index: u64) -> Result<serde_json::Value> {
        let ctx = || format!("shard {} sample {index}", self.path.display());
        let ci = *self.chunks.get(&index).ok_or_else(|| anyhow!("{}: not in this shard", ctx()))?;
        for (topic, _, data) in self.chunk_messages(ci).with_context(ctx)? {
            if topic == topics::SAMPLE_INFO {
                return serde_json::from_slice(&data).with_context(ctx);
            }
        }
        bail!("{}: missing message on {}", ctx(), topics::SAMPLE_INFO)
    }

    /// Reads sample `index`'s `/sample/info` as its type (FORMAT.md).
    pub fn read_sample_info(&self, index: u64) -> Result<crate::SampleInfo> {
        serde_json::from_value(self.read_info(index)?)
            .with_context(|| format!("shard {} sample {index}: /sample/info", self.path.display()))
    }

    /// Reads sample `index` (its index within the split).
    pub fn read(&self, index: u64) -> Result<Sample> {
        let ctx = || format!("shard {} sample {index}", self.path.display());
        let ci = *self.chunks.get(&index).ok_or_else(|| anyhow!("{}: not in this shard", ctx()))?;
        let messages = self.chunk_messages(ci).with_context(ctx)?;
        // The pads in the order the writer wrote them (the robot's pad order).
        let mut pads: Vec<String> = Vec::new();
        for pad in messages.iter().filter_map(|(topic, _, _)| pad_of_topic(topic)) {
            if !pads.iter().any(|p| p == pad) {
                pads.push(pad.to_string());
            }
        }
        // The sample is the chunk's messages at its first instant; an episode frame's chunk also
        // holds its touch and state streams up to the next frame.
        let start = self.summary.chunk_indexes[ci].message_start_time;
        let (now, later): (Vec<_>, Vec<_>) = messages.into_iter().partition(|(_, t, _)| *t == start);
        let by_topic: BTreeMap<String, Vec<u8>> = now.into_iter().map(|(topic, _, data)| (topic, data)).collect();
        let get = |topic: &str| by_topic.get(topic).ok_or_else(|| anyhow!("{}: missing message on {topic}", ctx()));
        let rgb = RawImage::decode(&get(topics::RGB)?[..]).with_context(ctx)?;
        let depth = RawImage::decode(&get(topics::DEPTH)?[..]).with_context(ctx)?;
        let mask = RawImage::decode(&get(topics::MASK)?[..]).with_context(ctx)?;
        let calib = CameraCalibration::decode(&get(topics::CALIBRATION)?[..]).with_context(ctx)?;
        let pose = PoseInFrame::decode(&get(topics::OBJECT_POSE)?[..]).with_context(ctx)?;
        let tf = FrameTransforms::decode(&get(topics::TF)?[..]).with_context(ctx)?;
        let info: crate::SampleInfo =
            serde_json::from_slice(get(topics::SAMPLE_INFO)?).with_context(|| format!("{}: {}", ctx(), topics::SAMPLE_INFO))?;
        let (w, h) = (rgb.width, rgb.height);
        let at = ctx();
        expect_encoding(&rgb, encodings::RGB8, &at)?;
        expect_encoding(&mask, encodings::MASK_MONO8, &at)?;
        let depth = depth_floats(&depth, (w, h), &at)?;
        let depth_noisy = match by_topic.get(topics::DEPTH_NOISY) {
            Some(raw) => Some(depth_floats(&RawImage::decode(&raw[..]).with_context(ctx)?, (w, h), &at)?),
            None => None,
        };
        let k: [f64; 9] = calib.k.as_slice().try_into().map_err(|_| anyhow!("{at}: calibration K has {} values", calib.k.len()))?;
        let p = pose.pose.ok_or_else(|| anyhow!("{at}: empty object pose"))?;
        let find_tf = |child: &str| -> Result<Pose> {
            let t = tf
                .transforms
                .iter()
                .find(|t| t.parent_frame_id == frames::WORLD && t.child_frame_id == child)
                .ok_or_else(|| anyhow!("{at}: /tf lacks world -> {child}"))?;
            to_pose(t.translation, t.rotation, &at)
        };
        Ok(Sample {
            index,
            width: w,
            height: h,
            rgb: unpadded(&rgb, 3, (w, h), &at)?,
            depth,
            depth_noisy,
            mask: unpadded(&mask, 1, (w, h), &at)?,
            k,
            t_camera_object: to_pose(p.position, p.orientation, &at)?,
            t_world_camera: find_tf(frames::CAMERA)?,
            t_world_object: find_tf(frames::OBJECT)?,
            extra_transforms: tf
                .transforms
                .iter()
                .filter(|t| {
                    !(t.parent_frame_id == frames::WORLD && (t.child_frame_id == frames::CAMERA || t.child_frame_id == frames::OBJECT))
                })
                .map(|t| Ok((t.parent_frame_id.clone(), t.child_frame_id.clone(), to_pose(t.translation, t.rotation, &at)?)))
                .collect::<Result<_>>()?,
            tactile: self.fill_references(read_tactile(&by_topic, &pads).with_context(ctx)?).with_context(ctx)?,
            episode: match self.episode {
                true => Some(read_episode_streams(start, &by_topic, later, &pads).with_context(ctx)?),
                false => None,
            },
            info,
        })
    }
}

/// An image's rows without their padding, checked to be `size` (width, height) with `bpp` bytes
/// per pixel; `at` names the sample in errors.
fn unpadded(img: &RawImage, bpp: usize, (w, h): (u32, u32), at: &str) -> Result<Vec<u8>> {
    let row = img.width as usize * bpp;
    let step = img.step as usize;
    if img.width != w || img.height != h || step < row || img.data.len() < step * h as usize {
        bail!("{at}: image '{}' has inconsistent size", img.encoding);
    }
    Ok(img.data.chunks(step).take(h as usize).flat_map(|r| &r[..row]).copied().collect())
}

fn expect_encoding(img: &RawImage, encoding: &str, at: &str) -> Result<()> {
    if img.encoding != encoding {
        bail!("{at}: expected encoding {encoding}, found {}", img.encoding)
    }
    Ok(())
}

/// A depth image's metres.
fn depth_floats(img: &RawImage, size: (u32, u32), at: &str) -> Result<Vec<f32>> {
    expect_encoding(img, encodings::DEPTH_32FC1, at)?;
    Ok(unpadded(img, 4, size, at)?.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect())
}

/// A Foxglove position and orientation as a pose; both must be there.
fn to_pose(p: Option<foxglove::schemas::Vector3>, q: Option<foxglove::schemas::Quaternion>, at: &str) -> Result<Pose> {
    let p = p.ok_or_else(|| anyhow!("{at}: pose lacks a position"))?;
    let q = q.ok_or_else(|| anyhow!("{at}: pose lacks an orientation"))?;
    Ok(Pose { position: [p.x, p.y, p.z], orientation: [q.x, q.y, q.z, q.w] })
}

/// An episode frame's streams: the state at the frame's instant, then the touch and states of the
/// `later` messages, grouped by time.
fn read_episode_streams(
    start: u64,
    now: &BTreeMap<String, Vec<u8>>,
    later: Vec<(String, u64, Vec<u8>)>,
    pads: &[String],
) -> Result<crate::sample::EpisodeData> {
    let state = |data: &[u8]| -> Result<crate::StateRecord> { serde_json::from_slice(data).context(topics::EPISODE_STATE) };
    let mut states = Vec::new();
    if let Some(data) = now.get(topics::EPISODE_STATE) {
        states.push((start, state(data)?));
    }
    let mut touch: BTreeMap<u64, BTreeMap<String, Vec<u8>>> = BTreeMap::new();
    for (topic, t, data) in later {
        if topic == topics::EPISODE_STATE {
            states.push((t, state(&data)?));
        } else if topic.starts_with("/tactile/") {
            touch.entry(t).or_default().insert(topic, data);
        }
    }
    let tactile = touch
        .into_iter()
        .map(|(t, by_topic)| Ok((t, read_tactile(&by_topic, pads)?.ok_or_else(|| anyhow!("touch at {t} ns without its points"))?)))
        .collect::<Result<_>>()?;
    Ok(crate::sample::EpisodeData { time_ns: start, tactile, states })
}

/// The pad a `/tactile/<pad>/depth` topic is of.
fn pad_of_topic(topic: &str) -> Option<&str> {
    topic.strip_prefix("/tactile/").and_then(|t| t.strip_suffix("/depth"))
}

/// The little-endian `f32` at byte `o` of a packed point.
fn f32_at(c: &[u8], o: usize) -> f32 {
    f32::from_le_bytes([c[o], c[o + 1], c[o + 2], c[o + 3]])
}

/// The tactile topics of a sample, if it has them, with its `pad_names` in the order the sample's
/// messages were written (the robot's pad order, which the points' pad indices refer to).
fn read_tactile(by_topic: &BTreeMap<String, Vec<u8>>, pad_names: &[String]) -> Result<Option<crate::sample::TactileData>> {
    use foxglove::schemas::PointCloud;
    let Some(raw) = by_topic.get(topics::TACTILE_POINTS) else { return Ok(None) };
    let cloud = PointCloud::decode(&raw[..])?;
    if cloud.point_stride != crate::tactile_points::STRIDE {
        bail!("tactile points have stride {}, expected {}", cloud.point_stride, crate::tactile_points::STRIDE);
    }
    let points = cloud
        .data
        .chunks_exact(crate::tactile_points::STRIDE as usize)
        .map(|c| crate::sample::TactilePointRecord {
            position: [f32_at(c, 0), f32_at(c, 4), f32_at(c, 8)],
            distance: f32_at(c, 12),
            pad: u32::from_le_bytes([c[16], c[17], c[18], c[19]]),
        })
        .collect();
    let mut pads = Vec::new();
    let mut depth = Vec::new();
    let mut resolution = 0;
    for name in pad_names {
        let raw = &by_topic[&crate::topics::tactile_depth(name)];
        let img = RawImage::decode(&raw[..])?;
        resolution = img.width;
        pads.push(name.clone());
        depth.push(img.data.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect());
    }
    let mut optical = Vec::new();
    for name in pad_names {
        let Some(raw) = by_topic.get(&crate::topics::tactile_image(name)) else { continue };
        let rgb = |raw: &[u8], what: &str| -> Result<RawImage> {
            let img = RawImage::decode(raw)?;
            if img.encoding != encodings::RGB8 || img.data.len() != (img.width * img.height * 3) as usize || img.step != img.width * 3 {
                bail!("/tactile/{name}/{what}: expected {}x{} rgb8 without padding", img.width, img.height);
            }
            Ok(img)
        };
        let image = rgb(raw, "image")?;
        // In an episode only its first frame has the reference: `fill_references` adds it.
        let reference = match by_topic.get(&crate::topics::tactile_reference(name)) {
            Some(raw) => {
                let reference = rgb(raw, "reference")?;
                if (reference.width, reference.height) != (image.width, image.height) {
                    bail!(
                        "/tactile/{name}/reference is {}x{}, its image {}x{}",
                        reference.width,
                        reference.height,
                        image.width,
                        image.height
                    );
                }
                reference.data.to_vec()
            }
            None => Vec::new(),
        };
        optical.push(crate::sample::OpticalPadImage {
            pad: name.clone(),
            width: image.width,
            height: image.height,
            image: image.data.to_vec(),
            reference,
        });
    }
    let mut forces = Vec::new();
    for name in pad_names {
        let Some(raw) = by_topic.get(&crate::topics::tactile_force(name)) else { continue };
        forces.push(read_force_field(name, &PointCloud::decode(&raw[..])?)?);
    }
    let mut marker_flow = Vec::new();
    for name in pad_names {
        let Some(raw) = by_topic.get(&crate::topics::tactile_markers(name)) else { continue };
        let cloud = PointCloud::decode(&raw[..])?;
        let stride = crate::marker_points::STRIDE as usize;
        if cloud.point_stride as usize != stride || !cloud.data.len().is_multiple_of(stride) {
            bail!(
                "/tactile/{name}/markers: expected {stride}-byte markers, got {} bytes of stride {}",
                cloud.data.len(),
                cloud.point_stride
            );
        }
        let markers = cloud.data.chunks_exact(stride).map(|c| ([f32_at(c, 12), f32_at(c, 16)], [f32_at(c, 0), f32_at(c, 4)])).collect();
        marker_flow.push(crate::sample::PadMarkerFlow { pad: name.clone(), markers });
    }
    Ok(Some(crate::sample::TactileData { pads, resolution, depth, points, optical, forces, marker_flow }))
}

/// A pad's `/tactile/<pad>/force` cloud: a square grid of cells, laid out as
/// [`crate::force_cells::FIELDS`] says.
fn read_force_field(pad: &str, cloud: &foxglove::schemas::PointCloud) -> Result<crate::sample::PadForceField> {
    let stride = crate::force_cells::STRIDE as usize;
    let n = cloud.data.len() / stride;
    let resolution = (n as f64).sqrt().round() as u32;
    if cloud.point_stride as usize != stride || !cloud.data.len().is_multiple_of(stride) || (resolution * resolution) as usize != n {
        bail!(
            "/tactile/{pad}/force: expected a square grid of {stride}-byte cells, got {} bytes of stride {}",
            cloud.data.len(),
            cloud.point_stride
        );
    }
    let cells = cloud
        .data
        .chunks_exact(stride)
        .map(|c| crate::sample::ForceCell {
            position: [f32_at(c, 0), f32_at(c, 4)],
            pressure: f32_at(c, 12),
            shear: [f32_at(c, 16), f32_at(c, 20)],
            slip: u32::from_le_bytes([c[24], c[25], c[26], c[27]]) != 0,
        })
        .collect();
    Ok(crate::sample::PadForceField { pad: pad.to_string(), resolution, cells })
}

/// A dataset directory opened through its manifest.
pub struct DatasetReader {
    root: PathBuf,
    manifest: Manifest,
}

impl DatasetReader {
    pub fn open(root: &Path) -> Result<Self> {
        let manifest = Manifest::load(&root.join(crate::MANIFEST_FILE))?;
        Ok(DatasetReader { root: root.to_path_buf(), manifest })
    }

    pub fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    pub fn root(&self) -> &Path {
        &self.root
    }

    /// The complete shards of a split, opened.
    pub fn shards(&self, split: &str) -> Result<Vec<ShardReader>> {
        let Some(s) = self.manifest.splits.get(split) else { bail!("dataset {} has no split '{split}'", self.root.display()) };
        s.shards.iter().filter(|e| e.sha256.is_some()).map(|e| ShardReader::open(&self.root.join(&e.file))).collect()
    }

    /// Every sample of a split, in order.
    pub fn samples(&self, split: &str) -> Result<impl Iterator<Item = Result<Sample>>> {
        let shards = self.shards(split)?;
        Ok(shards.into_iter().flat_map(|sh| {
            let idx: Vec<u64> = sh.indices().collect();
            idx.into_iter().map(move |i| sh.read(i))
        }))
    }
}

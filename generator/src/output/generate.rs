//! `vtgen generate`: config -> plan -> (per shard, per sample) scene -> render -> sample -> shard
//! writer, with resumable, atomically-renamed shards and a checksummed manifest.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use indicatif::{ProgressBar, ProgressStyle};
use sha2::{Digest, Sha256};
use vt_dataset::{
    Compression, GraspStats, Manifest, ModelInfo, ModelsInfo, OcclusionHistogram, ShardEntry, ShardMeta, ShardReceipt, SplitManifest,
    mask_ids,
};

use crate::assets::sources::MeshSources;
use crate::assets::{LoadedObject, MeshSource, load_objects};
use crate::config::{Config, LoadedConfig};
use crate::output::workers::run_pool;
use crate::output::writer_thread::WriterThread;
use crate::plan::{Plan, SPLITS, ShardPlan, ShardSelector};
use crate::render::WgpuRenderer;
use crate::sample::{SampleFactory, ShardTally};

pub const GENERATOR: &str = concat!("vtgen ", env!("CARGO_PKG_VERSION"));
/// The generator's build: a hash of the sources and dependency versions that decide a dataset's
/// bytes (`build.rs`). A dataset records it with the version in `generator.json`.
pub const GENERATOR_BUILD: &str = env!("VTGEN_BUILD_ID");
/// The dataset's record of the generator that made it.
pub const GENERATOR_FILE: &str = "generator.json";

#[derive(Debug, Clone)]
pub struct GenerateOptions {
    pub out: PathBuf,
    pub shard: ShardSelector,
    pub resume: bool,
    pub overwrite: bool,
    pub jobs: usize,
    pub quiet: bool,
    pub ycb_dir: Option<PathBuf>,
    /// Continue a dataset another generator build started (its shards and these then differ in
    /// how they were made).
    pub mix_generators: bool,
    /// Generate nothing: rebuild the manifest from the shards on disk and fail, naming them, if
    /// any selected shard is missing (a cluster's merge step).
    pub manifest_only: bool,
}

#[derive(Debug, Clone)]
pub struct GenerateSummary {
    pub samples: u64,
    pub shards_written: usize,
    pub shards_skipped: usize,
    pub bytes: u64,
    pub seconds: f64,
    pub adapter: String,
    pub complete: bool,
}

pub fn sha256_hex(data: &[u8]) -> String {
    Sha256::digest(data).iter().map(|b| format!("{b:02x}")).collect()
}

/// Writes `models/`: every object's rendered mesh as PLY and `models_info.json`, with the symmetries
/// of the object's declared kind derived and verified on that very mesh (real scan, custom mesh or
/// procedural stand-in). Returns one line per declared symmetry that does not hold on the mesh and
/// was dropped, for the caller to report.
fn write_models(out: &Path, objects: &[LoadedObject]) -> Result<Vec<String>> {
    let dir = out.join(vt_dataset::MODELS_DIR);
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut infos = Vec::new();
    let mut dropped = Vec::new();
    for o in objects {
        let file = format!("{}.ply", o.id);
        vt_dataset::write_ply(&dir.join(&file), &o.mesh.positions, &o.mesh.normals, &o.mesh.indices, vt_dataset::LengthUnit::Metres)?;
        let e = o.mesh.extents();
        let sym = vt_objects::derive_symmetries(&o.mesh.positions, &o.mesh.indices, o.symmetry);
        for c in sym.dropped() {
            dropped.push(format!(
                "{}: its declared {} symmetry '{}' does not hold on its mesh (moves the surface by {:.2} mm at the 95th percentile, \
                 {:.2} mm at the 99th; tolerance {:.2} mm): left out{}",
                o.id,
                sym.declared.as_str(),
                c.name,
                1e3 * c.derived.p95,
                1e3 * c.derived.p99,
                1e3 * sym.tolerance,
                if sym.kind == vt_objects::Symmetry::None { ", symmetry 'none'" } else { "" }
            ));
        }
        infos.push(ModelInfo {
            id: o.id.clone(),
            object_index: o.index,
            mask_id: mask_ids::TARGET_OBJECT,
            symmetry: sym.kind.as_str().into(),
            mass: o.mass,
            extents: [e.x as f64, e.y as f64, e.z as f64],
            diameter: o.mesh.diameter(),
            source: if o.source == MeshSource::Procedural { "procedural".into() } else { "mesh".into() },
            file,
            symmetries_discrete: sym.discrete_row_major(),
            symmetries_continuous: sym
                .continuous
                .iter()
                .map(|a| vt_dataset::ContinuousSymmetry { axis: a.axis.to_array(), offset: a.offset.to_array() })
                .collect(),
        });
    }
    let text = serde_json::to_string_pretty(&ModelsInfo { objects: infos })? + "\n";
    vt_dataset::write_atomic(&dir.join(vt_dataset::MODELS_INFO_FILE), text.as_bytes())?;
    Ok(dropped)
}

/// Prepares the output directory: refuses to mix datasets of different configs or of meshes loaded
/// from different sources, and to redo complete shards without `--resume` or `--overwrite`. Holds
/// the directory's lock, so `--shard` processes starting together cannot each claim it.
fn prepare_output(out: &Path, config_json: &str, sources: &MeshSources, plan: &Plan, opts: &GenerateOptions) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create output directory {}", out.display()))?;
    let _lock = lock_dataset(out)?;
    let cfg_path = out.join("config.json");
    let sources_path = out.join(vt_dataset::SOURCES_FILE);
    if let Ok(existing) = std::fs::read_to_string(&cfg_path) {
        let same = existing == config_json;
        if opts.overwrite {
            for d in SPLITS.iter().map(|s| s.as_str()).chain([vt_dataset::MODELS_DIR]) {
                let p = out.join(d);
                if p.exists() {
                    std::fs::remove_dir_all(&p).with_context(|| format!("cannot remove {}", p.display()))?;
                }
            }
            let _ = std::fs::remove_file(out.join(vt_dataset::MANIFEST_FILE));
        } else if !same {
            bail!(
                "{} holds a dataset generated from a different config; choose another --out, or pass --overwrite to replace it",
                out.display()
            );
        } else if let Some(diff) = read_sources(&sources_path)?.and_then(|dataset| sources.difference(&dataset)) {
            bail!(
                "{} holds a dataset whose meshes came from other sources ({diff}); pass the dataset's --ycb-dir and --robot-assets, \
                 choose another --out, or pass --overwrite to replace it",
                out.display()
            );
        } else if let Some(made_by) = read_generator(out)?
            && made_by != generator_identity()
            && !opts.mix_generators
        {
            bail!(
                "{} was generated by {} (build {}); this is {} (build {}): its shards would mix two generators' physics and \
                 rendering. Continue it with the vtgen that started it, choose another --out, pass --overwrite to start again, \
                 or --mix-generators to continue anyway",
                out.display(),
                made_by.generator,
                made_by.build,
                GENERATOR,
                GENERATOR_BUILD
            );
        } else if !opts.resume {
            let done = plan.shards.iter().filter(|s| opts.shard.selects(s) && out.join(s.file()).is_file()).count();
            if done > 0 {
                bail!(
                    "{} already has {done} complete shard(s) of this dataset; pass --resume to continue it or --overwrite to start again",
                    out.display()
                );
            }
        }
    }
    vt_dataset::write_atomic(&cfg_path, config_json.as_bytes())
        .with_context(|| format!("output directory {} is not writable", out.display()))?;
    // The first generator stays on record when others are let in (`--mix-generators`).
    if opts.overwrite || read_generator(out)?.is_none() {
        let text = serde_json::to_string_pretty(&generator_identity())? + "\n";
        vt_dataset::write_atomic(&out.join(GENERATOR_FILE), text.as_bytes())?;
    }
    vt_dataset::write_atomic(&sources_path, (serde_json::to_string_pretty(sources)? + "\n").as_bytes())
}

/// Writes `robot/` (FORMAT.md): the robot's URDF as simulated (an arm and a hand joined into one,
/// the description's joint corrections applied) and the upstream text they corrected, its
/// description, and the mesh files its URDF names by name, size and SHA-256, so that a reader can
/// redraw the robot from its own copy of them.
fn write_robot(out: &Path, robot: &vt_robot::Robot, assets: Option<&Path>) -> Result<()> {
    let dir = out.join(vt_dataset::ROBOT_DIR);
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    vt_dataset::write_atomic(&dir.join("robot.urdf"), robot.urdf_text.as_bytes())?;
    vt_dataset::write_atomic(&dir.join("robot.yaml"), robot.description_text.as_bytes())?;
    let upstream = dir.join("robot.upstream.urdf");
    match &robot.upstream_urdf_text {
        Some(text) => vt_dataset::write_atomic(&upstream, text.as_bytes())?,
        // A rerun over a dataset of a robot that had corrections: no stale upstream file stays.
        None if upstream.exists() => std::fs::remove_file(&upstream).with_context(|| format!("cannot remove {}", upstream.display()))?,
        None => {}
    }
    let meshes = crate::assets::sources::robot_mesh_files(robot, assets)?;
    let text = serde_json::to_string_pretty(&vt_dataset::RobotFiles { name: robot.name.clone(), meshes })? + "\n";
    vt_dataset::write_atomic(&dir.join("meshes.json"), text.as_bytes())
}

/// Which generator made a dataset (`generator.json`).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct GeneratorIdentity {
    pub generator: String,
    pub build: String,
}

/// This generator.
pub fn generator_identity() -> GeneratorIdentity {
    GeneratorIdentity { generator: GENERATOR.into(), build: GENERATOR_BUILD.into() }
}

/// The generator a dataset records, when it does.
fn read_generator(out: &Path) -> Result<Option<GeneratorIdentity>> {
    read_record(&out.join(GENERATOR_FILE), "generator record")
}

/// The dataset's mesh sources, when it has recorded them.
fn read_sources(path: &Path) -> Result<Option<MeshSources>> {
    read_record(path, "sources file")
}

/// A JSON record of the dataset's identity (`what` names it in errors); None when it is absent.
fn read_record<T: serde::de::DeserializeOwned>(path: &Path, what: &str) -> Result<Option<T>> {
    match std::fs::read_to_string(path) {
        Ok(text) => serde_json::from_str(&text).map(Some).with_context(|| format!("{} is not a valid {what}", path.display())),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(e).with_context(|| format!("cannot read {}", path.display())),
    }
}

/// Opens (creating, never truncating) a lock file of the dataset.
fn open_lock_file(lock_path: &Path) -> Result<std::fs::File> {
    std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(lock_path)
        .with_context(|| format!("cannot open {}", lock_path.display()))
}

/// Takes the dataset directory's lock (an advisory lock, released when the file closes), so that
/// processes of one dataset take turns at claiming the directory and rewriting the manifest.
fn lock_dataset(out: &Path) -> Result<std::fs::File> {
    let lock_path = out.join(".manifest.lock");
    let lock = open_lock_file(&lock_path)?;
    lock.lock().with_context(|| format!("cannot lock {}", lock_path.display()))?;
    Ok(lock)
}

/// Each split's shards as they are on disk (size and checksum: known ones reused when the size is
/// the same, complete unknown ones hashed), and whether every shard is there.
fn split_manifests(out: &Path, plan: &Plan, known: &BTreeMap<String, (u64, String)>) -> Result<(BTreeMap<String, SplitManifest>, bool)> {
    let mut splits = BTreeMap::new();
    let mut complete = true;
    for (si, split) in SPLITS.iter().enumerate() {
        let mut shards = Vec::new();
        for s in plan.shards.iter().filter(|s| s.split == *split) {
            let file = s.file();
            let path = out.join(&file);
            let (bytes, sha256) = match std::fs::metadata(&path) {
                Ok(m) => match known.get(&file) {
                    Some((b, h)) if *b == m.len() => (Some(*b), Some(h.clone())),
                    _ => {
                        let (b, h) = vt_dataset::sha256_file(&path)?;
                        (Some(b), Some(h))
                    }
                },
                Err(_) => {
                    complete = false;
                    (None, None)
                }
            };
            shards.push(ShardEntry {
                file,
                shard_index: s.shard_index,
                first_sample: s.first_sample,
                samples: s.samples.len() as u64,
                bytes,
                sha256,
            });
        }
        splits.insert(
            split.to_string(),
            SplitManifest { samples: plan.samples_per_split[si], samples_per_shard: plan.samples_per_shard, shards },
        );
    }
    Ok((splits, complete))
}

/// Figures summed over the complete shards: the grasp loop's (each shard stores those of the
/// trajectories that start in it) and the occlusion histogram.
fn summed_figures(out: &Path, splits: &BTreeMap<String, SplitManifest>) -> Result<(GraspStats, [u64; 3])> {
    let mut grasp_total = GraspStats::default();
    let mut histogram = [0u64; 3];
    for e in splits.values().flat_map(|s: &SplitManifest| &s.shards).filter(|e| e.sha256.is_some()) {
        let reader = vt_dataset::ShardReader::open(&out.join(&e.file))?;
        let extra = &reader.meta().extra;
        if let Some(j) = extra.get(vt_dataset::GRASP_STATS_KEY) {
            let st: GraspStats = serde_json::from_str(j).with_context(|| format!("{}: grasp_stats", e.file))?;
            grasp_total.merge(&st);
        }
        if let Some(j) = extra.get(vt_dataset::OCCLUSION_HISTOGRAM_KEY) {
            let h: [u64; 3] = serde_json::from_str(j).with_context(|| format!("{}: occlusion_histogram", e.file))?;
            (0..3).for_each(|i| histogram[i] += h[i]);
        }
    }
    Ok((grasp_total, histogram))
}

/// Rebuilds `manifest.json` from the shards on disk. Checksums already known (from this run or the
/// previous manifest, same size) are reused; unknown complete shards are hashed. Parallel `--shard`
/// processes on one directory each rewrite it this way, so the last one to finish lists them all.
// The lock is held from the read to the atomic write: one critical section.
fn update_manifest(out: &Path, config: &Config, config_sha: &str, plan: &Plan, receipts: &[(String, ShardReceipt)]) -> Result<Manifest> {
    // Parallel `--shard` processes finishing together take turns, so none writes a manifest that
    // misses a shard another just listed.
    let _lock = lock_dataset(out)?;
    let mut known = known_checksums(out, config_sha);
    for (file, r) in receipts {
        known.insert(file.clone(), (r.bytes, r.sha256.clone()));
    }
    let (splits, complete) = split_manifests(out, plan, &known)?;
    let (grasp_total, histogram) = summed_figures(out, &splits)?;
    let m = Manifest {
        format: vt_dataset::FORMAT_NAME.into(),
        format_version: vt_dataset::FORMAT_VERSION,
        generator: GENERATOR.into(),
        seed: config.seed,
        config_sha256: config_sha.into(),
        complete,
        splits,
        grasp: config.robot.is_some().then_some(grasp_total),
        occlusion: Some(OcclusionHistogram::new(histogram)),
    };
    m.save(&out.join(vt_dataset::MANIFEST_FILE))?;
    Ok(m)
}

/// The shards' sizes and checksums the dataset's manifest lists (when it is this config's).
fn known_checksums(out: &Path, config_sha: &str) -> BTreeMap<String, (u64, String)> {
    let mut known = BTreeMap::new();
    if let Ok(old) = Manifest::load(&out.join(vt_dataset::MANIFEST_FILE))
        && old.config_sha256 == config_sha
    {
        for s in old.splits.values().flat_map(|s| &s.shards) {
            if let (Some(b), Some(h)) = (s.bytes, &s.sha256) {
                known.insert(s.file.clone(), (b, h.clone()));
            }
        }
    }
    known
}

/// A shard's writer lock (`<split>/.shard-NNNNN.mcap.lock`), exclusive, held from the moment a
/// run decides to write the shard until it ends; the OS releases it if the process dies. A second
/// process that selects the shard meanwhile is refused, the lock named.
fn lock_shard(out: &Path, shard: &ShardPlan) -> Result<std::fs::File> {
    let path = out.join(shard.file());
    let dir = path.parent().expect("a shard lies in its split's folder");
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let name = path.file_name().expect("a shard file name").to_string_lossy();
    // The file stays (empty: a dataset's bytes do not depend on who wrote it); removing it would
    // let a third process lock a new file while a second still holds the old one.
    let lock_path = dir.join(format!(".{name}.lock"));
    let lock = open_lock_file(&lock_path)?;
    match lock.try_lock() {
        Ok(()) => Ok(lock),
        Err(std::fs::TryLockError::WouldBlock) => bail!(
            "{} is being written by another vtgen process (it holds {}): one shard has one writer, so this run leaves it; \
             when that one ends, rerun with --resume (its shard is kept if complete, redone otherwise)",
            shard.file(),
            lock_path.display()
        ),
        Err(std::fs::TryLockError::Error(e)) => Err(e).with_context(|| format!("cannot lock {}", lock_path.display())),
    }
}

/// Whether a shard on disk can be kept: the manifest's size and SHA-256 when it lists it (else
/// every chunk decoded, CRCs checked), and its own record of what it is (this config, this
/// generator, this shard's place). Err: why it must be redone.
fn verify_shard(out: &Path, shard: &ShardPlan, known: &BTreeMap<String, (u64, String)>, config_sha: &str) -> Result<(), String> {
    let file = shard.file();
    let path = out.join(&file);
    if let Some((bytes, sha)) = known.get(&file) {
        let (b, h) = vt_dataset::sha256_file(&path).map_err(|e| format!("cannot read it: {e:#}"))?;
        if b != *bytes {
            return Err(format!("{b} bytes, the manifest says {bytes} (truncated or replaced)"));
        }
        if h != *sha {
            return Err("its SHA-256 differs from the manifest's (corrupted)".into());
        }
    }
    let reader = vt_dataset::ShardReader::open(&path).map_err(|e| format!("{e:#}"))?;
    let m = reader.meta();
    let expected = (config_sha, shard.split.as_str(), shard.shard_index, shard.first_sample, shard.samples.len() as u64);
    if (m.config_sha256.as_str(), m.split.as_str(), m.shard_index, m.first_sample, m.sample_count) != expected {
        return Err("its own record says it is another config's or another shard".into());
    }
    if m.generator != GENERATOR {
        return Err(format!("made by {}, not {GENERATOR}", m.generator));
    }
    if !known.contains_key(&file) {
        reader.verify_chunks().map_err(|e| format!("{e:#}"))?;
    }
    Ok(())
}

/// Whether an error comes from a full disk, a full quota or the file size limit.
fn is_disk_full(e: &anyhow::Error) -> bool {
    use std::io::ErrorKind::{FileTooLarge, QuotaExceeded, StorageFull};
    e.chain().filter_map(|c| c.downcast_ref::<std::io::Error>()).any(|io| matches!(io.kind(), StorageFull | FileTooLarge | QuotaExceeded))
}

/// Free bytes for an unprivileged writer on the filesystem holding `dir`, when the OS says.
#[cfg(unix)]
fn free_bytes(dir: &Path) -> Option<u64> {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(dir.as_os_str().as_bytes()).ok()?;
    let mut s: libc::statvfs = unsafe { std::mem::zeroed() };
    // SAFETY: a valid NUL-terminated path and a statvfs struct to fill.
    (unsafe { libc::statvfs(c.as_ptr(), &mut s) } == 0).then(|| s.f_bavail as u64 * s.f_frsize as u64)
}

/// Elsewhere the run does not warn ahead; a full disk still stops it cleanly.
#[cfg(not(unix))]
fn free_bytes(_dir: &Path) -> Option<u64> {
    None
}

/// "a–b" of an estimate of `samples` samples' bytes.
fn estimate(config: &Config, samples: u64) -> String {
    let (low, high) = crate::plan::bytes_per_sample(config);
    format!("{}–{}", super::human_bytes(low * samples as f64), super::human_bytes(high * samples as f64))
}

fn write_shard(
    factory: &mut SampleFactory,
    out: &Path,
    shard: &ShardPlan,
    meta: &ShardMeta,
    compression: Compression,
    progress: &ProgressBar,
    abort: &AtomicBool,
) -> Result<Option<ShardReceipt>> {
    let path = out.join(shard.file());
    let mut writer = WriterThread::create(&path, meta, compression)?;
    let mut tally = ShardTally::default();
    for (k, r) in shard.samples.iter().enumerate() {
        if abort.load(Ordering::Relaxed) {
            return Ok(None);
        }
        let index = shard.first_sample + k as u64;
        if k == 0 || shard.samples[k - 1].object_index != r.object_index {
            writer.set_scene(factory.scene_models(r.object_index))?;
        }
        let sample = factory.make(shard.split, index, r, &mut tally).with_context(|| format!("{} sample {index}", shard.split))?;
        writer.write_sample(sample)?;
        progress.inc(1);
    }
    writer.set_metadata(vt_dataset::OCCLUSION_HISTOGRAM_KEY, serde_json::to_string(&tally.occlusion)?)?;
    if factory.has_robot() {
        writer.set_metadata(vt_dataset::GRASP_STATS_KEY, serde_json::to_string(&tally.grasp)?)?;
    }
    Ok(Some(writer.finish()?.0))
}

/// What a run will write: the selected shards still to write, each locked for this run, how many
/// were kept, and the shards redone with why.
struct ShardsToWrite<'p> {
    todo: Vec<&'p ShardPlan>,
    /// Held until the run ends ([`lock_shard`]).
    _locks: Vec<std::fs::File>,
    kept: usize,
    redone: Vec<String>,
}

/// The selected shards still to write, each locked for this run: a complete one is kept when it
/// checks out ([`verify_shard`]) and redone otherwise; a `.partial` leftover of an interrupted run
/// is removed and its shard redone (with the lock held, no other process owns it).
fn shards_to_write<'p>(out: &Path, plan: &'p Plan, opts: &GenerateOptions, config_sha: &str) -> Result<ShardsToWrite<'p>> {
    let known = known_checksums(out, config_sha);
    let mut run = ShardsToWrite { todo: Vec::new(), _locks: Vec::new(), kept: 0, redone: Vec::new() };
    for s in plan.shards.iter().filter(|s| opts.shard.selects(s)) {
        let lock = lock_shard(out, s)?;
        let path = out.join(s.file());
        if path.is_file() {
            match verify_shard(out, s, &known, config_sha) {
                Ok(()) => {
                    run.kept += 1;
                    continue;
                }
                Err(why) => {
                    run.redone.push(format!("{}: {why}", s.file()));
                    std::fs::remove_file(&path).with_context(|| format!("cannot remove {}", path.display()))?;
                }
            }
        }
        // A leftover from an interrupted run: never complete, always redone.
        let partial = PathBuf::from(format!("{}{}", path.display(), vt_dataset::PARTIAL_SUFFIX));
        if partial.exists() {
            std::fs::remove_file(&partial).with_context(|| format!("cannot remove {}", partial.display()))?;
        }
        run.todo.push(s);
        run._locks.push(lock);
    }
    Ok(run)
}

/// A warning up front when the disk holding `out` may be too small for `samples` samples.
fn warn_if_short_of_space(out: &Path, config: &Config, samples: u64, quiet: bool) {
    let needed = crate::plan::bytes_per_sample(config).1 * samples as f64;
    if let Some(free) = free_bytes(out)
        && (free as f64) < needed
        && !quiet
    {
        eprintln!(
            "warning: {} has {} free and this run may write {} (estimate); a full disk stops it cleanly and --resume continues",
            out.display(),
            super::human_bytes(free as f64),
            estimate(config, samples)
        );
    }
}

fn progress_bar(samples: u64, quiet: bool) -> ProgressBar {
    let progress = if quiet { ProgressBar::hidden() } else { ProgressBar::new(samples) };
    progress.set_style(
        ProgressStyle::with_template("{spinner} {elapsed_precise} [{bar:36}] {pos}/{len} samples  {per_sec}  ETA {eta}  {msg}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    progress
}

/// A shard that failed: its unfinished file removed, and a full disk explained (how much the
/// shard and the run still need, and that `--resume` keeps the complete shards).
fn shard_failed(e: anyhow::Error, out: &Path, config: &Config, shard: &ShardPlan, run_samples: u64) -> anyhow::Error {
    // The unfinished shard is never complete: its bytes are freed now (a full disk needs them),
    // and a resume would redo it anyway.
    let path = out.join(shard.file());
    let _ = std::fs::remove_file(format!("{}{}", path.display(), vt_dataset::PARTIAL_SUFFIX));
    if !is_disk_full(&e) {
        return e;
    }
    e.context(format!(
        "the disk is full writing {}: this shard needs about {}, the run's unwritten shards about {}; free space, then rerun with --resume (complete shards are kept)",
        path.display(),
        estimate(config, shard.samples.len() as u64),
        estimate(config, run_samples)
    ))
}

/// Generates the dataset (or this process's `--shard` part of it).
pub fn generate(cfg: &LoadedConfig, opts: &GenerateOptions) -> Result<GenerateSummary> {
    let started = Instant::now();
    let config = &cfg.config;
    let plan = Plan::new(config);
    let config_json = config.canonical_json();
    let config_sha = sha256_hex(config_json.as_bytes());
    let out = &opts.out;
    // Meshes first: a bad mesh is reported before anything is written.
    let objects = load_objects(cfg, opts.ycb_dir.as_ref())?;
    let sources = MeshSources::of(cfg, &objects)?;
    // An object the gripper can never hold is refused now, not hours into the run.
    let unholdable = unholdable_objects(cfg, &objects);
    if !unholdable.is_empty() {
        bail!("{} of the config's objects cannot be grasped:\n  {}", unholdable.len(), unholdable.join("\n  "));
    }
    prepare_output(out, &config_json, &sources, &plan, opts)?;
    if let Some(robot) = &cfg.robot {
        write_robot(out, robot, cfg.robot_assets.as_deref())?;
    }
    for line in write_models(out, &objects)? {
        if !opts.quiet {
            eprintln!("symmetry: {line}");
        }
    }

    if opts.manifest_only {
        let manifest = update_manifest(out, config, &config_sha, &plan, &[])?;
        let missing: Vec<&ShardPlan> = plan.shards.iter().filter(|s| opts.shard.selects(s) && !out.join(s.file()).is_file()).collect();
        if !missing.is_empty() {
            bail!(
                "{} of the dataset's shards are missing ({}): rerun the tasks that make them (with a cluster's array, the indices \
                 j mod N of shards j), e.g. `vtgen generate --resume --shard {}/N`",
                missing.len(),
                missing.iter().map(|s| s.file()).take(20).collect::<Vec<_>>().join(", "),
                missing[0].job
            );
        }
        return Ok(GenerateSummary {
            samples: 0,
            shards_written: 0,
            shards_skipped: plan.shards.iter().filter(|s| opts.shard.selects(s)).count(),
            bytes: 0,
            seconds: started.elapsed().as_secs_f64(),
            adapter: "none (nothing to render)".into(),
            complete: manifest.complete,
        });
    }
    let run = shards_to_write(out, &plan, opts, &config_sha)?;
    for line in &run.redone {
        eprintln!("redoing {line}");
    }
    let (todo, skipped) = (&run.todo, run.kept);
    let total: u64 = todo.iter().map(|s| s.samples.len() as u64).sum();
    warn_if_short_of_space(out, config, total, opts.quiet);
    let progress = progress_bar(total, opts.quiet);
    let compression = config.output.shard_compression();
    let abort = AtomicBool::new(false);
    let adapter = Mutex::new(None);
    let unmade: Mutex<Vec<String>> = Mutex::new(Vec::new());
    let pooled = run_pool(
        opts.jobs,
        todo,
        &abort,
        || {
            let renderer = WgpuRenderer::new(&config.renderer)?;
            let factory = SampleFactory::new(cfg, &objects, Box::new(renderer))?;
            adapter.lock().expect("not poisoned").get_or_insert_with(|| factory.renderer_name());
            Ok(factory)
        },
        |factory, _, s| {
            let meta = ShardMeta {
                generator: GENERATOR.into(),
                seed: config.seed,
                config_sha256: config_sha.clone(),
                split: s.split.to_string(),
                shard_index: s.shard_index,
                first_sample: s.first_sample,
                sample_count: s.samples.len() as u64,
                extra: episode_metadata(config, s).into_iter().collect(),
            };
            match write_shard(factory, out, s, &meta, compression, &progress, &abort) {
                Ok(r) => Ok(r.map(|r| (s.file(), r))),
                // An object no grasp holds fails its shard, not the run: the other shards go on.
                Err(e) if e.chain().any(|c| c.is::<crate::physics::grasp::NoGraspHeld>()) => {
                    let e = shard_failed(e, out, config, s, total);
                    unmade.lock().expect("not poisoned").push(format!("{}: {e:#}", s.file()));
                    Ok(None)
                }
                Err(e) => Err(shard_failed(e, out, config, s, total)),
            }
        },
        |_| Ok(()),
    );
    let receipts: Vec<(String, ShardReceipt)> = pooled.results.into_iter().map(|(_, r)| r).collect();
    let first_error = pooled.error;
    progress.finish_and_clear();
    let adapter = adapter.into_inner().expect("not poisoned").unwrap_or_else(|| "none (nothing to render)".into());
    // The manifest is rewritten even after an error, so finished shards are recorded.
    let manifest = update_manifest(out, config, &config_sha, &plan, &receipts);
    // The run's own error first: on a full disk the manifest may not be writable either (a
    // resume rebuilds it from the complete shards).
    if let Some(e) = first_error {
        return Err(e);
    }
    let manifest = manifest?;
    let unmade = unmade.into_inner().expect("not poisoned");
    if !unmade.is_empty() {
        bail!(
            "{} shard(s) could not be made; the other {} of this run are complete and kept:\n  {}",
            unmade.len(),
            receipts.len(),
            unmade.join("\n  ")
        );
    }
    Ok(GenerateSummary {
        samples: total,
        shards_written: receipts.len(),
        shards_skipped: skipped,
        bytes: receipts.iter().map(|r| r.1.bytes).sum(),
        seconds: started.elapsed().as_secs_f64(),
        adapter,
        complete: manifest.complete,
    })
}

/// The objects the config's robot can never hold, each with why and what to do (a parallel-jaw
/// gripper whose jaws are narrower than the object in every direction).
pub fn unholdable_objects(cfg: &LoadedConfig, objects: &[LoadedObject]) -> Vec<String> {
    let (Some(robot), Some(rc)) = (&cfg.robot, &cfg.config.robot) else { return Vec::new() };
    if robot.kind != vt_robot::GraspKind::ParallelJaw {
        return Vec::new();
    }
    objects
        .iter()
        .filter_map(|o| crate::physics::antipodal::cannot_fit_between_jaws(robot, &rc.grasp.preshape, &o.id, &o.mesh.positions))
        .collect()
}

/// An episode shard's `vtgen.shard` entry (FORMAT.md, "Episodes"): the episode's object and
/// trajectory, its streams' rates and its length. None for snapshot shards.
fn episode_metadata(config: &crate::config::Config, shard: &crate::plan::ShardPlan) -> Option<(String, String)> {
    let timeline = crate::plan::EpisodeTimeline::of(config)?;
    let first = shard.samples.first()?;
    let rate = |steps: u64| 1.0 / (steps as f64 * timeline.timestep);
    let p = timeline.periods;
    let record = vt_dataset::EpisodeRecord {
        object_id: config.objects[first.object_index as usize].id().to_string(),
        trajectory: first.trajectory,
        frames: timeline.frames,
        duration_s: timeline.steps as f64 * timeline.timestep,
        physics_hz: rate(1),
        camera_hz: rate(p.camera),
        tactile_hz: rate(p.tactile),
        state_hz: rate(p.state),
        camera_period_steps: p.camera,
        tactile_period_steps: p.tactile,
        state_period_steps: p.state,
        settled_s: timeline.settled_s(),
    };
    Some((vt_dataset::EPISODE_METADATA_KEY.to_string(), record.to_json()))
}

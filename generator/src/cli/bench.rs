//! `vtgen bench`: samples/s of the full sample path, run as `generate` runs it (workers with their
//! own renderer and physics, the writer on its own thread), and where the time goes: physics,
//! main render, readback, tactile views, tactile extraction, optical tactile images, occlusion,
//! encode + compress + write.
//! It reports the adapter and the process's peak RSS. Samples are whole trajectories taken from
//! the objects in turn (trajectory 0 of every object, then trajectory 1, …) so that physics is
//! amortised as in a real run and every object is measured. Nothing is written to the dataset.

use std::collections::BTreeMap;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use anyhow::{Result, bail};
use serde::Serialize;
use vt_dataset::{OcclusionBin, ShardMeta};

use crate::assets::load_objects;
use crate::config::LoadedConfig;
use crate::output::workers::run_pool;
use crate::output::writer_thread::{WriterThread, WriterTimes};
use crate::plan::{Plan, SampleRef, Split};
use crate::render::{PassTimes, WgpuRenderer};
use crate::sample::{SampleFactory, ShardTally, StageTimes};

#[derive(Debug, Clone, Serialize)]
pub struct BenchReport {
    pub samples: u64,
    pub jobs: usize,
    pub adapter: String,
    pub seconds: f64,
    pub samples_per_second: f64,
    /// Seconds per stage, summed over the samples (and workers). Readback is part of the two
    /// render times; encode + write runs on the writer threads, overlapped with the rest.
    pub physics: f64,
    pub main_render: f64,
    pub readback: f64,
    pub tactile_render: f64,
    pub tactile_extraction: f64,
    /// The optical tactile images (`robot.tactile.optical`): how many, their wall and CPU seconds
    /// (image formation on the worker's CPU; their depth views are in `tactile_render`).
    pub optical_images: u64,
    pub optical: f64,
    pub optical_cpu: f64,
    /// Where the optical images were shaded (`robot.tactile.optical_shading`): `cpu`, or `gpu`, in
    /// the tactile render's submission (its time is then in `tactile_render`).
    pub optical_shading: String,
    /// The pads' force fields (`robot.tactile.force_field`): how many, their wall seconds.
    pub force_fields: u64,
    pub force_field_seconds: f64,
    pub occlusion: f64,
    pub encode_and_write: f64,
    /// Shard bytes per sample (the shards' size over the samples: meshes and summaries included).
    pub bytes_per_sample: f64,
    /// Episodes (`sampling.record`): the camera rate, so that a sample is 1/camera_hz seconds of
    /// episode (the touch and state streams between frames ride with it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub episode_camera_hz: Option<f64>,
    /// Physics steps taken (failed attempts and redone moves included), and the grasp loop's CPU
    /// seconds per step.
    pub physics_steps: u64,
    pub physics_seconds_per_step: f64,
    /// CPU seconds, summed over threads (`cpu_clock`): the workers' grasp loop, the workers'
    /// time inside the renderer's calls, the rest of the workers' sample path (scene, textures,
    /// touch, occlusion, assembly), and the writer threads (encode, zstd, write).
    pub physics_cpu: f64,
    pub render_call_cpu: f64,
    pub other_cpu: f64,
    pub writer_cpu: f64,
    /// CPU seconds outside the rasterizer: physics + the rest of the sample path + readback
    /// handling + the writers. What a machine whose GPU rasterizes must still do on its cores.
    pub cpu_outside_rasterizer: f64,
    /// The process's CPU seconds (all threads, lavapipe's included) over the run.
    pub process_cpu: f64,
    /// Cores busy on average: the process's CPU seconds over the run's wall seconds. Below the
    /// jobs, workers waited (for the GPU, or idle at the end while the last trajectories ran).
    pub cores_busy: f64,
    /// `--predict-cores N`: N and the samples/s N cores would give with a free rasterizer.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub predicted: Option<(usize, f64)>,
    /// The same prediction if the workers' calls into the renderer (command encoding, uploads,
    /// submission: `render_call_cpu`) cost a GPU machine's cores what they cost here: a lower
    /// bound beside `predicted`'s upper one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub predicted_with_render_calls: Option<f64>,
    /// Tactile views' time relative to the main render (the 12 views are batched in one pass).
    pub tactile_over_main_render: f64,
    /// Largest resident set of the process (VmHWM), MiB.
    pub peak_rss_mib: f64,
    /// Trajectories left out because no grasp held (the grasp loop's failures), with the reason.
    pub skipped_trajectories: Vec<String>,
    /// Samples per object and occlusion bin (`OcclusionBin` order), to tune the camera and the grasp
    /// knobs towards the occlusion the experiment needs without writing a dataset.
    pub occlusion_bins: BTreeMap<String, [u64; 3]>,
    /// With a robot: grasp attempts per kept trajectory, per object (a trajectory the grasp loop
    /// gave up on counts its `robot.grasp.max_attempts`): every failed attempt is physics thrown
    /// away. Objects without a kept trajectory are left out.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub attempts_per_kept: BTreeMap<String, f64>,
    /// `--per-pass`: seconds per render pass by the pass's name, summed over the samples and
    /// workers, each pass timed on its own (submitted and waited for); passes that never ran are
    /// left out.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub render_passes: Option<BTreeMap<String, f64>>,
}

impl std::fmt::Display for BenchReport {
    /// The report as `vtgen bench` prints it: samples/s, milliseconds per sample and stage, peak
    /// RSS, and the share of samples per occlusion bin and object.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let r = self;
        writeln!(f, "adapter            {}", r.adapter)?;
        writeln!(
            f,
            "samples            {} in {:.2} s with {} job(s): {:.1} samples/s",
            r.samples, r.seconds, r.jobs, r.samples_per_second
        )?;
        let per = |x: f64| 1e3 * x / r.samples as f64;
        writeln!(f, "per sample (summed over jobs):")?;
        writeln!(f, "  physics          {:7.2} ms", per(r.physics))?;
        writeln!(f, "  main render      {:7.2} ms  (readback {:.2} ms of it and the tactile views)", per(r.main_render), per(r.readback))?;
        writeln!(
            f,
            "  tactile render   {:7.2} ms  ({:.0}% of the main render)",
            per(r.tactile_render),
            100.0 * r.tactile_over_main_render
        )?;
        writeln!(f, "  tactile points   {:7.2} ms", per(r.tactile_extraction))?;
        if r.optical_images > 0 {
            let each = r.optical_cpu / r.optical_images as f64;
            writeln!(
                f,
                "  optical images   {:7.2} ms  ({:.1} per sample; CPU {:.2} ms each: {:.0} images/s per core; {})",
                per(r.optical),
                r.optical_images as f64 / r.samples as f64,
                1e3 * each,
                1.0 / each.max(1e-12),
                if r.optical_shading == "gpu" {
                    "shaded on the GPU in the tactile render, markers and noise on the CPU"
                } else {
                    "shaded on the CPU"
                }
            )?;
        }
        if r.force_fields > 0 {
            writeln!(
                f,
                "  force fields     {:7.2} ms  ({:.1} per sample: {:.1} µs each)",
                per(r.force_field_seconds),
                r.force_fields as f64 / r.samples as f64,
                1e6 * r.force_field_seconds / r.force_fields as f64
            )?;
        }
        writeln!(f, "  occlusion        {:7.2} ms", per(r.occlusion))?;
        writeln!(f, "  encode + write   {:7.2} ms  (writer thread, overlapped)", per(r.encode_and_write))?;
        writeln!(
            f,
            "physics steps      {:.0} per sample, {:.1} µs of CPU each",
            r.physics_steps as f64 / r.samples as f64,
            1e6 * r.physics_seconds_per_step
        )?;
        writeln!(
            f,
            "CPU outside the rasterizer {:5.2} ms per sample  (physics {:.2}, scene/touch/occlusion/readback {:.2}, encode + write {:.2})",
            per(r.cpu_outside_rasterizer),
            per(r.physics_cpu),
            per(r.other_cpu + r.readback),
            per(r.writer_cpu)
        )?;
        writeln!(
            f,
            "CPU in all        {:6.2} ms per sample  (the rasterizer and the rest: {:.2} ms)",
            per(r.process_cpu),
            per(r.process_cpu - r.cpu_outside_rasterizer)
        )?;
        writeln!(
            f,
            "cores busy         {:.1} on average (CPU in all / wall){}",
            r.cores_busy,
            if r.jobs > 1 && r.cores_busy < 0.8 * r.jobs as f64 {
                ": fewer than the jobs: workers waited, for the device or at the end, where the last trajectories run alone (more samples shorten that)"
            } else {
                ""
            }
        )?;
        if let Some((cores, rate)) = r.predicted {
            writeln!(
                f,
                "predicted          {rate:.0} samples/s on {cores} cores like these with a free rasterizer (a GPU): {cores} / the CPU outside the rasterizer"
            )?;
        }
        if let Some(rate) = r.predicted_with_render_calls {
            writeln!(
                f,
                "                   {rate:.0} samples/s if the renderer's calls ({:.2} ms per sample) cost the GPU machine's cores as much as here",
                per(r.render_call_cpu)
            )?;
        }
        writeln!(f, "shard bytes        {:.2} MB per sample", r.bytes_per_sample / 1e6)?;
        if let Some(hz) = r.episode_camera_hz {
            writeln!(
                f,
                "episodes           a sample is a {hz:.0} Hz camera frame with its touch and states: {:.3} s of episode per second of run, {:.1} MB per second of episode, {:.0} ms of CPU per frame",
                r.samples_per_second / hz,
                r.bytes_per_sample * hz / 1e6,
                1e3 * r.process_cpu / r.samples as f64
            )?;
        }
        writeln!(f, "peak RSS           {:.0} MiB", r.peak_rss_mib)?;
        let bins = OcclusionBin::ALL.map(OcclusionBin::key);
        writeln!(f, "occlusion          {:>8} {:>8} {:>8}  (share of samples per bin)", bins[0], bins[1], bins[2])?;
        let share = |b: &[u64; 3]| {
            let n = b.iter().sum::<u64>().max(1) as f64;
            format!("{:>7.1}% {:>7.1}% {:>7.1}%", 100.0 * b[0] as f64 / n, 100.0 * b[1] as f64 / n, 100.0 * b[2] as f64 / n)
        };
        let mut all = [0u64; 3];
        for (id, b) in &r.occlusion_bins {
            writeln!(f, "  {id:<24}{}", share(b))?;
            all.iter_mut().zip(b).for_each(|(a, x)| *a += x);
        }
        writeln!(f, "  {:<24}{}", "all", share(&all))?;
        if let Some(passes) = &r.render_passes {
            let total: f64 = passes.values().sum();
            writeln!(f, "render passes      timed one by one (--per-pass), ms per sample and share of their sum:")?;
            let mut by_time: Vec<_> = passes.iter().collect();
            by_time.sort_by(|a, b| b.1.total_cmp(a.1));
            for (name, seconds) in by_time {
                writeln!(f, "  {name:<24}{:>8.2} ms {:>6.1}%", per(*seconds), 100.0 * seconds / total.max(1e-12))?;
            }
        }
        if !r.attempts_per_kept.is_empty() {
            writeln!(f, "grasp attempts per kept trajectory")?;
            for (id, a) in &r.attempts_per_kept {
                writeln!(f, "  {id:<24}{a:>8.1}")?;
            }
        }
        for s in &r.skipped_trajectories {
            writeln!(f, "skipped            {s}")?;
        }
        Ok(())
    }
}

/// The process's peak resident set size (Linux `VmHWM`), MiB.
pub fn peak_rss_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| s.lines().find(|l| l.starts_with("VmHWM:")).and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok()))
        .map_or(0.0, |kib| kib / 1024.0)
}

type Work = Vec<(Split, u64, SampleRef)>;

/// Whole trajectories, objects in turn, until `samples` samples (the last one cut short).
fn select(plan: &Plan, samples: u64) -> Vec<Work> {
    let mut by_traj: BTreeMap<(u32, u32), Work> = BTreeMap::new();
    for s in &plan.shards {
        for (k, r) in s.samples.iter().enumerate() {
            by_traj.entry((r.trajectory, r.object_index)).or_default().push((s.split, s.first_sample + k as u64, *r));
        }
    }
    let mut out = Vec::new();
    let mut left = samples as usize;
    for (_, mut w) in by_traj {
        if left == 0 {
            break;
        }
        w.sort_by_key(|x| x.2.instance);
        w.truncate(left);
        left -= w.len();
        out.push(w);
    }
    out
}

/// What one benchmarked trajectory gave.
struct TrajectoryRun {
    object_id: String,
    samples: u64,
    /// Why the trajectory was left out (the grasp loop gave up), if it was.
    skipped: Option<String>,
    occlusion: [u64; 3],
    /// Bytes of its shard.
    bytes: u64,
    /// The grasp attempts it took (a robot's trajectory that was kept).
    attempts: Option<u32>,
}

/// Makes and writes the samples of one trajectory (one shard, as `generate` writes shards of whole
/// trajectories), adding the writer's time to `write`.
fn bench_trajectory(
    cfg: &LoadedConfig,
    factory: &mut SampleFactory,
    write: &mut WriterTimes,
    dir: &std::path::Path,
    i: usize,
    traj: &Work,
) -> Result<TrajectoryRun> {
    let meta = ShardMeta {
        generator: crate::output::generate::GENERATOR.into(),
        seed: cfg.config.seed,
        config_sha256: String::new(),
        split: "bench".into(),
        shard_index: i as u32,
        first_sample: 0,
        sample_count: traj.len() as u64,
        extra: Default::default(),
    };
    let object_index = traj[0].2.object_index;
    let mut run = TrajectoryRun {
        object_id: cfg.config.objects[object_index as usize].id().to_string(),
        samples: 0,
        skipped: None,
        occlusion: [0; 3],
        bytes: 0,
        attempts: None,
    };
    let mut writer = WriterThread::create(&dir.join(format!("bench-{i}.mcap")), &meta, cfg.config.output.shard_compression())?;
    writer.set_scene(factory.scene_models(object_index))?;
    let mut tally = ShardTally::default();
    for (k, (split, index, r)) in traj.iter().enumerate() {
        match factory.make(*split, *index, r, &mut tally) {
            Ok(s) => {
                if k == 0 {
                    run.attempts = s.info.robot.as_ref().map(|r| r.grasp_attempts);
                }
                writer.write_sample(s)?
            }
            // The grasp loop gave up on this trajectory (its first sample simulates it): measure
            // the others.
            Err(e) if k == 0 && factory.has_robot() => {
                run.skipped = Some(format!("{e:#}"));
                return Ok(run);
            }
            Err(e) => return Err(e),
        }
        run.samples += 1;
    }
    let (receipt, times) = writer.finish()?;
    run.bytes = receipt.bytes;
    write.busy += times.busy;
    write.cpu += times.cpu;
    run.occlusion = tally.occlusion;
    Ok(run)
}

/// What `vtgen bench` runs and what it reports besides the stages.
#[derive(Debug, Clone)]
pub struct BenchOptions {
    /// Samples (whole trajectories, objects in turn) and parallel workers.
    pub samples: u64,
    pub jobs: usize,
    pub ycb_dir: Option<std::path::PathBuf>,
    /// Also predict the samples/s of that many cores with a free rasterizer.
    pub predict_cores: Option<usize>,
    /// Time every render pass on its own (slower: no overlap of recording and drawing).
    pub per_pass: bool,
}

/// Runs the benchmark.
pub fn bench(cfg: &LoadedConfig, options: &BenchOptions) -> Result<BenchReport> {
    let BenchOptions { samples, jobs, ref ycb_dir, predict_cores, per_pass } = *options;
    let ycb_dir = ycb_dir.as_ref();
    let plan = Plan::new(&cfg.config);
    let work = select(&plan, samples);
    if work.is_empty() {
        bail!("the config has no samples");
    }
    let objects = load_objects(cfg, ycb_dir)?;
    let dir = std::env::temp_dir().join(format!("vtgen-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let jobs = jobs.max(1).min(work.len());
    let abort = AtomicBool::new(false);
    let started = Instant::now();
    let cpu_started = crate::cpu_clock::process_cpu_time();
    let pooled = run_pool(
        jobs,
        &work,
        &abort,
        || {
            let renderer = WgpuRenderer::new(&cfg.config.renderer)?;
            let mut factory = SampleFactory::new(cfg, &objects, Box::new(renderer))?;
            if per_pass {
                factory.time_render_passes();
            }
            Ok((factory, WriterTimes::default()))
        },
        |(factory, write), i, traj| bench_trajectory(cfg, factory, write, &dir, i, traj).map(Some),
        |(factory, write)| {
            let done = Worker { times: factory.times, write, readback: factory.readback_time(), adapter: factory.renderer_name() };
            Ok((done, factory.render_pass_times()))
        },
    );
    let seconds = started.elapsed().as_secs_f64();
    let process_cpu = match (cpu_started, crate::cpu_clock::process_cpu_time()) {
        (Some(a), Some(b)) => (b - a).as_secs_f64(),
        _ => 0.0,
    };
    let _ = std::fs::remove_dir_all(&dir);
    let (done, workers) = pooled.into_result()?;
    let runs: Vec<TrajectoryRun> = done.into_iter().map(|(_, t)| t).collect();
    let episode_camera_hz = crate::plan::EpisodeTimeline::of(&cfg.config).map(|t| 1.0 / (t.periods.camera as f64 * t.timestep));
    let optical_shading = match cfg.config.robot.as_ref().map(|r| r.tactile.optical_shading) {
        Some(crate::config::OpticalShading::Gpu) => "gpu",
        _ => "cpu",
    };
    let optical_shading = optical_shading.to_string();
    let max_attempts = cfg.config.robot.as_ref().map_or(0, |r| r.grasp.max_attempts);
    report(runs, workers, Measured { jobs, seconds, process_cpu, predict_cores, episode_camera_hz, optical_shading, max_attempts })
}

/// What one worker measured: its stage times, its writers', its renderer's readback, and the
/// adapter it drew with.
struct Worker {
    times: StageTimes,
    write: WriterTimes,
    readback: Duration,
    adapter: String,
}

/// What `bench` measured around the workers.
struct Measured {
    jobs: usize,
    seconds: f64,
    process_cpu: f64,
    predict_cores: Option<usize>,
    episode_camera_hz: Option<f64>,
    optical_shading: String,
    /// `robot.grasp.max_attempts` (0 without a robot).
    max_attempts: u32,
}

/// The report of the benchmark's trajectories and of its workers' stage times.
fn report(runs: Vec<TrajectoryRun>, workers: Vec<(Worker, Option<PassTimes>)>, m: Measured) -> Result<BenchReport> {
    let Measured { jobs, seconds, process_cpu, predict_cores, episode_camera_hz, optical_shading, max_attempts } = m;
    // Per object: attempts spent (kept trajectories' own, given-up ones' all) and trajectories kept.
    let mut attempts: BTreeMap<String, (u64, u64)> = BTreeMap::new();
    for t in &runs {
        let a = attempts.entry(t.object_id.clone()).or_default();
        match (t.attempts, &t.skipped) {
            (Some(n), None) => *a = (a.0 + n as u64, a.1 + 1),
            (_, Some(_)) => a.0 += max_attempts as u64,
            (None, None) => {}
        }
    }
    let attempts_per_kept =
        attempts.into_iter().filter(|(_, (_, kept))| *kept > 0).map(|(id, (n, kept))| (id, n as f64 / kept as f64)).collect();
    let mut n = 0;
    let mut skipped = Vec::new();
    let mut occlusion_bins: BTreeMap<String, [u64; 3]> = BTreeMap::new();
    let mut bytes = 0;
    for t in runs {
        n += t.samples;
        bytes += t.bytes;
        skipped.extend(t.skipped);
        let b = occlusion_bins.entry(t.object_id).or_default();
        (0..3).for_each(|k| b[k] += t.occlusion[k]);
    }
    if n == 0 {
        bail!("no sample could be made: {}", skipped.join("; "));
    }
    let (mut t, mut write, mut readback, mut adapter) = (StageTimes::default(), WriterTimes::default(), Duration::ZERO, String::new());
    let mut passes: Option<PassTimes> = None;
    for (Worker { times, write: w, readback: r, adapter: a }, p) in workers {
        t += &times;
        write.busy += w.busy;
        write.cpu += w.cpu;
        readback += r;
        adapter = a;
        if let Some(p) = p {
            *passes.get_or_insert_default() += p;
        }
    }
    let cpu_outside = (t.physics_cpu + t.other_cpu + readback + write.cpu).as_secs_f64();
    Ok(BenchReport {
        episode_camera_hz,
        bytes_per_sample: bytes as f64 / n as f64,
        physics_steps: t.physics_steps,
        physics_seconds_per_step: t.physics_cpu.as_secs_f64() / t.physics_steps.max(1) as f64,
        physics_cpu: t.physics_cpu.as_secs_f64(),
        render_call_cpu: t.render_call_cpu.as_secs_f64(),
        other_cpu: t.other_cpu.as_secs_f64(),
        writer_cpu: write.cpu.as_secs_f64(),
        cpu_outside_rasterizer: cpu_outside,
        process_cpu,
        cores_busy: process_cpu / seconds.max(1e-9),
        predicted: predict_cores.map(|c| (c, c as f64 * n as f64 / cpu_outside.max(1e-9))),
        predicted_with_render_calls: predict_cores.map(|c| c as f64 * n as f64 / (cpu_outside + t.render_call_cpu.as_secs_f64()).max(1e-9)),
        samples: n,
        jobs,
        adapter,
        seconds,
        samples_per_second: n as f64 / seconds,
        physics: t.physics.as_secs_f64(),
        main_render: t.main_render.as_secs_f64(),
        readback: readback.as_secs_f64(),
        tactile_render: t.tactile_render.as_secs_f64(),
        tactile_extraction: t.tactile_extract.as_secs_f64(),
        optical_images: t.optical_images,
        optical: t.tactile_optical.as_secs_f64(),
        optical_cpu: t.tactile_optical_cpu.as_secs_f64(),
        optical_shading,
        force_fields: t.force_fields,
        force_field_seconds: t.tactile_forces.as_secs_f64(),
        occlusion: t.occlusion.as_secs_f64(),
        encode_and_write: write.busy.as_secs_f64(),
        tactile_over_main_render: t.tactile_render.as_secs_f64() / t.main_render.as_secs_f64().max(1e-12),
        peak_rss_mib: peak_rss_mib(),
        skipped_trajectories: skipped,
        occlusion_bins,
        attempts_per_kept,
        render_passes: passes.map(|p| p.named().into_iter().filter(|(_, s)| *s > 0.0).map(|(n, s)| (n.to_string(), s)).collect()),
    })
}

/// `vtgen bench`: the benchmark, printed as a table (or JSON).
pub fn run(cfg: &LoadedConfig, options: &BenchOptions, json: bool) -> Result<()> {
    let r = bench(cfg, options)?;
    if json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        print!("{r}");
    }
    Ok(())
}

//! `vtgen bench`: samples/s of the full sample path, run as `generate` runs it (workers with their
//! own renderer and physics, the writer on its own thread), and where the time goes: physics,
//! main render, readback, tactile views, tactile extraction, occlusion, encode + compress + write.
//! It reports the adapter and the process's peak RSS. Samples are whole trajectories taken from
//! the objects in turn (trajectory 0 of every object, then trajectory 1, …) so that physics is
//! amortised as in a real run and every object is measured. Nothing is written to the dataset.

use std::collections::BTreeMap;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Result, bail};
use serde::Serialize;
use vt_dataset::ShardMeta;

use crate::assets::load_objects;
use crate::config::LoadedConfig;
use crate::plan::{Plan, SampleRef};
use crate::render::WgpuRenderer;
use crate::sample::{SampleFactory, StageTimes};
use crate::writer_thread::WriterThread;

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
    pub occlusion: f64,
    pub encode_and_write: f64,
    /// Tactile views' time relative to the main render (the 12 views are batched in one pass).
    pub tactile_over_main_render: f64,
    /// Largest resident set of the process (VmHWM), MiB.
    pub peak_rss_mib: f64,
    /// Trajectories left out because no grasp held (the grasp loop's failures), with the reason.
    pub skipped_trajectories: Vec<String>,
}

/// The process's peak resident set size (Linux `VmHWM`), MiB.
pub fn peak_rss_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| s.lines().find(|l| l.starts_with("VmHWM:")).and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok()))
        .map_or(0.0, |kib| kib / 1024.0)
}

type Work = Vec<(&'static str, u64, SampleRef)>;

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

fn add(a: &mut StageTimes, b: &StageTimes) {
    a.physics += b.physics;
    a.main_render += b.main_render;
    a.tactile_render += b.tactile_render;
    a.tactile_extract += b.tactile_extract;
    a.occlusion += b.occlusion;
}

pub fn bench(cfg: &LoadedConfig, samples: u64, jobs: usize, ycb_dir: Option<&std::path::PathBuf>) -> Result<BenchReport> {
    let plan = Plan::new(&cfg.config);
    let work = select(&plan, samples);
    if work.is_empty() {
        bail!("the config has no samples");
    }
    let objects = load_objects(cfg, ycb_dir)?;
    let compression = cfg.config.output.shard_compression();
    let dir = std::env::temp_dir().join(format!("vtgen-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let jobs = jobs.max(1).min(work.len());
    let next = AtomicUsize::new(0);
    let made = AtomicUsize::new(0);
    let totals = Mutex::new((StageTimes::default(), Duration::ZERO, Duration::ZERO, String::new()));
    let skipped = Mutex::new(Vec::new());
    let started = Instant::now();
    let result: Result<()> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..jobs)
            .map(|_| {
                let (work, next, made, totals, skipped, objects, dir) = (&work, &next, &made, &totals, &skipped, &objects, &dir);
                scope.spawn(move || -> Result<()> {
                    let renderer = WgpuRenderer::new(&cfg.config.renderer)?;
                    let mut factory = SampleFactory::new(cfg, objects, Box::new(renderer))?;
                    let mut write = Duration::ZERO;
                    loop {
                        let i = next.fetch_add(1, Ordering::SeqCst);
                        let Some(traj) = work.get(i) else { break };
                        // One shard per trajectory, as `generate` writes shards of whole trajectories.
                        let meta = ShardMeta {
                            generator: crate::pipeline::GENERATOR.into(),
                            seed: cfg.config.seed,
                            config_sha256: String::new(),
                            split: "bench".into(),
                            shard_index: i as u32,
                            first_sample: 0,
                            sample_count: traj.len() as u64,
                            extra: Default::default(),
                        };
                        let mut writer = WriterThread::create(&dir.join(format!("bench-{i}.mcap")), &meta, compression)?;
                        writer.set_scene(factory.scene_models(traj[0].2.object_index))?;
                        let mut complete = true;
                        for (k, (split, index, r)) in traj.iter().enumerate() {
                            match factory.make(split, *index, r) {
                                Ok(s) => writer.write_sample(s)?,
                                // The grasp loop gave up on this trajectory (its first sample
                                // simulates it): measure the others.
                                Err(e) if k == 0 && factory.has_robot() => {
                                    skipped.lock().expect("not poisoned").push(format!("{e:#}"));
                                    complete = false;
                                    break;
                                }
                                Err(e) => return Err(e),
                            }
                            made.fetch_add(1, Ordering::SeqCst);
                        }
                        if complete {
                            write += writer.finish()?.1;
                        }
                    }
                    let mut t = totals.lock().expect("not poisoned");
                    add(&mut t.0, &factory.times);
                    t.1 += write;
                    t.2 += factory.readback_time();
                    t.3 = factory.renderer_name();
                    Ok(())
                })
            })
            .collect();
        for h in handles {
            h.join().map_err(|_| anyhow::anyhow!("a bench worker panicked"))??;
        }
        Ok(())
    });
    let seconds = started.elapsed().as_secs_f64();
    let _ = std::fs::remove_dir_all(&dir);
    result?;
    let n = made.load(Ordering::SeqCst) as u64;
    let skipped = skipped.into_inner().expect("not poisoned");
    if n == 0 {
        bail!("no sample could be made: {}", skipped.join("; "));
    }
    let (t, write, readback, adapter) = totals.into_inner().expect("not poisoned");
    Ok(BenchReport {
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
        occlusion: t.occlusion.as_secs_f64(),
        encode_and_write: write.as_secs_f64(),
        tactile_over_main_render: t.tactile_render.as_secs_f64() / t.main_render.as_secs_f64().max(1e-12),
        peak_rss_mib: peak_rss_mib(),
        skipped_trajectories: skipped,
    })
}

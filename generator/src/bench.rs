//! `vtgen bench`: samples/s of the full sample path and where the time goes, measured on the
//! config's first samples (physics, main render, tactile views, occlusion, encode + compress,
//! write), with the adapter it ran on. Nothing is written to the dataset.

use std::time::{Duration, Instant};

use anyhow::{Result, bail};
use serde::Serialize;
use vt_dataset::{Compression, ShardMeta, ShardWriter};

use crate::assets::load_objects;
use crate::config::{CompressionKind, LoadedConfig};
use crate::plan::Plan;
use crate::render::WgpuRenderer;
use crate::sample::SampleFactory;

#[derive(Debug, Clone, Serialize)]
pub struct BenchReport {
    pub samples: u64,
    pub adapter: String,
    pub seconds: f64,
    pub samples_per_second: f64,
    /// Seconds per stage, summed over the samples.
    pub physics: f64,
    pub main_render: f64,
    pub tactile_render: f64,
    pub occlusion: f64,
    pub encode_and_write: f64,
    /// Tactile views' time relative to the main render (the 12 views are batched in one pass).
    pub tactile_over_main_render: f64,
}

pub fn bench(cfg: &LoadedConfig, samples: u64, ycb_dir: Option<&std::path::PathBuf>) -> Result<BenchReport> {
    let plan = Plan::new(&cfg.config);
    let refs: Vec<_> = plan
        .shards
        .iter()
        .flat_map(|s| s.samples.iter().enumerate().map(move |(k, r)| (s.split, s.first_sample + k as u64, *r)))
        .take(samples as usize)
        .collect();
    if refs.is_empty() {
        bail!("the config has no samples");
    }
    let objects = load_objects(cfg, ycb_dir)?;
    let renderer = WgpuRenderer::new(&cfg.config.renderer)?;
    let mut factory = SampleFactory::new(cfg, &objects, Box::new(renderer))?;
    let adapter = factory.renderer_name();
    let dir = tempfile_dir()?;
    let compression = match cfg.config.output.compression {
        CompressionKind::Zstd => Compression::Zstd { level: cfg.config.output.zstd_level as u32 },
        CompressionKind::None => Compression::None,
    };
    let meta = ShardMeta {
        generator: crate::pipeline::GENERATOR.into(),
        seed: cfg.config.seed,
        config_sha256: String::new(),
        split: "bench".into(),
        shard_index: 0,
        first_sample: 0,
        sample_count: refs.len() as u64,
        extra: Default::default(),
    };
    let mut writer = ShardWriter::create(&dir.join("bench.mcap"), &meta, compression)?;
    let mut write = Duration::ZERO;
    let started = Instant::now();
    for (split, index, r) in &refs {
        let s = factory.make(split, *index, r)?;
        let t0 = Instant::now();
        writer.write_sample(&s)?;
        write += t0.elapsed();
    }
    let t0 = Instant::now();
    writer.finish()?;
    write += t0.elapsed();
    let seconds = started.elapsed().as_secs_f64();
    let _ = std::fs::remove_dir_all(&dir);
    let t = factory.times;
    Ok(BenchReport {
        samples: refs.len() as u64,
        adapter,
        seconds,
        samples_per_second: refs.len() as f64 / seconds,
        physics: t.physics.as_secs_f64(),
        main_render: t.main_render.as_secs_f64(),
        tactile_render: t.tactile.as_secs_f64(),
        occlusion: t.occlusion.as_secs_f64(),
        encode_and_write: write.as_secs_f64(),
        tactile_over_main_render: t.tactile.as_secs_f64() / t.main_render.as_secs_f64().max(1e-12),
    })
}

fn tempfile_dir() -> Result<std::path::PathBuf> {
    let d = std::env::temp_dir().join(format!("vtgen-bench-{}", std::process::id()));
    std::fs::create_dir_all(&d)?;
    Ok(d)
}

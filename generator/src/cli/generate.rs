//! `vtgen generate`: the dataset, and what the run did.

use anyhow::Result;

use crate::config::LoadedConfig;
use crate::output::generate::{GenerateOptions, generate};

/// Generates the dataset and says what the run did (unless `opts.quiet`).
pub fn run(cfg: &LoadedConfig, opts: &GenerateOptions) -> Result<()> {
    let s = generate(cfg, opts)?;
    if !opts.quiet {
        eprintln!("renderer: {}", s.adapter);
        eprintln!(
            "generated {} samples in {} shard(s) ({} skipped as complete), {} in {:.1} s: {:.1} samples/s",
            s.samples,
            s.shards_written,
            s.shards_skipped,
            super::human_bytes(s.bytes as f64),
            s.seconds,
            s.samples as f64 / s.seconds.max(1e-9)
        );
        eprintln!("dataset {}: {}", opts.out.display(), if s.complete { "complete" } else { "incomplete (other shards pending)" });
    }
    Ok(())
}

//! The subcommands that plan, read, check, measure or convert rather than generate: one file each.
//! `generate` itself is the output stage (`crate::output::generate`); `main.rs` parses the
//! command line and prints what these return.

pub mod bench;
pub mod dump;
pub mod export;
pub mod grasps;
pub mod inspect;
pub mod plan;
pub mod preview;
pub mod robot_check;
pub mod stats;
pub mod validate;

use anyhow::Result;
use vt_dataset::{DatasetReader, SampleInfo};

/// Calls `f(split, sample info)` for every sample of the dataset, split by split and shard by
/// shard, reading only the info messages (no image is decoded).
pub(crate) fn for_each_info(ds: &DatasetReader, mut f: impl FnMut(&str, &SampleInfo) -> Result<()>) -> Result<()> {
    let splits: Vec<String> = ds.manifest().splits.keys().cloned().collect();
    for split in &splits {
        for shard in ds.shards(split)? {
            for index in shard.indices().collect::<Vec<_>>() {
                f(split, &shard.read_sample_info(index)?)?;
            }
        }
    }
    Ok(())
}

pub use crate::output::human_bytes;

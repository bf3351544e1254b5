//! The subcommands, one file each: each owns its `run` (what the command does and prints);
//! `main.rs` only parses the command line and dispatches. `generate` is the output stage
//! (`crate::output::generate`); `generate.rs` here reports on it.

pub mod bench;
pub mod dump;
pub mod export;
pub mod generate;
pub mod grasps;
pub mod inspect;
pub mod plan;
pub mod preview;
pub mod robot_check;
pub mod robot_picture;
pub mod robot_suggest;
pub mod stats;
pub mod tactile;
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

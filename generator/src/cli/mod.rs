//! The subcommands that read, check, measure or convert rather than generate: one file each.
//! `generate` itself is the output stage (`crate::output::generate`); `main.rs` parses the
//! command line and prints what these return.

pub mod bench;
pub mod dump;
pub mod export;
pub mod grasps;
pub mod inspect;
pub mod preview;
pub mod stats;
pub mod validate;

use std::path::Path;

use anyhow::Result;
use vt_dataset::DatasetReader;

/// Calls `f(split, shard path, sample index, /sample/info)` for every sample of the dataset, split
/// by split and shard by shard, reading only the info messages (no image is decoded).
pub(crate) fn for_each_info(ds: &DatasetReader, mut f: impl FnMut(&str, &Path, u64, &serde_json::Value) -> Result<()>) -> Result<()> {
    let splits: Vec<String> = ds.manifest().splits.keys().cloned().collect();
    for split in &splits {
        for shard in ds.shards(split)? {
            for index in shard.indices().collect::<Vec<_>>() {
                f(split, shard.path(), index, &shard.read_info(index)?)?;
            }
        }
    }
    Ok(())
}

//! The last stage: the shard loop of `vtgen generate` (shards of whole trajectories, workers with
//! their own renderer and physics, resume, manifest) and the writer thread that encodes and
//! compresses samples while the workers render the next ones; `workers` is the thread pool that
//! `generate`, `bench` and `grasps` share.

pub mod generate;
pub mod workers;
pub mod writer_thread;

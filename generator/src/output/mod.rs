//! The last stage: the shard loop of `vtgen generate` (shards of whole trajectories, workers with
//! their own renderer and physics, resume, manifest) and the writer thread that encodes and
//! compresses samples while the workers render the next ones; `workers` is the thread pool that
//! `generate`, `bench` and `grasps` share.

pub mod generate;
pub mod workers;
pub mod writer_thread;

/// `1234567.0` -> `"1.2 MB"` (powers of 1000).
pub fn human_bytes(b: f64) -> String {
    let units = ["B", "KB", "MB", "GB", "TB"];
    let mut v = b;
    let mut u = 0;
    while v >= 1000.0 && u < units.len() - 1 {
        v /= 1000.0;
        u += 1;
    }
    format!("{v:.1} {}", units[u])
}

//! The dataset plan: which samples exist, their split, their order and their shard (FORMAT.md,
//! "Samples, splits and shards"). Pure arithmetic on the config.

pub use vt_dataset::Split;

use crate::config::Config;

/// The splits in the order the plan lists their shards.
pub const SPLITS: [Split; 2] = Split::ALL;

/// One sample's coordinates. In an episode dataset a sample is a camera frame, and `instance` is
/// the frame's index in its episode (its trajectory).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SampleRef {
    pub object_index: u32,
    pub trajectory: u32,
    pub instance: u32,
}

/// An episode's timeline: physics steps per stream period and in all, and its camera frames.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EpisodeTimeline {
    pub periods: crate::config::StreamPeriods,
    /// Physics steps recorded before the settled grasp (`sampling.record.grasp`; 0 without): a
    /// whole number of camera periods, so that the settled grasp is a frame.
    pub grasp_steps: u64,
    /// Physics steps from the episode's start to the end of the last arm move.
    pub steps: u64,
    /// Camera frames: one at step 0, then every `periods.camera` steps.
    pub frames: u64,
    pub timestep: f64,
}

impl EpisodeTimeline {
    /// The episode timeline of a config with `sampling.record` (None without).
    pub fn of(config: &Config) -> Option<Self> {
        let (record, robot) = (config.sampling.record.as_ref()?, config.robot.as_ref()?);
        let timestep = robot.physics.timestep;
        let periods = record.periods(timestep);
        let per_move = robot.grasp.move_steps(timestep) + record.in_hand_steps(timestep);
        let grasp_steps = record.grasp_steps(&robot.grasp, timestep);
        let steps = grasp_steps + config.sampling.instances_per_trajectory as u64 * per_move as u64;
        Some(EpisodeTimeline { periods, grasp_steps, steps, frames: steps / periods.camera + 1, timestep })
    }

    /// The settled grasp's time (s) when the grasp is recorded (`sampling.record.grasp`).
    pub fn settled_s(&self) -> Option<f64> {
        (self.grasp_steps > 0).then_some(self.grasp_steps as f64 * self.timestep)
    }

    /// Simulated time (ns) of physics step `step` from the episode's start (the settled grasp, or
    /// the object put in the open hand when the grasp is recorded).
    pub fn time_ns(&self, step: u64) -> u64 {
        (step as f64 * self.timestep * 1e9).round() as u64
    }
}

/// One shard to write.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ShardPlan {
    /// Position in the dataset's shard list (train shards, then test shards).
    pub job: usize,
    pub split: Split,
    pub shard_index: u32,
    pub first_sample: u64,
    pub samples: Vec<SampleRef>,
}

impl ShardPlan {
    pub fn file(&self) -> String {
        vt_dataset::shard_file(self.split.as_str(), self.shard_index)
    }
}

#[derive(Debug, Clone)]
pub struct Plan {
    pub shards: Vec<ShardPlan>,
    pub samples_per_split: [u64; 2],
    pub samples_per_shard: u64,
}

/// Uncompressed bytes of one sample: RGB, float depth and mask, plus ~2 KiB of metadata.
pub fn raw_bytes_per_sample(config: &Config) -> f64 {
    config.camera.width as f64 * config.camera.height as f64 * (3.0 + 4.0 + 1.0) + 2048.0
}

/// Bytes one sample takes on disk, low and high estimates: zstd keeps 10–40 % of the raw bytes
/// (measured: ~14 % on canonical scenes, more with randomized textures).
pub fn bytes_per_sample(config: &Config) -> (f64, f64) {
    let raw = raw_bytes_per_sample(config);
    match config.output.compression {
        crate::config::CompressionKind::Zstd => (0.1 * raw, 0.4 * raw),
        crate::config::CompressionKind::None => (raw, raw),
    }
}

/// Is trajectory `t` in the test split? Every `train + test` trajectories, the last `test` are.
pub fn is_test(config: &Config, trajectory: u32) -> bool {
    let s = config.sampling.split;
    trajectory % (s.train + s.test) >= s.train
}

impl Plan {
    pub fn new(config: &Config) -> Self {
        let s = &config.sampling;
        let per_shard = config.output.samples_per_shard as u64;
        let mut shards = Vec::new();
        let mut samples_per_split = [0u64; 2];
        for (si, split) in SPLITS.into_iter().enumerate() {
            let mut all = Vec::new();
            for o in 0..config.objects.len() as u32 {
                for t in (0..s.trajectories_per_object).filter(|&t| is_test(config, t) == (split == Split::Test)) {
                    all.extend((0..s.instances_per_trajectory).map(|i| SampleRef { object_index: o, trajectory: t, instance: i }));
                }
            }
            samples_per_split[si] = all.len() as u64;
            // Episodes: one shard per trajectory, its camera frames as samples.
            if let Some(timeline) = EpisodeTimeline::of(config) {
                let episodes: Vec<(u32, u32)> = all.iter().filter(|r| r.instance == 0).map(|r| (r.object_index, r.trajectory)).collect();
                samples_per_split[si] = episodes.len() as u64 * timeline.frames;
                for (k, &(object_index, trajectory)) in episodes.iter().enumerate() {
                    shards.push(ShardPlan {
                        job: shards.len(),
                        split,
                        shard_index: k as u32,
                        first_sample: k as u64 * timeline.frames,
                        samples: (0..timeline.frames as u32).map(|f| SampleRef { object_index, trajectory, instance: f }).collect(),
                    });
                }
                continue;
            }
            for (k, chunk) in all.chunks(per_shard as usize).enumerate() {
                shards.push(ShardPlan {
                    job: shards.len(),
                    split,
                    shard_index: k as u32,
                    first_sample: k as u64 * per_shard,
                    samples: chunk.to_vec(),
                });
            }
        }
        let samples_per_shard = EpisodeTimeline::of(config).map_or(per_shard, |t| t.frames);
        Plan { shards, samples_per_split, samples_per_shard }
    }

    pub fn total_samples(&self) -> u64 {
        self.samples_per_split.iter().sum()
    }
}

/// `--shard i/N`: which of the dataset's shards job `i` of `N` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ShardSelector {
    pub index: usize,
    pub count: usize,
}

impl ShardSelector {
    pub const ALL: ShardSelector = ShardSelector { index: 0, count: 1 };

    pub fn selects(&self, shard: &ShardPlan) -> bool {
        shard.job % self.count == self.index
    }
}

impl std::str::FromStr for ShardSelector {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let err = || format!("'{s}' is not a shard selector: expected i/N with 0 <= i < N, e.g. 0/4");
        let (i, n) = s.split_once('/').ok_or_else(err)?;
        let (index, count): (usize, usize) = (i.trim().parse().map_err(|_| err())?, n.trim().parse().map_err(|_| err())?);
        if count == 0 || index >= count {
            return Err(err());
        }
        Ok(ShardSelector { index, count })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_papers_config_plans_its_samples_and_a_set_its_tiny_split() {
        let paper = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/paper.yaml"));
        let full = crate::config::LoadedConfig::load(paper).unwrap().config;
        assert_eq!(Plan::new(&full).total_samples(), 220_000);
        let set: Vec<crate::config::Override> =
            ["sampling.trajectories_per_object=2", "sampling.instances_per_trajectory=5"].iter().map(|s| s.parse().unwrap()).collect();
        let small = crate::config::LoadedConfig::load_with(paper, &set).unwrap().config;
        assert_eq!(Plan::new(&small).total_samples(), 11 * 2 * 5);
    }

    fn config(trajectories: u32, instances: u32, per_shard: u32) -> Config {
        let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/tiny.yaml")).unwrap();
        let mut c = crate::config::LoadedConfig::parse(&text, std::path::Path::new("tiny.yaml")).unwrap().config;
        c.sampling.trajectories_per_object = trajectories;
        c.sampling.instances_per_trajectory = instances;
        c.output.samples_per_shard = per_shard;
        c
    }

    #[test]
    fn every_sample_once_split_by_trajectory_and_shards_in_order() {
        let c = config(10, 7, 5);
        let plan = Plan::new(&c);
        let n_objects = c.objects.len() as u64;
        assert_eq!(plan.total_samples(), n_objects * 10 * 7);
        // 4:1 by trajectory: trajectories 4 and 9 of every object are test.
        assert_eq!(plan.samples_per_split, [n_objects * 8 * 7, n_objects * 2 * 7]);
        let mut seen = std::collections::BTreeSet::new();
        for (split_index, split) in SPLITS.iter().enumerate() {
            let shards: Vec<_> = plan.shards.iter().filter(|s| s.split == *split).collect();
            let mut next = 0;
            for (k, s) in shards.iter().enumerate() {
                assert_eq!((s.shard_index as usize, s.first_sample), (k, next));
                assert!(!s.samples.is_empty() && s.samples.len() <= 5);
                next += s.samples.len() as u64;
                for r in &s.samples {
                    assert_eq!(is_test(&c, r.trajectory), split_index == 1);
                    assert!(seen.insert((r.object_index, r.trajectory, r.instance)), "{r:?} twice");
                }
            }
            assert_eq!(next, plan.samples_per_split[split_index]);
        }
        assert_eq!(seen.len() as u64, plan.total_samples());
        // Jobs number the shards train first, then test.
        assert!(plan.shards.iter().enumerate().all(|(i, s)| s.job == i));
    }

    #[test]
    fn shard_selectors_partition_the_shards_and_bad_ones_are_refused() {
        let plan = Plan::new(&config(10, 7, 3));
        for n in 1..5 {
            let mut count = vec![0; plan.shards.len()];
            for i in 0..n {
                let sel: ShardSelector = format!("{i}/{n}").parse().unwrap();
                plan.shards.iter().filter(|s| sel.selects(s)).for_each(|s| count[s.job] += 1);
            }
            assert!(count.iter().all(|&c| c == 1), "{n} jobs: {count:?}");
        }
        for bad in ["1/1", "0/0", "x/2", "3", "-1/2"] {
            let e = bad.parse::<ShardSelector>().unwrap_err();
            assert!(e.contains("is not a shard selector"), "{bad}: {e}");
        }
    }
}

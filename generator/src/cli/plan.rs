//! `vtgen plan`: what a config will generate (objects × trajectories × instances, splits, shards,
//! a disk estimate), computed from the config alone; nothing is simulated or written.

use std::path::Path;

use crate::config::Config;
use crate::plan::{Plan, SPLITS};

use super::human_bytes;

/// The plan of `config` (loaded from `path`) as the lines `vtgen plan` prints.
pub fn describe(path: &Path, c: &Config) -> String {
    let plan = Plan::new(c);
    let s = &c.sampling;
    let mut out = String::new();
    let mut line = |text: String| {
        out.push_str(&text);
        out.push('\n');
    };
    line(format!("config      {}", path.display()));
    line(format!("objects     {} ({})", c.objects.len(), c.objects.iter().map(|o| o.id()).collect::<Vec<_>>().join(", ")));
    match crate::plan::EpisodeTimeline::of(c) {
        None => line(format!(
            "samples     {} objects x {} trajectories x {} instances = {}",
            c.objects.len(),
            s.trajectories_per_object,
            s.instances_per_trajectory,
            plan.total_samples()
        )),
        Some(t) => {
            let hz = |steps: u64| 1.0 / (steps as f64 * t.timestep);
            let seconds = t.steps as f64 * t.timestep;
            let approach = s.record.as_ref().is_some_and(|r| r.approach_steps(t.timestep) > 0);
            let grasp = match t.grasp_steps {
                0 => String::new(),
                g if approach => format!("the approach and the grasp ({:.2} s) and ", g as f64 * t.timestep),
                g => format!("the grasp ({:.2} s) and ", g as f64 * t.timestep),
            };
            line(format!(
                "episodes    {} objects x {} trajectories, each {grasp}{} arm moves = {seconds:.2} s: {} camera frames (samples) at {:.1} Hz, touch at {:.1} Hz, state at {:.1} Hz",
                c.objects.len(),
                s.trajectories_per_object,
                s.instances_per_trajectory,
                t.frames,
                hz(t.periods.camera),
                hz(t.periods.tactile),
                hz(t.periods.state)
            ));
            let (low, high) = crate::plan::bytes_per_sample(c);
            line(format!(
                "            about {} to {} per second of episode from the camera alone (estimate; `vtgen bench` measures it with the touch)",
                human_bytes(low * hz(t.periods.camera)),
                human_bytes(high * hz(t.periods.camera))
            ));
        }
    }
    for (i, split) in SPLITS.iter().enumerate() {
        let shards = plan.shards.iter().filter(|x| x.split == *split).count();
        line(format!("{split:<11} {} samples in {shards} shard(s) of up to {}", plan.samples_per_split[i], plan.samples_per_shard));
    }
    let n = plan.total_samples() as f64;
    let (low, high) = crate::plan::bytes_per_sample(c);
    let raw = crate::plan::raw_bytes_per_sample(c) * n;
    line(format!("disk        {} raw; about {} to {} written (estimate)", human_bytes(raw), human_bytes(low * n), human_bytes(high * n)));
    line(format!("output      {}", c.output.dir.display()));
    if let Some(g) = c.robot.as_ref().map(|r| &r.grasp) {
        // Occlusion depends on the hand's pose in the picture: measured, not planned.
        line(format!(
            "occlusion   back of the hand to the camera in {:.0}% of arm moves; `vtgen bench {}` measures the share per occlusion bin",
            100.0 * g.back_to_camera_share,
            path.display()
        ));
    }
    out
}

/// `vtgen plan`: the plan of the config at `path`, printed.
pub fn run(path: &Path, cfg: &crate::config::LoadedConfig) {
    print!("{}", describe(path, &cfg.config));
}

/// `vtgen config`: the config as vtgen reads it (defaults filled in, overrides applied), as YAML.
pub fn run_config(cfg: &crate::config::LoadedConfig) -> anyhow::Result<()> {
    print!("{}", serde_yaml::to_string(&cfg.config)?);
    Ok(())
}

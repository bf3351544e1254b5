//! `vtgen grasps`: the grasp loop alone (no rendering), over the first trajectories of every
//! object of a config, exactly as `generate` simulates them. It reports per object how many
//! trajectories kept the object through all their instances, the attempts and failures that took,
//! and the worst recorded instance (penetration, contacts, slip, floor clearance): the figures of
//! the robot issue's acceptance test, in a minute per object instead of a full generation.

use std::collections::BTreeMap;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use anyhow::{Result, bail};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

use crate::assets::LoadedObject;
use crate::config::LoadedConfig;
use crate::output::workers::run_pool;
use crate::physics::grasp::{HoldScreen, StepLedger, floor_clearance};
use crate::physics::robot::{RobotScene, Simulated};

/// What to check.
#[derive(Debug, Clone)]
pub struct GraspCheckOptions {
    /// Trajectories per object (the first ones of the config's plan).
    pub trajectories: u32,
    /// Instances per trajectory (default: the config's).
    pub instances: Option<u32>,
    /// Parallel workers, each with its own physics world.
    pub jobs: usize,
    pub quiet: bool,
    /// Run the hold screen as a judge only (every attempt goes on) and count its verdicts against
    /// the attempts' outcomes.
    pub judge_screen: bool,
}

/// One object's figures.
#[derive(Debug, Clone, Default, Serialize)]
pub struct ObjectGraspReport {
    pub object_id: String,
    pub trajectories: u32,
    /// Trajectories that kept the object through every instance (retries allowed).
    pub kept: u32,
    pub kept_fraction: f64,
    /// Grasp attempts over all trajectories (1 per trajectory when every first grasp held).
    pub attempts: u64,
    /// Attempts per kept trajectory (every failed attempt is physics thrown away); None when none
    /// was kept.
    pub attempts_per_kept: Option<f64>,
    /// Failed attempts by kind.
    pub failures: BTreeMap<String, u64>,
    /// Where the physics steps went (per phase; failed attempts, redone moves, kept).
    pub physics_steps: StepLedger,
    /// Physics steps per kept trajectory, and the share of all steps that made no recorded
    /// instance.
    pub steps_per_kept: Option<f64>,
    pub wasted_share: f64,
    pub instances: u64,
    /// Worst recorded instance: deepest penetration of a hand link into the object (mm), fewest
    /// touch links in contact, largest slip since the grasp (mm), lowest object point above the
    /// floor (mm).
    pub max_penetration_mm: f64,
    pub min_links_in_contact: usize,
    pub max_slip_mm: f64,
    pub mean_slip_mm: f64,
    /// The slip distribution over the recorded instances (mm since the grasp settled): median and
    /// 90th percentile, and the share of instances that slipped more than 10 mm.
    pub median_slip_mm: f64,
    pub p90_slip_mm: f64,
    pub over_10mm_share: f64,
    pub min_floor_clearance_mm: f64,
    /// Physics seconds (summed over workers).
    pub seconds: f64,
    /// The trajectories that were not kept, with the reason (`trajectory: error`).
    pub lost: Vec<String>,
    /// Episodes (`sampling.record`): per kept trajectory, the object's rotation in the palm since
    /// the settled grasp, at the episode's end and the largest on the way (degrees, physics-step
    /// states: `vtgen inspect` gives the same figures at the camera frames).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub in_hand_rotation_deg: Vec<EpisodeRotation>,
    /// Episodes with in-hand motion: every in-hand window that kept the object (those of undone
    /// moves and failed attempts too), by how its turning ended: `target` (the episode's turn target
    /// reached), `window` (turning to the window's end), `slid` (the pivot's slide budget),
    /// `no_wrist_turn`, `joint_range` (a rolling joint at its most without regrasp),
    /// `others_not_holding` (a finger not lifted), `finger_put_back` (the object moved while it
    /// was lifted), `no_pinch` (a hand's pivoting found no two pads facing each other).
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub in_hand_ends: BTreeMap<String, u64>,
    /// Pads a hand's pivoting placed again to make a pinch where it had none
    /// (`sampling.record.pivot.repinches`), in the same windows.
    #[serde(skip_serializing_if = "is_zero")]
    pub repinches: u64,
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

/// One episode's in-hand rotation (degrees).
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct EpisodeRotation {
    pub trajectory: u32,
    pub last_deg: f64,
    pub largest_deg: f64,
    /// The episode's turn target (`sampling.record.turn_target_deg`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub target_deg: Option<f64>,
}

/// An episode reached its turn target when its largest rotation came this close (degrees): the
/// controllers stop turning a few degrees short, where the object's speed would carry it on.
pub const TURN_TARGET_TOLERANCE_DEG: f64 = 2.0;

impl EpisodeRotation {
    /// Whether the episode has a turn target and reached it.
    pub fn reached_target(&self) -> bool {
        self.target_deg.is_some_and(|t| self.largest_deg >= t - TURN_TARGET_TOLERANCE_DEG)
    }
}

impl ObjectGraspReport {
    /// The median of the episodes' largest in-hand rotations, and the share of episodes whose
    /// largest reaches `deg`.
    pub fn rotation_figures(&self, deg: f64) -> (f64, f64) {
        let mut largest: Vec<f64> = self.in_hand_rotation_deg.iter().map(|e| e.largest_deg).collect();
        largest.sort_by(f64::total_cmp);
        let n = largest.len().max(1) as f64;
        let median = largest.get(largest.len() / 2).copied().unwrap_or(0.0);
        (median, largest.iter().filter(|&&d| d >= deg).count() as f64 / n)
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct GraspCheckReport {
    pub physics_backend: String,
    pub instances_per_trajectory: u32,
    pub objects: Vec<ObjectGraspReport>,
    pub seconds: f64,
    /// Whether the hold screen only judged (`--judge-screen`).
    pub judged_screen: bool,
}

impl GraspCheckReport {
    /// The lowest kept fraction over the objects.
    pub fn worst_kept_fraction(&self) -> f64 {
        self.objects.iter().map(|o| o.kept_fraction).fold(1.0, f64::min)
    }

    /// A Markdown table of the figures.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "Grasp loop, {} physics, {} instances per trajectory ({:.0} s):\n\n",
            self.physics_backend, self.instances_per_trajectory, self.seconds
        );
        s.push_str("| object | kept | attempts | per kept | physics steps per kept | wasted | failures | max penetration (mm) | min contacts | slip median / 90% / max (mm) | slip > 10 mm | mean slip (mm) | min floor clearance (mm) |\n");
        s.push_str("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
        for o in &self.objects {
            let failures: Vec<String> = o.failures.iter().map(|(k, v)| format!("{k} {v}")).collect();
            s.push_str(&format!(
                "| {} | {}/{} ({:.0}%) | {} | {} | {} | {:.0}% | {} | {:.2} | {} | {:.1} / {:.1} / {:.1} | {:.1}% | {:.1} | {:.0} |\n",
                o.object_id,
                o.kept,
                o.trajectories,
                100.0 * o.kept_fraction,
                o.attempts,
                o.attempts_per_kept.map_or("-".to_string(), |a| format!("{a:.1}")),
                o.steps_per_kept.map_or("-".to_string(), |a| format!("{a:.0}")),
                100.0 * o.wasted_share,
                if failures.is_empty() { "none".into() } else { failures.join(", ") },
                o.max_penetration_mm,
                o.min_links_in_contact,
                o.median_slip_mm,
                o.p90_slip_mm,
                o.max_slip_mm,
                100.0 * o.over_10mm_share,
                o.mean_slip_mm,
                o.min_floor_clearance_mm,
            ));
        }
        s.push_str(&self.phase_line());
        if self.judged_screen {
            s.push_str("\n\nThe hold screen as a judge (every attempt went on; its verdict against the attempt's outcome):\n\n");
            s.push_str("| object | passed, held | passed, failed later | failed, but held | failed, failed | failures caught | held grasps lost |\n");
            s.push_str("|---|---|---|---|---|---|---|\n");
            for o in &self.objects {
                let j = o.physics_steps.screen_judged;
                let share =
                    |a: u64, b: u64| if a + b == 0 { "-".to_string() } else { format!("{:.0}%", 100.0 * a as f64 / (a + b) as f64) };
                s.push_str(&format!(
                    "| {} | {} | {} | {} | {} | {} | {} |\n",
                    o.object_id,
                    j.passed_held,
                    j.passed_failed,
                    j.failed_held,
                    j.failed_failed,
                    share(j.failed_failed, j.passed_failed),
                    share(j.failed_held, j.passed_held)
                ));
            }
        }
        if self.objects.iter().any(|o| !o.in_hand_rotation_deg.is_empty()) {
            s.push_str("\n\nIn-hand rotation per episode (the object's turn in the palm since the settled grasp):\n\n");
            let targets = self.objects.iter().flat_map(|o| &o.in_hand_rotation_deg).any(|e| e.target_deg.is_some());
            s.push_str("| object | episodes | largest: median (°) | largest: max (°) | at the end: median (°) | episodes >= 45° |");
            s.push_str(if targets { " turn target reached |" } else { "" });
            s.push_str(" windows' turning ended by |\n|---|---|---|---|---|---|---|");
            s.push_str(if targets { "---|\n" } else { "\n" });
            for o in &self.objects {
                let (median, share) = o.rotation_figures(45.0);
                let mut last: Vec<f64> = o.in_hand_rotation_deg.iter().map(|e| e.last_deg).collect();
                last.sort_by(f64::total_cmp);
                let max = o.in_hand_rotation_deg.iter().map(|e| e.largest_deg).fold(0.0, f64::max);
                s.push_str(&format!(
                    "| {} | {} | {median:.1} | {max:.1} | {:.1} | {:.0}% |",
                    o.object_id,
                    o.in_hand_rotation_deg.len(),
                    last.get(last.len() / 2).copied().unwrap_or(0.0),
                    100.0 * share
                ));
                if targets {
                    let reached = o.in_hand_rotation_deg.iter().filter(|e| e.reached_target()).count();
                    s.push_str(&format!(" {reached}/{} |", o.in_hand_rotation_deg.len()));
                }
                let mut ends: Vec<String> = o.in_hand_ends.iter().map(|(k, v)| format!("{k} {v}")).collect();
                if o.repinches > 0 {
                    ends.push(format!("(pads placed again {})", o.repinches));
                }
                s.push_str(&format!(" {} |\n", if ends.is_empty() { "-".to_string() } else { ends.join(", ") }));
            }
        }
        for o in &self.objects {
            for l in &o.lost {
                s.push_str(&format!("\nlost: {} trajectory {l}", o.object_id));
            }
        }
        s
    }
}

impl GraspCheckReport {
    /// Where the physics steps went over every object: per phase, and thrown away.
    fn phase_line(&self) -> String {
        let mut all = StepLedger::default();
        for o in &self.objects {
            all.merge(&o.physics_steps);
        }
        let total = all.total().max(1) as f64;
        let pct = |v: u64| 100.0 * v as f64 / total;
        format!(
            "\nPhysics steps ({}): placing {:.1}%, closing {:.1}%, settling {:.1}%, hold screen {:.1}%, arm moves {:.1}%, holds {:.1}%, \
             in-hand motion {:.1}%, squeeze waits {:.1}%; in failed attempts {:.1}% (they had recorded {:.1} instances on average), \
             in redone moves {:.1}%, making the kept trajectories {:.1}%. {} attempts screened out.\n",
            all.total(),
            pct(all.place),
            pct(all.close),
            pct(all.settle),
            pct(all.screen),
            pct(all.arm_move),
            pct(all.hold),
            pct(all.in_hand),
            pct(all.squeeze),
            pct(all.failed_attempts),
            all.instances_before_failure as f64 / self.objects.iter().map(|o| o.attempts - o.kept as u64).sum::<u64>().max(1) as f64,
            pct(all.redone_moves),
            pct(all.kept),
            all.screened_out
        )
    }
}

/// One trajectory's outcome.
struct TrajectoryResult {
    object: usize,
    trajectory: u32,
    /// Why the trajectory was lost; `None` when it was kept.
    lost: Option<String>,
    attempts: u64,
    failures: BTreeMap<String, u64>,
    steps: StepLedger,
    in_hand_ends: BTreeMap<&'static str, u64>,
    repinches: u64,
    instances: u64,
    max_penetration_mm: f64,
    min_contacts: usize,
    max_slip_mm: f64,
    sum_slip_mm: f64,
    slips_mm: Vec<f64>,
    min_clearance_mm: f64,
    seconds: f64,
    rotation: Option<EpisodeRotation>,
}

/// Simulates one trajectory as `generate` would and measures its recorded instances. A lost
/// trajectory (every attempt failed) keeps its attempts and failures.
fn check_trajectory(robot: &mut RobotScene, seed: u64, obj: &LoadedObject, o: usize, t: u32, instances: u32) -> TrajectoryResult {
    let t0 = Instant::now();
    let Simulated { trajectory: outcome, stats: st, steps, in_hand_ends, repinches } =
        robot.simulate(seed, o as u32, &obj.id, t, instances);
    let mut r = TrajectoryResult {
        object: o,
        trajectory: t,
        lost: outcome.as_ref().err().map(|e| format!("{e:#}")),
        attempts: st.attempts,
        failures: st.failures.clone(),
        steps,
        in_hand_ends,
        repinches,
        instances: 0,
        max_penetration_mm: 0.0,
        min_contacts: usize::MAX,
        max_slip_mm: 0.0,
        sum_slip_mm: 0.0,
        slips_mm: Vec::new(),
        min_clearance_mm: f64::MAX,
        seconds: 0.0,
        rotation: None,
    };
    for s in outcome.iter().flat_map(|traj| &traj.instances) {
        r.instances += 1;
        r.max_penetration_mm = r.max_penetration_mm.max(s.penetration * 1e3);
        r.min_contacts = r.min_contacts.min(s.contacts.iter().filter(|c| c.is_some()).count());
        r.max_slip_mm = r.max_slip_mm.max(s.slip_translation * 1e3);
        r.sum_slip_mm += s.slip_translation * 1e3;
        r.slips_mm.push(s.slip_translation * 1e3);
        let lowest = floor_clearance(&obj.mesh.positions, &(robot.t_world_base * s.t_base_palm * s.t_palm_object));
        r.min_clearance_mm = r.min_clearance_mm.min(lowest * 1e3);
    }
    if let Ok(traj) = &outcome
        && let (Some(first), Some(last)) = (traj.steps.get(traj.settled_step), traj.steps.last())
    {
        let orientation = |s: &crate::physics::grasp::InstanceState| glam::DQuat::from_mat3(&s.t_palm_object.matrix3).normalize();
        let turn = |s: &crate::physics::grasp::InstanceState| orientation(first).angle_between(orientation(s)).to_degrees();
        let largest = traj.steps[traj.settled_step..].iter().map(turn).fold(0.0, f64::max);
        r.rotation = Some(EpisodeRotation { trajectory: t, last_deg: turn(last), largest_deg: largest, target_deg: traj.turn_target_deg });
    }
    r.seconds = t0.elapsed().as_secs_f64();
    r
}

pub fn check_grasps(cfg: &LoadedConfig, objects: &[LoadedObject], opts: &GraspCheckOptions) -> Result<GraspCheckReport> {
    let config = &cfg.config;
    let Some(robot_cfg) = &config.robot else {
        bail!("{}: the config has no `robot:` section, so there is no grasp loop to check", cfg.path.display());
    };
    if opts.trajectories == 0 {
        bail!("--trajectories must be at least 1");
    }
    let instances = opts.instances.unwrap_or(config.sampling.instances_per_trajectory);
    let work: Vec<(usize, u32)> = (0..opts.trajectories).flat_map(|t| (0..objects.len()).map(move |o| (o, t))).collect();
    let progress = if opts.quiet { ProgressBar::hidden() } else { ProgressBar::new(work.len() as u64) };
    progress.set_style(
        ProgressStyle::with_template("{spinner} {elapsed_precise} [{bar:36}] {pos}/{len} trajectories  ETA {eta}  {msg}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    let started = Instant::now();
    let abort = AtomicBool::new(false);
    let pooled = run_pool(
        opts.jobs,
        &work,
        &abort,
        || {
            let mut scene = RobotScene::new(cfg, robot_cfg, objects)?;
            if opts.judge_screen {
                scene.hold_screen = Some(HoldScreen::Judge);
            }
            Ok(scene)
        },
        |robot, _, &(o, t)| {
            progress.set_message(format!("{} #{t}", objects[o].id));
            let r = check_trajectory(robot, config.seed, &objects[o], o, t, instances);
            progress.inc(1);
            Ok(Some(r))
        },
        |robot| Ok(robot.backend_name().to_string()),
    );
    progress.finish_and_clear();
    let (results, backends) = pooled.into_result()?;
    let per_object = per_object_figures(objects, results.into_iter().map(|(_, r)| r).collect());
    Ok(GraspCheckReport {
        physics_backend: backends.into_iter().next().unwrap_or_default(),
        instances_per_trajectory: instances,
        objects: per_object,
        seconds: started.elapsed().as_secs_f64(),
        judged_screen: opts.judge_screen,
    })
}

/// Each object's figures from its trajectories' results.
fn per_object_figures(objects: &[LoadedObject], mut results: Vec<TrajectoryResult>) -> Vec<ObjectGraspReport> {
    let mut per_object: Vec<ObjectGraspReport> = objects
        .iter()
        .map(|o| ObjectGraspReport {
            object_id: o.id.clone(),
            min_links_in_contact: usize::MAX,
            min_floor_clearance_mm: f64::MAX,
            ..Default::default()
        })
        .collect();
    results.sort_by_key(|r| (r.object, r.trajectory));
    let mut slips: Vec<Vec<f64>> = vec![Vec::new(); per_object.len()];
    for r in results {
        slips[r.object].extend_from_slice(&r.slips_mm);
        let o = &mut per_object[r.object];
        o.trajectories += 1;
        match r.lost {
            None => o.kept += 1,
            Some(why) => o.lost.push(format!("{}: {why}", r.trajectory)),
        }
        o.attempts += r.attempts;
        for (k, v) in r.failures {
            *o.failures.entry(k).or_default() += v;
        }
        o.physics_steps.merge(&r.steps);
        for (k, v) in r.in_hand_ends {
            *o.in_hand_ends.entry(k.to_string()).or_default() += v;
        }
        o.repinches += r.repinches;
        o.instances += r.instances;
        o.max_penetration_mm = o.max_penetration_mm.max(r.max_penetration_mm);
        o.min_links_in_contact = o.min_links_in_contact.min(r.min_contacts);
        o.max_slip_mm = o.max_slip_mm.max(r.max_slip_mm);
        o.mean_slip_mm += r.sum_slip_mm;
        o.min_floor_clearance_mm = o.min_floor_clearance_mm.min(r.min_clearance_mm);
        o.seconds += r.seconds;
        o.in_hand_rotation_deg.extend(r.rotation);
    }
    for (o, slips) in per_object.iter_mut().zip(&mut slips) {
        slips.sort_by(f64::total_cmp);
        let at = |q: f64| slips.get(((slips.len().max(1) - 1) as f64 * q).round() as usize).copied().unwrap_or(0.0);
        (o.median_slip_mm, o.p90_slip_mm) = (at(0.5), at(0.9));
        o.over_10mm_share = slips.iter().filter(|&&s| s > 10.0).count() as f64 / slips.len().max(1) as f64;
        o.kept_fraction = o.kept as f64 / o.trajectories.max(1) as f64;
        o.attempts_per_kept = (o.kept > 0).then(|| o.attempts as f64 / o.kept as f64);
        o.steps_per_kept = (o.kept > 0).then(|| o.physics_steps.total() as f64 / o.kept as f64);
        o.wasted_share = o.physics_steps.wasted() as f64 / o.physics_steps.total().max(1) as f64;
        o.mean_slip_mm /= o.instances.max(1) as f64;
        if o.instances == 0 {
            o.min_links_in_contact = 0;
            o.min_floor_clearance_mm = 0.0;
        }
    }
    per_object
}

/// `vtgen grasps`: the grasp loop's report per object (markdown or JSON); an error when an object
/// kept less than `min_kept` of its trajectories.
pub fn run(
    cfg: &LoadedConfig,
    ycb_dir: Option<&std::path::PathBuf>,
    opts: &GraspCheckOptions,
    json: bool,
    min_kept: Option<f64>,
) -> Result<()> {
    let objects = crate::assets::load_objects(cfg, ycb_dir)?;
    let r = check_grasps(cfg, &objects, opts)?;
    if json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        print!("{}", r.markdown());
    }
    if let Some(min) = min_kept
        && r.worst_kept_fraction() < min
    {
        bail!("an object kept {:.1}% of its trajectories, below --min-kept {min}", 100.0 * r.worst_kept_fraction());
    }
    Ok(())
}

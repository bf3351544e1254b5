//! `vtgen robot check --suggest CONFIG`: a home, a workspace and a base position with which the
//! robot check finds no problem, searched from the config's own, the smallest change first.
//!
//! The home is what the inverse kinematics starts every move from: a home facing away from the
//! workspace, or folded through the floor, fails poses the arm reaches well from another. Homes are
//! found by solving the grasp frame hand-up at the workspace's centre from seeds spread over the
//! joints' ranges, and ranked by how far every joint stays from its limits. When no home passes,
//! the workspace is raised or lowered and the base moved nearer or farther (the camera moves with
//! the workspace, so the picture frames it as before), nearest first.

use anyhow::Result;
use glam::{DAffine3, DVec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use vt_robot::{IkOptions, Robot};

use super::robot_check::{RobotCheckReport, check_setup, config_robot};
use crate::config::{LoadedConfig, RobotConfig};
use crate::physics::grasp::{palm_up, robot_floor_clearance};
use crate::physics::robot::t_world_base;

/// Seeds of the home search (joint values drawn over each arm joint's range).
const HOME_SEEDS: usize = 24;
/// Homes (the best-ranked) checked for each placement.
const HOMES_CHECKED: usize = 3;
/// A home keeps every link this far (m) above the floor.
const HOME_FLOOR_CLEARANCE: f64 = 0.02;
/// Workspace height changes (m) and base distance changes (m, + farther from the workspace) tried,
/// each list nearest first.
const WORKSPACE_SHIFTS: [f64; 9] = [0.0, 0.1, -0.1, 0.2, -0.2, 0.3, 0.4, 0.5, 0.6];
const BASE_SHIFTS: [f64; 5] = [0.0, -0.1, 0.1, -0.2, 0.2];
/// The workspace's floor never goes below this (m): the objects start above the floor.
const MIN_WORKSPACE_Z: f64 = 0.05;

/// Where the robot stands and how it moves: what the search changes.
#[derive(Debug, Clone, Serialize)]
pub struct Setup {
    pub home_arm: Vec<f64>,
    pub base_position: [f64; 3],
    pub workspace_min: [f64; 3],
    pub workspace_max: [f64; 3],
    /// The workspace's (and the camera's) height change, and the base's horizontal move away from
    /// the workspace (m).
    pub raised_m: f64,
    pub base_farther_m: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct Suggestion {
    pub before: RobotCheckReport,
    pub after: RobotCheckReport,
    pub setup: Setup,
    /// The `--set` overrides that apply it.
    pub sets: Vec<String>,
}

/// Arm homes (arm joint values) putting the grasp frame hand-up at the workspace's centre with
/// every link above the floor, the ones farthest from their joints' limits first.
pub fn homes(robot: &Robot, rc: &RobotConfig, n: usize) -> Vec<Vec<f64>> {
    let w = &rc.grasp.palm_workspace;
    let centre = DVec3::from_array(w.min).lerp(DVec3::from_array(w.max), 0.5);
    let t_world_base = t_world_base(rc);
    let target = t_world_base.inverse() * DAffine3::from_rotation_translation(palm_up(), centre);
    let model = &robot.model;
    let mut rng = ChaCha8Rng::seed_from_u64(0x686f_6d65); // "home"
    let mut found: Vec<(f64, Vec<f64>)> = Vec::new();
    for _ in 0..HOME_SEEDS {
        let mut seed = model.zero();
        for (&d, &j) in robot.arm_dofs.iter().zip(&robot.arm_joints) {
            let (lo, hi) = range(robot, j);
            seed[d] = rng.random_range(lo..=hi);
        }
        let Some(q) = robot.solve_grasp_ik(&target, &seed, &IkOptions::default()) else { continue };
        if robot_floor_clearance(robot, &t_world_base, &q).is_some_and(|(_, z)| z < HOME_FLOOR_CLEARANCE) {
            continue;
        }
        let arm: Vec<f64> = robot.arm_dofs.iter().zip(&robot.arm_joints).map(|(&d, &j)| nearest_zero_turn(robot, j, q[d])).collect();
        if found.iter().any(|(_, o)| o.iter().zip(&arm).all(|(a, b)| (a - b).abs() < 0.05)) {
            continue;
        }
        found.push((limit_margin(robot, &q), arm));
    }
    found.sort_by(|a, b| b.0.total_cmp(&a.0));
    found.into_iter().take(n).map(|(_, q)| q).collect()
}

/// `v` turned by whole turns to the value nearest zero within the joint's limits (a wrist at 5.06
/// rad reads -1.23): the same pose, the home a reader recognises.
fn nearest_zero_turn(robot: &Robot, joint: usize, v: f64) -> f64 {
    let j = &robot.model.joints[joint];
    let tau = std::f64::consts::TAU;
    let wrapped = v - tau * (v / tau).round();
    [wrapped, wrapped + tau, wrapped - tau]
        .into_iter()
        .filter(|x| (j.lower..=j.upper).contains(x))
        .min_by(|a, b| a.abs().total_cmp(&b.abs()))
        .unwrap_or(v)
}

/// A joint's range for seeding: its limits, or one turn about zero for a continuous joint.
fn range(robot: &Robot, joint: usize) -> (f64, f64) {
    let j = &robot.model.joints[joint];
    if (j.upper - j.lower).is_finite() { (j.lower, j.upper) } else { (-std::f64::consts::PI, std::f64::consts::PI) }
}

/// The least distance of an arm joint from its nearer limit, as a share of its range.
fn limit_margin(robot: &Robot, q: &[f64]) -> f64 {
    robot
        .arm_dofs
        .iter()
        .zip(&robot.arm_joints)
        .map(|(&d, &j)| {
            let jt = &robot.model.joints[j];
            if (jt.upper - jt.lower).is_finite() { (q[d] - jt.lower).min(jt.upper - q[d]) / (jt.upper - jt.lower) } else { 0.5 }
        })
        .fold(f64::MAX, f64::min)
}

/// How far a report is from passing: problems first, then the unreached share, the share under
/// the floor and the worst share at a joint limit.
fn badness(r: &RobotCheckReport) -> (usize, f64) {
    let at_limit = r.joints_at_limit.iter().map(|j| j.share).fold(0.0, f64::max);
    (r.problems.len(), (1.0 - r.reach_share) + r.under_floor_share + at_limit)
}

fn better(a: &RobotCheckReport, b: &RobotCheckReport) -> bool {
    let (pa, sa) = badness(a);
    let (pb, sb) = badness(b);
    (pa, sa) < (pb, sb) && !(pa == pb && (sa - sb).abs() < 1e-9)
}

/// `rc` with the workspace raised by `raised` and the base moved `farther` away from it.
fn placed(rc: &RobotConfig, raised: f64, farther: f64) -> RobotConfig {
    let mut out = rc.clone();
    let w = &mut out.grasp.palm_workspace;
    w.min[2] += raised;
    w.max[2] += raised;
    let centre = DVec3::from_array(rc.grasp.palm_workspace.min).lerp(DVec3::from_array(rc.grasp.palm_workspace.max), 0.5);
    let base = DVec3::from_array(rc.base_position);
    let away = (base - centre).with_z(0.0);
    // A base right under the workspace moves along its own x axis.
    let away = if away.length() > 1e-6 { away.normalize() } else { t_world_base(rc).transform_vector3(DVec3::X) };
    out.base_position = (base + away * farther).to_array();
    out
}

/// The best home for `rc`'s placement, and its check (the config's own home among the candidates).
fn best_home(robot: &Robot, rc: &RobotConfig, camera: DVec3, jaw_tolerance_deg: f64) -> (RobotConfig, RobotCheckReport) {
    let mut best = (rc.clone(), check_setup(robot, rc, camera, jaw_tolerance_deg));
    for home in homes(robot, rc, HOMES_CHECKED) {
        let mut candidate = rc.clone();
        candidate.grasp.home_arm = home;
        let report = check_setup(robot, &candidate, camera, jaw_tolerance_deg);
        if better(&report, &best.1) {
            best = (candidate, report);
        }
    }
    best
}

/// What the check would find with a searched home at the config's own placement (None when no
/// home reaches the workspace's centre hand-up).
pub fn with_searched_home(robot: &Robot, rc: &RobotConfig, camera: DVec3, jaw_tolerance_deg: f64) -> Option<(Vec<f64>, RobotCheckReport)> {
    let home = homes(robot, rc, 1).into_iter().next()?;
    let mut candidate = rc.clone();
    candidate.grasp.home_arm = home.clone();
    Some((home, check_setup(robot, &candidate, camera, jaw_tolerance_deg)))
}

/// The search: placements nearest first, each with its best home; the first that passes, else the
/// best seen.
pub fn suggest(cfg: &LoadedConfig, jaw_tolerance_deg: f64) -> Result<Suggestion> {
    let (robot, rc) = config_robot(cfg)?;
    let camera = DVec3::from_array(cfg.config.camera.position);
    let before = check_setup(robot, rc, camera, jaw_tolerance_deg);
    let mut placements: Vec<(f64, f64)> = WORKSPACE_SHIFTS
        .iter()
        .flat_map(|&dz| BASE_SHIFTS.iter().map(move |&dr| (dz, dr)))
        .filter(|&(dz, _)| dz == 0.0 || rc.grasp.palm_workspace.min[2] + dz >= MIN_WORKSPACE_Z)
        .collect();
    placements.sort_by(|a, b| (a.0.abs() + a.1.abs()).total_cmp(&(b.0.abs() + b.1.abs())));
    let mut best: Option<(f64, f64, RobotConfig, RobotCheckReport)> = None;
    for (dz, dr) in placements {
        let at = placed(rc, dz, dr);
        let (candidate, report) = best_home(robot, &at, camera + DVec3::Z * dz, jaw_tolerance_deg);
        let passes = report.problems.is_empty();
        if best.as_ref().is_none_or(|b| better(&report, &b.3)) {
            best = Some((dz, dr, candidate, report));
        }
        if passes {
            break;
        }
    }
    let (raised_m, base_farther_m, found, after) = best.expect("the config's own placement is always tried");
    let w = &found.grasp.palm_workspace;
    let setup = Setup {
        home_arm: found.grasp.home_arm.clone(),
        base_position: found.base_position,
        workspace_min: w.min,
        workspace_max: w.max,
        raised_m,
        base_farther_m,
    };
    let sets = set_lines(cfg, rc, &setup);
    Ok(Suggestion { before, after, setup, sets })
}

fn list(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| format!("{}", (x * 1e4).round() / 1e4)).collect();
    format!("[{}]", items.join(", "))
}

/// The `--set` lines that turn the config's setup into `setup` (only what changed).
fn set_lines(cfg: &LoadedConfig, rc: &RobotConfig, setup: &Setup) -> Vec<String> {
    let mut sets = Vec::new();
    if setup.home_arm.iter().zip(&rc.grasp.home_arm).any(|(a, b)| (a - b).abs() > 1e-9) {
        sets.push(format!("robot.grasp.home_arm={}", list(&setup.home_arm)));
    }
    if setup.base_farther_m != 0.0 {
        sets.push(format!("robot.base_position={}", list(&setup.base_position)));
    }
    if setup.raised_m != 0.0 {
        sets.push(format!("robot.grasp.palm_workspace.min={}", list(&setup.workspace_min)));
        sets.push(format!("robot.grasp.palm_workspace.max={}", list(&setup.workspace_max)));
        let camera = &cfg.config.camera;
        let up = |p: [f64; 3]| [p[0], p[1], p[2] + setup.raised_m];
        sets.push(format!("camera.position={}", list(&up(camera.position))));
        sets.push(format!("camera.look_at={}", list(&up(camera.look_at))));
    }
    sets
}

/// One line of a report's figures.
fn figures(r: &RobotCheckReport) -> String {
    let worst = r.joints_at_limit.iter().max_by(|a, b| a.share.total_cmp(&b.share));
    format!(
        "reach {:.0}%, a link under the floor in {:.0}%, {}: {}",
        100.0 * r.reach_share,
        100.0 * r.under_floor_share,
        worst.map_or("no arm joint at a limit".to_string(), |j| format!("'{}' at a limit in {:.0}%", j.joint, 100.0 * j.share)),
        if r.problems.is_empty() { "no problem".to_string() } else { format!("{} problem(s)", r.problems.len()) }
    )
}

impl std::fmt::Display for Suggestion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "before: {}", figures(&self.before))?;
        writeln!(f, "after:  {}", figures(&self.after))?;
        let s = &self.setup;
        writeln!(
            f,
            "  home: {} (the inverse kinematics starts every move from it)",
            if self.sets.iter().any(|l| l.starts_with("robot.grasp.home_arm")) { "searched" } else { "the config's" }
        )?;
        if s.raised_m != 0.0 {
            writeln!(
                f,
                "  workspace {} {:.2} m (the camera with it)",
                if s.raised_m > 0.0 { "raised" } else { "lowered" },
                s.raised_m.abs()
            )?;
        }
        if s.base_farther_m != 0.0 {
            writeln!(
                f,
                "  base {:.2} m {} the workspace",
                s.base_farther_m.abs(),
                if s.base_farther_m > 0.0 { "farther from" } else { "nearer to" }
            )?;
        }
        if self.sets.is_empty() {
            return write!(f, "nothing to change");
        }
        writeln!(f, "apply with (or write into the config; for a robot of your own, the home can be its description's arm.home):")?;
        let lines: Vec<String> = self.sets.iter().map(|l| format!("  --set '{l}'")).collect();
        write!(f, "{}", lines.join(" \\\n"))
    }
}

/// `vtgen robot check --suggest`: the suggestion (text or JSON); an error when even the best
/// setup found has a problem.
pub fn run(cfg: &LoadedConfig, json: bool, jaw_tolerance_deg: f64) -> Result<()> {
    let s = suggest(cfg, jaw_tolerance_deg)?;
    if json {
        println!("{}", serde_json::to_string_pretty(&s)?);
    } else {
        println!("{s}");
    }
    if !s.after.problems.is_empty() {
        let list: String = s.after.problems.iter().map(|p| format!("\n  - {p}")).collect();
        anyhow::bail!("robot check --suggest: no home, workspace or base placement tried passes; the best still has:{list}");
    }
    Ok(())
}

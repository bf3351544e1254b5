//! `vtgen robot check CONFIG`: the robot a config names, checked before any data is made. Loading
//! the config already reads every link's geometry (all mesh problems listed at once); this adds
//! what only the arm in its workspace shows: the share of grasp-frame poses the arm reaches, links
//! under the floor at those poses, joints pinned at a limit, and whether a gripper's jaws face
//! each other. A short hold test is `vtgen grasps CONFIG --trajectories 2`.

use anyhow::{Context, Result};
use glam::{DAffine3, DVec3};
use serde::Serialize;
use vt_robot::{GraspKind, Robot};

use crate::config::{LoadedConfig, RobotConfig};
use crate::physics::grasp::{GraspContext, MIN_REACHABLE_SHARE, REACH_SAMPLES, reach_samples, robot_floor_clearance};
use crate::physics::robot::{grasp_context, t_world_base};

/// A joint closer than this to a limit (rad, or m for a prismatic joint) counts as at the limit.
pub const AT_LIMIT: f64 = 0.01;
/// A share of reached poses above which a pinned joint or a link under the floor is a problem
/// (below it, the grasp loop's redos absorb them: a link under the floor redoes the move).
pub const MAX_BAD_SHARE: f64 = 0.1;

#[derive(Debug, Clone, Serialize)]
pub struct JointAtLimit {
    pub joint: String,
    /// Share of the reached poses with this joint within `AT_LIMIT` of a limit.
    pub share: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct RobotCheckReport {
    pub robot: String,
    pub links: usize,
    pub arm_joints: usize,
    pub hand_joints: usize,
    pub pads: Vec<String>,
    /// The mesh files its geometry was read from.
    pub mesh_files: usize,
    /// Grasp-frame poses drawn from `robot.grasp.palm_workspace`, and the share the arm reaches.
    pub poses: usize,
    pub reach_share: f64,
    /// Share of the reached poses with a moving link under the floor, and the lowest link seen.
    pub under_floor_share: f64,
    pub lowest_link: Option<String>,
    pub lowest_link_height_m: Option<f64>,
    /// Arm joints at a limit in more than none of the reached poses.
    pub joints_at_limit: Vec<JointAtLimit>,
    /// Parallel-jaw grippers: the first two pads over the closing ([`JawReport`]).
    pub jaws: Option<JawReport>,
    /// What must be fixed before making data (empty: none).
    pub problems: Vec<String>,
    /// What to change for the arm's placement problems, from their cause.
    pub advice: Vec<String>,
}

/// The config's robot and its `robot:` section.
pub fn config_robot(cfg: &LoadedConfig) -> Result<(&Robot, &RobotConfig)> {
    let rc = cfg.config.robot.as_ref().with_context(|| format!("{}: the config has no `robot:` section", cfg.path.display()))?;
    let robot = cfg.robot.as_ref().context("a config with a robot section has its robot loaded")?;
    Ok((robot, rc))
}

pub fn check_robot(cfg: &LoadedConfig, jaw_tolerance_deg: f64) -> Result<RobotCheckReport> {
    let (robot, rc) = config_robot(cfg)?;
    let camera = DVec3::from_array(cfg.config.camera.position);
    let mut report = check_setup(robot, rc, camera, jaw_tolerance_deg);
    report.advice = advice(robot, rc, camera, &report);
    Ok(report)
}

/// What to change, from the cause: the inverse kinematics starts every move from the home, so a
/// home facing away from the workspace (or one folding a link through the floor) fails poses the
/// arm reaches well from another. The check is redone with a searched home to tell the two apart.
fn advice(robot: &Robot, rc: &RobotConfig, camera: DVec3, report: &RobotCheckReport) -> Vec<String> {
    let placement_problem = report.reach_share < MIN_REACHABLE_SHARE
        || report.under_floor_share > MAX_BAD_SHARE
        || report.joints_at_limit.iter().any(|j| j.share > MAX_BAD_SHARE);
    if !placement_problem {
        return Vec::new();
    }
    let mut out = Vec::new();
    match super::robot_suggest::with_searched_home(robot, rc, camera, report.jaws.as_ref().map_or(JAW_TOLERANCE_DEG, |j| j.tolerance_deg)) {
        Some((home, with_home)) if with_home.problems.len() < report.problems.len() => {
            let values: Vec<String> = home.iter().map(|v| format!("{:.4}", v)).collect();
            out.push(format!(
                "the cause is the home the inverse kinematics starts from (robot.grasp.home_arm, else the description's arm.home): \
                 from the searched home [{}] the arm reaches {:.0}% with {} problem(s) left",
                values.join(", "),
                100.0 * with_home.reach_share,
                with_home.problems.len()
            ));
        }
        Some(_) => out.push(
            "a better home alone does not fix it: the workspace lies where the arm cannot hold the hand up; move the workspace \
             (robot.grasp.palm_workspace) or the base (robot.base_position)"
                .into(),
        ),
        None => out.push(
            "the arm cannot put the grasp frame hand-up at the workspace's centre from any seed tried: move the workspace \
             (robot.grasp.palm_workspace) or the base (robot.base_position)"
                .into(),
        ),
    }
    out.push("`vtgen robot check --suggest CONFIG` searches a home, workspace and base placement that pass".into());
    out
}

/// The check of `robot` placed and moved as `rc` says (its base, home and workspace).
pub fn check_setup(robot: &Robot, rc: &RobotConfig, camera_position: DVec3, jaw_tolerance_deg: f64) -> RobotCheckReport {
    let t_world_base = t_world_base(rc);
    let ctx = grasp_context(robot, t_world_base, rc, camera_position, None);
    let pre: Vec<f64> = rc.grasp.preshape.iter().map(|&(lo, _)| lo).collect();
    let reached: Vec<Vec<f64>> = reach_samples(&ctx, REACH_SAMPLES)
        .into_iter()
        .flatten()
        .map(|mut q| {
            robot.set_hand(&mut q, &pre);
            q
        })
        .collect();
    let mut problems = Vec::new();
    let reach_share = reached.len() as f64 / REACH_SAMPLES as f64;
    if reach_share < MIN_REACHABLE_SHARE {
        problems.push(format!(
            "the arm reaches {:.0}% of {REACH_SAMPLES} grasp-frame poses drawn from robot.grasp.palm_workspace (at least {:.0}% needed): \
             see the advice below",
            100.0 * reach_share,
            100.0 * MIN_REACHABLE_SHARE
        ));
    }
    let model = &robot.model;
    let (under_floor_share, lowest) = floor_clearance(robot, &t_world_base, &reached, &mut problems);
    let joints_at_limit = joints_at_limit(robot, &reached, &mut problems);
    let jaws = jaws(robot, &ctx, rc, jaw_tolerance_deg, &mut problems);
    RobotCheckReport {
        robot: robot.name.clone(),
        links: model.links.len(),
        arm_joints: robot.arm_joints.len(),
        hand_joints: robot.hand.len(),
        pads: robot.pad_names(),
        mesh_files: model.mesh_files.len(),
        poses: REACH_SAMPLES,
        reach_share,
        under_floor_share,
        lowest_link: lowest.map(|(l, _)| model.links[l].name.clone()),
        lowest_link_height_m: lowest.map(|(_, z)| z),
        joints_at_limit,
        jaws,
        problems,
        advice: Vec::new(),
    }
}

/// The share of the reached poses with a link under the floor, and the lowest link seen (its
/// height, m); a problem when the share is too high.
fn floor_clearance(
    robot: &Robot,
    t_world_base: &DAffine3,
    reached: &[Vec<f64>],
    problems: &mut Vec<String>,
) -> (f64, Option<(usize, f64)>) {
    let mut under = 0usize;
    let mut lowest: Option<(usize, f64)> = None;
    for q in reached {
        if let Some((link, z)) = robot_floor_clearance(robot, t_world_base, q) {
            under += usize::from(z < 0.0);
            if lowest.is_none_or(|(_, l)| z < l) {
                lowest = Some((link, z));
            }
        }
    }
    let under_floor_share = under as f64 / reached.len().max(1) as f64;
    if under_floor_share > MAX_BAD_SHARE {
        let (link, z) = lowest.expect("a link under the floor was seen");
        problems.push(format!(
            "a link is under the floor in {:.0}% of the reached grasp poses (lowest: '{}' at {:.0} mm): see the advice below \
             (the grasp loop redoes such moves)",
            100.0 * under_floor_share,
            robot.model.links[link].name,
            1000.0 * z
        ));
    }
    (under_floor_share, lowest)
}

/// The arm joints at a limit in some of the reached poses, with their share; a problem for each
/// that is there too often.
fn joints_at_limit(robot: &Robot, reached: &[Vec<f64>], problems: &mut Vec<String>) -> Vec<JointAtLimit> {
    let n = reached.len().max(1) as f64;
    let mut joints_at_limit = Vec::new();
    for &j in &robot.arm_joints {
        let joint = &robot.model.joints[j];
        let d = joint.dof.expect("an arm joint has a degree of freedom");
        let at = reached.iter().filter(|q| (q[d] - joint.lower).abs() < AT_LIMIT || (joint.upper - q[d]).abs() < AT_LIMIT).count();
        if at > 0 {
            let share = at as f64 / n;
            if share > MAX_BAD_SHARE {
                problems.push(format!(
                    "arm joint '{}' is at a limit in {:.0}% of the reached grasp poses: the inverse kinematics pins it there; \
                     see the advice below",
                    joint.name,
                    100.0 * share
                ));
            }
            joints_at_limit.push(JointAtLimit { joint: joint.name.clone(), share });
        }
    }
    joints_at_limit
}

/// The jaw check's default tolerance (degrees): the two pads' normals may be this far from opposite
/// where the jaws meet an object (a 20° tilt leaves an antipodal pair inside a friction cone of
/// μ ≈ 0.36 on both sides, the grasp sampler's own bound).
pub const JAW_TOLERANCE_DEG: f64 = 25.0;
/// Closing positions the jaw check steps through, from the preshape to the closing target.
const JAW_SWEEP_STEPS: usize = 40;

/// The jaws at one closing position: the gap between the first two pads (m) and how far their
/// normals are from opposite (degrees), or None when either pad faces away from the other.
fn jaw_at(robot: &Robot, ctx: &GraspContext, hand: &[f64]) -> (f64, Option<f64>) {
    let mut q = ctx.home();
    robot.set_hand(&mut q, hand);
    let poses = robot.model.forward_kinematics(&q);
    let (a, b) = (poses[robot.pads[0].frame], poses[robot.pads[1].frame]);
    let (za, zb) = (a.transform_vector3(DVec3::Z), b.transform_vector3(DVec3::Z));
    let ab = b.translation - a.translation;
    let towards = za.dot(ab) > 0.0 && zb.dot(-ab) > 0.0;
    (ab.length(), towards.then(|| (-za.dot(zb)).clamp(-1.0, 1.0).acos().to_degrees()))
}

/// A parallel-jaw gripper's first two pads, judged over the closing from the preshape to the
/// closing target (fingers that turn face each other only over part of it): the openings (m)
/// where they face within `tolerance_deg`, the gap and angle at the preshape; a problem when they
/// face nowhere. None for other robots.
fn jaws(robot: &Robot, ctx: &GraspContext, rc: &RobotConfig, tolerance_deg: f64, problems: &mut Vec<String>) -> Option<JawReport> {
    if robot.kind != GraspKind::ParallelJaw || robot.pads.len() < 2 {
        return None;
    }
    let open: Vec<f64> = rc.grasp.preshape.iter().map(|&(lo, _)| lo).collect();
    let closed: Vec<f64> = open.iter().zip(&rc.grasp.close).map(|(&o, c)| c.unwrap_or(o)).collect();
    let (gap_m, angle) = jaw_at(robot, ctx, &open);
    let facing: Vec<f64> = (0..=JAW_SWEEP_STEPS)
        .map(|i| i as f64 / JAW_SWEEP_STEPS as f64)
        .map(|t| open.iter().zip(&closed).map(|(o, c)| o + t * (c - o)).collect::<Vec<f64>>())
        .filter_map(|hand| match jaw_at(robot, ctx, &hand) {
            (gap, Some(a)) if a <= tolerance_deg => Some(gap),
            _ => None,
        })
        .collect();
    let band = (!facing.is_empty()).then(|| (facing.iter().copied().fold(f64::MAX, f64::min), facing.iter().copied().fold(0.0, f64::max)));
    if band.is_none() {
        problems.push(format!(
            "pads '{}' and '{}' face each other (normals within {tolerance_deg:.0}° of opposite, --jaw-tolerance-deg) at no opening \
             between the preshape and the closing target: a pad's +z must point out of its jaw at the other pad",
            robot.pads[0].name, robot.pads[1].name
        ));
    }
    Some(JawReport { facing: band.is_some(), gap_m, angle_deg: angle, tolerance_deg, facing_openings_m: band })
}

/// The jaw check's figures.
#[derive(Debug, Clone, Serialize)]
pub struct JawReport {
    /// The pads face each other within the tolerance at some opening of the closing.
    pub facing: bool,
    /// At the preshape: the gap between the pads (m) and their normals' angle from opposite
    /// (degrees; None: a pad faces away).
    pub gap_m: f64,
    pub angle_deg: Option<f64>,
    pub tolerance_deg: f64,
    /// The narrowest and widest opening (m) where they face within the tolerance: objects of those
    /// widths meet facing pads.
    pub facing_openings_m: Option<(f64, f64)>,
}

impl std::fmt::Display for RobotCheckReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "robot {}: {} links ({} mesh files), {} arm joints, {} hand joints, pads {}",
            self.robot,
            self.links,
            self.mesh_files,
            self.arm_joints,
            self.hand_joints,
            self.pads.join(", ")
        )?;
        writeln!(f, "reach: {:.0}% of {} grasp-frame poses from the workspace", 100.0 * self.reach_share, self.poses)?;
        match (&self.lowest_link, self.lowest_link_height_m) {
            (Some(l), Some(z)) => writeln!(
                f,
                "floor: a link under it in {:.0}% of the reached poses (such moves are redone); lowest link '{l}' at {:.0} mm",
                100.0 * self.under_floor_share,
                1000.0 * z
            )?,
            _ => writeln!(f, "floor: no moving link has collision geometry")?,
        }
        if self.joints_at_limit.is_empty() {
            writeln!(f, "joint limits: no arm joint at a limit")?;
        }
        for j in &self.joints_at_limit {
            writeln!(f, "joint limits: '{}' at a limit in {:.0}% of the reached poses", j.joint, 100.0 * j.share)?;
        }
        if let Some(j) = &self.jaws {
            let angle = j.angle_deg.map_or("a pad facing away".to_string(), |a| format!("normals {a:.0}° from opposite"));
            match j.facing_openings_m {
                Some((lo, hi)) => writeln!(
                    f,
                    "jaws: pads face each other within {:.0}° at openings {:.1} to {:.1} mm of the closing; {:.1} mm apart at the preshape ({angle})",
                    j.tolerance_deg,
                    1000.0 * lo,
                    1000.0 * hi,
                    1000.0 * j.gap_m
                )?,
                None => writeln!(
                    f,
                    "jaws: pads do NOT face each other within {:.0}° at any opening of the closing ({angle} at the preshape)",
                    j.tolerance_deg
                )?,
            }
        }
        if self.problems.is_empty() {
            write!(f, "ok: no problem found (next: `vtgen grasps CONFIG --trajectories 2` holds a few objects)")
        } else {
            write!(f, "{} problem(s):", self.problems.len())?;
            for p in &self.problems {
                write!(f, "\n  - {p}")?;
            }
            for a in &self.advice {
                write!(f, "\nadvice: {a}")?;
            }
            Ok(())
        }
    }
}

/// `vtgen robot check`: the report (text or JSON); an error when it found a problem.
pub fn run(cfg: &LoadedConfig, json: bool, jaw_tolerance_deg: f64) -> Result<()> {
    let r = check_robot(cfg, jaw_tolerance_deg)?;
    if json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        println!("{r}");
    }
    anyhow::ensure!(r.problems.is_empty(), "robot check: {} problem(s) found", r.problems.len());
    Ok(())
}

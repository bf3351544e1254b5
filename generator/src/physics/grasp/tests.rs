use glam::{DAffine3, DQuat, DVec3};
use rand_chacha::ChaCha8Rng;
use vt_robot::Robot;

use super::*;
use crate::config::{GraspConfig, PhysicsConfig};
use crate::physics::{PhysicsSettings, RapierHand};
use rand::SeedableRng;

/// The object's physics shape: the real mesh when `YCB_DIR` is set, else the procedural one.
pub fn physics_object(id: &str) -> PhysicsObject {
    let catalog = vt_objects::Catalog::builtin();
    let e = catalog.get(id).unwrap();
    let ycb = std::env::var_os("YCB_DIR").map(std::path::PathBuf::from);
    let (m, _) = crate::assets::catalog_mesh(id, e, ycb.as_deref()).unwrap();
    PhysicsObject { points: m.positions, mass: e.mass }
}

/// The grasp config's defaults with the Allegro hand's joint arrays.
fn allegro_grasp() -> GraspConfig {
    GraspConfig::default().with_robot_defaults(&Robot::default_robot())
}

/// The tomato soup can's procedural mesh, as the scripted hand's tests hold it.
fn procedural_soup_can() -> PhysicsObject {
    PhysicsObject {
        points: vt_objects::procedural_mesh(vt_objects::Catalog::builtin().get("005_tomato_soup_can").unwrap()).positions,
        mass: 0.35,
    }
}

/// The grasp loop's context with the robot base and the camera of `scenes/paper.yaml`, at 240 Hz.
fn paper_context<'a>(robot: &'a Robot, cfg: &'a GraspConfig) -> GraspContext<'a> {
    let t_world_base = DAffine3::from_rotation_translation(DQuat::from_rotation_z(std::f64::consts::PI), DVec3::new(0.0, 0.5, 0.0));
    GraspContext::new(robot, t_world_base, cfg, 1.0 / 240.0, DVec3::new(0.0, -0.75, 0.55))
}

/// An arm move's palm pose (its kind, then its pose) drawn from seed `k`.
fn move_palm(ctx: &GraspContext, k: u64) -> DAffine3 {
    let mut rng = ChaCha8Rng::seed_from_u64(k);
    let kind = ctx.draw_move_kind(&mut rng);
    ctx.sample_move_palm(kind, &mut rng)
}

/// The palm's normal (world) of `n` arm moves drawn with `cfg`.
fn move_normals(cfg: &GraspConfig, n: u64) -> Vec<(DVec3, DVec3)> {
    let robot = Robot::default_robot();
    let ctx = paper_context(&robot, cfg);
    (0..n)
        .map(|k| {
            let t = move_palm(&ctx, k);
            (t.matrix3 * DVec3::X, t.translation)
        })
        .collect()
}

#[test]
fn back_to_camera_moves_turn_the_palm_away_from_the_camera() {
    let mut cfg = GraspConfig { back_to_camera_share: 0.5, ..allegro_grasp() };
    let camera = DVec3::new(0.0, -0.75, 0.55);
    let normals = move_normals(&cfg, 400);
    let (lo, hi) = cfg.back_to_camera_tilt_deg;
    let mut back = 0;
    for (n, p) in &normals {
        assert!((n.length() - 1.0).abs() < 1e-9);
        let tilt = n.z.clamp(-1.0, 1.0).acos().to_degrees();
        if tilt <= cfg.max_tilt_deg + 1e-9 {
            continue;
        }
        // Outside the cone: a back-to-camera move, tilted within its range, away from the
        // camera (the normal's horizontal part points from the camera past the palm).
        back += 1;
        assert!(tilt >= lo - 1e-9 && tilt <= hi + 1e-9, "tilt {tilt}");
        let away = (*p - camera).with_z(0.0).normalize();
        let horizontal = n.with_z(0.0).normalize();
        assert!(horizontal.dot(away) > 0.99, "normal {n} is not turned away from the camera");
        // The camera looks at the back of the hand: the palm normal points along its view.
        assert!(n.dot((*p - camera).normalize()) > 0.0);
    }
    // About half of the moves (binomial, 400 draws: 5 standard deviations either way).
    assert!((150..=250).contains(&back), "{back} of 400 back-to-camera moves");
    // Without the knob no move leaves the cone, and the draws are those of the plain sampler.
    cfg.back_to_camera_share = 0.0;
    let robot = Robot::default_robot();
    let ctx = paper_context(&robot, &cfg);
    for k in 0..50 {
        let a = move_palm(&ctx, k);
        let b = ctx.sample_palm(&mut ChaCha8Rng::seed_from_u64(k));
        assert_eq!(a, b);
        assert!((a.matrix3 * DVec3::X).z >= cfg.max_tilt_deg.to_radians().cos() - 1e-9);
    }
}

/// Every arm joint's fastest turn (rad/s) over the steps of the path from `from` to `to`, and its
/// speed limit.
fn peak_joint_speeds(ctx: &GraspContext, from: &[f64], to: &[f64]) -> Vec<(f64, f64)> {
    let n = ctx.path_steps(from, to);
    let robot = ctx.robot;
    let at = |k: usize| arm_move::along_path(from, to, k as f64 / n as f64);
    robot
        .arm_joints
        .iter()
        .zip(&robot.arm_dofs)
        .map(|(&j, &d)| {
            let fastest = (0..n).map(|k| (at(k + 1)[d] - at(k)[d]).abs() / ctx.timestep).fold(0.0, f64::max);
            (fastest, robot.model.joints[j].velocity)
        })
        .collect()
}

#[test]
fn arm_moves_keep_every_joint_within_its_speed_limit() {
    let robot = Robot::default_robot();
    let cfg = GraspConfig { back_to_camera_share: 0.5, ..allegro_grasp() };
    let ctx = paper_context(&robot, &cfg);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut q = ctx.home();
    let mut moves = Vec::new();
    while moves.len() < 100 {
        let kind = ctx.draw_move_kind(&mut rng);
        if let Some(qt) = ctx.reach(&ctx.sample_move_palm(kind, &mut rng), &q) {
            moves.push((q.clone(), qt.clone()));
            q = qt;
        }
    }
    for (from, to) in &moves {
        for (fastest, limit) in peak_joint_speeds(&ctx, from, to) {
            assert!(limit > 0.0 && fastest <= limit * (1.0 + 1e-9), "a joint turns at {fastest:.2} rad/s, its limit {limit}");
        }
    }
    // The moves the test draws are the kind that needs it: at `move_seconds` alone many would
    // pass a limit, and an episode's moves keep that length.
    let fixed = GraspConfig { arm_speed_limits: false, ..cfg.clone() };
    let fixed_ctx = paper_context(&robot, &fixed);
    let too_fast = moves.iter().filter(|(from, to)| peak_joint_speeds(&fixed_ctx, from, to).iter().any(|(v, limit)| v > limit)).count();
    assert!(too_fast >= 20, "{too_fast} of 100 moves too fast at move_seconds");
    // An episode's moves keep that length and end short of a pose they cannot reach within the
    // limits: on the straight joint-space line to it, its fastest joint at its limit.
    let episode_ctx = GraspContext { record_steps: true, ..paper_context(&robot, &cfg) };
    let mut short = 0;
    for (from, to) in &moves {
        let end = episode_ctx.move_end(from, to);
        assert_eq!(episode_ctx.path_steps(from, &end), fixed_ctx.steps(cfg.move_seconds));
        let speeds = peak_joint_speeds(&episode_ctx, from, &end);
        for &(fastest, limit) in &speeds {
            assert!(fastest <= limit * (1.0 + 1e-9), "an episode's joint turns at {fastest:.2} rad/s, its limit {limit}");
        }
        let share = |k: usize| (end[k] - from[k]) / (to[k] - from[k]);
        let moving: Vec<usize> = (0..to.len()).filter(|&k| (to[k] - from[k]).abs() > 1e-6).collect();
        assert!(moving.iter().all(|&k| (share(k) - share(moving[0])).abs() < 1e-9), "off the line to the drawn pose");
        if end != *to {
            short += 1;
            assert!(speeds.iter().any(|&(fastest, limit)| fastest > 0.99 * limit), "a shortened move not at its limit: {speeds:?}");
        }
    }
    assert_eq!(short, too_fast, "the episode shortens exactly the moves too fast at move_seconds");
    let snapshot = moves.iter().all(|(from, to)| ctx.move_end(from, to) == *to);
    assert!(snapshot, "a snapshot's move ends at its drawn pose");
}

/// A recorded grasp's wrist turn (palm up to the grasp pose, in half the settle) keeps every arm
/// joint within its speed limit: over 12 recorded grasps of the scripted hand, no joint turns
/// faster than its limit between two of the grasp's states; without the limits at least one turn
/// would (the test's grasps are the kind that needs them).
#[test]
fn a_recorded_grasps_wrist_turn_keeps_every_joint_within_its_speed_limit() {
    let robot = Robot::default_robot();
    let object = procedural_soup_can();
    // The largest ratio of an arm joint's speed to its limit between two states up to the settled grasp.
    let fastest_turn = |cfg: &GraspConfig, trajectory: u32| -> f64 {
        let ctx = GraspContext { record_steps: true, recorded_grasp_steps: cfg.grasp_steps(1.0 / 240.0), ..paper_context(&robot, cfg) };
        let key = TrajectoryKey { seed: 5, object_id: "005_tomato_soup_can", trajectory, instances: 1 };
        let t = simulate_trajectory(&ctx, &mut crate::physics::fake::FakeHand::holding(3), &object, key, &mut GraspLog::default()).unwrap();
        let grasp = &t.steps[..=t.settled_step];
        assert!(grasp.len() > 100, "{} states recorded up to the settled grasp", grasp.len());
        robot
            .arm_joints
            .iter()
            .zip(&robot.arm_dofs)
            .flat_map(|(&j, &d)| {
                let limit = robot.model.joints[j].velocity;
                grasp.windows(2).map(move |w| (w[1].q[d] - w[0].q[d]).abs() / ctx.timestep / limit)
            })
            .fold(0.0, f64::max)
    };
    let cfg = allegro_grasp();
    let unlimited = GraspConfig { arm_speed_limits: false, ..cfg.clone() };
    let mut too_fast_without = 0;
    for trajectory in 0..12 {
        let ratio = fastest_turn(&cfg, trajectory);
        assert!(ratio <= 1.0 + 1e-9, "trajectory {trajectory}: a joint turns at {ratio:.2} times its limit");
        too_fast_without += usize::from(fastest_turn(&unlimited, trajectory) > 1.0);
    }
    assert!(too_fast_without >= 3, "{too_fast_without} of 12 wrist turns too fast without the limits");
}

/// A recorded grasp's approach (`sampling.record.approach`): the object stands still in the world
/// while the arm brings the open hand to it from `distance` back along the palm normal, every
/// joint within its speed limit; the grasp then records as without it, the approach's states
/// before it.
#[test]
fn a_recorded_approach_brings_the_open_hand_to_an_object_standing_still() {
    let robot = Robot::default_robot();
    let object = procedural_soup_can();
    let cfg = allegro_grasp();
    let grasp_steps = cfg.grasp_steps(1.0 / 240.0);
    let approach = Approach { steps: 120, distance: 0.06 };
    let ctx = GraspContext {
        record_steps: true,
        recorded_grasp_steps: grasp_steps + approach.steps,
        approach: Some(approach),
        ..paper_context(&robot, &cfg)
    };
    for trajectory in 0..4 {
        let key = TrajectoryKey { seed: 5, object_id: "005_tomato_soup_can", trajectory, instances: 1 };
        let t = simulate_trajectory(&ctx, &mut crate::physics::fake::FakeHand::holding(3), &object, key, &mut GraspLog::default()).unwrap();
        assert_eq!(t.settled_step, grasp_steps + approach.steps);
        // The approach's states and the first of the object put in the hand (the palm up there).
        let came = &t.steps[..=approach.steps];
        let palm = |s: &InstanceState| ctx.t_world_base * s.t_base_palm;
        let object_world = |s: &InstanceState| palm(s) * s.t_palm_object;
        let still = object_world(&came[0]);
        for s in came {
            let o = object_world(s);
            assert!((o.translation - still.translation).length() < 1e-9, "the object moved in the world during the approach");
            assert!(rot(&o).angle_between(rot(&still)) < 1e-6, "the object turned in the world during the approach");
        }
        let (start, end) = (palm(&came[0]), palm(&came[approach.steps]));
        let normal = rot(&end) * DVec3::X;
        let back = end.translation - start.translation;
        assert!((back.dot(normal) - approach.distance).abs() < 1e-3, "the palm starts {:.4} m back", back.dot(normal));
        assert!(back.reject_from(normal).length() < 1e-3, "the palm starts {:?} off its normal's line", back.reject_from(normal));
        // Nearer the object at every state, the joints within their speed limits.
        let gap = |s: &InstanceState| (object_world(s).translation - palm(s).translation).dot(normal);
        assert!(came.windows(2).all(|w| gap(&w[1]) <= gap(&w[0]) + 1e-9), "the palm moved away from the object");
        for (&j, &d) in robot.arm_joints.iter().zip(&robot.arm_dofs) {
            let limit = robot.model.joints[j].velocity;
            assert!(came.windows(2).all(|w| (w[1].q[d] - w[0].q[d]).abs() / ctx.timestep <= limit), "joint {d} too fast");
        }
    }
}

/// The grasp loop over the scripted hand: `cfg` with the paper's robot and camera.
fn run_fake(hand: &mut crate::physics::fake::FakeHand, cfg: &GraspConfig, instances: u32) -> (Result<Trajectory>, Vec<GraspEvent>) {
    let (t, log) = run_fake_screened(hand, cfg, instances, None);
    (t, log.events)
}

/// `run_fake` with the hold screen's mode set (None: the config's), and the whole log.
fn run_fake_screened(
    hand: &mut crate::physics::fake::FakeHand,
    cfg: &GraspConfig,
    instances: u32,
    screen: Option<HoldScreen>,
) -> (Result<Trajectory>, GraspLog) {
    let robot = Robot::default_robot();
    let mut ctx = paper_context(&robot, cfg);
    if let Some(mode) = screen {
        ctx.hold_screen = mode;
    }
    let object = procedural_soup_can();
    let mut log = GraspLog::default();
    let key = TrajectoryKey { seed: 3, object_id: "005_tomato_soup_can", trajectory: 0, instances };
    (simulate_trajectory(&ctx, hand, &object, key, &mut log), log)
}

/// Physics steps from the first attempt's placement to its settled grasp (240 Hz), about.
fn steps_to_settled(cfg: &GraspConfig) -> u64 {
    ((0.15f64 + cfg.close_seconds + cfg.settle_seconds) * 240.0).round() as u64
}

#[test]
fn a_held_object_gives_every_instance_without_slip_and_the_same_key_the_same_trajectory() {
    let cfg = allegro_grasp();
    let robot = Robot::default_robot();
    let mut hand = crate::physics::fake::FakeHand::holding(3);
    let (t, failures) = run_fake(&mut hand, &cfg, 4);
    let t = t.unwrap();
    assert_eq!((t.instances.len(), t.attempts), (4, 1), "{failures:?}");
    let grasped = t.instances[0].t_palm_object;
    for i in &t.instances {
        assert_eq!(i.t_palm_object, grasped);
        assert_eq!((i.slip_translation, i.slip_rotation), (0.0, 0.0));
        assert_eq!(i.contacts.iter().filter(|c| c.is_some()).count(), 3);
        // The recorded hand joints are the physics' (the fake reaches the closing targets).
        for (k, h) in robot.hand.iter().enumerate() {
            if let Some(target) = cfg.close[k] {
                assert_eq!(i.q[h.dof], target, "{}", h.name);
            }
        }
    }
    // Arm moves differ from instance to instance; the same key gives the same trajectory.
    assert_ne!(t.instances[0].t_base_palm, t.instances[1].t_base_palm);
    let (again, _) = run_fake(&mut crate::physics::fake::FakeHand::holding(3), &cfg, 4);
    let again = again.unwrap();
    assert!(t.instances.iter().zip(&again.instances).all(|(a, b)| a.q == b.q && a.t_palm_object == b.t_palm_object));
}

#[test]
fn grasps_that_do_not_hold_fail_each_attempt_and_the_trajectory_names_the_cause() {
    let cfg = GraspConfig { max_attempts: 3, ..allegro_grasp() };
    // The object slides 1 mm per step: more than 2 cm while the hand holds still.
    let mut sliding = crate::physics::fake::FakeHand::holding(3);
    sliding.drift_per_step = DVec3::new(0.0, 0.0, 0.001);
    let (t, failures) = run_fake(&mut sliding, &cfg, 2);
    let e = t.unwrap_err().to_string();
    assert!(e.contains("005_tomato_soup_can trajectory 0: no grasp held in 3 attempts"), "{e}");
    assert!(failures.iter().all(|f| matches!(f, GraspEvent::Failed(Failure::GraspNotHeld | Failure::Unreachable))), "{failures:?}");
    assert!(failures.contains(&GraspEvent::Failed(Failure::GraspNotHeld)));
    // One phalanx alone does not hold an object either.
    let (t, failures) = run_fake(&mut crate::physics::fake::FakeHand::holding(1), &cfg, 2);
    assert!(t.is_err());
    assert!(failures.contains(&GraspEvent::Failed(Failure::GraspNotHeld)), "{failures:?}");
    // A hand that presses into the object never records an instance (1.2 mm: placed, since
    // placement tolerates 1.5 mm, but over the 1 mm a recorded instance may have).
    let mut pressing = crate::physics::fake::FakeHand::holding(3);
    pressing.penetration = 1.2 * cfg.max_penetration;
    let (t, failures) = run_fake(&mut pressing, &cfg, 2);
    assert!(t.is_err());
    assert!(
        failures.contains(&GraspEvent::Redone(Redo::Penetration)) && failures.contains(&GraspEvent::Failed(Failure::Penetration)),
        "{failures:?}"
    );
}

/// A hand's pivoting window that finds no pinch before its first pivot would turn nothing: with
/// `require_pinch` its attempt fails as `NoPinch` at once (another arm move from the same grasp
/// seldom finds one) and the trajectory draws a new grasp; without it the episode is kept
/// unturned. The scripted hand touches the object with the index finger alone, so no thumb pad
/// pinches it, and the window may not place one (`repinches: 0`).
#[test]
fn a_pivot_window_with_no_pinch_to_begin_from_fails_its_attempt_where_a_pinch_is_required() {
    let cfg = GraspConfig { max_attempts: 2, ..allegro_grasp() };
    let robot = Robot::default_robot();
    let index_finger = |link: usize| robot.pads.iter().any(|p| p.link == link && p.name.starts_with("ff_"));
    let run = |require_pinch: bool| {
        let mut ctx = paper_context(&robot, &cfg);
        let pivot = crate::config::PivotConfig { pads: Some(["th_*".into(), "*".into()]), require_pinch, ..Default::default() };
        ctx.pivot = Some(PivotControl::of(&pivot, &robot, 1.0 / 240.0));
        let mut hand = crate::physics::fake::FakeHand::holding(0);
        hand.contacts = robot.touch_links.iter().map(|&l| index_finger(l).then_some(0.0)).collect();
        assert!(hand.contacts.iter().flatten().count() >= robot.min_touching, "the index finger holds the object");
        let mut log = GraspLog::default();
        let key = TrajectoryKey { seed: 3, object_id: "005_tomato_soup_can", trajectory: 0, instances: 2 };
        let t = simulate_trajectory(&ctx, &mut hand, &procedural_soup_can(), key, &mut log);
        (t, log)
    };
    let (t, log) = run(true);
    let e = t.unwrap_err().to_string();
    assert!(e.contains("2 held but had no pinch") && e.contains("require_pinch: false"), "{e}");
    assert_eq!(log.events, [GraspEvent::Failed(Failure::NoPinch); 2]);
    assert_eq!(log.in_hand_ends.get("no_pinch"), Some(&2));
    // Without it, each instance's window ends with no pinch and the trajectory is kept.
    let (t, log) = run(false);
    assert_eq!(t.unwrap().instances.len(), 2, "{:?}", log.events);
    assert!(log.events.is_empty(), "{:?}", log.events);
    assert_eq!(log.in_hand_ends.get("no_pinch"), Some(&2));
}

#[test]
fn a_move_that_drops_the_object_is_undone_and_redrawn() {
    // No hold screen: the drop comes in the first arm move.
    let cfg = GraspConfig { hold_screen: false, ..allegro_grasp() };
    // Steps of placing, resting, closing and settling, then well into the first arm move.
    let mut hand = crate::physics::fake::FakeHand::holding(3);
    hand.drop_at_step = Some(steps_to_settled(&cfg) + 60);
    let (t, failures) = run_fake(&mut hand, &cfg, 3);
    let t = t.unwrap();
    assert_eq!((t.instances.len(), t.attempts), (3, 1));
    assert_eq!(failures, vec![GraspEvent::Redone(Redo::Drop)]);
    // The redone move starts from the state saved before the drop: the object is back in the hand.
    assert!(t.instances.iter().all(|i| i.slip_translation == 0.0));
}

#[test]
fn a_lost_grasp_keeps_its_instances_and_a_new_grasp_records_the_rest_when_asked() {
    // Whole holds and every move `move_seconds` long (no speed limits), so that every instance
    // takes the same steps.
    let whole_holds = GraspConfig { hold_until_still: false, arm_speed_limits: false, ..allegro_grasp() };
    let regrasp = GraspConfig { regrasp_on_loss: true, ..whole_holds.clone() };
    // Each instance is a 0.5 s move and a 0.2 s hold (168 steps); from 60 steps into the third
    // move every try drops the object (each in its first step), so the first grasp is lost after
    // two instances, and the next attempt, placed after that, holds.
    let lost = steps_to_settled(&regrasp) + 2 * 168 + 60;
    let losing = || {
        let mut hand = crate::physics::fake::FakeHand::holding(3);
        hand.drop_between = Some((lost, lost + 4));
        hand
    };
    let (t, log) = run_fake_screened(&mut losing(), &regrasp, 5, None);
    let t = t.unwrap();
    assert_eq!((t.instances.len(), t.attempts), (5, 2));
    assert_eq!(t.instance_grasps, [1, 1, 2, 2, 2]);
    let mut events = vec![GraspEvent::Redone(Redo::Drop); 3];
    events.push(GraspEvent::Failed(Failure::LostDuringMotion));
    assert_eq!(log.events, events);
    // Only the lost grasp's last move and its redraws are thrown away; every step counted once.
    let steps = log.steps;
    assert_eq!(steps.instances_before_failure, 2);
    assert!(steps.failed_attempts < 168, "{steps:?}");
    assert_eq!(steps.total(), steps.failed_attempts + steps.kept + steps.redone_moves);
    assert_eq!(steps.arm_move, 5 * 120 + steps.failed_attempts);
    // By default the trajectory starts over: one grasp holds all of its instances, and the lost
    // grasp's two instances are thrown away with their steps.
    let (t, log) = run_fake_screened(&mut losing(), &whole_holds, 5, None);
    let t = t.unwrap();
    assert_eq!((t.instances.len(), t.attempts, t.instance_grasps), (5, 2, vec![2; 5]));
    assert!(log.steps.failed_attempts > steps_to_settled(&regrasp) + 2 * 168);
}

#[test]
fn a_grasp_that_lets_go_under_a_probe_is_screened_out_before_any_arm_move() {
    // Every move `move_seconds` long (no speed limits): 120 steps each.
    let cfg = GraspConfig { hold_screen: true, arm_speed_limits: false, ..allegro_grasp() };
    // The object flies out early in the first probe (once).
    let drop_at = steps_to_settled(&cfg) + 10;
    let dropping = || {
        let mut hand = crate::physics::fake::FakeHand::holding(3);
        hand.drop_at_step = Some(drop_at);
        hand
    };
    let (t, log) = run_fake_screened(&mut dropping(), &cfg, 3, None);
    let t = t.unwrap();
    assert_eq!((t.instances.len(), t.attempts), (3, 2));
    assert_eq!(log.events, vec![GraspEvent::Failed(Failure::HoldScreen)]);
    let steps = log.steps;
    assert_eq!(steps.screened_out, 1);
    // Acting on its verdicts, the screen judges nothing.
    assert_eq!(steps.screen_judged, ScreenJudged::default());
    // The screened-out attempt spent no arm move: it ended in the probe that lost the object.
    assert_eq!(steps.failed_attempts, drop_at);
    assert_eq!(steps.instances_before_failure, 0);
    // Every step is counted once, under its phase; the kept attempt's 4 probes (0.2 s turn, 0.1 s
    // hold) are wasted.
    let kept_probes = 4 * (48 + 24);
    assert_eq!(steps.total(), steps.failed_attempts + steps.kept + steps.redone_moves + kept_probes);
    assert_eq!(steps.wasted(), steps.failed_attempts + kept_probes);
    assert_eq!(steps.arm_move, 3 * 120);
    // Judging only, the attempt goes on from the settled state the probes left, and the verdict
    // is counted against its outcome.
    let (t, log) = run_fake_screened(&mut dropping(), &cfg, 3, Some(HoldScreen::Judge));
    assert_eq!(t.unwrap().attempts, 1);
    assert_eq!(log.steps.screen_judged, ScreenJudged { failed_held: 1, ..Default::default() });
    assert_eq!(log.steps.screened_out, 0);
    // Without it, no probe is run.
    let (t, log) = run_fake_screened(&mut crate::physics::fake::FakeHand::holding(3), &cfg, 3, Some(HoldScreen::Off));
    assert_eq!(t.unwrap().attempts, 1);
    assert_eq!(log.steps.screen, 0);
}

#[test]
fn a_snapshot_hold_ends_once_the_object_has_stopped() {
    use crate::physics::fake::FakeHand;
    let until_still = GraspConfig { hold_until_still: true, ..allegro_grasp() };
    // A still object: each hold ends when the 50 ms window (12 steps at 240 Hz) first compares
    // two poses, 13 steps in, instead of lasting 0.2 s (48 steps).
    let (t, log) = run_fake_screened(&mut FakeHand::holding(3), &until_still, 3, None);
    assert_eq!(t.unwrap().instances.len(), 3);
    assert_eq!(log.steps.hold, 3 * 13);
    let whole_hold = GraspConfig { hold_until_still: false, ..allegro_grasp() };
    let (_, log) = run_fake_screened(&mut FakeHand::holding(3), &whole_hold, 3, None);
    assert_eq!(log.steps.hold, 3 * 48);
    // An object sliding 0.1 mm per step (24 mm/s) has not stopped: the whole hold.
    let mut sliding = FakeHand::holding(3);
    sliding.drift_per_step = DVec3::new(0.0, 0.0, 1e-4);
    let (t, log) = run_fake_screened(&mut sliding, &until_still, 3, None);
    assert_eq!(t.unwrap().instances.len(), 3);
    assert_eq!(log.steps.hold, 3 * 48);
}

#[test]
fn the_hold_screen_probes_the_extremes_the_arm_moves_draw_from() {
    let robot = Robot::default_robot();
    let cfg = GraspConfig { back_to_camera_share: 0.5, ..allegro_grasp() };
    let ctx = paper_context(&robot, &cfg);
    let probes = ctx.probe_gravities();
    assert_eq!(probes.len(), 8);
    // Angle of each probe's gravity from the palm-up settle's: the cone's edge, then the
    // back-to-camera tilts at both ends.
    let from_up: Vec<f64> = probes.iter().map(|g| g.angle_between(PALM_UP_GRAVITY).to_degrees()).collect();
    for (k, want) in [50.0, 50.0, 50.0, 50.0, 80.0, 80.0, 120.0, 120.0].into_iter().enumerate() {
        assert!((from_up[k] - want).abs() < 1e-6, "probe {k}: {} deg from up, want {want}", from_up[k]);
        assert!((probes[k].length() - 9.81).abs() < 1e-9);
    }
    // Every probe is an apparent gravity the move sampler's draws come near: within 10 deg of one
    // of 4000 drawn moves.
    let drawn: Vec<DVec3> = (0..4000).map(|k| move_palm(&ctx, k)).map(|t| DQuat::from_mat3(&t.matrix3).inverse() * GRAVITY).collect();
    for (k, g) in probes.iter().enumerate() {
        let nearest = drawn.iter().map(|d| d.angle_between(*g).to_degrees()).fold(180.0, f64::min);
        assert!(nearest < 10.0, "probe {k} is {nearest} deg from every drawn move");
    }
    // Without back-to-camera moves only the cone's edge is probed.
    let cone_only = GraspConfig { back_to_camera_share: 0.0, ..cfg.clone() };
    assert_eq!(paper_context(&robot, &cone_only).probe_gravities().len(), 4);
}

#[test]
fn both_built_in_robots_reach_the_paper_workspace() {
    // The robots the binary carries (the Panda, built from its upstream files, has its own
    // tests where they are fetched: tests/panda.rs).
    for name in vt_robot::BUILTIN_ROBOTS.into_iter().filter(|&n| vt_robot::Robot::builtin(n).is_ok()) {
        let robot = Robot::builtin(name).unwrap();
        let cfg = GraspConfig::default().with_robot_defaults(&robot);
        let ctx = paper_context(&robot, &cfg);
        let share = reachable_share(&ctx, REACH_SAMPLES);
        eprintln!("{name}: {:.0}% of {REACH_SAMPLES} workspace poses reached", 100.0 * share);
        assert!(share >= 0.9, "{name}: {share}");
    }
}

#[test]
fn the_simulated_hand_starts_at_its_preshape_not_at_the_urdfs_zero() {
    let robot = Robot::default_robot();
    let settings = PhysicsSettings::from(&PhysicsConfig::default());
    let mut hand = RapierHand::new(&robot, settings).unwrap();
    let pre: Vec<f64> = robot.hand.iter().map(|h| 0.5 * (h.preshape.0 + h.preshape.1) + 0.1).collect();
    // The object far away: nothing touches the hand.
    hand.reset(&physics_object("009_gelatin_box"), DAffine3::from_translation(DVec3::new(1.0, 0.0, 0.0)), &pre).unwrap();
    hand.set_targets(&pre);
    hand.set_gravity(DVec3::ZERO);
    // Where the joints are before and after the first step: at the preshape, not at 0.
    for _ in 0..2 {
        for ((got, want), h) in hand.joint_positions().iter().zip(&pre).zip(&robot.hand) {
            let want = want.clamp(robot.model.joints[h.joint].lower, robot.model.joints[h.joint].upper);
            assert!((got - want).abs() < 0.02, "{}: {got} vs the preshape {want}", h.name);
        }
        hand.step();
    }
}

#[test]
fn a_link_under_the_floor_is_found_and_named() {
    let robot = Robot::default_robot();
    let mut q = robot.model.zero();
    for (&d, &v) in robot.arm_dofs.iter().zip(&robot.home) {
        q[d] = v;
    }
    let (link, z) = robot_floor_clearance(&robot, &DAffine3::IDENTITY, &q).unwrap();
    // Lowered by 2 m, the same link is 2 m lower: under the floor.
    let (low, zl) = robot_floor_clearance(&robot, &DAffine3::from_translation(DVec3::new(0.0, 0.0, -2.0)), &q).unwrap();
    assert_eq!(link, low);
    assert!((z - 2.0 - zl).abs() < 1e-9 && zl < 0.0, "{z} {zl}");
    // The base, fixed to the floor, does not count: the lowest link is one the arm moves.
    assert!(robot.model.is_below(link, robot.model.joints[robot.arm_joints[0]].child), "{}", robot.model.links[link].name);
}

#[test]
fn event_names_are_the_ones_earlier_datasets_count_under() {
    // Literal names: datasets carry them (`grasp_stats.failures`), so a renamed variant must not
    // rename them.
    use Failure::*;
    let names = [
        (GraspEvent::Failed(InitialOverlap), "InitialOverlap"),
        (GraspEvent::Failed(GraspNotHeld), "GraspNotHeld"),
        (GraspEvent::Failed(LostDuringMotion), "LostDuringMotion"),
        (GraspEvent::Failed(TooFewContacts), "TooFewContacts"),
        (GraspEvent::Failed(Penetration), "Penetration"),
        (GraspEvent::Failed(TouchesFloor), "TouchesFloor"),
        (GraspEvent::Failed(Unreachable), "Unreachable"),
        (GraspEvent::Failed(NoAntipodalPair), "NoAntipodalPair"),
        (GraspEvent::Failed(HoldScreen), "HoldScreen"),
        (GraspEvent::Failed(ApproachBlocked), "ApproachBlocked"),
        (GraspEvent::Failed(NoPinch), "NoPinch"),
        (GraspEvent::Redone(Redo::Penetration), "MoveRedoneForPenetration"),
        (GraspEvent::Redone(Redo::Contacts), "MoveRedoneForContacts"),
        (GraspEvent::Redone(Redo::Floor), "MoveRedoneForFloor"),
        (GraspEvent::Redone(Redo::Drop), "MoveRedoneForDrop"),
    ];
    for (event, name) in names {
        assert_eq!(event.name(), name);
    }
}

/// An arm move's target is drawn again, before any physics, where it would put the held object
/// (where it lies in the palm) on the floor: a large plate that the fake hand keeps where it is is
/// never moved onto the floor, where a good share of the drawn moves would put it.
#[test]
fn move_targets_that_put_the_held_object_on_the_floor_are_drawn_again() {
    use super::floor::MIN_FLOOR_CLEARANCE;
    let robot = Robot::default_robot();
    // Tilt-cone moves only: turned back to the camera (palm sideways) the plate reaches the floor
    // wherever the palm is.
    let cfg = allegro_grasp();
    let ctx = paper_context(&robot, &cfg);
    // A plate 0.6 m square and 1 cm thick, put flat on the palm: tilted, it reaches far below it.
    let corner =
        |k: usize| [if k & 1 == 0 { -0.3 } else { 0.3 }, if k & 2 == 0 { -0.3 } else { 0.3 }, if k & 4 == 0 { -0.005 } else { 0.005 }];
    let plate = PhysicsObject { points: (0..8).map(corner).collect(), mass: 0.3 };
    let mut hand = crate::physics::fake::FakeHand::holding(3);
    let mut log = GraspLog::default();
    let key = TrajectoryKey { seed: 5, object_id: "plate", trajectory: 0, instances: 40 };
    let t = simulate_trajectory(&ctx, &mut hand, &plate, key, &mut log).unwrap();
    let floor_redos = log.events.iter().filter(|e| matches!(e, GraspEvent::Redone(Redo::Floor))).count();
    assert_eq!(floor_redos, 0, "moves redone with the plate on the floor: {:?}", log.events);
    // The moves a grasp like this one draws, had they not been drawn again.
    let (held, q) = (t.instances[0].t_palm_object, &t.instances[0].q);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let (mut drawn, mut on_floor) = (0, 0);
    while drawn < 200 {
        let kind = ctx.draw_move_kind(&mut rng);
        if let Some(qt) = ctx.reach(&ctx.sample_move_palm(kind, &mut rng), q) {
            drawn += 1;
            let t_world_plate = ctx.t_world_base * robot.grasp_frame_pose(&qt) * held;
            on_floor += (floor_clearance(&plate.points, &t_world_plate) < MIN_FLOOR_CLEARANCE) as usize;
        }
    }
    assert!(on_floor >= 20, "only {on_floor} of {drawn} drawn moves put the plate on the floor: the test shows nothing");
}

/// An arm that wandered into a branch of its solutions where most moves put a link under the floor
/// (the shoulder turned under; a pose a `scenes/paper.yaml` trajectory reached at its 44th
/// instance) is brought back by a move drawn from its home, where every draw from its own pose
/// fails: the grasp is not ended for an unreachable move.
#[test]
fn an_arm_whose_moves_all_reach_under_the_floor_is_moved_back_towards_home() {
    use super::floor::robot_floor_clearance;
    let robot = Robot::default_robot();
    let cfg = allegro_grasp();
    let ctx = paper_context(&robot, &cfg);
    let mut q = ctx.home();
    let under = [1.9614, -3.3902, 2.0405, 0.8219, 4.8993, -4.9478];
    for (&d, v) in robot.arm_dofs.iter().zip(under) {
        q[d] = v;
    }
    // A 4 cm cube in the palm: its floor clearance never decides.
    let cube: Vec<[f32; 3]> = (0..8).map(|k| [[0.0, 0.04][k & 1], [-0.02, 0.02][(k >> 1) & 1], [-0.02, 0.02][(k >> 2) & 1]]).collect();
    let held = DAffine3::from_translation(DVec3::new(0.04, 0.0, 0.05));
    let above_floor = |qt: &[f64]| robot_floor_clearance(&robot, &ctx.t_world_base, qt).is_none_or(|(_, z)| z >= 0.0);
    const MOVES: u64 = 400;
    let mut stuck = 0;
    for seed in 0..MOVES {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let from_here = ctx.draw_move_target_from(&q, &q, &held, &cube, &mut rng.clone());
        let qt = ctx.draw_move_target(&q, &held, &cube, &mut rng).expect("a move is drawn");
        assert!(above_floor(&qt), "seed {seed}: a link under the floor at {qt:?}");
        match from_here {
            // The same draws as before where the arm's own pose gives one.
            Some(here) => assert_eq!(here, qt),
            None => {
                stuck += 1;
                // The home branch: the shoulder back above the base, as at home.
                let shoulder = robot.arm_dofs[1];
                assert!((qt[shoulder] - ctx.home()[shoulder]).abs() < 1.5, "seed {seed}: shoulder at {}", qt[shoulder]);
            }
        }
    }
    // About 2 % of the moves from this pose find no draw above the floor from it.
    assert!(stuck >= 2, "only {stuck} of {MOVES} moves were stuck: the test shows nothing");
}

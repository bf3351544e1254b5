//! Episodes (`sampling.record`): `scenes/tiny-episode.yaml` records each trajectory of the Allegro
//! hand as one episode, the camera at 30 Hz, the pads at 60 Hz (optical images on the distal
//! pads) and the state at every physics step. Every stream has its configured count and times, the
//! ground truth holds on every frame and every touch reading, and the episodes are deterministic.

use std::path::Path;
use std::sync::OnceLock;

use rapier3d::parry::query::PointQuery;
use vt_dataset::DatasetReader;

use crate::common::*;
use crate::own_robot::{generated, object_meshes, shard_job_matches, tactile_points_lie_on_the_object_within_their_pad};

fn episode_dataset() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| generated(&root().join("scenes/tiny-episode.yaml"))).path()
}

/// The `episode` entry of a shard's metadata.
fn episode_of(meta: &vt_dataset::ShardMeta) -> vt_dataset::EpisodeRecord {
    serde_json::from_str(&meta.extra[vt_dataset::EPISODE_METADATA_KEY]).expect("episode metadata is the episode record")
}

#[test]
fn every_stream_of_an_episode_is_at_its_rate_and_its_ground_truth_holds_on_every_frame() {
    let dir = episode_dataset();
    let ds = DatasetReader::open(dir).unwrap();
    let meshes = object_meshes(dir);
    let (mut episodes, mut between) = (0, 0);
    for split in ["train", "test"] {
        for shard in ds.shards(split).unwrap() {
            let e = episode_of(shard.meta());
            let (frames, cam, tac, state) = (e.frames, e.camera_period_steps, e.tactile_period_steps, e.state_period_steps);
            // 30 Hz camera, 60 Hz touch, every physics step of 0.0041667 s.
            assert_eq!((cam, tac, state), (8, 4, 1), "{e:?}");
            assert!((e.camera_hz - 30.0).abs() < 0.01 && (e.tactile_hz - 60.0).abs() < 0.01);
            let steps = (e.duration_s / 0.0041667).round() as u64;
            assert_eq!(frames, steps / cam + 1);
            assert_eq!(shard.len() as u64, frames);
            let time = |step: u64| (step as f64 * 0.0041667 * 1e9).round() as u64;
            let (mut touch_times, mut state_times) = (Vec::new(), Vec::new());
            let mut reference: Option<Vec<Vec<u8>>> = None;
            for (k, index) in shard.indices().enumerate() {
                let s = shard.read(index).unwrap();
                let ep = s.episode.as_ref().expect("an episode frame");
                let frame = s.info.episode.expect("the frame's place in its episode");
                assert_eq!((frame.frame, s.info.instance, ep.time_ns), (k as u32, k as u32, time(k as u64 * cam)));
                assert!((frame.time_s - k as f64 * cam as f64 * 0.0041667).abs() < 1e-9);
                // The frame's own instant: its touch is the sample's, its state the first one.
                touch_times.push(ep.time_ns);
                let (t0, first) = &ep.states[0];
                assert_eq!(*t0, ep.time_ns);
                assert!((first.t_camera_object.translation() - s.t_camera_object.translation()).length() < 1e-9);
                assert_eq!(first.links_in_contact, s.info.links_in_contact());
                state_times.extend(ep.states.iter().map(|(t, _)| *t));
                // The touch between frames, on the object where the state then puts it.
                for (t, touch) in &ep.tactile {
                    touch_times.push(*t);
                    let (_, st) = ep.states.iter().rev().find(|(ts, _)| ts <= t).expect("a state at every touch");
                    for p in &touch.points {
                        let q = st.t_camera_object.inverse().transform_point(glam::Vec3::from(p.position).as_dvec3());
                        let d = meshes[s.info.object_index as usize].distance_to_local_point(q.as_vec3(), false);
                        assert!(d <= 1e-3, "{split} frame {k}: a touch point at {t} ns is {:.2} mm off the surface", d * 1e3);
                        between += 1;
                    }
                }
                // Episodes store the depth on the 2^-14 m grid (`output.depth_grid: auto`): the
                // ground-truth checks below hold on it.
                assert!(
                    s.depth.iter().filter(|d| d.is_finite() && **d > 0.0).all(|d| (d * 16384.0).fract() == 0.0),
                    "{split} frame {k}: a depth off the 2^-14 m grid"
                );
                // Four optical fingertips, one sensor unit (and reference) for the whole episode.
                let tac_data = s.tactile.as_ref().expect("touch");
                let refs: Vec<Vec<u8>> = tac_data.optical.iter().map(|o| o.reference.clone()).collect();
                assert_eq!(refs.len(), 4);
                assert_eq!(reference.get_or_insert_with(|| refs.clone()), &refs, "{split} frame {k}: the reference changed");
            }
            assert_eq!(touch_times, (0..=steps / tac).map(|j| time(j * tac)).collect::<Vec<_>>(), "{split}: touch times");
            assert_eq!(state_times, (0..=steps / state).map(|j| time(j * state)).collect::<Vec<_>>(), "{split}: state times");
            episodes += 1;
        }
    }
    assert_eq!(episodes, 4);
    assert!(between > 1000, "{between} touch points between frames");
    crate::ground_truth::check_dataset(dir, 232);
    tactile_points_lie_on_the_object_within_their_pad(dir);
    let o = run(&["validate", dir.to_str().unwrap(), "--full"]);
    assert!(o.status.success(), "{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o));
}

#[test]
fn episodes_are_deterministic_and_a_shard_job_writes_the_same_bytes() {
    shard_job_matches(&root().join("scenes/tiny-episode.yaml"), 1, episode_dataset());
}

#[test]
fn rates_that_do_not_fit_the_physics_step_are_refused_with_the_field() {
    let cfg = root().join("scenes/tiny-episode.yaml");
    for (set, field, message) in [
        ("sampling.record.camera_hz=29", "sampling.record.camera_hz", "not a whole number of physics steps"),
        ("sampling.record.tactile_hz=40", "sampling.record.tactile_hz", "whole multiple of camera_hz"),
        ("sampling.record.state_hz=30", "sampling.record.state_hz", "whole multiple of tactile_hz"),
        ("sampling.record.camera_hz=0", "sampling.record.camera_hz", "out of range"),
    ] {
        let d = tempdir();
        let o = run_generate(&cfg, d.path(), &["--set", set]);
        let e = stderr(&o);
        assert!(!o.status.success() && e.contains(field) && e.contains(message), "{set}: {e}");
    }
}

/// A scripted finger motion: the listed joints swing after each arm move while the arm stands
/// still, the episode grows by `cycles · period` per move, and the ground truth still holds.
#[test]
fn a_finger_motion_moves_the_fingers_and_keeps_the_ground_truth() {
    let cfg = root().join("scenes/tiny-episode.yaml");
    let d = tempdir();
    let motion = "sampling.record.finger_motion={period_s: 0.25, cycles: 2, joints: [{joint: ff_joint_1, amplitude_deg: 20}, \
                  {joint: th_joint_2, amplitude_deg: 20, phase_deg: 180}]}";
    let o = run(&[
        "generate",
        cfg.to_str().unwrap(),
        "--out",
        d.path().to_str().unwrap(),
        "--quiet",
        "--set",
        "objects=[005_tomato_soup_can]",
        "--set",
        "sampling.trajectories_per_object=1",
        "--set",
        motion,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let ds = DatasetReader::open(d.path()).unwrap();
    let shard = &ds.shards("train").unwrap()[0];
    let e = episode_of(shard.meta());
    // Two moves of the plain episode's 1.90 s, each 0.5 s longer.
    assert!((e.duration_s - 2.90).abs() < 0.01, "{e:?}");
    let mut ff = Vec::new();
    for index in shard.indices() {
        let s = shard.read(index).unwrap();
        for (_, st) in &s.episode.as_ref().unwrap().states {
            ff.push(st.joint_positions["ff_joint_1"]);
        }
    }
    let (lo, hi) = ff.iter().fold((f64::MAX, f64::MIN), |(l, h), v| (l.min(*v), h.max(*v)));
    // The index finger follows its ±20° swing in part: the object stops it closing and the
    // joint's PD drive lags a 0.25 s period (3.7° measured, against 1.2° without the swing).
    assert!(hi - lo > 2.5f64.to_radians(), "ff_joint_1 moved {:.1}°", (hi - lo).to_degrees());
    let o = run(&["validate", d.path().to_str().unwrap(), "--full"]);
    assert!(o.status.success(), "{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o));
    // A joint that is not the hand's is refused with the field.
    let o =
        run(&["plan", cfg.to_str().unwrap(), "--set", "sampling.record.finger_motion={joints: [{joint: elbow_joint, amplitude_deg: 10}]}"]);
    let e = stderr(&o);
    assert!(
        !o.status.success() && e.contains("sampling.record.finger_motion.joints") && e.contains("'elbow_joint' is not a hand joint"),
        "{e}"
    );
}

/// `output.depth_grid`: `exact` keeps the rasterizer's floats in an episode; bits out of range are
/// refused with the field.
#[test]
fn the_depth_grid_is_the_configs() {
    let d = tempdir();
    let args = ["--set", "output.depth_grid=exact", "--set", "sampling.trajectories_per_object=1", "--set", "sampling.record.camera_hz=30"];
    generate(&root().join("scenes/tiny-episode.yaml"), d.path(), &args);
    let ds = DatasetReader::open(d.path()).unwrap();
    let s = ds.samples("train").unwrap().next().unwrap().unwrap();
    let off_grid = s.depth.iter().filter(|d| d.is_finite() && **d > 0.0 && (**d * 16384.0).fract() != 0.0).count();
    assert!(off_grid > 1000, "exact depth: only {off_grid} values off the grid");
    let o = run_generate(&root().join("scenes/tiny-episode.yaml"), &d.path().join("bad"), &["--set", "output.depth_grid=30"]);
    assert!(!o.status.success() && stderr(&o).contains("output.depth_grid") && stderr(&o).contains("30"), "{}", stderr(&o));
}

/// `vtgen inspect` gives each episode's in-hand rotation: the object's turn in the palm's frame
/// from its first camera frame, at its last and at its largest, recomputed here from the frames.
#[test]
fn inspect_reports_each_episodes_in_hand_rotation() {
    let dir = episode_dataset();
    let o = run(&["inspect", dir.to_str().unwrap(), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let reported = report["in_hand_rotation_deg"].as_array().expect("episodes report their rotation");
    assert_eq!(reported.len(), 4);
    let ds = DatasetReader::open(dir).unwrap();
    for split in ["train", "test"] {
        for shard in ds.shards(split).unwrap() {
            let in_palm: Vec<glam::DQuat> = shard
                .indices()
                .map(|i| {
                    let info = shard.read_sample_info(i).unwrap();
                    let palm = info.robot.as_ref().unwrap().t_world_palm.rotation();
                    palm.inverse() * info.t_world_camera.rotation() * info.t_camera_object.rotation()
                })
                .collect();
            let turned: Vec<f64> =
                in_palm.iter().map(|q| (*q * in_palm[0].inverse()).angle_between(glam::DQuat::IDENTITY).to_degrees()).collect();
            let info = shard.read_sample_info(shard.indices().next().unwrap()).unwrap();
            let entry = reported
                .iter()
                .find(|e| e["split"] == split && e["object_id"] == info.object_id.as_str() && e["trajectory"] == info.trajectory)
                .expect("the episode is reported");
            let (last, largest) = (turned[turned.len() - 1], turned.iter().cloned().fold(0.0, f64::max));
            assert!((entry["last_deg"].as_f64().unwrap() - last).abs() < 1e-6, "{entry} vs {last}");
            assert!((entry["largest_deg"].as_f64().unwrap() - largest).abs() < 1e-6, "{entry} vs {largest}");
        }
    }
    assert!(
        String::from_utf8_lossy(&run(&["inspect", dir.to_str().unwrap()]).stdout).contains("in-hand     the object's rotation in the palm")
    );
}

/// Per object, what `vtgen grasps CONFIG ARGS` reports.
fn grasp_report(config: &Path, args: &[&str]) -> Vec<serde_json::Value> {
    let mut all = vec!["grasps", config.to_str().unwrap(), "--json", "--quiet"];
    all.extend_from_slice(args);
    let o = run(&all);
    assert!(o.status.success(), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    report["objects"].as_array().unwrap().clone()
}

/// Per object, the median over its episodes of the largest in-hand rotation (degrees) that
/// `vtgen grasps CONFIG ARGS` reports.
fn median_in_hand_rotation(config: &Path, args: &[&str]) -> Vec<f64> {
    grasp_report(config, args)
        .iter()
        .map(|o| {
            let episodes = o["in_hand_rotation_deg"].as_array().unwrap();
            let mut largest: Vec<f64> = episodes.iter().map(|e| e["largest_deg"].as_f64().unwrap()).collect();
            assert!(!largest.is_empty(), "no episodes");
            largest.sort_by(f64::total_cmp);
            largest[largest.len() / 2]
        })
        .collect()
}

/// Gravity pivoting (`sampling.record.pivot`, `scenes/tiny-pivot.yaml`): the gripper turns the
/// object between its jaws far more than arm moves alone do (the physics-only `vtgen grasps`
/// figures over six episodes per object, with and without), a generated pivoting episode keeps
/// its ground truth on every frame and every touch point on the object, and the pivot is refused
/// with its field for a hand without the pads of its pinch. An episode's turn target
/// (`sampling.record.turn_target_deg`) ends the pivoting: the episodes turn less than without one,
/// most windows reach it and `vtgen grasps` counts them, and each sample names its episode's target. The
/// gripper's grasp records as the hand's does (`sampling.record.grasp`).
#[test]
fn gravity_pivoting_turns_the_object_between_the_jaws_and_keeps_the_ground_truth() {
    let cfg = root().join("scenes/tiny-pivot.yaml");
    let pivoting = median_in_hand_rotation(&cfg, &["--trajectories", "6"]);
    let still = median_in_hand_rotation(&cfg, &["--trajectories", "6", "--set", "sampling.record.pivot=null"]);
    for (p, s) in pivoting.iter().zip(&still) {
        assert!(*p >= 30.0 && *p >= 3.0 * s, "median largest in-hand rotation {p:.1}° pivoting against {s:.1}° without");
    }
    // A 4 s window: within the UR5e's speed limits the first wrist turn (the palm turned over)
    // takes 1.1-1.4 s, and in 3 s a pivot that stopped the object short of its target has no time
    // left to ease again (2 of 6 gelatin-box windows).
    let targeted = grasp_report(
        &cfg,
        &["--trajectories", "6", "--set", "sampling.record.turn_target_deg=[15, 15]", "--set", "sampling.record.pivot.seconds=4"],
    );
    for (o, p) in targeted.iter().zip(&pivoting) {
        // Every window counted by how it ended, the target in most of them: a pivot whose grip
        // tightened ahead of the target and stopped the object short eases again (without that,
        // the gelatin box stopped 2-6° short in 5 of 6 windows).
        assert!(o["in_hand_ends"]["target"].as_u64().unwrap_or(0) >= 4, "{}", o["in_hand_ends"]);
        let episodes = o["in_hand_rotation_deg"].as_array().unwrap();
        let mut largest: Vec<f64> = episodes.iter().map(|e| e["largest_deg"].as_f64().unwrap()).collect();
        largest.sort_by(f64::total_cmp);
        assert!(episodes.iter().all(|e| e["target_deg"].as_f64() == Some(15.0)), "{episodes:?}");
        assert!(largest[largest.len() / 2] < *p, "with a 15° target {largest:?}, without {p:.1}° (median)");
        assert!(largest.iter().any(|&l| l >= 13.0), "no episode reached its 15° target: {largest:?}");
    }

    let d = tempdir();
    let args = ["--set", "objects=[005_tomato_soup_can]", "--set", "sampling.trajectories_per_object=1"];
    // The jaws' grasp recorded too: the object floats still between the open jaws, they close,
    // the wrist turns.
    let recorded = ["--set", "sampling.record.turn_target_deg=[40, 40]", "--set", "sampling.record.grasp=true"];
    generate(&cfg, d.path(), &[&args[..], &recorded].concat());
    let ds = DatasetReader::open(d.path()).unwrap();
    let shard = &ds.shards("train").unwrap()[0];
    let target = shard.read_sample_info(shard.indices().next().unwrap()).unwrap().robot.unwrap().turn_target_deg;
    assert_eq!(target, Some(40.0));
    let e = episode_of(shard.meta());
    // The grasp (1.13 s), one arm move of 0.95 s (move, hold, settle window) and its 3 s pivoting
    // window.
    assert!((e.duration_s - e.settled_s.unwrap() - 3.95).abs() < 0.01 && e.settled_s > Some(1.1), "{e:?}");
    crate::ground_truth::check_dataset(d.path(), e.frames as usize);
    tactile_points_lie_on_the_object_within_their_pad(d.path());
    let o = run(&["inspect", d.path().to_str().unwrap(), "--json"]);
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let largest = report["in_hand_rotation_deg"][0]["largest_deg"].as_f64().unwrap();
    assert!(largest >= 20.0, "the pivoting episode turned the can {largest:.1}° in the palm");

    let o = run(&["plan", root().join("scenes/tiny-episode.yaml").to_str().unwrap(), "--set", "sampling.record.pivot={}"]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("sampling.record.pivot.pads") && e.contains("not a parallel-jaw gripper"), "{e}");
    let o = run(&["plan", cfg.to_str().unwrap(), "--set", "sampling.record.pivot.step_deg=[0, 10]"]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("sampling.record.pivot.step_deg"), "{e}");
    let o = run(&["plan", cfg.to_str().unwrap(), "--set", "sampling.record.turn_target_deg=[30, 200]"]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("sampling.record.turn_target_deg"), "{e}");
    let o =
        run(&["plan", cfg.to_str().unwrap(), "--set", "sampling.record.pivot=null", "--set", "sampling.record.turn_target_deg=[30, 60]"]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("sampling.record.turn_target_deg") && e.contains("needs a controller"), "{e}");
}

/// One episode of the tomato soup can with `record` (a `--set` of `sampling.record`, a 3 s in-hand
/// window): one arm move of 0.95 s and its window long, its ground truth on every frame and every
/// touch point on the object within its pad.
fn one_soup_can_episode_keeps_its_ground_truth(cfg: &Path, record: &str) {
    let d = one_soup_can_episode(cfg, record);
    let ds = DatasetReader::open(d.path()).unwrap();
    let e = episode_of(ds.shards("train").unwrap()[0].meta());
    assert!((e.duration_s - 3.95).abs() < 0.01, "{e:?}");
    crate::ground_truth::check_dataset(d.path(), e.frames as usize);
    tactile_points_lie_on_the_object_within_their_pad(d.path());
}

/// One episode of one arm move of the tomato soup can with `record` (a `--set` of
/// `sampling.record`), generated.
fn one_soup_can_episode(cfg: &Path, record: &str) -> tempfile::TempDir {
    one_soup_can_episode_with(cfg, &[record])
}

/// `one_soup_can_episode` with several `--set`s of `sampling.record`.
fn one_soup_can_episode_with(cfg: &Path, records: &[&str]) -> tempfile::TempDir {
    let d = tempdir();
    let mut args = vec![
        "--set",
        "objects=[005_tomato_soup_can]",
        "--set",
        "sampling.trajectories_per_object=1",
        "--set",
        "sampling.instances_per_trajectory=1",
    ];
    for record in records {
        args.extend(["--set", record]);
    }
    generate(cfg, d.path(), &args);
    d
}

/// Finger gaiting (`sampling.record.finger_roll.regrasp`) on the Allegro hand: with the fingers
/// lifted, moved back and placed again whenever a joint has moved its most, the same roll turns
/// the object further than without (the physics-only `vtgen grasps` figures over six 6 s windows
/// per object); a generated gaiting episode keeps its length, its ground truth on every frame and
/// every touch point on the object; bad regrasp settings are refused with their field.
#[test]
fn finger_gaiting_turns_the_object_further_than_the_roll_and_keeps_the_ground_truth() {
    let cfg = root().join("scenes/tiny-episode.yaml");
    let roll = "sampling.record={camera_hz: 30, tactile_hz: 60, finger_roll: {seconds: 6, axis: [0, 0, 1], \
                joints: [{joint: ff_joint_0}, {joint: mf_joint_0}, {joint: rf_joint_0}]}}";
    let gait = roll.replace("}]}}", "}], regrasp: {}}}");
    let episodes = ["--trajectories", "6", "--instances", "1", "--set"];
    let rolling = median_in_hand_rotation(&cfg, &[&episodes[..], &[roll]].concat());
    let gaiting = median_in_hand_rotation(&cfg, &[&episodes[..], &[gait.as_str()]].concat());
    for (g, r) in gaiting.iter().zip(&rolling) {
        assert!(*g >= 1.2 * r, "median largest in-hand rotation {g:.1}° gaiting against {r:.1}° rolling alone");
    }

    // A 3 s window, re-placements included.
    one_soup_can_episode_keeps_its_ground_truth(&cfg, &gait.replace("seconds: 6", "seconds: 3"));

    let o = run(&["plan", cfg.to_str().unwrap(), "--set", &gait.replace("regrasp: {}", "regrasp: {lift_deg: 0}")]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("sampling.record.finger_roll.regrasp.lift_deg"), "{e}");
}

/// Pinch pivoting on the Allegro hand (`sampling.record.pivot.pads`): before each pivot the thumb
/// and a finger take the object between two facing pads, the other fingers lift off and close on
/// it again after the pivot. It turns the objects further than finger gaiting over the same 6 s
/// windows (the physics-only `vtgen grasps` figures, six episodes per object), some episode past
/// 60°; a generated pinch-pivoting episode keeps its ground truth on every frame and every touch
/// point on the object; `scenes/tiny-pinch.yaml` plans; pads that select none of the hand's are
/// refused with the field.
#[test]
fn pinch_pivoting_turns_the_object_in_the_hand_further_than_gaiting_and_keeps_the_ground_truth() {
    let cfg = root().join("scenes/tiny-episode.yaml");
    let pinch = r#"sampling.record={camera_hz: 30, tactile_hz: 60, pivot: {seconds: 6, pads: ["th_*", "*"], max_slide_mm: 400}}"#;
    let gait = "sampling.record={camera_hz: 30, tactile_hz: 60, finger_roll: {seconds: 6, axis: [0, 0, 1], \
                joints: [{joint: ff_joint_0}, {joint: mf_joint_0}, {joint: rf_joint_0}], regrasp: {}}}";
    let episodes = ["--trajectories", "6", "--instances", "1", "--set"];
    let report = grasp_report(&cfg, &[&episodes[..], &[pinch]].concat());
    let gaiting = median_in_hand_rotation(&cfg, &[&episodes[..], &[gait]].concat());
    let mut furthest = 0.0f64;
    for (o, g) in report.iter().zip(&gaiting) {
        let mut largest: Vec<f64> =
            o["in_hand_rotation_deg"].as_array().unwrap().iter().map(|e| e["largest_deg"].as_f64().unwrap()).collect();
        largest.sort_by(f64::total_cmp);
        let median = largest[largest.len() / 2];
        assert!(
            median >= 1.3 * g,
            "{}: median largest in-hand rotation {median:.1}° pinch pivoting against {g:.1}° gaiting",
            o["object_id"]
        );
        furthest = furthest.max(largest[largest.len() - 1]);
    }
    assert!(furthest >= 60.0, "no pinch-pivoting episode turned its object 60°: at most {furthest:.1}°");

    one_soup_can_episode_keeps_its_ground_truth(&cfg, &pinch.replace("seconds: 6", "seconds: 3"));

    // The shipped pinch scene plans.
    let o = run(&["plan", root().join("scenes/tiny-pinch.yaml").to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = run(&["plan", cfg.to_str().unwrap(), "--set", &pinch.replace("th_*", "thumb")]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("sampling.record.pivot.pads") && e.contains("'thumb' selects no pad"), "{e}");
    let o = run(&["plan", cfg.to_str().unwrap(), "--set", &pinch.replace("max_slide_mm: 400", "max_slide_mm: 400, regrip_rate: 0")]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("sampling.record.pivot.regrip_rate"), "{e}");
    // A hand's pinch settings on a gripper, whose jaws are always its pinch, are refused, not
    // ignored.
    let gripper = root().join("scenes/tiny-pivot.yaml");
    for setting in ["require_pinch=true", "repinches=2"] {
        let o = run(&["plan", gripper.to_str().unwrap(), "--set", &format!("sampling.record.pivot.{setting}")]);
        let e = stderr(&o);
        let field = format!("sampling.record.pivot.{}", setting.split('=').next().unwrap());
        assert!(!o.status.success() && e.contains(&field) && e.contains("applies to a hand's pinch"), "{e}");
    }
}

/// The closed-loop finger roll (`sampling.record.finger_roll`) on the Allegro hand: it turns the
/// object in the hand more than arm moves alone (the physics-only `vtgen grasps` figures over six
/// episodes per object, with and without), a generated rolling episode keeps its ground truth on
/// every frame and every touch point on the object, and a joint that is not the hand's is refused
/// with the field.
#[test]
fn a_finger_roll_turns_the_object_in_the_hand_and_keeps_the_ground_truth() {
    let cfg = root().join("scenes/tiny-episode.yaml");
    let roll = "sampling.record={camera_hz: 30, tactile_hz: 60, finger_roll: {seconds: 3, axis: [0, 0, 1], \
                joints: [{joint: th_joint_1}, {joint: ff_joint_0}, {joint: mf_joint_0}, {joint: rf_joint_0}]}}";
    let episodes = ["--trajectories", "6", "--instances", "1", "--set"];
    let rolling = median_in_hand_rotation(&cfg, &[&episodes[..], &[roll]].concat());
    let still = median_in_hand_rotation(&cfg, &[&episodes[..], &["sampling.record={camera_hz: 30, tactile_hz: 60}"]].concat());
    for (r, s) in rolling.iter().zip(&still) {
        assert!(*r >= 3.0 && *r >= 3.0 * s, "median largest in-hand rotation {r:.1}° rolling against {s:.1}° without");
    }

    one_soup_can_episode_keeps_its_ground_truth(&cfg, roll);

    let o = run(&["plan", cfg.to_str().unwrap(), "--set", "sampling.record.finger_roll={joints: [{joint: wrist_1_joint}]}"]);
    let e = stderr(&o);
    assert!(
        !o.status.success() && e.contains("sampling.record.finger_roll.joints") && e.contains("'wrist_1_joint' is not a hand joint"),
        "{e}"
    );
}

/// The recorded grasp's approach (`sampling.record.approach`): the episode starts with the open
/// hand 60 mm back from the object along the palm normal, the object standing still in the world
/// and untouched while the palm comes to it; the grasp then records as without the approach. The
/// ground truth holds on every frame, the approach's included.
#[test]
fn a_recorded_approach_brings_the_open_hand_to_the_object_before_the_grasp() {
    let cfg = root().join("scenes/tiny-episode.yaml");
    let d = one_soup_can_episode_with(&cfg, &["sampling.record.grasp=true", "sampling.record.approach={}"]);
    let ds = DatasetReader::open(d.path()).unwrap();
    let shard = &ds.shards("train").unwrap()[0];
    let e = episode_of(shard.meta());
    // The approach's 0.5 s (120 steps at 240 Hz) before the grasp's 276, less the 4 that put the
    // settled grasp on a 30 Hz frame: the approach's first 4 states are left out.
    let dt = 0.0041667;
    assert!((e.settled_s.unwrap() - 392.0 * dt).abs() < 1e-9, "{e:?}");
    let frames: Vec<_> = shard.indices().map(|i| shard.read(i).unwrap()).collect();
    let approaching: Vec<_> = frames.iter().filter(|s| s.info.episode.unwrap().time_s < 116.0 * dt).collect();
    assert_eq!(approaching.len(), 15);
    let at_rest = &frames[approaching.len()];
    let palm = |s: &vt_dataset::Sample| s.info.robot.as_ref().unwrap().t_world_palm;
    let object = |s: &vt_dataset::Sample| s.t_world_camera.transform_point(s.t_camera_object.translation());
    let still = object(approaching[0]);
    for s in &approaching {
        let moved = (object(s) - still).length();
        assert!(moved < 1e-6, "the object moved {moved} m in the world at {:?}", s.info.episode);
        assert!(s.info.links_in_contact().is_empty(), "{:?} touch before the hand reached the object", s.info.links_in_contact());
    }
    // The palm comes from 60 mm back along its normal (facing up), to where the object is put in.
    let normal = palm(at_rest).rotation() * glam::DVec3::X;
    assert!(normal.z > (0.5f64).to_radians().cos(), "palm normal {normal} when the object is put in");
    let came = (palm(at_rest).translation() - palm(approaching[0]).translation()).dot(normal);
    assert!((came - 0.06).abs() < 1e-3, "the palm came {came:.4} m along its normal");
    crate::ground_truth::check_dataset(d.path(), e.frames as usize);
    tactile_points_lie_on_the_object_within_their_pad(d.path());

    // `vtgen plan` counts it in the episode's length.
    let o = run(&["plan", cfg.to_str().unwrap(), "--set", "sampling.record.grasp=true", "--set", "sampling.record.approach={}"]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && out.contains("each the approach and the grasp (1.63 s)"), "{out}");
    // An approach without the recorded grasp, or of no length, is refused with its field.
    let o = run(&["plan", cfg.to_str().unwrap(), "--set", "sampling.record.approach={}"]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("sampling.record.approach") && e.contains("sampling.record.grasp: true"), "{e}");
    let o =
        run(&["plan", cfg.to_str().unwrap(), "--set", "sampling.record.grasp=true", "--set", "sampling.record.approach={distance_mm: 0}"]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("sampling.record.approach.distance_mm"), "{e}");
}

/// Recording the grasp (`sampling.record.grasp`): an episode starts with the object in the open
/// hand, the palm facing up and no phalanx on it; the fingers close and the wrist turns the palm to
/// the grasp pose along a smooth arm path (no jump of the palm between two physics steps, its
/// position kept) before the settled grasp, which is a camera frame at `settled_s`. The ground
/// truth holds on every frame, the grasp's included, and the in-hand rotation counts from the
/// settled grasp.
#[test]
fn a_recorded_grasp_closes_the_open_hand_and_turns_the_wrist_before_the_settled_grasp() {
    let d = one_soup_can_episode(&root().join("scenes/tiny-episode.yaml"), "sampling.record.grasp=true");
    let ds = DatasetReader::open(d.path()).unwrap();
    let shard = &ds.shards("train").unwrap()[0];
    let e = episode_of(shard.meta());
    // Rest 0.15 s, closing 0.6 s and settle 0.4 s at 240 Hz (276 steps), less the 4 that put the
    // settled grasp on a 30 Hz frame (every 8 steps); then one arm move of 0.95 s.
    let dt = 0.0041667;
    let settled_s = e.settled_s.expect("the episode names its settled grasp");
    assert!((settled_s - 272.0 * dt).abs() < 1e-9 && (e.duration_s - settled_s - 0.95).abs() < 0.01, "{e:?}");
    let frames: Vec<_> = shard.indices().map(|i| shard.read(i).unwrap()).collect();
    let settled = frames.iter().position(|s| s.info.episode.unwrap().time_s == settled_s).expect("a frame at the settled grasp");
    assert_eq!(settled, 34);
    for s in &frames[..settled] {
        let frame = s.info.episode.unwrap();
        assert_eq!((frame.arm_move, frame.settled_s), (0, Some(settled_s)), "{frame:?}");
    }
    let palm = |s: &vt_dataset::Sample| s.info.robot.as_ref().unwrap().t_world_palm;
    let (open, held) = (&frames[0], &frames[settled]);
    // The palm's normal (its +x) straight up while the object is put in; nothing touches it yet.
    let normal = palm(open).rotation() * glam::DVec3::X;
    assert!(normal.z > (0.5f64).to_radians().cos(), "palm normal {normal} at the first frame");
    assert!(open.info.links_in_contact().is_empty(), "{:?}", open.info.links_in_contact());
    assert!(held.info.links_in_contact().len() >= 3, "{:?}", held.info.links_in_contact());
    // The wrist turns the palm from facing up to the grasp pose, in place, without a jump.
    let turned = palm(open).rotation().angle_between(palm(held).rotation()).to_degrees();
    assert!(turned > 1.0, "the palm turned {turned:.2}° before the settled grasp");
    assert!((palm(open).translation() - palm(held).translation()).length() < 1e-3);
    let states: Vec<_> = frames[..=settled].iter().flat_map(|s| s.episode.as_ref().unwrap().states.iter().map(|(_, st)| st)).collect();
    for w in states.windows(2) {
        let step = w[0].t_world_palm.rotation().angle_between(w[1].t_world_palm.rotation()).to_degrees();
        assert!(step < 1.0, "the palm jumped {step:.2}° in one physics step at {} s", w[1].time_s);
    }
    // The wrist turn, like the arm move after it, within every arm joint's speed limit (the URDF's
    // `velocity`): the turn goes as far towards the grasp pose as the limits let it in its time.
    let robot = vt_robot::Robot::builtin(vt_robot::DEFAULT_ROBOT).unwrap();
    let all: Vec<_> = frames.iter().flat_map(|s| s.episode.as_ref().unwrap().states.iter().map(|(_, st)| st)).collect();
    for &j in &robot.arm_joints {
        let joint = &robot.model.joints[j];
        let limit = joint.velocity;
        let fastest = all
            .windows(2)
            .map(|w| (w[1].joint_positions[&joint.name] - w[0].joint_positions[&joint.name]).abs() / (w[1].time_s - w[0].time_s))
            .fold(0.0, f64::max);
        assert!(fastest <= 1.001 * limit, "{}: {fastest:.3} rad/s, its limit {limit} rad/s", joint.name);
    }
    crate::ground_truth::check_dataset(d.path(), e.frames as usize);
    tactile_points_lie_on_the_object_within_their_pad(d.path());
    // The object moves in the closing hand; its in-hand rotation counts from the settled grasp.
    let o = run(&["inspect", d.path().to_str().unwrap(), "--json"]);
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let largest = report["in_hand_rotation_deg"][0]["largest_deg"].as_f64().unwrap();
    let since_open = frames
        .iter()
        .map(|s| {
            let in_palm =
                |f: &vt_dataset::Sample| palm(f).rotation().inverse() * f.t_world_camera.rotation() * f.t_camera_object.rotation();
            in_palm(open).angle_between(in_palm(s)).to_degrees()
        })
        .fold(0.0, f64::max);
    assert!(largest < 5.0 && since_open > largest, "largest {largest:.2}° from the settled grasp, {since_open:.2}° from the open hand");
}

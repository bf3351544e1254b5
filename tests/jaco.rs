//! Robots from upstream files nobody here wrote a line of: the Kinova Jaco 2 from
//! example-robot-data's unmodified `kinova.urdf` (its `fixed` finger joints made to turn by the
//! description's `joints:`, its fingers hanging off the arm's last link), and the UR5 with the
//! Allegro hand from two unmodified URDFs, when `VTGEN_ROBOT_ASSETS` holds the folder
//! `scripts/robot-assets` fills. `robot check --suggest` finds a placement for each from a bad
//! start; the Jaco's grasps hold and its data's ground truth is exact.

use std::path::{Path, PathBuf};

use crate::common::*;
use crate::own_robot::tactile_points_lie_on_the_object_within_their_pad;

const UPSTREAM: [&str; 2] =
    ["example-robot-data/robots/kinova_description/robots/kinova.urdf", "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf"];

fn assets() -> Option<PathBuf> {
    match std::env::var_os("VTGEN_ROBOT_ASSETS").map(PathBuf::from) {
        Some(d) if UPSTREAM.iter().all(|f| d.join(f).is_file()) => Some(d),
        _ => {
            eprintln!("skipped: VTGEN_ROBOT_ASSETS does not hold the Jaco's and the UR5's upstream files (scripts/test fetches them)");
            None
        }
    }
}

fn with(assets: &Path, args: &[&str]) -> std::process::Output {
    let mut all = vec!["--robot-assets", assets.to_str().unwrap()];
    all.extend_from_slice(args);
    run(&all)
}

fn scene(name: &str) -> String {
    root().join("scenes").join(name).display().to_string()
}

#[test]
fn the_jaco_from_its_unmodified_urdf_passes_its_check_and_suggest_finds_its_base() {
    let Some(a) = assets() else { return };
    let d = tempdir();
    let picture = d.path().join("check.png");
    let o = with(&a, &["robot", "check", &scene("tiny-jaco.yaml"), "--picture", picture.to_str().unwrap()]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{out}{}", stderr(&o));
    // Two panels side by side (at home, over a grasp), the hand's collision shapes drawn in both.
    let img = image::open(&picture).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (2 * 640 + 8, 480));
    let hand_pixels = |x0: u32| {
        (x0..x0 + 640).flat_map(|x| (0..480).map(move |y| (x, y))).filter(|&(x, y)| img.get_pixel(x, y).0 == [255, 140, 0]).count()
    };
    assert!(hand_pixels(0) > 50 && hand_pixels(648) > 50, "hand outlines: {} and {} pixels", hand_pixels(0), hand_pixels(648));
    assert!(out.contains("robot kinova_j2s6s200: 16 links (11 mesh files), 6 arm joints, 2 hand joints, pads finger_1, finger_2"), "{out}");
    // From the Panda's placement (base 0.4 m from the workspace) the Jaco fails; --suggest moves
    // the base back to where the scene has it.
    let bad = ["--set", "robot.base_position=[0, 0.4, 0]"];
    let o = with(&a, &[&bad[..], &["robot", "check", &scene("tiny-jaco.yaml")]].concat());
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(!o.status.success() && out.contains("problem(s):") && out.contains("advice: `vtgen robot check --suggest"), "{out}");
    let o = with(&a, &[&bad[..], &["robot", "check", "--suggest", "--json", &scene("tiny-jaco.yaml")]].concat());
    assert!(o.status.success(), "{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o));
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(!s["before"]["problems"].as_array().unwrap().is_empty(), "{s}");
    assert!(s["after"]["problems"].as_array().unwrap().is_empty(), "{s}");
    assert!(s["after"]["reach_share"].as_f64().unwrap() >= 0.5, "{s}");
    assert!(s["sets"].as_array().unwrap().iter().any(|l| l.as_str().unwrap().starts_with("robot.")), "{s}");
}

#[test]
fn suggest_finds_the_ur5_allegro_a_home_from_the_ur5es() {
    let Some(a) = assets() else { return };
    let config = scene("tiny-ur5-allegro.yaml");
    let o = with(&a, &["robot", "check", &config]);
    assert!(o.status.success(), "{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o));
    // The UR5e's home on the ROS UR5 (its shoulder pan's zero the other way): links under the floor,
    // and the advice names the home as the cause.
    let bad = "robot.grasp.home_arm=[-1.5707963267948966, -1.5707963267948966, 1.5707963267948966, -1.5707963267948966, -1.5707963267948966, 0.0]";
    let o = with(&a, &["--set", bad, "robot", "check", &config]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(!o.status.success() && out.contains("under the floor") && out.contains("the cause is the home"), "{out}");
    let o = with(&a, &["--set", bad, "robot", "check", "--suggest", "--json", &config]);
    assert!(o.status.success(), "{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o));
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let sets: Vec<&str> = s["sets"].as_array().unwrap().iter().map(|l| l.as_str().unwrap()).collect();
    assert!(sets.len() == 1 && sets[0].starts_with("robot.grasp.home_arm="), "only the home changes: {sets:?}");
    assert!(s["after"]["problems"].as_array().unwrap().is_empty(), "{s}");
}

#[test]
fn the_jaco_holds_objects_and_its_data_is_exact() {
    let Some(a) = assets() else { return };
    let o = with(&a, &["grasps", &scene("tiny-jaco.yaml"), "--trajectories", "3", "--json", "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for obj in r["objects"].as_array().unwrap() {
        assert_eq!(obj["kept"], 3, "{obj}");
        assert!(obj["max_penetration_mm"].as_f64().unwrap() <= 1.0, "{obj}");
        let per_kept = obj["attempts_per_kept"].as_f64().unwrap();
        assert!(per_kept >= 1.0 && per_kept == obj["attempts"].as_f64().unwrap() / 3.0, "{obj}");
    }
    let d = tempdir();
    let o = with(&a, &["generate", &scene("tiny-jaco.yaml"), "--out", d.path().to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = run(&["validate", "--full", d.path().to_str().unwrap()]);
    assert!(o.status.success(), "{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o));
    crate::ground_truth::check_dataset(d.path(), 40);
    tactile_points_lie_on_the_object_within_their_pad(d.path());
    // The dataset keeps the upstream URDF as it was, beside the simulated one with turning fingers.
    let upstream = std::fs::read(a.join(UPSTREAM[0])).unwrap();
    assert!(std::fs::read(d.path().join("robot/robot.upstream.urdf")).unwrap() == upstream);
    let simulated = std::fs::read_to_string(d.path().join("robot/robot.urdf")).unwrap();
    let paths = vt_robot::MeshPaths { urdf_dir: None, package_dirs: vec![a.clone()] };
    let model = vt_robot::RobotModel::from_urdf(&simulated, "robot/robot.urdf", &paths).unwrap();
    assert!(model.joint("j2s6s200_joint_finger_1").unwrap().moves() && model.joint("j2s6s200_joint_finger_2").unwrap().moves());
}

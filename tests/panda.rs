//! The Franka Panda built from example-robot-data's unmodified `panda.urdf` and meshes
//! (`robot.model: panda`, `scenes/tiny-panda.yaml`), when `VTGEN_ROBOT_ASSETS` holds the folder
//! `scripts/robot-assets` fills (`scripts/test` fetches it from PyPI): the robot check passes,
//! both jaws hold the objects, and a dataset passes `validate --full`, its ground truth is exact
//! and a shard job writes the whole run's bytes.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use crate::common::*;
use crate::own_robot::tactile_points_lie_on_the_object_within_their_pad;

fn assets() -> Option<PathBuf> {
    let dir = std::env::var_os("VTGEN_ROBOT_ASSETS").map(PathBuf::from);
    match dir {
        Some(d) if d.join("example-robot-data/robots/panda_description/urdf/panda.urdf").is_file() => Some(d),
        _ => {
            eprintln!("skipped: VTGEN_ROBOT_ASSETS does not hold the Panda's upstream files (scripts/test fetches them)");
            None
        }
    }
}

fn config() -> PathBuf {
    root().join("scenes/tiny-panda.yaml")
}

/// vtgen with the robot assets, the physics backend under test (`VTGEN_TEST_PHYSICS`) and `args`.
fn run_with(assets: &Path, args: &[&str]) -> std::process::Output {
    let backend = format!("robot.physics.backend={}", std::env::var("VTGEN_TEST_PHYSICS").unwrap_or_else(|_| "rapier".into()));
    let mut all = vec!["--robot-assets", assets.to_str().unwrap(), "--set", &backend];
    all.extend_from_slice(args);
    run(&all)
}

fn dataset(assets: &Path) -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let d = tempdir();
        let o = run_with(assets, &["generate", config().to_str().unwrap(), "--out", d.path().to_str().unwrap(), "--quiet"]);
        assert!(o.status.success(), "{}", stderr(&o));
        d
    })
    .path()
}

#[test]
fn the_panda_passes_its_robot_check_and_needs_its_files() {
    let Some(a) = assets() else { return };
    let o = run_with(&a, &["robot", "check", config().to_str().unwrap()]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{out}{}", stderr(&o));
    assert!(out.contains("robot panda: 16 links (19 mesh files), 7 arm joints, 1 hand joints, pads left, right"), "{out}");
    assert!(
        out.contains("jaws: pads face each other within 25° at openings 2.0 to 80.0 mm of the closing; 80.0 mm apart at the preshape"),
        "{out}"
    );
    // Without its files: an error that says where they come from.
    let o = run(&["robot", "check", config().to_str().unwrap()]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("robot.model") && e.contains("scripts/robot-assets"), "{e}");
}

#[test]
fn the_panda_holds_objects_between_its_pads() {
    let Some(a) = assets() else { return };
    let o = run_with(&a, &["grasps", config().to_str().unwrap(), "--trajectories", "3", "--json", "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for obj in r["objects"].as_array().unwrap() {
        assert_eq!(obj["kept"], 3, "{obj}");
        assert!(obj["max_penetration_mm"].as_f64().unwrap() <= 1.0, "{obj}");
        assert_eq!(obj["min_links_in_contact"], 2, "{obj}");
    }
}

#[test]
fn a_panda_dataset_is_valid_exact_and_deterministic() {
    let Some(a) = assets() else { return };
    let dir = dataset(&a);
    let o = run(&["validate", "--full", dir.to_str().unwrap()]);
    assert!(o.status.success(), "{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o));
    crate::ground_truth::check_dataset(dir, 40);
    tactile_points_lie_on_the_object_within_their_pad(dir);
    // The Panda's links are drawn: the arm's seven and the hand's.
    let ds = vt_dataset::DatasetReader::open(dir).unwrap();
    let mut ids = std::collections::BTreeSet::new();
    for s in ds.samples("train").unwrap() {
        let robot = |m: u8| {
            vt_dataset::mask_ids::ARM_LINKS.contains(&m) || m == vt_dataset::mask_ids::ARM_LINK_SEVENTH || m >= vt_dataset::mask_ids::PALM
        };
        ids.extend(s.unwrap().mask.iter().copied().filter(|&m| robot(m)));
    }
    assert!(ids.len() >= 6, "robot links seen in the masks: {ids:?}");
    // Shard 1 of 5 alone: the whole run's bytes.
    let other = tempdir();
    let o = run_with(&a, &["generate", config().to_str().unwrap(), "--out", other.path().to_str().unwrap(), "--quiet", "--shard", "1/5"]);
    assert!(o.status.success(), "{}", stderr(&o));
    for f in complete_shards(other.path()) {
        assert!(std::fs::read(other.path().join(&f)).unwrap() == std::fs::read(dir.join(&f)).unwrap(), "{f} differs");
    }
}

use std::path::Path;

use super::*;

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

#[test]
fn shipped_scenes_parse() {
    for scene in ["scenes/tiny.yaml", "scenes/paper.yaml"] {
        let c = LoadedConfig::load(&root().join(scene)).unwrap_or_else(|e| panic!("{e}"));
        assert!(!c.config.objects.is_empty());
    }
    let paper = LoadedConfig::load(&root().join("scenes/paper.yaml")).unwrap().config;
    assert_eq!(paper.objects.len(), 11);
    assert_eq!(crate::plan::Plan::new(&paper).total_samples(), 220_000);
    assert_eq!((paper.camera.width, paper.camera.height), (640, 480));
}

#[test]
fn fov_gives_centred_square_pixel_intrinsics() {
    let text = std::fs::read_to_string(root().join("scenes/tiny.yaml")).unwrap();
    let text = text.replace("intrinsics: {fx: 615.0, fy: 615.0, cx: 319.5, cy: 239.5}", "fov_y_deg: 90");
    let c = LoadedConfig::parse(&text, Path::new("x.yaml")).unwrap().config;
    let k = c.camera.k();
    assert!((k.fy - 240.0).abs() < 1e-9 && k.fx == k.fy && k.cx == 319.5 && k.cy == 239.5);
}

#[test]
fn custom_objects_and_cross_field_errors() {
    let text = std::fs::read_to_string(root().join("scenes/tiny.yaml")).unwrap();
    let t = text.replace("- 005_tomato_soup_can", "- {id: mine, mesh: m.obj, mass: 0.3, symmetry: continuous_z}");
    let c = LoadedConfig::parse(&t, Path::new("x.yaml")).unwrap();
    assert!(matches!(&c.config.objects[1], ObjectSpec::Custom(o) if o.id == "mine" && o.symmetry == vt_objects::Symmetry::ContinuousZ));
    let t = text.replace("max: [0.08, 0.08, 0.32]", "max: [0.08, -0.1, 0.32]");
    let e = LoadedConfig::parse(&t, Path::new("x.yaml")).unwrap_err().to_string();
    assert!(e.contains("scene.workspace.max: max[1] = -0.1 must be >= min[1] = -0.08"), "{e}");
    let t = text.replace("- 005_tomato_soup_can", "- 003_cracker_box");
    let e = LoadedConfig::parse(&t, Path::new("x.yaml")).unwrap_err().to_string();
    assert!(e.starts_with("x.yaml:6:5: objects[1]: object '003_cracker_box' is listed twice"), "{e}");
}

#[test]
fn the_config_hash_ignores_where_files_live() {
    let text = std::fs::read_to_string(root().join("scenes/tiny.yaml")).unwrap();
    let a = LoadedConfig::parse(&text, Path::new("x.yaml")).unwrap().config;
    let b = LoadedConfig::parse(&text.replace("dir: out/tiny", "dir: /elsewhere"), Path::new("x.yaml")).unwrap().config;
    assert_eq!(a.canonical_json(), b.canonical_json());
    let c = LoadedConfig::parse(&text.replace("seed: 7", "seed: 8"), Path::new("x.yaml")).unwrap().config;
    assert_ne!(a.canonical_json(), c.canonical_json());
}

#[test]
fn back_to_camera_knob_is_checked_and_leaves_other_configs_unchanged() {
    let text = std::fs::read_to_string(root().join("scenes/tiny-hand.yaml")).unwrap();
    assert!(text.contains("    max_tilt_deg: 50\n"));
    let with = |extra: &str| text.replace("    max_tilt_deg: 50\n", &format!("    max_tilt_deg: 50\n{extra}"));
    let plain = LoadedConfig::parse(&text, Path::new("x.yaml")).unwrap().config;
    // The knob at its default is not part of the dataset's definition: older datasets keep their hash.
    assert!(!plain.canonical_json().contains("back_to_camera"));
    let half = LoadedConfig::parse(&with("    back_to_camera_share: 0.5\n"), Path::new("x.yaml")).unwrap().config;
    assert_eq!(half.robot.as_ref().unwrap().grasp.back_to_camera_share, 0.5);
    assert_ne!(plain.canonical_json(), half.canonical_json());
    let e = LoadedConfig::parse(&with("    back_to_camera_share: 1.5\n"), Path::new("x.yaml")).unwrap_err().to_string();
    assert!(e.contains("robot.grasp.back_to_camera_share: 1.5 is out of range"), "{e}");
    let e = LoadedConfig::parse(&with("    back_to_camera_tilt_deg: [120, 80]\n"), Path::new("x.yaml")).unwrap_err().to_string();
    assert!(e.contains("robot.grasp.back_to_camera_tilt_deg: [120, 80] is not a range"), "{e}");
    let paper = LoadedConfig::load(&root().join("scenes/paper.yaml")).unwrap().config;
    assert_eq!(paper.robot.unwrap().grasp.back_to_camera_share, 0.5);
}

/// `objects:` alone is a config: every other section takes the paper's defaults, and the default
/// camera is exactly the paper camera of `scenes/paper.yaml`.
#[test]
fn objects_alone_is_a_config_with_the_papers_defaults() {
    let c = LoadedConfig::parse("objects: [005_tomato_soup_can]\n", Path::new("scenes/mine.yaml")).unwrap_or_else(|e| panic!("{e}"));
    let paper = LoadedConfig::load(&root().join("scenes/paper.yaml")).unwrap().config;
    let cfg = &c.config;
    assert_eq!((cfg.sampling.trajectories_per_object, cfg.sampling.instances_per_trajectory), (200, 100));
    assert_eq!((cfg.sampling.split.train, cfg.sampling.split.test), (4, 1));
    assert_eq!((cfg.camera.width, cfg.camera.height), (paper.camera.width, paper.camera.height));
    assert_eq!(cfg.camera.k(), paper.camera.k());
    assert_eq!((cfg.camera.position, cfg.camera.look_at), (paper.camera.position, paper.camera.look_at));
    assert_eq!(cfg.output.dir, Path::new("out/mine"));
    assert_eq!(cfg.output.samples_per_shard, paper.output.samples_per_shard);
    // A written file is unchanged by the defaults: the tiny config keeps its dataset hash inputs.
    let tiny = std::fs::read_to_string(root().join("scenes/tiny.yaml")).unwrap();
    let parsed = LoadedConfig::parse(&tiny, Path::new("x.yaml")).unwrap().config;
    assert!(parsed.canonical_json().contains("\"trajectories_per_object\":5"), "{}", parsed.canonical_json());
    // A partly written section keeps the defaults of the rest.
    let c = LoadedConfig::parse("objects: [011_banana]\ncamera: {width: 320, height: 240}\n", Path::new("x.yaml")).unwrap().config;
    let k = c.camera.k();
    assert_eq!((k.fx, k.cx, k.cy), (307.5, 159.5, 119.5));
}

fn set(overrides: &[&str]) -> Vec<Override> {
    overrides.iter().map(|o| o.parse().unwrap()).collect()
}

/// `--set` makes a tiny split of the paper's config; an error in an override names the override.
#[test]
fn overrides_set_any_key_with_the_same_checks() {
    let paper = root().join("scenes/paper.yaml");
    let small =
        LoadedConfig::load_with(&paper, &set(&["sampling.trajectories_per_object=2", "sampling.instances_per_trajectory=5"])).unwrap();
    assert_eq!(crate::plan::Plan::new(&small.config).total_samples(), 11 * 2 * 5);
    let full = LoadedConfig::load(&paper).unwrap();
    let mut expect = full.config.clone();
    expect.sampling.trajectories_per_object = 2;
    expect.sampling.instances_per_trajectory = 5;
    assert_eq!(small.config, expect, "nothing else changes");
    let c = LoadedConfig::load_with(
        &paper,
        &set(&["objects=[011_banana, 025_mug]", "objects.1=003_cracker_box", "robot.tactile.resolution=16"]),
    )
    .unwrap();
    assert_eq!(c.config.objects.iter().map(|o| o.id()).collect::<Vec<_>>(), ["011_banana", "003_cracker_box"]);
    assert_eq!(c.config.robot.unwrap().tactile.resolution, 16);
    // A problem the overrides make together with the file: the list item is named.
    let e = LoadedConfig::load_with(&paper, &set(&["objects[0]=011_banana"])).unwrap_err().to_string();
    assert!(e.ends_with("objects[6]: object '011_banana' is listed twice (with the --set overrides)"), "{e}");

    let e = LoadedConfig::load_with(&paper, &set(&["sampling.trajectories_per_object=two"])).unwrap_err().to_string();
    assert!(e.starts_with("--set sampling.trajectories_per_object=two: sampling.trajectories_per_object: invalid type"), "{e}");
    let e = LoadedConfig::load_with(&paper, &set(&["robot.tactile.resolution=1000"])).unwrap_err().to_string();
    assert_eq!(e, "--set robot.tactile.resolution=1000: robot.tactile.resolution: 1000 is out of range: allowed 4 ..= 256");
    let e = LoadedConfig::load_with(&paper, &set(&["sampling.trajectories=2"])).unwrap_err().to_string();
    assert!(e.starts_with("--set sampling.trajectories=2: sampling.trajectories: unknown field `trajectories`"), "{e}");
    // An error of the file itself is still located in the file.
    let dir = std::env::temp_dir().join(format!("vt-config-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.yaml");
    std::fs::write(&bad, "objects: [011_banana]\ncamera:\n  width: 7\n").unwrap();
    let e = LoadedConfig::load_with(&bad, &set(&["seed=3"])).unwrap_err().to_string();
    assert!(e.starts_with(&format!("{}:3:3: camera.width: 7 is out of range", bad.display())), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A type error names its field once (serde_yaml's message starts with the path too).
#[test]
fn type_errors_name_the_field_once() {
    let e = LoadedConfig::parse("objects: [011_banana]\ncamera:\n  width: wide\n", Path::new("x.yaml")).unwrap_err().to_string();
    assert!(e.starts_with("x.yaml:3:10: camera.width: invalid type: string \"wide\""), "{e}");
    assert_eq!(e.matches("camera.width").count(), 1, "{e}");
}

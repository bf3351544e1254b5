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
    assert_eq!((small.config.objects.len(), small.config.sampling.trajectories_per_object), (11, 2));
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

/// A palm-only grasp key set for a parallel-jaw gripper is refused, naming the key (its value
/// would be silently unused); the gripper's config without it loads.
#[test]
fn palm_only_grasp_keys_are_refused_for_a_gripper() {
    let gripper = root().join("scenes/tiny-gripper.yaml");
    LoadedConfig::load(&gripper).unwrap();
    for key in ["robot.grasp.palm_surface_x=0.02", "robot.grasp.max_grasp_depth=0.05"] {
        let e = LoadedConfig::load_with(&gripper, &set(&[key])).unwrap_err().to_string();
        let field = key.split('=').next().unwrap();
        assert!(e.contains(&format!("{field}: only palm grasps use it")), "{e}");
    }
    // The same keys are the palm grasp's to set.
    LoadedConfig::load_with(&root().join("scenes/tiny-hand.yaml"), &set(&["robot.grasp.palm_surface_x=0.02"])).unwrap();
}

/// A type error names its field once (serde_yaml's message starts with the path too).
#[test]
fn type_errors_name_the_field_once() {
    let e = LoadedConfig::parse("objects: [011_banana]\ncamera:\n  width: wide\n", Path::new("x.yaml")).unwrap_err().to_string();
    assert!(e.starts_with("x.yaml:3:10: camera.width: invalid type: string \"wide\""), "{e}");
    assert_eq!(e.matches("camera.width").count(), 1, "{e}");
}

/// The grasp loop's durations and penetration, the finger gains and the hand's joint ranges are
/// checked like every other knob: the error names the field path and its line.
#[test]
fn grasp_and_physics_knobs_are_checked_at_their_line() {
    let text = std::fs::read_to_string(root().join("scenes/tiny-hand.yaml")).unwrap();
    // The error for `text` with `from` replaced by `to`, and the line and column of `at` there.
    let check = |from: &str, to: &str, at: &str, expect: &str| {
        assert!(text.contains(from), "tiny-hand.yaml contains {from}");
        let t = text.replacen(from, to, 1);
        let (line, column) = t.lines().enumerate().find_map(|(i, l)| l.find(at).map(|c| (i + 1, c + 1))).unwrap();
        let e = LoadedConfig::parse(&t, Path::new("x.yaml")).unwrap_err().to_string();
        assert_eq!(e, format!("x.yaml:{line}:{column}: {expect}"));
    };
    let grasp = "    max_tilt_deg: 50\n";
    let with = |extra: &str| format!("{grasp}    {extra}\n");
    check(
        grasp,
        &with("move_seconds: -0.5"),
        "move_seconds",
        "robot.grasp.move_seconds: -0.5 is out of range: allowed 0 < move_seconds <= 60 s",
    );
    check(grasp, &with("hold_seconds: 0"), "hold_seconds", "robot.grasp.hold_seconds: 0 is out of range: allowed 0 < hold_seconds <= 60 s");
    check(
        grasp,
        &with("settle_seconds: .nan"),
        "settle_seconds",
        "robot.grasp.settle_seconds: NaN is out of range: allowed 0 < settle_seconds <= 60 s",
    );
    check(
        grasp,
        &with("close_seconds: 600"),
        "close_seconds",
        "robot.grasp.close_seconds: 600 is out of range: allowed 0 < close_seconds <= 60 s",
    );
    check(
        grasp,
        &with("max_penetration: -0.001"),
        "max_penetration",
        "robot.grasp.max_penetration: -0.001 is out of range: allowed 0 ..= 0.1",
    );
    check(
        grasp,
        &with("max_grasp_depth: 0"),
        "max_grasp_depth",
        "robot.grasp.max_grasp_depth: 0 is out of range: allowed 0 < max_grasp_depth <= 1 m",
    );
    // A flow sequence: the error points at its key.
    let pairs: Vec<&str> = (0..16).map(|k| if k == 2 { "[0.3, 0.1]" } else { "[0, 0.2]" }).collect();
    check(
        grasp,
        &with(&format!("preshape: [{}]", pairs.join(", "))),
        "preshape",
        "robot.grasp.preshape[2]: [0.3, 0.1] is not a range: allowed -3.141592653589793 <= min <= max <= 3.141592653589793",
    );
    let close = "[null, 1.5, 1.5, 1.4, null, 1.5, 1.5, 1.4, null, 1.5, 1.5, 9, 1.35, 0.9, 1.2, 1.2]";
    check(
        grasp,
        &with(&format!("close: {close}")),
        "close",
        "robot.grasp.close[11]: 9 is out of range: allowed -3.141592653589793 ..= 3.141592653589793",
    );
    check(
        "max: [0.08, 0.05, 0.32]}",
        "max: [0.08, -0.06, 0.32]}",
        "max: [0.08, -0.06",
        "robot.grasp.palm_workspace.max: max[1] = -0.06 must be >= min[1] = -0.05",
    );
    // Keys of a one-line flow mapping.
    let physics = "physics: {backend: rapier, timestep: 0.0041667}";
    let physics_with = |extra: &str| format!("physics: {{backend: rapier, timestep: 0.0041667, {extra}}}");
    check(
        physics,
        &physics_with("max_torque: 0"),
        "max_torque",
        "robot.physics.max_torque: 0 is out of range: allowed 0 < max_torque <= 1000 N·m",
    );
    check(
        physics,
        &physics_with("stiffness: -5"),
        "stiffness",
        "robot.physics.stiffness: -5 is out of range: allowed 0 < stiffness <= 10000 N·m/rad",
    );
    check(physics, &physics_with("damping: -0.1"), "damping", "robot.physics.damping: -0.1 is out of range: allowed 0 ..= 1000");
    check("base_yaw_deg: 180", "base_yaw_deg: 720", "base_yaw_deg", "robot.base_yaw_deg: 720 is out of range: allowed -360 ..= 360");
    check(
        "base_position: [0.0, 0.5, 0.0]",
        "base_position: [0.0, .inf, 0.0]",
        "base_position",
        "robot.base_position[1]: inf is out of range: allowed -100 ..= 100",
    );
    check(
        "    contact_threshold_mm: 2.0\n",
        "    contact_threshold_mm: 2.0\n    perspective_standoff_mm: 0\n",
        "perspective_standoff_mm",
        "robot.tactile.perspective_standoff_mm: 0 is out of range: allowed 0 < perspective_standoff_mm <= 100 mm",
    );
    check(
        "position: [0.0, -0.75, 0.55]",
        "position: [0.0, -0.75, 1e9]",
        "position",
        "camera.position[2]: 1000000000 is out of range: allowed -100 ..= 100",
    );
}

/// One step of a path into a YAML tree.
#[derive(Debug, Clone)]
enum Step {
    Key(String),
    Index(usize),
}

/// The path as the errors write it: `robot.grasp.preshape[3][0]`.
fn dotted(path: &[Step]) -> String {
    let mut s = String::new();
    for step in path {
        match step {
            Step::Key(k) if s.is_empty() => s.push_str(k),
            Step::Key(k) => s.push_str(&format!(".{k}")),
            Step::Index(i) => s.push_str(&format!("[{i}]")),
        }
    }
    s
}

/// Every number of a YAML tree, by path; whether it is an integer.
fn numbers(v: &serde_yaml::Value, path: &mut Vec<Step>, out: &mut Vec<(Vec<Step>, bool)>) {
    match v {
        serde_yaml::Value::Number(n) => out.push((path.clone(), !n.is_f64())),
        serde_yaml::Value::Sequence(s) => {
            for (i, x) in s.iter().enumerate() {
                path.push(Step::Index(i));
                numbers(x, path, out);
                path.pop();
            }
        }
        serde_yaml::Value::Mapping(m) => {
            for (k, x) in m {
                path.push(Step::Key(k.as_str().unwrap().to_string()));
                numbers(x, path, out);
                path.pop();
            }
        }
        _ => {}
    }
}

fn at_mut<'a>(v: &'a mut serde_yaml::Value, path: &[Step]) -> &'a mut serde_yaml::Value {
    path.iter().fold(v, |v, step| match step {
        Step::Key(k) => v.get_mut(k.as_str()).unwrap(),
        Step::Index(i) => v.get_mut(*i).unwrap(),
    })
}

/// Whether an error at `field` names the knob at `leaf`: the knob itself, the element or section
/// it is part of (a `[lo, hi]` pair, a sensor model), or the field a cross-field check compares it
/// with and reports at (`far_mm` above `near_mm`, `look_at` away from `position`, a box's `max`
/// above its `min`, the light's `position_max` above its `position_min`).
fn names_knob(field: &str, leaf: &str) -> bool {
    let parent = |p: &str| p.rfind(['.', '[']).map_or(String::new(), |i| p[..i].to_string());
    if field == leaf || field == parent(leaf) {
        return true;
    }
    let key_path = leaf.split('[').next().unwrap();
    [("near_mm", "far_mm"), ("position", "look_at"), ("min", "max"), ("position_min", "position_max")]
        .iter()
        .any(|(knob, reported)| key_path.ends_with(&format!(".{knob}")) && field == format!("{}.{reported}", parent(key_path)))
}

/// Every number of a resolved config with every optional section present is checked: NaN and
/// ±infinity in any float, the largest u32 in any integer, give an error (never a panic) located
/// in the file and naming that knob; only the seed takes any integer.
#[test]
fn every_numeric_knob_is_checked() {
    let sections = "robot:\n  grasp: {back_to_camera_share: 0.5, back_to_camera_tilt_deg: [70, 110]}\n  tactile:\n    projection: perspective\n    sensors: [{pads: proximal, model: optical, optical: {preset: gelsight_mini, markers: {}}}, {pads: medial, model: taxel_array, rows: 4, cols: 4}, {pads: distal, model: gelsight, gel_thickness_mm: 1.5}]\n    optical: {preset: digit, image_size: [320, 240], sensing_area_mm: [19, 16], gel_thickness_mm: 1, elastic_spread_mm: 0.3, ambient: 0.2, background: [0.7, 0.7, 0.7], vignetting: 0.3, noise_std: 1, markers: {pitch_mm: 1.6, radius_mm: 0.2, shift: 0.5, opacity: 0.8}, lights: [{direction: [1, 0, -0.5], color: [0.9, 0.1, 0.1], falloff: 0.4}, {direction: [-0.5, 0.87, -0.5], color: [0.1, 0.9, 0.1]}, {direction: [-0.5, -0.87, -0.5], color: [0.1, 0.1, 0.9]}]}\n";
    let objects = "objects: [005_tomato_soup_can, {id: mine, mesh: m.obj, mass: 0.3}]\nrandomization: {enabled: true, robot_materials: {}, tactile_sensors: {}}\n";
    let cameras = [
        "camera:\n  intrinsics: {fx: 615.0, fy: 615.0, cx: 319.5, cy: 239.5}\n  noise: {depth: {}, color: {}}\n",
        "camera:\n  fov_y_deg: 60\n",
    ];
    let mut checked = 0;
    for camera in cameras {
        let resolved = LoadedConfig::parse(&format!("{objects}{camera}{sections}"), Path::new("x.yaml")).unwrap().config;
        let tree = serde_yaml::to_value(&resolved).unwrap();
        let mut leaves = Vec::new();
        numbers(&tree, &mut Vec::new(), &mut leaves);
        for (path, integer) in leaves {
            let leaf = dotted(&path);
            let bad: Vec<serde_yaml::Value> =
                if integer { vec![u32::MAX.into()] } else { [f64::NAN, f64::INFINITY, f64::NEG_INFINITY].map(Into::into).to_vec() };
            for value in bad {
                let mut t = tree.clone();
                *at_mut(&mut t, &path) = value.clone();
                let text = serde_yaml::to_string(&t).unwrap();
                match LoadedConfig::parse(&text, Path::new("x.yaml")) {
                    Ok(_) => assert_eq!(leaf, "seed", "{leaf} = {value:?} is accepted"),
                    Err(e) => {
                        assert!(names_knob(&e.field, &leaf), "{leaf} = {value:?}: the error names another field: {e}");
                        assert!(e.line.is_some(), "{leaf} = {value:?}: the error is not located: {e}");
                    }
                }
                checked += 1;
            }
        }
    }
    assert!(checked > 200, "{checked}");
}

/// The optical sensor's bad values each end in one error naming their field, at its line.
#[test]
fn optical_sensor_errors_name_the_field() {
    let cases = [
        (
            "optical: {lights: [{direction: [0, 0, 0], color: [1, 0, 0]}, {direction: [0, 1, -1], color: [0, 1, 0]}, {direction: [1, 0, -1], color: [0, 0, 1]}]}",
            "robot.tactile.optical.lights[0].direction",
            "zero length",
        ),
        (
            "optical: {lights: [{direction: [1, 0, 1], color: [1, 0, 0]}, {direction: [0, 1, -1], color: [0, 1, 0]}, {direction: [1, 0, -1], color: [0, 0, 1]}]}",
            "robot.tactile.optical.lights[0].direction",
            "behind the gel",
        ),
        (
            "optical: {lights: [{direction: [1, 0, -1], color: [1, 1, 1]}, {direction: [0, 1, -1], color: [1, 1, 1]}, {direction: [1, 1, -1], color: [1, 1, 1]}]}",
            "robot.tactile.optical.lights",
            "cannot tell slopes apart",
        ),
        ("optical: {gel_thickness_mm: -1.5}", "robot.tactile.optical.gel_thickness_mm", "out of range"),
        ("optical: {image_size: [0, 240]}", "robot.tactile.optical.image_size[0]", "out of range"),
        ("optical: {preset: gelsight_maxi}", "robot.tactile.optical.preset", "unknown variant"),
        ("optical: {markers: {pitch_mm: 1.0, radius_mm: 0.6}}", "robot.tactile.optical.markers.radius_mm", "pitch / 2"),
    ];
    for (optical, field, message) in cases {
        let text =
            format!("objects: [005_tomato_soup_can]\nrobot:\n  tactile:\n    sensors: [{{pads: distal, model: optical}}]\n    {optical}\n");
        let e = LoadedConfig::parse(&text, Path::new("x.yaml")).expect_err(optical);
        assert_eq!(e.field, field, "{optical}: {e}");
        assert!(e.message.contains(message) && e.line == Some(5), "{optical}: {e}");
    }
    let bad = "objects: [005_tomato_soup_can]\nrandomization:\n  tactile_sensors: {led_color: 1.5}\n";
    let e = LoadedConfig::parse(bad, Path::new("x.yaml")).expect_err("led_color");
    assert_eq!(e.field, "randomization.tactile_sensors.led_color", "{e}");
}

/// Sensors go to pads by rules: the first rule that selects a pad (a glob over its name or one of
/// its labels) gives its sensor, then the description's rules, then a depth camera; any number
/// of kinds and optical configs on one hand; a rule that selects nothing and the older map by pad
/// group are refused, located.
#[test]
fn sensor_rules_assign_a_sensor_to_each_pad() {
    let config = |sensors: &str| format!("objects: [005_tomato_soup_can]\nrobot:\n  tactile:\n    sensors: {sensors}\n");
    let text = config(
        "[{pads: \"th_*\", model: optical, optical: {preset: digit}}, {pads: \"?f_distal\", model: optical}, \
         {pads: medial, model: taxel_array, rows: 4, cols: 4}]",
    );
    let loaded = LoadedConfig::parse(&text, Path::new("x.yaml")).unwrap();
    let robot = loaded.robot.as_ref().unwrap();
    let by_name: std::collections::BTreeMap<&str, &PadSensor> =
        robot.pads.iter().map(|p| p.name.as_str()).zip(&loaded.pad_sensors).collect();
    assert_eq!(by_name.len(), 12);
    let digit = OpticalConfig { preset: OpticalPreset::Digit, ..Default::default() }.resolve();
    let mini = OpticalConfig::default().resolve();
    assert_ne!(digit, mini);
    for name in ["th_proximal", "th_medial", "th_distal"] {
        assert_eq!(by_name[name].model, SensorModel::Optical, "{name}: the first rule wins over the label rule");
        assert_eq!(by_name[name].optical.as_ref(), Some(&digit), "{name}");
    }
    for name in ["ff_distal", "mf_distal", "rf_distal"] {
        assert_eq!(by_name[name].optical.as_ref(), Some(&mini), "{name}: the tactile section's sensor, its default preset");
    }
    for name in ["ff_medial", "mf_medial", "rf_medial"] {
        assert_eq!(by_name[name].model, SensorModel::TaxelArray { rows: 4, cols: 4 }, "{name}");
    }
    // Not selected by the config: the Allegro description's own rule (a depth camera everywhere).
    for name in ["ff_proximal", "mf_proximal", "rf_proximal"] {
        assert_eq!(*by_name[name], PadSensor { model: SensorModel::DepthCamera, optical: None }, "{name}");
    }
    // The rules round-trip through the config's serialization (config.json).
    let again = serde_yaml::from_value::<TactileConfig>(serde_yaml::to_value(&loaded.config.robot.as_ref().unwrap().tactile).unwrap());
    assert_eq!(again.unwrap().sensors, loaded.config.robot.as_ref().unwrap().tactile.sensors);

    let e = LoadedConfig::parse(&config("[{pads: \"lf_*\", model: depth_camera}]"), Path::new("x.yaml")).unwrap_err();
    assert!(e.field == "robot.tactile.sensors" && e.line == Some(4) && e.message.contains("'lf_*' selects no pad"), "{e}");
    let e = LoadedConfig::parse(&config("{proximal: {model: depth_camera}}"), Path::new("x.yaml")).unwrap_err();
    assert!(e.field == "robot.tactile.sensors" && e.message.contains("[{pads: proximal, model: ...}]"), "{e}");
    let e = LoadedConfig::parse(&config("[{pads: \"*\", model: taxel_array, rows: 4}]"), Path::new("x.yaml")).unwrap_err();
    assert!(e.message.contains("needs rows and cols"), "{e}");
    let e = LoadedConfig::parse(&config("[{pads: \"*\", model: depth_camera, optical: {}}]"), Path::new("x.yaml")).unwrap_err();
    assert!(e.message.contains("'optical' belongs to another model"), "{e}");
    let e = LoadedConfig::parse(&config("[{pads: \"*\", model: taxel_array, rows: 4, cols: 40}]"), Path::new("x.yaml")).unwrap_err();
    assert_eq!(e.field, "robot.tactile.sensors[0].cols", "{e}");
}

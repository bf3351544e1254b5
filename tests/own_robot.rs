//! A robot of one's own: a UR5e carrying a three-finger gripper with two phalanges per finger,
//! generated here (primitive links, the distal joints `<mimic>` the proximal ones), brought in by a
//! config's `robot.description`. Nothing in vtgen may assume the Allegro's 4 fingers, 16 joints or
//! 12 pads: this robot generates a valid, deterministic dataset whose ground truth holds.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use vt_dataset::{DatasetReader, read_ply};

use crate::common::*;

/// The gripper's fingers: name, origin on the palm, rpy (the bottom finger turned to point down).
const FINGERS: [(&str, [f64; 3], [f64; 3]); 3] = [
    ("left", [0.0, 0.03, 0.0], [0.0; 3]),
    ("right", [0.0, -0.03, 0.0], [0.0; 3]),
    ("thumb", [0.0, 0.0, -0.095], [std::f64::consts::PI, 0.0, 0.0]),
];
/// Phalanx lengths (m): proximal, distal (to the fingertip sphere's centre).
const LENGTHS: [f64; 2] = [0.05, 0.04];

/// The built-in UR5e arm (`robots/ur5e/arm.urdf`, base to flange; its primitives, the real
/// meshes' visuals left out) with the gripper on an adapter like the Allegro's.
pub fn three_finger_urdf() -> String {
    let arm = std::fs::read_to_string(root().join("robots/ur5e/arm.urdf")).unwrap();
    let cut = arm.rfind("</robot>").expect("the arm's URDF ends");
    let arm: String = arm[..cut].lines().filter(|l| !l.contains("<mesh filename=")).map(|l| format!("{l}\n")).collect();
    let mut x = arm.replace("name=\"ur5e\"", "name=\"ur5e_three_finger\"");
    let box_link = |x: &mut String, name: &str, mass: f64, size: [f64; 3], at: [f64; 3], tip: Option<(f64, f64)>| {
        let g = |x: &mut String, kind: &str| {
            let _ = write!(
                x,
                r#"<{kind}><origin xyz="{} {} {}"/><geometry><box size="{} {} {}"/></geometry></{kind}>"#,
                at[0], at[1], at[2], size[0], size[1], size[2]
            );
            if let Some((r, z)) = tip {
                let _ = write!(x, r#"<{kind}><origin xyz="0 0 {z}"/><geometry><sphere radius="{r}"/></geometry></{kind}>"#);
            }
        };
        let _ = write!(
            x,
            r#"<link name="{name}"><inertial><origin xyz="{} {} {}"/><mass value="{mass}"/><inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0" izz="1e-5"/></inertial>"#,
            at[0], at[1], at[2]
        );
        g(x, "visual");
        g(x, "collision");
        x.push_str("</link>\n");
    };
    let fixed = |x: &mut String, name: &str, parent: &str, child: &str, xyz: [f64; 3], rpy: [f64; 3]| {
        let _ = writeln!(
            x,
            r#"<joint name="{name}" type="fixed"><parent link="{parent}"/><child link="{child}"/><origin xyz="{} {} {}" rpy="{} {} {}"/></joint>"#,
            xyz[0], xyz[1], xyz[2], rpy[0], rpy[1], rpy[2]
        );
    };
    box_link(&mut x, "hand_adapter", 0.05, [0.06, 0.06, 0.01], [0.0, 0.0, 0.005], None);
    fixed(&mut x, "hand_adapter_joint", "flange", "hand_adapter", [0.0; 3], [0.0; 3]);
    // The Allegro's palm block: its palmar surface at x = 0.0111, the fingers' row at z = 0.
    box_link(&mut x, "palm", 0.4, [0.0408, 0.113, 0.095], [-0.0093, 0.0, -0.0475], None);
    fixed(&mut x, "palm_joint", "hand_adapter", "palm", [0.0, 0.0, 0.105], [0.0; 3]);
    for (finger, xyz, rpy) in FINGERS {
        let mut parent = "palm".to_string();
        let (mut origin, mut origin_rpy) = (xyz, rpy);
        for (k, phalanx) in ["proximal", "distal"].into_iter().enumerate() {
            let (link, length) = (format!("{finger}_{phalanx}"), LENGTHS[k]);
            let tip = (k == 1).then_some((0.01, length));
            box_link(&mut x, &link, 0.04, [0.0196, 0.0275, length], [0.0, 0.0, length / 2.0], tip);
            // Flexion about y turns the finger towards the palmar side (+x); the distal joint
            // follows the proximal one (an underactuated finger).
            let mimic =
                if k == 1 { format!(r#"<mimic joint="{finger}_proximal_joint" multiplier="0.8" offset="0"/>"#) } else { String::new() };
            let _ = writeln!(
                x,
                r#"<joint name="{link}_joint" type="revolute"><parent link="{parent}"/><child link="{link}"/><origin xyz="{} {} {}" rpy="{} {} {}"/><axis xyz="0 1 0"/><limit lower="-0.2" upper="1.6" effort="0.7" velocity="6"/>{mimic}</joint>"#,
                origin[0], origin[1], origin[2], origin_rpy[0], origin_rpy[1], origin_rpy[2]
            );
            let sensing = length + if k == 1 { 0.01 } else { 0.0 };
            let _ = writeln!(x, r#"<link name="{link}_pad"/>"#);
            fixed(
                &mut x,
                &format!("{link}_pad_joint"),
                &link,
                &format!("{link}_pad"),
                [0.0098, 0.0, sensing / 2.0],
                [0.0, std::f64::consts::FRAC_PI_2, 0.0],
            );
            parent = link;
            (origin, origin_rpy) = ([0.0, 0.0, length], [0.0; 3]);
        }
    }
    x.push_str("</robot>\n");
    x
}

/// Its description: the UR5e's arm and home, the palm grasp, three hand joints, six pads.
pub fn three_finger_yaml() -> String {
    let mut y = String::from(
        "name: ur5e_three_finger\nurdf: three_finger.urdf\narm:\n  base: base_link\n  flange: flange\n  \
         home: [-1.5707963267948966, -1.5707963267948966, 1.5707963267948966, -1.5707963267948966, -1.5707963267948966, 0.0]\n\
         grasp: {frame: palm, kind: palm, min_touching: 2}\nhand:\n",
    );
    for (finger, _, _) in FINGERS {
        let _ = writeln!(y, "  - {{joint: {finger}_proximal_joint, preshape: [-0.1, 0.2], close: 1.4}}");
    }
    y.push_str("pads:\n");
    for (finger, _, _) in FINGERS {
        for phalanx in ["proximal", "distal"] {
            let _ =
                writeln!(y, "  - {{name: {finger}_{phalanx}, link: {finger}_{phalanx}, frame: {finger}_{phalanx}_pad, group: {phalanx}}}");
        }
    }
    y
}

/// `scenes/tiny-hand.yaml` with the three-finger robot (the object held against the palm's middle,
/// where the three fingers close), in `dir`; returns the config's path.
fn write_config(dir: &Path) -> PathBuf {
    std::fs::write(dir.join("three_finger.urdf"), three_finger_urdf()).unwrap();
    std::fs::write(dir.join("three_finger.yaml"), three_finger_yaml()).unwrap();
    three_finger_config(dir, "three_finger.yaml", "three-finger.yaml")
}

/// `scenes/tiny-hand.yaml` written as `config` in `dir` with the robot of `description` (beside
/// it) grasping at the palm's middle, on the backend under test (`VTGEN_TEST_PHYSICS`); its sensor
/// rule for the Allegro's medial pads left out (this hand has none: a rule that selects no pad
/// is an error).
pub fn three_finger_config(dir: &Path, description: &str, config: &str) -> PathBuf {
    let text = std::fs::read_to_string(root().join("scenes/tiny-hand.yaml")).unwrap();
    let backend = std::env::var("VTGEN_TEST_PHYSICS").unwrap_or_else(|_| "rapier".into());
    let text = text
        .replace("robot:\n", &format!("robot:\n  description: {description}\n"))
        .replace("      - {pads: medial, model: taxel_array, rows: 4, cols: 4}\n", "")
        .replace("  grasp:\n", "  grasp:\n    object_offset: {min: [0.0, -0.01, -0.06], max: [0.0, 0.01, -0.035]}\n")
        .replace("backend: rapier", &format!("backend: {backend}"));
    let cfg = dir.join(config);
    std::fs::write(&cfg, text).unwrap();
    cfg
}

/// A config written once into a temporary directory that lives as long as the tests.
pub fn config_once(cell: &'static OnceLock<(tempfile::TempDir, PathBuf)>, write: fn(&Path) -> PathBuf) -> &'static Path {
    &cell
        .get_or_init(|| {
            let d = tempdir();
            let cfg = write(d.path());
            (d, cfg)
        })
        .1
}

fn config() -> &'static Path {
    static DIR: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    config_once(&DIR, write_config)
}

/// `config` generated into a fresh directory.
pub fn generated(config: &Path) -> tempfile::TempDir {
    let d = tempdir();
    let o = run_generate(config, d.path(), &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    d
}

/// `--shard i/5` of `config` alone writes train shard i, byte for byte the whole run's.
pub fn shard_job_matches(config: &Path, i: u32, whole: &Path) {
    let other = tempdir();
    let o = run_generate(config, other.path(), &["--shard", &format!("{i}/5")]);
    assert!(o.status.success(), "{}", stderr(&o));
    let shards = complete_shards(other.path());
    assert_eq!(shards, [format!("train/shard-{i:05}.mcap")]);
    for f in shards {
        assert!(std::fs::read(other.path().join(&f)).unwrap() == std::fs::read(whole.join(&f)).unwrap(), "{f} differs");
    }
}

fn dataset() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| generated(config())).path()
}

#[test]
fn a_three_finger_gripper_generates_a_valid_dataset() {
    let dir = dataset();
    let o = run(&["validate", dir.to_str().unwrap()]);
    assert!(o.status.success(), "{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o));
    let ds = DatasetReader::open(dir).unwrap();
    let pads: Vec<String> = FINGERS.iter().flat_map(|f| ["proximal", "distal"].map(|p| format!("{}_{p}", f.0))).collect();
    let mut n = 0;
    for split in ["train", "test"] {
        for s in ds.samples(split).unwrap() {
            let s = s.unwrap();
            let r = s.info.robot.as_ref().expect("a robot's info");
            // 6 arm joints and the 3 hand joints that move on their own (the mimics follow).
            assert_eq!(r.joint_positions.len(), 9, "{:?}", r.joint_positions);
            assert!(r.joint_positions.contains_key("thumb_proximal_joint"));
            assert!(r.links_in_contact.len() >= 2 && r.links_in_contact.iter().all(|p| pads.contains(p)), "{:?}", r.links_in_contact);
            let tac = s.tactile.as_ref().expect("tactile data");
            assert_eq!(tac.pads, pads);
            assert_eq!(tac.depth.len(), 6);
            let frames: Vec<&str> = s.extra_transforms.iter().map(|t| t.1.as_str()).collect();
            assert!(frames.contains(&"palm") && frames.iter().filter(|f| f.ends_with("_pad")).count() == 6, "{frames:?}");
            // The gripper's links are drawn with the hand-link mask ids: 3 joints, then 3 mimics.
            let ids: std::collections::BTreeSet<u8> =
                s.mask.iter().copied().filter(|&m| vt_dataset::mask_ids::HAND_LINKS.contains(&m)).collect();
            assert!(ids.iter().all(|&m| m < 17 + 6), "{ids:?}");
            n += 1;
        }
    }
    assert_eq!(n, 40);
}

#[test]
fn the_three_finger_ground_truth_is_exact() {
    crate::ground_truth::check_dataset(dataset(), 40);
    tactile_points_lie_on_the_object_within_their_pad(dataset());
}

#[test]
fn the_three_finger_dataset_is_deterministic() {
    shard_job_matches(config(), 1, dataset());
}

#[test]
fn bad_descriptions_are_reported_with_file_and_field() {
    let d = tempdir();
    let cfg = write_config(d.path());
    let yaml = three_finger_yaml();
    let cases = [
        (yaml.replace("link: thumb_distal,", "link: thumb_tip,"), "pads[5].link: no link 'thumb_tip' in the URDF"),
        (
            yaml.replace("frame: palm,", "frame: shoulder_pan_link,"),
            "grasp.frame: 'shoulder_pan_link' is not fixed below the flange 'flange'",
        ),
        (yaml.replace("base: base_link", "base: thumb_distal"), "arm: 'flange' is not below 'thumb_distal'"),
        (
            yaml.replace("  - {joint: thumb_proximal_joint, preshape: [-0.1, 0.2], close: 1.4}\n", ""),
            "joint 'thumb_proximal_joint' moves in the hand",
        ),
    ];
    for (text, want) in cases {
        std::fs::write(d.path().join("three_finger.yaml"), text).unwrap();
        let o = run_generate(&cfg, &d.path().join("o"), &[]);
        let e = stderr(&o);
        assert!(!o.status.success(), "{want}: {e}");
        assert!(e.contains("robot.description:") && e.contains("three_finger.yaml: ") && e.contains(want), "{want}: {e}");
        assert!(!d.path().join("o").join("manifest.json").exists());
    }
    // A mimic joint that names a missing joint: the URDF's error.
    std::fs::write(d.path().join("three_finger.yaml"), &yaml).unwrap();
    let urdf = three_finger_urdf().replace(r#"<mimic joint="left_proximal_joint""#, r#"<mimic joint="left_joint""#);
    std::fs::write(d.path().join("three_finger.urdf"), urdf).unwrap();
    let o = run_generate(&cfg, &d.path().join("o"), &[]);
    let e = stderr(&o);
    assert!(
        e.contains("three_finger.urdf: joint 'left_distal_joint': <mimic joint=\"left_joint\"> names a joint that does not exist"),
        "{e}"
    );
    // The grasp config's joint arrays must fit the robot.
    std::fs::write(d.path().join("three_finger.urdf"), three_finger_urdf()).unwrap();
    let o = run(&["generate", cfg.to_str().unwrap(), "--quiet", "--set", "robot.grasp.preshape=[[0,0.1],[0,0.1]]"]);
    let e = stderr(&o);
    assert!(e.contains("robot.grasp.preshape: 2 values for the 3 hand joints of robot 'ur5e_three_finger'"), "{e}");
}

/// The dataset's object models (`models/`, in `object_index` order) as meshes to measure
/// distances to.
pub fn object_meshes(dir: &Path) -> Vec<rapier3d::parry::shape::TriMesh> {
    let info: vt_dataset::ModelsInfo = serde_json::from_slice(&std::fs::read(dir.join("models/models_info.json")).unwrap()).unwrap();
    info.objects
        .iter()
        .map(|o| {
            let m = read_ply(&dir.join("models").join(&o.file)).unwrap();
            rapier3d::parry::shape::TriMesh::new(m.positions.iter().map(|p| glam::Vec3::from(*p)).collect(), m.triangles.clone()).unwrap()
        })
        .collect()
}

/// Every tactile point lies on the object's surface (1 mm), within its pad's footprint and within
/// the contact threshold of it, whatever the robot.
pub fn tactile_points_lie_on_the_object_within_their_pad(dir: &Path) {
    use rapier3d::parry::query::PointQuery;
    let ds = DatasetReader::open(dir).unwrap();
    let meshes = object_meshes(dir);
    let mut points = 0;
    // A hand that collides as its real meshes measures touch from their surfaces.
    let real_surfaces = std::fs::read_to_string(dir.join("robot/robot.yaml")).is_ok_and(|t| t.contains("hand_collision: mesh_hulls"));
    for split in ["train", "test"] {
        for s in ds.samples(split).unwrap() {
            let s = s.unwrap();
            let tac = s.tactile.as_ref().expect("robot samples carry tactile data");
            let mesh = &meshes[s.info.object_index as usize];
            let frames: std::collections::HashMap<&str, vt_dataset::Pose> =
                s.extra_transforms.iter().map(|(_, c, p)| (c.as_str(), *p)).collect();
            let to_camera = s.t_world_camera.inverse();
            let touch = s.info.robot.as_ref().and_then(|r| r.tactile.as_ref()).expect("touch info");
            for p in &tac.points {
                let pc = glam::Vec3::from(p.position).as_dvec3();
                let d = mesh.distance_to_local_point(s.t_camera_object.inverse().transform_point(pc).as_vec3(), false);
                assert!(d <= 1e-3, "{split} {}: tactile point {:.2} mm off the surface", s.index, d * 1e3);
                let name = &tac.pads[p.pad as usize];
                let local = to_camera.compose(&frames[format!("{name}_pad").as_str()]).inverse().transform_point(pc);
                let [len, wid] = touch.pads[name];
                assert!(local.x.abs() <= len / 2.0 + 1e-6 && local.y.abs() <= wid / 2.0 + 1e-6, "{local}");
                // Within the contact threshold of the pad's surface, at the distance it reports: its
                // depth from the pad plane, or (a hand on its real meshes) its height above the
                // finger's surface under its pixel, which may bulge above the plane or fall below it.
                assert!(p.distance as f64 <= 0.002 + 1e-6, "distance {}", p.distance);
                if real_surfaces {
                    assert!((local.z - p.distance as f64).abs() <= 0.01, "depth {} and distance {}", local.z, p.distance);
                } else {
                    assert!((local.z - p.distance as f64).abs() < 1e-5, "depth {} and distance {}", local.z, p.distance);
                }
                points += 1;
            }
        }
    }
    assert!(points > 0, "no tactile points");
}

/// The optical pads' images against their pad's depth view: the reference is the recorded sensor's
/// no-contact image exactly; an image differs from it (beyond noise) only near where the object is
/// within the gel; and the sensors vary between randomized samples only.
pub fn optical_images_change_only_where_the_object_is_in_the_gel(dir: &Path) {
    use vtgen::config::OpticalSensor;
    use vtgen::sensors::optical::{pixel_position, reference_image};
    let ds = DatasetReader::open(dir).unwrap();
    let (mut images, mut showing_contact) = (0, 0);
    let mut canonical_sensors = std::collections::BTreeSet::new();
    for split in ["train", "test"] {
        for s in ds.samples(split).unwrap() {
            let s = s.unwrap();
            let tac = s.tactile.as_ref().expect("tactile data");
            let touch = s.info.robot.as_ref().and_then(|r| r.tactile.as_ref()).expect("touch info");
            let sensors = touch.optical.as_ref().expect("the optical pads' sensors");
            assert_eq!(tac.optical.iter().map(|o| o.pad.as_str()).collect::<Vec<_>>(), ["left", "right"]);
            for o in &tac.optical {
                let sensor: OpticalSensor = serde_json::from_value(sensors[&o.pad].clone()).unwrap();
                if !s.info.randomized {
                    canonical_sensors.insert(serde_json::to_string(&sensor).unwrap());
                }
                assert_eq!([o.width, o.height], sensor.image_size);
                assert!(o.reference == reference_image(&sensor).rgb, "{split} {} {}: the reference is not the sensor's", s.index, o.pad);
                // The pad view's pixels where the object is within the gel (pad frame, m).
                let k = tac.pads.iter().position(|p| *p == o.pad).unwrap();
                let (n, [len, wid]) = (tac.resolution, touch.pads[&o.pad]);
                let gel = sensor.gel_thickness_mm * 1e-3;
                let inside: Vec<(f64, f64)> = (0..n * n)
                    .filter(|&i| tac.depth[k][i as usize] as f64 <= gel)
                    .map(|i| {
                        (((i % n) as f64 + 0.5 - n as f64 / 2.0) * len / n as f64, ((i / n) as f64 + 0.5 - n as f64 / 2.0) * wid / n as f64)
                    })
                    .collect();
                // How far the image may change beyond them: the gel's spread (3σ), a marker's
                // size and shift, and a pad pixel's diagonal.
                let markers = sensor.markers.map_or(0.0, |m| 2.0 * m.radius_mm * 1e-3 + m.shift * gel);
                let margin = 3.0 * sensor.elastic_spread_mm * 1e-3 + markers + (len / n as f64).hypot(wid / n as f64);
                let mut changed = 0;
                for v in 0..o.height {
                    for u in 0..o.width {
                        let i = ((v * o.width + u) * 3) as usize;
                        if (0..3).all(|c| (o.image[i + c] as f64 - o.reference[i + c] as f64).abs() <= 10.0 * sensor.noise_std.max(0.5)) {
                            continue;
                        }
                        changed += 1;
                        let (_, [x, y]) = pixel_position(&sensor, u, v);
                        let near = inside.iter().map(|(px, py)| (x - px).hypot(y - py)).fold(f64::INFINITY, f64::min);
                        assert!(
                            near <= margin,
                            "{split} {} {}: pixel ({u}, {v}) changed {:.2} mm from any contact",
                            s.index,
                            o.pad,
                            near * 1e3
                        );
                    }
                }
                images += 1;
                showing_contact += (changed > 0) as u32;
            }
        }
    }
    assert!(images == 80 && showing_contact >= 40, "{showing_contact} of {images} images show a contact");
    // The canonical samples share the configured sensor: one per pad design, here both the same.
    assert_eq!(canonical_sensors.len(), 1, "canonical samples have varied sensors");
}

/// `scenes/tiny-gripper.yaml` (the built-in UR5e + Robotiq 2F-85), generated once.
fn gripper_dataset() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| generated(&root().join("scenes/tiny-gripper.yaml"))).path()
}

#[test]
fn the_parallel_gripper_holds_objects_between_its_two_pads_and_its_ground_truth_is_exact() {
    let dir = gripper_dataset();
    let ds = DatasetReader::open(dir).unwrap();
    let mut n = 0;
    for split in ["train", "test"] {
        for s in ds.samples(split).unwrap() {
            let s = s.unwrap();
            let r = s.info.robot.as_ref().expect("a robot's info");
            // 6 arm joints and finger_joint (its five mimics follow it); both jaws touch.
            assert_eq!(r.joint_positions.len(), 7, "{:?}", r.joint_positions);
            assert_eq!(r.links_in_contact, ["left_inner_finger_pad", "right_inner_finger_pad"]);
            assert!(r.penetration_mm <= 1.0);
            assert_eq!(s.tactile.as_ref().expect("tactile data").pads, ["left", "right"]);
            let frames: Vec<&str> = s.extra_transforms.iter().map(|t| t.1.as_str()).collect();
            assert!(frames.contains(&"grasp_frame") && frames.contains(&"left_pad") && frames.contains(&"right_pad"), "{frames:?}");
            n += 1;
        }
    }
    assert_eq!(n, 40);
    crate::ground_truth::check_dataset(dir, 40);
    tactile_points_lie_on_the_object_within_their_pad(dir);
    optical_images_change_only_where_the_object_is_in_the_gel(dir);
    let o = run(&["validate", dir.to_str().unwrap()]);
    assert!(o.status.success(), "{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o));
}

#[test]
fn the_parallel_gripper_dataset_is_deterministic() {
    shard_job_matches(&root().join("scenes/tiny-gripper.yaml"), 3, gripper_dataset());
}

#[test]
fn a_workspace_the_arm_cannot_reach_is_refused_up_front() {
    let d = tempdir();
    let cfg = root().join("scenes/tiny-gripper.yaml");
    let o = run(&[
        "generate",
        cfg.to_str().unwrap(),
        "--out",
        d.path().to_str().unwrap(),
        "--quiet",
        "--set",
        "robot.base_position=[2.0,2.0,0.0]",
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("robot.grasp.palm_workspace: the arm of robot 'ur5e_robotiq_2f85' reaches 0% of 48 grasp-frame poses drawn from it"),
        "{e}"
    );
    assert!(complete_shards(d.path()).is_empty());
}

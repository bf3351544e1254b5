//! A lab's robot from its own files: the three-finger gripper of `own_robot.rs` as a ROS package
//! of its own (a hand URDF whose links are STL, OBJ and COLLADA meshes named `package://...`),
//! mounted on an arm from a second URDF. It loads, draws and collides as its meshes, generates a
//! valid dataset whose ground truth holds, deterministically; `vtgen robot check` reads it and
//! catches a workspace that puts the arm under the floor and a gripper whose pads face away.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use crate::common::*;
use crate::own_robot::{
    config_once, generated, shard_job_matches, tactile_points_lie_on_the_object_within_their_pad, three_finger_config, three_finger_urdf,
    three_finger_yaml,
};

/// A box of `size` centred at the origin as a mesh file of the given format.
fn box_file(size: [f64; 3], ext: &str) -> String {
    let h = size.map(|s| s / 2.0);
    let v: Vec<[f64; 3]> = (0..8)
        .map(|i| [if i & 1 == 0 { -h[0] } else { h[0] }, if i & 2 == 0 { -h[1] } else { h[1] }, if i & 4 == 0 { -h[2] } else { h[2] }])
        .collect();
    // Outward-facing triangles of the 6 faces.
    let tris = [
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    let mut s = String::new();
    match ext {
        "stl" => {
            s += "solid box\n";
            for t in tris {
                s += "facet normal 0 0 0\nouter loop\n";
                for i in t {
                    let _ = writeln!(s, "vertex {} {} {}", v[i][0], v[i][1], v[i][2]);
                }
                s += "endloop\nendfacet\n";
            }
            s += "endsolid box\n";
        }
        "obj" => {
            s += "mtllib box.mtl\nusemtl grey\n";
            for p in &v {
                let _ = writeln!(s, "v {} {} {}", p[0], p[1], p[2]);
            }
            for t in tris {
                let _ = writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
            }
        }
        _ => {
            // COLLADA in millimetres, Z up.
            let coords: Vec<String> = v.iter().flat_map(|p| p.map(|c| format!("{}", c * 1000.0))).collect();
            let idx: Vec<String> = tris.iter().flat_map(|t| t.map(|i| i.to_string())).collect();
            let _ = write!(
                s,
                r##"<?xml version="1.0"?><COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
<asset><unit meter="0.001" name="millimeter"/><up_axis>Z_UP</up_axis></asset>
<library_geometries><geometry id="g"><mesh>
<source id="p"><float_array id="pa" count="24">{}</float_array>
<technique_common><accessor source="#pa" count="8" stride="3"><param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/></accessor></technique_common></source>
<vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
<triangles count="12"><input semantic="VERTEX" source="#v" offset="0"/><p>{}</p></triangles>
</mesh></geometry></library_geometries>
<library_visual_scenes><visual_scene id="s"><node id="n"><instance_geometry url="#g"/></node></visual_scene></library_visual_scenes>
<scene><instance_visual_scene url="#s"/></scene></COLLADA>"##,
                coords.join(" "),
                idx.join(" ")
            );
        }
    }
    s
}

/// Writes the three-finger gripper as a package `three_finger_hand/` (its boxes as mesh files,
/// cycling through STL, OBJ and DAE) and the UR5e arm as `arm.urdf` in `dir`; returns the
/// description's text.
fn write_two_file_robot(dir: &Path) -> String {
    let whole = three_finger_urdf();
    let cut = whole.find("<link name=\"hand_adapter\">").expect("the gripper starts at its adapter");
    std::fs::write(dir.join("arm.urdf"), format!("{}</robot>\n", &whole[..cut])).unwrap();
    let pkg = dir.join("three_finger_hand");
    std::fs::create_dir_all(pkg.join("urdf")).unwrap();
    std::fs::create_dir_all(pkg.join("meshes")).unwrap();
    std::fs::write(pkg.join("meshes/box.mtl"), "newmtl grey\nKd 0.3 0.3 0.35\n").unwrap();
    // The hand alone: its mount on the flange becomes the description's `mount`.
    let mut hand = String::from("<robot name=\"three_finger_hand\">\n");
    hand += &whole[cut..].replace("</robot>\n", "");
    let mount = hand.lines().find(|l| l.contains("name=\"hand_adapter_joint\"")).expect("the adapter's joint").to_string();
    hand = hand.replace(&format!("{mount}\n"), "");
    hand += "</robot>\n";
    let mut k = 0;
    while let Some(at) = hand.find("<box size=\"") {
        let end = at + hand[at..].find("\"/>").unwrap() + 3;
        let size: Vec<f64> = hand[at + 11..end - 3].split_whitespace().map(|x| x.parse().unwrap()).collect();
        let ext = ["stl", "obj", "dae"][k % 3];
        let file = format!("box_{k}.{ext}");
        std::fs::write(pkg.join("meshes").join(&file), box_file([size[0], size[1], size[2]], ext)).unwrap();
        // Relative names and package:// names both resolve.
        let name = if k % 2 == 0 { format!("package://three_finger_hand/meshes/{file}") } else { format!("../meshes/{file}") };
        hand.replace_range(at..end, &format!("<mesh filename=\"{name}\"/>"));
        k += 1;
    }
    assert!(k >= 8, "every link's boxes became meshes ({k})");
    std::fs::write(pkg.join("urdf/hand.urdf"), hand).unwrap();
    three_finger_yaml()
        .replace("name: ur5e_three_finger", "name: ur5e_three_finger_meshes")
        .replace("urdf: three_finger.urdf\n", "urdf: arm.urdf\nhand_urdf: three_finger_hand/urdf/hand.urdf\nmount: {parent: flange}\n")
}

/// `scenes/tiny-hand.yaml` with the two-file mesh robot, in `dir`.
fn write_config(dir: &Path) -> PathBuf {
    std::fs::write(dir.join("robot.yaml"), write_two_file_robot(dir)).unwrap();
    three_finger_config(dir, "robot.yaml", "mesh-robot.yaml")
}

fn config() -> &'static Path {
    static DIR: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    config_once(&DIR, write_config)
}

fn dataset() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| generated(config())).path()
}

#[test]
fn a_mesh_robot_from_two_files_generates_a_valid_exact_deterministic_dataset() {
    let dir = dataset();
    let o = run(&["validate", "--full", dir.to_str().unwrap()]);
    assert!(o.status.success(), "{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o));
    crate::ground_truth::check_dataset(dir, 40);
    tactile_points_lie_on_the_object_within_their_pad(dir);
    shard_job_matches(config(), 2, dir);
    // Drawn as its meshes: every hand link has its mask id in some sample, and /scene/models
    // carries each link's mesh.
    let ds = vt_dataset::DatasetReader::open(dir).unwrap();
    let mut ids = std::collections::BTreeSet::new();
    for s in ds.samples("train").unwrap() {
        ids.extend(
            s.unwrap().mask.iter().copied().filter(|m| vt_dataset::mask_ids::HAND_LINKS.contains(m) || *m == vt_dataset::mask_ids::PALM),
        );
    }
    assert!(ids.contains(&vt_dataset::mask_ids::PALM) && ids.len() >= 4, "{ids:?}");
    // The dataset names the mesh files it was made from.
    let sources = std::fs::read_to_string(dir.join("sources.json")).unwrap();
    assert!(sources.contains("URDF mesh files"), "{sources}");
}

#[test]
fn robot_check_reads_a_mesh_robot_and_catches_the_floor() {
    let cfg = config();
    let o = run(&["robot", "check", cfg.to_str().unwrap()]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{out}{}", stderr(&o));
    assert!(out.contains("robot ur5e_three_finger_meshes:") && out.contains("mesh files") && out.contains("ok: no problem found"), "{out}");
    // A workspace at the floor: the arm's links go under it, and the check names the lowest.
    let o = run(&[
        "--set",
        "robot.grasp.palm_workspace={min: [-0.05, -0.05, 0.02], max: [0.05, 0.05, 0.05]}",
        "robot",
        "check",
        cfg.to_str().unwrap(),
    ]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(!o.status.success(), "{out}");
    assert!(out.contains("a link is under the floor in") && out.contains("lowest:"), "{out}");
}

#[test]
fn robot_check_catches_a_pad_facing_away_and_lists_every_missing_mesh() {
    let d = tempdir();
    // The 2F-85 (the arm's and the gripper's files, as its folder has them) with its right pad
    // frame turned to face out of the jaw.
    let desc = vt_robot::builtin_description("ur5e_robotiq_2f85").unwrap().replace("urdf: ../ur5e/arm.urdf", "urdf: arm.urdf");
    std::fs::write(d.path().join("gripper.yaml"), desc).unwrap();
    std::fs::copy(root().join("robots/ur5e/arm.urdf"), d.path().join("arm.urdf")).unwrap();
    let urdf = include_str!("../robots/ur5e_robotiq_2f85/gripper.urdf");
    let at = urdf.find("<joint name=\"right_pad_joint\"").unwrap();
    let turned = urdf[at..].replacen("rpy=\"1.57079633 0 0\"", "rpy=\"-1.57079633 0 0\"", 1);
    std::fs::write(d.path().join("gripper.urdf"), format!("{}{turned}", &urdf[..at])).unwrap();
    let text = std::fs::read_to_string(root().join("scenes/tiny-gripper.yaml"))
        .unwrap()
        .replace("  model: ur5e_robotiq_2f85", "  description: gripper.yaml");
    std::fs::write(d.path().join("c.yaml"), text).unwrap();
    let o = run(&["robot", "check", d.path().join("c.yaml").to_str().unwrap()]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        !o.status.success()
            && out.contains("pads 'left' and 'right' face each other (normals within 25° of opposite, --jaw-tolerance-deg) at no opening"),
        "{out}"
    );
    // Three mesh files gone: one error lists them all, by link.
    let m = tempdir();
    let cfg = write_config(m.path());
    for f in ["box_0.stl", "box_1.obj", "box_2.dae"] {
        std::fs::remove_file(m.path().join("three_finger_hand/meshes").join(f)).unwrap();
    }
    let o = run(&["robot", "check", cfg.to_str().unwrap()]);
    let e = stderr(&o);
    assert!(!o.status.success(), "{e}");
    assert!(e.contains("robot.description:") && e.contains("geometries cannot be loaded"), "{e}");
    for f in ["box_0.stl", "box_1.obj", "box_2.dae"] {
        assert!(e.contains(f), "{f}: {e}");
    }
    assert!(!e.contains("Mesh {"), "{e}");
}

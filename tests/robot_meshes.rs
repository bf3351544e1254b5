//! The real robot meshes (Allegro hand STL, UR5e OBJ; from `ROBOT_ASSETS`, e.g. ../shared/assets,
//! or `scripts/robot-assets`; never committed): they load into our link frames, the
//! simplified arm keeps its silhouette within a pixel at the paper camera, a dataset drawn with
//! them passes `vtgen validate --full`, and bad mesh directories give one clear error.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{DAffine3, DMat4, DVec3};
use vt_objects::TexturedMesh;
use vt_robot::Robot;
use vtgen::config::RendererConfig;
use vtgen::render::{Draw, DrawRole, Renderer, View, WgpuRenderer};
use vtgen::scene::drawable::TRIANGLES_PER_LINK;
use vtgen::scene::look_at;
use vtgen::scene::robot::link_mesh_with;

use crate::common::{root, run, stderr, tempdir};

fn assets() -> Option<PathBuf> {
    let dir = std::env::var_os("ROBOT_ASSETS").map(PathBuf::from);
    if dir.is_none() {
        eprintln!("skipped: ROBOT_ASSETS is not set (.ci/run sets it to ../shared/assets)");
    }
    dir
}

/// The built-in UR5e + Allegro drawn from the meshes in `dir` (its URDF's optional visuals).
fn real_robot(dir: &Path) -> Robot {
    Robot::builtin_with(vt_robot::DEFAULT_ROBOT, &[dir.to_path_buf()]).unwrap()
}

/// Each link drawn from meshes: whole, or simplified as the renderer draws it.
fn drawn_links(model: &vt_robot::RobotModel, simplified: bool) -> HashMap<usize, TexturedMesh> {
    let max = if simplified { TRIANGLES_PER_LINK } else { usize::MAX };
    (0..model.links.len())
        .filter(|&l| model.links[l].visuals.iter().any(|v| matches!(v.geometry, vt_robot::Geometry::Mesh { .. })))
        .filter_map(|l| link_mesh_with(model, l, max).map(|m| (l, m)))
        .collect()
}

fn z_range(m: &TexturedMesh) -> (f32, f32) {
    m.positions.iter().fold((f32::MAX, f32::MIN), |(lo, hi), p| (lo.min(p[2]), hi.max(p[2])))
}

#[test]
fn real_meshes_sit_in_our_link_frames() {
    let Some(dir) = assets() else { return };
    let robot = real_robot(&dir);
    let model = robot.model.clone();
    let meshes = drawn_links(&model, false);
    assert_eq!(meshes.len(), 7 + 17, "the arm's 7 links and the hand's palm, bases and phalanges");
    let get = |name: &str| &meshes[&model.link_id(name).unwrap()];
    // Phalanges run along their link's z from the joint to the next joint (the URDF's lengths),
    // the distal ones to the end of the fingertip (FACTS: 0.0267 + 0.012 finger, 0.0543 thumb).
    for (link, length) in
        [("ff_proximal", 0.054), ("mf_medial", 0.0384), ("ff_distal", 0.0387), ("th_medial", 0.0514), ("th_distal", 0.0543)]
    {
        let (lo, hi) = z_range(get(link));
        // The shells overlap their neighbours at the rounded joints by up to ~1 cm; a frame off by
        // a joint would be off by 1.6 cm or more.
        assert!(lo.abs() < 0.012 && (hi as f64 - length).abs() < 0.012, "{link}: z from {lo} to {hi}, length {length}");
    }
    // The upper arm runs from the shoulder to the elbow, 0.425 m along -x of our shoulder_lift_link.
    let upper = get("shoulder_lift_link");
    let (lo, hi) = upper.positions.iter().fold((f32::MAX, f32::MIN), |(lo, hi), p| (lo.min(p[0]), hi.max(p[0])));
    assert!((lo + 0.425 + 0.06).abs() < 0.04 && hi.abs() < 0.1, "upper arm x from {lo} to {hi}");
    assert_eq!(upper.triangle_count(), 40_120, "whole");
    let drawn = drawn_links(&model, true);
    let drawn_count = |name: &str| drawn[&model.link_id(name).unwrap()].triangle_count();
    assert!(drawn_count("shoulder_lift_link") <= 4 * TRIANGLES_PER_LINK / 3, "simplified: {}", drawn_count("shoulder_lift_link"));
    assert!(drawn_count("palm") < get("palm").triangle_count(), "the drawn hand is simplified too");
}

/// Pixels set in `a` and not in `b` with no pixel of `b` within one pixel.
fn outside_one_pixel(a: &[u8], b: &[u8], w: usize, h: usize) -> usize {
    let near_b = |x: usize, y: usize| {
        (y.saturating_sub(1)..=(y + 1).min(h - 1)).any(|yy| (x.saturating_sub(1)..=(x + 1).min(w - 1)).any(|xx| b[yy * w + xx] != 0))
    };
    (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).filter(|&(x, y)| a[y * w + x] != 0 && !near_b(x, y)).count()
}

#[test]
fn the_simplified_robot_keeps_its_silhouette_within_a_pixel_at_the_paper_camera() {
    let Some(dir) = assets() else { return };
    let robot = real_robot(&dir);
    let model = robot.model.clone();
    let full = drawn_links(&model, false);
    let simplified = drawn_links(&model, true);
    // scenes/paper.yaml: its camera, its robot base, the arm at its home pose.
    let paper = vtgen::config::LoadedConfig::load(&root().join("scenes/paper.yaml")).unwrap().config;
    let cam = &paper.camera;
    let view = View::of_camera(cam, look_at(DVec3::from_array(cam.position), DVec3::from_array(cam.look_at)).matrix());
    let rc = paper.robot.as_ref().unwrap();
    let t_world_base = DAffine3::from_rotation_translation(
        glam::DQuat::from_rotation_z(rc.base_yaw_deg.to_radians()),
        DVec3::from_array(rc.base_position),
    );
    let mut q = model.zero();
    for (&d, &v) in robot.arm_dofs.iter().zip(&rc.grasp.home_arm) {
        q[d] = v;
    }
    let links = model.forward_kinematics(&q);
    let mut r = WgpuRenderer::new(&RendererConfig::default()).unwrap();
    let mut checked = 0;
    let arm = ["base_link", "shoulder_pan_link", "shoulder_lift_link", "elbow_link", "wrist_1_link", "wrist_2_link", "wrist_3_link"];
    let hand = ["palm", "ff_base", "ff_proximal", "mf_medial", "rf_distal", "th_base", "th_proximal", "th_medial", "th_distal"];
    for name in arm.into_iter().chain(hand) {
        let id = model.link_id(name).unwrap();
        let pose = DMat4::from(t_world_base * links[id]);
        let mut mask = |m: &TexturedMesh| {
            let h = r.upload_mesh(m).unwrap();
            r.render_mask(&view, &[Draw { mesh: h, t_world_model: pose, mask_id: 1, role: DrawRole::Target }]).unwrap()
        };
        let (a, b) = (mask(&full[&id]), mask(&simplified[&id]));
        let seen = a.iter().filter(|&&m| m != 0).count();
        let (w, h) = (view.width as usize, view.height as usize);
        let (extra, missing) = (outside_one_pixel(&b, &a, w, h), outside_one_pixel(&a, &b, w, h));
        eprintln!(
            "{name}: {} -> {} triangles, {seen} px, {extra} px added and {missing} lost beyond 1 px",
            full[&id].triangle_count(),
            simplified[&id].triangle_count()
        );
        assert_eq!((extra, missing), (0, 0), "{name}: the simplified silhouette leaves the full one's by more than 1 px");
        checked += (seen > 0) as usize;
    }
    assert!(checked >= 4, "the arm is in view");
}

/// `scenes/tiny-hand.yaml` generated with the real robot (once per test run).
fn real_robot_dataset(assets: &Path) -> &'static Path {
    static DIR: std::sync::OnceLock<tempfile::TempDir> = std::sync::OnceLock::new();
    DIR.get_or_init(|| {
        let out = tempdir();
        let config = root().join("scenes/tiny-hand.yaml");
        let o = run(&[
            "generate",
            config.to_str().unwrap(),
            "--out",
            out.path().to_str().unwrap(),
            "--quiet",
            "--robot-assets",
            assets.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(!stderr(&o).contains("from primitives"), "{}", stderr(&o));
        out
    })
    .path()
}

#[test]
fn a_dataset_drawn_with_the_real_robot_is_valid_and_deterministic() {
    let Some(dir) = assets() else { return };
    let out = real_robot_dataset(&dir);
    let o = run(&["validate", out.to_str().unwrap(), "--full"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // The same config and meshes give the same bytes, the mesh directory given by the config's
    // `robot.assets` this time, and a copy of it: the same source in another place.
    let again = tempdir();
    let copy = again.path().join("robot-assets");
    for sub in ["allegro/meshes", "ur5e/visual"] {
        std::fs::create_dir_all(copy.join(sub)).unwrap();
        for e in std::fs::read_dir(dir.join(sub)).unwrap() {
            let p = e.unwrap().path();
            std::fs::copy(&p, copy.join(sub).join(p.file_name().unwrap())).unwrap();
        }
    }
    let text = std::fs::read_to_string(root().join("scenes/tiny-hand.yaml")).unwrap();
    let config = again.path().join("tiny-hand.yaml");
    std::fs::write(&config, text.replacen("robot:\n", &format!("robot:\n  assets: {}\n", copy.display()), 1)).unwrap();
    let out_again = again.path().join("out");
    let o = crate::common::vtgen()
        .args(["generate", config.to_str().unwrap(), "--out", out_again.to_str().unwrap(), "--quiet"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let (a, b) = (crate::common::files(out), crate::common::files(&out_again));
    assert_eq!(a.len(), b.len());
    for ((na, ba), (nb, bb)) in a.iter().zip(&b) {
        assert_eq!(na, nb);
        assert!(ba == bb, "{na} differs between two runs with the real robot");
    }
}

#[test]
fn tactile_points_lie_on_the_object_and_at_the_real_finger_surface() {
    use rapier3d::parry::query::PointQuery;
    let Some(dir) = assets() else { return };
    let out = real_robot_dataset(&dir);
    let robot = real_robot(&dir);
    let model = robot.model.clone();
    let hand = vtgen::assets::robot::hand_surface_meshes(&robot).unwrap();
    let trimesh = |m: &TexturedMesh| {
        let v = m.positions.iter().map(|p| glam::Vec3::from(*p)).collect();
        let t = m.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        rapier3d::parry::shape::TriMesh::new(v, t).unwrap()
    };
    let fingers: HashMap<String, rapier3d::parry::shape::TriMesh> =
        robot.pad_names().into_iter().map(|n| (n.clone(), trimesh(&hand[&model.link_id(&n).unwrap()]))).collect();
    let info: vt_dataset::ModelsInfo = serde_json::from_slice(&std::fs::read(out.join("models/models_info.json")).unwrap()).unwrap();
    let objects: Vec<rapier3d::parry::shape::TriMesh> = info
        .objects
        .iter()
        .map(|o| {
            let m = vt_dataset::read_ply(&out.join("models").join(&o.file)).unwrap();
            rapier3d::parry::shape::TriMesh::new(m.positions.iter().map(|p| glam::Vec3::from(*p)).collect(), m.triangles.clone()).unwrap()
        })
        .collect();
    let ds = vt_dataset::DatasetReader::open(out).unwrap();
    let mut finger_mm = Vec::new();
    let mut distance_mm = Vec::new();
    for split in ["train", "test"] {
        for s in ds.samples(split).unwrap() {
            let s = s.unwrap();
            let tac = s.tactile.as_ref().unwrap();
            let frames: HashMap<&str, vt_dataset::Pose> = s.extra_transforms.iter().map(|(_, c, p)| (c.as_str(), *p)).collect();
            let object = &objects[s.info.object_index as usize];
            let to_object = s.t_camera_object.inverse();
            for p in &tac.points {
                let on_object =
                    object.distance_to_local_point(to_object.transform_point(glam::Vec3::from(p.position).as_dvec3()).as_vec3(), false);
                assert!(on_object <= 1e-3, "{split} {}: tactile point {:.2} mm off the object", s.index, on_object * 1e3);
                let name = &tac.pads[p.pad as usize];
                // Camera frame -> world -> the phalanx's link frame.
                let world = s.t_world_camera.transform_point(glam::Vec3::from(p.position).as_dvec3());
                let local = frames[name.as_str()].inverse().transform_point(world);
                finger_mm.push(1e3 * fingers[name].distance_to_local_point(local.as_vec3(), false) as f64);
                distance_mm.push(1e3 * p.distance as f64);
            }
        }
    }
    assert!(finger_mm.len() > 100, "{} tactile points", finger_mm.len());
    finger_mm.sort_by(f64::total_cmp);
    let pct = |q: f64| finger_mm[((finger_mm.len() - 1) as f64 * q) as usize];
    eprintln!(
        "{} tactile points; distance to the real finger surface: median {:.2} mm, 90% {:.2} mm, max {:.2} mm",
        finger_mm.len(),
        pct(0.5),
        pct(0.9),
        pct(1.0)
    );
    // A pixel is a contact when the object is within 2 mm (contact_threshold_mm) of the finger's
    // real surface under it, along the pad's normal: the points are where the drawn finger
    // touches the object (half a pixel of the 32x32 pad for the raster).
    assert!(pct(1.0) <= 2.0 + 0.5, "median {:.2} mm, max {:.2} mm", pct(0.5), pct(1.0));
    // A point's distance is the object's above the real finger surface under its pixel: on the
    // round fingertips it reads no deeper press than the physics lets the object in (1 mm, plus
    // the slant of a round surface along the pad's normal), where a flat pad's plane read 5 mm.
    let pressed = distance_mm.iter().filter(|&&d| d < -1.0).count() as f64 / distance_mm.len() as f64;
    let deepest = distance_mm.iter().copied().fold(f64::MAX, f64::min);
    eprintln!("tactile distances: {:.1}% below -1 mm, deepest {deepest:.2} mm", 100.0 * pressed);
    assert!(pressed <= 0.02 && deepest >= -2.0, "{:.1}% below -1 mm, deepest {deepest:.2} mm", 100.0 * pressed);
}

#[test]
fn each_pad_sits_on_its_phalanx_real_surface() {
    use rapier3d::parry::query::PointQuery;
    let Some(dir) = assets() else { return };
    let robot = real_robot(&dir);
    let hand = vtgen::assets::robot::hand_surface_meshes(&robot).unwrap();
    let real = vtgen::assets::robot::with_real_hand(&robot, &hand).unwrap();
    let q = real.zero();
    let links = real.forward_kinematics(&q);
    for name in robot.pad_names() {
        let id = real.link_id(&name).unwrap();
        let pad = real.link_id(&format!("{name}_pad")).unwrap();
        let t_link_pad = links[id].inverse() * links[pad];
        let m = &hand[&id];
        let trimesh = rapier3d::parry::shape::TriMesh::new(
            m.positions.iter().map(|p| glam::Vec3::from(*p)).collect(),
            m.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
        )
        .unwrap();
        let d = trimesh.distance_to_local_point(t_link_pad.translation.as_vec3(), false) as f64;
        assert!(d <= 1e-3, "{name}: the pad origin is {:.2} mm from the real finger surface", d * 1e3);
        // z out of the finger: the palmar side (+x of the link), as the URDF's pads (their rpy
        // written to 8 digits).
        assert!((t_link_pad.transform_vector3(DVec3::Z) - DVec3::X).length() < 1e-7, "{name}");
    }
}

fn write(dir: &Path, rel: &str, bytes: &[u8]) {
    let p = dir.join(rel);
    std::fs::create_dir_all(p.parent().unwrap()).unwrap();
    std::fs::write(p, bytes).unwrap();
}

#[test]
fn bad_robot_mesh_directories_give_one_clear_error_naming_the_path() {
    let err = |dir: &Path| {
        let config = tempdir();
        let path = config.path().join("c.yaml");
        std::fs::write(&path, "objects: [005_tomato_soup_can]\nrobot: {}\n").unwrap();
        vtgen::config::LoadedConfig::load_with_assets(&path, &[], Some(dir)).map(|_| ()).unwrap_err().to_string()
    };
    // A directory of another robot (or of nothing).
    let other = tempdir();
    write(other.path(), "meshes/panda_link0.dae", b"<COLLADA/>");
    let e = err(other.path());
    assert!(
        e.contains("none of the meshes of robot 'ur5e_allegro'")
            && e.contains("ur5e/visual/base.obj")
            && e.contains("scripts/robot-assets"),
        "{e}"
    );
    // A corrupt STL.
    let corrupt = tempdir();
    if let Some(dir) = std::env::var_os("ROBOT_ASSETS").map(PathBuf::from) {
        for sub in ["allegro/meshes", "ur5e/visual"] {
            std::fs::create_dir_all(corrupt.path().join(sub)).unwrap();
            for f in std::fs::read_dir(dir.join(sub)).unwrap() {
                let f = f.unwrap().path();
                std::fs::copy(&f, corrupt.path().join(sub).join(f.file_name().unwrap())).unwrap();
            }
        }
        write(corrupt.path(), "allegro/meshes/base_link.STL", b"solid nothing useful\n");
        let e = err(corrupt.path());
        assert!(e.contains("base_link.STL") && e.contains("link 'palm' visual"), "{e}");
    }
    // A missing mesh of an otherwise complete directory.
    if let Some(dir) = std::env::var_os("ROBOT_ASSETS").map(PathBuf::from) {
        let partial = tempdir();
        for sub in ["allegro/meshes", "ur5e/visual"] {
            std::fs::create_dir_all(partial.path().join(sub)).unwrap();
            for f in std::fs::read_dir(dir.join(sub)).unwrap() {
                let f = f.unwrap().path();
                if f.file_name().unwrap() != "link_14.0.STL" {
                    std::fs::copy(&f, partial.path().join(sub).join(f.file_name().unwrap())).unwrap();
                }
            }
        }
        let e = err(partial.path());
        assert!(e.contains("link_14.0.STL") && e.contains("1 are not"), "{e}");
    }
    // The CLI: one error line, exit status 1.
    let config = root().join("scenes/tiny-hand.yaml");
    let out = tempdir();
    let o = run(&[
        "generate",
        config.to_str().unwrap(),
        "--out",
        out.path().to_str().unwrap(),
        "--quiet",
        "--robot-assets",
        "/nonexistent/robot",
    ]);
    assert!(!o.status.success());
    let s = stderr(&o);
    assert!(s.contains("/nonexistent/robot") && s.lines().filter(|l| l.starts_with("error:")).count() == 1, "{s}");
}

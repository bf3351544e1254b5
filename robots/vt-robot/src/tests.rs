use glam::{DAffine3, DQuat, DVec3};

use super::*;
use crate::GraspKind;

/// The default robot's URDF text: its arm's and its hand's, as one tree.
fn default_urdf() -> String {
    builtin_urdf(crate::DEFAULT_ROBOT).unwrap()
}

/// The default robot's hand, as its folder carries it.
const HAND: &str = include_str!("../../ur5e_allegro/hand.urdf");

/// The default robot as one URDF file: the arm, `between` (links and joints below the flange), and
/// the hand's links and joints with its adapter fixed to `hand_parent`.
fn allegro_on(between: &str, hand_parent: &str) -> String {
    let arm = include_str!("../../ur5e/arm.urdf");
    let arm = &arm[..arm.rfind("</robot>").unwrap()];
    let open = HAND.find("<robot").unwrap();
    let body = &HAND[open + HAND[open..].find('>').unwrap() + 1..HAND.rfind("</robot>").unwrap()];
    format!(
        "{arm}{between}<joint name=\"hand_adapter_joint\" type=\"fixed\"><parent link=\"{hand_parent}\"/><child link=\"hand_adapter\"/></joint>{body}</robot>\n"
    )
}

fn model() -> RobotModel {
    Robot::default_robot().model
}

const PALM: &str = "palm";

/// Fingertip sphere centre in the palm frame (FACTS: 0.0267 beyond j3 for fingers, 0.0423 thumb).
fn tip(m: &RobotModel, finger: &str, q4: [f64; 4]) -> DVec3 {
    let mut q = m.zero();
    for k in 0..4 {
        q[m.dof(&format!("{finger}_joint_{k}")).unwrap()] = q4[k];
    }
    let palm = m.link_id(PALM).unwrap();
    let distal = m.link_id(&format!("{finger}_distal")).unwrap();
    let len = if finger == "th" { 0.0423 } else { 0.0267 };
    m.relative_pose(&q, palm, distal).transform_point3(DVec3::new(0.0, 0.0, len))
}

#[test]
fn hand_forward_kinematics_matches_the_published_check_vectors() {
    let m = model();
    let cases: [(&str, [f64; 4], [f64; 3]); 9] = [
        ("ff", [0.0; 4], [0.0, 0.0553, 0.1334]),
        ("mf", [0.0; 4], [0.0, 0.0, 0.1362]),
        ("rf", [0.0; 4], [0.0, -0.0553, 0.1334]),
        ("ff", [0.3, 0.5, 0.5, 0.5], [0.0810, 0.0760, 0.0824]),
        ("mf", [0.3, 0.5, 0.5, 0.5], [0.0810, 0.0251, 0.0871]),
        ("rf", [0.3, 0.5, 0.5, 0.5], [0.0810, -0.0261, 0.0867]),
        ("th", [0.263, 0.0, 0.0, 0.0], [0.0260, 0.1612, -0.0855]),
        ("th", [0.3, 0.5, 0.5, 0.5], [0.0513, 0.1311, -0.0298]),
        ("th", [1.0, 0.5, 0.5, 0.5], [0.1058, 0.0608, -0.0237]),
    ];
    for (f, q, want) in cases {
        let got = tip(&m, f, q);
        assert!((got - DVec3::from_array(want)).length() < 2e-4, "{f} {q:?}: {got} vs {want:?}");
    }
}

#[test]
fn arm_forward_kinematics_matches_the_dh_check_vectors() {
    let robot = Robot::default_robot();
    let m = &robot.model;
    let flange = m.link_id("flange").unwrap();
    let arm = &robot.arm_dofs;
    let cases: [([f64; 6], [f64; 3]); 3] = [
        ([0.0; 6], [-0.8172, -0.2329, 0.0628]),
        ([0.0, -std::f64::consts::FRAC_PI_2, 0.0, -std::f64::consts::FRAC_PI_2, 0.0, 0.0], [0.0, -0.2329, 1.0794]),
        (
            [
                -std::f64::consts::FRAC_PI_2,
                -std::f64::consts::FRAC_PI_2,
                std::f64::consts::FRAC_PI_2,
                -std::f64::consts::FRAC_PI_2,
                -std::f64::consts::FRAC_PI_2,
                0.0,
            ],
            [-0.1333, 0.4919, 0.4879],
        ),
    ];
    for (qa, want) in cases {
        let mut q = m.zero();
        for k in 0..6 {
            q[arm[k]] = qa[k];
        }
        let got = m.forward_kinematics(&q)[flange].translation;
        assert!((got - DVec3::from_array(want)).length() < 2e-4, "{qa:?}: {got} vs {want:?}");
    }
}

#[test]
fn sensor_pads_sit_on_the_palmar_surface_facing_out() {
    let robot = Robot::default_robot();
    let m = &robot.model;
    let q = m.zero();
    for p in robot.pad_names() {
        let link = m.link_id(&p).unwrap();
        let pad = m.link_id(&format!("{p}_pad")).unwrap();
        let t = m.relative_pose(&q, link, pad);
        // z of the pad is +x of the phalanx (the side the finger flexes towards).
        assert!((t.matrix3.z_axis - DVec3::X).length() < 1e-7, "{p}");
        assert!((t.translation.x - 0.0098).abs() < 1e-9, "{p} on the surface");
    }
    assert_eq!((robot.hand.len(), robot.pads.len(), robot.touch_links.len()), (16, 12, 12));
    assert_eq!(m.dof_count(), 22);
    assert!(robot.followers.is_empty());
}

#[test]
fn ik_reaches_poses_in_front_of_the_robot() {
    let robot = Robot::default_robot();
    let arm = &robot.arm_dofs;
    let mut seed = robot.model.zero();
    use std::f64::consts::FRAC_PI_2;
    for (k, v) in [-FRAC_PI_2, -FRAC_PI_2, FRAC_PI_2, -FRAC_PI_2, -FRAC_PI_2, 0.0].into_iter().enumerate() {
        seed[arm[k]] = v;
    }
    for (i, p) in [[0.0, 0.45, 0.35], [0.1, 0.5, 0.25], [-0.15, 0.4, 0.45], [0.3, -0.4, 0.3]].into_iter().enumerate() {
        let rot = DQuat::from_rotation_x(std::f64::consts::PI - 0.4 * i as f64) * DQuat::from_rotation_y(0.3 * i as f64);
        let target = DAffine3::from_rotation_translation(rot, DVec3::from_array(p));
        let q = robot.solve_grasp_ik(&target, &seed, &IkOptions::default()).unwrap_or_else(|| panic!("pose {i} reachable"));
        let got = robot.grasp_frame_pose(&q);
        assert!((got.translation - target.translation).length() < 1e-4);
        assert!((got.matrix3 - target.matrix3).abs().to_cols_array().iter().all(|&x| x < 1e-3));
    }
}

#[test]
fn ik_never_turns_a_joint_a_whole_turn_from_its_seed() {
    // Palm poses over the workspace from seeds around the home pose: the local solver and its
    // retries from a turned first joint land some joints a turn or more from their seeds; the
    // answer is the same pose with every revolute arm joint within half a turn of its seed
    // wherever its range allows (the elbow's one turn of range does not always).
    let robot = Robot::default_robot();
    let arm = &robot.arm_dofs;
    use rand::{Rng, SeedableRng};
    use std::f64::consts::{FRAC_PI_2, PI, TAU};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let (mut solved, mut near_a_turn_away) = (0, 0);
    for _ in 0..150 {
        let mut seed = robot.model.zero();
        for (k, v) in [-FRAC_PI_2, -FRAC_PI_2, FRAC_PI_2, -FRAC_PI_2, -FRAC_PI_2, 0.0].into_iter().enumerate() {
            seed[arm[k]] = v + rng.random_range(-1.5..1.5);
        }
        let rot = DQuat::from_rotation_x(PI + rng.random_range(-1.2..1.2)) * DQuat::from_rotation_z(rng.random_range(-PI..PI));
        let p = DVec3::new(rng.random_range(-0.2..0.2), rng.random_range(0.3..0.6), rng.random_range(0.2..0.45));
        let target = DAffine3::from_rotation_translation(rot, p);
        let Some(q) = robot.solve_grasp_ik(&target, &seed, &IkOptions::default()) else { continue };
        solved += 1;
        let got = robot.grasp_frame_pose(&q);
        assert!((got.translation - target.translation).length() < 1e-4);
        for (&d, &j) in arm.iter().zip(&robot.arm_joints) {
            let jt = &robot.model.joints[j];
            let off = q[d] - seed[d];
            let other = q[d] - off.signum() * TAU;
            if off.abs() > PI && (jt.lower..=jt.upper).contains(&other) {
                panic!("{}: {:.2} from its seed {:.2}; {:.2} is the same pose and within its range", jt.name, q[d], seed[d], other);
            }
            near_a_turn_away += usize::from(off.abs() > PI);
        }
    }
    assert!(solved >= 100, "{solved} of 150 poses reached");
    // Only the elbow, whose range is one turn, may be further than half a turn from its seed.
    assert!(near_a_turn_away <= 5, "{near_a_turn_away}");
}

#[test]
fn broken_urdfs_give_clear_errors() {
    let cases = [
        (HAND.replace("<parent link=\"ff_base\"/>", "<parent link=\"ff_bse\"/>"), "missing parent link 'ff_bse'"),
        (HAND.replace("lower=\"-0.47\" upper=\"0.47\"", "lower=\"0.47\" upper=\"-0.47\""), "lower limit 0.47 is above upper limit -0.47"),
        ("<robot name=\"x\"><link name=\"a\"/>".to_string(), "not valid URDF"),
    ];
    for (text, want) in cases {
        let e = RobotModel::from_urdf_with(&text, "bad.urdf", &MeshPaths::default(), VisualMeshes::Optional).unwrap_err().to_string();
        assert!(e.starts_with("robot description bad.urdf: ") && e.contains(want), "{e}");
    }
}

/// The Allegro description with `from` replaced by `to`, resolved; the error it gives.
fn description_error(from: &str, to: &str) -> String {
    let text = include_str!("../../ur5e_allegro/robot.yaml");
    assert!(text.contains(from), "{from}");
    Robot::from_texts(&default_urdf(), "ur5e_allegro.urdf", &text.replacen(from, to, 1), "bad.yaml").unwrap_err().to_string()
}

#[test]
fn broken_descriptions_name_the_file_and_the_field() {
    let cases = [
        ("link: ff_distal,", "link: ff_distl,", "line 48: pads[2].link: no link 'ff_distl' in the URDF"),
        ("base: base_link", "base: palm", "arm: 'flange' is not below 'palm': the arm is not one serial chain"),
        ("frame: palm", "frame: base_link", "grasp.frame: 'base_link' is not fixed below the flange 'flange'"),
        ("frame: palm", "frame: ff_distal", "grasp.frame: 'ff_distal' moves against the flange"),
        ("joint: th_joint_2,", "joint: th_joint_x,", "hand[14].joint: no joint 'th_joint_x' in the URDF"),
        ("joint: th_joint_2,", "joint: shoulder_pan_joint,", "hand[14].joint: 'shoulder_pan_joint' is not below the hand's root 'palm'"),
        ("- {joint: th_joint_3, preshape: [-0.1, 0.3], close: 1.2}\n", "", "joint 'th_joint_3' moves in the hand but is neither listed"),
        ("preshape: [0.3, 0.5]", "preshape: [0.5, 0.3]", "hand[12].preshape: [0.5, 0.3] is not a range"),
        ("frame: th_distal_pad,", "frame: th_medial_pad,", "pads[11].frame: 'th_medial_pad' is not a link fixed to 'th_distal'"),
        ("min_touching: 2", "min_touching: 13", "grasp.min_touching: 13 is not within 1 ..= the 12 touch links"),
        ("home: [-1.5707963267948966, ", "home: [", "arm.home: 5 values for 6 arm joints"),
        ("kind: palm", "kind: suction", "line 21: grasp.kind: unknown variant `suction`"),
        ("min_touching: 2", "min_touching: 2\n  fingers: 4", "line 23: grasp: unknown field `fingers`"),
        (
            "frame: ff_medial_pad,",
            "frame: ff_medial_pad, contact: {modulus_mpa: 0, crown_radius_mm: 20},",
            "pads[1].contact.modulus_mpa: 0: must be positive (MPa)",
        ),
    ];
    for (from, to, want) in cases {
        let e = description_error(from, to);
        // Every error names the file, the line and the field.
        assert!(e.starts_with("robot description bad.yaml: line ") && e.contains(want), "{from} -> {to}: {e}");
    }
    // A pad given by an origin on its link becomes a frame of its own.
    let text = include_str!("../../ur5e_allegro/robot.yaml").replacen(
        "name: ff_distal, link: ff_distal, frame: ff_distal_pad,",
        "name: ff_tip, link: ff_distal, origin: {xyz: [0.0098, 0, 0.02], rpy: [0, 1.5707963267948966, 0]}, size: [0.03, 0.02],",
        1,
    );
    let robot = Robot::from_texts(&default_urdf(), "u", &text, "d").unwrap();
    let pad = &robot.pads[2];
    assert_eq!((robot.model.links[pad.frame].name.as_str(), pad.size), ("ff_tip_pad", Some((0.03, 0.02))));
    assert_eq!(robot.model.relative_pose(&robot.model.zero(), pad.link, pad.frame).translation, DVec3::new(0.0098, 0.0, 0.02));
}

#[test]
fn mimic_and_prismatic_joints_follow_their_leader() {
    let urdf = r#"<robot name="jaw">
      <link name="base"/><link name="a"/><link name="b"/>
      <joint name="slide" type="prismatic"><parent link="base"/><child link="a"/><axis xyz="0 1 0"/>
        <limit lower="0" upper="0.04" effort="20" velocity="1"/></joint>
      <joint name="mirror" type="prismatic"><parent link="base"/><child link="b"/><axis xyz="0 1 0"/>
        <limit lower="-0.04" upper="0" effort="20" velocity="1"/><mimic joint="slide" multiplier="-1" offset="0.001"/></joint>
    </robot>"#;
    let m = RobotModel::from_urdf_str(urdf, "jaw.urdf").unwrap();
    assert_eq!(m.dof_names(), vec!["slide"]);
    let links = m.forward_kinematics(&[0.03]);
    assert!((links[m.link_id("a").unwrap()].translation - DVec3::new(0.0, 0.03, 0.0)).length() < 1e-12);
    assert!((links[m.link_id("b").unwrap()].translation - DVec3::new(0.0, -0.029, 0.0)).length() < 1e-12);
    let missing = urdf.replace(r#"<mimic joint="slide""#, r#"<mimic joint="slid""#);
    let e = RobotModel::from_urdf_str(&missing, "jaw.urdf").unwrap_err().to_string();
    assert!(e.contains("joint 'mirror': <mimic joint=\"slid\"> names a joint that does not exist"), "{e}");
}

#[test]
fn the_robotiq_gripper_closes_its_parallel_pads_symmetrically() {
    let robot = Robot::builtin("ur5e_robotiq_2f85").unwrap();
    assert_eq!((robot.kind, robot.hand.len(), robot.followers.len(), robot.pads.len()), (GraspKind::ParallelJaw, 1, 5, 2));
    let m = &robot.model;
    let grasp = robot.grasp_frame;
    for closed in [0.0, 0.4, 0.8] {
        let mut q = m.zero();
        robot.set_hand(&mut q, &[closed]);
        let links = m.forward_kinematics(&q);
        let [l, r] = [0, 1].map(|k| links[grasp].inverse() * links[robot.pads[k].frame]);
        // Mirror images across the grasp frame's x-z plane, facing each other along y.
        assert!((l.translation.y + r.translation.y).abs() < 1e-9 && (l.translation.x - r.translation.x).abs() < 1e-9);
        assert!((l.matrix3.z_axis - DVec3::Y).length() < 1e-6 && (r.matrix3.z_axis + DVec3::Y).length() < 1e-6, "{closed}");
        if closed == 0.0 {
            // Open: 85 mm between the pads' faces, centred on the grasp frame.
            assert!((r.translation.y - l.translation.y - 0.086).abs() < 1e-3 && l.translation.length() - 0.043 < 1e-3, "{l:?}");
        }
    }
}

/// A two-link gripper URDF whose hand and finger are mesh files in a package laid out as ROS
/// keeps it (`<root>/my_gripper/{urdf,meshes}`), and a cube OBJ of half-size `h` there.
fn mesh_package(root: &std::path::Path, finger_mesh: &str) -> std::path::PathBuf {
    let pkg = root.join("my_gripper");
    std::fs::create_dir_all(pkg.join("urdf")).unwrap();
    std::fs::create_dir_all(pkg.join("meshes")).unwrap();
    let cube = |h: f64| {
        let mut s = String::new();
        for i in 0..8 {
            let c = |b: usize| if i & b == 0 { -h } else { h };
            s += &format!("v {} {} {}\n", c(1), c(2), c(4));
        }
        for f in ["1 3 4 2", "5 6 8 7", "1 2 6 5", "3 7 8 4", "1 5 7 3", "2 4 8 6"] {
            s += &format!("f {f}\n");
        }
        s
    };
    std::fs::write(pkg.join("meshes/hand.obj"), cube(0.02)).unwrap();
    std::fs::write(pkg.join("meshes/finger.obj"), cube(0.005)).unwrap();
    let urdf = format!(
        r#"<robot name="g">
      <link name="hand"><visual><geometry><mesh filename="package://my_gripper/meshes/hand.obj"/></geometry></visual>
        <collision><geometry><mesh filename="package://my_gripper/meshes/hand.obj" scale="1 1 2"/></geometry></collision></link>
      <link name="finger"><inertial><mass value="0.02"/><inertia ixx="1e-6" ixy="0" ixz="0" iyy="1e-6" iyz="0" izz="1e-6"/></inertial>
        <visual><geometry><mesh filename="{finger_mesh}"/></geometry></visual>
        <collision><geometry><mesh filename="../meshes/finger.obj"/></geometry></collision></link>
      <link name="tool"/>
      <joint name="slide" type="prismatic"><parent link="hand"/><child link="finger"/><origin xyz="0 0 0.05"/><axis xyz="0 1 0"/>
        <limit lower="0" upper="0.04" effort="30" velocity="1"/></joint>
      <joint name="tool_joint" type="fixed"><parent link="hand"/><child link="tool"/><origin xyz="0 0 0.1"/></joint>
    </robot>"#
    );
    let path = pkg.join("urdf/gripper.urdf");
    std::fs::write(&path, urdf).unwrap();
    path
}

#[test]
fn mesh_geometry_is_read_and_collides_as_its_hull() {
    let dir = tempfile::tempdir().unwrap();
    let path = mesh_package(dir.path(), "package://my_gripper/meshes/finger.obj");
    let m = RobotModel::from_urdf_file(&path).unwrap();
    let hand = m.link("hand").unwrap();
    let Geometry::Mesh { mesh } = &hand.visuals[0].geometry else { panic!("a visual mesh: {:?}", hand.visuals[0].geometry) };
    assert_eq!((mesh.triangles.len(), mesh.distinct_points().len()), (12, 8));
    // The collision mesh is its hull's points, scaled per axis.
    let points = hand.collisions[0].geometry.hull_points().expect("a collision mesh collides as its hull");
    assert_eq!(points.len(), 8);
    assert!(points.iter().all(|p| (p.z.abs() - 0.04).abs() < 1e-9 && (p.x.abs() - 0.02).abs() < 1e-9));
    assert_eq!(m.mesh_files.len(), 2, "{:?}", m.mesh_files);
}

#[test]
fn every_missing_mesh_is_listed_at_once_with_its_link() {
    let dir = tempfile::tempdir().unwrap();
    let path = mesh_package(dir.path(), "package://my_gripper/meshes/fingr.obj");
    std::fs::remove_file(dir.path().join("my_gripper/meshes/hand.obj")).unwrap();
    let e = RobotModel::from_urdf_file(&path).unwrap_err().to_string();
    assert!(e.contains("3 geometries cannot be loaded"), "{e}");
    for want in [
        "link 'hand' visual 0: mesh 'package://my_gripper/meshes/hand.obj': file not found",
        "link 'hand' collision 0: mesh 'package://my_gripper/meshes/hand.obj'",
        "link 'finger' visual 0: mesh 'package://my_gripper/meshes/fingr.obj'",
    ] {
        assert!(e.contains(want), "{want}: {e}");
    }
    assert!(!e.contains("Mesh {"), "no Debug text: {e}");
    // A URDF given as text cannot find relative meshes, and says so.
    let text = std::fs::read_to_string(&path).unwrap();
    let e = RobotModel::from_urdf_str(&text, "g.urdf").unwrap_err().to_string();
    assert!(e.contains("needs the URDF's folder"), "{e}");
}

/// The built-in UR5e arm up to its flange: its primitives (the real meshes' visuals left out).
fn ur5e_arm_urdf() -> String {
    include_str!("../../ur5e/arm.urdf").lines().filter(|l| !l.contains("<mesh filename=")).map(|l| format!("{l}\n")).collect()
}

#[test]
fn an_arm_and_a_gripper_from_two_files_with_a_grasp_frame_offset_and_urdf_drive_defaults() {
    let dir = tempfile::tempdir().unwrap();
    mesh_package(dir.path(), "package://my_gripper/meshes/finger.obj");
    std::fs::write(dir.path().join("arm.urdf"), ur5e_arm_urdf()).unwrap();
    let description = "name: two_files\nurdf: arm.urdf\nhand_urdf: my_gripper/urdf/gripper.urdf\n\
        mount: {parent: flange, origin: {xyz: [0, 0, 0.01], rpy: [0, 0, 0.5]}}\n\
        arm: {base: base_link, flange: flange, home: [-1.5707963267948966, -1.5707963267948966, 1.5707963267948966, -1.5707963267948966, -1.5707963267948966, 0.0]}\n\
        grasp: {frame: hand, origin: {xyz: [0, 0, 0.1], rpy: [0, -1.5707963267948966, 0]}, kind: palm, min_touching: 1}\n\
        hand:\n  - {joint: slide, preshape: [0.04, 0.04], close: 0.0}\n\
        pads:\n  - {name: p, link: finger, origin: {xyz: [0, -0.005, 0], rpy: [1.5707963267948966, 0, 0]}}\n";
    let desc = dir.path().join("robot.yaml");
    std::fs::write(&desc, description).unwrap();
    let robot = Robot::from_files(&desc, None, &[]).unwrap();
    let m = &robot.model;
    // One tree: the hand's root on the flange, its meshes found from its own folder.
    assert_eq!(m.links[m.links[m.link_id("hand").unwrap()].parent_joint.map(|j| m.joints[j].parent).unwrap()].name, "flange");
    assert_eq!(m.mesh_files.len(), 2);
    let t = m.relative_pose(&m.zero(), m.link_id("flange").unwrap(), m.link_id("hand").unwrap());
    assert!((t.translation - DVec3::new(0.0, 0.0, 0.01)).length() < 1e-12);
    let turn = DQuat::from_mat3(&t.matrix3).angle_between(DQuat::from_rotation_z(0.5));
    assert!(turn.abs() < 1e-6, "{turn} {t:?}");
    // The grasp frame is a link of its own at the offset.
    assert_eq!(m.links[robot.grasp_frame].name, "hand_grasp");
    let g = m.relative_pose(&m.zero(), m.link_id("hand").unwrap(), robot.grasp_frame);
    assert!((g.translation - DVec3::new(0.0, 0.0, 0.1)).length() < 1e-12 && (g.transform_vector3(DVec3::X) - DVec3::Z).length() < 1e-9);
    // The prismatic finger's drive: the URDF's effort (N), gains from it (N/m, N·s/m).
    let h = &robot.hand[0];
    assert_eq!(h.effort, Some(30.0));
    assert_eq!(h.stiffness, Some(30.0 / PRISMATIC_FULL_FORCE_ERROR));
    assert_eq!(h.damping, Some(30.0 / PRISMATIC_FULL_FORCE_ERROR * PRISMATIC_DAMPING_TIME));
    // A decomposition names links with collision meshes.
    std::fs::write(&desc, format!("{description}convex_decomposition: {{links: [finger], max_hulls: 4}}\n")).unwrap();
    let d = Robot::from_files(&desc, None, &[]).unwrap().decomposition.unwrap();
    assert_eq!((d.links, d.max_hulls, d.resolution), (vec![m.link_id("finger").unwrap()], 4, 64));
    std::fs::write(&desc, format!("{description}convex_decomposition: {{links: [tool]}}\n")).unwrap();
    let e = Robot::from_files(&desc, None, &[]).unwrap_err().to_string();
    assert!(e.contains("convex_decomposition.links[0]: 'tool' has no collision mesh to decompose"), "{e}");
    std::fs::write(&desc, format!("{description}convex_decomposition: {{links: [all], resolution: 8}}\n")).unwrap();
    let e = Robot::from_files(&desc, None, &[]).unwrap_err().to_string();
    assert!(e.contains("convex_decomposition.resolution: 8 is not within 16 ..= 256"), "{e}");
    // Names that clash, and a hand without a mount, are refused.
    std::fs::write(&desc, description.replace("mount: {parent: flange, origin: {xyz: [0, 0, 0.01], rpy: [0, 0, 0.5]}}\n", "")).unwrap();
    let e = Robot::from_files(&desc, None, &[]).unwrap_err().to_string();
    assert!(e.contains("mount: hand_urdf needs a mount"), "{e}");
    std::fs::write(&desc, description.replace("parent: flange", "parent: wrist_9")).unwrap();
    let e = Robot::from_files(&desc, None, &[]).unwrap_err().to_string();
    assert!(e.contains("mount.parent: no link 'wrist_9' in the arm's URDF"), "{e}");
    let clash = std::fs::read_to_string(dir.path().join("my_gripper/urdf/gripper.urdf")).unwrap().replace("\"tool\"", "\"flange\"");
    std::fs::write(dir.path().join("my_gripper/urdf/gripper.urdf"), clash).unwrap();
    std::fs::write(&desc, description).unwrap();
    let e = Robot::from_files(&desc, None, &[]).unwrap_err().to_string();
    assert!(e.contains("link 'flange' is in the arm's URDF too: rename one"), "{e}");
}

#[test]
fn the_builtin_revolute_hands_keep_their_drives_and_an_upstream_robot_says_where_its_files_come_from() {
    // The Allegro's URDF effort is the physics default: its drives are the ones it always had.
    let robot = Robot::default_robot();
    assert!(robot.hand.iter().all(|h| h.effort == Some(0.7) && h.stiffness.is_none() && h.damping.is_none()));
    let e = Robot::builtin("panda").unwrap_err().to_string();
    assert!(e.contains("package://example-robot-data/robots/panda_description/urdf/panda.urdf"), "{e}");
    assert!(e.contains("scripts/robot-assets") && e.contains("--robot-assets"), "{e}");
}

#[test]
fn a_redundant_arm_keeps_its_joints_off_their_limits() {
    // The UR5e with a seventh joint (a wrist roll on the flange): the null-space pull keeps every
    // joint within its range's inner 95 % over reachable targets.
    let urdf = allegro_on(
        "<link name=\"roll_link\"><inertial><mass value=\"0.1\"/><inertia ixx=\"1e-4\" ixy=\"0\" ixz=\"0\" iyy=\"1e-4\" iyz=\"0\" izz=\"1e-4\"/></inertial></link>\
         <joint name=\"roll\" type=\"revolute\"><parent link=\"flange\"/><child link=\"roll_link\"/><axis xyz=\"0 0 1\"/>\
         <limit lower=\"-2\" upper=\"2\" effort=\"10\" velocity=\"1\"/></joint>",
        "roll_link",
    );
    let text = include_str!("../../ur5e_allegro/robot.yaml").replace("flange: flange", "flange: roll_link").replace(
        "home: [-1.5707963267948966, -1.5707963267948966, 1.5707963267948966, -1.5707963267948966, -1.5707963267948966, 0.0]",
        "home: [-1.5707963267948966, -1.5707963267948966, 1.5707963267948966, -1.5707963267948966, -1.5707963267948966, 0.0, 0.0]",
    );
    let robot = Robot::from_texts(&urdf, "seven.urdf", &text, "seven.yaml").unwrap();
    assert_eq!(robot.arm_joints.len(), 7);
    let home = {
        let mut q = robot.model.zero();
        for (&d, &v) in robot.arm_dofs.iter().zip(&robot.home) {
            q[d] = v;
        }
        q
    };
    let start = robot.grasp_frame_pose(&home);
    let mut reached = 0;
    for k in 0..12 {
        let target = DAffine3::from_translation(DVec3::new(0.02 * (k % 4) as f64 - 0.03, 0.02 * (k / 4) as f64 - 0.02, -0.05)) * start;
        if let Some(q) = robot.solve_grasp_ik(&target, &home, &IkOptions::default()) {
            reached += 1;
            assert!((robot.grasp_frame_pose(&q).translation - target.translation).length() < 1e-4);
            let roll = robot.model.joints[robot.arm_joints[6]].dof.unwrap();
            assert!(q[roll].abs() < 0.95 * 2.0, "the redundant joint stays off its limit: {}", q[roll]);
        }
    }
    assert!(reached >= 10, "{reached}");
}

#[test]
fn a_pads_default_size_runs_along_its_own_axes() {
    // A fingertip box 10 (x) by 20 (y) by 30 (z) mm, its pad facing -y with x along the finger (z)
    // and y across it (-x): 30 by 10 mm, whatever the link's axes are called.
    let urdf = r#"<robot name="f">
      <link name="base"/><link name="finger"><inertial><mass value="0.02"/><inertia ixx="1e-6" ixy="0" ixz="0" iyy="1e-6" iyz="0" izz="1e-6"/></inertial>
        <collision><geometry><box size="0.01 0.02 0.03"/></geometry></collision></link>
      <joint name="j" type="prismatic"><parent link="base"/><child link="finger"/><axis xyz="0 1 0"/><limit lower="0" upper="0.04" effort="20" velocity="1"/></joint>
    </robot>"#;
    let m = RobotModel::from_urdf_str(urdf, "f.urdf").unwrap();
    let mut robot = Robot::default_robot();
    let mut model = m.clone();
    let finger = model.link_id("finger").unwrap();
    let frame = model
        .add_fixed_link(finger, "tip_pad", xyz_rpy([0.0, 0.01, 0.0], [0.0, -std::f64::consts::FRAC_PI_2, std::f64::consts::FRAC_PI_2]))
        .unwrap();
    robot.model = model;
    robot.pads = vec![Pad { name: "tip".into(), link: finger, frame, size: None, labels: Vec::new(), contact: Default::default() }];
    let (len, wid) = robot.pad_sizes()[0];
    assert!((len - 0.03).abs() < 1e-12 && (wid - 0.01).abs() < 1e-12, "{len} {wid}");
    // The Allegro's pads keep their sizes: box z by box y, plus the tip sphere on the distal ones.
    let allegro = Robot::default_robot();
    let sizes = allegro.pad_sizes();
    for (pad, (len, wid)) in allegro.pads.iter().zip(&sizes) {
        let boxes: Vec<DVec3> = allegro.model.links[pad.link]
            .collisions
            .iter()
            .filter_map(|s| if let Geometry::Box { size } = s.geometry { Some(size) } else { None })
            .collect();
        let last = boxes.last().unwrap();
        assert_eq!(*wid, last.y, "{}", pad.name);
        assert!(*len == last.z || *len > last.z + 0.005, "{}: the box's length, exactly, or with the tip sphere", pad.name);
    }
}

#[test]
fn a_sensor_rule_selects_pads_by_glob_or_label() {
    let robot = Robot::default_robot();
    let selected = |pattern: &str| robot.pads.iter().filter(|p| p.matches(pattern)).map(|p| p.name.clone()).collect::<Vec<_>>();
    assert_eq!(selected("*").len(), 12);
    assert_eq!(selected("th_*"), ["th_proximal", "th_medial", "th_distal"]);
    assert_eq!(selected("?f_medial"), ["ff_medial", "mf_medial", "rf_medial"]);
    assert_eq!(selected("distal"), ["ff_distal", "mf_distal", "rf_distal", "th_distal"], "a label");
    assert_eq!(selected("*_tip").len(), 0);
    assert_eq!(selected("ff_distal*"), ["ff_distal"]);
}

/// The UR5e arm with one finger link hanging off its last link through `joint` (the URDF text of a
/// `<joint>` whose child is `finger`).
fn finger_on_the_wrist(joint: &str) -> String {
    format!(
        "{}<link name=\"finger\"><inertial><mass value=\"0.05\"/><inertia ixx=\"1e-5\" ixy=\"0\" ixz=\"0\" iyy=\"1e-5\" iyz=\"0\" izz=\"1e-5\"/></inertial>\
         <collision><geometry><box size=\"0.01 0.01 0.04\"/></geometry></collision></link>{joint}</robot>\n",
        ur5e_arm_urdf().trim_end().strip_suffix("</robot>").unwrap()
    )
}

/// A description of that robot with the given hand list and extra top-level keys.
fn finger_description(name: &str, hand: &str, extra: &str) -> String {
    format!(
        "name: {name}\narm: {{base: base_link, flange: wrist_3_link, home: [-1.5707963267948966, -1.5707963267948966, 1.5707963267948966, -1.5707963267948966, -1.5707963267948966, 0.0]}}\n\
         grasp: {{frame: wrist_3_link, origin: {{xyz: [0, 0, 0.1], rpy: [0, -1.5707963267948966, 0]}}, kind: palm, min_touching: 1}}\n\
         hand:\n{hand}pads:\n  - {{name: p, link: finger, origin: {{xyz: [0, -0.005, 0], rpy: [1.5707963267948966, 0, 0]}}}}\n{extra}"
    )
}

/// Fingers that hang directly off the arm's last moving link (the hand's root is that link): the
/// arm's last joint carries the root and is not a hand joint, and listing it as one is refused.
#[test]
fn a_hand_rooted_at_the_arms_last_moving_link() {
    let urdf = finger_on_the_wrist(
        "<joint name=\"slide\" type=\"prismatic\"><parent link=\"wrist_3_link\"/><child link=\"finger\"/><axis xyz=\"0 1 0\"/>\
         <limit lower=\"0\" upper=\"0.04\" effort=\"20\" velocity=\"0.1\"/></joint>",
    );
    let description = |hand: &str| finger_description("wrist_hand", hand, "");
    let robot =
        Robot::from_texts(&urdf, "u.urdf", &description("  - {joint: slide, preshape: [0.04, 0.04], close: 0.0}\n"), "d.yaml").unwrap();
    assert_eq!((robot.hand.len(), robot.followers.len()), (1, 0));
    assert_eq!(robot.model.links[robot.hand_root].name, "wrist_3_link");
    let e = Robot::from_texts(&urdf, "u.urdf", &description("  - {joint: wrist_3_joint, preshape: [0, 0], close: 0.0}\n"), "d.yaml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("hand[0].joint: 'wrist_3_joint' is not below the hand's root 'wrist_3_link'"), "{e}");
}

/// An upstream URDF whose finger joint is `fixed` (as Kinova's are in example-robot-data): the
/// description's `joints:` makes it move, the simulated URDF carries the correction and the
/// upstream text is kept; a joint the URDF lacks, or a moving joint without a range, is refused at
/// its line.
#[test]
fn a_description_corrects_a_fixed_finger_joint() {
    let urdf = finger_on_the_wrist(
        "<joint name=\"finger_joint\" type=\"fixed\"><parent link=\"wrist_3_link\"/><child link=\"finger\"/><axis xyz=\"0 0 1\"/>\
         <limit lower=\"0\" upper=\"1.51\" effort=\"2\" velocity=\"1\"/></joint>",
    );
    let description =
        |joints: &str| finger_description("fixed_fingers", "  - {joint: finger_joint, preshape: [0.2, 0.4], close: 1.2}\n", joints);
    let e = Robot::from_texts(&urdf, "u.urdf", &description(""), "d.yaml").unwrap_err().to_string();
    assert!(e.contains("hand[0].joint: 'finger_joint' is fixed"), "{e}");
    let robot =
        Robot::from_texts(&urdf, "u.urdf", &description("joints:\n  finger_joint: {type: revolute, effort: 1.5}\n"), "d.yaml").unwrap();
    let j = robot.model.joint("finger_joint").unwrap();
    assert_eq!((j.kind, j.lower, j.upper, j.effort), (JointKind::Revolute, 0.0, 1.51, 1.5));
    assert_eq!(robot.upstream_urdf_text.as_deref(), Some(urdf.as_str()));
    assert!(RobotModel::from_urdf_str(&robot.urdf_text, "simulated").unwrap().joint("finger_joint").unwrap().moves());
    assert!(Robot::from_texts(&urdf, "u.urdf", &description(""), "d.yaml").is_err());
    let e =
        Robot::from_texts(&urdf, "u.urdf", &description("joints:\n  finger_jiont: {type: revolute}\n"), "d.yaml").unwrap_err().to_string();
    assert!(e.contains("line 9: joints.finger_jiont: no joint 'finger_jiont' in the URDF"), "{e}");
    let e = Robot::from_texts(&urdf, "u.urdf", &description("joints:\n  finger_joint: {type: revolute, upper: 0.0}\n"), "d.yaml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("joints.finger_joint: moves between 0 and 0"), "{e}");
    let plain = Robot::from_texts(&ur5e_arm_urdf(), "u.urdf", &description(""), "d.yaml");
    assert!(plain.is_err(), "no finger in the plain arm");
}

/// A pad's contact patch is Hertz's: radius `(3 N R / 4 E*)^(1/3)`, growing as the cube root of the
/// load, bounded by the pad; a description gives its skin per pad, others take the soft default.
#[test]
fn a_pads_contact_patch_follows_hertz_and_its_description() {
    let skin = PadContact { modulus_mpa: 0.4, crown_radius_mm: 20.0 };
    // 3 · 10 N · 0.02 m / (4 · 0.4 MPa) = 3.75e-7 m³.
    assert!((skin.patch_radius(10.0, None) - 3.75e-7f64.cbrt()).abs() < 1e-12);
    assert!((skin.patch_radius(80.0, None) / skin.patch_radius(10.0, None) - 2.0).abs() < 1e-12);
    assert_eq!(skin.patch_radius(80.0, Some(0.005)), 0.005);
    assert_eq!(skin.patch_radius(-1.0, None), 0.0);
    let text = include_str!("../../ur5e_allegro/robot.yaml").replacen(
        "frame: ff_medial_pad,",
        "frame: ff_medial_pad, contact: {modulus_mpa: 2.5, crown_radius_mm: 8},",
        1,
    );
    let robot = Robot::from_texts(&default_urdf(), "u", &text, "d").unwrap();
    assert_eq!(robot.pads[1].contact, PadContact { modulus_mpa: 2.5, crown_radius_mm: 8.0 });
    assert_eq!(robot.pads[0].contact, PadContact::default());
}

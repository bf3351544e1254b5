use glam::{DAffine3, DQuat, DVec3};

use super::*;
use crate::GraspKind;

fn model() -> RobotModel {
    Robot::allegro().model
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
    let robot = Robot::allegro();
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
    let robot = Robot::allegro();
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
    let robot = Robot::allegro();
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
fn broken_urdfs_give_clear_errors() {
    let cases = [
        (BUILTIN_URDF.replace("<parent link=\"ff_base\"/>", "<parent link=\"ff_bse\"/>"), "missing parent link 'ff_bse'"),
        (
            BUILTIN_URDF.replace("lower=\"-0.47\" upper=\"0.47\"", "lower=\"0.47\" upper=\"-0.47\""),
            "lower limit 0.47 is above upper limit -0.47",
        ),
        ("<robot name=\"x\"><link name=\"a\"/>".to_string(), "not valid URDF"),
    ];
    for (text, want) in cases {
        let e = RobotModel::from_urdf_str(&text, "bad.urdf").unwrap_err().to_string();
        assert!(e.starts_with("robot description bad.urdf: ") && e.contains(want), "{e}");
    }
}

/// The Allegro description with `from` replaced by `to`, resolved; the error it gives.
fn description_error(from: &str, to: &str) -> String {
    let text = include_str!("../ur5e_allegro.yaml");
    assert!(text.contains(from), "{from}");
    Robot::from_texts(BUILTIN_URDF, "ur5e_allegro.urdf", &text.replacen(from, to, 1), "bad.yaml").unwrap_err().to_string()
}

#[test]
fn broken_descriptions_name_the_file_and_the_field() {
    let cases = [
        ("link: ff_distal,", "link: ff_distl,", "bad.yaml: pads[2].link: no link 'ff_distl' in the URDF"),
        ("base: base_link", "base: palm", "bad.yaml: arm: 'flange' is not below 'palm': the arm is not one serial chain"),
        ("frame: palm", "frame: base_link", "bad.yaml: grasp.frame: 'base_link' is not fixed below the flange 'flange'"),
        ("frame: palm", "frame: ff_distal", "bad.yaml: grasp.frame: 'ff_distal' moves against the flange"),
        ("joint: th_joint_2,", "joint: th_joint_x,", "bad.yaml: hand[14].joint: no joint 'th_joint_x' in the URDF"),
        ("joint: th_joint_2,", "joint: shoulder_pan_joint,", "hand[14].joint: 'shoulder_pan_joint' is not below the hand's root 'palm'"),
        ("- {joint: th_joint_3, preshape: [-0.1, 0.3], close: 1.2}\n", "", "joint 'th_joint_3' moves in the hand but is neither listed"),
        ("preshape: [0.3, 0.5]", "preshape: [0.5, 0.3]", "hand[12].preshape: [0.5, 0.3] is not a range"),
        ("frame: th_distal_pad,", "frame: th_medial_pad,", "pads[11].frame: 'th_medial_pad' is not a link fixed to 'th_distal'"),
        ("min_touching: 2", "min_touching: 13", "grasp.min_touching: 13 is not within 1 ..= the 12 touch links"),
        ("home: [-1.5707963267948966, ", "home: [", "arm.home: 5 values for 6 arm joints"),
        ("kind: palm", "kind: suction", "bad.yaml: line 13: grasp.kind: unknown variant `suction`"),
        ("min_touching: 2", "min_touching: 2\n  fingers: 4", "bad.yaml: line 15: grasp: unknown field `fingers`"),
    ];
    for (from, to, want) in cases {
        let e = description_error(from, to);
        assert!(e.contains(want), "{from} -> {to}: {e}");
    }
    // A pad given by an origin on its link becomes a frame of its own.
    let text = include_str!("../ur5e_allegro.yaml").replacen(
        "name: ff_distal, link: ff_distal, frame: ff_distal_pad,",
        "name: ff_tip, link: ff_distal, origin: {xyz: [0.0098, 0, 0.02], rpy: [0, 1.5707963267948966, 0]}, size: [0.03, 0.02],",
        1,
    );
    let robot = Robot::from_texts(BUILTIN_URDF, "u", &text, "d").unwrap();
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

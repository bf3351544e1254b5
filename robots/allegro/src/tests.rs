use glam::{DAffine3, DQuat, DVec3};

use super::*;

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

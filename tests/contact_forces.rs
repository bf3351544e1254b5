//! The contact forces the physics reports (`HandPhysics::hand_contacts`) are the forces that hold
//! the object: in a settled hold they balance its weight, for the Allegro hand (palm grasps) and
//! the 2F-85 (friction between the jaws). MuJoCo gives them (scripts/test runs this file with
//! `VTGEN_TEST_PHYSICS=mujoco`); rapier gives none (see `HandPhysics::hand_contacts`).

use glam::DVec3;
use vtgen::config::{GraspConfig, PhysicsConfig};
use vtgen::physics::grasp::{GraspContext, GraspLog, TrajectoryKey, simulate_trajectory};
use vtgen::physics::{HandPhysics, PhysicsObject, PhysicsSettings, RapierHand};

fn backend() -> String {
    std::env::var("VTGEN_TEST_PHYSICS").unwrap_or_else(|_| "rapier".into())
}

fn hand(robot: &vt_robot::Robot, settings: PhysicsSettings) -> Box<dyn HandPhysics> {
    match backend().as_str() {
        #[cfg(feature = "mujoco")]
        "mujoco" => Box::new(vtgen::physics::MujocoHand::new(robot, settings).unwrap()),
        _ => Box::new(RapierHand::new(robot, settings).unwrap()),
    }
}

/// Held objects, settled for a second under a gravity the test sets: the links' contact forces sum
/// to the object's weight (within 5 % of it), and the pressure parts push into the links.
#[test]
fn contact_forces_in_a_settled_hold_balance_the_weight() {
    let pc = PhysicsConfig { timestep: 1.0 / 240.0, ..PhysicsConfig::default() };
    let settings = PhysicsSettings::from(&pc);
    let t_world_base =
        glam::DAffine3::from_rotation_translation(glam::DQuat::from_rotation_z(std::f64::consts::PI), DVec3::new(0.0, 0.5, 0.0));
    let catalog = vt_objects::Catalog::builtin();
    // The palm frame's x is its palmar normal: gravity along -x holds the object on the palm (the
    // hand), or pulls it along the jaws' faces (the gripper, held by friction alone).
    let gravity = DVec3::new(-9.81, 0.0, 0.0);
    for name in ["ur5e_allegro", "ur5e_robotiq_2f85"] {
        let robot = vt_robot::Robot::builtin(name).unwrap();
        let cfg = GraspConfig::default().with_robot_defaults(&robot);
        let ctx = GraspContext::new(&robot, t_world_base, &cfg, pc.timestep, DVec3::new(0.0, -0.75, 0.55));
        let mut physics = hand(&robot, settings);
        let (mut balanced, mut held) = (0, 0);
        for id in ["005_tomato_soup_can", "009_gelatin_box", "006_mustard_bottle"] {
            let entry = catalog.get(id).unwrap();
            let object = PhysicsObject { points: vt_objects::procedural_mesh(entry).positions, mass: entry.mass };
            let key = TrajectoryKey { seed: 5, object_id: id, trajectory: 0, instances: 1 };
            if simulate_trajectory(&ctx, physics.as_mut(), &object, key, &mut GraspLog::default()).is_err() {
                continue;
            }
            physics.set_gravity(gravity);
            physics.set_object_damping(0.0, 0.0);
            // A grip's contacts chatter from step to step (stiff contacts, PD fingers): the balance
            // holds for the forces averaged over the second half of a settled second.
            let steps = (1.0 / pc.timestep) as usize;
            let (mut before, mut on_links, mut contacts) = (physics.object_pose(), DVec3::ZERO, 0);
            for k in 0..steps {
                physics.step();
                if k == steps / 2 {
                    before = physics.object_pose();
                }
                if k > steps / 2 {
                    let Some(now) = physics.hand_contacts() else {
                        assert_eq!(physics.backend_name(), "rapier", "only rapier gives no contact forces");
                        return;
                    };
                    for c in &now {
                        assert!((c.normal.length() - 1.0).abs() < 1e-6, "{name}, {id}: normal {}", c.normal);
                        assert!(c.force.dot(c.normal) <= 1e-9, "{name}, {id}: the object pulls on link {} ({})", c.link, c.force);
                    }
                    on_links += now.iter().map(|c| c.force).sum::<DVec3>();
                    contacts += now.len();
                }
            }
            let drift = (physics.object_pose().translation - before.translation).length();
            if drift > 1e-3 {
                eprintln!("{name}, {id}: not at rest ({:.1} mm in 0.5 s), not checked", drift * 1e3);
                continue;
            }
            held += 1;
            let samples = (steps - steps / 2 - 1) as f64;
            // The object at rest: the links push on it with -Σ f, gravity pulls with m g.
            let on_links = on_links / samples;
            let weight = object.mass * gravity;
            let error = (on_links - weight).length() / weight.length();
            eprintln!(
                "{name} ({}), {id}: {:.1} contacts, mean Σ f = {:.3} N vs m g = {:.3} N: {:.1} %",
                backend(),
                contacts as f64 / samples,
                on_links,
                weight,
                error * 100.0
            );
            balanced += (error < 0.05) as usize;
        }
        assert!(held >= 1, "{name}: no object stayed held under palm-up gravity");
        assert_eq!(balanced, held, "{name}: {balanced} of {held} holds balance the weight within 5 %");
    }
}

/// The force fields in generated data (2F-85 and Allegro, `robot.tactile.force_field`): every
/// pad's grid sums to the physics' force on its sensing area (within 5 %), and at the recorded
/// instances (the arm still) the hand's contact forces hold the object's weight: within 1 % in
/// most, and within 25 % where the object still moves in the hand (its acceleration is the
/// rest). rapier refuses the config with the reason and the fix.
#[test]
fn force_fields_sum_to_the_pads_contact_forces_and_the_hand_holds_the_weight() {
    use crate::common::*;
    let catalog = vt_objects::Catalog::builtin();
    for scene in ["tiny-gripper.yaml", "tiny-hand.yaml"] {
        let d = tempdir();
        let backend_set = format!("robot.physics.backend={}", backend());
        let args = ["--set", "robot.tactile.force_field={resolution: 8}", "--set", &backend_set];
        let o = run_generate(&root().join("scenes").join(scene), d.path(), &args);
        if backend() == "rapier" {
            assert!(!o.status.success(), "{scene}: rapier must refuse force fields");
            assert!(
                stderr(&o).contains("robot.tactile.force_field: needs the contact forces") && stderr(&o).contains("backend: mujoco"),
                "{}",
                stderr(&o)
            );
            continue;
        }
        assert!(o.status.success(), "{scene}: {}", stderr(&o));
        let ds = vt_dataset::DatasetReader::open(d.path()).unwrap();
        let (mut samples, mut pads_loaded, mut worst_sum, mut worst_weight, mut balanced) = (0, 0, 0.0f64, 0.0f64, 0);
        let (mut on_pads, mut on_links) = (0.0, 0.0);
        for split in ["train", "test"] {
            for s in ds.samples(split).unwrap() {
                let s = s.unwrap();
                let tac = s.tactile.as_ref().expect("robot samples carry touch");
                let touch = s.info.robot.as_ref().and_then(|r| r.tactile.as_ref()).expect("touch info");
                let forces = touch.forces.as_ref().expect("force info");
                assert_eq!(tac.forces.len(), tac.pads.len(), "{scene}: a field per pad");
                for field in &tac.forces {
                    assert_eq!((field.resolution, field.cells.len()), (8, 64));
                    let [len, wid] = touch.pads[&field.pad];
                    let area = len * wid / 64.0;
                    let grid: DVec3 =
                        field.cells.iter().map(|c| DVec3::new(c.shear[0] as f64, c.shear[1] as f64, -(c.pressure as f64)) * area).sum();
                    let pad = DVec3::from_array(forces[&field.pad].force_n);
                    let error = (grid - pad).length();
                    assert!(
                        error <= 0.05 * pad.length() + 1e-4,
                        "{scene} sample {}, {}: grid {grid} vs contacts {pad}",
                        s.index,
                        field.pad
                    );
                    if pad.length() > 1e-3 {
                        worst_sum = worst_sum.max(error / pad.length());
                        pads_loaded += 1;
                    }
                    on_pads += pad.length();
                    on_links += DVec3::from_array(forces[&field.pad].link_force_n).length();
                }
                // The arm is still at a recorded instance: the hand holds the weight.
                let weight = catalog.get(&s.info.object_id).unwrap().mass * DVec3::new(0.0, 0.0, -9.81);
                let hand = DVec3::from_array(touch.hand_force_n.expect("the hand's force"));
                let error = (hand - weight).length() / weight.length();
                assert!(error < 0.25, "{scene} sample {}: the hand's force {hand} vs the weight {weight}", s.index);
                worst_weight = worst_weight.max(error);
                balanced += (error < 0.01) as usize;
                samples += 1;
            }
        }
        eprintln!(
            "{scene} ({}): {samples} samples, {pads_loaded} loaded pads; grid vs pad force within {:.3} %; hand vs weight within 1 % in \
             {balanced}, at most {:.1} %; {:.0} % of the touch links' force on the sensing areas",
            backend(),
            worst_sum * 100.0,
            worst_weight * 100.0,
            100.0 * on_pads / on_links.max(1e-9)
        );
        assert!(pads_loaded > samples, "{scene}: {pads_loaded} loaded pads in {samples} samples");
        markers_follow_the_gel(scene, &ds);
        dump_writes_the_fields(d.path(), &ds);
        assert!(balanced * 5 >= samples * 4, "{scene}: the hand holds the weight within 1 % in only {balanced} of {samples} samples");
    }
}

/// An episode's touch readings between camera frames carry every pad's force field too, made
/// from the physics' contacts at their own instant: the grids are square, slip only where the
/// object presses, and the frames' grids sum to their pads' forces.
#[test]
fn episode_touch_readings_carry_force_fields() {
    use crate::common::*;
    if backend() == "rapier" {
        return; // refused by the config check (above)
    }
    let d = tempdir();
    let args = ["--set", "robot.tactile.force_field={resolution: 4}", "--set", "robot.physics.backend=mujoco"];
    let o = run_generate(&root().join("scenes/tiny-episode.yaml"), d.path(), &args);
    assert!(o.status.success(), "{}", stderr(&o));
    let ds = vt_dataset::DatasetReader::open(d.path()).unwrap();
    let (mut readings, mut pressed) = (0, 0);
    for s in ds.samples("train").unwrap() {
        let s = s.unwrap();
        let episode = s.episode.as_ref().expect("an episode frame");
        let frame = s.tactile.as_ref().expect("touch at the frame");
        let touch = s.info.robot.as_ref().and_then(|r| r.tactile.as_ref()).expect("touch info");
        for field in &frame.forces {
            let [len, wid] = touch.pads[&field.pad];
            let area = len * wid / 16.0;
            let grid: DVec3 =
                field.cells.iter().map(|c| DVec3::new(c.shear[0] as f64, c.shear[1] as f64, -(c.pressure as f64)) * area).sum();
            let pad = DVec3::from_array(touch.forces.as_ref().expect("force info")[&field.pad].force_n);
            assert!((grid - pad).length() <= 0.05 * pad.length() + 1e-4, "frame {}: {} grid {grid} vs {pad}", s.index, field.pad);
        }
        for (_, tac) in std::iter::once(&(0, frame.clone())).chain(&episode.tactile) {
            assert_eq!(tac.forces.len(), tac.pads.len(), "a field per pad in every touch reading");
            for field in &tac.forces {
                assert_eq!(field.cells.len(), 16);
                assert!(
                    field.cells.iter().all(|c| c.pressure >= 0.0 && (!c.slip || c.pressure > 0.0)),
                    "{}: slip without pressure",
                    field.pad
                );
                pressed += field.cells.iter().any(|c| c.pressure > 0.0) as usize;
            }
            readings += 1;
        }
    }
    assert!(readings > 20 && pressed > readings, "{readings} touch readings, {pressed} pressed pads");
}

/// With force fields, each optical pad with markers carries its marker flow: every marker of the
/// sample's sensor's rest grid, in its order; a pad nothing touches has its markers at rest; a
/// loaded pad moves some, by less than the gel's thickness plus its elastic shear (a few mm).
fn markers_follow_the_gel(scene: &str, ds: &vt_dataset::DatasetReader) {
    let (mut pads, mut moved) = (0, 0);
    for s in ds.samples("train").unwrap() {
        let s = s.unwrap();
        let tac = s.tactile.as_ref().unwrap();
        let touch = s.info.robot.as_ref().and_then(|r| r.tactile.as_ref()).unwrap();
        let sensors = touch.optical.clone().unwrap_or_default();
        let with_markers: Vec<&String> = sensors.iter().filter(|(_, v)| !v["markers"].is_null()).map(|(p, _)| p).collect();
        let flow_pads: Vec<&String> = tac.marker_flow.iter().map(|f| &f.pad).collect();
        let mut expected = with_markers.clone();
        expected.sort_by_key(|p| tac.pads.iter().position(|q| q == *p));
        assert_eq!(flow_pads, expected, "{scene} sample {}: the optical pads with markers, in pad order", s.index);
        for flow in &tac.marker_flow {
            let sensor: vtgen::config::OpticalSensor = serde_json::from_value(sensors[&flow.pad].clone()).unwrap();
            let rest = vtgen::sensors::optical::marker_positions(&sensor);
            assert_eq!(flow.markers.len(), rest.len(), "{scene} {}", flow.pad);
            for ((r, _), g) in flow.markers.iter().zip(&rest) {
                assert!((r[0] as f64 - g[0]).abs() < 1e-7 && (r[1] as f64 - g[1]).abs() < 1e-7, "{}: rest {r:?} vs grid {g:?}", flow.pad);
            }
            let shift = |(r, m): &([f32; 2], [f32; 2])| ((m[0] - r[0]) as f64).hypot((m[1] - r[1]) as f64);
            let largest = flow.markers.iter().map(shift).fold(0.0, f64::max);
            let field = tac.forces.iter().find(|f| f.pad == flow.pad).unwrap();
            let touched = field.cells.iter().any(|c| c.pressure > 0.0);
            let depth = &tac.depth[tac.pads.iter().position(|p| *p == flow.pad).unwrap()];
            let near = depth.iter().any(|&d| (d as f64) < sensor.gel_thickness_mm * 1e-3);
            if !touched && !near {
                assert_eq!(largest, 0.0, "{scene} sample {} {}: untouched, yet a marker moved", s.index, flow.pad);
            }
            assert!(largest < 5e-3, "{scene} sample {} {}: a marker moved {largest} m", s.index, flow.pad);
            pads += 1;
            moved += (largest > 1e-5) as usize;
        }
    }
    if scene == "tiny-gripper.yaml" {
        assert!(pads > 0 && moved > 0, "{scene}: {moved} of {pads} optical pads moved their markers");
    }
    eprintln!("{scene}: {moved} of {pads} optical pads with markers moved them");
}

/// `vtgen dump` writes each pad's field of a sample as `tactile_<pad>_force.npy`, (R, R, 4)
/// float32: pressure, shear x, shear y, slip, as the reader returns them.
fn dump_writes_the_fields(dataset: &std::path::Path, ds: &vt_dataset::DatasetReader) {
    use crate::common::*;
    let out = tempdir();
    let o = run(&["dump", dataset.to_str().unwrap(), "--split", "train", "--index", "0", "--out", out.path().to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let sample = ds.samples("train").unwrap().next().unwrap().unwrap();
    for field in &sample.tactile.as_ref().unwrap().forces {
        let bytes = std::fs::read(out.path().join(format!("tactile_{}_force.npy", field.pad))).unwrap();
        // .npy 1.0: magic, version, a little-endian u16 header length, the header, then the data.
        let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        let header = std::str::from_utf8(&bytes[10..10 + header_len]).unwrap();
        let r = field.resolution;
        assert!(header.contains("'<f4'") && header.contains(&format!("({r}, {r}, 4)")), "{header}");
        let values: Vec<f32> = bytes[10 + header_len..].chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        let expected: Vec<f32> = field.cells.iter().flat_map(|c| [c.pressure, c.shear[0], c.shear[1], c.slip as u8 as f32]).collect();
        assert_eq!(values, expected, "{}", field.pad);
    }
    for flow in &sample.tactile.as_ref().unwrap().marker_flow {
        let bytes = std::fs::read(out.path().join(format!("tactile_{}_markers.npy", flow.pad))).unwrap();
        let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        let header = std::str::from_utf8(&bytes[10..10 + header_len]).unwrap();
        assert!(header.contains(&format!("({}, 4)", flow.markers.len())), "{header}");
        let values: Vec<f32> = bytes[10 + header_len..].chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        let expected: Vec<f32> = flow.markers.iter().flat_map(|(r, m)| [m[0], m[1], r[0], r[1]]).collect();
        assert_eq!(values, expected, "{}", flow.pad);
    }
}

//! The stored ground truth agrees with the stored images: the object's model, moved by the stored
//! pose and projected with the stored intrinsics, lands in the mask and on the depth.

use glam::DVec3;
use vt_dataset::{DatasetReader, read_ply};
use vtgen::cli::validate::{reproject, surface_points};

use crate::common::*;

/// Checks every sample of a dataset (`samples` of them). With a robot in the picture the object can be almost hidden:
/// samples with fewer than 30 visible model points are counted, not checked (at most a third).
pub fn check_dataset(dir: &std::path::Path, samples: usize) {
    let ds = DatasetReader::open(dir).unwrap();
    let info: vt_dataset::ModelsInfo = serde_json::from_slice(&std::fs::read(dir.join("models/models_info.json")).unwrap()).unwrap();
    let models: Vec<Vec<(DVec3, DVec3)>> =
        info.objects.iter().map(|o| surface_points(&read_ply(&dir.join("models").join(&o.file)).unwrap(), 3000)).collect();
    let (mut checked, mut hidden) = (0, 0);
    for split in ["train", "test"] {
        for s in ds.samples(split).unwrap() {
            let s = s.unwrap();
            let obj = s.info.object_index as usize;
            // The stored transforms are consistent with each other.
            let composed = s.t_world_camera.inverse().compose(&s.t_world_object);
            assert!((composed.translation() - s.t_camera_object.translation()).length() < 1e-9);
            assert!(composed.rotation().dot(s.t_camera_object.rotation()).abs() > 1.0 - 1e-12);
            let r = reproject(&s, &models[obj], 1);
            if s.info.robot.is_none() {
                // Nothing but the object itself can hide it.
                assert!(r.front_facing > 50, "{split} {}: the object is in view ({} points)", s.index, r.front_facing);
                assert!(r.visible * 2 >= r.front_facing, "{split} {}: {} of {} facing points visible", s.index, r.visible, r.front_facing);
            } else if r.visible < 30 {
                hidden += 1;
                continue;
            }
            // 1% may sit on an occluder's silhouette, where a pixel's centre and a model point on
            // either side of an edge disagree; with fewer than 100 visible points, one such point.
            let share = r.agreeing as f64 / r.visible as f64;
            assert!(
                r.visible - r.agreeing <= (r.visible / 100).max(1),
                "{split} {}: only {:.2}% of {} visible model points agree with mask and depth",
                s.index,
                100.0 * share,
                r.visible
            );
            checked += 1;
        }
    }
    let total = checked + hidden;
    assert_eq!(total, samples);
    assert!(hidden * 3 <= total, "{hidden} of {total} samples have the object hidden");
}

#[test]
fn every_sample_reprojects_onto_its_mask_and_depth() {
    check_dataset(reference_dataset(), 40);
}

#[test]
fn a_wrong_pose_is_caught() {
    // The check is not vacuous: a pose 5 mm too close to the camera fails it.
    let ds = DatasetReader::open(reference_dataset()).unwrap();
    let mut s = ds.samples("train").unwrap().next().unwrap().unwrap();
    let info: vt_dataset::ModelsInfo =
        serde_json::from_slice(&std::fs::read(reference_dataset().join("models/models_info.json")).unwrap()).unwrap();
    let obj = s.info.object_index as usize;
    let pts = surface_points(&read_ply(&reference_dataset().join("models").join(&info.objects[obj].file)).unwrap(), 3000);
    s.t_camera_object.position[2] -= 0.005;
    let r = reproject(&s, &pts, 1);
    assert!((r.agreeing as f64) < 0.5 * r.visible as f64, "{} of {} still agree", r.agreeing, r.visible);
}

//! The stored ground truth agrees with the stored images: the object's model, moved by the stored
//! pose and projected with the stored intrinsics, lands in the mask and on the depth.

use vt_dataset::DatasetReader;
use vtgen::cli::validate::{Model, check_ground_truth, pixels_off_the_mesh, reproject};

use crate::common::*;

/// Checks every sample of a dataset (`samples` of them). With a robot in the picture the object can be almost hidden:
/// samples with fewer than 30 visible model points are counted, not checked (at most a third).
pub fn check_dataset(dir: &std::path::Path, samples: usize) {
    let ds = DatasetReader::open(dir).unwrap();
    let models = models_of(dir);
    let (mut checked, mut hidden) = (0, 0);
    for split in ["train", "test"] {
        for s in ds.samples(split).unwrap() {
            let s = s.unwrap();
            let obj = s.info.object_index as usize;
            // The stored transforms are consistent with each other.
            let composed = s.t_world_camera.inverse().compose(&s.t_world_object);
            assert!((composed.translation() - s.t_camera_object.translation()).length() < 1e-9);
            assert!(composed.rotation().dot(s.t_camera_object.rotation()).abs() > 1.0 - 1e-12);
            let r = reproject(&s, &models[obj]);
            if s.info.robot.is_none() {
                // Nothing but the object itself can hide it.
                assert!(r.front_facing > 50, "{split} {}: the object is in view ({} points)", s.index, r.front_facing);
                assert!(r.visible * 2 >= r.front_facing, "{split} {}: {} of {} facing points visible", s.index, r.visible, r.front_facing);
            } else if r.visible < 30 {
                hidden += 1;
                continue;
            }
            // 1% may sit on the object's own silhouette, where a pixel's centre and a model point
            // on either side of the edge disagree; with fewer than 100 visible points, one such
            // point. (Points within a pixel of an occluder's edge are not counted as visible.)
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

/// A dataset's object models, in its models_info.json order.
fn models_of(dir: &std::path::Path) -> Vec<Model> {
    let info: vt_dataset::ModelsInfo = serde_json::from_slice(&std::fs::read(dir.join("models/models_info.json")).unwrap()).unwrap();
    Model::of_dataset(dir, &info).unwrap()
}

/// The first train sample of the reference dataset and the dataset's object models.
fn first_sample_and_models() -> (vt_dataset::Sample, Vec<Model>) {
    let ds = DatasetReader::open(reference_dataset()).unwrap();
    let s = ds.samples("train").unwrap().next().unwrap().unwrap();
    (s, models_of(reference_dataset()))
}

#[test]
fn a_wrong_pose_is_caught() {
    // The check is not vacuous: a pose 5 mm too close to the camera fails it, and so does one 5 mm
    // too far (whose points the picture's own object surface would hide, were the object's
    // occlusion taken from the picture and not from the posed model).
    let (s, models) = first_sample_and_models();
    let model = &models[s.info.object_index as usize];
    let right = reproject(&s, model);
    assert!(right.agreeing as f64 >= 0.99 * right.visible as f64 && right.visible > 50, "{} of {}", right.agreeing, right.visible);
    for dz in [-0.005, 0.005] {
        let mut s = s.clone();
        s.t_camera_object.position[2] += dz;
        let r = reproject(&s, model);
        assert!(r.visible > right.visible / 2, "{dz}: {} of {} points still visible", r.visible, right.visible);
        assert!((r.agreeing as f64) < 0.5 * r.visible as f64, "{dz}: {} of {} still agree", r.agreeing, r.visible);
        // And from the other side: the object's pixels leave the posed mesh.
        let off = pixels_off_the_mesh(&s, model);
        assert!(off.off * 2 > off.pixels, "{dz}: {} of {} pixels off the mesh", off.off, off.pixels);
        assert!(check_ground_truth(&s, &models).is_some(), "{dz}: `vtgen validate` passes it");
    }
    let on = pixels_off_the_mesh(&s, model);
    assert!(on.pixels > 100 && on.off == 0, "{} of {} pixels off the mesh, the farthest {} m", on.off, on.pixels, on.farthest);
    assert_eq!(check_ground_truth(&s, &models), None);
}

#[test]
fn points_at_an_occluders_edge_are_neither_visible_nor_hidden() {
    // An occluder's edge drawn over the object, with the object's sliver beside it two pixels wide
    // and covering no pixel centre (background there): the model points projecting into the sliver
    // have no object pixel within a pixel of them, and are counted apart, not as disagreeing.
    let (mut s, models) = first_sample_and_models();
    let model = &models[s.info.object_index as usize];
    let before = reproject(&s, model);
    // The object's columns; the band starts at their middle.
    let w = s.width as usize;
    let cols: Vec<usize> = (0..s.mask.len()).filter(|&i| s.mask[i] == 1).map(|i| i % w).collect();
    let c = (cols.iter().min().unwrap() + cols.iter().max().unwrap()) / 2;
    let near = s.depth.iter().zip(&s.mask).filter(|(_, m)| **m == 1).map(|(d, _)| *d).fold(f32::INFINITY, f32::min);
    for y in 0..s.height as usize {
        for x in c - 2..c + 6 {
            let i = y * w + x;
            if x < c {
                (s.mask[i], s.depth[i]) = (0, 0.0);
            } else {
                (s.mask[i], s.depth[i]) = (20, near - 0.05);
            }
        }
    }
    let r = reproject(&s, model);
    assert!(r.at_occluder_edge > before.at_occluder_edge, "no point lies at the drawn edge");
    assert!(
        r.visible - r.agreeing <= before.visible - before.agreeing,
        "{} of {} visible points agree beside the edge ({} of {} before)",
        r.agreeing,
        r.visible,
        before.agreeing,
        before.visible
    );
    assert!(r.visible + r.at_occluder_edge < before.visible, "the band hides some points");
}

//! The stored ground truth agrees with the stored images: the object's model, moved by the stored
//! pose and projected with the stored intrinsics, lands in the mask and on the depth.

use glam::DVec3;
use vt_dataset::{DatasetReader, PlyMesh, Sample, read_ply};

use crate::common::*;

/// Area-weighted points on the mesh surface with their face normals (deterministic).
pub fn surface_points(mesh: &PlyMesh, n: usize) -> Vec<(DVec3, DVec3)> {
    let tris: Vec<[DVec3; 3]> = mesh.triangles.iter().map(|t| t.map(|i| glam::Vec3::from(mesh.positions[i as usize]).as_dvec3())).collect();
    let areas: Vec<f64> = tris.iter().map(|t| 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length()).collect();
    let total: f64 = areas.iter().sum();
    let mut cdf = Vec::with_capacity(areas.len());
    let mut acc = 0.0;
    for a in &areas {
        acc += a / total;
        cdf.push(acc);
    }
    let mut state = 0x9e3779b97f4a7c15u64;
    let mut rnd = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..n)
        .map(|_| {
            let k = cdf.partition_point(|&c| c < rnd()).min(tris.len() - 1);
            let [a, b, c] = tris[k];
            let (mut u, mut v) = (rnd(), rnd());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            let p = a + (b - a) * u + (c - a) * v;
            (p, (b - a).cross(c - a).normalize())
        })
        .collect()
}

pub struct Reprojection {
    pub visible: usize,
    pub front_facing: usize,
    pub agreeing: usize,
}

/// Projects surface points with the sample's pose and intrinsics. A point is *visible* when it faces
/// the camera (not grazing) and nothing is drawn in front of it; it *agrees* when a pixel within one
/// pixel of its projection (edge pixels aside) has the object's mask id and its depth within 2 mm.
pub fn reproject(s: &Sample, points: &[(DVec3, DVec3)], mask_id: u8) -> Reprojection {
    let (w, h) = (s.width as i64, s.height as i64);
    let pose = s.t_camera_object;
    let r = pose.rotation();
    let mut out = Reprojection { visible: 0, front_facing: 0, agreeing: 0 };
    for (p, n) in points {
        let pc = pose.transform_point(*p);
        let nc = r * *n;
        if pc.z <= 0.0 {
            continue;
        }
        let u = s.fx() * pc.x / pc.z + s.cx();
        let v = s.fy() * pc.y / pc.z + s.cy();
        let (ui, vi) = (u.round() as i64, v.round() as i64);
        if ui < 1 || vi < 1 || ui >= w - 1 || vi >= h - 1 {
            continue;
        }
        // Closed meshes: a point faces the camera when its outward normal points at it.
        if nc.dot(-pc.normalize()) < 0.3 {
            continue;
        }
        out.front_facing += 1;
        let at = |x: i64, y: i64| (y * w + x) as usize;
        let d = s.depth[at(ui, vi)] as f64;
        if d > 0.0 && d < pc.z - 0.002 {
            continue; // occluded
        }
        out.visible += 1;
        let ok = (-1..=1).any(|dy| {
            (-1..=1).any(|dx| {
                let i = at(ui + dx, vi + dy);
                s.mask[i] == mask_id && (s.depth[i] as f64 - pc.z).abs() <= 0.002
            })
        });
        out.agreeing += ok as usize;
    }
    out
}

/// Checks every sample of a dataset. With a robot in the picture the object can be almost hidden:
/// samples with fewer than 30 visible model points are counted, not checked (at most a third).
pub fn check_dataset(dir: &std::path::Path) {
    let ds = DatasetReader::open(dir).unwrap();
    let info: vt_dataset::ModelsInfo = serde_json::from_slice(&std::fs::read(dir.join("models/models_info.json")).unwrap()).unwrap();
    let models: Vec<Vec<(DVec3, DVec3)>> =
        info.objects.iter().map(|o| surface_points(&read_ply(&dir.join("models").join(&o.file)).unwrap(), 3000)).collect();
    let (mut checked, mut hidden) = (0, 0);
    for split in ["train", "test"] {
        for s in ds.samples(split).unwrap() {
            let s = s.unwrap();
            let obj = s.info["object_index"].as_u64().unwrap() as usize;
            // The stored transforms are consistent with each other.
            let composed = s.t_world_camera.inverse().compose(&s.t_world_object);
            assert!((composed.translation() - s.t_camera_object.translation()).length() < 1e-9);
            assert!(composed.rotation().dot(s.t_camera_object.rotation()).abs() > 1.0 - 1e-12);
            let r = reproject(&s, &models[obj], 1);
            if s.info.get("physics_backend").is_none() {
                // Nothing but the object itself can hide it.
                assert!(r.front_facing > 50, "{split} {}: the object is in view ({} points)", s.index, r.front_facing);
                assert!(r.visible * 2 >= r.front_facing, "{split} {}: {} of {} facing points visible", s.index, r.visible, r.front_facing);
            } else if r.visible < 30 {
                hidden += 1;
                continue;
            }
            let share = r.agreeing as f64 / r.visible as f64;
            assert!(
                share >= 0.99,
                "{split} {}: only {:.2}% of {} visible model points agree with mask and depth",
                s.index,
                100.0 * share,
                r.visible
            );
            checked += 1;
        }
    }
    assert_eq!(checked + hidden, 40);
    assert!(hidden * 3 <= 40, "{hidden} of 40 samples have the object hidden");
}

#[test]
fn every_sample_reprojects_onto_its_mask_and_depth() {
    check_dataset(reference_dataset());
}

#[test]
fn a_wrong_pose_is_caught() {
    // The check is not vacuous: a pose 5 mm too close to the camera fails it.
    let ds = DatasetReader::open(reference_dataset()).unwrap();
    let mut s = ds.samples("train").unwrap().next().unwrap().unwrap();
    let info: vt_dataset::ModelsInfo =
        serde_json::from_slice(&std::fs::read(reference_dataset().join("models/models_info.json")).unwrap()).unwrap();
    let obj = s.info["object_index"].as_u64().unwrap() as usize;
    let pts = surface_points(&read_ply(&reference_dataset().join("models").join(&info.objects[obj].file)).unwrap(), 3000);
    s.t_camera_object.position[2] -= 0.005;
    let r = reproject(&s, &pts, 1);
    assert!((r.agreeing as f64) < 0.5 * r.visible as f64, "{} of {} still agree", r.agreeing, r.visible);
}

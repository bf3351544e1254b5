//! `vtgen export bop`: every image's BOP pixel counts agree with what the generator measured
//! (the re-rendered full silhouette has exactly the sample's `silhouette_pixels`, the visible mask
//! its `visible_pixels`), and an export never overwrites a directory. The Python suite reads the
//! export back with plyfile and PIL and re-projects the poses onto the exported depth.

use std::collections::BTreeMap;

use crate::common::*;

fn json(path: &std::path::Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))).unwrap()
}

// Long on purpose: one walk over the export, each BOP file checked against the sample it came
// from as it is met.
#[test]
fn bop_pixel_counts_match_the_generators_measurements() {
    let ds = reference_dataset();
    let out = tempdir();
    let bop = out.path().join("bop");
    let o = run(&["export", "bop", ds.to_str().unwrap(), bop.to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // (split, index) -> sample info, from the shards.
    let reader = vt_dataset::DatasetReader::open(ds).unwrap();
    let mut infos = BTreeMap::new();
    for split in ["train", "test"] {
        for shard in reader.shards(split).unwrap() {
            for i in shard.indices().collect::<Vec<_>>() {
                infos.insert((split, i), shard.read_info(i).unwrap());
            }
        }
    }
    let mut images = 0;
    let mut want_targets = Vec::new();
    for split in ["train", "test"] {
        for scene in std::fs::read_dir(bop.join(split)).unwrap() {
            let scene = scene.unwrap().path();
            let gt = json(&scene.join("scene_gt.json"));
            let gt_info = json(&scene.join("scene_gt_info.json"));
            for (im, list) in gt_info.as_object().unwrap() {
                let info = &infos[&(split, im.parse::<u64>().unwrap())];
                let g = &list[0];
                assert_eq!(g["px_count_all"], info["occlusion"]["silhouette_pixels"], "{split} {im}");
                assert_eq!(g["px_count_visib"], info["visible_pixels"], "{split} {im}");
                assert_eq!(gt[im][0]["obj_id"].as_u64().unwrap(), info["object_index"].as_u64().unwrap() + 1);
                let t = gt[im][0]["cam_t_m2c"].as_array().unwrap();
                let p = info["T_camera_object"]["position"].as_array().unwrap();
                for k in 0..3 {
                    assert!((t[k].as_f64().unwrap() - 1000.0 * p[k].as_f64().unwrap()).abs() < 1e-6);
                }
                assert!(scene.join(format!("depth/{:06}.png", im.parse::<u64>().unwrap())).is_file());
                // The boxes as bop_toolkit's calc_gt_info computes them from the written masks.
                let im_id = im.parse::<u64>().unwrap();
                for (key, mask) in [("bbox_obj", "mask"), ("bbox_visib", "mask_visib")] {
                    let png = image::open(scene.join(format!("{mask}/{im_id:06}_000000.png"))).unwrap().to_luma8();
                    assert_eq!(g[key], serde_json::json!(calc_2d_bbox(&png)), "{split} {im} {key}");
                }
                if split == "test" && g["px_count_visib"].as_u64().unwrap() > 0 {
                    let scene_id: u64 = scene.file_name().unwrap().to_str().unwrap().parse().unwrap();
                    want_targets
                        .push(serde_json::json!({"im_id": im_id, "inst_count": 1, "obj_id": gt[im][0]["obj_id"], "scene_id": scene_id}));
                }
                images += 1;
            }
        }
    }
    assert_eq!(images, infos.len());
    // Every test image with its object in sight is a BOP19 target; BOP24 lists the same images.
    let key = |t: &serde_json::Value| (t["scene_id"].as_u64(), t["im_id"].as_u64());
    let mut targets19 = json(&bop.join("test_targets_bop19.json")).as_array().unwrap().clone();
    targets19.sort_by_key(key);
    want_targets.sort_by_key(key);
    assert!(!want_targets.is_empty());
    assert_eq!(targets19, want_targets);
    let targets24 = json(&bop.join("test_targets_bop24.json"));
    let images24: Vec<_> = targets24.as_array().unwrap().iter().map(key).collect();
    assert_eq!(images24.len(), targets19.len());
    assert!(targets19.iter().all(|t| images24.contains(&key(t))));
    // The exported PLY says its unit.
    let ply = std::fs::read(bop.join("models/obj_000001.ply")).unwrap();
    assert!(ply.windows(11).any(|w| w == b"millimetres"));
    assert!(bop.join("models/obj_000001.ply").is_file() && bop.join("camera.json").is_file());
    // The symmetries are the ones measured on the meshes (models_info.json), in mm, and they hold on
    // the exported models: the cracker box's three flips, the soup can's revolution axis.
    let ours: vt_dataset::ModelsInfo = serde_json::from_value(json(&ds.join("models/models_info.json"))).unwrap();
    let info = json(&bop.join("models/models_info.json"));
    for m in &ours.objects {
        let entry = &info[(m.object_index + 1).to_string()];
        let ply = vt_dataset::read_ply(&bop.join(format!("models/obj_{:06}.ply", m.object_index + 1))).unwrap();
        let indices: Vec<u32> = ply.triangles.iter().flatten().copied().collect();
        let check = vt_objects::SymmetryChecker::new(&ply.positions, &indices);
        let tolerance_mm = 0.01 * entry["diameter"].as_f64().unwrap();
        let mut transforms = Vec::new();
        let discrete = entry["symmetries_discrete"].as_array().cloned().unwrap_or_default();
        assert_eq!(discrete.len(), m.symmetries_discrete.len(), "{}", m.id);
        for (t, t_m) in discrete.iter().zip(&m.symmetries_discrete) {
            let t: Vec<f64> = t.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
            for k in 0..16 {
                let scale = if k % 4 == 3 && k < 12 { 1000.0 } else { 1.0 };
                assert!((t[k] - t_m[k] * scale).abs() < 1e-9, "{}: {t:?} vs {t_m:?}", m.id);
            }
            transforms.push(glam::DMat4::from_cols_array(&t.try_into().unwrap()).transpose());
        }
        let continuous = entry["symmetries_continuous"].as_array().cloned().unwrap_or_default();
        assert_eq!(continuous.len(), m.symmetries_continuous.len(), "{}", m.id);
        for c in &continuous {
            let v = |k: &str| glam::DVec3::from_slice(&c[k].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect::<Vec<_>>());
            transforms.extend(vt_objects::revolution_turns(&vt_objects::ContinuousAxis { axis: v("axis"), offset: v("offset") }));
        }
        for t in &transforms {
            let d = check.displacement(t);
            assert!(d.p99 <= tolerance_mm, "{}: a BOP symmetry moves the exported model by {d:?} mm", m.id);
        }
        let want = match m.id.as_str() {
            "003_cracker_box" => (3, 0),
            "005_tomato_soup_can" => (0, 1),
            _ => (0, 0),
        };
        assert_eq!((discrete.len(), continuous.len()), want, "{}", m.id);
    }
    // A second export into the same directory is refused, and the first stays intact.
    let again = run(&["export", "bop", ds.to_str().unwrap(), bop.to_str().unwrap(), "--quiet"]);
    assert!(!again.status.success() && stderr(&again).contains("not empty"), "{}", stderr(&again));
}

/// `bop_toolkit_lib.misc.calc_2d_bbox` over a mask's nonzero pixels: `[x, y, max x - min x,
/// max y - min y]`; `calc_gt_info` writes `[-1, -1, -1, -1]` for an empty mask.
fn calc_2d_bbox(mask: &image::GrayImage) -> [i64; 4] {
    let on: Vec<(i64, i64)> = mask.enumerate_pixels().filter(|p| p.2[0] > 0).map(|(x, y, _)| (x as i64, y as i64)).collect();
    if on.is_empty() {
        return [-1, -1, -1, -1];
    }
    let (xs, ys): (Vec<i64>, Vec<i64>) = on.into_iter().unzip();
    let (x0, y0) = (*xs.iter().min().unwrap(), *ys.iter().min().unwrap());
    [x0, y0, xs.iter().max().unwrap() - x0, ys.iter().max().unwrap() - y0]
}

#[test]
fn exr_depth_holds_the_exact_float_depth() {
    let ds = reference_dataset();
    let out = tempdir();
    let o = run(&["dump", ds.to_str().unwrap(), "--split", "train", "--index", "3", "--out", out.path().to_str().unwrap(), "--exr"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (w, h, z) = vtgen::cli::dump::read_exr_depth(&out.path().join("depth.exr")).unwrap();
    let reader = vt_dataset::DatasetReader::open(ds).unwrap();
    let s = reader.shards("train").unwrap().into_iter().find(|s| s.indices().any(|i| i == 3)).unwrap().read(3).unwrap();
    assert_eq!((w, h), (s.width, s.height));
    assert!(z.iter().zip(&s.depth).all(|(a, b)| a.to_bits() == b.to_bits()), "bit-exact depth");
    assert!(s.depth.iter().any(|&d| d > 0.0));
}

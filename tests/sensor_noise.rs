//! The RGB-D noise model of `scenes/tiny-hand.yaml`: `/camera/depth_noisy` departs from the exact
//! depth as the model says (within 5σ where it reads, nothing on depth edges), while
//! `/camera/depth` stays the ground truth (the reprojection check holds on it).

use vtgen::sensors::rgbd_noise::DepthNoise;

#[test]
fn noisy_depth_follows_the_model_and_the_clean_depth_stays_exact() {
    let dir = crate::grasping::hand_dataset();
    let model = DepthNoise::default();
    let reader = vt_dataset::DatasetReader::open(dir).unwrap();
    let models: Vec<vtgen::cli::validate::Model> = ["009_gelatin_box", "005_tomato_soup_can"]
        .iter()
        .map(|id| vtgen::cli::validate::Model::new(&vt_dataset::read_ply(&dir.join(format!("models/{id}.ply"))).unwrap()).unwrap())
        .collect();
    let (mut valid, mut edges, mut edges_dropped) = (0usize, 0usize, 0usize);
    for s in reader.samples("train").unwrap() {
        let s = s.unwrap();
        assert_eq!(vtgen::cli::validate::check_ground_truth(&s, &models), None, "sample {}", s.index);
        let noisy = s.depth_noisy.as_ref().expect("tiny-hand has a depth noise model");
        let w = s.width as usize;
        for (i, (&d, &n)) in s.depth.iter().zip(noisy).enumerate() {
            if n > 0.0 {
                valid += 1;
                assert!(d > 0.0);
                // 5σ plus one disparity step.
                let step = (d as f64).powi(2) / (s.fx() * model.baseline_m * model.subpixel);
                assert!(((n - d) as f64).abs() < 5.0 * model.sigma_m(d as f64) + step, "pixel {i}: {n} vs {d}");
            }
            let (x, y) = (i % w, i / w);
            if x > 0 && x + 1 < w && y > 0 && y + 1 < s.height as usize && d > 0.0 {
                let right = s.depth[i + 1];
                if right > 0.0 && (right - d).abs() > 0.05 {
                    edges += 1;
                    edges_dropped += (n == 0.0) as usize;
                }
            }
        }
    }
    assert!(valid > 100_000, "{valid} pixels read");
    assert!(edges > 100 && edges_dropped == edges, "{edges_dropped} of {edges} depth-edge pixels read nothing");
}

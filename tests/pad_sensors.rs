//! Sensors assigned per pad by config alone: the Allegro with four sensor kinds (a DIGIT on the
//! thumb's tip, GelSight Minis with markers on the other fingertips, taxel arrays on the medial
//! links, the description's depth cameras elsewhere) gives a valid dataset whose every sample
//! says each pad's sensor, writes an optical image for exactly the optical pads, each at its own
//! sensor's size, and reports taxel points on the taxel grid only.

use vt_dataset::{DatasetReader, SensorModel};

use crate::common::{root, run, run_generate, stderr, tempdir};

#[test]
fn four_sensor_kinds_on_one_hand_by_config_alone() {
    let out = tempdir();
    let rules = "robot.tactile.sensors=[{pads: th_distal, model: optical, optical: {preset: digit}}, \
                 {pads: distal, model: optical, optical: {preset: gelsight_mini, markers: {}}}, \
                 {pads: medial, model: taxel_array, rows: 4, cols: 4}]";
    let o =
        run_generate(&root().join("scenes/tiny-hand.yaml"), out.path(), &["--set", rules, "--set", "sampling.trajectories_per_object=2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = run(&["validate", out.path().to_str().unwrap(), "--full"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let ds = DatasetReader::open(out.path()).unwrap();
    let (mut samples, mut taxel_points) = (0, 0);
    for split in ["train", "test"] {
        for s in ds.samples(split).unwrap() {
            let s = s.unwrap();
            let touch = s.info.robot.as_ref().and_then(|r| r.tactile.as_ref()).expect("touch info");
            let tac = s.tactile.as_ref().expect("tactile data");
            for (k, pad) in tac.pads.iter().enumerate() {
                let want = match pad.as_str() {
                    p if p.ends_with("_distal") => SensorModel::Optical,
                    p if p.ends_with("_medial") => SensorModel::TaxelArray { rows: 4, cols: 4 },
                    _ => SensorModel::DepthCamera,
                };
                assert_eq!(touch.sensors[pad], want, "{pad}");
                // A 4 x 4 taxel grid reports at most one point per taxel.
                let points = tac.points.iter().filter(|p| p.pad as usize == k).count();
                if pad.ends_with("_medial") {
                    assert!(points <= 16, "{pad}: {points} points");
                    taxel_points += points;
                }
            }
            // The optical images: the four fingertips', each at its sensor's size (the DIGIT's
            // sensing area on the thumb, the GelSight Mini's on the others).
            let optical = touch.optical.as_ref().expect("optical pads");
            let images: Vec<&str> = tac.optical.iter().map(|o| o.pad.as_str()).collect();
            assert_eq!(images, ["ff_distal", "mf_distal", "rf_distal", "th_distal"]);
            for o in &tac.optical {
                let area: [f64; 2] = serde_json::from_value(optical[&o.pad]["sensing_area_mm"].clone()).unwrap();
                let markers = !optical[&o.pad]["markers"].is_null();
                if o.pad == "th_distal" {
                    assert_eq!((area, markers), ([19.0, 16.0], false), "the DIGIT");
                } else {
                    assert_eq!((area, markers), ([18.6, 14.3], true), "{}: a GelSight Mini with markers", o.pad);
                }
                assert_eq!((o.width, o.height), (320, 240));
            }
            samples += 1;
        }
    }
    assert!(samples >= 8 && taxel_points > 0, "{samples} samples, {taxel_points} taxel points");
}

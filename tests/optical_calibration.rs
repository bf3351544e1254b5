//! `vtgen tactile calibrate` held to a sensor it must give back: a sensor unlike the presets (its
//! own LEDs, gel tint, vignetting and pixel size) renders a background and presses of a ball with
//! vtgen's image model, noise included; the fit of those images must recover the pixel size, and
//! the calibrated sensor, used through `robot.tactile.optical.calibration`, must render presses it
//! never saw (other places, other depths) as the true sensor does.

use std::path::Path;

use rand::SeedableRng;
use vtgen::config::{Led, LoadedConfig, OpticalPreset, OpticalSensor};
use vtgen::sensors::optical::{ball_press_depth, optical_image, reference_image};

/// An LED `elevation` degrees above the gel at `azimuth` degrees.
fn led(azimuth: f64, elevation: f64, color: [f64; 3], falloff: f64) -> Led {
    let (a, e) = (azimuth.to_radians(), elevation.to_radians());
    Led { direction: [e.cos() * a.cos(), e.cos() * a.sin(), -e.sin()], color, falloff }
}

/// The unit the images come from: 160 x 120 pixels of 0.075 mm, LEDs with cross-talk between
/// colours, a greenish gel, strong vignetting, 1 level of noise.
fn true_sensor() -> OpticalSensor {
    let mut s = OpticalPreset::GelsightMini.sensor();
    s.image_size = [160, 120];
    s.sensing_area_mm = [12.0, 9.0];
    s.lights = vec![
        led(60.0, 40.0, [0.80, 0.15, 0.08], 0.30),
        led(180.0, 32.0, [0.10, 0.70, 0.20], 0.20),
        led(300.0, 45.0, [0.12, 0.10, 0.85], 0.35),
    ];
    s.ambient = 0.2;
    s.background = [0.70, 0.78, 0.72];
    s.vignetting = 0.3;
    s.noise_std = 1.0;
    s
}

fn save(s: &OpticalSensor, rgb: Vec<u8>, path: &Path) {
    image::RgbImage::from_raw(s.image_size[0], s.image_size[1], rgb).unwrap().save(path).unwrap();
}

/// RMS difference (levels) of two images.
fn rms(a: &[u8], b: &[u8]) -> f64 {
    (a.iter().zip(b).map(|(x, y)| (*x as f64 - *y as f64).powi(2)).sum::<f64>() / a.len() as f64).sqrt()
}

#[test]
fn calibrate_gives_back_the_sensor_that_made_the_images() {
    use crate::common::*;
    let truth = true_sensor();
    let dir = tempdir();
    let images = dir.path().join("presses");
    std::fs::create_dir_all(&images).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let radius = 2e-3;
    // The background as a real unit gives it: one noisy image.
    save(&truth, optical_image(&truth, None, None, Some(&mut rng)).rgb, &images.join("background.png"));
    let presses = [
        ([0.0, 0.0], 0.45e-3),
        ([-3.5e-3, -2.0e-3], 0.35e-3),
        ([3.5e-3, -2.2e-3], 0.5e-3),
        ([-3.2e-3, 2.3e-3], 0.4e-3),
        ([3.0e-3, 2.0e-3], 0.3e-3),
        ([0.5e-3, -2.5e-3], 0.55e-3),
        ([-1.0e-3, 2.5e-3], 0.5e-3),
        ([1.5e-3, 0.5e-3], 0.4e-3),
    ];
    for (k, (centre, depth)) in presses.iter().enumerate() {
        let img = optical_image(&truth, Some(&ball_press_depth(&truth, radius, *depth, *centre)), None, Some(&mut rng));
        save(&truth, img.rgb, &images.join(format!("press_{k:02}.png")));
    }
    // Fitted pixel size, then the pixel size given as a lab measures it.
    let config = dir.path().join("config.yaml");
    std::fs::write(&config, std::fs::read_to_string(root().join("scenes/tiny-gripper.yaml")).unwrap()).unwrap();
    for (run_name, given, size_tolerance, contact_tolerance) in [("fitted", None, 0.05, 4.0), ("given", Some("0.075"), 1e-9, 2.5)] {
        let out = dir.path().join(format!("calibration-{run_name}"));
        let mut args = vec!["tactile", "calibrate", images.to_str().unwrap(), "--ball-radius", "2", "--out", out.to_str().unwrap()];
        args.extend(given.iter().flat_map(|g| ["--pixel-size-mm", *g]));
        let o = run(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        eprintln!("pixel size {run_name}:\n{}", String::from_utf8_lossy(&o.stdout));
        let text = std::fs::read_to_string(out.join("calibration.yaml")).unwrap();
        let file: vtgen::config::optical_calibration::CalibrationFile = serde_yaml::from_str(&text).unwrap();
        let size_error = (file.pixel_size_mm - 0.075).abs() / 0.075;
        assert!(size_error <= size_tolerance, "{run_name}: pixel size {} mm, true 0.075 mm", file.pixel_size_mm);
        assert_eq!(
            (file.image_size, file.model.as_str()),
            ([160, 120], "polynomial"),
            "{run_name}: the LEDs' cross-talk needs the polynomial"
        );

        // The calibrated sensor through a config, as a user takes it.
        let set = format!(
            "robot.tactile.optical={{preset: gelsight_mini, calibration: {}, noise_std: 0}}",
            out.join("calibration.yaml").display()
        );
        let loaded = LoadedConfig::load_with(&config, &[set.parse::<vtgen::config::Override>().unwrap()]).unwrap();
        let fitted = loaded.config.robot.as_ref().unwrap().tactile.optical_sensor();
        assert_eq!(fitted.image_size, truth.image_size);
        assert_eq!(fitted.calibration.as_ref().map(|c| c.model.as_str()), Some("polynomial"));

        // With nothing touching, the calibrated sensor shows the true one's reference within the
        // background image's own noise (1 level).
        let mut clean = truth.clone();
        clean.noise_std = 0.0;
        let reference = reference_image(&clean);
        let no_contact = rms(&reference_image(&fitted).rgb, &reference.rgb);
        assert!(no_contact < 1.3, "{run_name}: no-contact image {no_contact:.2} levels RMS from the true sensor's");
        // Presses it never saw (other places, other depths), noise-free.
        let held_out = [([-1.5e-3, -1.0e-3], 0.5e-3), ([2.2e-3, 1.2e-3], 0.35e-3), ([-2.5e-3, 0.8e-3], 0.45e-3)];
        for (centre, depth) in held_out {
            let want = optical_image(&clean, Some(&ball_press_depth(&clean, radius, depth, centre)), None, None);
            let got = optical_image(&fitted, Some(&ball_press_depth(&fitted, radius, depth, centre)), None, None);
            let image = rms(&want.rgb, &got.rgb);
            // The contact: where the true image differs from its reference by more than noise.
            let touched: Vec<usize> = (0..want.rgb.len()).filter(|&i| want.rgb[i].abs_diff(reference.rgb[i]) > 3).collect();
            let contact =
                (touched.iter().map(|&i| (want.rgb[i] as f64 - got.rgb[i] as f64).powi(2)).sum::<f64>() / touched.len() as f64).sqrt();
            let signal = (touched.iter().map(|&i| (want.rgb[i] as f64 - reference.rgb[i] as f64).powi(2)).sum::<f64>()
                / touched.len() as f64)
                .sqrt();
            eprintln!(
                "{run_name}: held-out press at {centre:?} m, {depth} m deep: {image:.2} levels RMS over the image, {contact:.2} over its {} \
                 contact values (their signal: {signal:.1} levels RMS)",
                touched.len()
            );
            assert!(
                image < 1.5 && contact < contact_tolerance,
                "{run_name}: held-out press at {centre:?}: {image:.2} / {contact:.2} levels RMS"
            );
        }
    }

    // Data made with the calibrated sensor: its images are the calibration's size, its references
    // are the calibration's background (the model without noise), and /sample/info names the
    // calibration.
    let calibration = dir.path().join("calibration-given/calibration.yaml");
    let data = dir.path().join("data");
    let set = format!("robot.tactile.optical={{calibration: {}, markers: {{}}}}", calibration.display());
    let sets = ["--set", set.as_str(), "--set", "sampling.trajectories_per_object=1", "--set", "sampling.instances_per_trajectory=2"];
    generate(&root().join("scenes/tiny-gripper.yaml"), &data, &sets);
    let background = image::open(dir.path().join("calibration-given/background.png")).unwrap().to_rgb8().into_raw();
    let ds = vt_dataset::DatasetReader::open(&data).unwrap();
    let mut seen = 0;
    for s in ds.samples("train").unwrap() {
        let s = s.unwrap();
        let touch = s.info.robot.as_ref().and_then(|r| r.tactile.as_ref()).unwrap();
        for o in &s.tactile.as_ref().unwrap().optical {
            assert_eq!((o.width, o.height), (160, 120));
            let sensor = &touch.optical.as_ref().unwrap()[&o.pad];
            assert_eq!(sensor["calibration"]["model"], "polynomial", "{sensor}");
            // Markers darken their dots; elsewhere the reference is the unit's background.
            let off = o.reference.iter().zip(&background).filter(|(r, b)| r.abs_diff(**b) > 1).count();
            assert!(off < o.reference.len() / 5, "{}: {off} reference values off the background", o.pad);
            seen += 1;
        }
    }
    assert!(seen > 0, "no optical images");
}

/// Bad input is named: a folder without a background image, a calibration file that is not there.
#[test]
fn calibrate_and_the_config_name_what_is_wrong() {
    use crate::common::*;
    let dir = tempdir();
    let truth = true_sensor();
    save(&truth, reference_image(&truth).rgb, &dir.path().join("press_a.png"));
    save(&truth, reference_image(&truth).rgb, &dir.path().join("press_b.png"));
    let o = run(&["tactile", "calibrate", dir.path().to_str().unwrap(), "--ball-radius", "2"]);
    assert!(
        !o.status.success() && stderr(&o).contains("no background image: name the image with nothing touching the gel background.png"),
        "{}",
        stderr(&o)
    );
    save(&truth, reference_image(&truth).rgb, &dir.path().join("background.png"));
    let o = run(&["tactile", "calibrate", dir.path().to_str().unwrap(), "--ball-radius", "2"]);
    assert!(!o.status.success() && stderr(&o).contains("press_a.png: no contact found"), "{}", stderr(&o));
    let o = run(&[
        "generate",
        "scenes/tiny-gripper.yaml",
        "--out",
        dir.path().join("out").to_str().unwrap(),
        "--set",
        "robot.tactile.optical.calibration=nowhere/calibration.yaml",
    ]);
    let e = stderr(&o);
    assert!(
        !o.status.success() && e.contains("robot.tactile.optical.calibration") && e.contains("nowhere/calibration.yaml: cannot read"),
        "{e}"
    );
}

//! The optical image model checked against geometry: a sphere of known radius pressed a known
//! depth into the gel, and photometric stereo back to the gel's height map.

use super::*;
use crate::config::{OpticalConfig, OpticalPreset};
use rand::SeedableRng;

fn sensor(preset: OpticalPreset) -> OpticalSensor {
    OpticalConfig { preset, ..Default::default() }.resolve()
}

/// The radius (m) of a disc with the area of the pixels where two images differ.
fn changed_radius(s: &OpticalSensor, a: &OpticalImage, b: &OpticalImage) -> f64 {
    let changed = a.rgb.chunks(3).zip(b.rgb.chunks(3)).filter(|(p, q)| p != q).count();
    let (px, py) = pitch(s);
    (changed as f64 * px * py / std::f64::consts::PI).sqrt()
}

#[test]
fn a_pressed_sphere_makes_a_contact_disc_of_the_geometric_radius() {
    for preset in [OpticalPreset::GelsightMini, OpticalPreset::Digit] {
        let mut s = sensor(preset);
        // The contact disc itself: no spread, markers or noise around it.
        s.elastic_spread_mm = 0.0;
        s.noise_std = 0.0;
        let reference = reference_image(&s);
        let (px, _) = pitch(&s);
        for (r, d) in [(0.004, 0.0003), (0.006, 0.0008), (0.010, 0.0005), (0.003, 0.001)] {
            let img = optical_image(&s, Some(&ball_press_depth(&s, r, d, [0.0, 0.0])), None, None);
            let expected = (2.0 * r * d - d * d).sqrt();
            let got = changed_radius(&s, &img, &reference);
            eprintln!(
                "{preset:?} R {r} d {d}: disc radius {:.4} mm, geometric {:.4} mm, pixel {:.4} mm",
                got * 1e3,
                expected * 1e3,
                px * 1e3
            );
            // Within a quarter of a pixel (the issue asks for one).
            assert!((got - expected).abs() <= 0.25 * px, "{preset:?} R {r} d {d}: disc radius {got} vs {expected} (pixel {px})");
        }
    }
}

/// Solves ∇²g = div(slopes) with g = 0 on the image border (successive over-relaxation): the
/// height map whose slopes are closest to the given ones.
fn integrate(s: &OpticalSensor, slopes: &[(f64, f64)]) -> Vec<f64> {
    let [w, h] = s.image_size.map(|v| v as usize);
    let (px, py) = pitch(s);
    let at = |x: usize, y: usize| slopes[y * w + x];
    // The divergence of central-difference slopes, at the pixel: (g(x+1) - 2g + g(x-1)) / px².
    let mut div = vec![0.0; w * h];
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            div[y * w + x] = (at(x + 1, y).0 - at(x - 1, y).0) / (2.0 * px) + (at(x, y + 1).1 - at(x, y - 1).1) / (2.0 * py);
        }
    }
    let (cx, cy) = (1.0 / (px * px), 1.0 / (py * py));
    let mut g = vec![0.0; w * h];
    for _ in 0..3000 {
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let i = y * w + x;
                let gs = ((g[i - 1] + g[i + 1]) * cx + (g[i - w] + g[i + w]) * cy - div[i]) / (2.0 * (cx + cy));
                g[i] += 1.9 * (gs - g[i]);
            }
        }
    }
    g
}

#[test]
fn photometric_stereo_on_the_image_gives_back_the_gels_height_map() {
    for preset in [OpticalPreset::GelsightMini, OpticalPreset::Digit] {
        let mut s = sensor(preset);
        s.noise_std = 0.0;
        let depth = ball_press_depth(&s, 0.008, 0.0006, [0.001, -0.0005]);
        let gel = gel_surface(&s, &indentation(&s, &depth));
        let img = optical_image(&s, Some(&depth), None, None);
        let height = integrate(&s, &slopes_from_image(&s, &img));
        let errors: Vec<f64> = height.iter().zip(&gel).map(|(a, b)| (a - b).abs()).collect();
        let max = errors.iter().cloned().fold(0.0, f64::max);
        let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
        let peak = gel.iter().cloned().fold(0.0, f64::max);
        eprintln!("{preset:?}: height error max {:.2} µm rms {:.2} µm, dent {:.3} mm", max * 1e6, rms * 1e6, peak * 1e3);
        // 8-bit levels bound each slope to ~0.006, but their errors are unbiased and average out
        // along the integration: a few µm at most over a 0.6 mm dent.
        assert!(max < 5e-6 && rms < 1e-6, "{preset:?}: height error max {max} rms {rms} (peak {peak})");
        assert!((peak - 0.0006).abs() < 1e-6, "{preset:?}: the gel's deepest point {peak} is the sphere's");
    }
}

#[test]
fn no_contact_gives_the_reference_image_exactly_and_noise_is_the_configured_noise() {
    let s = sensor(OpticalPreset::GelsightMini);
    let reference = reference_image(&s);
    let far = vec![f32::INFINITY; (s.image_size[0] * s.image_size[1]) as usize];
    assert_eq!(optical_image(&s, None, None, None), reference);
    assert_eq!(optical_image(&s, Some(&far), None, None), reference);
    // An object beyond the gel's free surface does not touch it either.
    let beyond = vec![(s.gel_thickness_mm * 1e-3 + 1e-4) as f32; far.len()];
    assert_eq!(optical_image(&s, Some(&beyond), None, None), reference);
    let noisy = optical_image(&s, None, None, Some(&mut ChaCha8Rng::seed_from_u64(1)));
    let d: Vec<f64> = noisy.rgb.iter().zip(&reference.rgb).map(|(a, b)| *a as f64 - *b as f64).collect();
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    let std = (d.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / d.len() as f64).sqrt();
    // Rounding the noisy and the clean value to levels adds 1/12 of a level² of variance each.
    let expected = (s.noise_std * s.noise_std + 2.0 / 12.0).sqrt();
    assert!(mean.abs() < 0.01 && (std - expected).abs() < 0.03, "noise mean {mean} std {std} vs {expected}");
}

#[test]
fn images_are_deterministic_per_noise_stream() {
    let mut s = sensor(OpticalPreset::Digit);
    s.markers = Some(OpticalPreset::Digit.markers());
    let depth = ball_press_depth(&s, 0.006, 0.0005, [0.0, 0.0]);
    let a = optical_image(&s, Some(&depth), None, Some(&mut ChaCha8Rng::seed_from_u64(5)));
    assert_eq!(a, optical_image(&s, Some(&depth), None, Some(&mut ChaCha8Rng::seed_from_u64(5))));
    assert_ne!(a, optical_image(&s, Some(&depth), None, Some(&mut ChaCha8Rng::seed_from_u64(6))));
}

/// The centroid (m) of the darkest pixels (markers) within `half` of `around`.
fn marker_centroid(s: &OpticalSensor, img: &OpticalImage, reference: &OpticalImage, around: [f64; 2], half: f64) -> [f64; 2] {
    let [w, h] = s.image_size;
    let (mut sum, mut weight) = ([0.0; 2], 0.0);
    for v in 0..h {
        for u in 0..w {
            let (_, [x, y]) = pixel_position(s, u, v);
            if (x - around[0]).abs() > half || (y - around[1]).abs() > half {
                continue;
            }
            // Darkness relative to the unmarked gel's brightness there: the reference without markers.
            let k = ((v * w + u) * 3) as usize;
            let lum = |i: &OpticalImage| i.rgb[k..k + 3].iter().map(|&c| c as f64).sum::<f64>();
            let dark = (1.0 - lum(img) / lum(reference)).max(0.0);
            if dark > 0.3 {
                sum = [sum[0] + dark * x, sum[1] + dark * y];
                weight += dark;
            }
        }
    }
    [sum[0] / weight, sum[1] / weight]
}

#[test]
fn markers_move_away_from_a_contact() {
    let mut s = sensor(OpticalPreset::GelsightMini);
    s.noise_std = 0.0;
    let mut marked = s.clone();
    marked.markers = Some(OpticalPreset::GelsightMini.markers());
    let pitch = marked.markers.unwrap().pitch_mm * 1e-3;
    // A sphere centred on a marker near the middle; the next marker to its right sits on the
    // dent's slope (the contact disc's radius is 3.5 mm, the pitch 2 mm).
    let centre = marker_positions(&marked).into_iter().min_by(|a, b| a[0].hypot(a[1]).total_cmp(&b[0].hypot(b[1]))).unwrap();
    let depth = ball_press_depth(&s, 0.008, 0.0008, centre);
    let plain = optical_image(&s, Some(&depth), None, None);
    let pressed = optical_image(&marked, Some(&depth), None, None);
    let rest = optical_image(&marked, None, None, None);
    let flat = reference_image(&s);
    let marker = [centre[0] + pitch, centre[1]];
    let before = marker_centroid(&marked, &rest, &flat, marker, pitch / 2.0);
    let after = marker_centroid(&marked, &pressed, &plain, marker, pitch / 2.0);
    assert!((before[0] - marker[0]).abs() < 0.02e-3 && (before[1] - marker[1]).abs() < 0.02e-3, "{before:?} vs {marker:?}");
    let moved = [after[0] - before[0], after[1] - before[1]];
    assert!(moved[0] > 0.02e-3 && moved[1].abs() < 0.3 * moved[0], "the marker moved {moved:?}: away from the contact along +x");
}

/// Darkness-weighted centroid (m) of the marker painted near `rest` in `img` over the shading
/// `base` (the same image without markers), within half a marker pitch of `rest`.
fn painted_marker_centroid(s: &OpticalSensor, base: &[f64], img: &[f64], rest: [f64; 2]) -> [f64; 2] {
    let half = 0.5 * s.markers.expect("markers").pitch_mm * 1e-3;
    let [w, h] = s.image_size;
    let (mut sum, mut x, mut y) = (0.0, 0.0, 0.0);
    for v in 0..h {
        for u in 0..w {
            let (_, [px, py]) = pixel_position(s, u, v);
            if (px - rest[0]).abs() < half && (py - rest[1]).abs() < half {
                let k = (v * w + u) as usize * 3;
                let dark: f64 = (0..3).map(|c| base[k + c] - img[k + c]).sum();
                (sum, x, y) = (sum + dark, x + dark * px, y + dark * py);
            }
        }
    }
    [x / sum, y / sum]
}

/// The shear test: a flat indenter pressed into the gel with 4 N over the pad's left half, then
/// dragged along the pad's x with a growing force up to the friction limit (0.8 × 4 N). Every
/// marker moves by the elastic model's displacement (Cerruti, `GelShear`) at its rest position,
/// measured on the painted image to a tenth of a pixel; the displacement grows in proportion to
/// the drag while the contact sticks, and at the limit every pressed cell slips. With no shear the
/// image is the one without force fields.
#[test]
fn markers_follow_the_gels_shear_displacement_until_the_contact_slips() {
    use crate::sensors::force_field::{GelShear, PadContact, PadTouch, force_field};
    let mut s = sensor(OpticalPreset::GelsightMini);
    s.markers = Some(OpticalPreset::GelsightMini.markers());
    s.noise_std = 0.0;
    let size = (s.sensing_area_mm[0] * 1e-3, s.sensing_area_mm[1] * 1e-3);
    // The pad's 16 x 16 view: the indenter flat against the left half.
    let gap: Vec<f32> = (0..256).map(|i| if i % 16 < 8 { 0.0 } else { f32::INFINITY }).collect();
    let base = shade(&s, None);
    let painted = |shear: Option<&GelShear>| {
        let mut img = base.clone();
        paint_markers(&s, &mut img, &marker_flow(&s, None, shear));
        img
    };
    let at_rest = painted(None);
    let markers = marker_positions(&s);
    let probe = markers.iter().copied().min_by(|a, b| a[0].hypot(a[1]).total_cmp(&b[0].hypot(b[1]))).expect("markers");
    let (px, _) = pitch(&s);
    let mut per_newton = Vec::new();
    for drag in [0.8, 1.6, 2.4, 3.2] {
        let contacts = [PadContact { point: glam::DVec3::new(-size.0 / 4.0, 0.0, 0.0), force: glam::DVec3::new(drag, 0.0, -4.0) }];
        let touch = PadTouch { pad: "left", contacts: &contacts, gap: &gap, n: 16, threshold: 0.002, size, friction: 0.8 };
        let field = force_field(&touch, 16);
        let shear = GelShear::new(&field, size, 500e3);
        let img = painted(Some(&shear));
        let radius = s.markers.expect("markers").radius_mm * 1e-3;
        let (ax, ay) = (size.0 / 2.0, size.1 / 2.0);
        let (mut checked, mut worst) = (0, 0.0f64);
        for &rest in &markers {
            let [ux, uy] = shear.at(rest);
            // A dot the image's edge cuts has a biased centroid: only whole dots are measured.
            let reach = radius + ux.abs().max(uy.abs()) + 2.0 * px;
            if rest[0].abs() + reach > ax || rest[1].abs() + reach > ay {
                continue;
            }
            let moved = painted_marker_centroid(&s, &base, &img, rest);
            let still = painted_marker_centroid(&s, &base, &at_rest, rest);
            let error = ((moved[0] - still[0] - ux).powi(2) + (moved[1] - still[1] - uy).powi(2)).sqrt();
            assert!(
                error < 0.1 * px,
                "drag {drag} N, marker at {rest:?}: moved {:?}, model ({ux}, {uy})",
                [moved[0] - still[0], moved[1] - still[1]]
            );
            (checked, worst) = (checked + 1, worst.max(error / px));
        }
        assert!(checked * 2 > markers.len(), "drag {drag}: {checked} of {} markers measured", markers.len());
        eprintln!("drag {drag} N: {checked} markers within {worst:.3} px of the model");
        // Along the drag, most under the contact.
        let u = shear.at(probe);
        assert!(u[0] > 0.0 && u[0] > 5.0 * u[1].abs(), "drag {drag}: {u:?}");
        per_newton.push(u[0] / drag);
        let slipping = field.cells.iter().filter(|c| c.slip).count();
        if drag < 3.2 {
            assert_eq!(slipping, 0, "drag {drag}: a uniform press sticks below the limit");
        } else {
            assert_eq!(slipping, 128, "at the friction limit every pressed cell slips");
        }
    }
    // Elastic: the same displacement per newton at every drag.
    assert!(per_newton.iter().all(|k| (k / per_newton[0] - 1.0).abs() < 1e-6), "{per_newton:?}");
    // No shear: the markers stay where the image without force fields has them.
    let still = GelShear::new(
        &force_field(&PadTouch { pad: "left", contacts: &[], gap: &gap, n: 16, threshold: 0.002, size, friction: 0.8 }, 16),
        size,
        500e3,
    );
    assert!(still.is_empty());
    assert_eq!(optical_image(&s, None, Some(&still), None), optical_image(&s, None, None, None));
}

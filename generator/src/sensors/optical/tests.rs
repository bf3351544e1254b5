//! The optical image model checked against geometry: a sphere of known radius pressed a known
//! depth into the gel, and photometric stereo back to the gel's height map.

use super::*;
use crate::config::{OpticalConfig, OpticalPreset};
use rand::SeedableRng;

fn sensor(preset: OpticalPreset) -> OpticalSensor {
    OpticalConfig { preset, ..Default::default() }.resolve()
}

/// The depth (from the pad plane) of a sphere of radius `r` whose lowest point is `pressed` into
/// the gel's free surface, centred over the image position `centre` (m).
fn sphere_depth(s: &OpticalSensor, r: f64, pressed: f64, centre: [f64; 2]) -> Vec<f32> {
    let lowest = s.gel_thickness_mm * 1e-3 - pressed;
    let [w, h] = s.image_size;
    (0..h)
        .flat_map(|v| (0..w).map(move |u| (u, v)))
        .map(|(u, v)| {
            let (_, [x, y]) = pixel_position(s, u, v);
            let q = (x - centre[0]).powi(2) + (y - centre[1]).powi(2);
            if q < r * r { (lowest + r - (r * r - q).sqrt()) as f32 } else { f32::INFINITY }
        })
        .collect()
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
            let img = optical_image(&s, Some(&sphere_depth(&s, r, d, [0.0, 0.0])), None);
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
        let depth = sphere_depth(&s, 0.008, 0.0006, [0.001, -0.0005]);
        let gel = gel_surface(&s, &indentation(&s, &depth));
        let img = optical_image(&s, Some(&depth), None);
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
    assert_eq!(optical_image(&s, None, None), reference);
    assert_eq!(optical_image(&s, Some(&far), None), reference);
    // An object beyond the gel's free surface does not touch it either.
    let beyond = vec![(s.gel_thickness_mm * 1e-3 + 1e-4) as f32; far.len()];
    assert_eq!(optical_image(&s, Some(&beyond), None), reference);
    let noisy = optical_image(&s, None, Some(&mut ChaCha8Rng::seed_from_u64(1)));
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
    let depth = sphere_depth(&s, 0.006, 0.0005, [0.0, 0.0]);
    let a = optical_image(&s, Some(&depth), Some(&mut ChaCha8Rng::seed_from_u64(5)));
    assert_eq!(a, optical_image(&s, Some(&depth), Some(&mut ChaCha8Rng::seed_from_u64(5))));
    assert_ne!(a, optical_image(&s, Some(&depth), Some(&mut ChaCha8Rng::seed_from_u64(6))));
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
    let depth = sphere_depth(&s, 0.008, 0.0008, centre);
    let plain = optical_image(&s, Some(&depth), None);
    let pressed = optical_image(&marked, Some(&depth), None);
    let rest = optical_image(&marked, None, None);
    let flat = reference_image(&s);
    let marker = [centre[0] + pitch, centre[1]];
    let before = marker_centroid(&marked, &rest, &flat, marker, pitch / 2.0);
    let after = marker_centroid(&marked, &pressed, &plain, marker, pitch / 2.0);
    assert!((before[0] - marker[0]).abs() < 0.02e-3 && (before[1] - marker[1]).abs() < 0.02e-3, "{before:?} vs {marker:?}");
    let moved = [after[0] - before[0], after[1] - before[1]];
    assert!(moved[0] > 0.02e-3 && moved[1].abs() < 0.3 * moved[0], "the marker moved {moved:?}: away from the contact along +x");
}

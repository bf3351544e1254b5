//! Sensor realism for sim-to-real (beyond the paper): an RGB-D noise model applied after rendering.
//! The clean z-depth stays the ground truth (`/camera/depth`); the noisy one is stored beside it
//! (`/camera/depth_noisy`). Colour noise is applied to `/camera/rgb` itself. Its parameters are the
//! config's `camera.noise` (`config::noise`).
//!
//! The depth model follows structured-light / active-stereo cameras (Kinect, RealSense):
//! - axial noise growing with the square of the distance, σ(z) = σ₀ + k·z²;
//! - disparity quantization: the depth is measured as a disparity `f·b/z` in 1/`subpixel` pixel steps;
//! - no measurement at depth edges (the pattern is split between two surfaces) and on surfaces
//!   seen at grazing angles (the pattern is too stretched to match);
//! - random dropouts.

use rand::Rng;
use rand_chacha::ChaCha8Rng;

pub use crate::config::{CameraNoiseConfig, ColorNoise, DepthNoise};

/// A standard normal draw (Box–Muller; one draw per call keeps the stream simple to reason about).
fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = rng.random::<f64>().max(1e-300);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

impl DepthNoise {
    pub fn sigma_m(&self, z: f64) -> f64 {
        (self.sigma_mm + self.sigma_quadratic_mm * z * z) * 1e-3
    }

    /// The noisy depth image of a clean z-depth image (0 = no surface), with focal length `fx`
    /// (pixels) for the disparity and `k` to reconstruct viewing rays.
    pub fn apply(&self, depth: &[f32], width: u32, height: u32, k: [f64; 4], rng: &mut ChaCha8Rng) -> Vec<f32> {
        let [fx, fy, cx, cy] = k;
        let (w, h) = (width as usize, height as usize);
        let z = |x: usize, y: usize| depth[y * w + x] as f64;
        let cos_grazing = self.grazing_deg.to_radians().cos();
        let mut out = vec![0f32; depth.len()];
        for y in 0..h {
            for x in 0..w {
                let d = z(x, y);
                // Draw every pixel's numbers whether or not it is kept, so a pixel's noise does
                // not depend on its neighbours.
                let (n, drop) = (normal(rng), rng.random::<f64>() < self.dropout);
                if d <= 0.0 || drop || x == 0 || y == 0 || x + 1 == w || y + 1 == h {
                    continue;
                }
                let nb = [z(x - 1, y), z(x + 1, y), z(x, y - 1), z(x, y + 1)];
                let edge = self.edge_mm * 1e-3 + 0.02 * d;
                if nb.iter().any(|&v| v <= 0.0 || (v - d).abs() > edge) {
                    continue;
                }
                // Surface normal from the back-projected neighbours; compare with the viewing ray.
                let p = |u: f64, v: f64, zz: f64| glam::DVec3::new((u - cx) / fx * zz, (v - cy) / fy * zz, zz);
                let (xf, yf) = (x as f64, y as f64);
                let du = p(xf + 1.0, yf, nb[1]) - p(xf - 1.0, yf, nb[0]);
                let dv = p(xf, yf + 1.0, nb[3]) - p(xf, yf - 1.0, nb[2]);
                let normal_v = du.cross(dv).normalize_or_zero();
                let ray = p(xf, yf, d).normalize();
                if normal_v.dot(ray).abs() < cos_grazing {
                    continue;
                }
                let mut noisy = d + n * self.sigma_m(d);
                if self.baseline_m > 0.0 && self.subpixel > 0.0 {
                    let disparity = fx * self.baseline_m / noisy;
                    noisy = fx * self.baseline_m / ((disparity * self.subpixel).round() / self.subpixel);
                }
                out[y * w + x] = noisy.max(0.0) as f32;
            }
        }
        out
    }
}

impl ColorNoise {
    /// Adds read and shot noise to an sRGB image in place.
    pub fn apply(&self, rgb: &mut [u8], rng: &mut ChaCha8Rng) {
        for c in rgb.iter_mut() {
            let v = *c as f64;
            let sigma = (self.sigma * self.sigma + self.shot * v).sqrt();
            *c = (v + normal(rng) * sigma).round().clamp(0.0, 255.0) as u8;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    /// A fronto-parallel plane at `z` with a step to `z + 0.2` in the right half.
    fn plane(z: f32) -> Vec<f32> {
        (0..64 * 48).map(|i| if i % 64 < 32 { z } else { z + 0.2 }).collect()
    }

    const K: [f64; 4] = [600.0, 600.0, 31.5, 23.5];

    #[test]
    fn axial_noise_follows_the_model_and_the_step_edge_is_invalid() {
        let noise = DepthNoise { baseline_m: 0.0, dropout: 0.0, ..Default::default() };
        let clean = plane(1.5);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut err = Vec::new();
        for _ in 0..20 {
            let noisy = noise.apply(&clean, 64, 48, K, &mut rng);
            for y in 1..47 {
                // The columns next to the step have no measurement; the rest have one.
                assert_eq!(noisy[y * 64 + 31], 0.0);
                assert_eq!(noisy[y * 64 + 32], 0.0);
                for x in 1..30 {
                    assert!(noisy[y * 64 + x] > 0.0);
                    err.push(noisy[y * 64 + x] as f64 - 1.5);
                }
            }
        }
        let mean = err.iter().sum::<f64>() / err.len() as f64;
        let sd = (err.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / err.len() as f64).sqrt();
        let want = noise.sigma_m(1.5);
        assert!(mean.abs() < 0.1 * want, "unbiased: {mean}");
        assert!((sd / want - 1.0).abs() < 0.05, "σ {sd} vs model {want}");
    }

    #[test]
    fn quantization_puts_depths_on_disparity_steps_and_grazing_surfaces_drop_out() {
        let noise = DepthNoise { sigma_mm: 0.0, sigma_quadratic_mm: 0.0, dropout: 0.0, ..Default::default() };
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let noisy = noise.apply(&plane(2.0), 64, 48, K, &mut rng);
        let v = noisy[10 * 64 + 10] as f64;
        let steps = 600.0 * 0.05 / v * 8.0;
        assert!((steps - steps.round()).abs() < 1e-3, "on a disparity step: {steps}");
        assert!((v - 2.0).abs() < 2.0 * 2.0 / (600.0 * 0.05 * 8.0), "within one step of the truth");
        // A plane seen at about 84° from its normal (z grows 10 pixel widths per pixel at z = 1)
        // reads nothing on its near half; one at about 45° reads everywhere inside the border.
        let ramp = |slope: f32| -> Vec<f32> { (0..64 * 48).map(|i| 1.0 + ((i % 64) as f32) * slope / 600.0).collect() };
        let out = noise.apply(&ramp(10.0), 64, 48, K, &mut rng);
        assert!((0..64 * 48).filter(|i| i % 64 < 32).all(|i| out[i] == 0.0), "grazing surfaces read nothing");
        let out = noise.apply(&ramp(1.0), 64, 48, K, &mut rng);
        assert!((0..64 * 48).filter(|i| (1..63).contains(&(i % 64)) && (1..47).contains(&(i / 64))).all(|i| out[i] > 0.0));
    }

    #[test]
    fn colour_noise_has_the_configured_spread() {
        let noise = ColorNoise { sigma: 2.0, shot: 0.0 };
        let mut img = vec![128u8; 30000];
        noise.apply(&mut img, &mut ChaCha8Rng::seed_from_u64(5));
        let sd = (img.iter().map(|&v| (v as f64 - 128.0).powi(2)).sum::<f64>() / img.len() as f64).sqrt();
        assert!((sd - 2.0).abs() < 0.15, "σ {sd}");
    }
}

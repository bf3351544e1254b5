//! The global stage: thousands of rotations spread evenly over SO(3), each given the translation
//! that puts its camera-facing surface on the observed points, translation-only Gauss-Newton
//! steps on the distance field, and a truncated-quadratic score, coarse to fine; the best few
//! distinct hypotheses go on to the local stage.

use glam::{DMat3, DQuat, DVec3};

use super::shape::ObjectShape;
use super::{Observation, Pose, RefineConfig};

/// `n` unit quaternions spread evenly over the 3-sphere (super-Fibonacci spirals, Alexa, CVPR
/// 2022): deterministic, no rejection, no clustering at the poles.
pub fn super_fibonacci(n: usize) -> Vec<DQuat> {
    let phi = std::f64::consts::SQRT_2;
    let psi = 1.533_751_168_755_204_3_f64;
    (0..n)
        .map(|i| {
            let s = i as f64 + 0.5;
            let (r, big_r) = ((s / n as f64).sqrt(), (1.0 - s / n as f64).sqrt());
            let (alpha, beta) = (std::f64::consts::TAU * s / phi, std::f64::consts::TAU * s / psi);
            DQuat::from_xyzw(r * alpha.sin(), r * alpha.cos(), big_r * beta.sin(), big_r * beta.cos()).normalize()
        })
        .collect()
}

/// Every `k`-th point so that at most `n` remain (an even spread of an already random subset).
fn spread(points: &[DVec3], n: usize) -> Vec<DVec3> {
    if points.len() <= n {
        return points.to_vec();
    }
    (0..n).map(|i| points[i * points.len() / n]).collect()
}

/// The distance-field score of a pose: the weighted truncated squares of the points' distances,
/// each group averaged. Lower is better.
fn field_cost(shape: &ObjectShape, groups: &[(&[DVec3], f64)], q: DQuat, t: DVec3, tau: f64) -> f64 {
    let inv = q.inverse();
    groups
        .iter()
        .filter(|(pts, _)| !pts.is_empty())
        .map(|(pts, w)| {
            let sum: f64 = pts
                .iter()
                .map(|p| {
                    let (d, _) = shape.field.sample((inv * (*p - t)).as_vec3());
                    (d as f64).min(tau).powi(2)
                })
                .sum();
            w * sum / pts.len() as f64
        })
        .sum()
}

/// Gauss-Newton steps on the translation alone, the distance field's gradient as the Jacobian;
/// points farther than `tau` are left out.
fn fit_translation(shape: &ObjectShape, groups: &[(&[DVec3], f64)], q: DQuat, mut t: DVec3, tau: f64, steps: usize) -> DVec3 {
    let inv = q.inverse();
    for _ in 0..steps {
        let (mut h, mut g) = (DMat3::ZERO, DVec3::ZERO);
        for (pts, w) in groups.iter().filter(|(pts, _)| !pts.is_empty()) {
            let w = w / pts.len() as f64;
            for p in pts.iter() {
                let (d, grad) = shape.field.sample((inv * (*p - t)).as_vec3());
                let d = d as f64;
                if d >= tau {
                    continue;
                }
                // d(q⁻¹(p − t)) / dt = −R⁻¹: the Jacobian row is −(R ∇d)ᵀ.
                let j = -(q * grad.as_dvec3());
                h += DMat3::from_cols(j * j.x, j * j.y, j * j.z) * w;
                g += j * (d * w);
            }
        }
        if h.determinant().abs() < 1e-18 {
            break;
        }
        let damped = h + DMat3::from_diagonal(DVec3::splat(1e-9 + 1e-3 * (h.x_axis.x + h.y_axis.y + h.z_axis.z) / 3.0));
        t -= damped.inverse() * g;
    }
    t
}

/// The global search (see the module docs), coarse to fine: every rotation scored with a
/// quarter of the points after one translation step, the best `cfg.search_keep` again with all
/// of them after `cfg.search_translation_steps`; the best `cfg.candidates` distinct hypotheses,
/// lowest score first.
pub fn hypotheses(shape: &ObjectShape, obs: &Observation, cfg: &RefineConfig, rotations: &[DQuat]) -> Vec<Pose> {
    let depth = spread(&obs.depth, cfg.search_depth_points);
    let touch = spread(&obs.touch, cfg.search_touch_points);
    let anchor: &[DVec3] = if depth.is_empty() { &touch } else { &depth };
    if anchor.is_empty() {
        return Vec::new();
    }
    let center = anchor.iter().sum::<DVec3>() / anchor.len() as f64;
    let view = center.normalize_or(DVec3::Z);
    let tau = cfg.search_tau_m;
    let (coarse_depth, coarse_touch) = (spread(&depth, depth.len().div_ceil(4)), spread(&touch, touch.len().div_ceil(4)));
    let coarse: [(&[DVec3], f64); 2] = [(&coarse_depth, 1.0), (&coarse_touch, cfg.touch_weight)];
    let mut scored: Vec<(f64, Pose)> = rotations
        .iter()
        .map(|&q| {
            let t0 = center - q * shape.facing_centroid(q.inverse() * view);
            let t = fit_translation(shape, &coarse, q, t0, 2.0 * tau, 1);
            (field_cost(shape, &coarse, q, t, tau), (q, t))
        })
        .collect();
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    scored.truncate(cfg.search_keep);
    let fine: [(&[DVec3], f64); 2] = [(&depth, 1.0), (&touch, cfg.touch_weight)];
    let mut scored: Vec<(f64, Pose)> = scored
        .into_iter()
        .map(|(_, (q, t0))| {
            let t = fit_translation(shape, &fine, q, t0, 2.0 * tau, cfg.search_translation_steps);
            (field_cost(shape, &fine, q, t, tau), (q, t))
        })
        .collect();
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Non-maximum suppression: a hypothesis near a kept one adds nothing.
    let mut kept: Vec<Pose> = Vec::with_capacity(cfg.candidates);
    for (_, (q, t)) in scored {
        let near = kept.iter().any(|(kq, kt)| kq.angle_between(q).to_degrees() < cfg.distinct_deg && kt.distance(t) < cfg.distinct_m);
        if !near {
            kept.push((q, t));
            if kept.len() == cfg.candidates {
                break;
            }
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_spiral_covers_rotations_evenly() {
        let qs = super_fibonacci(4096);
        assert!(qs.iter().all(|q| (q.length() - 1.0).abs() < 1e-12));
        // The default 4096 leave no probe rotation farther than 15° from one of them.
        let probes = super_fibonacci(97).into_iter().map(|q| q * DQuat::from_rotation_x(0.3));
        let nearest: Vec<f64> = probes.map(|p| qs.iter().map(|q| q.angle_between(p).to_degrees()).fold(f64::MAX, f64::min)).collect();
        let (max, mean) = (nearest.iter().copied().fold(0.0, f64::max), nearest.iter().sum::<f64>() / nearest.len() as f64);
        assert!(max < 15.0 && mean < 10.0, "nearest rotation: max {max:.1}°, mean {mean:.1}°");
    }
}

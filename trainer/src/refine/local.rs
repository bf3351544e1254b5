//! The local stage: robust point-to-plane Gauss-Newton on SE(3). Each observed point (the depth
//! points, and the tactile points as point-to-surface terms of their own weight) is matched to
//! the nearest of the object's surface points; its residual is the distance along that point's
//! normal; Geman-McClure weights with a shrinking scale let the outliers (points of another
//! surface the mask let in, a wrong match early on) fade out. The final score adds the free-space
//! term: the share of the object's camera-facing surface that the depth image shows to be empty.

use glam::{DMat3, DQuat, DVec3};
use nalgebra::{Matrix6, Vector6};

use super::shape::ObjectShape;
use super::{Observation, Pose, RefineConfig};

/// The pose `T_object_camera` as the solver moves it: `x = A p + b`.
#[derive(Debug, Clone, Copy)]
struct Inverse {
    a: DMat3,
    b: DVec3,
}

impl Inverse {
    fn of((q, t): Pose) -> Self {
        let a = DMat3::from_quat(q.inverse());
        Inverse { a, b: -(a * t) }
    }

    fn pose(&self) -> Pose {
        let q = DQuat::from_mat3(&self.a).normalize().inverse();
        (q, -(self.a.transpose() * self.b))
    }

    fn apply(&self, p: DVec3) -> DVec3 {
        self.a * p + self.b
    }

    /// Left-multiplies `exp(ω, v)`: `x' = R(ω) x + v`.
    fn perturbed(&self, omega: DVec3, v: DVec3) -> Self {
        let r = DMat3::from_quat(DQuat::from_scaled_axis(omega));
        Inverse { a: r * self.a, b: r * self.b + v }
    }
}

/// The point-to-plane residual of `p` (camera frame) under `inv`, and its object-frame point and
/// normal.
fn residual(shape: &ObjectShape, inv: &Inverse, p: DVec3) -> (f64, DVec3, DVec3) {
    let x = inv.apply(p);
    let k = shape.nearest(x);
    let n = shape.normals[k];
    (n.dot(x - shape.points[k]), x, n)
}

/// Refines `start` by Gauss-Newton (see the module docs).
pub fn refine(shape: &ObjectShape, obs: &Observation, cfg: &RefineConfig, start: Pose) -> Pose {
    let groups: [(&[DVec3], f64); 2] = [(&obs.depth, 1.0), (&obs.touch, cfg.touch_weight)];
    let mut inv = Inverse::of(start);
    for it in 0..cfg.local_iterations {
        let sigma = (cfg.local_sigma_start_m * cfg.local_sigma_decay.powi(it as i32)).max(cfg.local_sigma_min_m);
        let (mut h, mut g) = (Matrix6::<f64>::zeros(), Vector6::<f64>::zeros());
        for (pts, w) in groups.iter().filter(|(pts, _)| !pts.is_empty()) {
            let w = w / pts.len() as f64;
            for &p in pts.iter() {
                let (r, x, n) = residual(shape, &inv, p);
                let u = r / sigma;
                let robust = 1.0 / (1.0 + u * u).powi(2);
                let xn = x.cross(n);
                let j = Vector6::new(xn.x, xn.y, xn.z, n.x, n.y, n.z);
                h += j * j.transpose() * (w * robust);
                g += j * (r * w * robust);
            }
        }
        // Levenberg-Marquardt damping: a flat patch leaves some directions unconstrained.
        let lambda = 1e-6 + 1e-4 * h.trace() / 6.0;
        let damped = h + Matrix6::identity() * lambda;
        let Some(chol) = damped.cholesky() else { break };
        let delta = chol.solve(&(-g));
        let (omega, v) = (DVec3::new(delta[0], delta[1], delta[2]), DVec3::new(delta[3], delta[4], delta[5]));
        inv = inv.perturbed(omega, v);
        if omega.length() < 1e-5 && v.length() < 1e-6 {
            break;
        }
    }
    inv.pose()
}

/// The score of a pose (lower is better): per group, the mean truncated square of the
/// point-to-plane distances; plus the share of the object's camera-facing surface points that
/// the depth image shows to be empty, times the truncation's square and `cfg.free_space_weight`.
pub fn score(shape: &ObjectShape, obs: &Observation, cfg: &RefineConfig, pose: Pose) -> f64 {
    let inv = Inverse::of(pose);
    let tau2 = cfg.score_tau_m * cfg.score_tau_m;
    let groups: [(&[DVec3], f64); 2] = [(&obs.depth, 1.0), (&obs.touch, cfg.touch_weight)];
    let mut cost = 0.0;
    for (pts, w) in groups.iter().filter(|(pts, _)| !pts.is_empty()) {
        let sum: f64 = pts.iter().map(|&p| residual(shape, &inv, p).0.powi(2).min(tau2)).sum();
        cost += w * sum / pts.len() as f64;
    }
    if let Some(fs) = &obs.free_space {
        let (q, t) = pose;
        let (mut facing, mut empty) = (0usize, 0usize);
        for &k in &shape.free_space {
            let p = q * shape.points[k] + t;
            // Facing the camera: the normal points back along the ray.
            if (q * shape.normals[k]).dot(p) >= 0.0 {
                continue;
            }
            facing += 1;
            empty += fs.violated(p, cfg.free_space_margin_m) as usize;
        }
        if facing > 0 {
            cost += cfg.free_space_weight * tau2 * empty as f64 / facing as f64;
        }
    }
    cost
}

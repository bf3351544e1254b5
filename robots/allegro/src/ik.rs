//! Inverse kinematics of the palm pose over the 6 arm joints: damped least squares on a numerical
//! Jacobian (6 extra forward passes per iteration; the chain is short, so this is cheap and exact).

use glam::{DAffine3, DQuat, DVec3};

use crate::model::RobotModel;
use crate::{ARM_JOINTS, PALM};

#[derive(Debug, Clone, Copy)]
pub struct IkOptions {
    pub max_iterations: usize,
    /// Converged when the position error is below this (m) …
    pub position_tolerance: f64,
    /// … and the rotation error below this (rad).
    pub rotation_tolerance: f64,
    pub damping: f64,
}

impl Default for IkOptions {
    fn default() -> Self {
        IkOptions { max_iterations: 150, position_tolerance: 1e-5, rotation_tolerance: 1e-4, damping: 1e-3 }
    }
}

/// The 6-vector (position error, rotation error as axis * angle) from `current` to `target`.
fn pose_error(current: &DAffine3, target: &DAffine3) -> [f64; 6] {
    let dp = target.translation - current.translation;
    let rc = DQuat::from_mat3(&current.matrix3);
    let rt = DQuat::from_mat3(&target.matrix3);
    let mut dq = rt * rc.inverse();
    if dq.w < 0.0 {
        dq = -dq;
    }
    let (axis, angle) = dq.to_axis_angle();
    let dr = if angle.is_finite() { axis * angle } else { DVec3::ZERO };
    [dp.x, dp.y, dp.z, dr.x, dr.y, dr.z]
}

/// Solves the 6x6 system `(J Jᵀ + λ² I) y = e` by Gaussian elimination and returns `Jᵀ y`.
fn dls_step(j: &[[f64; 6]; 6], e: &[f64; 6], lambda: f64) -> [f64; 6] {
    let mut a = [[0.0; 7]; 6];
    for r in 0..6 {
        for c in 0..6 {
            a[r][c] = (0..6).map(|k| j[r][k] * j[c][k]).sum::<f64>() + if r == c { lambda * lambda } else { 0.0 };
        }
        a[r][6] = e[r];
    }
    for col in 0..6 {
        let piv = (col..6).max_by(|&x, &y| a[x][col].abs().total_cmp(&a[y][col].abs())).unwrap();
        a.swap(col, piv);
        let pivot_row = a[col];
        for (r, row) in a.iter_mut().enumerate() {
            if r != col {
                let f = row[col] / pivot_row[col];
                for (x, p) in row[col..].iter_mut().zip(&pivot_row[col..]) {
                    *x -= f * p;
                }
            }
        }
    }
    let y: Vec<f64> = (0..6).map(|r| a[r][6] / a[r][r]).collect();
    std::array::from_fn(|k| (0..6).map(|r| j[r][k] * y[r]).sum())
}

impl RobotModel {
    /// Indices of the arm joints in the joint-value vector.
    pub fn arm_dofs(&self) -> [usize; 6] {
        ARM_JOINTS.map(|n| self.dof(n).expect("validated at load"))
    }

    /// Pose of the palm in the robot base frame.
    pub fn palm_pose(&self, q: &[f64]) -> DAffine3 {
        self.relative_pose(q, self.root, self.link_id(PALM).expect("validated at load"))
    }

    /// Arm joint values that put the palm at `target` (robot base frame), starting from `q`
    /// (only the arm entries change; joint limits are respected). None if it does not converge.
    pub fn solve_palm_ik(&self, target: &DAffine3, q: &[f64], opts: &IkOptions) -> Option<Vec<f64>> {
        if let Some(q) = self.solve_palm_ik_from(target, q, opts) {
            return Some(q);
        }
        // Local solvers fail when the seed faces away from the target: retry with the shoulder
        // turned towards the target's azimuth (and its neighbours).
        let pan = self.arm_dofs()[0];
        let azimuth = target.translation.y.atan2(target.translation.x);
        let current = q[pan];
        for offset in [0.0, 0.5, -0.5, 1.0, -1.0, std::f64::consts::PI] {
            let mut seed = q.to_vec();
            // UR link lengths are negative: the palm sits roughly opposite the pan angle.
            let turn = azimuth - std::f64::consts::PI + offset;
            seed[pan] = current + (turn - current + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
            if let Some(q) = self.solve_palm_ik_from(target, &seed, opts) {
                return Some(q);
            }
        }
        None
    }

    fn solve_palm_ik_from(&self, target: &DAffine3, q: &[f64], opts: &IkOptions) -> Option<Vec<f64>> {
        let arm = self.arm_dofs();
        let palm = self.link_id(PALM)?;
        let mut q = q.to_vec();
        let h = 1e-6;
        for _ in 0..opts.max_iterations {
            let cur = self.relative_pose(&q, self.root, palm);
            let e = pose_error(&cur, target);
            let pe = (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt();
            let re = (e[3] * e[3] + e[4] * e[4] + e[5] * e[5]).sqrt();
            if pe < opts.position_tolerance && re < opts.rotation_tolerance {
                return Some(q);
            }
            let mut jac = [[0.0; 6]; 6];
            for (k, &d) in arm.iter().enumerate() {
                let mut qh = q.clone();
                qh[d] += h;
                let moved = self.relative_pose(&qh, self.root, palm);
                // d(error)/dq = -(d(pose)/dq); the error to `moved` measures the change.
                let de = pose_error(&cur, &moved);
                for r in 0..6 {
                    jac[r][k] = de[r] / h;
                }
            }
            // Limit the step so the linearisation holds.
            let scale = (0.2 / pe.max(1e-12)).min(1.0).min((0.5 / re.max(1e-12)).min(1.0));
            let es: [f64; 6] = e.map(|x| x * scale);
            let dq = dls_step(&jac, &es, opts.damping);
            for (k, &d) in arm.iter().enumerate() {
                let jt = &self.joints[self.dof_joint(d)];
                q[d] = (q[d] + dq[k]).clamp(jt.lower, jt.upper);
            }
        }
        None
    }

    fn dof_joint(&self, dof: usize) -> usize {
        self.joints.iter().position(|j| j.dof == Some(dof)).expect("dof exists")
    }
}

//! Inverse kinematics of the grasp frame's pose over the arm chain (6 or 7 joints): damped least
//! squares on a numerical Jacobian (one extra forward pass per arm joint and iteration; the chain
//! is short, so this is cheap and exact).

use glam::{DAffine3, DQuat, DVec3};

use crate::description::Robot;

/// How strongly a redundant arm's null-space motion pulls each joint home per iteration (rad per
/// unit of the joint's range away).
const NULL_SPACE_GAIN: f64 = 0.2;

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

/// Solves the 6x6 system `(J Jᵀ + λ² I) y = e` by Gaussian elimination and returns `Jᵀ y`
/// (`j` holds one column of 6 per arm joint).
fn dls_step(j: &[[f64; 6]], e: &[f64; 6], lambda: f64) -> Vec<f64> {
    let mut a = [[0.0; 7]; 6];
    for r in 0..6 {
        for c in 0..6 {
            a[r][c] = j.iter().map(|col| col[r] * col[c]).sum::<f64>() + if r == c { lambda * lambda } else { 0.0 };
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
    j.iter().map(|col| (0..6).map(|r| col[r] * y[r]).sum()).collect()
}

impl Robot {
    /// Arm joint values that put the grasp frame at `target` (robot base frame), starting from
    /// `q` (only the arm entries change; joint limits are respected). Of the values a revolute
    /// joint can take for the same pose (whole turns apart), the one nearest `q` within its
    /// limits: the arm's path from `q` never spins a joint a full turn. None if it does not
    /// converge.
    pub fn solve_grasp_ik(&self, target: &DAffine3, q: &[f64], opts: &IkOptions) -> Option<Vec<f64>> {
        let solved = self.solve_grasp_ik_seeded(target, q, opts)?;
        Some(self.nearest_turns(solved, q))
    }

    /// `solved` with each revolute arm joint turned by whole turns (the same pose) to lie as near
    /// `seed` as its limits allow. The local solver, or its retries from a turned first joint, can
    /// land a wrist joint a turn or more from its seed (the UR5e's joints range over two turns).
    fn nearest_turns(&self, mut solved: Vec<f64>, seed: &[f64]) -> Vec<f64> {
        use std::f64::consts::TAU;
        for (&d, &j) in self.arm_dofs.iter().zip(&self.arm_joints) {
            let jt = &self.model.joints[j];
            if jt.kind != crate::model::JointKind::Revolute {
                continue;
            }
            let turns = ((seed[d] - solved[d]) / TAU).round();
            if turns == 0.0 {
                continue;
            }
            // The nearest whole turn, else one fewer when that one leaves the joint's range.
            if let Some(v) =
                [turns, turns - turns.signum()].map(|k| solved[d] + k * TAU).into_iter().find(|v| (jt.lower..=jt.upper).contains(v))
            {
                solved[d] = v;
            }
        }
        solved
    }

    fn solve_grasp_ik_seeded(&self, target: &DAffine3, q: &[f64], opts: &IkOptions) -> Option<Vec<f64>> {
        if let Some(q) = self.solve_grasp_ik_from(target, q, opts) {
            return Some(q);
        }
        // Local solvers fail when the seed faces away from the target: retry with the first arm
        // joint turned so that the grasp frame's azimuth meets the target's (and its neighbours).
        let pan = self.arm_dofs[0];
        let azimuth = target.translation.y.atan2(target.translation.x);
        let current = q[pan];
        for offset in [0.0, 0.5, -0.5, 1.0, -1.0, std::f64::consts::PI] {
            let mut seed = q.to_vec();
            let turn = azimuth - self.azimuth_offset + offset;
            seed[pan] = current + (turn - current + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
            if let Some(q) = self.solve_grasp_ik_from(target, &seed, opts) {
                return Some(q);
            }
        }
        None
    }

    fn solve_grasp_ik_from(&self, target: &DAffine3, q: &[f64], opts: &IkOptions) -> Option<Vec<f64>> {
        let m = &self.model;
        let frame = self.grasp_frame;
        let mut q = q.to_vec();
        let h = 1e-6;
        let mut jac = vec![[0.0; 6]; self.arm_dofs.len()];
        for _ in 0..opts.max_iterations {
            let cur = m.relative_pose(&q, m.root, frame);
            let e = pose_error(&cur, target);
            let pe = (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt();
            let re = (e[3] * e[3] + e[4] * e[4] + e[5] * e[5]).sqrt();
            if pe < opts.position_tolerance && re < opts.rotation_tolerance {
                return Some(q);
            }
            for (col, &d) in jac.iter_mut().zip(&self.arm_dofs) {
                let mut qh = q.clone();
                qh[d] += h;
                let moved = m.relative_pose(&qh, m.root, frame);
                // d(error)/dq = -(d(pose)/dq); the error to `moved` measures the change.
                let de = pose_error(&cur, &moved);
                for r in 0..6 {
                    col[r] = de[r] / h;
                }
            }
            // Limit the step so the linearisation holds.
            let scale = (0.2 / pe.max(1e-12)).min(1.0).min((0.5 / re.max(1e-12)).min(1.0));
            let es: [f64; 6] = e.map(|x| x * scale);
            let mut dq = dls_step(&jac, &es, opts.damping);
            // A redundant (7-joint) arm moves in the task's null space towards its home, each
            // joint by the share of its range it is away: the elbow stays where the home puts
            // it instead of drifting onto a joint limit. (A 6-joint arm has no null space.)
            if self.arm_dofs.len() > 6 {
                let pull: Vec<f64> = self
                    .arm_dofs
                    .iter()
                    .zip(&self.arm_joints)
                    .zip(&self.home)
                    .map(|((&d, &j), &home)| {
                        let jt = &m.joints[j];
                        let range = if (jt.upper - jt.lower).is_finite() { jt.upper - jt.lower } else { std::f64::consts::TAU };
                        NULL_SPACE_GAIN * (home - q[d]) / range
                    })
                    .collect();
                let mut jz = [0.0; 6];
                for (col, z) in jac.iter().zip(&pull) {
                    for r in 0..6 {
                        jz[r] += col[r] * z;
                    }
                }
                let back = dls_step(&jac, &jz, opts.damping);
                for ((s, z), b) in dq.iter_mut().zip(&pull).zip(back) {
                    *s += z - b;
                }
            }
            for ((&d, &j), step) in self.arm_dofs.iter().zip(&self.arm_joints).zip(dq) {
                let jt = &m.joints[j];
                q[d] = (q[d] + step).clamp(jt.lower, jt.upper);
            }
        }
        None
    }
}

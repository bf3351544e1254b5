//! Rotations: the network's unit quaternions as rotation matrices (on tensors, differentiable),
//! the host-side conversions of the format's quaternions, and an object's symmetries (the
//! rotations that make it look the same).
//!
//! Convention: the network outputs quaternions as **(w, x, y, z)** (DenseFusion's order); the
//! dataset stores (x, y, z, w) (FORMAT.md). `R` is the Hamilton rotation matrix, row-major, as
//! glam's `Mat3::from_quat`.

use burn::prelude::*;
use glam::{DMat3, DQuat, DVec3};

/// Unit quaternions `(.., 4)` in (w, x, y, z) order to row-major rotation matrices `(.., 9)`.
///
/// The quaternions must be normalised: the formula is the one of a unit quaternion.
pub fn quat_to_matrix<const D: usize>(q: Tensor<D>) -> Tensor<D> {
    let last = D - 1;
    let c = |i: usize| q.clone().narrow(last, i, 1);
    let (w, x, y, z) = (c(0), c(1), c(2), c(3));
    let two = |t: Tensor<D>| t.mul_scalar(2.0);
    let one_minus = |t: Tensor<D>| t.mul_scalar(-2.0).add_scalar(1.0);
    let (xx, yy, zz) = (x.clone() * x.clone(), y.clone() * y.clone(), z.clone() * z.clone());
    let (xy, xz, yz) = (x.clone() * y.clone(), x.clone() * z.clone(), y.clone() * z.clone());
    let (wx, wy, wz) = (w.clone() * x, w.clone() * y, w * z);
    Tensor::cat(
        vec![
            one_minus(yy.clone() + zz.clone()),
            two(xy.clone() - wz.clone()),
            two(xz.clone() + wy.clone()),
            two(xy + wz),
            one_minus(xx.clone() + zz),
            two(yz.clone() - wx.clone()),
            two(xz - wy),
            two(yz + wx),
            one_minus(xx + yy),
        ],
        last,
    )
}

/// The continuous 6D rotation representation (Zhou et al., CVPR 2019) `(.., 6)` to row-major
/// rotation matrices `(.., 9)`: the first two columns `a1`, `a2` orthonormalised by Gram–Schmidt,
/// the third their cross product. Unlike a quaternion (`q` and `−q` are one rotation) it has no
/// antipodal ambiguity and no discontinuity for a network to straddle.
pub fn rot6d_to_matrix<const D: usize>(r: Tensor<D>) -> Tensor<D> {
    let last = D - 1;
    let unit = |v: Tensor<D>| {
        let norm = v.clone().square().sum_dim(last).sqrt().clamp_min(1e-8);
        v / norm
    };
    let b1 = unit(r.clone().narrow(last, 0, 3));
    let a2 = r.narrow(last, 3, 3);
    let b2 = unit(a2.clone() - b1.clone() * (b1.clone() * a2).sum_dim(last));
    let c = |v: &Tensor<D>, i: usize| v.clone().narrow(last, i, 1);
    let b3 = Tensor::cat(
        vec![
            c(&b1, 1) * c(&b2, 2) - c(&b1, 2) * c(&b2, 1),
            c(&b1, 2) * c(&b2, 0) - c(&b1, 0) * c(&b2, 2),
            c(&b1, 0) * c(&b2, 1) - c(&b1, 1) * c(&b2, 0),
        ],
        last,
    );
    // Columns b1, b2, b3 in row-major order: row i is (b1_i, b2_i, b3_i).
    Tensor::cat((0..3).flat_map(|i| [c(&b1, i), c(&b2, i), c(&b3, i)]).collect(), last)
}

/// A row-major rotation matrix as a quaternion (w, x, y, z).
pub fn rows_to_wxyz(m: &[f32; 9]) -> [f32; 4] {
    let cols = DMat3::from_cols_array(&std::array::from_fn(|k| m[(k % 3) * 3 + k / 3] as f64));
    let q = DQuat::from_mat3(&cols).normalize();
    [q.w as f32, q.x as f32, q.y as f32, q.z as f32]
}

/// Normalises quaternions along the last axis (the norm clamped away from 0).
pub fn normalize_quat<const D: usize>(q: Tensor<D>) -> Tensor<D> {
    let norm = q.clone().square().sum_dim(D - 1).sqrt().clamp_min(1e-8);
    q / norm
}

/// A network quaternion (w, x, y, z) as glam's (x, y, z, w), normalised.
pub fn wxyz_to_quat(q: [f32; 4]) -> glam::DQuat {
    glam::DQuat::from_xyzw(q[1] as f64, q[2] as f64, q[3] as f64, q[0] as f64).normalize()
}

/// Row-major 3×3 of a rotation.
pub fn matrix_rows(q: glam::DQuat) -> [f32; 9] {
    let m = glam::DMat3::from_quat(q);
    // glam is column-major: row r, column c is m.col(c)[r].
    std::array::from_fn(|k| m.col(k % 3)[k / 3] as f32)
}

/// The rotations that make an object look the same (model frame): the discrete symmetries'
/// rotation parts and, for a body of revolution, its axis.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Symmetries {
    pub rotations: Vec<DQuat>,
    pub axis: Option<DVec3>,
}

impl Symmetries {
    /// From `models_info.json`: the mesh-verified transforms (row-major 4×4, BOP layout) and
    /// revolution axes when the dataset has them, else the axis-aligned ones the `symmetry` kind
    /// names (datasets written before the transforms were measured).
    pub fn from_models_info(kind: &str, discrete: &[[f64; 16]], continuous: &[vt_dataset::ContinuousSymmetry]) -> Self {
        if discrete.is_empty() && continuous.is_empty() {
            return Self::of_kind(kind);
        }
        Symmetries {
            rotations: discrete
                .iter()
                .map(|m| DQuat::from_mat3(&DMat3::from_cols_array(&[m[0], m[4], m[8], m[1], m[5], m[9], m[2], m[6], m[10]])).normalize())
                .collect(),
            axis: continuous.first().map(|c| DVec3::from_array(c.axis).normalize()),
        }
    }

    /// The axis-aligned symmetries a kind names: `continuous_z` (revolution about model z),
    /// `discrete` (the three 180° flips about the model axes), otherwise none.
    pub fn of_kind(kind: &str) -> Self {
        use std::f64::consts::PI;
        match kind {
            "continuous_z" => Symmetries { rotations: Vec::new(), axis: Some(DVec3::Z) },
            "discrete" => Symmetries {
                rotations: vec![DQuat::from_rotation_x(PI), DQuat::from_rotation_y(PI), DQuat::from_rotation_z(PI)],
                axis: None,
            },
            _ => Symmetries::default(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::cpu;

    #[test]
    fn rot6d_gives_the_rotation_of_its_two_columns() {
        let device = cpu();
        let q = glam::DQuat::from_euler(glam::EulerRot::XYZ, 0.7, -0.4, 2.0);
        let m = glam::DMat3::from_quat(q);
        // The first two columns, scaled and with a part of the first added to the second: the
        // Gram–Schmidt step recovers the rotation.
        let (c1, c2) = (m.col(0) * 2.0, m.col(1) * 0.5 + m.col(0) * 0.3);
        let data: Vec<f32> = [c1.x, c1.y, c1.z, c2.x, c2.y, c2.z].iter().map(|v| *v as f32).collect();
        let got: Vec<f32> =
            rot6d_to_matrix(Tensor::<2>::from_data(TensorData::new(data, [1, 6]), &device)).into_data().iter::<f32>().collect();
        let want = matrix_rows(q);
        for k in 0..9 {
            assert!((got[k] - want[k]).abs() < 1e-5, "entry {k}: {} vs {}", got[k], want[k]);
        }
    }

    #[test]
    fn quaternion_matrix_matches_glam() {
        let device = cpu();
        let qs = [
            glam::DQuat::IDENTITY,
            glam::DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2),
            glam::DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -1.2, 2.5),
        ];
        let data: Vec<f32> = qs.iter().flat_map(|q| [q.w as f32, q.x as f32, q.y as f32, q.z as f32]).collect();
        let m = quat_to_matrix(Tensor::<2>::from_data(TensorData::new(data, [3, 4]), &device));
        let got: Vec<f32> = m.into_data().iter::<f32>().collect();
        for (i, q) in qs.iter().enumerate() {
            let want = matrix_rows(*q);
            for k in 0..9 {
                assert!((got[i * 9 + k] - want[k]).abs() < 1e-6, "q {i} entry {k}: {} vs {}", got[i * 9 + k], want[k]);
            }
        }
        // Back from the matrices.
        for (i, q) in qs.iter().enumerate() {
            let rows: [f32; 9] = std::array::from_fn(|k| got[i * 9 + k]);
            let back = wxyz_to_quat(rows_to_wxyz(&rows));
            assert!(back.angle_between(*q) < 1e-5, "q {i}");
        }
        // Round trip of the (w, x, y, z) <-> glam conversion.
        let q = qs[2];
        let back = wxyz_to_quat([q.w as f32, q.x as f32, q.y as f32, q.z as f32]);
        assert!(back.angle_between(q) < 1e-6);
    }
}

//! The small dense linear algebra of the symmetry search: a 6×6 solve, outer products, and the
//! eigen-decomposition of a symmetric 3×3 matrix.

use glam::{DMat3, DVec3};

/// Solves the 6×6 system `a x = b` (Gaussian elimination, partial pivoting); `None` when singular.
pub(super) fn solve6(mut a: [[f64; 6]; 6], mut b: [f64; 6]) -> Option<[f64; 6]> {
    for col in 0..6 {
        let piv = (col..6).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[piv][col].abs() < 1e-300 || !a[piv][col].is_finite() {
            return None;
        }
        a.swap(col, piv);
        b.swap(col, piv);
        for row in col + 1..6 {
            let f = a[row][col] / a[col][col];
            let pivot_row = a[col];
            for (x, p) in a[row].iter_mut().zip(pivot_row).skip(col) {
                *x -= f * p;
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = [0.0; 6];
    for row in (0..6).rev() {
        let s: f64 = (row + 1..6).map(|k| a[row][k] * x[k]).sum();
        x[row] = (b[row] - s) / a[row][row];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

pub(super) fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// Eigen-decomposition of a symmetric 3×3 matrix (cyclic Jacobi): eigenvalues and unit
/// eigenvectors, in no particular order.
pub(super) fn symmetric_eigen(m: DMat3) -> ([f64; 3], [DVec3; 3]) {
    let mut a = m.to_cols_array_2d(); // a[col][row]; symmetric, so a[i][j] = a[j][i]
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]; // v[col][row]: columns are eigenvectors
    for _ in 0..64 {
        let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        let scale = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
        if off <= 1e-30 * scale.max(1e-300) {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // A <- Jᵀ A J with the rotation J in the (p, q) plane.
            for row in &mut a {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (row_p, row_q) = (a[p], a[q]);
            for k in 0..3 {
                a[p][k] = c * row_p[k] - s * row_q[k];
                a[q][k] = s * row_p[k] + c * row_q[k];
            }
            let (row_p, row_q) = (v[p], v[q]);
            for k in 0..3 {
                v[p][k] = c * row_p[k] - s * row_q[k];
                v[q][k] = s * row_p[k] + c * row_q[k];
            }
        }
    }
    ([a[0][0], a[1][1], a[2][2]], [DVec3::from(v[0]), DVec3::from(v[1]), DVec3::from(v[2])])
}

#[cfg(test)]
mod tests {
    use glam::DQuat;

    use super::*;

    #[test]
    fn eigen_decomposition_of_a_turned_diagonal() {
        let r = DMat3::from_quat(DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.7, 1.1));
        let m = r * DMat3::from_diagonal(DVec3::new(1.0, 4.0, 9.0)) * r.transpose();
        let (vals, vecs) = symmetric_eigen(m);
        let mut seen = [false; 3];
        for (l, v) in vals.iter().zip(vecs) {
            assert!((m * v - v * *l).length() < 1e-12, "{l} {v}");
            assert!((v.length() - 1.0).abs() < 1e-12);
            let k = [1.0, 4.0, 9.0].iter().position(|x| (x - l).abs() < 1e-9).unwrap();
            seen[k] = true;
        }
        assert_eq!(seen, [true; 3]);
    }
}

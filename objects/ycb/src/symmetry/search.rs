//! The search for a symmetry group's frame: the candidate transforms (180° flips, turns by 30°)
//! about a frame, and the frame refined until the surface, moved by them, best matches itself.

use glam::{DMat3, DMat4, DQuat, DVec3};

use super::linalg::{solve6, symmetric_eigen};
use super::measure::SymmetryChecker;

/// The samples the refinement search uses (a prefix of the random samples, so a random subset).
const SEARCH_SAMPLES: usize = 1000;

impl SymmetryChecker {
    /// The frame of the principal axes of the surface covariance, centred on the bounding box of
    /// the vertices in that frame (a box scan's centroid is pulled towards its better-scanned
    /// faces; the box's centre is not). Its local axes are the principal axes nearest the model x,
    /// y, z axes (`axis_nearest_z`: only local z is matched, to the axis nearest model z).
    pub(super) fn principal_frame(&self, axis_nearest_z: bool) -> Frame {
        let (_, vecs) = symmetric_eigen(self.covariance);
        // Assign principal axes to model axes: the permutation with the largest total |cos|.
        const PERMS: [[usize; 3]; 6] = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
        let score = |p: &[usize; 3]| {
            if axis_nearest_z { vecs[p[2]].z.abs() } else { (0..3).map(|k| vecs[p[k]][k].abs()).sum::<f64>() }
        };
        let best = PERMS.iter().copied().fold(PERMS[0], |b, p| if score(&p) > score(&b) { p } else { b });
        let mut x = vecs[best[0]];
        let mut z = vecs[best[2]];
        if x.x < 0.0 {
            x = -x;
        }
        if z.z < 0.0 {
            z = -z;
        }
        let y = z.cross(x);
        let r = DQuat::from_mat3(&DMat3::from_cols(x, y, z)).normalize();
        let rm = DMat3::from_cols(x, y, z);
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for v in &self.vertices {
            let l = rm.transpose() * (*v - self.centroid);
            lo = lo.min(l);
            hi = hi.max(l);
        }
        Frame { r, c: self.centroid + rm * ((lo + hi) * 0.5) }
    }

    /// Refines the principal frame and the model frame (the two starts) against the local
    /// transforms `ops` and returns the better one.
    pub(super) fn best_frame(&self, principal: &Frame, ops: &[DMat3]) -> Frame {
        let starts = [*principal, Frame { r: DQuat::IDENTITY, c: DVec3::ZERO }];
        let mut best: Option<(f64, Frame)> = None;
        for s in starts {
            let (f, cost) = self.refine(s, ops);
            if best.is_none_or(|(c, _)| cost < c) {
                best = Some((cost, f));
            }
        }
        best.expect("two starts").1
    }

    /// The search objective at `frame`: over `ops`, the mean displacement of the search samples,
    /// each capped at 3 tolerances (a transform that does not hold then weighs little and cannot
    /// drag the frame away from the ones that do); and the Gauss–Newton normal equations of the
    /// point-to-plane residuals of the samples within the cap, for the frame's 6 parameters (a turn
    /// about its own axes, a move along the model axes).
    fn evaluate(&self, frame: &Frame, ops: &[DMat3], stack: &mut Vec<usize>) -> (f64, [[f64; 6]; 6], [f64; 6]) {
        let cap = 3.0 * self.tolerance();
        let n = self.samples.len().min(SEARCH_SAMPLES);
        let (mut sum, mut jtj, mut jtr) = (0.0, [[0.0; 6]; 6], [0.0; 6]);
        const H: f64 = 1e-7;
        for op in ops {
            let t = frame.model_transform(op);
            // d(T p)/d(parameter k) = D_k p: T is affine in p, so one difference per parameter.
            let d: [DMat4; 6] = std::array::from_fn(|k| (frame.step(k, H).model_transform(op) - t) * (1.0 / H));
            for p in &self.samples[..n] {
                let y = t.transform_point3(*p);
                match self.surface.closest(y, cap * cap, stack) {
                    Some((dist_sq, q, normal)) => {
                        sum += dist_sq.sqrt();
                        let r = normal.dot(y - q);
                        let j: [f64; 6] = std::array::from_fn(|k| normal.dot(d[k].transform_vector3(*p) + d[k].w_axis.truncate()));
                        for a in 0..6 {
                            jtr[a] += j[a] * r;
                            for b in 0..6 {
                                jtj[a][b] += j[a] * j[b];
                            }
                        }
                    }
                    None => sum += cap,
                }
            }
        }
        (sum / (n * ops.len()) as f64, jtj, jtr)
    }

    /// Levenberg–Marquardt on the point-to-plane residuals from `start` (an ICP whose moved copy is
    /// the surface under `ops`), each step kept only when the capped mean displacement drops; stops
    /// when it drops by less than 1 nm or no step helps. Returns the frame and that mean.
    fn refine(&self, start: Frame, ops: &[DMat3]) -> (Frame, f64) {
        let mut stack = Vec::with_capacity(64);
        let mut frame = start;
        let (mut cost, mut jtj, mut jtr) = self.evaluate(&frame, ops, &mut stack);
        let mut lambda = 1e-3;
        for _ in 0..60 {
            let mut a = jtj;
            let trace: f64 = (0..6).map(|k| jtj[k][k]).sum();
            for (k, row) in a.iter_mut().enumerate() {
                // Marquardt's scaling, and a floor for the directions no residual sees (a turn
                // about a revolution axis, a move along a flip axis).
                row[k] += lambda * jtj[k][k] + 1e-12 * trace;
            }
            let Some(delta) = solve6(a, jtr.map(|v| -v)) else { break };
            let mut cand = frame;
            for (k, dk) in delta.iter().enumerate() {
                cand = cand.step(k, *dk);
            }
            let (c, j2, r2) = self.evaluate(&cand, ops, &mut stack);
            if c < cost {
                let gain = cost - c;
                (frame, cost, jtj, jtr) = (cand, c, j2, r2);
                lambda = (lambda / 3.0).max(1e-9);
                if gain < 1e-9 {
                    break;
                }
            } else {
                lambda *= 4.0;
                if lambda > 1e6 {
                    break;
                }
            }
        }
        (frame, cost)
    }
}

/// The three 180° flips about the local x, y, z axes.
pub(super) const FLIPS: [DMat3; 3] = [
    DMat3::from_cols(DVec3::X, DVec3::NEG_Y, DVec3::NEG_Z),
    DMat3::from_cols(DVec3::NEG_X, DVec3::Y, DVec3::NEG_Z),
    DMat3::from_cols(DVec3::NEG_X, DVec3::NEG_Y, DVec3::Z),
];

/// A turn by `k`·30° about the local z axis (exact sines: no libm, same bits everywhere).
pub(super) fn turn_z_30(k: u32) -> DMat3 {
    let h = 0.75f64.sqrt();
    // k·30° = q·90° + r·30°.
    let (c0, s0) = [(1.0, 0.0), (h, 0.5), (0.5, h)][(k % 3) as usize];
    let (c, s) = match (k / 3) % 4 {
        0 => (c0, s0),
        1 => (-s0, c0),
        2 => (-c0, -s0),
        _ => (s0, -c0),
    };
    DMat3::from_cols(DVec3::new(c, s, 0.0), DVec3::new(-s, c, 0.0), DVec3::Z)
}

/// The rotation by the small rotation vector `v` (Cayley-like: only `√`, no libm trigonometry).
fn small_rotation(v: DVec3) -> DQuat {
    DQuat::from_xyzw(0.5 * v.x, 0.5 * v.y, 0.5 * v.z, 1.0).normalize()
}

/// A symmetry group's frame: `r` turns local axes into model axes, `c` is the local origin.
#[derive(Debug, Clone, Copy)]
pub(super) struct Frame {
    pub(super) r: DQuat,
    pub(super) c: DVec3,
}

impl Frame {
    /// The frame moved by `amount` along parameter `k`: 0–2 turn it about its own x, y, z axes
    /// (radians), 3–5 move its origin along the model x, y, z axes (metres).
    fn step(&self, k: usize, amount: f64) -> Frame {
        let mut v = DVec3::ZERO;
        v[k % 3] = amount;
        if k < 3 { Frame { r: (self.r * small_rotation(v)).normalize(), c: self.c } } else { Frame { r: self.r, c: self.c + v } }
    }

    /// The local linear map `op` (about the frame's origin) as a model-frame transform.
    pub(super) fn model_transform(&self, op: &DMat3) -> DMat4 {
        let r = DMat3::from_quat(self.r);
        let m = r * *op * r.transpose();
        let t = self.c - m * self.c;
        DMat4::from_cols(m.x_axis.extend(0.0), m.y_axis.extend(0.0), m.z_axis.extend(0.0), t.extend(1.0))
    }
}

/// Rounds to 1e-9 (nanometres for translations): the written values do not carry the search's
/// last bits.
fn round9(x: f64) -> f64 {
    let r = (x * 1e9).round() / 1e9;
    if r == 0.0 { 0.0 } else { r }
}

pub(super) fn round_vec(v: DVec3) -> DVec3 {
    DVec3::new(round9(v.x), round9(v.y), round9(v.z))
}

pub(super) fn round_transform(m: &DMat4) -> DMat4 {
    DMat4::from_cols_array(&m.to_cols_array().map(round9))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn turns_by_30_degrees_are_exact_rotations() {
        for k in 0..12 {
            let m = turn_z_30(k);
            let a = (k as f64 * 30.0).to_radians();
            assert!((m.x_axis - DVec3::new(a.cos(), a.sin(), 0.0)).length() < 1e-15, "{k}");
            assert!((m.determinant() - 1.0).abs() < 1e-15);
        }
    }
}

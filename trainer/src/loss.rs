//! The training loss of DenseFusion and the paper (§III-C, eqs. 1–3).
//!
//! For every estimate `i` of a sample (rotation `R̂_i`, translation `t̂_i`, confidence `c_i`) and
//! the `M` model points `x_j`:
//!
//! ```text
//! L_i = 1/M Σ_j ‖(R x_j + t) − (R̂_i x_j + t̂_i)‖                 (1)
//! L   = 1/N Σ_i (L_i c_i − w log c_i),   w = 0.015               (2, 3)
//! ```
//!
//! For objects whose `symmetry` is not `none`, the distance of a moved model point is to the
//! *closest* true model point (`min_k ‖(R x_k + t) − (R̂_i x_j + t̂_i)‖`), as DenseFusion does for
//! symmetric objects: a pose that differs from the truth by a symmetry costs nothing.
//!
//! The paper prints eq. 2–3 as `L^c_i = Ĉ_i − C^e_i − w log C_i` with `C^e_i = 0.5^{L_i}`; taken
//! literally the confidence would carry no information about the estimate's error (the term is
//! minimised at `Ĉ = w` whatever `L_i` is). The form above is the one DenseFusion's code and the
//! issue specify, in which the confidence weights the distance, so the most confident estimate
//! is the one the network expects to be right.
//!
//! `N` counts the sample's valid estimates (the tactile channel of a sample without touch has
//! none); the batch loss is the mean over its samples.
//!
//! Efficiency: for asymmetric samples the distances come from a quadratic form. With
//! `A = R̂_i − R`, `b = t̂_i − t`: `‖A x + b‖² = xᵀ(AᵀA)x + 2(Aᵀb)·x + bᵀb`, a 10-vector per
//! estimate dotted with a 10-vector per model point, so `(B, E, M)` distances cost one batched
//! matmul instead of `(B, E, M, 3)` moved points. Symmetric samples find each moved point's closest
//! true point on the host (a k-d tree per sample, no gradient), then differentiate the distance to
//! it.

use burn::prelude::*;
use burn::tensor::Int;
use kiddo::{ImmutableKdTree, SquaredEuclidean};

use crate::data::Targets;
use crate::model::PoseOutput;

/// The paper's confidence regulariser.
pub const W_DEFAULT: f64 = 0.015;
/// Added under the square roots (m²): keeps gradients finite at zero distance (a 10 µm floor).
const EPS: f64 = 1e-10;

/// The weights of the loss's terms.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LossWeights {
    /// The confidence regulariser `w` (the paper: 0.015).
    pub w: f64,
    /// Metres of distance per unit of chordal rotation error `‖R̂_i − R‖_F` added to each
    /// estimate's `L_i` (0: the paper's loss). See [`pose_loss`].
    pub rotation: f64,
}

impl LossWeights {
    /// The paper's loss with regulariser `w`.
    pub fn paper(w: f64) -> Self {
        LossWeights { w, rotation: 0.0 }
    }
}

/// The loss of a batch and its per-estimate distances.
#[derive(Debug, Clone)]
pub struct LossOutput {
    /// Scalar loss (eq. 2–3), differentiable.
    pub loss: Tensor<1>,
    /// `(B, E)` per-estimate mean model-point distances `L_i` (eq. 1), metres, detached.
    pub distance: Tensor<2>,
}

/// The loss of `out` against `targets`. With `weights.rotation` > 0 each estimate's distance in
/// eq. 2 becomes `L_i + λ ‖R̂_i − R‖_F`: the mean model-point distance barely sees a rotation about
/// an axis along which the object hardly moves (a flat, elongated tool's long axis), and the
/// chordal term charges every rotation axis alike (a deviation from the paper; `distance` stays
/// `L_i`).
pub fn pose_loss(out: &PoseOutput, targets: &Targets, weights: LossWeights) -> LossOutput {
    let [b, e, _] = out.rotation.dims();
    let device = out.rotation.device();
    let rot = out.rotation.clone().reshape([b, e, 3, 3]);
    // Samples by kind; the per-sample losses are computed per group and put back in order.
    let (sym, asym): (Vec<usize>, Vec<usize>) = (0..b).partition(|&i| targets.symmetric[i]);
    let mut distances = Vec::new();
    let mut order = Vec::new();
    for (group, symmetric) in [(asym, false), (sym, true)] {
        if group.is_empty() {
            continue;
        }
        let pick = |idx: &[usize]| {
            Tensor::<1, Int>::from_data(TensorData::new(idx.iter().map(|&i| i as i64).collect::<Vec<_>>(), [idx.len()]), &device)
        };
        let all = group.len() == b;
        let sel = pick(&group);
        let take3 = |t: Tensor<3>| if all { t } else { t.select(0, sel.clone()) };
        let r_hat = if all { rot.clone() } else { rot.clone().select(0, sel.clone()) };
        let t_hat = take3(out.translation.clone());
        let x = take3(targets.model_points.clone());
        let r = take3(targets.rotation.clone());
        let t = if all { targets.translation.clone() } else { targets.translation.clone().select(0, sel.clone()) };
        let d = if symmetric {
            let nearest = closest_points(&r_hat, &t_hat, targets, &group);
            closest_point_distance(r_hat, t_hat, x, r, t, nearest)
        } else {
            model_point_distance(r_hat, t_hat, x, r, t)
        };
        distances.push(d);
        order.extend(group);
    }
    // Back to batch order.
    let mut inverse = vec![0i64; b];
    for (k, &i) in order.iter().enumerate() {
        inverse[i] = k as i64;
    }
    let distance = Tensor::cat(distances, 0).select(0, Tensor::<1, Int>::from_data(TensorData::new(inverse, [b]), &device));
    let charged = if weights.rotation > 0.0 {
        let truth = targets.rotation.clone().reshape([b, 1, 9]).expand([b, e, 9]);
        let chordal = (out.rotation.clone() - truth).square().sum_dim(2).add_scalar(EPS).sqrt().reshape([b, e]);
        distance.clone() + chordal.mul_scalar(weights.rotation)
    } else {
        distance.clone()
    };
    let loss = confidence_loss(charged, out.confidence.clone(), out.valid.clone(), weights.w);
    LossOutput { loss, distance: distance.detach() }
}

/// Eq. 2–3 given the distances `L` `(B, E)`, confidences and validity: the mean over samples of
/// `Σ_i valid_i (L_i c_i − w log c_i) / Σ_i valid_i`.
pub fn confidence_loss(distance: Tensor<2>, confidence: Tensor<2>, valid: Tensor<2>, w: f64) -> Tensor<1> {
    let per_estimate = distance * confidence.clone() - confidence.clamp_min(1e-7).log().mul_scalar(w);
    let per_sample = (per_estimate * valid.clone()).sum_dim(1) / valid.sum_dim(1).clamp_min(1.0);
    per_sample.mean()
}

/// Eq. 1 for asymmetric objects: `(B, E)` mean distances between the model points moved by the
/// estimates `R̂ (B, E, 3, 3)`, `t̂ (B, E, 3)` and by the truth `R (B, 3, 3)`, `t (B, 3)`;
/// `x (B, M, 3)`. Computed as a quadratic form (see the module docs).
pub fn model_point_distance(r_hat: Tensor<4>, t_hat: Tensor<3>, x: Tensor<3>, r: Tensor<3>, t: Tensor<2>) -> Tensor<2> {
    let [b, e, _, _] = r_hat.dims();
    let device = r_hat.device();
    let a = r_hat - r.reshape([b, 1, 3, 3]).expand([b, e, 3, 3]); // R̂ − R
    let bias = t_hat - t.reshape([b, 1, 3]).expand([b, e, 3]); // t̂ − t
    let at = a.clone().swap_dims(2, 3);
    let q = at.clone().matmul(a).reshape([b, e, 9]); // AᵀA, symmetric
    let v = at.matmul(bias.clone().reshape([b, e, 3, 1])).reshape([b, e, 3]); // Aᵀb
    let bb = bias.square().sum_dim(2); // bᵀb, (B, E, 1)
    let idx = |i: [i64; 3]| Tensor::<1, Int>::from_data(TensorData::new(i.to_vec(), [3]), &device);
    let psi = Tensor::cat(vec![q.clone().select(2, idx([0, 4, 8])), q.select(2, idx([1, 2, 5])).mul_scalar(2.0), v.mul_scalar(2.0), bb], 2);
    let phi = quadratic_features(x.detach()); // (B, M, 10)
    let squared = psi.matmul(phi.swap_dims(1, 2)); // (B, E, M)
    squared.clamp_min(0.0).add_scalar(EPS).sqrt().mean_dim(2).reshape([b, e])
}

/// `[x², y², z², xy, xz, yz, x, y, z, 1]` of points `(B, M, 3)`.
fn quadratic_features(x: Tensor<3>) -> Tensor<3> {
    let [b, m, _] = x.dims();
    let c = |i: usize| x.clone().narrow(2, i, 1);
    let (px, py, pz) = (c(0), c(1), c(2));
    Tensor::cat(
        vec![
            px.clone().square(),
            py.clone().square(),
            pz.clone().square(),
            px.clone() * py.clone(),
            px.clone() * pz.clone(),
            py.clone() * pz.clone(),
            px,
            py,
            pz,
            Tensor::ones([b, m, 1], &x.device()),
        ],
        2,
    )
}

/// Eq. 1 the direct way, model points moved explicitly: `(B, E)`. With `nearest` `(B, E, M)`
/// the distance of moved point `j` is to true point `nearest[j]` (the symmetric variant), else to
/// true point `j`.
pub fn explicit_distance(
    r_hat: Tensor<4>,
    t_hat: Tensor<3>,
    x: Tensor<3>,
    r: Tensor<3>,
    t: Tensor<2>,
    nearest: Option<Tensor<3, Int>>,
) -> Tensor<2> {
    let [b, e, _, _] = r_hat.dims();
    let m = x.dims()[1];
    // Moved by the estimates: (B, E, M, 3) = x (B, E, M, 3) · R̂ᵀ + t̂.
    let moved = x.clone().reshape([b, 1, m, 3]).expand([b, e, m, 3]).matmul(r_hat.swap_dims(2, 3))
        + t_hat.reshape([b, e, 1, 3]).expand([b, e, m, 3]);
    // Moved by the truth: (B, M, 3).
    let truth = x.matmul(r.swap_dims(1, 2)) + t.reshape([b, 1, 3]).expand([b, m, 3]);
    let truth = match nearest {
        Some(nn) => truth.gather(1, nn.reshape([b, e * m, 1]).expand([b, e * m, 3])).reshape([b, e, m, 3]),
        None => truth.reshape([b, 1, m, 3]).expand([b, e, m, 3]),
    };
    (moved - truth).square().sum_dim(3).add_scalar(EPS).sqrt().mean_dim(2).reshape([b, e])
}

/// The symmetric variant of eq. 1: distances to the closest true model points, found beforehand.
fn closest_point_distance(
    r_hat: Tensor<4>,
    t_hat: Tensor<3>,
    x: Tensor<3>,
    r: Tensor<3>,
    t: Tensor<2>,
    nearest: Tensor<3, Int>,
) -> Tensor<2> {
    explicit_distance(r_hat, t_hat, x, r, t, Some(nearest))
}

/// For the samples `group` of the batch: the index of the true model point closest to every
/// model point moved by every estimate, `(G, E, M)` (host k-d tree per sample, samples spread
/// over the available cores; no gradient).
fn closest_points(r_hat: &Tensor<4>, t_hat: &Tensor<3>, targets: &Targets, group: &[usize]) -> Tensor<3, Int> {
    let [g, e, _, _] = r_hat.dims();
    let rot: Vec<f32> = r_hat.clone().detach().into_data().iter::<f32>().collect();
    let tra: Vec<f32> = t_hat.clone().detach().into_data().iter::<f32>().collect();
    let m = targets.host_points[group[0]].len();
    let mut out = vec![0i64; g * e * m];
    let one_sample = |k: usize, s: usize, dst: &mut [i64]| {
        let (x, r, t) = (&targets.host_points[s], &targets.host_rotation[s], &targets.host_translation[s]);
        let truth: Vec<[f32; 3]> = x.iter().map(|p| transform(r, t, p)).collect();
        let tree: ImmutableKdTree<f32, 3> = ImmutableKdTree::new_from_slice(&truth);
        for i in 0..e {
            let o = k * e + i;
            let ri: [f32; 9] = rot[o * 9..o * 9 + 9].try_into().expect("9");
            let ti: [f32; 3] = tra[o * 3..o * 3 + 3].try_into().expect("3");
            for (j, p) in x.iter().enumerate() {
                dst[i * m + j] = tree.nearest_one::<SquaredEuclidean>(&transform(&ri, &ti, p)).item as i64;
            }
        }
    };
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).min(g);
    let per_thread = g.div_ceil(threads);
    std::thread::scope(|scope| {
        for (c, chunk) in out.chunks_mut(per_thread * e * m).enumerate() {
            let one_sample = &one_sample;
            scope.spawn(move || {
                for (local, dst) in chunk.chunks_mut(e * m).enumerate() {
                    let k = c * per_thread + local;
                    one_sample(k, group[k], dst);
                }
            });
        }
    });
    Tensor::from_data(TensorData::new(out, [g, e, m]), &r_hat.device())
}

/// `R p + t` with a row-major `R`.
pub fn transform(r: &[f32; 9], t: &[f32; 3], p: &[f32; 3]) -> [f32; 3] {
    std::array::from_fn(|row| r[row * 3] * p[0] + r[row * 3 + 1] * p[1] + r[row * 3 + 2] * p[2] + t[row])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::{Batch, Prepared};
    use crate::device::cpu;
    use crate::model::PoseOutput;
    use glam::{DQuat, DVec3};

    fn t2(v: Vec<f32>, s: [usize; 2]) -> Tensor<2> {
        Tensor::from_data(TensorData::new(v, s), &cpu())
    }
    fn t3(v: Vec<f32>, s: [usize; 3]) -> Tensor<3> {
        Tensor::from_data(TensorData::new(v, s), &cpu())
    }
    fn scalar(t: Tensor<1>) -> f32 {
        t.into_data().iter::<f32>().next().unwrap()
    }

    /// A batch of one sample: model points `x`, true pose identity at t = (0, 0, 1).
    fn one_sample(x: &[[f32; 3]], symmetric: bool) -> Batch {
        Batch {
            samples: vec![Prepared {
                index: 0,
                object: 0,
                slot: 0,
                symmetric,
                occlusion: 0.5,
                trajectory: 0,
                instance: 0,
                time_s: f64::NAN,
                cloud: vec![],
                choose: vec![],
                img: vec![],
                cloud_count: 1,
                tactile: vec![],
                tactile_count: 0,
                model_points: x.concat(),
                rotation: DQuat::IDENTITY,
                translation: DVec3::new(0.0, 0.0, 1.0),
            }],
        }
    }

    fn output(quats: &[[f32; 4]], trans: &[[f32; 3]], conf: &[f32]) -> PoseOutput {
        let e = quats.len();
        PoseOutput {
            rotation: crate::geometry::quat_to_matrix(t3(quats.concat(), [1, e, 4])),
            translation: t3(trans.concat(), [1, e, 3]),
            confidence: t2(conf.to_vec(), [1, e]),
            valid: t2(vec![1.0; e], [1, e]),
        }
    }

    #[test]
    fn loss_matches_a_hand_computed_case() {
        // Two model points; estimate 0 is off by 3 cm along x (every moved point 0.03 away);
        // estimate 1 is the truth rotated 180° about z: (1,0,0) -> (-1,0,0) (distance 2) and
        // (0,0,0) stays (distance 0): L_1 = 1.
        let x = [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]];
        let batch = one_sample(&x, false);
        let out = output(&[[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]], &[[0.03, 0.0, 1.0], [0.0, 0.0, 1.0]], &[0.8, 0.1]);
        let l = pose_loss(&out, &batch.targets(&cpu()), LossWeights::paper(W_DEFAULT));
        let d: Vec<f32> = l.distance.into_data().iter::<f32>().collect();
        assert!((d[0] - 0.03).abs() < 1e-4 && (d[1] - 1.0).abs() < 1e-4, "{d:?}");
        // L = 1/2 [(0.03·0.8 − 0.015 ln 0.8) + (1·0.1 − 0.015 ln 0.1)]
        let want = 0.5 * ((0.03 * 0.8 - 0.015 * 0.8f64.ln()) + (1.0 * 0.1 - 0.015 * 0.1f64.ln()));
        assert!((scalar(l.loss) as f64 - want).abs() < 1e-5, "want {want}");

        // Symmetric variant: the 180° flip maps the point set {(1,0,0), (0,0,0)} onto
        // {(-1,0,0), (0,0,0)}: (-1,0,0)'s closest true point is (0,0,0), at 1; (0,0,0) is on a
        // true point: L_1 = 0.5. The shifted estimate: closest points are the same as before.
        let batch = one_sample(&x, true);
        let l = pose_loss(&out, &batch.targets(&cpu()), LossWeights::paper(W_DEFAULT));
        let d: Vec<f32> = l.distance.into_data().iter::<f32>().collect();
        assert!((d[0] - 0.03).abs() < 1e-4 && (d[1] - 0.5).abs() < 1e-4, "{d:?}");
    }

    #[test]
    fn the_rotation_term_charges_the_chordal_error() {
        // Estimate 1 is the truth turned 180° about z: ‖R̂ − R‖_F = ‖diag(−2, −2, 0)‖ = 2√2.
        let x = [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]];
        let batch = one_sample(&x, false);
        let out = output(&[[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]], &[[0.03, 0.0, 1.0], [0.0, 0.0, 1.0]], &[0.8, 0.1]);
        let targets = batch.targets(&cpu());
        let paper = pose_loss(&out, &targets, LossWeights::paper(W_DEFAULT));
        let charged = pose_loss(&out, &targets, LossWeights { w: W_DEFAULT, rotation: 0.1 });
        // Only estimate 1 is charged, 0.1 · 2√2 weighted by its confidence 0.1, over 2 estimates.
        let want = 0.5 * 0.1 * 0.1 * 2.0 * 2f64.sqrt();
        assert!(((scalar(charged.loss) - scalar(paper.loss)) as f64 - want).abs() < 1e-5, "want + {want}");
        // The distances stay L_i.
        let d: Vec<f32> = charged.distance.into_data().iter::<f32>().collect();
        assert!((d[0] - 0.03).abs() < 1e-4 && (d[1] - 1.0).abs() < 1e-4, "{d:?}");
    }

    #[test]
    fn quadratic_form_equals_explicit_distances() {
        let device = cpu();
        let (b, e, m) = (2, 5, 7);
        let q = normalize(Tensor::<3>::random([b, e, 4], burn::tensor::Distribution::Normal(0.0, 1.0), &device));
        let r_hat = crate::geometry::quat_to_matrix(q).reshape([b, e, 3, 3]);
        let t_hat = Tensor::<3>::random([b, e, 3], burn::tensor::Distribution::Uniform(-0.1, 0.1), &device);
        let x = Tensor::<3>::random([b, m, 3], burn::tensor::Distribution::Uniform(-0.05, 0.05), &device);
        let qt = normalize(Tensor::<3>::random([b, 1, 4], burn::tensor::Distribution::Normal(0.0, 1.0), &device));
        let r = crate::geometry::quat_to_matrix(qt).reshape([b, 3, 3]);
        let t = Tensor::<2>::random([b, 3], burn::tensor::Distribution::Uniform(-0.1, 0.1), &device);
        let fast: Vec<f32> =
            model_point_distance(r_hat.clone(), t_hat.clone(), x.clone(), r.clone(), t.clone()).into_data().iter::<f32>().collect();
        let slow: Vec<f32> = explicit_distance(r_hat, t_hat, x, r, t, None).into_data().iter::<f32>().collect();
        for (a, b) in fast.iter().zip(&slow) {
            assert!((a - b).abs() < 1e-5, "{a} vs {b}");
        }
    }

    fn normalize(q: Tensor<3>) -> Tensor<3> {
        crate::geometry::normalize_quat(q)
    }

    #[test]
    fn gradient_flows_and_one_adam_step_changes_the_network() {
        use burn::module::Module;
        use burn::optim::{AdamConfig, GradientsParams};
        let data = crate::data::DataConfig { n_points: 32, n_tactile: 8, n_model_points: 16, crop_size: 16, ..Default::default() };
        // Both CPU backends (flex, the default, and ndarray).
        // And the 6D rotation representation.
        use crate::model::{RotationKind, Variant};
        for (plain_device, variant, rotation) in [
            (cpu(), Variant::TactileChannel, RotationKind::Quaternion),
            (cpu(), Variant::VisionOnly, RotationKind::Quaternion),
            (crate::device::ndarray(), Variant::TactileChannel, RotationKind::Quaternion),
            (cpu(), Variant::TactileChannel, RotationKind::Rot6d),
        ] {
            let device = plain_device.clone().autodiff();
            device.seed(1);
            let model = crate::model::ModelConfig {
                variant,
                global_dims: vec![32],
                head_dims: vec![32],
                rotation,
                ..crate::model::ModelConfig::default()
            }
            .init(1, &device);
            let input = crate::synthetic::input(&data, &device);
            let x = [[0.02f32, 0.0, 0.0], [0.0, 0.03, 0.0], [0.0, 0.0, 0.01], [0.01, 0.01, 0.01]];
            for symmetric in [false, true] {
                let mut batch = one_sample(&x, symmetric);
                batch.samples[0].translation = DVec3::new(0.0, 0.0, 0.7);
                let targets = batch.targets(&device);
                let plain = crate::synthetic::input(&data, &plain_device);
                let pose = |m: &crate::model::PoseNet| -> Vec<f32> {
                    let out = m.valid().forward(&plain);
                    out.translation.into_data().iter::<f32>().chain(out.rotation.into_data().iter::<f32>()).collect()
                };
                let before = pose(&model);
                let out = model.forward(&input);
                let l = pose_loss(&out, &targets, LossWeights::paper(W_DEFAULT));
                assert!(scalar(l.loss.clone()).is_finite());
                let grads = GradientsParams::from_grads(l.loss.backward(), &model);
                assert!(!grads.is_empty(), "{variant:?}: no gradients");
                let mut optim = AdamConfig::new().init();
                let stepped = optim.step(1e-3, model.clone(), grads);
                let after = pose(&stepped);
                let change = before.iter().zip(&after).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
                assert!(change > 1e-6, "{variant:?} {rotation:?} symmetric={symmetric}: the step changed nothing ({change})");
            }
        }
    }
}

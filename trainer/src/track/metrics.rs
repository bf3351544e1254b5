//! Tracking metrics of one sequence of per-frame errors (ADD-S, metres, in time order):
//!
//! - **ADD-S AUC** (%): the area under the accuracy–threshold curve of the sequence's frames for
//!   thresholds 0 … 10 cm (YCB-Video, as PoseCNN, DenseFusion and NeuralFeels report tracking),
//!   [`crate::eval::metrics::auc`]; a frame without a pose counts as a failure (0 at every
//!   threshold). The benchmark reports it per episode and its mean over episodes.
//! - **Drift**: how the error grows over the episode, two ways: the least-squares **slope** of
//!   ADD-S (cm) against time (cm/s), and **end − start**: the mean ADD-S of the episode's last
//!   fifth of frames minus that of its first fifth (cm; at least one frame each). Positive: the
//!   error grows. Frames without a pose are left out.
//! - **Jitter** (mm): the mean frame-to-frame change of the translation error, ‖(t̂ₖ − tₖ) −
//!   (t̂ₖ₋₁ − tₖ₋₁)‖ over consecutive frames that both have a pose: how much the estimate shakes
//!   around the truth's motion.

use glam::DVec3;

use crate::eval::metrics::auc;

/// ADD-S AUC of a sequence for thresholds up to `max_m` (%); `None` frames count as failures.
/// NaN for an empty sequence.
pub fn sequence_auc(errors_m: &[Option<f64>], max_m: f64) -> f64 {
    let e: Vec<f64> = errors_m.iter().map(|e| e.unwrap_or(f64::INFINITY)).collect();
    auc(&e, max_m)
}

/// The least-squares slope of `values` against `times` (units of value per unit of time) over the
/// points with a value; NaN with fewer than two such points or no spread in time.
pub fn slope(times: &[f64], values: &[Option<f64>]) -> f64 {
    let pts: Vec<(f64, f64)> = times.iter().zip(values).filter_map(|(&t, v)| v.map(|v| (t, v))).collect();
    if pts.len() < 2 {
        return f64::NAN;
    }
    let n = pts.len() as f64;
    let (mt, mv) = (pts.iter().map(|p| p.0).sum::<f64>() / n, pts.iter().map(|p| p.1).sum::<f64>() / n);
    let sxx: f64 = pts.iter().map(|p| (p.0 - mt).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mt) * (p.1 - mv)).sum();
    if sxx <= 0.0 { f64::NAN } else { sxy / sxx }
}

/// The mean of the last fifth of the values with a value minus the mean of the first fifth (at
/// least one each); NaN without values.
pub fn end_minus_start(values: &[Option<f64>]) -> f64 {
    let v: Vec<f64> = values.iter().filter_map(|v| *v).collect();
    if v.is_empty() {
        return f64::NAN;
    }
    let k = (v.len() / 5).max(1);
    let mean = |s: &[f64]| s.iter().sum::<f64>() / s.len() as f64;
    mean(&v[v.len() - k..]) - mean(&v[..k])
}

/// The mean norm of the change of `offsets` (estimate minus truth) between consecutive frames
/// that both have one; NaN when no two consecutive frames do.
pub fn jitter(offsets: &[Option<DVec3>]) -> f64 {
    let steps: Vec<f64> = offsets.windows(2).filter_map(|w| Some((w[1]? - w[0]?).length())).collect();
    if steps.is_empty() { f64::NAN } else { steps.iter().sum::<f64>() / steps.len() as f64 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auc_of_a_known_sequence() {
        // 0, 2.5, 5 and 10 cm: 100, 75, 50 and 0 % of the thresholds up to 10 cm.
        let e = [Some(0.0), Some(0.025), Some(0.05), Some(0.10)];
        assert!((sequence_auc(&e, 0.10) - 56.25).abs() < 1e-9);
        // A frame without a pose is a failure: the same three and a miss.
        let missed = [Some(0.0), Some(0.025), Some(0.05), None];
        assert!((sequence_auc(&missed, 0.10) - 56.25).abs() < 1e-9);
        let missed = [Some(0.0), None];
        assert!((sequence_auc(&missed, 0.10) - 50.0).abs() < 1e-9);
        assert!(sequence_auc(&[], 0.10).is_nan());
    }

    #[test]
    fn drift_of_a_linear_error() {
        // ADD-S = 1 cm + 3 cm/s · t over 2 s at 10 Hz.
        let times: Vec<f64> = (0..21).map(|k| k as f64 * 0.1).collect();
        let err: Vec<Option<f64>> = times.iter().map(|t| Some(1.0 + 3.0 * t)).collect();
        assert!((slope(&times, &err) - 3.0).abs() < 1e-9);
        // Last fifth (4 frames: 1.7 … 2.0 s) minus the first (0 … 0.3 s): 3 cm/s · 1.7 s.
        assert!((end_minus_start(&err) - 5.1).abs() < 1e-9);
        // Missing frames are left out, not zeros.
        let mut gappy = err.clone();
        gappy[5] = None;
        gappy[20] = None;
        assert!((slope(&times, &gappy) - 3.0).abs() < 1e-9);
        // A constant error does not drift.
        let flat = vec![Some(2.0); 21];
        assert_eq!(slope(&times, &flat), 0.0);
        assert_eq!(end_minus_start(&flat), 0.0);
        assert!(slope(&times[..1], &err[..1]).is_nan());
    }

    #[test]
    fn jitter_of_a_shaking_estimate() {
        // An offset alternating between +1 mm and −1 mm in x: 2 mm per frame; a constant offset: 0.
        let shaking: Vec<Option<DVec3>> = (0..5).map(|k| Some(DVec3::X * if k % 2 == 0 { 0.001 } else { -0.001 })).collect();
        assert!((jitter(&shaking) - 0.002).abs() < 1e-12);
        assert_eq!(jitter(&[Some(DVec3::ONE), Some(DVec3::ONE)]), 0.0);
        assert!(jitter(&[Some(DVec3::ONE), None, Some(DVec3::ONE)]).is_nan());
    }
}

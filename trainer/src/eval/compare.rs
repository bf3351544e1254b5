//! What touch buys: a tactile network against a vision-only one on the same samples.
//!
//! Samples of one trajectory share a grasp (the same contacts, nearly the same view of the
//! object), so they are not independent: the comparison pairs the two networks **per grasp**
//! (object, trajectory), takes each network's mean error over the grasp's samples, and counts the
//! grasps on which touch is better. The two-sided **sign test** on those counts asks whether touch
//! wins more often than a coin would; it needs no assumption about the errors' distribution.
//!
//! The channel diagnosis says how the tactile network answers: the share of samples whose most
//! confident estimate came from the tactile channel, and the error of those against the others.

use std::collections::BTreeMap;

use serde::Serialize;

use super::{ModelEval, SampleResult};
use crate::model::Variant;

/// One grasp's mean errors under both networks.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GraspPair {
    pub object: String,
    pub trajectory: u32,
    pub samples: usize,
    /// Mean position error (cm) and angle error (°) of the tactile network, then the baseline.
    pub tactile_position_cm: f64,
    pub vision_position_cm: f64,
    pub tactile_angle_deg: f64,
    pub vision_angle_deg: f64,
}

/// The paired comparison of two evaluations.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Paired {
    pub grasps: Vec<GraspPair>,
    /// Grasps on which the tactile network's mean position error is lower, higher, equal.
    pub position: SignTest,
    pub angle: SignTest,
}

/// Wins, losses and ties of the tactile network, and the two-sided sign test's p-value.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SignTest {
    pub better: usize,
    pub worse: usize,
    pub ties: usize,
    pub p_value: f64,
    /// Mean of (tactile − vision) over the grasps (negative: touch helps).
    pub mean_difference: f64,
}

/// Two-sided exact sign test: the probability, under a fair coin, of a split at least as uneven
/// as `wins : losses` (ties dropped).
pub fn sign_test_p(wins: usize, losses: usize) -> f64 {
    let n = wins + losses;
    if n == 0 {
        return 1.0;
    }
    let k = wins.min(losses);
    // Σ_{i ≤ k} C(n, i) / 2^n, in logs to stay finite for large n.
    let ln_choose = |n: usize, i: usize| ln_factorial(n) - ln_factorial(i) - ln_factorial(n - i);
    let tail: f64 = (0..=k).map(|i| (ln_choose(n, i) - n as f64 * std::f64::consts::LN_2).exp()).sum();
    (2.0 * tail).min(1.0)
}

fn ln_factorial(n: usize) -> f64 {
    (2..=n).map(|i| (i as f64).ln()).sum()
}

fn sign_test(pairs: &[(f64, f64)]) -> SignTest {
    let better = pairs.iter().filter(|(t, v)| t < v).count();
    let worse = pairs.iter().filter(|(t, v)| t > v).count();
    SignTest {
        better,
        worse,
        ties: pairs.len() - better - worse,
        p_value: sign_test_p(better, worse),
        mean_difference: if pairs.is_empty() { f64::NAN } else { pairs.iter().map(|(t, v)| t - v).sum::<f64>() / pairs.len() as f64 },
    }
}

/// Pairs `tactile` and `vision` results by sample, then by grasp. Samples scored by only one of
/// them are left out; `None` when the results carry no trajectory (an old dataset).
pub fn paired(tactile: &[SampleResult], vision: &[SampleResult]) -> Option<Paired> {
    let by_index: BTreeMap<(String, u64), &SampleResult> = vision.iter().map(|r| ((r.object.clone(), r.index), r)).collect();
    let mut grasps: BTreeMap<(String, u32), Vec<(&SampleResult, &SampleResult)>> = BTreeMap::new();
    for t in tactile {
        if t.trajectory == u32::MAX {
            return None;
        }
        if let Some(v) = by_index.get(&(t.object.clone(), t.index)) {
            grasps.entry((t.object.clone(), t.trajectory)).or_default().push((t, v));
        }
    }
    if grasps.is_empty() {
        return None;
    }
    let mean = |xs: &[(&SampleResult, &SampleResult)], f: &dyn Fn(&(&SampleResult, &SampleResult)) -> f64| {
        xs.iter().map(f).sum::<f64>() / xs.len() as f64
    };
    let grasps: Vec<GraspPair> = grasps
        .into_iter()
        .map(|((object, trajectory), xs)| GraspPair {
            object,
            trajectory,
            samples: xs.len(),
            tactile_position_cm: mean(&xs, &|(t, _)| t.position_cm),
            vision_position_cm: mean(&xs, &|(_, v)| v.position_cm),
            tactile_angle_deg: mean(&xs, &|(t, _)| t.angle_deg),
            vision_angle_deg: mean(&xs, &|(_, v)| v.angle_deg),
        })
        .collect();
    let position = sign_test(&grasps.iter().map(|g| (g.tactile_position_cm, g.vision_position_cm)).collect::<Vec<_>>());
    let angle = sign_test(&grasps.iter().map(|g| (g.tactile_angle_deg, g.vision_angle_deg)).collect::<Vec<_>>());
    Some(Paired { grasps, position, angle })
}

/// A tactile network against the vision-only baseline, with their paired comparison: computed
/// once here for the report's tables, `results.json` and plots.
#[derive(Debug, Clone)]
pub struct Comparison<'a> {
    pub tactile: &'a ModelEval,
    pub vision: &'a ModelEval,
    /// `None` when the results carry no trajectory (see [`paired`]).
    pub paired: Option<Paired>,
}

/// The first vision-only evaluation against every tactile one that also sees colour.
pub fn comparisons(evals: &[ModelEval]) -> Vec<Comparison<'_>> {
    let Some(vision) = evals.iter().find(|e| e.variant == Variant::VisionOnly) else { return Vec::new() };
    evals
        .iter()
        .filter(|e| e.variant.uses_tactile() && e.variant.uses_color())
        .map(|tactile| Comparison { tactile, vision, paired: paired(&tactile.results, &vision.results) })
        .collect()
}

/// How a tactile network answers: which channel's estimate it picks, and how good those are.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ChannelUse {
    pub n: usize,
    /// Share (%) of samples answered by the tactile channel.
    pub tactile_share: f64,
    /// Mean position error (cm) of the samples answered by each channel.
    pub tactile_position_cm: f64,
    pub visual_position_cm: f64,
    /// Mean confidence of the chosen estimates of each channel.
    pub tactile_confidence: f64,
    pub visual_confidence: f64,
}

pub fn channel_use<'a>(results: impl IntoIterator<Item = &'a SampleResult>) -> ChannelUse {
    let r: Vec<&SampleResult> = results.into_iter().collect();
    let part = |tactile: bool| r.iter().filter(|s| s.tactile_estimate == tactile).copied().collect::<Vec<_>>();
    let mean = |xs: &[&SampleResult], f: &dyn Fn(&SampleResult) -> f64| {
        if xs.is_empty() { f64::NAN } else { xs.iter().map(|s| f(s)).sum::<f64>() / xs.len() as f64 }
    };
    let (t, v) = (part(true), part(false));
    ChannelUse {
        n: r.len(),
        tactile_share: if r.is_empty() { f64::NAN } else { 100.0 * t.len() as f64 / r.len() as f64 },
        tactile_position_cm: mean(&t, &|s| s.position_cm),
        visual_position_cm: mean(&v, &|s| s.position_cm),
        tactile_confidence: mean(&t, &|s| s.confidence as f64),
        visual_confidence: mean(&v, &|s| s.confidence as f64),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sign_test_matches_hand_values() {
        // 14 wins of 24: p = 2 · P(X ≤ 10), X ~ Bin(24, 1/2) = 0.5413 (the first run).
        assert!((sign_test_p(14, 10) - 0.5413).abs() < 1e-3, "{}", sign_test_p(14, 10));
        // 10 of 10: 2 / 1024.
        assert!((sign_test_p(10, 0) - 2.0 / 1024.0).abs() < 1e-12);
        assert_eq!(sign_test_p(5, 5), 1.0);
        assert_eq!(sign_test_p(0, 0), 1.0);
        // Symmetric in its arguments; large n stays finite.
        assert_eq!(sign_test_p(3, 9), sign_test_p(9, 3));
        let p = sign_test_p(600, 400);
        assert!(p > 0.0 && p < 1e-9, "{p}");
    }

    fn result(object: &str, index: u64, trajectory: u32, position_cm: f64, tactile_estimate: bool) -> SampleResult {
        SampleResult {
            index,
            object: object.into(),
            trajectory,
            instance: 0,
            symmetric: false,
            occlusion: 0.5,
            tactile_points: 10,
            position_cm,
            angle_deg: 10.0,
            angle_sym_deg: 10.0,
            add_m: 0.01,
            adds_m: 0.01,
            confidence: 0.5,
            tactile_estimate,
            estimate: Default::default(),
        }
    }

    #[test]
    fn pairs_by_grasp() {
        // Two grasps of two samples each; touch better on the first, worse on the second.
        let t = [result("a", 0, 1, 1.0, true), result("a", 1, 1, 2.0, false), result("a", 2, 6, 3.0, true), result("a", 3, 6, 3.0, true)];
        let v =
            [result("a", 0, 1, 2.0, false), result("a", 1, 1, 2.0, false), result("a", 2, 6, 1.0, false), result("a", 3, 6, 1.0, false)];
        let p = paired(&t, &v).unwrap();
        assert_eq!(p.grasps.len(), 2);
        assert_eq!((p.grasps[0].tactile_position_cm, p.grasps[0].vision_position_cm), (1.5, 2.0));
        assert_eq!((p.position.better, p.position.worse, p.position.ties), (1, 1, 0));
        assert_eq!((p.angle.better, p.angle.worse, p.angle.ties), (0, 0, 2));
        assert!((p.position.mean_difference - 0.75).abs() < 1e-12); // (-0.5 + 2) / 2
        let u = channel_use(&t);
        assert_eq!(u.tactile_share, 75.0);
        assert!((u.tactile_position_cm - 7.0 / 3.0).abs() < 1e-12 && u.visual_position_cm == 2.0);
    }
}

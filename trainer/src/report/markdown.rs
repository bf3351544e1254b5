//! `report.md`: the summaries of every run overall, per object and per occlusion bin, the paired
//! comparison with the vision-only baseline ("what touch buys"), which channel answers, the
//! tactile-point sweep and the touch control.

use std::fmt::Write as _;

use vt_dataset::OcclusionBin;

use crate::data::TACTILE_SWEEP;
use crate::eval::compare::{Comparison, Paired, channel_use, comparisons, paired};
use crate::eval::control::{ControlComparison, TouchControl};
use crate::eval::{ModelEval, SampleResult, Summary};
use crate::model::Variant;

fn pct(v: f64) -> String {
    if v.is_nan() { "–".into() } else { format!("{v:.1}") }
}

/// The Markdown report (see the module docs): the metrics, then the same split per object, per
/// occlusion level, what touch buys, and the tactile-point sweep.
pub fn report_markdown(evals: &[ModelEval], split: &str, device: &str) -> String {
    markdown(evals, &comparisons(evals), split, device)
}

/// [`report_markdown`] with the comparisons already made.
pub(super) fn markdown(evals: &[ModelEval], pairs: &[Comparison], split: &str, device: &str) -> String {
    let mut s = String::new();
    report_header(&mut s, evals, split, device);
    overall_section(&mut s, evals);
    per_object_section(&mut s, evals);
    per_occlusion_section(&mut s, evals);
    angle_distribution_section(&mut s, evals);
    touch_section(&mut s, pairs);
    tactile_sweep_section(&mut s, evals);
    touch_control_section(&mut s, evals);
    learning_curve_section(&mut s, evals);
    s
}

/// Upper edges (°) of the angle-error bins of [`angle_distribution_section`].
const ANGLE_BINS: [f64; 5] = [10.0, 30.0, 90.0, 150.0, 180.0];

/// How the angle errors spread, per run: a network that has learned an object's orientation up to
/// a flip puts its samples near 0° and near 180°, one that has not spreads them like a random
/// rotation (82 % of whose errors are above 90°; median 132°, mean 126°).
fn angle_distribution_section(s: &mut String, evals: &[ModelEval]) {
    if evals.iter().all(|e| e.results.is_empty()) {
        return;
    }
    let _ = writeln!(
        s,
        "## Angle errors
"
    );
    let _ = writeln!(
        s,
        "Share of samples (%) per angle-error bin, and the median: near 180° are flips.
"
    );
    let mut header = String::from("| run | n | median (°) |");
    let mut lower = 0.0;
    for upper in ANGLE_BINS {
        let _ = write!(header, " {lower:.0}–{upper:.0}° |");
        lower = upper;
    }
    let _ = writeln!(
        s,
        "{header}
|{}",
        "---|".repeat(3 + ANGLE_BINS.len())
    );
    for e in evals.iter().filter(|e| !e.results.is_empty()) {
        let angles: Vec<f64> = e.results.iter().map(|r| r.angle_deg).collect();
        let m = Summary::of(&e.results);
        let _ = write!(s, "| {} | {} | {:.1} |", e.name, angles.len(), m.angle_median_deg);
        let mut lower = f64::NEG_INFINITY;
        for upper in ANGLE_BINS {
            let inside = angles.iter().filter(|&&a| a > lower && a <= upper).count();
            let _ = write!(s, " {:.1} |", 100.0 * inside as f64 / angles.len() as f64);
            lower = upper;
        }
        let _ = writeln!(s);
    }
    // P(angle <= x) of a uniform rotation is (x − sin x)/π; its median (132.3°) solves that = 1/2
    // (its mean is 126.5°).
    let random = |deg: f64| {
        let x = deg.to_radians();
        (x - x.sin()) / std::f64::consts::PI
    };
    let _ = write!(s, "| uniformly random rotation | – | 132.3 |");
    let mut lower = 0.0;
    for upper in ANGLE_BINS {
        let _ = write!(s, " {:.1} |", 100.0 * (random(upper) - random(lower)));
        lower = upper;
    }
    let _ = writeln!(s, "\n");
}

/// Per run that evaluated while training: its held-out errors at each evaluated epoch (a fixed,
/// evenly spread subset of the test split), with the pictures.
fn learning_curve_section(s: &mut String, evals: &[ModelEval]) {
    let runs: Vec<&ModelEval> = evals.iter().filter(|e| !e.curve.is_empty()).collect();
    if runs.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "## Learning curves
"
    );
    let _ = writeln!(
        s,
        "Held-out errors during training (`train.eval_every`, on `train.eval_samples` samples spread evenly over the test \
         split, the same at every evaluation): where position saturates and whether orientation still improves.\n"
    );
    if runs.iter().any(|e| e.curve.len() >= 2) {
        let _ = writeln!(s, "![position](learning-position.svg)\n\n![angle](learning-angle.svg)\n");
    }
    let _ = writeln!(s, "| run | epoch | steps | training loss | n | position (cm) | median (cm) | angle (°) | median (°) |");
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|");
    for e in runs {
        for p in &e.curve {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {:.5} | {} | {:.3} | {} | {:.1} | {} |",
                e.name,
                p.epoch,
                p.steps,
                p.loss,
                p.n,
                p.position_cm,
                if p.position_median_cm.is_nan() { "–".into() } else { format!("{:.3}", p.position_median_cm) },
                p.angle_deg,
                if p.angle_median_deg.is_nan() { "–".into() } else { format!("{:.1}", p.angle_median_deg) },
            );
        }
    }
    let _ = writeln!(s);
}

fn report_header(s: &mut String, evals: &[ModelEval], split: &str, device: &str) {
    let _ = writeln!(s, "# vtpose evaluation\n");
    let datasets: Vec<String> =
        evals.iter().map(|e| e.dataset.display().to_string()).collect::<std::collections::BTreeSet<_>>().into_iter().collect();
    let _ = writeln!(
        s,
        "Dataset {}, split `{split}`, device `{device}`. Each sample is scored by the network's most confident estimate.",
        datasets.join(", ")
    );
    let _ = writeln!(
        s,
        "Errors are mean ± standard error. Position: Euclidean distance (cm); angle: arccos(2⟨q̂,q⟩²−1) (°); \
         ADD / ADD-S: mean (closest-)model-point distance (cm), AUC up to 10 cm (%) as YCB-Video; \
         ADD(-S) < 2 cm: ADD-S for symmetric objects, ADD otherwise (%). Angle up to symmetry (not a paper metric): the \
         smallest angle to a rotation the object's symmetry (models_info.json) makes look the same as the truth.\n"
    );
}

/// One row per run: every metric over the whole split.
fn overall_section(s: &mut String, evals: &[ModelEval]) {
    let _ = writeln!(s, "## Overall\n");
    let _ = writeln!(
        s,
        "| run | model | n | skipped | position (cm) | angle (°) | angle up to symmetry (°) | ADD (cm) | ADD-S (cm) | ADD AUC | ADD-S AUC | ADD(-S) < 2 cm | tactile estimate chosen |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for e in evals {
        let m = Summary::of(&e.results);
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {:.2} | {:.2} | {} | {} | {} | {} | {} | {} |",
            e.name,
            e.variant.label(),
            m.n,
            e.skipped,
            m.position_cm,
            m.angle_deg,
            m.angle_sym_deg,
            m.add_cm,
            m.adds_cm,
            pct(m.add_auc),
            pct(m.adds_auc),
            pct(m.accuracy_2cm),
            if e.variant.uses_tactile() { pct(m.tactile_chosen) } else { "–".into() }
        );
    }
}

fn per_object_section(s: &mut String, evals: &[ModelEval]) {
    let _ = writeln!(s, "\n## Per object\n");
    let _ =
        writeln!(s, "| object | run | n | position (cm) | angle (°) | angle up to symmetry (°) | ADD AUC | ADD-S AUC | ADD(-S) < 2 cm |");
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|");
    let objects: std::collections::BTreeSet<String> = evals.iter().flat_map(|e| e.results.iter().map(|r| r.object.clone())).collect();
    for o in &objects {
        for e in evals {
            let m = Summary::of(e.results.iter().filter(|r| &r.object == o));
            if m.n > 0 {
                let _ = writeln!(
                    s,
                    "| {o} | {} | {} | {} | {:.2} | {:.2} | {} | {} | {} |",
                    e.name,
                    m.n,
                    m.position_cm,
                    m.angle_deg,
                    m.angle_sym_deg,
                    pct(m.add_auc),
                    pct(m.adds_auc),
                    pct(m.accuracy_2cm)
                );
            }
        }
    }
}

fn per_occlusion_section(s: &mut String, evals: &[ModelEval]) {
    let _ = writeln!(s, "\n## Per occlusion level\n");
    let _ = writeln!(s, "The paper's bins of the occlusion level (share of model points the camera does not see).\n");
    let _ = writeln!(s, "| occlusion | run | n | position (cm) | angle (°) | ADD-S AUC | ADD(-S) < 2 cm |");
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for bin in OcclusionBin::ALL {
        for e in evals {
            let m = Summary::of(e.results.iter().filter(|r| OcclusionBin::of_f32(r.occlusion) == Some(bin)));
            if m.n > 0 {
                summary_row(s, bin.label(), &e.name, &m);
            } else {
                let _ = writeln!(s, "| {} | {} | 0 | – | – | – | – |", bin.label(), e.name);
            }
        }
    }
}

/// One table row: the group, the run, and the run's summary over the group.
fn summary_row(s: &mut String, group: &str, run: &str, m: &Summary) {
    let _ = writeln!(
        s,
        "| {group} | {run} | {} | {} | {:.2} | {} | {} |",
        m.n,
        m.position_cm,
        m.angle_deg,
        pct(m.adds_auc),
        pct(m.accuracy_2cm)
    );
}

/// Tactile networks evaluated with other numbers of tactile points (when the sweep ran).
fn tactile_sweep_section(s: &mut String, evals: &[ModelEval]) {
    if evals.iter().any(|e| !e.sweep.is_empty()) {
        let _ = writeln!(s, "\n## Number of tactile points\n");
        let _ = writeln!(
            s,
            "Tactile models evaluated with n_t tactile points per sample (trained with their config's n_t); vision-only runs for reference.\n"
        );
        let _ = writeln!(s, "| n_t | run | n | position (cm) | angle (°) | ADD-S AUC | ADD(-S) < 2 cm |");
        let _ = writeln!(s, "|---|---|---|---|---|---|---|");
        for nt in TACTILE_SWEEP {
            for e in evals {
                if let Some((_, r)) = e.sweep.iter().find(|(k, _)| *k == nt) {
                    let m = Summary::of(r);
                    summary_row(s, &nt.to_string(), &e.name, &m);
                }
            }
        }
        for e in evals.iter().filter(|e| !e.variant.uses_tactile()) {
            let m = Summary::of(&e.results);
            summary_row(s, "–", &format!("{} (vision only)", e.name), &m);
        }
    }
}

/// Part of an evaluation's samples: one occlusion bin's, or one object's.
enum Subset<'a> {
    Bin(OcclusionBin),
    Object(&'a str),
}

impl Subset<'_> {
    fn of(&self, results: &[SampleResult]) -> Vec<SampleResult> {
        let keep = |r: &&SampleResult| match self {
            Subset::Bin(b) => OcclusionBin::of_f32(r.occlusion) == Some(*b),
            Subset::Object(o) => r.object == *o,
        };
        results.iter().filter(keep).cloned().collect()
    }
}

/// The paired comparison within each occlusion bin and each object: a grasp's samples in the
/// subset, their mean error under both networks, and the sign test over those grasps.
fn paired_by_subset(s: &mut String, pairs: &[Comparison]) {
    let _ = writeln!(
        s,
        "\nBy occlusion bin and by object: each grasp's samples within the subset, paired the same way.\n\n\
         | tactile run | vs | subset | samples | position, tactile / vision (cm) | grasps: better / worse | p | angle, tactile / vision (°) |\n\
         |---|---|---|---|---|---|---|---|"
    );
    for Comparison { tactile: t, vision: v, .. } in pairs {
        let mut objects: Vec<&str> = t.results.iter().map(|r| r.object.as_str()).collect();
        objects.sort();
        objects.dedup();
        let bins = OcclusionBin::ALL.map(|b| (b.label().to_string(), Subset::Bin(b)));
        for (label, subset) in bins.into_iter().chain(objects.into_iter().map(|o| (o.to_string(), Subset::Object(o)))) {
            let (ts, vs) = (subset.of(&t.results), subset.of(&v.results));
            let Some(p) = paired(&ts, &vs) else { continue };
            let n: usize = p.grasps.iter().map(|g| g.samples).sum();
            let mean = |f: &dyn Fn(&crate::eval::compare::GraspPair) -> f64| {
                p.grasps.iter().map(|g| f(g) * g.samples as f64).sum::<f64>() / n.max(1) as f64
            };
            let _ = writeln!(
                s,
                "| {} | {} | {label} | {n} | {:.3} / {:.3} | {} / {} | {:.3} | {:.1} / {:.1} |",
                t.name,
                v.name,
                mean(&|g| g.tactile_position_cm),
                mean(&|g| g.vision_position_cm),
                p.position.better,
                p.position.worse,
                p.position.p_value,
                mean(&|g| g.tactile_angle_deg),
                mean(&|g| g.vision_angle_deg),
            );
        }
    }
}

/// "What touch buys": the paired per-grasp comparison and how the tactile network answers.
fn touch_section(s: &mut String, pairs: &[Comparison]) {
    if pairs.is_empty() {
        return;
    }
    let _ = writeln!(s, "\n## What touch buys: paired per grasp\n");
    let _ = writeln!(
        s,
        "Samples of one trajectory share a grasp, so the networks are compared per grasp (object, trajectory): each \
         network's mean error over the grasp's samples; `better` counts the grasps on which the tactile network's mean \
         error is lower. p: two-sided exact sign test (ties dropped). Δ: mean over grasps of tactile − vision (negative: touch helps).\n"
    );
    let _ = writeln!(
        s,
        "| tactile run | vs | grasps | position: better / worse | p | Δ position (cm) | angle: better / worse | p | Δ angle (°) |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|");
    for Comparison { tactile: t, vision: v, paired } in pairs {
        match paired {
            Some(p) => {
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {} / {} | {:.3} | {:+.3} | {} / {} | {:.3} | {:+.2} |",
                    t.name,
                    v.name,
                    p.grasps.len(),
                    p.position.better,
                    p.position.worse,
                    p.position.p_value,
                    p.position.mean_difference,
                    p.angle.better,
                    p.angle.worse,
                    p.angle.p_value,
                    p.angle.mean_difference
                );
            }
            None => {
                let _ = writeln!(s, "| {} | {} | – (the dataset records no trajectories) | | | | | | |", t.name, v.name);
            }
        }
    }
    paired_by_subset(s, pairs);
    let _ = writeln!(s, "\n## Which channel answers\n");
    let _ = writeln!(
        s,
        "The tactile network picks its most confident estimate from either channel. Share: samples answered by the \
         tactile channel; the position error and mean confidence of the samples each channel answered.\n"
    );
    let _ = writeln!(
        s,
        "| run | occlusion | n | tactile share (%) | position, tactile answers (cm) | position, visual answers (cm) | confidence tactile / visual |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for Comparison { tactile: t, .. } in pairs {
        let rows = std::iter::once(("all".to_string(), channel_use(&t.results))).chain(
            OcclusionBin::ALL
                .iter()
                .map(|b| (b.label().to_string(), channel_use(t.results.iter().filter(|r| OcclusionBin::of_f32(r.occlusion) == Some(*b))))),
        );
        for (label, u) in rows {
            if u.n == 0 {
                continue;
            }
            let _ = writeln!(
                s,
                "| {} | {label} | {} | {} | {:.3} | {:.3} | {:.3} / {:.3} |",
                t.name,
                u.n,
                pct(u.tactile_share),
                u.tactile_position_cm,
                u.visual_position_cm,
                u.tactile_confidence,
                u.visual_confidence
            );
        }
    }
}

/// The touch control: each tactile network with its true touch, another grasp's and none, and
/// the true touch paired per grasp against each.
fn touch_control_section(s: &mut String, evals: &[ModelEval]) {
    let controlled: Vec<(&ModelEval, &TouchControl)> = evals.iter().filter_map(|e| e.touch_control.as_ref().map(|c| (e, c))).collect();
    if controlled.is_empty() {
        return;
    }
    let _ = writeln!(s, "\n## Touch control\n");
    let _ = writeln!(
        s,
        "Each tactile network on the same samples with its true touch, with the touch of another grasp of the same object \
         (the next trajectory's, same instance) and with no touch, beside the trained vision-only network (the baseline \
         the paper compares against: a tactile network fed no touch is outside its training, a network trained without \
         touch is not). A network that uses touch gets worse with the wrong touch. Paired per grasp: `better` counts the \
         grasps on which the true touch gives the lower mean error; p: two-sided exact sign test; Δ: mean over grasps of \
         true − control (negative: the true touch helps).\n"
    );
    let _ = writeln!(
        s,
        "| run | touch | n | position (cm) | angle (°) | ADD(-S) < 2 cm (%) | position: better / worse | p | Δ position (cm) |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|");
    let vision = evals.iter().find(|e| e.variant == Variant::VisionOnly);
    for (e, c) in &controlled {
        let cmp = ControlComparison::of(&e.results, c);
        let trained_baseline =
            vision.map(|v| (format!("trained vision-only ({})", v.name), &v.results[..], paired(&e.results, &v.results)));
        let mut rows: Vec<(String, &[SampleResult], Option<Paired>)> = vec![
            ("true".into(), &e.results, None),
            ("another grasp's".into(), &c.other_grasp, cmp.other_grasp.clone()),
            ("none".into(), &c.no_touch, cmp.no_touch.clone()),
        ];
        rows.extend(trained_baseline);
        for (label, results, p) in rows {
            let p = p.as_ref();
            let m = Summary::of(results);
            let paired = match p {
                Some(p) => {
                    format!("{} / {} | {:.3} | {:+.3}", p.position.better, p.position.worse, p.position.p_value, p.position.mean_difference)
                }
                None if label == "true" => "– | – | –".to_string(),
                None => "(no grasps to pair) | | ".to_string(),
            };
            let _ = writeln!(
                s,
                "| {} | {label} | {} | {} | {} | {} | {paired} |",
                e.name,
                m.n,
                m.position_cm,
                m.angle_deg,
                pct(m.accuracy_2cm)
            );
        }
    }
    let _ = writeln!(s);
    for (e, c) in &controlled {
        let verdict = match ControlComparison::of(&e.results, c).uses_touch() {
            Some(true) => "uses touch: its position error rises with another grasp's touch (p < 0.05)",
            Some(false) => {
                "does **not** show that it uses touch: its position error does not rise with another grasp's touch (p ≥ 0.05, or not on more grasps than it falls)"
            }
            None => "cannot be checked: no object has a second grasp in this split",
        };
        let _ = writeln!(s, "- {}: {verdict}.", e.name);
    }
}

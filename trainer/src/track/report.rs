//! The tracking report: `tracking.md` (the tables), `tracking.json` (every method's summary and
//! per-episode scores, the error and occlusion against time), `episodes.csv` (one row per method
//! and episode), `frames.csv` (one row per method and frame: the scores every number above is
//! computed from), `error-time.svg` (mean ADD-S against time per method) and `occlusion-time.svg`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use vt_dataset::OcclusionBin;

use super::{MethodResult, MethodSummary, TouchSource, Tracking};
use crate::eval::AUC_MAX_M;
use crate::eval::compare::sign_test_p;
use crate::eval::metrics::auc;
use crate::report::plots::{Curve, line_chart};

/// The error and occlusion against time: per frame of the episodes (episodes of one config have
/// the same frames), the mean time, the mean occlusion (%) and each method's mean ADD-S (cm) over
/// the episodes with a pose at that frame.
#[derive(Debug, Clone, serde::Serialize)]
pub struct TimeCurve {
    pub frame: usize,
    pub time_s: f64,
    pub occlusion_pct: f64,
    /// Per method (in [`Tracking::methods`] order); NaN where no episode has a pose.
    pub adds_cm: Vec<f64>,
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 { f64::NAN } else { sum / n as f64 }
}

/// The [`TimeCurve`] of every frame index.
pub fn time_curve(t: &Tracking) -> Vec<TimeCurve> {
    let longest = t.episodes.iter().map(|e| e.frames.len()).max().unwrap_or(0);
    (0..longest)
        .map(|k| {
            let at_k = || t.episodes.iter().filter_map(move |e| e.frames.get(k));
            TimeCurve {
                frame: k,
                time_s: mean(at_k().map(|f| f.time_s)),
                occlusion_pct: mean(at_k().map(|f| 100.0 * f.occlusion as f64).filter(|v| v.is_finite())),
                adds_cm: t
                    .methods
                    .iter()
                    .map(|m| mean(m.episodes.iter().filter_map(|e| e.frames.get(k)?.adds_m).map(|e| 100.0 * e)))
                    .collect(),
            }
        })
        .collect()
}

/// Episodes on which `m`'s ADD-S AUC is higher and lower than `base`'s (both scored), with the
/// sign test's two-sided p.
pub fn paired_auc(m: &MethodResult, base: &MethodResult) -> (usize, usize, f64) {
    let (mut better, mut worse) = (0, 0);
    for (a, b) in m.episodes.iter().zip(&base.episodes) {
        if let (Some(a), Some(b)) = (&a.score, &b.score) {
            if a.adds_auc > b.adds_auc {
                better += 1;
            } else if a.adds_auc < b.adds_auc {
                worse += 1;
            }
        }
    }
    (better, worse, sign_test_p(better, worse))
}

/// What each method is compared with: a network's method with the same network per frame with
/// its own touch; a refined method with the same refiner's depth-only method.
fn baseline_of<'a>(t: &'a Tracking, m: &MethodResult) -> Option<&'a MethodResult> {
    if m.refined {
        return t.methods.iter().find(|b| b.run == m.run && b.refined && b.touch == TouchSource::None);
    }
    t.methods.iter().find(|b| b.run == m.run && !b.refined && b.touch == TouchSource::Own && !b.filtered)
}

fn f(v: f64, p: usize) -> String {
    if v.is_finite() { format!("{v:.p$}") } else { "–".into() }
}

/// `tracking.md`.
pub fn markdown(t: &Tracking, device: &str) -> String {
    let mut s = String::new();
    let frames: usize = t.episodes.iter().map(|e| e.frames.len()).sum();
    let rate = t.episodes.iter().find_map(|e| {
        let (a, b) = (e.frames.first()?, e.frames.get(1)?);
        Some(1.0 / (b.time_s - a.time_s))
    });
    let _ = writeln!(s, "# vtpose tracking\n");
    let _ = writeln!(
        s,
        "Dataset {}, split `{}`, device `{device}`: {} episodes, {frames} frames{}. Each frame is estimated by the per-frame network \
         (its most confident estimate); the filtered methods pass those estimates through the constant-velocity filter \
         (α = {}, β = {:.3}, gate {} cm / {}°, a new track after {} rejections). The touch control feeds each frame the touch of the \
         same frame of the next test episode of the same object.\n",
        t.dataset.display(),
        t.split,
        t.episodes.len(),
        rate.map_or(String::new(), |r| format!(" at {r:.1} Hz")),
        t.filter.alpha,
        t.filter.beta,
        t.filter.gate_cm,
        t.filter.gate_deg,
        t.filter.reinit_after,
    );
    let _ = writeln!(
        s,
        "ADD-S AUC: area under the ADD-S accuracy–threshold curve for thresholds 0–10 cm, per episode (%; a frame without a pose \
         is a failure), mean ± standard error over episodes. Drift: least-squares slope of ADD-S against time (cm/s), and the mean \
         ADD-S of the last fifth of an episode's frames minus the first fifth (cm). Jitter: mean frame-to-frame change of the \
         translation error (mm). vs per frame: episodes on which the method's AUC is higher / lower than the same network's per-frame \
         AUC (for a refined method: than the same refiner's with the depth alone), with the sign test's p. The refined methods \
         (`refine …`) fit the object's mesh to each frame's depth points, free space and, with touch, tactile points, warm-started \
         from the previous frame's pose (and the network's estimate of the frame where a run is named), searched from nothing at \
         the first frame and when the warm start fits poorly.\n"
    );
    let _ = writeln!(s, "## Overall\n");
    let _ = writeln!(
        s,
        "| method | episodes | frames | no pose | ADD-S AUC (%) | ADD-S (cm) | ADD-S < 2 cm (%) | drift (cm/s) | end − start (cm) | jitter (mm) | gate rejections | vs per frame |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|---|");
    for m in &t.methods {
        let sm: MethodSummary = m.summary();
        let vs = match baseline_of(t, m) {
            Some(b) if !std::ptr::eq(b, m) => {
                let (better, worse, p) = paired_auc(m, b);
                format!("{better} / {worse} (p = {p:.3})")
            }
            _ => "–".into(),
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.1} | {:.2} | {} | {:.2} | {:.2} | {:.2} | {} | {vs} |",
            m.label,
            sm.episodes,
            sm.frames,
            sm.missing,
            sm.adds_auc,
            sm.adds_cm,
            f(sm.adds_below_2cm, 1),
            sm.drift_cm_per_s,
            sm.end_minus_start_cm,
            sm.jitter_mm,
            if m.filtered { m.rejected.to_string() } else { "–".into() },
        );
    }
    per_object_section(&mut s, t);
    per_occlusion_section(&mut s, t);
    time_section(&mut s, t);
    s
}

fn per_object_section(s: &mut String, t: &Tracking) {
    let mut objects: Vec<&str> = t.episodes.iter().map(|e| e.object.as_str()).collect();
    objects.dedup();
    let _ = writeln!(s, "\n## ADD-S AUC per object\n\nMean ± standard error over the object's episodes (%).\n");
    let _ = writeln!(s, "| method | {} |", objects.join(" | "));
    let _ = writeln!(s, "|---|{}", "---|".repeat(objects.len()));
    for m in &t.methods {
        let cells: Vec<String> = objects
            .iter()
            .map(|o| {
                let aucs: Vec<f64> = t
                    .episodes
                    .iter()
                    .zip(&m.episodes)
                    .filter(|(e, _)| e.object == *o)
                    .filter_map(|(_, r)| Some(r.score.as_ref()?.adds_auc))
                    .collect();
                format!("{:.1} (n = {})", crate::eval::metrics::MeanSe::of(&aucs), aucs.len())
            })
            .collect();
        let _ = writeln!(s, "| {} | {} |", m.label, cells.join(" | "));
    }
}

fn per_occlusion_section(s: &mut String, t: &Tracking) {
    let bins = OcclusionBin::ALL;
    let _ = writeln!(
        s,
        "\n## ADD-S AUC per occlusion level\n\nThe frames of every episode pooled by the paper's occlusion bins (share of the model points \
         the camera does not see); AUC over the bin's frames (%), frames without a pose as failures.\n"
    );
    let _ = writeln!(s, "| method | {} |", bins.iter().map(|b| b.label()).collect::<Vec<_>>().join(" | "));
    let _ = writeln!(s, "|---|{}", "---|".repeat(bins.len()));
    for m in &t.methods {
        let cells: Vec<String> = bins
            .iter()
            .map(|bin| {
                let errors: Vec<f64> = t
                    .episodes
                    .iter()
                    .zip(&m.episodes)
                    .flat_map(|(e, r)| e.frames.iter().zip(&r.frames))
                    .filter(|(f, _)| OcclusionBin::of_f32(f.occlusion) == Some(*bin))
                    .map(|(_, score)| score.adds_m.unwrap_or(f64::INFINITY))
                    .collect();
                if errors.is_empty() { "–".into() } else { format!("{:.1} (n = {})", auc(&errors, AUC_MAX_M), errors.len()) }
            })
            .collect();
        let _ = writeln!(s, "| {} | {} |", m.label, cells.join(" | "));
    }
}

/// At most 10 rows: every frame, or frames pooled into 10 equal runs.
fn time_section(s: &mut String, t: &Tracking) {
    let curve = time_curve(t);
    let rows = curve.len().min(10);
    let _ = writeln!(
        s,
        "\n## Error and occlusion against time\n\nMean ADD-S (cm) over the episodes with a pose at the frame{}, and the mean \
         occlusion. Chart: `error-time.svg` (every frame), `occlusion-time.svg`.\n",
        if rows < curve.len() { "s of each row (the episode's frames in 10 runs)" } else { "" }
    );
    let _ = writeln!(s, "| time (s) | occlusion (%) | {} |", t.methods.iter().map(|m| m.label.as_str()).collect::<Vec<_>>().join(" | "));
    let _ = writeln!(s, "|---|---|{}", "---|".repeat(t.methods.len()));
    for r in 0..rows {
        let part = &curve[r * curve.len() / rows..(r + 1) * curve.len() / rows];
        let span = match (part.first(), part.last()) {
            (Some(a), Some(b)) if part.len() > 1 => format!("{:.2}–{:.2}", a.time_s, b.time_s),
            (Some(a), _) => format!("{:.2}", a.time_s),
            _ => continue,
        };
        let cells: Vec<String> =
            (0..t.methods.len()).map(|k| f(mean(part.iter().map(|c| c.adds_cm[k]).filter(|v| v.is_finite())), 2)).collect();
        let _ = writeln!(
            s,
            "| {span} | {} | {} |",
            f(mean(part.iter().map(|c| c.occlusion_pct).filter(|v| v.is_finite())), 1),
            cells.join(" | ")
        );
    }
}

/// Writes every file of the report into `out`; returns the path of `tracking.md`.
pub fn write_tracking_report(t: &Tracking, device: &str, out: &Path) -> Result<PathBuf> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let write = |name: &str, text: String| {
        let p = out.join(name);
        std::fs::write(&p, text).with_context(|| format!("cannot write {}", p.display()))
    };
    let curve = time_curve(t);
    let json = serde_json::json!({
        "dataset": t.dataset, "split": t.split, "device": device, "filter": t.filter,
        "episodes": t.episodes.iter().map(|e| serde_json::json!({
            "object": e.object, "trajectory": e.trajectory, "frames": e.frames.len(), "donor": e.donor,
        })).collect::<Vec<_>>(),
        "methods": t.methods.iter().map(|m| serde_json::json!({
            "label": m.label, "run": m.run, "variant": m.variant, "touch": m.touch, "filtered": m.filtered, "refined": m.refined,
            "rejected": m.rejected,
            "summary": m.summary(),
            "vs_per_frame": baseline_of(t, m).filter(|b| !std::ptr::eq(*b, m)).map(|b| {
                let (better, worse, p) = paired_auc(m, b);
                serde_json::json!({"better": better, "worse": worse, "p_value": p})
            }),
            "episodes": m.episodes.iter().map(|e| &e.score).collect::<Vec<_>>(),
        })).collect::<Vec<_>>(),
        "time_curve": &curve,
    });
    write("tracking.json", serde_json::to_string_pretty(&json)?)?;
    write("episodes.csv", episodes_csv(t))?;
    write("frames.csv", frames_csv(t))?;
    let curves: Vec<Curve> = t
        .methods
        .iter()
        .enumerate()
        .map(|(k, m)| Curve {
            name: m.label.clone(),
            color: color_of(t, m),
            dashed: m.filtered,
            points: curve.iter().map(|c| (c.time_s, c.adds_cm[k])).collect(),
        })
        .collect();
    write("error-time.svg", line_chart("Mean ADD-S over the test episodes against time", "time (s)", "ADD-S (cm)", &curves, &[])?)?;
    let occlusion = [Curve {
        name: "mean occlusion".into(),
        color: 0,
        dashed: false,
        points: curve.iter().map(|c| (c.time_s, c.occlusion_pct)).collect(),
    }];
    write(
        "occlusion-time.svg",
        line_chart("Occlusion against time (mean over the test episodes)", "time (s)", "occlusion (%)", &occlusion, &[])?,
    )?;
    let report = out.join("tracking.md");
    std::fs::write(&report, markdown(t, device)).with_context(|| format!("cannot write {}", report.display()))?;
    Ok(report)
}

/// One colour per run, refinement and touch source: a method and its filtered twin share it (the
/// twin dashed).
fn color_of(t: &Tracking, m: &MethodResult) -> usize {
    let mut keys: Vec<(&str, bool, TouchSource)> = Vec::new();
    for n in &t.methods {
        if !keys.contains(&(n.run.as_str(), n.refined, n.touch)) {
            keys.push((n.run.as_str(), n.refined, n.touch));
        }
    }
    keys.iter().position(|k| *k == (m.run.as_str(), m.refined, m.touch)).unwrap_or(0)
}

fn cell(v: Option<f64>) -> String {
    v.map_or(String::new(), |v| format!("{v:.6}"))
}

fn episodes_csv(t: &Tracking) -> String {
    let mut s = String::from("method,object,trajectory,frames,missing,adds_auc,adds_cm,drift_cm_per_s,end_minus_start_cm,jitter_mm\n");
    for m in &t.methods {
        for (e, r) in t.episodes.iter().zip(&m.episodes) {
            let Some(sc) = &r.score else { continue };
            let _ = writeln!(
                s,
                "{},{},{},{},{},{:.6},{:.6},{:.6},{:.6},{:.6}",
                m.label.replace(',', ";"),
                e.object,
                e.trajectory,
                r.frames.len(),
                sc.missing,
                sc.adds_auc,
                sc.adds_cm,
                sc.drift_cm_per_s,
                sc.end_minus_start_cm,
                sc.jitter_mm
            );
        }
    }
    s
}

fn frames_csv(t: &Tracking) -> String {
    let mut s = String::from("method,object,trajectory,frame,index,time_s,occlusion,tactile_points,visible,adds_m,position_cm,angle_deg\n");
    for m in &t.methods {
        for (e, r) in t.episodes.iter().zip(&m.episodes) {
            for (f, sc) in e.frames.iter().zip(&r.frames) {
                let _ = writeln!(
                    s,
                    "{},{},{},{},{},{:.6},{:.4},{},{},{},{},{}",
                    m.label.replace(',', ";"),
                    e.object,
                    e.trajectory,
                    f.frame,
                    f.index,
                    f.time_s,
                    f.occlusion,
                    f.tactile_points,
                    f.visible,
                    cell(sc.adds_m),
                    cell(sc.position_cm),
                    cell(sc.angle_deg)
                );
            }
        }
    }
    s
}

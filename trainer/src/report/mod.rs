//! The report of an evaluation: `report.md` ([`markdown`]), `results.json` (the summaries and the
//! paired comparisons), `samples-<run>.csv` (every sample's scores) and the SVG charts ([`plots`]).
//! It only writes out what [`crate::eval`] computed.

pub mod markdown;
pub mod plots;
pub mod refine;
pub mod sheet;

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use vt_dataset::OcclusionBin;

use crate::eval::compare::{Comparison, channel_use, comparisons};
use crate::eval::{ModelEval, SampleResult, Summary};
pub use markdown::report_markdown;

/// Writes `report.md`, `results.json` (summaries), `samples-<run>.csv` (per-sample scores) and
/// the charts into `out`; returns the path of `report.md`.
pub fn write_report(evals: &[ModelEval], split: &str, device: &str, out: &Path) -> Result<PathBuf> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let pairs = comparisons(evals);
    let report = out.join("report.md");
    std::fs::write(&report, markdown::markdown(evals, &pairs, split, device))
        .with_context(|| format!("cannot write {}", report.display()))?;
    write_results_json(evals, &pairs, out)?;
    plots::write_plots(evals, &pairs, out)?;
    for e in evals {
        write_samples_csv(e, out)?;
    }
    Ok(report)
}

/// `results.json`: per run the summaries overall, per object, per occlusion bin and per tactile
/// point count; then the paired comparisons.
fn write_results_json(evals: &[ModelEval], pairs: &[Comparison], out: &Path) -> Result<()> {
    let vision = evals.iter().find(|e| e.variant == crate::model::Variant::VisionOnly);
    let summaries: Vec<serde_json::Value> = evals
        .iter()
        .map(|e| {
            serde_json::json!({
                "name": e.name, "run": e.run, "variant": e.variant, "dataset": e.dataset, "n_tactile": e.n_tactile,
                "skipped": e.skipped, "overall": Summary::of(&e.results),
                "per_object": group(&e.results, |r| Some(r.object.clone())).into_iter().map(|(k, v)| (k, Summary::of(v))).collect::<BTreeMap<_, _>>(),
                "per_occlusion": group(&e.results, |r| OcclusionBin::of_f32(r.occlusion).map(|b| b.label().to_string())).into_iter().map(|(k, v)| (k, Summary::of(v))).collect::<BTreeMap<_, _>>(),
                "tactile_sweep": e.sweep.iter().map(|(nt, r)| serde_json::json!({"n_tactile": nt, "summary": Summary::of(r)})).collect::<Vec<_>>(),
                "touch_control": e.touch_control.as_ref().map(|c| {
                    let cmp = crate::eval::control::ControlComparison::of(&e.results, c);
                    serde_json::json!({
                        "other_grasp": {"summary": Summary::of(&c.other_grasp), "paired": cmp.other_grasp},
                        "no_touch": {"summary": Summary::of(&c.no_touch), "paired": cmp.no_touch},
                        "uses_touch": cmp.uses_touch(),
                        "trained_vision_only": vision.map(|v| serde_json::json!({
                            "name": v.name, "summary": Summary::of(&v.results),
                            "paired": crate::eval::compare::paired(&e.results, &v.results),
                        })),
                    })
                }),
            })
        })
        .collect();
    let paired: Vec<serde_json::Value> = pairs
        .iter()
        .filter_map(|c| {
            c.paired.as_ref().map(|p| {
                serde_json::json!({"tactile": c.tactile.name, "vision": c.vision.name, "position": p.position, "angle": p.angle, "grasps": p.grasps,
                    "channel_use": channel_use(&c.tactile.results)})
            })
        })
        .collect();
    let all = serde_json::json!({"runs": summaries, "paired": paired});
    std::fs::write(out.join("results.json"), serde_json::to_string_pretty(&all)? + "\n")?;
    Ok(())
}

/// `samples-<run>.csv`: one row per scored sample.
fn write_samples_csv(e: &ModelEval, out: &Path) -> Result<()> {
    let mut csv = String::from(
        "index,object,trajectory,instance,symmetric,occlusion,tactile_points,position_cm,angle_deg,angle_sym_deg,add_cm,adds_cm,confidence,tactile_estimate\n",
    );
    for r in &e.results {
        writeln!(
            csv,
            "{},{},{},{},{},{:.4},{},{:.4},{:.3},{:.3},{:.4},{:.4},{:.4},{}",
            r.index,
            r.object,
            r.trajectory,
            r.instance,
            r.symmetric,
            r.occlusion,
            r.tactile_points,
            r.position_cm,
            r.angle_deg,
            r.angle_sym_deg,
            100.0 * r.add_m,
            100.0 * r.adds_m,
            r.confidence,
            r.tactile_estimate
        )?;
    }
    std::fs::write(out.join(format!("samples-{}.csv", e.name)), csv)?;
    Ok(())
}

/// `results` grouped by `key` (None: left out), keys in order.
pub(super) fn group<K: Ord>(results: &[SampleResult], key: impl Fn(&SampleResult) -> Option<K>) -> BTreeMap<K, Vec<&SampleResult>> {
    let mut m: BTreeMap<K, Vec<&SampleResult>> = BTreeMap::new();
    for r in results {
        if let Some(k) = key(r) {
            m.entry(k).or_default().push(r);
        }
    }
    m
}

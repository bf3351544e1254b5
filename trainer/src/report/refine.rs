//! The report of `vtpose refine`: `refine.md` (every estimator overall, per occlusion bin, per
//! object; the paired comparisons; time per sample), `refine.json` (the same with every grasp's
//! pairing) and `samples-refine.csv` (every estimator's per-sample scores).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use vt_dataset::OcclusionBin;

use super::group;
use crate::eval::metrics::MeanSe;
use crate::eval::refined::{EstimatorPair, RefineEval, comparisons};
use crate::eval::{SampleResult, Summary, median};

/// Writes the report into `out`; returns the path of `refine.md`.
pub fn write_refine_report(eval: &RefineEval, out: &Path) -> Result<PathBuf> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let pairs = comparisons(eval);
    let md = out.join("refine.md");
    std::fs::write(&md, markdown(eval, &pairs)).with_context(|| format!("cannot write {}", md.display()))?;
    let json = serde_json::json!({
        "dataset": eval.dataset, "split": eval.split, "config": eval.config, "samples": eval.samples,
        "threads": eval.threads, "wall_s": eval.wall_s, "shapes_s": eval.shapes_s,
        "estimators": eval.estimators.iter().map(|e| serde_json::json!({
            "label": e.label, "run": e.run, "refined": e.refined, "touch": e.touch, "ms_per_sample": e.ms_per_sample,
            "overall": Summary::of(&e.results),
            "per_occlusion": group(&e.results, |r| OcclusionBin::of_f32(r.occlusion).map(|b| b.label().to_string())).into_iter().map(|(k, v)| (k, Summary::of(v))).collect::<BTreeMap<_, _>>(),
            "per_object": group(&e.results, |r| Some(r.object.clone())).into_iter().map(|(k, v)| (k, Summary::of(v))).collect::<BTreeMap<_, _>>(),
        })).collect::<Vec<_>>(),
        "paired": pairs,
    });
    std::fs::write(out.join("refine.json"), serde_json::to_string_pretty(&json)? + "\n")?;
    let mut csv = String::from(
        "estimator,index,object,trajectory,instance,symmetric,occlusion,tactile_points,position_cm,angle_deg,angle_sym_deg,add_cm,adds_cm\n",
    );
    for e in &eval.estimators {
        for r in &e.results {
            writeln!(
                csv,
                "\"{}\",{},{},{},{},{},{:.4},{},{:.4},{:.3},{:.3},{:.4},{:.4}",
                e.label,
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
                100.0 * r.adds_m
            )?;
        }
    }
    std::fs::write(out.join("samples-refine.csv"), csv)?;
    Ok(md)
}

/// Pools the reports of several `vtpose refine` runs (their `samples-refine.csv` and
/// `refine.json`, e.g. one per object pair) into one evaluation: each estimator's samples
/// concatenated, its time per sample averaged over the samples. The runs must not share an
/// object (its samples would be counted twice).
pub fn pool_reports(dirs: &[PathBuf]) -> Result<RefineEval> {
    use crate::eval::refined::{EstimatorResult, TouchUse};
    let mut estimators: Vec<EstimatorResult> = Vec::new();
    let mut times: BTreeMap<String, (f64, usize)> = BTreeMap::new();
    let (mut samples, mut wall_s, mut shapes_s, mut threads) = (0, 0.0, 0.0, 0);
    let mut objects_seen: BTreeMap<String, PathBuf> = BTreeMap::new();
    let mut config = None;
    for dir in dirs {
        let json_path = dir.join("refine.json");
        let text = std::fs::read_to_string(&json_path)
            .with_context(|| format!("cannot read {} (run `vtpose refine` there first)", json_path.display()))?;
        let json: serde_json::Value = serde_json::from_str(&text).with_context(|| format!("{} is not JSON", json_path.display()))?;
        samples += json["samples"].as_u64().unwrap_or(0) as usize;
        wall_s += json["wall_s"].as_f64().unwrap_or(0.0);
        shapes_s += json["shapes_s"].as_f64().unwrap_or(0.0);
        threads = threads.max(json["threads"].as_u64().unwrap_or(0) as usize);
        if config.is_none() {
            config = serde_json::from_value(json["config"].clone()).ok();
        }
        let csv_path = dir.join("samples-refine.csv");
        let text = std::fs::read_to_string(&csv_path).with_context(|| format!("cannot read {}", csv_path.display()))?;
        let mut this_dir: BTreeMap<String, ()> = BTreeMap::new();
        for (line_no, line) in text.lines().enumerate().skip(1) {
            let bad = |what: &str| anyhow::anyhow!("{} line {}: {what}", csv_path.display(), line_no + 1);
            let (label, rest) = line.strip_prefix('"').and_then(|l| l.split_once("\",")).ok_or_else(|| bad("no quoted estimator label"))?;
            let f: Vec<&str> = rest.split(',').collect();
            if f.len() != 12 {
                return Err(bad(&format!("{} fields after the label, expected 12", f.len())));
            }
            let num = |k: usize, name: &str| f[k].parse::<f64>().map_err(|_| bad(&format!("{name} '{}' is not a number", f[k])));
            let r = SampleResult {
                index: num(0, "index")? as u64,
                object: f[1].to_string(),
                trajectory: num(2, "trajectory")? as u32,
                instance: num(3, "instance")? as u32,
                symmetric: f[4] == "true",
                occlusion: num(5, "occlusion")? as f32,
                tactile_points: num(6, "tactile_points")? as usize,
                position_cm: num(7, "position_cm")?,
                angle_deg: num(8, "angle_deg")?,
                angle_sym_deg: num(9, "angle_sym_deg")?,
                add_m: num(10, "add_cm")? / 100.0,
                adds_m: num(11, "adds_cm")? / 100.0,
                confidence: f32::NAN,
                tactile_estimate: false,
                estimate: Default::default(),
            };
            if let Some(other) = objects_seen.get(&r.object).filter(|d| *d != dir) {
                anyhow::bail!(
                    "{} and {} both have object '{}': pool reports of distinct objects",
                    other.display(),
                    dir.display(),
                    r.object
                );
            }
            this_dir.insert(r.object.clone(), ());
            match estimators.iter_mut().find(|e| e.label == label) {
                Some(e) => e.results.push(r),
                None => {
                    let refined = label.contains("refine:");
                    let touch = if label.contains("other grasp") {
                        TouchUse::OtherGrasp
                    } else if label.contains("touch") || !refined {
                        TouchUse::Own
                    } else {
                        TouchUse::None
                    };
                    estimators.push(EstimatorResult {
                        label: label.to_string(),
                        run: None,
                        refined,
                        touch,
                        results: vec![r],
                        ms_per_sample: f64::NAN,
                    });
                }
            }
        }
        for o in this_dir.into_keys() {
            objects_seen.insert(o, dir.clone());
        }
        for e in json["estimators"].as_array().into_iter().flatten() {
            let (Some(label), Some(ms), Some(n)) = (e["label"].as_str(), e["ms_per_sample"].as_f64(), e["overall"]["n"].as_u64()) else {
                continue;
            };
            let t = times.entry(label.to_string()).or_default();
            (t.0, t.1) = (t.0 + ms * n as f64, t.1 + n as usize);
        }
    }
    for e in &mut estimators {
        if let Some((total, n)) = times.get(&e.label).filter(|(_, n)| *n > 0) {
            e.ms_per_sample = total / *n as f64;
        }
    }
    Ok(RefineEval {
        dataset: PathBuf::from(dirs.iter().map(|d| d.display().to_string()).collect::<Vec<_>>().join(" + ")),
        split: "test".into(),
        config: config.unwrap_or_default(),
        samples,
        threads,
        wall_s,
        shapes_s,
        estimators,
        positions: BTreeMap::new(),
        max_samples: 0,
    })
}

fn num(v: f64, digits: usize) -> String {
    if v.is_finite() { format!("{v:.digits$}") } else { "–".into() }
}

fn mean_se(m: &MeanSe, digits: usize) -> String {
    if m.n == 0 { "–".into() } else { format!("{} ± {}", num(m.mean, digits), num(m.se, digits)) }
}

/// One table row of `results`: n, position, angles, ADD-S AUC, ADD(-S) < 2 cm.
fn row(label: &str, results: &[&SampleResult]) -> String {
    let s = Summary::of(results.iter().copied());
    let sym_median = median(results.iter().map(|r| r.angle_sym_deg).collect());
    format!(
        "| {label} | {} | {} | {} | {} | {} | {} | {} |",
        s.n,
        mean_se(&s.position_cm, 2),
        num(s.position_median_cm, 2),
        num(s.angle_median_deg, 1),
        num(sym_median, 1),
        num(s.adds_auc, 1),
        num(s.accuracy_2cm, 1)
    )
}

const HEADER: &str = "| estimator | n | position (cm) | position median (cm) | angle median (°) | angle up to symmetry, median (°) | ADD-S AUC | ADD(-S) < 2 cm (%) |\n|---|---|---|---|---|---|---|---|";

fn markdown(eval: &RefineEval, pairs: &[EstimatorPair]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# vtpose refine\n");
    let _ = writeln!(
        s,
        "Dataset {}, split `{}`, {} samples with the object visible. Every estimator on the same samples; position: Euclidean \
         distance (cm); angle: arccos(2⟨q̂,q⟩²−1) (°, the paper's); angle up to symmetry: to the nearest rotation the object's \
         symmetry makes look the same; ADD-S AUC up to 10 cm (%); ADD(-S) < 2 cm: ADD-S for symmetric objects, ADD otherwise.\n",
        eval.dataset.display(),
        eval.split,
        eval.samples
    );
    let _ = writeln!(s, "## Overall\n\n{HEADER}");
    for e in &eval.estimators {
        let _ = writeln!(s, "{}", row(&e.label, &e.results.iter().collect::<Vec<_>>()));
    }
    let _ = writeln!(
        s,
        "\n## Per occlusion level\n\nThe paper's bins of the occlusion level (share of model points the camera does not see).\n"
    );
    for bin in OcclusionBin::ALL {
        let _ = writeln!(s, "### {}\n\n{HEADER}", bin.label());
        for e in &eval.estimators {
            let rs: Vec<&SampleResult> = e.results.iter().filter(|r| OcclusionBin::of_f32(r.occlusion) == Some(bin)).collect();
            let _ = writeln!(s, "{}", row(&e.label, &rs));
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(s, "## Per object\n");
    let objects: Vec<String> =
        eval.estimators.first().map(|e| group(&e.results, |r| Some(r.object.clone())).into_keys().collect()).unwrap_or_default();
    for o in &objects {
        let _ = writeln!(s, "### {o}\n\n{HEADER}");
        for e in &eval.estimators {
            let rs: Vec<&SampleResult> = e.results.iter().filter(|r| &r.object == o).collect();
            let _ = writeln!(s, "{}", row(&e.label, &rs));
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(
        s,
        "## Paired per grasp\n\nSamples of one trajectory share a grasp: each estimator's mean error over the grasp's samples, \
         compared per grasp. `better / worse`: grasps on which the first estimator's mean error is lower / higher; p: two-sided \
         exact sign test (ties dropped); Δ: mean over grasps of first − second (negative: the first is better). A touch \
         estimator against its control (another grasp's touch) says whether it uses touch.\n"
    );
    let _ = writeln!(
        s,
        "| first | second | samples | grasps | position: better / worse | p | Δ position (cm) | angle: better / worse | p | Δ angle (°) |\n|---|---|---|---|---|---|---|---|---|---|"
    );
    for p in pairs {
        let Some(pd) = &p.paired else { continue };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} / {} | {} | {} | {} / {} | {} | {} |",
            p.first,
            p.second,
            p.subset,
            pd.grasps.len(),
            pd.position.better,
            pd.position.worse,
            p_value(pd.position.p_value),
            num(pd.position.mean_difference, 3),
            pd.angle.better,
            pd.angle.worse,
            p_value(pd.angle.p_value),
            num(pd.angle.mean_difference, 2)
        );
    }
    let _ = writeln!(s, "\n## Time\n");
    let _ = writeln!(
        s,
        "The refiner on one core per sample (mean over the samples), and all of them on {} threads in {:.1} s of wall time \
         ({:.1} ms per sample per estimator). The objects' distance fields and surface trees took {:.1} s, once per run.\n",
        eval.threads,
        eval.wall_s,
        1000.0 * eval.wall_s / (eval.samples.max(1) * eval.estimators.iter().filter(|e| e.refined).count().max(1)) as f64,
        eval.shapes_s
    );
    let _ = writeln!(s, "| estimator | ms per sample, one core |\n|---|---|");
    for e in eval.estimators.iter().filter(|e| e.refined) {
        let _ = writeln!(s, "| {} | {} |", e.label, num(e.ms_per_sample, 1));
    }
    s
}

fn p_value(p: f64) -> String {
    if p < 0.001 { format!("{p:.1e}") } else { format!("{p:.3}") }
}

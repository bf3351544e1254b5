//! Evaluation (`vtpose eval`): the trained networks on a split, the paper's metrics per object,
//! per occlusion bin and over a sweep of tactile point counts, and a Markdown report.
//!
//! Per sample the network's most confident estimate is compared with the ground truth:
//! position error (cm), angle error `arccos(2⟨q̂, q⟩² − 1)` (°), ADD and ADD-S (over
//! [`crate::data::EVAL_MODEL_POINTS`] fixed surface points of the object). Summaries give
//! mean ± standard error, the AUC of ADD and ADD-S for thresholds up to 10 cm (YCB-Video), and
//! the share of samples with ADD(-S) (ADD-S for symmetric objects) under 2 cm. Samples whose object
//! has no visible pixel with depth cannot be fed to the network (nor, to the tactile-only network,
//! samples without touch); they are counted, not scored.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use burn::prelude::*;
use glam::DVec3;
use serde::Serialize;

use crate::config::{AugmentConfig, TACTILE_SWEEP, TrainConfig};
use crate::data::{Loaded, Loader, Pass, PrepareOptions, SplitSource, load_models};
use crate::geometry::wxyz_to_quat;
use crate::metrics::{MeanSe, OcclusionBin, add, add_s, angle_error_deg, angle_error_up_to_deg, auc, below, position_error_cm};
use crate::model::{PoseNet, Variant};
use crate::run::{RunDir, slot_table};

/// ADD/ADD-S AUC range (YCB-Video): 10 cm.
pub const AUC_MAX_M: f64 = 0.10;
/// The ADD(-S) accuracy threshold of the tables: 2 cm.
pub const ACCURACY_M: f64 = 0.02;

/// How to evaluate one network.
#[derive(Debug, Clone)]
pub struct EvalOptions {
    pub prep: PrepareOptions,
    pub batch_size: usize,
    /// Where the inputs go (the model's device, without autodiff).
    pub device: Device,
}

impl EvalOptions {
    /// The test split, the config's sampling, no augmentation; `n_tactile` overrides the config's.
    pub fn for_config(cfg: &TrainConfig, slots: &[Option<usize>], n_tactile: Option<usize>) -> Self {
        let mut data = cfg.data.clone();
        if let Some(nt) = n_tactile {
            data.n_tactile = nt;
        }
        EvalOptions {
            // No loss in evaluation: the closest-point choice does not matter.
            prep: PrepareOptions {
                data,
                augment: AugmentConfig::NONE,
                seed: cfg.train.seed,
                split: "test".into(),
                slots: slots.to_vec(),
                closest_point: Vec::new(),
            },
            batch_size: cfg.train.batch_size,
            device: crate::device::cpu(),
        }
    }

    pub fn on(mut self, device: &Device) -> Self {
        self.device = device.clone().without_autodiff();
        self
    }
}

/// The scores of one sample.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SampleResult {
    pub index: u64,
    pub object: String,
    /// The sample's grasp and arm pose (`u32::MAX` when the dataset does not say).
    pub trajectory: u32,
    pub instance: u32,
    pub symmetric: bool,
    pub occlusion: f32,
    pub tactile_points: usize,
    pub position_cm: f64,
    pub angle_deg: f64,
    /// The angle error up to the object's symmetry (not a paper metric).
    pub angle_sym_deg: f64,
    pub add_m: f64,
    pub adds_m: f64,
    pub confidence: f32,
    /// Whether the chosen estimate came from the tactile channel.
    pub tactile_estimate: bool,
}

impl SampleResult {
    /// ADD-S for symmetric objects, ADD otherwise.
    pub fn add_or_adds(&self) -> f64 {
        if self.symmetric { self.adds_m } else { self.add_m }
    }
}

/// Runs `model` over `source` (one pass, no augmentation). Returns the scores, the indices of
/// the samples that were not scored (object not visible; for `tactile_only`, also no touch), and
/// the source (with its cache) for the next evaluation.
pub fn evaluate(model: &PoseNet, source: SplitSource, opts: &EvalOptions) -> Result<(Vec<SampleResult>, Vec<u64>, SplitSource)> {
    let models = source.models.clone();
    let n = source.len();
    let variant = model.variant();
    let n_points = opts.prep.data.n_points;
    let loader = Loader::spawn(
        source,
        vec![Pass { epoch: 0, order: (0..n).collect() }],
        opts.prep.clone(),
        opts.batch_size,
        opts.prep.data.prefetch,
    );
    let mut results = Vec::with_capacity(n);
    let mut skipped = Vec::new();
    while let Some(msg) = loader.recv() {
        match msg? {
            Loaded::Batch { batch, .. } => {
                let best = model.forward(&batch.inputs(&opts.device)).best();
                for (p, est) in batch.samples.iter().zip(best) {
                    if variant == Variant::TactileOnly && p.tactile_count == 0 {
                        skipped.push(p.index); // no estimate without touch
                        continue;
                    }
                    let m = &models[p.object];
                    let (q_hat, t_hat) = (wxyz_to_quat(est.rotation), DVec3::from_array(est.translation.map(f64::from)));
                    results.push(SampleResult {
                        index: p.index,
                        object: m.id.clone(),
                        trajectory: p.trajectory,
                        instance: p.instance,
                        symmetric: m.symmetric(),
                        occlusion: p.occlusion,
                        tactile_points: p.tactile_count,
                        position_cm: position_error_cm(t_hat, p.translation),
                        angle_deg: angle_error_deg(q_hat, p.rotation),
                        angle_sym_deg: angle_error_up_to_deg(q_hat, p.rotation, &m.symmetries),
                        add_m: add(&m.eval_points, q_hat, t_hat, p.rotation, p.translation),
                        adds_m: add_s(&m.eval_points, q_hat, t_hat, p.rotation, p.translation),
                        confidence: est.confidence,
                        tactile_estimate: variant == Variant::TactileOnly || (variant.uses_tactile() && est.index >= n_points),
                    });
                }
            }
            Loaded::EndOfPass { skipped: s, .. } => skipped.extend(s),
        }
    }
    Ok((results, skipped, loader.finish()))
}

/// Summary statistics of a set of samples.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    pub n: usize,
    pub position_cm: MeanSe,
    pub angle_deg: MeanSe,
    pub angle_sym_deg: MeanSe,
    pub add_cm: MeanSe,
    pub adds_cm: MeanSe,
    /// AUC (%) of ADD and ADD-S up to 10 cm.
    pub add_auc: f64,
    pub adds_auc: f64,
    /// Share (%) with ADD(-S) < 2 cm.
    pub accuracy_2cm: f64,
    /// Share (%) of chosen estimates from the tactile channel.
    pub tactile_chosen: f64,
}

impl Summary {
    pub fn of<'a>(results: impl IntoIterator<Item = &'a SampleResult>) -> Summary {
        let r: Vec<&SampleResult> = results.into_iter().collect();
        let col = |f: &dyn Fn(&SampleResult) -> f64| r.iter().map(|s| f(s)).collect::<Vec<f64>>();
        let (add_m, adds_m) = (col(&|s| s.add_m), col(&|s| s.adds_m));
        Summary {
            n: r.len(),
            position_cm: MeanSe::of(&col(&|s| s.position_cm)),
            angle_deg: MeanSe::of(&col(&|s| s.angle_deg)),
            angle_sym_deg: MeanSe::of(&col(&|s| s.angle_sym_deg)),
            add_cm: MeanSe::of(&col(&|s| 100.0 * s.add_m)),
            adds_cm: MeanSe::of(&col(&|s| 100.0 * s.adds_m)),
            add_auc: auc(&add_m, AUC_MAX_M),
            adds_auc: auc(&adds_m, AUC_MAX_M),
            accuracy_2cm: below(&col(&|s| s.add_or_adds()), ACCURACY_M),
            tactile_chosen: if r.is_empty() {
                f64::NAN
            } else {
                100.0 * r.iter().filter(|s| s.tactile_estimate).count() as f64 / r.len() as f64
            },
        }
    }
}

/// One evaluated network.
#[derive(Debug, Clone, Serialize)]
pub struct ModelEval {
    /// The run directory's name.
    pub name: String,
    pub run: PathBuf,
    pub variant: Variant,
    pub dataset: PathBuf,
    pub n_tactile: usize,
    pub results: Vec<SampleResult>,
    /// Samples not scored (object not visible; tactile-only: no touch).
    pub skipped: usize,
    /// `(n_t, scores)` of the tactile-point sweep (tactile variants only).
    pub sweep: Vec<(usize, Vec<SampleResult>)>,
}

/// What `vtpose eval` does besides the runs.
#[derive(Debug, Clone)]
pub struct EvalCommand {
    /// Evaluate on this dataset instead of each run's own.
    pub dataset: Option<PathBuf>,
    pub split: String,
    /// At most this many samples (an even spread; 0: all).
    pub max_samples: usize,
    /// The tactile-point sweep ([`TACTILE_SWEEP`]) for tactile variants.
    pub sweep: bool,
    pub device: Device,
    pub quiet: bool,
}

/// Evaluates every run (see [`EvalCommand`]).
pub fn evaluate_runs(runs: &[PathBuf], cmd: &EvalCommand) -> Result<Vec<ModelEval>> {
    let mut out = Vec::new();
    for run in runs {
        let dir = RunDir(run.clone());
        let (cfg, state, model) = dir.load_model(&cmd.device).with_context(|| format!("run {}", run.display()))?;
        let model = model.valid();
        let dataset = cmd.dataset.clone().unwrap_or_else(|| cfg.dataset.clone());
        let models = load_models(&dataset)?;
        let slots = slot_table(&models, &state.objects);
        let mut source = SplitSource::open(&dataset, &cmd.split, &state.objects, cfg.data.depth, true)?;
        source.spread(cmd.max_samples);
        let mut opts = EvalOptions::for_config(&cfg, &slots, None).on(&cmd.device);
        opts.prep.split = cmd.split.clone();
        let name = run.file_name().map_or_else(|| run.display().to_string(), |n| n.to_string_lossy().into_owned());
        if !cmd.quiet {
            eprintln!(
                "vtpose: evaluating {name} ({}) on {} samples of {} {}",
                state.variant.label(),
                source.len(),
                dataset.display(),
                cmd.split
            );
        }
        let (results, skipped, mut source) = evaluate(&model, source, &opts)?;
        let mut sweep = Vec::new();
        if cmd.sweep && state.variant.uses_tactile() {
            for nt in TACTILE_SWEEP {
                let mut o = opts.clone();
                o.prep.data.n_tactile = nt;
                let (r, _, s) = evaluate(&model, source, &o)?;
                source = s;
                sweep.push((nt, r));
            }
        }
        out.push(ModelEval {
            name,
            run: run.clone(),
            variant: state.variant,
            dataset,
            n_tactile: cfg.data.n_tactile,
            results,
            skipped: skipped.len(),
            sweep,
        });
    }
    Ok(out)
}

/// Writes `report.md`, `results.json` (summaries) and `samples-<run>.csv` (per-sample scores).
pub fn write_report(evals: &[ModelEval], split: &str, device: &str, out: &Path) -> Result<PathBuf> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let report = out.join("report.md");
    std::fs::write(&report, report_markdown(evals, split, device)).with_context(|| format!("cannot write {}", report.display()))?;
    let summaries: Vec<serde_json::Value> = evals
        .iter()
        .map(|e| {
            serde_json::json!({
                "name": e.name, "run": e.run, "variant": e.variant, "dataset": e.dataset, "n_tactile": e.n_tactile,
                "skipped": e.skipped, "overall": Summary::of(&e.results),
                "per_object": group(&e.results, |r| Some(r.object.clone())).into_iter().map(|(k, v)| (k, Summary::of(v))).collect::<BTreeMap<_, _>>(),
                "per_occlusion": group(&e.results, |r| OcclusionBin::of(r.occlusion).map(|b| b.label().to_string())).into_iter().map(|(k, v)| (k, Summary::of(v))).collect::<BTreeMap<_, _>>(),
                "tactile_sweep": e.sweep.iter().map(|(nt, r)| serde_json::json!({"n_tactile": nt, "summary": Summary::of(r)})).collect::<Vec<_>>(),
            })
        })
        .collect();
    let paired: Vec<serde_json::Value> = comparisons(evals)
        .into_iter()
        .filter_map(|(t, v)| {
            crate::compare::paired(&t.results, &v.results).map(|p| {
                serde_json::json!({"tactile": t.name, "vision": v.name, "position": p.position, "angle": p.angle, "grasps": p.grasps,
                    "channel_use": crate::compare::channel_use(&t.results)})
            })
        })
        .collect();
    let all = serde_json::json!({"runs": summaries, "paired": paired});
    std::fs::write(out.join("results.json"), serde_json::to_string_pretty(&all)? + "\n")?;
    crate::plots::write_plots(evals, out)?;
    for e in evals {
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
    }
    Ok(report)
}

fn group<K: Ord>(results: &[SampleResult], key: impl Fn(&SampleResult) -> Option<K>) -> BTreeMap<K, Vec<&SampleResult>> {
    let mut m: BTreeMap<K, Vec<&SampleResult>> = BTreeMap::new();
    for r in results {
        if let Some(k) = key(r) {
            m.entry(k).or_default().push(r);
        }
    }
    m
}

fn pct(v: f64) -> String {
    if v.is_nan() { "–".into() } else { format!("{v:.1}") }
}

/// The Markdown report (see the module docs): the metrics, then the same split per object, per
/// occlusion level, what touch buys, and the tactile-point sweep.
pub fn report_markdown(evals: &[ModelEval], split: &str, device: &str) -> String {
    let mut s = String::new();
    report_header(&mut s, evals, split, device);
    overall_section(&mut s, evals);
    per_object_section(&mut s, evals);
    per_occlusion_section(&mut s, evals);
    touch_section(&mut s, evals);
    tactile_sweep_section(&mut s, evals);
    s
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
            let m = Summary::of(e.results.iter().filter(|r| OcclusionBin::of(r.occlusion) == Some(bin)));
            if m.n > 0 {
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {} | {:.2} | {} | {} |",
                    bin.label(),
                    e.name,
                    m.n,
                    m.position_cm,
                    m.angle_deg,
                    pct(m.adds_auc),
                    pct(m.accuracy_2cm)
                );
            } else {
                let _ = writeln!(s, "| {} | {} | 0 | – | – | – | – |", bin.label(), e.name);
            }
        }
    }
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
                    let _ = writeln!(
                        s,
                        "| {nt} | {} | {} | {} | {:.2} | {} | {} |",
                        e.name,
                        m.n,
                        m.position_cm,
                        m.angle_deg,
                        pct(m.adds_auc),
                        pct(m.accuracy_2cm)
                    );
                }
            }
        }
        for e in evals.iter().filter(|e| !e.variant.uses_tactile()) {
            let m = Summary::of(&e.results);
            let _ = writeln!(
                s,
                "| – | {} (vision only) | {} | {} | {:.2} | {} | {} |",
                e.name,
                m.n,
                m.position_cm,
                m.angle_deg,
                pct(m.adds_auc),
                pct(m.accuracy_2cm)
            );
        }
    }
}

/// The first vision-only evaluation and every tactile one, to compare (see [`crate::compare`]).
pub fn comparisons(evals: &[ModelEval]) -> Vec<(&ModelEval, &ModelEval)> {
    let Some(vision) = evals.iter().find(|e| e.variant == Variant::VisionOnly) else { return Vec::new() };
    evals.iter().filter(|e| e.variant.uses_tactile() && e.variant.uses_color()).map(|t| (t, vision)).collect()
}

/// "What touch buys": the paired per-grasp comparison and how the tactile network answers.
fn touch_section(s: &mut String, evals: &[ModelEval]) {
    let pairs = comparisons(evals);
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
    for (t, v) in &pairs {
        match crate::compare::paired(&t.results, &v.results) {
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
    for (t, _) in &pairs {
        let rows = std::iter::once(("all".to_string(), crate::compare::channel_use(&t.results))).chain(OcclusionBin::ALL.iter().map(|b| {
            (b.label().to_string(), crate::compare::channel_use(t.results.iter().filter(|r| OcclusionBin::of(r.occlusion) == Some(*b))))
        }));
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

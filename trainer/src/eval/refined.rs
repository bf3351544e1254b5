//! What the touch's geometry buys (`vtpose refine`): the geometric refiner ([`crate::refine`])
//! against and on top of the trained networks, on the same held-out samples.
//!
//! The estimators, each scored per sample with the metrics of [`super::metrics`]:
//!
//! - `refine: depth` and `refine: depth + touch`: the refiner from no initial pose (its global
//!   search), with the depth points and free space alone, and with the tactile points too;
//! - per trained run `R`: `R` (the network alone), `R + refine: depth`, `R + refine: depth + touch`
//!   (the refiner's local stage from the network's estimate);
//! - the touch control of every estimator that uses touch: the same samples with the touch of
//!   **another grasp** of the same object ([`super::control::GraspBank`]). "No touch" is the
//!   depth-only estimator beside it. An estimator that uses touch must get worse with the wrong
//!   touch.
//!
//! The comparisons pair the estimators per grasp with the sign test ([`super::compare`]).
//! Deterministic: every sample's refinement depends on that sample alone; samples run in
//! parallel on every core ([`rayon`]), each refinement on one core, timed.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use burn::prelude::*;
use glam::{DQuat, DVec3};
use rayon::prelude::*;
use serde::Serialize;

use super::compare::{Paired, paired};
use super::control::GraspBank;
use super::metrics::{add, add_s, angle_error_deg, angle_error_up_to_deg, position_error_cm};
use super::{EvalCommand, SampleResult, evaluate_runs, run_names};
use crate::data::{DepthSource, ObjectModel, SplitSource, load_models};
use crate::refine::{ObjectShape, Observation, Pose, RefineConfig, Refiner, Start};

/// What `vtpose refine` evaluates.
#[derive(Debug, Clone)]
pub struct RefineCommand {
    pub dataset: PathBuf,
    pub split: String,
    /// At most this many samples, evenly spread (0: all).
    pub max_samples: usize,
    /// Trained runs whose estimates the refiner starts from (none: the refiner alone).
    pub runs: Vec<PathBuf>,
    pub config: RefineConfig,
    /// The touch control (another grasp's touch) for every estimator that uses touch.
    pub touch_control: bool,
    pub device: Device,
    pub quiet: bool,
}

/// Where an estimator's touch comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TouchUse {
    None,
    Own,
    OtherGrasp,
}

/// One estimator's results.
#[derive(Debug, Clone, Serialize)]
pub struct EstimatorResult {
    pub label: String,
    /// The network run it starts from (None: the refiner's global search).
    pub run: Option<String>,
    /// Whether the refiner ran (false: the network alone).
    pub refined: bool,
    pub touch: TouchUse,
    pub results: Vec<SampleResult>,
    /// The refiner's time per sample on one core (ms), mean over the samples; 0 for a network.
    pub ms_per_sample: f64,
}

/// `vtpose refine`'s output: every estimator on the same samples.
#[derive(Debug, Clone, Serialize)]
pub struct RefineEval {
    pub dataset: PathBuf,
    pub split: String,
    pub config: RefineConfig,
    pub samples: usize,
    /// Threads the samples ran on, and the wall time of all the refinements (s).
    pub threads: usize,
    pub wall_s: f64,
    /// Time to build the objects' distance fields and surface trees (s, all cores).
    pub shapes_s: f64,
    pub estimators: Vec<EstimatorResult>,
    /// Each refined sample's position among the split's selected samples (after the spread of
    /// `max_samples`), by split index.
    #[serde(skip)]
    pub positions: BTreeMap<u64, usize>,
    /// The spread the samples were chosen with (0: all).
    pub max_samples: usize,
}

/// Samples decoded at a time: their observations (a depth image and mask each) are dropped after.
const DECODE_CHUNK: usize = 64;

/// A sample as the estimators see it.
struct Item {
    index: u64,
    object: usize,
    trajectory: u32,
    instance: u32,
    occlusion: f32,
    truth: Pose,
    /// Its tactile points (the observation's subset), lent to another grasp by the control.
    touch: Vec<DVec3>,
}

/// One estimator to run per sample.
#[derive(Debug, Clone)]
struct Plan {
    label: String,
    run: Option<usize>,
    touch: TouchUse,
}

/// The scores of `pose` on `item` (the network's fields left neutral).
fn score_sample(item: &Item, model: &ObjectModel, pose: Pose, touch_points: usize) -> SampleResult {
    let (q_hat, t_hat) = pose;
    let (q, t) = item.truth;
    SampleResult {
        index: item.index,
        object: model.id.clone(),
        trajectory: item.trajectory,
        instance: item.instance,
        symmetric: model.symmetric(),
        occlusion: item.occlusion,
        tactile_points: touch_points,
        position_cm: position_error_cm(t_hat, t),
        angle_deg: angle_error_deg(q_hat, q),
        angle_sym_deg: angle_error_up_to_deg(q_hat, q, &model.symmetries),
        add_m: add(&model.eval_points, q_hat, t_hat, q, t),
        adds_m: add_s(&model.eval_points, q_hat, t_hat, q, t),
        confidence: f32::NAN,
        tactile_estimate: false,
        estimate: pose,
    }
}

/// Runs every estimator (see the module docs).
pub fn evaluate_refined(cmd: &RefineCommand) -> Result<RefineEval> {
    let refiner = Refiner::new(cmd.config.clone())?;
    let models = load_models(&cmd.dataset)?;
    let ids: Vec<String> = models.iter().map(|m| m.id.clone()).collect();
    let mut source = SplitSource::open(&cmd.dataset, &cmd.split, &ids, DepthSource::Exact, false)
        .with_context(|| format!("dataset {}", cmd.dataset.display()))?;
    source.spread(cmd.max_samples);
    if source.is_empty() {
        bail!("dataset {}: the {} split has no sample to refine", cmd.dataset.display(), cmd.split);
    }
    // The networks first, on the same spread of samples: their estimates by (object, index).
    let names = run_names(&cmd.runs);
    let mut network: Vec<BTreeMap<(String, u64), SampleResult>> = Vec::new();
    if !cmd.runs.is_empty() {
        let eval = EvalCommand {
            dataset: Some(cmd.dataset.clone()),
            split: cmd.split.clone(),
            max_samples: cmd.max_samples,
            sweep: false,
            touch_control: false,
            device: cmd.device.clone(),
            quiet: cmd.quiet,
        };
        for e in evaluate_runs(&cmd.runs, &eval)? {
            network.push(e.results.into_iter().map(|r| ((r.object.clone(), r.index), r)).collect());
        }
    }
    let started = Instant::now();
    let shapes: Vec<ObjectShape> = models.par_iter().map(ObjectShape::of).collect::<Result<_>>()?;
    let shapes_s = started.elapsed().as_secs_f64();
    if !cmd.quiet {
        eprintln!(
            "vtpose: refining {} samples of {} {} ({} objects' fields in {shapes_s:.1} s)",
            source.len(),
            cmd.dataset.display(),
            cmd.split,
            models.len()
        );
    }
    let mut plans = vec![
        Plan { label: "refine: depth".into(), run: None, touch: TouchUse::None },
        Plan { label: "refine: depth + touch".into(), run: None, touch: TouchUse::Own },
    ];
    if cmd.touch_control {
        plans.push(Plan { label: "refine: depth + other grasp's touch".into(), run: None, touch: TouchUse::OtherGrasp });
    }
    for (r, name) in names.iter().enumerate() {
        plans.push(Plan { label: format!("{name} + refine: depth"), run: Some(r), touch: TouchUse::None });
        plans.push(Plan { label: format!("{name} + refine: depth + touch"), run: Some(r), touch: TouchUse::Own });
        if cmd.touch_control {
            plans.push(Plan { label: format!("{name} + refine: depth + other grasp's touch"), run: Some(r), touch: TouchUse::OtherGrasp });
        }
    }
    // One plan on one sample: the pose, the tactile points it used, the time (s); None when the
    // plan has nothing to start from (no network estimate, no other grasp).
    let run_plan = |plan: &Plan, it: &Item, obs: &Observation, touch: Vec<DVec3>| -> Option<(Pose, usize, f64)> {
        let start = match plan.run {
            None => Start::Search,
            Some(r) => Start::From(vec![network[r].get(&(models[it.object].id.clone(), it.index))?.estimate]),
        };
        let n_touch = touch.len();
        let obs = obs.with_touch(touch);
        let clock = Instant::now();
        let refined = refiner.refine(&shapes[it.object], &obs, &start)?;
        Some((refined.pose, n_touch, clock.elapsed().as_secs_f64()))
    };
    // The samples are decoded a chunk at a time (a full image is megabytes), in a first pass for
    // every plan but the touch control, then again for the control, which needs every sample's
    // touch to lend it to another grasp.
    let controls = plans.iter().any(|p| p.touch == TouchUse::OtherGrasp);
    let progress = progress_bar(source.len() as u64 * (1 + controls as u64), cmd.quiet, "refine");
    let mut items: Vec<Item> = Vec::with_capacity(source.len());
    let mut rows: Vec<Vec<Option<(Pose, usize, f64)>>> = Vec::with_capacity(source.len());
    let mut positions = BTreeMap::new();
    let mut wall_s = 0.0;
    for pass in 0..1 + controls as usize {
        let bank: GraspBank<usize> = {
            let mut b = GraspBank::default();
            for (k, it) in items.iter().enumerate() {
                b.insert(it.object, it.trajectory, it.instance, k);
            }
            b
        };
        let mut k = 0;
        for first in (0..source.len()).step_by(DECODE_CHUNK) {
            let mut chunk: Vec<(Item, Observation)> = Vec::with_capacity(DECODE_CHUNK);
            for i in first..(first + DECODE_CHUNK).min(source.len()) {
                let (s, object) = source.sample(i)?;
                progress.inc(1);
                if !s.mask.iter().zip(&s.depth).any(|(&m, &z)| m == s.info.mask_id && z > 0.0) {
                    continue;
                }
                positions.insert(s.index, i);
                let obs = refiner.observe(&s);
                let item = Item {
                    index: s.index,
                    object,
                    trajectory: s.info.trajectory,
                    instance: s.info.instance,
                    occlusion: s.info.occlusion.map_or(f32::NAN, |o| o.level as f32),
                    truth: (s.t_camera_object.rotation(), s.t_camera_object.translation()),
                    touch: obs.touch.clone(),
                };
                chunk.push((item, obs));
            }
            let started = Instant::now();
            let chunk_rows: Vec<Vec<Option<(Pose, usize, f64)>>> = chunk
                .par_iter()
                .map(|(it, obs)| {
                    plans
                        .iter()
                        .map(|plan| match (pass, plan.touch) {
                            (0, TouchUse::None) => run_plan(plan, it, obs, Vec::new()),
                            (0, TouchUse::Own) => run_plan(plan, it, obs, obs.touch.clone()),
                            (1, TouchUse::OtherGrasp) => {
                                let donor = &items[*bank.other_grasp(it.object, it.trajectory, it.instance)?];
                                run_plan(plan, it, obs, donor.touch.clone())
                            }
                            _ => None,
                        })
                        .collect()
                })
                .collect();
            wall_s += started.elapsed().as_secs_f64();
            for ((it, _), row) in chunk.into_iter().zip(chunk_rows) {
                if pass == 0 {
                    items.push(it);
                    rows.push(row);
                } else {
                    debug_assert_eq!(items[k].index, it.index, "both passes see the samples in one order");
                    for (cell, new) in rows[k].iter_mut().zip(row) {
                        if new.is_some() {
                            *cell = new;
                        }
                    }
                    k += 1;
                }
            }
        }
    }
    progress.finish_and_clear();
    let per_item = rows;
    let mut estimators = Vec::new();
    for (r, name) in names.iter().enumerate() {
        // The network alone, on the samples the refiner saw.
        let results = items.iter().filter_map(|it| network[r].get(&(models[it.object].id.clone(), it.index)).cloned()).collect();
        estimators.push(EstimatorResult {
            label: name.clone(),
            run: Some(name.clone()),
            refined: false,
            touch: TouchUse::Own,
            results,
            ms_per_sample: 0.0,
        });
    }
    for (p, plan) in plans.iter().enumerate() {
        let mut results = Vec::new();
        let mut seconds = Vec::new();
        for (it, row) in items.iter().zip(&per_item) {
            if let Some((pose, n_touch, s)) = row[p] {
                results.push(score_sample(it, &models[it.object], pose, n_touch));
                seconds.push(s);
            }
        }
        let ms = if seconds.is_empty() { f64::NAN } else { 1000.0 * seconds.iter().sum::<f64>() / seconds.len() as f64 };
        estimators.push(EstimatorResult {
            label: plan.label.clone(),
            run: plan.run.map(|r| names[r].clone()),
            refined: true,
            touch: plan.touch,
            results,
            ms_per_sample: ms,
        });
    }
    Ok(RefineEval {
        dataset: cmd.dataset.clone(),
        split: cmd.split.clone(),
        config: cmd.config.clone(),
        samples: items.len(),
        threads: rayon::current_num_threads(),
        wall_s,
        shapes_s,
        estimators,
        positions,
        max_samples: cmd.max_samples,
    })
}

fn progress_bar(n: u64, quiet: bool, what: &str) -> indicatif::ProgressBar {
    if quiet {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(n);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{prefix:>7} [{bar:30}] {pos}/{len} samples ({per_sec}, {eta} left)")
            .expect("a valid template")
            .progress_chars("=> "),
    );
    bar.set_prefix(what.to_string());
    bar
}

/// A comparison of two estimators, paired per grasp: `better` counts the grasps on which the
/// first has the lower mean error.
#[derive(Debug, Clone, Serialize)]
pub struct EstimatorPair {
    pub first: String,
    pub second: String,
    /// Which samples: `all` or an occlusion bin's label.
    pub subset: String,
    pub paired: Option<Paired>,
}

/// The comparisons the experiment asks: touch against depth alone, the refiner against its
/// network, and each touch estimator against its control; over all samples and per occlusion
/// bin.
pub fn comparisons(eval: &RefineEval) -> Vec<EstimatorPair> {
    let find = |label: &str| eval.estimators.iter().find(|e| e.label == label);
    let mut pairs: Vec<(String, String)> = Vec::new();
    let mut add_pair = |a: String, b: String| {
        if find(&a).is_some() && find(&b).is_some() {
            pairs.push((a, b));
        }
    };
    add_pair("refine: depth + touch".into(), "refine: depth".into());
    add_pair("refine: depth + touch".into(), "refine: depth + other grasp's touch".into());
    let runs: Vec<String> = eval.estimators.iter().filter(|e| !e.refined).map(|e| e.label.clone()).collect();
    for r in &runs {
        add_pair(format!("{r} + refine: depth"), r.clone());
        add_pair(format!("{r} + refine: depth + touch"), format!("{r} + refine: depth"));
        add_pair(format!("{r} + refine: depth + touch"), r.clone());
        add_pair(format!("{r} + refine: depth + touch"), format!("{r} + refine: depth + other grasp's touch"));
        add_pair("refine: depth + touch".into(), r.clone());
    }
    let mut out = Vec::new();
    for (a, b) in pairs {
        let (ea, eb) = (find(&a).expect("listed"), find(&b).expect("listed"));
        out.push(EstimatorPair { first: a.clone(), second: b.clone(), subset: "all".into(), paired: paired(&ea.results, &eb.results) });
        for bin in vt_dataset::OcclusionBin::ALL {
            let keep = |r: &&SampleResult| vt_dataset::OcclusionBin::of_f32(r.occlusion) == Some(bin);
            let sa: Vec<SampleResult> = ea.results.iter().filter(keep).cloned().collect();
            let sb: Vec<SampleResult> = eb.results.iter().filter(keep).cloned().collect();
            out.push(EstimatorPair { first: a.clone(), second: b.clone(), subset: bin.label().into(), paired: paired(&sa, &sb) });
        }
    }
    out
}

/// The estimate of `label` for each sample (for the picture sheet): by split index.
pub fn estimates_of(eval: &RefineEval, label: &str) -> BTreeMap<u64, (DQuat, DVec3)> {
    eval.estimators.iter().find(|e| e.label == label).map(|e| e.results.iter().map(|r| (r.index, r.estimate)).collect()).unwrap_or_default()
}

/// `vtpose eval --refine`: per evaluated network, its estimates refined with the depth alone and
/// with touch (the local stage from each estimate), as two more rows of the evaluation, named
/// `<run> + refine: depth` and `<run> + refine: depth + touch`.
pub fn refined_evals(evals: &[super::ModelEval], cmd: &EvalCommand, config: &RefineConfig) -> Result<Vec<super::ModelEval>> {
    let mut out = Vec::new();
    for e in evals {
        let refined = evaluate_refined(&RefineCommand {
            dataset: e.dataset.clone(),
            split: cmd.split.clone(),
            max_samples: cmd.max_samples,
            runs: vec![e.run.clone()],
            config: config.clone(),
            touch_control: false,
            device: cmd.device.clone(),
            quiet: cmd.quiet,
        })?;
        for est in refined.estimators.into_iter().filter(|est| est.run.is_some() && est.refined) {
            let what = if est.touch == TouchUse::Own { "depth + touch" } else { "depth" };
            out.push(super::ModelEval {
                name: format!("{} + refine: {what}", e.name),
                run: e.run.clone(),
                variant: e.variant,
                dataset: e.dataset.clone(),
                n_tactile: e.n_tactile,
                results: est.results,
                skipped: e.skipped,
                sweep: Vec::new(),
                curve: Vec::new(),
                touch_control: None,
            });
        }
    }
    Ok(out)
}

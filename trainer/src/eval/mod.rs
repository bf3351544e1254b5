//! Evaluation (`vtpose eval`): the trained networks on a split, scored with the paper's metrics
//! ([`metrics`]) per sample, summarised ([`Summary`]), and compared pairwise ([`compare`]).
//!
//! Per sample the network's most confident estimate is compared with the ground truth:
//! position error (cm), angle error `arccos(2⟨q̂, q⟩² − 1)` (°), ADD and ADD-S (over
//! [`crate::data::EVAL_MODEL_POINTS`] fixed surface points of the object). Summaries give
//! mean ± standard error, the AUC of ADD and ADD-S for thresholds up to 10 cm (YCB-Video), and
//! the share of samples with ADD(-S) (ADD-S for symmetric objects) under 2 cm. Samples whose object
//! has no visible pixel with depth cannot be fed to the network (nor, to the tactile-only network,
//! samples without touch); they are counted, not scored.

pub mod compare;
pub mod control;
pub mod metrics;
pub mod refined;

use std::path::PathBuf;

use anyhow::{Context, Result};
use burn::prelude::*;
use glam::{DQuat, DVec3};
use serde::Serialize;

use crate::config::TrainConfig;
use crate::data::{AugmentConfig, Batch, Loaded, Loader, Pass, PrepareOptions, SplitSource, TACTILE_SWEEP, load_models};
use crate::geometry::wxyz_to_quat;
use crate::model::{PoseNet, Variant};
use crate::run::{RunDir, slot_table};
use control::{TouchBank, TouchControl, TouchInput};
use metrics::{MeanSe, add, add_s, angle_error_deg, angle_error_up_to_deg, auc, below, position_error_cm};

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
    /// Threads each batch's forward pass is split over (`train.step_threads`, resolved by `on`).
    pub threads: usize,
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
            threads: cfg.train.step_threads,
        }
    }

    /// On `device`; the batch's threads resolved for it ([`crate::device::batch_threads`]).
    pub fn on(mut self, device: &Device) -> Self {
        self.device = device.clone().without_autodiff();
        self.threads = crate::device::batch_threads(self.threads, &self.device);
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
    /// The estimate `T_camera_object` (rotation, translation in m), for a refiner to start from.
    #[serde(skip)]
    pub estimate: (DQuat, DVec3),
}

impl SampleResult {
    /// ADD-S for symmetric objects, ADD otherwise.
    pub fn add_or_adds(&self) -> f64 {
        if self.symmetric { self.adds_m } else { self.add_m }
    }
}

/// The most confident estimate of every sample of `batch`, the batch split over `opts.threads`
/// threads (each a forward pass of its share; burn's CPU kernels parallelise only large tensors).
pub fn best_estimates(model: &PoseNet, batch: &Batch, opts: &EvalOptions) -> Vec<crate::model::Estimate> {
    let parts = batch.split(opts.threads);
    if parts.len() == 1 {
        return model.forward(&batch.inputs(&opts.device)).best();
    }
    std::thread::scope(|scope| {
        let handles: Vec<_> = parts.iter().map(|part| scope.spawn(move || model.forward(&part.inputs(&opts.device)).best())).collect();
        handles.into_iter().flat_map(|h| h.join().expect("an evaluation thread panicked")).collect()
    })
}

/// Runs `model` over `source` (one pass, no augmentation). Returns the scores, the indices of
/// the samples that were not scored (object not visible; for `tactile_only`, also no touch), and
/// the source (with its cache) for the next evaluation.
pub fn evaluate(model: &PoseNet, source: SplitSource, opts: &EvalOptions) -> Result<(Vec<SampleResult>, Vec<u64>, SplitSource)> {
    evaluate_with(model, source, opts, &mut TouchInput::True)
}

/// [`evaluate`] with the tactile input `touch` gives (the touch control, [`control`]); samples
/// it has none for are not scored.
pub fn evaluate_with(
    model: &PoseNet,
    source: SplitSource,
    opts: &EvalOptions,
    touch: &mut TouchInput,
) -> Result<(Vec<SampleResult>, Vec<u64>, SplitSource)> {
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
            Loaded::Batch { mut batch, .. } => {
                let mut unscored = Vec::new();
                for (k, p) in batch.samples.iter_mut().enumerate() {
                    if !touch.apply(p) {
                        unscored.push(k);
                    }
                }
                let best = best_estimates(model, &batch, opts);
                for (k, (p, est)) in batch.samples.iter().zip(best).enumerate() {
                    if unscored.contains(&k) {
                        skipped.push(p.index); // no other grasp of its object to take touch from
                        continue;
                    }
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
                        estimate: (q_hat, t_hat),
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
    /// Medians: the angle's mean is pulled up by the flips a symmetric-looking object invites,
    /// its median says what a typical sample gets.
    pub position_median_cm: f64,
    pub angle_median_deg: f64,
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

/// The median (the mean of the middle two for an even count); NaN when empty.
pub fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    match values.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => values[n / 2],
        n => 0.5 * (values[n / 2 - 1] + values[n / 2]),
    }
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
            position_median_cm: median(col(&|s| s.position_cm)),
            angle_median_deg: median(col(&|s| s.angle_deg)),
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
    /// The run's held-out metrics during training (`train.eval_every`; empty when it did not).
    pub curve: Vec<crate::run::CurvePoint>,
    /// The same samples with another grasp's touch and with none (tactile variants).
    pub touch_control: Option<TouchControl>,
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
    /// The touch control ([`control`]) for tactile variants.
    pub touch_control: bool,
    pub device: Device,
    pub quiet: bool,
}

/// Each run's name in the report and in its file names (`samples-NAME.csv`): its directory's
/// name, or its parent's and its own (`a-run`, `b-run`) where two runs share one, numbered when
/// they share that too, so that no run's rows or files stand for another's.
pub fn run_names(runs: &[PathBuf]) -> Vec<String> {
    let name = |p: &std::path::Path| p.file_name().map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into_owned());
    let own: Vec<String> = runs.iter().map(|r| name(r)).collect();
    let mut names: Vec<String> = runs
        .iter()
        .zip(&own)
        .map(|(run, n)| match run.parent().filter(|_| own.iter().filter(|m| *m == n).count() > 1) {
            Some(parent) => format!("{}-{n}", name(parent)),
            None => n.clone(),
        })
        .collect();
    for i in 0..names.len() {
        if names[..i].contains(&names[i]) {
            names[i] = format!("{}-{}", names[i], i + 1);
        }
    }
    names
}

/// Evaluates every run (see [`EvalCommand`]).
pub fn evaluate_runs(runs: &[PathBuf], cmd: &EvalCommand) -> Result<Vec<ModelEval>> {
    let mut out = Vec::new();
    for (run, name) in runs.iter().zip(run_names(runs)) {
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
        if !cmd.quiet {
            eprintln!(
                "vtpose: evaluating {name} ({}) on {} samples of {} {}",
                state.variant.label(),
                source.len(),
                dataset.display(),
                cmd.split
            );
        }
        let control = cmd.touch_control && state.variant.uses_tactile();
        let mut bank = TouchBank::default();
        let mut touch = if control { TouchInput::Record(&mut bank) } else { TouchInput::True };
        let (results, skipped, mut source) = evaluate_with(&model, source, &opts, &mut touch)?;
        let mut touch_control = None;
        if control {
            let (other_grasp, _, s) = evaluate_with(&model, source, &opts, &mut TouchInput::OtherGrasp(&bank))?;
            let (no_touch, _, s) = evaluate_with(&model, s, &opts, &mut TouchInput::Without)?;
            source = s;
            touch_control = Some(TouchControl { other_grasp, no_touch });
        }
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
            curve: RunDir(run.clone()).learning_curve()?,
            touch_control,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_with_the_same_directory_name_get_distinct_names() {
        let runs: Vec<PathBuf> =
            ["x/allegro/run", "x/gripper/run", "y/tactile_channel", "z/allegro/run"].iter().map(PathBuf::from).collect();
        assert_eq!(run_names(&runs), ["allegro-run", "gripper-run", "tactile_channel", "allegro-run-4"]);
        let runs: Vec<PathBuf> = ["a/tactile_channel", "a/vision_only"].iter().map(PathBuf::from).collect();
        assert_eq!(run_names(&runs), ["tactile_channel", "vision_only"]);
    }
}

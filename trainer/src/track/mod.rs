//! The tracking benchmark (`vtpose track`): per-frame pose networks run over every frame of the
//! test **episodes** of an episode dataset (FORMAT.md, "Episodes"), each episode scored as a
//! tracked sequence ([`metrics`]: ADD-S AUC per sequence, drift, jitter; error and occlusion
//! against time), with, per run:
//!
//! 1. **per frame**: the network's most confident estimate of each frame, alone;
//! 2. **+ filter**: those estimates through the constant-velocity filter ([`filter`]);
//! 3. for tactile networks, the **touch control**: each frame fed the touch of the same frame of
//!    **another episode** of the same object (the next test episode of the object in trajectory
//!    order, wrapping around; [`donors`]), per frame and filtered. A network whose tracking does
//!    not get worse with another episode's touch is not using touch.
//!
//! The networks are the snapshot networks of `vtpose train` (a frame is a sample), trained on the
//! frames of the train episodes of the same kind of dataset. A frame whose object has no visible
//! pixel with depth has no per-frame estimate; it counts as a failure in the AUC and the filter
//! carries its prediction through it.
//!
//! The report ([`report`]) writes `tracking.md`, `tracking.json`, `episodes.csv`, `frames.csv`,
//! `error-time.svg` and `occlusion-time.svg`.

pub mod filter;
pub mod metrics;
pub mod refined;
pub mod report;

use std::collections::{BTreeMap, HashMap};
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use burn::prelude::*;
use glam::DVec3;
use serde::Serialize;

use crate::data::{Loaded, Loader, Pass, Prepared, SplitSource, load_models};
use crate::eval::metrics::{MeanSe, add_s, angle_error_up_to_deg, position_error_cm};
use crate::eval::{AUC_MAX_M, EvalOptions, best_estimates};
use crate::geometry::wxyz_to_quat;
use crate::model::{PoseNet, Variant};
use crate::refine::{RefineConfig, Refiner};
use crate::run::{RunDir, slot_table};
use filter::{FilterConfig, Pose, filter_sequence};
use metrics::{end_minus_start, jitter, sequence_auc, slope};
use refined::{RefineContext, refine_methods};

/// What `vtpose track` does besides the runs.
#[derive(Debug, Clone)]
pub struct TrackOptions {
    /// Track on this dataset instead of each run's own.
    pub dataset: Option<PathBuf>,
    pub split: String,
    /// At most this many episodes, evenly spread over the split (0: all).
    pub max_episodes: usize,
    pub filter: FilterConfig,
    /// The touch control for tactile networks (one more pass).
    pub touch_control: bool,
    /// Track with the geometric refiner too ([`crate::refine`]): alone and from each run's
    /// estimates, warm-started from the previous frame, with depth, with touch, and with another
    /// episode's touch.
    pub refine: Option<RefineConfig>,
    pub device: Device,
    pub quiet: bool,
}

/// Where a method's touch comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TouchSource {
    /// No touch (the refiner with the depth alone).
    None,
    /// The frame's own touch (the vision-only network reads none).
    Own,
    /// The same frame of another episode of the same object ([`donors`]).
    OtherEpisode,
}

/// One frame of a test episode: where it is and its ground truth (for scoring only).
#[derive(Debug, Clone, Serialize)]
pub struct FrameTruth {
    /// The frame's index in the split.
    pub index: u64,
    /// The frame's index in its episode.
    pub frame: u32,
    pub time_s: f64,
    /// The paper's occlusion level (NaN when the dataset has none).
    pub occlusion: f32,
    pub tactile_points: usize,
    /// Whether the object has a visible pixel with depth (else the network gets no input).
    pub visible: bool,
    #[serde(skip)]
    pub truth: Pose,
}

/// One test episode.
#[derive(Debug, Clone, Serialize)]
pub struct EpisodeTruth {
    pub object: String,
    pub trajectory: u32,
    pub frames: Vec<FrameTruth>,
    /// The episode whose touch the touch control feeds it (position in the list; None: its object
    /// has no other test episode).
    pub donor: Option<usize>,
    #[serde(skip)]
    object_index: usize,
    /// The frames' positions among the split's selected samples.
    #[serde(skip)]
    positions: Vec<usize>,
}

/// A frame's scores under one method (None: no pose for the frame).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FrameScore {
    pub adds_m: Option<f64>,
    pub position_cm: Option<f64>,
    /// The angle error up to the object's symmetry (°).
    pub angle_deg: Option<f64>,
    /// Estimate minus truth translation (m), for the jitter.
    #[serde(skip)]
    pub offset: Option<DVec3>,
}

/// An episode's tracking scores under one method ([`metrics`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EpisodeScore {
    /// ADD-S AUC up to 10 cm (%), frames without a pose as failures.
    pub adds_auc: f64,
    /// Mean ADD-S over the frames with a pose (cm).
    pub adds_cm: f64,
    /// Least-squares slope of ADD-S against time (cm/s).
    pub drift_cm_per_s: f64,
    /// Mean ADD-S of the last fifth of the frames minus the first fifth (cm).
    pub end_minus_start_cm: f64,
    /// Mean frame-to-frame change of the translation error (mm).
    pub jitter_mm: f64,
    /// Frames without a pose.
    pub missing: usize,
}

impl EpisodeScore {
    pub fn of(times_s: &[f64], frames: &[FrameScore]) -> Self {
        let adds: Vec<Option<f64>> = frames.iter().map(|f| f.adds_m).collect();
        let adds_cm: Vec<Option<f64>> = adds.iter().map(|e| e.map(|e| 100.0 * e)).collect();
        let present: Vec<f64> = adds_cm.iter().filter_map(|e| *e).collect();
        EpisodeScore {
            adds_auc: sequence_auc(&adds, AUC_MAX_M),
            adds_cm: if present.is_empty() { f64::NAN } else { present.iter().sum::<f64>() / present.len() as f64 },
            drift_cm_per_s: slope(times_s, &adds_cm),
            end_minus_start_cm: end_minus_start(&adds_cm),
            jitter_mm: 1000.0 * jitter(&frames.iter().map(|f| f.offset).collect::<Vec<_>>()),
            missing: frames.iter().filter(|f| f.adds_m.is_none()).count(),
        }
    }
}

/// One method's result on one episode; `frames` empty and `score` None when the method does not
/// apply to it (the touch control of an episode without a donor).
#[derive(Debug, Clone, Serialize)]
pub struct EpisodeResult {
    pub frames: Vec<FrameScore>,
    pub score: Option<EpisodeScore>,
}

/// One tracked method: a run's network, its touch, with or without the filter.
#[derive(Debug, Clone, Serialize)]
pub struct MethodResult {
    /// `<run> per frame`, `<run> + filter`, `<run> (other episode's touch) per frame`,
    /// `<run> + refine (depth + touch)`, `refine (depth)`, … .
    pub label: String,
    /// The run's name; `refiner` for the refiner alone.
    pub run: String,
    /// The run's network (None: the refiner alone).
    pub variant: Option<Variant>,
    pub touch: TouchSource,
    pub filtered: bool,
    /// Whether the geometric refiner made the poses (warm-started from the previous frame).
    pub refined: bool,
    /// Per-frame estimates the filter's gate rejected (filtered methods).
    pub rejected: usize,
    /// Per episode, in the order of [`Tracking::episodes`].
    pub episodes: Vec<EpisodeResult>,
}

/// A method's scores over the episodes it applies to.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MethodSummary {
    pub episodes: usize,
    pub frames: usize,
    pub missing: usize,
    /// Mean ± standard error over episodes.
    pub adds_auc: MeanSe,
    pub adds_cm: MeanSe,
    pub drift_cm_per_s: MeanSe,
    pub end_minus_start_cm: MeanSe,
    pub jitter_mm: MeanSe,
    /// Share (%) of the frames with ADD-S < 2 cm (frames without a pose count as failures).
    pub adds_below_2cm: f64,
}

impl MethodResult {
    pub fn summary(&self) -> MethodSummary {
        let scored: Vec<(&EpisodeResult, &EpisodeScore)> = self.episodes.iter().filter_map(|e| Some((e, e.score.as_ref()?))).collect();
        let col =
            |f: &dyn Fn(&EpisodeScore) -> f64| MeanSe::of(&scored.iter().map(|(_, s)| f(s)).filter(|v| v.is_finite()).collect::<Vec<_>>());
        let frames: Vec<&FrameScore> = scored.iter().flat_map(|(e, _)| &e.frames).collect();
        let below = frames.iter().filter(|f| f.adds_m.is_some_and(|e| e < crate::eval::ACCURACY_M)).count();
        MethodSummary {
            episodes: scored.len(),
            frames: frames.len(),
            missing: frames.iter().filter(|f| f.adds_m.is_none()).count(),
            adds_auc: col(&|s| s.adds_auc),
            adds_cm: col(&|s| s.adds_cm),
            drift_cm_per_s: col(&|s| s.drift_cm_per_s),
            end_minus_start_cm: col(&|s| s.end_minus_start_cm),
            jitter_mm: col(&|s| s.jitter_mm),
            adds_below_2cm: if frames.is_empty() { f64::NAN } else { 100.0 * below as f64 / frames.len() as f64 },
        }
    }
}

/// The benchmark: the test episodes and every method's results on them.
#[derive(Debug, Clone, Serialize)]
pub struct Tracking {
    pub dataset: PathBuf,
    pub split: String,
    pub filter: FilterConfig,
    pub episodes: Vec<EpisodeTruth>,
    pub methods: Vec<MethodResult>,
}

/// Per episode, the episode whose touch the touch control lends it: the next episode of the same
/// object in the list (episodes are listed by object, trajectories ascending), wrapping around
/// to the object's first; None when the object has only one. `episodes[i]` is (object,
/// trajectory).
pub fn donors(episodes: &[(usize, u32)]) -> Vec<Option<usize>> {
    let mut by_object: BTreeMap<usize, Vec<(u32, usize)>> = BTreeMap::new();
    for (i, &(object, trajectory)) in episodes.iter().enumerate() {
        by_object.entry(object).or_default().push((trajectory, i));
    }
    by_object.values_mut().for_each(|v| v.sort());
    episodes
        .iter()
        .map(|&(object, trajectory)| {
            let same = &by_object[&object];
            if same.len() < 2 {
                return None;
            }
            let at = same.iter().position(|&(t, _)| t == trajectory).expect("listed");
            Some(same[(at + 1) % same.len()].1)
        })
        .collect()
}

/// A prepared frame's tactile input: its `(n_t, 3)` points and how many are real.
type Touch = (Vec<f32>, usize);

/// Something recorded per frame of a pass, by (episode, frame), for the touch control.
#[derive(Debug)]
struct FrameBank<T>(BTreeMap<(usize, u32), T>);

impl<T> Default for FrameBank<T> {
    fn default() -> Self {
        FrameBank(BTreeMap::new())
    }
}

/// The touch of every frame of a pass.
type TouchBank = FrameBank<Touch>;

impl<T> FrameBank<T> {
    /// The value of frame `frame` of `episode`, or of its nearest recorded frame (the earlier of
    /// two as near): a frame without a visible object was never prepared.
    fn at(&self, episode: usize, frame: u32) -> Option<&T> {
        let after = self.0.range((episode, frame)..=(episode, u32::MAX)).next();
        let before = self.0.range((episode, 0)..(episode, frame)).next_back();
        match (before, after) {
            (Some(b), Some(a)) => Some(if frame - b.0.1 <= a.0.1 - frame { b.1 } else { a.1 }),
            (b, a) => b.or(a).map(|(_, t)| t),
        }
    }
}

/// The tactile input a pass gives each frame.
enum PassTouch<'a> {
    /// The frame's own, kept in the bank.
    Own(&'a mut TouchBank),
    /// The donor episode's, from the bank of an [`PassTouch::Own`] pass.
    Donor(&'a TouchBank),
}

/// The most confident estimate of every visible frame of `order`, by split index; frames that
/// got no input (a donor-less episode's in the touch control)
/// have none.
fn estimate_frames(
    model: &PoseNet,
    source: SplitSource,
    order: Vec<usize>,
    opts: &EvalOptions,
    episode_of: &HashMap<(usize, u32), usize>,
    episodes: &[EpisodeTruth],
    touch: &mut PassTouch,
) -> Result<(HashMap<u64, Pose>, SplitSource)> {
    let variant = model.variant();
    let loader = Loader::spawn(source, vec![Pass { epoch: 0, order }], opts.prep.clone(), opts.batch_size, opts.prep.data.prefetch);
    let mut poses = HashMap::new();
    while let Some(msg) = loader.recv() {
        let Loaded::Batch { mut batch, .. } = msg? else { continue };
        let mut fed = Vec::with_capacity(batch.len());
        for p in batch.samples.iter_mut() {
            let episode = episode_of[&(p.object, p.trajectory)];
            fed.push(match touch {
                PassTouch::Own(bank) => {
                    bank.0.insert((episode, p.instance), (p.tactile.clone(), p.tactile_count));
                    true
                }
                PassTouch::Donor(bank) => give_donor_touch(p, episodes[episode].donor, bank),
            });
        }
        for ((p, est), fed) in batch.samples.iter().zip(best_estimates(model, &batch, opts)).zip(fed) {
            if !fed || (variant == Variant::TactileOnly && p.tactile_count == 0) {
                continue;
            }
            poses.insert(p.index, (wxyz_to_quat(est.rotation), DVec3::from_array(est.translation.map(f64::from))));
        }
    }
    Ok((poses, loader.finish()))
}

/// Replaces `p`'s touch with its donor episode's at the same frame; false when there is none.
fn give_donor_touch(p: &mut Prepared, donor: Option<usize>, bank: &TouchBank) -> bool {
    match donor.and_then(|d| bank.at(d, p.instance)) {
        Some((points, count)) => {
            (p.tactile, p.tactile_count) = (points.clone(), *count);
            true
        }
        None => false,
    }
}

/// The frames of `source`'s episodes (at most `max` episodes, evenly spread) with their truth.
fn episode_truths(source: &mut SplitSource, max: usize) -> Result<(Vec<EpisodeTruth>, Vec<usize>)> {
    let mut listed = source.episodes()?;
    if max > 0 && listed.len() > max {
        let n = listed.len();
        listed = (0..max).map(|i| listed[i * n / max].clone()).collect();
    }
    let mut episodes = Vec::with_capacity(listed.len());
    let mut order = Vec::new();
    for e in &listed {
        let mut frames = Vec::with_capacity(e.frames.len());
        for &pos in &e.frames {
            let v = source.view(pos)?;
            frames.push(FrameTruth {
                index: v.index,
                frame: v.instance,
                time_s: v.time_s,
                occlusion: v.occlusion,
                tactile_points: v.tactile.len(),
                visible: v.visible(),
                truth: (v.rotation, v.translation),
            });
        }
        if let Some(bad) = frames.iter().find(|f| !f.time_s.is_finite()) {
            bail!("{}: frame {} has no episode time (/sample/info episode.time_s)", e.path.display(), bad.index);
        }
        order.extend(&e.frames);
        let object = source.models[e.object].id.clone();
        episodes.push(EpisodeTruth {
            object,
            trajectory: e.record.trajectory,
            frames,
            donor: None,
            object_index: e.object,
            positions: e.frames.clone(),
        });
    }
    let keys: Vec<(usize, u32)> = episodes.iter().map(|e| (e.object_index, e.trajectory)).collect();
    for (e, d) in episodes.iter_mut().zip(donors(&keys)) {
        e.donor = d;
    }
    Ok((episodes, order))
}

/// Scores `poses` (per episode, per frame) against the truth.
fn score(episodes: &[EpisodeTruth], models: &[crate::data::ObjectModel], poses: &[Vec<Option<Pose>>]) -> Vec<EpisodeResult> {
    episodes
        .iter()
        .zip(poses)
        .map(|(e, poses)| {
            let m = &models[e.object_index];
            let frames: Vec<FrameScore> = e
                .frames
                .iter()
                .zip(poses)
                .map(|(f, pose)| match pose {
                    None => FrameScore { adds_m: None, position_cm: None, angle_deg: None, offset: None },
                    Some((q_hat, t_hat)) => {
                        let (q, t) = f.truth;
                        FrameScore {
                            adds_m: Some(add_s(&m.eval_points, *q_hat, *t_hat, q, t)),
                            position_cm: Some(position_error_cm(*t_hat, t)),
                            angle_deg: Some(angle_error_up_to_deg(*q_hat, q, &m.symmetries)),
                            offset: Some(*t_hat - t),
                        }
                    }
                })
                .collect();
            let times: Vec<f64> = e.frames.iter().map(|f| f.time_s).collect();
            let score = EpisodeScore::of(&times, &frames);
            EpisodeResult { frames, score: Some(score) }
        })
        .collect()
}

/// The per-frame and filtered methods of one pass's estimates. The touch control scores only the
/// episodes with a donor.
fn methods_of(
    run: &str,
    variant: Variant,
    touch: TouchSource,
    episodes: &[EpisodeTruth],
    models: &[crate::data::ObjectModel],
    estimates: &HashMap<u64, Pose>,
    filter: &FilterConfig,
) -> [MethodResult; 2] {
    let applies = |e: &EpisodeTruth| touch == TouchSource::Own || e.donor.is_some();
    let raw: Vec<Vec<Option<Pose>>> =
        episodes.iter().map(|e| e.frames.iter().map(|f| estimates.get(&f.index).copied()).collect()).collect();
    let mut rejected = 0;
    let filtered: Vec<Vec<Option<Pose>>> = episodes
        .iter()
        .zip(&raw)
        .map(|(e, raw)| {
            let times: Vec<f64> = e.frames.iter().map(|f| f.time_s).collect();
            let (out, r) = filter_sequence(filter, &times, raw);
            rejected += if applies(e) { r } else { 0 };
            out
        })
        .collect();
    let base = match touch {
        TouchSource::None | TouchSource::Own => run.to_string(),
        TouchSource::OtherEpisode => format!("{run} (other episode's touch)"),
    };
    let make = |poses: &[Vec<Option<Pose>>], filtered: bool, rejected: usize| {
        let mut results = score(episodes, models, poses);
        for (r, e) in results.iter_mut().zip(episodes) {
            if !applies(e) {
                *r = EpisodeResult { frames: Vec::new(), score: None };
            }
        }
        MethodResult {
            label: format!("{base}{}", if filtered { " + filter" } else { " per frame" }),
            run: run.to_string(),
            variant: Some(variant),
            touch,
            filtered,
            refined: false,
            rejected,
            episodes: results,
        }
    };
    [make(&raw, false, 0), make(&filtered, true, rejected)]
}

/// Tracks every run over the test episodes (see the module docs), and with the refiner when
/// `opts.refine` asks (from each run's estimates and alone; with no run, the refiner alone on
/// `opts.dataset`). The runs must see the same episodes (the same dataset and objects).
pub fn track_runs(runs: &[PathBuf], names: &[String], opts: &TrackOptions) -> Result<Tracking> {
    opts.filter.validate()?;
    let refiner = opts.refine.clone().map(Refiner::new).transpose()?;
    let mut tracking: Option<Tracking> = None;
    let mut context: Option<(RefineContext, Vec<crate::data::ObjectModel>)> = None;
    for (run, name) in runs.iter().zip(names) {
        let dir = RunDir(run.clone());
        if !dir.model().is_file() {
            bail!("run {}: no trained network ({} is missing; train it with `vtpose train`)", run.display(), dir.model().display());
        }
        let (cfg, state, model) = dir.load_model(&opts.device).with_context(|| format!("run {}", run.display()))?;
        let model = model.valid();
        let dataset = opts.dataset.clone().unwrap_or_else(|| cfg.dataset.clone());
        let models = load_models(&dataset)?;
        let slots = slot_table(&models, &state.objects);
        let mut source = SplitSource::open(&dataset, &opts.split, &state.objects, cfg.data.depth, true)
            .with_context(|| format!("run {}: dataset {}", run.display(), dataset.display()))?;
        let (episodes, order) = episode_truths(&mut source, opts.max_episodes)?;
        if episodes.is_empty() {
            bail!(
                "dataset {}: the {} split has no episodes of the run's objects ({}): nothing to track",
                dataset.display(),
                opts.split,
                state.objects.join(", ")
            );
        }
        let mut eval = EvalOptions::for_config(&cfg, &slots, None).on(&opts.device);
        eval.prep.split = opts.split.clone();
        if !opts.quiet {
            let frames: usize = episodes.iter().map(|e| e.frames.len()).sum();
            eprintln!(
                "vtpose: tracking with {name} ({}) over {} episodes ({frames} frames) of {} {}",
                state.variant.label(),
                episodes.len(),
                dataset.display(),
                opts.split
            );
        }
        let episode_of: HashMap<(usize, u32), usize> =
            episodes.iter().enumerate().map(|(i, e)| ((e.object_index, e.trajectory), i)).collect();
        let mut bank = TouchBank::default();
        let (own, mut source) =
            estimate_frames(&model, source, order.clone(), &eval, &episode_of, &episodes, &mut PassTouch::Own(&mut bank))?;
        let mut methods = methods_of(name, state.variant, TouchSource::Own, &episodes, &models, &own, &opts.filter).to_vec();
        if let Some(refiner) = &refiner
            && context.is_none()
        {
            context = Some((RefineContext::new(refiner.clone(), &mut source, &episodes, &models)?, models.clone()));
        }
        if opts.touch_control && state.variant.uses_tactile() {
            let (other, _) = estimate_frames(&model, source, order, &eval, &episode_of, &episodes, &mut PassTouch::Donor(&bank))?;
            methods.extend(methods_of(name, state.variant, TouchSource::OtherEpisode, &episodes, &models, &other, &opts.filter));
        }
        match tracking.as_mut() {
            None => {
                tracking = Some(Tracking { dataset, split: opts.split.clone(), filter: opts.filter, episodes, methods });
            }
            Some(t) => {
                let key = |es: &[EpisodeTruth]| es.iter().map(|e| (e.object.clone(), e.trajectory, e.frames.len())).collect::<Vec<_>>();
                if key(&t.episodes) != key(&episodes) {
                    bail!(
                        "run {} sees other test episodes than {} (another dataset or other objects): track them separately",
                        run.display(),
                        runs[0].display()
                    );
                }
                t.methods.extend(methods);
            }
        }
        if let (Some((ctx, models)), Some(t)) = (&context, tracking.as_mut()) {
            if !opts.quiet {
                eprintln!("vtpose: refining {name}'s estimates, warm-started from frame to frame");
            }
            let refined = refine_methods(ctx, name, Some(state.variant), Some(&own), &t.episodes, models);
            t.methods.extend(refined);
        }
    }
    let Some(refiner) = refiner else { return tracking.context("no run to track") };
    if tracking.is_none() {
        let dataset = opts.dataset.clone().context("tracking with the refiner alone needs --dataset (no run names one)")?;
        let models = load_models(&dataset)?;
        let ids: Vec<String> = models.iter().map(|m| m.id.clone()).collect();
        let mut source = SplitSource::open(&dataset, &opts.split, &ids, crate::data::DepthSource::Exact, true)
            .with_context(|| format!("dataset {}", dataset.display()))?;
        let (episodes, _) = episode_truths(&mut source, opts.max_episodes)?;
        if episodes.is_empty() {
            bail!("dataset {}: the {} split has no episodes: nothing to track", dataset.display(), opts.split);
        }
        context = Some((RefineContext::new(refiner, &mut source, &episodes, &models)?, models));
        tracking = Some(Tracking { dataset, split: opts.split.clone(), filter: opts.filter, episodes, methods: Vec::new() });
    }
    let (Some((ctx, models)), Some(t)) = (&context, tracking.as_mut()) else { unreachable!("set above") };
    if !opts.quiet {
        eprintln!("vtpose: tracking with the refiner alone over {} episodes", t.episodes.len());
    }
    let alone = refine_methods(ctx, "refiner", None, None, &t.episodes, models);
    t.methods.extend(alone);
    tracking.context("no run to track")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_episode_borrows_the_touch_of_the_next_episode_of_its_object() {
        // Object 0: trajectories 1, 4, 9; object 1: trajectory 2 alone; object 2: 0 and 5.
        let episodes = [(0, 1), (0, 4), (0, 9), (1, 2), (2, 0), (2, 5)];
        assert_eq!(donors(&episodes), [Some(1), Some(2), Some(0), None, Some(5), Some(4)]);
        // No episode lends to itself, each donor has the same object.
        for (i, d) in donors(&episodes).into_iter().enumerate() {
            if let Some(d) = d {
                assert_ne!(d, i);
                assert_eq!(episodes[d].0, episodes[i].0);
            }
        }
    }

    #[test]
    fn the_donor_frame_is_the_same_frame_or_the_nearest_recorded() {
        let mut bank = TouchBank::default();
        for frame in [0, 1, 2, 5, 9] {
            bank.0.insert((3, frame), (vec![frame as f32; 3], 1));
        }
        bank.0.insert((4, 7), (vec![70.0; 3], 1));
        let at = |e, f| bank.at(e, f).map(|t| t.0[0]);
        assert_eq!(at(3, 2), Some(2.0));
        assert_eq!(at(3, 3), Some(2.0)); // 2 and 5: 2 is nearer
        assert_eq!(at(3, 4), Some(5.0));
        assert_eq!(at(3, 7), Some(5.0)); // 5 and 9 as near: the earlier
        assert_eq!(at(3, 30), Some(9.0));
        assert_eq!(at(4, 0), Some(70.0)); // another episode's frames are never taken
        assert_eq!(at(5, 0), None);
        // The control replaces the frame's touch, or reports that there is none to give.
        let mut p = Prepared { instance: 1, tactile: vec![-1.0; 3], tactile_count: 1, ..Prepared::default() };
        assert!(give_donor_touch(&mut p, Some(3), &bank));
        assert_eq!(p.tactile, [1.0; 3]);
        assert!(!give_donor_touch(&mut p, None, &bank));
    }

    #[test]
    fn an_episode_score_is_computed_from_its_frames() {
        let frame = |cm: f64| FrameScore {
            adds_m: Some(cm / 100.0),
            position_cm: Some(cm),
            angle_deg: Some(0.0),
            offset: Some(DVec3::X * cm / 100.0),
        };
        let times = [0.0, 0.1, 0.2, 0.3, 0.4];
        let frames =
            [frame(1.0), frame(2.0), frame(3.0), frame(4.0), FrameScore { adds_m: None, position_cm: None, angle_deg: None, offset: None }];
        let s = EpisodeScore::of(&times, &frames);
        // AUC: (0.9 + 0.8 + 0.7 + 0.6 + 0) / 5.
        assert!((s.adds_auc - 60.0).abs() < 1e-9, "{}", s.adds_auc);
        assert!((s.adds_cm - 2.5).abs() < 1e-9);
        assert!((s.drift_cm_per_s - 10.0).abs() < 1e-9);
        assert!((s.end_minus_start_cm - 3.0).abs() < 1e-9);
        assert!((s.jitter_mm - 10.0).abs() < 1e-9);
        assert_eq!(s.missing, 1);
    }
}

//! Tracking with the geometric refiner ([`crate::refine`]): each frame's pose refined from the
//! previous frame's (and from the network's estimate of the frame, when a run is given), the
//! best-scoring kept; the first frame, and a frame whose warm-started fit is poor (the track was
//! lost), start from the refiner's global search. Causal: frame `k` uses frames `0..=k` only.
//!
//! Three methods per starting point: the depth alone, with the frame's touch, and with the touch
//! of the same frame of another episode of the same object (the touch control).

use std::collections::HashMap;

use anyhow::Result;
use rayon::prelude::*;

use super::filter::Pose;
use super::{EpisodeResult, EpisodeTruth, FrameBank, MethodResult, TouchSource, score};
use crate::data::{ObjectModel, SplitSource};
use crate::model::Variant;
use crate::refine::{ObjectShape, Observation, Refiner, Start};

/// What every refined method needs: the refiner, the objects' shapes and each frame's
/// observation (None: the object is neither seen nor touched).
pub struct RefineContext {
    pub refiner: Refiner,
    pub shapes: Vec<ObjectShape>,
    pub observations: Vec<Vec<Option<Observation>>>,
}

impl RefineContext {
    /// Decodes every frame of `episodes` once and builds the objects' shapes.
    pub fn new(refiner: Refiner, source: &mut SplitSource, episodes: &[EpisodeTruth], models: &[ObjectModel]) -> Result<Self> {
        let shapes = models.par_iter().map(ObjectShape::of).collect::<Result<Vec<_>>>()?;
        let mut observations = Vec::with_capacity(episodes.len());
        for e in episodes {
            let mut frames = Vec::with_capacity(e.positions.len());
            for &pos in &e.positions {
                let (sample, _) = source.sample(pos)?;
                let obs = refiner.observe(&sample);
                frames.push((!obs.depth.is_empty() || !obs.touch.is_empty()).then_some(obs));
            }
            observations.push(frames);
        }
        Ok(RefineContext { refiner, shapes, observations })
    }
}

/// One episode tracked by the refiner: `network` gives the frame's extra starting pose.
fn track_episode(ctx: &RefineContext, shape: &ObjectShape, frames: &[Option<Observation>], network: &[Option<Pose>]) -> Vec<Option<Pose>> {
    let lost = ctx.refiner.config.lost_rms_m.powi(2);
    let mut previous: Option<Pose> = None;
    frames
        .iter()
        .zip(network)
        .map(|(obs, net)| {
            let obs = obs.as_ref()?;
            let seeds: Vec<Pose> = previous.iter().chain(net.iter()).copied().collect();
            let warm = if seeds.is_empty() { None } else { ctx.refiner.refine(shape, obs, &Start::From(seeds)) };
            let best = match warm {
                Some(w) if w.score <= lost => Some(w),
                w => {
                    let searched = ctx.refiner.refine(shape, obs, &Start::Search);
                    match (w, searched) {
                        (Some(a), Some(b)) => Some(if b.score < a.score { b } else { a }),
                        (a, b) => a.or(b),
                    }
                }
            };
            previous = best.map(|b| b.pose).or(previous);
            best.map(|b| b.pose)
        })
        .collect()
}

/// The refined methods of one starting point (`run`: a run's name, or `refiner` alone with
/// `network` None): depth, depth + touch and, where an episode has a donor, depth + the donor
/// episode's touch.
pub fn refine_methods(
    ctx: &RefineContext,
    run: &str,
    variant: Option<Variant>,
    network: Option<&HashMap<u64, Pose>>,
    episodes: &[EpisodeTruth],
    models: &[ObjectModel],
) -> Vec<MethodResult> {
    // The donors' touch, by (episode, frame).
    let mut bank: FrameBank<Vec<glam::DVec3>> = FrameBank::default();
    for (e, (truth, frames)) in episodes.iter().zip(&ctx.observations).enumerate() {
        for (f, obs) in truth.frames.iter().zip(frames) {
            if let Some(obs) = obs {
                bank.0.insert((e, f.frame), obs.touch.clone());
            }
        }
    }
    let prefix = if network.is_some() { format!("{run} + refine") } else { "refine".to_string() };
    [TouchSource::None, TouchSource::Own, TouchSource::OtherEpisode]
        .into_iter()
        .map(|touch| {
            let poses: Vec<Option<Vec<Option<Pose>>>> = episodes
                .par_iter()
                .enumerate()
                .map(|(k, e)| {
                    let frames: Vec<Option<Observation>> = ctx.observations[k]
                        .iter()
                        .zip(&e.frames)
                        .map(|(obs, f)| {
                            let obs = obs.as_ref()?;
                            Some(match touch {
                                TouchSource::None => obs.with_touch(Vec::new()),
                                TouchSource::Own => obs.clone(),
                                TouchSource::OtherEpisode => obs.with_touch(bank.at(e.donor?, f.frame)?.clone()),
                            })
                        })
                        .collect();
                    if touch == TouchSource::OtherEpisode && e.donor.is_none() {
                        return None;
                    }
                    let net: Vec<Option<Pose>> = e.frames.iter().map(|f| network.and_then(|n| n.get(&f.index).copied())).collect();
                    Some(track_episode(ctx, &ctx.shapes[e.object_index], &frames, &net))
                })
                .collect();
            let filled: Vec<Vec<Option<Pose>>> =
                poses.iter().zip(episodes).map(|(p, e)| p.clone().unwrap_or_else(|| vec![None; e.frames.len()])).collect();
            let mut results = score(episodes, models, &filled);
            for (r, p) in results.iter_mut().zip(&poses) {
                if p.is_none() {
                    *r = EpisodeResult { frames: Vec::new(), score: None };
                }
            }
            let what = match touch {
                TouchSource::None => "depth",
                TouchSource::Own => "depth + touch",
                TouchSource::OtherEpisode => "depth + other episode's touch",
            };
            MethodResult {
                label: format!("{prefix} ({what})"),
                run: run.to_string(),
                variant,
                touch,
                filtered: false,
                refined: true,
                rejected: 0,
                episodes: results,
            }
        })
        .collect()
}

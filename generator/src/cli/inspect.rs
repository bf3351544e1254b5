//! `vtgen inspect`: what a dataset holds, from its manifest and the samples' `/sample/info`
//! (no image is decoded): counts per split and object, shards and bytes, the occlusion
//! histogram, tactile points per sample, contacts per touch link, grasp figures, randomized share.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, Result};
use serde::Serialize;
use vt_dataset::{DatasetReader, Manifest, OcclusionBin};

#[derive(Debug, Clone, Serialize)]
pub struct Inspection {
    pub complete: bool,
    pub shards: usize,
    pub shards_complete: usize,
    pub bytes: u64,
    /// Samples per split and object.
    pub samples: BTreeMap<String, BTreeMap<String, u64>>,
    /// Samples per split and occlusion bin (`OcclusionBin::key`): touch matters most in the heavy
    /// bin, so its share in the test split says how much a test can show.
    pub occlusion: BTreeMap<String, BTreeMap<String, u64>>,
    pub randomized_share: f64,
    /// Tactile points per sample (robot datasets): min, median, max.
    pub tactile_points: Option<[u64; 3]>,
    /// Share of samples in which each touch link touches the object.
    pub contact_share: BTreeMap<String, f64>,
    pub grasp: Option<vt_dataset::GraspStats>,
    /// Episode datasets: the complete episodes' shard metadata (`episode`), in shard order.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub episodes: Vec<vt_dataset::EpisodeRecord>,
    /// Episode datasets: per episode (split, object, trajectory), the object's rotation in the
    /// palm's frame from its settled grasp (degrees): at its last frame and the largest.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub in_hand_rotation_deg: Vec<InHandRotation>,
}

/// How far an episode's object turned in the hand, from the palm's and the object's poses of its
/// camera frames (`/sample/info` `robot.T_world_palm`, `T_world_camera · T_camera_object`).
#[derive(Debug, Clone, Serialize)]
pub struct InHandRotation {
    pub split: String,
    pub object_id: String,
    pub trajectory: u64,
    pub last_deg: f64,
    pub largest_deg: f64,
}

fn median(mut v: Vec<u64>) -> Option<[u64; 3]> {
    if v.is_empty() {
        return None;
    }
    v.sort_unstable();
    Some([v[0], v[v.len() / 2], v[v.len() - 1]])
}

pub fn inspect(root: &Path) -> Result<Inspection> {
    let manifest: Manifest = Manifest::load(&root.join(vt_dataset::MANIFEST_FILE))?;
    let ds = DatasetReader::open(root)?;
    let entries: Vec<_> = manifest.splits.values().flat_map(|s| &s.shards).collect();
    let mut samples: BTreeMap<String, BTreeMap<String, u64>> = BTreeMap::new();
    let mut occlusion: BTreeMap<String, BTreeMap<String, u64>> = BTreeMap::new();
    let (mut n, mut randomized) = (0u64, 0u64);
    let mut tactile = Vec::new();
    let mut contacts: BTreeMap<String, u64> = BTreeMap::new();
    for split in manifest.splits.keys() {
        occlusion.insert(split.clone(), OcclusionBin::ALL.iter().map(|b| (b.key().to_string(), 0)).collect());
    }
    // Per episode: the object's orientation in the palm at its settled grasp (its first frame
    // unless the grasp is recorded), and the rotations since.
    let mut rotation: BTreeMap<(String, String, u64), (glam::DQuat, f64, f64)> = BTreeMap::new();
    super::for_each_info(&ds, |split, info| {
        if let (Some(episode), Some(robot)) = (info.episode, &info.robot)
            && episode.settled_s.is_none_or(|settled| episode.time_s >= settled - 1e-9)
        {
            let object = info.t_world_camera.rotation() * info.t_camera_object.rotation();
            let in_palm = robot.t_world_palm.rotation().inverse() * object;
            let entry = rotation.entry((split.to_string(), info.object_id.clone(), info.trajectory as u64)).or_insert((in_palm, 0.0, 0.0));
            let turned = (in_palm * entry.0.inverse()).normalize().angle_between(glam::DQuat::IDENTITY).to_degrees();
            entry.1 = turned;
            entry.2 = entry.2.max(turned);
        }
        n += 1;
        *samples.entry(split.to_string()).or_default().entry(info.object_id.clone()).or_default() += 1;
        randomized += info.randomized as u64;
        if let Some(bin) = info.occlusion.and_then(|o| OcclusionBin::of(o.level)) {
            *occlusion.entry(split.to_string()).or_default().entry(bin.key().to_string()).or_default() += 1;
        }
        tactile.extend(info.tactile_points());
        for p in info.links_in_contact() {
            *contacts.entry(p.clone()).or_default() += 1;
        }
        Ok(())
    })?;
    let mut episodes = Vec::new();
    for split in manifest.splits.keys() {
        for shard in ds.shards(split)? {
            if let Some(e) = shard.meta().extra.get(vt_dataset::EPISODE_METADATA_KEY) {
                episodes.push(
                    serde_json::from_str(e).with_context(|| format!("{}: {}", shard.path().display(), vt_dataset::EPISODE_METADATA_KEY))?,
                );
            }
        }
    }
    let in_hand_rotation_deg = rotation
        .into_iter()
        .map(|((split, object_id, trajectory), (_, last_deg, largest_deg))| InHandRotation {
            split,
            object_id,
            trajectory,
            last_deg,
            largest_deg,
        })
        .collect();
    Ok(Inspection {
        episodes,
        in_hand_rotation_deg,
        complete: manifest.complete,
        shards: entries.len(),
        shards_complete: entries.iter().filter(|e| e.sha256.is_some()).count(),
        bytes: entries.iter().filter_map(|e| e.bytes).sum(),
        samples,
        occlusion,
        randomized_share: randomized as f64 / n.max(1) as f64,
        tactile_points: median(tactile),
        contact_share: contacts.into_iter().map(|(k, v)| (k, v as f64 / n.max(1) as f64)).collect(),
        grasp: manifest.grasp.clone(),
    })
}

impl Inspection {
    /// The summary as `vtgen inspect` prints it (`dataset` is the directory inspected).
    pub fn text(&self, dataset: &Path) -> String {
        let r = self;
        let mut out = vec![format!(
            "dataset     {} ({}; {}/{} shards, {})",
            dataset.display(),
            if r.complete { "complete" } else { "incomplete" },
            r.shards_complete,
            r.shards,
            super::human_bytes(r.bytes as f64)
        )];
        for (split, objects) in &r.samples {
            let total: u64 = objects.values().sum();
            let per: Vec<String> = objects.iter().map(|(o, c)| format!("{o} {c}")).collect();
            out.push(format!("{split:<11} {total} samples: {}", per.join(", ")));
        }
        for (split, bins) in &r.occlusion {
            let total = bins.values().sum::<u64>().max(1) as f64;
            let occ: Vec<String> = bins.iter().map(|(b, c)| format!("{b} {c} ({:.1}%)", 100.0 * *c as f64 / total)).collect();
            out.push(format!("occlusion   {split}: {}", occ.join(", ")));
        }
        if let Some(e) = r.episodes.first() {
            out.push(format!(
                "episodes    {} of {} frames ({:.2} s): camera {:.1} Hz, touch {:.1} Hz, state {:.1} Hz",
                r.episodes.len(),
                e.frames,
                e.duration_s,
                e.camera_hz,
                e.tactile_hz,
                e.state_hz
            ));
        }
        if !r.in_hand_rotation_deg.is_empty() {
            let mut last: Vec<f64> = r.in_hand_rotation_deg.iter().map(|e| e.last_deg).collect();
            let mut largest: Vec<f64> = r.in_hand_rotation_deg.iter().map(|e| e.largest_deg).collect();
            last.sort_by(f64::total_cmp);
            largest.sort_by(f64::total_cmp);
            out.push(format!(
                "in-hand     the object's rotation in the palm per episode, settled grasp to last frame: median {:.2}°, max {:.2}°; largest on the way: median {:.2}°, max {:.2}°",
                last[last.len() / 2],
                last[last.len() - 1],
                largest[largest.len() / 2],
                largest[largest.len() - 1]
            ));
        }
        out.push(format!("randomized  {:.1}%", 100.0 * r.randomized_share));
        if let Some([lo, med, hi]) = r.tactile_points {
            out.push(format!("touch       tactile points per sample: min {lo}, median {med}, max {hi}"));
            let c: Vec<String> = r.contact_share.iter().map(|(p, s)| format!("{p} {:.0}%", 100.0 * s)).collect();
            out.push(format!("contacts    {}", c.join(", ")));
        }
        if let Some(g) = &r.grasp {
            out.push(format!("grasps      {g}"));
        }
        out.iter().map(|l| format!("{l}\n")).collect()
    }
}

/// `vtgen inspect`: the summary (text or JSON).
pub fn run(dataset: &Path, json: bool) -> Result<()> {
    let r = inspect(dataset)?;
    if json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        print!("{}", r.text(dataset));
    }
    Ok(())
}

//! One split of a dataset, restricted to the selected objects, with an optional view cache.

use super::*;

/// One split of a dataset, restricted to the selected objects, with an optional view cache.
pub struct SplitSource {
    pub root: PathBuf,
    pub split: String,
    shards: Vec<ShardReader>,
    /// Selected samples: (shard, split index, object index).
    entries: Vec<(usize, u64, usize)>,
    pub models: Arc<Vec<ObjectModel>>,
    depth: DepthSource,
    cache: Option<HashMap<usize, Arc<ObjectView>>>,
}

impl SplitSource {
    /// Opens `split` of the dataset at `root`, keeping the samples of `objects` (ids).
    pub fn open(root: &Path, split: &str, objects: &[String], depth: DepthSource, cache: bool) -> Result<Self> {
        let reader = DatasetReader::open(root)?;
        let models = load_models(root)?;
        let shards = reader.shards(split)?;
        let object_of = sample_objects(root, split, models.len())?;
        let wanted: Vec<bool> = models.iter().map(|m| objects.contains(&m.id)).collect();
        let mut entries = Vec::new();
        for (k, sh) in shards.iter().enumerate() {
            // An episode shard names its object; a snapshot's object follows from its index.
            let episode_object = match episode_record(sh)? {
                Some(record) => Some(models.iter().position(|m| m.id == record.object_id).ok_or_else(|| {
                    anyhow!("shard {}: episode of object '{}', which models/ does not have", sh.path().display(), record.object_id)
                })?),
                None => None,
            };
            for i in sh.indices() {
                let o = match episode_object {
                    Some(o) => o,
                    None => object_of(i)?,
                };
                if wanted[o] {
                    entries.push((k, i, o));
                }
            }
        }
        Ok(SplitSource {
            root: root.to_path_buf(),
            split: split.to_string(),
            shards,
            entries,
            models: Arc::new(models),
            depth,
            cache: cache.then(HashMap::new),
        })
    }

    /// Selected samples.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Keeps only the first `n` selected samples.
    pub fn truncate(&mut self, n: usize) {
        self.entries.truncate(n);
    }

    /// Keeps every `k`-th selected sample so that at most `n` remain (an even spread).
    pub fn spread(&mut self, n: usize) {
        if n > 0 && self.entries.len() > n {
            let len = self.entries.len();
            self.entries = (0..n).map(|i| self.entries[i * len / n]).collect();
        }
    }

    /// The episodes of the split (FORMAT.md, "Episodes"), each with its selected frames in time
    /// order; an error naming the shard when the split holds a snapshot shard (not an episode
    /// dataset).
    pub fn episodes(&self) -> Result<Vec<Episode>> {
        let mut episodes: Vec<Episode> = Vec::new();
        for (i, &(shard, _, object)) in self.entries.iter().enumerate() {
            let sh = &self.shards[shard];
            let record = episode_record(sh)?.ok_or_else(|| {
                anyhow!(
                    "{} split of {}: shard {} is a snapshot shard, not an episode (its vtgen.shard metadata has no `{}` entry; \
                     record episodes with sampling.record)",
                    self.split,
                    self.root.display(),
                    sh.path().display(),
                    vt_dataset::EPISODE_METADATA_KEY
                )
            })?;
            match episodes.last_mut() {
                Some(e) if e.shard == shard => e.frames.push(i),
                _ => episodes.push(Episode { shard, object, path: sh.path().to_path_buf(), record, frames: vec![i] }),
            }
        }
        Ok(episodes)
    }

    /// Selected sample `i` (0-based among the selected) decoded whole, with its object's index
    /// (never cached: a full image is megabytes).
    pub fn sample(&mut self, i: usize) -> Result<(vt_dataset::Sample, usize)> {
        let (shard, index, object) = self.entries[i];
        let sample = self.shards[shard].read(index)?;
        let id = &sample.info.object_id;
        if *id != self.models[object].id {
            bail!("{} sample {index}: object '{id}', expected '{}' from the dataset's config.json", self.split, self.models[object].id);
        }
        Ok((sample, object))
    }

    /// The decoded view of selected sample `i` (0-based among the selected).
    pub fn view(&mut self, i: usize) -> Result<Arc<ObjectView>> {
        if let Some(v) = self.cache.as_ref().and_then(|c| c.get(&i)) {
            return Ok(v.clone());
        }
        let (sample, object) = self.sample(i)?;
        let view = Arc::new(ObjectView::from_sample(&sample, object, self.depth)?);
        if let Some(c) = self.cache.as_mut() {
            c.insert(i, view.clone());
        }
        Ok(view)
    }
}

/// One episode of a split: its shard and record, and its selected frames (positions among the
/// [`SplitSource`]'s selected samples, ascending: the frames in time order).
#[derive(Debug, Clone)]
pub struct Episode {
    /// The shard's position in the split.
    pub shard: usize,
    /// The dataset's `object_index` of its object.
    pub object: usize,
    pub path: PathBuf,
    pub record: vt_dataset::EpisodeRecord,
    pub frames: Vec<usize>,
}

/// The `episode` record of an episode shard's `vtgen.shard` metadata; None for a snapshot shard.
fn episode_record(shard: &ShardReader) -> Result<Option<vt_dataset::EpisodeRecord>> {
    let Some(json) = shard.meta().extra.get(vt_dataset::EPISODE_METADATA_KEY) else { return Ok(None) };
    serde_json::from_str(json).map(Some).with_context(|| {
        format!("shard {}: its `{}` metadata is not an episode record", shard.path().display(), vt_dataset::EPISODE_METADATA_KEY)
    })
}

/// The object of every split index, from the dataset's `config.json` (FORMAT.md: objects in
/// config order, trajectories ascending, instances ascending; trajectory `t` is a test trajectory
/// iff `t mod (train + test) >= train`), so no sample has to be decoded to be selected.
fn sample_objects(root: &Path, split: &str, num_objects: usize) -> Result<impl Fn(u64) -> Result<usize> + use<>> {
    let path = root.join("config.json");
    let text = std::fs::read_to_string(&path).with_context(|| format!("cannot read {}", path.display()))?;
    let cfg: serde_json::Value = serde_json::from_str(&text).with_context(|| format!("{} is not JSON", path.display()))?;
    let num = |p: &str| cfg.pointer(p).and_then(|v| v.as_u64()).ok_or_else(|| anyhow!("{}: no {p}", path.display()));
    let (trajectories, instances) = (num("/sampling/trajectories_per_object")?, num("/sampling/instances_per_trajectory")?);
    let (a, b) = (num("/sampling/split/train")?, num("/sampling/split/test")?);
    let in_split = (0..trajectories).filter(|t| (t % (a + b) >= a) == (split == "test")).count() as u64;
    let per_object = in_split * instances;
    let objects = cfg.pointer("/objects").and_then(|v| v.as_array()).map_or(0, |v| v.len());
    if objects != num_objects {
        bail!("{}: {objects} objects, but models/ has {num_objects}", path.display());
    }
    let split = split.to_string();
    Ok(move |index: u64| {
        let o = index.checked_div(per_object).unwrap_or(u64::MAX) as usize;
        if o >= num_objects {
            bail!("{split} sample {index} is beyond the dataset's {} samples", per_object * num_objects as u64);
        }
        Ok(o)
    })
}

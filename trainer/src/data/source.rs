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
            for i in sh.indices() {
                let o = object_of(i)?;
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

    /// The decoded view of selected sample `i` (0-based among the selected).
    pub fn view(&mut self, i: usize) -> Result<Arc<ObjectView>> {
        if let Some(v) = self.cache.as_ref().and_then(|c| c.get(&i)) {
            return Ok(v.clone());
        }
        let (shard, index, object) = self.entries[i];
        let sample = self.shards[shard].read(index)?;
        let id = &sample.info.object_id;
        if *id != self.models[object].id {
            bail!("{} sample {index}: object '{id}', expected '{}' from the dataset's config.json", self.split, self.models[object].id);
        }
        let view = Arc::new(ObjectView::from_sample(&sample, object, self.depth)?);
        if let Some(c) = self.cache.as_mut() {
            c.insert(i, view.clone());
        }
        Ok(view)
    }
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

//! A run directory: the config it was trained with, its state (epochs, steps, the objects of its
//! head slots), the weights, checkpoints and `metrics.csv`. Training writes it; evaluation, the
//! sweep and `--resume` read it.

use std::path::PathBuf;

use anyhow::{Context, Result};
use burn::module::Module;
use burn::prelude::*;
use serde::{Deserialize, Serialize};

use crate::config::TrainConfig;
use crate::model::{PoseNet, Variant};

/// `state.json` of a run directory.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunState {
    pub epochs_done: usize,
    pub steps: u64,
    /// The object of each head slot.
    pub objects: Vec<String>,
    pub variant: Variant,
    /// `vtpose <version>` that wrote the run.
    pub trainer: String,
}

/// Files of a run directory.
#[derive(Debug, Clone)]
pub struct RunDir(pub PathBuf);

impl RunDir {
    pub fn config(&self) -> PathBuf {
        self.0.join("config.yaml")
    }
    pub fn state(&self) -> PathBuf {
        self.0.join("state.json")
    }
    pub fn model(&self) -> PathBuf {
        self.0.join("model.bpk")
    }
    pub fn optimizer(&self) -> PathBuf {
        self.0.join("optimizer.bpk")
    }
    pub fn checkpoint(&self, epoch: usize) -> PathBuf {
        self.0.join("checkpoints").join(format!("epoch-{epoch:04}.bpk"))
    }
    pub fn metrics(&self) -> PathBuf {
        self.0.join("metrics.csv")
    }

    pub fn load_state(&self) -> Result<RunState> {
        let text =
            std::fs::read_to_string(self.state()).with_context(|| format!("{} is not a vtpose run (no state.json)", self.0.display()))?;
        serde_json::from_str(&text).with_context(|| format!("{} is not a valid state.json", self.state().display()))
    }

    pub(crate) fn save_state(&self, s: &RunState) -> Result<()> {
        let tmp = self.0.join(".state.json.tmp");
        std::fs::write(&tmp, serde_json::to_string_pretty(s)? + "\n")?;
        std::fs::rename(&tmp, self.state()).with_context(|| format!("cannot write {}", self.state().display()))
    }

    /// The trained network of this run on `device` (its config, state and weights).
    pub fn load_model(&self, device: &Device) -> Result<(TrainConfig, RunState, PoseNet)> {
        let cfg = TrainConfig::load(&self.config())?;
        let state = self.load_state()?;
        let model = cfg.model.net(state.objects.len()).init(device);
        let model = model.try_load_file(self.model()).map_err(|e| anyhow::anyhow!("cannot load {}: {e}", self.model().display()))?;
        Ok((cfg, state, model))
    }
}

/// Head slot of each dataset object (`None`: not trained on).
pub fn slot_table(models: &[crate::data::ObjectModel], objects: &[String]) -> Vec<Option<usize>> {
    models.iter().map(|m| objects.iter().position(|o| o == &m.id)).collect()
}

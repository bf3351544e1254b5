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
        let model = cfg.model.init(state.objects.len(), device);
        let model = model.try_load_file(self.model()).map_err(|e| anyhow::anyhow!("cannot load {}: {e}", self.model().display()))?;
        Ok((cfg, state, model))
    }
}

/// One evaluated epoch of a run's `metrics.csv`: its learning curve on the held-out samples.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CurvePoint {
    pub epoch: usize,
    pub steps: u64,
    /// Mean training loss of the epoch.
    pub loss: f64,
    /// Held-out samples evaluated.
    pub n: usize,
    pub position_cm: f64,
    pub angle_deg: f64,
    /// NaN in a `metrics.csv` written before medians were recorded.
    pub position_median_cm: f64,
    pub angle_median_deg: f64,
}

impl RunDir {
    /// The epochs of `metrics.csv` with held-out metrics (`train.eval_every`), in order; empty
    /// when the run never evaluated during training. Columns are found by their header names.
    pub fn learning_curve(&self) -> Result<Vec<CurvePoint>> {
        let path = self.metrics();
        let text = std::fs::read_to_string(&path).with_context(|| format!("cannot read {}", path.display()))?;
        let mut lines = text.lines();
        let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
        let column = |name: &str| header.iter().position(|h| *h == name);
        let required = |name: &str| column(name).with_context(|| format!("{}: no column `{name}`", path.display()));
        let (epoch, steps, loss, n) = (required("epoch")?, required("steps")?, required("loss")?, required("eval_n")?);
        let (position, angle) = (required("eval_position_cm")?, required("eval_angle_deg")?);
        let (position_median, angle_median) = (column("eval_position_median_cm"), column("eval_angle_median_deg"));
        let mut curve = Vec::new();
        for (k, line) in lines.enumerate() {
            let cells: Vec<&str> = line.split(',').collect();
            let cell = |i: usize| cells.get(i).copied().unwrap_or_default();
            if cell(n).is_empty() {
                continue;
            }
            let value = |i: usize| -> Result<f64> {
                cell(i).parse().with_context(|| format!("{} line {}: `{}` is not a number", path.display(), k + 2, cell(i)))
            };
            let optional = |i: Option<usize>| i.and_then(|i| cell(i).parse().ok()).unwrap_or(f64::NAN);
            curve.push(CurvePoint {
                epoch: value(epoch)? as usize,
                steps: value(steps)? as u64,
                loss: value(loss)?,
                n: value(n)? as usize,
                position_cm: value(position)?,
                angle_deg: value(angle)?,
                position_median_cm: optional(position_median),
                angle_median_deg: optional(angle_median),
            });
        }
        Ok(curve)
    }
}

/// Head slot of each dataset object (`None`: not trained on).
pub fn slot_table(models: &[crate::data::ObjectModel], objects: &[String]) -> Vec<Option<usize>> {
    models.iter().map(|m| objects.iter().position(|o| o == &m.id)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_learning_curve_reads_the_evaluated_epochs_by_column_name() {
        let dir = tempfile::tempdir().unwrap();
        let run = RunDir(dir.path().to_path_buf());
        // Epoch 2 was not evaluated; an older file without the median columns reads NaN there.
        std::fs::write(
            run.metrics(),
            "epoch,steps,samples,skipped,loss,distance_cm,seconds,eval_n,eval_position_cm,eval_angle_deg,eval_add_auc,eval_adds_auc,eval_position_median_cm,eval_angle_median_deg\n\
             1,10,160,0,0.05,9.0,3.0,40,4.5,118.0,30.0,70.0,4.2,124.5\n\
             2,20,160,0,0.04,8.0,3.0,,,,,,,\n\
             3,30,160,0,0.03,7.0,3.0,40,3.2,110.0,40.0,76.0,2.9,101.0\n",
        )
        .unwrap();
        let curve = run.learning_curve().unwrap();
        assert_eq!(curve.iter().map(|p| p.epoch).collect::<Vec<_>>(), [1, 3]);
        assert_eq!((curve[1].steps, curve[1].n, curve[1].position_cm, curve[1].angle_median_deg), (30, 40, 3.2, 101.0));
        std::fs::write(
            run.metrics(),
            "epoch,steps,samples,skipped,loss,distance_cm,seconds,eval_n,eval_position_cm,eval_angle_deg,eval_add_auc,eval_adds_auc\n\
             5,50,160,0,0.02,6.0,3.0,40,2.0,100.0,50.0,80.0\n",
        )
        .unwrap();
        let old = run.learning_curve().unwrap();
        assert_eq!((old[0].epoch, old[0].angle_deg), (5, 100.0));
        assert!(old[0].angle_median_deg.is_nan());
        // A cell that is not a number names the file and line.
        std::fs::write(
            run.metrics(),
            "epoch,steps,samples,skipped,loss,distance_cm,seconds,eval_n,eval_position_cm,eval_angle_deg\n1,10,1,0,x,1,1,4,1.0,2.0\n",
        )
        .unwrap();
        let err = format!("{:#}", run.learning_curve().unwrap_err());
        assert!(err.contains("metrics.csv line 2") && err.contains("`x`"), "{err}");
    }
}

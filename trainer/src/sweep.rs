//! The paper's tactile-point experiment (§VI-A-3: "we modified the proposed network to accept 4,
//! 12, 36, 60, 240 tactile contact points"): one network **trained** per tactile point count,
//! each evaluated on the test split, with a vision-only baseline for reference.
//!
//! ```text
//! OUT/
//!   nt-0004/ … nt-0240/     one run directory per count (resumable: a finished run is kept)
//!   report.md, results.json, samples-*.csv, *.svg     the evaluation of every run (vtpose eval)
//!   sweep-position.svg, sweep-angle.svg                 error against the number of tactile points
//! ```

use std::path::{Path, PathBuf};

use anyhow::{Result, bail};
use burn::prelude::Device;

use crate::config::TrainConfig;
use crate::data::N_TACTILE_RANGE;
use crate::eval::metrics::MeanSe;
use crate::eval::{EvalCommand, ModelEval, Summary, evaluate_runs};
use crate::report::plots::bar_chart;
use crate::report::write_report;
use crate::train::{TrainOptions, train};

/// How to run [`sweep`].
#[derive(Debug, Clone)]
pub struct SweepOptions {
    /// Tactile point counts, one trained network each.
    pub counts: Vec<usize>,
    pub out: PathBuf,
    /// A trained vision-only run evaluated alongside, for reference.
    pub baseline: Option<PathBuf>,
    /// At most this many test samples (0: all).
    pub max_samples: usize,
    pub device: Device,
    pub quiet: bool,
}

/// The run directory of count `n_t`.
pub fn run_dir(out: &Path, n_tactile: usize) -> PathBuf {
    out.join(format!("nt-{n_tactile:04}"))
}

/// Trains (or finishes) one network per count, evaluates them all and writes the report.
pub fn sweep(cfg: &TrainConfig, opts: &SweepOptions) -> Result<Vec<ModelEval>> {
    if !cfg.model.variant.uses_tactile() {
        bail!("vtpose sweep: the config's variant {} has no tactile channel", cfg.model.variant);
    }
    if opts.counts.is_empty() {
        bail!("vtpose sweep: no tactile point counts");
    }
    let (lo, hi) = N_TACTILE_RANGE;
    let mut runs = Vec::new();
    for &nt in &opts.counts {
        if !(lo..=hi).contains(&nt) {
            bail!("vtpose sweep: {nt} tactile points is outside {lo}..={hi}");
        }
        let mut c = cfg.clone();
        c.data.n_tactile = nt;
        let dir = run_dir(&opts.out, nt);
        if !opts.quiet {
            eprintln!("vtpose sweep: {nt} tactile points -> {}", dir.display());
        }
        // `resume` continues an interrupted run and keeps a finished one.
        train(&c, &TrainOptions { out: dir.clone(), resume: true, overwrite: false, device: opts.device.clone(), quiet: opts.quiet })?;
        runs.push(dir);
    }
    runs.extend(opts.baseline.clone());
    let cmd = EvalCommand {
        dataset: None,
        split: "test".into(),
        max_samples: opts.max_samples,
        sweep: false,
        // The sweep compares point counts; `vtpose eval` of its runs gives the touch control.
        touch_control: false,
        device: opts.device.clone(),
        quiet: opts.quiet,
    };
    let evals = evaluate_runs(&runs, &cmd)?;
    write_report(&evals, "test", &format!("{:?}", opts.device), &opts.out)?;
    let groups: Vec<String> =
        evals.iter().map(|e| if e.variant.uses_tactile() { e.n_tactile.to_string() } else { "vision only".into() }).collect();
    for (file, title, label, f) in [
        (
            "sweep-position.svg",
            "Position error by number of tactile points (one network each)",
            "position error (cm)",
            (|s: &Summary| s.position_cm) as fn(&Summary) -> MeanSe,
        ),
        ("sweep-angle.svg", "Angle error by number of tactile points (one network each)", "angle error (°)", |s: &Summary| s.angle_deg),
    ] {
        let values: Vec<MeanSe> = evals.iter().map(|e| f(&Summary::of(&e.results))).collect();
        std::fs::write(opts.out.join(file), bar_chart(title, label, &groups, &[("test split".to_string(), values)])?)?;
    }
    Ok(evals)
}

//! `vtgen export FORMAT`: a dataset converted for other tools, one exporter per file. The shards
//! stay the one format `generate` writes; an exporter reads them (`vt_dataset::DatasetReader`, or
//! `vtdata` in Python) and writes its format. A new format is a file here implementing
//! [`Exporter`] and its subcommand in `main.rs`.

use std::path::Path;

use anyhow::Result;

pub mod bop;
pub mod lerobot;

pub use bop::{Bop, BopOptions, DEPTH_SCALE, ExportSummary, export_bop};
pub use lerobot::LerobotOptions;

/// One output format.
pub trait Exporter {
    /// The format's name, for messages.
    fn name(&self) -> &'static str;
    /// Writes `dataset` in the format into `out` (a new or empty folder) and prints what it wrote.
    fn export(&self, dataset: &Path, out: &Path) -> Result<()>;
}

/// Runs `exporter`, naming its format in any error.
pub fn run(exporter: &dyn Exporter, dataset: &Path, out: &Path) -> Result<()> {
    exporter.export(dataset, out).map_err(|e| e.context(format!("export to {} of {}", exporter.name(), dataset.display())))
}

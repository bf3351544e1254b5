//! `vtgen export lerobot DATASET --out OUT`: a LeRobotDataset v3.0, written by LeRobot's own
//! writer in Python (`vtdata.lerobot`, docs/data.md "LeRobot export"), so the parquet files and
//! videos are what LeRobot writes.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result};

/// What `vtgen export lerobot` passes to `python -m vtdata.lerobot`.
#[derive(Debug, Clone, Default)]
pub struct LerobotOptions {
    pub repo_id: Option<String>,
    pub fps: Option<u32>,
    pub vcodec: String,
    /// The interpreter; default `$VTGEN_PYTHON`, else `python3`.
    pub python: Option<PathBuf>,
    pub quiet: bool,
}

/// `vtgen export lerobot`: a LeRobotDataset v3.0, written by LeRobot's own writer in Python
/// (`vtdata.lerobot`, docs/data.md "LeRobot export"), so the parquet files and videos are what
/// LeRobot writes. Checks first that the interpreter runs and imports `vtdata`; the module itself
/// says when LeRobot is missing (with the pip line) and names the file or option of any other
/// user error.
impl super::Exporter for LerobotOptions {
    fn name(&self) -> &'static str {
        "LeRobot"
    }

    fn export(&self, dataset: &Path, out: &Path) -> Result<()> {
        run_lerobot(dataset, out, self)
    }
}

fn run_lerobot(dataset: &Path, out: &Path, opts: &LerobotOptions) -> Result<()> {
    let python = opts
        .python
        .clone()
        .or_else(|| std::env::var_os("VTGEN_PYTHON").filter(|v| !v.is_empty()).map(PathBuf::from))
        .unwrap_or_else(|| PathBuf::from("python3"));
    let probe = Command::new(&python).args(["-c", "import vtdata"]).output();
    match probe {
        Err(e) => anyhow::bail!(
            "cannot run the Python interpreter {} ({e}): give one with --python or VTGEN_PYTHON (a venv with vtdata and lerobot)",
            python.display()
        ),
        Ok(o) if !o.status.success() => {
            let stderr = String::from_utf8_lossy(&o.stderr);
            let why = stderr.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or("no output").trim().to_string();
            anyhow::bail!(
                "{} cannot import vtdata ({why}): install it with `{} -m pip install -e \"datasets/python[lerobot]\"` (from the vtgen \
                 checkout), or name the venv that has it with --python or VTGEN_PYTHON",
                python.display(),
                python.display()
            )
        }
        Ok(_) => {}
    }
    let mut cmd = Command::new(&python);
    cmd.args(["-m", "vtdata.lerobot"]).arg(dataset).arg("--out").arg(out).args(["--vcodec", &opts.vcodec]);
    if let Some(repo_id) = &opts.repo_id {
        cmd.args(["--repo-id", repo_id]);
    }
    if let Some(fps) = opts.fps {
        cmd.args(["--fps", &fps.to_string()]);
    }
    if opts.quiet {
        cmd.arg("--quiet");
    }
    let status = cmd.status().with_context(|| format!("cannot run {} -m vtdata.lerobot", python.display()))?;
    // The module printed its own one-line error (or LeRobot's traceback for a bug).
    anyhow::ensure!(status.success(), "the LeRobot export failed ({status})");
    Ok(())
}

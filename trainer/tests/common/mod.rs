//! What the trainer's integration tests share: the workspace root, a tiny dataset generated
//! through the generator library, and a network small enough to train in seconds on a CPU.

#![allow(dead_code)] // each test crate uses its own part

use std::path::{Path, PathBuf};

use vt_trainer::config::{AugmentConfig, DataConfig, ModelConfig, OptimConfig, TrainConfig};
use vt_trainer::model::Variant;

pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("workspace root").to_path_buf()
}

/// `scenes/tiny-hand.yaml` with `overrides`, generated into `target/tmp/vtpose-<name>-<pid>`
/// (the copies of earlier test processes that are gone are removed first).
pub fn generate(name: &str, overrides: &[&str]) -> PathBuf {
    // Mesa's drivers want a runtime directory on headless machines.
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        let xdg = std::env::temp_dir().join("vtgen-xdg-runtime");
        std::fs::create_dir_all(&xdg).unwrap();
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let _ = std::fs::set_permissions(&xdg, std::fs::Permissions::from_mode(0o700));
        }
        // SAFETY: set before the renderer (the only reader) starts; the datasets are generated
        // one at a time under the tests' OnceLocks.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", &xdg) };
    }
    let base = Path::new(env!("CARGO_TARGET_TMPDIR"));
    let prefix = format!("vtpose-{name}-");
    for entry in std::fs::read_dir(base).into_iter().flatten().flatten() {
        let file = entry.file_name().to_string_lossy().into_owned();
        if let Some(pid) = file.strip_prefix(&prefix)
            && !Path::new("/proc").join(pid).exists()
        {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
    let out = base.join(format!("{prefix}{}", std::process::id()));
    let overrides: Vec<vtgen::config::Override> = overrides.iter().map(|o| o.parse().unwrap_or_else(|e| panic!("{o}: {e}"))).collect();
    let cfg = vtgen::config::LoadedConfig::load_with(&root().join("scenes/tiny-hand.yaml"), &overrides).unwrap_or_else(|e| panic!("{e}"));
    let opts = vtgen::output::generate::GenerateOptions {
        out: out.clone(),
        shard: vtgen::plan::ShardSelector::ALL,
        resume: false,
        overwrite: true,
        jobs: 1,
        quiet: true,
        ycb_dir: None,
        mix_generators: false,
        manifest_only: false,
    };
    vtgen::output::generate::generate(&cfg, &opts).unwrap_or_else(|e| panic!("generating {name}: {e:#}"));
    out
}

/// A config small enough to train in seconds on a CPU: `epochs` over 8 samples of `dataset`.
pub fn small_config(dataset: &Path, variant: Variant, epochs: usize) -> TrainConfig {
    let mut c = TrainConfig::new(dataset);
    c.model = ModelConfig {
        variant,
        cnn_channels: [8, 16],
        color_dim: 16,
        point_dims: [16, 32],
        global_dims: vec![64, 128],
        head_dims: vec![64],
        ..ModelConfig::default()
    };
    c.data = DataConfig { n_points: 64, n_tactile: 32, n_model_points: 64, crop_size: 32, ..DataConfig::default() };
    c.augment = AugmentConfig::NONE;
    c.train = OptimConfig { epochs, batch_size: 8, lr: 1e-3, eval_every: 0, max_train_samples: 8, ..OptimConfig::default() };
    c
}

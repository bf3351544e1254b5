//! Shared helpers: running the binary, the reference tiny dataset (generated once per test run).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("workspace root").to_path_buf()
}

pub fn tiny_config() -> PathBuf {
    root().join("scenes/tiny.yaml")
}

pub fn vtgen() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_vtgen"));
    c.current_dir(root());
    c
}

pub fn run(args: &[&str]) -> Output {
    vtgen().args(args).output().expect("vtgen runs")
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A fresh directory for one test, inside this process's run directory.
pub fn tempdir() -> tempfile::TempDir {
    tempfile::Builder::new().prefix("vtgen-test-").tempdir_in(run_dir()).expect("temp dir")
}

/// The parent of every test directory of this process, removed when the process exits: the
/// datasets the tests share live in statics, which Rust never drops, and would otherwise stay in
/// the temp dir after every run.
fn run_dir() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    unsafe extern "C" {
        fn atexit(callback: extern "C" fn()) -> i32;
    }
    extern "C" fn remove_run_dir() {
        if let Some(dir) = DIR.get() {
            let _ = std::fs::remove_dir_all(dir);
        }
    }
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("vtgen-test-run-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("test run dir");
        // SAFETY: `remove_run_dir` only reads a set OnceLock and removes files; it runs once, at exit.
        unsafe { atexit(remove_run_dir) };
        dir
    })
}

/// `vtgen generate CONFIG --out OUT --quiet EXTRA…`: the run's output, success or not.
pub fn run_generate(config: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["generate", config.to_str().unwrap(), "--out", out.to_str().unwrap(), "--quiet"];
    args.extend_from_slice(extra);
    run(&args)
}

/// Generates `config` into `out` with the CLI, asserting success.
pub fn generate(config: &Path, out: &Path, extra: &[&str]) {
    let o = run_generate(config, out, extra);
    assert!(o.status.success(), "vtgen generate {} failed: {}", config.display(), stderr(&o));
}

/// The reference dataset: `scenes/tiny.yaml` generated once with the README's main command.
pub fn reference_dataset() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let d = tempdir();
        generate(&tiny_config(), d.path(), &[]);
        d
    })
    .path()
}

/// Every file under `dir` (relative path -> bytes), sorted.
pub fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    assert!(dir.is_dir(), "{} is not a directory", dir.display());
    files_named(dir, |_| true)
        .into_iter()
        .map(|name| {
            let bytes = std::fs::read(dir.join(&name)).unwrap_or_else(|e| panic!("{name}: {e}"));
            (name, bytes)
        })
        .collect()
}

/// Names of the complete shard files (`*.mcap`) under a dataset directory.
pub fn complete_shards(dir: &Path) -> Vec<String> {
    files_named(dir, |n| n.ends_with(".mcap"))
}

/// Names (relative paths) of the files under `dir` that `pred` accepts, sorted. Names only, so
/// that it may look while a run is writing: a temporary file renamed or removed between the
/// listing and a look at it is simply not there (reading every file's bytes while it wrote hit
/// such a file now and then).
pub fn files_named(dir: &Path, pred: impl Fn(&str) -> bool) -> Vec<String> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else { continue };
        for e in entries.flatten() {
            let p = e.path();
            match e.file_type() {
                Ok(t) if t.is_dir() => stack.push(p),
                Ok(_) => {
                    let name = p.strip_prefix(dir).unwrap().display().to_string();
                    if pred(&name) {
                        out.push(name);
                    }
                }
                Err(_) => {}
            }
        }
    }
    out.sort();
    out
}

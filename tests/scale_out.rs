//! Scale-out on batch schedulers: the Slurm array script and the Kubernetes Indexed Job entry point,
//! run as N processes at once on this machine into one directory, then their merge step. The union
//! must equal the single-process run byte for byte (manifest included) and pass `vtgen validate`.

use std::path::Path;
use std::process::{Child, Command};

use crate::common::*;

fn script(rel: &str, out: &Path, env: &[(&str, String)]) -> Command {
    let mut c = Command::new("bash");
    c.arg(root().join(rel)).current_dir(root());
    c.env("VTGEN", env!("CARGO_BIN_EXE_vtgen")).env("CONFIG", tiny_config()).env("OUT", out).env_remove("YCB_DIR");
    for (k, v) in env {
        c.env(k, v);
    }
    c
}

/// Starts `count` copies of a script at once, copy `i` with the environment `env(i)`.
fn spawn_all(rel: &str, out: &Path, count: usize, env: impl Fn(usize) -> Vec<(&'static str, String)>) -> Vec<Child> {
    (0..count)
        .map(|i| script(rel, out, &env(i)).stdout(std::process::Stdio::piped()).stderr(std::process::Stdio::piped()).spawn().unwrap())
        .collect()
}

fn wait_all(children: Vec<Child>) {
    for c in children {
        let o = c.wait_with_output().unwrap();
        assert!(o.status.success(), "a shard process failed: {}", String::from_utf8_lossy(&o.stderr));
    }
}

fn assert_equals_the_single_process_run(dir: &Path) {
    let a = files(reference_dataset());
    let b = files(dir);
    let names = |v: &[(String, Vec<u8>)]| v.iter().map(|f| f.0.clone()).collect::<Vec<_>>();
    assert_eq!(names(&a), names(&b));
    for (fa, fb) in a.iter().zip(&b) {
        assert!(fa.1 == fb.1, "{} differs from the single-process run", fa.0);
    }
}

#[test]
fn slurm_array_tasks_in_parallel_union_to_the_single_process_run() {
    let d = tempdir();
    let n = 3;
    let children = spawn_all("deploy/slurm/generate.sbatch", d.path(), n, |i| {
        vec![("SLURM_ARRAY_TASK_ID", i.to_string()), ("SLURM_ARRAY_TASK_COUNT", n.to_string())]
    });
    wait_all(children);
    let o = script("deploy/slurm/merge.sbatch", d.path(), &[]).output().unwrap();
    assert!(o.status.success(), "merge failed: {}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains(": valid"), "validate did not pass: {}", String::from_utf8_lossy(&o.stdout));
    assert_equals_the_single_process_run(d.path());
}

#[test]
fn kubernetes_indexed_pods_in_parallel_union_to_the_single_process_run() {
    let d = tempdir();
    // The manifest's completions and SHARD_COUNT agree, and the pods run the entry point tested here.
    let job: serde_yaml::Value =
        serde_yaml::from_str(&std::fs::read_to_string(root().join("deploy/kubernetes/job.yaml")).unwrap()).unwrap();
    assert_eq!(job["spec"]["completionMode"].as_str(), Some("Indexed"));
    let completions = job["spec"]["completions"].as_u64().unwrap();
    let env = job["spec"]["template"]["spec"]["containers"][0]["env"].as_sequence().unwrap();
    let shard_count = env.iter().find(|e| e["name"].as_str() == Some("SHARD_COUNT")).unwrap()["value"].as_str().unwrap();
    assert_eq!(shard_count, completions.to_string());
    let dockerfile = std::fs::read_to_string(root().join("deploy/kubernetes/Dockerfile")).unwrap();
    assert!(dockerfile.contains("deploy/kubernetes/run-shard.sh"));

    let n = 2;
    let children = spawn_all("deploy/kubernetes/run-shard.sh", d.path(), n, |i| {
        vec![("JOB_COMPLETION_INDEX", i.to_string()), ("SHARD_COUNT", n.to_string())]
    });
    wait_all(children);
    let o = script("deploy/kubernetes/run-shard.sh", d.path(), &[("MODE", "merge".into())]).output().unwrap();
    assert!(o.status.success(), "merge failed: {}", String::from_utf8_lossy(&o.stderr));
    assert_equals_the_single_process_run(d.path());
}

#[test]
fn a_pod_without_its_index_says_what_is_missing() {
    let d = tempdir();
    let o = script("deploy/kubernetes/run-shard.sh", d.path(), &[("SHARD_COUNT", "2".into())])
        .env_remove("JOB_COMPLETION_INDEX")
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("JOB_COMPLETION_INDEX"), "{}", String::from_utf8_lossy(&o.stderr));
}

/// A copy of the reference dataset in a fresh directory.
fn copy_of_reference() -> tempfile::TempDir {
    let d = tempdir();
    for (name, bytes) in files(reference_dataset()) {
        let p = d.path().join(&name);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, bytes).unwrap();
    }
    d
}

/// Two writers of one shard: while one process holds a shard (its lock, as a running
/// `vtgen generate` holds it), a second selecting it is refused, the lock named, and removes
/// nothing; once the first is gone a rerun completes it, and the dataset is the single run's.
#[test]
fn a_second_writer_of_a_shard_is_refused_and_the_dataset_stays_the_single_runs() {
    let d = tempdir();
    let shard = |i: usize, n: usize| run_generate(&tiny_config(), d.path(), &["--shard", &format!("{i}/{n}"), "--resume"]);
    let o = shard(0, 2);
    assert!(o.status.success(), "{}", stderr(&o));
    // Slice 1 of 2 makes the shard at job 1; a writer holds it, with a leftover `.partial` of its own.
    let plan = vtgen::plan::Plan::new(&vtgen::config::LoadedConfig::load(&tiny_config()).unwrap().config);
    let held = plan.shards.iter().find(|s| s.job == 1).unwrap().file();
    let held_path = d.path().join(&held);
    let lock_path = held_path.with_file_name(format!(".{}.lock", held_path.file_name().unwrap().to_string_lossy()));
    let partial = format!("{}{}", held_path.display(), vt_dataset::PARTIAL_SUFFIX);
    std::fs::write(&partial, b"being written").unwrap();
    let lock = std::fs::OpenOptions::new().create(true).truncate(false).write(true).open(&lock_path).unwrap();
    lock.lock().unwrap();
    let o = shard(1, 2);
    let e = stderr(&o);
    assert!(!o.status.success(), "a second writer ran");
    assert!(e.contains(&format!("{held} is being written by another vtgen process")) && e.contains(".lock"), "{e}");
    assert_eq!(std::fs::read(&partial).unwrap(), b"being written", "the refused run touched the other writer's file");
    drop(lock);
    let o = shard(1, 2);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!Path::new(&partial).exists(), "the leftover of a writer that is gone is removed");
    let o = run_generate(&tiny_config(), d.path(), &["--manifest-only"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_equals_the_single_process_run(d.path());
}

/// `--resume` keeps only shards that check out: one truncated and one with a byte flipped are
/// redone and named (the manifest's checksum), one flipped with no manifest to compare is found
/// by its chunks' CRCs; the dataset is then the single run's again.
#[test]
fn resume_redoes_damaged_shards_and_says_why() {
    let d = copy_of_reference();
    let shards = complete_shards(d.path());
    assert!(shards.len() >= 3, "{shards:?}");
    let flip = |name: &str| {
        let p = d.path().join(name);
        let mut b = std::fs::read(&p).unwrap();
        let k = b.len() / 2;
        b[k] ^= 0x5a;
        std::fs::write(&p, b).unwrap();
    };
    let truncated = d.path().join(&shards[0]);
    let len = std::fs::metadata(&truncated).unwrap().len();
    std::fs::OpenOptions::new().write(true).open(&truncated).unwrap().set_len(len / 3).unwrap();
    flip(&shards[1]);
    let o = run_generate(&tiny_config(), d.path(), &["--resume"]);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert!(e.contains(&format!("redoing {}: ", shards[0])) && e.contains("truncated"), "{e}");
    assert!(e.contains(&format!("redoing {}: its SHA-256 differs from the manifest's", shards[1])), "{e}");
    assert_equals_the_single_process_run(d.path());

    std::fs::remove_file(d.path().join("manifest.json")).unwrap();
    flip(&shards[2]);
    let o = run_generate(&tiny_config(), d.path(), &["--resume"]);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert!(e.contains(&format!("redoing {}: ", shards[2])), "the damaged shard was kept: {e}");
    assert_equals_the_single_process_run(d.path());
}

/// A dataset another generator build started is not continued: `--resume` is refused naming both
/// builds, unless `--mix-generators`.
#[test]
fn resume_with_another_generator_build_is_refused() {
    let d = copy_of_reference();
    let record = d.path().join("generator.json");
    let ours = std::fs::read_to_string(&record).unwrap();
    assert!(ours.contains(&format!("\"build\": \"{}\"", vtgen::output::generate::GENERATOR_BUILD)), "{ours}");
    std::fs::write(&record, r#"{"generator": "vtgen 0.0.9", "build": "0123456789abcdef"}"#).unwrap();
    let o = run_generate(&tiny_config(), d.path(), &["--resume"]);
    let e = stderr(&o);
    assert!(
        !o.status.success() && e.contains("was generated by vtgen 0.0.9 (build 0123456789abcdef)") && e.contains("--mix-generators"),
        "{e}"
    );
    let o = run_generate(&tiny_config(), d.path(), &["--resume", "--mix-generators"]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// The merge generates nothing: a missing shard fails it, named.
#[test]
fn the_merge_names_missing_shards_instead_of_making_them() {
    let d = copy_of_reference();
    let shards = complete_shards(d.path());
    std::fs::remove_file(d.path().join(&shards[1])).unwrap();
    let o = run_generate(&tiny_config(), d.path(), &["--manifest-only"]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("missing") && e.contains(&shards[1]), "{e}");
    assert!(!d.path().join(&shards[1]).exists(), "the merge made a shard");
}

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

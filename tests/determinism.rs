//! Same config and seed, same bytes: across runs, across `--shard` jobs, across an interruption.

use std::time::{Duration, Instant};

use crate::common::*;

#[test]
fn the_main_command_makes_a_complete_dataset() {
    let d = reference_dataset();
    let m = vt_dataset::Manifest::load(&d.join("manifest.json")).unwrap();
    assert!(m.complete);
    assert_eq!(m.splits["train"].samples, 32);
    assert_eq!(m.splits["test"].samples, 8);
    let ds = vt_dataset::DatasetReader::open(d).unwrap();
    for split in ["train", "test"] {
        let n = ds.samples(split).unwrap().inspect(|s| assert!(s.is_ok())).count() as u64;
        assert_eq!(n, m.splits[split].samples);
    }
    // Checksums in the manifest are those of the files.
    for s in m.splits.values().flat_map(|s| &s.shards) {
        let (bytes, sha) = vt_dataset::sha256_file(&d.join(&s.file)).unwrap();
        assert_eq!(Some(bytes), s.bytes);
        assert_eq!(Some(sha), s.sha256);
    }
}

#[test]
fn two_full_runs_are_byte_identical() {
    let other = tempdir();
    generate(&tiny_config(), other.path(), &[]);
    let a = files(reference_dataset());
    let b = files(other.path());
    assert_eq!(a.len(), b.len());
    for (fa, fb) in a.iter().zip(&b) {
        assert_eq!(fa.0, fb.0);
        assert!(fa.1 == fb.1, "{} differs between two runs", fa.0);
    }
}

#[test]
fn parallel_workers_write_the_same_bytes_as_one() {
    // `--jobs 2`: two workers, each with its own renderer (and, on lavapipe, its own share of the
    // rasterizer threads) and a writer thread: the same files as the single-worker run.
    let other = tempdir();
    generate(&tiny_config(), other.path(), &["--jobs", "2"]);
    let a = files(reference_dataset());
    let b = files(other.path());
    assert_eq!(a.iter().map(|f| &f.0).collect::<Vec<_>>(), b.iter().map(|f| &f.0).collect::<Vec<_>>());
    for (fa, fb) in a.iter().zip(&b) {
        assert!(fa.1 == fb.1, "{} differs with --jobs 2", fa.0);
    }
}

#[test]
fn a_shard_job_alone_writes_the_same_bytes_as_the_full_run() {
    let part = tempdir();
    generate(&tiny_config(), part.path(), &["--shard", "1/2"]);
    let mine = complete_shards(part.path());
    // Jobs are train shards 0..4 then test shard 0: job 1 of 2 takes train 1 and train 3.
    assert_eq!(mine, ["train/shard-00001.mcap", "train/shard-00003.mcap"]);
    for f in &mine {
        assert!(
            std::fs::read(part.path().join(f)).unwrap() == std::fs::read(reference_dataset().join(f)).unwrap(),
            "{f} differs from the full run"
        );
    }
    let m = vt_dataset::Manifest::load(&part.path().join("manifest.json")).unwrap();
    assert!(!m.complete, "a partial run says so in its manifest");
    // The other job completes the dataset in the same directory.
    generate(&tiny_config(), part.path(), &["--shard", "0/2"]);
    let m = vt_dataset::Manifest::load(&part.path().join("manifest.json")).unwrap();
    assert!(m.complete);
    assert_eq!(
        std::fs::read(part.path().join("manifest.json")).unwrap(),
        std::fs::read(reference_dataset().join("manifest.json")).unwrap()
    );
}

#[test]
fn a_killed_run_leaves_no_complete_looking_shard_and_resume_finishes_it_identically() {
    let d = tempdir();
    let mut child =
        vtgen().args(["generate", tiny_config().to_str().unwrap(), "--out", d.path().to_str().unwrap(), "--quiet"]).spawn().unwrap();
    // Wait until a shard is being written, then SIGKILL.
    let deadline = Instant::now() + Duration::from_secs(120);
    loop {
        let partial = files_named(d.path(), |n| n.ends_with(".mcap.partial"));
        if !partial.is_empty() && !complete_shards(d.path()).is_empty() {
            break;
        }
        if let Some(status) = child.try_wait().unwrap() {
            panic!("generation finished ({status}) before it could be interrupted");
        }
        assert!(Instant::now() < deadline, "no shard appeared");
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let complete = complete_shards(d.path());
    assert!(complete.len() < 5, "the run was interrupted before the end");
    // Every complete-looking shard really is complete: identical to the reference.
    for f in &complete {
        assert!(std::fs::read(d.path().join(f)).unwrap() == std::fs::read(reference_dataset().join(f)).unwrap(), "{f}");
    }
    // Without --resume the directory is not silently reused.
    let o = run_generate(&tiny_config(), d.path(), &[]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--resume"), "{}", stderr(&o));
    generate(&tiny_config(), d.path(), &["--resume"]);
    assert!(files_named(d.path(), |n| n.ends_with(".partial")).is_empty());
    let a = files(reference_dataset());
    let b = files(d.path());
    assert_eq!(a.iter().map(|f| &f.0).collect::<Vec<_>>(), b.iter().map(|f| &f.0).collect::<Vec<_>>());
    for (fa, fb) in a.iter().zip(&b) {
        assert!(fa.1 == fb.1, "{} differs after resume", fa.0);
    }
}

//! Bad input gets a clear error naming the file/line/field or path, a non-zero exit, and leaves
//! no complete-looking output.

use std::path::Path;

use crate::common::*;

/// Writes `yaml` as a config next to a fresh output dir, runs generate, and checks the failure.
fn fails(yaml: &str, expect: &[&str]) -> String {
    let d = tempdir();
    let cfg = d.path().join("bad.yaml");
    std::fs::write(&cfg, yaml).unwrap();
    let out = d.path().join("out");
    let o = run_generate(&cfg, &out, &[]);
    let err = stderr(&o);
    assert!(!o.status.success(), "must fail: {yaml}");
    assert_eq!(err.lines().count(), 1, "one clear line: {err}");
    assert!(err.starts_with("error: "), "{err}");
    for e in expect {
        assert!(err.contains(e), "'{e}' missing from: {err}");
    }
    assert_nothing_complete(&out);
    err
}

fn assert_nothing_complete(out: &Path) {
    assert!(complete_shards(out).is_empty(), "no shard may look complete");
    assert!(!out.join("manifest.json").exists(), "no manifest");
}

fn tiny_with(from: &str, to: &str) -> String {
    let text = std::fs::read_to_string(tiny_config()).unwrap();
    assert!(text.contains(from), "tiny.yaml contains {from}");
    text.replacen(from, to, 1)
}

fn line_of(yaml: &str, needle: &str) -> usize {
    yaml.lines().position(|l| l.contains(needle)).unwrap() + 1
}

#[test]
fn malformed_yaml_names_file_and_line() {
    let y = tiny_with("seed: 7", "seed: [7");
    let line = line_of(&y, "seed: [7");
    let e = fails(&y, &["bad.yaml:"]);
    // The parser reports where the flow sequence breaks, at or after its start.
    let reported: usize = e.split("bad.yaml:").nth(1).unwrap().split(':').next().unwrap().parse().unwrap();
    assert!(reported >= line, "{e}");
}

#[test]
fn an_unknown_key_names_file_line_and_key() {
    let y = tiny_with("camera:\n", "camera:\n  focal: 3\n");
    let line = line_of(&y, "focal: 3");
    fails(&y, &[&format!("bad.yaml:{line}:3: "), "unknown field `focal`"]);
}

#[test]
fn an_out_of_range_value_names_the_field_and_the_range() {
    let y = tiny_with("width: 640", "width: 0");
    let line = line_of(&y, "width: 0");
    fails(&y, &[&format!("bad.yaml:{line}:3: camera.width: 0 is out of range: allowed 8 ..= 8192")]);
    let y = tiny_with("fx: 615.0", "fx: -615.0");
    let line = line_of(&y, "fx: -615.0");
    fails(&y, &[&format!("bad.yaml:{line}:"), "camera.intrinsics.fx: -615 is out of range"]);
    let y = tiny_with("zstd_level: 3", "zstd_level: 40");
    fails(&y, &["output.zstd_level: 40 is out of range: allowed 1 ..= 19"]);
}

#[test]
fn a_grasp_duration_or_finger_gain_out_of_range_names_the_field_and_line() {
    let hand = std::fs::read_to_string(tiny_config().with_file_name("tiny-hand.yaml")).unwrap();
    let grasp = "    max_tilt_deg: 50\n";
    assert!(hand.contains(grasp));
    let y = hand.replacen(grasp, &format!("{grasp}    move_seconds: -0.5\n"), 1);
    let line = line_of(&y, "move_seconds");
    fails(&y, &[&format!("bad.yaml:{line}:5: robot.grasp.move_seconds: -0.5 is out of range: allowed 0 < move_seconds <= 60 s")]);
    let y = hand.replacen("timestep: 0.0041667}", "timestep: 0.0041667, max_torque: 0}", 1);
    let line = line_of(&y, "max_torque");
    fails(&y, &[&format!("bad.yaml:{line}:"), "robot.physics.max_torque: 0 is out of range: allowed 0 < max_torque <= 1000 N·m"]);
}

#[test]
fn a_wrong_type_names_the_field() {
    let y = tiny_with("trajectories_per_object: 5", "trajectories_per_object: many");
    let line = line_of(&y, "many");
    fails(&y, &[&format!("bad.yaml:{line}:"), "sampling.trajectories_per_object: invalid type"]);
}

#[test]
fn an_unknown_object_id_is_named_with_the_catalogue() {
    let y = tiny_with("- 005_tomato_soup_can", "- 005_tomato_soop_can");
    let line = line_of(&y, "soop");
    fails(&y, &[&format!("bad.yaml:{line}:5: objects[1]: unknown object id '005_tomato_soop_can'"), "003_cracker_box"]);
}

#[test]
fn a_missing_or_corrupt_mesh_names_the_path() {
    let y = tiny_with("- 005_tomato_soup_can", "- {id: thing, mesh: meshes/thing.obj}");
    fails(&y, &["meshes/thing.obj", "not found"]);

    let d = tempdir();
    std::fs::write(d.path().join("broken.obj"), "v 0 0 0\nv 1 0 0\nf 1 2 9\n").unwrap();
    let cfg = d.path().join("c.yaml");
    std::fs::write(&cfg, tiny_with("- 005_tomato_soup_can", "- {id: thing, mesh: broken.obj}")).unwrap();
    let o = run_generate(&cfg, &d.path().join("out"), &[]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("broken.obj"), "{}", stderr(&o));
    assert_nothing_complete(&d.path().join("out"));

    let ycb = tempdir();
    let o = run(&[
        "generate",
        tiny_config().to_str().unwrap(),
        "--ycb-dir",
        ycb.path().to_str().unwrap(),
        "--out",
        ycb.path().join("out").to_str().unwrap(),
        "--quiet",
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("003_cracker_box/google_16k/textured.obj"), "{}", stderr(&o));
}

#[test]
fn an_unwritable_output_directory_is_named() {
    let d = tempdir();
    let file = d.path().join("a-file");
    std::fs::write(&file, "x").unwrap();
    let out = file.join("out");
    let o = run_generate(&tiny_config(), &out, &[]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("cannot create output directory") && stderr(&o).contains("a-file/out"), "{}", stderr(&o));
}

#[test]
fn a_missing_config_and_a_bad_shard_selector_are_clear() {
    let o = run(&["generate", "nope.yaml"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("nope.yaml: cannot read config"), "{}", stderr(&o));
    let o = run(&["generate", tiny_config().to_str().unwrap(), "--shard", "2/2"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("0 <= i < N"), "{}", stderr(&o));
}

#[test]
fn a_different_config_never_mixes_into_an_existing_dataset() {
    let d = tempdir();
    generate(&tiny_config(), d.path(), &["--shard", "0/5"]);
    let cfg = d.path().join("other.yaml");
    std::fs::write(&cfg, tiny_with("seed: 7", "seed: 8")).unwrap();
    let o = run(&["generate", cfg.to_str().unwrap(), "--out", d.path().to_str().unwrap(), "--resume", "--quiet"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("different config"), "{}", stderr(&o));
}

#[test]
fn plan_prints_the_dataset_and_writes_nothing() {
    let o = run(&["plan", tiny_config().to_str().unwrap()]);
    assert!(o.status.success());
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("2 objects x 5 trajectories x 4 instances = 40"), "{text}");
    assert!(text.contains("train       32 samples in 4 shard(s)"), "{text}");
    assert!(text.contains("test        8 samples in 1 shard(s)"), "{text}");
}

/// An adapter that cannot render the float depth/mask targets (Mesa's GL llvmpipe) is refused with
/// a line that says what to install, not a wgpu panic. Where the GL adapter can render them (a real
/// GPU), the run simply succeeds.
#[test]
fn an_adapter_without_float_targets_gets_a_clear_error() {
    let d = tempdir();
    let cfg = d.path().join("gl.yaml");
    let text = std::fs::read_to_string(tiny_config()).unwrap();
    std::fs::write(&cfg, format!("{text}\nrenderer:\n  backend: gl\n")).unwrap();
    let out = d.path().join("out");
    let o = run_generate(&cfg, &out, &[]);
    let err = stderr(&o);
    assert!(!err.contains("panicked"), "{err}");
    if !o.status.success() {
        assert!(err.starts_with("error: ") && err.lines().count() == 1, "one clear line: {err}");
        assert!(err.contains("R32Float") || err.contains("no graphics adapter"), "{err}");
        assert!(complete_shards(&out).is_empty(), "no shard may look complete");
    }
}

/// `objects:` alone generates (the paper's defaults fill the rest), `--set` sizes it down, `vtgen
/// config` prints what was resolved, and a bad override is one line naming the override.
#[test]
fn a_config_of_only_objects_generates_and_set_overrides_it() {
    let d = tempdir();
    let cfg = d.path().join("mine.yaml");
    std::fs::write(&cfg, "objects: [005_tomato_soup_can]\n").unwrap();
    let cfg = cfg.to_str().unwrap();
    let small =
        ["--set", "sampling.trajectories_per_object=1", "--set", "sampling.instances_per_trajectory=2", "--set", "camera.width=160"];
    let o = run(&[&["config", cfg][..], &small].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let resolved = String::from_utf8_lossy(&o.stdout).to_string();
    for line in ["trajectories_per_object: 1", "instances_per_trajectory: 2", "width: 160", "height: 480", "dir: out/mine"] {
        assert!(resolved.contains(line), "{line} missing from:\n{resolved}");
    }
    let out = d.path().join("out");
    let o = run(&[&["generate", cfg, "--out", out.to_str().unwrap(), "--quiet"][..], &small].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let manifest: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest["complete"], true);
    let samples: u64 = ["train", "test"].iter().map(|s| manifest["splits"][s]["samples"].as_u64().unwrap_or(0)).sum();
    assert_eq!(samples, 2);
    let o = run(&["plan", cfg, "--set", "camera.width=wide"]);
    let err = stderr(&o);
    assert!(!o.status.success());
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.starts_with("error: --set camera.width=wide: camera.width: invalid type: string \"wide\""), "{err}");
    let o = run(&["inspect", out.to_str().unwrap(), "--set", "seed=1"]);
    assert!(!o.status.success() && stderr(&o).contains("--set overrides a config's keys"), "{}", stderr(&o));
}

/// A full disk (here the file size limit, RLIMIT_FSIZE at 1 MiB, which fails a shard's write as a
/// full disk does): one line naming the shard and the bytes it needs, no shard that looks
/// complete and no `.partial` left; `--resume` afterwards completes byte-identical to a run that
/// never failed. Unix only: the file size limit stands in for the full disk.
#[cfg(unix)]
#[test]
fn a_full_disk_stops_cleanly_and_resume_completes_byte_identical() {
    use std::os::unix::process::CommandExt;
    let d = tempdir();
    let out = d.path().join("out");
    let config = tiny_config();
    let mut cmd = vtgen();
    cmd.args(["generate", config.to_str().unwrap(), "--out", out.to_str().unwrap(), "--quiet"]);
    // SAFETY: only async-signal-safe calls between fork and exec.
    unsafe {
        cmd.pre_exec(|| {
            // Past the limit a write fails with EFBIG instead of killing the process.
            libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
            let limit = libc::rlimit { rlim_cur: 1 << 20, rlim_max: 1 << 20 };
            if libc::setrlimit(libc::RLIMIT_FSIZE, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let o = cmd.output().unwrap();
    let err = stderr(&o);
    assert!(!o.status.success(), "must fail: {err}");
    assert_eq!(err.lines().count(), 1, "one line: {err}");
    assert!(err.starts_with("error: the disk is full writing "), "{err}");
    assert!(err.contains("shard-00000.mcap: this shard needs about ") && err.contains("--resume"), "{err}");
    assert!(complete_shards(&out).is_empty(), "no complete-looking shard");
    assert!(files_named(&out, |n| n.ends_with(".partial")).is_empty(), "the unfinished shard's bytes are freed");
    generate(&tiny_config(), &out, &["--resume"]);
    let (a, b) = (files(&out), files(reference_dataset()));
    assert_eq!(a.iter().map(|f| &f.0).collect::<Vec<_>>(), b.iter().map(|f| &f.0).collect::<Vec<_>>());
    for ((name, x), (_, y)) in a.iter().zip(&b) {
        assert!(x == y, "{name} differs from an uninterrupted run");
    }
    eprintln!("{err}");
}

/// A YCB download for `scenes/tiny.yaml`'s two objects (boxes, in metres) in YCB's layout.
fn small_ycb_download(dir: &Path) {
    for (id, half) in [("003_cracker_box", [0.08, 0.03, 0.1]), ("005_tomato_soup_can", [0.034, 0.034, 0.05])] {
        let d = dir.join(id).join("google_16k");
        std::fs::create_dir_all(&d).unwrap();
        let mut obj = String::new();
        for k in 0..8 {
            let s = |bit: usize, h: f64| if k & bit == 0 { -h } else { h };
            obj += &format!("v {} {} {}\n", s(1, half[0]), s(2, half[1]), s(4, half[2]));
        }
        // The six faces, counter-clockwise seen from outside (vertex k has bits x=1, y=2, z=4).
        for f in ["1 3 4 2", "5 6 8 7", "1 2 6 5", "3 7 8 4", "1 5 7 3", "2 4 8 6"] {
            obj += &format!("f {f}\n");
        }
        std::fs::write(d.join("textured.obj"), obj).unwrap();
    }
}

/// `--shard 0/2` with real meshes, then `--shard 1/2` or `--resume` without them (a node without
/// the YCB download): refused with one line naming both sources, `models/` untouched; the same
/// download from another directory is the same source and completes the dataset.
#[test]
fn shards_of_other_mesh_sources_never_mix_into_a_dataset() {
    let d = tempdir();
    let (out, ycb) = (d.path().join("out"), d.path().join("ycb"));
    small_ycb_download(&ycb);
    generate(&tiny_config(), &out, &["--shard", "0/2", "--ycb-dir", ycb.to_str().unwrap()]);
    let models = files(&out.join("models"));
    let shards = complete_shards(&out);
    let config = tiny_config();
    let args = |extra: &[&str]| {
        let mut a = vec!["generate", config.to_str().unwrap(), "--out", out.to_str().unwrap(), "--quiet"];
        a.extend_from_slice(extra);
        run(&a)
    };
    for extra in [&["--shard", "1/2"][..], &["--resume"]] {
        let o = args(extra);
        let err = stderr(&o);
        assert!(!o.status.success(), "{extra:?} must be refused");
        assert_eq!(err.lines().count(), 1, "one clear line: {err}");
        assert!(err.contains("meshes came from other sources"), "{err}");
        assert!(err.contains("dataset mesh 003_cracker_box/google_16k/textured.obj"), "names the dataset's source: {err}");
        assert!(err.contains("this run procedural stand-in"), "names the run's source: {err}");
        assert_eq!(files(&out.join("models")), models, "models/ is never rewritten from another source");
        assert_eq!(complete_shards(&out), shards, "no shard of another source");
    }
    // The same meshes from another directory: the same source.
    let copy = d.path().join("ycb-copy");
    small_ycb_download(&copy);
    let o = args(&["--resume", "--ycb-dir", copy.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let m = vt_dataset::Manifest::load(&out.join("manifest.json")).unwrap();
    assert!(m.complete);
    let o = run(&["validate", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stdout) + stderr(&o).as_str());
}

/// An object the parallel-jaw gripper can never hold (a 10 cm cube; the 2F-85 opens 85 mm) is
/// refused before anything is written, named with why and what to do.
#[test]
fn an_object_the_gripper_cannot_hold_is_refused_before_the_run() {
    let d = tempdir();
    let corners: Vec<(f64, f64, f64)> = (0..8)
        .map(|i| (if i & 4 == 0 { -0.05 } else { 0.05 }, if i & 2 == 0 { -0.05 } else { 0.05 }, if i & 1 == 0 { -0.05 } else { 0.05 }))
        .collect();
    let faces = [(1, 2, 4, 3), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 3, 7, 5), (2, 6, 8, 4)];
    let mut obj: String = corners.iter().map(|(x, y, z)| format!("v {x} {y} {z}\n")).collect();
    obj += &faces.iter().map(|(a, b, c, e)| format!("f {a} {b} {c}\nf {a} {c} {e}\n")).collect::<String>();
    let mesh = d.path().join("cube.obj");
    std::fs::write(&mesh, obj).unwrap();
    let out = d.path().join("out");
    let set = format!("objects=[009_gelatin_box, {{id: big_cube, mesh: {}, mass: 0.3}}]", mesh.display());
    let o = run_generate(&root().join("scenes/tiny-gripper.yaml"), &out, &["--set", &set]);
    let e = stderr(&o);
    assert!(!o.status.success(), "a run with an unholdable object started");
    assert!(e.contains("big_cube is at least 100.0 mm wide in every direction") && e.contains("Leave it out of `objects`"), "{e}");
    assert!(!out.join("config.json").exists(), "something was written before the refusal");
}

//! `vtgen bench`'s figures hang together: the CPU outside the rasterizer is the sum of its parts
//! and no more than the process's CPU, the physics steps and their cost are counted, and
//! `--predict-cores` is N over that CPU (and, as a lower bound, over it plus the renderer's calls). (No wall-clock expectations: those depend on the machine.)

use crate::common::{root, run, stderr};

#[test]
fn bench_reports_cpu_outside_the_rasterizer_and_predicts_from_it() {
    let config = root().join("scenes/tiny-hand.yaml");
    let o = run(&["bench", config.to_str().unwrap(), "--samples", "4", "--jobs", "1", "--predict-cores", "16", "--per-pass", "--json"]);
    assert!(o.status.success(), "vtgen bench failed: {}", stderr(&o));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).expect("bench --json prints JSON");
    let f = |k: &str| r[k].as_f64().unwrap_or_else(|| panic!("no number {k} in {r}"));
    let samples = f("samples");
    assert!(samples > 0.0);
    // The robot config simulates its grasp loop: steps are counted, each with some CPU.
    assert!(f("physics_steps") > 0.0 && f("physics_seconds_per_step") > 0.0, "{r}");
    assert!((f("physics_seconds_per_step") * f("physics_steps") - f("physics_cpu")).abs() < 1e-9, "{r}");
    let parts = f("physics_cpu") + f("other_cpu") + f("readback") + f("writer_cpu");
    assert!((f("cpu_outside_rasterizer") - parts).abs() < 1e-9, "the outside CPU is not the sum of its parts: {r}");
    assert!(f("writer_cpu") > 0.0 && f("other_cpu") > 0.0, "{r}");
    if cfg!(all(target_os = "linux", target_env = "gnu")) {
        // Thread CPU times inside the run cannot exceed the whole process's (1 ms of clock slack).
        assert!(f("process_cpu") + 1e-3 >= f("cpu_outside_rasterizer"), "{r}");
    }
    // Cores busy: the process's CPU over the run's wall time.
    assert!((f("cores_busy") - f("process_cpu") / f("seconds")).abs() < 1e-9 * f("cores_busy").max(1.0), "{r}");
    let predicted = r["predicted"].as_array().expect("--predict-cores gives a prediction");
    assert_eq!(predicted[0].as_u64(), Some(16));
    let rate = predicted[1].as_f64().unwrap();
    assert!((rate - 16.0 * samples / f("cpu_outside_rasterizer")).abs() < 1e-6 * rate, "{r}");
    // The lower bound keeps the renderer's calls on the CPU too.
    let low = f("predicted_with_render_calls");
    assert!(f("render_call_cpu") > 0.0 && low < rate, "{r}");
    assert!((low - 16.0 * samples / (f("cpu_outside_rasterizer") + f("render_call_cpu"))).abs() < 1e-6 * low, "{r}");
    assert!(f("bytes_per_sample") > 0.0, "{r}");
    // The grasp loop's attempts per kept trajectory: at least one, for the object it made samples of.
    let attempts = r["attempts_per_kept"].as_object().expect("a robot config reports attempts per kept trajectory");
    assert!(!attempts.is_empty() && attempts.values().all(|a| a.as_f64().unwrap() >= 1.0), "{r}");
    // --per-pass: the main camera's and the pads' passes, each timed.
    let passes = r["render_passes"].as_object().expect("--per-pass times the render passes");
    for pass in ["main views", "depth views", "copy and map"] {
        assert!(passes.get(pass).and_then(|s| s.as_f64()).is_some_and(|s| s > 0.0), "{pass}: {r}");
    }
}

#[test]
fn bench_refuses_zero_cores() {
    let config = root().join("scenes/tiny.yaml");
    let o = run(&["bench", config.to_str().unwrap(), "--samples", "1", "--predict-cores", "0"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--predict-cores"), "{}", stderr(&o));
}

//! The tracking benchmark end to end on a tiny episode dataset (`scenes/tiny-hand.yaml` recorded as
//! episodes at 10 Hz, two test episodes per object), generated once per test binary with the
//! generator library: two barely trained networks tracked over every test frame, the report's
//! files and structure, the numbers recomputed from its per-frame scores, determinism, and the
//! errors for bad input.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use common::{generate, small_config};
use vt_trainer::device::cpu;
use vt_trainer::eval::metrics::auc;
use vt_trainer::model::Variant;
use vt_trainer::track::filter::FilterConfig;
use vt_trainer::track::report::write_tracking_report;
use vt_trainer::track::{TouchSource, TrackOptions, track_runs};
use vt_trainer::train::{TrainOptions, train};

/// A small camera: the tests read every frame.
const SMALL_CAMERA: [&str; 3] = ["camera.width=320", "camera.height=240", "camera.intrinsics={fx: 307.5, fy: 307.5, cx: 159.5, cy: 119.5}"];

/// 2 objects x 4 episodes of one arm move at 10 Hz; trajectories 1 and 3 of each object are the
/// test episodes.
fn episodes() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let mut o = vec![
            "sampling.trajectories_per_object=4",
            "sampling.instances_per_trajectory=1",
            "sampling.split={train: 1, test: 1}",
            "sampling.record={camera_hz: 10, tactile_hz: 10, state_hz: 10}",
        ];
        o.extend(SMALL_CAMERA);
        generate("tracking-episodes", &o)
    })
}

/// A network trained for one epoch on 8 train frames: it does not have to be good.
fn trained(variant: Variant) -> &'static Path {
    static RUNS: OnceLock<(tempfile::TempDir, BTreeMap<String, PathBuf>)> = OnceLock::new();
    let (_, runs) = RUNS.get_or_init(|| {
        let dir = tempfile::Builder::new().prefix("vtpose-tracking-runs-").tempdir().unwrap();
        let mut runs = BTreeMap::new();
        for v in [Variant::TactileChannel, Variant::VisionOnly] {
            let c = small_config(episodes(), v, 1);
            let out = dir.path().join(v.to_string());
            train(&c, &TrainOptions { out: out.clone(), resume: false, overwrite: false, device: cpu(), quiet: true }).unwrap();
            runs.insert(v.to_string(), out);
        }
        (dir, runs)
    });
    &runs[&variant.to_string()]
}

fn options() -> TrackOptions {
    TrackOptions {
        dataset: None,
        split: "test".into(),
        max_episodes: 0,
        filter: FilterConfig::default(),
        touch_control: true,
        refine: None,
        device: cpu(),
        quiet: true,
    }
}

fn csv(path: &Path) -> Vec<BTreeMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(str::to_string).collect();
    lines.map(|l| header.iter().cloned().zip(l.split(',').map(str::to_string)).collect()).collect()
}

#[test]
fn tracking_scores_every_test_frame_from_the_networks_estimates() {
    let runs = [trained(Variant::TactileChannel).to_path_buf(), trained(Variant::VisionOnly).to_path_buf()];
    let names = ["tactile".to_string(), "vision".to_string()];
    let t = track_runs(&runs, &names, &options()).unwrap();

    // The test episodes: trajectories 1 and 3 of each object, frames in time order, each lending
    // its touch to the other episode of its object.
    assert_eq!(t.episodes.len(), 4);
    for (i, e) in t.episodes.iter().enumerate() {
        assert!(e.trajectory % 2 == 1, "{} is a train trajectory", e.trajectory);
        assert!(e.frames.len() >= 3, "an episode of one arm move at 10 Hz has several frames");
        assert!(e.frames.windows(2).all(|w| w[1].time_s > w[0].time_s && w[1].frame == w[0].frame + 1));
        assert!((e.frames[1].time_s - e.frames[0].time_s - 0.1).abs() < 1e-6, "10 Hz");
        let d = e.donor.expect("two test episodes per object");
        assert!(d != i && t.episodes[d].object == e.object);
    }
    // The tactile network: per frame, filtered, and both with another episode's touch; the
    // vision-only network: per frame and filtered.
    let labels: Vec<&str> = t.methods.iter().map(|m| m.label.as_str()).collect();
    assert_eq!(
        labels,
        [
            "tactile per frame",
            "tactile + filter",
            "tactile (other episode's touch) per frame",
            "tactile (other episode's touch) + filter",
            "vision per frame",
            "vision + filter"
        ]
    );
    let frames: usize = t.episodes.iter().map(|e| e.frames.len()).sum();
    for m in &t.methods {
        let s = m.summary();
        assert_eq!((s.episodes, s.frames), (4, frames), "{}", m.label);
        assert!(s.adds_auc.mean.is_finite() && (0.0..=100.0).contains(&s.adds_auc.mean), "{}: {:?}", m.label, s.adds_auc);
    }
    // The filter changes the estimates; another episode's touch changes the tactile network's.
    let adds = |k: usize| t.methods[k].episodes.iter().flat_map(|e| e.frames.iter().map(|f| f.adds_m)).collect::<Vec<_>>();
    assert_ne!(adds(0), adds(1), "the filter left every estimate as it was");
    assert_ne!(adds(0), adds(2), "another episode's touch changed nothing");
    assert_eq!(t.methods[2].touch, TouchSource::OtherEpisode);

    // The report: its files, its sections, and its numbers recomputed from frames.csv.
    let out = tempfile::tempdir().unwrap();
    let report = write_tracking_report(&t, "cpu", out.path()).unwrap();
    let md = std::fs::read_to_string(&report).unwrap();
    for section in ["## Overall", "## ADD-S AUC per object", "## ADD-S AUC per occlusion level", "## Error and occlusion against time"] {
        assert!(md.contains(section), "tracking.md lacks {section}:\n{md}");
    }
    for label in &labels {
        assert!(md.contains(&format!("| {label} |")), "tracking.md has no row for {label}");
    }
    for file in ["tracking.json", "episodes.csv", "frames.csv", "error-time.svg", "occlusion-time.svg"] {
        assert!(out.path().join(file).is_file(), "{file} was not written");
    }
    let svg = std::fs::read_to_string(out.path().join("error-time.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("tactile + filter"));
    let frame_rows = csv(&out.path().join("frames.csv"));
    assert_eq!(frame_rows.len(), frames * labels.len());
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.path().join("tracking.json")).unwrap()).unwrap();
    for (k, label) in labels.iter().enumerate() {
        // Each episode's AUC from its frames' ADD-S (a frame without a pose: a failure).
        let mut per_episode: BTreeMap<(String, String), Vec<f64>> = BTreeMap::new();
        for r in frame_rows.iter().filter(|r| r["method"] == *label) {
            let e = r["adds_m"].parse().unwrap_or(f64::INFINITY);
            per_episode.entry((r["object"].clone(), r["trajectory"].clone())).or_default().push(e);
        }
        let aucs: Vec<f64> = per_episode.values().map(|e| auc(e, 0.10)).collect();
        let mean = aucs.iter().sum::<f64>() / aucs.len() as f64;
        let reported = json["methods"][k]["summary"]["adds_auc"]["mean"].as_f64().unwrap();
        assert!((mean - reported).abs() < 1e-4, "{label}: AUC {reported} reported, {mean} from frames.csv");
        let row = md.lines().find(|l| l.starts_with(&format!("| {label} |"))).unwrap();
        assert!(row.contains(&format!("| {mean:.1} ±")), "{label}: tracking.md row {row}, AUC from frames {mean:.1}");
        let rows: Vec<_> = csv(&out.path().join("episodes.csv")).into_iter().filter(|r| r["method"] == *label).collect();
        assert_eq!(rows.len(), 4);
    }

    // The same runs and options give the same numbers.
    let again = track_runs(&runs, &names, &options()).unwrap();
    let out2 = tempfile::tempdir().unwrap();
    write_tracking_report(&again, "cpu", out2.path()).unwrap();
    assert_eq!(
        std::fs::read_to_string(out.path().join("frames.csv")).unwrap(),
        std::fs::read_to_string(out2.path().join("frames.csv")).unwrap(),
        "tracking is not deterministic"
    );
}

#[test]
fn bad_input_gets_an_error_naming_it() {
    let tactile = trained(Variant::TactileChannel).to_path_buf();
    let name = ["tactile".to_string()];
    let message = |runs: &[PathBuf], opts: &TrackOptions| format!("{:#}", track_runs(runs, &name, opts).unwrap_err());

    // A run directory without a trained network.
    let empty = tempfile::tempdir().unwrap();
    let e = message(&[empty.path().to_path_buf()], &options());
    assert!(e.contains("model.bpk") && e.contains(&empty.path().display().to_string()), "{e}");

    // A snapshot dataset where episodes are needed.
    let mut o = vec!["sampling.trajectories_per_object=2", "sampling.instances_per_trajectory=1", "sampling.split={train: 1, test: 1}"];
    o.extend(SMALL_CAMERA);
    let snapshots = generate("tracking-snapshots", &o);
    let e = message(std::slice::from_ref(&tactile), &TrackOptions { dataset: Some(snapshots.clone()), ..options() });
    assert!(e.contains("snapshot shard") && e.contains("sampling.record") && e.contains(&snapshots.display().to_string()), "{e}");

    // A split the dataset does not have, and filter parameters out of range.
    let e = message(std::slice::from_ref(&tactile), &TrackOptions { split: "validation".into(), ..options() });
    assert!(e.contains("validation"), "{e}");
    let e = message(&[tactile], &TrackOptions { filter: FilterConfig { alpha: 1.5, ..FilterConfig::default() }, ..options() });
    assert!(e.contains("alpha"), "{e}");
}

/// Tracking with the refiner: alone (no run, the dataset named) and from a network's estimates,
/// each with depth, touch and another episode's touch, on every test frame; the refiner alone
/// tracks most frames to within 2 cm on this exact synthetic depth.
#[test]
fn the_refiner_tracks_alone_and_from_a_network() {
    use vt_trainer::refine::RefineConfig;
    let opts = TrackOptions { dataset: Some(episodes().to_path_buf()), refine: Some(RefineConfig::default()), ..options() };
    let t = track_runs(&[], &[], &opts).unwrap();
    let labels: Vec<&str> = t.methods.iter().map(|m| m.label.as_str()).collect();
    assert_eq!(labels, ["refine (depth)", "refine (depth + touch)", "refine (depth + other episode's touch)"]);
    assert!(t.methods.iter().all(|m| m.refined && m.variant.is_none()));
    let frames: usize = t.episodes.iter().map(|e| e.frames.len()).sum();
    let s = t.methods[1].summary();
    assert_eq!((s.episodes, s.frames), (4, frames));
    assert!(s.adds_below_2cm > 50.0, "the refiner with touch tracks {:.0} % of the frames within 2 cm ADD-S", s.adds_below_2cm);
    let out = tempfile::tempdir().unwrap();
    let report = write_tracking_report(&t, "cpu", out.path()).unwrap();
    let md = std::fs::read_to_string(report).unwrap();
    assert!(md.contains("| refine (depth + touch) |"), "{md}");

    // From a network: its per-frame methods, then its refined ones, then the refiner alone.
    let runs = [trained(Variant::TactileChannel).to_path_buf()];
    let t = track_runs(&runs, &["tactile".to_string()], &TrackOptions { touch_control: false, ..opts }).unwrap();
    let labels: Vec<&str> = t.methods.iter().map(|m| m.label.as_str()).collect();
    assert_eq!(
        labels,
        [
            "tactile per frame",
            "tactile + filter",
            "tactile + refine (depth)",
            "tactile + refine (depth + touch)",
            "tactile + refine (depth + other episode's touch)",
            "refine (depth)",
            "refine (depth + touch)",
            "refine (depth + other episode's touch)"
        ]
    );
}

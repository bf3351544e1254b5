//! `vtgen stats DATASET --out DIR`: what a dataset covers, as SVG plots and a Markdown page that
//! ties them together: object positions in the camera frame, rotation coverage, occlusion levels
//! (with the paper's bins), tactile points per sample and contacts per touch link.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result, anyhow};
use glam::DVec3;
use plotters::prelude::*;
use vt_dataset::{DatasetReader, OcclusionBin};

use crate::cli::inspect::{Inspection, inspect};

/// What the plots are made of: one entry per sample.
#[derive(Debug, Default)]
struct Collected {
    /// Object position in the camera frame, metres.
    positions: Vec<DVec3>,
    /// The object's model z and x axes in the camera frame.
    z_axes: Vec<DVec3>,
    x_axes: Vec<DVec3>,
    occlusion: Vec<f64>,
    tactile_points: Vec<u64>,
    /// Per touch link (e.g. the links of a hand), by name: samples in contact.
    contacts: Vec<(String, u64)>,
}

fn collect(root: &Path) -> Result<Collected> {
    let ds = DatasetReader::open(root)?;
    let mut c = Collected::default();
    // The robot's touch links as the samples name them (any robot: the dataset says which).
    let mut contacts = std::collections::BTreeMap::<String, u64>::new();
    super::for_each_info(&ds, |_, info| {
        let pose = info.t_camera_object;
        c.positions.push(pose.translation());
        c.z_axes.push(pose.rotation() * DVec3::Z);
        c.x_axes.push(pose.rotation() * DVec3::X);
        if let Some(o) = &info.occlusion {
            c.occlusion.push(o.level);
        }
        c.tactile_points.extend(info.tactile_points());
        for p in info.links_in_contact() {
            *contacts.entry(p.clone()).or_default() += 1;
        }
        Ok(())
    })?;
    c.contacts = contacts.into_iter().collect();
    Ok(c)
}

/// plotters' errors carry the backend's error type; one message is all a user needs.
fn plot_err<E: std::fmt::Display>(e: E) -> anyhow::Error {
    anyhow!("drawing a plot: {e}")
}

fn range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return 0.0..1.0;
    }
    let pad = ((hi - lo) * 0.05).max(0.5);
    (lo - pad)..(hi + pad)
}

/// Object positions in the camera frame: top view (x, z) and image-plane view (x, y), in cm.
fn plot_positions(c: &Collected, path: &Path) -> Result<()> {
    let root = SVGBackend::new(path, (960, 440)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let (left, right) = root.split_horizontally(480);
    let cm: Vec<DVec3> = c.positions.iter().map(|p| *p * 100.0).collect();
    for (area, name, y_of) in [
        (&left, "top view: z (cm, forward)", (|p: &DVec3| p.z) as fn(&DVec3) -> f64),
        (&right, "image plane: y (cm, down)", (|p: &DVec3| p.y) as fn(&DVec3) -> f64),
    ] {
        let mut chart = ChartBuilder::on(area)
            .caption(format!("object position in the camera frame ({} samples)", cm.len()), ("sans-serif", 16))
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(48)
            .build_cartesian_2d(range(cm.iter().map(|p| p.x)), range(cm.iter().map(y_of)))
            .map_err(plot_err)?;
        chart.configure_mesh().x_desc("x (cm, right)").y_desc(name).draw().map_err(plot_err)?;
        chart.draw_series(cm.iter().map(|p| Circle::new((p.x, y_of(p)), 2, BLUE.mix(0.5).filled()))).map_err(plot_err)?;
    }
    root.present().map_err(plot_err)
}

/// Rotation coverage: where the object's z and x axes point in the camera frame, on an equal-area
/// map (azimuth, sin elevation), so uniformly random rotations fill it evenly.
fn plot_rotations(c: &Collected, path: &Path) -> Result<()> {
    let root = SVGBackend::new(path, (720, 420)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption("rotation coverage: model axes in the camera frame (equal-area map)", ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(48)
        .build_cartesian_2d(-180.0..180.0, -1.0..1.0)
        .map_err(plot_err)?;
    chart.configure_mesh().x_desc("azimuth atan2(y, x) (deg)").y_desc("camera-frame z component").draw().map_err(plot_err)?;
    let map = |d: &DVec3| (d.y.atan2(d.x).to_degrees(), d.z.clamp(-1.0, 1.0));
    chart
        .draw_series(c.z_axes.iter().map(|d| Circle::new(map(d), 2, BLUE.mix(0.5).filled())))
        .map_err(plot_err)?
        .label("model z axis")
        .legend(|(x, y)| Circle::new((x, y), 3, BLUE.filled()));
    chart
        .draw_series(c.x_axes.iter().map(|d| Circle::new(map(d), 2, RED.mix(0.4).filled())))
        .map_err(plot_err)?
        .label("model x axis")
        .legend(|(x, y)| Circle::new((x, y), 3, RED.filled()));
    chart.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw().map_err(plot_err)?;
    root.present().map_err(plot_err)
}

/// How a histogram looks: `bins` bins over [lo, hi), captions, and vertical markers at `markers`.
struct HistogramStyle<'a> {
    lo: f64,
    hi: f64,
    bins: usize,
    caption: &'a str,
    x_desc: &'a str,
    markers: &'a [f64],
}

/// A histogram of `values`.
fn plot_histogram(values: &[f64], style: &HistogramStyle, path: &Path) -> Result<()> {
    let HistogramStyle { lo, hi, bins, caption, x_desc, markers } = *style;
    let mut counts = vec![0u64; bins];
    let w = (hi - lo) / bins as f64;
    for v in values {
        let k = (((v - lo) / w).floor().max(0.0) as usize).min(bins - 1);
        counts[k] += 1;
    }
    let top = counts.iter().copied().max().unwrap_or(0).max(1) as f64 * 1.1;
    let root = SVGBackend::new(path, (720, 400)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(caption, ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(48)
        .build_cartesian_2d(lo..hi, 0.0..top)
        .map_err(plot_err)?;
    chart.configure_mesh().x_desc(x_desc).y_desc("samples").draw().map_err(plot_err)?;
    chart
        .draw_series(counts.iter().enumerate().map(|(k, &n)| {
            let x0 = lo + k as f64 * w;
            Rectangle::new([(x0 + w * 0.05, 0.0), (x0 + w * 0.95, n as f64)], BLUE.mix(0.7).filled())
        }))
        .map_err(plot_err)?;
    for &m in markers {
        chart.draw_series(LineSeries::new([(m, 0.0), (m, top)], RED.stroke_width(2))).map_err(plot_err)?;
    }
    root.present().map_err(plot_err)
}

/// Share of samples in which each touch link touches the object.
fn plot_contacts(c: &Collected, samples: usize, path: &Path) -> Result<()> {
    let root = SVGBackend::new(path, (840, 400)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let n = c.contacts.len();
    let names: Vec<String> = c.contacts.iter().map(|(k, _)| k.clone()).collect();
    let mut chart = ChartBuilder::on(&root)
        .caption("touch links in contact with the object (share of samples)", ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(48)
        .build_cartesian_2d(0.0..n as f64, 0.0..1.05)
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_labels(n)
        .x_label_formatter(&|x| names.get(x.floor() as usize).map(|s| s.replace('_', " ")).unwrap_or_default())
        .y_desc("share of samples")
        .draw()
        .map_err(plot_err)?;
    chart
        .draw_series(c.contacts.iter().enumerate().map(|(k, (_, v))| {
            let share = *v as f64 / samples.max(1) as f64;
            Rectangle::new([(k as f64 + 0.1, 0.0), (k as f64 + 0.9, share)], GREEN.mix(0.7).filled())
        }))
        .map_err(plot_err)?;
    root.present().map_err(plot_err)
}

/// Writes the plots and `stats.md` into `out`; returns the files written.
pub fn write_stats(root: &Path, out: &Path) -> Result<Vec<String>> {
    let summary: Inspection = inspect(root)?;
    let c = collect(root)?;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let mut files = vec!["positions.svg".to_string(), "rotations.svg".into(), "occlusion.svg".into()];
    plot_positions(&c, &out.join("positions.svg"))?;
    plot_rotations(&c, &out.join("rotations.svg"))?;
    let occlusion = HistogramStyle {
        lo: 0.0,
        hi: 1.0,
        bins: 20,
        caption: "occlusion level (share of model points not visible); red: the paper's bins at 80% and 85%",
        x_desc: "occlusion level",
        markers: &OcclusionBin::BOUNDS,
    };
    plot_histogram(&c.occlusion, &occlusion, &out.join("occlusion.svg"))?;
    let touch = !c.tactile_points.is_empty();
    if touch {
        let pts: Vec<f64> = c.tactile_points.iter().map(|&v| v as f64).collect();
        let hi = pts.iter().copied().fold(1.0, f64::max) + 1.0;
        let style = HistogramStyle { lo: 0.0, hi, bins: 30, caption: "tactile points per sample", x_desc: "tactile points", markers: &[] };
        plot_histogram(&pts, &style, &out.join("tactile_points.svg"))?;
        plot_contacts(&c, c.positions.len(), &out.join("contacts.svg"))?;
        files.extend(["tactile_points.svg".to_string(), "contacts.svg".into()]);
    }

    let mut md = String::new();
    writeln!(md, "# Dataset statistics: `{}`\n", root.display())?;
    writeln!(
        md,
        "Made by `vtgen stats`. {} samples, {} of {} shards complete.\n",
        c.positions.len(),
        summary.shards_complete,
        summary.shards
    )?;
    writeln!(md, "| split | object | samples |\n|---|---|---|")?;
    for (split, objects) in &summary.samples {
        for (o, n) in objects {
            writeln!(md, "| {split} | {o} | {n} |")?;
        }
    }
    writeln!(md, "\n| figure | value |\n|---|---|")?;
    for (split, bins) in &summary.occlusion {
        for bin in OcclusionBin::ALL.map(OcclusionBin::key) {
            writeln!(md, "| occlusion {bin} ({split}) | {} |", bins.get(bin).copied().unwrap_or(0))?;
        }
    }
    writeln!(md, "| randomized share | {:.1}% |", 100.0 * summary.randomized_share)?;
    if let Some([lo, med, hi]) = summary.tactile_points {
        writeln!(md, "| tactile points per sample (min / median / max) | {lo} / {med} / {hi} |")?;
    }
    if let Some(g) = &summary.grasp {
        writeln!(md, "| grasps | `{g}` |")?;
    }
    writeln!(md, "\n## Object positions\n\n![positions](positions.svg)\n")?;
    writeln!(
        md,
        "## Rotation coverage\n\nWhere the model's z (blue) and x (red) axes point in the camera frame; the map is equal-area, so uniformly random orientations cover it evenly.\n\n![rotations](rotations.svg)\n"
    )?;
    writeln!(md, "## Occlusion\n\n![occlusion](occlusion.svg)\n")?;
    if touch {
        writeln!(md, "## Touch\n\n![tactile points](tactile_points.svg)\n\n![contacts](contacts.svg)\n")?;
    }
    vt_dataset::write_atomic(&out.join("stats.md"), md.as_bytes())?;
    files.push("stats.md".into());
    Ok(files)
}

/// `vtgen stats`: the statistics files, written to `out`.
pub fn run(dataset: &Path, out: &Path) -> Result<()> {
    let files = write_stats(dataset, out)?;
    println!("wrote {} files to {}: {}", files.len(), out.display(), files.join(", "));
    Ok(())
}

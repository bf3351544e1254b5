//! The optical tactile picture sheet of the docs: for a few grasps, one row per grasp with the pad's
//! depth view, its optical image with and without markers, and the same contact seen by two
//! randomized sensor units. The grasps are made once per sensor setting by the generator itself
//! (same seed, so the same grasp); only the optical sensor differs between columns.
//!
//! ```text
//! cargo run --release -p vtgen --example optical_sheet -- CONFIG OUT.png [--ycb-dir DIR] [--robot-assets DIR] [--rows N]
//! ```
//! CONFIG needs a robot with an `optical` pad (e.g. `scenes/tiny-gripper.yaml`).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use image::{Rgb, RgbImage};
use vtgen::assets::load_objects;
use vtgen::config::{LoadedConfig, OpticalSensor, Override};
use vtgen::plan::Plan;
use vtgen::render::WgpuRenderer;
use vtgen::sample::{SampleFactory, ShardTally};
use vtgen::sensors::optical::pixel_position;

/// The columns: a label and the config overrides of its sensor.
const COLUMNS: [(&str, &[&str]); 4] = [
    ("markers", &["robot.tactile.optical.markers={}", "randomization.tactile_sensors=null"]),
    ("no markers", &["robot.tactile.optical.markers=null", "randomization.tactile_sensors=null"]),
    // Two sensor units: every sample randomized, the units drawn from two sets of ranges.
    ("unit A", &["robot.tactile.optical.markers={}", "randomization.unrandomized_share=0", "randomization.tactile_sensors={}"]),
    (
        "unit B",
        &[
            "robot.tactile.optical.markers={}",
            "randomization.unrandomized_share=0",
            "randomization.tactile_sensors={led_color: 0.35, led_intensity: [0.6, 1.3], background: 0.2, elastic_spread: [1.5, 2.5], marker_pitch: [0.8, 0.9], vignetting: [0.2, 0.3]}",
        ],
    ),
];

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let flag = |name: &str| args.iter().position(|a| a == name).and_then(|i| args.get(i + 1)).map(PathBuf::from);
    let (Some(config), Some(out)) = (args.first(), args.get(1)) else {
        bail!("usage: optical_sheet CONFIG OUT.png [--ycb-dir DIR] [--robot-assets DIR] [--rows N]")
    };
    let rows: usize = flag("--rows").map_or(Ok(4), |r| r.to_string_lossy().parse()).context("--rows")?;
    let (ycb, assets) = (flag("--ycb-dir"), flag("--robot-assets"));
    // Per column: the samples of the rows (their first optical pad's depth view and image).
    let mut columns: Vec<Vec<(String, RgbImage, RgbImage)>> = Vec::new();
    for (_, overrides) in COLUMNS {
        let overrides: Vec<Override> =
            overrides.iter().map(|o| o.parse().map_err(|e: String| anyhow::anyhow!(e))).collect::<Result<_>>()?;
        let pads: Option<Vec<String>> = columns.first().map(|c| c.iter().map(|r| r.0.clone()).collect());
        columns.push(samples(Path::new(config), &overrides, ycb.as_ref(), assets.clone(), rows, pads.as_deref())?);
    }
    let (w, h) = (columns[0][0].2.width(), columns[0][0].2.height());
    let gap = 6;
    let sheet_w = (w + gap) * (COLUMNS.len() as u32 + 1);
    let mut sheet = RgbImage::from_pixel(sheet_w, (h + gap) * rows as u32, Rgb([255, 255, 255]));
    for r in 0..rows {
        let y = (r as u32 * (h + gap)) as i64;
        image::imageops::overlay(&mut sheet, &columns[0][r].1, 0, y);
        for (c, column) in columns.iter().enumerate() {
            image::imageops::overlay(&mut sheet, &column[r].2, ((c as u32 + 1) * (w + gap)) as i64, y);
        }
    }
    sheet.save(out).with_context(|| format!("cannot write {out}"))?;
    println!("{out}: {rows} grasps; columns: pad depth, {}", COLUMNS.map(|c| c.0).join(", "));
    Ok(())
}

/// `rows` samples spread over the plan (the last instance of evenly spaced trajectories), each as
/// one optical pad's depth view (colour-mapped, at the image's size) and optical image: the pad
/// whose image shows the most contact in the first column's setting.
fn samples(
    config: &Path,
    overrides: &[Override],
    ycb: Option<&PathBuf>,
    assets: Option<PathBuf>,
    rows: usize,
    pads: Option<&[String]>,
) -> Result<Vec<(String, RgbImage, RgbImage)>> {
    let cfg = LoadedConfig::load_with_assets(config, overrides, assets.as_deref())?;
    let objects = load_objects(&cfg, ycb)?;
    let mut factory = SampleFactory::new(&cfg, &objects, Box::new(WgpuRenderer::new(&cfg.config.renderer)?))?;
    let plan = Plan::new(&cfg.config);
    let all: Vec<_> =
        plan.shards.iter().flat_map(|s| s.samples.iter().enumerate().map(move |(k, r)| (s.split, s.first_sample + k as u64, *r))).collect();
    // The last instance of each trajectory: the grasp after its arm moves.
    let last = cfg.config.sampling.instances_per_trajectory - 1;
    let picks: Vec<_> = all.iter().filter(|(_, _, r)| r.instance == last).collect();
    let step = (picks.len() / rows.max(1)).max(1);
    let mut out = Vec::new();
    for (row, (split, index, r)) in picks.iter().step_by(step).take(rows).enumerate() {
        let s = factory.make(*split, *index, r, &mut ShardTally::default())?;
        let tac = s.tactile.as_ref().context("the config has no robot")?;
        // The pad whose image shows the most contact (pixels well off its reference).
        let contact = |o: &&vt_dataset::OpticalPadImage| o.image.iter().zip(&o.reference).filter(|(a, b)| a.abs_diff(**b) > 12).count();
        let o = match pads {
            Some(p) => tac.optical.iter().find(|o| o.pad == p[row]),
            None => tac.optical.iter().max_by_key(contact),
        }
        .context("the config has no optical pad")?;
        let image = RgbImage::from_raw(o.width, o.height, o.image.clone()).context("image size")?;
        let k = tac.pads.iter().position(|p| *p == o.pad).context("pad")?;
        let touch = s.info.robot.as_ref().and_then(|r| r.tactile.as_ref()).context("touch info")?;
        let sensor: OpticalSensor = serde_json::from_value(touch.optical.as_ref().context("optical info")?[&o.pad].clone())?;
        out.push((o.pad.clone(), depth_view(&tac.depth[k], tac.resolution, touch.pads[&o.pad], &sensor), image));
    }
    Ok(out)
}

/// A pad depth view over the optical image's sensing area, pixel for pixel (nearest pad pixel),
/// colour-mapped: near bright, 3 mm and beyond dark.
fn depth_view(depth: &[f32], n: u32, [len, wid]: [f64; 2], sensor: &OpticalSensor) -> RgbImage {
    let [w, h] = sensor.image_size;
    RgbImage::from_fn(w, h, |u, v| {
        let (_, [x, y]) = pixel_position(sensor, u, v);
        let pu = ((x / len + 0.5) * n as f64).floor().clamp(0.0, n as f64 - 1.0) as u32;
        let pv = ((y / wid + 0.5) * n as f64).floor().clamp(0.0, n as f64 - 1.0) as u32;
        let d = depth[(pv * n + pu) as usize];
        let t = if d.is_finite() { (1.0 - (d as f64 / 0.003)).clamp(0.0, 1.0) } else { 0.0 };
        Rgb([(40.0 + 215.0 * t) as u8, (20.0 + 200.0 * t * t) as u8, (80.0 * (1.0 - t) + 30.0) as u8])
    })
}

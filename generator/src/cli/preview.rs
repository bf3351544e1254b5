//! `vtgen preview`: a contact sheet to look at. One row per sample, cropped around the object: the
//! RGB image with the object's mask tinted, the tactile points projected as dots and the ground-truth pose drawn as
//! axes (x red, y green, z blue, 5 cm), next to the depth colour-mapped (near bright, far dark),
//! the optical tactile images of the pads that have them, and the force fields of the pads the
//! object presses on (pressure from white to red, shear as black arrows, slipping cells framed in
//! blue; scaled to the sample's largest pressure and shear).
//! A strip on the left of each row tells randomized samples (orange) from canonical ones (grey).

use std::path::Path;

use anyhow::{Context, Result};
use glam::DVec3;
use image::{Rgb, RgbImage};
use vt_dataset::{DatasetReader, Sample};

use crate::assets::load_objects;
use crate::config::{LoadedConfig, Override};
use crate::plan::Plan;
use crate::render::WgpuRenderer;
use crate::sample::{SampleFactory, ShardTally};

/// `n` samples spread over a config's plan (generated in memory, with `overrides` applied and the
/// robot drawn from `robot_assets` when given) or over a dataset directory's train split.
pub fn samples(
    source: &Path,
    n: usize,
    ycb_dir: Option<&std::path::PathBuf>,
    robot_assets: Option<std::path::PathBuf>,
    overrides: &[Override],
) -> Result<Vec<Sample>> {
    if source.is_dir() {
        anyhow::ensure!(overrides.is_empty(), "--set applies to a config, not to the dataset {}", source.display());
        let ds = DatasetReader::open(source)?;
        let shards = ds.shards("train")?;
        let all: Vec<(usize, u64)> = shards.iter().enumerate().flat_map(|(k, s)| s.indices().map(move |i| (k, i))).collect();
        let step = (all.len() / n.max(1)).max(1);
        return all.iter().step_by(step).take(n).map(|&(k, i)| shards[k].read(i)).collect();
    }
    let cfg = LoadedConfig::load_with_assets(source, overrides, robot_assets.as_deref())?;
    config_samples(&cfg, n, ycb_dir)
}

/// `n` samples spread over a loaded config's plan, generated in memory.
pub fn config_samples(cfg: &LoadedConfig, n: usize, ycb_dir: Option<&std::path::PathBuf>) -> Result<Vec<Sample>> {
    let plan = Plan::new(&cfg.config);
    let objects = load_objects(cfg, ycb_dir)?;
    let mut factory = SampleFactory::new(cfg, &objects, Box::new(WgpuRenderer::new(&cfg.config.renderer)?))?;
    // Spread the rows over the plan so that every object shows up.
    let all: Vec<_> =
        plan.shards.iter().flat_map(|s| s.samples.iter().enumerate().map(move |(k, r)| (s.split, s.first_sample + k as u64, *r))).collect();
    let step = (all.len() / n.max(1)).max(1);
    all.iter().step_by(step).take(n).map(|(split, i, r)| factory.make(*split, *i, r, &mut ShardTally::default())).collect()
}

fn project(s: &Sample, p: DVec3) -> Option<(f64, f64)> {
    (p.z > 1e-6).then(|| (s.fx() * p.x / p.z + s.cx(), s.fy() * p.y / p.z + s.cy()))
}

fn put(img: &mut RgbImage, x: i64, y: i64, c: [u8; 3]) {
    if x >= 0 && y >= 0 && (x as u32) < img.width() && (y as u32) < img.height() {
        img.put_pixel(x as u32, y as u32, Rgb(c));
    }
}

/// A 2-pixel line from `a` to `b` (pixels), clipped to the image.
pub(crate) fn line(img: &mut RgbImage, a: (f64, f64), b: (f64, f64), c: [u8; 3]) {
    let n = ((b.0 - a.0).abs().max((b.1 - a.1).abs()) as usize).max(1);
    for k in 0..=n {
        let t = k as f64 / n as f64;
        let (x, y) = (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t);
        for (dx, dy) in [(0, 0), (1, 0), (0, 1)] {
            put(img, x as i64 + dx, y as i64 + dy, c);
        }
    }
}

/// The sample's RGB annotated: the object's visible mask as a green outline (so its texture stays
/// visible), the tactile points in magenta, the object's axes (x red, y green, z blue, 5 cm).
fn annotated_rgb(s: &Sample) -> RgbImage {
    let (w, h) = (s.width, s.height);
    let mut rgb = RgbImage::from_raw(w, h, s.rgb.clone()).expect("w x h x 3 bytes");
    let is_object = |x: i64, y: i64| {
        x >= 0 && y >= 0 && x < w as i64 && y < h as i64 && s.mask[(y * w as i64 + x) as usize] == vt_dataset::mask_ids::TARGET_OBJECT
    };
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            if is_object(x, y) && [(1, 0), (-1, 0), (0, 1), (0, -1)].iter().any(|(dx, dy)| !is_object(x + dx, y + dy)) {
                rgb.put_pixel(x as u32, y as u32, Rgb([40, 255, 80]));
            }
        }
    }
    if let Some(t) = &s.tactile {
        for p in &t.points {
            if let Some((u, v)) = project(s, glam::Vec3::from(p.position).as_dvec3()) {
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    put(&mut rgb, u.round() as i64 + dx, v.round() as i64 + dy, [255, 40, 200]);
                }
            }
        }
    }
    let pose = s.t_camera_object;
    let o = pose.transform_point(DVec3::ZERO);
    for (axis, c) in [(DVec3::X, [230, 40, 40]), (DVec3::Y, [40, 230, 40]), (DVec3::Z, [60, 90, 255])] {
        if let (Some(a), Some(b)) = (project(s, o), project(s, pose.transform_point(axis * 0.05))) {
            line(&mut rgb, a, b, c);
        }
    }
    rgb
}

/// The crop around the object (its mask's box, widened 2.5x, 4:3), so hand and object are
/// legible: (x0, y0, width, height).
fn object_crop(s: &Sample) -> (u32, u32, u32, u32) {
    let (w, h) = (s.width, s.height);
    let (mut u0, mut v0, mut u1, mut v1) = (w, h, 0, 0);
    for (i, m) in s.mask.iter().enumerate() {
        if *m == 1 {
            let (u, v) = (i as u32 % w, i as u32 / w);
            (u0, v0, u1, v1) = (u0.min(u), v0.min(v), u1.max(u), v1.max(v));
        }
    }
    let (cu, cv, half_w) = if u1 >= u0 && v1 >= v0 {
        let hw = (((u1 - u0) as f64).max((v1 - v0) as f64 * 4.0 / 3.0) * 1.25).max(w as f64 / 6.0).min(w as f64 / 2.0);
        ((u0 + u1) as f64 / 2.0, (v0 + v1) as f64 / 2.0, hw)
    } else {
        (w as f64 / 2.0, h as f64 / 2.0, w as f64 / 2.0)
    };
    let half_h = half_w * 3.0 / 4.0;
    let x0 = (cu - half_w).clamp(0.0, w as f64 - 2.0 * half_w) as u32;
    let y0 = (cv - half_h).clamp(0.0, (h as f64 - 2.0 * half_h).max(0.0)) as u32;
    (x0, y0, (2.0 * half_w) as u32, ((2.0 * half_h) as u32).min(h))
}

/// The depth colour-mapped over the range seen inside the crop: near is bright yellow, far dark
/// purple, no reading black.
fn depth_image(s: &Sample, (x0, y0, cw, ch): (u32, u32, u32, u32)) -> RgbImage {
    let w = s.width;
    let in_crop = |i: usize| {
        let (u, v) = (i as u32 % w, i as u32 / w);
        u >= x0 && u < x0 + cw && v >= y0 && v < y0 + ch
    };
    let valid: Vec<f32> = s.depth.iter().enumerate().filter(|(i, d)| **d > 0.0 && d.is_finite() && in_crop(*i)).map(|(_, d)| *d).collect();
    let (lo, hi) = valid.iter().fold((f32::MAX, f32::MIN), |(l, h), d| (l.min(*d), h.max(*d)));
    let mut depth = RgbImage::new(w, s.height);
    for (i, d) in s.depth.iter().enumerate() {
        let c = if *d > 0.0 && d.is_finite() {
            let t = (1.0 - (d - lo) / (hi - lo).max(1e-6)).clamp(0.0, 1.0);
            [(60.0 + 195.0 * t) as u8, (20.0 + 200.0 * t * t) as u8, (90.0 * (1.0 - t) + 30.0) as u8]
        } else {
            [0, 0, 0]
        };
        depth.put_pixel(i as u32 % w, i as u32 / w, Rgb(c));
    }
    depth
}

/// The force fields of a sample's pressed pads, each `CELL_PX` pixels per cell: pressure from
/// white (none) to red (the sample's largest), the shear traction as a black arrow from each
/// cell's centre (the sample's largest: most of a cell), slipping cells framed in blue; the pad's
/// x to the right, its y down, as its depth image.
fn force_images(s: &Sample) -> Vec<RgbImage> {
    const CELL_PX: u32 = 96;
    let fields: Vec<&vt_dataset::PadForceField> =
        s.tactile.iter().flat_map(|t| &t.forces).filter(|f| f.cells.iter().any(|c| c.pressure > 0.0)).collect();
    let cells = || fields.iter().flat_map(|f| &f.cells);
    let p_max = cells().map(|c| c.pressure).fold(0.0f32, f32::max).max(1e-9);
    let s_max = cells().map(|c| c.shear[0].hypot(c.shear[1])).fold(0.0f32, f32::max).max(1e-9);
    fields
        .iter()
        .map(|f| {
            let r = f.resolution;
            let px = (CELL_PX / r).max(4);
            let mut img = RgbImage::from_pixel(r * px, r * px, Rgb([235, 235, 235]));
            for (i, c) in f.cells.iter().enumerate() {
                let (u, v) = (i as u32 % r, i as u32 / r);
                let t = (c.pressure / p_max).clamp(0.0, 1.0);
                let fill = if c.pressure > 0.0 { [255, (255.0 * (1.0 - t)) as u8, (255.0 * (1.0 - t)) as u8] } else { [235, 235, 235] };
                for y in v * px..(v + 1) * px {
                    for x in u * px..(u + 1) * px {
                        let edge = x == u * px || y == v * px || x + 1 == (u + 1) * px || y + 1 == (v + 1) * px;
                        img.put_pixel(x, y, Rgb(if c.slip && edge { [30, 90, 255] } else { fill }));
                    }
                }
                let centre = ((u as f64 + 0.5) * px as f64, (v as f64 + 0.5) * px as f64);
                let k = 0.9 * px as f64 / s_max as f64;
                let tip = (centre.0 + k * c.shear[0] as f64, centre.1 + k * c.shear[1] as f64);
                if c.shear != [0.0, 0.0] {
                    line(&mut img, centre, tip, [0, 0, 0]);
                }
            }
            img
        })
        .collect()
}

/// One row: annotated RGB | colour-mapped depth, cropped around the object, and a column on the
/// right: the optical pads' images, then the pressed pads' force fields.
fn row(s: &Sample) -> RgbImage {
    let (x0, y0, cw, ch) = object_crop(s);
    let crop = |img: &RgbImage| image::imageops::crop_imm(img, x0, y0, cw, ch).to_image();
    let (rgb, depth) = (crop(&annotated_rgb(s)), crop(&depth_image(s, (x0, y0, cw, ch))));
    let mut side: Vec<RgbImage> =
        s.tactile.iter().flat_map(|t| &t.optical).filter_map(|o| RgbImage::from_raw(o.width, o.height, o.image.clone())).collect();
    side.extend(force_images(s));
    let n = side.len().max(1) as u32;
    let side: Vec<RgbImage> = side
        .iter()
        .map(|img| {
            let th = (ch / n).max(1);
            let tw = (img.width() as u64 * th as u64 / img.height().max(1) as u64).max(1) as u32;
            image::imageops::resize(img, tw, th, image::imageops::FilterType::Triangle)
        })
        .collect();
    let column = side.iter().map(|i| i.width()).max().unwrap_or(0);
    let mut out = RgbImage::new(2 * cw + column, ch);
    image::imageops::overlay(&mut out, &rgb, 0, 0);
    image::imageops::overlay(&mut out, &depth, cw as i64, 0);
    let mut top = 0;
    for img in &side {
        image::imageops::overlay(&mut out, img, 2 * cw as i64, top);
        top += img.height() as i64;
    }
    out
}

/// Writes the contact sheet of `samples` (rows scaled to `row_width` pixels wide, in `columns`
/// columns) as a PNG.
pub fn write_sheet(samples: &[Sample], out: &Path, row_width: u32, columns: u32) -> Result<()> {
    let rows: Vec<RgbImage> = samples
        .iter()
        .map(|s| {
            let r = row(s);
            let hgt = (r.height() as f64 * row_width as f64 / r.width() as f64).round() as u32;
            let mut r = image::imageops::resize(&r, row_width, hgt, image::imageops::FilterType::Triangle);
            // A strip on the left: orange for a randomized sample, light grey for a canonical one.
            let c = if s.info.randomized { [255, 140, 0] } else { [210, 210, 210] };
            for y in 0..hgt {
                for x in 0..6.min(row_width) {
                    r.put_pixel(x, y, Rgb(c));
                }
            }
            r
        })
        .collect();
    let columns = columns.clamp(1, rows.len().max(1) as u32) as usize;
    let cells: Vec<&[RgbImage]> = rows.chunks(columns).collect();
    let height = cells.iter().map(|c| c.iter().map(|r| r.height()).max().unwrap_or(0)).sum::<u32>().max(1);
    let gap = 4;
    let mut sheet = RgbImage::from_pixel(columns as u32 * (row_width + gap) - gap, height, Rgb([255, 255, 255]));
    let mut y = 0;
    for line in &cells {
        for (k, r) in line.iter().enumerate() {
            image::imageops::overlay(&mut sheet, r, (k as u32 * (row_width + gap)) as i64, y as i64);
        }
        y += line.iter().map(|r| r.height()).max().unwrap_or(0);
    }
    sheet.save(out).with_context(|| format!("cannot write {}", out.display()))
}

/// `vtgen preview`: the contact sheet of `n` samples of a config or dataset, written to `out`.
pub fn run(
    source: &Path,
    n: usize,
    out: &Path,
    layout: (u32, u32),
    ycb_dir: Option<&std::path::PathBuf>,
    robot_assets: Option<std::path::PathBuf>,
    overrides: &[Override],
) -> Result<()> {
    let samples = samples(source, n, ycb_dir, robot_assets, overrides)?;
    write_sheet(&samples, out, layout.0, layout.1)?;
    println!("wrote {} ({} samples)", out.display(), samples.len());
    Ok(())
}

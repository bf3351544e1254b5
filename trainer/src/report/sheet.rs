//! The picture sheet of `vtpose refine --sheet N`: the samples where the depth alone fails and
//! the touch recovers the pose, each tile the camera's image around the object with the model
//! drawn at each estimate: the truth in **green** (under the others), depth only in **red**,
//! depth + touch in **blue** (on top: where it is right it hides the green), and the tactile
//! points in **magenta**.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use glam::{DMat3, DVec3};
use image::{Rgb, RgbImage};

use crate::data::{DepthSource, SplitSource, load_models};
use crate::eval::refined::{RefineEval, estimates_of};
use crate::refine::Pose;

/// The side of a tile (px).
const TILE: u32 = 256;
/// Model points drawn per estimate.
const DRAWN_POINTS: usize = 600;
const TRUTH: Rgb<u8> = Rgb([40, 220, 60]);
const DEPTH_ONLY: Rgb<u8> = Rgb([235, 50, 40]);
const WITH_TOUCH: Rgb<u8> = Rgb([40, 110, 255]);
const TOUCH: Rgb<u8> = Rgb([255, 0, 255]);

/// The samples where `refine: depth` misses (ADD(-S) ≥ 2 cm) and `refine: depth + touch` gets the
/// pose (ADD(-S) < 1 cm), largest gain first, at most `n`, one per grasp.
pub fn recovered(eval: &RefineEval, n: usize) -> Vec<u64> {
    let find = |label: &str| eval.estimators.iter().find(|e| e.label == label);
    let (Some(depth), Some(touch)) = (find("refine: depth"), find("refine: depth + touch")) else { return Vec::new() };
    let by_index: std::collections::HashMap<u64, f64> = depth.results.iter().map(|r| (r.index, r.add_or_adds())).collect();
    let mut gains: Vec<(f64, u64, (String, u32))> = touch
        .results
        .iter()
        .filter_map(|r| {
            let d = *by_index.get(&r.index)?;
            (d >= 0.02 && r.add_or_adds() < 0.01).then(|| (d - r.add_or_adds(), r.index, (r.object.clone(), r.trajectory)))
        })
        .collect();
    gains.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let mut grasps = std::collections::BTreeSet::new();
    gains.into_iter().filter(|(_, _, g)| grasps.insert(g.clone())).take(n).map(|(_, i, _)| i).collect()
}

/// Writes `sheet.png` into `out` with the tiles of [`recovered`] (None when no sample qualifies).
pub fn write_sheet(eval: &RefineEval, n: usize, out: &Path) -> Result<Option<PathBuf>> {
    let chosen = recovered(eval, n);
    if chosen.is_empty() {
        return Ok(None);
    }
    let models = load_models(&eval.dataset)?;
    let ids: Vec<String> = models.iter().map(|m| m.id.clone()).collect();
    let mut source = SplitSource::open(&eval.dataset, &eval.split, &ids, DepthSource::Exact, false)?;
    source.spread(eval.max_samples);
    let (depth, touch) = (estimates_of(eval, "refine: depth"), estimates_of(eval, "refine: depth + touch"));
    let cols = chosen.len().min(4) as u32;
    let rows = (chosen.len() as u32).div_ceil(cols);
    let mut sheet = RgbImage::from_pixel(cols * TILE, rows * TILE, Rgb([255, 255, 255]));
    for (k, index) in chosen.iter().enumerate() {
        let position = *eval.positions.get(index).context("a chosen sample's position in the split")?;
        let (s, object) = source.sample(position)?;
        let points = &models[object].eval_points[..DRAWN_POINTS.min(models[object].eval_points.len())];
        let truth = (s.t_camera_object.rotation(), s.t_camera_object.translation());
        let k_mat = [s.fx(), s.fy(), s.cx(), s.cy()];
        let project = |p: DVec3| (k_mat[0] * p.x / p.z + k_mat[2], k_mat[1] * p.y / p.z + k_mat[3]);
        let moved = |pose: Pose| -> Vec<(f64, f64)> {
            let r = DMat3::from_quat(pose.0);
            points.iter().map(|p| project(r * DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64) + pose.1)).collect()
        };
        // The tile frames the truth's projection with a margin.
        let truth_px = moved(truth);
        let (mut lo, mut hi) = ((f64::MAX, f64::MAX), (f64::MIN, f64::MIN));
        for &(u, v) in &truth_px {
            (lo, hi) = ((lo.0.min(u), lo.1.min(v)), (hi.0.max(u), hi.1.max(v)));
        }
        let side = (hi.0 - lo.0).max(hi.1 - lo.1) * 1.8 + 20.0;
        let (cu, cv) = (0.5 * (lo.0 + hi.0), 0.5 * (lo.1 + hi.1));
        let scale = side / TILE as f64;
        let (ox, oy) = ((k as u32 % cols) * TILE, (k as u32 / cols) * TILE);
        for y in 0..TILE {
            for x in 0..TILE {
                let (u, v) = ((cu - side / 2.0 + x as f64 * scale) as i64, (cv - side / 2.0 + y as f64 * scale) as i64);
                if u >= 0 && v >= 0 && (u as u32) < s.width && (v as u32) < s.height {
                    let i = (v as usize * s.width as usize + u as usize) * 3;
                    sheet.put_pixel(ox + x, oy + y, Rgb([s.rgb[i], s.rgb[i + 1], s.rgb[i + 2]]));
                }
            }
        }
        let mut dot = |(u, v): (f64, f64), colour: Rgb<u8>, radius: i64| {
            let (x, y) = (((u - (cu - side / 2.0)) / scale) as i64, ((v - (cv - side / 2.0)) / scale) as i64);
            for dy in -radius..=radius {
                for dx in -radius..=radius {
                    let (px, py) = (x + dx, y + dy);
                    if px >= 0 && py >= 0 && px < TILE as i64 && py < TILE as i64 {
                        sheet.put_pixel(ox + px as u32, oy + py as u32, colour);
                    }
                }
            }
        };
        for (pose, colour) in [(Some(&truth), TRUTH), (depth.get(index), DEPTH_ONLY), (touch.get(index), WITH_TOUCH)] {
            if let Some(pose) = pose {
                moved(*pose).into_iter().for_each(|p| dot(p, colour, 0));
            }
        }
        if let Some(t) = &s.tactile {
            for p in &t.points {
                let p = DVec3::from_array(p.position.map(f64::from));
                dot(project(p), TOUCH, 1);
            }
        }
    }
    let path = out.join("sheet.png");
    sheet.save(&path).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(Some(path))
}

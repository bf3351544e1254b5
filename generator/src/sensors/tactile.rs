//! Tactile sensing as the paper defines it: a virtual depth camera on every phalanx (origin on the
//! pad, z out of the finger) sees the object's surface; the pixels within the contact threshold
//! are back-projected into the **tactile point cloud**, the same whatever the sensor or gripper.
//! The 12 views are orthographic over each pad and rendered in one batched submission.

use anyhow::Result;
use glam::{DAffine3, DMat4, DVec3};
use vt_robot::{Geometry, RobotModel, phalanx_names};

use crate::config::{PadProjection, SensorModel, TactileConfig};
use crate::render::{DepthView, Draw, Renderer};

/// One tactile point in the main camera frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TactilePoint {
    pub position: DVec3,
    /// Depth from the pad plane (m): the pressure proxy; negative when pressed into the pad.
    pub distance: f64,
    /// Phalanx index 0..11 (`vt_robot::phalanx_names` order).
    pub phalanx: u32,
}

/// What the 12 phalanx cameras saw in one sample.
#[derive(Debug, Clone, PartialEq)]
pub struct TactileReading {
    /// Per phalanx: `resolution²` z-depths from the pad plane, `+inf` where nothing is in range.
    pub depth: Vec<Vec<f32>>,
    pub points: Vec<TactilePoint>,
    pub counts: [u32; 12],
    /// Time the 12 depth views took to render (the rest of `sense` is point extraction).
    pub render_time: std::time::Duration,
}

/// Sensing area of each phalanx pad: (length along the finger, width across it), metres: the
/// phalanx's collision box, plus the fingertip sphere on the distal phalanges.
pub fn pad_sizes(model: &RobotModel) -> [(f64, f64); 12] {
    let names = phalanx_names();
    std::array::from_fn(|k| {
        let link = model.link(&names[k]).expect("validated at load");
        let (mut len, mut wid) = (0.02, 0.02);
        for s in &link.collisions {
            match s.geometry {
                Geometry::Box { size } => (len, wid) = (size.z, size.y),
                Geometry::Sphere { radius } => len += radius,
                Geometry::Cylinder { .. } => {}
            }
        }
        (len, wid)
    })
}

/// Renders the 12 pad views of the object (drawn alone: the hand does not occlude its own pads)
/// and extracts the tactile points, in the frame `t_camera_world` maps to.
pub fn sense(
    renderer: &mut dyn Renderer,
    cfg: &TactileConfig,
    pads: &[(f64, f64); 12],
    t_world_pads: &[DAffine3; 12],
    object: Draw,
    t_camera_world: &DAffine3,
) -> Result<TactileReading> {
    let n = cfg.resolution;
    let standoff = (cfg.projection == PadProjection::Perspective).then_some(cfg.perspective_standoff_mm * 1e-3);
    let views: Vec<DepthView> = (0..12)
        .map(|k| DepthView {
            width: n,
            height: n,
            half_x: pads[k].0 / 2.0,
            half_y: pads[k].1 / 2.0,
            near: cfg.near_mm * 1e-3,
            far: cfg.far_mm * 1e-3,
            t_world_camera: DMat4::from(t_world_pads[k]),
            perspective_standoff: standoff,
        })
        .collect();
    let t0 = std::time::Instant::now();
    let depth = renderer.render_depth_views(&views, &[object])?;
    let render_time = t0.elapsed();
    let mut points = Vec::new();
    let mut counts = [0u32; 12];
    for k in 0..12 {
        let (len, wid) = pads[k];
        let to_camera = *t_camera_world * t_world_pads[k];
        let model = match k % 3 {
            0 => cfg.sensors.proximal,
            1 => cfg.sensors.medial,
            _ => cfg.sensors.distal,
        };
        for (u, v) in contact_pixels(&depth[k], n, model, cfg.contact_threshold_mm * 1e-3) {
            let d = depth[k][(v * n + u) as usize] as f64;
            // The pixel's ray meets the pad plane at (x, y); a pinhole's ray spreads with depth.
            let spread = standoff.map_or(1.0, |s| (s + d) / s);
            let x = (u as f64 + 0.5 - n as f64 / 2.0) * len / n as f64 * spread;
            let y = (v as f64 + 0.5 - n as f64 / 2.0) * wid / n as f64 * spread;
            points.push(TactilePoint { position: to_camera.transform_point3(DVec3::new(x, y, d)), distance: d, phalanx: k as u32 });
            counts[k] += 1;
        }
    }
    Ok(TactileReading { depth, points, counts, render_time })
}

/// The pixels (u, v) of an `n x n` pad depth image that a sensor model reports as contacts. Every
/// model reports actual surface points (a pixel's depth), so their clouds lie on the same surface.
pub fn contact_pixels(depth: &[f32], n: u32, model: SensorModel, threshold: f64) -> Vec<(u32, u32)> {
    let at = |u: u32, v: u32| depth[(v * n + u) as usize] as f64;
    let all =
        |limit: f64| (0..n).flat_map(move |v| (0..n).map(move |u| (u, v))).filter(move |&(u, v)| at(u, v) <= limit).collect::<Vec<_>>();
    match model {
        SensorModel::DepthCamera => all(threshold),
        SensorModel::Gelsight { gel_thickness_mm } => all(gel_thickness_mm * 1e-3),
        SensorModel::TaxelArray { rows, cols } => {
            let mut out = Vec::new();
            for r in 0..rows {
                for c in 0..cols {
                    // The taxel's block of pixels, and its closest surface pixel.
                    let (u0, u1) = (c * n / cols, ((c + 1) * n / cols).max(c * n / cols + 1));
                    let (v0, v1) = (r * n / rows, ((r + 1) * n / rows).max(r * n / rows + 1));
                    let best = (v0..v1).flat_map(|v| (u0..u1).map(move |u| (u, v))).min_by(|a, b| at(a.0, a.1).total_cmp(&at(b.0, b.1)));
                    if let Some((u, v)) = best.filter(|&(u, v)| at(u, v) <= threshold) {
                        out.push((u, v));
                    }
                }
            }
            out
        }
    }
}

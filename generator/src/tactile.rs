//! Tactile sensing as the paper defines it: a virtual depth camera on every phalanx (origin on the
//! pad, z out of the finger) sees the object's surface; the pixels within the contact threshold
//! are back-projected into the **tactile point cloud**, the same whatever the sensor or gripper.
//! The 12 views are orthographic over each pad and rendered in one batched submission.

use anyhow::Result;
use glam::{DAffine3, DMat4, DVec3};
use vt_robot::{Geometry, RobotModel, phalanx_names};

use crate::config::TactileConfig;
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
}

/// Sensing area of each phalanx pad: (length along the finger, width across it), metres, from the
/// phalanx's collision box.
pub fn pad_sizes(model: &RobotModel) -> [(f64, f64); 12] {
    let names = phalanx_names();
    std::array::from_fn(|k| {
        let link = model.link(&names[k]).expect("validated at load");
        link.collisions
            .iter()
            .find_map(|s| match s.geometry {
                Geometry::Box { size } => Some((size.z, size.y)),
                _ => None,
            })
            .unwrap_or((0.02, 0.02))
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
    let views: Vec<DepthView> = (0..12)
        .map(|k| DepthView {
            width: n,
            height: n,
            half_x: pads[k].0 / 2.0,
            half_y: pads[k].1 / 2.0,
            near: cfg.near_mm * 1e-3,
            far: cfg.far_mm * 1e-3,
            t_world_camera: DMat4::from(t_world_pads[k]),
        })
        .collect();
    let depth = renderer.render_depth_views(&views, &[object])?;
    let threshold = cfg.contact_threshold_mm * 1e-3;
    let mut points = Vec::new();
    let mut counts = [0u32; 12];
    for k in 0..12 {
        let (len, wid) = pads[k];
        let to_camera = *t_camera_world * t_world_pads[k];
        for v in 0..n {
            for u in 0..n {
                let d = depth[k][(v * n + u) as usize] as f64;
                if !(d <= threshold) {
                    continue;
                }
                let x = (u as f64 + 0.5 - n as f64 / 2.0) * len / n as f64;
                let y = (v as f64 + 0.5 - n as f64 / 2.0) * wid / n as f64;
                points.push(TactilePoint { position: to_camera.transform_point3(DVec3::new(x, y, d)), distance: d, phalanx: k as u32 });
                counts[k] += 1;
            }
        }
    }
    Ok(TactileReading { depth, points, counts })
}

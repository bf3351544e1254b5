//! Tactile sensing as the paper defines it: a virtual depth camera on every pad (origin on the
//! pad, z out of the finger) sees the object's surface; the pixels within the contact threshold
//! are back-projected into the **tactile point cloud**, the same whatever the sensor or gripper.
//! The views are orthographic over each pad and rendered in one batched submission.

use anyhow::Result;
use glam::{DAffine3, DMat4, DVec3};

use super::optical::gel_shading;
use crate::config::{OpticalSensor, OpticalShading, PadProjection, PadSensor, SensorModel, TactileConfig};
use crate::render::{DepthView, Draw, GelShading, Renderer};

/// One kind of pad sensor: the view it needs besides the pad camera and the pixels of the pad
/// camera it reports as contacts. Every pad writes `/tactile/<pad>/depth` and its points; a kind
/// with a view of its own (the optical sensor) also makes an image of it (`/tactile/<pad>/image`,
/// `/reference`, with force fields `/markers`; FORMAT.md). A new kind is a `SensorModel`
/// variant (the format's) and an implementation here, chosen in [`sensor_kind`].
pub trait SensorKind {
    /// The pixels (u, v) of the `n x n` pad image `gap` (the object's distance above the pad's
    /// surface, m) that the sensor reports; every kind reports actual surface points, so their
    /// clouds lie on the same surface.
    fn contact_pixels(&self, gap: &[f32], n: u32, threshold: f64) -> Vec<(u32, u32)>;
    /// The depth view of the object it needs besides the pad camera, from the pad frame
    /// `t_world_pad`, from `near` (m) on (None: the pad camera suffices).
    fn own_view(&self, _t_world_pad: &DAffine3, _near: f64) -> Option<DepthView> {
        None
    }
}

/// The paper's sensor: every pixel within the contact threshold.
struct DepthCamera;
/// A grid of taxels, each firing at its closest pixel within the threshold.
struct TaxelArray {
    rows: u32,
    cols: u32,
}
/// A gel of this thickness: every pixel that indents it.
struct GelPad {
    gel_thickness_mm: f64,
}
/// A gel sensor with its camera: the gel rule with its gel's thickness, and its image.
struct OpticalPad<'a>(&'a OpticalSensor);

/// Pixels of an `n x n` image within `limit`.
fn within(gap: &[f32], n: u32, limit: f64) -> Vec<(u32, u32)> {
    (0..n).flat_map(move |v| (0..n).map(move |u| (u, v))).filter(|&(u, v)| gap[(v * n + u) as usize] as f64 <= limit).collect()
}

impl SensorKind for DepthCamera {
    fn contact_pixels(&self, gap: &[f32], n: u32, threshold: f64) -> Vec<(u32, u32)> {
        within(gap, n, threshold)
    }
}

impl SensorKind for GelPad {
    fn contact_pixels(&self, gap: &[f32], n: u32, _threshold: f64) -> Vec<(u32, u32)> {
        within(gap, n, self.gel_thickness_mm * 1e-3)
    }
}

impl SensorKind for OpticalPad<'_> {
    fn contact_pixels(&self, gap: &[f32], n: u32, _threshold: f64) -> Vec<(u32, u32)> {
        within(gap, n, self.0.gel_thickness_mm * 1e-3)
    }
    /// Orthographic over the sensing area at the image's size, out to the gel's free surface.
    fn own_view(&self, t_world_pad: &DAffine3, near: f64) -> Option<DepthView> {
        let sensor = self.0;
        Some(DepthView {
            width: sensor.image_size[0],
            height: sensor.image_size[1],
            half_x: sensor.sensing_area_mm[0] * 0.5e-3,
            half_y: sensor.sensing_area_mm[1] * 0.5e-3,
            near,
            far: (sensor.gel_thickness_mm + 0.1) * 1e-3,
            t_world_camera: DMat4::from(*t_world_pad),
            perspective_standoff: None,
        })
    }
}

impl SensorKind for TaxelArray {
    fn contact_pixels(&self, gap: &[f32], n: u32, threshold: f64) -> Vec<(u32, u32)> {
        let at = |u: u32, v: u32| gap[(v * n + u) as usize] as f64;
        let (rows, cols) = (self.rows, self.cols);
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

/// The kind of a pad's resolved sensor.
pub fn sensor_kind(sensor: &PadSensor) -> Box<dyn SensorKind + '_> {
    match (sensor.model, &sensor.optical) {
        (SensorModel::DepthCamera, _) => Box::new(DepthCamera),
        (SensorModel::TaxelArray { rows, cols }, _) => Box::new(TaxelArray { rows, cols }),
        (SensorModel::Gelsight { gel_thickness_mm }, _) => Box::new(GelPad { gel_thickness_mm }),
        (SensorModel::Optical, Some(o)) => Box::new(OpticalPad(o)),
        // Resolution gives every optical pad its sensor (`TactileConfig::pad_sensors`).
        (SensorModel::Optical, None) => Box::new(DepthCamera),
    }
}

/// One tactile point in the main camera frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TactilePoint {
    pub position: DVec3,
    /// Depth from the pad plane (m): the pressure proxy; negative when pressed into the pad.
    pub distance: f64,
    /// Pad index (`Robot::pads` order).
    pub pad: u32,
}

/// One pad as a sample sees it: its sensing area (length, width; m), its sensor in this sample
/// (an optical one varied per sensor unit), its pose (world) and whether its link touches the
/// object.
#[derive(Debug, Clone, PartialEq)]
pub struct PadView {
    pub size: (f64, f64),
    pub sensor: PadSensor,
    pub t_world_pad: DAffine3,
    pub touching: bool,
}

impl PadView {
    /// The pad's optical sensor, when it has one.
    pub fn optical(&self) -> Option<&OpticalSensor> {
        self.sensor.optical.as_ref().filter(|_| self.sensor.model == SensorModel::Optical)
    }
}

/// What the pad cameras saw in one sample.
#[derive(Debug, Clone, PartialEq)]
pub struct TactileReading {
    /// Per pad: `resolution²` z-depths from the pad plane, `+inf` where nothing is in range.
    pub depth: Vec<Vec<f32>>,
    pub points: Vec<TactilePoint>,
    pub counts: Vec<u32>,
    /// Per pad: the object's depth over an optical sensor's image (its sensing area at its image
    /// size, `+inf` where nothing is in range), for the optical pads that touch the object.
    pub optical_depth: Vec<Option<Vec<f32>>>,
    /// Per pad, with `optical_shading: gpu`: its optical image as the GPU shaded it (linear R, G,
    /// B and the gel's surface per pixel; `sensors::optical::optical_image_shaded`).
    pub optical_shaded: Vec<Option<Vec<f32>>>,
    /// Time the depth views took to render (the rest of `sense` is point extraction).
    pub render_time: std::time::Duration,
}

/// Where the finger's real surface lies under each pad pixel: its height along the pad's z (m,
/// <= 0 behind the pad plane; `-inf` where no finger is under the pixel), `resolution²` per pad,
/// rows as the pad's depth image. The URDF's flat pads have none: their surface is the plane.
pub type FingerSurface = Vec<Vec<f32>>;

/// Where pixel (u, v) of an `n x n` pad camera over a pad of `size` (length, width) looks from,
/// in the pad frame's (x, y) (FORMAT.md, `/tactile/*`).
fn pad_pixel(u: u32, v: u32, n: u32, (len, wid): (f64, f64)) -> (f64, f64) {
    ((u as f64 + 0.5 - n as f64 / 2.0) * len / n as f64, (v as f64 + 0.5 - n as f64 / 2.0) * wid / n as f64)
}

/// The finger surface under each pad pixel of `mesh` (the pad link's real mesh, link frame), seen
/// along the pad's -z from the pad frame `t_link_pad`, over the pad's `size` at `n x n` pixels.
pub fn finger_surface(mesh: &vt_objects::TexturedMesh, t_link_pad: &DAffine3, size: (f64, f64), n: u32) -> Result<Vec<f32>> {
    use rapier3d::parry::query::{Ray, RayCast};
    let vertices = mesh.positions.iter().map(|p| glam::Vec3::from(*p)).collect();
    let triangles = mesh.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
    let trimesh = rapier3d::parry::shape::TriMesh::new(vertices, triangles)
        .map_err(|e| anyhow::anyhow!("a finger mesh cannot be ray-cast: {e:?}"))?;
    // Rays start this far in front of the pad plane, outside any finger.
    const ABOVE: f64 = 0.05;
    let dir = t_link_pad.transform_vector3(-DVec3::Z).as_vec3();
    Ok((0..n)
        .flat_map(|v| (0..n).map(move |u| (u, v)))
        .map(|(u, v)| {
            let (x, y) = pad_pixel(u, v, n, size);
            let origin = t_link_pad.transform_point3(DVec3::new(x, y, ABOVE)).as_vec3();
            trimesh.cast_local_ray(&Ray::new(origin, dir), 1.0, false).map_or(f32::NEG_INFINITY, |toi| (ABOVE - toi as f64) as f32)
        })
        .collect())
}

/// Renders the pad views of the object (drawn alone: the hand does not occlude its own pads), and
/// the image-sized views of the touching optical pads in the same submission, and extracts the
/// tactile points, in the frame `t_camera_world` maps to. Only the pads of the
/// links `touching` the object (the physics' contacts) report points: a sensor answers to
/// contact, and an object hovering within the threshold of an untouched pad is not felt. With
/// `surface`, a pixel's contact rule applies to the object's distance from the finger's real
/// surface under it (not from the pad plane): the points are where the finger touches the object.
pub fn sense(
    renderer: &mut dyn Renderer,
    cfg: &TactileConfig,
    pads: &[PadView],
    surface: Option<&FingerSurface>,
    object: Draw,
    t_camera_world: &DAffine3,
) -> Result<TactileReading> {
    let n = cfg.resolution;
    let standoff = (cfg.projection == PadProjection::Perspective).then_some(cfg.perspective_standoff_mm * 1e-3);
    let mut views: Vec<DepthView> = pads
        .iter()
        .map(|pad| DepthView {
            width: n,
            height: n,
            half_x: pad.size.0 / 2.0,
            half_y: pad.size.1 / 2.0,
            near: cfg.near_mm * 1e-3,
            far: cfg.far_mm * 1e-3,
            t_world_camera: DMat4::from(pad.t_world_pad),
            perspective_standoff: standoff,
        })
        .collect();
    // The views the touching pads' sensors need of their own (the optical pads' images).
    let mut optical = Vec::new();
    for (k, pad) in pads.iter().enumerate().filter(|(_, p)| p.touching) {
        if let Some(view) = sensor_kind(&pad.sensor).own_view(&pad.t_world_pad, cfg.near_mm * 1e-3) {
            views.push(view);
            optical.push(k);
        }
    }
    // With GPU shading, each optical view's image model runs after the views, in their submission.
    let shading: Vec<GelShading> = match cfg.optical_shading {
        OpticalShading::Gpu => {
            optical.iter().enumerate().filter_map(|(i, &k)| gel_shading(pads[k].optical().expect("optical pads"), pads.len() + i)).collect()
        }
        OpticalShading::Cpu => Vec::new(),
    };
    let t0 = std::time::Instant::now();
    let (mut depth, shaded) = if shading.is_empty() {
        (renderer.render_depth_views(&views, &[object])?, None)
    } else {
        renderer.render_depth_views_shaded(&views, &shading, &[object])?
    };
    let render_time = t0.elapsed();
    drop_depths_outside_views(&mut depth, &views);
    let mut optical_depth = vec![None; pads.len()];
    for (&k, d) in optical.iter().zip(depth.drain(pads.len()..)) {
        optical_depth[k] = Some(d);
    }
    let mut optical_shaded = vec![None; pads.len()];
    for (s, image) in shading.iter().zip(shaded.into_iter().flatten()) {
        optical_shaded[optical[s.view - pads.len()]] = Some(image);
    }
    let mut points = Vec::new();
    let mut counts = vec![0u32; pads.len()];
    for (k, pad) in pads.iter().enumerate().filter(|(_, p)| p.touching) {
        let to_camera = *t_camera_world * pad.t_world_pad;
        let gap = gap_above_surface(&depth[k], surface.map(|s| &s[k][..]));
        for (u, v) in sensor_kind(&pad.sensor).contact_pixels(&gap, n, cfg.contact_threshold_mm * 1e-3) {
            let d = depth[k][(v * n + u) as usize] as f64;
            // The pixel's ray meets the pad plane at (x, y); a pinhole's ray spreads with depth.
            let spread = standoff.map_or(1.0, |s| (s + d) / s);
            let (x, y) = pad_pixel(u, v, n, pad.size);
            let (x, y) = (x * spread, y * spread);
            // The distance is the object's above the finger's real surface under the pixel (the
            // pad plane when no surface is known): a round fingertip curving away from a flat pad
            // reads no false press.
            let above = gap[(v * n + u) as usize] as f64;
            points.push(TactilePoint { position: to_camera.transform_point3(DVec3::new(x, y, d)), distance: above, pad: k as u32 });
            counts[k] += 1;
        }
    }
    Ok(TactileReading { depth, points, counts, optical_depth, optical_shaded, render_time })
}

/// Every depth a view cannot see, nearer than its near plane or beyond its far one, made no reading
/// (`+inf`). The rasterizer can carry a triangle's interpolated depth past its own vertices at a
/// pixel centre that its edge just covers, most where the triangle is nearly edge-on to the view
/// (its depth changes by millimetres within a pixel). `scenes/tiny-pinch.yaml` had 10 such pixels in
/// all its pad views, one of them read 7.4 mm into a pad whose view starts 5 mm in: a contact
/// 7.8 mm off the object.
fn drop_depths_outside_views(depth: &mut [Vec<f32>], views: &[DepthView]) {
    for (image, view) in depth.iter_mut().zip(views) {
        let (near, far) = (view.near as f32, view.far as f32);
        for d in image.iter_mut().filter(|d| d.is_finite() && !(near..=far).contains(*d)) {
            *d = f32::INFINITY;
        }
    }
}

/// The object's distance above the pad's surface per pixel of its depth view: above the finger's
/// real surface under the pixel (`surface`, FingerSurface), else above the pad plane.
pub fn gap_above_surface<'a>(depth: &'a [f32], surface: Option<&[f32]>) -> std::borrow::Cow<'a, [f32]> {
    match surface {
        Some(s) => depth.iter().zip(s).map(|(d, h)| d - h).collect::<Vec<_>>().into(),
        None => depth.into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::fake::PlaneRenderer;
    use crate::render::{DrawRole, MeshHandle};
    use glam::DQuat;

    /// 12 pads in a row 10 cm above the floor, looking down (z out of the pad = world -z); pad k
    /// sits `lift(k)` higher.
    fn pads(lift: impl Fn(usize) -> f64) -> [DAffine3; 12] {
        std::array::from_fn(|k| {
            DAffine3::from_rotation_translation(
                DQuat::from_rotation_x(std::f64::consts::PI),
                DVec3::new(0.03 * k as f64, 0.0, 0.1 + lift(k)),
            )
        })
    }

    /// The 12 pads 2 x 1 cm, touching; every third pad (0, 3, 6, 9) has `first`, the others
    /// depth cameras.
    fn views(first: SensorModel, t_world_pads: &[DAffine3; 12]) -> Vec<PadView> {
        (0..12)
            .map(|k| PadView {
                size: (0.02, 0.01),
                sensor: PadSensor { model: if k % 3 == 0 { first } else { SensorModel::DepthCamera }, optical: None },
                t_world_pad: t_world_pads[k],
                touching: true,
            })
            .collect()
    }

    /// `kind`'s contact pixels of a pad image.
    fn contact_pixels(gap: &[f32], n: u32, model: SensorModel, threshold: f64) -> Vec<(u32, u32)> {
        sensor_kind(&PadSensor { model, optical: None }).contact_pixels(gap, n, threshold)
    }

    #[test]
    fn a_surface_within_the_threshold_gives_points_on_it_and_one_beyond_gives_none() {
        // The object's surface is the plane z = 0.099: 1 mm under the even pads (contact), 4 mm
        // under the odd ones (over the 2 mm threshold).
        let mut renderer = PlaneRenderer::new(0.099);
        let cfg = TactileConfig { resolution: 16, ..TactileConfig::default() };
        let t_world_pads = pads(|k| if k % 2 == 0 { 0.0 } else { 0.003 });
        let object = Draw { mesh: MeshHandle(0), t_world_model: DMat4::IDENTITY, mask_id: 1, role: DrawRole::Target };
        // Points come out in the frame `t_camera_world` maps to: a camera 1 m above, looking down.
        let t_world_camera = DAffine3::from_rotation_translation(DQuat::from_rotation_x(std::f64::consts::PI), DVec3::new(0.0, 0.0, 1.0));
        let r =
            sense(&mut renderer, &cfg, &views(SensorModel::DepthCamera, &t_world_pads), None, object, &t_world_camera.inverse()).unwrap();
        for k in 0..12 {
            assert_eq!(r.counts[k], if k % 2 == 0 { 256 } else { 0 }, "pad {k}");
            assert_eq!(r.depth[k].len(), 256);
        }
        assert_eq!(r.points.len(), 6 * 256);
        for p in &r.points {
            let world = t_world_camera.transform_point3(p.position);
            let pad = t_world_pads[p.pad as usize].translation;
            // On the surface, under its pad, at the depth it reports.
            assert!((world.z - 0.099).abs() < 1e-6, "{world}");
            assert!((world.x - pad.x).abs() <= 0.01 + 1e-9 && (world.y - pad.y).abs() <= 0.005 + 1e-9, "{world} off pad {pad}");
            assert!((p.distance - 0.001).abs() < 1e-6);
        }
        // A taxel array reports one point per fired taxel, on the same surface.
        let taxels = views(SensorModel::TaxelArray { rows: 4, cols: 2 }, &t_world_pads);
        let r = sense(&mut renderer, &cfg, &taxels, None, object, &t_world_camera.inverse()).unwrap();
        // The taxel pads are 0, 3, 6, 9: in contact are 0 and 6.
        assert_eq!([r.counts[0], r.counts[3], r.counts[6], r.counts[9]], [8, 0, 8, 0]);
        assert!(r.points.iter().all(|p| (t_world_camera.transform_point3(p.position).z - 0.099).abs() < 1e-6));
    }

    #[test]
    fn a_depth_outside_its_view_is_no_reading() {
        let view = |near: f64, far: f64| DepthView {
            width: 2,
            height: 2,
            half_x: 0.01,
            half_y: 0.01,
            near,
            far,
            t_world_camera: DMat4::IDENTITY,
            perspective_standoff: None,
        };
        let views = [view(-0.005, 0.03), view(0.0, 0.01)];
        let mut depth = vec![vec![-0.0074, -0.005, 0.001, f32::INFINITY], vec![-0.001, 0.0, 0.01, 0.011]];
        drop_depths_outside_views(&mut depth, &views);
        assert_eq!(depth[0], vec![f32::INFINITY, -0.005, 0.001, f32::INFINITY]);
        assert_eq!(depth[1], vec![f32::INFINITY, 0.0, 0.01, f32::INFINITY]);
        // No contact where there is no reading.
        let gap = gap_above_surface(&depth[0], None);
        assert_eq!(contact_pixels(&gap, 2, SensorModel::DepthCamera, 0.002), vec![(1, 0), (0, 1)]);
    }

    #[test]
    fn contact_rules_of_the_sensor_models() {
        // A 4x4 pad: a ramp of depths 0..15 mm.
        let depth: Vec<f32> = (0..16).map(|i| i as f32 * 1e-3).collect();
        assert_eq!(contact_pixels(&depth, 4, SensorModel::DepthCamera, 0.0025).len(), 3);
        assert_eq!(contact_pixels(&depth, 4, SensorModel::Gelsight { gel_thickness_mm: 5.5 }, 0.0025).len(), 6);
        // 2x2 taxels of 2x2 pixels each, closest pixels at 0, 2, 8 and 10 mm: each fires at its
        // closest pixel.
        let taxels = SensorModel::TaxelArray { rows: 2, cols: 2 };
        assert_eq!(contact_pixels(&depth, 4, taxels, 0.0015), vec![(0, 0)]);
        assert_eq!(contact_pixels(&depth, 4, taxels, 0.0085), vec![(0, 0), (2, 0), (0, 2)]);
    }
}

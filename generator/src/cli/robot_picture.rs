//! `vtgen robot check --picture FILE`: what the physics and the touch see of the robot, drawn over
//! it from the config's camera. Left, the robot at its home with the hand at the preshape's low
//! end, as wireframes on a plain ground: each link's collision shapes (the arm's grey-blue, the
//! hand's orange) and each pad (its sensing rectangle in magenta, its axes x red, y green, z blue).
//! Right, the same drawn over a grasp the config makes (its first sample, rendered as
//! `vtgen preview` renders it): a pad floating off its finger, a collision hull wider than the
//! finger or a pad facing away shows at a glance.

use std::path::Path;

use anyhow::{Context, Result};
use glam::{DAffine3, DVec3, Vec3};
use image::{Rgb, RgbImage};
use vt_robot::{Geometry, Robot, RobotModel};

use super::preview::{config_samples, line};
use super::robot_check::config_robot;
use crate::assets::robot::{hand_surface_meshes, with_real_hand};
use crate::config::LoadedConfig;
use crate::physics::robot::{grasp_context, t_world_base};

const ARM: [u8; 3] = [70, 90, 130];
const HAND: [u8; 3] = [255, 140, 0];
const PAD: [u8; 3] = [230, 0, 200];
const AXES: [(DVec3, [u8; 3]); 3] = [(DVec3::X, [230, 40, 40]), (DVec3::Y, [30, 170, 30]), (DVec3::Z, [50, 80, 255])];
/// Pad axes' length (m).
const AXIS_LENGTH: f64 = 0.015;
/// A hull's edge is drawn where its two faces meet at more than this angle (degrees).
const CREASE_DEG: f64 = 25.0;
/// Segments of a drawn circle.
const CIRCLE: usize = 24;

/// A pinhole camera (OpenCV frame) and its image size.
struct Camera {
    t_camera_world: DAffine3,
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
}

impl Camera {
    fn project(&self, world: DVec3) -> Option<(f64, f64)> {
        let p = self.t_camera_world.transform_point3(world);
        (p.z > 1e-3).then(|| (self.fx * p.x / p.z + self.cx, self.fy * p.y / p.z + self.cy))
    }

    fn segment(&self, img: &mut RgbImage, a: DVec3, b: DVec3, colour: [u8; 3]) {
        if let (Some(pa), Some(pb)) = (self.project(a), self.project(b)) {
            // Far off-image segments (behind-the-camera clipping aside) are not drawn.
            let far = |p: (f64, f64)| p.0.abs() > 1e5 || p.1.abs() > 1e5;
            if !far(pa) && !far(pb) {
                line(img, pa, pb, colour);
            }
        }
    }
}

/// The edges of a collision shape in its link's frame.
fn edges(geometry: &Geometry) -> Vec<(DVec3, DVec3)> {
    let circle = |radius: f64, z: f64, axes: (DVec3, DVec3)| -> Vec<(DVec3, DVec3)> {
        (0..CIRCLE)
            .map(|k| {
                let at = |k: usize| {
                    let a = std::f64::consts::TAU * k as f64 / CIRCLE as f64;
                    (axes.0 * a.cos() + axes.1 * a.sin()) * radius + DVec3::Z * z
                };
                (at(k), at(k + 1))
            })
            .collect()
    };
    match geometry {
        Geometry::Box { size } => {
            let h = *size * 0.5;
            let corner = |c: usize| {
                DVec3::new(if c & 1 == 0 { -h.x } else { h.x }, if c & 2 == 0 { -h.y } else { h.y }, if c & 4 == 0 { -h.z } else { h.z })
            };
            (0..8usize)
                .flat_map(|c| [1usize, 2, 4].into_iter().filter(move |&bit| c & bit == 0).map(move |bit| (corner(c), corner(c | bit))))
                .collect()
        }
        Geometry::Sphere { radius } => {
            let mut out = circle(*radius, 0.0, (DVec3::X, DVec3::Y));
            out.extend(circle(*radius, 0.0, (DVec3::X, DVec3::Z)));
            out.extend(circle(*radius, 0.0, (DVec3::Y, DVec3::Z)));
            out
        }
        Geometry::Cylinder { radius, length } => {
            let (lo, hi) = (-length / 2.0, length / 2.0);
            let mut out = circle(*radius, lo, (DVec3::X, DVec3::Y));
            out.extend(circle(*radius, hi, (DVec3::X, DVec3::Y)));
            out.extend([DVec3::X, DVec3::Y, -DVec3::X, -DVec3::Y].map(|d| (d * *radius + DVec3::Z * lo, d * *radius + DVec3::Z * hi)));
            out
        }
        // Hulls are drawn by `hull_edges`, from the camera.
        Geometry::ConvexHull { .. } | Geometry::Mesh { .. } => Vec::new(),
    }
}

/// A hull's edges with the normals of the faces on either side (link frame).
type HullEdge = (DVec3, DVec3, DVec3, DVec3);

/// The edges of a hull or a mesh's hull, each with its two faces' normals.
fn hull_edges(geometry: &Geometry) -> Vec<HullEdge> {
    let points: Vec<Vec3> = geometry.hull_points().unwrap_or_default().iter().map(|p| p.as_vec3()).collect();
    if points.len() < 4 {
        return Vec::new();
    }
    let (vertices, faces) = rapier3d::parry::transformation::convex_hull(&points);
    let v = |i: u32| vertices[i as usize].as_dvec3();
    let mut normals: std::collections::BTreeMap<(u32, u32), Vec<DVec3>> = std::collections::BTreeMap::new();
    for f in &faces {
        let n = (v(f[1]) - v(f[0])).cross(v(f[2]) - v(f[0])).normalize_or_zero();
        for (a, b) in [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])] {
            normals.entry((a.min(b), a.max(b))).or_default().push(n);
        }
    }
    normals.into_iter().map(|((a, b), n)| (v(a), v(b), n[0], *n.get(1).unwrap_or(&n[0]))).collect()
}

/// Draws the robot's collision shapes and pads at joint values `q` (its base at `t_world_base`).
fn draw_robot(img: &mut RgbImage, robot: &Robot, model: &RobotModel, q: &[f64], t_world_base: &DAffine3, camera: &Camera) {
    let poses = model.forward_kinematics(q);
    for (id, link) in model.links.iter().enumerate() {
        let hand = id == robot.hand_root || model.is_below(id, robot.hand_root);
        let t_world_link = *t_world_base * poses[id];
        let colour = if hand { HAND } else { ARM };
        for shape in &link.collisions {
            let t = t_world_link * shape.origin;
            for (a, b) in edges(&shape.geometry) {
                camera.segment(img, t.transform_point3(a), t.transform_point3(b), colour);
            }
            // A hull's outline as the camera sees it (where a face towards it meets one away from
            // it) and its creases: every edge of a dense mesh's hull would hide the robot.
            let eye = camera.t_camera_world.inverse().translation;
            let crease = CREASE_DEG.to_radians().cos();
            for (a, b, n1, n2) in hull_edges(&shape.geometry) {
                let (a, b) = (t.transform_point3(a), t.transform_point3(b));
                let view = (a + b) * 0.5 - eye;
                let (f1, f2) = (t.transform_vector3(n1).dot(view) < 0.0, t.transform_vector3(n2).dot(view) < 0.0);
                if f1 != f2 || (n1.dot(n2) < crease && (f1 || f2)) {
                    camera.segment(img, a, b, colour);
                }
            }
        }
    }
    let sized = Robot { model: model.clone(), ..robot.clone() };
    for (pad, (length, width)) in robot.pads.iter().zip(sized.pad_sizes()) {
        let t = *t_world_base * poses[pad.frame];
        let (hx, hy) = (length / 2.0, width / 2.0);
        let corners = [DVec3::new(-hx, -hy, 0.0), DVec3::new(hx, -hy, 0.0), DVec3::new(hx, hy, 0.0), DVec3::new(-hx, hy, 0.0)];
        for k in 0..4 {
            camera.segment(img, t.transform_point3(corners[k]), t.transform_point3(corners[(k + 1) % 4]), PAD);
        }
        for (axis, colour) in AXES {
            camera.segment(img, t.translation, t.transform_point3(axis * AXIS_LENGTH), colour);
        }
    }
}

/// The floor's grid lines (every 0.1 m) around the robot's base and the workspace.
fn draw_floor(img: &mut RgbImage, camera: &Camera, centre: DVec3) {
    let grey = [200, 200, 200];
    for k in -8..=8 {
        let d = k as f64 * 0.1;
        camera.segment(img, centre + DVec3::new(d, -0.8, 0.0), centre + DVec3::new(d, 0.8, 0.0), grey);
        camera.segment(img, centre + DVec3::new(-0.8, d, 0.0), centre + DVec3::new(0.8, d, 0.0), grey);
    }
}

/// Writes the picture (PNG): the robot at home, and over the config's first grasp.
pub fn write(cfg: &LoadedConfig, ycb_dir: Option<&std::path::PathBuf>, out: &Path) -> Result<()> {
    let (robot, rc) = config_robot(cfg)?;
    // The shapes the physics collides with: the hand's mesh hulls and its pads on their surfaces
    // when the robot's description asks for them and its meshes are drawn.
    let model = match hand_surface_meshes(robot) {
        Some(hand) => with_real_hand(robot, &hand)?,
        None => robot.model.clone(),
    };
    let sample = config_samples(cfg, 1, ycb_dir)?.into_iter().next().context("the config makes no sample")?;
    let camera = Camera {
        t_camera_world: {
            let p = sample.t_world_camera.inverse();
            DAffine3::from_rotation_translation(p.rotation(), p.translation())
        },
        fx: sample.fx(),
        fy: sample.fy(),
        cx: sample.cx(),
        cy: sample.cy(),
    };
    let t_world_base = t_world_base(rc);
    let (w, h) = (sample.width, sample.height);
    // Left: at home, the hand at its preshape's low end, on a plain ground.
    let mut home = RgbImage::from_pixel(w, h, Rgb([245, 245, 245]));
    let ctx = grasp_context(robot, t_world_base, rc, DVec3::from_array(cfg.config.camera.position), None);
    let mut q = ctx.home();
    let pre: Vec<f64> = rc.grasp.preshape.iter().map(|&(lo, _)| lo).collect();
    robot.set_hand(&mut q, &pre);
    let w_centre = DVec3::from_array(rc.grasp.palm_workspace.min).lerp(DVec3::from_array(rc.grasp.palm_workspace.max), 0.5);
    draw_floor(&mut home, &camera, w_centre.with_z(0.0));
    draw_robot(&mut home, robot, &model, &q, &t_world_base, &camera);
    // Right: over the grasp the config's first sample shows, at its joint values.
    let mut grasp = RgbImage::from_raw(w, h, sample.rgb.clone()).context("an RGB image of its size")?;
    let info = sample.info.robot.as_ref().context("a robot sample carries its joint values")?;
    let q: Vec<f64> = model.dof_names().iter().map(|n| info.joint_positions.get(*n).copied().unwrap_or(0.0)).collect();
    draw_robot(&mut grasp, robot, &model, &q, &t_world_base, &camera);
    let mut sheet = RgbImage::from_pixel(2 * w + 8, h, Rgb([255, 255, 255]));
    image::imageops::replace(&mut sheet, &home, 0, 0);
    image::imageops::replace(&mut sheet, &grasp, (w + 8) as i64, 0);
    sheet.save(out).with_context(|| format!("cannot write {}", out.display()))?;
    eprintln!(
        "wrote {} (left: at home; right: over a grasp; collision shapes: arm grey-blue, hand orange; pads magenta with x, y, z axes)",
        out.display()
    );
    Ok(())
}

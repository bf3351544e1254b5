//! The renderer against analytic geometry: a plane and a box at known poses render to their exact
//! z-depth (within 1 mm) and cover exactly the expected pixels (edge pixels aside).

use glam::{DMat4, DQuat, DVec3};
use vt_objects::{Catalog, TexturedMesh, procedural_mesh};
use vtgen::config::{Intrinsics, RendererConfig};
use vtgen::render::{Draw, DrawRole, Lighting, Renderer, View, WgpuRenderer};
use vtgen::scene::look_at;

const W: u32 = 320;
const H: u32 = 240;

fn view(t_world_camera: DMat4) -> View {
    View { width: W, height: H, k: Intrinsics { fx: 300.0, fy: 310.0, cx: 161.3, cy: 118.7 }, near: 0.05, far: 20.0, t_world_camera }
}

fn lighting() -> Lighting {
    Lighting::spot(DVec3::new(0.0, 0.0, 3.0), DVec3::ZERO, [1.0; 3], [0.2; 3])
}

/// Camera-frame ray direction through the centre of pixel (u, v), with z = 1.
fn ray(v: &View, u: u32, row: u32) -> DVec3 {
    DVec3::new((u as f64 - v.k.cx) / v.k.fx, (row as f64 - v.k.cy) / v.k.fy, 1.0)
}

/// Compares a render with an analytic `hit(pixel) -> Option<z-depth>`; pixels whose 3x3
/// neighbourhood is not entirely inside or outside the shape are edge pixels and only need to be
/// consistent (drawn => depth right).
fn compare(img: &vtgen::render::RenderOutput, mask_id: u8, hit: impl Fn(u32, u32) -> Option<f64>) -> usize {
    let expect: Vec<Option<f64>> = (0..H).flat_map(|r| (0..W).map(move |u| (u, r))).map(|(u, r)| hit(u, r)).collect();
    let mut interior = 0;
    for r in 1..H - 1 {
        for u in 1..W - 1 {
            let i = (r * W + u) as usize;
            let inside = (-1i32..=1)
                .all(|dy| (-1i32..=1).all(|dx| expect[((r as i32 + dy) as u32 * W + (u as i32 + dx) as u32) as usize].is_some()));
            let outside = (-1i32..=1)
                .all(|dy| (-1i32..=1).all(|dx| expect[((r as i32 + dy) as u32 * W + (u as i32 + dx) as u32) as usize].is_none()));
            let drawn = img.mask[i] == mask_id;
            if inside {
                assert!(drawn, "pixel ({u}, {r}) should be covered");
                let err = (img.depth[i] as f64 - expect[i].unwrap()).abs();
                assert!(err < 1e-3, "pixel ({u}, {r}): depth {} vs analytic {} ({} mm off)", img.depth[i], expect[i].unwrap(), err * 1e3);
                interior += 1;
            } else if outside {
                assert!(!drawn, "pixel ({u}, {r}) should not be covered");
                assert_eq!(img.depth[i], 0.0, "pixel ({u}, {r}): nothing drawn, depth 0");
            } else if drawn && let Some(z) = expect[i] {
                assert!((img.depth[i] as f64 - z).abs() < 1e-3, "edge pixel ({u}, {r})");
            }
        }
    }
    interior
}

fn quad(half: f32) -> TexturedMesh {
    let c = [[-half, -half], [half, -half], [half, half], [-half, half]];
    TexturedMesh {
        positions: c.iter().map(|p| [p[0], p[1], 0.0]).collect(),
        normals: vec![[0.0, 0.0, 1.0]; 4],
        uvs: vec![[0.0, 0.0]; 4],
        indices: vec![0, 1, 2, 0, 2, 3],
        texture: vt_objects::Texture::solid([200, 200, 200]),
    }
}

#[test]
fn a_plane_renders_to_its_analytic_depth_and_coverage() {
    let mut r = WgpuRenderer::new(&RendererConfig::default()).unwrap();
    let plane = r.upload_mesh(&quad(0.3)).unwrap();
    let cam = look_at(DVec3::new(0.2, -0.9, 0.7), DVec3::new(0.05, 0.0, 0.0));
    let v = view(cam.matrix());
    let img =
        r.render(&v, &lighting(), &[Draw { mesh: plane, t_world_model: DMat4::IDENTITY, mask_id: 7, role: DrawRole::Occluder }]).unwrap();
    let (rot, o) = (cam.rotation(), cam.translation());
    let interior = compare(&img, 7, |u, row| {
        let d = rot * ray(&v, u, row);
        let s = -o.z / d.z; // world ray o + s d meets z = 0; camera-frame z of that point is s
        let p = o + d * s;
        (s > 0.0 && p.x.abs() <= 0.3 && p.y.abs() <= 0.3).then_some(s)
    });
    assert!(interior > 5000, "the plane covers a good part of the image ({interior} px)");
}

#[test]
fn a_box_renders_to_its_analytic_depth_and_coverage() {
    let mut r = WgpuRenderer::new(&RendererConfig::default()).unwrap();
    let entry = Catalog::builtin().get("003_cracker_box").unwrap().clone();
    let half = DVec3::from_array(entry.extents) * 0.5;
    let boxm = r.upload_mesh(&procedural_mesh(&entry)).unwrap();
    let cam = look_at(DVec3::new(0.0, -0.7, 0.4), DVec3::new(0.0, 0.0, 0.2));
    let v = view(cam.matrix());
    let pose = DMat4::from_rotation_translation(DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.5, 0.9), DVec3::new(0.02, 0.01, 0.22));
    let img = r.render(&v, &lighting(), &[Draw { mesh: boxm, t_world_model: pose, mask_id: 1, role: DrawRole::Target }]).unwrap();
    // Slab intersection in the box frame; the hit's camera z is the ray parameter (ray z = 1).
    let to_box = pose.inverse() * cam.matrix();
    let interior = compare(&img, 1, |u, row| {
        let o = to_box.transform_point3(DVec3::ZERO);
        let d = to_box.transform_vector3(ray(&v, u, row));
        let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
        for a in 0..3 {
            let (ta, tb) = ((-half[a] - o[a]) / d[a], (half[a] - o[a]) / d[a]);
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
        (t0 <= t1 && t0 > 0.0).then_some(t0)
    });
    assert!(interior > 3000, "the box covers a good part of the image ({interior} px)");
}

#[test]
fn the_main_pass_silhouette_is_the_object_drawn_alone() {
    // A box (the target, mask id 1) half hidden behind a plate held in front of it, listed first
    // and last: the silhouette the main pass counts is exactly the box's coverage with nothing in
    // front, pixel for pixel what the box alone renders to.
    let mut r = WgpuRenderer::new(&RendererConfig::default()).unwrap();
    let entry = Catalog::builtin().get("004_sugar_box").unwrap().clone();
    let boxm = r.upload_mesh(&procedural_mesh(&entry)).unwrap();
    let plate = r.upload_mesh(&quad(0.05)).unwrap();
    let cam = look_at(DVec3::new(0.0, -0.7, 0.4), DVec3::new(0.0, 0.0, 0.2));
    let v = view(cam.matrix());
    let pose = DMat4::from_rotation_translation(DQuat::from_euler(glam::EulerRot::XYZ, 0.2, -0.4, 0.7), DVec3::new(0.0, 0.0, 0.2));
    // The plate faces the camera 20 cm in front of the box, off to one side.
    let plate_pose = cam.matrix() * DMat4::from_translation(DVec3::new(0.03, 0.0, 0.5));
    let target = Draw { mesh: boxm, t_world_model: pose, mask_id: 1, role: DrawRole::Target };
    let occluder = Draw { mesh: plate, t_world_model: plate_pose, mask_id: 5, role: DrawRole::Occluder };
    let alone = r.render_mask(&v, &[target]).unwrap().iter().filter(|&&m| m == 1).count();
    for draws in [[occluder, target], [target, occluder]] {
        let img = r.render(&v, &lighting(), &draws).unwrap();
        let visible = img.mask.iter().filter(|&&m| m == 1).count();
        let hidden = img.mask.iter().filter(|&&m| m == 5).count();
        assert!(hidden > 500 && visible > 500, "the plate hides part of the box ({hidden} px plate, {visible} px box)");
        assert!(visible < alone, "the box is partly hidden ({visible} of {alone} px)");
        assert_eq!(img.silhouette_pixels, alone, "the silhouette counts every pixel the box covers alone");
    }
}

#[test]
fn the_principal_point_is_at_the_pixel_centre_convention() {
    // A 0.5-pixel square on the optical axis covers exactly pixel (cx, cy): pixel centres sit at
    // integer image coordinates (FORMAT.md). Half a pixel off, it would cover no pixel centre.
    let mut r = WgpuRenderer::new(&RendererConfig::default()).unwrap();
    let dot = r.upload_mesh(&quad(0.25 / 600.0)).unwrap();
    let cam = look_at(DVec3::new(0.1, -0.8, 0.5), DVec3::new(0.0, 0.0, 0.1));
    let v = View { k: Intrinsics { fx: 600.0, fy: 600.0, cx: 100.0, cy: 60.0 }, ..view(cam.matrix()) };
    // The square lies in the camera's image plane, 1 m in front of it, centred on the axis.
    let pose = cam.matrix() * DMat4::from_translation(DVec3::new(0.0, 0.0, 1.0));
    let img = r.render(&v, &lighting(), &[Draw { mesh: dot, t_world_model: pose, mask_id: 3, role: DrawRole::Occluder }]).unwrap();
    let covered: Vec<(u32, u32)> =
        (0..H).flat_map(|y| (0..W).map(move |x| (x, y))).filter(|&(x, y)| img.mask[(y * W + x) as usize] == 3).collect();
    assert_eq!(covered, vec![(100, 60)]);
    assert!((img.depth[(60 * W + 100) as usize] - 1.0).abs() < 1e-5);
}

#[test]
fn a_pad_pressed_on_a_box_sees_its_whole_footprint_and_a_free_pad_sees_nothing() {
    use vtgen::config::{SensorModel, TactileConfig};
    use vtgen::sensors::tactile::sense;
    let mut r = WgpuRenderer::new(&RendererConfig::default()).unwrap();
    let entry = Catalog::builtin().get("009_gelatin_box").unwrap().clone();
    let boxm = r.upload_mesh(&procedural_mesh(&entry)).unwrap();
    let half = DVec3::from_array(entry.extents) * 0.5;
    // The box's +z face lies 0.5 mm in front of pad 0 (its z points at the box); other pads look away.
    let pad0 = DMat4::from_rotation_translation(DQuat::from_rotation_x(std::f64::consts::PI), DVec3::new(0.0, 0.0, half.z + 0.0005));
    let far = DMat4::from_translation(DVec3::new(0.0, 0.0, 1.0));
    let pads: [glam::DAffine3; 12] = std::array::from_fn(|k| glam::DAffine3::from_mat4(if k == 0 { pad0 } else { far }));
    let cfg = TactileConfig::default();
    let object = Draw { mesh: boxm, t_world_model: DMat4::IDENTITY, mask_id: 1, role: DrawRole::Target };
    let reading = sense(&mut r, &cfg, &pad_views(SensorModel::DepthCamera, &pads), None, object, &glam::DAffine3::IDENTITY).unwrap();
    assert_eq!(reading.counts[0], 32 * 32, "the whole pad footprint is in contact");
    assert!(reading.depth[0].iter().all(|d| (d - 0.0005).abs() < 1e-5), "flat face at 0.5 mm");
    assert!(reading.counts[1..].iter().all(|&c| c == 0), "pads away from the object report nothing");
    assert!(reading.depth[1].iter().all(|d| d.is_infinite()));
    // Points are on the box face, in the frame the caller asked for (here the world).
    assert!(
        reading.points.iter().all(|p| (p.position.z - half.z).abs() < 1e-5 && p.position.x.abs() <= 0.015 && p.position.y.abs() <= 0.01)
    );
}

/// 3 x 2 cm pads at `pads`, all touching, each with sensor `model`.
fn pad_views(model: vtgen::config::SensorModel, pads: &[glam::DAffine3]) -> Vec<vtgen::sensors::tactile::PadView> {
    pads.iter()
        .map(|&t_world_pad| vtgen::sensors::tactile::PadView {
            size: (0.03, 0.02),
            sensor: vtgen::config::PadSensor { model, optical: None },
            t_world_pad,
            touching: true,
        })
        .collect()
}

/// A gelatin-box face tilted 15 degrees about x crossing the pad plane of 12 identical pads at the
/// origin (looking at the box): only part of each pad is within the contact threshold. Returns the
/// renderer, the box draw, the pads, and the face's normal and a point on it.
fn tilted_face() -> (WgpuRenderer, Draw, [glam::DAffine3; 12], DVec3, DVec3) {
    let mut r = WgpuRenderer::new(&RendererConfig::default()).unwrap();
    let entry = Catalog::builtin().get("009_gelatin_box").unwrap().clone();
    let boxm = r.upload_mesh(&procedural_mesh(&entry)).unwrap();
    let half = DVec3::from_array(entry.extents) * 0.5;
    let tilt = DQuat::from_rotation_x(15f64.to_radians());
    let pose = DMat4::from_rotation_translation(tilt, DVec3::new(0.0, 0.0, -half.z));
    let (normal, on_face) = (tilt * DVec3::Z, pose.transform_point3(DVec3::new(0.0, 0.0, half.z)));
    let pad = DMat4::from_rotation_translation(DQuat::from_rotation_x(std::f64::consts::PI), DVec3::new(0.0, 0.0, 0.0005));
    let pads: [glam::DAffine3; 12] = std::array::from_fn(|_| glam::DAffine3::from_mat4(pad));
    (r, Draw { mesh: boxm, t_world_model: pose, mask_id: 1, role: DrawRole::Target }, pads, normal, on_face)
}

#[test]
fn the_three_sensor_models_report_the_same_surface_patch() {
    use vtgen::config::{SensorModel, TactileConfig};
    use vtgen::sensors::tactile::sense;
    let (mut r, object, pads, normal, on_face) = tilted_face();
    let mut cloud = |model: SensorModel| {
        let cfg = TactileConfig::default();
        let reading = sense(&mut r, &cfg, &pad_views(model, &pads), None, object, &glam::DAffine3::IDENTITY).unwrap();
        reading.points.iter().filter(|p| p.pad == 0).map(|p| p.position).collect::<Vec<_>>()
    };
    let camera = cloud(SensorModel::DepthCamera);
    let gel = cloud(SensorModel::Gelsight { gel_thickness_mm: 1.0 });
    let taxels = cloud(SensorModel::TaxelArray { rows: 4, cols: 6 });
    for (name, pts) in [("depth camera", &camera), ("gelsight", &gel), ("taxels", &taxels)] {
        assert!(!pts.is_empty(), "{name} sees the contact");
        for p in pts.iter() {
            assert!(normal.dot(*p - on_face).abs() < 2e-5, "{name}: point {p} off the face");
        }
    }
    assert!(camera.len() < 32 * 32, "the tilted face touches part of the pad only ({})", camera.len());
    // The gel (1 mm) and the taxels sample inside the camera's 2 mm contact patch.
    let inside = |p: &DVec3| camera.iter().any(|q| q.distance(*p) < 1e-9);
    assert!(gel.len() < camera.len() && gel.iter().all(inside));
    assert!(taxels.len() <= 24 && taxels.iter().all(inside));
}

#[test]
fn perspective_pads_see_the_same_surface_as_orthographic_ones() {
    use vtgen::config::{PadProjection, SensorModel, TactileConfig};
    use vtgen::sensors::tactile::sense;
    let (mut r, object, pads, normal, on_face) = tilted_face();
    let cfg = TactileConfig { projection: PadProjection::Perspective, ..TactileConfig::default() };
    let persp = sense(&mut r, &cfg, &pad_views(SensorModel::DepthCamera, &pads), None, object, &glam::DAffine3::IDENTITY).unwrap();
    let plain = TactileConfig::default();
    let ortho = sense(&mut r, &plain, &pad_views(SensorModel::DepthCamera, &pads), None, object, &glam::DAffine3::IDENTITY).unwrap();
    assert!(persp.counts[0] > 100 && persp.counts[0] < 1024);
    for p in persp.points.iter().filter(|p| p.pad == 0) {
        assert!(normal.dot(p.position - on_face).abs() < 2e-5, "perspective point {} off the face", p.position);
    }
    // The same contact patch, up to a few rows of pixels (the pinhole's rays spread with depth).
    let diff = persp.counts[0] as i64 - ortho.counts[0] as i64;
    assert!(diff.abs() <= 96, "{} vs {}", persp.counts[0], ortho.counts[0]);
}

/// Does the segment from `p` to `light` pass through the axis-aligned box `centre ± half`?
fn segment_hits_box(p: DVec3, light: DVec3, centre: DVec3, half: DVec3) -> bool {
    let d = light - p;
    let (mut t0, mut t1) = (1e-6f64, 1.0f64);
    for a in 0..3 {
        let (lo, hi) = (centre[a] - half[a], centre[a] + half[a]);
        if d[a].abs() < 1e-12 {
            if p[a] < lo || p[a] > hi {
                return false;
            }
            continue;
        }
        let (ta, tb) = ((lo - p[a]) / d[a], (hi - p[a]) / d[a]);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    t0 <= t1
}

#[test]
fn a_box_casts_its_shadow_where_geometry_puts_it() {
    // A 10 x 10 x 20 cm box on a white floor under a spotlight at a known position: every floor
    // pixel more than 3 px from the analytic shadow's outline is dark inside it and lit outside.
    let mut r = WgpuRenderer::new(&RendererConfig::default()).unwrap();
    let floor = r.upload_mesh(&quad(1.5)).unwrap();
    let half = DVec3::new(0.05, 0.05, 0.1);
    let unit_box = procedural_mesh(&vt_objects::CatalogEntry {
        extents: (half * 2.0).to_array(),
        ..Catalog::builtin().get("003_cracker_box").unwrap().clone()
    });
    let boxm = r.upload_mesh(&unit_box).unwrap();
    let centre = DVec3::new(0.0, 0.0, 0.1);
    let light = DVec3::new(0.35, 0.25, 0.9);
    let lighting = Lighting { cone_deg: 60.0, softness: 0.9, ..Lighting::spot(light, DVec3::ZERO, [1.0; 3], [0.08; 3]) };
    let cam = look_at(DVec3::new(-0.15, -0.75, 0.8), DVec3::new(-0.1, -0.05, 0.0));
    let v = view(cam.matrix());
    let draws = [
        Draw { mesh: floor, t_world_model: DMat4::IDENTITY, mask_id: 5, role: DrawRole::Occluder },
        Draw { mesh: boxm, t_world_model: DMat4::from_translation(centre), mask_id: 1, role: DrawRole::Target },
    ];
    let img = r.render(&v, &lighting, &draws).unwrap();
    if let Ok(path) = std::env::var("VTGEN_TEST_SHADOW_PNG") {
        image::RgbImage::from_raw(W, H, img.rgb.clone()).unwrap().save(path).unwrap();
    }
    let (rot, o) = (cam.rotation(), cam.translation());
    // Per pixel: Some(in shadow?) for floor pixels seen directly, by ray casting.
    let class: Vec<Option<bool>> = (0..H)
        .flat_map(|row| (0..W).map(move |u| (u, row)))
        .map(|(u, row)| {
            let d = rot * ray(&v, u, row);
            let p = o + d * (-o.z / d.z);
            // Floor seen directly, well inside the spot's cone.
            let seen = !segment_hits_box(o, p, centre, half) && p.truncate().length() < 0.45;
            seen.then(|| segment_hits_box(p, light, centre, half))
        })
        .collect();
    let luma = |i: usize| img.rgb[3 * i] as f64 * 0.3 + img.rgb[3 * i + 1] as f64 * 0.59 + img.rgb[3 * i + 2] as f64 * 0.11;
    let (mut shadow, mut lit) = (Vec::new(), Vec::new());
    let margin = 3i64;
    for row in margin..H as i64 - margin {
        for u in margin..W as i64 - margin {
            let i = (row * W as i64 + u) as usize;
            let Some(c) = class[i] else { continue };
            let clear =
                (-margin..=margin).all(|dy| (-margin..=margin).all(|dx| class[((row + dy) * W as i64 + u + dx) as usize] == Some(c)));
            if clear {
                assert_eq!(img.mask[i], 5, "pixel ({u}, {row}) is floor");
                if c { shadow.push(luma(i)) } else { lit.push(luma(i)) }
            }
        }
    }
    assert!(shadow.len() > 500 && lit.len() > 5000, "{} shadow and {} lit pixels to compare", shadow.len(), lit.len());
    let max_shadow = shadow.iter().copied().fold(0.0, f64::max);
    let lit_sorted = {
        let mut l = lit.clone();
        l.sort_by(f64::total_cmp);
        l
    };
    // Every shadowed pixel is darker than 99.9% of the lit floor near the box.
    let dark_enough = lit_sorted[lit_sorted.len() / 1000];
    assert!(max_shadow < dark_enough, "shadow up to {max_shadow}, lit floor from {dark_enough}");
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    assert!(mean(&lit) > 2.5 * mean(&shadow), "lit {} vs shadow {}", mean(&lit), mean(&shadow));
}

#[test]
fn msaa_smooths_colour_edges_and_leaves_depth_and_mask_exact() {
    let entry = Catalog::builtin().get("009_gelatin_box").unwrap().clone();
    let cam = look_at(DVec3::new(0.0, -0.6, 0.35), DVec3::new(0.0, 0.0, 0.2));
    let pose = DMat4::from_rotation_translation(DQuat::from_euler(glam::EulerRot::XYZ, 0.4, -0.3, 0.7), DVec3::new(0.0, 0.0, 0.2));
    let render = |msaa: u32| {
        let mut r = WgpuRenderer::new(&RendererConfig { msaa, ..RendererConfig::default() }).unwrap();
        let m = r.upload_mesh(&procedural_mesh(&entry)).unwrap();
        r.render(&view(cam.matrix()), &lighting(), &[Draw { mesh: m, t_world_model: pose, mask_id: 1, role: DrawRole::Target }]).unwrap()
    };
    let (plain, smooth) = (render(1), render(4));
    assert_eq!(plain.depth, smooth.depth, "depth is exact either way");
    assert_eq!(plain.mask, smooth.mask, "mask is exact either way");
    let on_edge = |i: usize| {
        let (x, y) = ((i as u32 % W) as i64, (i as u32 / W) as i64);
        (-1..=1).any(|dy| {
            (-1..=1).any(|dx| {
                let (u, v) = (x + dx, y + dy);
                u >= 0 && v >= 0 && u < W as i64 && v < H as i64 && plain.mask[(v * W as i64 + u) as usize] != plain.mask[i]
            })
        })
    };
    let changed: Vec<usize> = (0..(W * H) as usize).filter(|&i| plain.rgb[3 * i..3 * i + 3] != smooth.rgb[3 * i..3 * i + 3]).collect();
    let edge_changes = changed.iter().filter(|&&i| on_edge(i)).count();
    assert!(edge_changes > 50, "anti-aliasing changes the silhouette's pixels ({edge_changes})");
    // Texture and shading sample at the same pixel centres elsewhere: small differences only.
    let big_interior = changed
        .iter()
        .filter(|&&i| !on_edge(i))
        .filter(|&&i| (0..3).any(|c| plain.rgb[3 * i + c].abs_diff(smooth.rgb[3 * i + c]) > 24))
        .count();
    assert!(big_interior < edge_changes / 4, "{big_interior} interior pixels changed much");
}

#[test]
fn timing_the_passes_one_by_one_changes_no_pixel_and_times_each_pass_run() {
    // A lit box casting a shadow, and the pads' depth views: once as `generate` renders, once
    // with every pass submitted and waited for on its own (`vtgen bench --per-pass`).
    let renders = |timed: bool| {
        let mut r = WgpuRenderer::new(&RendererConfig::default()).unwrap();
        assert!(!timed || r.time_passes(), "the wgpu renderer times its passes");
        let floor = r.upload_mesh(&quad(1.5)).unwrap();
        let boxm = r.upload_mesh(&procedural_mesh(Catalog::builtin().get("003_cracker_box").unwrap())).unwrap();
        let lighting = Lighting { cone_deg: 60.0, ..Lighting::spot(DVec3::new(0.35, 0.25, 0.9), DVec3::ZERO, [1.0; 3], [0.08; 3]) };
        let v = view(look_at(DVec3::new(-0.15, -0.75, 0.8), DVec3::new(-0.1, -0.05, 0.0)).matrix());
        let draws = [
            Draw { mesh: floor, t_world_model: DMat4::IDENTITY, mask_id: 5, role: DrawRole::Occluder },
            Draw { mesh: boxm, t_world_model: DMat4::from_translation(DVec3::new(0.0, 0.0, 0.11)), mask_id: 1, role: DrawRole::Target },
        ];
        let img = r.render(&v, &lighting, &draws).unwrap();
        // Twelve 32 x 32 views looking down at the box's top from 5 cm above it.
        let pad = vtgen::render::DepthView {
            width: 32,
            height: 32,
            half_x: 0.02,
            half_y: 0.02,
            near: 0.0,
            far: 0.1,
            // Looking straight down (z forward = -Z), x along X, y along -Y.
            t_world_camera: DMat4::from_cols(glam::DVec4::X, glam::DVec4::NEG_Y, glam::DVec4::NEG_Z, glam::DVec4::new(0.0, 0.0, 0.27, 1.0)),
            perspective_standoff: None,
        };
        let depths = r.render_depth_views(&[pad; 12], &draws).unwrap();
        assert!(depths[0].iter().any(|d| d.is_finite()), "the views see the box");
        (img, depths, r.pass_times())
    };
    let (plain, plain_depths, none) = renders(false);
    let (timed, timed_depths, times) = renders(true);
    assert!(none.is_none(), "passes are timed only when asked");
    assert_eq!((&plain.rgb, &plain.depth, &plain.mask), (&timed.rgb, &timed.depth, &timed.mask), "timing changed the image");
    assert_eq!(plain_depths, timed_depths, "timing changed the depth views");
    let t = times.expect("timed");
    for (name, seconds) in t.named() {
        let ran = !matches!(name, "main colour msaa" | "mask views" | "optical shading");
        assert_eq!(seconds > 0.0, ran, "{name}: {seconds} s");
    }
}

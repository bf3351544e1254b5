//! `vtgen validate`: a dataset is intact and its ground truth is right. Checks the manifest's
//! checksums, that every complete shard on disk is in the manifest, that every shard's summary and
//! chunk indexes are readable, that every sample is there with all its messages (decompressing a
//! chunk verifies its CRC), and re-projects the object model onto the stored mask and depth and the
//! object's pixels onto the posed model for a sample of each shard (every sample with `--full`).

use std::path::Path;

use anyhow::Result;
use glam::DVec3;
use vt_dataset::{Manifest, PlyMesh, Sample, ShardReader, read_ply, topics};
use vt_objects::SurfaceSampler;

/// Area-weighted points on the mesh surface with their face normals (deterministic).
pub fn surface_points(mesh: &PlyMesh, n: usize) -> Vec<(DVec3, DVec3)> {
    let surface = SurfaceSampler::from_mesh(&mesh.positions, mesh.triangles.iter().copied());
    if surface.is_empty() {
        return Vec::new();
    }
    let mut state = 0x9e3779b97f4a7c15u64;
    let mut rnd = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..n)
        .map(|_| {
            let k = surface.pick(rnd());
            let (u, v) = (rnd(), rnd());
            (surface.point(k, u, v), surface.face_normal(k))
        })
        .collect()
}

pub struct Reprojection {
    pub visible: usize,
    pub front_facing: usize,
    pub agreeing: usize,
    /// Facing points under a robot surface that touches them (within 2 mm): where a pad presses
    /// on the object, the picture shows the pad. Neither visible nor hidden.
    pub touched: usize,
    /// Facing points not hidden at their own pixel but within a pixel of an occluder's edge:
    /// something else drawn in front of them, or the object's own nearer part where the posed
    /// model puts one. The object's sliver between such an edge and its own silhouette may cover
    /// no pixel centre. Neither visible nor hidden.
    pub at_occluder_edge: usize,
}

/// Projects the model's surface points with the sample's pose and intrinsics. A point is *visible*
/// when it faces the camera (not grazing), the posed model does not hide it behind another part of
/// itself, and nothing else is drawn in front of it (a robot link touching it, within 2 mm, is
/// counted apart: `touched`; so is a point within a pixel of an occluder's edge,
/// `at_occluder_edge`); it *agrees* when a pixel within one pixel of its projection has the
/// object's mask id and its depth within 2 mm of the point's depth or of the point's tangent plane
/// seen through that pixel's centre. The plane is for flat faces seen at a grazing angle (at 72°
/// their depth changes by 4 mm per pixel at 0.9 m, and the nearest pixel centre may be 0.7 px
/// away); the point's depth for curved ones, which bend away from the plane. The object's own
/// occlusion is the posed model's (a ray cast), never the picture's, so a pose a few millimetres
/// off, nearer or further, fails.
pub fn reproject(s: &Sample, model: &Model) -> Reprojection {
    use rapier3d::parry::query::{Ray, RayCast};
    let mask_id = vt_dataset::mask_ids::TARGET_OBJECT;
    let (w, h) = (s.width as i64, s.height as i64);
    let pose = s.t_camera_object;
    let r = pose.rotation();
    let to_object = pose.inverse();
    let eye = to_object.transform_point(DVec3::ZERO).as_vec3();
    // The z-depth (camera frame) where the posed model first meets the camera ray along `dir`.
    let model_depth = |dir: DVec3| {
        let dir = dir.normalize();
        let ray = Ray::new(eye, (to_object.rotation() * dir).as_vec3());
        model.mesh.cast_local_ray(&ray, f32::MAX, false).map(|t| t as f64 * dir.z)
    };
    let mut out = Reprojection { visible: 0, front_facing: 0, agreeing: 0, touched: 0, at_occluder_edge: 0 };
    for (p, n) in &model.points {
        let pc = pose.transform_point(*p);
        let nc = r * *n;
        if pc.z <= 0.0 {
            continue;
        }
        let u = s.fx() * pc.x / pc.z + s.cx();
        let v = s.fy() * pc.y / pc.z + s.cy();
        let (ui, vi) = (u.round() as i64, v.round() as i64);
        if ui < 1 || vi < 1 || ui >= w - 1 || vi >= h - 1 {
            continue;
        }
        // Closed meshes: a point faces the camera when its outward normal points at it.
        if nc.dot(-pc.normalize()) < 0.3 {
            continue;
        }
        out.front_facing += 1;
        let at = |x: i64, y: i64| (y * w + x) as usize;
        let (d, mask) = (s.depth[at(ui, vi)], s.mask[at(ui, vi)]);
        let nearer = |d: f32| d > 0.0 && (d as f64) < pc.z - 0.002;
        if mask != mask_id && nearer(d) {
            continue; // something else in front
        }
        if mask == mask_id && nearer(d) && model_depth(pc).is_some_and(|z| z < pc.z - 0.002) {
            continue; // behind another part of the object
        }
        if vt_dataset::mask_ids::is_robot(mask) && (d as f64 - pc.z).abs() <= 0.002 {
            out.touched += 1;
            continue;
        }
        let neighbours = || (-1..=1).flat_map(|dy| (-1..=1).map(move |dx| (ui + dx, vi + dy)));
        if neighbours().any(|(x, y)| s.mask[at(x, y)] != mask_id && nearer(s.depth[at(x, y)])) {
            out.at_occluder_edge += 1;
            continue;
        }
        // The tangent plane n·X = n·p meets the pixel centre's ray r at z = n·p / n·r.
        let plane_depth = |x: i64, y: i64| nc.dot(pc) / nc.dot(pixel_ray(s, x as f64, y as f64));
        let agrees = neighbours().any(|(x, y)| {
            let (i, z) = (at(x, y), plane_depth(x, y));
            let d = s.depth[i] as f64;
            s.mask[i] == mask_id && ((d - pc.z).abs() <= 0.002 || (d - z).abs() <= 0.002)
        });
        // Not seen at any pixel centre near it, where the posed model puts a nearer part of the
        // object within a pixel (beyond the point's own tangent plane): a self-occlusion edge.
        if !agrees
            && neighbours()
                .any(|(x, y)| model_depth(pixel_ray(s, x as f64, y as f64)).is_some_and(|z| z < pc.z.min(plane_depth(x, y)) - 0.002))
        {
            out.at_occluder_edge += 1;
            continue;
        }
        out.visible += 1;
        out.agreeing += agrees as usize;
    }
    out
}

/// The camera-frame ray through pixel (x, y) of the sample's image, scaled to z = 1: a z-depth
/// times it is the point seen there.
fn pixel_ray(s: &Sample, x: f64, y: f64) -> DVec3 {
    DVec3::new((x - s.cx()) / s.fx(), (y - s.cy()) / s.fy(), 1.0)
}

/// The object's pixels against its posed mesh.
pub struct PixelsOnMesh {
    /// Pixels with the object's mask id and a depth.
    pub pixels: usize,
    /// Those that, back-projected with their depth, lie more than 1 mm from the posed mesh.
    pub off: usize,
    /// The largest such distance (m).
    pub farthest: f64,
}

/// Every pixel with the object's mask id, back-projected with its depth, against the posed mesh:
/// the check from the other side (pixels onto the model, where `reproject` takes the model onto
/// the pixels). A wrong pose moves every pixel off the mesh; a pixel alone off it is the
/// rasterizer's (an edge-on triangle's depth carried past its vertices: one pixel in 10.8 million,
/// 1.8 mm, over the datasets measured), so a sample may have one in a thousand.
pub fn pixels_off_the_mesh(s: &Sample, model: &Model) -> PixelsOnMesh {
    use rapier3d::parry::query::PointQuery;
    let to_object = s.t_camera_object.inverse();
    let w = s.width as usize;
    let mut out = PixelsOnMesh { pixels: 0, off: 0, farthest: 0.0 };
    for (i, (&m, &d)) in s.mask.iter().zip(&s.depth).enumerate() {
        if m != vt_dataset::mask_ids::TARGET_OBJECT || !(d > 0.0 && d.is_finite()) {
            continue;
        }
        let (u, v, d) = ((i % w) as f64, (i / w) as f64, d as f64);
        let p = pixel_ray(s, u, v) * d;
        let e = model.mesh.distance_to_local_point(to_object.transform_point(p).as_vec3(), false) as f64;
        out.pixels += 1;
        if e > 1e-3 {
            out.off += 1;
            out.farthest = out.farthest.max(e);
        }
    }
    out
}

/// Minimum share of visible model points that must agree with mask and depth.
pub const AGREEMENT: f64 = 0.99;

/// One problem found, naming the shard and sample when it concerns one.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    pub shard: Option<String>,
    pub sample: Option<u64>,
    pub message: String,
}

impl std::fmt::Display for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match (&self.shard, self.sample) {
            (Some(s), Some(i)) => write!(f, "{s} sample {i}: {}", self.message),
            (Some(s), None) => write!(f, "{s}: {}", self.message),
            _ => write!(f, "{}", self.message),
        }
    }
}

#[derive(Debug, Clone, Default)]
pub struct Report {
    pub shards: usize,
    pub samples: u64,
    pub ground_truth_checked: u64,
    pub problems: Vec<Problem>,
}

/// Validates the dataset at `root`.
pub fn validate(root: &Path, full: bool) -> Result<Report> {
    let manifest = Manifest::load(&root.join("manifest.json"))?;
    let mut report = Report::default();
    let mut problems = Vec::new();
    let info: Option<vt_dataset::ModelsInfo> =
        std::fs::read(root.join("models/models_info.json")).ok().and_then(|b| serde_json::from_slice(&b).ok());
    let models: Vec<Model> = match &info {
        Some(i) => Model::of_dataset(root, i)?,
        None => {
            problems.push(Problem { shard: None, sample: None, message: "models/models_info.json is missing or unreadable".into() });
            Vec::new()
        }
    };
    let listed: std::collections::BTreeSet<String> = manifest.splits.values().flat_map(|s| &s.shards).map(|e| e.file.clone()).collect();
    for split in manifest.splits.keys() {
        if let Ok(dir) = std::fs::read_dir(root.join(split)) {
            for e in dir.flatten() {
                let name = format!("{split}/{}", e.file_name().to_string_lossy());
                if name.ends_with(".mcap") && !listed.contains(&name) {
                    problems.push(Problem {
                        shard: Some(name),
                        sample: None,
                        message: "complete shard on disk but not in the manifest".into(),
                    });
                }
            }
        }
    }
    for split in manifest.splits.values() {
        for e in &split.shards {
            let Some(sha) = &e.sha256 else { continue };
            let path = root.join(&e.file);
            let p = |m: String| Problem { shard: Some(e.file.clone()), sample: None, message: m };
            match vt_dataset::sha256_file(&path) {
                Err(_) => {
                    problems.push(p("listed in the manifest but missing".into()));
                    continue;
                }
                Ok((bytes, h)) => {
                    if Some(bytes) != e.bytes {
                        problems.push(p(format!("{bytes} bytes, the manifest says {} (truncated or replaced)", e.bytes.unwrap_or(0))));
                    } else if &h != sha {
                        problems.push(p("SHA-256 differs from the manifest (corrupted)".into()));
                    }
                }
            }
            let reader = match ShardReader::open(&path) {
                Ok(r) => r,
                Err(err) => {
                    problems.push(p(format!("{err:#}")));
                    continue;
                }
            };
            report.shards += 1;
            for index in e.first_sample..e.first_sample + e.samples {
                let sample = match reader.read(index) {
                    Ok(s) => s,
                    Err(err) => {
                        let msg = format!("{err:#}");
                        let msg = msg.rsplit(&format!("sample {index}: ")).next().unwrap_or(&msg).to_string();
                        problems.push(Problem { shard: Some(e.file.clone()), sample: Some(index), message: msg });
                        continue;
                    }
                };
                report.samples += 1;
                let spot = full || index == e.first_sample;
                if spot && !models.is_empty() {
                    if let Some(m) = check_ground_truth(&sample, &models) {
                        problems.push(Problem { shard: Some(e.file.clone()), sample: Some(index), message: m });
                    }
                    report.ground_truth_checked += 1;
                }
            }
        }
    }
    report.problems = problems;
    Ok(report)
}

/// An object model as the checks need it: surface points with normals, and the mesh for distances.
pub struct Model {
    pub points: Vec<(DVec3, DVec3)>,
    pub mesh: rapier3d::parry::shape::TriMesh,
}

impl Model {
    pub fn new(m: &PlyMesh) -> Result<Self> {
        let v = m.positions.iter().map(|p| glam::Vec3::from(*p)).collect();
        let mesh = rapier3d::parry::shape::TriMesh::new(v, m.triangles.clone()).map_err(|e| anyhow::anyhow!("model mesh: {e:?}"))?;
        Ok(Model { points: surface_points(m, 3000), mesh })
    }

    /// A dataset's object models (`root/models/`), in its models_info.json order.
    pub fn of_dataset(root: &Path, info: &vt_dataset::ModelsInfo) -> Result<Vec<Self>> {
        info.objects.iter().map(|o| read_ply(&root.join("models").join(&o.file)).and_then(|m| Model::new(&m))).collect()
    }
}

/// The sample's ground truth against its images and its tactile points; a message when it does
/// not hold.
pub fn check_ground_truth(s: &Sample, models: &[Model]) -> Option<String> {
    use rapier3d::parry::query::PointQuery;
    let info = &s.info;
    let Some(obj) = Some(info.object_index as usize).filter(|&o| o < models.len()) else {
        return Some(format!("{} object_index {} is not in models_info.json", topics::SAMPLE_INFO, info.object_index));
    };
    let model = &models[obj];
    if let Some(t) = &s.tactile {
        // The touch of the frame's instant, and an episode's touch between frames: on the surface
        // of the object where its pose (the state's, then) puts it.
        let mut readings = vec![(None, &t.points, s.t_camera_object)];
        for (time, touch) in s.episode.iter().flat_map(|e| &e.tactile) {
            let state = s.episode.iter().flat_map(|e| &e.states).rev().find(|(ts, _)| ts <= time).map(|(_, st)| st);
            let Some(state) = state else { return Some(format!("touch at {time} ns has no state at or before it")) };
            readings.push((Some(*time), &touch.points, state.t_camera_object));
        }
        for (time, points, t_camera_object) in readings {
            let to_object = t_camera_object.inverse();
            for p in points {
                let q = to_object.transform_point(glam::Vec3::from(p.position).as_dvec3());
                let d = model.mesh.distance_to_local_point(q.as_vec3(), false);
                if d > 1e-3 {
                    let at = time.map_or(String::new(), |t| format!(" at {t} ns"));
                    return Some(format!("a tactile point{at} is {:.2} mm off the object's surface", d * 1e3));
                }
            }
        }
        // The optical images are those of the sensors `/sample/info` lists, at their size.
        let sensors = info.robot.as_ref().and_then(|r| r.tactile.as_ref()).and_then(|t| t.optical.as_ref());
        let listed: Vec<&String> = sensors.map(|m| t.pads.iter().filter(|p| m.contains_key(*p)).collect()).unwrap_or_default();
        if t.optical.iter().map(|o| &o.pad).ne(listed.iter().copied()) {
            return Some(format!(
                "the optical images ({:?}) are not those of the sensors /sample/info lists ({listed:?})",
                t.optical.iter().map(|o| &o.pad).collect::<Vec<_>>()
            ));
        }
        for o in &t.optical {
            let size = sensors.and_then(|m| m[&o.pad].get("image_size")).and_then(|v| serde_json::from_value::<[u32; 2]>(v.clone()).ok());
            if size != Some([o.width, o.height]) {
                return Some(format!("/tactile/{}/image is {}x{}, its sensor's image_size {size:?}", o.pad, o.width, o.height));
            }
        }
    }
    let off = pixels_off_the_mesh(s, model);
    if off.off > (off.pixels / 1000).max(1) {
        return Some(format!(
            "{} of {} object pixels lie more than 1 mm off the posed mesh (the farthest {:.2} mm)",
            off.off,
            off.pixels,
            off.farthest * 1e3
        ));
    }
    let r = reproject(s, model);
    if r.visible < 30 {
        return None; // hidden (by the hand): nothing to compare
    }
    let share = r.agreeing as f64 / r.visible as f64;
    (share < AGREEMENT).then(|| format!("only {:.1}% of {} visible model points agree with mask and depth", 100.0 * share, r.visible))
}

/// `vtgen validate`: every problem found, the verdict; an error when the dataset is not valid.
pub fn run(dataset: &Path, full: bool) -> Result<()> {
    let r = validate(dataset, full)?;
    for p in &r.problems {
        eprintln!("problem: {p}");
    }
    println!(
        "{}: {} shards, {} samples read, ground truth checked on {}: {}",
        dataset.display(),
        r.shards,
        r.samples,
        r.ground_truth_checked,
        if r.problems.is_empty() { "valid".to_string() } else { format!("{} problem(s)", r.problems.len()) }
    );
    anyhow::ensure!(r.problems.is_empty(), "{} is not valid ({} problem(s))", dataset.display(), r.problems.len());
    Ok(())
}

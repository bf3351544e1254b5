//! `vtgen export bop DATASET OUT`: the dataset in the BOP format (bop.felk.cvut.cz, "datasets
//! format"), so the BOP toolkit and BOP-based trainers read it unchanged.
//!
//! Layout: one BOP scene per shard (`<split>/<shard index:06>/`), `im_id` = the sample's index in
//! its split, `obj_id` = the object's position in the config + 1. Lengths in millimetres, as BOP
//! wants. The amodal masks (`mask/`) are re-rendered: a shard stores only the visible mask, so the
//! object is drawn alone at its ground-truth pose with the same intrinsics. Tactile points go to a
//! `scene_tactile.json` beside the BOP files (see `datasets/FORMAT.md`, "BOP export").

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, Result};
use glam::{DMat3, DMat4, DVec3};
use image::{GrayImage, ImageBuffer, Luma, RgbImage};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::{Value, json};
use vt_dataset::{ContinuousSymmetry, DatasetReader, LengthUnit, ModelsInfo, Sample, read_ply, write_ply};
use vt_objects::{Symmetry, Texture, TexturedMesh};

use crate::config::{Intrinsics, RendererConfig};
use crate::plan::SPLITS;
use crate::render::{Draw, DrawRole, MeshHandle, Renderer, View, WgpuRenderer};

/// BOP depth images are uint16 with `depth_mm = value × depth_scale`: 0.1 mm steps reach 6.55 m.
pub const DEPTH_SCALE: f64 = 0.1;

#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct ExportSummary {
    pub scenes: usize,
    pub images: usize,
    pub objects: usize,
}

fn mm(v: DVec3) -> [f64; 3] {
    (v * 1000.0).to_array()
}

/// Row-major 3×3, as BOP's `cam_R_*` fields.
fn row_major(r: DMat3) -> [f64; 9] {
    let c = r.to_cols_array();
    [c[0], c[3], c[6], c[1], c[4], c[7], c[2], c[5], c[8]]
}

/// BOP's `models_info.json` entry: bounding box and diameter in mm, and the object's symmetries as
/// `models_info.json` lists them (measured on the mesh by `generate`), translations and offsets
/// converted to mm. A dataset written before the transforms were listed has only the kind: they are
/// derived from its mesh (`positions`, `indices`: the model in metres) here, as `generate` does now.
fn model_info(m: &vt_dataset::ModelInfo, lo: DVec3, hi: DVec3, positions: &[[f32; 3]], indices: &[u32]) -> Value {
    let mut v = json!({
        "diameter": m.diameter * 1000.0,
        "min_x": lo.x * 1000.0, "min_y": lo.y * 1000.0, "min_z": lo.z * 1000.0,
        "size_x": (hi.x - lo.x) * 1000.0, "size_y": (hi.y - lo.y) * 1000.0, "size_z": (hi.z - lo.z) * 1000.0,
    });
    let listed = !m.symmetries_discrete.is_empty() || !m.symmetries_continuous.is_empty();
    let (discrete, continuous) = match m.symmetry.parse::<Symmetry>() {
        Ok(kind) if !listed && kind != Symmetry::None => {
            let d = vt_objects::derive_symmetries(positions, indices, kind);
            let continuous =
                d.continuous.iter().map(|a| ContinuousSymmetry { axis: a.axis.to_array(), offset: a.offset.to_array() }).collect();
            (d.discrete_row_major(), continuous)
        }
        _ => (m.symmetries_discrete.clone(), m.symmetries_continuous.clone()),
    };
    if !discrete.is_empty() {
        let mm: Vec<Vec<f64>> = discrete
            .iter()
            .map(|t| t.iter().enumerate().map(|(k, x)| if k % 4 == 3 && k < 12 { x * 1000.0 } else { *x }).collect())
            .collect();
        v["symmetries_discrete"] = json!(mm);
    }
    if !continuous.is_empty() {
        v["symmetries_continuous"] =
            continuous.iter().map(|c| json!({"axis": c.axis, "offset": c.offset.map(|x| x * 1000.0)})).collect::<Vec<Value>>().into();
    }
    v
}

/// x, y, width, height of the pixels where `inside` holds, as `bop_toolkit`'s `calc_2d_bbox`
/// measures them (width = max x - min x: a one-pixel box is 0 wide); `[-1, -1, -1, -1]` for none.
fn bbox(width: u32, height: u32, inside: impl Fn(usize) -> bool) -> [i64; 4] {
    let (mut x0, mut y0, mut x1, mut y1) = (i64::MAX, i64::MAX, -1i64, -1i64);
    for y in 0..height as i64 {
        for x in 0..width as i64 {
            if inside((y * width as i64 + x) as usize) {
                x0 = x0.min(x);
                y0 = y0.min(y);
                x1 = x1.max(x);
                y1 = y1.max(y);
            }
        }
    }
    if x1 < 0 { [-1, -1, -1, -1] } else { [x0, y0, x1 - x0, y1 - y0] }
}

fn save_png<P: image::Pixel<Subpixel = S> + image::PixelWithColorType, S: image::Primitive>(
    img: &ImageBuffer<P, Vec<S>>,
    path: &Path,
) -> Result<()>
where
    [S]: image::EncodableLayout,
{
    img.save(path).with_context(|| format!("cannot write {}", path.display()))
}

fn write_json(path: &Path, v: &Value) -> Result<()> {
    vt_dataset::write_atomic(path, serde_json::to_string_pretty(v)?.as_bytes())
}

/// One BOP scene (a shard) being written.
#[derive(Default)]
struct Scene {
    camera: BTreeMap<u64, Value>,
    gt: BTreeMap<u64, Value>,
    gt_info: BTreeMap<u64, Value>,
    tactile: BTreeMap<u64, Value>,
}

fn keyed(m: &BTreeMap<u64, Value>) -> Value {
    Value::Object(m.iter().map(|(k, v)| (k.to_string(), v.clone())).collect())
}

/// What `export_bop` writes besides the images.
#[derive(Debug, Clone, Copy)]
pub struct BopOptions {
    /// Also write the exact float depth as OpenEXR.
    pub exr: bool,
    /// The test targets (`test_targets_bop19.json`, `test_targets_bop24.json`) list the test
    /// images whose object is visible at least this fraction (and by one pixel); BOP's own
    /// datasets use 0.1, the paper evaluates up to > 85 % occlusion, hence 0 by default.
    pub targets_min_visib: f64,
}

/// Exports the dataset at `root` to `out` (created; must be empty or absent).
pub fn export_bop(root: &Path, out: &Path, renderer: &RendererConfig, quiet: bool, options: BopOptions) -> Result<ExportSummary> {
    let BopOptions { exr, targets_min_visib } = options;
    let ds = DatasetReader::open(root)?;
    if out.exists() && std::fs::read_dir(out).map(|mut d| d.next().is_some()).unwrap_or(true) {
        anyhow::bail!("{} exists and is not empty: choose a new directory for the export", out.display());
    }
    std::fs::create_dir_all(out.join("models")).with_context(|| format!("cannot create {}", out.join("models").display()))?;
    let info_path = root.join("models/models_info.json");
    let models: ModelsInfo =
        serde_json::from_slice(&std::fs::read(&info_path).with_context(|| format!("cannot read {}", info_path.display()))?)
            .with_context(|| format!("{} is not a models_info.json", info_path.display()))?;

    // Models in mm, and uploaded for the amodal masks.
    let mut r = WgpuRenderer::new(renderer)?;
    let handles = export_models(root, out, &models, &mut r)?;

    let total: u64 = SPLITS.iter().map(|s| ds.manifest().splits.get(s.as_str()).map(|m| m.samples).unwrap_or(0)).sum();
    let progress = if quiet { ProgressBar::hidden() } else { ProgressBar::new(total) };
    progress.set_style(
        ProgressStyle::with_template("{spinner} {elapsed_precise} [{bar:36}] {pos}/{len} images  {per_sec}  ETA {eta}")
            .expect("valid template"),
    );
    let mut summary = ExportSummary { objects: models.objects.len(), ..Default::default() };
    let mut camera_json: Option<Value> = None;
    // BOP19 targets (localization: object and instance count per image), BOP24 (detection: images).
    let (mut targets19, mut targets24) = (Vec::new(), Vec::new());
    for split in SPLITS.map(|s| s.as_str()) {
        for shard in ds.shards(split)? {
            let dir = out.join(split).join(format!("{:06}", shard.meta().shard_index));
            for sub in ["rgb", "depth", "mask", "mask_visib"].into_iter().chain(exr.then_some("depth_exr")) {
                std::fs::create_dir_all(dir.join(sub)).with_context(|| format!("cannot create {}", dir.join(sub).display()))?;
            }
            let mut scene = Scene::default();
            for index in shard.indices().collect::<Vec<_>>() {
                let s = shard.read(index)?;
                let obj = Some(s.info.object_index as u64).filter(|&o| (o as usize) < handles.len()).with_context(|| {
                    format!("{} sample {index}: object_index is missing or not in models_info.json", shard.path().display())
                })? as usize;
                let amodal = render_alone(&mut r, &s, handles[obj])?;
                let (px_visib, visib_fract) = write_image(&mut scene, &dir, &s, obj + 1, &amodal)?;
                if split == "test" && px_visib > 0 && visib_fract >= targets_min_visib {
                    let scene_id = shard.meta().shard_index;
                    targets19.push(json!({"im_id": index, "inst_count": 1, "obj_id": obj + 1, "scene_id": scene_id}));
                    targets24.push(json!({"im_id": index, "scene_id": scene_id}));
                }
                if exr {
                    crate::cli::dump::write_exr_depth(&dir.join(format!("depth_exr/{index:06}.exr")), s.width, s.height, &s.depth)?;
                }
                camera_json.get_or_insert_with(|| {
                    json!({"width": s.width, "height": s.height, "fx": s.fx(), "fy": s.fy(), "cx": s.cx(), "cy": s.cy(), "depth_scale": DEPTH_SCALE})
                });
                summary.images += 1;
                progress.inc(1);
            }
            write_json(&dir.join("scene_camera.json"), &keyed(&scene.camera))?;
            write_json(&dir.join("scene_gt.json"), &keyed(&scene.gt))?;
            write_json(&dir.join("scene_gt_info.json"), &keyed(&scene.gt_info))?;
            if !scene.tactile.is_empty() {
                write_json(&dir.join("scene_tactile.json"), &keyed(&scene.tactile))?;
            }
            summary.scenes += 1;
        }
    }
    progress.finish_and_clear();
    if let Some(c) = camera_json {
        write_json(&out.join("camera.json"), &c)?;
    }
    write_json(&out.join("test_targets_bop19.json"), &Value::Array(targets19))?;
    write_json(&out.join("test_targets_bop24.json"), &Value::Array(targets24))?;
    Ok(summary)
}

/// The models as BOP's (`models/obj_NNNNNN.ply` in mm, `models_info.json`, and which object id
/// each `obj_id` is), each uploaded to `r` for the amodal masks: their handles, in `obj_id` order.
fn export_models(root: &Path, out: &Path, models: &ModelsInfo, r: &mut WgpuRenderer) -> Result<Vec<MeshHandle>> {
    let mut handles: Vec<MeshHandle> = Vec::new();
    let mut bop_info = serde_json::Map::new();
    let mut ids = serde_json::Map::new();
    for (k, m) in models.objects.iter().enumerate() {
        let path = root.join("models").join(&m.file);
        let ply = read_ply(&path)?;
        let obj_id = k + 1;
        let mm_positions: Vec<[f32; 3]> = ply.positions.iter().map(|p| p.map(|v| v * 1000.0)).collect();
        let indices: Vec<u32> = ply.triangles.iter().flatten().copied().collect();
        write_ply(&out.join(format!("models/obj_{obj_id:06}.ply")), &mm_positions, &ply.normals, &indices, LengthUnit::Millimetres)?;
        let (lo, hi) = ply.positions.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
            let v = glam::Vec3::from(*p).as_dvec3();
            (lo.min(v), hi.max(v))
        });
        ids.insert(obj_id.to_string(), json!(m.id));
        bop_info.insert(obj_id.to_string(), model_info(m, lo, hi, &ply.positions, &indices));
        let mesh = TexturedMesh {
            positions: ply.positions.clone(),
            normals: ply.normals.clone(),
            uvs: vec![[0.0, 0.0]; ply.positions.len()],
            indices,
            texture: Texture::solid([255, 255, 255]),
        };
        handles.push(r.upload_mesh(&mesh).with_context(|| format!("uploading {}", path.display()))?);
    }
    write_json(&out.join("models/models_info.json"), &Value::Object(bop_info))?;
    write_json(&out.join("vtgen_objects.json"), &json!({"obj_id_to_object_id": ids, "source": root.display().to_string()}))?;
    Ok(handles)
}

/// The object's full silhouette: drawn alone at its ground-truth pose (camera frame = world).
fn render_alone(r: &mut WgpuRenderer, s: &Sample, mesh: MeshHandle) -> Result<Vec<u8>> {
    let view = View {
        width: s.width,
        height: s.height,
        k: Intrinsics { fx: s.fx(), fy: s.fy(), cx: s.cx(), cy: s.cy() },
        near: 0.01,
        far: 100.0,
        t_world_camera: DMat4::IDENTITY,
    };
    r.render_mask(
        &view,
        &[Draw { mesh, t_world_model: s.t_camera_object.matrix(), mask_id: vt_dataset::mask_ids::TARGET_OBJECT, role: DrawRole::Target }],
    )
}

/// Writes one image's files and annotations; returns its visible pixels and visible fraction.
fn write_image(scene: &mut Scene, dir: &Path, s: &Sample, obj_id: usize, amodal: &[u8]) -> Result<(usize, f64)> {
    let (w, h) = (s.width, s.height);
    let im = s.index;
    let target = vt_dataset::mask_ids::TARGET_OBJECT;
    save_png(&RgbImage::from_raw(w, h, s.rgb.clone()).context("rgb size")?, &dir.join(format!("rgb/{im:06}.png")))?;
    let depth: Vec<u16> =
        s.depth.iter().map(|&d| if d > 0.0 { (d as f64 * 1000.0 / DEPTH_SCALE).round().min(u16::MAX as f64) as u16 } else { 0 }).collect();
    save_png(&ImageBuffer::<Luma<u16>, _>::from_raw(w, h, depth.clone()).context("depth size")?, &dir.join(format!("depth/{im:06}.png")))?;
    let visible: Vec<u8> = s.mask.iter().map(|&m| if m == target { 255 } else { 0 }).collect();
    let full: Vec<u8> = amodal.iter().map(|&m| if m == target { 255 } else { 0 }).collect();
    save_png(&GrayImage::from_raw(w, h, full.clone()).context("mask size")?, &dir.join(format!("mask/{im:06}_000000.png")))?;
    save_png(&GrayImage::from_raw(w, h, visible.clone()).context("mask size")?, &dir.join(format!("mask_visib/{im:06}_000000.png")))?;

    let px_all = full.iter().filter(|&&m| m > 0).count();
    let px_valid = full.iter().zip(&depth).filter(|&(&m, &d)| m > 0 && d > 0).count();
    let px_visib = visible.iter().filter(|&&m| m > 0).count();
    let visib_fract = if px_all > 0 { px_visib as f64 / px_all as f64 } else { 0.0 };
    let t_world_camera = s.t_world_camera;
    let t_camera_world = t_world_camera.inverse();
    scene.camera.insert(
        im,
        json!({
            "cam_K": s.k, "depth_scale": DEPTH_SCALE,
            "cam_R_w2c": row_major(DMat3::from_quat(t_camera_world.rotation())), "cam_t_w2c": mm(t_camera_world.translation()),
        }),
    );
    let t = &s.t_camera_object;
    scene
        .gt
        .insert(im, json!([{"cam_R_m2c": row_major(DMat3::from_quat(t.rotation())), "cam_t_m2c": mm(t.translation()), "obj_id": obj_id}]));
    scene.gt_info.insert(
        im,
        json!([{
            "bbox_obj": bbox(w, h, |i| full[i] > 0),
            "bbox_visib": bbox(w, h, |i| visible[i] > 0),
            "px_count_all": px_all, "px_count_valid": px_valid, "px_count_visib": px_visib,
            "visib_fract": visib_fract,
        }]),
    );
    if let Some(tac) = &s.tactile {
        let points: Vec<[f64; 3]> = tac.points.iter().map(|p| mm(glam::Vec3::from(p.position).as_dvec3())).collect();
        scene.tactile.insert(
            im,
            json!({
                "points_mm": points,
                "distance_mm": tac.points.iter().map(|p| p.distance as f64 * 1000.0).collect::<Vec<_>>(),
                "pad": tac.points.iter().map(|p| p.pad).collect::<Vec<_>>(),
                "pad_names": tac.pads,
            }),
        );
    }
    Ok((px_visib, visib_fract))
}

/// `vtgen export bop`: the BOP format, its amodal masks rendered with the renderer the dataset
/// was made with (its `config.json`'s adapter choice).
pub struct Bop {
    pub quiet: bool,
    pub options: BopOptions,
}

impl super::Exporter for Bop {
    fn name(&self) -> &'static str {
        "BOP"
    }

    fn export(&self, dataset: &Path, out: &Path) -> Result<()> {
        run_bop(dataset, out, self.quiet, self.options)
    }
}

fn run_bop(dataset: &Path, out: &Path, quiet: bool, opts: BopOptions) -> Result<()> {
    let renderer = std::fs::read(dataset.join("config.json"))
        .ok()
        .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok())
        .and_then(|c| serde_json::from_value(c["renderer"].clone()).ok())
        .unwrap_or_default();
    let r = export_bop(dataset, out, &renderer, quiet, opts)?;
    println!("wrote {}: {} objects, {} scenes, {} images (BOP format)", out.display(), r.objects, r.scenes, r.images);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use vt_objects::{Catalog, procedural_mesh};

    fn info(symmetry: &str) -> vt_dataset::ModelInfo {
        vt_dataset::ModelInfo {
            id: "box".into(),
            object_index: 0,
            mask_id: 1,
            symmetry: symmetry.into(),
            mass: 0.1,
            extents: [0.1, 0.1, 0.03],
            diameter: 0.114,
            source: "procedural".into(),
            file: "box.ply".into(),
            symmetries_discrete: Vec::new(),
            symmetries_continuous: Vec::new(),
        }
    }

    #[test]
    fn bop_symmetries_are_the_listed_ones_in_millimetres() {
        let mut m = info("discrete");
        m.symmetries_discrete = vec![[-1.0, 0.0, 0.0, 0.002, 0.0, -1.0, 0.0, -0.0005, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]];
        let v = model_info(&m, DVec3::splat(-0.05), DVec3::splat(0.05), &[], &[]);
        assert_eq!(v["symmetries_discrete"], json!([[-1.0, 0.0, 0.0, 2.0, 0.0, -1.0, 0.0, -0.5, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]]));
        assert!(v.get("symmetries_continuous").is_none());
        let mut m = info("continuous_z");
        m.symmetries_continuous = vec![ContinuousSymmetry { axis: [0.0, 0.6, 0.8], offset: [0.001, -0.002, 0.0] }];
        let v = model_info(&m, DVec3::splat(-0.05), DVec3::splat(0.05), &[], &[]);
        assert_eq!(v["symmetries_continuous"], json!([{"axis": [0.0, 0.6, 0.8], "offset": [1.0, -2.0, 0.0]}]));
        assert!(v.get("symmetries_discrete").is_none());
        // A symmetry that did not hold on the mesh is written as `none`: nothing to export.
        let v = model_info(&info("none"), DVec3::splat(-0.05), DVec3::splat(0.05), &[], &[]);
        assert!(v.get("symmetries_discrete").is_none() && v.get("symmetries_continuous").is_none());
    }

    /// A dataset written before the transforms were listed: they come from its mesh, not from the
    /// model axes (a box turned 13° about z, as the real gelatin box).
    #[test]
    fn older_datasets_get_the_symmetries_of_their_mesh() {
        let mut mesh = procedural_mesh(Catalog::builtin().get("009_gelatin_box").unwrap());
        let q = glam::Quat::from_rotation_z(13f32.to_radians());
        for p in &mut mesh.positions {
            *p = (q * glam::Vec3::from(*p)).into();
        }
        mesh.center_on_aabb();
        let v = model_info(&info("discrete"), DVec3::splat(-0.05), DVec3::splat(0.05), &mesh.positions, &mesh.indices);
        let flips = v["symmetries_discrete"].as_array().unwrap();
        assert_eq!(flips.len(), 3);
        // The flip about the box's x axis: R = 2uuᵀ − I with u = (cos 13°, sin 13°, 0).
        let (c, s) = (13f64.to_radians().cos(), 13f64.to_radians().sin());
        let want = [2.0 * c * c - 1.0, 2.0 * c * s, 0.0, 2.0 * c * s, 2.0 * s * s - 1.0, 0.0, 0.0, 0.0, -1.0];
        let got: Vec<f64> = flips[0].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
        for (k, w) in [0, 1, 2, 4, 5, 6, 8, 9, 10].iter().zip(want) {
            assert!((got[*k] - w).abs() < 1e-4, "{got:?}");
        }
        assert!(got[3].abs() < 0.01 && got[7].abs() < 0.01, "through the box centre (mm): {got:?}");
    }
}

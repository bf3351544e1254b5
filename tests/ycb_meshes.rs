//! Real YCB meshes (from `YCB_DIR`, e.g. ../shared/assets/ycb; never committed) load for all 11
//! catalogue objects, sit in the model frame, and render with their texture visible.

use glam::{DMat4, DQuat, DVec3};
use vt_objects::{Catalog, find_ycb_mesh, load_mesh};
use vtgen::config::{Intrinsics, RendererConfig};
use vtgen::render::{Draw, DrawRole, Lighting, Renderer, View, WgpuRenderer};
use vtgen::scene::look_at;

#[test]
fn all_eleven_ycb_objects_load_and_render_textured() {
    let Ok(dir) = std::env::var("YCB_DIR") else {
        eprintln!("skipped: YCB_DIR is not set (.ci/run sets it to ../shared/assets/ycb)");
        return;
    };
    let dir = std::path::PathBuf::from(dir);
    let mut r = WgpuRenderer::new(&RendererConfig::default()).unwrap();
    for e in Catalog::builtin().entries() {
        let path = find_ycb_mesh(&dir, &e.id).unwrap_or_else(|t| panic!("{}: no mesh, tried {t:?}", e.id));
        let mesh = load_mesh(&path).unwrap();
        assert!(mesh.triangle_count() > 10_000, "{}: google_16k scan", e.id);
        let (lo, hi) = mesh.aabb();
        assert!((lo + hi).length() < 1e-6, "{}: model frame centred on the bounding box", e.id);
        let ext = mesh.extents();
        for k in 0..3 {
            assert!((ext[k] as f64 - e.extents[k]).abs() < 2e-3, "{}: extent {k} {} vs catalogue {}", e.id, ext[k], e.extents[k]);
        }
        assert!(mesh.texture.width >= 512, "{}: texture loaded", e.id);
        let h = r.upload_mesh(&mesh).unwrap();
        let cam = look_at(DVec3::new(0.0, -0.45, 0.3), DVec3::new(0.0, 0.0, 0.1));
        let v = View {
            width: 320,
            height: 240,
            k: Intrinsics { fx: 300.0, fy: 300.0, cx: 159.5, cy: 119.5 },
            near: 0.05,
            far: 5.0,
            t_world_camera: cam.matrix(),
        };
        let light = Lighting::spot(DVec3::new(0.0, -1.0, 1.0), DVec3::ZERO, [1.0; 3], [0.4; 3]);
        let pose = DMat4::from_rotation_translation(DQuat::from_rotation_x(0.4), DVec3::new(0.0, 0.0, 0.12));
        let img = r.render(&v, &light, &[Draw { mesh: h, t_world_model: pose, mask_id: 1, role: DrawRole::Target }]).unwrap();
        let px: Vec<[u8; 3]> = img
            .mask
            .iter()
            .enumerate()
            .filter(|(_, m)| **m == 1)
            .map(|(i, _)| [img.rgb[3 * i], img.rgb[3 * i + 1], img.rgb[3 * i + 2]])
            .collect();
        assert!(px.len() > 800, "{}: visible ({} px)", e.id, px.len());
        // Texture visible: the object's pixels are far from one flat colour.
        let mean =
            px.iter().fold([0f64; 3], |a, p| [a[0] + p[0] as f64, a[1] + p[1] as f64, a[2] + p[2] as f64]).map(|s| s / px.len() as f64);
        let var = px.iter().map(|p| (0..3).map(|c| (p[c] as f64 - mean[c]).powi(2)).sum::<f64>()).sum::<f64>() / px.len() as f64;
        assert!(var.sqrt() > 12.0, "{}: colour spread {:.1} shows the texture", e.id, var.sqrt());
    }
}

//! A `Renderer` for unit tests of the stages after rendering, without a GPU or lavapipe: every
//! mesh is the horizontal plane `z = plane_z` (world), ray-cast exactly. The main view sees the
//! plane's depth everywhere, with mask id of the first draw; orthographic depth views see it where
//! it is within their range.

use glam::{DMat4, DVec3, DVec4};
use vt_objects::{Texture, TexturedMesh};

use super::{DepthView, Draw, Lighting, Material, MeshHandle, RenderOutput, Renderer, View};

pub struct PlaneRenderer {
    pub plane_z: f64,
    meshes: usize,
}

impl PlaneRenderer {
    pub fn new(plane_z: f64) -> Self {
        PlaneRenderer { plane_z, meshes: 0 }
    }

    /// Distance along `dir` (world, unit) from `origin` to the plane, if it is ahead.
    fn hit(&self, origin: DVec3, dir: DVec3) -> Option<f64> {
        (dir.z.abs() > 1e-12).then(|| (self.plane_z - origin.z) / dir.z).filter(|t| t.is_finite())
    }
}

impl Renderer for PlaneRenderer {
    fn describe(&self) -> String {
        "plane (test)".into()
    }
    fn upload_mesh_with(&mut self, _mesh: &TexturedMesh, _material: Material) -> anyhow::Result<MeshHandle> {
        self.meshes += 1;
        Ok(MeshHandle(self.meshes - 1))
    }
    fn set_texture(&mut self, _mesh: MeshHandle, _texture: &Texture, _uv_scale: f32) -> anyhow::Result<()> {
        Ok(())
    }
    fn set_material(&mut self, _mesh: MeshHandle, _material: Material) -> anyhow::Result<()> {
        Ok(())
    }
    fn render(&mut self, view: &View, _lighting: &Lighting, draws: &[Draw]) -> anyhow::Result<RenderOutput> {
        let (w, h) = (view.width as usize, view.height as usize);
        let mut depth = vec![0.0f32; w * h];
        let origin = view.t_world_camera.transform_point3(DVec3::ZERO);
        let forward = view.t_world_camera.transform_vector3(DVec3::Z);
        for v in 0..h {
            for u in 0..w {
                let ray = DVec3::new((u as f64 - view.k.cx) / view.k.fx, (v as f64 - view.k.cy) / view.k.fy, 1.0);
                let dir = view.t_world_camera.transform_vector3(ray).normalize();
                if let Some(t) = self.hit(origin, dir).filter(|_| !draws.is_empty()) {
                    let z = t * dir.dot(forward);
                    if z >= view.near && z <= view.far {
                        depth[v * w + u] = z as f32;
                    }
                }
            }
        }
        let id = draws.first().map_or(0, |d| d.mask_id);
        let mask: Vec<u8> = depth.iter().map(|&d| if d > 0.0 { id } else { 0 }).collect();
        let is_target = draws.first().is_some_and(|d| d.role == super::DrawRole::Target);
        let silhouette_pixels = if is_target { depth.iter().filter(|&&d| d > 0.0).count() } else { 0 };
        Ok(RenderOutput { width: view.width, height: view.height, rgb: vec![128; w * h * 3], depth, mask, silhouette_pixels })
    }
    fn render_mask(&mut self, view: &View, draws: &[Draw]) -> anyhow::Result<Vec<u8>> {
        Ok(self.render(view, &Lighting::unlit(), draws)?.mask)
    }
    fn render_depth_views(&mut self, views: &[DepthView], draws: &[Draw]) -> anyhow::Result<Vec<Vec<f32>>> {
        Ok(views
            .iter()
            .map(|view| {
                let (w, h) = (view.width, view.height);
                let t: DMat4 = view.t_world_camera;
                let forward = t.transform_vector3(DVec3::Z).normalize();
                (0..h)
                    .flat_map(|v| (0..w).map(move |u| (u, v)))
                    .map(|(u, v)| {
                        // The pixel's centre on the camera plane; orthographic rays go along +z.
                        let x = (u as f64 + 0.5) / w as f64 * 2.0 * view.half_x - view.half_x;
                        let y = (v as f64 + 0.5) / h as f64 * 2.0 * view.half_y - view.half_y;
                        assert!(view.perspective_standoff.is_none(), "the plane renderer is orthographic only");
                        let origin = (t * DVec4::new(x, y, 0.0, 1.0)).truncate();
                        match self.hit(origin, forward).filter(|_| !draws.is_empty()) {
                            Some(z) if z >= view.near && z <= view.far => z as f32,
                            _ => f32::INFINITY,
                        }
                    })
                    .collect()
            })
            .collect())
    }
}

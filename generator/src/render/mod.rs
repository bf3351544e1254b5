//! Rendering behind a small trait. The wgpu rasterizer is the one backend today; it runs on Mesa's
//! lavapipe (CPU) and on real GPUs alike.

#[cfg(test)]
pub(crate) mod fake;
mod mipmaps;
mod wgpu;

use glam::DMat4;
use vt_objects::TexturedMesh;

pub use self::wgpu::WgpuRenderer;

use crate::config::Intrinsics;

/// Handle of a mesh uploaded to a renderer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MeshHandle(pub(crate) usize);

/// A pinhole view: OpenCV camera frame, z-depth between `near` and `far`.
#[derive(Debug, Clone, Copy)]
pub struct View {
    pub width: u32,
    pub height: u32,
    pub k: Intrinsics,
    pub near: f64,
    pub far: f64,
    pub t_world_camera: DMat4,
}

impl View {
    /// The config's camera at `t_world_camera`.
    pub fn of_camera(camera: &crate::config::CameraConfig, t_world_camera: DMat4) -> View {
        View { width: camera.width, height: camera.height, k: camera.k(), near: camera.near, far: camera.far, t_world_camera }
    }
}

/// A spotlight (with shadows) and an ambient hemisphere term, world frame, linear RGB.
#[derive(Debug, Clone, Copy)]
pub struct Lighting {
    pub light_position: glam::DVec3,
    /// The point the spot's axis goes through.
    pub light_target: glam::DVec3,
    /// Colour × intensity: the irradiance a surface facing the light gets at the target's distance
    /// (it falls off with the squared distance from the light).
    pub light_color: [f32; 3],
    /// Outer half-angle of the cone, degrees (< 80).
    pub cone_deg: f64,
    /// Inner/outer angle ratio: the light fades from the inner angle to the outer one.
    pub softness: f64,
    pub ambient: [f32; 3],
    /// sRGB colour where nothing is drawn.
    pub background: [u8; 3],
    /// Shadow mapping of the spotlight.
    pub shadows: bool,
}

impl Lighting {
    /// No light at all: for passes that only want depth or the mask.
    pub fn unlit() -> Self {
        Lighting {
            light_position: glam::DVec3::Z,
            light_target: glam::DVec3::ZERO,
            light_color: [0.0; 3],
            cone_deg: 45.0,
            softness: 0.8,
            ambient: [0.0; 3],
            background: [0, 0, 0],
            shadows: false,
        }
    }

    /// A spotlight at `position` aimed at `target` with a 45° cone and shadows.
    pub fn spot(position: glam::DVec3, target: glam::DVec3, color: [f32; 3], ambient: [f32; 3]) -> Self {
        Lighting { light_position: position, light_target: target, light_color: color, ambient, shadows: true, ..Lighting::unlit() }
    }
}

/// glTF metallic-roughness factors of a mesh (the base colour is its texture).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    pub roughness: f32,
    pub metallic: f32,
}

impl Default for Material {
    fn default() -> Self {
        Material { roughness: 0.7, metallic: 0.0 }
    }
}

/// One mesh placed in the world, with the mask id its pixels get and its role in the picture.
#[derive(Debug, Clone, Copy)]
pub struct Draw {
    pub mesh: MeshHandle,
    pub t_world_model: DMat4,
    pub mask_id: u8,
    pub role: DrawRole,
}

/// What a draw is to the renderer. The role, not the mask id (whose meaning belongs to the
/// dataset), decides the draw order, who casts shadows and whose silhouette is measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DrawRole {
    /// Floor and backdrop: receive shadows but cast none, drawn last (behind everything).
    Environment,
    /// The object whose unoccluded silhouette `RenderOutput::silhouette_pixels` counts; drawn first.
    Target,
    /// Everything else in front of the environment: hand, arm, distractors.
    Occluder,
}

/// The images of one view, row-major, row 0 at the top.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderOutput {
    pub width: u32,
    pub height: u32,
    /// sRGB, 3 bytes per pixel.
    pub rgb: Vec<u8>,
    /// z-depth in metres, 0 where nothing was drawn.
    pub depth: Vec<f32>,
    pub mask: Vec<u8>,
    /// Pixels the target draw (`DrawRole::Target`) covers with nothing in front of it: its silhouette
    /// had it been drawn alone (`render_mask` of it), from the same pass.
    pub silhouette_pixels: usize,
}

/// An orthographic depth view (a pad camera): looks along +z of `t_world_camera`, covering
/// `[-half_x, half_x] x [-half_y, half_y]` metres over `width x height` pixels, depth in
/// `[near, far]` (near may be negative: surfaces pressed behind the camera plane).
#[derive(Debug, Clone, Copy)]
pub struct DepthView {
    pub width: u32,
    pub height: u32,
    pub half_x: f64,
    pub half_y: f64,
    pub near: f64,
    pub far: f64,
    pub t_world_camera: DMat4,
    /// None: orthographic. Some(s): a pinhole `s` metres behind the camera plane whose field of
    /// view covers the `half_x x half_y` rectangle on that plane. Depths are still measured from
    /// the camera plane, so both projections report the same surface at the same depth.
    pub perspective_standoff: Option<f64>,
}

/// An optical tactile sensor's image model for one depth view, shaded on the GPU
/// (`robot.tactile.optical_shading: gpu`); `sensors::optical` is its reference and builds it.
#[derive(Debug, Clone, PartialEq)]
pub struct GelShading {
    /// The depth view (an index into the views of the call) the gel lies over.
    pub view: usize,
    /// How far the gel's free surface lies in front of the pad plane (m).
    pub gel_thickness: f64,
    /// Pixel pitch along x and y (m).
    pub pitch: [f64; 2],
    /// The gel's elastic spread, σ in pixels along x and y (0: none).
    pub spread_sigma_px: [f64; 2],
    pub lights: Vec<GelLight>,
    pub ambient: f64,
    /// The gel's tint (linear RGB).
    pub tint: [f64; 3],
    pub vignetting: f64,
}

/// One LED of a [`GelShading`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GelLight {
    /// Towards the LED, normalised (pad frame).
    pub direction: [f64; 3],
    pub color: [f64; 3],
    pub falloff: f64,
    /// The LED's azimuth in the pad plane, normalised (zero when straight behind).
    pub azimuth: [f64; 2],
}

/// One float image per view (depth views, optical shadings), row-major.
pub type Images = Vec<Vec<f32>>;

/// The most LEDs a [`GelShading`] holds.
pub const MAX_GEL_LIGHTS: usize = 8;

pub trait Renderer {
    /// Adapter and backend in words, e.g. "llvmpipe (LLVM 15.0.6, 256 bits) [Vulkan, Cpu]".
    fn describe(&self) -> String;
    fn upload_mesh(&mut self, mesh: &TexturedMesh) -> anyhow::Result<MeshHandle> {
        self.upload_mesh_with(mesh, Material::default())
    }
    fn upload_mesh_with(&mut self, mesh: &TexturedMesh, material: Material) -> anyhow::Result<MeshHandle>;
    /// Replaces a mesh's base-colour texture (randomized floors and backdrops); texture
    /// coordinates are multiplied by `uv_scale` (the texture repeats that many times per UV unit).
    fn set_texture(&mut self, mesh: MeshHandle, texture: &vt_objects::Texture, uv_scale: f32) -> anyhow::Result<()>;
    /// Replaces a mesh's roughness and metallic factors (randomized robot materials).
    fn set_material(&mut self, mesh: MeshHandle, material: Material) -> anyhow::Result<()>;
    fn render(&mut self, view: &View, lighting: &Lighting, draws: &[Draw]) -> anyhow::Result<RenderOutput>;
    /// The instance mask alone (cheaper: no colour or depth readback), e.g. an object's unoccluded
    /// silhouette.
    fn render_mask(&mut self, view: &View, draws: &[Draw]) -> anyhow::Result<Vec<u8>>;
    /// Renders several depth views of the same draws in one submission; z-depth per view, row-major,
    /// `+inf` where no surface is within range.
    fn render_depth_views(&mut self, views: &[DepthView], draws: &[Draw]) -> anyhow::Result<Vec<Vec<f32>>>;
    /// `render_depth_views`, and the optical shading of some of those views in the same
    /// submission: per shading, `width * height * 4` f32 (linear R, G, B before clipping, and the
    /// gel's surface indentation in m). None: this renderer does not shade (the CPU does).
    fn render_depth_views_shaded(
        &mut self,
        views: &[DepthView],
        shading: &[GelShading],
        draws: &[Draw],
    ) -> anyhow::Result<(Images, Option<Images>)> {
        let _ = shading;
        Ok((self.render_depth_views(views, draws)?, None))
    }
    /// Time spent copying images out of mapped readback buffers since the renderer was made
    /// (part of every render call's time), for `vtgen bench`.
    fn readback_time(&self) -> std::time::Duration {
        std::time::Duration::ZERO
    }
    /// Times every pass on its own from now on (`vtgen bench --per-pass`): each is submitted and
    /// waited for before the next is recorded, which costs the overlap of recording and drawing,
    /// so the whole is slower than without. The images are the same. False: this renderer has no
    /// passes to time.
    fn time_passes(&mut self) -> bool {
        false
    }
    /// The passes' times since `time_passes`; None before it.
    fn pass_times(&self) -> Option<PassTimes> {
        None
    }
}

/// Wall time per render pass (`Renderer::time_passes`), summed over the calls: each pass from its
/// submission to the device's being idle again.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PassTimes {
    /// Uniforms and textures written since the last submission (randomized looks), uploaded.
    pub uploads: std::time::Duration,
    /// The spotlight's shadow map (lit colour renders that cast shadows).
    pub shadow_map: std::time::Duration,
    /// The main camera's single-sample pass: colour, z-depth, mask and silhouette.
    pub main_views: std::time::Duration,
    /// The anti-aliased colour pass (`renderer.msaa: 4`).
    pub main_msaa: std::time::Duration,
    /// Instance-mask-only renders (the occlusion's unoccluded silhouette).
    pub mask_views: std::time::Duration,
    /// The depth views of the pads (and the other depth views) in their atlas.
    pub depth_views: std::time::Duration,
    /// Optical tactile shading on the GPU (compute).
    pub optical_shading: std::time::Duration,
    /// Copying the targets into readback buffers and mapping them.
    pub copy_and_map: std::time::Duration,
    /// Unpadding the mapped rows on the CPU (`readback_time`).
    pub readback: std::time::Duration,
}

impl std::ops::AddAssign for PassTimes {
    fn add_assign(&mut self, o: PassTimes) {
        let PassTimes { uploads, shadow_map, main_views, main_msaa, mask_views, depth_views, optical_shading, copy_and_map, readback } = o;
        self.uploads += uploads;
        self.shadow_map += shadow_map;
        self.main_views += main_views;
        self.main_msaa += main_msaa;
        self.mask_views += mask_views;
        self.depth_views += depth_views;
        self.optical_shading += optical_shading;
        self.copy_and_map += copy_and_map;
        self.readback += readback;
    }
}

impl PassTimes {
    /// (name, seconds) of every pass, in the order a sample runs them.
    pub fn named(&self) -> [(&'static str, f64); 9] {
        [
            ("uploads", self.uploads.as_secs_f64()),
            ("shadow map", self.shadow_map.as_secs_f64()),
            ("main views", self.main_views.as_secs_f64()),
            ("main colour msaa", self.main_msaa.as_secs_f64()),
            ("mask views", self.mask_views.as_secs_f64()),
            ("depth views", self.depth_views.as_secs_f64()),
            ("optical shading", self.optical_shading.as_secs_f64()),
            ("copy and map", self.copy_and_map.as_secs_f64()),
            ("readback", self.readback.as_secs_f64()),
        ]
    }
}

/// Orthographic projection of a depth view: x right, y down (as OpenCV), z forward.
pub fn orthographic(v: &DepthView) -> glam::DMat4 {
    let (n, f) = (v.near, v.far);
    glam::DMat4::from_cols(
        glam::DVec4::new(1.0 / v.half_x, 0.0, 0.0, 0.0),
        glam::DVec4::new(0.0, -1.0 / v.half_y, 0.0, 0.0),
        glam::DVec4::new(0.0, 0.0, 1.0 / (f - n), 0.0),
        glam::DVec4::new(0.0, 0.0, -n / (f - n), 1.0),
    )
}

/// OpenCV intrinsics to a wgpu clip-space projection (column-major). Pixel (u, v) of the image is
/// centred at framebuffer coordinate (u + 0.5, v + 0.5), which is where the rasterizer samples, so
/// a point projecting to `u = fx x/z + cx` is drawn in pixel round(u) (FORMAT.md).
pub fn projection(view: &View) -> glam::DMat4 {
    let (w, h) = (view.width as f64, view.height as f64);
    let k = view.k;
    let (n, f) = (view.near, view.far);
    glam::DMat4::from_cols(
        glam::DVec4::new(2.0 * k.fx / w, 0.0, 0.0, 0.0),
        glam::DVec4::new(0.0, -2.0 * k.fy / h, 0.0, 0.0),
        glam::DVec4::new(2.0 * (k.cx + 0.5) / w - 1.0, 1.0 - 2.0 * (k.cy + 0.5) / h, f / (f - n), 1.0),
        glam::DVec4::new(0.0, 0.0, -f * n / (f - n), 0.0),
    )
}

//! The wgpu rasterizer. A submission (`passes.rs`) draws the spotlight's shadow map, then one pass
//! that writes four colour targets (sRGB colour, R32Float z-depth, R8Uint mask, R8Uint target
//! silhouette) and a z-buffer into each view's viewport, then (msaa > 1) an anti-aliased colour
//! pass; the targets are copied into 256-byte-aligned readback buffers and unpadded on the CPU.
//!
//! One file per concern: `device.rs` adapter choice, `pipelines.rs` layouts, pipelines, shadow
//! map and uniform buffers, `geometry.rs` vertices, uniforms and mesh clusters, `materials.rs`
//! textures, `targets.rs` targets and readback, `passes.rs` the passes, `shader.wgsl`.

use anyhow::{Context, Result, anyhow, bail};
use bytemuck::{Pod, Zeroable};
use glam::DMat4;
use vt_dataset::srgb_to_linear;
use vt_objects::TexturedMesh;
use wgpu::util::DeviceExt;

use super::{
    DepthView, Draw, DrawRole, GelShading, Images, Lighting, Material, MeshHandle, RenderOutput, Renderer, View, orthographic, projection,
};
use crate::config::{Backend, Intrinsics, RendererConfig, ToneMapping};

const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Float;
const MASK_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R8Uint;
/// The target object's unoccluded coverage, written in the main pass (see `record_views`).
const SILHOUETTE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R8Uint;
const ZBUF_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
const SHADOW_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Instance uniforms live in a buffer at 256-byte strides, frame uniforms at 512 (dynamic offsets).
const UNIFORM_STRIDE: u64 = 256;
const FRAME_STRIDE: u64 = 512;
/// Draw records (view x draw) per render call.
const MAX_DRAWS: usize = 1024;
/// Views per render call (the main camera, or the pad cameras).
const MAX_VIEWS: usize = 16;

mod device;
mod geometry;
mod materials;
mod optical;
mod passes;
mod pipelines;
mod targets;

use device::*;
use geometry::*;
use materials::*;
use passes::*;
use pipelines::*;
use targets::*;

pub struct WgpuRenderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    pipelines: Pipelines,
    msaa: u32,
    shadow: ShadowMap,
    tonemapping: ToneMapping,
    material_layout: wgpu::BindGroupLayout,
    sampler: wgpu::Sampler,
    /// Frame uniforms (camera, light), one record per view of a submission.
    frames: UniformArena,
    /// Instance uniforms (model-view, mask id), one record per view x draw.
    instances: UniformArena,
    meshes: Vec<GpuMesh>,
    /// Render targets by `Slot`, created on first use at their size.
    targets: [Option<Targets>; 2],
    /// Time spent copying out of mapped readback buffers (`Renderer::readback_time`).
    readback: std::time::Duration,
    /// The optical shading's compute pipelines, made on first use.
    optical: Option<optical::OpticalPipelines>,
    /// Per-pass times, when timed (`Renderer::time_passes`).
    pass_times: Option<crate::render::PassTimes>,
    /// Taken when the renderer is dropped and declared last (fields drop in order), so that the
    /// device and instance go while it is held (`DeviceTurn`).
    teardown: DeviceTurn,
}

impl Drop for WgpuRenderer {
    fn drop(&mut self) {
        self.teardown = DeviceTurn::take();
    }
}

impl WgpuRenderer {
    /// Picks an adapter as the config says and builds the pipelines.
    pub fn new(cfg: &RendererConfig) -> Result<Self> {
        let OpenDevice { device, queue, info, max_texture_size } = open_device(cfg)?;
        let layouts = BindLayouts::new(&device);
        let msaa = if cfg.msaa > 1 { 4 } else { 1 };
        let pipelines = Pipelines::new(&device, &layouts, msaa);
        let shadow = ShadowMap::new(&device, &layouts.shadow, cfg.shadow_map_size.clamp(256, max_texture_size.min(8192)));
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("base colour"),
            address_mode_u: wgpu::AddressMode::Repeat,
            address_mode_v: wgpu::AddressMode::Repeat,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            // Trilinear: no visible seam where the floor's texture switches level.
            mipmap_filter: wgpu::MipmapFilterMode::Linear,
            ..Default::default()
        });
        let frames = UniformArena::new::<FrameUniform>(&device, &layouts.frame, "frame", FRAME_STRIDE, MAX_VIEWS + 1);
        let instances = UniformArena::new::<InstanceUniform>(&device, &layouts.instance, "instances", UNIFORM_STRIDE, MAX_DRAWS);
        Ok(WgpuRenderer {
            device,
            queue,
            info,
            pipelines,
            msaa,
            shadow,
            tonemapping: cfg.tonemapping,
            material_layout: layouts.material,
            sampler,
            frames,
            instances,
            meshes: Vec::new(),
            targets: [None, None],
            readback: std::time::Duration::ZERO,
            optical: None,
            pass_times: None,
            teardown: DeviceTurn::none(),
        })
    }
}

fn mat(m: DMat4) -> [[f32; 4]; 4] {
    m.as_mat4().to_cols_array_2d()
}

impl Renderer for WgpuRenderer {
    fn readback_time(&self) -> std::time::Duration {
        self.readback
    }

    fn time_passes(&mut self) -> bool {
        self.pass_times.get_or_insert_default();
        true
    }

    fn pass_times(&self) -> Option<crate::render::PassTimes> {
        self.pass_times.map(|mut p| {
            p.readback = self.readback;
            p
        })
    }

    fn describe(&self) -> String {
        describe_adapter(&self.info)
    }

    fn upload_mesh_with(&mut self, mesh: &TexturedMesh, material: Material) -> Result<MeshHandle> {
        let n = mesh.positions.len();
        if mesh.normals.len() != n || mesh.uvs.len() != n {
            bail!("mesh has {n} positions but {} normals and {} uvs", mesh.normals.len(), mesh.uvs.len());
        }
        let vertices: Vec<Vertex> =
            (0..n).map(|i| Vertex { position: mesh.positions[i], normal: mesh.normals[i], uv: mesh.uvs[i] }).collect();
        let vbuf = self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vertices"),
            contents: bytemuck::cast_slice(&vertices),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let (indices, clusters) = cluster_triangles(mesh);
        let ibuf = self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("indices"),
            contents: bytemuck::cast_slice(&indices),
            usage: wgpu::BufferUsages::INDEX,
        });
        let shadow_lod = shadow_lod(mesh);
        let shadow_ibuf = self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("shadow indices"),
            contents: bytemuck::cast_slice(&shadow_lod),
            usage: wgpu::BufferUsages::INDEX,
        });
        let factors = self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("material factors"),
            contents: bytemuck::cast_slice(&[material.roughness, material.metallic, 1.0, 0.0]),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        let (texture, group) = self.make_material(&mesh.texture, &factors)?;
        self.meshes.push(GpuMesh {
            vertices: vbuf,
            indices: ibuf,
            index_count: mesh.indices.len() as u32,
            bounds: {
                let (lo, hi) = mesh.aabb();
                (lo.as_dvec3(), hi.as_dvec3())
            },
            shadow_indices: shadow_ibuf,
            shadow_index_count: shadow_lod.len() as u32,
            material: group,
            factors,
            pbr: material,
            uv_scale: 1.0,
            texture,
            clusters,
        });
        Ok(MeshHandle(self.meshes.len() - 1))
    }

    fn set_texture(&mut self, mesh: MeshHandle, texture: &vt_objects::Texture, uv_scale: f32) -> Result<()> {
        let m = self.meshes.get_mut(mesh.0).ok_or_else(|| anyhow!("no mesh {}", mesh.0))?;
        m.uv_scale = uv_scale;
        let m = &self.meshes[mesh.0];
        self.queue.write_buffer(&m.factors, 0, bytemuck::cast_slice(&[m.pbr.roughness, m.pbr.metallic, uv_scale, 0.0]));
        if m.texture.width() == texture.width && m.texture.height() == texture.height {
            write_texture(&self.queue, &m.texture, texture);
            return Ok(());
        }
        let (tex, group) = self.make_material(texture, &m.factors)?;
        let m = &mut self.meshes[mesh.0];
        m.texture = tex;
        m.material = group;
        Ok(())
    }

    fn set_material(&mut self, mesh: MeshHandle, material: Material) -> Result<()> {
        let m = self.meshes.get_mut(mesh.0).ok_or_else(|| anyhow!("no mesh {}", mesh.0))?;
        m.pbr = material;
        self.queue.write_buffer(&m.factors, 0, bytemuck::cast_slice(&[material.roughness, material.metallic, m.uv_scale, 0.0]));
        Ok(())
    }

    fn render(&mut self, view: &View, lighting: &Lighting, draws: &[Draw]) -> Result<RenderOutput> {
        let (w, h) = (view.width, view.height);
        let views = [ViewSpec {
            t_world_camera: view.t_world_camera,
            proj: projection(view),
            viewport: [0, 0, w, h],
            depth_range: [view.near as f32, view.far as f32],
        }];
        let sub = Submission { slot: Slot::Main, size: (w, h), views: &views, readback: Readback::All, cull: None, optical: &[] };
        let images = self.draw_views(&sub, lighting, draws)?;
        let rgb = images.rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
        let silhouette_pixels = images.silhouette.iter().filter(|&&s| s != 0).count();
        let depth = bytemuck::pod_collect_to_vec::<u8, f32>(&images.depth);
        Ok(RenderOutput { width: w, height: h, rgb, depth, mask: images.mask, silhouette_pixels })
    }

    fn render_mask(&mut self, view: &View, draws: &[Draw]) -> Result<Vec<u8>> {
        let (w, h) = (view.width, view.height);
        let views = [ViewSpec {
            t_world_camera: view.t_world_camera,
            proj: projection(view),
            viewport: [0, 0, w, h],
            depth_range: [view.near as f32, view.far as f32],
        }];
        let sub = Submission { slot: Slot::Main, size: (w, h), views: &views, readback: Readback::Mask, cull: None, optical: &[] };
        Ok(self.draw_views(&sub, &Lighting::unlit(), draws)?.mask)
    }

    fn render_depth_views(&mut self, views: &[DepthView], draws: &[Draw]) -> Result<Vec<Vec<f32>>> {
        Ok(self.depth_views(views, &[], draws)?.0)
    }

    fn render_depth_views_shaded(
        &mut self,
        views: &[DepthView],
        shading: &[GelShading],
        draws: &[Draw],
    ) -> Result<(Images, Option<Images>)> {
        let (depth, shaded) = self.depth_views(views, shading, draws)?;
        Ok((depth, Some(shaded)))
    }
}

impl WgpuRenderer {
    /// The depth views in one submission, and the optical shading of some of them after them.
    fn depth_views(&mut self, views: &[DepthView], shading: &[GelShading], draws: &[Draw]) -> Result<(Images, Images)> {
        if views.is_empty() {
            return Ok((Vec::new(), Vec::new()));
        }
        let (atlas_size, viewports) = atlas_layout(views);
        let specs: Vec<ViewSpec> = views
            .iter()
            .zip(&viewports)
            .map(|(v, &viewport)| {
                let (vw, vh) = (v.width, v.height);
                match v.perspective_standoff {
                    None => ViewSpec {
                        t_world_camera: v.t_world_camera,
                        proj: orthographic(v),
                        viewport,
                        depth_range: [v.near as f32, v.far as f32],
                    },
                    Some(s) => {
                        let pinhole = View {
                            width: vw,
                            height: vh,
                            k: crate::config::Intrinsics {
                                fx: vw as f64 * s / (2.0 * v.half_x),
                                fy: vh as f64 * s / (2.0 * v.half_y),
                                cx: (vw as f64 - 1.0) / 2.0,
                                cy: (vh as f64 - 1.0) / 2.0,
                            },
                            near: (s + v.near).max(0.05 * s),
                            far: s + v.far,
                            t_world_camera: v.t_world_camera * DMat4::from_translation(glam::DVec3::new(0.0, 0.0, -s)),
                        };
                        ViewSpec {
                            t_world_camera: pinhole.t_world_camera,
                            proj: projection(&pinhole),
                            viewport,
                            depth_range: [(s + v.near) as f32, (s + v.far) as f32],
                        }
                    }
                }
            })
            .collect();
        let lighting = Lighting::unlit();
        // Cull boxes in each view's camera frame (for a pinhole: the frustum's bounding box).
        let cull: Vec<[f64; 4]> = views
            .iter()
            .map(|v| match v.perspective_standoff {
                None => [v.half_x, v.half_y, v.near, v.far],
                Some(s) => {
                    let spread = (s + v.far) / s;
                    [v.half_x * spread, v.half_y * spread, 0.0, s + v.far]
                }
            })
            .collect();
        let sub = Submission {
            slot: Slot::TactileAtlas,
            size: atlas_size,
            views: &specs,
            readback: Readback::Depth,
            cull: Some(&cull),
            optical: shading,
        };
        let images = self.draw_views(&sub, &lighting, draws)?;
        let atlas: Vec<f32> = bytemuck::pod_collect_to_vec(&images.depth);
        let aw = atlas_size.0 as usize;
        let depth = specs
            .iter()
            .zip(views)
            .map(|(spec, v)| {
                let vp = spec.viewport;
                let (vw, vh) = (v.width, v.height);
                // Pinhole depths are measured from the pinhole: shift them to the camera plane.
                let shift = v.perspective_standoff.unwrap_or(0.0) as f32;
                (0..vh as usize)
                    .flat_map(|r| {
                        let start = (vp[1] as usize + r) * aw + vp[0] as usize;
                        atlas[start..start + vw as usize].iter().map(move |d| d - shift)
                    })
                    .collect()
            })
            .collect();
        Ok((depth, images.optical))
    }
}

/// Where each depth view goes in the atlas, and the atlas' size. Consecutive views of one size form
/// a block of up to 4 columns (the pads' 32 x 32 views: one block, as they always were); blocks
/// stack downwards.
fn atlas_layout(views: &[DepthView]) -> ((u32, u32), Vec<[u32; 4]>) {
    let mut viewports = Vec::with_capacity(views.len());
    let (mut width, mut top) = (0, 0);
    let mut start = 0;
    while start < views.len() {
        let (vw, vh) = (views[start].width, views[start].height);
        let count = views[start..].iter().take_while(|v| (v.width, v.height) == (vw, vh)).count() as u32;
        let cols = 4u32.min(count);
        for i in 0..count {
            viewports.push([(i % cols) * vw, top + (i / cols) * vh, vw, vh]);
        }
        width = width.max(cols * vw);
        top += count.div_ceil(cols) * vh;
        start += count as usize;
    }
    ((width, top), viewports)
}

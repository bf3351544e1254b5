//! The wgpu rasterizer. One render pass writes three colour targets (sRGB colour, R32Float
//! z-depth, R8Uint mask) plus a depth buffer for the z-test; the targets are copied into
//! 256-byte-aligned readback buffers and unpadded on the CPU.

use anyhow::{Context, Result, anyhow, bail};
use bytemuck::{Pod, Zeroable};
use glam::DMat4;
use vt_dataset::srgb_to_linear;
use vt_objects::TexturedMesh;
use wgpu::util::DeviceExt;

use super::{DepthView, Draw, Lighting, Material, MeshHandle, RenderOutput, Renderer, View, orthographic, projection};
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
/// Views per render call (the main camera, or the 12 phalanx cameras).
const MAX_VIEWS: usize = 16;

mod device;
mod geometry;
mod materials;
mod passes;
mod targets;

use device::*;
use geometry::*;
use materials::*;
use targets::*;

pub struct WgpuRenderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    pipeline: wgpu::RenderPipeline,
    /// `pipeline` that also writes the silhouette target: the target object's draws in the main pass.
    silhouette_pipeline: wgpu::RenderPipeline,
    /// The multisampled colour-only pass, when `msaa` > 1.
    msaa_pipeline: Option<wgpu::RenderPipeline>,
    msaa: u32,
    /// Depth-only pass from the spotlight into `shadow_map`.
    shadow_pipeline: wgpu::RenderPipeline,
    shadow_map: wgpu::TextureView,
    shadow_group: wgpu::BindGroup,
    shadow_size: u32,
    tonemapping: ToneMapping,
    material_layout: wgpu::BindGroupLayout,
    sampler: wgpu::Sampler,
    frame_buffer: wgpu::Buffer,
    frame_group: wgpu::BindGroup,
    instance_buffer: wgpu::Buffer,
    instance_group: wgpu::BindGroup,
    meshes: Vec<GpuMesh>,
    /// Render targets: [main view, tactile atlas], created on first use at their size.
    targets: [Option<Targets>; 2],
    /// Time spent copying out of mapped readback buffers (`Renderer::readback_time`).
    readback: std::time::Duration,
}

impl WgpuRenderer {
    /// Picks an adapter as the config says and builds the pipeline.
    pub fn new(cfg: &RendererConfig) -> Result<Self> {
        // With `auto`, the native APIs are probed first and GL only when they offer nothing: GL
        // needs Mesa overrides for float targets, and probing EGL is noisy on headless machines.
        let tries = match cfg.backend {
            Backend::Auto => vec![wgpu::Backends::PRIMARY, wgpu::Backends::SECONDARY],
            b => vec![backends(b)],
        };
        let mut adapters = Vec::new();
        for b in tries {
            let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
            desc.backends = b;
            let instance = wgpu::Instance::new(desc);
            adapters = pollster::block_on(instance.enumerate_adapters(b));
            if !adapters.is_empty() {
                break;
            }
        }
        if adapters.is_empty() {
            bail!(
                "no graphics adapter found for backend {:?}. On a machine without a GPU install Mesa's CPU Vulkan driver: \
                 `sudo apt-get install mesa-vulkan-drivers libvulkan1` (Debian/Ubuntu)",
                cfg.backend
            );
        }
        let names: Vec<String> = adapters.iter().map(|a| describe_adapter(&a.get_info())).collect();
        if let Some(want) = &cfg.adapter {
            adapters.retain(|a| a.get_info().name.to_lowercase().contains(&want.to_lowercase()));
            if adapters.is_empty() {
                bail!("no adapter name contains '{want}'; found: {}", names.join("; "));
            }
        }
        // Depth and mask targets are R32Float: an adapter that cannot render to it (Mesa's GL
        // llvmpipe without overrides) would fail at pipeline creation, deep inside wgpu.
        let float_target =
            |a: &wgpu::Adapter| a.get_texture_format_features(DEPTH_FORMAT).allowed_usages.contains(wgpu::TextureUsages::RENDER_ATTACHMENT);
        if !adapters.iter().any(float_target) {
            bail!(
                "no graphics adapter can render to R32Float targets (found: {}). On a machine without a GPU install \
                 Mesa's CPU Vulkan driver: `sudo apt-get install mesa-vulkan-drivers libvulkan1` (Debian/Ubuntu, \
                 or run scripts/system-deps)",
                names.join("; ")
            );
        }
        adapters.retain(float_target);
        adapters.sort_by_key(|a| rank(&a.get_info()));
        let adapter = adapters.into_iter().next().expect("non-empty");
        let info = adapter.get_info();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("vtgen"),
            required_features: wgpu::Features::empty(),
            required_limits: wgpu::Limits::downlevel_defaults().using_resolution(adapter.limits()),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .with_context(|| format!("cannot open a device on {}", describe_adapter(&info)))?;

        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("main view"),
            source: wgpu::ShaderSource::Wgsl(include_str!("shader.wgsl").into()),
        });
        let uniform_entry = |dynamic: bool, size: u64| wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: dynamic,
                min_binding_size: wgpu::BufferSize::new(size),
            },
            count: None,
        };
        let frame_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("frame"),
            entries: &[uniform_entry(true, size_of::<FrameUniform>() as u64)],
        });
        let instance_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("instance"),
            entries: &[uniform_entry(true, size_of::<InstanceUniform>() as u64)],
        });
        let material_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("material"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
                wgpu::BindGroupLayoutEntry { binding: 2, ..uniform_entry(false, 16) },
            ],
        });
        let shadow_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("shadow map"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Depth,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Comparison),
                    count: None,
                },
            ],
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("main view"),
            bind_group_layouts: &[Some(&frame_layout), Some(&instance_layout), Some(&material_layout), Some(&shadow_layout)],
            immediate_size: 0,
        });
        let shadow_pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("shadow map"),
            bind_group_layouts: &[Some(&frame_layout), Some(&instance_layout)],
            immediate_size: 0,
        });
        let vertex_layout = wgpu::VertexBufferLayout {
            array_stride: size_of::<Vertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x2],
        };
        // The three pipelines (shadow map, main view, multisampled colour) share the vertex
        // layout, the triangle lists without culling (scanned and user meshes are not reliably
        // closed or consistently wound) and a writing Less depth test; they differ in the rest.
        let make_pipeline = |label: &str,
                             layout: &wgpu::PipelineLayout,
                             vertex_entry: &str,
                             depth: (wgpu::TextureFormat, wgpu::DepthBiasState),
                             samples: u32,
                             fragment: Option<(&str, &[Option<wgpu::ColorTargetState>])>| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(layout),
                vertex: wgpu::VertexState {
                    module: &shader,
                    entry_point: Some(vertex_entry),
                    compilation_options: Default::default(),
                    buffers: &[Some(vertex_layout.clone())],
                },
                primitive: wgpu::PrimitiveState { topology: wgpu::PrimitiveTopology::TriangleList, cull_mode: None, ..Default::default() },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: depth.0,
                    depth_write_enabled: Some(true),
                    depth_compare: Some(wgpu::CompareFunction::Less),
                    stencil: Default::default(),
                    bias: depth.1,
                }),
                multisample: wgpu::MultisampleState { count: samples, ..Default::default() },
                fragment: fragment.map(|(entry, targets)| wgpu::FragmentState {
                    module: &shader,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    targets,
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        // A small slope-scaled bias; the normal offset in the lookup does the rest.
        let shadow_bias = wgpu::DepthBiasState { constant: 2, slope_scale: 1.5, clamp: 0.0 };
        let shadow_pipeline = make_pipeline("shadow map", &shadow_pipeline_layout, "vs_shadow", (SHADOW_FORMAT, shadow_bias), 1, None);
        let shadow_size = cfg.shadow_map_size.clamp(256, adapter.limits().max_texture_dimension_2d.min(8192));
        let shadow_tex = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("shadow map"),
            size: wgpu::Extent3d { width: shadow_size, height: shadow_size, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: SHADOW_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let shadow_map = shadow_tex.create_view(&Default::default());
        let shadow_sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("shadow"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            compare: Some(wgpu::CompareFunction::LessEqual),
            ..Default::default()
        });
        let shadow_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shadow map"),
            layout: &shadow_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(&shadow_map) },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::Sampler(&shadow_sampler) },
            ],
        });
        let target = |format| Some(wgpu::ColorTargetState { format, blend: None, write_mask: wgpu::ColorWrites::ALL });
        // Two pipelines that differ only in whether they write the silhouette target: the target
        // object's draws come first in the pass with `silhouette_pipeline`, everything else follows
        // with `pipeline`, which leaves the silhouette alone.
        let mut main_targets = [target(COLOR_FORMAT), target(DEPTH_FORMAT), target(MASK_FORMAT), target(SILHOUETTE_FORMAT)];
        let silhouette_pipeline = make_pipeline(
            "main view, target object",
            &layout,
            "vs_main",
            (ZBUF_FORMAT, Default::default()),
            1,
            Some(("fs_main", &main_targets)),
        );
        main_targets[3] = Some(wgpu::ColorTargetState { format: SILHOUETTE_FORMAT, blend: None, write_mask: wgpu::ColorWrites::empty() });
        let pipeline =
            make_pipeline("main view", &layout, "vs_main", (ZBUF_FORMAT, Default::default()), 1, Some(("fs_main", &main_targets)));
        let msaa = if cfg.msaa > 1 { 4 } else { 1 };
        let msaa_pipeline = (msaa > 1).then(|| {
            let colour = [target(COLOR_FORMAT)];
            make_pipeline(
                "main view, multisampled colour",
                &layout,
                "vs_main",
                (ZBUF_FORMAT, Default::default()),
                msaa,
                Some(("fs_color", &colour)),
            )
        });
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
        let frame_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame"),
            size: FRAME_STRIDE * (MAX_VIEWS + 1) as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let frame_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("frame"),
            layout: &frame_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &frame_buffer,
                    offset: 0,
                    size: wgpu::BufferSize::new(size_of::<FrameUniform>() as u64),
                }),
            }],
        });
        let instance_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("instances"),
            size: UNIFORM_STRIDE * MAX_DRAWS as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let instance_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("instances"),
            layout: &instance_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &instance_buffer,
                    offset: 0,
                    size: wgpu::BufferSize::new(size_of::<InstanceUniform>() as u64),
                }),
            }],
        });
        Ok(WgpuRenderer {
            device,
            queue,
            info,
            pipeline,
            silhouette_pipeline,
            msaa_pipeline,
            msaa,
            shadow_pipeline,
            shadow_map,
            shadow_group,
            shadow_size,
            tonemapping: cfg.tonemapping,
            material_layout,
            sampler,
            frame_buffer,
            frame_group,
            instance_buffer,
            instance_group,
            meshes: Vec::new(),
            targets: [None, None],
            readback: std::time::Duration::ZERO,
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
            material: group,
            factors,
            pbr: material,
            texture,
            clusters,
        });
        Ok(MeshHandle(self.meshes.len() - 1))
    }

    fn set_texture(&mut self, mesh: MeshHandle, texture: &vt_objects::Texture, uv_scale: f32) -> Result<()> {
        let m = self.meshes.get(mesh.0).ok_or_else(|| anyhow!("no mesh {}", mesh.0))?;
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

    fn render(&mut self, view: &View, lighting: &Lighting, draws: &[Draw]) -> Result<RenderOutput> {
        let (w, h) = (view.width, view.height);
        let (rgba, depth, mask, silhouette) =
            self.draw_views(0, (w, h), &[(view.t_world_camera, projection(view), [0, 0, w, h])], lighting, draws, Readback::All, None)?;
        let rgb = rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
        let silhouette_pixels = silhouette.iter().filter(|&&s| s != 0).count();
        Ok(RenderOutput { width: w, height: h, rgb, depth: bytemuck::pod_collect_to_vec::<u8, f32>(&depth), mask, silhouette_pixels })
    }

    fn render_mask(&mut self, view: &View, draws: &[Draw]) -> Result<Vec<u8>> {
        let (w, h) = (view.width, view.height);
        let lighting = Lighting::unlit();
        let (_, _, mask, _) =
            self.draw_views(0, (w, h), &[(view.t_world_camera, projection(view), [0, 0, w, h])], &lighting, draws, Readback::Mask, None)?;
        Ok(mask)
    }

    fn render_depth_views(&mut self, views: &[DepthView], draws: &[Draw]) -> Result<Vec<Vec<f32>>> {
        let Some(first) = views.first() else { return Ok(Vec::new()) };
        let (vw, vh) = (first.width, first.height);
        if views.iter().any(|v| v.width != vw || v.height != vh) {
            bail!("depth views of one call share their size");
        }
        // An atlas of 4 columns: one pass, one readback (rows of 4 x 32 x 4 bytes are aligned).
        let cols = 4u32.min(views.len() as u32);
        let rows = (views.len() as u32).div_ceil(cols);
        let specs: Vec<(DMat4, DMat4, [u32; 4])> = views
            .iter()
            .enumerate()
            .map(|(i, v)| {
                let viewport = [(i as u32 % cols) * vw, (i as u32 / cols) * vh, vw, vh];
                match v.perspective_standoff {
                    None => (v.t_world_camera, orthographic(v), viewport),
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
                        (pinhole.t_world_camera, projection(&pinhole), viewport)
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
        let (_, depth, _, _) = self.draw_views(1, (cols * vw, rows * vh), &specs, &lighting, draws, Readback::Depth, Some(&cull))?;
        let atlas: Vec<f32> = bytemuck::pod_collect_to_vec(&depth);
        let aw = (cols * vw) as usize;
        Ok(specs
            .iter()
            .zip(views)
            .map(|((_, _, vp), v)| {
                // Pinhole depths are measured from the pinhole: shift them to the camera plane.
                let shift = v.perspective_standoff.unwrap_or(0.0) as f32;
                (0..vh as usize)
                    .flat_map(|r| {
                        let start = (vp[1] as usize + r) * aw + vp[0] as usize;
                        atlas[start..start + vw as usize].iter().map(move |d| d - shift)
                    })
                    .collect()
            })
            .collect())
    }
}

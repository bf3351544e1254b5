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

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Vertex {
    position: [f32; 3],
    normal: [f32; 3],
    uv: [f32; 2],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct FrameUniform {
    view: [[f32; 4]; 4],
    proj: [[f32; 4]; 4],
    light_pos: [f32; 4],
    light_color: [f32; 4],
    ambient: [f32; 4],
    light_dir: [f32; 4],
    spot: [f32; 4],
    up: [f32; 4],
    shadow_vp: [[f32; 4]; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct InstanceUniform {
    model_view: [[f32; 4]; 4],
    normal_mat: [[f32; 4]; 4],
    mask_id: [u32; 4],
}

struct GpuMesh {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    index_count: u32,
    material: wgpu::BindGroup,
    /// Roughness, metallic and UV scale (uniform of the material bind group).
    factors: wgpu::Buffer,
    pbr: Material,
    texture: wgpu::Texture,
    /// Triangles grouped into spatial clusters (index range, model-frame bounding box), so that
    /// small views draw only the part of a mesh they can see.
    clusters: Vec<Cluster>,
}

/// A range of a mesh's reordered indices and the bounding box (min, max) of its triangles.
type Cluster = (std::ops::Range<u32>, glam::DVec3, glam::DVec3);

/// Reorders triangles into the cells of an 8x8x8 grid over the mesh's bounding box and returns the
/// new indices with each non-empty cell's index range and bounding box.
fn cluster_triangles(mesh: &TexturedMesh) -> (Vec<u32>, Vec<Cluster>) {
    const N: usize = 8;
    let (lo, hi) = mesh.aabb();
    let (lo, size) = (lo.as_dvec3(), (hi - lo).as_dvec3().max(glam::DVec3::splat(1e-9)));
    let p = |i: u32| glam::Vec3::from(mesh.positions[i as usize]).as_dvec3();
    let mut cells: Vec<Vec<[u32; 3]>> = vec![Vec::new(); N * N * N];
    for t in mesh.indices.chunks_exact(3) {
        let c = (p(t[0]) + p(t[1]) + p(t[2])) / 3.0;
        let g = ((c - lo) / size * N as f64).floor().clamp(glam::DVec3::ZERO, glam::DVec3::splat((N - 1) as f64));
        cells[(g.x as usize * N + g.y as usize) * N + g.z as usize].push([t[0], t[1], t[2]]);
    }
    let mut indices = Vec::with_capacity(mesh.indices.len());
    let mut clusters = Vec::new();
    for cell in cells.into_iter().filter(|c| !c.is_empty()) {
        let start = indices.len() as u32;
        let (mut a, mut b) = (glam::DVec3::splat(f64::MAX), glam::DVec3::splat(f64::MIN));
        for t in cell {
            for i in t {
                a = a.min(p(i));
                b = b.max(p(i));
                indices.push(i);
            }
        }
        clusters.push((start..indices.len() as u32, a, b));
    }
    (indices, clusters)
}

/// Does the box `[lo, hi]` (model frame), seen through `model_view`, overlap the view volume
/// `[-hx, hx] x [-hy, hy] x [near, far]` (camera frame)?
fn box_overlaps_view(model_view: &DMat4, lo: glam::DVec3, hi: glam::DVec3, cull: [f64; 4]) -> bool {
    let [hx, hy, near, far] = cull;
    let (mut a, mut b) = (glam::DVec3::splat(f64::MAX), glam::DVec3::splat(f64::MIN));
    for k in 0..8 {
        let c = glam::DVec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        );
        let q = model_view.transform_point3(c);
        a = a.min(q);
        b = b.max(q);
    }
    a.x <= hx && b.x >= -hx && a.y <= hy && b.y >= -hy && a.z <= far && b.z >= near
}

struct Targets {
    width: u32,
    height: u32,
    color: wgpu::TextureView,
    depth: wgpu::TextureView,
    mask: wgpu::TextureView,
    silhouette: wgpu::TextureView,
    zbuf: wgpu::TextureView,
    /// Multisampled colour and z-buffer of the anti-aliased colour pass (msaa > 1).
    msaa: Option<(wgpu::TextureView, wgpu::TextureView)>,
    color_tex: wgpu::Texture,
    depth_tex: wgpu::Texture,
    mask_tex: wgpu::Texture,
    silhouette_tex: wgpu::Texture,
    /// Colour, depth, mask, silhouette.
    readback: [wgpu::Buffer; 4],
}

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

fn backends(b: Backend) -> wgpu::Backends {
    match b {
        Backend::Auto => wgpu::Backends::all(),
        Backend::Vulkan => wgpu::Backends::VULKAN,
        Backend::Gl => wgpu::Backends::GL,
        Backend::Metal => wgpu::Backends::METAL,
        Backend::Dx12 => wgpu::Backends::DX12,
    }
}

/// Preference among adapters: real GPUs first, then CPU rasterizers; Vulkan before GL, whose
/// R32Float targets need Mesa overrides.
fn rank(info: &wgpu::AdapterInfo) -> (u8, u8) {
    let kind = match info.device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    };
    let api = match info.backend {
        wgpu::Backend::Vulkan | wgpu::Backend::Metal | wgpu::Backend::Dx12 => 0,
        _ => 1,
    };
    (kind, api)
}

pub fn describe_adapter(info: &wgpu::AdapterInfo) -> String {
    let driver = if info.driver_info.is_empty() { String::new() } else { format!(" ({})", info.driver_info) };
    format!("{}{driver} [{:?}, {:?}]", info.name, info.backend, info.device_type)
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

    fn ensure_targets(&mut self, slot: usize, width: u32, height: u32) {
        if self.targets[slot].as_ref().is_none_or(|t| t.width != width || t.height != height) {
            let make = |label, format| {
                self.device.create_texture(&wgpu::TextureDescriptor {
                    label: Some(label),
                    size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format,
                    usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                    view_formats: &[],
                })
            };
            let color_tex = make("colour", COLOR_FORMAT);
            let depth_tex = make("depth", DEPTH_FORMAT);
            let mask_tex = make("mask", MASK_FORMAT);
            let silhouette_tex = make("silhouette", SILHOUETTE_FORMAT);
            let zbuf_tex = make("z-buffer", ZBUF_FORMAT);
            // Only the main view (slot 0) is anti-aliased; the phalanx depth views are not.
            let msaa = (slot == 0 && self.msaa > 1).then(|| {
                let make_ms = |label, format| {
                    self.device
                        .create_texture(&wgpu::TextureDescriptor {
                            label: Some(label),
                            size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
                            mip_level_count: 1,
                            sample_count: self.msaa,
                            dimension: wgpu::TextureDimension::D2,
                            format,
                            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                            view_formats: &[],
                        })
                        .create_view(&Default::default())
                };
                (make_ms("colour (multisampled)", COLOR_FORMAT), make_ms("z-buffer (multisampled)", ZBUF_FORMAT))
            });
            let readback = [4u32, 4, 1, 1].map(|bpp| {
                self.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("readback"),
                    size: padded_row(width * bpp) as u64 * height as u64,
                    usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            });
            self.targets[slot] = Some(Targets {
                width,
                height,
                color: color_tex.create_view(&Default::default()),
                depth: depth_tex.create_view(&Default::default()),
                mask: mask_tex.create_view(&Default::default()),
                silhouette: silhouette_tex.create_view(&Default::default()),
                zbuf: zbuf_tex.create_view(&Default::default()),
                msaa,
                color_tex,
                depth_tex,
                mask_tex,
                silhouette_tex,
                readback,
            });
        }
    }

    /// Records `draws` into each of `views` (its viewport and frame record) in an open pass whose
    /// shadow group is set; with `cull`, only the mesh clusters inside each view. With
    /// `pipelines` = (silhouette, rest), the target object's draws (mask id 1) go first with the
    /// pipeline that also writes the silhouette target: nothing is in the z-buffer yet, so the
    /// first of its fragments at every pixel it covers passes the depth test, and the silhouette
    /// is its coverage with nothing in front (what `render_mask` of it alone gives). Without, the
    /// pass's pipeline is already set.
    fn record_views(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        views: &[(DMat4, DMat4, [u32; 4])],
        draws: &[Draw],
        cull: Option<&[[f64; 4]]>,
        pipelines: Option<(&wgpu::RenderPipeline, &wgpu::RenderPipeline)>,
    ) {
        // The target object first, then the rest, last listed first: callers list the environment
        // (floor, backdrop) first and the object last, so the near things fill the depth buffer
        // early and the early depth test skips shading the floor and wall behind them.
        let is_target = |d: &Draw| d.mask_id == vt_dataset::mask_ids::TARGET_OBJECT;
        let order: Vec<usize> = (0..draws.len())
            .rev()
            .filter(|&i| is_target(&draws[i]))
            .chain((0..draws.len()).rev().filter(|&i| !is_target(&draws[i])))
            .collect();
        for (vi, (_, _, vp)) in views.iter().enumerate() {
            pass.set_viewport(vp[0] as f32, vp[1] as f32, vp[2] as f32, vp[3] as f32, 0.0, 1.0);
            pass.set_scissor_rect(vp[0], vp[1], vp[2], vp[3]);
            pass.set_bind_group(0, &self.frame_group, &[(vi as u64 * FRAME_STRIDE) as u32]);
            for (k, &di) in order.iter().enumerate() {
                let d = &draws[di];
                if let Some((silhouette, rest)) = pipelines {
                    if k == 0 && is_target(d) {
                        pass.set_pipeline(silhouette);
                    } else if k == 0 || (!is_target(d) && is_target(&draws[order[k - 1]])) {
                        pass.set_pipeline(rest);
                    }
                }
                let m = &self.meshes[d.mesh.0];
                pass.set_bind_group(1, &self.instance_group, &[((vi * draws.len() + di) as u64 * UNIFORM_STRIDE) as u32]);
                pass.set_bind_group(2, &m.material, &[]);
                pass.set_vertex_buffer(0, m.vertices.slice(..));
                pass.set_index_buffer(m.indices.slice(..), wgpu::IndexFormat::Uint32);
                match cull {
                    // Small orthographic views: only the clusters inside the view volume.
                    Some(c) => {
                        let mv = views[vi].0.inverse() * d.t_world_model;
                        for (range, lo, hi) in &m.clusters {
                            if box_overlaps_view(&mv, *lo, *hi, c[vi]) {
                                pass.draw_indexed(range.clone(), 0, 0..1);
                            }
                        }
                    }
                    None => pass.draw_indexed(0..m.index_count, 0, 0..1),
                }
            }
        }
    }

    /// One render pass drawing `draws` into each of `views` (its own viewport of the target in
    /// `slot`), then one readback of the target's colour, depth, mask and target-object silhouette
    /// (`readback` says which). Returns (rgba, depth, mask, silhouette) of the whole target.
    fn draw_views(
        &mut self,
        slot: usize,
        size: (u32, u32),
        views: &[(DMat4, DMat4, [u32; 4])],
        lighting: &Lighting,
        draws: &[Draw],
        readback: Readback,
        cull: Option<&[[f64; 4]]>,
    ) -> Result<TargetImages> {
        // The spotlight's shadow pass draws the scene once more, as an extra view record.
        let shadow = (readback == Readback::All && lighting.shadows).then(|| light_view(lighting));
        let records = views.len() + shadow.is_some() as usize;
        if views.len() > MAX_VIEWS || records * draws.len() > MAX_DRAWS {
            bail!("{} views x {} draws in one pass; at most {MAX_VIEWS} views and {MAX_DRAWS} draw records", views.len(), draws.len());
        }
        for d in draws {
            if d.mesh.0 >= self.meshes.len() {
                bail!("draw refers to mesh {} of {}", d.mesh.0, self.meshes.len());
            }
        }
        let mut frames = vec![0u8; FRAME_STRIDE as usize * records.max(1)];
        let mut inst = vec![0u8; UNIFORM_STRIDE as usize * (records * draws.len()).max(1)];
        let lit = readback == Readback::All;
        let all_views = views.iter().map(|(t, p, _)| (*t, *p)).chain(shadow);
        for (vi, (t_world_camera, proj)) in all_views.enumerate() {
            let t_camera_world = t_world_camera.inverse();
            let light = t_camera_world.transform_point3(lighting.light_position);
            let axis = t_camera_world.transform_vector3(lighting.light_target - lighting.light_position).normalize_or_zero();
            let outer = lighting.cone_deg.to_radians();
            let up = t_camera_world.transform_vector3(glam::DVec3::Z);
            let (shadow_vp, texel) = match shadow {
                Some((t_world_light, light_proj)) => {
                    // Shadow-map texel size at 1 m from the light: 2 tan(fov / 2) / size.
                    (light_proj * t_world_light.inverse() * t_world_camera, 2.0 * shadow_half_tan(lighting) / self.shadow_size as f64)
                }
                None => (DMat4::IDENTITY, 0.0),
            };
            let frame = FrameUniform {
                view: mat(t_camera_world),
                proj: mat(proj),
                light_pos: [light.x as f32, light.y as f32, light.z as f32, lighting.light_position.distance(lighting.light_target) as f32],
                light_color: [lighting.light_color[0], lighting.light_color[1], lighting.light_color[2], if lit { 1.0 } else { 0.0 }],
                ambient: [lighting.ambient[0], lighting.ambient[1], lighting.ambient[2], if shadow.is_some() { 1.0 } else { 0.0 }],
                light_dir: [axis.x as f32, axis.y as f32, axis.z as f32, outer.cos() as f32],
                spot: [
                    (outer * lighting.softness.clamp(0.0, 0.999)).cos() as f32,
                    texel as f32,
                    (self.tonemapping == ToneMapping::Aces) as u8 as f32,
                    0.0,
                ],
                up: [up.x as f32, up.y as f32, up.z as f32, 0.0],
                shadow_vp: mat(shadow_vp),
            };
            let o = vi * FRAME_STRIDE as usize;
            frames[o..o + size_of::<FrameUniform>()].copy_from_slice(bytemuck::bytes_of(&frame));
            for (di, d) in draws.iter().enumerate() {
                // Model-view in f64, then f32: keeps camera-frame coordinates exact to ~1e-7 m.
                let mv = t_camera_world * d.t_world_model;
                let u = InstanceUniform {
                    model_view: mat(mv),
                    normal_mat: mat(mv.inverse().transpose()),
                    mask_id: [d.mask_id as u32, 0, 0, 0],
                };
                let o = (vi * draws.len() + di) * UNIFORM_STRIDE as usize;
                inst[o..o + size_of::<InstanceUniform>()].copy_from_slice(bytemuck::bytes_of(&u));
            }
        }
        self.queue.write_buffer(&self.frame_buffer, 0, &frames);
        self.queue.write_buffer(&self.instance_buffer, 0, &inst);
        let (w, h) = size;
        self.ensure_targets(slot, w, h);
        let t = self.targets[slot].as_ref().expect("created above");
        let bg = lighting.background.map(|c| srgb_to_linear(c) as f64);
        let mut enc = self.device.create_command_encoder(&Default::default());
        if shadow.is_some() {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("shadow map"),
                color_attachments: &[],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &self.shadow_map,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.shadow_pipeline);
            let vi = views.len();
            pass.set_bind_group(0, &self.frame_group, &[(vi as u64 * FRAME_STRIDE) as u32]);
            // The environment (mask id 0: floor, backdrop) receives shadows but casts none onto
            // anything the camera cares about; leaving it out saves filling the whole map.
            for (di, d) in draws.iter().enumerate().filter(|(_, d)| d.mask_id != 0) {
                let m = &self.meshes[d.mesh.0];
                pass.set_bind_group(1, &self.instance_group, &[((vi * draws.len() + di) as u64 * UNIFORM_STRIDE) as u32]);
                pass.set_vertex_buffer(0, m.vertices.slice(..));
                pass.set_index_buffer(m.indices.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..m.index_count, 0, 0..1);
            }
        }
        {
            let color_att = |view, clear: wgpu::Color| {
                Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations { load: wgpu::LoadOp::Clear(clear), store: wgpu::StoreOp::Store },
                })
            };
            // Depth-view targets are cleared to +inf: "no surface in range".
            let depth_clear = if readback == Readback::Depth { f64::INFINITY } else { 0.0 };
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("views"),
                color_attachments: &[
                    color_att(&t.color, wgpu::Color { r: bg[0], g: bg[1], b: bg[2], a: 1.0 }),
                    color_att(&t.depth, wgpu::Color { r: depth_clear, g: 0.0, b: 0.0, a: 0.0 }),
                    color_att(&t.mask, wgpu::Color::TRANSPARENT),
                    color_att(&t.silhouette, wgpu::Color::TRANSPARENT),
                ],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &t.zbuf,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Discard }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_bind_group(3, &self.shadow_group, &[]);
            if readback == Readback::All {
                self.record_views(&mut pass, views, draws, cull, Some((&self.silhouette_pipeline, &self.pipeline)));
            } else {
                pass.set_pipeline(&self.pipeline);
                self.record_views(&mut pass, views, draws, cull, None);
            }
        }
        if let (Readback::All, Some(pipeline), Some((ms_color, ms_zbuf))) = (readback, &self.msaa_pipeline, &t.msaa) {
            // The anti-aliased colour, resolved over the single-sample colour of the pass above.
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("colour (multisampled)"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: ms_color,
                    depth_slice: None,
                    resolve_target: Some(&t.color),
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color { r: bg[0], g: bg[1], b: bg[2], a: 1.0 }),
                        store: wgpu::StoreOp::Discard,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: ms_zbuf,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Discard }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(3, &self.shadow_group, &[]);
            self.record_views(&mut pass, views, draws, None, None);
        }
        let copies: Vec<(&wgpu::Texture, &wgpu::Buffer, u32)> = match readback {
            Readback::Depth => vec![(&t.depth_tex, &t.readback[1], 4)],
            Readback::Mask => vec![(&t.mask_tex, &t.readback[2], 1)],
            Readback::All => vec![
                (&t.color_tex, &t.readback[0], 4),
                (&t.depth_tex, &t.readback[1], 4),
                (&t.mask_tex, &t.readback[2], 1),
                (&t.silhouette_tex, &t.readback[3], 1),
            ],
        };
        for (tex, buf, bpp) in &copies {
            enc.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo { texture: tex, mip_level: 0, origin: wgpu::Origin3d::ZERO, aspect: wgpu::TextureAspect::All },
                wgpu::TexelCopyBufferInfo {
                    buffer: buf,
                    layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(padded_row(w * bpp)), rows_per_image: Some(h) },
                },
                wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
            );
        }
        self.queue.submit([enc.finish()]);
        for (_, b, _) in &copies {
            b.slice(..).map_async(wgpu::MapMode::Read, |r| {
                if let Err(e) = r {
                    eprintln!("vtgen: readback mapping failed: {e}");
                }
            });
        }
        self.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| anyhow!("GPU wait failed: {e}"))?;
        let t_read = std::time::Instant::now();
        let read = |buf: &wgpu::Buffer, bpp: u32| -> Result<Vec<u8>> {
            let data = buf.slice(..).get_mapped_range().map_err(|e| anyhow!("readback failed: {e:?}"))?;
            let row = (w * bpp) as usize;
            let padded = padded_row(w * bpp) as usize;
            let mut out = Vec::with_capacity(row * h as usize);
            for r in 0..h as usize {
                out.extend_from_slice(&data[r * padded..r * padded + row]);
            }
            Ok(out)
        };
        let mut out = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        if readback == Readback::All {
            out.0 = read(&t.readback[0], 4)?;
            out.3 = read(&t.readback[3], 1)?;
        }
        if readback != Readback::Mask {
            out.1 = read(&t.readback[1], 4)?;
        }
        if readback != Readback::Depth {
            out.2 = read(&t.readback[2], 1)?;
        }
        for (_, b, _) in &copies {
            b.unmap();
        }
        self.readback += t_read.elapsed();
        Ok(out)
    }
}

/// tan of the half field of view of the shadow map: the cone with a margin for the PCF kernel.
fn shadow_half_tan(l: &Lighting) -> f64 {
    (l.cone_deg.clamp(1.0, 80.0) * 1.05).to_radians().tan()
}

/// The spotlight as a camera (OpenCV frame looking along the spot's axis) and its projection.
fn light_view(l: &Lighting) -> (DMat4, DMat4) {
    let t = crate::scene::look_at(l.light_position, l.light_target).matrix();
    let f = 1.0 / shadow_half_tan(l);
    let dist = l.light_position.distance(l.light_target);
    let v = View {
        width: 2,
        height: 2,
        // A 2x2 "image" with the optical axis at its centre: only the field of view matters.
        k: Intrinsics { fx: f, fy: f, cx: 0.5, cy: 0.5 },
        near: (dist * 0.05).max(0.02),
        far: dist * 4.0 + 2.0,
        t_world_camera: t,
    };
    (t, projection(&v))
}

/// Uploads `t` and its mip chain (the texture was created with every level).
fn write_texture(queue: &wgpu::Queue, texture: &wgpu::Texture, t: &vt_objects::Texture) {
    let levels = super::mipmaps::mip_levels(t);
    for (mip_level, l) in std::iter::once(t).chain(&levels).enumerate() {
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture,
                mip_level: mip_level as u32,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            &l.rgba,
            wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(4 * l.width), rows_per_image: Some(l.height) },
            wgpu::Extent3d { width: l.width, height: l.height, depth_or_array_layers: 1 },
        );
    }
}

impl WgpuRenderer {
    /// A base-colour texture and the material bind group (texture, sampler, factors) around it.
    fn make_material(&self, t: &vt_objects::Texture, factors: &wgpu::Buffer) -> Result<(wgpu::Texture, wgpu::BindGroup)> {
        let max = self.device.limits().max_texture_dimension_2d;
        if t.width > max || t.height > max {
            bail!("texture {}x{} exceeds the adapter's limit of {max}", t.width, t.height);
        }
        if t.rgba.len() != (t.width * t.height * 4) as usize {
            bail!("texture {}x{} has {} bytes, expected {}", t.width, t.height, t.rgba.len(), t.width * t.height * 4);
        }
        let texture = self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("base colour"),
            size: wgpu::Extent3d { width: t.width, height: t.height, depth_or_array_layers: 1 },
            mip_level_count: super::mipmaps::level_count(t.width, t.height),
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba8UnormSrgb,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        write_texture(&self.queue, &texture, t);
        let view = texture.create_view(&Default::default());
        let group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("material"),
            layout: &self.material_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(&view) },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::Sampler(&self.sampler) },
                wgpu::BindGroupEntry { binding: 2, resource: factors.as_entire_binding() },
            ],
        });
        Ok((texture, group))
    }
}

/// Bytes of a pass's targets: rgba, depth, mask, silhouette (empty when not read back).
type TargetImages = (Vec<u8>, Vec<u8>, Vec<u8>, Vec<u8>);

/// Which targets a pass reads back.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Readback {
    All,
    Depth,
    Mask,
}

fn padded_row(bytes: u32) -> u32 {
    bytes.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT
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

//! The bind-group layouts and the render pipelines: shadow map, main view (with and without the
//! silhouette target) and the multisampled colour pass.

use super::*;

/// The four bind groups every pipeline reads: frame (camera, light) and instance (model-view,
/// mask id) uniforms at dynamic offsets, the material (texture, sampler, factors), the shadow map.
pub(super) struct BindLayouts {
    pub(super) frame: wgpu::BindGroupLayout,
    pub(super) instance: wgpu::BindGroupLayout,
    pub(super) material: wgpu::BindGroupLayout,
    pub(super) shadow: wgpu::BindGroupLayout,
}

fn uniform_entry(binding: u32, dynamic: bool, size: u64) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: dynamic,
            min_binding_size: wgpu::BufferSize::new(size),
        },
        count: None,
    }
}

fn texture_entry(sample_type: wgpu::TextureSampleType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding: 0,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture { sample_type, view_dimension: wgpu::TextureViewDimension::D2, multisampled: false },
        count: None,
    }
}

fn sampler_entry(kind: wgpu::SamplerBindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry { binding: 1, visibility: wgpu::ShaderStages::FRAGMENT, ty: wgpu::BindingType::Sampler(kind), count: None }
}

impl BindLayouts {
    pub(super) fn new(device: &wgpu::Device) -> Self {
        let layout = |label, entries: &[wgpu::BindGroupLayoutEntry]| {
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries })
        };
        BindLayouts {
            frame: layout("frame", &[uniform_entry(0, true, size_of::<FrameUniform>() as u64)]),
            instance: layout("instance", &[uniform_entry(0, true, size_of::<InstanceUniform>() as u64)]),
            material: layout(
                "material",
                &[
                    texture_entry(wgpu::TextureSampleType::Float { filterable: true }),
                    sampler_entry(wgpu::SamplerBindingType::Filtering),
                    uniform_entry(2, false, 16),
                ],
            ),
            shadow: layout(
                "shadow map",
                &[texture_entry(wgpu::TextureSampleType::Depth), sampler_entry(wgpu::SamplerBindingType::Comparison)],
            ),
        }
    }
}

/// The render pipelines of one renderer.
pub(super) struct Pipelines {
    /// The main view's targets without writing the silhouette: everything but the target object.
    pub(super) main: wgpu::RenderPipeline,
    /// `main` that also writes the silhouette target: the target object's draws in the main pass.
    pub(super) silhouette: wgpu::RenderPipeline,
    /// The multisampled colour-only pass, when `msaa` > 1.
    pub(super) msaa: Option<wgpu::RenderPipeline>,
    /// Depth-only pass from the spotlight into the shadow map.
    pub(super) shadow: wgpu::RenderPipeline,
}

/// What differs between the pipelines; the rest (the vertex layout, triangle lists without
/// culling, because scanned and user meshes are not reliably closed or consistently wound, and a
/// writing Less depth test) they share.
struct PipelineSpec<'a> {
    label: &'a str,
    layout: &'a wgpu::PipelineLayout,
    vertex_entry: &'a str,
    depth_format: wgpu::TextureFormat,
    depth_bias: wgpu::DepthBiasState,
    samples: u32,
    /// Fragment entry point and colour targets; None for a depth-only pass.
    fragment: Option<(&'a str, &'a [Option<wgpu::ColorTargetState>])>,
}

fn make_pipeline(device: &wgpu::Device, shader: &wgpu::ShaderModule, spec: PipelineSpec<'_>) -> wgpu::RenderPipeline {
    let vertex_layout = wgpu::VertexBufferLayout {
        array_stride: size_of::<Vertex>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x2],
    };
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(spec.label),
        layout: Some(spec.layout),
        vertex: wgpu::VertexState {
            module: shader,
            entry_point: Some(spec.vertex_entry),
            compilation_options: Default::default(),
            buffers: &[Some(vertex_layout)],
        },
        primitive: wgpu::PrimitiveState { topology: wgpu::PrimitiveTopology::TriangleList, cull_mode: None, ..Default::default() },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: spec.depth_format,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: Default::default(),
            bias: spec.depth_bias,
        }),
        multisample: wgpu::MultisampleState { count: spec.samples, ..Default::default() },
        fragment: spec.fragment.map(|(entry, targets)| wgpu::FragmentState {
            module: shader,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            targets,
        }),
        multiview_mask: None,
        cache: None,
    })
}

impl Pipelines {
    pub(super) fn new(device: &wgpu::Device, layouts: &BindLayouts, msaa: u32) -> Self {
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("main view"),
            source: wgpu::ShaderSource::Wgsl(include_str!("shader.wgsl").into()),
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("main view"),
            bind_group_layouts: &[Some(&layouts.frame), Some(&layouts.instance), Some(&layouts.material), Some(&layouts.shadow)],
            immediate_size: 0,
        });
        let shadow_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("shadow map"),
            bind_group_layouts: &[Some(&layouts.frame), Some(&layouts.instance)],
            immediate_size: 0,
        });
        let main_view = |label, samples, fragment| PipelineSpec {
            label,
            layout: &layout,
            vertex_entry: "vs_main",
            depth_format: ZBUF_FORMAT,
            depth_bias: Default::default(),
            samples,
            fragment: Some(fragment),
        };
        let shadow = make_pipeline(
            device,
            &shader,
            PipelineSpec {
                label: "shadow map",
                layout: &shadow_layout,
                vertex_entry: "vs_shadow",
                depth_format: SHADOW_FORMAT,
                // A small slope-scaled bias; the normal offset in the lookup does the rest.
                depth_bias: wgpu::DepthBiasState { constant: 2, slope_scale: 1.5, clamp: 0.0 },
                samples: 1,
                fragment: None,
            },
        );
        let target = |format| Some(wgpu::ColorTargetState { format, blend: None, write_mask: wgpu::ColorWrites::ALL });
        // Two pipelines that differ only in whether they write the silhouette target: the target
        // object's draws come first in the pass with `silhouette`, everything else follows with
        // `main`, which leaves the silhouette alone.
        let silhouette_targets = [target(COLOR_FORMAT), target(DEPTH_FORMAT), target(MASK_FORMAT), target(SILHOUETTE_FORMAT)];
        let mut main_targets = silhouette_targets.clone();
        main_targets[3] = Some(wgpu::ColorTargetState { format: SILHOUETTE_FORMAT, blend: None, write_mask: wgpu::ColorWrites::empty() });
        let silhouette = make_pipeline(device, &shader, main_view("main view, target object", 1, ("fs_main", &silhouette_targets)));
        let main = make_pipeline(device, &shader, main_view("main view", 1, ("fs_main", &main_targets)));
        let colour = [target(COLOR_FORMAT)];
        let msaa =
            (msaa > 1).then(|| make_pipeline(device, &shader, main_view("main view, multisampled colour", msaa, ("fs_color", &colour))));
        Pipelines { main, silhouette, msaa, shadow }
    }
}

/// The spotlight's depth map and the bind group the main pass samples it through.
pub(super) struct ShadowMap {
    pub(super) view: wgpu::TextureView,
    pub(super) group: wgpu::BindGroup,
    pub(super) size: u32,
}

impl ShadowMap {
    pub(super) fn new(device: &wgpu::Device, layout: &wgpu::BindGroupLayout, size: u32) -> Self {
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("shadow map"),
            size: wgpu::Extent3d { width: size, height: size, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: SHADOW_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let view = texture.create_view(&Default::default());
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("shadow"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            compare: Some(wgpu::CompareFunction::LessEqual),
            ..Default::default()
        });
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shadow map"),
            layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(&view) },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::Sampler(&sampler) },
            ],
        });
        ShadowMap { view, group, size }
    }
}

/// A uniform buffer of `records` records bound at dynamic offsets, one `T` visible at a time.
pub(super) struct UniformArena {
    pub(super) buffer: wgpu::Buffer,
    pub(super) group: wgpu::BindGroup,
}

impl UniformArena {
    pub(super) fn new<T>(device: &wgpu::Device, layout: &wgpu::BindGroupLayout, label: &str, stride: u64, records: usize) -> Self {
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: stride * records as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &buffer,
                    offset: 0,
                    size: wgpu::BufferSize::new(size_of::<T>() as u64),
                }),
            }],
        });
        UniformArena { buffer, group }
    }
}

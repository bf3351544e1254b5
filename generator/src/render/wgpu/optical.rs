//! The optical tactile images' shading (`optical.wgsl`): three compute dispatches per sensor view,
//! encoded after the depth views' draw in their submission, reading the atlas' depth target; the
//! result is copied to a readback buffer with the depth.

use super::*;
use crate::render::{GelShading, MAX_GEL_LIGHTS};

/// `Job` in `optical.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct JobUniform {
    viewport: [u32; 4],
    offset_radius: [u32; 4],
    geometry: [f32; 4],
    spread: [f32; 4],
    tint: [f32; 4],
    depth_range: [f32; 4],
    light_dir: [[f32; 4]; MAX_GEL_LIGHTS],
    light_color: [[f32; 4]; MAX_GEL_LIGHTS],
    light_azimuth: [[f32; 4]; MAX_GEL_LIGHTS],
}

/// Job uniforms sit at this stride (the minimum uniform offset alignment).
const JOB_STRIDE: u64 = 512;

pub(super) struct OpticalPipelines {
    layout: wgpu::BindGroupLayout,
    blur_rows: wgpu::ComputePipeline,
    gel_surface: wgpu::ComputePipeline,
    shade: wgpu::ComputePipeline,
}

impl OpticalPipelines {
    pub(super) fn new(device: &wgpu::Device) -> Self {
        let storage = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: false },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("optical shading"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: true,
                        min_binding_size: wgpu::BufferSize::new(size_of::<JobUniform>() as u64),
                    },
                    count: None,
                },
                storage(2),
                storage(3),
            ],
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("optical.wgsl"),
            source: wgpu::ShaderSource::Wgsl(include_str!("optical.wgsl").into()),
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("optical shading"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = |entry| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        OpticalPipelines { blur_rows: pipeline("blur_rows"), gel_surface: pipeline("gel_surface"), shade: pipeline("shade"), layout }
    }
}

/// The shading of one submission, encoded: its readback buffer and each view's pixel range.
pub(super) struct EncodedShading {
    pub(super) readback: wgpu::Buffer,
    pub(super) ranges: Vec<(usize, usize)>,
}

impl WgpuRenderer {
    /// Encodes the shading of `shading` (over the atlas views `views`, indexed by each shading's
    /// `view`) reading `atlas` (the depth target), and its copy for readback.
    pub(super) fn encode_optical(
        &self,
        enc: &mut wgpu::CommandEncoder,
        atlas: &wgpu::TextureView,
        views: &[ViewSpec],
        shading: &[GelShading],
    ) -> Result<EncodedShading> {
        let pipelines = self.optical.as_ref().expect("made before encoding");
        let mut ranges = Vec::with_capacity(shading.len());
        let mut uniforms = vec![0u8; JOB_STRIDE as usize * shading.len()];
        let mut offset = 0usize;
        for (k, s) in shading.iter().enumerate() {
            let view = views.get(s.view).ok_or_else(|| anyhow!("optical shading of view {} of {}", s.view, views.len()))?;
            let vp = view.viewport;
            if s.lights.len() > MAX_GEL_LIGHTS {
                bail!("{} LEDs: the GPU shading holds {MAX_GEL_LIGHTS}", s.lights.len());
            }
            let pixels = (vp[2] * vp[3]) as usize;
            let radius = |sigma: f64| if sigma > 0.0 { (3.0 * sigma).ceil() as u32 } else { 0 };
            let spread_on = s.spread_sigma_px[0] > 0.0 && s.spread_sigma_px[1] > 0.0;
            let mut job = JobUniform {
                viewport: vp,
                offset_radius: [offset as u32, radius(s.spread_sigma_px[0]), radius(s.spread_sigma_px[1]), s.lights.len() as u32],
                geometry: [s.gel_thickness as f32, s.pitch[0] as f32, s.pitch[1] as f32, s.ambient as f32],
                spread: [s.spread_sigma_px[0] as f32, s.spread_sigma_px[1] as f32, s.vignetting as f32, spread_on as u8 as f32],
                tint: [s.tint[0] as f32, s.tint[1] as f32, s.tint[2] as f32, 0.0],
                depth_range: [view.depth_range[0], view.depth_range[1], 0.0, 0.0],
                light_dir: [[0.0; 4]; MAX_GEL_LIGHTS],
                light_color: [[0.0; 4]; MAX_GEL_LIGHTS],
                light_azimuth: [[0.0; 4]; MAX_GEL_LIGHTS],
            };
            for (i, l) in s.lights.iter().enumerate() {
                job.light_dir[i] = [l.direction[0] as f32, l.direction[1] as f32, l.direction[2] as f32, l.falloff as f32];
                job.light_color[i] = [l.color[0] as f32, l.color[1] as f32, l.color[2] as f32, 0.0];
                job.light_azimuth[i] = [l.azimuth[0] as f32, l.azimuth[1] as f32, 0.0, 0.0];
            }
            let at = k * JOB_STRIDE as usize;
            uniforms[at..at + size_of::<JobUniform>()].copy_from_slice(bytemuck::bytes_of(&job));
            ranges.push((offset, pixels));
            offset += pixels;
        }
        let uniform = self.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("optical jobs"),
            contents: &uniforms,
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let storage = |label, bytes: usize, usage| {
            self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes.max(16) as u64,
                usage,
                mapped_at_creation: false,
            })
        };
        let rows = storage("optical rows", offset * 4, wgpu::BufferUsages::STORAGE);
        let shaded = storage("optical shading", offset * 16, wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC);
        let readback = storage("optical readback", offset * 16, wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
        let bind = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("optical shading"),
            layout: &pipelines.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(atlas) },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &uniform,
                        offset: 0,
                        size: wgpu::BufferSize::new(size_of::<JobUniform>() as u64),
                    }),
                },
                wgpu::BindGroupEntry { binding: 2, resource: rows.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: shaded.as_entire_binding() },
            ],
        });
        // One compute pass per step: each step reads what the previous one wrote over the view.
        for pipeline in [&pipelines.blur_rows, &pipelines.gel_surface, &pipelines.shade] {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("optical shading"), timestamp_writes: None });
            pass.set_pipeline(pipeline);
            for (k, s) in shading.iter().enumerate() {
                let vp = views[s.view].viewport;
                pass.set_bind_group(0, &bind, &[(k as u64 * JOB_STRIDE) as u32]);
                pass.dispatch_workgroups(vp[2].div_ceil(8), vp[3].div_ceil(8), 1);
            }
        }
        enc.copy_buffer_to_buffer(&shaded, 0, &readback, 0, (offset * 16).max(16) as u64);
        Ok(EncodedShading { readback, ranges })
    }
}

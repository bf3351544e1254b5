//! The render targets of a view slot (colour, z-depth, mask, silhouette, z-buffer) and their
//! 256-byte-aligned readback.

use super::*;

pub(super) struct Targets {
    pub(super) width: u32,
    pub(super) height: u32,
    pub(super) color: wgpu::TextureView,
    pub(super) depth: wgpu::TextureView,
    pub(super) mask: wgpu::TextureView,
    pub(super) silhouette: wgpu::TextureView,
    pub(super) zbuf: wgpu::TextureView,
    /// Multisampled colour and z-buffer of the anti-aliased colour pass (msaa > 1).
    pub(super) msaa: Option<(wgpu::TextureView, wgpu::TextureView)>,
    pub(super) color_tex: wgpu::Texture,
    pub(super) depth_tex: wgpu::Texture,
    pub(super) mask_tex: wgpu::Texture,
    pub(super) silhouette_tex: wgpu::Texture,
    pub(super) readback: Readbacks,
}

/// Mappable copies of the targets, rows padded to 256 bytes.
pub(super) struct Readbacks {
    pub(super) color: wgpu::Buffer,
    pub(super) depth: wgpu::Buffer,
    pub(super) mask: wgpu::Buffer,
    pub(super) silhouette: wgpu::Buffer,
}

/// The two target sets of a renderer: they differ in size and in anti-aliasing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Slot {
    /// The main camera (anti-aliased when msaa > 1).
    Main = 0,
    /// The atlas of pad depth views.
    TactileAtlas = 1,
}

impl WgpuRenderer {
    pub(super) fn ensure_targets(&mut self, slot: Slot, width: u32, height: u32) {
        if self.targets[slot as usize].as_ref().is_none_or(|t| t.width != width || t.height != height) {
            let make = |label, format| {
                self.device.create_texture(&wgpu::TextureDescriptor {
                    label: Some(label),
                    size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format,
                    // Texture binding: the optical shading reads the atlas' depth (`optical.rs`).
                    usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC | wgpu::TextureUsages::TEXTURE_BINDING,
                    view_formats: &[],
                })
            };
            let color_tex = make("colour", COLOR_FORMAT);
            let depth_tex = make("depth", DEPTH_FORMAT);
            let mask_tex = make("mask", MASK_FORMAT);
            let silhouette_tex = make("silhouette", SILHOUETTE_FORMAT);
            let zbuf_tex = make("z-buffer", ZBUF_FORMAT);
            // Only the main view is anti-aliased; the pad depth views are not.
            let msaa = (slot == Slot::Main && self.msaa > 1).then(|| {
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
            let readback_buffer = |bpp: u32| {
                self.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("readback"),
                    size: padded_row(width * bpp) as u64 * height as u64,
                    usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            };
            let readback = Readbacks {
                color: readback_buffer(4),
                depth: readback_buffer(4),
                mask: readback_buffer(1),
                silhouette: readback_buffer(1),
            };
            self.targets[slot as usize] = Some(Targets {
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
}

/// Bytes of a submission's targets, row-major without padding (empty when not read back).
#[derive(Default)]
pub(super) struct TargetImages {
    /// sRGB colour, 4 bytes per pixel.
    pub(super) rgba: Vec<u8>,
    /// z-depth, f32 little-endian.
    pub(super) depth: Vec<u8>,
    pub(super) mask: Vec<u8>,
    /// Non-zero where the target draw covers the pixel with nothing in front.
    pub(super) silhouette: Vec<u8>,
    /// Per optical shading of the submission: linear R, G, B and the gel's surface per pixel.
    pub(super) optical: Vec<Vec<f32>>,
}

/// Which targets a pass reads back.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Readback {
    All,
    Depth,
    Mask,
}

pub(super) fn padded_row(bytes: u32) -> u32 {
    bytes.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT
}

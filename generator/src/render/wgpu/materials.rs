//! Materials: base-colour textures (with their mip chain) and the glTF factors, as bind groups.

use super::*;

/// Uploads `t` and its mip chain (the texture was created with every level).
pub(super) fn write_texture(queue: &wgpu::Queue, texture: &wgpu::Texture, t: &vt_objects::Texture) {
    let levels = crate::render::mipmaps::mip_levels(t);
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
    pub(super) fn make_material(&self, t: &vt_objects::Texture, factors: &wgpu::Buffer) -> Result<(wgpu::Texture, wgpu::BindGroup)> {
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
            mip_level_count: crate::render::mipmaps::level_count(t.width, t.height),
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

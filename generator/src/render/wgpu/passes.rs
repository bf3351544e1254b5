//! The render passes: the shadow map, then every view of a submission drawn into its viewport,
//! and the spotlight's view for the shadow map.

use super::*;

/// One view of a submission: the camera's pose, its projection, its viewport in the target.
#[derive(Debug, Clone, Copy)]
pub(super) struct ViewSpec {
    pub(super) t_world_camera: DMat4,
    pub(super) proj: DMat4,
    /// x, y, width, height in target pixels.
    pub(super) viewport: [u32; 4],
    /// The depths the view sees (near, far plane), as its target stores them: from its camera
    /// plane, or from the pinhole of a pinhole pad view.
    pub(super) depth_range: [f32; 2],
}

/// One render pass drawing the same draws into several views of one target set, and what of it
/// is read back.
pub(super) struct Submission<'a> {
    pub(super) slot: Slot,
    /// The whole target's size.
    pub(super) size: (u32, u32),
    pub(super) views: &'a [ViewSpec],
    pub(super) readback: Readback,
    /// Per view, a box in its camera frame (half x, half y, near, far): only the mesh clusters
    /// that overlap it are drawn (the small pad views see a few of them).
    pub(super) cull: Option<&'a [[f64; 4]]>,
    /// Optical tactile images shaded from the depth views, after them (`optical.rs`).
    pub(super) optical: &'a [crate::render::GelShading],
}

impl WgpuRenderer {
    /// Records `draws` into each of `views` (its viewport and frame record) in an open pass whose
    /// shadow group is set; with `cull`, only the mesh clusters inside each view. With
    /// `pipelines` = (silhouette, rest), the target draw goes first with the pipeline that also
    /// writes the silhouette target: nothing is in the z-buffer yet, so the first of its
    /// fragments at every pixel it covers passes the depth test, and the silhouette is its
    /// coverage with nothing in front (what `render_mask` of it alone gives). Without, the pass's
    /// pipeline is already set.
    pub(super) fn record_views(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        views: &[ViewSpec],
        draws: &[Draw],
        cull: Option<&[[f64; 4]]>,
        pipelines: Option<(&wgpu::RenderPipeline, &wgpu::RenderPipeline)>,
    ) {
        // The target first, then the rest, last listed first: callers list the environment
        // (floor, backdrop) first and the object last, so the near things fill the depth buffer
        // early and the early depth test skips shading the floor and wall behind them.
        let is_target = |d: &Draw| d.role == DrawRole::Target;
        let order: Vec<usize> = (0..draws.len())
            .rev()
            .filter(|&i| is_target(&draws[i]))
            .chain((0..draws.len()).rev().filter(|&i| !is_target(&draws[i])))
            .collect();
        for (vi, view) in views.iter().enumerate() {
            let view_proj = view.proj * view.t_world_camera.inverse();
            let vp = view.viewport;
            pass.set_viewport(vp[0] as f32, vp[1] as f32, vp[2] as f32, vp[3] as f32, 0.0, 1.0);
            pass.set_scissor_rect(vp[0], vp[1], vp[2], vp[3]);
            pass.set_bind_group(0, &self.frames.group, &[(vi as u64 * FRAME_STRIDE) as u32]);
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
                // A mesh wholly outside the view (the arm's base, a distractor off the image)
                // would only cost vertex shading and clipping.
                if cull.is_none() && box_outside_clip(&(view_proj * d.t_world_model), m.bounds.0, m.bounds.1) {
                    continue;
                }
                pass.set_bind_group(1, &self.instances.group, &[((vi * draws.len() + di) as u64 * UNIFORM_STRIDE) as u32]);
                pass.set_bind_group(2, &m.material, &[]);
                pass.set_vertex_buffer(0, m.vertices.slice(..));
                pass.set_index_buffer(m.indices.slice(..), wgpu::IndexFormat::Uint32);
                match cull {
                    // Small orthographic views: only the clusters inside the view volume.
                    Some(c) => {
                        let mv = view.t_world_camera.inverse() * d.t_world_model;
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

    /// One submission: the shadow map when the lit colour is read back and the light casts
    /// shadows, one pass drawing `draws` into each view (its own viewport of the slot's target),
    /// the multisampled colour when enabled, then one readback of what `sub.readback` asks for.
    pub(super) fn draw_views(&mut self, sub: &Submission<'_>, lighting: &Lighting, draws: &[Draw]) -> Result<TargetImages> {
        // The spotlight's shadow pass draws the scene once more, as an extra view record.
        let shadow = (sub.readback == Readback::All && lighting.shadows).then(|| light_view(lighting));
        let records = sub.views.len() + shadow.is_some() as usize;
        if sub.views.len() > MAX_VIEWS || records * draws.len() > MAX_DRAWS {
            bail!("{} views x {} draws in one pass; at most {MAX_VIEWS} views and {MAX_DRAWS} draw records", sub.views.len(), draws.len());
        }
        for d in draws {
            if d.mesh.0 >= self.meshes.len() {
                bail!("draw refers to mesh {} of {}", d.mesh.0, self.meshes.len());
            }
        }
        self.write_uniforms(sub, shadow, lighting, draws);
        if !sub.optical.is_empty() && self.optical.is_none() {
            self.optical = Some(super::optical::OpticalPipelines::new(&self.device));
        }
        let (w, h) = sub.size;
        self.ensure_targets(sub.slot, w, h);
        let t = self.targets[sub.slot as usize].as_ref().expect("created above");
        let bg = lighting.background.map(|c| srgb_to_linear(c) as f64);
        let background = wgpu::Color { r: bg[0], g: bg[1], b: bg[2], a: 1.0 };
        // With pass timing (`Renderer::time_passes`): what is recorded so far is submitted and
        // waited for, and its wall time charged to `field`; the next pass gets a fresh encoder.
        let timing = self.pass_times.is_some();
        let mut laps = crate::render::PassTimes::default();
        let mut clock = std::time::Instant::now();
        let mut lap = |enc: wgpu::CommandEncoder, field: &mut std::time::Duration| -> Result<wgpu::CommandEncoder> {
            if !timing {
                return Ok(enc);
            }
            self.queue.submit([enc.finish()]);
            self.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| anyhow!("GPU wait failed: {e}"))?;
            *field += clock.elapsed();
            clock = std::time::Instant::now();
            Ok(self.device.create_command_encoder(&Default::default()))
        };
        // The uniforms and any texture written since the last submission.
        let mut enc = lap(self.device.create_command_encoder(&Default::default()), &mut laps.uploads)?;
        if let Some((t_world_light, light_proj)) = shadow {
            self.encode_shadow_pass(&mut enc, sub.views.len(), light_proj * t_world_light.inverse(), draws);
            enc = lap(enc, &mut laps.shadow_map)?;
        }
        self.encode_view_pass(&mut enc, t, sub, draws, background);
        enc = lap(
            enc,
            match sub.readback {
                Readback::All => &mut laps.main_views,
                Readback::Mask => &mut laps.mask_views,
                Readback::Depth => &mut laps.depth_views,
            },
        )?;
        if let (Readback::All, Some(pipeline), Some(ms)) = (sub.readback, &self.pipelines.msaa, &t.msaa) {
            self.encode_msaa_pass(&mut enc, t, ms, pipeline, sub.views, draws, background);
            enc = lap(enc, &mut laps.main_msaa)?;
        }
        let shading = match sub.optical {
            [] => None,
            jobs => {
                let shading = self.encode_optical(&mut enc, &t.depth, sub.views, jobs)?;
                enc = lap(enc, &mut laps.optical_shading)?;
                Some(shading)
            }
        };
        let copies = copy_targets(&mut enc, t, sub.readback, w, h);
        self.queue.submit([enc.finish()]);
        let buffers = copies.iter().map(|(_, b, _)| *b).chain(shading.as_ref().map(|s| &s.readback));
        for b in buffers {
            b.slice(..).map_async(wgpu::MapMode::Read, |r| {
                if let Err(e) = r {
                    eprintln!("vtgen: readback mapping failed: {e}");
                }
            });
        }
        self.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| anyhow!("GPU wait failed: {e}"))?;
        if timing {
            laps.copy_and_map += clock.elapsed();
        }
        let t_read = std::time::Instant::now();
        let read = |buf: &wgpu::Buffer, bpp: u32| -> Result<Vec<u8>> { read_unpadded(buf, w * bpp, h) };
        let rb = &t.readback;
        let mut out = TargetImages::default();
        if sub.readback == Readback::All {
            out.rgba = read(&rb.color, 4)?;
            out.silhouette = read(&rb.silhouette, 1)?;
        }
        if sub.readback != Readback::Mask {
            out.depth = read(&rb.depth, 4)?;
        }
        if sub.readback != Readback::Depth {
            out.mask = read(&rb.mask, 1)?;
        }
        for (_, b, _) in &copies {
            b.unmap();
        }
        if let Some(shading) = &shading {
            let data = shading.readback.slice(..).get_mapped_range().map_err(|e| anyhow!("optical readback failed: {e:?}"))?;
            let values: &[f32] = bytemuck::cast_slice(&data);
            out.optical = shading.ranges.iter().map(|&(start, pixels)| values[start * 4..(start + pixels) * 4].to_vec()).collect();
            drop(data);
            shading.readback.unmap();
        }
        self.readback += t_read.elapsed();
        if let Some(times) = self.pass_times.as_mut() {
            *times += laps;
        }
        Ok(out)
    }

    /// The frame record of every view (and of the spotlight's, last, when `shadow` is set) and
    /// the instance record of every view x draw, written to their uniform buffers.
    fn write_uniforms(&self, sub: &Submission<'_>, shadow: Option<(DMat4, DMat4)>, lighting: &Lighting, draws: &[Draw]) {
        let records = sub.views.len() + shadow.is_some() as usize;
        let mut frames = vec![0u8; FRAME_STRIDE as usize * records.max(1)];
        let mut inst = vec![0u8; UNIFORM_STRIDE as usize * (records * draws.len()).max(1)];
        let lit = sub.readback == Readback::All;
        let all_views = sub.views.iter().map(|v| (v.t_world_camera, v.proj)).chain(shadow);
        for (vi, (t_world_camera, proj)) in all_views.enumerate() {
            let t_camera_world = t_world_camera.inverse();
            let light = t_camera_world.transform_point3(lighting.light_position);
            let axis = t_camera_world.transform_vector3(lighting.light_target - lighting.light_position).normalize_or_zero();
            let outer = lighting.cone_deg.to_radians();
            let up = t_camera_world.transform_vector3(glam::DVec3::Z);
            let (shadow_vp, texel) = match shadow {
                Some((t_world_light, light_proj)) => {
                    // Shadow-map texel size at 1 m from the light: 2 tan(fov / 2) / size.
                    (light_proj * t_world_light.inverse() * t_world_camera, 2.0 * shadow_half_tan(lighting) / self.shadow.size as f64)
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
        self.queue.write_buffer(&self.frames.buffer, 0, &frames);
        self.queue.write_buffer(&self.instances.buffer, 0, &inst);
    }

    /// The spotlight's depth into the shadow map; `record` is the spotlight's frame record and
    /// `light_view_proj` its world-to-clip transform (casters outside the cone are skipped).
    fn encode_shadow_pass(&self, enc: &mut wgpu::CommandEncoder, record: usize, light_view_proj: DMat4, draws: &[Draw]) {
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("shadow map"),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.shadow.view,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipelines.shadow);
        pass.set_bind_group(0, &self.frames.group, &[(record as u64 * FRAME_STRIDE) as u32]);
        // The environment (floor, backdrop) receives shadows but casts none onto anything the
        // camera cares about; leaving it out saves filling the whole map.
        for (di, d) in draws.iter().enumerate().filter(|(_, d)| d.role != DrawRole::Environment) {
            let m = &self.meshes[d.mesh.0];
            if box_outside_clip(&(light_view_proj * d.t_world_model), m.bounds.0, m.bounds.1) {
                continue;
            }
            pass.set_bind_group(1, &self.instances.group, &[((record * draws.len() + di) as u64 * UNIFORM_STRIDE) as u32]);
            pass.set_vertex_buffer(0, m.vertices.slice(..));
            pass.set_index_buffer(m.shadow_indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..m.shadow_index_count, 0, 0..1);
        }
    }

    /// The views pass: colour, z-depth, mask and silhouette of every view into its viewport.
    fn encode_view_pass(&self, enc: &mut wgpu::CommandEncoder, t: &Targets, sub: &Submission<'_>, draws: &[Draw], background: wgpu::Color) {
        let color_att = |view, clear: wgpu::Color| {
            Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations { load: wgpu::LoadOp::Clear(clear), store: wgpu::StoreOp::Store },
            })
        };
        // Depth-view targets are cleared to +inf: "no surface in range".
        let depth_clear = if sub.readback == Readback::Depth { f64::INFINITY } else { 0.0 };
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("views"),
            color_attachments: &[
                color_att(&t.color, background),
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
        pass.set_bind_group(3, &self.shadow.group, &[]);
        if sub.readback == Readback::All {
            self.record_views(&mut pass, sub.views, draws, sub.cull, Some((&self.pipelines.silhouette, &self.pipelines.main)));
        } else {
            pass.set_pipeline(&self.pipelines.main);
            self.record_views(&mut pass, sub.views, draws, sub.cull, None);
        }
    }

    /// The anti-aliased colour, resolved over the single-sample colour of the views pass.
    #[allow(clippy::too_many_arguments)] // one pass's explicit resources, as wgpu's examples pass them
    fn encode_msaa_pass(
        &self,
        enc: &mut wgpu::CommandEncoder,
        t: &Targets,
        (ms_color, ms_zbuf): &(wgpu::TextureView, wgpu::TextureView),
        pipeline: &wgpu::RenderPipeline,
        views: &[ViewSpec],
        draws: &[Draw],
        background: wgpu::Color,
    ) {
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("colour (multisampled)"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: ms_color,
                depth_slice: None,
                resolve_target: Some(&t.color),
                ops: wgpu::Operations { load: wgpu::LoadOp::Clear(background), store: wgpu::StoreOp::Discard },
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
        pass.set_bind_group(3, &self.shadow.group, &[]);
        self.record_views(&mut pass, views, draws, None, None);
    }
}

/// Copies the targets `readback` asks for into their readback buffers; returns (texture, buffer,
/// bytes per pixel) of each copy.
fn copy_targets<'t>(
    enc: &mut wgpu::CommandEncoder,
    t: &'t Targets,
    readback: Readback,
    w: u32,
    h: u32,
) -> Vec<(&'t wgpu::Texture, &'t wgpu::Buffer, u32)> {
    let rb = &t.readback;
    let copies = match readback {
        Readback::Depth => vec![(&t.depth_tex, &rb.depth, 4)],
        Readback::Mask => vec![(&t.mask_tex, &rb.mask, 1)],
        Readback::All => {
            vec![
                (&t.color_tex, &rb.color, 4),
                (&t.depth_tex, &rb.depth, 4),
                (&t.mask_tex, &rb.mask, 1),
                (&t.silhouette_tex, &rb.silhouette, 1),
            ]
        }
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
    copies
}

/// The rows of a mapped readback buffer without their 256-byte padding.
fn read_unpadded(buf: &wgpu::Buffer, row_bytes: u32, rows: u32) -> Result<Vec<u8>> {
    let data = buf.slice(..).get_mapped_range().map_err(|e| anyhow!("readback failed: {e:?}"))?;
    let row = row_bytes as usize;
    let padded = padded_row(row_bytes) as usize;
    let mut out = Vec::with_capacity(row * rows as usize);
    for r in 0..rows as usize {
        out.extend_from_slice(&data[r * padded..r * padded + row]);
    }
    Ok(out)
}

/// tan of the half field of view of the shadow map: the cone with a margin for the PCF kernel.
pub(super) fn shadow_half_tan(l: &Lighting) -> f64 {
    (l.cone_deg.clamp(1.0, 80.0) * 1.05).to_radians().tan()
}

/// The spotlight as a camera (OpenCV frame looking along the spot's axis) and its projection.
pub(super) fn light_view(l: &Lighting) -> (DMat4, DMat4) {
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

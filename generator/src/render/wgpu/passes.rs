//! The render passes: the shadow map, then every view of a submission drawn into its viewport,
//! and the spotlight's view for the shadow map.

use super::*;

impl WgpuRenderer {
    /// Records `draws` into each of `views` (its viewport and frame record) in an open pass whose
    /// shadow group is set; with `cull`, only the mesh clusters inside each view. With
    /// `pipelines` = (silhouette, rest), the target object's draws (mask id 1) go first with the
    /// pipeline that also writes the silhouette target: nothing is in the z-buffer yet, so the
    /// first of its fragments at every pixel it covers passes the depth test, and the silhouette
    /// is its coverage with nothing in front (what `render_mask` of it alone gives). Without, the
    /// pass's pipeline is already set.
    pub(super) fn record_views(
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
    pub(super) fn draw_views(
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

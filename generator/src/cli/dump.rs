//! `vtgen dump`: one sample as NumPy `.npy` files, for quick looks and cross-language checks.

use std::path::Path;

use anyhow::{Context, Result, bail};
use vt_dataset::{DatasetReader, ShardReader};

/// Writes an array as `.npy` (format 1.0). `descr` is the NumPy dtype string, e.g. `<f4`.
pub fn write_npy(path: &Path, descr: &str, shape: &[usize], data: &[u8]) -> Result<()> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape = if dims.len() == 1 { format!("({},)", dims[0]) } else { format!("({})", dims.join(", ")) };
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    // Magic (6) + version (2) + length (2) + header + '\n' is padded to a multiple of 64.
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat(unpadded.next_multiple_of(64) - unpadded));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + data.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out.extend_from_slice(data);
    std::fs::write(path, out).with_context(|| format!("cannot write {}", path.display()))
}

/// Writes a float image as a one-channel OpenEXR file (channel `Z`, 32-bit float, lossless ZIP),
/// for tools that expect depth as EXR (Blender, Nuke, OpenCV).
pub fn write_exr_depth(path: &Path, width: u32, height: u32, depth: &[f32]) -> Result<()> {
    use exr::prelude::*;
    anyhow::ensure!(depth.len() == (width * height) as usize, "depth has {} values for {width}x{height}", depth.len());
    let channel = AnyChannel::new("Z", FlatSamples::F32(depth.to_vec()));
    let mut channels = SmallVec::new();
    channels.push(channel);
    let layer = Layer::new(
        (width as usize, height as usize),
        LayerAttributes::named("depth"),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(channels),
    );
    Image::from_layer(layer).write().to_file(path).with_context(|| format!("cannot write {}", path.display()))
}

/// Reads the `Z` channel written by [`write_exr_depth`]: (width, height, values).
pub fn read_exr_depth(path: &Path) -> Result<(u32, u32, Vec<f32>)> {
    use exr::prelude::*;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .with_context(|| format!("cannot read {}", path.display()))?;
    let layer = image.layer_data;
    let z = layer.channel_data.list.iter().find(|c| c.name.eq("Z")).with_context(|| format!("{} has no Z channel", path.display()))?;
    Ok((layer.size.width() as u32, layer.size.height() as u32, z.sample_data.values_as_f32().collect()))
}

pub fn dump(dataset: &Path, split: &str, index: u64, out: &Path, exr: bool) -> Result<()> {
    let ds = DatasetReader::open(dataset)?;
    let Some(sm) = ds.manifest().splits.get(split) else {
        bail!("dataset {} has no split '{split}' (use train or test)", dataset.display())
    };
    let entry = sm
        .shards
        .iter()
        .find(|s| (s.first_sample..s.first_sample + s.samples).contains(&index))
        .with_context(|| format!("{split} has {} samples; index {index} is out of range", sm.samples))?;
    if entry.sha256.is_none() {
        bail!("shard {} holding sample {index} has not been generated", entry.file);
    }
    let s = ShardReader::open(&dataset.join(&entry.file))?.read(index)?;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let (h, w) = (s.height as usize, s.width as usize);
    write_npy(&out.join("rgb.npy"), "|u1", &[h, w, 3], &s.rgb)?;
    write_npy(&out.join("depth.npy"), "<f4", &[h, w], bytemuck::cast_slice(&s.depth))?;
    if exr {
        write_exr_depth(&out.join("depth.exr"), s.width, s.height, &s.depth)?;
    }
    if let Some(noisy) = &s.depth_noisy {
        write_npy(&out.join("depth_noisy.npy"), "<f4", &[h, w], bytemuck::cast_slice(noisy))?;
        if exr {
            write_exr_depth(&out.join("depth_noisy.exr"), s.width, s.height, noisy)?;
        }
    }
    write_npy(&out.join("mask.npy"), "|u1", &[h, w], &s.mask)?;
    write_npy(&out.join("K.npy"), "<f8", &[3, 3], bytemuck::cast_slice(&s.k))?;
    // Row-major 4x4 of T_camera_object (glam is column-major).
    let m = s.t_camera_object.matrix().transpose().to_cols_array();
    write_npy(&out.join("T_camera_object.npy"), "<f8", &[4, 4], bytemuck::cast_slice(&m))?;
    // Optical tactile images: as arrays, and as PNGs to look at.
    for o in s.tactile.iter().flat_map(|t| &t.optical) {
        let (h, w) = (o.height as usize, o.width as usize);
        for (what, rgb) in [("image", &o.image), ("reference", &o.reference)] {
            let stem = format!("tactile_{}_{what}", o.pad);
            write_npy(&out.join(format!("{stem}.npy")), "|u1", &[h, w, 3], rgb)?;
            let png = out.join(format!("{stem}.png"));
            image::RgbImage::from_raw(o.width, o.height, rgb.clone())
                .context("optical image size")?
                .save(&png)
                .with_context(|| format!("cannot write {}", png.display()))?;
        }
    }
    // Force fields: per pad (R, R, 4) float32, the channels pressure (Pa), shear x, shear y (Pa),
    // slip (0 or 1); rows along the pad's y as its depth image.
    for f in s.tactile.iter().flat_map(|t| &t.forces) {
        let r = f.resolution as usize;
        let values: Vec<f32> = f.cells.iter().flat_map(|c| [c.pressure, c.shear[0], c.shear[1], c.slip as u8 as f32]).collect();
        write_npy(&out.join(format!("tactile_{}_force.npy", f.pad)), "<f4", &[r, r, 4], bytemuck::cast_slice(&values))?;
    }
    // Marker flow: per optical pad with markers (N, 4) float32, x, y (where each marker is) and
    // rest x, rest y (m, pad frame), in the rest grid's order.
    for f in s.tactile.iter().flat_map(|t| &t.marker_flow) {
        let values: Vec<f32> = f.markers.iter().flat_map(|(rest, moved)| [moved[0], moved[1], rest[0], rest[1]]).collect();
        write_npy(&out.join(format!("tactile_{}_markers.npy", f.pad)), "<f4", &[f.markers.len(), 4], bytemuck::cast_slice(&values))?;
    }
    std::fs::write(out.join("info.json"), serde_json::to_string_pretty(&s.info.to_value())? + "\n")?;
    Ok(())
}

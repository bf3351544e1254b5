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

pub fn dump(dataset: &Path, split: &str, index: u64, out: &Path) -> Result<()> {
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
    write_npy(&out.join("mask.npy"), "|u1", &[h, w], &s.mask)?;
    write_npy(&out.join("K.npy"), "<f8", &[3, 3], bytemuck::cast_slice(&s.k))?;
    // Row-major 4x4 of T_camera_object (glam is column-major).
    let m = s.t_camera_object.matrix().transpose().to_cols_array();
    write_npy(&out.join("T_camera_object.npy"), "<f8", &[4, 4], bytemuck::cast_slice(&m))?;
    std::fs::write(out.join("info.json"), serde_json::to_string_pretty(&s.info)? + "\n")?;
    Ok(())
}

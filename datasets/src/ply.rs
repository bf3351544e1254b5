//! The PLY files of `models/`: binary little-endian, float x y z nx ny nz, triangle faces.

use std::io::{BufRead, BufReader, Read, Write};
use std::path::Path;

use anyhow::{Context, Result, bail};

#[derive(Debug, Clone, PartialEq)]
pub struct PlyMesh {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

/// The length unit of a PLY's coordinates, written in its header comment: metres in a dataset's
/// `models/`, millimetres in a BOP export (as BOP wants).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LengthUnit {
    Metres,
    Millimetres,
}

pub fn write_ply(path: &Path, positions: &[[f32; 3]], normals: &[[f32; 3]], indices: &[u32], unit: LengthUnit) -> Result<()> {
    let unit = match unit {
        LengthUnit::Metres => "metres",
        LengthUnit::Millimetres => "millimetres",
    };
    let mut out = Vec::with_capacity(positions.len() * 24 + indices.len() * 5 + 256);
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\ncomment vtgen model frame, {unit}\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        positions.len(),
        indices.len() / 3,
    )?;
    for (p, n) in positions.iter().zip(normals) {
        for v in p.iter().chain(n) {
            out.extend(v.to_le_bytes());
        }
    }
    for t in indices.chunks_exact(3) {
        out.push(3);
        for &i in t {
            out.extend((i as i32).to_le_bytes());
        }
    }
    crate::write_atomic(path, &out)
}

/// Reads the PLY files this crate writes (and any binary little-endian PLY with float xyz[+normals]
/// vertices and `list uchar int` triangle faces).
pub fn read_ply(path: &Path) -> Result<PlyMesh> {
    let ctx = || format!("model {}", path.display());
    let file = std::fs::File::open(path).with_context(ctx)?;
    let file_len = file.metadata().with_context(ctx)?.len();
    let mut r = BufReader::new(file);
    let mut props: Vec<String> = Vec::new();
    let (mut nv, mut nf) = (0usize, 0usize);
    let mut in_vertex = false;
    let mut header_len = 0u64;
    loop {
        let mut line = String::new();
        let n = r.read_line(&mut line).with_context(ctx)?;
        if n == 0 {
            bail!("{}: header ends early", ctx());
        }
        header_len += n as u64;
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.as_slice() {
            ["format", f, ..] if *f != "binary_little_endian" => {
                bail!("{}: format {f} is not supported", ctx())
            }
            ["element", "vertex", n] => {
                nv = n.parse().with_context(ctx)?;
                in_vertex = true;
            }
            ["element", "face", n] => {
                nf = n.parse().with_context(ctx)?;
                in_vertex = false;
            }
            ["property", "float", name] if in_vertex => props.push(name.to_string()),
            ["property", t, ..] if in_vertex => {
                bail!("{}: vertex property type {t} is not supported", ctx())
            }
            ["end_header"] => break,
            _ => {}
        }
    }
    let pos = |n: &str| props.iter().position(|p| p == n);
    let (Some(x), Some(y), Some(z)) = (pos("x"), pos("y"), pos("z")) else { bail!("{}: vertices lack x y z", ctx()) };
    let normal_ix = (pos("nx"), pos("ny"), pos("nz"));
    // The counts come from the header: they must fit in the file before anything is allocated
    // for them (a damaged count once asked for 48 GB; found by `tests/fuzz`).
    let body = (nv as u128) * (props.len() as u128) * 4 + (nf as u128) * 13;
    if body > (file_len - header_len.min(file_len)) as u128 {
        bail!("{}: the header announces {nv} vertices and {nf} faces, more than the file's {file_len} bytes hold", ctx());
    }
    let mut rec = vec![0u8; props.len() * 4];
    let mut mesh = PlyMesh { positions: Vec::with_capacity(nv), normals: Vec::new(), triangles: Vec::with_capacity(nf) };
    for _ in 0..nv {
        r.read_exact(&mut rec).with_context(ctx)?;
        let f = |i: usize| f32::from_le_bytes([rec[4 * i], rec[4 * i + 1], rec[4 * i + 2], rec[4 * i + 3]]);
        mesh.positions.push([f(x), f(y), f(z)]);
        if let (Some(a), Some(b), Some(c)) = normal_ix {
            mesh.normals.push([f(a), f(b), f(c)]);
        }
    }
    let mut tri = [0u8; 13];
    for _ in 0..nf {
        r.read_exact(&mut tri).with_context(ctx)?;
        if tri[0] != 3 {
            bail!("{}: only triangle faces are supported", ctx());
        }
        let i = |k: usize| i32::from_le_bytes([tri[1 + 4 * k], tri[2 + 4 * k], tri[3 + 4 * k], tri[4 + 4 * k]]) as u32;
        let t = [i(0), i(1), i(2)];
        if t.iter().any(|&v| v as usize >= nv) {
            bail!("{}: a face refers to a missing vertex", ctx());
        }
        mesh.triangles.push(t);
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ply_round_trip() {
        let p = std::env::temp_dir().join(format!("vt-ply-{}.ply", std::process::id()));
        let pos = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.5]];
        let nrm = vec![[0.0, 0.0, 1.0]; 3];
        write_ply(&p, &pos, &nrm, &[0, 1, 2], LengthUnit::Metres).unwrap();
        let m = read_ply(&p).unwrap();
        assert_eq!(m.positions, pos);
        assert_eq!(m.normals, nrm);
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
        // The header says the unit the values are in (BOP exports are in millimetres).
        write_ply(&p, &pos, &nrm, &[0, 1, 2], LengthUnit::Millimetres).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert!(bytes.starts_with(b"ply\nformat binary_little_endian 1.0\ncomment vtgen model frame, millimetres\n"));
        assert_eq!(read_ply(&p).unwrap(), m);
        std::fs::remove_file(&p).ok();
    }
}

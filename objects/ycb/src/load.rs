//! Mesh loading: Wavefront OBJ + MTL (the YCB download layout) and glTF 2.0 (.gltf/.glb).
//! Every loader returns the mesh in the model frame (bounding-box centre at the origin).

use std::path::{Path, PathBuf};

use glam::{Mat3, Mat4, Vec3};

use crate::mesh::{Texture, TexturedMesh, linear_to_srgb8};

/// A mesh that could not be loaded; always names the offending file.
#[derive(Debug, thiserror::Error)]
#[error("mesh {path}: {message}")]
pub struct MeshError {
    pub path: PathBuf,
    pub message: String,
}

/// The colour of a mesh whose file names neither a texture nor a base colour.
const UNTEXTURED_GREY: [u8; 3] = [180, 180, 180];

fn err(path: &Path, message: impl Into<String>) -> MeshError {
    MeshError { path: path.to_path_buf(), message: message.into() }
}

/// Finds an object's mesh in a YCB directory laid out as the official download
/// (`<dir>/<id>/google_16k/textured.obj`) or flattened (`<dir>/<id>/textured.obj`).
/// Returns the paths that were tried when none exists.
pub fn find_ycb_mesh(ycb_dir: &Path, id: &str) -> Result<PathBuf, Vec<PathBuf>> {
    let candidates = [
        ycb_dir.join(id).join("google_16k").join("textured.obj"),
        ycb_dir.join(id).join("textured.obj"),
        ycb_dir.join(id).join("google_16k").join("textured.glb"),
        ycb_dir.join(id).join("textured.glb"),
    ];
    match candidates.iter().find(|p| p.is_file()) {
        Some(p) => Ok(p.clone()),
        None => Err(candidates.to_vec()),
    }
}

/// Loads an OBJ (with its MTL and base-colour texture) or a glTF/GLB file, and moves it into the
/// model frame.
pub fn load_mesh(path: &Path) -> Result<TexturedMesh, MeshError> {
    if !path.is_file() {
        return Err(err(path, "file not found"));
    }
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let mut mesh = match ext.as_str() {
        "obj" => load_obj(path)?,
        "gltf" | "glb" => load_gltf(path)?,
        other => {
            return Err(err(path, format!("unsupported mesh format '.{other}' (use .obj, .gltf or .glb)")));
        }
    };
    if mesh.indices.is_empty() {
        return Err(err(path, "contains no triangles"));
    }
    let n = mesh.positions.len() as u32;
    if mesh.indices.iter().any(|&i| i >= n) {
        return Err(err(path, "a face refers to a vertex that does not exist"));
    }
    if mesh.positions.iter().flatten().any(|c| !c.is_finite()) {
        return Err(err(path, "contains non-finite vertex coordinates"));
    }
    if mesh.normals.len() != mesh.positions.len() {
        mesh.compute_normals();
    }
    if mesh.uvs.len() != mesh.positions.len() {
        mesh.uvs = vec![[0.0, 0.0]; mesh.positions.len()];
    }
    mesh.center_on_aabb();
    Ok(mesh)
}

fn load_texture(path: &Path) -> Result<Texture, MeshError> {
    let img = image::open(path).map_err(|e| err(path, format!("texture cannot be read: {e}")))?;
    let rgba = img.to_rgba8();
    Ok(Texture { width: rgba.width(), height: rgba.height(), rgba: rgba.into_raw() })
}

/// `tobj::load_obj`, except that an MTL file with a colour line of fewer than three numbers
/// (`Kd 0.5`), on which tobj 4 panics, is refused as tobj refuses other malformed MTL files (the
/// materials come back as an error; found by `tests/fuzz`).
pub fn load_obj_file(path: &Path, opts: &tobj::LoadOptions) -> tobj::LoadResult {
    let file = std::fs::File::open(path).map_err(|_| tobj::LoadError::OpenFileFailed)?;
    let dir = path.parent().unwrap_or(Path::new(""));
    tobj::load_obj_buf(&mut std::io::BufReader::new(file), opts, |mtl| {
        let text = std::fs::read(dir.join(mtl)).map_err(|_| tobj::LoadError::OpenFileFailed)?;
        let short_colour = String::from_utf8_lossy(&text).lines().any(|l| {
            let mut words = l.split_whitespace();
            matches!(words.next(), Some("Ka" | "Kd" | "Ks" | "Ke")) && words.count() < 3
        });
        if short_colour {
            return Err(tobj::LoadError::MaterialParseError);
        }
        tobj::load_mtl_buf(&mut &text[..])
    })
}

fn load_obj(path: &Path) -> Result<TexturedMesh, MeshError> {
    let opts = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let (models, materials) = load_obj_file(path, &opts).map_err(|e| err(path, format!("not a valid OBJ file: {e}")))?;
    let materials = materials.unwrap_or_default();
    let mut mesh = TexturedMesh::empty(Texture::solid(UNTEXTURED_GREY));
    let mut all_have_normals = true;
    let mut texture_set = false;
    for m in &models {
        let base = mesh.positions.len() as u32;
        let tm = &m.mesh;
        let nv = tm.positions.len() / 3;
        mesh.positions.extend(tm.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
        if tm.normals.len() == tm.positions.len() {
            mesh.normals.extend(tm.normals.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
        } else {
            all_have_normals = false;
        }
        if tm.texcoords.len() / 2 == nv {
            // OBJ's v runs bottom-to-top; textures are stored top row first.
            mesh.uvs.extend(tm.texcoords.chunks_exact(2).map(|t| [t[0], 1.0 - t[1]]));
        } else {
            mesh.uvs.extend(std::iter::repeat_n([0.0, 0.0], nv));
        }
        mesh.indices.extend(tm.indices.iter().map(|&i| i + base));
        if !texture_set && let Some(mat) = tm.material_id.and_then(|id| materials.get(id)) {
            if let Some(tex) = &mat.diffuse_texture {
                let tex_path = path.parent().unwrap_or(Path::new(".")).join(tex);
                mesh.texture = load_texture(&tex_path)?;
                texture_set = true;
            } else if let Some(kd) = mat.diffuse {
                mesh.texture = Texture::solid(kd.map(|x| linear_to_srgb8(x as f64)));
            }
        }
    }
    if !all_have_normals {
        mesh.normals.clear();
    }
    Ok(mesh)
}

/// A binary glTF's header states the file's length, which the gltf crate allocates before reading
/// (a damaged header asked for 4 GB; found by `tests/fuzz`): it must be the file's own length.
fn check_glb_header(path: &Path) -> Result<(), MeshError> {
    use std::io::Read;
    let mut header = [0u8; 12];
    let mut f = std::fs::File::open(path).map_err(|e| err(path, format!("cannot open: {e}")))?;
    if f.read_exact(&mut header).is_err() || &header[..4] != b"glTF" {
        return Ok(()); // not binary glTF: the JSON form has no such field (gltf reports the rest)
    }
    let stated = u32::from_le_bytes(header[8..12].try_into().expect("4 bytes")) as u64;
    let actual = f.metadata().map_err(|e| err(path, format!("cannot read: {e}")))?.len();
    if stated != actual {
        return Err(err(
            path,
            format!("not a valid glTF file: its header says {stated} bytes, the file has {actual} (truncated or damaged)"),
        ));
    }
    Ok(())
}

fn load_gltf(path: &Path) -> Result<TexturedMesh, MeshError> {
    check_glb_header(path)?;
    // gltf-json's validation panics on some damaged files (an index it trusts, found by
    // tests/fuzz): a damaged file is an error here, not a crash.
    let (doc, buffers, images) = std::panic::catch_unwind(|| gltf::import(path))
        .map_err(|_| err(path, "not a valid glTF file: its reader failed on it (damaged?)"))?
        .map_err(|e| err(path, format!("not a valid glTF file: {e}")))?;
    let mut mesh = TexturedMesh::empty(Texture::solid(UNTEXTURED_GREY));
    let mut texture_set = false;
    let mut all_have_normals = true;
    let scene = doc.default_scene().or_else(|| doc.scenes().next()).ok_or_else(|| err(path, "has no scene"))?;
    let mut stack: Vec<(gltf::Node, Mat4)> = scene.nodes().map(|n| (n, Mat4::IDENTITY)).collect();
    while let Some((node, parent)) = stack.pop() {
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        for child in node.children() {
            stack.push((child, world));
        }
        let Some(gmesh) = node.mesh() else { continue };
        let normal_mat = Mat3::from_mat4(world).inverse().transpose();
        for prim in gmesh.primitives() {
            if prim.mode() != gltf::mesh::Mode::Triangles {
                continue;
            }
            let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
            let Some(pos) = reader.read_positions() else {
                continue;
            };
            let base = mesh.positions.len() as u32;
            let pos: Vec<[f32; 3]> = pos.map(|p| world.transform_point3(Vec3::from(p)).into()).collect();
            let nv = pos.len();
            mesh.positions.extend(pos);
            match reader.read_normals() {
                Some(ns) => mesh.normals.extend(ns.map(|n| (normal_mat * Vec3::from(n)).normalize_or(Vec3::Z).to_array())),
                None => all_have_normals = false,
            }
            match reader.read_tex_coords(0) {
                Some(uv) => mesh.uvs.extend(uv.into_f32()),
                None => mesh.uvs.extend(std::iter::repeat_n([0.0, 0.0], nv)),
            }
            match reader.read_indices() {
                Some(ix) => mesh.indices.extend(ix.into_u32().map(|i| i + base)),
                None => mesh.indices.extend(base..base + nv as u32),
            }
            if !texture_set {
                let pbr = prim.material().pbr_metallic_roughness();
                if let Some(info) = pbr.base_color_texture() {
                    let img = images
                        .get(info.texture().source().index())
                        .ok_or_else(|| err(path, "refers to a texture image that does not exist"))?;
                    mesh.texture = gltf_image_to_texture(img).ok_or_else(|| err(path, "has a texture in an unsupported pixel format"))?;
                    texture_set = true;
                } else {
                    let f = pbr.base_color_factor();
                    mesh.texture = Texture::solid([f[0], f[1], f[2]].map(|x| linear_to_srgb8(x as f64)));
                }
            }
        }
    }
    if !all_have_normals {
        mesh.normals.clear();
    }
    Ok(mesh)
}

fn gltf_image_to_texture(img: &gltf::image::Data) -> Option<Texture> {
    use gltf::image::Format;
    let px = (img.width * img.height) as usize;
    let rgba: Vec<u8> = match img.format {
        Format::R8G8B8A8 => img.pixels.clone(),
        Format::R8G8B8 => img.pixels.chunks_exact(3).flat_map(|c| [c[0], c[1], c[2], 255]).collect(),
        Format::R8 => img.pixels.iter().flat_map(|&g| [g, g, g, 255]).collect(),
        Format::R8G8 => img.pixels.chunks_exact(2).flat_map(|c| [c[0], c[0], c[0], c[1]]).collect(),
        _ => return None,
    };
    (rgba.len() == px * 4).then_some(Texture { width: img.width, height: img.height, rgba })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmpdir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("vt-objects-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn obj_is_recentred_and_errors_name_the_path() {
        let d = tmpdir("obj");
        let obj = d.join("tri.obj");
        std::fs::write(&obj, "v 1 1 1\nv 3 1 1\nv 1 5 1\nv 1 1 3\nf 1 2 3\nf 1 3 4\n").unwrap();
        let m = load_mesh(&obj).unwrap();
        let (lo, hi) = m.aabb();
        assert!((lo + hi).length() < 1e-6, "bounding box centred at the origin");
        assert_eq!(m.normals.len(), m.positions.len());

        let missing = d.join("nope.obj");
        let e = load_mesh(&missing).unwrap_err().to_string();
        assert!(e.contains("nope.obj") && e.contains("not found"), "{e}");

        let bad = d.join("bad.obj");
        std::fs::write(&bad, "v 0 0 0\nf 1 2 3\n").unwrap();
        let e = load_mesh(&bad).unwrap_err().to_string();
        assert!(e.contains("bad.obj"), "{e}");

        let mtl = d.join("tex.mtl");
        std::fs::write(&mtl, "newmtl m\nmap_Kd missing.png\n").unwrap();
        let texobj = d.join("tex.obj");
        std::fs::write(&texobj, "mtllib tex.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nusemtl m\nf 1/1 2/1 3/1\n").unwrap();
        let e = load_mesh(&texobj).unwrap_err().to_string();
        assert!(e.contains("missing.png"), "{e}");
    }

    #[test]
    fn gltf_applies_node_transforms_and_base_colour() {
        let d = tmpdir("gltf");
        let mut bin = Vec::new();
        for v in [[0.0f32, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.2, 0.0]] {
            for c in v {
                bin.extend(c.to_le_bytes());
            }
        }
        for i in [0u16, 1, 2, 0] {
            bin.extend(i.to_le_bytes()); // 3 indices + padding
        }
        std::fs::write(d.join("tri.bin"), &bin).unwrap();
        let json = r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],
            "nodes":[{"mesh":0,"translation":[1,2,3],"scale":[2,2,2]}],
            "meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1,"material":0}]}],
            "materials":[{"pbrMetallicRoughness":{"baseColorFactor":[1,0,0,1]}}],
            "buffers":[{"uri":"tri.bin","byteLength":44}],
            "bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":6}],
            "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[0.1,0.2,0]},
                         {"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}]}"#;
        let path = d.join("tri.gltf");
        std::fs::write(&path, json).unwrap();
        let m = load_mesh(&path).unwrap();
        assert_eq!(m.indices, vec![0, 1, 2]);
        // Scaled by 2 by the node, then centred.
        let e = m.extents();
        assert!((e.x - 0.2).abs() < 1e-6 && (e.y - 0.4).abs() < 1e-6, "{e}");
        assert_eq!(m.texture.rgba, vec![255, 0, 0, 255]);
        assert_eq!(m.normals.len(), 3);

        std::fs::write(&path, "{ not json").unwrap();
        let err = load_mesh(&path).unwrap_err().to_string();
        assert!(err.contains("tri.gltf") && err.contains("glTF"), "{err}");
    }
}

//! A URDF's mesh geometry: `<mesh filename scale>` resolved to a file (`package://NAME/...`,
//! `file://...`, or a path relative to the URDF) and read into triangles in the link's shape
//! frame, in metres. Formats: STL (binary and ASCII), OBJ with its MTL colours, COLLADA/DAE (its
//! `<unit>` and `<up_axis>` applied, as ROS tools draw them) and glTF/GLB (node transforms applied).

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DMat4, DVec3};

/// The grey a mesh is drawn in when neither the URDF nor the mesh file gives a colour.
pub const DEFAULT_MESH_RGB: [f64; 3] = [0.6, 0.6, 0.6];

/// A triangle mesh read from a file, scaled, in its shape frame (the URDF `<origin>` places it).
#[derive(Debug, Clone, PartialEq)]
pub struct TriangleMesh {
    pub positions: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
    /// Per triangle: the file's material colour (linear RGB), or None where it gives none.
    pub colours: Vec<Option<[f64; 3]>>,
    /// The file it was read from (a dataset's sources name it by content).
    pub file: PathBuf,
    /// `positions` with their duplicates merged (STL repeats each vertex per facet): the points a
    /// collision mesh's convex hull is taken of, found once.
    points: Vec<DVec3>,
}

impl TriangleMesh {
    pub fn new(positions: Vec<DVec3>, triangles: Vec<[u32; 3]>, colours: Vec<Option<[f64; 3]>>, file: PathBuf) -> Self {
        let mut seen = std::collections::HashSet::new();
        let points = positions.iter().copied().filter(|p| seen.insert(p.to_array().map(f64::to_bits))).collect();
        TriangleMesh { positions, triangles, colours, file, points }
    }

    /// The distinct vertices, in the order first met.
    pub fn distinct_points(&self) -> &[DVec3] {
        &self.points
    }
}

/// Where mesh file names are looked up: the URDF's own folder (relative names) and package roots
/// (`package://NAME/...`): given folders first, then the folders above the URDF.
#[derive(Debug, Clone, Default)]
pub struct MeshPaths {
    /// The folder of the URDF file (None: a URDF given as text, whose meshes cannot be found).
    pub urdf_dir: Option<PathBuf>,
    /// Folders that are a package's root (named after it) or hold package roots.
    pub package_dirs: Vec<PathBuf>,
}

impl MeshPaths {
    pub fn beside(urdf: &Path) -> Self {
        MeshPaths { urdf_dir: Some(urdf.parent().unwrap_or(Path::new(".")).to_path_buf()), package_dirs: Vec::new() }
    }

    /// The file a URDF mesh `filename` names; the error says where it looked.
    pub fn resolve(&self, uri: &str) -> Result<PathBuf, String> {
        if let Some(rest) = uri.strip_prefix("package://") {
            let (package, inner) = rest.split_once('/').unwrap_or((rest, ""));
            let mut roots: Vec<PathBuf> = Vec::new();
            for dir in &self.package_dirs {
                roots.push(if dir.file_name().is_some_and(|n| n == package) { dir.clone() } else { dir.join(package) });
            }
            if let Some(dir) = &self.urdf_dir {
                for a in dir.ancestors() {
                    if a.file_name().is_some_and(|n| n == package) {
                        roots.push(a.to_path_buf());
                    }
                    roots.push(a.join(package));
                }
            }
            return match roots.iter().map(|r| r.join(inner)).find(|p| p.is_file()) {
                Some(p) => Ok(canonical(p)),
                None if roots.is_empty() => Err("file not found: no folder to look for package roots in".into()),
                None => Err(format!(
                    "file not found: no package root '{package}' holding it above the URDF's folder or in the given package folders \
                     (robot.package_dirs / the description's package_dirs)"
                )),
            };
        }
        let path = PathBuf::from(uri.strip_prefix("file://").unwrap_or(uri));
        let path = match (&self.urdf_dir, path.is_absolute()) {
            (_, true) => path,
            (Some(dir), false) => dir.join(path),
            (None, false) => return Err("a relative mesh path needs the URDF's folder (the URDF was given as text)".into()),
        };
        if path.is_file() { Ok(canonical(path)) } else { Err(format!("file not found: {}", path.display())) }
    }
}

/// One name per file (`a/urdf/../meshes/m.stl` and `a/meshes/m.stl` are one mesh, read once).
fn canonical(path: PathBuf) -> PathBuf {
    std::fs::canonicalize(&path).unwrap_or(path)
}

/// Meshes read once per file and scale while a URDF is parsed (one mesh can serve several links).
#[derive(Default)]
pub struct MeshCache {
    meshes: HashMap<(PathBuf, [u64; 3]), Arc<TriangleMesh>>,
    files: Vec<PathBuf>,
}

impl MeshCache {
    /// The files read, each once, in the order first read.
    pub fn files(&self) -> Vec<PathBuf> {
        self.files.clone()
    }

    pub fn read(&mut self, path: &Path, scale: DVec3) -> Result<Arc<TriangleMesh>, String> {
        let key = (path.to_path_buf(), scale.to_array().map(f64::to_bits));
        if let Some(m) = self.meshes.get(&key) {
            return Ok(m.clone());
        }
        let mesh = Arc::new(read_mesh(path, scale)?);
        if !self.files.iter().any(|f| f == path) {
            self.files.push(path.to_path_buf());
        }
        self.meshes.insert(key, mesh.clone());
        Ok(mesh)
    }
}

/// Reads a mesh file (by its extension) and scales it. Errors say what is wrong, without the
/// file's name (the caller names it).
pub fn read_mesh(path: &Path, scale: DVec3) -> Result<TriangleMesh, String> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    let (mut positions, triangles, colours) = match ext.as_str() {
        "stl" | "obj" | "dae" => read_with_mesh_loader(path, &ext)?,
        "gltf" | "glb" => read_gltf(path)?,
        _ => return Err(format!("unsupported mesh format '.{ext}' (STL, OBJ, DAE, glTF or GLB)")),
    };
    if triangles.is_empty() {
        return Err("contains no triangles".into());
    }
    if positions.iter().any(|p| !p.is_finite()) {
        return Err("contains non-finite vertex coordinates".into());
    }
    for p in &mut positions {
        *p *= scale;
    }
    Ok(TriangleMesh::new(positions, triangles, colours, path.to_path_buf()))
}

type Triangles = (Vec<DVec3>, Vec<[u32; 3]>, Vec<Option<[f64; 3]>>);

fn read_with_mesh_loader(path: &Path, ext: &str) -> Result<Triangles, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("cannot read: {e}"))?;
    let loader = mesh_loader::Loader::default();
    // mesh-loader's COLLADA reader panics on some damaged files (an index it trusts, found by
    // tests/fuzz): a damaged file is an error here, not a crash.
    let load = std::panic::AssertUnwindSafe(|| match ext {
        "stl" => loader.load_stl_from_slice(&bytes, path),
        // The MTL it names is read from beside `path`.
        "obj" => loader.load_obj_from_slice(&bytes, path),
        _ => loader.load_collada_from_slice(&bytes, path),
    });
    let scene = std::panic::catch_unwind(load)
        .map_err(|_| format!("not a readable {} file: its reader failed on it (damaged?)", ext.to_ascii_uppercase()))?
        .map_err(|e| format!("not a readable {} file: {e}", ext.to_ascii_uppercase()))?;
    // COLLADA's up axis (mesh-loader applies the unit): ROS draws Y_UP and X_UP files turned to Z up.
    let up = if ext == "dae" { collada_up_axis(&bytes) } else { UpAxis::Z };
    let (mut positions, mut triangles, mut colours) = (Vec::new(), Vec::new(), Vec::new());
    for (k, mesh) in scene.meshes.iter().enumerate() {
        let colour = scene.materials.get(k).and_then(|m| m.color.diffuse).map(|c| [c[0], c[1], c[2]].map(f64::from));
        let base = positions.len() as u32;
        positions.extend(mesh.vertices.iter().map(|v| up.to_z_up(DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64))));
        for f in &mesh.faces {
            if f.iter().any(|&i| i as usize >= mesh.vertices.len()) {
                return Err("a face refers to a vertex that does not exist".into());
            }
            triangles.push(f.map(|i| i + base));
            colours.push(colour);
        }
    }
    Ok((positions, triangles, colours))
}

#[derive(Clone, Copy)]
enum UpAxis {
    X,
    Y,
    Z,
}

impl UpAxis {
    fn to_z_up(self, v: DVec3) -> DVec3 {
        match self {
            UpAxis::Z => v,
            // +90° about x: y up becomes z up.
            UpAxis::Y => DVec3::new(v.x, -v.z, v.y),
            // -90° about y: x up becomes z up.
            UpAxis::X => DVec3::new(-v.z, v.y, v.x),
        }
    }
}

/// The `<asset><up_axis>` of a COLLADA file (Y_UP when it gives none, as the standard says).
fn collada_up_axis(bytes: &[u8]) -> UpAxis {
    let text = String::from_utf8_lossy(&bytes[..bytes.len().min(8192)]);
    let axis = text.split_once("<up_axis>").and_then(|(_, rest)| rest.split_once("</up_axis>")).map(|(a, _)| a.trim().to_string());
    match axis.as_deref() {
        Some("Z_UP") => UpAxis::Z,
        Some("X_UP") => UpAxis::X,
        _ => UpAxis::Y,
    }
}

/// A glTF or GLB file's triangles in its scene's frame (every node's transform applied) with each
/// primitive's base colour.
fn read_gltf(path: &Path) -> Result<Triangles, String> {
    // gltf-json's validation panics on some damaged files (found by tests/fuzz): an error here.
    let (doc, buffers, _) = std::panic::catch_unwind(|| gltf::import(path))
        .map_err(|_| "not a readable glTF file: its reader failed on it (damaged?)".to_string())?
        .map_err(|e| format!("not a readable glTF file: {e}"))?;
    let (mut positions, mut triangles, mut colours) = (Vec::new(), Vec::new(), Vec::new());
    let scene = doc.default_scene().or_else(|| doc.scenes().next()).ok_or("has no scene")?;
    let mut stack: Vec<(gltf::Node, DMat4)> = scene.nodes().map(|n| (n, DMat4::IDENTITY)).collect();
    while let Some((node, parent)) = stack.pop() {
        let t = parent * glam::Mat4::from_cols_array_2d(&node.transform().matrix()).as_dmat4();
        if let Some(mesh) = node.mesh() {
            for prim in mesh.primitives() {
                if prim.mode() != gltf::mesh::Mode::Triangles {
                    continue;
                }
                let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
                let Some(pos) = reader.read_positions() else { continue };
                let base = positions.len() as u32;
                positions.extend(pos.map(|p| t.transform_point3(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64))));
                let n = positions.len() as u32 - base;
                let idx: Vec<u32> = match reader.read_indices() {
                    Some(i) => i.into_u32().collect(),
                    None => (0..n).collect(),
                };
                if idx.iter().any(|&i| i >= n) {
                    return Err("a primitive's index refers to a vertex that does not exist".into());
                }
                let c = prim.material().pbr_metallic_roughness().base_color_factor();
                let colour = Some([c[0], c[1], c[2]].map(f64::from));
                for tri in idx.chunks_exact(3) {
                    triangles.push([tri[0] + base, tri[1] + base, tri[2] + base]);
                    colours.push(colour);
                }
            }
        }
        stack.extend(node.children().map(|c| (c, t)));
    }
    Ok((positions, triangles, colours))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(&p, text).unwrap();
        p
    }

    const TETRA_OBJ: &str = "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nusemtl red\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

    #[test]
    fn package_uris_resolve_above_the_urdf_and_in_given_folders() {
        let dir = tempfile::tempdir().unwrap();
        let mesh = write(dir.path(), "my_robot/meshes/a.obj", TETRA_OBJ);
        let urdf_dir = dir.path().join("my_robot/urdf");
        std::fs::create_dir_all(&urdf_dir).unwrap();
        let paths = MeshPaths { urdf_dir: Some(urdf_dir.clone()), package_dirs: vec![] };
        let mesh = mesh.canonicalize().unwrap();
        assert_eq!(paths.resolve("package://my_robot/meshes/a.obj").unwrap(), mesh);
        assert_eq!(paths.resolve("../meshes/a.obj").unwrap(), mesh);
        let err = paths.resolve("package://other/meshes/a.obj").unwrap_err();
        assert!(err.contains("no package root 'other'"), "{err}");
        let given = MeshPaths { urdf_dir: None, package_dirs: vec![dir.path().to_path_buf()] };
        assert_eq!(given.resolve("package://my_robot/meshes/a.obj").unwrap(), mesh);
        assert!(given.resolve("meshes/a.obj").unwrap_err().contains("URDF's folder"));
    }

    #[test]
    fn obj_with_mtl_colours_and_scale() {
        let dir = tempfile::tempdir().unwrap();
        write(dir.path(), "t.mtl", "newmtl red\nKd 0.8 0.1 0.1\n");
        let p = write(dir.path(), "t.obj", TETRA_OBJ);
        let m = read_mesh(&p, DVec3::new(0.001, 0.002, 0.003)).unwrap();
        assert_eq!(m.triangles.len(), 4);
        assert!(m.positions.iter().any(|v| (*v - DVec3::new(0.0, 0.0, 0.003)).length() < 1e-12));
        assert_eq!(m.colours[0].map(|c| (c[0] * 10.0).round()), Some(8.0));
    }

    #[test]
    fn ascii_and_binary_stl() {
        let dir = tempfile::tempdir().unwrap();
        let ascii = "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n";
        let a = read_mesh(&write(dir.path(), "a.stl", ascii), DVec3::ONE).unwrap();
        let mut bin = vec![0u8; 80];
        bin.extend(1u32.to_le_bytes());
        for v in [[0f32, 0., 1.], [0., 0., 0.], [1., 0., 0.], [0., 1., 0.]] {
            for c in v {
                bin.extend(c.to_le_bytes());
            }
        }
        bin.extend([0u8, 0]);
        let p = dir.path().join("b.STL");
        std::fs::write(&p, bin).unwrap();
        let b = read_mesh(&p, DVec3::ONE).unwrap();
        assert_eq!((a.triangles.len(), b.triangles.len()), (1, 1));
        assert_eq!(a.distinct_points().len(), 3);
        assert!(b.positions.contains(&DVec3::new(1.0, 0.0, 0.0)));
    }

    #[test]
    fn collada_unit_and_up_axis_are_applied() {
        let dae = |unit: f64, up: &str| {
            format!(
                r##"<?xml version="1.0"?><COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
<asset><unit meter="{unit}" name="u"/><up_axis>{up}</up_axis></asset>
<library_geometries><geometry id="g"><mesh>
<source id="p"><float_array id="pa" count="9">0 0 0 1 0 0 0 1 0</float_array>
<technique_common><accessor source="#pa" count="3" stride="3"><param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/></accessor></technique_common></source>
<vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
<triangles count="1"><input semantic="VERTEX" source="#v" offset="0"/><p>0 1 2</p></triangles>
</mesh></geometry></library_geometries>
<library_visual_scenes><visual_scene id="s"><node id="n"><instance_geometry url="#g"/></node></visual_scene></library_visual_scenes>
<scene><instance_visual_scene url="#s"/></scene></COLLADA>"##
            )
        };
        let dir = tempfile::tempdir().unwrap();
        let z = read_mesh(&write(dir.path(), "z.dae", &dae(0.001, "Z_UP")), DVec3::ONE).unwrap();
        assert!(z.positions.iter().any(|p| (*p - DVec3::new(0.0, 0.001, 0.0)).length() < 1e-9), "{:?}", z.positions);
        let y = read_mesh(&write(dir.path(), "y.dae", &dae(1.0, "Y_UP")), DVec3::ONE).unwrap();
        assert!(y.positions.iter().any(|p| (*p - DVec3::new(0.0, 0.0, 1.0)).length() < 1e-9), "Y up becomes Z up: {:?}", y.positions);
    }

    #[test]
    fn gltf_with_its_node_transform_and_base_colour() {
        let dir = tempfile::tempdir().unwrap();
        let mut bin: Vec<u8> = [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.]].iter().flatten().flat_map(|c| c.to_le_bytes()).collect();
        bin.extend([0u16, 1, 2].iter().flat_map(|i| i.to_le_bytes()));
        bin.extend([0u8, 0]);
        std::fs::write(dir.path().join("t.bin"), &bin).unwrap();
        let gltf = r#"{"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
          "nodes": [{"mesh": 0, "translation": [0, 0, 2], "scale": [0.5, 0.5, 0.5]}],
          "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
          "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.4, 0.6, 1.0]}}],
          "buffers": [{"uri": "t.bin", "byteLength": 44}],
          "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
          "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
                        {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}]}"#;
        let m = read_mesh(&write(dir.path(), "t.gltf", gltf), DVec3::ONE).unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
        assert!((m.positions[1] - DVec3::new(0.5, 0.0, 2.0)).length() < 1e-6, "{:?}", m.positions);
        assert!((m.colours[0].unwrap()[1] - 0.4).abs() < 1e-6);
    }

    #[test]
    fn bad_files_say_what_is_wrong() {
        let dir = tempfile::tempdir().unwrap();
        assert!(read_mesh(&write(dir.path(), "a.ply", "ply"), DVec3::ONE).unwrap_err().contains("unsupported mesh format '.ply'"));
        assert!(read_mesh(&write(dir.path(), "e.obj", "# nothing\n"), DVec3::ONE).unwrap_err().contains("no triangles"));
        assert!(read_mesh(&write(dir.path(), "x.dae", "not xml"), DVec3::ONE).unwrap_err().contains("DAE"));
    }
}

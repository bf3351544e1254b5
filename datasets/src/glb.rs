//! Binary glTF 2.0 (`.glb`) of a vertex-coloured triangle mesh: how shards carry the object and
//! robot meshes for Foxglove's 3D panel (`foxglove.SceneUpdate` model primitives).
//!
//! Vertices stay in the model frame (z up, FORMAT.md). glTF is y up, so the single node carries
//! the rotation that maps z-up data into a y-up scene (−90° about x); viewers that convert glTF
//! back to z-up (Foxglove rotates every glTF scene +90° about x) show the model in its own frame.

use serde_json::json;

/// A triangle mesh with per-vertex sRGB colours, in metres.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ColoredMesh {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    /// sRGB, alpha linear.
    pub colors: Vec<[u8; 4]>,
    /// Triangles, counter-clockwise seen from outside.
    pub indices: Vec<u32>,
}

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;

/// An 8-bit sRGB channel as linear intensity (the sRGB transfer function).
pub fn srgb_to_linear(c: u8) -> f32 {
    let c = c as f32 / 255.0;
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

/// Encodes `mesh` as a self-contained GLB (one buffer, one mesh, one matte material).
pub fn encode_glb(mesh: &ColoredMesh) -> Vec<u8> {
    assert_eq!(mesh.positions.len(), mesh.normals.len(), "one normal per vertex");
    assert_eq!(mesh.positions.len(), mesh.colors.len(), "one colour per vertex");
    let n = mesh.positions.len();
    let mut bin: Vec<u8> = Vec::with_capacity(n * 32 + mesh.indices.len() * 4);
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in &mesh.positions {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
        bin.extend(p.iter().flat_map(|v| v.to_le_bytes()));
    }
    let normals_at = bin.len();
    bin.extend(mesh.normals.iter().flatten().flat_map(|v| v.to_le_bytes()));
    // glTF vertex colours are linear; 16-bit keeps the dark shades of the scans.
    let colors_at = bin.len();
    for c in &mesh.colors {
        let linear = [srgb_to_linear(c[0]), srgb_to_linear(c[1]), srgb_to_linear(c[2]), c[3] as f32 / 255.0];
        bin.extend(linear.iter().flat_map(|v| ((v * 65535.0).round() as u16).to_le_bytes()));
    }
    let indices_at = bin.len();
    bin.extend(mesh.indices.iter().flat_map(|i| i.to_le_bytes()));
    let indices_len = bin.len() - indices_at;
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    if n == 0 {
        (lo, hi) = ([0.0; 3], [0.0; 3]);
    }
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let doc = json!({
        "asset": {"version": "2.0", "generator": concat!("vtgen ", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "rotation": [-h, 0.0, 0.0, h]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "COLOR_0": 2}, "indices": 3, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.8}}],
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": n * 12, "target": ARRAY_BUFFER},
            {"buffer": 0, "byteOffset": normals_at, "byteLength": n * 12, "target": ARRAY_BUFFER},
            {"buffer": 0, "byteOffset": colors_at, "byteLength": n * 8, "target": ARRAY_BUFFER},
            {"buffer": 0, "byteOffset": indices_at, "byteLength": indices_len, "target": ELEMENT_ARRAY_BUFFER},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": FLOAT, "count": n, "type": "VEC3", "min": lo, "max": hi},
            {"bufferView": 1, "componentType": FLOAT, "count": n, "type": "VEC3"},
            {"bufferView": 2, "componentType": UNSIGNED_SHORT, "normalized": true, "count": n, "type": "VEC4"},
            {"bufferView": 3, "componentType": UNSIGNED_INT, "count": mesh.indices.len(), "type": "SCALAR"},
        ],
    });
    let mut json_bytes = serde_json::to_vec(&doc).expect("a JSON value serialises");
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let total = 12 + 8 + json_bytes.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((json_bytes.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(json_bytes);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(bin);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glb_has_valid_chunks_and_accessors() {
        let mesh = ColoredMesh {
            positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.5]],
            normals: vec![[0.0, 0.0, 1.0]; 3],
            colors: vec![[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255]],
            indices: vec![0, 1, 2],
        };
        let glb = encode_glb(&mesh);
        assert_eq!(&glb[0..4], b"glTF");
        assert_eq!(u32::from_le_bytes(glb[8..12].try_into().unwrap()) as usize, glb.len());
        let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
        assert_eq!(json_len % 4, 0);
        let doc: serde_json::Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
        assert_eq!(doc["accessors"][0]["max"], json!([1.0, 2.0, 0.5]));
        assert_eq!(doc["accessors"][3]["count"], 3);
        let bin_at = 20 + json_len;
        let bin_len = u32::from_le_bytes(glb[bin_at..bin_at + 4].try_into().unwrap()) as usize;
        assert_eq!(&glb[bin_at + 4..bin_at + 8], b"BIN\0");
        assert_eq!(bin_at + 8 + bin_len, glb.len());
        assert_eq!(doc["buffers"][0]["byteLength"], bin_len);
        // The last index sits where the indices' buffer view says.
        let view = &doc["bufferViews"][3];
        let end = bin_at + 8 + view["byteOffset"].as_u64().unwrap() as usize + view["byteLength"].as_u64().unwrap() as usize;
        assert_eq!(u32::from_le_bytes(glb[end - 4..end].try_into().unwrap()), 2);
    }
}

//! The scene around the object and the robot: the floor and the backdrop, the distractors standing
//! on the floor, and meshes as the GLB models shards carry for Foxglove's 3D view.

use vt_dataset::{ColoredMesh, Pose, encode_glb, mask_ids};
use vt_objects::{Texture, TexturedMesh};

use super::SampledScene;
use crate::assets::LoadedObject;
use crate::config::Config;

/// The floor: a 6 m textured quad on z = 0, texture coordinates in metres (the renderer scales
/// them by 1 / tile size).
pub fn floor_mesh() -> TexturedMesh {
    let half = 3.0f32;
    let corners = [[-half, -half], [half, -half], [half, half], [-half, half]];
    TexturedMesh {
        positions: corners.iter().map(|c| [c[0], c[1], 0.0]).collect(),
        normals: vec![[0.0, 0.0, 1.0]; 4],
        uvs: corners.iter().map(|c| [c[0], -c[1]]).collect(),
        indices: vec![0, 1, 2, 0, 2, 3],
        texture: Texture::solid([128, 128, 128]),
    }
}

/// The backdrop: a 6 m × 3 m wall standing on the floor behind the workspace, facing the camera,
/// texture coordinates in metres.
pub fn backdrop_mesh(config: &Config) -> TexturedMesh {
    let cam = glam::DVec3::from_array(config.camera.position);
    let at = glam::DVec3::from_array(config.camera.look_at);
    let forward = ((at - cam) * glam::DVec3::new(1.0, 1.0, 0.0)).normalize_or(glam::DVec3::Y);
    let side = forward.cross(glam::DVec3::Z);
    let base = glam::DVec3::new(at.x, at.y, 0.0) + forward * 1.2;
    let (w, h) = (3.0, 3.0);
    let corners = [(-w, 0.0), (w, 0.0), (w, h), (-w, h)];
    TexturedMesh {
        positions: corners.iter().map(|&(x, z)| (base + side * x + glam::DVec3::Z * z).as_vec3().to_array()).collect(),
        normals: vec![(-forward).as_vec3().to_array(); 4],
        uvs: corners.iter().map(|&(x, z)| [x as f32, -(z as f32)]).collect(),
        indices: vec![0, 1, 2, 0, 2, 3],
        texture: Texture::solid([196, 198, 200]),
    }
}

/// A mesh as a vertex-coloured GLB for the shards' 3D view.
pub fn glb_of(mesh: &TexturedMesh) -> std::sync::Arc<Vec<u8>> {
    let colored = ColoredMesh {
        positions: mesh.positions.clone(),
        normals: mesh.normals.clone(),
        colors: mesh.vertex_colors(),
        indices: mesh.indices.clone(),
    };
    std::sync::Arc::new(encode_glb(&colored))
}

/// A distractor object standing on the floor.
pub struct Distractor {
    pub object: usize,
    pub mask_id: u8,
    pub pose: Pose,
}

/// The randomizer's distractors as objects standing upright on the floor (`mask_ids::DISTRACTORS`
/// in order), leaving out any that would overlap the target's footprint or an earlier distractor.
pub fn place_distractors(objects: &[LoadedObject], scene: &SampledScene, target: usize) -> Vec<Distractor> {
    let radius = |o: usize| {
        let e = objects[o].mesh.extents();
        0.5 * (e.x as f64).hypot(e.y as f64)
    };
    let target_xy = scene.t_world_object.translation().truncate();
    let mut placed: Vec<(Distractor, glam::DVec2, f64)> = Vec::new();
    for d in &scene.appearance.distractors {
        let Some(mask_id) = mask_ids::nth(&mask_ids::DISTRACTORS, placed.len()) else {
            break; // no mask id left
        };
        let object = if d.candidate >= target { d.candidate + 1 } else { d.candidate };
        if object >= objects.len() {
            continue;
        }
        let xy = glam::DVec2::from_array(d.position_xy);
        let r = radius(object);
        if xy.distance(target_xy) < r + radius(target) || placed.iter().any(|(_, p, pr)| xy.distance(*p) < r + pr) {
            continue;
        }
        let z = 0.5 * objects[object].mesh.extents().z as f64;
        let pose = Pose::from_rt(glam::DQuat::from_rotation_z(d.yaw), xy.extend(z));
        placed.push((Distractor { object, mask_id, pose }, xy, r));
    }
    placed.into_iter().map(|p| p.0).collect()
}

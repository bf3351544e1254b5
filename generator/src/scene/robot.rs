//! The robot in the scene: joint values turned into world poses of its links, pads and frames,
//! and the arm and hand links as renderable meshes with their mask ids (FORMAT.md).

use glam::{DAffine3, Vec3};
use vt_dataset::{Pose, frames, mask_ids};
use vt_objects::{Texture, TexturedMesh};
use vt_robot::{Geometry, Robot, RobotModel};

use super::drawable::{RawMesh, TRIANGLES_PER_LINK, drawable_link};
use super::pose_of;

/// Mask id of a robot link (`vt_dataset::mask_ids`): the base and the arm link moved by arm joint
/// k, the hand's body (the links fixed between flange and grasp frame), the hand link moved by
/// hand joint k (then by each mimic joint), a link fixed below a hand link with that link's id.
/// None: not drawn (e.g. the flange and links fixed to arm links).
pub fn mask_id(robot: &Robot, link: usize) -> Option<u8> {
    let model = &robot.model;
    if link == robot.base {
        return Some(*mask_ids::ARM_LINKS.start());
    }
    if link != robot.flange && model.is_below(link, robot.flange) && !moves_below(model, robot.flange, link) {
        return Some(mask_ids::PALM);
    }
    let j = model.links[link].parent_joint?;
    if let Some(k) = robot.arm_joints.iter().position(|&a| a == j) {
        return mask_ids::arm_link(k);
    }
    if let Some(k) = robot.hand.iter().position(|h| h.joint == j) {
        return mask_ids::nth(&mask_ids::HAND_LINKS, k);
    }
    if let Some(k) = robot.followers.iter().position(|&f| f == j) {
        return mask_ids::nth(&mask_ids::HAND_LINKS, robot.hand.len() + k);
    }
    let joint = &model.joints[j];
    if !joint.moves() && model.is_below(link, robot.hand_root) { mask_id(robot, joint.parent) } else { None }
}

/// Whether a moving joint lies between `top` and `link` (below it).
fn moves_below(model: &RobotModel, top: usize, link: usize) -> bool {
    let mut l = link;
    while l != top {
        let Some(j) = model.links[l].parent_joint else { return false };
        if model.joints[j].moves() {
            return true;
        }
        l = model.joints[j].parent;
    }
    false
}

/// A link's visual shapes as one mesh (its colours in a small texture, one texel per shape; a
/// link with URDF meshes: see [`mesh_link`]).
pub fn link_mesh(model: &RobotModel, link: usize) -> Option<TexturedMesh> {
    link_mesh_with(model, link, TRIANGLES_PER_LINK)
}

/// [`link_mesh`] with a link drawn from meshes simplified to about `max_triangles` (`usize::MAX`:
/// whole).
pub fn link_mesh_with(model: &RobotModel, link: usize, max_triangles: usize) -> Option<TexturedMesh> {
    let shapes = &model.links[link].visuals;
    if shapes.is_empty() {
        return None;
    }
    if shapes.iter().any(|s| matches!(s.geometry, Geometry::Mesh { .. })) {
        return Some(mesh_link(shapes, max_triangles));
    }
    let n = shapes.len();
    let mut mesh = TexturedMesh {
        positions: Vec::new(),
        normals: Vec::new(),
        uvs: Vec::new(),
        indices: Vec::new(),
        texture: Texture {
            width: n as u32,
            height: 1,
            rgba: shapes.iter().flat_map(|s| s.rgba.map(vt_objects::linear_to_srgb8)).collect(),
        },
    };
    for (i, s) in shapes.iter().enumerate() {
        let uv = [(i as f32 + 0.5) / n as f32, 0.5];
        let (pos, nrm, idx) = primitive(&s.geometry);
        let base = mesh.positions.len() as u32;
        let m = s.origin;
        let r = m.matrix3;
        mesh.positions.extend(pos.iter().map(|p| m.transform_point3(p.as_dvec3()).as_vec3().to_array()));
        mesh.normals.extend(nrm.iter().map(|v| (r * v.as_dvec3()).normalize().as_vec3().to_array()));
        mesh.uvs.extend(std::iter::repeat_n(uv, pos.len()));
        mesh.indices.extend(idx.iter().map(|i| i + base));
    }
    Some(mesh)
}

/// A link drawn from its URDF's meshes (and any primitives beside them), each triangle in the
/// URDF's colour or else its mesh file's, simplified (`scene::drawable`).
fn mesh_link(shapes: &[vt_robot::Shape], max_triangles: usize) -> TexturedMesh {
    let mut raw = RawMesh { positions: Vec::new(), triangles: Vec::new(), colours: Vec::new() };
    for s in shapes {
        let urdf_colour = (s.rgba != vt_robot::NO_RGBA).then(|| [s.rgba[0], s.rgba[1], s.rgba[2]]);
        let base = raw.positions.len() as u32;
        match &s.geometry {
            Geometry::Mesh { mesh } => {
                raw.positions.extend(mesh.positions.iter().map(|p| s.origin.transform_point3(*p).as_vec3()));
                raw.triangles.extend(mesh.triangles.iter().map(|t| t.map(|i| i + base)));
                raw.colours.extend(mesh.colours.iter().map(|c| urdf_colour.or(*c).unwrap_or(vt_robot::mesh::DEFAULT_MESH_RGB)));
            }
            g => {
                let (pos, _, idx) = primitive(g);
                raw.positions.extend(pos.iter().map(|p| s.origin.transform_point3(p.as_dvec3()).as_vec3()));
                raw.triangles.extend(idx.chunks_exact(3).map(|t| [t[0] + base, t[1] + base, t[2] + base]));
                raw.colours.extend(std::iter::repeat_n(urdf_colour.unwrap_or(vt_robot::mesh::DEFAULT_MESH_RGB), idx.len() / 3));
            }
        }
    }
    drawable_link(raw, max_triangles)
}

/// Box, cylinder (along z) or sphere as positions, normals and triangles.
fn primitive(g: &Geometry) -> (Vec<Vec3>, Vec<Vec3>, Vec<u32>) {
    let (mut p, mut n, mut t) = (Vec::new(), Vec::new(), Vec::new());
    match *g {
        Geometry::Box { size } => {
            let h = size.as_vec3() * 0.5;
            for (nn, u, v) in vt_objects::BOX_FACES {
                let b = p.len() as u32;
                for (a, c) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                    p.push((nn + u * a + v * c) * h);
                    n.push(nn);
                }
                t.extend([b, b + 1, b + 2, b, b + 2, b + 3]);
            }
        }
        Geometry::Cylinder { radius, length } => {
            let (r, hl, seg) = (radius as f32, length as f32 / 2.0, 24u32);
            for j in 0..=seg {
                let a = std::f32::consts::TAU * j as f32 / seg as f32;
                let d = Vec3::new(a.cos(), a.sin(), 0.0);
                p.extend([d * r - Vec3::Z * hl, d * r + Vec3::Z * hl]);
                n.extend([d, d]);
            }
            for j in 0..seg {
                let b = 2 * j;
                t.extend([b, b + 2, b + 3, b, b + 3, b + 1]);
            }
            for (z, nz) in [(-hl, Vec3::NEG_Z), (hl, Vec3::Z)] {
                let c = p.len() as u32;
                p.push(Vec3::Z * z);
                n.push(nz);
                for j in 0..=seg {
                    let a = std::f32::consts::TAU * j as f32 / seg as f32;
                    p.push(Vec3::new(a.cos() * r, a.sin() * r, z));
                    n.push(nz);
                }
                for j in 0..seg {
                    if z < 0.0 { t.extend([c, c + 2 + j, c + 1 + j]) } else { t.extend([c, c + 1 + j, c + 2 + j]) }
                }
            }
        }
        // Hulls are collision shapes; meshes are drawn by `mesh_link`.
        Geometry::ConvexHull { .. } | Geometry::Mesh { .. } => {}
        Geometry::Sphere { radius } => {
            let (r, st, sl) = (radius as f32, 12u32, 24u32);
            for i in 0..=st {
                let th = std::f32::consts::PI * i as f32 / st as f32;
                for j in 0..=sl {
                    let ph = std::f32::consts::TAU * j as f32 / sl as f32;
                    let d = Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
                    p.push(d * r);
                    n.push(d);
                }
            }
            for i in 0..st {
                for j in 0..sl {
                    let a = i * (sl + 1) + j;
                    let b = a + sl + 1;
                    t.extend([a, b, b + 1, a, b + 1, a + 1]);
                }
            }
        }
    }
    (p, n, t)
}

/// The robot posed at joint values `q` (`RobotModel::dof_names` order) with its base at
/// `t_world_base`: the drawn links' world poses, the `/tf` frames (the grasp frame, the drawn
/// links, one `<pad>_pad` frame per pad; FORMAT.md) and the pads' world poses.
pub struct PosedLinks {
    pub links: Vec<(usize, DAffine3)>,
    pub transforms: Vec<(String, String, Pose)>,
    pub pads: Vec<DAffine3>,
}

/// Poses `robot` at `q`, its grasp frame at `t_world_palm` (as the grasp loop recorded it); `drawn`
/// are the links that are drawn (they carry meshes in `/scene/models`).
pub fn pose_links(
    robot: &Robot,
    t_world_base: DAffine3,
    t_world_palm: DAffine3,
    q: &[f64],
    drawn: impl IntoIterator<Item = usize>,
) -> PosedLinks {
    let model = &robot.model;
    let links = model.forward_kinematics(q);
    let grasp_frame = robot.grasp_frame;
    let mut transforms = vec![(frames::WORLD.to_string(), model.links[grasp_frame].name.clone(), pose_of(&t_world_palm))];
    let mut posed = Vec::new();
    for link in drawn {
        let t_world_link = t_world_base * links[link];
        posed.push((link, t_world_link));
        if link != grasp_frame {
            transforms.push((frames::WORLD.to_string(), model.links[link].name.clone(), pose_of(&t_world_link)));
        }
    }
    let pads: Vec<DAffine3> = robot.pads.iter().map(|p| t_world_base * links[p.frame]).collect();
    for (p, t) in robot.pads.iter().zip(&pads) {
        transforms.push((frames::WORLD.to_string(), format!("{}_pad", p.name), pose_of(t)));
    }
    PosedLinks { links: posed, transforms, pads }
}

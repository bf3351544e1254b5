//! The hand on its real meshes: a robot whose description says `hand_collision: mesh_hulls`
//! collides, where its visual meshes are drawn (the robot assets), as the convex hull of each hand
//! link's meshes, and each pad sits on its link's real palmar surface. The pads' contact rule
//! measures from the same surfaces (`sensors::touch`).

use std::collections::HashMap;

use anyhow::{Context, Result};
use glam::{DAffine3, DQuat, DVec3, Vec3};
use vt_objects::{Texture, TexturedMesh};
use vt_robot::{Geometry, HandCollision, Robot, RobotModel};

/// The whole visual meshes (link frame, positions and triangles) of the hand's links that are
/// drawn from meshes, when the robot's hand collides as their hulls (`hand_collision:
/// mesh_hulls`) and they are there; None otherwise.
pub fn hand_surface_meshes(robot: &Robot) -> Option<HashMap<usize, TexturedMesh>> {
    if robot.hand_collision != HandCollision::MeshHulls {
        return None;
    }
    let model = &robot.model;
    let meshes: HashMap<usize, TexturedMesh> = (0..model.links.len())
        .filter(|&l| l == robot.hand_root || model.is_below(l, robot.hand_root))
        .filter_map(|l| {
            let mut out = TexturedMesh {
                positions: Vec::new(),
                normals: Vec::new(),
                uvs: Vec::new(),
                indices: Vec::new(),
                texture: Texture { width: 1, height: 1, rgba: vec![255; 4] },
            };
            for s in &model.links[l].visuals {
                let Geometry::Mesh { mesh } = &s.geometry else { continue };
                // Each triangle with its own three vertices, as a drawn mesh holds them.
                for t in &mesh.triangles {
                    for &i in t {
                        out.indices.push(out.positions.len() as u32);
                        out.positions.push(s.origin.transform_point3(mesh.positions[i as usize]).as_vec3().to_array());
                    }
                }
            }
            (!out.positions.is_empty()).then_some((l, out))
        })
        .collect();
    (!meshes.is_empty()).then_some(meshes)
}

/// The robot with its hand on the real meshes: each hand link collides as the convex hull of its
/// mesh (for rapier and MuJoCo alike; only the hull's vertices are kept), and each pad sits on
/// its link's real palmar surface at mid-length of its sensing span ([`pad_on_surface`]).
pub fn with_real_hand(robot: &Robot, hand: &HashMap<usize, TexturedMesh>) -> Result<RobotModel> {
    let model = &robot.model;
    let hulls: HashMap<usize, Vec<DVec3>> = hand
        .iter()
        .map(|(&id, m)| {
            let points: Vec<Vec3> = m.positions.iter().map(|p| Vec3::from(*p)).collect();
            (id, rapier3d::parry::transformation::convex_hull(&points).0.iter().map(|p| p.as_dvec3()).collect())
        })
        .collect();
    let mut out = Robot { model: model.with_mesh_collisions(&hulls), ..robot.clone() };
    // The pads' spans (joint to joint, distal to the fingertip's end) from the hulls.
    let spans = out.pad_sizes();
    for (pad, (length, _)) in robot.pads.iter().zip(spans) {
        let mesh = hand.get(&pad.link).with_context(|| format!("pad {}: no real mesh of its link", pad.name))?;
        let origin = pad_on_surface(mesh, 0.5 * length, (0.0, length))
            .with_context(|| format!("{}: no palmar surface of the real mesh at mid-length", pad.name))?;
        let frame = model.links[pad.frame].name.clone();
        out.model.set_fixed_link_origin(&frame, origin).map_err(anyhow::Error::msg)?;
    }
    Ok(out.model)
}

/// The pad frame on the palmar (+x) surface of a finger link, at height `z` along the finger: origin
/// where the line (y = 0, z) leaves the mesh on the +x side; where the mesh has a bore or a gap
/// on that line (the thumb's short proximal link is a joint housing open at mid-length), on the
/// nearest line (y, z) within `span` that meets the surface. z axis along +x (out of the finger),
/// as the URDF's pads (rpy 0, pi/2, 0).
pub fn pad_on_surface(mesh: &TexturedMesh, z: f64, span: (f64, f64)) -> Option<DAffine3> {
    let points: Vec<DVec3> = mesh.positions.iter().map(|p| Vec3::from(*p).as_dvec3()).collect();
    let exit = |y: f64, z: f64| {
        mesh.indices
            .chunks_exact(3)
            .filter_map(|t| ray_x_hit(DVec3::new(-1.0, y, z), points[t[0] as usize], points[t[1] as usize], points[t[2] as usize]))
            .reduce(f64::max)
    };
    // Candidate lines by distance from (0, z), 0.5 mm apart.
    let mut lines: Vec<(f64, f64)> = (-8..=8)
        .flat_map(|i| (-80..=80).map(move |j| (i as f64 * 5e-4, z + j as f64 * 5e-4)))
        .filter(|&(_, zz)| zz >= span.0 && zz <= span.1)
        .collect();
    lines.sort_by(|a, b| (a.0.hypot(a.1 - z)).total_cmp(&b.0.hypot(b.1 - z)));
    let (y, z, x) = lines.into_iter().find_map(|(y, zz)| exit(y, zz).map(|x| (y, zz, x)))?;
    Some(DAffine3::from_rotation_translation(DQuat::from_rotation_y(std::f64::consts::FRAC_PI_2), DVec3::new(x, y, z)))
}

/// Where the ray from `o` along +x crosses triangle (a, b, c): its x, if it does.
fn ray_x_hit(o: DVec3, a: DVec3, b: DVec3, c: DVec3) -> Option<f64> {
    // Project onto the (y, z) plane: barycentric coordinates of (o.y, o.z) in the triangle.
    let (ab, ac, ao) = (b - a, c - a, o - a);
    let det = ab.y * ac.z - ab.z * ac.y;
    if det.abs() < 1e-18 {
        return None;
    }
    let u = (ao.y * ac.z - ao.z * ac.y) / det;
    let v = (ab.y * ao.z - ab.z * ao.y) / det;
    (u >= 0.0 && v >= 0.0 && u + v <= 1.0).then_some(a.x + u * ab.x + v * ac.x)
}

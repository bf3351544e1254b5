//! The hand on its real meshes: a robot whose description says `hand_collision: mesh_hulls`
//! collides, where its visual meshes are drawn (the robot assets), as the convex hull of each hand
//! link's meshes, and each pad is moved along its own normal onto its link's real surface. The
//! pads' contact rule measures from the same surfaces (`sensors::touch`).

use std::collections::HashMap;

use anyhow::{Context, Result};
use glam::{DAffine3, DVec3, Vec3};
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
/// mesh (for rapier and MuJoCo alike; only the hull's vertices are kept), and each pad is moved
/// along its own normal onto its link's real surface ([`pad_on_surface`]).
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
    // Each pad's sensing length (its description's size, else its link's span from the hulls)
    // bounds how far along the pad a line may be moved to find the surface.
    let sizes = out.pad_sizes();
    for (pad, (length, _)) in robot.pads.iter().zip(sizes) {
        let mesh = hand.get(&pad.link).with_context(|| format!("pad {}: no real mesh of its link", pad.name))?;
        let t_link_pad = model.joints[model.links[pad.frame].parent_joint.expect("a pad frame is fixed to its link")].origin;
        let origin = pad_on_surface(mesh, &t_link_pad, 0.5 * length)
            .with_context(|| format!("{}: no surface of the real mesh under the pad (along its z)", pad.name))?;
        let frame = model.links[pad.frame].name.clone();
        out.model.set_fixed_link_origin(&frame, origin).map_err(anyhow::Error::msg)?;
    }
    Ok(out.model)
}

/// The pad frame `t_link_pad` moved along its own z onto the outermost surface of `mesh` (link
/// frame) there: origin where the line through the pad's origin along its z leaves the mesh on the
/// pad's +z side; where the mesh has a bore or a gap on that line (the Allegro thumb's short
/// proximal link is a joint housing open at mid-length), on the nearest parallel line within
/// `half_length` along the pad's x and 4 mm along its y that meets the surface. The orientation is
/// the pad's own (z out of the surface, as its description gives it).
pub fn pad_on_surface(mesh: &TexturedMesh, t_link_pad: &DAffine3, half_length: f64) -> Option<DAffine3> {
    let to_pad = t_link_pad.inverse();
    let points: Vec<DVec3> = mesh.positions.iter().map(|p| to_pad.transform_point3(Vec3::from(*p).as_dvec3())).collect();
    let exit = |x: f64, y: f64| {
        mesh.indices
            .chunks_exact(3)
            .filter_map(|t| ray_z_hit(x, y, points[t[0] as usize], points[t[1] as usize], points[t[2] as usize]))
            .reduce(f64::max)
    };
    // Candidate lines by distance from the pad's origin, 0.5 mm apart.
    let mut lines: Vec<(f64, f64)> = (-80..=80)
        .flat_map(|i| (-8..=8).map(move |j| (i as f64 * 5e-4, j as f64 * 5e-4)))
        .filter(|&(x, _)| x.abs() <= half_length + 1e-12)
        .collect();
    lines.sort_by(|a, b| a.0.hypot(a.1).total_cmp(&b.0.hypot(b.1)));
    let (x, y, z) = lines.into_iter().find_map(|(x, y)| exit(x, y).map(|z| (x, y, z)))?;
    Some(*t_link_pad * DAffine3::from_translation(DVec3::new(x, y, z)))
}

/// Where the line (x, y, ·) parallel to z crosses triangle (a, b, c): its z, if it does.
fn ray_z_hit(x: f64, y: f64, a: DVec3, b: DVec3, c: DVec3) -> Option<f64> {
    // Barycentric coordinates of (x, y) in the triangle projected onto the (x, y) plane.
    let (ab, ac) = (b - a, c - a);
    let det = ab.x * ac.y - ab.y * ac.x;
    if det.abs() < 1e-18 {
        return None;
    }
    let (px, py) = (x - a.x, y - a.y);
    let u = (px * ac.y - py * ac.x) / det;
    let v = (ab.x * py - ab.y * px) / det;
    (u >= 0.0 && v >= 0.0 && u + v <= 1.0).then_some(a.z + u * ab.z + v * ac.z)
}

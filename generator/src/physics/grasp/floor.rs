//! Heights above the floor (world z = 0): the object's and the robot's lowest points.

use glam::{DAffine3, DVec3};
use vt_robot::Robot;

/// Smallest height (m) of the object above the floor a recorded instance may have.
pub(super) const MIN_FLOOR_CLEARANCE: f64 = 0.005;

/// The lowest link of the robot at joint values `q` (its base at `t_world_base`) that an arm joint
/// moves, and the height of its lowest collision point above the floor (world z = 0); None: no
/// such link has collision geometry.
pub fn robot_floor_clearance(robot: &Robot, t_world_base: &DAffine3, q: &[f64]) -> Option<(usize, f64)> {
    let model = &robot.model;
    let first_moved = model.joints[*robot.arm_joints.first()?].child;
    let poses = model.forward_kinematics(q);
    let mut lowest: Option<(usize, f64)> = None;
    for (id, link) in model.links.iter().enumerate() {
        if !model.is_below(id, first_moved) {
            continue;
        }
        let t_world_link = *t_world_base * poses[id];
        for s in &link.collisions {
            let t = t_world_link * s.origin;
            let z = match &s.geometry {
                vt_robot::Geometry::Box { size } => {
                    let h = *size * 0.5;
                    (0..8)
                        .map(|c| {
                            let corner = DVec3::new(
                                if c & 1 == 0 { -h.x } else { h.x },
                                if c & 2 == 0 { -h.y } else { h.y },
                                if c & 4 == 0 { -h.z } else { h.z },
                            );
                            t.transform_point3(corner).z
                        })
                        .fold(f64::MAX, f64::min)
                }
                vt_robot::Geometry::Sphere { radius } => t.translation.z - radius,
                vt_robot::Geometry::Cylinder { radius, length } => {
                    let uz = t.transform_vector3(DVec3::Z).normalize().z;
                    t.translation.z - uz.abs() * length / 2.0 - radius * (1.0 - uz * uz).max(0.0).sqrt()
                }
                g => g.hull_points().unwrap_or(&[]).iter().map(|p| t.transform_point3(*p).z).fold(f64::MAX, f64::min),
            };
            if lowest.is_none_or(|(_, l)| z < l) {
                lowest = Some((id, z));
            }
        }
    }
    lowest
}

/// Height above the floor (world z = 0) of the lowest of `points` (model frame) posed by
/// `t_world_object`.
pub fn floor_clearance(points: &[[f32; 3]], t_world_object: &DAffine3) -> f64 {
    points.iter().map(|p| t_world_object.transform_point3(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)).z).fold(f64::MAX, f64::min)
}

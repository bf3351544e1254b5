//! Antipodal grasps for a parallel-jaw gripper: two points of the object's convex hull (its
//! physics shape) whose outward normals oppose each other, closer together than the open jaws,
//! put on the line between the two pads with their midpoint between the pads and a random turn
//! about that line.

use glam::{DAffine3, DQuat, DVec3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use vt_objects::SurfaceSampler;
use vt_robot::Robot;

/// The open jaws (grasp frame): the pads' midpoint, the unit direction from the first pad to the
/// second, and the gap between their faces (the pad frames lie on the faces).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Jaws {
    pub centre: DVec3,
    pub axis: DVec3,
    pub opening: f64,
}

impl Jaws {
    /// The first two pads of `robot` with its hand joints at `hand` (`Robot::hand` order).
    pub fn of(robot: &Robot, hand: &[f64]) -> Jaws {
        Jaws::between(robot, hand, [0, 1])
    }

    /// Pads `pads` (indices in `Robot::pads`) of `robot` with its hand joints at `hand`.
    pub fn between(robot: &Robot, hand: &[f64], pads: [usize; 2]) -> Jaws {
        let m = &robot.model;
        let mut q = m.zero();
        robot.set_hand(&mut q, hand);
        let links = m.forward_kinematics(&q);
        let to_grasp = links[robot.grasp_frame].inverse();
        let [a, b] = pads.map(|k| to_grasp.transform_point3(links[robot.pads[k].frame].translation));
        Jaws { centre: (a + b) * 0.5, axis: (b - a).normalize_or(DVec3::Y), opening: a.distance(b) }
    }
}

/// A convex hull as its outward face planes (`n · x <= d` inside) and its surface.
pub struct Hull {
    planes: Vec<(DVec3, f64)>,
    surface: SurfaceSampler,
}

impl Hull {
    /// The convex hull of `points` (model frame); None when they span no volume.
    pub fn of(points: &[[f32; 3]]) -> Option<Hull> {
        let pts: Vec<glam::Vec3> = points.iter().map(|p| glam::Vec3::from_array(*p)).collect();
        let (vertices, faces) = rapier3d::parry::transformation::convex_hull(&pts);
        if faces.len() < 4 {
            return None;
        }
        let v: Vec<DVec3> = vertices.iter().map(|p| p.as_dvec3()).collect();
        let inside = v.iter().copied().sum::<DVec3>() / v.len() as f64;
        let mut triangles = Vec::with_capacity(faces.len());
        let mut planes = Vec::with_capacity(faces.len());
        for f in &faces {
            let [a, b, c] = f.map(|i| v[i as usize]);
            let n = (b - a).cross(c - a);
            if n.length() < 1e-12 {
                continue;
            }
            // Outward, whatever the winding.
            let n = if n.dot(a - inside) < 0.0 { -n.normalize() } else { n.normalize() };
            planes.push((n, n.dot(a)));
            triangles.push([a, b, c]);
        }
        Some(Hull { planes, surface: SurfaceSampler::new(triangles) })
    }

    /// The outward normal of the face nearest `p` (a point on or near the hull): the face plane
    /// `p` lies furthest outside of, or least inside.
    pub fn normal_near(&self, p: DVec3) -> DVec3 {
        self.planes.iter().max_by(|a, b| (a.0.dot(p) - a.1).total_cmp(&(b.0.dot(p) - b.1))).map_or(DVec3::Z, |&(n, _)| n)
    }

    /// The hull's faces: each one's outward normal and triangle.
    pub fn faces(&self) -> impl Iterator<Item = (DVec3, &[DVec3; 3])> {
        self.planes.iter().map(|&(n, _)| n).zip(self.surface.triangles())
    }

    /// Where a ray from `p` (on the hull) along `dir` (into it) leaves the hull: the distance and
    /// the outward normal there.
    fn exit(&self, p: DVec3, dir: DVec3) -> Option<(f64, DVec3)> {
        self.planes
            .iter()
            .filter(|(n, _)| n.dot(dir) > 1e-9)
            .map(|&(n, d)| ((d - n.dot(p)) / n.dot(dir), n))
            .filter(|(t, _)| *t > 1e-6)
            .min_by(|a, b| a.0.total_cmp(&b.0))
    }
}

/// The hull's narrowest width (m): the least extent of `points` along any of its face normals
/// (where a convex body's width is least). None when the points span no volume.
pub fn narrowest_width(points: &[[f32; 3]]) -> Option<f64> {
    let hull = Hull::of(points)?;
    let pts: Vec<DVec3> = points.iter().map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)).collect();
    hull.planes.iter().map(|&(n, d)| d - pts.iter().map(|p| n.dot(*p)).fold(f64::MAX, f64::min)).min_by(f64::total_cmp)
}

/// Why a parallel-jaw gripper can never hold an object, found before any physics: no antipodal
/// pair fits its jaws when the object is wider, along every direction, than the jaws open (less
/// their clearance) at the widest preshape. None when it may fit.
pub fn cannot_fit_between_jaws(robot: &Robot, preshape: &[(f64, f64)], object_id: &str, points: &[[f32; 3]]) -> Option<String> {
    // The jaws' opening at each end of every joint's preshape range (the widest of them).
    let corners: Vec<Vec<f64>> = [0.0, 0.5, 1.0].iter().map(|t| preshape.iter().map(|(lo, hi)| lo + t * (hi - lo)).collect()).collect();
    let opening = corners.iter().map(|pre| Jaws::of(robot, pre).opening).fold(0.0, f64::max);
    let room = opening - 2.0 * CLEARANCE;
    let width = narrowest_width(points)?;
    (width > room).then(|| {
        format!(
            "{object_id} is at least {:.1} mm wide in every direction, and the jaws of {} open {:.1} mm at most (less {:.0} mm clearance \
             on each side): no grasp can hold it. Leave it out of `objects`, scale it down, or use a gripper that opens wider",
            1e3 * width,
            robot.name,
            1e3 * opening,
            1e3 * CLEARANCE
        )
    })
}

/// Antipodal pairs drawn before an attempt is given up.
const DRAWS: u32 = 64;
/// The pair's normals may be this far (rad) from opposite: inside a friction cone of μ ≈ 0.36.
const MAX_NORMAL_ANGLE: f64 = 0.35;
/// Clearance (m) each open jaw keeps from the object, and the narrowest width grasped.
const CLEARANCE: f64 = 0.004;
const MIN_WIDTH: f64 = 0.005;

/// A pose of the object (grasp frame) with an antipodal pair of its hull on the jaws' line, the
/// pair's midpoint at the jaws' centre, turned about the line at random; None when no pair fits
/// the open jaws in `DRAWS` draws.
pub fn antipodal_pose(hull: &Hull, jaws: &Jaws, rng: &mut ChaCha8Rng) -> Option<DAffine3> {
    for _ in 0..DRAWS {
        let (u, u1, u2, spin): (f64, f64, f64, f64) = (rng.random(), rng.random(), rng.random(), rng.random());
        let k = hull.surface.pick(u);
        let p = hull.surface.point(k, u1, u2);
        let n = hull.surface.face_normal(k);
        // `face_normal` follows the triangle's winding: the outward one is the plane's.
        let n = if n.dot(hull.planes[k].0) < 0.0 { -n } else { n };
        let Some((width, n_exit)) = hull.exit(p, -n) else { continue };
        if !(MIN_WIDTH..=jaws.opening - 2.0 * CLEARANCE).contains(&width) || n.dot(-n_exit) < MAX_NORMAL_ANGLE.cos() {
            continue;
        }
        // `p` faces the first pad (its normal against the jaws' axis), its partner the second.
        let turn = DQuat::from_axis_angle(jaws.axis, std::f64::consts::TAU * spin) * DQuat::from_rotation_arc(n, -jaws.axis);
        let middle = p - n * (0.5 * width);
        return Some(DAffine3::from_rotation_translation(turn, jaws.centre - turn * middle));
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn a_box_is_grasped_across_a_pair_of_its_faces_centred_between_the_jaws() {
        let e = [0.03f32, 0.05, 0.12];
        let corners: Vec<[f32; 3]> = (0..8)
            .map(|i| [if i & 1 == 0 { -e[0] } else { e[0] }, if i & 2 == 0 { -e[1] } else { e[1] }, if i & 4 == 0 { -e[2] } else { e[2] }])
            .collect();
        let hull = Hull::of(&corners).unwrap();
        let jaws = Jaws { centre: DVec3::new(0.0, 0.0, 0.0), axis: DVec3::Y, opening: 0.086 };
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..50 {
            let t = antipodal_pose(&hull, &jaws, &mut rng).expect("the 6 cm side fits the 8.6 cm jaws");
            // The box's extent along the jaws' line is one of its widths that fit: 6 cm (10 cm
            // and 24 cm do not), and it is centred between the jaws.
            let along: Vec<f64> = corners.iter().map(|c| t.transform_point3(DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64)).y).collect();
            let (lo, hi) = along.iter().fold((f64::MAX, f64::MIN), |(a, b), &y| (a.min(y), b.max(y)));
            assert!((hi - lo - 0.06).abs() < 1e-6 && (hi + lo).abs() < 1e-6, "{lo} {hi}");
        }
        // Too wide for the jaws: no grasp.
        let narrow = Jaws { opening: 0.05, ..jaws };
        assert!(antipodal_pose(&hull, &narrow, &mut rng).is_none());
        // The nearest face's outward normal, for points just outside, on and just inside a face.
        for (p, n) in [
            (DVec3::new(0.031, 0.01, -0.02), DVec3::X),
            (DVec3::new(-0.01, -0.05, 0.1), DVec3::NEG_Y),
            (DVec3::new(0.0, 0.02, 0.118), DVec3::Z),
            (DVec3::new(0.005, 0.0, -0.125), DVec3::NEG_Z),
        ] {
            assert!(hull.normal_near(p).distance(n) < 1e-9, "{p}: {}", hull.normal_near(p));
        }
    }
}

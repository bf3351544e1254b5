//! A hand's pinch made again where it has none (`sampling.record.pivot.repinches`): a pad of the
//! pinch's first pattern (the thumb's) is lifted off and placed again on a face of the object
//! opposite a touching pad of the second pattern, where the two can pinch. Where it goes comes from
//! the object's convex hull and the hand's kinematics alone: of the hull's faces whose normals are
//! at least 120° from the touching pad's contact normal, the point nearest the moved pad, and a
//! damped least-squares solve over the joints that move that pad (and not the other) for the joint
//! values that put it there, clear of the surface first and then pressing into it. (Aiming along
//! the touching pad's normal through the object instead found points out of the thumb's reach:
//! 8–23 cm away on the large boxes.)

use glam::{DAffine3, DVec3};
use nalgebra::{DMatrix, DVector};
use vt_objects::closest_point_on_triangle;
use vt_robot::Robot;

use super::pivot::{moves, on_one_finger};
use crate::physics::antipodal::Hull;

/// How far (m) off the surface the pad is put before it presses, and how far into it its press
/// aims (the drive's effort limit sets the force).
const CLEARANCE: f64 = 0.015;
const PRESS_DEPTH: f64 = 0.006;
/// A placement counts as reachable when the solve puts the pad this close (m) to both points.
const MAX_REACH_ERROR: f64 = 0.006;
/// The pad's facing weighs this much (m per unit of the normals' difference) against its position:
/// a rounded fingertip touches over a range of facings, so position comes first.
const FACING_WEIGHT: f64 = 0.002;
/// The time (s) the lifted pad takes from where it was to its place clear of the surface.
pub(super) const TRANSFER_SECONDS: f64 = 0.3;
const SOLVE_ITERATIONS: usize = 80;
const SOLVE_DAMPING: f64 = 1e-4;
const FINITE_STEP: f64 = 1e-6;

/// A re-placement of one pad: the hand joints that move it, and the hand's joint targets with it
/// clear of the object's surface and pressing into it (`Robot::hand` order).
pub(super) struct Replacement {
    pub chain: Vec<usize>,
    pub clear: Vec<f64>,
    pub press: Vec<f64>,
}

/// A pad's frame (grasp frame) with the hand joints at `hand`: its origin and its +z.
fn pad_frame(robot: &Robot, hand: &[f64], pad: usize) -> (DVec3, DVec3) {
    let m = &robot.model;
    let mut q = m.zero();
    robot.set_hand(&mut q, hand);
    let links = m.forward_kinematics(&q);
    let to_grasp = links[robot.grasp_frame].inverse();
    let frame = links[robot.pads[pad].frame];
    (to_grasp.transform_point3(frame.translation), to_grasp.transform_vector3(frame.matrix3.z_axis))
}

/// The joint values, from `start`, that put `pad`'s origin at `point` with its +z along `facing`,
/// moving only the hand joints in `chain` within their limits; and how far (m) the pad's origin
/// then is from `point`.
fn reach(robot: &Robot, start: &[f64], chain: &[usize], pad: usize, point: DVec3, facing: DVec3) -> Option<(Vec<f64>, f64)> {
    let residual = |hand: &[f64]| -> DVector<f64> {
        let (p, z) = pad_frame(robot, hand, pad);
        let (e, f) = (p - point, (z - facing) * FACING_WEIGHT);
        DVector::from_row_slice(&[e.x, e.y, e.z, f.x, f.y, f.z])
    };
    let mut hand = start.to_vec();
    for _ in 0..SOLVE_ITERATIONS {
        let r = residual(&hand);
        let mut jac = DMatrix::zeros(6, chain.len());
        for (c, &h) in chain.iter().enumerate() {
            let mut moved = hand.clone();
            moved[h] += FINITE_STEP;
            jac.set_column(c, &((residual(&moved) - &r) / FINITE_STEP));
        }
        let jt = jac.transpose();
        let normal = &jt * &jac + DMatrix::identity(chain.len(), chain.len()) * SOLVE_DAMPING;
        let step = normal.lu().solve(&(jt * &r))?;
        for (c, &h) in chain.iter().enumerate() {
            let joint = &robot.model.joints[robot.hand[h].joint];
            let v = hand[h] - step[c];
            hand[h] = if joint.lower < joint.upper { v.clamp(joint.lower, joint.upper) } else { v };
        }
    }
    let error = pad_frame(robot, &hand, pad).0.distance(point);
    Some((hand, error))
}

/// Two contact normals at least this far apart (cosine: 120°) make a pinch a re-placement aims for.
const OPPOSED: f64 = -0.5;

/// Where a pad of `first` can be placed again to pinch the object (at `object`, palm frame)
/// against a touching pad of `second` on another finger: on the object's faces whose normals are
/// at least 120° from the touching pad's contact normal, the point nearest where the moved pad is
/// now. Of those the hand's kinematics reach, the nearest, moving a finger only where the touch
/// links it does not move (of `holding`, those touching the object now) are still at least the
/// robot's `min_touching`; None when there is none. `hand` is where the hand's joints stand,
/// `touching` per `Robot::pads`.
#[allow(clippy::too_many_arguments)]
pub(super) fn plan(
    robot: &Robot,
    hand: &[f64],
    touching: &[bool],
    holding: &[usize],
    first: &[usize],
    second: &[usize],
    hull: &Hull,
    object: &DAffine3,
) -> Option<Replacement> {
    let to_object = object.inverse();
    // (the touching pad, the pad moved opposite it). Moving the second pattern's pads opposite a
    // touching first pad as well turned the objects no further (seeds 7 and 8, both backends,
    // 6 s and 12 s: 249 against 247 of 480 episodes past 90°) and dropped them more often.
    let pairs = second.iter().filter(|&&b| touching[b]).flat_map(|&b| first.iter().map(move |&a| (b, a)));
    let mut best: Option<(f64, Replacement)> = None;
    for (anchor, mover) in pairs {
        if anchor == mover || on_one_finger(robot, anchor, mover) {
            continue;
        }
        // On another finger than the anchor, every joint that moves the pad leaves the anchor be.
        let chain: Vec<usize> = (0..robot.hand.len()).filter(|&h| moves(robot, h, robot.pads[mover].link)).collect();
        if chain.is_empty() {
            continue;
        }
        let still_holding = holding.iter().filter(|&&l| !chain.iter().any(|&h| moves(robot, h, l))).count();
        if still_holding < robot.min_touching {
            continue;
        }
        let outward = hull.normal_near(to_object.transform_point3(pad_frame(robot, hand, anchor).0));
        let now = to_object.transform_point3(pad_frame(robot, hand, mover).0);
        let Some((point, normal)) = hull
            .faces()
            .filter(|(n, _)| n.dot(outward) <= OPPOSED)
            .map(|(n, t)| (closest_point_on_triangle(now, t), n))
            .min_by(|x, y| x.0.distance(now).total_cmp(&y.0.distance(now)))
        else {
            continue;
        };
        let distance = point.distance(now);
        let (point, normal) = (object.transform_point3(point), object.transform_vector3(normal));
        // The pad's +z faces into the object, as a touching pad's does.
        let Some((clear, e_clear)) = reach(robot, hand, &chain, mover, point + normal * CLEARANCE, -normal) else { continue };
        let Some((press, e_press)) = reach(robot, &clear, &chain, mover, point - normal * PRESS_DEPTH, -normal) else { continue };
        let error = e_clear.max(e_press);
        if error <= MAX_REACH_ERROR && best.as_ref().is_none_or(|(d, _)| distance < *d) {
            best = Some((distance, Replacement { chain, clear, press }));
        }
    }
    best.map(|(_, r)| r)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    /// A box (half sizes `half`) about the origin, as the hull of its corners.
    fn box_hull(half: DVec3) -> Hull {
        let corners: Vec<[f32; 3]> = (0..8)
            .map(|i| {
                let s = |bit: i32| if i & bit == 0 { -1.0 } else { 1.0 };
                [(s(1) * half.x) as f32, (s(2) * half.y) as f32, (s(4) * half.z) as f32]
            })
            .collect();
        Hull::of(&corners).expect("a box spans a volume")
    }

    /// The Allegro's middle fingertip touching a box's face: the thumb is placed on the opposite
    /// face, clear of it and then pressing into it, by the thumb's joints alone; a box too large to
    /// reach round has no placement, and nor has a box the other fingers do not hold.
    #[test]
    fn the_thumb_is_placed_on_the_face_opposite_a_touching_fingertip() {
        let robot = Robot::builtin("ur5e_allegro").unwrap();
        let pad = |n: &str| robot.pads.iter().position(|p| p.name == n).unwrap();
        let first: Vec<usize> = ["th_proximal", "th_medial", "th_distal"].map(pad).to_vec();
        let second = vec![pad("mf_distal")];
        let mut touching = vec![false; robot.pads.len()];
        touching[pad("mf_distal")] = true;
        let hand: Vec<f64> = robot.hand.iter().map(|h| h.close.unwrap_or(0.0) * 0.5).collect();
        let (th, mf) = (pad_frame(&robot, &hand, pad("th_distal")).0, pad_frame(&robot, &hand, pad("mf_distal")).0);
        // The box's +x face through the middle fingertip, its -x face 2 cm short of the thumb.
        let outward = (mf - th).normalize();
        let half = DVec3::new(0.5 * (th.distance(mf) - 0.02), 0.03, 0.03);
        let centre = mf - outward * half.x;
        let object = DAffine3::from_rotation_translation(DQuat::from_rotation_arc(DVec3::X, outward), centre);
        let hull = box_hull(half);
        // The fingertips hold the object while the thumb moves.
        let holding: Vec<usize> = ["ff_distal", "mf_distal", "rf_distal"].map(|n| robot.pads[pad(n)].link).to_vec();
        let plan = plan(&robot, &hand, &touching, &holding, &first, &second, &hull, &object).expect("the thumb reaches the opposite face");
        assert!(!plan.chain.is_empty() && plan.chain.iter().all(|&h| robot.hand[h].name.starts_with("th_")), "only the thumb moves");
        for (h, (c, p)) in plan.clear.iter().zip(&plan.press).enumerate() {
            if !plan.chain.contains(&h) {
                assert!(*c == hand[h] && *p == hand[h], "joint {} moved", robot.hand[h].name);
            }
        }
        // Some thumb pad lies CLEARANCE outside the -x face at `clear` and PRESS_DEPTH inside it
        // at `press`, within the face.
        let to_box = object.inverse();
        let placed = |hand: &[f64], off: f64| {
            first.iter().any(|&a| {
                let p = to_box.transform_point3(pad_frame(&robot, hand, a).0);
                (-p.x - half.x - off).abs() <= MAX_REACH_ERROR && p.y.abs() <= half.y + 1e-3 && p.z.abs() <= half.z + 1e-3
            })
        };
        assert!(placed(&plan.clear, CLEARANCE), "clear of the face");
        assert!(placed(&plan.press, -PRESS_DEPTH), "pressing into the face");
        // A box 40 cm deep: its opposite face is out of the thumb's reach.
        let deep = DVec3::new(0.2, 0.03, 0.03);
        let far = DAffine3::from_rotation_translation(DQuat::from_rotation_arc(DVec3::X, outward), mf - outward * deep.x);
        assert!(super::plan(&robot, &hand, &touching, &holding, &first, &second, &box_hull(deep), &far).is_none());
        // One fingertip alone does not hold the object (the Allegro's `min_touching` is 2): the
        // thumb stays.
        assert!(super::plan(&robot, &hand, &touching, &holding[1..2], &first, &second, &hull, &object).is_none());
    }
}

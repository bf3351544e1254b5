//! A URDF model checked against its description, one part at a time (the arm, the grasp frame, the
//! hand's joints, the pads, the touch links, the decomposition), each name resolved to an index
//! once. Every problem names its own field of the description, and the error the line it is on.
//!
//! `!(a <= b)` on purpose throughout: a NaN must fail the checks too.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use vt_check::{Problem, Seg, key};

use crate::description::{
    ArmSpec, Decomposition, DecompositionSpec, Description, GraspKind, GraspSpec, HandJoint, HandJointSpec, PRISMATIC_DAMPING_TIME,
    PRISMATIC_FULL_FORCE_ERROR, Pad, PadSpec, Robot,
};
use crate::model::{Geometry, JointKind, RobotError, RobotModel, xyz_rpy};

/// A problem at a path of keys and indices below the description's root.
fn at(path: impl IntoIterator<Item = Seg>, message: impl Into<String>) -> Problem {
    Problem { path: path.into_iter().collect(), message: message.into() }
}

/// The link named `name`, or a problem at `path`.
fn link(model: &RobotModel, path: impl IntoIterator<Item = Seg>, name: &str) -> Result<usize, Problem> {
    model.link_id(name).ok_or_else(|| at(path, format!("no link '{name}' in the URDF")))
}

/// The joints from `top` down to `link` (in order), or None when `link` is not below `top`.
fn path_down(model: &RobotModel, top: usize, link: usize) -> Option<Vec<usize>> {
    let mut joints = Vec::new();
    let mut l = link;
    while l != top {
        let j = model.links[l].parent_joint?;
        joints.push(j);
        l = model.joints[j].parent;
    }
    joints.reverse();
    Some(joints)
}

/// Whether joint `j` moves a link of the hand rooted at `hand_root`: its child is below the root,
/// not the root itself (the joint carrying the root, e.g. an arm's last joint when the fingers
/// hang off its link, is the arm's).
fn in_hand(model: &RobotModel, j: usize, hand_root: usize) -> bool {
    let child = model.joints[j].child;
    child != hand_root && model.is_below(child, hand_root)
}

/// Whether `link` hangs below `top` through fixed joints only.
fn fixed_below(model: &RobotModel, top: usize, link: usize) -> bool {
    path_down(model, top, link).is_some_and(|p| p.iter().all(|&j| !model.joints[j].moves()))
}

/// The arm resolved: its base and flange links, its moving joints and their degrees of freedom.
struct Arm {
    base: usize,
    flange: usize,
    joints: Vec<usize>,
    dofs: Vec<usize>,
}

impl Arm {
    fn resolve(model: &RobotModel, arm: &ArmSpec) -> Result<Self, Problem> {
        let here = |k: &'static str| [Seg::key("arm"), Seg::key(k)];
        let base = link(model, here(key!(arm.base)), &arm.base)?;
        let flange = link(model, here(key!(arm.flange)), &arm.flange)?;
        let Some(chain) = path_down(model, base, flange) else {
            return Err(at([Seg::key("arm")], format!("'{}' is not below '{}': the arm is not one serial chain", arm.flange, arm.base)));
        };
        let joints: Vec<usize> = chain.into_iter().filter(|&j| model.joints[j].moves()).collect();
        if let Some(&j) = joints.iter().find(|&&j| model.joints[j].mimic.is_some()) {
            return Err(at([Seg::key("arm")], format!("joint '{}' mimics another: arm joints move on their own", model.joints[j].name)));
        }
        if !(6..=7).contains(&joints.len()) {
            return Err(at(
                [Seg::key("arm")],
                format!("the chain from base to flange has {} moving joints; 6 or 7 are supported", joints.len()),
            ));
        }
        if arm.home.len() != joints.len() {
            return Err(at(here(key!(arm.home)), format!("{} values for {} arm joints", arm.home.len(), joints.len())));
        }
        let dofs = joints.iter().map(|&j| model.joints[j].dof.expect("moving, no mimic")).collect();
        Ok(Arm { base, flange, joints, dofs })
    }
}

/// The grasp frame (a link fixed below the flange, added when the description gives an origin)
/// and the hand's root link: (grasp frame, hand root).
fn grasp_frame(model: &mut RobotModel, grasp: &GraspSpec, arm: &ArmSpec, flange: usize) -> Result<(usize, usize), Problem> {
    let here = |k: &'static str| [Seg::key("grasp"), Seg::key(k)];
    let named = link(model, here(key!(grasp.frame)), &grasp.frame)?;
    let frame = match grasp.origin {
        Some(o) => model
            .add_fixed_link(named, &format!("{}_grasp", grasp.frame), xyz_rpy(o.xyz, o.rpy))
            .map_err(|m| at(here(key!(grasp.origin)), m))?,
        None => named,
    };
    let frame_name = &model.links[frame].name;
    match path_down(model, flange, frame) {
        Some(p) if p.iter().all(|&j| !model.joints[j].moves()) => {}
        Some(_) => return Err(at(here(key!(grasp.frame)), format!("'{frame_name}' moves against the flange: a joint between them moves"))),
        None => {
            return Err(at(
                here(key!(grasp.frame)),
                format!("'{frame_name}' is not fixed below the flange '{}' (no joint chain connects them)", arm.flange),
            ));
        }
    }
    // The hand's root defaults to the link the grasp frame is named by (not its offset child).
    let hand_root = match &grasp.hand_root {
        Some(name) => {
            let root = link(model, here(key!(grasp.hand_root)), name)?;
            if !fixed_below(model, root, frame) {
                return Err(at(here(key!(grasp.hand_root)), format!("the grasp frame '{frame_name}' is not fixed below '{name}'")));
            }
            root
        }
        None => named,
    };
    Ok((frame, hand_root))
}

/// Hand joint `i` of the description, checked and with its drive's defaults filled in.
fn hand_joint(model: &RobotModel, i: usize, h: &HandJointSpec, hand_root: usize, listed: &[HandJoint]) -> Result<HandJoint, Problem> {
    let here = |k: &'static str| [Seg::key("hand"), Seg::Index(i), Seg::key(k)];
    let field = here(key!(h.joint));
    let j = model.joint_id(&h.joint).ok_or_else(|| at(field.clone(), format!("no joint '{}' in the URDF", h.joint)))?;
    let joint = &model.joints[j];
    if joint.mimic.is_some() {
        return Err(at(field, format!("'{}' mimics another joint: list the joint it follows", h.joint)));
    }
    let Some(dof) = joint.dof else { return Err(at(field, format!("'{}' is fixed", h.joint))) };
    if !in_hand(model, j, hand_root) {
        let root = &model.links[hand_root].name;
        return Err(at(field, format!("'{}' is not below the hand's root '{root}'", h.joint)));
    }
    if listed.iter().any(|o| o.joint == j) {
        return Err(at(field, format!("'{}' is listed twice", h.joint)));
    }
    if !(h.preshape.0 <= h.preshape.1) {
        return Err(at(here(key!(h.preshape)), format!("[{}, {}] is not a range (low first)", h.preshape.0, h.preshape.1)));
    }
    for (key, value) in [(key!(h.effort), h.effort), (key!(h.stiffness), h.stiffness)] {
        if let Some(v) = value
            && !(v > 0.0 && v.is_finite())
        {
            return Err(at(here(key), format!("{v} must be a positive number")));
        }
    }
    if let Some(d) = h.damping
        && !(d >= 0.0 && d.is_finite())
    {
        return Err(at(here(key!(h.damping)), format!("{d} must be zero or a positive number")));
    }
    // Drive defaults: the URDF's `<limit effort>`; a prismatic joint's gains from its effort
    // (full force at `PRISMATIC_FULL_FORCE_ERROR`), in N/m and N·s/m.
    let effort = h.effort.or((joint.effort > 0.0 && joint.effort.is_finite()).then_some(joint.effort));
    let prismatic = joint.kind == JointKind::Prismatic;
    let stiffness = h.stiffness.or(effort.filter(|_| prismatic).map(|e| e / PRISMATIC_FULL_FORCE_ERROR));
    let damping = h.damping.or(stiffness.filter(|_| prismatic && h.stiffness.is_none()).map(|k| k * PRISMATIC_DAMPING_TIME));
    Ok(HandJoint { name: h.joint.clone(), joint: j, dof, preshape: h.preshape, close: h.close, effort, stiffness, damping })
}

/// The hand's listed joints, and the joints that follow them (`<mimic>`): every joint that moves
/// in the hand is one or the other.
fn hand(model: &RobotModel, specs: &[HandJointSpec], hand_root: usize) -> Result<(Vec<HandJoint>, Vec<usize>), Problem> {
    let mut hand = Vec::new();
    for (i, h) in specs.iter().enumerate() {
        hand.push(hand_joint(model, i, h, hand_root, &hand)?);
    }
    if hand.is_empty() {
        return Err(at([Seg::key("hand")], "no joints: a hand or gripper needs at least one"));
    }
    let mut followers = Vec::new();
    for (j, joint) in model.joints.iter().enumerate() {
        if !joint.moves() || !in_hand(model, j, hand_root) || hand.iter().any(|h| h.joint == j) {
            continue;
        }
        match joint.mimic {
            Some(m) if hand.iter().any(|h| h.joint == m.leader) => followers.push(j),
            _ => {
                return Err(at(
                    [Seg::key("hand")],
                    format!("joint '{}' moves in the hand but is neither listed nor a <mimic> of a listed joint", joint.name),
                ));
            }
        }
    }
    Ok((hand, followers))
}

/// Pad `i` of the description: its link in the hand, a unique name, its frame (a fixed child link,
/// or one added at its origin) and its size.
fn pad(model: &mut RobotModel, i: usize, p: &PadSpec, hand_root: usize, listed: &[Pad]) -> Result<Pad, Problem> {
    let here = |k: &'static str| [Seg::key("pads"), Seg::Index(i), Seg::key(k)];
    let on = link(model, here(key!(p.link)), &p.link)?;
    if !model.is_below(on, hand_root) {
        let root = &model.links[hand_root].name;
        return Err(at(here(key!(p.link)), format!("'{}' is not part of the hand (below '{root}')", p.link)));
    }
    if listed.iter().any(|o| o.name == p.name) || p.name.is_empty() || p.name.contains('/') {
        return Err(at(here(key!(p.name)), format!("'{}' must be unique, not empty and without '/'", p.name)));
    }
    let frame = match (&p.frame, &p.origin) {
        (Some(f), None) => {
            let id = link(model, here(key!(p.frame)), f)?;
            match model.links[id].parent_joint {
                Some(j) if model.joints[j].parent == on && !model.joints[j].moves() => id,
                _ => return Err(at(here(key!(p.frame)), format!("'{f}' is not a link fixed to '{}'", p.link))),
            }
        }
        (None, Some(o)) => {
            model.add_fixed_link(on, &format!("{}_pad", p.name), xyz_rpy(o.xyz, o.rpy)).map_err(|m| at(here(key!(p.origin)), m))?
        }
        _ => return Err(at(here(key!(p.frame)), "give either a frame link or an origin")),
    };
    let size = match p.size {
        Some([l, w]) if l > 0.0 && w > 0.0 && l.is_finite() && w.is_finite() => Some((l, w)),
        Some(s) => return Err(at(here(key!(p.size)), format!("{s:?}: length and width must be positive (m)"))),
        None => None,
    };
    let labels = p.labels.iter().chain(&p.group).cloned().collect();
    let contact = p.contact.unwrap_or_default();
    for (value, field, unit) in [(contact.modulus_mpa, "modulus_mpa", "MPa"), (contact.crown_radius_mm, "crown_radius_mm", "mm")] {
        if !(value > 0.0 && value.is_finite()) {
            return Err(at(
                [Seg::key("pads"), Seg::Index(i), Seg::key("contact"), Seg::key(field)],
                format!("{value}: must be positive ({unit})"),
            ));
        }
    }
    Ok(Pad { name: p.name.clone(), link: on, frame, size, labels, contact })
}

/// The links whose contact counts as touching: the description's, or the pads' links.
fn touch_links(model: &RobotModel, named: Option<&[String]>, pads: &[Pad], hand_root: usize) -> Result<Vec<usize>, Problem> {
    let Some(names) = named else {
        let mut links: Vec<usize> = Vec::new();
        for p in pads {
            if !links.contains(&p.link) {
                links.push(p.link);
            }
        }
        return Ok(links);
    };
    let mut links = Vec::new();
    for (i, name) in names.iter().enumerate() {
        let here = [Seg::key("touch_links"), Seg::Index(i)];
        let id = link(model, here.clone(), name)?;
        if !model.is_below(id, hand_root) {
            return Err(at(here, format!("'{name}' is not part of the hand")));
        }
        links.push(id);
    }
    Ok(links)
}

/// The collision meshes to decompose: the links named (each with a collision mesh), or `[all]`.
fn decomposition(model: &RobotModel, spec: &DecompositionSpec) -> Result<Decomposition, Problem> {
    let here = |k: &'static str| vec![Seg::key("convex_decomposition"), Seg::key(k)];
    let has_mesh = |l: usize| model.links[l].collisions.iter().any(|s| matches!(s.geometry, Geometry::Mesh { .. }));
    let links = if spec.links == ["all"] {
        (0..model.links.len()).filter(|&l| has_mesh(l)).collect()
    } else {
        let mut ids = Vec::new();
        for (i, name) in spec.links.iter().enumerate() {
            let mut field = here(key!(spec.links));
            field.push(Seg::Index(i));
            let id = link(model, field.clone(), name)?;
            if !has_mesh(id) {
                return Err(at(field, format!("'{name}' has no collision mesh to decompose")));
            }
            ids.push(id);
        }
        ids
    };
    if !(1..=64).contains(&spec.max_hulls) {
        return Err(at(here(key!(spec.max_hulls)), format!("{} is not within 1 ..= 64", spec.max_hulls)));
    }
    if !(16..=256).contains(&spec.resolution) {
        return Err(at(here(key!(spec.resolution)), format!("{} is not within 16 ..= 256", spec.resolution)));
    }
    Ok(Decomposition { links, max_hulls: spec.max_hulls, resolution: spec.resolution })
}

impl Robot {
    /// The URDF model checked against the description (`description_text` is the text it was
    /// parsed from, kept with the robot); errors name the description's field and its line.
    pub fn resolve(
        model: RobotModel,
        urdf_text: String,
        desc: Description,
        description_text: &str,
        source_name: &str,
    ) -> Result<Self, RobotError> {
        Robot::resolve_parts(model, urdf_text, desc, description_text).map_err(|problem| {
            let line = vt_check::locate::locate(description_text, &problem.path).map(|(l, _)| format!("line {l}: ")).unwrap_or_default();
            RobotError { source_name: source_name.to_string(), message: format!("{line}{problem}") }
        })
    }

    fn resolve_parts(mut model: RobotModel, urdf_text: String, desc: Description, description_text: &str) -> Result<Self, Problem> {
        let arm = Arm::resolve(&model, &desc.arm)?;
        let (grasp_frame, hand_root) = grasp_frame(&mut model, &desc.grasp, &desc.arm, arm.flange)?;
        let (hand, followers) = hand(&model, &desc.hand, hand_root)?;
        let mut pads = Vec::new();
        for (i, p) in desc.pads.iter().enumerate() {
            pads.push(pad(&mut model, i, p, hand_root, &pads)?);
        }
        if pads.is_empty() {
            return Err(at([Seg::key("pads")], "no pads: the tactile point cloud needs at least one"));
        }
        let touch_links = touch_links(&model, desc.touch_links.as_deref(), &pads, hand_root)?;
        let grasp = &desc.grasp;
        if grasp.kind == GraspKind::ParallelJaw && pads.len() < 2 {
            return Err(at([Seg::key("pads")], "a parallel-jaw grasp needs two pads, one on each jaw (the first two)"));
        }
        if grasp.min_touching == 0 || grasp.min_touching > touch_links.len() {
            return Err(at(
                [Seg::key("grasp"), Seg::key(key!(grasp.min_touching))],
                format!("{} is not within 1 ..= the {} touch links", grasp.min_touching, touch_links.len()),
            ));
        }
        let decomposition = desc.convex_decomposition.as_ref().map(|spec| decomposition(&model, spec)).transpose()?;
        let mut robot = Robot {
            name: desc.name,
            model,
            urdf_text,
            upstream_urdf_text: None,
            description_text: description_text.to_string(),
            arm_joints: arm.joints,
            arm_dofs: arm.dofs,
            base: arm.base,
            flange: arm.flange,
            home: desc.arm.home,
            azimuth_offset: 0.0,
            grasp_frame,
            hand_root,
            kind: grasp.kind,
            min_touching: grasp.min_touching,
            hand,
            followers,
            pads,
            touch_links,
            decomposition,
            sensors: desc.sensors,
            hand_collision: desc.hand_collision,
        };
        robot.azimuth_offset = match desc.arm.azimuth_offset {
            Some(a) => a,
            None => robot.measured_azimuth_offset(),
        };
        Ok(robot)
    }
}

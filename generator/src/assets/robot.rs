//! The built-in robots' real visual meshes, in vtgen's link frames: the Allegro hand v4 (binary
//! STL), the UR5e (OBJ + MTL) and the Robotiq 2F-85 (OBJ). `scripts/robot-assets` fetches them from
//! PyPI by package name into
//!
//! ```text
//! DIR/allegro/meshes/*.STL         example-robot-data 6.0.0 (allegro_hand_description/meshes)
//! DIR/ur5e/visual/*.obj            airo-models 0.0.12 (arms/ur5e/visual)
//! DIR/robotiq_2f85/visual/*.obj    airo-models 0.0.12 (grippers/robotiq_2f_85/meshes/visual)
//! ```
//!
//! (`../shared/assets` has the same layout). Frames:
//! - each hand mesh is in its link's frame of the SimLab/Wonik `allegro_hand_description` URDF,
//!   whose joint origins `robots/allegro/robot.urdf` uses unchanged: identity, plus the
//!   fingertip meshes at the tip joint (0.0267 m, thumb 0.0423 m along the distal link's z);
//! - each arm mesh sits in its link of Universal Robots' ROS description through that URDF's
//!   visual origin (`ROS_CHAIN`); the ROS link frames differ from the DH link frames of our
//!   URDF by a fixed offset per link, computed from both chains at q = 0 (`ros_link_offsets`,
//!   unit-tested to hold at any q).
//!
//! - each 2F-85 mesh is in its link's frame of airo-models' `robotiq_2f_85.urdf`, whose joint
//!   origins `robots/robotiq_2f85/robot.urdf` uses unchanged (its `gripper_body` is the
//!   package's `base_link_inertia`); the finger meshes are in millimetres.
//!
//! Colours: the hand black with white fingertips (as the URDF's materials), the arm its MTL
//! colours (UR blue, joint grey, black), the gripper its URDF colours, baked into a small palette
//! texture per link.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use glam::{DAffine3, DQuat, DVec3, Vec3};
use vt_objects::{Texture, TexturedMesh, linear_to_srgb8};
use vt_robot::{Robot, RobotModel, xyz_rpy};

use crate::config::LoadedConfig;

/// The hand's URDF colours (linear RGB, as `robots/allegro/robot.urdf`'s materials).
const HAND_BLACK: [f64; 3] = [0.2, 0.2, 0.2];
const TIP_WHITE: [f64; 3] = [0.9, 0.9, 0.9];
/// Fingertip mesh origins along the distal link's z (the URDF's fixed tip joints).
const FINGER_TIP_Z: f64 = 0.0267;
const THUMB_TIP_Z: f64 = 0.0423;
/// The simplifier's error bound, relative to a mesh's extent: 0.2 % of the upper arm's 0.5 m is
/// 1 mm, under a pixel of the paper camera at the arm's distance (about 1.6 mm at 1 m).
const MAX_SIMPLIFY_ERROR: f32 = 0.002;
/// Faces whose normals differ by more than this keep a hard edge between them (CAD meshes have
/// sharp edges that averaged normals would round off).
const CREASE_DEG: f32 = 40.0;

/// The built-in robots drawn from primitive URDFs whose real meshes `scripts/robot-assets`
/// fetches, matched to their links by the tables below (robots whose URDF names its own meshes,
/// as the Panda's does, need none of this).
pub const ROBOTS_WITH_MESHES: [&str; 2] = [ROBOT_COLLIDING_AS_MESHES, "ur5e_robotiq_2f85"];
/// The one of them whose hand collides as its real meshes' hulls when the run has them (the
/// 2F-85 keeps its URDF's boxes).
const ROBOT_COLLIDING_AS_MESHES: &str = "ur5e_allegro";

pub fn collides_as_real_meshes(robot: &str) -> bool {
    robot == ROBOT_COLLIDING_AS_MESHES
}

/// The folders of a robot mesh directory the loaders read for robot `name` (`scripts/robot-assets`
/// fills them).
pub fn mesh_dirs(name: &str) -> &'static [&'static str] {
    match name {
        "ur5e_robotiq_2f85" => &["robotiq_2f85/visual", "ur5e/visual"],
        _ => &["allegro/meshes", "ur5e/visual"],
    }
}

/// Triangles per arm link after simplification: the arm is a background occluder seen at a few
/// hundred pixels; the full meshes have 126 000 triangles in all.
pub const ARM_TRIANGLES_PER_LINK: usize = 3000;
/// Triangles per hand mesh file drawn (the physics and the pads use the whole meshes): the
/// simplifier's error bound keeps the silhouette within a pixel (`tests/robot_meshes.rs`).
pub const HAND_TRIANGLES_PER_PART: usize = 400;

/// The robot mesh directory a run draws from: `--robot-assets` over the config's `robot.assets`
/// (relative to the config file); None: the primitive robot.
pub fn robot_assets_dir(cfg: &LoadedConfig) -> Option<PathBuf> {
    cfg.robot_assets.clone()
}

/// One mesh file placed in a link frame, with the colour it is drawn in (None: the OBJ's own
/// material colours).
struct Part {
    file: String,
    origin: DAffine3,
    colour: Option<[f64; 3]>,
}

fn stl(file: &str, origin: DAffine3, colour: [f64; 3]) -> Part {
    Part { file: format!("allegro/meshes/{file}"), origin, colour: Some(colour) }
}

/// The hand link's mesh files (our link names; the SimLab names in the comments).
fn hand_parts(link: &str) -> Option<Vec<Part>> {
    let id = DAffine3::IDENTITY;
    let tip = |z: f64, file: &str| stl(file, DAffine3::from_translation(DVec3::new(0.0, 0.0, z)), TIP_WHITE);
    Some(match link {
        "palm" => vec![stl("base_link.STL", id, HAND_BLACK)],
        // link_0.0 / link_4.0 / link_8.0 and their children: the three fingers share meshes.
        "ff_base" | "mf_base" | "rf_base" => vec![stl("link_0.0.STL", id, HAND_BLACK)],
        "ff_proximal" | "mf_proximal" | "rf_proximal" => vec![stl("link_1.0.STL", id, HAND_BLACK)],
        "ff_medial" | "mf_medial" | "rf_medial" => vec![stl("link_2.0.STL", id, HAND_BLACK)],
        "ff_distal" | "mf_distal" | "rf_distal" => {
            vec![stl("link_3.0.STL", id, HAND_BLACK), tip(FINGER_TIP_Z, "link_3.0_tip.STL")]
        }
        "th_base" => vec![stl("link_12.0_right.STL", id, HAND_BLACK)],
        "th_proximal" => vec![stl("link_13.0.STL", id, HAND_BLACK)],
        "th_medial" => vec![stl("link_14.0.STL", id, HAND_BLACK)],
        "th_distal" => vec![stl("link_15.0.STL", id, HAND_BLACK), tip(THUMB_TIP_Z, "link_15.0_tip.STL")],
        _ => return None,
    })
}

/// The 2F-85's link mesh files (airo-models 0.0.12, its visual OBJs: the body's in metres, the
/// rest in millimetres), in our link frames (the package's, for these links) and the URDF's colours.
fn gripper_parts(link: &str) -> Option<Vec<Part>> {
    let mm = DAffine3::from_scale(DVec3::splat(0.001));
    let part =
        |file: &str, origin: DAffine3, colour: [f64; 3]| Part { file: format!("robotiq_2f85/visual/{file}"), origin, colour: Some(colour) };
    const BLACK: [f64; 3] = [0.1, 0.1, 0.1];
    const KNUCKLE: [f64; 3] = [0.79, 0.82, 0.93];
    Some(match link {
        "gripper_body" => vec![part("robotiq_arg2f_85_base_link.obj", DAffine3::IDENTITY, BLACK)],
        "left_outer_knuckle" | "right_outer_knuckle" => vec![part("robotiq_arg2f_85_outer_knuckle.obj", mm, KNUCKLE)],
        "left_outer_finger" | "right_outer_finger" => vec![part("robotiq_arg2f_85_outer_finger.obj", mm, BLACK)],
        "left_inner_finger" | "right_inner_finger" => vec![part("robotiq_arg2f_85_inner_finger.obj", mm, BLACK)],
        "left_inner_knuckle" | "right_inner_knuckle" => vec![part("robotiq_arg2f_85_inner_knuckle.obj", mm, BLACK)],
        _ => return None,
    })
}

/// One link of Universal Robots' ROS description of the UR5e, as far as the meshes need it.
struct RosLink {
    /// Our URDF's name of the link.
    link: &'static str,
    /// The ROS joint origin that leads to it (xyz, rpy).
    joint: ([f64; 3], [f64; 3]),
    mesh: &'static str,
    /// The mesh's visual origin in the ROS link (xyz, rpy).
    visual: ([f64; 3], [f64; 3]),
}

/// The UR5e from `ur5e.urdf` of airo-models 0.0.12 (its `base_link_inertia` is our `base_link`:
/// the DH base frame).
const ROS_CHAIN: [RosLink; 7] = {
    use std::f64::consts::{FRAC_PI_2 as H, PI};
    const Z: [f64; 3] = [0.0; 3];
    [
        RosLink { link: "base_link", joint: (Z, Z), mesh: "base.obj", visual: (Z, [0.0, 0.0, PI]) },
        RosLink { link: "shoulder_pan_link", joint: ([0.0, 0.0, 0.1625], Z), mesh: "shoulder.obj", visual: (Z, [0.0, 0.0, PI]) },
        RosLink { link: "shoulder_lift_link", joint: (Z, [H, 0.0, 0.0]), mesh: "upperarm.obj", visual: ([0.0, 0.0, 0.138], [H, 0.0, -H]) },
        RosLink { link: "elbow_link", joint: ([-0.425, 0.0, 0.0], Z), mesh: "forearm.obj", visual: ([0.0, 0.0, 0.007], [H, 0.0, -H]) },
        RosLink {
            link: "wrist_1_link",
            joint: ([-0.3922, 0.0, 0.1333], Z),
            mesh: "wrist1.obj",
            visual: ([0.0, 0.0, -0.127], [H, 0.0, 0.0]),
        },
        RosLink { link: "wrist_2_link", joint: ([0.0, -0.0997, 0.0], [H, 0.0, 0.0]), mesh: "wrist2.obj", visual: ([0.0, 0.0, -0.0997], Z) },
        RosLink {
            link: "wrist_3_link",
            joint: ([0.0, 0.0996, 0.0], [H, PI, PI]),
            mesh: "wrist3.obj",
            visual: ([0.0, 0.0, -0.0989], [H, 0.0, 0.0]),
        },
    ]
};

/// Per arm link of `ROS_CHAIN`: the ROS link frame in our link frame (both chains at q = 0; both
/// turn each joint about its local z, so the offset holds at any q: see the unit test).
pub fn ros_link_offsets(model: &RobotModel) -> Result<Vec<(usize, DAffine3)>> {
    let ours = model.forward_kinematics(&vec![0.0; model.dof_count()]);
    let base = model.link_id("base_link").context("robot description has no base_link")?;
    let mut t_base_ros = DAffine3::IDENTITY;
    let mut out = Vec::new();
    for RosLink { link, joint: (xyz, r), .. } in ROS_CHAIN {
        let id = model.link_id(link).with_context(|| format!("robot description has no link '{link}'"))?;
        t_base_ros *= xyz_rpy(xyz, r);
        out.push((id, ours[id].inverse() * ours[base] * t_base_ros));
    }
    Ok(out)
}

fn check_layout(dir: &Path, probe: &str, what: &str) -> Result<()> {
    if !dir.join(probe).is_file() {
        bail!(
            "robot assets {}: no {what} meshes ({} is missing). Fetch them with `scripts/robot-assets` (it prints the directory), \
             or point --robot-assets at a directory with its layout (ur5e/visual/, allegro/meshes/, robotiq_2f85/visual/)",
            dir.display(),
            dir.join(probe).display()
        );
    }
    Ok(())
}

/// The real meshes a built-in robot is drawn with (`ROBOTS_WITH_MESHES`), as
/// [`load_robot_meshes`] gives them.
pub fn load_drawn_meshes(dir: &Path, robot: &Robot, simplified: bool) -> Result<HashMap<usize, TexturedMesh>> {
    match robot.name.as_str() {
        "ur5e_robotiq_2f85" => {
            check_layout(dir, "robotiq_2f85/visual/robotiq_arg2f_85_inner_finger.obj", "Robotiq 2F-85")?;
            let mut out = HashMap::new();
            for (id, link) in robot.model.links.iter().enumerate() {
                if let Some(parts) = gripper_parts(&link.name) {
                    out.insert(id, build_link_mesh(dir, &parts, simplified.then_some(HAND_TRIANGLES_PER_PART))?);
                }
            }
            out.extend(load_arm_meshes(dir, &robot.model, if simplified { ARM_TRIANGLES_PER_LINK } else { usize::MAX })?);
            Ok(out)
        }
        _ => load_robot_meshes(dir, &robot.model, simplified),
    }
}

/// The real meshes of every robot link that has one, in the link frame, as drawn: link index ->
/// mesh. `simplified`: the arm links to about `ARM_TRIANGLES_PER_LINK` and the hand's mesh files
/// to about `HAND_TRIANGLES_PER_PART` triangles (within the simplifier's error bound); else whole.
pub fn load_robot_meshes(dir: &Path, model: &RobotModel, simplified: bool) -> Result<HashMap<usize, TexturedMesh>> {
    let mut out = load_hand_meshes(dir, model, simplified.then_some(HAND_TRIANGLES_PER_PART))?;
    out.extend(load_arm_meshes(dir, model, if simplified { ARM_TRIANGLES_PER_LINK } else { usize::MAX })?);
    Ok(out)
}

/// The Allegro hand's meshes (palm, bases, phalanges) in our link frames, each mesh file
/// simplified to about `max_triangles` (None: whole, as the physics and the pads use them).
pub fn load_hand_meshes(dir: &Path, model: &RobotModel, max_triangles: Option<usize>) -> Result<HashMap<usize, TexturedMesh>> {
    check_layout(dir, "allegro/meshes/base_link.STL", "Allegro hand")?;
    let mut out = HashMap::new();
    for (id, link) in model.links.iter().enumerate() {
        if let Some(parts) = hand_parts(&link.name) {
            out.insert(id, build_link_mesh(dir, &parts, max_triangles)?);
        }
    }
    Ok(out)
}

/// The UR5e's meshes, each link simplified to about `arm_triangles`, in our link frames.
pub fn load_arm_meshes(dir: &Path, model: &RobotModel, arm_triangles: usize) -> Result<HashMap<usize, TexturedMesh>> {
    check_layout(dir, "ur5e/visual/upperarm.obj", "UR5e")?;
    let mut out = HashMap::new();
    for (k, (id, offset)) in ros_link_offsets(model)?.into_iter().enumerate() {
        let RosLink { mesh, visual: (xyz, r), .. } = ROS_CHAIN[k];
        let part = Part { file: format!("ur5e/visual/{mesh}"), origin: offset * xyz_rpy(xyz, r), colour: None };
        out.insert(id, build_link_mesh(dir, &[part], Some(arm_triangles))?);
    }
    Ok(out)
}

/// The robot with its hand on the real meshes: each hand link collides as the convex hull of its
/// mesh (for rapier and MuJoCo alike; only the hull's vertices are kept), and each pad sits on
/// its link's real palmar surface at mid-length of its sensing span ([`pad_on_surface`]). The
/// visual shapes stay the URDF's (the renderer draws the meshes).
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

/// The pad frame on the palmar (+x) surface of a phalanx, at height `z` along the finger: origin
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

/// Triangles of one mesh file in its own frame, with a colour per triangle (linear RGB).
pub struct RawMesh {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub colours: Vec<[f64; 3]>,
}

/// Triangles per link drawn from a URDF's own visual meshes: as the built-in arm's links, within
/// the simplifier's error bound.
pub const URDF_MESH_TRIANGLES_PER_LINK: usize = ARM_TRIANGLES_PER_LINK;

/// A link's triangles (link frame) as the renderer draws them: vertices welded, simplified to
/// about `max_triangles` within `MAX_SIMPLIFY_ERROR` of the extent, creased normals, a palette.
pub fn drawable_link(raw: RawMesh, max_triangles: usize) -> TexturedMesh {
    let raw = simplify(weld(raw), max_triangles);
    drawable(&raw.positions, &raw.triangles, &raw.colours)
}

/// One robot mesh part as read from disk: positions, triangles, a colour per triangle.
/// (Public for the fuzz targets, `tests/fuzz`.)
pub fn read_stl(path: &Path, colour: [f64; 3]) -> Result<RawMesh> {
    let mut f = std::fs::File::open(path).with_context(|| format!("robot mesh {}: cannot open", path.display()))?;
    let m = stl_io::read_stl(&mut f).map_err(|e| anyhow::anyhow!("robot mesh {}: not a valid STL file: {e}", path.display()))?;
    let positions: Vec<Vec3> = m.vertices.iter().map(|v| Vec3::new(v[0], v[1], v[2])).collect();
    let n = positions.len();
    let mut triangles = Vec::with_capacity(m.faces.len());
    for f in &m.faces {
        if f.vertices.iter().any(|&i| i >= n) {
            bail!("robot mesh {}: a face refers to a vertex that does not exist", path.display());
        }
        triangles.push(f.vertices.map(|i| i as u32));
    }
    Ok(RawMesh { colours: vec![colour; triangles.len()], positions, triangles })
}

/// An arm mesh part (OBJ + MTL) as read from disk (public for the fuzz targets, `tests/fuzz`).
pub fn read_obj(path: &Path) -> Result<RawMesh> {
    let opts = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let (models, materials) =
        vt_objects::load_obj_file(path, &opts).map_err(|e| anyhow::anyhow!("robot mesh {}: not a valid OBJ file: {e}", path.display()))?;
    let materials = materials.unwrap_or_default();
    let mut raw = RawMesh { positions: Vec::new(), triangles: Vec::new(), colours: Vec::new() };
    for m in &models {
        let base = raw.positions.len() as u32;
        let n = (m.mesh.positions.len() / 3) as u32;
        raw.positions.extend(m.mesh.positions.chunks_exact(3).map(|p| Vec3::new(p[0], p[1], p[2])));
        let kd = m.mesh.material_id.and_then(|id| materials.get(id)).and_then(|mat| mat.diffuse).unwrap_or([0.6, 0.6, 0.6]);
        for t in m.mesh.indices.chunks_exact(3) {
            if t.iter().any(|&i| i >= n) {
                bail!("robot mesh {}: a face refers to a vertex that does not exist", path.display());
            }
            raw.triangles.push([t[0] + base, t[1] + base, t[2] + base]);
            raw.colours.push(kd.map(|c| c as f64));
        }
    }
    Ok(raw)
}

/// Reads `parts`, welds vertices, simplifies to `max_triangles` (when given), places them in the
/// link frame and builds the drawable mesh: creased normals, a palette texture of the colours.
fn build_link_mesh(dir: &Path, parts: &[Part], max_triangles: Option<usize>) -> Result<TexturedMesh> {
    let mut positions: Vec<Vec3> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut colours: Vec<[f64; 3]> = Vec::new();
    for part in parts {
        let path = dir.join(&part.file);
        if !path.is_file() {
            bail!("robot mesh {}: file not found", path.display());
        }
        let raw = match (part.colour, part.file.ends_with(".obj")) {
            (Some(c), false) => read_stl(&path, c)?,
            (Some(c), true) => {
                let mut raw = read_obj(&path)?;
                raw.colours.iter_mut().for_each(|x| *x = c);
                raw
            }
            (None, _) => read_obj(&path)?,
        };
        if raw.triangles.is_empty() {
            bail!("robot mesh {}: contains no triangles", path.display());
        }
        if raw.positions.iter().any(|p| !p.is_finite()) {
            bail!("robot mesh {}: contains non-finite vertex coordinates", path.display());
        }
        let mut raw = weld(raw);
        if let Some(max) = max_triangles {
            raw = simplify(raw, max);
        }
        let base = positions.len() as u32;
        let o = part.origin;
        positions.extend(raw.positions.iter().map(|p| o.transform_point3(p.as_dvec3()).as_vec3()));
        triangles.extend(raw.triangles.iter().map(|t| t.map(|i| i + base)));
        colours.extend(raw.colours);
    }
    Ok(drawable(&positions, &triangles, &colours))
}

/// Merges vertices at the same position (STL repeats them per facet; OBJ per normal), so that
/// simplification and normals see the surface as connected.
fn weld(raw: RawMesh) -> RawMesh {
    let mut index: HashMap<[u32; 3], u32> = HashMap::new();
    let mut positions = Vec::new();
    let remap: Vec<u32> = raw
        .positions
        .iter()
        .map(|p| {
            *index.entry(p.to_array().map(f32::to_bits)).or_insert_with(|| {
                positions.push(*p);
                positions.len() as u32 - 1
            })
        })
        .collect();
    let mut triangles = Vec::with_capacity(raw.triangles.len());
    let mut colours = Vec::with_capacity(raw.triangles.len());
    for (t, c) in raw.triangles.iter().zip(&raw.colours) {
        let t = t.map(|i| remap[i as usize]);
        if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
            triangles.push(t);
            colours.push(*c);
        }
    }
    RawMesh { positions, triangles, colours }
}

/// Simplifies each colour's triangles separately (so that colour borders stay where they are)
/// to about `max_triangles` in all, with meshoptimizer's edge-collapse simplifier.
fn simplify(raw: RawMesh, max_triangles: usize) -> RawMesh {
    if raw.triangles.len() <= max_triangles {
        return raw;
    }
    let vertices: Vec<[f32; 3]> = raw.positions.iter().map(|p| p.to_array()).collect();
    let adapter = meshopt::VertexDataAdapter::new(bytemuck::cast_slice(&vertices), 12, 0).expect("tightly packed f32x3");
    let mut groups: Vec<([f64; 3], Vec<u32>)> = Vec::new();
    for (t, c) in raw.triangles.iter().zip(&raw.colours) {
        match groups.iter_mut().find(|(gc, _)| gc == c) {
            Some((_, idx)) => idx.extend_from_slice(t),
            None => groups.push((*c, t.to_vec())),
        }
    }
    let ratio = max_triangles as f64 / raw.triangles.len() as f64;
    let mut triangles = Vec::new();
    let mut colours = Vec::new();
    for (c, idx) in groups {
        let target = ((idx.len() as f64 * ratio) as usize / 3).max(1) * 3;
        // Stops at the target count or when the next collapse would move the surface by more than
        // `MAX_SIMPLIFY_ERROR` of the mesh's extent, whichever comes first.
        let kept = meshopt::simplify(&idx, &adapter, target, MAX_SIMPLIFY_ERROR, meshopt::SimplifyOptions::LockBorder, None);
        for t in kept.chunks_exact(3) {
            triangles.push([t[0], t[1], t[2]]);
            colours.push(c);
        }
    }
    RawMesh { positions: raw.positions, triangles, colours }
}

/// The mesh the renderer draws: every triangle with its own three vertices (positions shared
/// only through the normals), normals averaged over the faces around a vertex within
/// `CREASE_DEG` of the triangle's own, and texture coordinates into a palette of the colours.
fn drawable(positions: &[Vec3], triangles: &[[u32; 3]], colours: &[[f64; 3]]) -> TexturedMesh {
    let mut palette: Vec<[f64; 3]> = Vec::new();
    for c in colours {
        if !palette.contains(c) {
            palette.push(*c);
        }
    }
    let face_normal = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        (b - a).cross(c - a)
    };
    let normals: Vec<Vec3> = triangles.iter().map(face_normal).collect();
    let mut around: Vec<Vec<u32>> = vec![Vec::new(); positions.len()];
    for (f, t) in triangles.iter().enumerate() {
        for &v in t {
            around[v as usize].push(f as u32);
        }
    }
    let cos_crease = CREASE_DEG.to_radians().cos();
    let mut mesh = TexturedMesh {
        positions: Vec::with_capacity(triangles.len() * 3),
        normals: Vec::with_capacity(triangles.len() * 3),
        uvs: Vec::with_capacity(triangles.len() * 3),
        indices: (0..triangles.len() as u32 * 3).collect(),
        texture: Texture {
            width: palette.len() as u32,
            height: 1,
            rgba: palette.iter().flat_map(|c| [c[0], c[1], c[2], 1.0].map(linear_to_srgb8)).collect(),
        },
    };
    for (f, t) in triangles.iter().enumerate() {
        let own = normals[f].normalize_or_zero();
        let k = palette.iter().position(|c| c == &colours[f]).expect("in the palette");
        let uv = [(k as f32 + 0.5) / palette.len() as f32, 0.5];
        for &v in t {
            let n: Vec3 =
                around[v as usize].iter().map(|&g| normals[g as usize]).filter(|n| n.normalize_or_zero().dot(own) >= cos_crease).sum();
            mesh.positions.push(positions[v as usize].to_array());
            mesh.normals.push(n.normalize_or(own).to_array());
            mesh.uvs.push(uv);
        }
    }
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ros_link_frames_ride_on_ours_at_any_joint_values() {
        let robot = Robot::allegro();
        let model = &robot.model;
        let offsets = ros_link_offsets(model).unwrap();
        let arm = &robot.arm_dofs;
        for k in 0..20 {
            let mut q = vec![0.0; model.dof_count()];
            for (i, &d) in arm.iter().enumerate() {
                q[d] = ((k * 7 + i * 3) % 11) as f64 * 0.57 - 2.8;
            }
            let ours = model.forward_kinematics(&q);
            // The ROS chain at the same joint values, from its base (= our base_link).
            let base = model.link_id("base_link").unwrap();
            let mut t = ours[base];
            for (i, (id, offset)) in offsets.iter().enumerate() {
                let RosLink { joint: (xyz, r), .. } = ROS_CHAIN[i];
                t *= xyz_rpy(xyz, r);
                if i > 0 {
                    t *= DAffine3::from_rotation_z(q[arm[i - 1]]);
                }
                let via_ours = ours[*id] * *offset;
                assert!(via_ours.translation.distance(t.translation) < 1e-9, "link {i} at q {q:?}");
                assert!(via_ours.matrix3.abs_diff_eq(t.matrix3, 1e-9), "link {i}");
            }
        }
    }

    #[test]
    fn creased_normals_keep_a_cube_flat_and_the_palette_holds_each_colour_once() {
        let p = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.], [0., 0., 1.], [1., 0., 1.], [1., 1., 1.], [0., 1., 1.]]
            .map(Vec3::from_array);
        let tris = [
            [0, 2, 1],
            [0, 3, 2],
            [4, 5, 6],
            [4, 6, 7],
            [0, 1, 5],
            [0, 5, 4],
            [2, 3, 7],
            [2, 7, 6],
            [1, 2, 6],
            [1, 6, 5],
            [0, 4, 7],
            [0, 7, 3],
        ];
        let colours: Vec<[f64; 3]> = (0..12).map(|i| if i < 2 { TIP_WHITE } else { HAND_BLACK }).collect();
        let m = drawable(&p, &tris, &colours);
        assert_eq!((m.positions.len(), m.texture.width), (36, 2));
        for (t, tri) in m.indices.chunks_exact(3).zip(&tris) {
            let face = (p[tri[1] as usize] - p[tri[0] as usize]).cross(p[tri[2] as usize] - p[tri[0] as usize]).normalize();
            for &i in t {
                assert!(Vec3::from(m.normals[i as usize]).dot(face) > 0.9999, "a cube's faces stay flat");
            }
        }
        assert!(m.uvs[0][0] < 0.5 && m.uvs[35][0] > 0.5, "white on the first faces, black on the rest");
    }
}

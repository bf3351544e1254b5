use std::collections::HashMap;

use glam::{DAffine3, DQuat, DVec3};

use crate::mesh::{MeshCache, MeshPaths, TriangleMesh};

/// A robot description that cannot be used; names what is wrong.
#[derive(Debug, thiserror::Error)]
#[error("robot description {source_name}: {message}")]
pub struct RobotError {
    pub source_name: String,
    pub message: String,
}

#[derive(Debug, Clone, PartialEq)]
pub enum Geometry {
    Box {
        size: DVec3,
    },
    Cylinder {
        radius: f64,
        length: f64,
    },
    Sphere {
        radius: f64,
    },
    /// The convex hull of these points (a real link mesh's vertices: see
    /// [`RobotModel::with_mesh_collisions`]).
    ConvexHull {
        points: std::sync::Arc<Vec<DVec3>>,
    },
    /// A URDF `<mesh>` read from its file (scaled): drawn as its triangles; a collision mesh
    /// collides as the convex hull of its vertices ([`Geometry::hull_points`]).
    Mesh {
        mesh: std::sync::Arc<TriangleMesh>,
    },
}

impl Geometry {
    /// The points whose convex hull is the collision shape of a hull or a mesh.
    pub fn hull_points(&self) -> Option<&[DVec3]> {
        match self {
            Geometry::ConvexHull { points } => Some(points),
            Geometry::Mesh { mesh } => Some(mesh.distinct_points()),
            _ => None,
        }
    }
}

/// A shape placed in its link's frame, with an sRGB-ish colour (0..1, from the URDF material).
#[derive(Debug, Clone, PartialEq)]
pub struct Shape {
    pub geometry: Geometry,
    pub origin: DAffine3,
    pub rgba: [f64; 4],
}

#[derive(Debug, Clone, PartialEq)]
pub struct Link {
    pub name: String,
    pub mass: f64,
    /// Centre of mass in the link frame.
    pub com: DVec3,
    pub visuals: Vec<Shape>,
    pub collisions: Vec<Shape>,
    /// The joint whose child this link is (None for the root).
    pub parent_joint: Option<usize>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    Revolute,
    Prismatic,
    Fixed,
}

/// A URDF `<mimic>`: this joint's value is `multiplier * leader + offset` (the leader is a joint
/// with a degree of freedom of its own).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mimic {
    pub leader: usize,
    pub multiplier: f64,
    pub offset: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    pub name: String,
    pub kind: JointKind,
    pub parent: usize,
    pub child: usize,
    /// Child joint frame in the parent link frame at q = 0.
    pub origin: DAffine3,
    pub axis: DVec3,
    pub lower: f64,
    pub upper: f64,
    pub effort: f64,
    pub velocity: f64,
    /// Position in the robot's vector of joint values (moving joints that mimic no other).
    pub dof: Option<usize>,
    pub mimic: Option<Mimic>,
}

impl Joint {
    /// Revolute or prismatic.
    pub fn moves(&self) -> bool {
        self.kind != JointKind::Fixed
    }
}

/// The kinematic model. Joint values are a `Vec<f64>` with one entry per moving joint that mimics
/// no other, in the order of [`RobotModel::dof_names`].
#[derive(Debug, Clone)]
pub struct RobotModel {
    pub links: Vec<Link>,
    /// Topologically ordered: a joint comes after the joint of its parent link.
    pub joints: Vec<Joint>,
    pub root: usize,
    dofs: Vec<usize>,
    link_index: HashMap<String, usize>,
    joint_index: HashMap<String, usize>,
    /// The mesh files the URDF's geometry was read from, each once, in the order first met.
    pub mesh_files: Vec<std::path::PathBuf>,
    /// Visual meshes left out because their files are not there ([`VisualMeshes::Optional`]), as
    /// the URDF names them: their links are drawn from their primitive visuals.
    pub visual_meshes_left_out: Vec<String>,
}

/// Whether a URDF's visual meshes must be found (`drawn_meshes` in a robot description).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VisualMeshes {
    /// Every mesh file must be found.
    #[default]
    Required,
    /// A robot drawn from its primitive visuals unless its meshes are there (the built-in robots,
    /// whose meshes come with the robot assets): a link with visual meshes is drawn from them
    /// alone when they are found, from its primitive visuals alone when none are; some found and
    /// some not is an error (a robot half real, half primitive would pass silently).
    Optional,
}

/// The colour of a visual mesh the URDF gives no colour: drawn in its file's own colours.
pub const NO_RGBA: [f64; 4] = [-1.0; 4];

fn pose(p: &urdf_rs::Pose) -> DAffine3 {
    xyz_rpy(p.xyz.0, p.rpy.0)
}

/// A URDF `<origin xyz rpy>`: fixed-axis roll about x, then pitch about y, then yaw about z
/// (R = Rz * Ry * Rx), then the translation.
pub fn xyz_rpy(xyz: [f64; 3], rpy: [f64; 3]) -> DAffine3 {
    let [r, p, y] = rpy;
    let rot = DQuat::from_rotation_z(y) * DQuat::from_rotation_y(p) * DQuat::from_rotation_x(r);
    DAffine3::from_rotation_translation(rot, DVec3::from_array(xyz))
}

impl RobotModel {
    pub fn from_urdf_file(path: &std::path::Path) -> Result<Self, RobotError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| RobotError { source_name: path.display().to_string(), message: format!("cannot read: {e}") })?;
        Self::from_urdf(&text, &path.display().to_string(), &MeshPaths::beside(path))
    }

    /// A URDF given as text, without mesh geometry (its files could not be found).
    pub fn from_urdf_str(text: &str, source_name: &str) -> Result<Self, RobotError> {
        Self::from_urdf(text, source_name, &MeshPaths::default())
    }

    /// A URDF whose `<mesh>` files are found through `paths`. Every mesh problem (a missing file, an
    /// unreadable one) is listed in one error; every other names its link or joint.
    pub fn from_urdf(text: &str, source_name: &str, paths: &MeshPaths) -> Result<Self, RobotError> {
        Self::from_urdf_with(text, source_name, paths, VisualMeshes::Required)
    }

    /// `from_urdf` with the visual meshes required or optional.
    pub fn from_urdf_with(text: &str, source_name: &str, paths: &MeshPaths, visual_meshes: VisualMeshes) -> Result<Self, RobotError> {
        let err = |message: String| RobotError { source_name: source_name.to_string(), message };
        let urdf = urdf_rs::read_from_string(text).map_err(|e| err(format!("not valid URDF: {e}")))?;
        let mut meshes = MeshCache::default();
        let (mut links, link_index, visual_meshes_left_out) = read_links(&urdf, paths, &mut meshes, visual_meshes).map_err(err)?;
        let mut joints = Vec::new();
        let mut joint_index = HashMap::new();
        for j in &urdf.joints {
            let joint = read_joint(j, &link_index).map_err(err)?;
            if links[joint.child].parent_joint.is_some() {
                return Err(err(format!("link '{}' is the child of two joints", j.child.link)));
            }
            links[joint.child].parent_joint = Some(joints.len());
            joint_index.insert(j.name.clone(), joints.len());
            joints.push(joint);
        }
        resolve_mimics(&urdf, &mut joints, &joint_index).map_err(err)?;
        let (root, mut joints, joint_index) = topological_order(&mut links, joints, joint_index).map_err(err)?;
        let mut dofs = Vec::new();
        for (i, j) in joints.iter_mut().enumerate() {
            if j.moves() && j.mimic.is_none() {
                j.dof = Some(dofs.len());
                dofs.push(i);
            }
        }
        Ok(RobotModel { links, joints, root, dofs, link_index, joint_index, mesh_files: meshes.files(), visual_meshes_left_out })
    }

    /// This model with the collision shapes of the given links replaced by the convex hull of
    /// each link's points (link frame): physics then touches the real surfaces the picture shows.
    pub fn with_mesh_collisions(&self, hulls: &HashMap<usize, Vec<DVec3>>) -> RobotModel {
        let mut m = self.clone();
        for (&link, points) in hulls {
            m.links[link].collisions = vec![Shape {
                geometry: Geometry::ConvexHull { points: std::sync::Arc::new(points.clone()) },
                origin: DAffine3::IDENTITY,
                rgba: [0.0; 4],
            }];
        }
        m
    }

    /// Adds a massless link without geometry fixed to `parent` at `origin` (a sensor pad's frame).
    pub fn add_fixed_link(&mut self, parent: usize, name: &str, origin: DAffine3) -> Result<usize, String> {
        if self.link_index.contains_key(name) {
            return Err(format!("a link named '{name}' exists already"));
        }
        let link = self.links.len();
        let joint = self.joints.len();
        self.links.push(Link {
            name: name.to_string(),
            mass: 0.0,
            com: DVec3::ZERO,
            visuals: Vec::new(),
            collisions: Vec::new(),
            parent_joint: Some(joint),
        });
        self.link_index.insert(name.to_string(), link);
        let joint_name = format!("{name}_joint");
        self.joint_index.insert(joint_name.clone(), joint);
        // Appended last: still after its parent's joint, as the topological order requires.
        self.joints.push(Joint {
            name: joint_name,
            kind: JointKind::Fixed,
            parent,
            child: link,
            origin,
            axis: DVec3::Z,
            lower: 0.0,
            upper: 0.0,
            effort: 0.0,
            velocity: 0.0,
            dof: None,
            mimic: None,
        });
        Ok(link)
    }

    /// Moves a fixed child link (a sensor pad) to `origin` in its parent link's frame.
    pub fn set_fixed_link_origin(&mut self, link: &str, origin: DAffine3) -> Result<(), String> {
        let id = self.link_id(link).ok_or_else(|| format!("no link '{link}'"))?;
        let j = self.links[id].parent_joint.ok_or_else(|| format!("link '{link}' is the root"))?;
        if self.joints[j].kind != JointKind::Fixed {
            return Err(format!("link '{link}' is not fixed to its parent"));
        }
        self.joints[j].origin = origin;
        Ok(())
    }

    pub fn link(&self, name: &str) -> Option<&Link> {
        self.link_index.get(name).map(|&i| &self.links[i])
    }

    pub fn link_id(&self, name: &str) -> Option<usize> {
        self.link_index.get(name).copied()
    }

    pub fn joint(&self, name: &str) -> Option<&Joint> {
        self.joint_index.get(name).map(|&i| &self.joints[i])
    }

    pub fn joint_id(&self, name: &str) -> Option<usize> {
        self.joint_index.get(name).copied()
    }

    /// Number of entries of a joint-value vector.
    pub fn dof_count(&self) -> usize {
        self.dofs.len()
    }

    pub fn dof_names(&self) -> Vec<&str> {
        self.dofs.iter().map(|&j| self.joints[j].name.as_str()).collect()
    }

    /// Index in the joint-value vector of a joint that moves on its own.
    pub fn dof(&self, joint: &str) -> Option<usize> {
        self.joint(joint).and_then(|j| j.dof)
    }

    /// Joint values at zero, clamped into the limits.
    pub fn zero(&self) -> Vec<f64> {
        self.dofs.iter().map(|&j| 0.0f64.clamp(self.joints[j].lower, self.joints[j].upper)).collect()
    }

    /// The value of joint `joint` in the joint-value vector `q` (a mimic joint's from its
    /// leader's); None for a fixed joint.
    pub fn joint_value(&self, joint: usize, q: &[f64]) -> Option<f64> {
        let j = &self.joints[joint];
        match (j.dof, j.mimic) {
            (Some(d), _) => Some(q[d]),
            (None, Some(m)) => Some(m.multiplier * q[self.joints[m.leader].dof.expect("a leader has a dof")] + m.offset),
            (None, None) => None,
        }
    }

    /// The joint's transform for value `q`: origin, then rotation about (revolute) or translation
    /// along (prismatic) the axis.
    pub fn joint_transform(&self, joint: usize, q: &[f64]) -> DAffine3 {
        let j = &self.joints[joint];
        match (self.joint_value(joint, q), j.kind) {
            (Some(v), JointKind::Revolute) => j.origin * DAffine3::from_quat(DQuat::from_axis_angle(j.axis, v)),
            (Some(v), JointKind::Prismatic) => j.origin * DAffine3::from_translation(j.axis * v),
            _ => j.origin,
        }
    }

    /// Pose of every link in the root (robot base) frame.
    pub fn forward_kinematics(&self, q: &[f64]) -> Vec<DAffine3> {
        assert_eq!(q.len(), self.dofs.len(), "one value per joint with a degree of freedom");
        let mut out = vec![DAffine3::IDENTITY; self.links.len()];
        for (i, j) in self.joints.iter().enumerate() {
            out[j.child] = out[j.parent] * self.joint_transform(i, q);
        }
        out
    }

    /// Pose of `link` relative to `ancestor` (e.g. a finger link in the palm frame).
    pub fn relative_pose(&self, q: &[f64], ancestor: usize, link: usize) -> DAffine3 {
        let mut t = DAffine3::IDENTITY;
        let mut l = link;
        while l != ancestor {
            let Some(j) = self.links[l].parent_joint else {
                panic!("'{}' is not below '{}'", self.links[link].name, self.links[ancestor].name)
            };
            t = self.joint_transform(j, q) * t;
            l = self.joints[j].parent;
        }
        t
    }

    /// Is `link` in the subtree of `ancestor` (itself included)?
    pub fn is_below(&self, link: usize, ancestor: usize) -> bool {
        let mut l = link;
        loop {
            if l == ancestor {
                return true;
            }
            match self.links[l].parent_joint {
                Some(j) => l = self.joints[j].parent,
                None => return false,
            }
        }
    }
}

/// A URDF's links, their index by name, and the optional visual meshes left out (as named).
type ReadLinks = (Vec<Link>, HashMap<String, usize>, Vec<String>);

/// The URDF's links with their visual and collision shapes, their index by name, and the optional
/// visual meshes left out. Every mesh that cannot be read is listed in the one error.
fn read_links(urdf: &urdf_rs::Robot, paths: &MeshPaths, meshes: &mut MeshCache, visual_meshes: VisualMeshes) -> Result<ReadLinks, String> {
    let mut mesh_problems: Vec<String> = Vec::new();
    // Optional visual meshes: the ones found and the ones left out, by file name.
    let (mut found, mut left_out): (Vec<String>, Vec<String>) = (Vec::new(), Vec::new());
    let colours: HashMap<&str, [f64; 4]> =
        urdf.materials.iter().filter_map(|m| m.color.as_ref().map(|c| (m.name.as_str(), c.rgba.0))).collect();
    // A shape, or None when its mesh could not be read (the problem is listed).
    let mut shape = |origin: &urdf_rs::Pose, g: &urdf_rs::Geometry, rgba: [f64; 4], owner: &str| -> Option<Shape> {
        let geometry = match g {
            urdf_rs::Geometry::Box { size } => Geometry::Box { size: DVec3::from_array(size.0) },
            urdf_rs::Geometry::Cylinder { radius, length } => Geometry::Cylinder { radius: *radius, length: *length },
            urdf_rs::Geometry::Capsule { radius, length } => {
                mesh_problems.push(format!("{owner}: capsule (r {radius}, length {length}) is not supported: use a cylinder or a mesh"));
                return None;
            }
            urdf_rs::Geometry::Sphere { radius } => Geometry::Sphere { radius: *radius },
            urdf_rs::Geometry::Mesh { filename, scale } => {
                let scale = scale.map_or(DVec3::ONE, |s| DVec3::from_array(s.0));
                let read = paths.resolve(filename).and_then(|p| meshes.read(&p, scale).map_err(|e| format!("{}: {e}", p.display())));
                match read {
                    Ok(mesh) => Geometry::Mesh { mesh },
                    Err(e) => {
                        mesh_problems.push(format!("{owner}: mesh '{filename}': {e}"));
                        return None;
                    }
                }
            }
        };
        Some(Shape { geometry, origin: pose(origin), rgba })
    };
    let mut links = Vec::new();
    let mut link_index = HashMap::new();
    for l in &urdf.links {
        if link_index.insert(l.name.clone(), links.len()).is_some() {
            return Err(format!("link '{}' is defined twice", l.name));
        }
        let mut visuals = Vec::new();
        let optional = visual_meshes == VisualMeshes::Optional;
        for (i, v) in l.visual.iter().enumerate() {
            if let (true, urdf_rs::Geometry::Mesh { filename, .. }) = (optional, &v.geometry) {
                if paths.resolve(filename).is_err() {
                    left_out.push(filename.clone());
                    continue;
                }
                found.push(filename.clone());
            }
            let colour =
                v.material.as_ref().and_then(|m| m.color.as_ref().map(|c| c.rgba.0).or_else(|| colours.get(m.name.as_str()).copied()));
            // A mesh without a URDF colour keeps its file's colours (`NO_RGBA` marks it).
            let rgba = match (&v.geometry, colour) {
                (_, Some(c)) => c,
                (urdf_rs::Geometry::Mesh { .. }, None) => NO_RGBA,
                (_, None) => [0.5, 0.5, 0.5, 1.0],
            };
            visuals.extend(shape(&v.origin, &v.geometry, rgba, &format!("link '{}' visual {i}", l.name)));
        }
        // Optional meshes: a link drawn from its meshes keeps none of its primitive visuals.
        if optional && visuals.iter().any(|s| matches!(s.geometry, Geometry::Mesh { .. })) {
            visuals.retain(|s| matches!(s.geometry, Geometry::Mesh { .. }));
        }
        let collisions = l
            .collision
            .iter()
            .enumerate()
            .filter_map(|(i, c)| shape(&c.origin, &c.geometry, [0.0; 4], &format!("link '{}' collision {i}", l.name)))
            // A collision mesh collides as the convex hull of its vertices in both backends (or as
            // the hulls of its convex decomposition, when the description asks).
            .collect();
        links.push(Link {
            name: l.name.clone(),
            mass: l.inertial.mass.value,
            com: DVec3::from_array(l.inertial.origin.xyz.0),
            visuals,
            collisions,
            parent_joint: None,
        });
    }
    if !found.is_empty() && !left_out.is_empty() {
        let n = left_out.len();
        let list: String = left_out.iter().take(8).map(|p| format!("\n  - {p}")).collect();
        mesh_problems.push(format!(
            "{} of the robot's visual meshes are there and {n} are not (the robot assets hold only part of this robot's meshes): {list}",
            found.len()
        ));
    }
    if !mesh_problems.is_empty() {
        let n = mesh_problems.len();
        let list: String = mesh_problems.iter().map(|p| format!("\n  - {p}")).collect();
        return Err(format!("{n} geometr{} cannot be loaded:{list}", if n == 1 { "y" } else { "ies" }));
    }
    Ok((links, link_index, left_out))
}

/// A URDF joint between known links, its type supported, its limits a range and its axis not zero
/// (`!(a <= b)` on purpose: a NaN limit or axis fails too). Its mimic is resolved later.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
fn read_joint(j: &urdf_rs::Joint, link_index: &HashMap<String, usize>) -> Result<Joint, String> {
    let find = |name: &str, role: &str| {
        link_index.get(name).copied().ok_or_else(|| format!("joint '{}' refers to a missing {role} link '{name}'", j.name))
    };
    let (parent, child) = (find(&j.parent.link, "parent")?, find(&j.child.link, "child")?);
    let kind = match j.joint_type {
        urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => JointKind::Revolute,
        urdf_rs::JointType::Prismatic => JointKind::Prismatic,
        urdf_rs::JointType::Fixed => JointKind::Fixed,
        ref other => return Err(format!("joint '{}': type {other:?} is not supported (revolute, continuous, prismatic, fixed)", j.name)),
    };
    let (mut lower, mut upper) = (j.limit.lower, j.limit.upper);
    if j.joint_type == urdf_rs::JointType::Continuous {
        (lower, upper) = (f64::NEG_INFINITY, f64::INFINITY);
    }
    if kind != JointKind::Fixed && !(lower <= upper) {
        return Err(format!("joint '{}': lower limit {lower} is above upper limit {upper}", j.name));
    }
    let axis = DVec3::from_array(j.axis.xyz.0);
    if kind != JointKind::Fixed && !(axis.length() > 1e-9) {
        return Err(format!("joint '{}': axis is zero", j.name));
    }
    Ok(Joint {
        name: j.name.clone(),
        kind,
        parent,
        child,
        origin: pose(&j.origin),
        axis: axis.normalize_or_zero(),
        lower,
        upper,
        effort: j.limit.effort,
        velocity: j.limit.velocity,
        dof: None,
        mimic: None,
    })
}

/// Each `<mimic>`'s leader, by name once every joint is known: a joint that moves on its own.
fn resolve_mimics(urdf: &urdf_rs::Robot, joints: &mut [Joint], joint_index: &HashMap<String, usize>) -> Result<(), String> {
    for j in &urdf.joints {
        let Some(m) = &j.mimic else { continue };
        let Some(&leader) = joint_index.get(&m.joint) else {
            return Err(format!("joint '{}': <mimic joint=\"{}\"> names a joint that does not exist", j.name, m.joint));
        };
        let follower = joint_index[&j.name];
        if joints[follower].kind == JointKind::Fixed {
            return Err(format!("joint '{}': a fixed joint cannot mimic another", j.name));
        }
        if !joints[leader].moves() || urdf.joints.iter().any(|o| o.name == m.joint && o.mimic.is_some()) {
            return Err(format!("joint '{}': mimics '{}', which does not move on its own", j.name, m.joint));
        }
        let (multiplier, offset) = (m.multiplier.unwrap_or(1.0), m.offset.unwrap_or(0.0));
        if !(multiplier.is_finite() && offset.is_finite()) {
            return Err(format!("joint '{}': mimic multiplier and offset must be finite numbers", j.name));
        }
        joints[follower].mimic = Some(Mimic { leader, multiplier, offset });
    }
    Ok(())
}

/// The root link and the joints in topological order from it (a joint after the joint of its
/// parent link), with the links' parent joints and the name index renumbered. Fails unless the
/// joints form one tree.
#[allow(clippy::type_complexity)]
fn topological_order(
    links: &mut [Link],
    joints: Vec<Joint>,
    joint_index: HashMap<String, usize>,
) -> Result<(usize, Vec<Joint>, HashMap<String, usize>), String> {
    let roots: Vec<usize> = (0..links.len()).filter(|&i| links[i].parent_joint.is_none()).collect();
    let [root] = roots[..] else {
        let names: Vec<&str> = roots.iter().map(|&i| links[i].name.as_str()).collect();
        return Err(format!("expected one root link, found {}: {}", names.len(), names.join(", ")));
    };
    // Depth-first from the root (also detects cycles: unreachable links).
    let mut order = Vec::with_capacity(joints.len());
    let mut stack = vec![root];
    while let Some(l) = stack.pop() {
        for (ji, j) in joints.iter().enumerate() {
            if j.parent == l {
                order.push(ji);
                stack.push(j.child);
            }
        }
    }
    if order.len() != joints.len() {
        return Err("the joints do not form a tree".into());
    }
    let mut remap = vec![0; joints.len()];
    let mut sorted = Vec::with_capacity(joints.len());
    for (new, &old) in order.iter().enumerate() {
        remap[old] = new;
        sorted.push(joints[old].clone());
    }
    for j in sorted.iter_mut() {
        if let Some(m) = j.mimic.as_mut() {
            m.leader = remap[m.leader];
        }
    }
    for l in links.iter_mut() {
        l.parent_joint = l.parent_joint.map(|j| remap[j]);
    }
    let joint_index = joint_index.into_iter().map(|(k, v)| (k, remap[v])).collect();
    Ok((root, sorted, joint_index))
}

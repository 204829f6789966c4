//! URDF loader.
//!
//! The tree is traversed depth first from the root link; the children of a link are
//! visited in the byte order of their joints' names, as Pinocchio's parser does. A link
//! attached by a fixed joint is merged into its parent body (its inertia is added to the
//! parent joint's body) and gets a `BODY` frame; the fixed joint gets a `FIXED_JOINT`
//! frame. Links welded to the world are merged into the universe.
//!
//! Loading takes time and memory linear in the size of the file (hash maps for the
//! names, an explicit stack for the depth-first traversal: no recursion on depth).

use crate::error::{Error, Result};
use crate::joint::{Axis, JointType};
use crate::model::{Frame, FrameType, Geometry, JointLimits, MimicJoint, Model, RootJoint, Visual, inertia_defect};
use crate::spatial::{Inertia, Mat3, Se3, Vec3};
use nalgebra::Rotation3;
use roxmltree::Node;
use std::collections::HashMap;

/// What the URDF loader does with `<mimic>` joints.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MimicPolicy {
    /// A mimic joint is an independent joint (Pinocchio's default, `mimic=false`); the
    /// relation is recorded in [`Model::mimic_joints`].
    #[default]
    Independent,
    /// A URDF with a mimic joint is refused with an error naming the joint.
    Refuse,
}

/// Options of the URDF loader ([`Model::from_urdf_str_with`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UrdfOptions {
    /// Treatment of `<mimic>` joints (default [`MimicPolicy::Independent`]).
    pub mimic: MimicPolicy,
}

struct Ctx<'a> {
    file: &'a str,
}

impl Ctx<'_> {
    fn err(&self, node: &Node, message: impl Into<String>) -> Error {
        let name = node
            .attribute("name")
            .map(|n| format!(" name=\"{n}\""))
            .unwrap_or_default();
        Error::Element {
            file: self.file.to_string(),
            element: node.tag_name().name().to_string(),
            name,
            message: message.into(),
        }
    }

    fn attr<'n>(&self, node: &Node<'n, 'n>, key: &str) -> Result<&'n str> {
        node.attribute(key)
            .ok_or_else(|| self.err(node, format!("missing attribute `{key}`")))
    }

    fn float(&self, node: &Node, key: &str) -> Result<f64> {
        let s = self.attr(node, key)?;
        parse_float(s).ok_or_else(|| self.err(node, format!("attribute `{key}`: `{s}` is not a finite number")))
    }

    fn float_or(&self, node: &Node, key: &str, default: f64) -> Result<f64> {
        if node.attribute(key).is_some() {
            self.float(node, key)
        } else {
            Ok(default)
        }
    }

    fn vec3(&self, node: &Node, key: &str, default: Vec3) -> Result<Vec3> {
        let Some(s) = node.attribute(key) else {
            return Ok(default);
        };
        let vals: Option<Vec<f64>> = s.split_whitespace().map(parse_float).collect();
        match vals {
            Some(v) if v.len() == 3 => Ok(Vec3::new(v[0], v[1], v[2])),
            _ => Err(self.err(node, format!("attribute `{key}`: `{s}` is not three finite numbers"))),
        }
    }

    /// `<origin xyz rpy>` child of `node`, identity if absent.
    fn origin(&self, node: &Node) -> Result<Se3> {
        match child(node, "origin") {
            None => Ok(Se3::identity()),
            Some(o) => {
                let xyz = self.vec3(&o, "xyz", Vec3::zeros())?;
                let rpy = self.vec3(&o, "rpy", Vec3::zeros())?;
                Ok(Se3::new(rpy_matrix(&rpy), xyz))
            }
        }
    }
}

fn parse_float(s: &str) -> Option<f64> {
    s.trim().parse::<f64>().ok().filter(|v| v.is_finite())
}

fn child<'a, 'i>(node: &Node<'a, 'i>, tag: &str) -> Option<Node<'a, 'i>> {
    node.children().find(|c| c.is_element() && c.tag_name().name() == tag)
}

/// Rotation `Rz(yaw) Ry(pitch) Rx(roll)`.
pub(crate) fn rpy_matrix(rpy: &Vec3) -> Mat3 {
    Rotation3::from_euler_angles(rpy.x, rpy.y, rpy.z).into_inner()
}

struct LinkInfo<'a, 'i> {
    node: Node<'a, 'i>,
    inertia: Inertia,
}

/// A `<mimic joint multiplier offset>` element, validated.
struct MimicInfo<'a> {
    joint: &'a str,
    multiplier: f64,
    offset: f64,
}

struct JointInfo<'a, 'i> {
    node: Node<'a, 'i>,
    name: &'a str,
    kind: &'a str,
    parent: &'a str,
    child: &'a str,
    origin: Se3,
    mimic: Option<MimicInfo<'a>>,
}

impl Model {
    /// Loads a URDF file with the default [`UrdfOptions`]. `package://` mesh URIs are kept
    /// as written in [`Model::visuals`].
    pub fn from_urdf_file(path: impl AsRef<std::path::Path>, root: RootJoint) -> Result<Model> {
        Self::from_urdf_file_with(path, root, &UrdfOptions::default())
    }

    /// Loads a URDF file with `options`.
    pub fn from_urdf_file_with(
        path: impl AsRef<std::path::Path>,
        root: RootJoint,
        options: &UrdfOptions,
    ) -> Result<Model> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        parse_urdf(&text, &path.display().to_string(), root, options)
    }

    /// Loads a URDF from a string with the default [`UrdfOptions`].
    pub fn from_urdf_str(xml: &str, root: RootJoint) -> Result<Model> {
        Self::from_urdf_str_with(xml, root, &UrdfOptions::default())
    }

    /// Loads a URDF from a string with `options`.
    ///
    /// Errors name the offending element: malformed numbers, missing links, cycles,
    /// physically invalid inertias (see [`Model::INERTIA_TOLERANCE`]), invalid or refused
    /// `<mimic>` elements; a model beyond [`Model::MAX_NV`] gives [`Error::ModelTooLarge`].
    pub fn from_urdf_str_with(xml: &str, root: RootJoint, options: &UrdfOptions) -> Result<Model> {
        parse_urdf(xml, "URDF", root, options)
    }
}

fn parse_urdf(text: &str, file: &str, root: RootJoint, options: &UrdfOptions) -> Result<Model> {
    let ctx = Ctx { file };
    let doc = roxmltree::Document::parse(text).map_err(|e| Error::Xml {
        file: file.into(),
        message: e.to_string(),
    })?;
    let robot = doc.root_element();
    if robot.tag_name().name() != "robot" {
        return Err(ctx.err(&robot, "the root element must be <robot>"));
    }
    let el = read_elements(&ctx, &robot)?;
    let (children, root_link) = kinematic_tree(&ctx, &robot, &el)?;
    let mut model = Model::new(robot.attribute("name").unwrap_or(""));
    let (root_joint, root_frame) = add_root(&ctx, &mut model, root, root_link, &el.links[root_link])?;
    let visited = descend(
        &ctx,
        &mut model,
        &el.joints,
        &el.links,
        &children,
        (root_link, root_joint, root_frame, Se3::identity()),
    )?;
    if visited != el.links.len() {
        return Err(ctx.err(
            &robot,
            "some links are not connected to the root link (cycle in the kinematic graph)",
        ));
    }
    record_mimics(&ctx, &mut model, &el.joints, &el.joint_index, options)?;
    Ok(model)
}

/// The `<link>` and `<joint>` elements of a URDF, validated one by one.
struct Elements<'a, 'i> {
    links: HashMap<&'a str, LinkInfo<'a, 'i>>,
    /// Link names in document order.
    link_order: Vec<&'a str>,
    joints: Vec<JointInfo<'a, 'i>>,
    joint_index: HashMap<&'a str, usize>,
}

/// Reads the links and joints of `<robot>` (duplicate names are errors).
fn read_elements<'a, 'i>(ctx: &Ctx, robot: &Node<'a, 'i>) -> Result<Elements<'a, 'i>> {
    let mut el = Elements {
        links: HashMap::new(),
        link_order: Vec::new(),
        joints: Vec::new(),
        joint_index: HashMap::new(),
    };
    for node in robot.children().filter(|n| n.is_element()) {
        match node.tag_name().name() {
            "link" => {
                let name = ctx.attr(&node, "name")?;
                let inertia = parse_inertial(ctx, &node)?;
                if el.links.insert(name, LinkInfo { node, inertia }).is_some() {
                    return Err(ctx.err(&node, "duplicate link name"));
                }
                el.link_order.push(name);
            }
            "joint" => {
                let name = ctx.attr(&node, "name")?;
                let kind = ctx.attr(&node, "type")?;
                let parent = child(&node, "parent").ok_or_else(|| ctx.err(&node, "missing <parent>"))?;
                let childn = child(&node, "child").ok_or_else(|| ctx.err(&node, "missing <child>"))?;
                let parent = ctx.attr(&parent, "link")?;
                let childl = ctx.attr(&childn, "link")?;
                let origin = ctx.origin(&node)?;
                let mimic = parse_mimic(ctx, &node)?;
                if el.joint_index.insert(name, el.joints.len()).is_some() {
                    return Err(ctx.err(&node, "duplicate joint name"));
                }
                el.joints.push(JointInfo {
                    node,
                    name,
                    kind,
                    parent,
                    child: childl,
                    origin,
                    mimic,
                });
            }
            _ => {}
        }
    }
    if el.links.is_empty() {
        return Err(ctx.err(robot, "no <link>"));
    }
    Ok(el)
}

/// The child joints of each link (sorted by name) and the root link: every joint joins
/// existing links, no link has two parents, exactly one link has none.
fn kinematic_tree<'a>(
    ctx: &Ctx,
    robot: &Node,
    el: &Elements<'a, '_>,
) -> Result<(HashMap<&'a str, Vec<usize>>, &'a str)> {
    let mut parent_joint_of: HashMap<&str, usize> = HashMap::new();
    let mut children: HashMap<&str, Vec<usize>> = HashMap::new();
    for (k, j) in el.joints.iter().enumerate() {
        if !el.links.contains_key(j.parent) {
            return Err(ctx.err(&j.node, format!("parent link `{}` does not exist", j.parent)));
        }
        if !el.links.contains_key(j.child) {
            return Err(ctx.err(&j.node, format!("child link `{}` does not exist", j.child)));
        }
        if parent_joint_of.insert(j.child, k).is_some() {
            return Err(ctx.err(&j.node, format!("link `{}` has two parent joints", j.child)));
        }
        children.entry(j.parent).or_default().push(k);
    }
    for list in children.values_mut() {
        list.sort_by(|a, b| el.joints[*a].name.cmp(el.joints[*b].name));
    }
    let roots: Vec<&str> = el
        .link_order
        .iter()
        .copied()
        .filter(|l| !parent_joint_of.contains_key(l))
        .collect();
    if roots.len() != 1 {
        return Err(ctx.err(
            robot,
            format!("expected exactly one root link, found {} ({:?})", roots.len(), roots),
        ));
    }
    Ok((children, roots[0]))
}

/// The root link's body, frame and visuals, on a free-flyer joint or on the universe:
/// returns the joint it moves with and its body frame.
fn add_root(
    ctx: &Ctx,
    model: &mut Model,
    root: RootJoint,
    root_link: &str,
    root_info: &LinkInfo,
) -> Result<(usize, usize)> {
    let (root_joint, root_parent_frame) = match root {
        RootJoint::Fixed => (0, 0),
        RootJoint::FreeFlyer => {
            let kind = JointType::FreeFlyer;
            let j = model.add_joint(0, kind, Se3::identity(), "root_joint", JointLimits::unbounded(&kind))?;
            let f = model.add_frame(Frame {
                name: "root_joint".into(),
                kind: FrameType::Joint,
                parent_joint: j,
                parent_frame: 0,
                placement: Se3::identity(),
            })?;
            (j, f)
        }
    };
    model.append_body_to_joint(root_joint, &root_info.inertia, &Se3::identity())?;
    let root_frame = model.add_frame(Frame {
        name: root_link.into(),
        kind: FrameType::Body,
        parent_joint: root_joint,
        parent_frame: root_parent_frame,
        placement: Se3::identity(),
    })?;
    add_visuals(
        ctx,
        model,
        root_link,
        &root_info.node,
        root_joint,
        root_frame,
        &Se3::identity(),
    )?;
    Ok((root_joint, root_frame))
}

/// Reads a joint's `<mimic joint multiplier offset/>` (URDF defaults 1 and 0).
fn parse_mimic<'a>(ctx: &Ctx, joint: &Node<'a, 'a>) -> Result<Option<MimicInfo<'a>>> {
    let Some(m) = child(joint, "mimic") else {
        return Ok(None);
    };
    Ok(Some(MimicInfo {
        joint: ctx.attr(&m, "joint")?,
        multiplier: ctx.float_or(&m, "multiplier", 1.0)?,
        offset: ctx.float_or(&m, "offset", 0.0)?,
    }))
}

/// Checks every mimic joint (the mimicked joint exists, both are moving one-dof joints)
/// and records it, or refuses it under [`MimicPolicy::Refuse`].
fn record_mimics(
    ctx: &Ctx,
    model: &mut Model,
    joints: &[JointInfo],
    joint_index: &HashMap<&str, usize>,
    options: &UrdfOptions,
) -> Result<()> {
    for j in joints {
        let Some(m) = &j.mimic else { continue };
        if options.mimic == MimicPolicy::Refuse {
            return Err(ctx.err(
                &j.node,
                format!("mimic joint (mimics `{}`), refused by MimicPolicy::Refuse", m.joint),
            ));
        }
        if m.joint == j.name {
            return Err(ctx.err(&j.node, "a joint cannot mimic itself"));
        }
        if !joint_index.contains_key(m.joint) {
            return Err(ctx.err(&j.node, format!("mimicked joint `{}` does not exist", m.joint)));
        }
        let one_dof = |name: &str| model.joint_id(name).ok().filter(|&id| model.joints[id].nv == 1);
        let (Some(joint), Some(mimicked)) = (one_dof(j.name), one_dof(m.joint)) else {
            return Err(ctx.err(
                &j.node,
                format!(
                    "mimic joint and mimicked joint `{}` must both be revolute, continuous or prismatic",
                    m.joint
                ),
            ));
        };
        model.add_mimic(MimicJoint {
            joint,
            mimicked,
            multiplier: m.multiplier,
            offset: m.offset,
        });
    }
    Ok(())
}

/// State of a processed link: (link, joint it moves with, its body frame, its placement in that joint).
type LinkState<'a> = (&'a str, usize, usize, Se3);

/// Adds the subtree below the root link depth first, children in joint-name order, and
/// returns the number of links visited.
fn descend<'a>(
    ctx: &Ctx,
    model: &mut Model,
    joints: &[JointInfo<'a, '_>],
    links: &HashMap<&'a str, LinkInfo<'a, '_>>,
    children: &HashMap<&'a str, Vec<usize>>,
    root: LinkState<'a>,
) -> Result<usize> {
    // Each stack entry: (link state, index of its next child joint to process).
    let mut stack: Vec<(LinkState<'a>, usize)> = vec![(root, 0)];
    let mut visited = 1;
    while let Some(top) = stack.last_mut() {
        let ((link, pj, pf, pplace), next) = (top.0, top.1);
        let kids = children.get(link).map(|v| v.as_slice()).unwrap_or(&[]);
        if next >= kids.len() {
            stack.pop();
            continue;
        }
        top.1 += 1;
        visited += 1;
        let j = &joints[kids[next]];
        let placement = pplace.compose(&j.origin);
        let info = &links[j.child];
        let on_joint = |e: Error| ctx.err(&j.node, e.to_string());
        let state = if j.kind == "fixed" {
            let f = model
                .add_frame(Frame {
                    name: j.name.into(),
                    kind: FrameType::FixedJoint,
                    parent_joint: pj,
                    parent_frame: pf,
                    placement,
                })
                .map_err(on_joint)?;
            model
                .append_body_to_joint(pj, &info.inertia, &placement)
                .map_err(|e| ctx.err(&info.node, format!("merged through fixed joint `{}`: {e}", j.name)))?;
            let b = model.add_frame(Frame {
                name: j.child.into(),
                kind: FrameType::Body,
                parent_joint: pj,
                parent_frame: f,
                placement,
            })?;
            add_visuals(ctx, model, j.child, &info.node, pj, b, &placement)?;
            (j.child, pj, b, placement)
        } else {
            let (kind, limits) = joint_type_and_limits(ctx, j)?;
            let id = model
                .add_joint(pj, kind, placement, j.name, limits)
                .map_err(|e| match e {
                    Error::ModelTooLarge { .. } => e,
                    e => on_joint(e),
                })?;
            let f = model.add_frame(Frame {
                name: j.name.into(),
                kind: FrameType::Joint,
                parent_joint: id,
                parent_frame: pf,
                placement: Se3::identity(),
            })?;
            model.append_body_to_joint(id, &info.inertia, &Se3::identity())?;
            let b = model.add_frame(Frame {
                name: j.child.into(),
                kind: FrameType::Body,
                parent_joint: id,
                parent_frame: f,
                placement: Se3::identity(),
            })?;
            add_visuals(ctx, model, j.child, &info.node, id, b, &Se3::identity())?;
            (j.child, id, b, Se3::identity())
        };
        stack.push((state, 0));
    }
    Ok(visited)
}

fn parse_inertial(ctx: &Ctx, link: &Node) -> Result<Inertia> {
    let Some(inertial) = child(link, "inertial") else {
        return Ok(Inertia::zero());
    };
    let origin = ctx.origin(&inertial)?;
    let mass_node = child(&inertial, "mass").ok_or_else(|| ctx.err(&inertial, "missing <mass>"))?;
    let mass = ctx.float(&mass_node, "value")?;
    let i = child(&inertial, "inertia").ok_or_else(|| ctx.err(&inertial, "missing <inertia>"))?;
    let (ixx, ixy, ixz) = (ctx.float(&i, "ixx")?, ctx.float(&i, "ixy")?, ctx.float(&i, "ixz")?);
    let (iyy, iyz, izz) = (ctx.float(&i, "iyy")?, ctx.float(&i, "iyz")?, ctx.float(&i, "izz")?);
    let ic = Mat3::new(ixx, ixy, ixz, ixy, iyy, iyz, ixz, iyz, izz);
    let r = origin.rotation;
    let y = Inertia::from_com(mass, origin.translation, r * ic * r.transpose());
    match inertia_defect(&y) {
        None => Ok(y),
        Some(m) => Err(ctx.err(link, format!("inertia is not physically valid: {m}"))),
    }
}

fn joint_type_and_limits(ctx: &Ctx, j: &JointInfo) -> Result<(JointType, JointLimits)> {
    let axis_node = child(&j.node, "axis");
    let axis = match &axis_node {
        Some(a) => ctx.vec3(a, "xyz", Vec3::x())?,
        None => Vec3::x(),
    };
    let kind = match j.kind {
        "revolute" | "continuous" | "prismatic" => {
            let m = axis.amax();
            if m == 0.0 || m * (axis / m).norm() < 1e-12 {
                return Err(ctx.err(&j.node, "zero joint axis"));
            }
            let a = Axis::from_vector(axis);
            match j.kind {
                "revolute" => JointType::Revolute(a),
                "continuous" => JointType::RevoluteUnbounded(a),
                _ => JointType::Prismatic(a),
            }
        }
        "floating" => JointType::FreeFlyer,
        "planar" => JointType::Planar,
        other => return Err(ctx.err(&j.node, format!("unsupported joint type `{other}`"))),
    };
    let mut limits = JointLimits::unbounded(&kind);
    if let Some(l) = child(&j.node, "limit") {
        let nv = kind.nv();
        if matches!(kind, JointType::Revolute(_) | JointType::Prismatic(_)) {
            let (lower, upper) = (ctx.float_or(&l, "lower", 0.0)?, ctx.float_or(&l, "upper", 0.0)?);
            if lower > upper {
                return Err(ctx.err(&l, format!("limit lower = {lower} exceeds upper = {upper}")));
            }
            (limits.lower, limits.upper) = (vec![lower], vec![upper]);
        }
        if nv == 1 {
            let nonnegative = |key: &str| match ctx.float(&l, key)? {
                v if v < 0.0 => Err(ctx.err(&l, format!("limit {key} = {v} is negative"))),
                v => Ok(v),
            };
            limits.effort = vec![nonnegative("effort")?];
            limits.velocity = vec![nonnegative("velocity")?];
        }
    }
    if let Some(d) = child(&j.node, "dynamics") {
        let nv = kind.nv();
        limits.damping = vec![ctx.float_or(&d, "damping", 0.0)?; nv];
        limits.friction = vec![ctx.float_or(&d, "friction", 0.0)?; nv];
    }
    Ok((kind, limits))
}

fn add_visuals(
    ctx: &Ctx,
    model: &mut Model,
    link: &str,
    node: &Node,
    joint: usize,
    frame: usize,
    placement: &Se3,
) -> Result<()> {
    for v in node
        .children()
        .filter(|c| c.is_element() && c.tag_name().name() == "visual")
    {
        let origin = ctx.origin(&v)?;
        let g = child(&v, "geometry").ok_or_else(|| ctx.err(&v, "missing <geometry>"))?;
        let shape = g
            .children()
            .find(|c| c.is_element())
            .ok_or_else(|| ctx.err(&g, "empty <geometry>"))?;
        let geometry = match shape.tag_name().name() {
            "mesh" => Geometry::Mesh {
                filename: ctx.attr(&shape, "filename")?.to_string(),
                scale: ctx.vec3(&shape, "scale", Vec3::new(1.0, 1.0, 1.0))?,
            },
            "box" => Geometry::Box {
                size: ctx.vec3(&shape, "size", Vec3::zeros())?,
            },
            "cylinder" => Geometry::Cylinder {
                radius: ctx.float(&shape, "radius")?,
                length: ctx.float(&shape, "length")?,
            },
            "sphere" => Geometry::Sphere {
                radius: ctx.float(&shape, "radius")?,
            },
            other => return Err(ctx.err(&shape, format!("unsupported geometry `{other}`"))),
        };
        model.visuals.push(Visual {
            link: link.to_string(),
            parent_joint: joint,
            parent_frame: frame,
            placement: placement.compose(&origin),
            geometry,
        });
    }
    Ok(())
}

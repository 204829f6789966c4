//! The kinematic tree: joints, bodies, frames, limits and gravity.

use crate::data::Data;
use crate::error::{Error, Result};
use crate::joint::{JointModel, JointType};
use crate::linalg::DofTree;
use crate::spatial::{Inertia, Motion, Se3, Vec3};
use std::collections::HashMap;

/// Sentinel for "no parent degree of freedom".
pub(crate) const NONE: usize = usize::MAX;

/// Kind of a frame (Pinocchio's `FrameType`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameType {
    /// Operational frame added by the user.
    OpFrame,
    /// Frame of a joint.
    Joint,
    /// Frame of a fixed (merged) joint.
    FixedJoint,
    /// Frame of a body (URDF link).
    Body,
    /// Sensor frame.
    Sensor,
}

impl FrameType {
    /// Pinocchio's name of the type (`OP_FRAME`, `JOINT`, `FIXED_JOINT`, `BODY`, `SENSOR`).
    pub fn name(&self) -> &'static str {
        match self {
            FrameType::OpFrame => "OP_FRAME",
            FrameType::Joint => "JOINT",
            FrameType::FixedJoint => "FIXED_JOINT",
            FrameType::Body => "BODY",
            FrameType::Sensor => "SENSOR",
        }
    }
}

/// A frame attached to a joint.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Frame name.
    pub name: String,
    /// Frame type.
    pub kind: FrameType,
    /// Joint the frame moves with.
    pub parent_joint: usize,
    /// Frame this one was attached to when the model was built.
    pub parent_frame: usize,
    /// Placement of the frame in its parent joint's frame.
    pub placement: Se3,
}

/// Geometry of a visual element (kept for visualization, unused by the dynamics).
#[derive(Clone, Debug, PartialEq)]
pub enum Geometry {
    /// Mesh file, with its URI as written in the URDF (e.g. `package://...`) and scale.
    Mesh {
        /// URI or path.
        filename: String,
        /// Scale along x, y, z.
        scale: Vec3,
    },
    /// Box with full side lengths.
    Box {
        /// Side lengths.
        size: Vec3,
    },
    /// Cylinder along z.
    Cylinder {
        /// Radius.
        radius: f64,
        /// Length.
        length: f64,
    },
    /// Sphere.
    Sphere {
        /// Radius.
        radius: f64,
    },
}

/// A visual element of a body.
#[derive(Clone, Debug, PartialEq)]
pub struct Visual {
    /// Name of the link the visual belongs to.
    pub link: String,
    /// Joint the visual moves with.
    pub parent_joint: usize,
    /// Body frame of the link.
    pub parent_frame: usize,
    /// Placement in the parent joint's frame.
    pub placement: Se3,
    /// Shape.
    pub geometry: Geometry,
}

/// Limits and passive parameters of one joint, given when the joint is added.
#[derive(Clone, Debug, PartialEq)]
pub struct JointLimits {
    /// Lower position limits (nq).
    pub lower: Vec<f64>,
    /// Upper position limits (nq).
    pub upper: Vec<f64>,
    /// Velocity limits (nv).
    pub velocity: Vec<f64>,
    /// Effort limits (nv).
    pub effort: Vec<f64>,
    /// Viscous damping (nv), informative.
    pub damping: Vec<f64>,
    /// Dry friction (nv), informative.
    pub friction: Vec<f64>,
}

impl JointLimits {
    /// No limits: ±f64::MAX positions (±1.01 for the cos/sin entries of unbounded
    /// revolute and planar joints, as Pinocchio), f64::MAX velocity and effort.
    pub fn unbounded(kind: &JointType) -> Self {
        let (nq, nv) = (kind.nq(), kind.nv());
        let mut lower = vec![-f64::MAX; nq];
        let mut upper = vec![f64::MAX; nq];
        match kind {
            JointType::RevoluteUnbounded(_) => {
                lower.fill(-1.01);
                upper.fill(1.01);
            }
            JointType::Planar => {
                lower[2..].fill(-1.01);
                upper[2..].fill(1.01);
            }
            _ => {}
        }
        Self {
            lower,
            upper,
            velocity: vec![f64::MAX; nv],
            effort: vec![f64::MAX; nv],
            damping: vec![0.0; nv],
            friction: vec![0.0; nv],
        }
    }
}

/// A joint whose URDF declares `<mimic joint="..." multiplier="..." offset="..."/>`:
/// `q_joint = multiplier · q_mimicked + offset`. The model keeps it an independent joint
/// (Pinocchio's default, `mimic=false`); the relation is recorded for the user.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MimicJoint {
    /// The mimicking joint.
    pub joint: usize,
    /// The joint it mimics.
    pub mimicked: usize,
    /// Multiplier (URDF default 1).
    pub multiplier: f64,
    /// Offset (URDF default 0).
    pub offset: f64,
}

/// Position in q of a block that must have unit norm: a quaternion (free flyer,
/// spherical) or a (cos θ, sin θ) pair (unbounded revolute, planar).
#[derive(Clone, Copy, Debug)]
pub(crate) struct UnitBlock {
    pub(crate) joint: usize,
    pub(crate) start: usize,
    pub(crate) len: usize,
}

/// Root joint used when loading a URDF.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RootJoint {
    /// The root link is welded to the world.
    Fixed,
    /// A free-flyer joint named `root_joint` connects the world to the root link.
    FreeFlyer,
}

/// Which argument a Jacobian is taken with respect to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ArgumentPosition {
    /// First argument (q in `integrate`, q0 in `difference`).
    Arg0,
    /// Second argument (v in `integrate`, q1 in `difference`).
    Arg1,
}

/// Reference frame of velocities, accelerations, Jacobians and contact quantities.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReferenceFrame {
    /// Axes and origin of the frame itself.
    Local,
    /// World axes and world origin.
    World,
    /// World axes, origin at the frame's origin.
    LocalWorldAligned,
}

/// Kinematic tree with inertias, frames and limits. Immutable once built; everything
/// the algorithms write lives in [`Data`].
#[derive(Clone, Debug)]
pub struct Model {
    /// Robot name.
    pub name: String,
    pub(crate) joints: Vec<JointModel>,
    pub(crate) names: Vec<String>,
    /// Joint id of every name.
    pub(crate) name_index: HashMap<String, usize>,
    /// The unit-norm blocks of q, joint by joint.
    pub(crate) unit_blocks: Vec<UnitBlock>,
    pub(crate) mimic: Vec<MimicJoint>,
    /// The joints without children, and the position of every joint in that list (or
    /// `NONE`): a value computed root to leaves is finite everywhere if it is at the
    /// leaves, since a NaN or infinity propagates to the children.
    pub(crate) leaves: Vec<usize>,
    leaf_slot: Vec<usize>,
    pub(crate) parents: Vec<usize>,
    pub(crate) placements: Vec<Se3>,
    pub(crate) inertias: Vec<Inertia>,
    pub(crate) frames: Vec<Frame>,
    pub(crate) nq: usize,
    pub(crate) nv: usize,
    /// Parent degree of freedom (in the tree of dofs), or `NONE`.
    pub(crate) dof_parent: Vec<usize>,
    /// Joint of each degree of freedom.
    pub(crate) dof_joint: Vec<usize>,
    /// Offsets of the per-dof ancestor rows of a compressed `L` (row k has one entry per
    /// ancestor of dof k): row k is `dof_anc_start[k]..dof_anc_start[k + 1]`.
    pub(crate) dof_anc_start: Vec<usize>,
    /// Hash of `dof_parent`, recorded by `Data` and `ContactData` to check that they are
    /// used with a model of the same tree.
    pub(crate) dof_tree_hash: u64,
    /// Lower position limits (nq).
    pub lower_position_limit: Vec<f64>,
    /// Upper position limits (nq).
    pub upper_position_limit: Vec<f64>,
    /// Velocity limits (nv).
    pub velocity_limit: Vec<f64>,
    /// Effort limits (nv).
    pub effort_limit: Vec<f64>,
    /// Armature (nv), added to the diagonal of the mass matrix in every algorithm.
    pub armature: Vec<f64>,
    /// Viscous damping (nv); informative, no algorithm uses it.
    pub damping: Vec<f64>,
    /// Dry friction (nv); informative.
    pub friction: Vec<f64>,
    /// Rotor inertia (nv) from an SRDF.
    pub rotor_inertia: Vec<f64>,
    /// Rotor gear ratio (nv) from an SRDF.
    pub rotor_gear_ratio: Vec<f64>,
    /// Gravity as a spatial acceleration `[g, 0]` in the world frame.
    pub gravity: Motion,
    /// Named reference configurations (SRDF `group_state`s).
    pub reference_configurations: Vec<(String, Vec<f64>)>,
    /// Visual elements (URDF `<visual>`), kept for visualization.
    pub visuals: Vec<Visual>,
}

impl Model {
    /// An empty model (only the universe joint and frame), gravity `[0, 0, −9.81]`.
    pub fn new(name: &str) -> Self {
        Self {
            name: name.to_string(),
            joints: vec![JointModel {
                kind: JointType::Universe,
                idx_q: 0,
                idx_v: 0,
                nq: 0,
                nv: 0,
            }],
            names: vec!["universe".to_string()],
            name_index: HashMap::from([("universe".to_string(), 0)]),
            unit_blocks: Vec::new(),
            mimic: Vec::new(),
            leaves: Vec::new(),
            leaf_slot: vec![NONE],
            parents: vec![0],
            placements: vec![Se3::identity()],
            inertias: vec![Inertia::zero()],
            frames: vec![Frame {
                name: "universe".to_string(),
                kind: FrameType::FixedJoint,
                parent_joint: 0,
                parent_frame: 0,
                placement: Se3::identity(),
            }],
            nq: 0,
            nv: 0,
            dof_parent: Vec::new(),
            dof_joint: Vec::new(),
            dof_anc_start: vec![0],
            dof_tree_hash: 0,
            lower_position_limit: Vec::new(),
            upper_position_limit: Vec::new(),
            velocity_limit: Vec::new(),
            effort_limit: Vec::new(),
            armature: Vec::new(),
            damping: Vec::new(),
            friction: Vec::new(),
            rotor_inertia: Vec::new(),
            rotor_gear_ratio: Vec::new(),
            gravity: Motion::new(Vec3::new(0.0, 0.0, -9.81), Vec3::zeros()),
            reference_configurations: Vec::new(),
            visuals: Vec::new(),
        }
    }

    /// Largest tangent size `nv` of a model: [`Model::add_joint`] refuses a joint that
    /// would exceed it. `Data` holds six dense nv × nv matrices (the mass matrix, its
    /// inverse and four derivative matrices), a `ContactData` about five more: at
    /// nv = 2048 one matrix takes 32 MiB and a `Data` about 200 MiB, which is as much as
    /// one model's workspace should take. (Typical robots have nv < 100.)
    pub const MAX_NV: usize = 2048;

    /// Tolerance on `|‖·‖ − 1|` of the quaternions (free flyer, spherical) and
    /// (cos θ, sin θ) pairs (unbounded revolute, planar) of a configuration. Every
    /// algorithm taking q rejects a configuration outside it with
    /// [`Error::NotNormalized`] (naming the joint); inside it the entries are used as
    /// given, as Pinocchio does (a norm of 1 + ε scales rotations by about 1 + 2ε). Use
    /// [`normalize`](crate::normalize) to project a configuration.
    pub const UNIT_NORM_TOLERANCE: f64 = 1e-6;

    /// Relative tolerance of the inertia check of [`Model::set_inertia`],
    /// [`Model::append_body_to_joint`] and the URDF loader. An inertia is accepted when
    /// its entries are finite, its mass is ≥ 0, a zero mass has a zero first moment, and
    /// its rotational inertia about the centre of mass `I_c` is symmetric and positive
    /// semidefinite up to `INERTIA_TOLERANCE · s` (asymmetry and smallest eigenvalue ≥
    /// −tol·s), `s` being the largest absolute entry of the rotational inertia about the
    /// reference origin or about the centre of mass. This is exactly the condition for
    /// the 6×6 spatial inertia to be positive semidefinite. The all-zero inertia (a
    /// massless dummy link) is valid. The triangle inequalities of the principal moments
    /// are not enforced (many CAD-exported URDFs violate them slightly).
    pub const INERTIA_TOLERANCE: f64 = 1e-6;

    /// Adds a joint below `parent` at `placement` (in the parent joint's frame) and
    /// returns its id. Joints must be added parents first. Fails (leaving the model
    /// unchanged) on an unknown parent, a used name, limits of the wrong sizes or when
    /// the model would exceed [`Model::MAX_NV`]. Takes O(1) time (amortized) whatever the
    /// depth of the tree.
    pub fn add_joint(
        &mut self,
        parent: usize,
        kind: JointType,
        placement: Se3,
        name: &str,
        limits: JointLimits,
    ) -> Result<usize> {
        self.check_new_joint(parent, kind, &placement, name, &limits)?;
        let (nq, nv) = (kind.nq(), kind.nv());
        let id = self.joints.len();
        let jm = JointModel {
            kind,
            idx_q: self.nq,
            idx_v: self.nv,
            nq,
            nv,
        };
        self.push_dofs(parent, id, nv);
        if let Some((start, len)) = kind.unit_block() {
            self.unit_blocks.push(UnitBlock {
                joint: id,
                start: self.nq + start,
                len,
            });
        }
        self.joints.push(jm);
        self.names.push(name.to_string());
        self.name_index.insert(name.to_string(), id);
        // The new joint is a leaf and takes its parent's place in the list, if it had one.
        match self.leaf_slot[parent] {
            NONE => {
                self.leaf_slot.push(self.leaves.len());
                self.leaves.push(id);
            }
            slot => {
                self.leaves[slot] = id;
                self.leaf_slot[parent] = NONE;
                self.leaf_slot.push(slot);
            }
        }
        self.parents.push(parent);
        self.placements.push(placement);
        self.inertias.push(Inertia::zero());
        self.nq += nq;
        self.nv += nv;
        self.lower_position_limit.extend_from_slice(&limits.lower);
        self.upper_position_limit.extend_from_slice(&limits.upper);
        self.velocity_limit.extend_from_slice(&limits.velocity);
        self.effort_limit.extend_from_slice(&limits.effort);
        self.damping.extend_from_slice(&limits.damping);
        self.friction.extend_from_slice(&limits.friction);
        self.armature.extend(std::iter::repeat_n(0.0, nv));
        self.rotor_inertia.extend(std::iter::repeat_n(0.0, nv));
        self.rotor_gear_ratio.extend(std::iter::repeat_n(1.0, nv));
        Ok(id)
    }

    /// The checks of [`Model::add_joint`], before anything changes.
    fn check_new_joint(
        &self,
        parent: usize,
        kind: JointType,
        placement: &Se3,
        name: &str,
        limits: &JointLimits,
    ) -> Result<()> {
        if parent >= self.joints.len() {
            return Err(Error::NotFound {
                what: "parent joint".into(),
                name: parent.to_string(),
            });
        }
        if kind == JointType::Universe {
            return Err(Error::Invalid(format!("joint {name}: the universe cannot be added")));
        }
        if self.name_index.contains_key(name) {
            return Err(Error::Invalid(format!("joint {name}: name already used")));
        }
        if !placement.is_finite() {
            return Err(Error::Invalid(format!("joint {name}: placement is not finite")));
        }
        let (nq, nv) = (kind.nq(), kind.nv());
        if self.nv + nv > Self::MAX_NV {
            return Err(Error::ModelTooLarge {
                joint: name.to_string(),
                nv: self.nv + nv,
                max: Self::MAX_NV,
            });
        }
        let sizes = [
            ("lower", limits.lower.len(), nq),
            ("upper", limits.upper.len(), nq),
            ("velocity", limits.velocity.len(), nv),
            ("effort", limits.effort.len(), nv),
            ("damping", limits.damping.len(), nv),
            ("friction", limits.friction.len(), nv),
        ];
        for (what, got, expected) in sizes {
            if got != expected {
                return Err(Error::Dimension {
                    what: format!("joint {name}: {what} limits"),
                    expected,
                    got,
                });
            }
        }
        Ok(())
    }

    /// Appends the `nv` degrees of freedom of the new joint `id` below `parent` to the
    /// dof tree: parents, joints, ancestor ranges and the tree's hash.
    fn push_dofs(&mut self, parent: usize, id: usize, nv: usize) {
        // Parent dof of this joint's first dof: the last dof of the nearest ancestor with dofs.
        let mut anc = parent;
        while anc != 0 && self.joints[anc].nv == 0 {
            anc = self.parents[anc];
        }
        let mut prev = if anc == 0 {
            NONE
        } else {
            self.joints[anc].idx_v + self.joints[anc].nv - 1
        };
        for k in 0..nv {
            self.dof_parent.push(prev);
            self.dof_joint.push(id);
            // Depth of the new dof = number of its ancestors = depth(prev) + 1.
            let depth = if prev == NONE {
                0
            } else {
                self.dof_anc_start[prev + 1] - self.dof_anc_start[prev] + 1
            };
            let end = self.dof_anc_start[self.nv + k] + depth;
            self.dof_anc_start.push(end);
            // FNV-1a step over the parent index (NONE included).
            self.dof_tree_hash = (self.dof_tree_hash ^ prev as u64).wrapping_mul(0x0100_0000_01b3);
            prev = self.nv + k;
        }
    }

    /// Adds the inertia `y` (given in a frame placed at `placement` in the joint frame) to
    /// the body of `joint`. Fails with [`Error::InvalidInertia`] if `y` is not physically
    /// valid (see [`Model::INERTIA_TOLERANCE`]) or the result overflows.
    pub fn append_body_to_joint(&mut self, joint: usize, y: &Inertia, placement: &Se3) -> Result<()> {
        self.check_joint_index(joint)?;
        self.check_inertia(joint, y)?;
        let mut sum = self.inertias[joint];
        sum += y.transformed(placement);
        self.check_inertia(joint, &sum)?;
        self.inertias[joint] = sum;
        Ok(())
    }

    /// Error naming joint `joint` if `y` is not a physically valid inertia.
    fn check_inertia(&self, joint: usize, y: &Inertia) -> Result<()> {
        match inertia_defect(y) {
            None => Ok(()),
            Some(message) => Err(Error::InvalidInertia {
                what: format!("body of joint `{}`", self.names[joint]),
                message,
            }),
        }
    }

    fn check_joint_index(&self, joint: usize) -> Result<()> {
        if joint < self.joints.len() {
            Ok(())
        } else {
            Err(Error::NotFound {
                what: "joint".into(),
                name: joint.to_string(),
            })
        }
    }

    /// Adds a frame and returns its id. Fails on an unknown parent joint or frame or a
    /// non-finite placement.
    pub fn add_frame(&mut self, frame: Frame) -> Result<usize> {
        if !frame.placement.is_finite() {
            return Err(Error::Invalid(format!("frame {}: placement is not finite", frame.name)));
        }
        if frame.parent_joint >= self.joints.len() {
            return Err(Error::NotFound {
                what: "parent joint of frame".into(),
                name: frame.name,
            });
        }
        if frame.parent_frame >= self.frames.len() {
            return Err(Error::NotFound {
                what: "parent frame of frame".into(),
                name: frame.name,
            });
        }
        self.frames.push(frame);
        Ok(self.frames.len() - 1)
    }

    /// Configuration size.
    pub fn nq(&self) -> usize {
        self.nq
    }

    /// Tangent size.
    pub fn nv(&self) -> usize {
        self.nv
    }

    /// Number of joints, the universe included.
    pub fn njoints(&self) -> usize {
        self.joints.len()
    }

    /// Number of frames, the universe frame included.
    pub fn nframes(&self) -> usize {
        self.frames.len()
    }

    /// Joint models (index 0 is the universe).
    pub fn joints(&self) -> &[JointModel] {
        &self.joints
    }

    /// Joint names.
    pub fn joint_names(&self) -> &[String] {
        &self.names
    }

    /// Parent joint of every joint (the universe is its own parent).
    pub fn parents(&self) -> &[usize] {
        &self.parents
    }

    /// Joint placements in their parent joint frames (at q = neutral).
    pub fn joint_placements(&self) -> &[Se3] {
        &self.placements
    }

    /// Body inertias in their joint frames (fixed-link merges included).
    pub fn inertias(&self) -> &[Inertia] {
        &self.inertias
    }

    /// Replaces the inertia of a joint's body. Fails with [`Error::InvalidInertia`] if `y`
    /// is not physically valid (see [`Model::INERTIA_TOLERANCE`]).
    pub fn set_inertia(&mut self, joint: usize, y: Inertia) -> Result<()> {
        self.check_joint_index(joint)?;
        self.check_inertia(joint, &y)?;
        self.inertias[joint] = y;
        Ok(())
    }

    /// The joints declared as mimic joints in the URDF (kept independent, see
    /// [`MimicJoint`]), in the order of the URDF's joint elements.
    pub fn mimic_joints(&self) -> &[MimicJoint] {
        &self.mimic
    }

    /// Frames (index 0 is the universe frame).
    pub fn frames(&self) -> &[Frame] {
        &self.frames
    }

    /// Id of the joint with this name.
    pub fn joint_id(&self, name: &str) -> Result<usize> {
        self.name_index.get(name).copied().ok_or_else(|| Error::NotFound {
            what: "joint".into(),
            name: name.into(),
        })
    }

    /// Id of the first frame with this name.
    pub fn frame_id(&self, name: &str) -> Result<usize> {
        self.frames
            .iter()
            .position(|f| f.name == name)
            .ok_or_else(|| Error::NotFound {
                what: "frame".into(),
                name: name.into(),
            })
    }

    /// Total mass of the bodies (the universe excluded).
    pub fn total_mass(&self) -> f64 {
        self.inertias[1..].iter().fold(0.0, |m, y| m + y.mass)
    }

    /// Allocates the workspace of every algorithm for this model.
    pub fn create_data(&self) -> Data {
        Data::new(self)
    }

    /// The tree of degrees of freedom, for the tree-sparse matrix kernels, with the
    /// subtree ends computed by [`Model::dof_subtree_ends`] (kept in `Data`).
    pub(crate) fn dof_tree<'a>(&'a self, subtree_end: &'a [usize]) -> DofTree<'a> {
        DofTree {
            parent: &self.dof_parent,
            subtree_end,
            anc_start: &self.dof_anc_start,
        }
    }

    /// For every dof `k`, the end (exclusive) of a range `k..end` of dofs containing
    /// every descendant of `k` (exactly its subtree when joints were added depth first,
    /// as the URDF loader does). O(nv): descendants have larger indices than their
    /// ancestors, so one pass from the leaves propagates the ends up.
    pub(crate) fn dof_subtree_ends(&self) -> Vec<usize> {
        let mut end: Vec<usize> = (1..=self.nv).collect();
        for k in (0..self.nv).rev() {
            let p = self.dof_parent[k];
            if p != NONE {
                end[p] = end[p].max(end[k]);
            }
        }
        end
    }

    /// Checks a configuration argument: length nq, finite entries, and unit-norm
    /// quaternions and (cos, sin) pairs within [`Model::UNIT_NORM_TOLERANCE`].
    pub(crate) fn check_configuration(&self, what: &str, q: &[f64]) -> Result<()> {
        crate::error::check_vec(what, q, self.nq)?;
        for b in &self.unit_blocks {
            let norm = q[b.start..b.start + b.len].iter().map(|x| x * x).sum::<f64>().sqrt();
            // The entries are finite, so the norm is not NaN (it may overflow to inf).
            if (norm - 1.0).abs() > Self::UNIT_NORM_TOLERANCE {
                return Err(Error::NotNormalized {
                    what: what.to_string(),
                    joint: self.names[b.joint].clone(),
                    block: if b.len == 4 { "quaternion" } else { "(cos, sin) pair" }.to_string(),
                    norm,
                    tolerance: Self::UNIT_NORM_TOLERANCE,
                });
            }
        }
        Ok(())
    }

    /// Records a mimic relation (URDF loader).
    pub(crate) fn add_mimic(&mut self, m: MimicJoint) {
        self.mimic.push(m);
    }

    /// Checks a frame id.
    pub(crate) fn check_frame(&self, frame: usize) -> Result<()> {
        if frame < self.frames.len() {
            Ok(())
        } else {
            Err(Error::NotFound {
                what: "frame".into(),
                name: frame.to_string(),
            })
        }
    }
}

/// What makes `y` physically invalid, or `None` (see [`Model::INERTIA_TOLERANCE`]).
pub(crate) fn inertia_defect(y: &Inertia) -> Option<String> {
    if !y.is_finite() {
        return Some(format!(
            "non-finite entries (mass {}, first moment {:?}, rotational {:?})",
            y.mass,
            y.first_moment.as_slice(),
            y.rotational.as_slice()
        ));
    }
    if y.mass < 0.0 {
        return Some(format!("negative mass {:e}", y.mass));
    }
    if y.mass == 0.0 && y.first_moment != Vec3::zeros() {
        return Some(format!(
            "zero mass with a nonzero first moment {:?}",
            y.first_moment.as_slice()
        ));
    }
    let ic = y.inertia_com();
    if !ic.iter().all(|x| x.is_finite()) {
        return Some("the rotational inertia about the centre of mass overflows".into());
    }
    let s = y.rotational.amax().max(ic.amax());
    let tol = Model::INERTIA_TOLERANCE * s;
    let asym = (ic - ic.transpose()).amax();
    if asym > tol {
        return Some(format!("rotational inertia not symmetric (asymmetry {asym:e})"));
    }
    let lmin = ic.symmetric_eigenvalues().min();
    // Also refuses a NaN eigenvalue (an overflow inside the eigensolver).
    if lmin.is_nan() || lmin < -tol {
        return Some(format!(
            "rotational inertia about the centre of mass not positive semidefinite (eigenvalue {lmin:e}, tolerance {tol:e})"
        ));
    }
    None
}

//! The kinematic tree: joints, bodies, frames, limits and gravity.

use crate::data::Data;
use crate::error::{Error, Result};
use crate::joint::{JointModel, JointType};
use crate::linalg::DofTree;
use crate::spatial::{Inertia, Motion, Se3, Vec3};

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
    /// End (exclusive) of a range `k..end` of dofs containing every descendant of dof `k`
    /// (exactly its subtree when joints were added depth first, as the URDF loader does).
    pub(crate) dof_subtree_end: Vec<usize>,
    /// Ancestors of every dof, nearest first, concatenated; those of dof k are
    /// `dof_anc[dof_anc_start[k]..dof_anc_start[k + 1]]`.
    pub(crate) dof_anc: Vec<usize>,
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
            dof_subtree_end: Vec::new(),
            dof_anc: Vec::new(),
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

    /// Adds a joint below `parent` at `placement` (in the parent joint's frame) and
    /// returns its id. Joints must be added parents first.
    pub fn add_joint(
        &mut self,
        parent: usize,
        kind: JointType,
        placement: Se3,
        name: &str,
        limits: JointLimits,
    ) -> Result<usize> {
        if parent >= self.joints.len() {
            return Err(Error::NotFound {
                what: "parent joint".into(),
                name: parent.to_string(),
            });
        }
        if kind == JointType::Universe {
            return Err(Error::Invalid(format!("joint {name}: the universe cannot be added")));
        }
        if self.names.iter().any(|n| n == name) {
            return Err(Error::Invalid(format!("joint {name}: name already used")));
        }
        let (nq, nv) = (kind.nq(), kind.nv());
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
        let id = self.joints.len();
        let jm = JointModel {
            kind,
            idx_q: self.nq,
            idx_v: self.nv,
            nq,
            nv,
        };
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
        let mut a = prev;
        while a != NONE {
            self.dof_subtree_end[a] = self.nv + nv;
            a = self.dof_parent[a];
        }
        for k in 0..nv {
            self.dof_parent.push(prev);
            self.dof_joint.push(id);
            self.dof_subtree_end.push(self.nv + nv);
            if prev != NONE {
                self.dof_anc.push(prev);
                self.dof_anc
                    .extend_from_within(self.dof_anc_start[prev]..self.dof_anc_start[prev + 1]);
            }
            self.dof_anc_start.push(self.dof_anc.len());
            // FNV-1a step over the parent index (NONE included).
            self.dof_tree_hash = (self.dof_tree_hash ^ prev as u64).wrapping_mul(0x0100_0000_01b3);
            prev = self.nv + k;
        }
        self.joints.push(jm);
        self.names.push(name.to_string());
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

    /// Adds the inertia `y` (given in a frame placed at `placement` in the joint frame) to
    /// the body of `joint`.
    pub fn append_body_to_joint(&mut self, joint: usize, y: &Inertia, placement: &Se3) -> Result<()> {
        if joint >= self.joints.len() {
            return Err(Error::NotFound {
                what: "joint".into(),
                name: joint.to_string(),
            });
        }
        self.inertias[joint] += y.transformed(placement);
        Ok(())
    }

    /// Adds a frame and returns its id.
    pub fn add_frame(&mut self, frame: Frame) -> Result<usize> {
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

    /// Replaces the inertia of a joint's body.
    pub fn set_inertia(&mut self, joint: usize, y: Inertia) -> Result<()> {
        match self.inertias.get_mut(joint) {
            Some(slot) => {
                *slot = y;
                Ok(())
            }
            None => Err(Error::NotFound {
                what: "joint".into(),
                name: joint.to_string(),
            }),
        }
    }

    /// Frames (index 0 is the universe frame).
    pub fn frames(&self) -> &[Frame] {
        &self.frames
    }

    /// Id of the joint with this name.
    pub fn joint_id(&self, name: &str) -> Result<usize> {
        self.names
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| Error::NotFound {
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
        self.inertias[1..].iter().map(|y| y.mass).sum()
    }

    /// Allocates the workspace of every algorithm for this model.
    pub fn create_data(&self) -> Data {
        Data::new(self)
    }

    /// The tree of degrees of freedom, for the tree-sparse matrix kernels.
    pub(crate) fn dof_tree(&self) -> DofTree<'_> {
        DofTree {
            parent: &self.dof_parent,
            subtree_end: &self.dof_subtree_end,
            anc_start: &self.dof_anc_start,
            anc: &self.dof_anc,
        }
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

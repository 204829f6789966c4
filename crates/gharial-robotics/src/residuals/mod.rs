//! Residuals of a multibody state `x = (q, v)` (and control `u`) for costs and
//! constraints, with analytical Jacobians with respect to the tangent `(dq, dv)` (and
//! `u`), as ALIGATOR's and Crocoddyl's residual models:
//!
//! | residual | r | nr | set for a constraint |
//! |---|---|---:|---|
//! | [`FramePlacementResidual`] | `log6(M_ref⁻¹ oMf(q))` | 6 | equality |
//! | [`FrameTranslationResidual`] | `p_f(q) − p_ref` (world) | 3 | equality, box |
//! | [`FrameRotationResidual`] | `log3(R_refᵀ R_f(q))` | 3 | equality |
//! | [`FrameVelocityResidual`] | `v_f(q, v) − v_ref` (LOCAL, WORLD or LWA) | 6 | equality |
//! | [`RelativePlacementResidual`] | `log6(M_ref⁻¹ oMa⁻¹ oMb)` | 6 | equality |
//! | [`FlyHighResidual`] | `v_xy(f) · exp(−slope · (z(f) − z_ground(x, y)))`, the ground a settable plane (default `z = 0`) | 2 | (cost) |
//! | [`CenterOfMassTranslationResidual`] | `c(q) − c_ref` | 3 | equality, box |
//! | [`CenterOfMassVelocityResidual`] | `ċ(q, v) − ċ_ref` | 3 | equality |
//! | [`GravityCompensationResidual`] | `B u − g(q)` | nv | (cost) |
//! | [`ContactForceResidual`] | `λ_k(x, u) − λ_ref` | 3 / 6 | equality |
//! | [`FrictionConeResidual`] | `(μ f_n, f_t)` of `λ_k` | 3 | [`SecondOrderCone`] |
//! | [`SmoothFrictionConeResidual`] | `(−f_n, ‖f_t‖_ε − μ f_n)` of `λ_k` | 2 | [`NegativeOrthant`] |
//! | [`WrenchConeResidual`] | `A λ_k` (rectangular foot) | 17 | [`NegativeOrthant`] |
//! | [`position_limits`], [`velocity_limits`], [`effort_limits`] | `q_S`, `v_S`, `u_S` | – | [`BoxConstraint`] |
//!
//! State-only residuals implement [`UnaryFunction`] (lift them to a stage with
//! [`gharial::functions::Unary`]); those of the control implement [`StageFunction`].
//! Frame names are resolved at construction; targets are checked and can be moved
//! between solves (`set_target`) without reallocation. Each residual keeps its own
//! multibody `Data` in its workspace: evaluation and Jacobians do not allocate, and
//! the Jacobians visit only the degrees of freedom that move the frame.
//!
//! A multibody error during evaluation (a non-finite state, a quaternion that is not
//! normalised) fills the output with NaN, which the solvers report as non-finite.
//!
//! ```
//! use std::sync::Arc;
//! use gharial::constraints::EqualityConstraintSet;
//! use gharial::costs::QuadraticResidualCost;
//! use gharial::functions::{StageFunction, Unary};
//! use gharial::problem::StageConstraint;
//! use gharial_multibody::{Model, RootJoint};
//! use gharial_robotics::MultibodyPhaseSpace;
//! use gharial_robotics::residuals::{FrameTranslationResidual, position_limits};
//! let urdf = r#"<robot name="arm"><link name="a"/><link name="b"/>
//!   <joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
//!   <origin xyz="0.5 0 0"/><limit lower="-1" upper="1" effort="5" velocity="2"/></joint></robot>"#;
//! let model = Arc::new(Model::from_urdf_str(urdf, RootJoint::Fixed)?);
//! let space = MultibodyPhaseSpace::new(model);
//! let nu = 1;
//! let ee: Arc<dyn StageFunction> =
//!     Arc::new(Unary::new(Arc::new(FrameTranslationResidual::new(&space, "b", &[0.5, 0.0, 0.0])?), nu));
//! let cost = QuadraticResidualCost::diagonal(ee.clone(), &[1.0; 3])?;
//! let reach = StageConstraint::new("reach", ee, Arc::new(EqualityConstraintSet));
//! let limits = position_limits(&space, nu)?;
//! assert_eq!((reach.nr(), limits.nr()), (3, 1));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! [`SecondOrderCone`]: gharial::constraints::SecondOrderCone
//! [`NegativeOrthant`]: gharial::constraints::NegativeOrthant
//! [`BoxConstraint`]: gharial::constraints::BoxConstraint
//! [`UnaryFunction`]: gharial::functions::UnaryFunction
//! [`StageFunction`]: gharial::functions::StageFunction

use faer::MatMut;
use gharial::functions::Workspace;
use gharial::param::ParamVec;
use gharial::{Error, Result};
use gharial_multibody::spatial::{Mat3, Motion, Se3, Vec3};
use gharial_multibody::{Data, Model};

use crate::MultibodyPhaseSpace;
use crate::multibody_error;

/// Implements the size methods of [`UnaryFunction`] from the field `layout` (a
/// [`StateLayout`]), for residuals with a workspace of their own.
macro_rules! unary_dims {
    ($nr:expr) => {
        fn nx(&self) -> usize {
            self.layout.nx()
        }
        fn ndx(&self) -> usize {
            self.layout.ndx()
        }
        fn nr(&self) -> usize {
            $nr
        }
    };
}

/// [`unary_dims`] and a [`MultibodyWs`] workspace from the field `model`.
macro_rules! unary_sizes {
    ($nr:expr) => {
        unary_dims!($nr);
        fn create_workspace(&self) -> Workspace {
            MultibodyWs::boxed(&self.model)
        }
    };
}

mod com;
mod contact;
mod frame;
mod gravity;
mod limits;
mod velocity;

pub use com::{CenterOfMassTranslationResidual, CenterOfMassVelocityResidual};
pub use contact::{
    ContactForceResidual, ContactResidual, ForceError, ForceMap, FrictionCone, FrictionConeResidual,
    SmoothFrictionCone, SmoothFrictionConeResidual, StackedContactResidual, WrenchCone, WrenchConeResidual,
};
pub use frame::{FramePlacementResidual, FrameRotationResidual, FrameTranslationResidual, RelativePlacementResidual};
pub use gravity::GravityCompensationResidual;
pub use limits::{ControlSelection, StateSelection, effort_limits, position_limits, velocity_limits};
pub use velocity::{FlyHighResidual, FrameVelocityResidual};

/// Sizes of a phase-space state `x = (q, v)`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct StateLayout {
    pub nq: usize,
    pub nv: usize,
}

impl StateLayout {
    pub fn of(space: &MultibodyPhaseSpace) -> Self {
        Self {
            nq: space.nq(),
            nv: space.nv(),
        }
    }
    pub fn nx(&self) -> usize {
        self.nq + self.nv
    }
    pub fn ndx(&self) -> usize {
        2 * self.nv
    }
    /// `q` of a state.
    pub fn q<'a>(&self, x: &'a [f64]) -> &'a [f64] {
        &x[..self.nq]
    }
    /// `v` of a state.
    pub fn v<'a>(&self, x: &'a [f64]) -> &'a [f64] {
        &x[self.nq..self.nq + self.nv]
    }
}

/// A frame of the model resolved at construction, with the degrees of freedom that
/// move it (the dofs of its parent joint and of all the joint's ancestors).
#[derive(Debug, Clone)]
pub(crate) struct FrameRef {
    /// Frame index in the model.
    pub id: usize,
    /// Joint the frame moves with.
    pub joint: usize,
    /// Placement of the frame in the joint frame.
    pub placement: Se3,
    /// The dofs moving the frame.
    pub support: Vec<usize>,
}

impl FrameRef {
    /// Resolves `name` in `model`; errors name `owner`.
    pub fn resolve(model: &Model, owner: &str, name: &str) -> Result<Self> {
        let id = model
            .frame_id(name)
            .map_err(|e| multibody_error(&format!("{owner}: model `{}`", model.name), e))?;
        let frame = &model.frames()[id];
        Ok(Self {
            id,
            joint: frame.parent_joint,
            placement: frame.placement,
            support: support_dofs(model, frame.parent_joint),
        })
    }

    /// World placement `oMf` from the joint placements in `data`.
    #[inline]
    pub fn placement(&self, data: &Data) -> Se3 {
        data.joint_placement(self.joint).compose(&self.placement)
    }
}

/// The dofs of `joint` and of all its ancestors.
pub(crate) fn support_dofs(model: &Model, joint: usize) -> Vec<usize> {
    let mut dofs = Vec::new();
    let mut j = joint;
    while j != 0 {
        let jm = &model.joints()[j];
        dofs.extend(jm.idx_v..jm.idx_v + jm.nv);
        j = model.parents()[j];
    }
    dofs.sort_unstable();
    dofs
}

/// The model's private data of a residual: a multibody `Data` and zero vectors
/// (velocities and accelerations for the kinematic passes that need them).
pub(crate) struct MultibodyWs {
    pub data: Data,
    pub zeros: Vec<f64>,
}

impl MultibodyWs {
    pub fn new(model: &Model) -> Self {
        Self {
            data: model.create_data(),
            zeros: vec![0.0; model.nv()],
        }
    }

    /// Boxed as a core workspace.
    pub fn boxed(model: &Model) -> Workspace {
        Box::new(Self::new(model))
    }
}

/// The workspace of a function's data, downcast (borrowing only the workspace field).
///
/// # Panics
/// If the data was created by another model (a programming error).
pub(crate) fn ws<T: 'static>(ws: &mut Workspace) -> &mut T {
    ws.downcast_mut::<T>()
        .expect("function data used with a residual that did not create it")
}

/// Fills `out` with NaN when a multibody computation failed during evaluation (the
/// functions' `evaluate` cannot return an error; the solvers report the non-finite
/// values). Returns whether it succeeded.
pub(crate) fn ok_or_nan<T>(res: gharial_multibody::Result<T>, out: &mut [f64]) -> bool {
    if res.is_err() {
        out.fill(f64::NAN);
        return false;
    }
    true
}

/// [`ok_or_nan`] for a Jacobian.
pub(crate) fn ok_or_nan_mat<T>(res: gharial_multibody::Result<T>, mut out: MatMut<'_, f64>) -> bool {
    if res.is_err() {
        out.fill(f64::NAN);
        return false;
    }
    true
}

/// Writes a 3-vector into rows `row..row + 3` of column `col`.
#[inline]
pub(crate) fn put3(m: &mut MatMut<'_, f64>, row: usize, col: usize, v: &Vec3) {
    for i in 0..3 {
        m[(row + i, col)] = v[i];
    }
}

/// Writes a motion `[linear, angular]` into rows `0..6` of column `col`.
#[inline]
pub(crate) fn put6(m: &mut MatMut<'_, f64>, col: usize, v: &Motion) {
    put3(m, 0, col, &v.linear);
    put3(m, 3, col, &v.angular);
}

/// Checks a reference vector's size and finiteness.
pub(crate) fn check_vector(what: &str, v: &[f64], n: usize) -> Result<()> {
    gharial::error::check_dim(what, n, v.len())?;
    gharial::error::check_finite(what, v)
}

/// Checks that a placement is finite with a rotation matrix (orthonormal within 1e-9,
/// determinant 1).
pub(crate) fn check_placement(what: &str, m: &Se3) -> Result<()> {
    gharial::error::check_finite(what, m.translation.as_slice())?;
    check_rotation(what, &m.rotation)
}

/// Checks that a matrix is a rotation (orthonormal within 1e-9, determinant 1).
pub(crate) fn check_rotation(what: &str, r: &Mat3) -> Result<()> {
    if !r.iter().all(|x| x.is_finite()) {
        return Err(Error::non_finite(what));
    }
    let gap = (r.transpose() * r - Mat3::identity()).amax();
    if gap > 1e-9 || r.determinant() < 0.0 {
        return Err(Error::InvalidModel(format!(
            "{what}: the rotation is not orthonormal with determinant 1 (|RᵀR − I| = {gap:e})"
        )));
    }
    Ok(())
}

/// A placement target stored as 12 numbers (rotation column-major, then translation),
/// movable through `&self`.
#[derive(Debug)]
pub(crate) struct PlacementTarget {
    what: &'static str,
    values: ParamVec,
}

impl PlacementTarget {
    pub fn new(what: &'static str, m: &Se3) -> Result<Self> {
        check_placement(what, m)?;
        Ok(Self {
            what,
            values: ParamVec::new(&Self::pack(m)),
        })
    }

    fn pack(m: &Se3) -> [f64; 12] {
        let mut p = [0.0; 12];
        p[..9].copy_from_slice(m.rotation.as_slice());
        p[9..].copy_from_slice(m.translation.as_slice());
        p
    }

    pub fn set(&self, m: &Se3) -> Result<()> {
        check_placement(self.what, m)?;
        self.values.write(&Self::pack(m))
    }

    pub fn get(&self) -> Se3 {
        let mut p = [0.0; 12];
        self.values.read(&mut p);
        Se3::new(Mat3::from_column_slice(&p[..9]), Vec3::new(p[9], p[10], p[11]))
    }
}

/// A vector target of fixed size, movable through `&self`.
#[derive(Debug)]
pub(crate) struct VectorTarget {
    what: &'static str,
    values: ParamVec,
}

impl VectorTarget {
    pub fn new(what: &'static str, v: &[f64], n: usize) -> Result<Self> {
        check_vector(what, v, n)?;
        Ok(Self {
            what,
            values: ParamVec::new(v),
        })
    }

    pub fn set(&self, v: &[f64]) -> Result<()> {
        check_vector(self.what, v, self.values.len())?;
        self.values.write(v)
    }

    pub fn get(&self) -> Vec<f64> {
        self.values.to_vec()
    }

    /// Size.
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// Entry `i`.
    #[inline]
    pub fn at(&self, i: usize) -> f64 {
        self.values.get(i)
    }

    /// The first three entries.
    #[inline]
    pub fn vec3(&self) -> Vec3 {
        Vec3::new(self.at(0), self.at(1), self.at(2))
    }
}

//! Multibody dynamics as core [`Ode`](gharial::dynamics::Ode)s on the phase space `x = (q, v)`.
//!
//! - [`MultibodyFreeFwdDynamics`]: `ẋ = (v, a)` with `a = ABA(q, v, B u)`.
//! - [`MultibodyConstraintFwdDynamics`]: rigid 3D / 6D contacts with Baumgarte
//!   stabilisation (ProxDDP paper, (55) and (56)): `a` and the contact forces `λ` solve
//!   `M a + b = B u + Jcᵀ λ`, `Jc a + γ = −Kp c(q) − Kd ċ` exactly (KKT solve).
//! - [`MultibodyWeldFwdDynamics`]: a free body (a grasped object) held at its parent
//!   frame by a 6D constraint with Baumgarte stabilisation; its free dynamics release it.
//!
//! Both take the actuation matrix `B` (`nv × nu`, [`Actuation`]), the armature from the
//! model (`Model::armature`, on the diagonal of `M` in every multibody algorithm), and
//! give the Jacobians in tangent coordinates (`δx = (δq, δv)`, `δq` of size `nv`):
//! ```text
//! ∂ẋ/∂x = [ 0      I     ]      ∂ẋ/∂u = [ 0        ]
//!         [ ∂a/∂q  ∂a/∂v ]              [ ∂a/∂τ B  ]      (∂a/∂τ = M⁻¹ without contacts)
//! ```
//! Turn them into discrete dynamics with the core's integrators: `SemiImplicitEuler`
//! (given the configuration space [`crate::MultibodyPhaseSpace::configuration`]),
//! `ExplicitRungeKutta` (Euler, RK2, RK4).
//!
//! # Bad input during evaluation
//! The [`Ode`](gharial::dynamics::Ode) trait has no `Result`: when `x` or `u` is invalid (wrong size, NaN or
//! infinity, a quaternion of norm other than 1) or the multibody algorithm fails (e.g. a
//! rank-deficient contact Jacobian), `evaluate` writes NaN into `ẋ` and `jacobians` NaN
//! into the Jacobians; the solvers detect the non-finite values and stop with their
//! non-finite status. The error is kept in the data: read it with [`last_error`]. The
//! same checks are available with a `Result` as `check_inputs` on each ODE.

use std::sync::Arc;

use faer::prelude::ReborrowMut;
use faer::{MatMut, MatRef};
use gharial::dynamics::OdeData;
use gharial::error::{check_dim, check_finite};
use gharial::linalg::copy;
use gharial::spaces::{Manifold, VALID_TOL};
use gharial::{Error, Result};
use gharial_multibody::{JointType, Model};

use crate::MultibodyPhaseSpace;

mod actuation;
mod constrained;
mod contacts;
mod free;
mod weld;

pub use actuation::Actuation;
pub use constrained::{ContactDynamicsData, MultibodyConstraintFwdDynamics, SharedContactData};
pub use contacts::{ContactSpec, contacts_at_frames, set_contact_references};
pub use free::MultibodyFreeFwdDynamics;
pub use weld::{MultibodyWeldFwdDynamics, WeldData};

/// What both multibody ODEs share: the phase space, the actuation and the checks and
/// writes of `(x, u)`, `ẋ` and the Jacobians.
#[derive(Clone)]
struct PhaseOde {
    /// Name of the ODE type, for error messages.
    name: &'static str,
    space: Arc<MultibodyPhaseSpace>,
    /// The same space as a core manifold.
    manifold: Arc<dyn Manifold>,
    actuation: Arc<Actuation>,
}

impl PhaseOde {
    fn new(name: &'static str, space: Arc<MultibodyPhaseSpace>, actuation: Arc<Actuation>) -> Result<Self> {
        check_dim(
            format_args!("{name}: rows of the actuation matrix B (nv of the model)"),
            space.nv(),
            actuation.nv(),
        )?;
        let manifold: Arc<dyn Manifold> = space.clone();
        Ok(Self {
            name,
            space,
            manifold,
            actuation,
        })
    }

    fn model(&self) -> &Model {
        self.space.model()
    }

    fn nq(&self) -> usize {
        self.space.nq()
    }

    fn nv(&self) -> usize {
        self.space.nv()
    }

    /// Checks the sizes and finiteness of `x` and `u` and that `q` lies on the
    /// configuration manifold (unit quaternions and (cos, sin) pairs within
    /// [`VALID_TOL`]). Allocates only when it fails.
    fn check_inputs(&self, x: &[f64], u: &[f64]) -> Result<()> {
        let name = self.name;
        self.check_sizes(x, u)?;
        check_finite(format_args!("{name}: state x"), x)?;
        check_finite(format_args!("{name}: control u"), u)?;
        // On a vector space every finite point is valid.
        if !self.space.is_vector_space() && !self.space.is_valid(x) {
            return Err(Error::InvalidModel(format!(
                "{name}: state x is not on the configuration manifold: {}",
                off_manifold_joint(self.model(), &x[..self.nq()])
            )));
        }
        Ok(())
    }

    /// Checks the sizes of `x` and `u` only: for the Jacobians, at the point of an
    /// `evaluate` that checked it whole (the multibody algorithms still refuse
    /// non-finite entries and quaternions off the unit sphere).
    fn check_sizes(&self, x: &[f64], u: &[f64]) -> Result<()> {
        let (name, nq, nv) = (self.name, self.nq(), self.nv());
        check_dim(
            format_args!("{name}: state x (nq + nv = {nq} + {nv})"),
            nq + nv,
            x.len(),
        )?;
        check_dim(format_args!("{name}: control u (nu)"), self.actuation.nu(), u.len())
    }

    /// `ẋ = (v, a)`.
    fn write_xdot(&self, x: &[f64], a: &[f64], xdot: &mut [f64]) {
        let (nq, nv) = (self.nq(), self.nv());
        xdot[..nv].copy_from_slice(&x[nq..]);
        xdot[nv..].copy_from_slice(a);
    }

    /// `∂ẋ/∂x = [[0, I], [∂a/∂q, ∂a/∂v]]`, `∂ẋ/∂u = [[0], [∂a/∂τ B]]`; the bottom rows
    /// only unless `full` ([`gharial::dynamics::Ode::acceleration_jacobians`]).
    fn write_jacobians(
        &self,
        da_dq: MatRef<'_, f64>,
        da_dv: MatRef<'_, f64>,
        da_dtau: MatRef<'_, f64>,
        (jx, ju): (MatMut<'_, f64>, MatMut<'_, f64>),
        full: bool,
    ) {
        let nv = self.nv();
        let (mut top, mut bottom) = jx.split_at_row_mut(nv);
        let (mut utop, ubottom) = ju.split_at_row_mut(nv);
        if full {
            gharial::linalg::fill(top.as_mut(), 0.0);
            for i in 0..nv {
                top[(i, nv + i)] = 1.0;
            }
            gharial::linalg::fill(utop.as_mut(), 0.0);
        }
        let (dq, dv) = bottom.rb_mut().split_at_col_mut(nv);
        copy(dq, da_dq);
        copy(dv, da_dv);
        self.actuation.right_multiply(da_dtau, ubottom);
    }
}

/// The joint whose configuration is off its manifold, for the error message.
fn off_manifold_joint(model: &Model, q: &[f64]) -> String {
    for (j, name) in model.joints().iter().zip(model.joint_names()) {
        let block = &q[j.idx_q..j.idx_q + j.nq];
        let unit = match j.kind {
            JointType::FreeFlyer => &block[3..7],
            JointType::Spherical => block,
            JointType::Planar => &block[2..4],
            JointType::RevoluteUnbounded(_) => block,
            _ => continue,
        };
        let norm = unit.iter().map(|v| v * v).sum::<f64>().sqrt();
        if (norm - 1.0).abs() > VALID_TOL {
            return format!(
                "joint `{name}` (q[{}..{}]) has a unit-norm part of norm {norm} (tolerance {VALID_TOL:e})",
                j.idx_q,
                j.idx_q + j.nq
            );
        }
    }
    "no joint found off its manifold".into()
}

/// The workspace of an ODE's data as its own type.
///
/// # Panics
/// If the data was created by another model (a programming error).
fn workspace<T: 'static>(ws: &mut gharial::functions::Workspace) -> &mut T {
    ws.downcast_mut::<T>()
        .expect("ODE data used with a model that did not create it")
}

/// Writes NaN into `ẋ` (the failure value of `evaluate`).
fn nan_xdot(data: &mut OdeData) {
    data.xdot.fill(f64::NAN);
}

/// Writes NaN into the Jacobians (the failure value of `jacobians`).
fn nan_jacobians(data: &mut OdeData) {
    data.jx.fill(f64::NAN);
    data.ju.fill(f64::NAN);
}

/// The error of the last failed `evaluate` or `jacobians` of a multibody ODE on `data`
/// (`None` after a successful call, or if `data` was not created by a multibody ODE).
pub fn last_error(data: &OdeData) -> Option<&Error> {
    if let Some(ws) = data.ws.downcast_ref::<free::FreeWs>() {
        return ws.error.as_ref();
    }
    data.ws
        .downcast_ref::<constrained::ContactOdeWs>()
        .and_then(|ws| ws.error.as_ref())
}

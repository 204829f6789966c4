//! Dynamics in the two forms of the ProxDDP paper: explicit `y = φ(x, u)` and implicit
//! `f(x, u, y) = 0`, and continuous-time ODEs `ẋ = f(x, u)` that the integrators turn
//! into discrete dynamics.
//!
//! The dynamics constraint seen by the solvers is `f(x, u, y) = 0` with values in the
//! tangent space of the next state (`ndx_next`). Explicit dynamics enter it as
//! `f(x, u, y) = φ(x, u) ⊖ y`, i.e. `difference(y, φ(x, u))`, whose Jacobian in `y` is
//! `-I` on vector spaces.

use std::sync::Arc;

use faer::{Col, Mat};

use crate::functions::{Workspace, no_workspace};
use crate::spaces::Manifold;

pub mod implicit;
pub mod integrators;
mod linear;
#[cfg(test)]
pub(crate) mod manifold_tests;

pub use implicit::{ExplicitAsImplicit, ImplicitEuler, ImplicitMidpoint};
pub use integrators::{ExplicitRungeKutta, RkMethod, SemiImplicitEuler};
pub use linear::{LinearDiscreteDynamics, LinearOde};

/// What [`ExplicitDynamics`] writes: next state and Jacobians.
#[derive(Debug)]
pub struct ExplicitDynamicsData {
    /// `φ(x, u)` (`nx_next`).
    pub xnext: Col<f64>,
    /// `dφ/dx` (`ndx_next x ndx`), tangent convention on both sides.
    pub jx: Mat<f64>,
    /// `dφ/du` (`ndx_next x nu`).
    pub ju: Mat<f64>,
    /// Second-order term `d²(λ · ψ)/dx²` (`ndx x ndx`) where
    /// `ψ(δx, δu) = φ(x ⊕ δx, u + δu) ⊖ φ(x, u)`.
    pub vhp_xx: Mat<f64>,
    /// `d²(λ · ψ)/dxdu` (`ndx x nu`).
    pub vhp_xu: Mat<f64>,
    /// `d²(λ · ψ)/du²` (`nu x nu`).
    pub vhp_uu: Mat<f64>,
    /// The model's private scratch memory.
    pub ws: Workspace,
}

impl ExplicitDynamicsData {
    /// Zero-filled data.
    pub fn new(nx_next: usize, ndx_next: usize, ndx: usize, nu: usize, ws: Workspace) -> Self {
        Self {
            xnext: Col::zeros(nx_next),
            jx: Mat::zeros(ndx_next, ndx),
            ju: Mat::zeros(ndx_next, nu),
            vhp_xx: Mat::zeros(ndx, ndx),
            vhp_xu: Mat::zeros(ndx, nu),
            vhp_uu: Mat::zeros(nu, nu),
            ws,
        }
    }

    /// The next state as a slice.
    pub fn xnext(&self) -> &[f64] {
        crate::linalg::slice(&self.xnext)
    }

    /// The next state as a mutable slice.
    pub fn xnext_mut(&mut self) -> &mut [f64] {
        crate::linalg::slice_mut(&mut self.xnext)
    }

    /// Downcasts the workspace to the model's own type.
    ///
    /// # Panics
    /// If the data was created by another model (a programming error).
    pub fn ws<T: 'static>(&mut self) -> &mut T {
        self.ws
            .downcast_mut::<T>()
            .expect("dynamics data used with a model that did not create it")
    }
}

/// Discrete dynamics `y = φ(x, u)`.
pub trait ExplicitDynamics: Send + Sync {
    /// Space of the current state `x`.
    fn space(&self) -> &Arc<dyn Manifold>;
    /// Space of the next state `y` (default: the same as `x`).
    fn space_next(&self) -> &Arc<dyn Manifold> {
        self.space()
    }
    /// Control size.
    fn nu(&self) -> usize;

    /// Creates the private scratch memory (default: none).
    fn create_workspace(&self) -> Workspace {
        no_workspace()
    }

    /// Creates the data this model writes into.
    fn create_data(&self) -> ExplicitDynamicsData {
        let (s, sn) = (self.space(), self.space_next());
        ExplicitDynamicsData::new(sn.nx(), sn.ndx(), s.ndx(), self.nu(), self.create_workspace())
    }

    /// Writes `φ(x, u)` into `data.xnext`.
    fn forward(&self, x: &[f64], u: &[f64], data: &mut ExplicitDynamicsData);

    /// Writes `dφ/dx`, `dφ/du` into `data.jx`, `data.ju`; `forward` has been called at
    /// the same point before.
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut ExplicitDynamicsData);

    /// Whether `jacobians` writes the same `jx`, `ju` at every point (linear dynamics;
    /// default: false), so that callers may skip it after a first call on the same data.
    /// `vhp` must then not depend on a call of `jacobians` at the same point.
    fn jacobians_are_constant(&self) -> bool {
        false
    }

    /// Whether [`ExplicitDynamics::vhp`] computes the second-order term.
    fn has_vhp(&self) -> bool {
        false
    }

    /// Writes the vector-Hessian products for the co-state `lambda` (`ndx_next`) into
    /// `data.vhp_*`; `jacobians` has been called before. Default: zero.
    fn vhp(&self, x: &[f64], u: &[f64], lambda: &[f64], data: &mut ExplicitDynamicsData) {
        let _ = (x, u, lambda);
        data.vhp_xx.fill(0.0);
        data.vhp_xu.fill(0.0);
        data.vhp_uu.fill(0.0);
    }
}

/// What [`ImplicitDynamics`] writes: residual, Jacobians and vector-Hessian products.
#[derive(Debug)]
pub struct ImplicitDynamicsData {
    /// `f(x, u, y)` (`ndx_next`).
    pub value: Col<f64>,
    /// `df/dx` (`ndx_next x ndx`).
    pub jx: Mat<f64>,
    /// `df/du` (`ndx_next x nu`).
    pub ju: Mat<f64>,
    /// `df/dy` (`ndx_next x ndx_next`).
    pub jy: Mat<f64>,
    /// `d²(λᵀ f)/dx²`.
    pub vhp_xx: Mat<f64>,
    /// `d²(λᵀ f)/dxdu`.
    pub vhp_xu: Mat<f64>,
    /// `d²(λᵀ f)/du²`.
    pub vhp_uu: Mat<f64>,
    /// `d²(λᵀ f)/dxdy` (`ndx x ndx_next`).
    pub vhp_xy: Mat<f64>,
    /// `d²(λᵀ f)/dudy` (`nu x ndx_next`).
    pub vhp_uy: Mat<f64>,
    /// `d²(λᵀ f)/dy²`.
    pub vhp_yy: Mat<f64>,
    /// The model's private scratch memory.
    pub ws: Workspace,
}

impl ImplicitDynamicsData {
    /// Zero-filled data.
    pub fn new(ndx: usize, nu: usize, ndx_next: usize, ws: Workspace) -> Self {
        Self {
            value: Col::zeros(ndx_next),
            jx: Mat::zeros(ndx_next, ndx),
            ju: Mat::zeros(ndx_next, nu),
            jy: Mat::zeros(ndx_next, ndx_next),
            vhp_xx: Mat::zeros(ndx, ndx),
            vhp_xu: Mat::zeros(ndx, nu),
            vhp_uu: Mat::zeros(nu, nu),
            vhp_xy: Mat::zeros(ndx, ndx_next),
            vhp_uy: Mat::zeros(nu, ndx_next),
            vhp_yy: Mat::zeros(ndx_next, ndx_next),
            ws,
        }
    }

    /// The residual as a slice.
    pub fn value(&self) -> &[f64] {
        crate::linalg::slice(&self.value)
    }

    /// The residual as a mutable slice.
    pub fn value_mut(&mut self) -> &mut [f64] {
        crate::linalg::slice_mut(&mut self.value)
    }

    /// Downcasts the workspace to the model's own type.
    ///
    /// # Panics
    /// If the data was created by another model (a programming error).
    pub fn ws<T: 'static>(&mut self) -> &mut T {
        self.ws
            .downcast_mut::<T>()
            .expect("dynamics data used with a model that did not create it")
    }
}

/// Discrete dynamics in implicit form `f(x, u, y) = 0`, `y` the next state.
pub trait ImplicitDynamics: Send + Sync {
    /// Space of the current state `x`.
    fn space(&self) -> &Arc<dyn Manifold>;
    /// Space of the next state `y` (default: the same as `x`).
    fn space_next(&self) -> &Arc<dyn Manifold> {
        self.space()
    }
    /// Control size.
    fn nu(&self) -> usize;

    /// Creates the private scratch memory (default: none).
    fn create_workspace(&self) -> Workspace {
        no_workspace()
    }

    /// Creates the data this model writes into.
    fn create_data(&self) -> ImplicitDynamicsData {
        ImplicitDynamicsData::new(
            self.space().ndx(),
            self.nu(),
            self.space_next().ndx(),
            self.create_workspace(),
        )
    }

    /// Writes `f(x, u, y)` into `data.value`.
    fn evaluate(&self, x: &[f64], u: &[f64], y: &[f64], data: &mut ImplicitDynamicsData);

    /// Writes the Jacobians into `data.jx`, `data.ju`, `data.jy`; `evaluate` has been
    /// called at the same point before.
    fn jacobians(&self, x: &[f64], u: &[f64], y: &[f64], data: &mut ImplicitDynamicsData);

    /// Whether `jacobians` writes the same `jx`, `ju`, `jy` at every point (default:
    /// false); see [`ExplicitDynamics::jacobians_are_constant`].
    fn jacobians_are_constant(&self) -> bool {
        false
    }

    /// Whether [`ImplicitDynamics::vhp`] computes the second-order term.
    fn has_vhp(&self) -> bool {
        false
    }

    /// Writes the vector-Hessian products for `lambda` (`ndx_next`) into `data.vhp_*`.
    /// Default: zero.
    fn vhp(&self, x: &[f64], u: &[f64], y: &[f64], lambda: &[f64], data: &mut ImplicitDynamicsData) {
        let _ = (x, u, y, lambda);
        data.vhp_xx.fill(0.0);
        data.vhp_xu.fill(0.0);
        data.vhp_uu.fill(0.0);
        data.vhp_xy.fill(0.0);
        data.vhp_uy.fill(0.0);
        data.vhp_yy.fill(0.0);
    }
}

/// The dynamics of a stage, in either form.
#[derive(Clone)]
pub enum Dynamics {
    /// `y = φ(x, u)`.
    Explicit(Arc<dyn ExplicitDynamics>),
    /// `f(x, u, y) = 0`.
    Implicit(Arc<dyn ImplicitDynamics>),
}

impl Dynamics {
    /// Space of the current state.
    pub fn space(&self) -> &Arc<dyn Manifold> {
        match self {
            Dynamics::Explicit(d) => d.space(),
            Dynamics::Implicit(d) => d.space(),
        }
    }

    /// Space of the next state.
    pub fn space_next(&self) -> &Arc<dyn Manifold> {
        match self {
            Dynamics::Explicit(d) => d.space_next(),
            Dynamics::Implicit(d) => d.space_next(),
        }
    }

    /// Control size.
    pub fn nu(&self) -> usize {
        match self {
            Dynamics::Explicit(d) => d.nu(),
            Dynamics::Implicit(d) => d.nu(),
        }
    }

    /// Whether the Jacobians of the implicit form `f(x, u, y)` are the same at every
    /// point: constant model Jacobians, and for explicit dynamics next states in a
    /// vector space (`f = φ(x, u) - y`).
    pub fn jacobians_are_constant(&self) -> bool {
        match self {
            Dynamics::Explicit(d) => d.jacobians_are_constant() && d.space_next().is_vector_space(),
            Dynamics::Implicit(d) => d.jacobians_are_constant(),
        }
    }

    /// Whether the model provides second-order terms.
    pub fn has_vhp(&self) -> bool {
        match self {
            Dynamics::Explicit(d) => d.has_vhp(),
            Dynamics::Implicit(d) => d.has_vhp(),
        }
    }
}

/// What an [`Ode`] writes: the velocity and its Jacobians.
#[derive(Debug)]
pub struct OdeData {
    /// `ẋ = f(x, u)` as a tangent vector at `x` (`ndx`).
    pub xdot: Col<f64>,
    /// `df/dx` (`ndx x ndx`).
    pub jx: Mat<f64>,
    /// `df/du` (`ndx x nu`).
    pub ju: Mat<f64>,
    /// The model's private scratch memory.
    pub ws: Workspace,
}

impl OdeData {
    /// Zero-filled data.
    pub fn new(ndx: usize, nu: usize, ws: Workspace) -> Self {
        Self {
            xdot: Col::zeros(ndx),
            jx: Mat::zeros(ndx, ndx),
            ju: Mat::zeros(ndx, nu),
            ws,
        }
    }

    /// The velocity as a slice.
    pub fn xdot(&self) -> &[f64] {
        crate::linalg::slice(&self.xdot)
    }

    /// The velocity as a mutable slice.
    pub fn xdot_mut(&mut self) -> &mut [f64] {
        crate::linalg::slice_mut(&mut self.xdot)
    }

    /// Downcasts the workspace to the model's own type.
    ///
    /// # Panics
    /// If the data was created by another model (a programming error).
    pub fn ws<T: 'static>(&mut self) -> &mut T {
        self.ws
            .downcast_mut::<T>()
            .expect("ODE data used with a model that did not create it")
    }
}

/// Continuous-time dynamics `ẋ = f(x, u)` with `ẋ` in the tangent space at `x`.
pub trait Ode: Send + Sync {
    /// State space.
    fn space(&self) -> &Arc<dyn Manifold>;
    /// Control size.
    fn nu(&self) -> usize;

    /// Creates the private scratch memory (default: none).
    fn create_workspace(&self) -> Workspace {
        no_workspace()
    }

    /// Creates the data this model writes into.
    fn create_data(&self) -> OdeData {
        OdeData::new(self.space().ndx(), self.nu(), self.create_workspace())
    }

    /// Writes `f(x, u)` into `data.xdot`.
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut OdeData);

    /// Writes `df/dx`, `df/du`; `evaluate` has been called at the same point before.
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut OdeData);

    /// Writes at least the rows of `df/dx`, `df/du` past the first `ndx / 2`: the
    /// accelerations of a second-order system `ẋ = (v, a(x, u))`, the only rows that its
    /// integrators read ([`SemiImplicitEuler`]); `evaluate` has been called at the same
    /// point before. Default: [`Ode::jacobians`]; the multibody models leave their
    /// constant first rows (`[0 I]` and `0`) as they are.
    fn acceleration_jacobians(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        self.jacobians(x, u, data);
    }
}

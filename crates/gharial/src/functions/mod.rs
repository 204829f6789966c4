//! Differentiable vector functions of the state and control: stage functions `r(x, u)`
//! and unary functions `r(x)`. They are the residuals that costs and constraints are
//! built from.
//!
//! Model / data: a function is immutable and shared (`Arc<dyn StageFunction>`); each
//! evaluation writes into a [`StageFunctionData`] created once by
//! [`StageFunction::create_data`]. Jacobians are taken with respect to tangent
//! perturbations of `x` (`ndx` columns) and plain perturbations of `u`.

use std::any::Any;
use std::sync::Arc;

use faer::{Col, Mat};

mod compose;
mod linear;
mod shared;
mod state_error;
#[cfg(test)]
pub(crate) mod testing;
pub(crate) mod util;

pub use compose::{FunctionStack, LinearComposition, Slice};
pub use linear::{LinearFunction, LinearUnaryFunction};
pub use shared::{lock, shared_data, with_shared_data};
pub use state_error::{ControlError, StateError};

/// Scratch memory owned by a data object and private to the model that created it.
pub type Workspace = Box<dyn Any + Send + Sync>;

/// An empty workspace, for models that need no scratch memory.
pub fn no_workspace() -> Workspace {
    Box::new(())
}

/// What a [`StageFunction`] writes: value, Jacobians and vector-Hessian products.
#[derive(Debug)]
pub struct StageFunctionData {
    /// `r(x, u)` (`nr`).
    pub value: Col<f64>,
    /// `dr/dx` (`nr x ndx`).
    pub jx: Mat<f64>,
    /// `dr/du` (`nr x nu`).
    pub ju: Mat<f64>,
    /// `d²(λᵀ r)/dx²` (`ndx x ndx`) for the last `λ` passed to `vhp`.
    pub vhp_xx: Mat<f64>,
    /// `d²(λᵀ r)/dxdu` (`ndx x nu`).
    pub vhp_xu: Mat<f64>,
    /// `d²(λᵀ r)/du²` (`nu x nu`).
    pub vhp_uu: Mat<f64>,
    /// The model's private scratch memory.
    pub ws: Workspace,
}

impl StageFunctionData {
    /// Zero-filled data for a function of dimensions `(ndx, nu, nr)`.
    pub fn new(ndx: usize, nu: usize, nr: usize, ws: Workspace) -> Self {
        Self {
            value: Col::zeros(nr),
            jx: Mat::zeros(nr, ndx),
            ju: Mat::zeros(nr, nu),
            vhp_xx: Mat::zeros(ndx, ndx),
            vhp_xu: Mat::zeros(ndx, nu),
            vhp_uu: Mat::zeros(nu, nu),
            ws,
        }
    }

    /// The value as a slice.
    pub fn value(&self) -> &[f64] {
        crate::linalg::slice(&self.value)
    }

    /// The value as a mutable slice.
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
            .expect("function data used with a model that did not create it")
    }
}

/// A differentiable function `r(x, u)` of a state on a manifold and a control vector.
pub trait StageFunction: Send + Sync {
    /// Representation size of the state.
    fn nx(&self) -> usize;
    /// Tangent size of the state.
    fn ndx(&self) -> usize;
    /// Control size.
    fn nu(&self) -> usize;
    /// Output size.
    fn nr(&self) -> usize;

    /// Creates the private scratch memory of this function (default: none).
    fn create_workspace(&self) -> Workspace {
        no_workspace()
    }

    /// Creates the data this function writes into.
    fn create_data(&self) -> StageFunctionData {
        StageFunctionData::new(self.ndx(), self.nu(), self.nr(), self.create_workspace())
    }

    /// Writes `r(x, u)` into `data.value`.
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData);

    /// Writes `dr/dx`, `dr/du` into `data.jx`, `data.ju`. `evaluate` has been called at
    /// the same point before.
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData);

    /// Whether `jacobians` writes the same `jx`, `ju` at every point (affine functions;
    /// default: false), so that callers may skip it after a first call on the same data.
    /// `vhp` must then not depend on a call of `jacobians` at the same point.
    fn jacobians_are_constant(&self) -> bool {
        false
    }

    /// Whether [`StageFunction::vhp`] computes the second-order term (otherwise it is
    /// zero, which is exact for linear functions and the Gauss-Newton approximation
    /// for others).
    fn has_vhp(&self) -> bool {
        false
    }

    /// Writes the vector-Hessian products `d²(λᵀ r)` into `data.vhp_*`. `jacobians`
    /// has been called at the same point before. Default: zero.
    fn vhp(&self, x: &[f64], u: &[f64], lambda: &[f64], data: &mut StageFunctionData) {
        let _ = (x, u, lambda);
        crate::linalg::fill(data.vhp_xx.as_mut(), 0.0);
        crate::linalg::fill(data.vhp_xu.as_mut(), 0.0);
        crate::linalg::fill(data.vhp_uu.as_mut(), 0.0);
    }
}

/// A differentiable function `r(x)` of the state only.
///
/// It writes into a [`StageFunctionData`] whose control blocks are left untouched, so
/// that [`Unary`] can lift it to a [`StageFunction`] of any control size.
pub trait UnaryFunction: Send + Sync {
    /// Representation size of the state.
    fn nx(&self) -> usize;
    /// Tangent size of the state.
    fn ndx(&self) -> usize;
    /// Output size.
    fn nr(&self) -> usize;

    /// Creates the private scratch memory of this function (default: none).
    fn create_workspace(&self) -> Workspace {
        no_workspace()
    }

    /// Writes `r(x)` into `data.value`.
    fn evaluate(&self, x: &[f64], data: &mut StageFunctionData);

    /// Writes `dr/dx` into `data.jx`.
    fn jacobian(&self, x: &[f64], data: &mut StageFunctionData);

    /// Whether `jacobian` writes the same `jx` at every point (default: false); see
    /// [`StageFunction::jacobians_are_constant`].
    fn jacobian_is_constant(&self) -> bool {
        false
    }

    /// Whether [`UnaryFunction::vhp`] computes the second-order term.
    fn has_vhp(&self) -> bool {
        false
    }

    /// Writes `d²(λᵀ r)/dx²` into `data.vhp_xx`. Default: zero.
    fn vhp(&self, x: &[f64], lambda: &[f64], data: &mut StageFunctionData) {
        let _ = (x, lambda);
        crate::linalg::fill(data.vhp_xx.as_mut(), 0.0);
    }
}

/// Lifts a [`UnaryFunction`] to a [`StageFunction`] with `nu` controls and a zero
/// control Jacobian.
#[derive(Clone)]
pub struct Unary {
    f: Arc<dyn UnaryFunction>,
    nu: usize,
}

impl Unary {
    /// `r(x, u) = f(x)` for controls of size `nu`.
    pub fn new(f: Arc<dyn UnaryFunction>, nu: usize) -> Self {
        Self { f, nu }
    }

    /// The wrapped function.
    pub fn inner(&self) -> &Arc<dyn UnaryFunction> {
        &self.f
    }
}

impl StageFunction for Unary {
    fn nx(&self) -> usize {
        self.f.nx()
    }
    fn ndx(&self) -> usize {
        self.f.ndx()
    }
    fn nu(&self) -> usize {
        self.nu
    }
    fn nr(&self) -> usize {
        self.f.nr()
    }
    fn create_workspace(&self) -> Workspace {
        self.f.create_workspace()
    }
    fn evaluate(&self, x: &[f64], _u: &[f64], data: &mut StageFunctionData) {
        self.f.evaluate(x, data);
    }
    fn jacobians(&self, x: &[f64], _u: &[f64], data: &mut StageFunctionData) {
        self.f.jacobian(x, data);
        crate::linalg::fill(data.ju.as_mut(), 0.0);
    }
    fn jacobians_are_constant(&self) -> bool {
        self.f.jacobian_is_constant()
    }
    fn has_vhp(&self) -> bool {
        self.f.has_vhp()
    }
    fn vhp(&self, x: &[f64], _u: &[f64], lambda: &[f64], data: &mut StageFunctionData) {
        self.f.vhp(x, lambda, data);
        crate::linalg::fill(data.vhp_xu.as_mut(), 0.0);
        crate::linalg::fill(data.vhp_uu.as_mut(), 0.0);
    }
}

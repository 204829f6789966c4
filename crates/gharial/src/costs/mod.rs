//! Costs `ℓ(x, u)` with gradient and Hessian, stage-wise and terminal (`nu = 0`).
//!
//! Derivatives with respect to the state are tangent (`ndx`), like every other model of
//! the library.

use faer::prelude::ReborrowMut;
use faer::{Col, Mat, MatMut};

use crate::functions::util::add_scaled;
use crate::functions::{Workspace, no_workspace};
use crate::linalg::{add_scaled_lower, as_mat, as_mat_mut};

mod quadratic;
mod residual;
mod stack;

pub use quadratic::{ConstantCost, QuadraticCost};
pub use residual::{LogBarrierCost, QuadraticControlCost, QuadraticResidualCost, QuadraticStateCost};
pub use stack::CostStack;

/// What a [`Cost`] writes: value, gradient and Hessian.
#[derive(Debug)]
pub struct CostData {
    /// `ℓ(x, u)`.
    pub value: f64,
    /// `dℓ/dx` (`ndx`).
    pub lx: Col<f64>,
    /// `dℓ/du` (`nu`).
    pub lu: Col<f64>,
    /// `d²ℓ/dx²` (`ndx x ndx`).
    pub lxx: Mat<f64>,
    /// `d²ℓ/dxdu` (`ndx x nu`).
    pub lxu: Mat<f64>,
    /// `d²ℓ/du²` (`nu x nu`).
    pub luu: Mat<f64>,
    /// The model's private scratch memory.
    pub ws: Workspace,
}

impl CostData {
    /// Zero-filled data for a cost of dimensions `(ndx, nu)`.
    pub fn new(ndx: usize, nu: usize, ws: Workspace) -> Self {
        Self {
            value: 0.0,
            lx: Col::zeros(ndx),
            lu: Col::zeros(nu),
            lxx: Mat::zeros(ndx, ndx),
            lxu: Mat::zeros(ndx, nu),
            luu: Mat::zeros(nu, nu),
            ws,
        }
    }

    /// The state gradient as a slice.
    pub fn lx(&self) -> &[f64] {
        crate::linalg::slice(&self.lx)
    }

    /// The control gradient as a slice.
    pub fn lu(&self) -> &[f64] {
        crate::linalg::slice(&self.lu)
    }

    /// The gradient, the Hessian blocks and the workspace, borrowed apart (for models
    /// that write their derivatives while using their workspace).
    pub fn parts(&mut self) -> CostParts<'_> {
        CostParts {
            lx: crate::linalg::slice_mut(&mut self.lx),
            lu: crate::linalg::slice_mut(&mut self.lu),
            hessian: HessianMut::of(&mut self.lxx, &mut self.lxu, &mut self.luu),
            ws: &mut self.ws,
        }
    }

    /// Downcasts the workspace to the model's own type.
    ///
    /// # Panics
    /// If the data was created by another model (a programming error).
    pub fn ws<T: 'static>(&mut self) -> &mut T {
        self.ws
            .downcast_mut::<T>()
            .expect("cost data used with a model that did not create it")
    }
}

/// The blocks and the workspace of a [`CostData`], borrowed apart ([`CostData::parts`]).
#[derive(Debug)]
pub struct CostParts<'a> {
    /// `dℓ/dx` (`ndx`).
    pub lx: &'a mut [f64],
    /// `dℓ/du` (`nu`).
    pub lu: &'a mut [f64],
    /// The whole Hessian blocks.
    pub hessian: HessianMut<'a>,
    /// The model's private scratch memory.
    pub ws: &'a mut Workspace,
}

/// The Hessian blocks that [`Cost::add_derivatives`] adds to: the lower triangles
/// (diagonal included) of `lxx` and `luu`, whose strict upper triangles are left as they
/// are, and all of `lxu`.
#[derive(Debug)]
pub struct HessianMut<'a> {
    /// `d²ℓ/dx²` (`ndx x ndx`), lower triangle.
    pub lxx: MatMut<'a, f64>,
    /// `d²ℓ/dxdu` (`ndx x nu`).
    pub lxu: MatMut<'a, f64>,
    /// `d²ℓ/du²` (`nu x nu`), lower triangle.
    pub luu: MatMut<'a, f64>,
}

impl<'a> HessianMut<'a> {
    /// The blocks `lxx`, `lxu`, `luu` of whole matrices.
    pub fn of(lxx: &'a mut Mat<f64>, lxu: &'a mut Mat<f64>, luu: &'a mut Mat<f64>) -> Self {
        Self {
            lxx: lxx.as_mut(),
            lxu: lxu.as_mut(),
            luu: luu.as_mut(),
        }
    }
}

impl HessianMut<'_> {
    /// A shorter-lived view of the same blocks.
    pub fn rb_mut(&mut self) -> HessianMut<'_> {
        HessianMut {
            lxx: self.lxx.rb_mut(),
            lxu: self.lxu.rb_mut(),
            luu: self.luu.rb_mut(),
        }
    }
}

/// Where [`Cost::add_derivatives`] adds its scaled derivatives (the sums of a
/// [`CostStack`]).
#[derive(Debug)]
pub struct DerivativesMut<'a> {
    /// `dℓ/dx` (`ndx`).
    pub lx: &'a mut [f64],
    /// `dℓ/du` (`nu`).
    pub lu: &'a mut [f64],
    /// The Hessian blocks, or `None` for the gradient only.
    pub hessian: Option<HessianMut<'a>>,
}

/// A twice-differentiable cost `ℓ(x, u)`.
pub trait Cost: Send + Sync {
    /// Representation size of the state.
    fn nx(&self) -> usize;
    /// Tangent size of the state.
    fn ndx(&self) -> usize;
    /// Control size (0 for terminal costs).
    fn nu(&self) -> usize;

    /// Creates the private scratch memory of this cost (default: none).
    fn create_workspace(&self) -> Workspace {
        no_workspace()
    }

    /// Creates the data this cost writes into.
    fn create_data(&self) -> CostData {
        CostData::new(self.ndx(), self.nu(), self.create_workspace())
    }

    /// Writes `ℓ(x, u)` into `data.value`.
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut CostData);

    /// Writes the gradient and Hessian into `data`. `evaluate` has been called at the
    /// same point before.
    fn derivatives(&self, x: &[f64], u: &[f64], data: &mut CostData);

    /// Whether the Hessian is the same at every point (default: false), so that callers
    /// may keep the one written by a first [`Cost::derivatives`] and call
    /// [`Cost::gradient`] afterwards. A cost whose Hessian depends on parameters that
    /// change in place may only say true if they change between solves, and not
    /// between the cycles of a receding horizon (a solve after a shift keeps the
    /// Hessians of the stages that moved, [`crate::problem::ProblemData::start_solve`]).
    fn hessian_is_constant(&self) -> bool {
        false
    }

    /// Writes the gradient into `data.lx`, `data.lu`; the Hessian blocks may be left as
    /// they are. `evaluate` has been called at the same point before, and
    /// [`Cost::derivatives`] on the same data at some point. Default: `derivatives`.
    fn gradient(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        self.derivatives(x, u, data);
    }

    /// The derivatives, knowing whether `data` already holds, from an earlier call on it,
    /// the blocks this cost declares constant (`reuse`): [`Cost::gradient`] for a
    /// constant Hessian then, [`Cost::derivatives`] otherwise. Compositions (a
    /// [`CostStack`]) pass `reuse` on to their components, whose Hessians may be
    /// constant when the composition's is not.
    fn derivatives_reusing(&self, x: &[f64], u: &[f64], data: &mut CostData, reuse: bool) {
        if reuse && self.hessian_is_constant() {
            self.gradient(x, u, data);
        } else {
            self.derivatives(x, u, data);
        }
    }

    /// Adds `scale` times the gradient, and the Hessian when `out.hessian` is given, to
    /// `out` (the lower triangles of the symmetric blocks only), with the blocks this cost
    /// declares constant reused as in [`Cost::derivatives_reusing`] (`reuse`: `data` was
    /// passed to an earlier call of this method). `data`'s own derivative blocks may be
    /// left as they are. Default: `derivatives_reusing` into
    /// `data`, then the scaled sums; costs built on a residual override it to add their
    /// chain-rule products straight into `out`.
    fn add_derivatives(
        &self,
        x: &[f64],
        u: &[f64],
        data: &mut CostData,
        reuse: bool,
        scale: f64,
        out: DerivativesMut<'_>,
    ) {
        self.derivatives_reusing(x, u, data, reuse);
        add_scaled(as_mat_mut(out.lx), scale, as_mat(data.lx()));
        add_scaled(as_mat_mut(out.lu), scale, as_mat(data.lu()));
        if let Some(h) = out.hessian {
            add_scaled_lower(h.lxx, scale, data.lxx.as_ref());
            add_scaled(h.lxu, scale, data.lxu.as_ref());
            add_scaled_lower(h.luu, scale, data.luu.as_ref());
        }
    }
}

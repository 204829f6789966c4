//! Automatic derivatives: write a model once, generic over a [`ManifoldScalar`] (`f64`,
//! dual and hyper-dual numbers), and get exact Jacobians (forward-mode dual numbers)
//! and exact Hessians (hyper-dual numbers). The model can use every operation of
//! [`Scalar`] (arithmetic, `sin`, `exp`, `sqrt`, ...) and the `⊕`, `⊖` of any space
//! (`D::integrate(space, x, v, out)`, `D::difference(space, x0, x1, out)`).
//!
//! Closures cannot be generic, so a model is a small type implementing one of
//! [`AutoStageFn`] (`r(x, u)`), [`AutoUnaryFn`] (`r(x)`), [`AutoCostFn`] (`ℓ(x, u)`),
//! [`AutoDynamicsFn`] (`y = φ(x, u)`, `y` on any manifold) or [`AutoOdeFn`]
//! (`ẋ = f(x, u)`). [`AutoDiff`] wraps it into the library's [`StageFunction`],
//! [`UnaryFunction`], [`Cost`], [`ExplicitDynamics`] or [`Ode`].
//!
//! ```
//! use std::sync::Arc;
//! use gharial::dynamics::Ode;
//! use gharial::autodiff::{AutoDiff, AutoOdeFn, ManifoldScalar};
//! use gharial::spaces::VectorSpace;
//!
//! /// A pendulum: x = (θ, θ̇), u = torque.
//! struct Pendulum {
//!     g_over_l: f64,
//! }
//!
//! impl AutoOdeFn for Pendulum {
//!     fn nx(&self) -> usize {
//!         2
//!     }
//!     fn nu(&self) -> usize {
//!         1
//!     }
//!     fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], xdot: &mut [D]) {
//!         xdot[0] = x[1];
//!         xdot[1] = -x[0].sin() * self.g_over_l + u[0];
//!     }
//! }
//!
//! let ode = AutoDiff::ode(Arc::new(VectorSpace::new(2)), Pendulum { g_over_l: 9.81 }).unwrap();
//! let mut data = ode.create_data();
//! ode.evaluate(&[0.3, 0.0], &[0.1], &mut data);
//! ode.jacobians(&[0.3, 0.0], &[0.1], &mut data);
//! assert!((data.jx[(1, 0)] + 9.81 * 0.3f64.cos()).abs() < 1e-14);
//! ```
//!
//! # What is computed
//!
//! States live on a manifold `M` (any [`Manifold`]); the model is written on the
//! representation `x ∈ R^nx`. Derivatives are taken in the tangent convention of the
//! library:
//! - Jacobians: column `j` of `dr/dx` is `d/dε r(x ⊕ ε e_j)`, obtained in one dual
//!   pass by seeding `x + ε T(x) e_j`, `T = tangent_map(x)` (exact at first order);
//!   `ndx + nu` passes in all.
//! - Values on a manifold `N` (explicit dynamics): the Jacobian of `φ(x ⊕ δ) ⊖ φ(x)`
//!   is `T⁻¹(φ(x)) dφ`, with `T⁻¹ = tangent_map_inverse`.
//! - Second order: `d²/dδ_i dδ_j g(x ⊕ δ_x, u + δ_u)` at `δ = 0`, one hyper-dual pass
//!   per pair `i ≤ j` (`n (n + 1) / 2` passes for `n = ndx + nu`), where `x ⊕ δ` runs
//!   through the manifold's own [`Manifold::integrate_hyper`]. The result is the
//!   symmetric Hessian of `δ ↦ g(x ⊕ δ)`, including the curvature of `⊕`. For
//!   vector-Hessian products `g = λᵀ r`; for dynamics on a manifold
//!   `g = λᵀ (φ(x ⊕ δ_x, u + δ_u) ⊖ φ(x, u))`; for costs `g = ℓ`.
//!
//! Every buffer lives in the workspace created by `create_data`: evaluations and
//! derivatives do not allocate. The same passes implement the dual-number derivative
//! checker ([`crate::check`]).

use std::sync::Arc;

use faer::reborrow::ReborrowMut;
use faer::{Mat, MatMut};

pub use crate::spaces::{ManifoldScalar, Scalar};
pub use num_dual::{Dual64, DualNum, HyperDual64};

use crate::costs::{Cost, CostData};
use crate::dynamics::{ExplicitDynamics, ExplicitDynamicsData, Ode, OdeData};
use crate::error::{Result, check_dim};
use crate::functions::{StageFunction, StageFunctionData, UnaryFunction, Workspace};
use crate::spaces::Manifold;

/// A vector function `r(x, u)` written once for every scalar type.
pub trait AutoStageFn: Send + Sync {
    /// Representation size of the state.
    fn nx(&self) -> usize;
    /// Control size.
    fn nu(&self) -> usize;
    /// Output size.
    fn nr(&self) -> usize;
    /// Writes `r(x, u)` into `out` (`nr`).
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], out: &mut [D]);
}

/// A vector function `r(x)` of the state only, written once for every scalar type.
pub trait AutoUnaryFn: Send + Sync {
    /// Representation size of the state.
    fn nx(&self) -> usize;
    /// Output size.
    fn nr(&self) -> usize;
    /// Writes `r(x)` into `out` (`nr`).
    fn eval<D: ManifoldScalar>(&self, x: &[D], out: &mut [D]);
}

/// A cost `ℓ(x, u)` written once for every scalar type (`nu = 0` for terminal costs).
pub trait AutoCostFn: Send + Sync {
    /// Representation size of the state.
    fn nx(&self) -> usize;
    /// Control size.
    fn nu(&self) -> usize;
    /// `ℓ(x, u)`.
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D]) -> D;
}

/// Discrete dynamics `y = φ(x, u)` written once for every scalar type; `y` is the
/// representation of a point of the next state space.
pub trait AutoDynamicsFn: Send + Sync {
    /// Representation size of the state.
    fn nx(&self) -> usize;
    /// Control size.
    fn nu(&self) -> usize;
    /// Representation size of the next state (default: `nx`).
    fn nx_next(&self) -> usize {
        self.nx()
    }
    /// Writes `φ(x, u)` into `y` (`nx_next`).
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], y: &mut [D]);
}

/// Continuous dynamics `ẋ = f(x, u)` written once for every scalar type; `ẋ` is a
/// tangent vector at `x` (`ndx` components).
pub trait AutoOdeFn: Send + Sync {
    /// Representation size of the state.
    fn nx(&self) -> usize;
    /// Control size.
    fn nu(&self) -> usize;
    /// Writes `f(x, u)` into `xdot` (`ndx`).
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], xdot: &mut [D]);
}

// ---------------------------------------------------------------------------------
// The dual-number passes, shared by the adapters and the derivative checker.

/// Where the values of a function live.
#[derive(Clone, Copy)]
pub(crate) enum Output<'a> {
    /// `R^n`.
    Vector(usize),
    /// A manifold, with the value `y` at the unperturbed point.
    Manifold(&'a dyn Manifold, &'a [f64]),
}

/// Scratch memory of the dual passes, allocated once.
#[derive(Debug)]
pub(crate) struct DualScratch {
    /// `tangent_map(x)` (`nx x ndx`).
    tm: Mat<f64>,
    /// `tangent_map_inverse(y)` of a manifold-valued output (`ndy x ny`).
    tmi: Mat<f64>,
    xd: Vec<Dual64>,
    ud: Vec<Dual64>,
    yd: Vec<Dual64>,
    vh: Vec<HyperDual64>,
    x0h: Vec<HyperDual64>,
    xh: Vec<HyperDual64>,
    uh: Vec<HyperDual64>,
    yh: Vec<HyperDual64>,
    y0h: Vec<HyperDual64>,
    dh: Vec<HyperDual64>,
}

fn hd(re: f64) -> HyperDual64 {
    HyperDual64::new(re, 0.0, 0.0, 0.0)
}

impl DualScratch {
    /// Buffers for a function of `x ∈ space`, `u ∈ R^nu` with values in `R^ny`
    /// (`out_space = None`) or in `out_space` (`ny = out_space.nx()`).
    pub(crate) fn new(space: &dyn Manifold, nu: usize, ny: usize, out_space: Option<&dyn Manifold>) -> Self {
        let (nx, ndx) = (space.nx(), space.ndx());
        let (ny, ndy) = match out_space {
            Some(m) => (m.nx(), m.ndx()),
            None => (ny, ny),
        };
        Self {
            tm: Mat::zeros(nx, ndx),
            tmi: Mat::zeros(ndy, ny),
            xd: vec![Dual64::new(0.0, 0.0); nx],
            ud: vec![Dual64::new(0.0, 0.0); nu],
            yd: vec![Dual64::new(0.0, 0.0); ny],
            vh: vec![hd(0.0); ndx],
            x0h: vec![hd(0.0); nx],
            xh: vec![hd(0.0); nx],
            uh: vec![hd(0.0); nu],
            yh: vec![hd(0.0); ny],
            y0h: vec![hd(0.0); ny],
            dh: vec![hd(0.0); ndy],
        }
    }
}

/// Writes the tangent derivative `T⁻¹ dy` (or `dy` on a vector space) of a dual output
/// into column `col` of `jac`.
fn write_column(out: Output<'_>, tmi: &Mat<f64>, yd: &[Dual64], mut jac: MatMut<'_, f64>, col: usize) {
    match out {
        Output::Manifold(m, _) if !m.is_vector_space() => {
            for i in 0..jac.nrows() {
                let mut s = 0.0;
                for (k, y) in yd.iter().enumerate() {
                    s += tmi[(i, k)] * y.eps;
                }
                jac[(i, col)] = s;
            }
        }
        _ => {
            for (i, y) in yd.iter().enumerate() {
                jac[(i, col)] = y.eps;
            }
        }
    }
}

/// Jacobians of `g(x, u)` with respect to tangent perturbations of `x` and plain
/// perturbations of `u`, one forward dual pass per direction.
pub(crate) fn jacobians_dual(
    space: &dyn Manifold,
    out: Output<'_>,
    x: &[f64],
    u: &[f64],
    s: &mut DualScratch,
    mut jx: MatMut<'_, f64>,
    mut ju: MatMut<'_, f64>,
    mut g: impl FnMut(&[Dual64], &[Dual64], &mut [Dual64]),
) {
    let vector = space.is_vector_space();
    if !vector {
        space.tangent_map(x, s.tm.as_mut());
    }
    if let Output::Manifold(m, y) = out
        && !m.is_vector_space()
    {
        m.tangent_map_inverse(y, s.tmi.as_mut());
    }
    for (d, &v) in s.ud.iter_mut().zip(u) {
        *d = Dual64::new(v, 0.0);
    }
    for (d, &v) in s.xd.iter_mut().zip(x) {
        *d = Dual64::new(v, 0.0);
    }
    for j in 0..space.ndx() {
        for (k, d) in s.xd.iter_mut().enumerate() {
            d.eps = if vector {
                if k == j { 1.0 } else { 0.0 }
            } else {
                s.tm[(k, j)]
            };
        }
        g(&s.xd, &s.ud, &mut s.yd);
        write_column(out, &s.tmi, &s.yd, jx.rb_mut(), j);
    }
    for d in s.xd.iter_mut() {
        d.eps = 0.0;
    }
    for j in 0..u.len() {
        s.ud[j].eps = 1.0;
        g(&s.xd, &s.ud, &mut s.yd);
        s.ud[j].eps = 0.0;
        write_column(out, &s.tmi, &s.yd, ju.rb_mut(), j);
    }
}

/// The second-order blocks written by [`hessian_hyper`].
pub(crate) struct Hessian<'a> {
    pub xx: MatMut<'a, f64>,
    pub xu: MatMut<'a, f64>,
    pub uu: MatMut<'a, f64>,
    /// Gradient blocks `(g_x, g_u)` of the weighted output, if wanted.
    pub grad: Option<(&'a mut [f64], &'a mut [f64])>,
}

/// Symmetric Hessian of `δ ↦ wᵀ (g(x ⊕ δ_x, u + δ_u) [⊖ y])`, one hyper-dual pass per
/// pair of directions.
pub(crate) fn hessian_hyper(
    space: &dyn Manifold,
    out: Output<'_>,
    x: &[f64],
    u: &[f64],
    w: &[f64],
    s: &mut DualScratch,
    mut h: Hessian<'_>,
    mut g: impl FnMut(&[HyperDual64], &[HyperDual64], &mut [HyperDual64]),
) {
    let (ndx, nu) = (space.ndx(), u.len());
    let n = ndx + nu;
    let manifold_out = load_point(space, out, x, u, s);
    for i in 0..n {
        for j in i..n {
            let perturb_x = seed_pair(space, x, s, i, j);
            let xin = if perturb_x { &s.xh } else { &s.x0h };
            g(xin, &s.uh, &mut s.yh);
            if !perturb_x {
                s.uh[i - ndx].eps1 = 0.0;
            }
            if j >= ndx {
                s.uh[j - ndx].eps2 = 0.0;
            }
            let vals: &[HyperDual64] = match manifold_out {
                Some(m) => {
                    m.difference_hyper(&s.y0h, &s.yh, &mut s.dh);
                    &s.dh
                }
                None => &s.yh,
            };
            let (mut second, mut first) = (0.0, 0.0);
            for (wk, v) in w.iter().zip(vals) {
                second += wk * v.eps1eps2;
                first += wk * v.eps1;
            }
            h.store(ndx, i, j, first, second);
        }
    }
}

/// Loads the point `(x, u)` (and the output's base point `y` on a curved output
/// manifold, which is returned) into the hyper-dual scratch, with the tangent map at
/// `x` on a curved state space.
fn load_point<'m>(
    space: &dyn Manifold,
    out: Output<'m>,
    x: &[f64],
    u: &[f64],
    s: &mut DualScratch,
) -> Option<&'m dyn Manifold> {
    let manifold_out = match out {
        Output::Manifold(m, y) if !m.is_vector_space() => {
            for (d, &v) in s.y0h.iter_mut().zip(y) {
                *d = hd(v);
            }
            Some(m)
        }
        _ => None,
    };
    for (d, &v) in s.x0h.iter_mut().zip(x) {
        *d = hd(v);
    }
    for (d, &v) in s.uh.iter_mut().zip(u) {
        *d = hd(v);
    }
    if !space.is_vector_space() {
        space.tangent_map(x, s.tm.as_mut());
    }
    manifold_out
}

/// Seeds the directions `i ≤ j` of `(δ_x, δ_u)` (ε1 along `i`, ε2 along `j`) into
/// `s.xh` (a state direction: returns `true`) or `s.uh`.
fn seed_pair(space: &dyn Manifold, x: &[f64], s: &mut DualScratch, i: usize, j: usize) -> bool {
    let ndx = space.ndx();
    let vector = space.is_vector_space();
    // Seed of x along tangent direction i: column i of the tangent map.
    let seed = |tm: &Mat<f64>, k: usize, i: usize| {
        if vector {
            if k == i { 1.0 } else { 0.0 }
        } else {
            tm[(k, i)]
        }
    };
    let perturb_x = i < ndx;
    if perturb_x && j < ndx && !vector {
        // Both directions on a curved x: the ε1ε2 term of x ⊕ δ is needed.
        for v in s.vh.iter_mut() {
            *v = hd(0.0);
        }
        s.vh[i].eps1 = 1.0;
        s.vh[j].eps2 = 1.0;
        space.integrate_hyper(&s.x0h, &s.vh, &mut s.xh);
    } else if perturb_x {
        // A vector space, or one direction on u: x depends linearly on ε1 and ε2 up to
        // ε1², ε2² (which vanish), so seeding with the tangent map is exact.
        for (k, xk) in s.xh.iter_mut().enumerate() {
            let e2 = if j < ndx { seed(&s.tm, k, j) } else { 0.0 };
            *xk = HyperDual64::new(x[k], seed(&s.tm, k, i), e2, 0.0);
        }
    } else {
        s.uh[i - ndx].eps1 = 1.0;
    }
    if j >= ndx {
        s.uh[j - ndx].eps2 = 1.0;
    }
    perturb_x
}

impl Hessian<'_> {
    /// Stores the second derivative along the directions `i ≤ j` (both symmetric
    /// entries) and, when `i = j`, the first derivative along `i` into the gradient.
    fn store(&mut self, ndx: usize, i: usize, j: usize, first: f64, second: f64) {
        if i == j
            && let Some((gx, gu)) = self.grad.as_mut()
        {
            if i < ndx {
                gx[i] = first;
            } else {
                gu[i - ndx] = first;
            }
        }
        match (i < ndx, j < ndx) {
            (true, true) => {
                self.xx[(i, j)] = second;
                self.xx[(j, i)] = second;
            }
            (true, false) => self.xu[(i, j - ndx)] = second,
            _ => {
                self.uu[(i - ndx, j - ndx)] = second;
                self.uu[(j - ndx, i - ndx)] = second;
            }
        }
    }
}

// ---------------------------------------------------------------------------------
// The adapter.

/// Turns a model written once for every [`ManifoldScalar`] into a library model with exact
/// derivatives: a [`StageFunction`] (from [`AutoStageFn`]), [`UnaryFunction`]
/// ([`AutoUnaryFn`]), [`Cost`] ([`AutoCostFn`]), [`ExplicitDynamics`]
/// ([`AutoDynamicsFn`]) or [`Ode`] ([`AutoOdeFn`]).
///
/// Second-order terms (vector-Hessian products) are exact by default; call
/// [`AutoDiff::gauss_newton`] to drop them (faster; exact for linear models).
pub struct AutoDiff<F> {
    f: F,
    space: Arc<dyn Manifold>,
    space_next: Arc<dyn Manifold>,
    second_order: bool,
}

impl<F> std::fmt::Debug for AutoDiff<F> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AutoDiff")
            .field("space", &self.space)
            .field("space_next", &self.space_next)
            .field("second_order", &self.second_order)
            .finish()
    }
}

impl<F> AutoDiff<F> {
    fn with(space: Arc<dyn Manifold>, space_next: Arc<dyn Manifold>, f: F) -> Self {
        Self {
            f,
            space,
            space_next,
            second_order: true,
        }
    }

    /// The wrapped model.
    pub fn inner(&self) -> &F {
        &self.f
    }

    /// Drops the second-order terms of stage functions and dynamics (`has_vhp()`
    /// becomes `false`): the solvers then use the Gauss-Newton approximation. Costs
    /// keep their exact Hessian.
    pub fn gauss_newton(mut self) -> Self {
        self.second_order = false;
        self
    }

    fn scratch(ws: &mut Workspace) -> &mut DualScratch {
        ws.downcast_mut::<DualScratch>()
            .expect("data used with an AutoDiff model that did not create it")
    }

    /// The dual-pass scratch of a model with `nu` controls and `ny` values (in
    /// `out_space` if given), the workspace of every kind.
    fn dual_workspace(&self, nu: usize, ny: usize, out_space: Option<&dyn Manifold>) -> Workspace {
        Box::new(DualScratch::new(self.space.as_ref(), nu, ny, out_space))
    }

    /// First derivatives of `g` at `(x, u)` into `jx`, `ju` (one dual pass per direction),
    /// the `jacobians` of every kind.
    fn dual_jacobians(
        &self,
        ws: &mut Workspace,
        out: Output<'_>,
        x: &[f64],
        u: &[f64],
        jx: MatMut<'_, f64>,
        ju: MatMut<'_, f64>,
        g: impl FnMut(&[Dual64], &[Dual64], &mut [Dual64]),
    ) {
        jacobians_dual(self.space.as_ref(), out, x, u, Self::scratch(ws), jx, ju, g);
    }

    /// Second derivatives of `wᵀ g` at `(x, u)` into `h` (one hyper-dual pass per pair of
    /// directions), or zero blocks under [`AutoDiff::gauss_newton`] unless `exact`: the
    /// `vhp` of every kind and the cost Hessian (`exact`).
    fn hyper_hessian(
        &self,
        ws: &mut Workspace,
        out: Output<'_>,
        x: &[f64],
        u: &[f64],
        w: &[f64],
        exact: bool,
        mut h: Hessian<'_>,
        g: impl FnMut(&[HyperDual64], &[HyperDual64], &mut [HyperDual64]),
    ) {
        if !(exact || self.second_order) {
            h.xx.fill(0.0);
            h.xu.fill(0.0);
            h.uu.fill(0.0);
            return;
        }
        hessian_hyper(self.space.as_ref(), out, x, u, w, Self::scratch(ws), h, g);
    }
}

impl<'a> Hessian<'a> {
    /// The blocks `xx`, `xu`, `uu` (no gradient).
    fn blocks(xx: MatMut<'a, f64>, xu: MatMut<'a, f64>, uu: MatMut<'a, f64>) -> Self {
        Self { xx, xu, uu, grad: None }
    }
}

impl<F: AutoStageFn> AutoDiff<F> {
    /// A stage function `r(x, u)` with `x` on `space`.
    ///
    /// # Errors
    /// If `f.nx()` differs from `space.nx()`.
    pub fn stage(space: Arc<dyn Manifold>, f: F) -> Result<Self> {
        check_dim("AutoDiff stage function: state representation size", space.nx(), f.nx())?;
        Ok(Self::with(space.clone(), space, f))
    }
}

impl<F: AutoUnaryFn> AutoDiff<F> {
    /// A unary function `r(x)` with `x` on `space`.
    ///
    /// # Errors
    /// If `f.nx()` differs from `space.nx()`.
    pub fn unary(space: Arc<dyn Manifold>, f: F) -> Result<Self> {
        check_dim("AutoDiff unary function: state representation size", space.nx(), f.nx())?;
        Ok(Self::with(space.clone(), space, f))
    }
}

impl<F: AutoCostFn> AutoDiff<F> {
    /// A cost `ℓ(x, u)` with `x` on `space`.
    ///
    /// # Errors
    /// If `f.nx()` differs from `space.nx()`.
    pub fn cost(space: Arc<dyn Manifold>, f: F) -> Result<Self> {
        check_dim("AutoDiff cost: state representation size", space.nx(), f.nx())?;
        Ok(Self::with(space.clone(), space, f))
    }
}

impl<F: AutoDynamicsFn> AutoDiff<F> {
    /// Explicit dynamics `y = φ(x, u)` from `space` to `space_next`.
    ///
    /// # Errors
    /// If `f.nx()` or `f.nx_next()` differ from the spaces' representation sizes.
    pub fn explicit_dynamics(space: Arc<dyn Manifold>, space_next: Arc<dyn Manifold>, f: F) -> Result<Self> {
        check_dim("AutoDiff dynamics: state representation size", space.nx(), f.nx())?;
        check_dim(
            "AutoDiff dynamics: next state representation size",
            space_next.nx(),
            f.nx_next(),
        )?;
        Ok(Self::with(space, space_next, f))
    }
}

impl<F: AutoOdeFn> AutoDiff<F> {
    /// An ODE `ẋ = f(x, u)` with `x` on `space`.
    ///
    /// # Errors
    /// If `f.nx()` differs from `space.nx()`.
    pub fn ode(space: Arc<dyn Manifold>, f: F) -> Result<Self> {
        check_dim("AutoDiff ODE: state representation size", space.nx(), f.nx())?;
        Ok(Self::with(space.clone(), space, f))
    }
}

impl<F: AutoStageFn> StageFunction for AutoDiff<F> {
    fn nx(&self) -> usize {
        self.space.nx()
    }
    fn ndx(&self) -> usize {
        self.space.ndx()
    }
    fn nu(&self) -> usize {
        self.f.nu()
    }
    fn nr(&self) -> usize {
        self.f.nr()
    }

    fn create_workspace(&self) -> Workspace {
        self.dual_workspace(self.f.nu(), self.f.nr(), None)
    }

    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        self.f.eval(x, u, data.value_mut());
    }

    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let (jx, ju) = (data.jx.as_mut(), data.ju.as_mut());
        let out = Output::Vector(self.f.nr());
        self.dual_jacobians(&mut data.ws, out, x, u, jx, ju, |x, u, r| self.f.eval(x, u, r));
    }

    fn has_vhp(&self) -> bool {
        self.second_order
    }

    fn vhp(&self, x: &[f64], u: &[f64], lambda: &[f64], data: &mut StageFunctionData) {
        let h = Hessian::blocks(data.vhp_xx.as_mut(), data.vhp_xu.as_mut(), data.vhp_uu.as_mut());
        let out = Output::Vector(self.f.nr());
        self.hyper_hessian(&mut data.ws, out, x, u, lambda, false, h, |x, u, r| {
            self.f.eval(x, u, r)
        });
    }
}

impl<F: AutoUnaryFn> UnaryFunction for AutoDiff<F> {
    fn nx(&self) -> usize {
        self.space.nx()
    }
    fn ndx(&self) -> usize {
        self.space.ndx()
    }
    fn nr(&self) -> usize {
        self.f.nr()
    }

    fn create_workspace(&self) -> Workspace {
        self.dual_workspace(0, self.f.nr(), None)
    }

    fn evaluate(&self, x: &[f64], data: &mut StageFunctionData) {
        self.f.eval(x, data.value_mut());
    }

    fn jacobian(&self, x: &[f64], data: &mut StageFunctionData) {
        let (jx, ju) = (data.jx.as_mut(), data.ju.as_mut().subcols_mut(0, 0));
        let out = Output::Vector(self.f.nr());
        self.dual_jacobians(&mut data.ws, out, x, &[], jx, ju, |x, _, r| self.f.eval(x, r));
    }

    fn has_vhp(&self) -> bool {
        self.second_order
    }

    fn vhp(&self, x: &[f64], lambda: &[f64], data: &mut StageFunctionData) {
        let h = Hessian::blocks(
            data.vhp_xx.as_mut(),
            data.vhp_xu.as_mut().subcols_mut(0, 0),
            data.vhp_uu.as_mut().submatrix_mut(0, 0, 0, 0),
        );
        let out = Output::Vector(self.f.nr());
        self.hyper_hessian(&mut data.ws, out, x, &[], lambda, false, h, |x, _, r| self.f.eval(x, r));
    }
}

impl<F: AutoCostFn> Cost for AutoDiff<F> {
    fn nx(&self) -> usize {
        self.space.nx()
    }
    fn ndx(&self) -> usize {
        self.space.ndx()
    }
    fn nu(&self) -> usize {
        self.f.nu()
    }

    fn create_workspace(&self) -> Workspace {
        self.dual_workspace(self.f.nu(), 1, None)
    }

    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        data.value = self.f.eval(x, u);
    }

    fn derivatives(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        let h = Hessian {
            xx: data.lxx.as_mut(),
            xu: data.lxu.as_mut(),
            uu: data.luu.as_mut(),
            grad: Some((
                crate::linalg::slice_mut(&mut data.lx),
                crate::linalg::slice_mut(&mut data.lu),
            )),
        };
        self.hyper_hessian(&mut data.ws, Output::Vector(1), x, u, &[1.0], true, h, |x, u, r| {
            r[0] = self.f.eval(x, u)
        });
    }
}

impl<F: AutoDynamicsFn> ExplicitDynamics for AutoDiff<F> {
    fn space(&self) -> &Arc<dyn Manifold> {
        &self.space
    }
    fn space_next(&self) -> &Arc<dyn Manifold> {
        &self.space_next
    }
    fn nu(&self) -> usize {
        self.f.nu()
    }

    fn create_workspace(&self) -> Workspace {
        let sn = self.space_next.as_ref();
        self.dual_workspace(self.f.nu(), sn.nx(), Some(sn))
    }

    fn forward(&self, x: &[f64], u: &[f64], data: &mut ExplicitDynamicsData) {
        self.f.eval(x, u, data.xnext_mut());
    }

    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut ExplicitDynamicsData) {
        let (jx, ju) = (data.jx.as_mut(), data.ju.as_mut());
        let out = Output::Manifold(self.space_next.as_ref(), crate::linalg::slice(&data.xnext));
        self.dual_jacobians(&mut data.ws, out, x, u, jx, ju, |x, u, y| self.f.eval(x, u, y));
    }

    fn has_vhp(&self) -> bool {
        self.second_order
    }

    fn vhp(&self, x: &[f64], u: &[f64], lambda: &[f64], data: &mut ExplicitDynamicsData) {
        let out = Output::Manifold(self.space_next.as_ref(), crate::linalg::slice(&data.xnext));
        let h = Hessian::blocks(data.vhp_xx.as_mut(), data.vhp_xu.as_mut(), data.vhp_uu.as_mut());
        self.hyper_hessian(&mut data.ws, out, x, u, lambda, false, h, |x, u, y| {
            self.f.eval(x, u, y)
        });
    }
}

impl<F: AutoOdeFn> Ode for AutoDiff<F> {
    fn space(&self) -> &Arc<dyn Manifold> {
        &self.space
    }
    fn nu(&self) -> usize {
        self.f.nu()
    }

    fn create_workspace(&self) -> Workspace {
        self.dual_workspace(self.f.nu(), self.space.ndx(), None)
    }

    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        self.f.eval(x, u, data.xdot_mut());
    }

    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        let (jx, ju) = (data.jx.as_mut(), data.ju.as_mut());
        let out = Output::Vector(self.space.ndx());
        self.dual_jacobians(&mut data.ws, out, x, u, jx, ju, |x, u, v| self.f.eval(x, u, v));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{
        CheckOptions, DualCheckOptions, check_cost, check_cost_dual, check_explicit_dynamics,
        check_explicit_dynamics_dual, check_explicit_dynamics_vhp_dual, check_ode, check_ode_dual,
        check_stage_function, check_stage_function_dual, check_stage_function_vhp_dual, rel_error,
    };
    use crate::functions::Unary;
    use crate::spaces::lie;
    use crate::spaces::{Arg, SE2, SE3, SO3, TangentBundle, VectorSpace};
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    fn vs(n: usize) -> Arc<dyn Manifold> {
        Arc::new(VectorSpace::new(n))
    }

    fn rand_vec(rng: &mut SmallRng, n: usize) -> Vec<f64> {
        (0..n).map(|_| rng.random_range(-1.0..=1.0)).collect()
    }

    /// Damped pendulum `θ̈ = -g/l sin θ - b θ̇ + u / (m l²)`.
    struct Pendulum {
        g_l: f64,
        b: f64,
        inv_ml2: f64,
    }

    impl AutoOdeFn for Pendulum {
        fn nx(&self) -> usize {
            2
        }
        fn nu(&self) -> usize {
            1
        }
        fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], xdot: &mut [D]) {
            xdot[0] = x[1];
            xdot[1] = -x[0].sin() * self.g_l - x[1] * self.b + u[0] * self.inv_ml2;
        }
    }

    #[test]
    fn pendulum_ode_matches_hand_jacobians() {
        let p = Pendulum {
            g_l: 9.81 / 0.7,
            b: 0.3,
            inv_ml2: 1.0 / (1.3 * 0.49),
        };
        let (g_l, b, k) = (p.g_l, p.b, p.inv_ml2);
        let ode = AutoDiff::ode(vs(2), p).unwrap();
        let mut data = ode.create_data();
        let mut rng = SmallRng::seed_from_u64(1);
        for _ in 0..20 {
            let x = [rng.random_range(-3.0..3.0), rng.random_range(-5.0..5.0)];
            let u = [rng.random_range(-2.0..2.0)];
            ode.evaluate(&x, &u, &mut data);
            ode.jacobians(&x, &u, &mut data);
            let jx = Mat::from_fn(2, 2, |i, j| [[0.0, 1.0], [-g_l * x[0].cos(), -b]][i][j]);
            let ju = Mat::from_fn(2, 1, |i, _| [0.0, k][i]);
            assert!(rel_error(&data.jx, &jx) < 1e-15);
            assert!(rel_error(&data.ju, &ju) < 1e-15);
            assert!((data.xdot()[1] - (-g_l * x[0].sin() - b * x[1] + k * u[0])).abs() < 1e-14);
            check_ode(&ode, &x, &u, CheckOptions::default()).assert_ok();
            let reference = |x: &[Dual64], u: &[Dual64], out: &mut [Dual64]| ode.inner().eval(x, u, out);
            check_ode_dual(&ode, &x, &u, reference, DualCheckOptions::default()).assert_ok();
        }
    }

    /// `ℓ = ½ xᵀ Q x + xᵀ S u + ½ uᵀ R u + qᵀ x + rᵀ u`.
    struct Quadratic {
        q_mat: Mat<f64>,
        s_mat: Mat<f64>,
        r_mat: Mat<f64>,
        q: Vec<f64>,
        r: Vec<f64>,
    }

    impl AutoCostFn for Quadratic {
        fn nx(&self) -> usize {
            self.q.len()
        }
        fn nu(&self) -> usize {
            self.r.len()
        }
        fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D]) -> D {
            let (n, m) = (x.len(), u.len());
            let mut l = D::from(0.0);
            for i in 0..n {
                l += x[i] * self.q[i];
                for j in 0..n {
                    l += x[i] * x[j] * (0.5 * self.q_mat[(i, j)]);
                }
                for j in 0..m {
                    l += x[i] * u[j] * self.s_mat[(i, j)];
                }
            }
            for i in 0..m {
                l += u[i] * self.r[i];
                for j in 0..m {
                    l += u[i] * u[j] * (0.5 * self.r_mat[(i, j)]);
                }
            }
            l
        }
    }

    #[test]
    fn quadratic_cost_has_exact_gradient_and_hessian() {
        let mut rng = SmallRng::seed_from_u64(2);
        let (n, m) = (4, 3);
        let sym = |rng: &mut SmallRng, k: usize| {
            let a = Mat::from_fn(k, k, |_, _| rng.random_range(-1.0..1.0));
            Mat::from_fn(k, k, |i, j| a[(i, j)] + a[(j, i)])
        };
        let f = Quadratic {
            q_mat: sym(&mut rng, n),
            s_mat: Mat::from_fn(n, m, |_, _| rng.random_range(-1.0..1.0)),
            r_mat: sym(&mut rng, m),
            q: rand_vec(&mut rng, n),
            r: rand_vec(&mut rng, m),
        };
        let (qm, sm, rm, q, r) = (
            f.q_mat.clone(),
            f.s_mat.clone(),
            f.r_mat.clone(),
            f.q.clone(),
            f.r.clone(),
        );
        let cost = AutoDiff::cost(vs(n), f).unwrap();
        let mut data = cost.create_data();
        for _ in 0..10 {
            let (x, u) = (rand_vec(&mut rng, n), rand_vec(&mut rng, m));
            cost.evaluate(&x, &u, &mut data);
            cost.derivatives(&x, &u, &mut data);
            let lx = Mat::from_fn(n, 1, |i, _| {
                q[i] + (0..n).map(|j| qm[(i, j)] * x[j]).sum::<f64>() + (0..m).map(|j| sm[(i, j)] * u[j]).sum::<f64>()
            });
            let lu = Mat::from_fn(m, 1, |i, _| {
                r[i] + (0..m).map(|j| rm[(i, j)] * u[j]).sum::<f64>() + (0..n).map(|j| sm[(j, i)] * x[j]).sum::<f64>()
            });
            assert!(rel_error(&data.lx.as_mat().to_owned(), &lx) < 1e-14);
            assert!(rel_error(&data.lu.as_mat().to_owned(), &lu) < 1e-14);
            assert!(rel_error(&data.lxx, &qm) < 1e-15);
            assert!(rel_error(&data.lxu, &sm) < 1e-15);
            assert!(rel_error(&data.luu, &rm) < 1e-15);
            check_cost(&cost, &VectorSpace::new(n), &x, &u, CheckOptions::default()).assert_ok();
        }
    }

    /// `r(x, u) = (x0 x1 + sin u0, exp(x2) u1, x0² u0 u1)`.
    struct Residual;

    impl AutoStageFn for Residual {
        fn nx(&self) -> usize {
            3
        }
        fn nu(&self) -> usize {
            2
        }
        fn nr(&self) -> usize {
            3
        }
        fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], out: &mut [D]) {
            out[0] = x[0] * x[1] + u[0].sin();
            out[1] = x[2].exp() * u[1];
            out[2] = x[0] * x[0] * u[0] * u[1];
        }
    }

    #[test]
    fn nonlinear_residual_matches_hand_derivatives() {
        let f = AutoDiff::stage(vs(3), Residual).unwrap();
        let mut data = f.create_data();
        let mut rng = SmallRng::seed_from_u64(3);
        for _ in 0..10 {
            let (x, u, lam) = (rand_vec(&mut rng, 3), rand_vec(&mut rng, 2), rand_vec(&mut rng, 3));
            f.evaluate(&x, &u, &mut data);
            f.jacobians(&x, &u, &mut data);
            f.vhp(&x, &u, &lam, &mut data);
            let e2 = x[2].exp();
            let jx = [
                [x[1], x[0], 0.0],
                [0.0, 0.0, e2 * u[1]],
                [2.0 * x[0] * u[0] * u[1], 0.0, 0.0],
            ];
            let ju = [[u[0].cos(), 0.0], [0.0, e2], [x[0] * x[0] * u[1], x[0] * x[0] * u[0]]];
            let hxx = [
                [lam[2] * 2.0 * u[0] * u[1], lam[0], 0.0],
                [lam[0], 0.0, 0.0],
                [0.0, 0.0, lam[1] * e2 * u[1]],
            ];
            let hxu = [
                [lam[2] * 2.0 * x[0] * u[1], lam[2] * 2.0 * x[0] * u[0]],
                [0.0, 0.0],
                [0.0, lam[1] * e2],
            ];
            let huu = [
                [-lam[0] * u[0].sin(), lam[2] * x[0] * x[0]],
                [lam[2] * x[0] * x[0], 0.0],
            ];
            let m = |a: &[[f64; 3]; 3]| Mat::from_fn(3, 3, |i, j| a[i][j]);
            assert!(rel_error(&data.jx, &m(&jx)) < 1e-15);
            assert!(rel_error(&data.ju, &Mat::from_fn(3, 2, |i, j| ju[i][j])) < 1e-15);
            assert!(rel_error(&data.vhp_xx, &m(&hxx)) < 1e-15);
            assert!(rel_error(&data.vhp_xu, &Mat::from_fn(3, 2, |i, j| hxu[i][j])) < 1e-15);
            assert!(rel_error(&data.vhp_uu, &Mat::from_fn(2, 2, |i, j| huu[i][j])) < 1e-15);
            check_stage_function(&f, &VectorSpace::new(3), &x, &u, Some(&lam), CheckOptions::default()).assert_ok();
        }
        let gn = AutoDiff::stage(vs(3), Residual).unwrap().gauss_newton();
        assert!(!gn.has_vhp());
        let mut data = gn.create_data();
        gn.vhp(&[1.0, 2.0, 3.0], &[0.5, 0.5], &[1.0, 1.0, 1.0], &mut data);
        assert_eq!(crate::linalg::norm_max(data.vhp_xx.as_ref()), 0.0);
    }

    /// `ℓ(q) = aᵀ R(q) b` on SO(3), written on the quaternion. With `c = R(q)ᵀ a`, the
    /// tangent gradient is `b × c` and the Hessian of `δ ↦ ℓ(q ⊕ δ)` is
    /// `sym(c bᵀ) - (cᵀ b) I` (from `exp(δ) ≈ I + [δ]× + ½ [δ]×²`).
    struct Bilinear {
        a: [f64; 3],
        b: [f64; 3],
    }

    impl AutoCostFn for Bilinear {
        fn nx(&self) -> usize {
            4
        }
        fn nu(&self) -> usize {
            0
        }
        fn eval<D: ManifoldScalar>(&self, x: &[D], _u: &[D]) -> D {
            let q = [x[0], x[1], x[2], x[3]];
            let rb = lie::qrot(&q, &self.b.map(D::from));
            rb[0] * self.a[0] + rb[1] * self.a[1] + rb[2] * self.a[2]
        }
    }

    #[test]
    fn cost_on_so3_has_the_manifold_hessian() {
        let mut rng = SmallRng::seed_from_u64(4);
        let space: Arc<dyn Manifold> = Arc::new(SO3);
        for _ in 0..20 {
            let (a, b) = ([0.3, -1.0, 0.7], [1.1, 0.2, -0.5]);
            let cost = AutoDiff::cost(space.clone(), Bilinear { a, b }).unwrap();
            let mut q = [0.0; 4];
            space.random(&mut rng, &mut q);
            let mut data = cost.create_data();
            cost.evaluate(&q, &[], &mut data);
            cost.derivatives(&q, &[], &mut data);
            let r = lie::quat_to_rot(&q);
            let c: [f64; 3] = std::array::from_fn(|i| (0..3).map(|k| r[k][i] * a[k]).sum());
            let g = lie::cross(&b, &c);
            let cb = lie::dot3(&c, &b);
            let h = Mat::from_fn(3, 3, |i, j| {
                0.5 * (c[i] * b[j] + c[j] * b[i]) - if i == j { cb } else { 0.0 }
            });
            assert!((data.value - lie::dot3(&a, &lie::qrot(&q, &b))).abs() < 1e-15);
            assert!(rel_error(&data.lx.as_mat().to_owned(), &Mat::from_fn(3, 1, |i, _| g[i])) < 1e-14);
            assert!(rel_error(&data.lxx, &h) < 1e-14, "{:?} vs {h:?}", data.lxx);
            check_cost(&cost, space.as_ref(), &q, &[], CheckOptions::default()).assert_ok();
        }
    }

    /// `y = q ⊗ exp(dt u)` on SO(3): `dy/dq = R(dt u)ᵀ`, `dy/du = dt J_r(dt u)`.
    struct Attitude {
        dt: f64,
    }

    impl AutoDynamicsFn for Attitude {
        fn nx(&self) -> usize {
            4
        }
        fn nu(&self) -> usize {
            3
        }
        fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], y: &mut [D]) {
            let q = [x[0], x[1], x[2], x[3]];
            let w = [u[0] * self.dt, u[1] * self.dt, u[2] * self.dt];
            y.copy_from_slice(&lie::qmul(&q, &lie::exp3(&w)));
        }
    }

    /// Symmetric Hessian of `δ ↦ λᵀ (φ(x ⊕ δx, u + δu) ⊖ φ(x, u))` by second central
    /// differences, an independent reference for the hyper-dual passes.
    fn fd_dynamics_hessian(d: &dyn ExplicitDynamics, x: &[f64], u: &[f64], lam: &[f64]) -> Mat<f64> {
        let (s, sn) = (d.space().clone(), d.space_next().clone());
        let (ndx, nu) = (s.ndx(), u.len());
        let n = ndx + nu;
        let mut data = d.create_data();
        d.forward(x, u, &mut data);
        let y0 = data.xnext().to_vec();
        let mut g = |dz: &[f64]| {
            let mut xp = vec![0.0; s.nx()];
            s.integrate(x, &dz[..ndx], &mut xp);
            let up: Vec<f64> = (0..nu).map(|i| u[i] + dz[ndx + i]).collect();
            d.forward(&xp, &up, &mut data);
            let mut e = vec![0.0; sn.ndx()];
            sn.difference(&y0, data.xnext(), &mut e);
            e.iter().zip(lam).map(|(a, b)| a * b).sum::<f64>()
        };
        let h = 1e-4;
        Mat::from_fn(n, n, |i, j| {
            let mut z = vec![0.0; n];
            let mut f = |si: f64, sj: f64| {
                z.fill(0.0);
                z[i] += si * h;
                z[j] += sj * h;
                g(&z)
            };
            (f(1.0, 1.0) - f(1.0, -1.0) - f(-1.0, 1.0) + f(-1.0, -1.0)) / (4.0 * h * h)
        })
    }

    #[test]
    fn dynamics_on_so3_match_the_group_jacobians() {
        let space: Arc<dyn Manifold> = Arc::new(SO3);
        let dt = 0.1;
        let dyn_ = AutoDiff::explicit_dynamics(space.clone(), space.clone(), Attitude { dt }).unwrap();
        let mut data = dyn_.create_data();
        let mut rng = SmallRng::seed_from_u64(5);
        let mut j = Mat::zeros(3, 3);
        for _ in 0..20 {
            let mut q = [0.0; 4];
            space.random(&mut rng, &mut q);
            let u = rand_vec(&mut rng, 3);
            let lam = rand_vec(&mut rng, 3);
            dyn_.forward(&q, &u, &mut data);
            dyn_.jacobians(&q, &u, &mut data);
            dyn_.vhp(&q, &u, &lam, &mut data);
            let w: Vec<f64> = u.iter().map(|v| v * dt).collect();
            SO3.jintegrate(&q, &w, Arg::First, j.as_mut());
            assert!(rel_error(&data.jx, &j) < 1e-14);
            SO3.jintegrate(&q, &w, Arg::Second, j.as_mut());
            assert!(rel_error(&data.ju, &Mat::from_fn(3, 3, |a, b| dt * j[(a, b)])) < 1e-14);
            check_explicit_dynamics(&dyn_, &q, &u, CheckOptions::default()).assert_ok();
            let reference = |x: &[Dual64], u: &[Dual64], y: &mut [Dual64]| dyn_.inner().eval(x, u, y);
            check_explicit_dynamics_dual(&dyn_, &q, &u, reference, DualCheckOptions::default()).assert_ok();
            let reference = |x: &[HyperDual64], u: &[HyperDual64], y: &mut [HyperDual64]| dyn_.inner().eval(x, u, y);
            check_explicit_dynamics_vhp_dual(&dyn_, &q, &u, &lam, reference, DualCheckOptions::default()).assert_ok();
            let h = fd_dynamics_hessian(&dyn_, &q, &u, &lam);
            let mut ad = Mat::zeros(6, 6);
            ad.as_mut().submatrix_mut(0, 0, 3, 3).copy_from(&data.vhp_xx);
            ad.as_mut().submatrix_mut(0, 3, 3, 3).copy_from(&data.vhp_xu);
            ad.as_mut().submatrix_mut(3, 0, 3, 3).copy_from(data.vhp_xu.transpose());
            ad.as_mut().submatrix_mut(3, 3, 3, 3).copy_from(&data.vhp_uu);
            assert!(rel_error(&ad, &h) < 1e-6, "{ad:?} vs {h:?}");
        }
    }

    /// A unicycle on SE(2) with a non-trivial control map: `y = x ⊕ dt (u0, 0, u1 u0)`,
    /// written on the representation.
    struct Unicycle {
        dt: f64,
    }

    impl AutoDynamicsFn for Unicycle {
        fn nx(&self) -> usize {
            4
        }
        fn nu(&self) -> usize {
            2
        }
        fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], y: &mut [D]) {
            let (c, s) = (x[2], x[3]);
            let (v, w) = (u[0] * self.dt, u[1] * u[0] * self.dt);
            let (sw, cw) = w.sin_cos();
            y[0] = x[0] + c * v;
            y[1] = x[1] + s * v;
            y[2] = c * cw - s * sw;
            y[3] = s * cw + c * sw;
        }
    }

    #[test]
    fn dynamics_on_se2_pass_both_checkers() {
        let space: Arc<dyn Manifold> = Arc::new(SE2);
        let d = AutoDiff::explicit_dynamics(space.clone(), space.clone(), Unicycle { dt: 0.2 }).unwrap();
        let mut rng = SmallRng::seed_from_u64(6);
        for _ in 0..20 {
            let mut x = [0.0; 4];
            space.random(&mut rng, &mut x);
            let (u, lam) = (rand_vec(&mut rng, 2), rand_vec(&mut rng, 3));
            check_explicit_dynamics(&d, &x, &u, CheckOptions::default()).assert_ok();
            let mut data = d.create_data();
            d.forward(&x, &u, &mut data);
            d.jacobians(&x, &u, &mut data);
            d.vhp(&x, &u, &lam, &mut data);
            let h = fd_dynamics_hessian(&d, &x, &u, &lam);
            assert!(rel_error(&data.vhp_xx, &h.as_ref().submatrix(0, 0, 3, 3).to_owned()) < 1e-6);
            assert!(rel_error(&data.vhp_xu, &h.as_ref().submatrix(0, 3, 3, 2).to_owned()) < 1e-6);
            assert!(rel_error(&data.vhp_uu, &h.as_ref().submatrix(3, 3, 2, 2).to_owned()) < 1e-6);
        }
    }

    /// `y = x ⊕ dt u` on SE(3), written with the space's own `⊕`: `dy/dx = Ad(exp(dt u))⁻¹`,
    /// `dy/du = dt J_r(dt u)`.
    struct TwistStep {
        dt: f64,
    }

    impl AutoDynamicsFn for TwistStep {
        fn nx(&self) -> usize {
            7
        }
        fn nu(&self) -> usize {
            6
        }
        fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], y: &mut [D]) {
            let v: [D; 6] = std::array::from_fn(|i| u[i] * self.dt);
            D::integrate(&SE3, x, &v, y);
        }
    }

    /// Semi-implicit Euler on the tangent bundle of SE(2): `v⁺ = v + dt u`,
    /// `q⁺ = q ⊕ dt v⁺`, written with the base space's `⊕`.
    struct SemiImplicit {
        dt: f64,
    }

    impl AutoDynamicsFn for SemiImplicit {
        fn nx(&self) -> usize {
            7
        }
        fn nu(&self) -> usize {
            3
        }
        fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], y: &mut [D]) {
            for i in 0..3 {
                y[4 + i] = x[4 + i] + u[i] * self.dt;
            }
            let dq: [D; 3] = std::array::from_fn(|i| y[4 + i] * self.dt);
            D::integrate(&SE2, &x[..4], &dq, &mut y[..4]);
        }
    }

    #[test]
    fn models_using_the_space_operations() {
        let mut rng = SmallRng::seed_from_u64(8);
        let se3: Arc<dyn Manifold> = Arc::new(SE3);
        let dt = 0.3;
        let d = AutoDiff::explicit_dynamics(se3.clone(), se3.clone(), TwistStep { dt }).unwrap();
        let mut data = d.create_data();
        let mut j = Mat::zeros(6, 6);
        for _ in 0..10 {
            let mut x = [0.0; 7];
            se3.random(&mut rng, &mut x);
            let (u, lam) = (rand_vec(&mut rng, 6), rand_vec(&mut rng, 6));
            d.forward(&x, &u, &mut data);
            d.jacobians(&x, &u, &mut data);
            d.vhp(&x, &u, &lam, &mut data);
            let v: Vec<f64> = u.iter().map(|ui| ui * dt).collect();
            SE3.jintegrate(&x, &v, Arg::First, j.as_mut());
            assert!(rel_error(&data.jx, &j) < 1e-14);
            SE3.jintegrate(&x, &v, Arg::Second, j.as_mut());
            assert!(rel_error(&data.ju, &Mat::from_fn(6, 6, |a, b| dt * j[(a, b)])) < 1e-14);
            let h = fd_dynamics_hessian(&d, &x, &u, &lam);
            assert!(rel_error(&data.vhp_xx, &h.as_ref().submatrix(0, 0, 6, 6).to_owned()) < 1e-6);
            assert!(rel_error(&data.vhp_xu, &h.as_ref().submatrix(0, 6, 6, 6).to_owned()) < 1e-6);
            assert!(rel_error(&data.vhp_uu, &h.as_ref().submatrix(6, 6, 6, 6).to_owned()) < 1e-6);
        }

        let tb: Arc<dyn Manifold> = Arc::new(TangentBundle::new(Arc::new(SE2)));
        let d = AutoDiff::explicit_dynamics(tb.clone(), tb.clone(), SemiImplicit { dt: 0.1 }).unwrap();
        for _ in 0..10 {
            let mut x = [0.0; 7];
            tb.random(&mut rng, &mut x);
            let (u, lam) = (rand_vec(&mut rng, 3), rand_vec(&mut rng, 6));
            check_explicit_dynamics(&d, &x, &u, CheckOptions::default()).assert_ok();
            let mut data = d.create_data();
            d.forward(&x, &u, &mut data);
            d.jacobians(&x, &u, &mut data);
            d.vhp(&x, &u, &lam, &mut data);
            let h = fd_dynamics_hessian(&d, &x, &u, &lam);
            assert!(rel_error(&data.vhp_xx, &h.as_ref().submatrix(0, 0, 6, 6).to_owned()) < 1e-6);
            assert!(rel_error(&data.vhp_xu, &h.as_ref().submatrix(0, 6, 6, 3).to_owned()) < 1e-6);
            assert!(rel_error(&data.vhp_uu, &h.as_ref().submatrix(6, 6, 3, 3).to_owned()) < 1e-6);
        }
    }

    /// `r(x) = (R(q) v, |v|²)` on the tangent bundle of SO(3), lifted to a stage function.
    struct BodyVelocity;

    impl AutoUnaryFn for BodyVelocity {
        fn nx(&self) -> usize {
            7
        }
        fn nr(&self) -> usize {
            4
        }
        fn eval<D: ManifoldScalar>(&self, x: &[D], out: &mut [D]) {
            let q = [x[0], x[1], x[2], x[3]];
            let v = [x[4], x[5], x[6]];
            out[..3].copy_from_slice(&lie::qrot(&q, &v));
            out[3] = lie::dot3(&v, &v);
        }
    }

    #[test]
    fn unary_function_on_a_tangent_bundle() {
        let space: Arc<dyn Manifold> = Arc::new(TangentBundle::new(Arc::new(SO3)));
        let f = Unary::new(Arc::new(AutoDiff::unary(space.clone(), BodyVelocity).unwrap()), 2);
        let mut rng = SmallRng::seed_from_u64(7);
        for _ in 0..20 {
            let mut x = [0.0; 7];
            space.random(&mut rng, &mut x);
            let (u, lam) = (rand_vec(&mut rng, 2), rand_vec(&mut rng, 4));
            check_stage_function(&f, space.as_ref(), &x, &u, Some(&lam), CheckOptions::default()).assert_ok();
            let r = |x: &[Dual64], _: &[Dual64], out: &mut [Dual64]| BodyVelocity.eval(x, out);
            check_stage_function_dual(&f, space.as_ref(), &x, &u, r, DualCheckOptions::default()).assert_ok();
            let r = |x: &[HyperDual64], _: &[HyperDual64], out: &mut [HyperDual64]| BodyVelocity.eval(x, out);
            check_stage_function_vhp_dual(&f, space.as_ref(), &x, &u, &lam, r, DualCheckOptions::default()).assert_ok();
        }
    }

    #[test]
    fn wrong_sizes_are_reported() {
        let err = AutoDiff::stage(vs(4), Residual).unwrap_err();
        assert!(
            matches!(
                err,
                crate::Error::Dimension {
                    expected: 4,
                    got: 3,
                    ..
                }
            ),
            "{err}"
        );
        assert!(
            AutoDiff::cost(
                Arc::new(SO3),
                Bilinear {
                    a: [0.0; 3],
                    b: [0.0; 3]
                }
            )
            .is_ok()
        );
        assert!(
            AutoDiff::cost(
                vs(3),
                Bilinear {
                    a: [0.0; 3],
                    b: [0.0; 3]
                }
            )
            .is_err()
        );
        assert!(AutoDiff::explicit_dynamics(Arc::new(SO3), vs(3), Attitude { dt: 0.1 }).is_err());
        assert!(
            AutoDiff::ode(
                vs(3),
                Pendulum {
                    g_l: 1.0,
                    b: 0.0,
                    inv_ml2: 1.0
                }
            )
            .is_err()
        );
    }

    #[test]
    fn dual_checks_catch_wrong_models() {
        // A stage function whose Jacobian is off in one entry.
        struct Off(AutoDiff<Residual>);
        impl StageFunction for Off {
            fn nx(&self) -> usize {
                3
            }
            fn ndx(&self) -> usize {
                3
            }
            fn nu(&self) -> usize {
                2
            }
            fn nr(&self) -> usize {
                3
            }
            fn create_workspace(&self) -> Workspace {
                self.0.create_workspace()
            }
            fn evaluate(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
                self.0.evaluate(x, u, data)
            }
            fn jacobians(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
                self.0.jacobians(x, u, data);
                data.jx[(1, 2)] += 1e-9;
            }
        }
        let f = Off(AutoDiff::stage(vs(3), Residual).unwrap());
        let (x, u) = ([0.1, 0.2, 0.3], [0.4, -0.5]);
        let r = |x: &[Dual64], u: &[Dual64], out: &mut [Dual64]| Residual.eval(x, u, out);
        let rep = check_stage_function_dual(&f, &VectorSpace::new(3), &x, &u, r, DualCheckOptions::default());
        assert!(!rep.passed());
        assert!((rep.max_error() - 1e-9).abs() < 1e-12, "{rep:?}");
        // A reference that computes another function fails on the value.
        let other = |x: &[Dual64], u: &[Dual64], out: &mut [Dual64]| {
            Residual.eval(x, u, out);
            out[0] += 1e-6;
        };
        let rep = check_stage_function_dual(&f.0, &VectorSpace::new(3), &x, &u, other, DualCheckOptions::default());
        assert!(!rep.passed());
        assert_eq!(rep.errors[0].0, "value");
        // A cost checked against a reference with another Hessian fails.
        let cost = AutoDiff::cost(
            Arc::new(SO3),
            Bilinear {
                a: [1.0, 0.0, 0.0],
                b: [0.0, 1.0, 0.0],
            },
        )
        .unwrap();
        let q = SO3::exp(&[0.3, 0.2, -0.1]);
        let good = |x: &[HyperDual64], u: &[HyperDual64]| cost.inner().eval(x, u);
        check_cost_dual(&cost, &SO3, &q, &[], good, DualCheckOptions::default()).assert_ok();
        // Same value and gradient at q, another Hessian.
        let bad = |x: &[HyperDual64], u: &[HyperDual64]| {
            let d = x[0] - q[0];
            cost.inner().eval(x, u) + d * d * 1e-3
        };
        let rep = check_cost_dual(&cost, &SO3, &q, &[], bad, DualCheckOptions::default());
        assert!(!rep.passed());
        assert!(
            rep.errors.iter().all(|(name, e)| (*e > 1e-6) == (name == "lxx")),
            "{rep:?}"
        );
    }
}

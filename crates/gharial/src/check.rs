//! Derivative checker, with two references:
//! - **finite differences**: central differences along tangent directions
//!   (`x ⊕ ε e_j`) of the model's own `f64` evaluation. Errors are relative:
//!   `max|J - J_fd| / max(1, max|J_fd|)`. With the default step (`1e-6`) smooth models
//!   agree to about `1e-9`; the default tolerance is `1e-6`.
//! - **dual numbers** (`check_*_dual`): exact derivatives of a *reference
//!   implementation* supplied by the caller, written once generic over
//!   [`Scalar`](crate::spaces::Scalar) and passed as a function item (the compiler picks
//!   the dual type). The default tolerance is `1e-12`. The reference's value is
//!   compared too, so a reference that computes something else fails. A reference
//!   on a manifold can be generic over
//!   [`ManifoldScalar`](crate::spaces::ManifoldScalar) to use the space's `⊕` and `⊖`
//!   (`D::integrate(space, ...)`, `D::difference(space, ...)`).
//!
//! Every model of the library is tested with both; users can run them on their own
//! models.
//!
//! Conventions: state derivatives are tangent (`ndx`), as everywhere in the library.
//! Second derivatives with respect to the state are the symmetric Hessians of
//! `δ ↦ g(x ⊕ δ)` at `δ = 0`. The finite-difference reference differentiates the
//! tangent gradient at `x ⊕ ε e_j`, whose state-state block differs from that Hessian
//! by an antisymmetric term on curved spaces (the Lie bracket of the two directions),
//! so its symmetric part is compared.
//!
//! # Example
//!
//! ```
//! use gharial::check::{DualCheckOptions, check_stage_function_dual};
//! use gharial::functions::{StageFunction, StageFunctionData};
//! use gharial::spaces::{Scalar, VectorSpace};
//!
//! /// r(x, u) = (x0 u0, sin x1), with hand-written Jacobians.
//! struct MyResidual;
//!
//! impl StageFunction for MyResidual {
//!     fn nx(&self) -> usize { 2 }
//!     fn ndx(&self) -> usize { 2 }
//!     fn nu(&self) -> usize { 1 }
//!     fn nr(&self) -> usize { 2 }
//!     fn evaluate(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
//!         data.value_mut().copy_from_slice(&[x[0] * u[0], x[1].sin()]);
//!     }
//!     fn jacobians(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
//!         data.jx.fill(0.0);
//!         data.jx[(0, 0)] = u[0];
//!         data.jx[(1, 1)] = x[1].cos();
//!         data.ju[(0, 0)] = x[0];
//!         data.ju[(1, 0)] = 0.0;
//!     }
//! }
//!
//! /// The same function, written once for every scalar.
//! fn reference<D: Scalar>(x: &[D], u: &[D], out: &mut [D]) {
//!     out[0] = x[0] * u[0];
//!     out[1] = x[1].sin();
//! }
//!
//! let space = VectorSpace::new(2);
//! let report = check_stage_function_dual(
//!     &MyResidual, &space, &[0.3, -1.2], &[2.0], reference, DualCheckOptions::default(),
//! );
//! report.assert_ok();
//! assert!(report.max_error() < 1e-15);
//! ```

use std::sync::Arc;

use faer::Mat;
use num_dual::{Dual64, HyperDual64};

use crate::autodiff::{DualScratch, Hessian, Output, hessian_hyper, jacobians_dual};
use crate::costs::{Cost, CostData};
use crate::dynamics::{ExplicitDynamics, ExplicitDynamicsData, ImplicitDynamics, ImplicitDynamicsData, Ode, OdeData};
use crate::functions::{StageFunction, StageFunctionData};
use crate::linalg::norm_max;
use crate::spaces::{Arg, Manifold};

/// Step and tolerance of the checks.
#[derive(Debug, Clone, Copy)]
pub struct CheckOptions {
    /// Finite-difference step (default `1e-6`).
    pub eps: f64,
    /// Largest accepted relative error (default `1e-6`).
    pub tol: f64,
}

impl Default for CheckOptions {
    fn default() -> Self {
        Self { eps: 1e-6, tol: 1e-6 }
    }
}

/// The outcome of a derivative check: one relative error per derivative block.
#[derive(Debug, Clone, Default)]
pub struct CheckReport {
    /// `(name of the block, relative error)`.
    pub errors: Vec<(String, f64)>,
    /// Tolerance the errors are compared with.
    pub tol: f64,
}

impl CheckReport {
    fn new(tol: f64) -> Self {
        Self {
            errors: Vec::new(),
            tol,
        }
    }

    fn push(&mut self, name: &str, analytic: &Mat<f64>, reference: &Mat<f64>) {
        self.errors.push((name.to_string(), rel_error(analytic, reference)));
    }

    /// Records how far a square Jacobian `reference` is from `diag(J_b, s I)`: it against
    /// itself with every entry outside the leading `k × k` block replaced by `s I`'s.
    fn push_structure(&mut self, name: &str, k: usize, s: f64, reference: &Mat<f64>) {
        let claimed = Mat::from_fn(reference.nrows(), reference.ncols(), |i, j| {
            match (i < k && j < k, i == j) {
                (true, _) => reference[(i, j)],
                (false, true) => s,
                (false, false) => 0.0,
            }
        });
        self.push(&format!("nonlinear_dim: {name}"), &claimed, reference);
    }

    /// Largest relative error over all blocks.
    pub fn max_error(&self) -> f64 {
        self.errors.iter().fold(0.0_f64, |a, (_, e)| a.max(*e))
    }

    /// Whether every block is within tolerance (and finite).
    pub fn passed(&self) -> bool {
        self.errors.iter().all(|(_, e)| e.is_finite() && *e <= self.tol)
    }

    /// Panics with the report if a block is out of tolerance (for tests).
    #[track_caller]
    pub fn assert_ok(&self) {
        assert!(
            self.passed(),
            "derivative check failed (tol {:e}): {:?}",
            self.tol,
            self.errors
        );
    }
}

/// `max|a - b| / max(1, max|b|)`; infinite if the shapes differ or a value is NaN.
pub fn rel_error(a: &Mat<f64>, b: &Mat<f64>) -> f64 {
    if a.nrows() != b.nrows() || a.ncols() != b.ncols() {
        return f64::INFINITY;
    }
    let mut err: f64 = 0.0;
    for j in 0..a.ncols() {
        for i in 0..a.nrows() {
            let d = (a[(i, j)] - b[(i, j)]).abs();
            if d.is_nan() {
                return f64::INFINITY;
            }
            err = err.max(d);
        }
    }
    err / norm_max(b.as_ref()).max(1.0)
}

/// The symmetric part of the leading `n x n` block of `m`.
fn symmetric_part(m: &Mat<f64>, n: usize) -> Mat<f64> {
    Mat::from_fn(n, n, |i, j| 0.5 * (m[(i, j)] + m[(j, i)]))
}

/// Central differences of a vector map `g` (values in a space `out_space`) along the
/// tangent directions of `x ∈ space`, returning `out_space.ndx() x space.ndx()`.
fn fd_state(
    space: &dyn Manifold,
    x: &[f64],
    out_space: &dyn Manifold,
    eps: f64,
    mut g: impl FnMut(&[f64], &mut [f64]),
) -> Mat<f64> {
    let (ndx, nout, ndout) = (space.ndx(), out_space.nx(), out_space.ndx());
    let mut jac = Mat::zeros(ndout, ndx);
    let mut v = vec![0.0; ndx];
    let mut xp = vec![0.0; space.nx()];
    let (mut gp, mut gm, mut g0) = (vec![0.0; nout], vec![0.0; nout], vec![0.0; nout]);
    let (mut dp, mut dm) = (vec![0.0; ndout], vec![0.0; ndout]);
    g(x, &mut g0);
    for j in 0..ndx {
        v.fill(0.0);
        v[j] = eps;
        space.integrate(x, &v, &mut xp);
        g(&xp, &mut gp);
        v[j] = -eps;
        space.integrate(x, &v, &mut xp);
        g(&xp, &mut gm);
        out_space.difference(&g0, &gp, &mut dp);
        out_space.difference(&g0, &gm, &mut dm);
        for i in 0..ndout {
            jac[(i, j)] = (dp[i] - dm[i]) / (2.0 * eps);
        }
    }
    jac
}

/// Central differences of a vector map of a plain vector `u`.
fn fd_vec(u: &[f64], nout_space: &dyn Manifold, eps: f64, mut g: impl FnMut(&[f64], &mut [f64])) -> Mat<f64> {
    let vs = crate::spaces::VectorSpace::new(u.len());
    fd_state(&vs, u, nout_space, eps, &mut g)
}

/// Checks `jintegrate`, `jdifference`, `jintegrate_transport`, `tangent_map` and
/// `tangent_map_inverse` of a manifold at `x`, `v` and `x1`, that the
/// finite-difference Jacobians of `integrate` and `difference` are `±I` outside the
/// block of [`Manifold::nonlinear_dim`] (entries `nonlinear_dim: ...`), and that
/// `jdifference_block` is that block of `jdifference`.
pub fn check_manifold(m: &dyn Manifold, x: &[f64], v: &[f64], x1: &[f64], opts: CheckOptions) -> CheckReport {
    let mut rep = CheckReport::new(opts.tol);
    let (nx, ndx) = (m.nx(), m.ndx());
    let tangent = crate::spaces::VectorSpace::new(ndx);
    let mut j = Mat::zeros(ndx, ndx);
    let mut buf = vec![0.0; nx];

    m.jintegrate(x, v, Arg::First, j.as_mut());
    let fd = fd_state(m, x, m, opts.eps, |xp, out| m.integrate(xp, v, out));
    rep.push("jintegrate(x)", &j, &fd);
    rep.push_structure("jintegrate(x)", m.nonlinear_dim(), 1.0, &fd);
    m.jintegrate(x, v, Arg::Second, j.as_mut());
    let fd = fd_state(&tangent, v, m, opts.eps, |vp, out| m.integrate(x, vp, out));
    rep.push("jintegrate(v)", &j, &fd);
    rep.push_structure("jintegrate(v)", m.nonlinear_dim(), 1.0, &fd);

    for arg in [Arg::First, Arg::Second] {
        let mut t = Mat::from_fn(ndx, 3, |i, k| ((i + 2 * k) % 5) as f64 - 2.0);
        let t0 = t.clone();
        m.jintegrate_transport(x, v, arg, t.as_mut());
        m.jintegrate(x, v, arg, j.as_mut());
        let mut expect = Mat::zeros(ndx, 3);
        crate::linalg::matmul(expect.as_mut(), faer::Accum::Replace, j.as_ref(), t0.as_ref(), 1.0);
        rep.push(&format!("jintegrate_transport({arg:?})"), &t, &expect);
    }

    m.jdifference(x, x1, Arg::First, j.as_mut());
    let fd = fd_state(m, x, &tangent, opts.eps, |xp, out| m.difference(xp, x1, out));
    rep.push("jdifference(x0)", &j, &fd);
    rep.push_structure("jdifference(x0)", m.nonlinear_dim(), -1.0, &fd);
    m.jdifference(x, x1, Arg::Second, j.as_mut());
    let fd = fd_state(m, x1, &tangent, opts.eps, |xp, out| m.difference(x, xp, out));
    rep.push("jdifference(x1)", &j, &fd);
    rep.push_structure("jdifference(x1)", m.nonlinear_dim(), 1.0, &fd);
    let k = m.nonlinear_dim();
    for arg in [Arg::First, Arg::Second] {
        // From NaN: an entry the method does not write fails the check.
        let mut block = Mat::from_fn(k, k, |_, _| f64::NAN);
        m.jdifference_block(x, x1, arg, block.as_mut());
        m.jdifference(x, x1, arg, j.as_mut());
        let lead = j.as_ref().submatrix(0, 0, k, k).to_owned();
        rep.push(&format!("jdifference_block({arg:?})"), &block, &lead);
    }

    // tangent_map: representation derivative of x ⊕ v at v = 0.
    let mut tm = Mat::zeros(nx, ndx);
    m.tangent_map(x, tm.as_mut());
    let rep_space = crate::spaces::VectorSpace::new(nx);
    let zero = vec![0.0; ndx];
    let fd = fd_state(&tangent, &zero, &rep_space, opts.eps, |vp, out| {
        m.integrate(x, vp, &mut buf);
        out.copy_from_slice(&buf);
    });
    rep.push("tangent_map", &tm, &fd);

    // tangent_map_inverse: representation derivative of z ↦ z ⊖ x at z = x.
    let mut tmi = Mat::zeros(ndx, nx);
    m.tangent_map_inverse(x, tmi.as_mut());
    let fd = fd_state(&rep_space, x, &tangent, opts.eps, |z, out| m.difference(x, z, out));
    rep.push("tangent_map_inverse", &tmi, &fd);
    rep
}

// ---------------------------------------------------------------------------------
// Dual-number references.

/// Tolerance of the dual-number checks.
#[derive(Debug, Clone, Copy)]
pub struct DualCheckOptions {
    /// Largest accepted relative error (default `1e-12`).
    pub tol: f64,
}

impl Default for DualCheckOptions {
    fn default() -> Self {
        Self { tol: 1e-12 }
    }
}

/// Value and first derivatives of a reference implementation, from dual numbers.
#[derive(Debug, Clone)]
pub struct DualJacobians {
    /// The value at the point (representation of a point for explicit dynamics).
    pub value: Vec<f64>,
    /// Derivative with respect to tangent perturbations of the state.
    pub jx: Mat<f64>,
    /// Derivative with respect to the control.
    pub ju: Mat<f64>,
}

/// Second-order blocks of a reference implementation, from hyper-dual numbers.
#[derive(Debug, Clone)]
pub struct DualHessians {
    /// State-state block (`ndx x ndx`), symmetric.
    pub xx: Mat<f64>,
    /// State-control block (`ndx x nu`).
    pub xu: Mat<f64>,
    /// Control-control block (`nu x nu`), symmetric.
    pub uu: Mat<f64>,
}

/// Value, gradient and Hessian of a reference cost, from hyper-dual numbers.
#[derive(Debug, Clone)]
pub struct DualCostDerivatives {
    /// `ℓ(x, u)`.
    pub value: f64,
    /// Tangent gradient (`ndx`).
    pub lx: Vec<f64>,
    /// Control gradient (`nu`).
    pub lu: Vec<f64>,
    /// `d²ℓ/dx²`.
    pub lxx: Mat<f64>,
    /// `d²ℓ/dxdu`.
    pub lxu: Mat<f64>,
    /// `d²ℓ/du²`.
    pub luu: Mat<f64>,
}

fn duals(v: &[f64]) -> Vec<Dual64> {
    v.iter().map(|&r| Dual64::new(r, 0.0)).collect()
}

fn hypers(v: &[f64]) -> Vec<HyperDual64> {
    v.iter().map(|&r| HyperDual64::new(r, 0.0, 0.0, 0.0)).collect()
}

fn column(v: &[f64]) -> Mat<f64> {
    Mat::from_fn(v.len(), 1, |i, _| v[i])
}

/// Value of a dual-number function at a point (derivative parts zero).
fn dual_value(x: &[f64], u: &[f64], n: usize, mut f: impl FnMut(&[Dual64], &[Dual64], &mut [Dual64])) -> Vec<f64> {
    let mut out = vec![Dual64::new(0.0, 0.0); n];
    f(&duals(x), &duals(u), &mut out);
    out.iter().map(|d| d.re).collect()
}

/// Value and Jacobians of a reference `r(x, u)` (`nr` outputs) with dual numbers, `x`
/// on `space`.
pub fn dual_stage_jacobians(
    space: &dyn Manifold,
    x: &[f64],
    u: &[f64],
    nr: usize,
    mut r: impl FnMut(&[Dual64], &[Dual64], &mut [Dual64]),
) -> DualJacobians {
    let value = dual_value(x, u, nr, &mut r);
    let mut s = DualScratch::new(space, u.len(), nr, None);
    let (mut jx, mut ju) = (Mat::zeros(nr, space.ndx()), Mat::zeros(nr, u.len()));
    jacobians_dual(space, Output::Vector(nr), x, u, &mut s, jx.as_mut(), ju.as_mut(), r);
    DualJacobians { value, jx, ju }
}

/// Second-order blocks of `λᵀ r(x ⊕ δx, u + δu)` for a reference `r` with hyper-dual
/// numbers (`nr = lambda.len()`).
pub fn hyper_stage_vhp(
    space: &dyn Manifold,
    x: &[f64],
    u: &[f64],
    lambda: &[f64],
    r: impl FnMut(&[HyperDual64], &[HyperDual64], &mut [HyperDual64]),
) -> DualHessians {
    hessians(space, Output::Vector(lambda.len()), x, u, lambda, r)
}

fn hessians(
    space: &dyn Manifold,
    out: Output<'_>,
    x: &[f64],
    u: &[f64],
    w: &[f64],
    r: impl FnMut(&[HyperDual64], &[HyperDual64], &mut [HyperDual64]),
) -> DualHessians {
    let (ndx, nu) = (space.ndx(), u.len());
    let (ny, out_space) = match out {
        Output::Vector(n) => (n, None),
        Output::Manifold(m, _) => (m.nx(), Some(m)),
    };
    let mut s = DualScratch::new(space, nu, ny, out_space);
    let mut h = DualHessians {
        xx: Mat::zeros(ndx, ndx),
        xu: Mat::zeros(ndx, nu),
        uu: Mat::zeros(nu, nu),
    };
    let blocks = Hessian {
        xx: h.xx.as_mut(),
        xu: h.xu.as_mut(),
        uu: h.uu.as_mut(),
        grad: None,
    };
    hessian_hyper(space, out, x, u, w, &mut s, blocks, r);
    h
}

/// Value, gradient and Hessian of a reference cost `ℓ(x, u)` with hyper-dual numbers.
pub fn hyper_cost_derivatives(
    space: &dyn Manifold,
    x: &[f64],
    u: &[f64],
    mut l: impl FnMut(&[HyperDual64], &[HyperDual64]) -> HyperDual64,
) -> DualCostDerivatives {
    let (ndx, nu) = (space.ndx(), u.len());
    let value = l(&hypers(x), &hypers(u)).re;
    let mut s = DualScratch::new(space, nu, 1, None);
    let mut d = DualCostDerivatives {
        value,
        lx: vec![0.0; ndx],
        lu: vec![0.0; nu],
        lxx: Mat::zeros(ndx, ndx),
        lxu: Mat::zeros(ndx, nu),
        luu: Mat::zeros(nu, nu),
    };
    let blocks = Hessian {
        xx: d.lxx.as_mut(),
        xu: d.lxu.as_mut(),
        uu: d.luu.as_mut(),
        grad: Some((&mut d.lx, &mut d.lu)),
    };
    hessian_hyper(space, Output::Vector(1), x, u, &[1.0], &mut s, blocks, |x, u, out| {
        out[0] = l(x, u)
    });
    d
}

/// Next state and Jacobians of reference explicit dynamics `y = φ(x, u)` with dual
/// numbers; the Jacobians are those of `φ(x ⊕ δx, u + δu) ⊖ φ(x, u)`.
pub fn dual_explicit_dynamics_jacobians(
    space: &dyn Manifold,
    space_next: &dyn Manifold,
    x: &[f64],
    u: &[f64],
    mut phi: impl FnMut(&[Dual64], &[Dual64], &mut [Dual64]),
) -> DualJacobians {
    let y = dual_value(x, u, space_next.nx(), &mut phi);
    let mut s = DualScratch::new(space, u.len(), space_next.nx(), Some(space_next));
    let ndy = space_next.ndx();
    let (mut jx, mut ju) = (Mat::zeros(ndy, space.ndx()), Mat::zeros(ndy, u.len()));
    let out = Output::Manifold(space_next, &y);
    jacobians_dual(space, out, x, u, &mut s, jx.as_mut(), ju.as_mut(), phi);
    DualJacobians { value: y, jx, ju }
}

/// Second-order blocks of `λᵀ (φ(x ⊕ δx, u + δu) ⊖ φ(x, u))` for reference explicit
/// dynamics with hyper-dual numbers (`lambda`: `ndx_next`).
pub fn hyper_explicit_dynamics_vhp(
    space: &dyn Manifold,
    space_next: &dyn Manifold,
    x: &[f64],
    u: &[f64],
    lambda: &[f64],
    mut phi: impl FnMut(&[HyperDual64], &[HyperDual64], &mut [HyperDual64]),
) -> DualHessians {
    let mut yh = vec![HyperDual64::new(0.0, 0.0, 0.0, 0.0); space_next.nx()];
    phi(&hypers(x), &hypers(u), &mut yh);
    let y: Vec<f64> = yh.iter().map(|v| v.re).collect();
    hessians(space, Output::Manifold(space_next, &y), x, u, lambda, phi)
}

/// Residual and Jacobians of reference implicit dynamics `f(x, u, y)` (`ndx_next`
/// outputs) with dual numbers: `(value, jx, ju)` and `jy`.
pub fn dual_implicit_dynamics_jacobians(
    space: &dyn Manifold,
    space_next: &dyn Manifold,
    x: &[f64],
    u: &[f64],
    y: &[f64],
    mut f: impl FnMut(&[Dual64], &[Dual64], &[Dual64], &mut [Dual64]),
) -> (DualJacobians, Mat<f64>) {
    let n = space_next.ndx();
    let yd = duals(y);
    let first = dual_stage_jacobians(space, x, u, n, |x, u, out| f(x, u, &yd, out));
    let (xd, ud) = (duals(x), duals(u));
    let jy = dual_stage_jacobians(space_next, y, &[], n, |y, _, out| f(&xd, &ud, y, out)).jx;
    (first, jy)
}

/// Velocity and Jacobians of a reference ODE `ẋ = f(x, u)` (`ndx` outputs) with dual
/// numbers.
pub fn dual_ode_jacobians(
    space: &dyn Manifold,
    x: &[f64],
    u: &[f64],
    f: impl FnMut(&[Dual64], &[Dual64], &mut [Dual64]),
) -> DualJacobians {
    dual_stage_jacobians(space, x, u, space.ndx(), f)
}

// ---------------------------------------------------------------------------------
// One checker for every model kind.

/// A model kind as the checkers see it: a map `(x, u[, y]) ↦ value` with analytic first
/// derivatives and, where the kind has them, analytic second derivatives of a weighted
/// value. One thin adapter per kind; the finite-difference and dual-number bodies below
/// are written once against it.
trait Checked {
    /// The model's data.
    type Data;
    /// Names of the first-order blocks (`x`, `u`, `y`).
    const FIRST: [&'static str; 3];
    /// Names of the second-order blocks (`xx`, `xu`, `uu`).
    const SECOND: [&'static str; 3] = ["vhp_xx", "vhp_xu", "vhp_uu"];
    /// Fresh data.
    fn create_data(&self) -> Self::Data;
    /// Writes the value at `(x, u, y)` into `out`, using `d` as scratch.
    fn value(&self, x: &[f64], u: &[f64], y: &[f64], d: &mut Self::Data, out: &mut [f64]);
    /// Evaluates and writes the analytic first derivatives into `d`.
    fn derive(&self, x: &[f64], u: &[f64], y: &[f64], d: &mut Self::Data);
    /// The value in `d`.
    fn current<'d>(&self, d: &'d Self::Data) -> &'d [f64];
    /// The analytic first-order blocks in `d`, one row per value component.
    fn first_order(&self, d: &Self::Data) -> Vec<Mat<f64>>;
    /// The analytic second-order blocks of `wᵀ value` at `(x, u)` (after `derive`).
    fn second_order(&self, x: &[f64], u: &[f64], w: &[f64], d: &mut Self::Data) -> [Mat<f64>; 3] {
        let _ = (x, u, w, d);
        unreachable!("this model kind has no second-order check")
    }
    /// Writes the analytic gradient of `wᵀ value` at `(x, u)` (tangent `x`, then `u`)
    /// into `out`, using `d` as scratch.
    fn gradient(&self, x: &[f64], u: &[f64], w: &[f64], d: &mut Self::Data, out: &mut [f64]) {
        let _ = (x, u, w, d, out);
        unreachable!("this model kind has no second-order check")
    }
    /// The analytic and reference values as two comparable columns (default: as they are).
    fn value_pair(&self, analytic: &[f64], reference: &[f64]) -> (Mat<f64>, Mat<f64>) {
        (column(analytic), column(reference))
    }
}

/// The spaces of a checked map: of the state, of the values (which are differenced in
/// it) and of a third argument `y`, if the map has one.
struct Spaces<'a> {
    x: &'a dyn Manifold,
    values: Arc<dyn Manifold>,
    y: Option<&'a dyn Manifold>,
}

impl<'a> Spaces<'a> {
    /// A map of `x ∈ x` with `n` plain values.
    fn vector(x: &'a dyn Manifold, n: usize) -> Self {
        let values = Arc::new(crate::spaces::VectorSpace::new(n));
        Self { x, values, y: None }
    }
}

/// The derivative blocks of one side of a comparison; the reference side decides which
/// blocks are compared.
#[derive(Default)]
struct Blocks {
    value: Option<Vec<f64>>,
    first: Vec<Mat<f64>>,
    second: Option<[Mat<f64>; 3]>,
}

/// The comparison of the analytic blocks with the reference blocks, in the order value,
/// first order, second order.
fn compare<M: Checked + ?Sized>(m: &M, analytic: Blocks, reference: Blocks, tol: f64) -> CheckReport {
    let mut rep = CheckReport::new(tol);
    if let (Some(a), Some(r)) = (&analytic.value, &reference.value) {
        let (a, r) = m.value_pair(a, r);
        rep.push("value", &a, &r);
    }
    for ((name, a), r) in M::FIRST.iter().zip(&analytic.first).zip(&reference.first) {
        rep.push(name, a, r);
    }
    if let (Some(a), Some(r)) = (&analytic.second, &reference.second) {
        for ((name, a), r) in M::SECOND.iter().zip(a).zip(r) {
            rep.push(name, a, r);
        }
    }
    rep
}

/// Central differences of the value along `x`, `u` (and `y`), and, with weights `w`, of
/// the analytic gradient of `wᵀ value` along `x` and `u`.
fn check_fd<M: Checked + ?Sized>(
    m: &M,
    spaces: Spaces<'_>,
    x: &[f64],
    u: &[f64],
    y: &[f64],
    w: Option<&[f64]>,
    opts: CheckOptions,
) -> CheckReport {
    let (space, values) = (spaces.x, spaces.values.as_ref());
    let mut data = m.create_data();
    m.derive(x, u, y, &mut data);
    let mut analytic = Blocks {
        first: m.first_order(&data),
        ..Blocks::default()
    };
    let mut d2 = m.create_data();
    let mut fd = Blocks::default();
    fd.first.push(fd_state(space, x, values, opts.eps, |xp, out| {
        m.value(xp, u, y, &mut d2, out)
    }));
    fd.first
        .push(fd_vec(u, values, opts.eps, |up, out| m.value(x, up, y, &mut d2, out)));
    if let Some(third) = spaces.y {
        fd.first.push(fd_state(third, y, values, opts.eps, |yp, out| {
            m.value(x, u, yp, &mut d2, out)
        }));
    }
    if let Some(w) = w {
        analytic.second = Some(m.second_order(x, u, w, &mut data));
        // The gradient of wᵀ value along x and u, differentiated again.
        let (ndx, nu) = (space.ndx(), u.len());
        let gs = crate::spaces::VectorSpace::new(ndx + nu);
        let hx = fd_state(space, x, &gs, opts.eps, |xp, out| m.gradient(xp, u, w, &mut d2, out));
        let hu = fd_vec(u, &gs, opts.eps, |up, out| m.gradient(x, up, w, &mut d2, out));
        fd.second = Some([
            symmetric_part(&hx, ndx),
            hu.as_ref().submatrix(0, 0, ndx, nu).to_owned(),
            hu.as_ref().submatrix(ndx, 0, nu, nu).to_owned(),
        ]);
    }
    compare(m, analytic, fd, opts.tol)
}

/// Compares the analytic blocks at `(x, u, y)` (second order with weights `w`) with the
/// blocks of a dual-number reference, computed after them.
fn check_dual<M: Checked + ?Sized>(
    m: &M,
    x: &[f64],
    u: &[f64],
    y: &[f64],
    w: Option<&[f64]>,
    reference: impl FnOnce() -> Blocks,
    opts: DualCheckOptions,
) -> CheckReport {
    let mut data = m.create_data();
    m.derive(x, u, y, &mut data);
    let second = w.map(|w| m.second_order(x, u, w, &mut data));
    let analytic = Blocks {
        value: Some(m.current(&data).to_vec()),
        first: m.first_order(&data),
        second,
    };
    compare(m, analytic, reference(), opts.tol)
}

/// `λᵀ J` for the rows of `j` (`out` has `j.ncols()` entries).
fn weighted_rows(lambda: &[f64], j: &Mat<f64>, out: &mut [f64]) {
    for (c, o) in out.iter_mut().enumerate() {
        *o = (0..lambda.len()).map(|i| lambda[i] * j[(i, c)]).sum();
    }
}

impl Checked for dyn StageFunction + '_ {
    type Data = StageFunctionData;
    const FIRST: [&'static str; 3] = ["jx", "ju", "jy"];
    fn create_data(&self) -> StageFunctionData {
        StageFunction::create_data(self)
    }
    fn value(&self, x: &[f64], u: &[f64], _y: &[f64], d: &mut StageFunctionData, out: &mut [f64]) {
        self.evaluate(x, u, d);
        out.copy_from_slice(d.value());
    }
    fn derive(&self, x: &[f64], u: &[f64], _y: &[f64], d: &mut StageFunctionData) {
        self.evaluate(x, u, d);
        self.jacobians(x, u, d);
    }
    fn current<'d>(&self, d: &'d StageFunctionData) -> &'d [f64] {
        d.value()
    }
    fn first_order(&self, d: &StageFunctionData) -> Vec<Mat<f64>> {
        vec![d.jx.clone(), d.ju.clone()]
    }
    fn second_order(&self, x: &[f64], u: &[f64], w: &[f64], d: &mut StageFunctionData) -> [Mat<f64>; 3] {
        self.vhp(x, u, w, d);
        [d.vhp_xx.clone(), d.vhp_xu.clone(), d.vhp_uu.clone()]
    }
    fn gradient(&self, x: &[f64], u: &[f64], w: &[f64], d: &mut StageFunctionData, out: &mut [f64]) {
        self.derive(x, u, &[], d);
        let ndx = d.jx.ncols();
        weighted_rows(w, &d.jx, &mut out[..ndx]);
        weighted_rows(w, &d.ju, &mut out[ndx..ndx + d.ju.ncols()]);
    }
}

/// `v` as a row.
fn row(v: &[f64]) -> Mat<f64> {
    Mat::from_fn(1, v.len(), |_, j| v[j])
}

impl Checked for dyn Cost + '_ {
    type Data = CostData;
    const FIRST: [&'static str; 3] = ["lx", "lu", "ly"];
    const SECOND: [&'static str; 3] = ["lxx", "lxu", "luu"];
    fn create_data(&self) -> CostData {
        Cost::create_data(self)
    }
    fn value(&self, x: &[f64], u: &[f64], _y: &[f64], d: &mut CostData, out: &mut [f64]) {
        self.evaluate(x, u, d);
        out[0] = d.value;
    }
    fn derive(&self, x: &[f64], u: &[f64], _y: &[f64], d: &mut CostData) {
        self.evaluate(x, u, d);
        self.derivatives(x, u, d);
    }
    fn current<'d>(&self, d: &'d CostData) -> &'d [f64] {
        std::slice::from_ref(&d.value)
    }
    fn first_order(&self, d: &CostData) -> Vec<Mat<f64>> {
        vec![row(d.lx()), row(d.lu())]
    }
    fn second_order(&self, _x: &[f64], _u: &[f64], _w: &[f64], d: &mut CostData) -> [Mat<f64>; 3] {
        [d.lxx.clone(), d.lxu.clone(), d.luu.clone()]
    }
    fn gradient(&self, x: &[f64], u: &[f64], _w: &[f64], d: &mut CostData, out: &mut [f64]) {
        self.derive(x, u, &[], d);
        let ndx = d.lx().len();
        out[..ndx].copy_from_slice(d.lx());
        out[ndx..].copy_from_slice(d.lu());
    }
}

impl Checked for dyn ExplicitDynamics + '_ {
    type Data = ExplicitDynamicsData;
    const FIRST: [&'static str; 3] = ["jx", "ju", "jy"];
    fn create_data(&self) -> ExplicitDynamicsData {
        ExplicitDynamics::create_data(self)
    }
    fn value(&self, x: &[f64], u: &[f64], _y: &[f64], d: &mut ExplicitDynamicsData, out: &mut [f64]) {
        self.forward(x, u, d);
        out.copy_from_slice(d.xnext());
    }
    fn derive(&self, x: &[f64], u: &[f64], _y: &[f64], d: &mut ExplicitDynamicsData) {
        self.forward(x, u, d);
        self.jacobians(x, u, d);
    }
    fn current<'d>(&self, d: &'d ExplicitDynamicsData) -> &'d [f64] {
        d.xnext()
    }
    fn first_order(&self, d: &ExplicitDynamicsData) -> Vec<Mat<f64>> {
        vec![d.jx.clone(), d.ju.clone()]
    }
    fn second_order(&self, x: &[f64], u: &[f64], w: &[f64], d: &mut ExplicitDynamicsData) -> [Mat<f64>; 3] {
        self.vhp(x, u, w, d);
        [d.vhp_xx.clone(), d.vhp_xu.clone(), d.vhp_uu.clone()]
    }
    /// Next states are compared through `⊖` (so `q` and `-q` are the same rotation).
    fn value_pair(&self, analytic: &[f64], reference: &[f64]) -> (Mat<f64>, Mat<f64>) {
        let sn = self.space_next();
        let mut gap = vec![0.0; sn.ndx()];
        sn.difference(reference, analytic, &mut gap);
        (column(&gap), Mat::zeros(gap.len(), 1))
    }
}

impl Checked for dyn ImplicitDynamics + '_ {
    type Data = ImplicitDynamicsData;
    const FIRST: [&'static str; 3] = ["jx", "ju", "jy"];
    fn create_data(&self) -> ImplicitDynamicsData {
        ImplicitDynamics::create_data(self)
    }
    fn value(&self, x: &[f64], u: &[f64], y: &[f64], d: &mut ImplicitDynamicsData, out: &mut [f64]) {
        self.evaluate(x, u, y, d);
        out.copy_from_slice(d.value());
    }
    fn derive(&self, x: &[f64], u: &[f64], y: &[f64], d: &mut ImplicitDynamicsData) {
        self.evaluate(x, u, y, d);
        self.jacobians(x, u, y, d);
    }
    fn current<'d>(&self, d: &'d ImplicitDynamicsData) -> &'d [f64] {
        d.value()
    }
    fn first_order(&self, d: &ImplicitDynamicsData) -> Vec<Mat<f64>> {
        vec![d.jx.clone(), d.ju.clone(), d.jy.clone()]
    }
}

impl Checked for dyn Ode + '_ {
    type Data = OdeData;
    const FIRST: [&'static str; 3] = ["jx", "ju", "jy"];
    fn create_data(&self) -> OdeData {
        Ode::create_data(self)
    }
    fn value(&self, x: &[f64], u: &[f64], _y: &[f64], d: &mut OdeData, out: &mut [f64]) {
        self.evaluate(x, u, d);
        out.copy_from_slice(d.xdot());
    }
    fn derive(&self, x: &[f64], u: &[f64], _y: &[f64], d: &mut OdeData) {
        self.evaluate(x, u, d);
        self.jacobians(x, u, d);
    }
    fn current<'d>(&self, d: &'d OdeData) -> &'d [f64] {
        d.xdot()
    }
    fn first_order(&self, d: &OdeData) -> Vec<Mat<f64>> {
        vec![d.jx.clone(), d.ju.clone()]
    }
}

/// Checks `jacobians` (and `vhp` when `lambda` is given and the function has one) of a
/// stage function at `(x, u)`, `x` on `space`.
pub fn check_stage_function(
    f: &dyn StageFunction,
    space: &dyn Manifold,
    x: &[f64],
    u: &[f64],
    lambda: Option<&[f64]>,
    opts: CheckOptions,
) -> CheckReport {
    let w = lambda.filter(|_| f.has_vhp());
    check_fd(f, Spaces::vector(space, f.nr()), x, u, &[], w, opts)
}

/// Checks the gradient and Hessian of a cost at `(x, u)`.
pub fn check_cost(c: &dyn Cost, space: &dyn Manifold, x: &[f64], u: &[f64], opts: CheckOptions) -> CheckReport {
    check_fd(c, Spaces::vector(space, 1), x, u, &[], Some(&[1.0]), opts)
}

/// Checks the Jacobians of explicit dynamics at `(x, u)`.
pub fn check_explicit_dynamics(d: &dyn ExplicitDynamics, x: &[f64], u: &[f64], opts: CheckOptions) -> CheckReport {
    let (space, values) = (d.space().as_ref(), d.space_next().clone());
    check_fd(
        d,
        Spaces {
            x: space,
            values,
            y: None,
        },
        x,
        u,
        &[],
        None,
        opts,
    )
}

/// Checks the Jacobians of implicit dynamics at `(x, u, y)`.
pub fn check_implicit_dynamics(
    d: &dyn ImplicitDynamics,
    x: &[f64],
    u: &[f64],
    y: &[f64],
    opts: CheckOptions,
) -> CheckReport {
    let (space, next) = (d.space().as_ref(), d.space_next().as_ref());
    let spaces = Spaces {
        y: Some(next),
        ..Spaces::vector(space, next.ndx())
    };
    check_fd(d, spaces, x, u, y, None, opts)
}

/// Checks the Jacobians of an ODE at `(x, u)`.
///
/// The velocity lives in the tangent space at `x`, so its `x`-derivative is only
/// meaningful on vector spaces or for ODEs whose velocity is expressed in a frame that
/// does not move with `x`; the check differentiates the coordinates as they are.
pub fn check_ode(ode: &dyn Ode, x: &[f64], u: &[f64], opts: CheckOptions) -> CheckReport {
    check_fd(
        ode,
        Spaces::vector(ode.space().as_ref(), ode.space().ndx()),
        x,
        u,
        &[],
        None,
        opts,
    )
}

/// The reference blocks `value`, `jx`, `ju` of dual-number Jacobians.
fn jacobian_blocks(r: DualJacobians) -> Blocks {
    Blocks {
        value: Some(r.value),
        first: vec![r.jx, r.ju],
        second: None,
    }
}

/// The reference second-order blocks of hyper-dual numbers.
fn hessian_blocks(h: DualHessians) -> Blocks {
    Blocks {
        second: Some([h.xx, h.xu, h.uu]),
        ..Blocks::default()
    }
}

/// Checks the value and Jacobians of a stage function at `(x, u)` against a reference
/// implementation differentiated with dual numbers.
pub fn check_stage_function_dual(
    f: &dyn StageFunction,
    space: &dyn Manifold,
    x: &[f64],
    u: &[f64],
    reference: impl FnMut(&[Dual64], &[Dual64], &mut [Dual64]),
    opts: DualCheckOptions,
) -> CheckReport {
    let r = || jacobian_blocks(dual_stage_jacobians(space, x, u, f.nr(), reference));
    check_dual(f, x, u, &[], None, r, opts)
}

/// Checks the vector-Hessian products of a stage function at `(x, u, λ)` against a
/// reference implementation differentiated with hyper-dual numbers (a model without
/// second-order terms is compared as zero).
pub fn check_stage_function_vhp_dual(
    f: &dyn StageFunction,
    space: &dyn Manifold,
    x: &[f64],
    u: &[f64],
    lambda: &[f64],
    reference: impl FnMut(&[HyperDual64], &[HyperDual64], &mut [HyperDual64]),
    opts: DualCheckOptions,
) -> CheckReport {
    let r = || hessian_blocks(hyper_stage_vhp(space, x, u, lambda, reference));
    check_dual(f, x, u, &[], Some(lambda), r, opts)
}

/// Checks the value, gradient and Hessian of a cost at `(x, u)` against a reference
/// implementation differentiated with hyper-dual numbers.
pub fn check_cost_dual(
    c: &dyn Cost,
    space: &dyn Manifold,
    x: &[f64],
    u: &[f64],
    reference: impl FnMut(&[HyperDual64], &[HyperDual64]) -> HyperDual64,
    opts: DualCheckOptions,
) -> CheckReport {
    let r = || {
        let r = hyper_cost_derivatives(space, x, u, reference);
        Blocks {
            value: Some(vec![r.value]),
            first: vec![row(&r.lx), row(&r.lu)],
            second: Some([r.lxx, r.lxu, r.luu]),
        }
    };
    check_dual(c, x, u, &[], Some(&[1.0]), r, opts)
}

/// Checks the next state and Jacobians of explicit dynamics at `(x, u)` against a
/// reference implementation differentiated with dual numbers. The next states are
/// compared through `⊖` (so `q` and `-q` are the same rotation).
pub fn check_explicit_dynamics_dual(
    d: &dyn ExplicitDynamics,
    x: &[f64],
    u: &[f64],
    reference: impl FnMut(&[Dual64], &[Dual64], &mut [Dual64]),
    opts: DualCheckOptions,
) -> CheckReport {
    let (s, sn) = (d.space().as_ref(), d.space_next().as_ref());
    let r = || jacobian_blocks(dual_explicit_dynamics_jacobians(s, sn, x, u, reference));
    check_dual(d, x, u, &[], None, r, opts)
}

/// Checks the vector-Hessian products of explicit dynamics at `(x, u, λ)` against a
/// reference implementation differentiated with hyper-dual numbers.
pub fn check_explicit_dynamics_vhp_dual(
    d: &dyn ExplicitDynamics,
    x: &[f64],
    u: &[f64],
    lambda: &[f64],
    reference: impl FnMut(&[HyperDual64], &[HyperDual64], &mut [HyperDual64]),
    opts: DualCheckOptions,
) -> CheckReport {
    let (s, sn) = (d.space().as_ref(), d.space_next().as_ref());
    let r = || hessian_blocks(hyper_explicit_dynamics_vhp(s, sn, x, u, lambda, reference));
    check_dual(d, x, u, &[], Some(lambda), r, opts)
}

/// Checks the residual and Jacobians of implicit dynamics at `(x, u, y)` against a
/// reference implementation differentiated with dual numbers.
pub fn check_implicit_dynamics_dual(
    d: &dyn ImplicitDynamics,
    x: &[f64],
    u: &[f64],
    y: &[f64],
    reference: impl FnMut(&[Dual64], &[Dual64], &[Dual64], &mut [Dual64]),
    opts: DualCheckOptions,
) -> CheckReport {
    let (s, sn) = (d.space().as_ref(), d.space_next().as_ref());
    let r = || {
        let (r, jy) = dual_implicit_dynamics_jacobians(s, sn, x, u, y, reference);
        let mut blocks = jacobian_blocks(r);
        blocks.first.push(jy);
        blocks
    };
    check_dual(d, x, u, y, None, r, opts)
}

/// Checks the velocity and Jacobians of an ODE at `(x, u)` against a reference
/// implementation differentiated with dual numbers (coordinates differentiated as they
/// are, like [`check_ode`]).
pub fn check_ode_dual(
    ode: &dyn Ode,
    x: &[f64],
    u: &[f64],
    reference: impl FnMut(&[Dual64], &[Dual64], &mut [Dual64]),
    opts: DualCheckOptions,
) -> CheckReport {
    let r = || jacobian_blocks(dual_ode_jacobians(ode.space().as_ref(), x, u, reference));
    check_dual(ode, x, u, &[], None, r, opts)
}

/// Tangent-convention Jacobian of a tangent-valued map `g` of `x ∈ m`, by dual numbers:
/// column `j` is `d/dε g(x ⊕ ε e_j)`, with `x ⊕ ε e_j` computed by the manifold's dual
/// `integrate`.
fn dual_state_jacobian(
    m: &dyn Manifold,
    x: &[f64],
    nout: usize,
    mut g: impl FnMut(&[Dual64], &mut [Dual64]),
) -> Mat<f64> {
    let ndx = m.ndx();
    let xd = duals(x);
    let mut v = vec![Dual64::new(0.0, 0.0); ndx];
    let mut xp = vec![Dual64::new(0.0, 0.0); m.nx()];
    let mut out = vec![Dual64::new(0.0, 0.0); nout];
    let mut jac = Mat::zeros(nout, ndx);
    for j in 0..ndx {
        v[j].eps = 1.0;
        m.integrate_dual(&xd, &v, &mut xp);
        v[j].eps = 0.0;
        g(&xp, &mut out);
        for i in 0..nout {
            jac[(i, j)] = out[i].eps;
        }
    }
    jac
}

/// Checks `jintegrate`, `jdifference`, `jintegrate_transport`, `tangent_map` and
/// `tangent_map_inverse` of a manifold at `x`, `v` and `x1` against dual-number
/// derivatives of its own `integrate_dual` and `difference_dual`.
pub fn check_manifold_dual(m: &dyn Manifold, x: &[f64], v: &[f64], x1: &[f64], opts: DualCheckOptions) -> CheckReport {
    let mut rep = CheckReport::new(opts.tol);
    let (nx, ndx) = (m.nx(), m.ndx());
    let tangent = crate::spaces::VectorSpace::new(ndx);
    let mut j = Mat::zeros(ndx, ndx);
    let mut y = vec![0.0; nx];
    m.integrate(x, v, &mut y);
    let (vd, yd, x1d) = (duals(v), duals(&y), duals(x1));
    let mut tmp = vec![Dual64::new(0.0, 0.0); nx];

    m.jintegrate(x, v, Arg::First, j.as_mut());
    let r = dual_state_jacobian(m, x, ndx, |xp, out| {
        m.integrate_dual(xp, &vd, &mut tmp);
        m.difference_dual(&yd, &tmp, out);
    });
    rep.push("jintegrate(x)", &j, &r);

    m.jintegrate(x, v, Arg::Second, j.as_mut());
    let xd = duals(x);
    let r = dual_state_jacobian(&tangent, v, ndx, |vp, out| {
        m.integrate_dual(&xd, vp, &mut tmp);
        m.difference_dual(&yd, &tmp, out);
    });
    rep.push("jintegrate(v)", &j, &r);

    for arg in [Arg::First, Arg::Second] {
        let mut t = Mat::from_fn(ndx, 3, |i, k| ((i + 2 * k) % 5) as f64 - 2.0);
        let t0 = t.clone();
        m.jintegrate_transport(x, v, arg, t.as_mut());
        m.jintegrate(x, v, arg, j.as_mut());
        let mut expect = Mat::zeros(ndx, 3);
        crate::linalg::matmul(expect.as_mut(), faer::Accum::Replace, j.as_ref(), t0.as_ref(), 1.0);
        rep.push(&format!("jintegrate_transport({arg:?})"), &t, &expect);
    }

    m.jdifference(x, x1, Arg::First, j.as_mut());
    let r = dual_state_jacobian(m, x, ndx, |xp, out| m.difference_dual(xp, &x1d, out));
    rep.push("jdifference(x0)", &j, &r);
    m.jdifference(x, x1, Arg::Second, j.as_mut());
    let r = dual_state_jacobian(m, x1, ndx, |xp, out| m.difference_dual(&xd, xp, out));
    rep.push("jdifference(x1)", &j, &r);

    let mut tm = Mat::zeros(nx, ndx);
    m.tangent_map(x, tm.as_mut());
    let r = dual_state_jacobian(m, x, nx, |xp, out| out.copy_from_slice(xp));
    rep.push("tangent_map", &tm, &r);

    let mut tmi = Mat::zeros(ndx, nx);
    m.tangent_map_inverse(x, tmi.as_mut());
    let rep_space = crate::spaces::VectorSpace::new(nx);
    let r = dual_state_jacobian(&rep_space, x, ndx, |z, out| m.difference_dual(&xd, z, out));
    rep.push("tangent_map_inverse", &tmi, &r);
    rep
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spaces::VectorSpace;

    /// The structure check of `Manifold::nonlinear_dim` on finite-difference Jacobians of
    /// SE(3) x R^2: its true block (6) passes, a smaller claim fails, and the product
    /// claims 6.
    #[test]
    fn a_false_nonlinear_block_claim_fails() {
        use crate::spaces::{CartesianProduct, SE3};
        use std::sync::Arc;
        let m = CartesianProduct::pair(Arc::new(SE3), Arc::new(VectorSpace::new(2)));
        assert_eq!(m.nonlinear_dim(), 6);
        let mut rng = <rand::rngs::SmallRng as rand::SeedableRng>::seed_from_u64(3);
        let (mut x, mut x1) = (vec![0.0; m.nx()], vec![0.0; m.nx()]);
        m.random(&mut rng, &mut x);
        m.random(&mut rng, &mut x1);
        let tangent = VectorSpace::new(m.ndx());
        let fd = fd_state(&m, x1.as_slice(), &tangent, 1e-6, |xp, out| m.difference(&x, xp, out));
        for (k, ok) in [(6, true), (8, true), (3, false), (0, false)] {
            let mut rep = CheckReport::new(1e-6);
            rep.push_structure("jdifference(x1)", k, 1.0, &fd);
            assert_eq!(rep.passed(), ok, "claim {k}: {:?}", rep.errors);
        }
        check_manifold(&m, &x, &[0.1; 8], &x1, CheckOptions::default()).assert_ok();
    }

    #[test]
    fn vector_space_passes_and_a_wrong_jacobian_fails() {
        let m = VectorSpace::new(3);
        let x = [0.1, -0.2, 0.3];
        let v = [1.0, 2.0, -1.0];
        let x1 = [0.5, 0.5, 0.5];
        check_manifold(&m, &x, &v, &x1, CheckOptions::default()).assert_ok();

        #[derive(Debug)]
        struct Wrong(VectorSpace);
        impl Manifold for Wrong {
            fn nx(&self) -> usize {
                self.0.nx()
            }
            fn ndx(&self) -> usize {
                self.0.ndx()
            }
            fn neutral(&self, out: &mut [f64]) {
                self.0.neutral(out)
            }
            fn random(&self, rng: &mut dyn rand::RngCore, out: &mut [f64]) {
                self.0.random(rng, out)
            }
            fn integrate(&self, x: &[f64], v: &[f64], out: &mut [f64]) {
                self.0.integrate(x, v, out)
            }
            fn difference(&self, x0: &[f64], x1: &[f64], out: &mut [f64]) {
                self.0.difference(x0, x1, out)
            }
            fn integrate_dual(&self, x: &[Dual64], v: &[Dual64], out: &mut [Dual64]) {
                self.0.integrate_dual(x, v, out)
            }
            fn difference_dual(&self, x0: &[Dual64], x1: &[Dual64], out: &mut [Dual64]) {
                self.0.difference_dual(x0, x1, out)
            }
            fn integrate_hyper(&self, x: &[HyperDual64], v: &[HyperDual64], out: &mut [HyperDual64]) {
                self.0.integrate_hyper(x, v, out)
            }
            fn difference_hyper(&self, x0: &[HyperDual64], x1: &[HyperDual64], out: &mut [HyperDual64]) {
                self.0.difference_hyper(x0, x1, out)
            }
            fn interpolate(&self, x0: &[f64], x1: &[f64], t: f64, out: &mut [f64]) {
                self.0.interpolate(x0, x1, t, out)
            }
            fn jintegrate(&self, x: &[f64], v: &[f64], arg: Arg, mut j: faer::MatMut<'_, f64>) {
                self.0.jintegrate(x, v, arg, j.rb_mut());
                j[(0, 1)] = 0.5;
            }
            fn jdifference(&self, x0: &[f64], x1: &[f64], arg: Arg, j: faer::MatMut<'_, f64>) {
                self.0.jdifference(x0, x1, arg, j)
            }
            fn jintegrate_transport(&self, x: &[f64], v: &[f64], arg: Arg, m: faer::MatMut<'_, f64>) {
                self.0.jintegrate_transport(x, v, arg, m)
            }
            fn tangent_map(&self, x: &[f64], j: faer::MatMut<'_, f64>) {
                self.0.tangent_map(x, j)
            }
            fn tangent_map_inverse(&self, x: &[f64], j: faer::MatMut<'_, f64>) {
                self.0.tangent_map_inverse(x, j)
            }
        }
        use faer::reborrow::ReborrowMut;
        let rep = check_manifold(&Wrong(m), &x, &v, &x1, CheckOptions::default());
        assert!(!rep.passed());
        assert!((rep.errors[0].1 - 0.5).abs() < 1e-6, "{:?}", rep.errors);
    }

    /// `f(x, u, y) = (y ⊖ x) - dt u` on SO(3): an implicit Euler step of `ẋ = u` written
    /// by hand with the group Jacobians; `bump` spoils `jy`.
    struct ImplicitStep {
        space: std::sync::Arc<dyn Manifold>,
        dt: f64,
        bump: f64,
    }

    impl ImplicitDynamics for ImplicitStep {
        fn space(&self) -> &std::sync::Arc<dyn Manifold> {
            &self.space
        }
        fn nu(&self) -> usize {
            3
        }
        fn evaluate(&self, x: &[f64], u: &[f64], y: &[f64], data: &mut crate::dynamics::ImplicitDynamicsData) {
            let v = data.value_mut();
            self.space.difference(x, y, v);
            for i in 0..3 {
                v[i] -= self.dt * u[i];
            }
        }
        fn jacobians(&self, x: &[f64], _u: &[f64], y: &[f64], data: &mut crate::dynamics::ImplicitDynamicsData) {
            self.space.jdifference(x, y, Arg::First, data.jx.as_mut());
            self.space.jdifference(x, y, Arg::Second, data.jy.as_mut());
            data.jy[(2, 0)] += self.bump;
            data.ju.fill(0.0);
            for i in 0..3 {
                data.ju[(i, i)] = -self.dt;
            }
        }
    }

    #[test]
    fn implicit_dynamics_dual_check() {
        use crate::spaces::SO3;
        let space: std::sync::Arc<dyn Manifold> = std::sync::Arc::new(SO3);
        let x = SO3::exp(&[0.2, -0.4, 1.0]);
        let y = SO3::exp(&[0.5, 0.1, 0.9]);
        let u = [0.3, 0.2, -0.1];
        let dt = 0.05;
        let reference = |x: &[Dual64], u: &[Dual64], y: &[Dual64], out: &mut [Dual64]| {
            SO3.difference_dual(x, y, out);
            for i in 0..3 {
                out[i] -= u[i] * dt;
            }
        };
        let good = ImplicitStep {
            space: space.clone(),
            dt,
            bump: 0.0,
        };
        check_implicit_dynamics(&good, &x, &u, &y, CheckOptions::default()).assert_ok();
        let rep = check_implicit_dynamics_dual(&good, &x, &u, &y, reference, DualCheckOptions::default());
        rep.assert_ok();
        assert!(rep.max_error() < 1e-14, "{rep:?}");
        let bad = ImplicitStep { space, dt, bump: 1e-10 };
        let rep = check_implicit_dynamics_dual(&bad, &x, &u, &y, reference, DualCheckOptions::default());
        assert!(!rep.passed());
        assert_eq!(rep.errors.iter().filter(|(_, e)| *e > 1e-12).count(), 1);
        assert_eq!(rep.errors[3].0, "jy");
    }
}

//! Costs of a residual `r(x, u)` given by any [`StageFunction`]:
//! - [`QuadraticResidualCost`]: `ℓ = ½ rᵀ W r`;
//! - [`QuadraticStateCost`]: `ℓ = ½ (x ⊖ x_ref)ᵀ W (x ⊖ x_ref)` on any manifold;
//! - [`QuadraticControlCost`]: `ℓ = ½ (u - u_ref)ᵀ W (u - u_ref)`;
//! - [`LogBarrierCost`]: a relaxed logarithmic barrier keeping `r(x, u) < 0`.
//!
//! All are `ℓ = φ(r(x, u))` with derivatives by the chain rule, `J = [r_x r_u]`:
//! ```text
//! ∇ℓ  = Jᵀ g,                    g = φ'(r)
//! ∇²ℓ = Jᵀ H J + Σ_i g_i ∇²r_i,  H = φ''(r)
//! ```
//! The first Hessian term is the Gauss-Newton approximation; the second (exact) term is
//! added when the cost is built with `exact_hessian(true)` and the function provides
//! vector-Hessian products ([`StageFunction::has_vhp`]); it is `vhp(g)`. Without it the
//! Hessian is exact only for affine residuals.

use std::sync::Arc;

use faer::reborrow::ReborrowMut;
use faer::{Accum, Mat, MatRef};

use super::{Cost, CostData, CostParts, DerivativesMut};
use crate::error::{check_dim, check_finite};
use crate::functions::util::{add_scaled, checked_sym, downcast};
use crate::functions::{ControlError, StageFunction, StageFunctionData, StateError, Unary, Workspace};
use crate::linalg::{GramScratch, GramWeight, add_scaled_lower, fill_lower, matmul, scale_rows, symmetrize_from_lower};
use crate::param::ParamVec;
use crate::spaces::Manifold;
use crate::{Error, Result};

/// The weight `W` of a quadratic residual cost: diagonal or a full symmetric matrix.
#[derive(Debug, Clone)]
enum Metric {
    Diagonal(Vec<f64>),
    Full(Mat<f64>),
}

impl Metric {
    fn diagonal(what: &str, w: &[f64], nr: usize) -> Result<Self> {
        check_dim(what, nr, w.len())?;
        check_finite(what, w)?;
        Ok(Metric::Diagonal(w.to_vec()))
    }

    fn full(what: &str, w: MatRef<'_, f64>, nr: usize) -> Result<Self> {
        Ok(Metric::Full(checked_sym(what, w, nr)?))
    }

    /// `out = W r`.
    fn apply(&self, r: &[f64], out: &mut [f64]) {
        match self {
            Metric::Diagonal(w) => {
                for i in 0..r.len() {
                    out[i] = w[i] * r[i];
                }
            }
            Metric::Full(w) => crate::linalg::matvec(out, Accum::Replace, w.as_ref(), r, 1.0),
        }
    }
}

/// Scratch memory of the residual costs.
struct ResidualWs {
    fd: StageFunctionData,
    /// `g = φ'(r)` (`nr`).
    g: Vec<f64>,
    /// The scaled curvature `s φ''(r)` when diagonal (`nr`).
    h: Vec<f64>,
    /// `W r_x` (`nr x ndx`), for a full `W`.
    hjx: Mat<f64>,
    /// `H r_u` (`nr x nu`).
    hju: Mat<f64>,
    /// `r_x` and `r_u` read for their products.
    gram_x: GramScratch,
    gram_u: GramScratch,
}

impl ResidualWs {
    fn new(f: &dyn StageFunction) -> Self {
        let (nr, ndx, nu) = (f.nr(), f.ndx(), f.nu());
        Self {
            fd: f.create_data(),
            g: vec![0.0; nr],
            h: vec![0.0; nr],
            hjx: Mat::zeros(nr, ndx),
            hju: Mat::zeros(nr, nu),
            gram_x: GramScratch::new(nr, ndx),
            gram_u: GramScratch::new(nr, nu),
        }
    }
}

/// The Gauss-Newton curvature `H = φ''(r)` of a residual cost, times the scale `s` of
/// [`Cost::add_derivatives`].
enum Curvature<'a> {
    /// Diagonal: `s H` is in the workspace's `h`.
    Diagonal,
    /// The full weight `W` and the scale `s`.
    Full(&'a Mat<f64>, f64),
}

/// Adds `s Jᵀ g` to the gradient and, if asked, `s Jᵀ H J` and, if `exact`, `s vhp(g)`
/// to the lower Hessian blocks, with `g` and `J` in `ws` (`J` new since the last call if
/// `fresh`): the chain rule of every residual cost (module documentation). The products
/// of a zero Jacobian block (a residual of the state only, or of the control only) are
/// skipped.
fn add_chain_rule(
    f: &dyn StageFunction,
    (x, u): (&[f64], &[f64]),
    (exact, fresh): (bool, bool),
    ws: &mut ResidualWs,
    h: Curvature<'_>,
    s: f64,
    out: DerivativesMut<'_>,
) {
    let ResidualWs {
        fd,
        g,
        h: hd,
        hjx,
        hju,
        gram_x,
        gram_u,
    } = ws;
    let (jx, ju) = (fd.jx.as_ref(), fd.ju.as_ref());
    if fresh {
        gram_x.load(jx);
        gram_u.load(ju);
    }
    gram_x.matvec_t_add(out.lx, jx, g, s);
    gram_u.matvec_t_add(out.lu, ju, g, s);
    let Some(mut out) = out.hessian else {
        return;
    };
    let (x_zero, u_zero) = (gram_x.is_zero(), gram_u.is_zero());
    let (wx, wu, alpha) = match h {
        Curvature::Diagonal => {
            if !(x_zero || u_zero) {
                scale_rows(hju.as_mut(), hd, ju);
            }
            (GramWeight::Diagonal(hd), GramWeight::Diagonal(hd), 1.0)
        }
        Curvature::Full(w, s) => {
            if !x_zero {
                matmul(hjx.as_mut(), Accum::Replace, w.as_ref(), jx, 1.0);
            }
            if !u_zero {
                matmul(hju.as_mut(), Accum::Replace, w.as_ref(), ju, 1.0);
            }
            (
                GramWeight::Product(hjx.as_ref(), s),
                GramWeight::Product(hju.as_ref(), s),
                s,
            )
        }
    };
    if !x_zero {
        gram_x.gram_lower_add(out.lxx.rb_mut(), jx, wx);
    }
    if !u_zero {
        gram_u.gram_lower_add(out.luu.rb_mut(), ju, wu);
        if !x_zero {
            matmul(out.lxu.rb_mut(), Accum::Add, jx.transpose(), hju.as_ref(), alpha);
        }
    }
    if exact && f.has_vhp() {
        f.vhp(x, u, g, fd);
        add_scaled_lower(out.lxx, s, fd.vhp_xx.as_ref());
        add_scaled(out.lxu, s, fd.vhp_xu.as_ref());
        add_scaled_lower(out.luu, s, fd.vhp_uu.as_ref());
    }
}

/// Writes the derivatives of a residual cost into `data`'s own blocks by its
/// `add_derivatives` (`add`, scale 1), the Hessian too if `hessian`, and mirrors the
/// symmetric blocks.
fn write_own(data: &mut CostData, hessian: bool, add: impl FnOnce(&mut ResidualWs, DerivativesMut<'_>)) {
    let CostParts {
        lx,
        lu,
        hessian: mut h,
        ws,
    } = data.parts();
    lx.fill(0.0);
    lu.fill(0.0);
    if hessian {
        fill_lower(h.lxx.rb_mut(), 0.0);
        h.lxu.fill(0.0);
        fill_lower(h.luu.rb_mut(), 0.0);
    }
    let out = DerivativesMut {
        lx: &mut *lx,
        lu: &mut *lu,
        hessian: hessian.then(|| h.rb_mut()),
    };
    add(downcast(ws), out);
    if hessian {
        symmetrize_from_lower(h.lxx);
        symmetrize_from_lower(h.luu);
    }
}

/// `ℓ(x, u) = ½ r(x, u)ᵀ W r(x, u)` for any stage function `r`.
///
/// Gradient `Jᵀ W r`; Hessian `Jᵀ W J`, plus `Σ_i (W r)_i ∇²r_i` with
/// [`QuadraticResidualCost::exact_hessian`]. `W` is replaced by its symmetric part.
#[derive(Clone)]
pub struct QuadraticResidualCost {
    f: Arc<dyn StageFunction>,
    w: Metric,
    exact: bool,
}

impl std::fmt::Debug for QuadraticResidualCost {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("QuadraticResidualCost")
            .field("w", &self.w)
            .field("exact_hessian", &self.exact)
            .finish_non_exhaustive()
    }
}

impl QuadraticResidualCost {
    /// `½ rᵀ W r` with a full weight matrix `W` (`nr x nr`).
    ///
    /// # Errors
    /// If `W` is not `nr x nr` or has a non-finite entry.
    pub fn new(f: Arc<dyn StageFunction>, w: MatRef<'_, f64>) -> Result<Self> {
        let w = Metric::full("QuadraticResidualCost W", w, f.nr())?;
        Ok(Self { f, w, exact: false })
    }

    /// `½ Σ_i w_i r_i²` with diagonal weights `w` (`nr`).
    ///
    /// # Errors
    /// If `w` does not have `nr` entries or has a non-finite entry.
    pub fn diagonal(f: Arc<dyn StageFunction>, w: &[f64]) -> Result<Self> {
        let w = Metric::diagonal("QuadraticResidualCost weights w", w, f.nr())?;
        Ok(Self { f, w, exact: false })
    }

    /// Whether to add the second-order term `Σ (W r)_i ∇²r_i` (when the function has
    /// vector-Hessian products). Default: off (Gauss-Newton).
    pub fn exact_hessian(mut self, on: bool) -> Self {
        self.exact = on;
        self
    }

    /// The residual function.
    pub fn function(&self) -> &Arc<dyn StageFunction> {
        &self.f
    }
}

impl QuadraticResidualCost {
    /// [`Cost::add_derivatives`] with the workspace apart.
    fn add(&self, x: &[f64], u: &[f64], ws: &mut ResidualWs, reuse: bool, s: f64, out: DerivativesMut<'_>) {
        // With a constant Hessian and `reuse`, `J` is the one of the first call and
        // `g = W r` is from `evaluate`.
        let fresh = !(reuse && self.hessian_is_constant());
        if fresh {
            self.f.jacobians(x, u, &mut ws.fd);
            self.w.apply(ws.fd.value(), &mut ws.g);
        }
        let h = match &self.w {
            Metric::Diagonal(w) => {
                for (hi, wi) in ws.h.iter_mut().zip(w) {
                    *hi = s * wi;
                }
                Curvature::Diagonal
            }
            Metric::Full(w) => Curvature::Full(w, s),
        };
        add_chain_rule(self.f.as_ref(), (x, u), (self.exact, fresh), ws, h, s, out);
    }
}

impl Cost for QuadraticResidualCost {
    fn nx(&self) -> usize {
        self.f.nx()
    }
    fn ndx(&self) -> usize {
        self.f.ndx()
    }
    fn nu(&self) -> usize {
        self.f.nu()
    }
    fn create_workspace(&self) -> Workspace {
        Box::new(ResidualWs::new(self.f.as_ref()))
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        let ws: &mut ResidualWs = downcast(&mut data.ws);
        self.f.evaluate(x, u, &mut ws.fd);
        self.w.apply(ws.fd.value(), &mut ws.g);
        data.value = 0.5 * ws.fd.value().iter().zip(&ws.g).map(|(r, g)| r * g).sum::<f64>();
    }
    fn derivatives(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        write_own(data, true, |ws, out| self.add(x, u, ws, false, 1.0, out));
    }
    /// `Jᵀ W J` is constant when the Jacobians are (`W` is fixed at construction) and
    /// no second-order term `vhp(W r)` is added.
    fn hessian_is_constant(&self) -> bool {
        self.f.jacobians_are_constant() && !(self.exact && self.f.has_vhp())
    }
    fn gradient(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        if !self.hessian_is_constant() {
            return self.derivatives(x, u, data);
        }
        write_own(data, false, |ws, out| self.add(x, u, ws, true, 1.0, out));
    }
    fn add_derivatives(&self, x: &[f64], u: &[f64], data: &mut CostData, reuse: bool, s: f64, out: DerivativesMut<'_>) {
        self.add(x, u, downcast(&mut data.ws), reuse, s, out);
    }
}

/// `ℓ(x, u) = ½ (x ⊖ x_ref)ᵀ W (x ⊖ x_ref)` on any manifold, with a movable target.
///
/// A [`QuadraticResidualCost`] of [`StateError`]: the gradient `Jᵀ W (x ⊖ x_ref)` is
/// exact; the Hessian `Jᵀ W J` (`J = jdifference(x_ref, x)`) is exact on vector spaces
/// and at `x = x_ref`, and the Gauss-Newton approximation elsewhere on Lie groups. With
/// `nu = 0` it is a terminal cost.
#[derive(Debug, Clone)]
pub struct QuadraticStateCost {
    error: Arc<StateError>,
    inner: QuadraticResidualCost,
}

impl QuadraticStateCost {
    /// With a full weight matrix `W` (`ndx x ndx`), for `nu` controls.
    ///
    /// # Errors
    /// If `x_ref` is not a valid point of `space`, or `W` has the wrong shape or a
    /// non-finite entry.
    pub fn new(space: Arc<dyn Manifold>, x_ref: &[f64], w: MatRef<'_, f64>, nu: usize) -> Result<Self> {
        let error = Arc::new(StateError::new(space, x_ref)?);
        let f = Arc::new(Unary::new(error.clone(), nu));
        let w = Metric::full("QuadraticStateCost W", w, f.nr())?;
        Ok(Self {
            error,
            inner: QuadraticResidualCost { f, w, exact: false },
        })
    }

    /// With diagonal weights `w` (`ndx`), for `nu` controls.
    ///
    /// # Errors
    /// As [`QuadraticStateCost::new`].
    pub fn diagonal(space: Arc<dyn Manifold>, x_ref: &[f64], w: &[f64], nu: usize) -> Result<Self> {
        let error = Arc::new(StateError::new(space, x_ref)?);
        let f = Arc::new(Unary::new(error.clone(), nu));
        let w = Metric::diagonal("QuadraticStateCost weights w", w, f.nr())?;
        Ok(Self {
            error,
            inner: QuadraticResidualCost { f, w, exact: false },
        })
    }

    /// Moves the target (see [`StateError::set_target`]).
    ///
    /// # Errors
    /// If `x_ref` is not a valid point of the space.
    pub fn set_target(&self, x_ref: &[f64]) -> Result<()> {
        self.error.set_target(x_ref)
    }

    /// The state error inside the cost.
    pub fn error(&self) -> &Arc<StateError> {
        &self.error
    }

    /// [`Cost::add_derivatives`] with the workspace apart. On a Lie group times vector
    /// spaces `J = jdifference(x_ref, x) = diag(J_b, I)` with `J_b` of size `k × k`
    /// ([`Manifold::nonlinear_dim`]): with diagonal weights the chain rule is then the
    /// product `J_bᵀ W_b J_b` (the Gram kernels on the block) and the weights themselves
    /// on the rest of the diagonal, where the general path scans and multiplies all of
    /// `J` (and of the zero control Jacobian).
    fn add(&self, x: &[f64], u: &[f64], ws: &mut ResidualWs, reuse: bool, s: f64, out: DerivativesMut<'_>) {
        let Metric::Diagonal(w) = &self.inner.w else {
            return self.inner.add(x, u, ws, reuse, s, out);
        };
        // A constant Hessian (vector spaces) is the general path's: its reuse reads the
        // Jacobian that path loaded.
        let k = self.error.space().nonlinear_dim();
        if self.inner.hessian_is_constant() || 2 * k > w.len() {
            return self.inner.add(x, u, ws, reuse, s, out);
        }
        self.error.jacobian_block(x, &mut ws.fd);
        self.inner.w.apply(ws.fd.value(), &mut ws.g);
        // The Gram kernels on the block (the general path's operations on its rows, so
        // the same bits); the identity rows add `s w_i r_i` and `s w_i`.
        let ResidualWs {
            fd, g, h: hd, gram_x, ..
        } = ws;
        let (n, jb) = (w.len(), fd.jx.as_ref().submatrix(0, 0, k, k));
        gram_x.load(jb);
        gram_x.matvec_t_add(&mut out.lx[..k], jb, &g[..k], s);
        for i in k..n {
            out.lx[i] += s * g[i];
        }
        let Some(mut h) = out.hessian else {
            return;
        };
        for (hi, wi) in hd.iter_mut().zip(w) {
            *hi = s * wi;
        }
        let block = h.lxx.rb_mut().submatrix_mut(0, 0, k, k);
        gram_x.gram_lower_add(block, jb, GramWeight::Diagonal(&hd[..k]));
        for i in k..n {
            if hd[i] != 0.0 {
                h.lxx[(i, i)] += hd[i];
            }
        }
    }
}

/// `ℓ(x, u) = ½ (u - u_ref)ᵀ W (u - u_ref)`, with a movable target; exact Hessian `W`.
#[derive(Debug, Clone)]
pub struct QuadraticControlCost {
    error: Arc<ControlError>,
    inner: QuadraticResidualCost,
}

impl QuadraticControlCost {
    /// With a full weight matrix `W` (`nu x nu`, `nu = u_ref.len()`).
    ///
    /// # Errors
    /// If `u_ref` is not finite or `W` has the wrong shape or a non-finite entry.
    pub fn new(space: &dyn Manifold, u_ref: &[f64], w: MatRef<'_, f64>) -> Result<Self> {
        let error = Arc::new(ControlError::new(space, u_ref)?);
        let w = Metric::full("QuadraticControlCost W", w, u_ref.len())?;
        Ok(Self {
            inner: QuadraticResidualCost {
                f: error.clone(),
                w,
                exact: false,
            },
            error,
        })
    }

    /// With diagonal weights `w` (`nu`).
    ///
    /// # Errors
    /// As [`QuadraticControlCost::new`].
    pub fn diagonal(space: &dyn Manifold, u_ref: &[f64], w: &[f64]) -> Result<Self> {
        let error = Arc::new(ControlError::new(space, u_ref)?);
        let w = Metric::diagonal("QuadraticControlCost weights w", w, u_ref.len())?;
        Ok(Self {
            inner: QuadraticResidualCost {
                f: error.clone(),
                w,
                exact: false,
            },
            error,
        })
    }

    /// Moves the target (see [`ControlError::set_target`]).
    ///
    /// # Errors
    /// If `u_ref` has the wrong size or is not finite.
    pub fn set_target(&self, u_ref: &[f64]) -> Result<()> {
        self.error.set_target(u_ref)
    }
}

impl QuadraticControlCost {
    /// [`Cost::add_derivatives`] with the workspace apart: the residual cost's.
    fn add(&self, x: &[f64], u: &[f64], ws: &mut ResidualWs, reuse: bool, s: f64, out: DerivativesMut<'_>) {
        self.inner.add(x, u, ws, reuse, s, out);
    }
}

/// [`Cost`] for a wrapper of a [`QuadraticResidualCost`] (`inner`, its sizes, workspace,
/// value and Hessian constancy) whose derivatives come from its own `add`.
macro_rules! residual_wrapper_cost {
    ($t:ty) => {
        impl Cost for $t {
            fn nx(&self) -> usize {
                self.inner.nx()
            }
            fn ndx(&self) -> usize {
                self.inner.ndx()
            }
            fn nu(&self) -> usize {
                self.inner.nu()
            }
            fn create_workspace(&self) -> Workspace {
                self.inner.create_workspace()
            }
            fn evaluate(&self, x: &[f64], u: &[f64], data: &mut CostData) {
                self.inner.evaluate(x, u, data)
            }
            fn derivatives(&self, x: &[f64], u: &[f64], data: &mut CostData) {
                write_own(data, true, |ws, out| self.add(x, u, ws, false, 1.0, out));
            }
            fn hessian_is_constant(&self) -> bool {
                self.inner.hessian_is_constant()
            }
            fn gradient(&self, x: &[f64], u: &[f64], data: &mut CostData) {
                if !self.hessian_is_constant() {
                    return self.derivatives(x, u, data);
                }
                write_own(data, false, |ws, out| self.add(x, u, ws, true, 1.0, out));
            }
            fn add_derivatives(
                &self,
                x: &[f64],
                u: &[f64],
                data: &mut CostData,
                reuse: bool,
                s: f64,
                out: DerivativesMut<'_>,
            ) {
                self.add(x, u, downcast(&mut data.ws), reuse, s, out);
            }
        }
    };
}
residual_wrapper_cost!(QuadraticStateCost);
residual_wrapper_cost!(QuadraticControlCost);

/// A relaxed logarithmic barrier for `r(x, u) < 0`:
/// ```text
/// ℓ(x, u) = w Σ_i β(-r_i(x, u)),
/// β(z) = -ln z                               for z ≥ δ,
/// β(z) = ½ [((z - 2δ)/δ)² - 1] - ln δ         for z < δ,
/// ```
/// `β` is the log barrier inside `{r ≤ -δ}` and its second-order Taylor expansion at
/// `z = δ` beyond; it is twice continuously differentiable, finite and convex
/// everywhere (`β'' = 1/z²` inside, `1/δ²` beyond), so infeasible points give finite
/// values and a useful descent direction instead of NaN. Take `δ` small (e.g. `1e-3` times the
/// scale of `r`) to approach the exact barrier.
///
/// Gradient `Jᵀ g` with `g_i = -w β'(-r_i)`, Hessian `Jᵀ diag(w β''(-r_i)) J`, plus
/// `Σ g_i ∇²r_i` with [`LogBarrierCost::exact_hessian`].
#[derive(Clone)]
pub struct LogBarrierCost {
    f: Arc<dyn StageFunction>,
    weight: ParamVec,
    delta: f64,
    exact: bool,
}

impl std::fmt::Debug for LogBarrierCost {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LogBarrierCost")
            .field("weight", &self.weight.get(0))
            .field("delta", &self.delta)
            .field("exact_hessian", &self.exact)
            .finish_non_exhaustive()
    }
}

/// `(β(z), β'(z), β''(z))` of the relaxed barrier.
fn relaxed_log(z: f64, delta: f64) -> (f64, f64, f64) {
    if z >= delta {
        (-z.ln(), -1.0 / z, 1.0 / (z * z))
    } else {
        let t = (z - 2.0 * delta) / delta;
        (0.5 * (t * t - 1.0) - delta.ln(), t / delta, 1.0 / (delta * delta))
    }
}

fn check_barrier_weight(w: f64) -> Result<()> {
    if !(w.is_finite() && w >= 0.0) {
        return Err(Error::option(
            "LogBarrierCost weight",
            format!("must be finite and >= 0, got {}", crate::error::Num(w)),
        ));
    }
    Ok(())
}

impl LogBarrierCost {
    /// `w Σ β(-r_i)` with relaxation threshold `delta`.
    ///
    /// # Errors
    /// If `weight` is negative or not finite, or `delta` is not positive and finite.
    pub fn new(f: Arc<dyn StageFunction>, weight: f64, delta: f64) -> Result<Self> {
        check_barrier_weight(weight)?;
        if !(delta.is_finite() && delta > 0.0) {
            return Err(Error::option(
                "LogBarrierCost delta",
                format!("must be finite and > 0, got {}", crate::error::Num(delta)),
            ));
        }
        Ok(Self {
            f,
            weight: ParamVec::new(&[weight]),
            delta,
            exact: false,
        })
    }

    /// Whether to add `Σ g_i ∇²r_i` (when the function has vector-Hessian products).
    pub fn exact_hessian(mut self, on: bool) -> Self {
        self.exact = on;
        self
    }

    /// Changes the barrier weight through `&self` (e.g. to decrease it between solves).
    ///
    /// # Errors
    /// If `w` is negative or not finite.
    pub fn set_weight(&self, w: f64) -> Result<()> {
        check_barrier_weight(w)?;
        self.weight.set(0, w);
        Ok(())
    }

    /// The barrier weight.
    pub fn weight(&self) -> f64 {
        self.weight.get(0)
    }
}

impl Cost for LogBarrierCost {
    fn nx(&self) -> usize {
        self.f.nx()
    }
    fn ndx(&self) -> usize {
        self.f.ndx()
    }
    fn nu(&self) -> usize {
        self.f.nu()
    }
    fn create_workspace(&self) -> Workspace {
        Box::new(ResidualWs::new(self.f.as_ref()))
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        let ws: &mut ResidualWs = downcast(&mut data.ws);
        self.f.evaluate(x, u, &mut ws.fd);
        let w = self.weight.get(0);
        data.value = w * ws
            .fd
            .value()
            .iter()
            .map(|&r| relaxed_log(-r, self.delta).0)
            .sum::<f64>();
    }
    fn derivatives(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        write_own(data, true, |ws, out| self.add(x, u, ws, 1.0, out));
    }
    fn add_derivatives(
        &self,
        x: &[f64],
        u: &[f64],
        data: &mut CostData,
        _reuse: bool,
        s: f64,
        out: DerivativesMut<'_>,
    ) {
        self.add(x, u, downcast(&mut data.ws), s, out);
    }
}

impl LogBarrierCost {
    /// [`Cost::add_derivatives`] with the workspace apart.
    fn add(&self, x: &[f64], u: &[f64], ws: &mut ResidualWs, s: f64, out: DerivativesMut<'_>) {
        self.f.jacobians(x, u, &mut ws.fd);
        let w = self.weight.get(0);
        for (i, &r) in ws.fd.value().iter().enumerate() {
            let (_, d1, d2) = relaxed_log(-r, self.delta);
            ws.g[i] = -w * d1;
            ws.h[i] = s * (w * d2);
        }
        add_chain_rule(
            self.f.as_ref(),
            (x, u),
            (self.exact, true),
            ws,
            Curvature::Diagonal,
            s,
            out,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{CheckOptions, check_cost};
    use crate::costs::HessianMut;
    use crate::functions::testing::{
        TestFunction, assert_close, dual_check_cost, dual_jacobian, random_mat, random_vec, rng, test_fn,
    };
    use crate::functions::{LinearComposition, LinearFunction};
    use crate::spaces::VectorSpace;
    use num_dual::DualNum;
    use rand::Rng;

    fn points(seed: u64, n: usize) -> Vec<(Vec<f64>, Vec<f64>)> {
        let mut g = rng(seed);
        (0..n)
            .map(|_| (random_vec(&mut g, 3, 1.0), random_vec(&mut g, 2, 1.0)))
            .collect()
    }

    fn weighted_ref<D: DualNum<Primitive = f64> + Copy>(z: &[D], w: &Mat<f64>) -> D {
        let r = test_fn(&z[..3], &z[3..]);
        let mut v = D::from(0.0);
        for i in 0..3 {
            for j in 0..3 {
                v += r[i] * r[j] * (0.5 * w[(i, j)]);
            }
        }
        v
    }

    /// `Jᵀ W J` from dual-number Jacobians of the test function.
    fn gauss_newton_ref(x: &[f64], u: &[f64], w: &Mat<f64>) -> Mat<f64> {
        let z: Vec<f64> = x.iter().chain(u).copied().collect();
        let j = dual_jacobian(&z, |zz| test_fn(&zz[..3], &zz[3..]));
        let ws = Mat::from_fn(3, 3, |a, b| 0.5 * (w[(a, b)] + w[(b, a)]));
        let wj = &ws * &j;
        j.transpose() * &wj
    }

    #[test]
    fn quadratic_residual_cost_gauss_newton_and_exact_hessians() {
        let mut g = rng(40);
        let w = random_mat(&mut g, 3, 3, 1.0);
        let f: Arc<dyn StageFunction> = Arc::new(TestFunction);
        let gn = QuadraticResidualCost::new(f.clone(), w.as_ref()).unwrap();
        let exact = QuadraticResidualCost::new(f.clone(), w.as_ref())
            .unwrap()
            .exact_hessian(true);
        let wd = [0.5, 2.0, 1.5];
        let diag = QuadraticResidualCost::diagonal(f.clone(), &wd)
            .unwrap()
            .exact_hessian(true);
        let wdm = Mat::from_fn(3, 3, |i, j| if i == j { wd[i] } else { 0.0 });
        let space = VectorSpace::new(3);
        for (x, u) in points(41, 5) {
            // Exact Hessians: finite differences of the gradient and hyper-dual numbers.
            check_cost(&exact, &space, &x, &u, CheckOptions::default()).assert_ok();
            check_cost(&diag, &space, &x, &u, CheckOptions::default()).assert_ok();
            dual_check_cost(&exact, &x, &u, |z| weighted_ref(z, &w), true, 1e-12);
            dual_check_cost(&diag, &x, &u, |z| weighted_ref(z, &wdm), true, 1e-12);
            // Gauss-Newton: exact gradient, Hessian Jᵀ W J.
            dual_check_cost(&gn, &x, &u, |z| weighted_ref(z, &w), false, 1e-12);
            let mut d = gn.create_data();
            gn.evaluate(&x, &u, &mut d);
            gn.derivatives(&x, &u, &mut d);
            let h = gauss_newton_ref(&x, &u, &w);
            assert_close("GN lxx", &d.lxx, &h.as_ref().submatrix(0, 0, 3, 3).to_owned(), 1e-12);
            assert_close("GN lxu", &d.lxu, &h.as_ref().submatrix(0, 3, 3, 2).to_owned(), 1e-12);
            assert_close("GN luu", &d.luu, &h.as_ref().submatrix(3, 3, 2, 2).to_owned(), 1e-12);
        }
        let err = QuadraticResidualCost::diagonal(f.clone(), &[1.0]).unwrap_err();
        assert!(err.to_string().contains("QuadraticResidualCost weights w"), "{err}");
        let err = QuadraticResidualCost::new(f, w.as_ref().submatrix(0, 0, 3, 2)).unwrap_err();
        assert!(err.to_string().contains("QuadraticResidualCost W columns"), "{err}");
    }

    /// `init + s M` on the lower triangle of a square `m`, `init` above it.
    fn lower_plus(init: &Mat<f64>, s: f64, m: &Mat<f64>) -> Mat<f64> {
        Mat::from_fn(init.nrows(), init.ncols(), |i, j| {
            if i >= j {
                init[(i, j)] + s * m[(i, j)]
            } else {
                init[(i, j)]
            }
        })
    }

    /// A Jacobian of the shape of a residual family: dense, sparse by rows (an identity
    /// with a dense leading block, like a state error on a Lie group), or zero.
    fn jacobian(g: &mut rand::rngs::SmallRng, nr: usize, n: usize, kind: usize) -> Mat<f64> {
        let m = random_mat(g, nr, n, 1.0);
        match kind {
            0 => m,
            1 => Mat::from_fn(nr, n, |r, c| if r == c || (r < 3 && c < 3) { m[(r, c)] } else { 0.0 }),
            _ => Mat::zeros(nr, n),
        }
    }

    /// `add_derivatives` adds `s Jᵀ W r`, the lower triangles of `s Jᵀ W J` and all of
    /// `s J_xᵀ W J_u` to whatever the blocks hold, against the dense products, for dense
    /// (faer's product from a size on), row-sparse and zero Jacobian blocks, diagonal
    /// (with a zero entry) and full weights, with and without `reuse`; and the barrier
    /// adds `s` times the derivatives it writes on its own.
    #[test]
    fn add_derivatives_adds_the_scaled_products_to_the_blocks() {
        let mut g = rng(46);
        let shapes = [
            (12, 36, 12, 0, 0),
            (36, 36, 12, 1, 2),
            (3, 12, 6, 1, 2),
            (4, 5, 3, 2, 0),
            (12, 12, 12, 0, 1),
        ];
        for (nr, ndx, nu, kx, ku) in shapes {
            let (jx, ju) = (jacobian(&mut g, nr, ndx, kx), jacobian(&mut g, nr, nu, ku));
            let f: Arc<dyn StageFunction> =
                Arc::new(LinearFunction::new(jx.as_ref(), ju.as_ref(), &random_vec(&mut g, nr, 1.0)).unwrap());
            let wd: Vec<f64> = (0..nr).map(|i| if i == 1 { 0.0 } else { 0.5 + i as f64 }).collect();
            let a = random_mat(&mut g, nr, nr, 1.0);
            let wf = &a * a.transpose();
            let costs = [
                (
                    QuadraticResidualCost::diagonal(f.clone(), &wd).unwrap(),
                    Mat::from_fn(nr, nr, |i, j| if i == j { wd[i] } else { 0.0 }),
                ),
                (QuadraticResidualCost::new(f.clone(), wf.as_ref()).unwrap(), wf.clone()),
            ];
            for (cost, w) in &costs {
                let mut d = cost.create_data();
                for reuse in [false, true] {
                    let (x, u) = (random_vec(&mut g, ndx, 1.0), random_vec(&mut g, nu, 1.0));
                    let s = 0.3 + g.random::<f64>();
                    cost.evaluate(&x, &u, &mut d);
                    let mut fd = f.create_data();
                    f.evaluate(&x, &u, &mut fd);
                    let wr = w * Mat::from_fn(nr, 1, |i, _| fd.value()[i]);
                    let (init_x, init_u) = (random_mat(&mut g, ndx, 1, 1.0), random_mat(&mut g, nu, 1, 1.0));
                    let (hxx, hxu, huu) = (
                        random_mat(&mut g, ndx, ndx, 1.0),
                        random_mat(&mut g, ndx, nu, 1.0),
                        random_mat(&mut g, nu, nu, 1.0),
                    );
                    let (mut lx, mut lu) = (init_x.clone(), init_u.clone());
                    let (mut lxx, mut lxu, mut luu) = (hxx.clone(), hxu.clone(), huu.clone());
                    let out = DerivativesMut {
                        lx: crate::linalg::col_of_mut(&mut lx, 0),
                        lu: crate::linalg::col_of_mut(&mut lu, 0),
                        hessian: Some(HessianMut::of(&mut lxx, &mut lxu, &mut luu)),
                    };
                    cost.add_derivatives(&x, &u, &mut d, reuse, s, out);
                    let tol = 1e-12;
                    assert_close("lx", &lx, &(&init_x + s * (jx.transpose() * &wr)), tol);
                    assert_close("lu", &lu, &(&init_u + s * (ju.transpose() * &wr)), tol);
                    assert_close("lxx", &lxx, &lower_plus(&hxx, s, &(jx.transpose() * (w * &jx))), tol);
                    assert_close("lxu", &lxu, &(&hxu + s * (jx.transpose() * (w * &ju))), tol);
                    assert_close("luu", &luu, &lower_plus(&huu, s, &(ju.transpose() * (w * &ju))), tol);
                }
            }
            check_barrier_blocks(&f, &jx, (ndx, nu), &mut g);
        }
    }

    /// The log barrier on the residual `f` (Jacobian `jx` in `x`): `add_derivatives`
    /// adds `s` times the blocks it writes itself, and its Hessian is
    /// `Jᵀ diag(w β''(-r)) J`.
    fn check_barrier_blocks(
        f: &Arc<dyn StageFunction>,
        jx: &Mat<f64>,
        (ndx, nu): (usize, usize),
        g: &mut rand::rngs::SmallRng,
    ) {
        let nr = f.nr();
        // The barrier on the same residual: `s` times the blocks it writes itself.
        let barrier = LogBarrierCost::new(f.clone(), 0.7, 0.5).unwrap();
        let (x, u) = (random_vec(g, ndx, 1.0), random_vec(g, nu, 1.0));
        let (mut own, mut d) = (barrier.create_data(), barrier.create_data());
        barrier.evaluate(&x, &u, &mut own);
        barrier.derivatives(&x, &u, &mut own);
        barrier.evaluate(&x, &u, &mut d);
        let (mut lx, mut lu) = (Mat::zeros(ndx, 1), Mat::zeros(nu, 1));
        let (mut lxx, mut lxu, mut luu) = (Mat::zeros(ndx, ndx), Mat::zeros(ndx, nu), Mat::zeros(nu, nu));
        let out = DerivativesMut {
            lx: crate::linalg::col_of_mut(&mut lx, 0),
            lu: crate::linalg::col_of_mut(&mut lu, 0),
            hessian: Some(HessianMut::of(&mut lxx, &mut lxu, &mut luu)),
        };
        barrier.add_derivatives(&x, &u, &mut d, false, 2.5, out);
        let zero_upper = |m: &Mat<f64>| Mat::from_fn(m.nrows(), m.ncols(), |i, j| if i >= j { m[(i, j)] } else { 0.0 });
        assert_close("barrier lx", &lx, &(2.5 * own.lx.as_mat().to_owned()), 1e-12);
        assert_close("barrier lu", &lu, &(2.5 * own.lu.as_mat().to_owned()), 1e-12);
        assert_close("barrier lxx", &lxx, &(2.5 * zero_upper(&own.lxx)), 1e-12);
        assert_close("barrier lxu", &lxu, &(2.5 * &own.lxu), 1e-12);
        assert_close("barrier luu", &luu, &(2.5 * zero_upper(&own.luu)), 1e-12);
        // The barrier's Hessian itself: Jᵀ diag(w β''(-r)) J.
        let mut fd = f.create_data();
        f.evaluate(&x, &u, &mut fd);
        let h = Mat::from_fn(nr, nr, |i, j| {
            if i == j {
                0.7 * relaxed_log(-fd.value()[i], 0.5).2
            } else {
                0.0
            }
        });
        assert_close("barrier GN", &own.lxx, &(jx.transpose() * (&h * jx)), 1e-12);
    }

    fn state_ref<D: DualNum<Primitive = f64> + Copy>(z: &[D], x_ref: &[f64], w: &Mat<f64>) -> D {
        let n = x_ref.len();
        let mut v = D::from(0.0);
        for i in 0..n {
            for j in 0..n {
                v += (z[i] - x_ref[i]) * (z[j] - x_ref[j]) * (0.5 * w[(i, j)]);
            }
        }
        v
    }

    #[test]
    fn state_and_control_costs_on_vector_spaces() {
        let mut g = rng(42);
        let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(3));
        let x_ref = random_vec(&mut g, 3, 1.0);
        let w = random_mat(&mut g, 3, 3, 1.0);
        let c = QuadraticStateCost::new(space.clone(), &x_ref, w.as_ref(), 2).unwrap();
        let term = QuadraticStateCost::diagonal(space.clone(), &x_ref, &[1.0, 2.0, 3.0], 0).unwrap();
        let wd = Mat::from_fn(3, 3, |i, j| if i == j { (i + 1) as f64 } else { 0.0 });
        let u_ref = random_vec(&mut g, 2, 1.0);
        let wu = random_mat(&mut g, 2, 2, 1.0);
        let cu = QuadraticControlCost::new(space.as_ref(), &u_ref, wu.as_ref()).unwrap();
        let cud = QuadraticControlCost::diagonal(space.as_ref(), &u_ref, &[0.1, 0.2]).unwrap();
        let wud = Mat::from_fn(2, 2, |i, j| if i == j { 0.1 * (i + 1) as f64 } else { 0.0 });
        for (x, u) in points(43, 4) {
            check_cost(&c, space.as_ref(), &x, &u, CheckOptions::default()).assert_ok();
            check_cost(&cu, space.as_ref(), &x, &u, CheckOptions::default()).assert_ok();
            check_cost(&term, space.as_ref(), &x, &[], CheckOptions::default()).assert_ok();
            dual_check_cost(&c, &x, &u, |z| state_ref(z, &x_ref, &w), true, 1e-12);
            dual_check_cost(&term, &x, &[], |z| state_ref(z, &x_ref, &wd), true, 1e-12);
            dual_check_cost(&cu, &x, &u, |z| state_ref(&z[3..], &u_ref, &wu), true, 1e-12);
            dual_check_cost(&cud, &x, &u, |z| state_ref(&z[3..], &u_ref, &wud), true, 1e-12);
        }
        // Moving the targets through shared costs.
        let new_ref = random_vec(&mut g, 3, 1.0);
        c.set_target(&new_ref).unwrap();
        assert_eq!(c.error().target(), new_ref);
        let mut d = c.create_data();
        c.evaluate(&new_ref, &[0.0, 0.0], &mut d);
        assert_eq!(d.value, 0.0);
        cu.set_target(&[0.0, 0.0]).unwrap();
        let mut d = cu.create_data();
        cu.evaluate(&x_ref, &[0.0, 0.0], &mut d);
        assert_eq!(d.value, 0.0);
        assert!(c.set_target(&[0.0]).is_err());
        let err = QuadraticStateCost::diagonal(space.clone(), &x_ref, &[1.0], 0).unwrap_err();
        assert!(err.to_string().contains("QuadraticStateCost weights w"), "{err}");
        let err = QuadraticStateCost::new(space, &x_ref[..2], w.as_ref(), 0).unwrap_err();
        assert!(err.to_string().contains("StateError target x_ref"), "{err}");
    }

    fn barrier_ref<D: DualNum<Primitive = f64> + Copy>(z: &[D], shift: f64, w: f64, delta: f64) -> D {
        test_fn(&z[..3], &z[3..]).iter().fold(D::from(0.0), |acc, &r| {
            let s = -(r - shift);
            let b = if s.re() >= delta {
                -s.ln()
            } else {
                let t = (s - 2.0 * delta) / delta;
                (t * t - 1.0) * 0.5 - delta.ln()
            };
            acc + b * w
        })
    }

    #[test]
    fn relaxed_barrier_is_twice_continuously_differentiable() {
        let delta = 0.1;
        let (a, b) = (
            relaxed_log(delta * (1.0 + 1e-12), delta),
            relaxed_log(delta * (1.0 - 1e-12), delta),
        );
        assert!((a.0 - b.0).abs() < 1e-10 && (a.1 - b.1).abs() < 1e-9 && (a.2 - b.2).abs() < 1e-7);
        assert!((a.0 + delta.ln()).abs() < 1e-10);
        // Far outside the domain: finite, growing, convex.
        for z in [-1e6, -1.0, 0.0, 1e-300] {
            let (v, d1, d2) = relaxed_log(z, delta);
            assert!(v.is_finite() && d1.is_finite() && d2 > 0.0, "z = {z}: {v} {d1} {d2}");
            assert!(d1 < 0.0);
        }
    }

    #[test]
    fn log_barrier_matches_finite_differences_and_dual_numbers_on_both_branches() {
        let (shift, w, delta) = (1.0, 0.7, 0.5);
        let f: Arc<dyn StageFunction> = Arc::new(TestFunction);
        let eye = Mat::<f64>::identity(3, 3);
        let shifted: Arc<dyn StageFunction> = Arc::new(LinearComposition::new(f, eye.as_ref(), &[-shift; 3]).unwrap());
        let gn = LogBarrierCost::new(shifted.clone(), w, delta).unwrap();
        let exact = LogBarrierCost::new(shifted.clone(), w, delta)
            .unwrap()
            .exact_hessian(true);
        let space = VectorSpace::new(3);
        let (mut inside, mut relaxed) = (0, 0);
        let mut fd = shifted.create_data();
        for (x, u) in points(44, 8) {
            shifted.evaluate(&x, &u, &mut fd);
            for &r in fd.value() {
                if -r >= delta { inside += 1 } else { relaxed += 1 }
            }
            check_cost(&exact, &space, &x, &u, CheckOptions::default()).assert_ok();
            dual_check_cost(&exact, &x, &u, |z| barrier_ref(z, shift, w, delta), true, 1e-12);
            dual_check_cost(&gn, &x, &u, |z| barrier_ref(z, shift, w, delta), false, 1e-12);
        }
        assert!(inside > 3 && relaxed > 3, "both branches exercised: {inside} {relaxed}");
        // Far outside the domain the value stays finite.
        let mut d = gn.create_data();
        gn.evaluate(&[30.0, 30.0, 30.0], &[1.0, 1.0], &mut d);
        gn.derivatives(&[30.0, 30.0, 30.0], &[1.0, 1.0], &mut d);
        assert!(d.value.is_finite() && crate::linalg::all_finite(d.lxx.as_ref()));
        // The weight can change through a shared reference.
        gn.set_weight(2.0 * w).unwrap();
        let mut d2 = gn.create_data();
        gn.evaluate(&[30.0, 30.0, 30.0], &[1.0, 1.0], &mut d2);
        assert!((d2.value - 2.0 * d.value).abs() <= 1e-12 * d.value.abs());
        assert!(gn.set_weight(-1.0).is_err());
        assert!(LogBarrierCost::new(shifted.clone(), 1.0, 0.0).is_err());
        assert!(LogBarrierCost::new(shifted, f64::NAN, 0.1).is_err());
    }

    #[test]
    fn state_cost_on_lie_groups_has_exact_gradient_and_gauss_newton_hessian() {
        use crate::check::{DualCheckOptions, check_cost_dual, dual_stage_jacobians, hyper_cost_derivatives};
        use num_dual::{Dual64, HyperDual64};
        let mut g = rng(45);
        for space in crate::functions::testing::lie_spaces() {
            let (nx, ndx) = (space.nx(), space.ndx());
            let mut x_ref = vec![0.0; nx];
            space.random(&mut g, &mut x_ref);
            let a = random_mat(&mut g, ndx, ndx, 1.0);
            let w = &a * a.transpose();
            let cost = QuadraticStateCost::new(space.clone(), &x_ref, w.as_ref(), 1).unwrap();
            let xr_h: Vec<HyperDual64> = x_ref.iter().map(|&v| HyperDual64::from(v)).collect();
            let xr_d: Vec<Dual64> = x_ref.iter().map(|&v| Dual64::from(v)).collect();
            let reference = |x: &[HyperDual64], _u: &[HyperDual64]| {
                let mut r = vec![HyperDual64::from(0.0); ndx];
                space.difference_hyper(&xr_h, x, &mut r);
                let mut v = HyperDual64::from(0.0);
                for i in 0..ndx {
                    for j in 0..ndx {
                        v += r[i] * r[j] * (0.5 * w[(i, j)]);
                    }
                }
                v
            };
            // At the target the Gauss-Newton Hessian is exact.
            let rep = check_cost_dual(
                &cost,
                space.as_ref(),
                &x_ref,
                &[0.3],
                reference,
                DualCheckOptions::default(),
            );
            assert!(rep.passed(), "{space:?}: {rep:?}");
            check_cost(&cost, space.as_ref(), &x_ref, &[0.3], CheckOptions::default()).assert_ok();
            // Elsewhere: exact gradient, Hessian Jᵀ W J with J = d(x ⊖ x_ref)/dx.
            for _ in 0..4 {
                let mut x = vec![0.0; nx];
                space.random(&mut g, &mut x);
                let mut d = cost.create_data();
                cost.evaluate(&x, &[0.3], &mut d);
                cost.derivatives(&x, &[0.3], &mut d);
                let r = hyper_cost_derivatives(space.as_ref(), &x, &[0.3], reference);
                assert!((d.value - r.value).abs() <= 1e-12 * r.value.max(1.0));
                let lx = Mat::from_fn(ndx, 1, |i, _| r.lx[i]);
                assert_close("lx", &d.lx.as_mat().to_owned(), &lx, 1e-12);
                let j = dual_stage_jacobians(space.as_ref(), &x, &[0.3], ndx, |x, _u, out| {
                    space.difference_dual(&xr_d, x, out)
                })
                .jx;
                let gn = j.transpose() * (&w * &j);
                assert_close("lxx", &d.lxx, &gn, 1e-12);
                let rep = check_cost(&cost, space.as_ref(), &x, &[0.3], CheckOptions::default());
                for (name, e) in &rep.errors {
                    if name != "lxx" {
                        assert!(*e <= 1e-6, "{space:?} {name}: {e}");
                    }
                }
            }
        }
    }
    /// Diagonal weights on a Lie group times vector spaces take the block path
    /// (`Manifold::nonlinear_dim`): gradient `Jᵀ W r` and Hessian `Jᵀ W J` against
    /// dual-number Jacobians of `x ⊖ x_ref`, bit for bit those of the general residual
    /// path, the control blocks zero, and a scaled accumulation into existing blocks.
    #[test]
    fn diagonal_state_cost_works_on_the_nonlinear_block() {
        use crate::check::dual_stage_jacobians;
        use crate::spaces::{CartesianProduct, SE3, SO3, TangentBundle};
        use num_dual::Dual64;
        let mut g = rng(46);
        let floating: Arc<dyn Manifold> = Arc::new(CartesianProduct::new(vec![
            Arc::new(SE3),
            Arc::new(VectorSpace::new(4)),
        ]));
        let spaces: Vec<Arc<dyn Manifold>> = vec![
            Arc::new(TangentBundle::new(floating.clone())),
            floating,
            Arc::new(TangentBundle::new(Arc::new(SO3))),
            Arc::new(SE3),
        ];
        for space in spaces {
            let (nx, ndx) = (space.nx(), space.ndx());
            let (mut x_ref, mut x) = (vec![0.0; nx], vec![0.0; nx]);
            space.random(&mut g, &mut x_ref);
            space.random(&mut g, &mut x);
            let w: Vec<f64> = (0..ndx).map(|_| g.random_range(0.1..2.0)).collect();
            let cost = QuadraticStateCost::diagonal(space.clone(), &x_ref, &w, 2).unwrap();
            let mut d = cost.create_data();
            cost.evaluate(&x, &[0.3, 0.1], &mut d);
            cost.derivatives(&x, &[0.3, 0.1], &mut d);
            let xr: Vec<Dual64> = x_ref.iter().map(|&v| Dual64::from(v)).collect();
            let j = dual_stage_jacobians(space.as_ref(), &x, &[0.3, 0.1], ndx, |x, _u, out| {
                space.difference_dual(&xr, x, out)
            })
            .jx;
            let mut r = vec![0.0; ndx];
            space.difference(&x_ref, &x, &mut r);
            let wm = Mat::from_fn(ndx, ndx, |i, k| if i == k { w[i] } else { 0.0 });
            let lx = j.transpose() * (&wm * Mat::from_fn(ndx, 1, |i, _| r[i]));
            let gn = j.transpose() * (&wm * &j);
            assert_close("lx", &d.lx.as_mat().to_owned(), &lx, 1e-12);
            assert_close("lxx", &d.lxx, &gn, 1e-12);
            assert!(d.lu().iter().all(|&v| v == 0.0) && d.lxu.norm_max() == 0.0);
            // The same bits as the general residual path.
            let general = QuadraticResidualCost::diagonal(Arc::new(Unary::new(cost.error().clone(), 2)), &w).unwrap();
            let mut dg = general.create_data();
            general.evaluate(&x, &[0.3, 0.1], &mut dg);
            general.derivatives(&x, &[0.3, 0.1], &mut dg);
            assert!(
                d.lx() == dg.lx() && d.lxx == dg.lxx,
                "{space:?}: not the general path's bits"
            );
            // s ∇ℓ added to what is there (lower triangle only).
            let (mut ax, mut au) = (vec![1.0; ndx], vec![2.0; 2]);
            let (mut axx, mut axu, mut auu) = (Mat::<f64>::zeros(ndx, ndx), Mat::zeros(ndx, 2), Mat::zeros(2, 2));
            let out = DerivativesMut {
                lx: &mut ax,
                lu: &mut au,
                hessian: Some(HessianMut {
                    lxx: axx.as_mut(),
                    lxu: axu.as_mut(),
                    luu: auu.as_mut(),
                }),
            };
            cost.add_derivatives(&x, &[0.3, 0.1], &mut d, false, 0.5, out);
            for i in 0..ndx {
                assert!((ax[i] - 1.0 - 0.5 * lx[(i, 0)]).abs() <= 1e-12 * (1.0 + lx[(i, 0)].abs()));
                for k in 0..=i {
                    assert!((axx[(i, k)] - 0.5 * gn[(i, k)]).abs() <= 1e-12 * (1.0 + gn[(i, k)].abs()));
                }
            }
            assert_eq!(au, [2.0, 2.0]);
        }
    }
}

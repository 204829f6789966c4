//! ProxNLP's workspace: iterates, multipliers, estimates, the primal-dual Newton system
//! (dense or sparse, [`super::kkt`]), and the per-iteration computations (residuals,
//! Newton step, merit). Everything is allocated in [`Workspace::new`]; no method
//! allocates.

use std::ops::Range;

use faer::prelude::ReborrowMut;
use faer::{Accum, Mat};

use super::kkt::{Kkt, NonFiniteStep};
use super::options::ProxNlpOptions;
use super::problem::{Nlp, NlpData};
use crate::error::Result;
use crate::linalg::{col_of, col_of_mut, dot, matmul, norm_inf};
use crate::solvers::HessianApprox;

/// Residuals at the current point: ProxDDP (19), (52), (53) for one "stage".
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Residuals {
    /// Primal residual (53): `max |c - proj_C(c + mu ν_e)|`.
    pub prim: f64,
    /// Dual residual (52): `|∇f + Jᵀν|_∞`.
    pub dual: f64,
    /// Inner criterion (19): the dual residual and `|mu (ν⁺ - ν)|_∞`.
    pub inner: f64,
    /// Complementarity of the current multipliers, `|c - proj_C(c + ν)|_∞`.
    pub comp: f64,
}

/// A primal-dual point `(x, ν)` and the evaluation of the NLP at `x`.
pub(super) struct Point {
    pub x: Vec<f64>,
    pub nu: Vec<f64>,
    pub data: NlpData,
}

impl Point {
    fn new(nlp: &dyn Nlp, nc: usize) -> Self {
        Self {
            x: vec![0.0; nlp.space().nx()],
            nu: vec![0.0; nc],
            data: nlp.create_data(),
        }
    }

    /// Evaluates the NLP at `x`; returns the cost, or `None` if a value is not finite.
    pub fn evaluate(&mut self, nlp: &dyn Nlp) -> Option<f64> {
        nlp.evaluate(&self.x, &mut self.data);
        let d = &self.data;
        (d.cost.is_finite() && d.values.iter().all(|v| v.is_finite())).then_some(d.cost)
    }
}

pub(super) struct Workspace {
    /// Rows of each constraint block in the stacked constraint vector.
    pub rows: Vec<Range<usize>>,
    /// Penalty scale of each block.
    scales: Vec<f64>,
    pub ndx: usize,
    pub nc: usize,
    pub cur: Point,
    pub trial: Point,
    /// Best point so far (smallest `max(prim, dual)`), for the time budget.
    pub best_x: Vec<f64>,
    pub best_nu: Vec<f64>,
    pub best_err: f64,
    /// Outer multipliers `ν_e` (Algorithm 2).
    pub nu_e: Vec<f64>,
    /// First-order estimates `ν⁺` (39).
    pub nu_p: Vec<f64>,
    /// Effective multipliers of the Newton system's gradient, `ν⁺ - J_N (ν⁺ - ν)`.
    nu_g: Vec<f64>,
    /// Scratch of constraint size.
    zbuf: Vec<f64>,
    wbuf: Vec<f64>,
    /// `J δx`.
    jdx: Vec<f64>,
    /// Scratch of tangent size (Lagrangian gradient, `α δx`).
    gbuf: Vec<f64>,
    /// Per block: whether the Jacobian `J_N` of its normal-cone projection is not a
    /// projector at the current point (a cone boundary), so that its rows of the Newton
    /// system are `√J_N J` (see [`Workspace::build_system`]).
    sqrt_block: Vec<bool>,
    /// Scratch of the largest block's size: `J_N`, `J_N²` and Jacobi eigenvectors.
    jn: Mat<f64>,
    jn2: Mat<f64>,
    eig: Mat<f64>,
    /// The rows `C` of a constraint block on its columns (largest block's size).
    cbuf: Mat<f64>,
    /// The Newton system (42)-(46) and its factorization.
    pub kkt: Kkt,
    /// Right-hand side and step `(δν, δx)`.
    rhs: Mat<f64>,
    pub step: Mat<f64>,
}

impl Workspace {
    /// The workspace of `nlp` (allocates everything a solve needs), with the Newton
    /// system solved as `opts.kkt` says.
    ///
    /// # Errors
    /// As [`Kkt::new`].
    pub fn new(nlp: &dyn Nlp, opts: &ProxNlpOptions) -> Result<Self> {
        let mut rows = Vec::with_capacity(nlp.num_blocks());
        let mut scales = Vec::with_capacity(nlp.num_blocks());
        let mut off = 0;
        for k in 0..nlp.num_blocks() {
            let b = nlp.block(k);
            rows.push(off..off + b.nr);
            scales.push(b.scale);
            off += b.nr;
        }
        let (ndx, nc) = (nlp.space().ndx(), off);
        let n = ndx + nc;
        let mmax = rows.iter().map(|r| r.len()).max().unwrap_or(0);
        let cur = Point::new(nlp, nc);
        let sp = &cur.data.sparsity;
        let kkt = Kkt::new(opts.kkt, ndx, &rows, sp)?;
        let smax = sp.jacobian.iter().map(|c| c.len()).max().unwrap_or(0);
        Ok(Self {
            rows,
            scales,
            ndx,
            nc,
            trial: Point::new(nlp, nc),
            best_x: cur.x.clone(),
            best_nu: cur.nu.clone(),
            best_err: f64::INFINITY,
            cur,
            nu_e: vec![0.0; nc],
            nu_p: vec![0.0; nc],
            nu_g: vec![0.0; nc],
            zbuf: vec![0.0; nc],
            wbuf: vec![0.0; nc],
            jdx: vec![0.0; nc],
            gbuf: vec![0.0; ndx],
            sqrt_block: vec![false; nlp.num_blocks()],
            jn: Mat::zeros(mmax, mmax),
            jn2: Mat::zeros(mmax, mmax),
            eig: Mat::zeros(mmax, mmax),
            cbuf: Mat::zeros(mmax, smax),
            kkt,
            rhs: Mat::zeros(n, 1),
            step: Mat::zeros(n, 1),
        })
    }

    /// Loads the starting point; `ν_e` starts at the initial multipliers (zero if absent).
    pub fn load(&mut self, x0: &[f64], nu0: Option<&[f64]>) {
        self.cur.x.copy_from_slice(x0);
        match nu0 {
            Some(v) => self.cur.nu.copy_from_slice(v),
            None => self.cur.nu.fill(0.0),
        }
        self.nu_e.copy_from_slice(&self.cur.nu);
        self.best_err = f64::INFINITY;
    }

    /// Evaluates values and first derivatives at the current point; returns the cost, or
    /// `None` if a value is not finite.
    pub fn evaluate_current(&mut self, nlp: &dyn Nlp) -> Option<f64> {
        let c = self.cur.evaluate(nlp)?;
        nlp.derivatives(&self.cur.x, &mut self.cur.data);
        Some(c)
    }

    /// Makes the trial point (evaluated last) the current one and computes its first
    /// derivatives; returns its cost.
    pub fn accept_trial(&mut self, nlp: &dyn Nlp) -> f64 {
        std::mem::swap(&mut self.cur, &mut self.trial);
        nlp.derivatives(&self.cur.x, &mut self.cur.data);
        self.cur.data.cost
    }

    /// Accepts the current multipliers as the outer ones (BCL success).
    pub fn accept_multipliers(&mut self) {
        self.nu_e.copy_from_slice(&self.cur.nu);
    }

    /// Keeps a copy of the current point if it is the best so far.
    pub fn record_best(&mut self, err: f64) {
        if err < self.best_err {
            self.best_err = err;
            self.best_x.copy_from_slice(&self.cur.x);
            self.best_nu.copy_from_slice(&self.cur.nu);
        }
    }

    /// Returns to the best point (time budget); returns its cost, `None` if not finite.
    pub fn restore_best(&mut self, nlp: &dyn Nlp) -> Option<f64> {
        self.cur.x.copy_from_slice(&self.best_x);
        self.cur.nu.copy_from_slice(&self.best_nu);
        self.evaluate_current(nlp)
    }

    /// Multiplier estimates (39) `ν⁺ = N_C(c + mu ν_e) / mu` and the residuals (19),
    /// (52), (53) at the current point.
    pub fn estimates_and_residuals(&mut self, nlp: &dyn Nlp, mu: f64) -> Residuals {
        let (mut prim, mut inner, mut comp) = (0.0_f64, 0.0_f64, 0.0_f64);
        let c = &self.cur.data.values;
        for (k, r) in self.rows.iter().enumerate() {
            let set = nlp.block(k).set;
            let mu_k = self.scales[k] * mu;
            let z = &mut self.zbuf[r.clone()];
            for ((zi, ci), ei) in z.iter_mut().zip(&c[r.clone()]).zip(&self.nu_e[r.clone()]) {
                *zi = ci + mu_k * ei;
            }
            set.normal_cone_project(z, mu_k, &mut self.nu_p[r.clone()]);
            for i in r.clone() {
                self.nu_p[i] /= mu_k;
                prim = prim.max((mu_k * (self.nu_e[i] - self.nu_p[i])).abs());
                inner = inner.max((mu_k * (self.nu_p[i] - self.cur.nu[i])).abs());
            }
            // Complementarity: c - proj_C(c + ν).
            let w = &mut self.wbuf[r.clone()];
            for ((wi, ci), ni) in w.iter_mut().zip(&c[r.clone()]).zip(&self.cur.nu[r.clone()]) {
                *wi = ci + ni;
            }
            let p = &mut self.zbuf[r.clone()];
            set.project(&self.wbuf[r.clone()], 1.0, p);
            for (ci, pi) in c[r.clone()].iter().zip(p.iter()) {
                comp = comp.max((ci - pi).abs());
            }
        }
        lagrangian_gradient(&self.cur.data, &self.rows, &self.cur.nu, &mut self.gbuf);
        let dual = norm_inf(&self.gbuf);
        Residuals {
            prim,
            dual,
            inner: inner.max(dual),
            comp,
        }
    }

    /// The Newton system (42)-(46) at the current point, without the primal
    /// regularisation, into `kkt_base` and `rhs`: with `z = c + mu ν_e`,
    /// `ν̂ = N(z) / mu` and `J_N` the Jacobian of the normal-cone projection at `z`,
    /// ```text
    /// [ H     Cᵀ   ] [δx]     [ ∇f + Jᵀ ν_g ]     C   = J_N J,
    /// [ C   -mu I  ] [δν] = - [ mu (ν̂ - ν)  ]     ν_g = ν̂ - J_N (ν̂ - ν),
    /// ```
    /// the semi-smooth Newton step on `∇f + Jᵀν = 0`, `N(c + mu ν_e) = mu ν` (38) when
    /// `J_N` is a projector (equality, orthant, box; eliminating `δν` gives the primal
    /// Newton matrix `H + Jᵀ J_N² J / mu`). Where it is not (a cone's boundary), the
    /// block's rows are `C = √J_N J`, `ν_g = ν̂` and a zero right-hand side, whose
    /// elimination gives the exact `H + Jᵀ J_N J / mu`; the multiplier step of such a
    /// block is recovered after the solve ([`Workspace::solve_system`]).
    pub fn build_system(&mut self, nlp: &dyn Nlp, opts: &ProxNlpOptions, mu: f64) {
        self.kkt.clear();
        let d = &self.cur.data;
        for (h, m) in d.hess.iter().enumerate() {
            self.kkt.add_hessian(h, &d.sparsity.hessian[h], m.as_ref());
        }
        for b in 0..self.rows.len() {
            self.constraint_rows(nlp, b, mu);
        }
        if opts.hessian == HessianApprox::Exact {
            nlp.second_order(&self.cur.x, &self.nu_p, &mut self.cur.data);
            let d = &self.cur.data;
            for (h, m) in d.vhp.iter().enumerate() {
                self.kkt.add_hessian(h, &d.sparsity.hessian[h], m.as_ref());
            }
        }
        lagrangian_gradient(&self.cur.data, &self.rows, &self.nu_g, &mut self.gbuf);
        let rhs = col_of_mut(&mut self.rhs, 0);
        for (r, g) in rhs[self.nc..].iter_mut().zip(&self.gbuf) {
            *r = -g;
        }
    }

    /// The rows of block `b` in the system of [`build_system`](Self::build_system), its
    /// effective multipliers `ν_g` and its part of the right-hand side.
    fn constraint_rows(&mut self, nlp: &dyn Nlp, b: usize, mu: f64) {
        let r = self.rows[b].clone();
        let (m, set) = (r.len(), nlp.block(b).set);
        let mu_k = self.scales[b] * mu;
        let d = &self.cur.data;
        let z = &mut self.zbuf[r.clone()];
        for ((zi, ci), ei) in z.iter_mut().zip(&d.values[r.clone()]).zip(&self.nu_e[r.clone()]) {
            *zi = ci + mu_k * ei;
        }
        // J_N densely, and whether it is a projector.
        let mut jn = self.jn.as_mut().submatrix_mut(0, 0, m, m);
        for i in 0..m {
            for j in 0..m {
                jn[(i, j)] = f64::from(u8::from(i == j));
            }
        }
        let projector = set.is_equality() || {
            set.apply_normal_cone_jacobian(z, mu_k, jn.rb_mut());
            let mut jn2 = self.jn2.as_mut().submatrix_mut(0, 0, m, m);
            matmul(jn2.rb_mut(), Accum::Replace, jn.as_ref(), jn.as_ref(), 1.0);
            (0..m).all(|i| (0..m).all(|j| (jn2[(i, j)] - jn[(i, j)]).abs() <= 1e-12))
        };
        self.sqrt_block[b] = !projector;
        let rhs = col_of_mut(&mut self.rhs, 0);
        let jac = d.jac[b].as_ref();
        let mut c = self.cbuf.as_mut().submatrix_mut(0, 0, m, jac.ncols());
        if projector {
            let w = &mut self.wbuf[r.clone()];
            for i in r.clone() {
                w[i - r.start] = self.nu_p[i] - self.cur.nu[i];
                rhs[i] = -mu_k * w[i - r.start];
            }
            set.apply_normal_cone_jacobian_vec(z, mu_k, w);
            for i in r.clone() {
                self.nu_g[i] = self.nu_p[i] - w[i - r.start];
            }
            crate::linalg::copy(c.rb_mut(), jac);
            set.apply_normal_cone_jacobian(z, mu_k, c.rb_mut());
        } else {
            for i in r.clone() {
                self.nu_g[i] = self.nu_p[i];
                rhs[i] = 0.0;
            }
            let mut v = self.eig.as_mut().submatrix_mut(0, 0, m, m);
            crate::linalg::psd_sqrt(jn.rb_mut(), v.rb_mut());
            matmul(c.rb_mut(), Accum::Replace, jn.as_ref(), jac, 1.0);
        }
        self.kkt
            .set_constraint_rows(b, &r, &d.sparsity.jacobian[b], c.as_ref(), mu_k);
    }

    /// The multiplier steps of the blocks whose rows are `√J_N J`: from the linearised
    /// `N(z + J δx) = mu (ν + δν)`, `δν = ν̂ - ν + J_N J δx / mu`.
    fn recover_multiplier_steps(&mut self, nlp: &dyn Nlp, mu: f64) {
        let st = col_of_mut(&mut self.step, 0);
        let (dnu, dx) = st.split_at_mut(self.nc);
        for (b, r) in self.rows.iter().enumerate() {
            if !self.sqrt_block[b] {
                continue;
            }
            let set = nlp.block(b).set;
            let mu_k = self.scales[b] * mu;
            let d = &self.cur.data;
            let z = &mut self.zbuf[r.clone()];
            for ((zi, ci), ei) in z.iter_mut().zip(&d.values[r.clone()]).zip(&self.nu_e[r.clone()]) {
                *zi = ci + mu_k * ei;
            }
            let w = &mut self.wbuf[r.clone()];
            d.jacobian_mul(b, dx, w);
            set.apply_normal_cone_jacobian_vec(z, mu_k, w);
            for i in r.clone() {
                dnu[i] = self.nu_p[i] - self.cur.nu[i] + w[i - r.start] / mu_k;
            }
        }
    }

    /// Solves the system of [`build_system`](Self::build_system) (ordered multipliers
    /// first, then the primal step) with the primal regularisation `preg`, checking its
    /// inertia (`ndx` positive, `nc` negative eigenvalues: the reduced Hessian is positive
    /// definite), with one step of iterative refinement, then the multiplier steps of the
    /// cone-boundary blocks. Returns `Ok(false)` for the wrong inertia.
    pub fn solve_system(&mut self, nlp: &dyn Nlp, mu: f64, preg: f64) -> std::result::Result<bool, NonFiniteStep> {
        let n = self.ndx + self.nc;
        if !self
            .kkt
            .solve(preg, col_of(&self.rhs, 0), col_of_mut(&mut self.step, 0))?
        {
            return Ok(false);
        }
        self.recover_multiplier_steps(nlp, mu);
        let s = col_of(&self.step, 0);
        if s[..n].iter().all(|v| v.is_finite()) {
            Ok(true)
        } else {
            Err(NonFiniteStep)
        }
    }

    /// Directional derivative `dφ(0)` of the primal-dual merit (17) along the step
    /// `(δx, δν)`: with `z = c + mu (ν_e - ν/2)`,
    /// `∇f·δx + Σ (2/mu) N(z)·J δx + (mu/2 ν - N(z))·δν`.
    pub fn merit_slope(&mut self, nlp: &dyn Nlp, mu: f64) -> f64 {
        let st = col_of(&self.step, 0);
        let (dnu, dx) = st.split_at(self.nc);
        let d = &self.cur.data;
        for (b, r) in self.rows.iter().enumerate() {
            d.jacobian_mul(b, dx, &mut self.jdx[r.clone()]);
        }
        let mut slope = dot(&d.grad, dx);
        for (b, r) in self.rows.iter().enumerate() {
            let set = nlp.block(b).set;
            let mu_k = self.scales[b] * mu;
            let z = &mut self.zbuf[r.clone()];
            for i in r.clone() {
                z[i - r.start] = d.values[i] + mu_k * (self.nu_e[i] - 0.5 * self.cur.nu[i]);
            }
            let w = &mut self.wbuf[r.clone()];
            set.normal_cone_project(z, mu_k, w);
            for i in r.clone() {
                let ni = w[i - r.start];
                slope += 2.0 / mu_k * ni * self.jdx[i] + (0.5 * mu_k * self.cur.nu[i] - ni) * dnu[i];
            }
        }
        slope
    }

    /// The trial point `x ⊕ α δx`, `ν + α δν` (ProxDDP (50)), evaluated; returns its
    /// merit and infeasibility `(φ, θ)`, `NaN` if a value is not finite.
    pub fn trial(&mut self, nlp: &dyn Nlp, alpha: f64, mu: f64) -> (f64, f64) {
        let st = col_of(&self.step, 0);
        let (dnu, dx) = st.split_at(self.nc);
        for (g, d) in self.gbuf.iter_mut().zip(dx) {
            *g = alpha * d;
        }
        nlp.space().integrate(&self.cur.x, &self.gbuf, &mut self.trial.x);
        for ((t, c), d) in self.trial.nu.iter_mut().zip(&self.cur.nu).zip(dnu) {
            *t = c + alpha * d;
        }
        if self.trial.evaluate(nlp).is_none() {
            return (f64::NAN, f64::NAN);
        }
        merit(
            nlp,
            &self.trial,
            &self.nu_e,
            &self.scales,
            &self.rows,
            mu,
            &mut self.zbuf,
            &mut self.wbuf,
        )
    }

    /// Merit and infeasibility of the current point.
    pub fn current_merit(&mut self, nlp: &dyn Nlp, mu: f64) -> (f64, f64) {
        merit(
            nlp,
            &self.cur,
            &self.nu_e,
            &self.scales,
            &self.rows,
            mu,
            &mut self.zbuf,
            &mut self.wbuf,
        )
    }
}

/// `∇f + Jᵀ ν` into `out` (`rows`: the rows of each constraint block).
fn lagrangian_gradient(d: &NlpData, rows: &[Range<usize>], nu: &[f64], out: &mut [f64]) {
    out.copy_from_slice(&d.grad);
    for (b, r) in rows.iter().enumerate() {
        d.jacobian_t_mul_add(b, &nu[r.clone()], out);
    }
}

/// The primal-dual merit function (17) at `p` and its infeasibility `max_k dist(c_k, C_k)`:
/// `f + Σ_k 2 e_k(z) + (mu_k/4)|ν|²` with `z = c + mu_k (ν_e - ν/2)` and `e_k` the Moreau
/// envelope of the set, `2 e(z) = 2 g(proj(z)) + |z - proj(z)|² / mu_k`.
#[allow(clippy::too_many_arguments)]
fn merit(
    nlp: &dyn Nlp,
    p: &Point,
    nu_e: &[f64],
    scales: &[f64],
    rows: &[Range<usize>],
    mu: f64,
    zbuf: &mut [f64],
    wbuf: &mut [f64],
) -> (f64, f64) {
    let c = &p.data.values;
    let mut m = p.data.cost;
    let mut theta: f64 = 0.0;
    for (b, r) in rows.iter().enumerate() {
        let set = nlp.block(b).set;
        let mu_k = scales[b] * mu;
        theta = theta.max(set.violation(&c[r.clone()]));
        let z = &mut zbuf[r.clone()];
        for i in r.clone() {
            z[i - r.start] = c[i] + mu_k * (nu_e[i] - 0.5 * p.nu[i]);
        }
        let w = &mut wbuf[r.clone()];
        set.project(z, mu_k, w);
        m += 2.0 * set.penalty(w);
        for i in r.clone() {
            let (d, v) = (z[i - r.start] - w[i - r.start], p.nu[i]);
            m += d * d / mu_k + 0.25 * mu_k * v * v;
        }
    }
    (m, theta)
}

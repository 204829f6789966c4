//! The augmented Lagrangian of one stage as a [`Cost`] (ALTRO paper, (5)-(6)), so that
//! the inner iLQR of AL-iLQR is the DDP of [`crate::solvers::ddp`] on a problem whose
//! costs are these and which has no constraint.
//!
//! For a constraint `c(x, u) ∈ K` with multiplier `λ` and penalty `μ` (one per constraint:
//! the penalty of the paper's `I_μ` times the constraint's [`StageConstraint::scale`]), the
//! term is the PHR augmented Lagrangian
//! ```text
//! ψ(c) = μ/2 |y - proj_K(y)|² - |λ|²/(2μ),   y = c + λ/μ,
//! ```
//! which for `K = {0}` is `λᵀc + μ/2 |c|²` and for `K = R_-` (an inequality `c ≤ 0`) is
//! `λᵀc + ½cᵀI_μc` with the paper's active set (6): `I_μ = μ` where `c ≥ 0` or `λ > 0`.
//! Its gradient is `Jᵀλ⁺` with `λ⁺ = μ(y - proj_K(y))`, the multiplier update (17), and its
//! Gauss-Newton Hessian `μ Jᵀ(I - P(y))J` (`P` the projection's Jacobian: for boxes and
//! orthants the paper's `c_xᵀI_μc_x`, (8)-(10)).

use std::sync::Arc;

use faer::Mat;
use faer::prelude::ReborrowMut;

use crate::costs::{Cost, CostData, CostParts, HessianMut};
use crate::functions::{StageFunctionData, Workspace};
use crate::linalg::{self, matmul, matvec_t, slice};
use crate::param::ParamVec;
use crate::problem::StageConstraint;

/// `ℓ(x, u) + Σ_i ψ_i(c_i(x, u))`: a stage cost with its constraints' AL terms.
pub(super) struct AlCost {
    base: Arc<dyn Cost>,
    cons: Vec<StageConstraint>,
    /// Row offset of each constraint.
    offsets: Vec<usize>,
    /// `λ`, one entry per constraint row.
    pub lambda: ParamVec,
    /// `μ`, one entry per constraint (the constraint's scale included), then the slack's.
    pub mu: ParamVec,
    /// Controls of the base cost and the constraints; slack controls after them (III-B).
    nu: usize,
    ns: usize,
    /// `R_s` of the slack cost (32).
    slack_weight: f64,
    /// Rows of the constraints (the slack's multipliers follow).
    nr: usize,
}

/// Scratch of [`AlCost`].
struct AlWs {
    base: CostData,
    fdata: Vec<StageFunctionData>,
    y: Vec<f64>,
    e: Vec<f64>,
    /// `[J_x J_u]` of one constraint, and `(I - P)[J_x J_u]`.
    jac: Mat<f64>,
    pjac: Mat<f64>,
}

impl AlCost {
    /// The AL cost of `base` and `cons`, with `λ = 0` and `μ = 1`.
    pub(super) fn new(base: Arc<dyn Cost>, cons: Vec<StageConstraint>) -> Self {
        Self::with_slack(base, cons, 0, 0.0)
    }

    /// The AL cost with `ns` slack controls after the base's (III-B): the cost
    /// `½ R_s|s|²` (32) and the constraint `s = 0` in the augmented Lagrangian.
    pub(super) fn with_slack(base: Arc<dyn Cost>, cons: Vec<StageConstraint>, ns: usize, slack_weight: f64) -> Self {
        let mut offsets = Vec::with_capacity(cons.len());
        let mut nr = 0;
        for c in &cons {
            offsets.push(nr);
            nr += c.nr();
        }
        Self {
            lambda: ParamVec::new(&vec![0.0; nr + ns]),
            mu: ParamVec::new(&vec![1.0; cons.len() + usize::from(ns > 0)]),
            nu: base.nu(),
            ns,
            slack_weight,
            nr,
            base,
            cons,
            offsets,
        }
    }

    /// The slack part of the AL at the slack controls `s`: `½R_s|s|² + λ_sᵀs + ½μ_s|s|²`.
    fn slack_value(&self, s: &[f64]) -> f64 {
        if self.ns == 0 {
            return 0.0;
        }
        let mu = self.mu.get(self.cons.len());
        s.iter()
            .enumerate()
            .map(|(i, si)| (0.5 * (self.slack_weight + mu) * si + self.lambda.get(self.nr + i)) * si)
            .sum()
    }

    /// `λ` of row `i` of constraint `k`.
    pub(super) fn lambda_of(&self, k: usize, i: usize) -> f64 {
        self.lambda.get(self.offsets[k] + i)
    }

    /// The constraints.
    pub(super) fn constraints(&self) -> &[StageConstraint] {
        &self.cons
    }

    /// Data for [`AlCost::update_multipliers`]: one per constraint.
    pub(super) fn create_function_data(&self) -> Vec<StageFunctionData> {
        self.cons.iter().map(|c| c.func.create_data()).collect()
    }

    /// Evaluates the constraints at `(x, u)` into `fdata`, applies the multiplier update
    /// (17) `λ ← μ(y - proj_K(y))` when `update`, and returns the largest violation
    /// `|c - proj_K(c)|_∞`. `y`, `e` are scratch of the largest constraint's size.
    pub(super) fn update_multipliers(
        &self,
        x: &[f64],
        u: &[f64],
        fdata: &mut [StageFunctionData],
        y: &mut [f64],
        e: &mut [f64],
        update: bool,
    ) -> f64 {
        let mut viol: f64 = 0.0;
        let (u, slack) = u.split_at(self.nu.min(u.len()));
        for (i, s) in slack.iter().enumerate() {
            viol = viol.max(s.abs());
            if update {
                let mu = self.mu.get(self.cons.len());
                self.lambda.set(self.nr + i, self.lambda.get(self.nr + i) + mu * s);
            }
        }
        for (i, c) in self.cons.iter().enumerate() {
            c.func.evaluate(x, u, &mut fdata[i]);
            let v = slice(&fdata[i].value);
            viol = crate::linalg::max_nan(viol, crate::constraints::violation_or_nan(c.set.as_ref(), v));
            if update {
                let m = v.len();
                let mu = self.mu.get(i);
                self.shifted(i, v, mu, &mut y[..m], &mut e[..m]);
                for (r, er) in e[..m].iter().enumerate() {
                    self.lambda.set(self.offsets[i] + r, mu * er);
                }
            }
        }
        viol
    }

    /// `y = c + λ/μ` and `e = y - proj_K(y)` of constraint `i` at residual `c`; returns
    /// the AL term `μ/2|e|² - |λ|²/(2μ)`.
    fn shifted(&self, i: usize, c: &[f64], mu: f64, y: &mut [f64], e: &mut [f64]) -> f64 {
        let mut lam2 = 0.0;
        for (r, yr) in y.iter_mut().enumerate() {
            let l = self.lambda.get(self.offsets[i] + r);
            lam2 += l * l;
            *yr = c[r] + l / mu;
        }
        self.cons[i].set.normal_cone_project(y, 1.0 / mu, e);
        0.5 * mu * linalg::dot(e, e) - 0.5 * lam2 / mu
    }
}

impl Cost for AlCost {
    fn nx(&self) -> usize {
        self.base.nx()
    }
    fn ndx(&self) -> usize {
        self.base.ndx()
    }
    fn nu(&self) -> usize {
        self.nu + self.ns
    }

    fn create_workspace(&self) -> Workspace {
        let nr = self.cons.iter().map(|c| c.nr()).max().unwrap_or(0);
        let n = self.ndx() + self.nu();
        Box::new(AlWs {
            base: self.base.create_data(),
            fdata: self.create_function_data(),
            y: vec![0.0; nr],
            e: vec![0.0; nr],
            jac: Mat::zeros(nr, n),
            pjac: Mat::zeros(nr, n),
        })
    }

    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        let ws = data.ws::<AlWs>();
        let (u, slack) = u.split_at(self.nu);
        self.base.evaluate(x, u, &mut ws.base);
        let mut value = ws.base.value + self.slack_value(slack);
        for (i, c) in self.cons.iter().enumerate() {
            c.func.evaluate(x, u, &mut ws.fdata[i]);
            let m = c.nr();
            let mu = self.mu.get(i);
            value += self.shifted(i, slice(&ws.fdata[i].value), mu, &mut ws.y[..m], &mut ws.e[..m]);
        }
        data.value = value;
    }

    fn derivatives(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        let CostParts {
            lx,
            lu,
            hessian:
                HessianMut {
                    mut lxx,
                    mut lxu,
                    mut luu,
                },
            ws,
        } = data.parts();
        let ws = ws.downcast_mut::<AlWs>().expect("AL cost data");
        let (u, slack) = u.split_at(self.nu);
        let (ndx, nu) = (self.ndx(), self.nu);
        self.base.derivatives(x, u, &mut ws.base);
        linalg::copy(lxx.rb_mut(), ws.base.lxx.as_ref());
        lxu.fill(0.0);
        luu.fill(0.0);
        linalg::copy(lxu.rb_mut().subcols_mut(0, nu), ws.base.lxu.as_ref());
        linalg::copy(luu.rb_mut().submatrix_mut(0, 0, nu, nu), ws.base.luu.as_ref());
        lx.copy_from_slice(ws.base.lx());
        lu[..nu].copy_from_slice(ws.base.lu());
        // Slack (32) and s = 0: gradient (R_s + μ_s)s + λ_s, Hessian (R_s + μ_s)I.
        let mu_s = if self.ns > 0 { self.mu.get(self.cons.len()) } else { 0.0 };
        for (i, si) in slack.iter().enumerate() {
            lu[nu + i] = (self.slack_weight + mu_s) * si + self.lambda.get(self.nr + i);
            luu[(nu + i, nu + i)] = self.slack_weight + mu_s;
        }
        for (i, c) in self.cons.iter().enumerate() {
            let m = c.nr();
            // `evaluate` ran at this point on this data: the residual is current.
            let fd = &mut ws.fdata[i];
            c.func.jacobians(x, u, fd);
            let mu = self.mu.get(i);
            self.shifted(i, slice(&fd.value), mu, &mut ws.y[..m], &mut ws.e[..m]);
            // Gradient Jᵀλ⁺ with λ⁺ = μe (11)-(12).
            matvec_t(lx, faer::Accum::Add, fd.jx.as_ref(), &ws.e[..m], mu);
            matvec_t(&mut lu[..nu], faer::Accum::Add, fd.ju.as_ref(), &ws.e[..m], mu);
            // Gauss-Newton Hessian μ Jᵀ(I - P)J (8)-(10).
            let mut jac = ws.jac.as_mut().subrows_mut(0, m);
            linalg::copy(jac.rb_mut().subcols_mut(0, ndx), fd.jx.as_ref());
            linalg::copy(jac.rb_mut().subcols_mut(ndx, nu), fd.ju.as_ref());
            let mut pj = ws.pjac.as_mut().subrows_mut(0, m);
            linalg::copy(pj.rb_mut(), ws.jac.as_ref().subrows(0, m));
            c.set.apply_normal_cone_jacobian(&ws.y[..m], 1.0 / mu, pj.rb_mut());
            let (j, pj) = (ws.jac.as_ref().subrows(0, m), ws.pjac.as_ref().subrows(0, m));
            let add = faer::Accum::Add;
            let (jx, ju) = (j.subcols(0, ndx), j.subcols(ndx, nu));
            let (pjx, pju) = (pj.subcols(0, ndx), pj.subcols(ndx, nu));
            matmul(lxx.rb_mut(), add, jx.transpose(), pjx, mu);
            matmul(lxu.rb_mut().subcols_mut(0, nu), add, jx.transpose(), pju, mu);
            matmul(luu.rb_mut().submatrix_mut(0, 0, nu, nu), add, ju.transpose(), pju, mu);
        }
    }
}

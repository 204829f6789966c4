//! The augmented-Lagrangian terms that the DDP workspace carries for BCL-DDP (El Kazdadi
//! et al. 2021, [`crate::solvers::bcl_ddp`]): equality constraints `h_t = 0` at the knots,
//! their multipliers `λ_t` (constant, III-A, or affine in the state, `λ_t(x) = λ_t +
//! Λ_t (x ⊖ x_t)`, (25), III-B) and the penalty `μ`.
//!
//! The DDP machinery sees them in three places: the merit of the line search is the
//! augmented Lagrangian (22)/(26) instead of the cost; the LQ knots carry the constraint
//! rows of (18), `h_x δx + h_u δu + h + λ/μ - ν/μ = 0`, so that the Riccati recursion
//! solves the augmented Q-function (23) without forming `μ h_uᵀh_u`; and with affine
//! multipliers the cross terms of (27) enter the knots' cost blocks. Everything is
//! allocated in [`Augmented::new`].

use faer::{Accum, Mat};

use crate::error::{Error, Result};
use crate::functions::StageFunctionData;
use crate::linalg::{dot, matmul, matvec, matvec_t, norm_inf, slice, slice_mut};
use crate::lq::{LqKnot, RiccatiStage};
use crate::problem::{Problem, ProblemData};

/// Multipliers and penalty of the augmented Lagrangian of equality constraints.
#[derive(Debug, Clone)]
pub(crate) struct Augmented {
    /// Penalty `μ` (the paper's: a weight, large is stiff).
    pub mu: f64,
    /// Multipliers `λ_t` at the origin `x_t`, stacked over the constraints of knot `t`
    /// (`t = 0..=N`, the last the terminal constraints).
    pub lambda: Vec<Vec<f64>>,
    /// Affine multipliers (25): their feedback `Λ_t = λ_{t,x}` (`nc_t x ndx_t`).
    pub lambda_x: Option<Vec<Mat<f64>>>,
    /// Scratch of the largest constraint size: `λ_t + Λ_t δx_t`.
    scratch: Vec<f64>,
}

impl Augmented {
    /// The terms of `problem`'s constraints, which must all be equalities; `affine`
    /// chooses the multipliers (25) with feedback.
    ///
    /// # Errors
    /// Names the first constraint whose set is not the equality set.
    pub fn new(problem: &Problem, affine: bool, solver: &str) -> Result<Self> {
        let n = problem.horizon();
        for t in 0..=n {
            let where_ = |t: usize| {
                if t < n {
                    format!("stage {t}")
                } else {
                    "the terminal knot".to_string()
                }
            };
            if let Some(c) = problem.constraints(t).iter().find(|c| !c.set.is_equality()) {
                return Err(Error::InvalidModel(format!(
                    "{solver} handles equality constraints only: constraint `{}` of {} has the set {:?} \
                     (use proxddp for inequalities and cones)",
                    c.name,
                    where_(t),
                    c.set
                )));
            }
        }
        let ncs: Vec<usize> = (0..=n)
            .map(|t| problem.constraints(t).iter().map(|c| c.nr()).sum())
            .collect();
        let lambda_x = affine.then(|| (0..=n).map(|t| Mat::zeros(ncs[t], problem.space(t).ndx())).collect());
        Ok(Self {
            mu: 1.0,
            lambda: ncs.iter().map(|&k| vec![0.0; k]).collect(),
            lambda_x,
            scratch: vec![0.0; ncs.iter().copied().max().unwrap_or(0)],
        })
    }

    /// Starts a solve: multipliers from `nus` (the solution layout: stacked per knot) or
    /// zero, no feedback, penalty `mu`.
    pub fn reset(&mut self, nus: Option<&[Vec<f64>]>, mu: f64) {
        self.mu = mu;
        match nus {
            Some(v) => crate::solvers::skeleton::copy_trajectory(&mut self.lambda, v),
            None => self.lambda.iter_mut().for_each(|l| l.fill(0.0)),
        }
        if let Some(lx) = &mut self.lambda_x {
            lx.iter_mut().for_each(|m| m.fill(0.0));
        }
    }

    /// `λ_t + Λ_t δx_t` into the scratch (`λ_t` for constant multipliers or no `dx`).
    fn multiplier_at(&mut self, t: usize, dx: Option<&[f64]>) -> &[f64] {
        let nc = self.lambda[t].len();
        let w = &mut self.scratch[..nc];
        w.copy_from_slice(&self.lambda[t]);
        if let (Some(lx), Some(dx)) = (&self.lambda_x, dx) {
            matvec(w, Accum::Add, lx[t].as_ref(), dx, 1.0);
        }
        w
    }

    /// The augmented-Lagrangian terms of (22)/(26) at the point of the data's last
    /// evaluation, `Σ_t λ_t(x̃_t)ᵀh_t + μ/2 |h_t|²`, the multipliers taken at
    /// `δx_t = x̃_t ⊖ x_t` (`dx`; `None`: at the origin).
    pub fn value(&mut self, data: &ProblemData, dx: Option<&[Vec<f64>]>) -> f64 {
        let mu = self.mu;
        let mut total = 0.0;
        for t in 0..self.lambda.len() {
            let lam = self.multiplier_at(t, dx.map(|d| &d[t][..]));
            let mut off = 0;
            for cd in data.constraint_data(t) {
                let h = slice(&cd.value);
                total += dot(&lam[off..off + h.len()], h) + 0.5 * mu * dot(h, h);
                off += h.len();
            }
        }
        total
    }

    /// `max_t |h_t|_∞` at the point of the data's last evaluation.
    pub fn violation(data: &ProblemData, knots: usize) -> f64 {
        (0..knots)
            .flat_map(|t| data.constraint_data(t))
            .map(|cd| norm_inf(slice(&cd.value)))
            .fold(0.0, f64::max)
    }

    /// Writes the constraint rows of knot `t` (18): `C = h_x`, `D = h_u`,
    /// `d = h + λ/μ`, dual regularisation `1/μ`; with affine multipliers adds the terms
    /// of (27) to the cost blocks: `Q += h_xᵀΛ + Λᵀh_x`, `S += Λᵀh_u`, `q += Λᵀh`.
    pub fn fill_knot(&self, t: usize, knot: &mut LqKnot, cds: &[StageFunctionData]) {
        let inv_mu = 1.0 / self.mu;
        let mut off = 0;
        for cd in cds {
            let nr = cd.value.nrows();
            crate::linalg::copy(knot.C.as_mut().subrows_mut(off, nr), cd.jx.as_ref());
            if knot.nu > 0 {
                crate::linalg::copy(knot.D.as_mut().subrows_mut(off, nr), cd.ju.as_ref());
            }
            for i in 0..nr {
                knot.d[off + i] = cd.value[i] + self.lambda[t][off + i] * inv_mu;
                knot.mu_c[off + i] = inv_mu;
            }
            if let Some(lx) = &self.lambda_x {
                let l = lx[t].as_ref().subrows(off, nr);
                matmul(knot.Q.as_mut(), Accum::Add, cd.jx.transpose(), l, 1.0);
                matmul(knot.Q.as_mut(), Accum::Add, l.transpose(), cd.jx.as_ref(), 1.0);
                if knot.nu > 0 {
                    matmul(knot.S.as_mut(), Accum::Add, l.transpose(), cd.ju.as_ref(), 1.0);
                }
                matvec_t(slice_mut(&mut knot.q), Accum::Add, l, slice(&cd.value), 1.0);
            }
            off += nr;
        }
    }

    /// Affine multipliers after an accepted step `δx = x' ⊖ x` (III-B): the origin moves
    /// to `x'` and `λ ← λ + Λ δx`.
    pub fn move_origin(&mut self, dx: &[Vec<f64>]) {
        if let Some(lx) = &self.lambda_x {
            for (t, lam) in self.lambda.iter_mut().enumerate() {
                matvec(lam, Accum::Add, lx[t].as_ref(), &dx[t], 1.0);
            }
        }
    }

    /// The multiplier update at the minimiser of the augmented Lagrangian: (24)
    /// `λ ← λ + μ h`, and for affine multipliers (28) `Λ ← Λ + μ (h_x + h_u K)` with the
    /// gains `K` of the last backward pass, on the rows that depend on the controls
    /// (`Λ` stays 0 on state-only rows and at the terminal knot).
    pub fn update(&mut self, data: &ProblemData, stages: &[RiccatiStage]) {
        let mu = self.mu;
        let n = self.lambda.len() - 1;
        for t in 0..=n {
            let mut off = 0;
            for cd in data.constraint_data(t) {
                let nr = cd.value.nrows();
                for i in 0..nr {
                    self.lambda[t][off + i] += mu * cd.value[i];
                }
                // State-only rows (`h_u = 0`, the terminal ones) keep constant multipliers:
                // no control makes them hold to first order, there is no policy (III-B).
                let has_policy = t < n && cd.ju.col_iter().any(|c| c.iter().any(|&v| v != 0.0));
                if let (Some(lx), true) = (&mut self.lambda_x, has_policy) {
                    let mut l = lx[t].as_mut().subrows_mut(off, nr);
                    for j in 0..l.ncols() {
                        for i in 0..nr {
                            l[(i, j)] += mu * cd.jx[(i, j)];
                        }
                    }
                    matmul(l, Accum::Add, cd.ju.as_ref(), stages[t].K(), mu);
                }
                off += nr;
            }
        }
    }

    /// Terms of the expected decrease and the control gradient of the augmented
    /// Q-function (23) that the constraint rows of knot `t < N` add to those of its
    /// Riccati stage: with `ζ` the row multipliers of the step and
    /// `D k = diag(1/μ) ζ - d`, returns `(Δ_g, Δ_q)` contributions
    /// `(-μ dᵀ D k, -μ |D k|²)` and writes `Q_u^c = Q_u + μ Dᵀ d` into `qu`.
    pub fn condensed(knot: &LqKnot, st: &RiccatiStage, qu: &mut [f64]) -> (f64, f64) {
        qu.copy_from_slice(st.Q_u());
        let (mut dg, mut dq) = (0.0, 0.0);
        let zeta = st.zeta();
        for i in 0..knot.nc {
            let (m, d) = (knot.mu_c[i], knot.d[i]);
            let dk = m * zeta[i] - d;
            dg -= d * dk / m;
            dq -= dk * dk / m;
            for (j, g) in qu.iter_mut().enumerate() {
                *g += knot.D[(i, j)] * d / m;
            }
        }
        (dg, dq)
    }
}

//! Linear-quadratic (LQ) subproblems and their solvers.
//!
//! An [`LqProblem`] is a chain of knots `t = 0..=N`; knot `t` holds
//! ```text
//! cost         ½ [x; u]ᵀ [Q S; Sᵀ R] [x; u] + qᵀ x + rᵀ u
//! dynamics     A x_t + B u_t + E x_{t+1} + f - mu_dyn λ_{t+1} = 0      (t < N)
//! constraints  C x_t + D u_t + d - diag(mu_c) ν_t = 0
//! ```
//! and the problem an initial constraint `G0 x_0 + g0 - mu0 λ_0 = 0` (possibly with no
//! rows: then `x_0` is free). The last knot has `nu = 0` and no dynamics. The `mu`
//! terms are the proximal (dual) regularisation of the ProxDDP subproblem; with
//! `mu_dyn = 0`, `E = -I` and no constraints this is the classical LQR of DDP, FDDP
//! and SQP. The Lagrangian is
//! `Σ_t cost_t + λ_0ᵀ(G0 x_0 + g0) + Σ_t λ_{t+1}ᵀ(A x + B u + E x' + f) + ν_tᵀ(C x + D u + d)
//! - ½ mu0 |λ_0|² - ½ Σ mu_dyn |λ_{t+1}|² - ½ Σ ν_tᵀ diag(mu_c) ν_t`.
#![allow(non_snake_case)]

use faer::{Col, Mat};

/// One knot of an LQ problem. Matrix names follow the ProxDDP paper and the LQ literature.
#[derive(Debug, Clone)]
pub struct LqKnot {
    /// State (tangent) dimension at this knot.
    pub nx: usize,
    /// Control dimension (0 at the last knot).
    pub nu: usize,
    /// Number of constraint rows.
    pub nc: usize,
    /// State dimension of the next knot (0 at the last knot).
    pub nx_next: usize,
    /// Cost Hessian block `Q` (`nx x nx`).
    pub Q: Mat<f64>,
    /// Cost cross term `S` (`nx x nu`).
    pub S: Mat<f64>,
    /// Cost Hessian block `R` (`nu x nu`).
    pub R: Mat<f64>,
    /// Cost gradient `q` (`nx`).
    pub q: Col<f64>,
    /// Cost gradient `r` (`nu`).
    pub r: Col<f64>,
    /// Dynamics `A` (`nx_next x nx`).
    pub A: Mat<f64>,
    /// Dynamics `B` (`nx_next x nu`).
    pub B: Mat<f64>,
    /// Dynamics `E` (`nx_next x nx_next`), `-I` for explicit dynamics on vector spaces.
    pub E: Mat<f64>,
    /// Dynamics offset `f` (`nx_next`): the gap (defect) of the linearised dynamics.
    pub f: Col<f64>,
    /// Constraint Jacobian `C` (`nc x nx`).
    pub C: Mat<f64>,
    /// Constraint Jacobian `D` (`nc x nu`).
    pub D: Mat<f64>,
    /// Constraint offset `d` (`nc`).
    pub d: Col<f64>,
    /// Dual regularisation of the dynamics rows (`mu_dyn ≥ 0`).
    pub mu_dyn: f64,
    /// Dual regularisation of each constraint row (`mu_c ≥ 0`, `nc`).
    pub mu_c: Col<f64>,
}

impl LqKnot {
    /// A zero knot of the given dimensions with `E = -I`, `mu_dyn = 0` and `mu_c = 0`.
    pub fn new(nx: usize, nu: usize, nc: usize, nx_next: usize) -> Self {
        let mut E = Mat::zeros(nx_next, nx_next);
        for i in 0..nx_next {
            E[(i, i)] = -1.0;
        }
        Self {
            nx,
            nu,
            nc,
            nx_next,
            Q: Mat::zeros(nx, nx),
            S: Mat::zeros(nx, nu),
            R: Mat::zeros(nu, nu),
            q: Col::zeros(nx),
            r: Col::zeros(nu),
            A: Mat::zeros(nx_next, nx),
            B: Mat::zeros(nx_next, nu),
            E,
            f: Col::zeros(nx_next),
            C: Mat::zeros(nc, nx),
            D: Mat::zeros(nc, nu),
            d: Col::zeros(nc),
            mu_dyn: 0.0,
            mu_c: Col::zeros(nc),
        }
    }
}

/// A chain of LQ knots with an initial constraint.
#[derive(Debug, Clone)]
pub struct LqProblem {
    /// Knots `0..=N`; the last one has `nu = 0` and `nx_next = 0`.
    pub knots: Vec<LqKnot>,
    /// Initial constraint matrix `G0` (`nc0 x nx_0`).
    pub G0: Mat<f64>,
    /// Initial constraint offset `g0` (`nc0`).
    pub g0: Col<f64>,
    /// Dual regularisation of the initial constraint (`mu0 ≥ 0`).
    pub mu0: f64,
}

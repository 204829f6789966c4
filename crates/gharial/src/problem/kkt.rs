//! First-order optimality (KKT) residuals of a primal-dual point, computed from the
//! problem alone, independently of any solver.
//!
//! With the Lagrangian of [`crate::solvers::Solution`],
//! `L = J + λ_0ᵀ r_0(x_0) + Σ_t λ_{t+1}ᵀ f_t(x_t, u_t, x_{t+1}) + Σ_t ν_tᵀ h_t + ν_Nᵀ h_N`,
//! a KKT point satisfies (ProxDDP (24)-(25)):
//! - stationarity `∇_x L = 0`, `∇_u L = 0`;
//! - feasibility `r_0 = 0`, `f_t = 0`, `h ∈ C`;
//! - complementarity `ν ∈ N_C(h)`, measured by the natural residual
//!   `|h - proj_C(h + ν)|` (zero exactly when `ν` is in the normal cone of `C` at `h`;
//!   for penalty sets, when `ν ∈ ∂g(h)`).

use super::{Problem, ProblemData, StageConstraint};
use crate::error::{Result, check_dim};
use crate::functions::StageFunctionData;
use crate::linalg::norm_inf;

/// Infinity norms of the KKT conditions at a primal-dual point.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct KktResiduals {
    /// Initial condition residual `|r_0(x_0)|`.
    pub initial: f64,
    /// Largest dynamics gap `|f_t(x_t, u_t, x_{t+1})|`.
    pub dynamics: f64,
    /// Largest constraint violation `|h - proj_C(h)|` (0 for penalty sets).
    pub constraints: f64,
    /// Largest complementarity residual `|h - proj_C(h + ν)|`.
    pub complementarity: f64,
    /// Largest Lagrangian gradient entry `|∇_x L|`, `|∇_u L|`.
    pub stationarity: f64,
}

impl KktResiduals {
    /// The largest of all residuals.
    pub fn max(&self) -> f64 {
        self.initial
            .max(self.dynamics)
            .max(self.constraints)
            .max(self.complementarity)
            .max(self.stationarity)
    }

    /// Primal infeasibility: the largest of the initial, dynamics and constraint residuals.
    pub fn primal(&self) -> f64 {
        self.initial.max(self.dynamics).max(self.constraints)
    }
}

/// Folds the violation and complementarity residuals of a constraint stack into `res`.
fn constraint_residuals(cs: &[StageConstraint], data: &[StageFunctionData], nu: &[f64], res: &mut KktResiduals) {
    let mut off = 0;
    for (c, d) in cs.iter().zip(data) {
        let nr = c.nr();
        let h = d.value();
        let v = &nu[off..off + nr];
        res.constraints = res.constraints.max(c.set.violation(h));
        let z: Vec<f64> = h.iter().zip(v).map(|(a, b)| a + b).collect();
        let mut p = vec![0.0; nr];
        c.set.project(&z, 1.0, &mut p);
        for i in 0..nr {
            res.complementarity = res.complementarity.max((h[i] - p[i]).abs());
        }
        off += nr;
    }
}

/// KKT residuals of `(xs, us, lambdas, nus)` for `problem` (multiplier layout as in
/// [`crate::solvers::Solution`]).
///
/// # Errors
/// If a size is wrong or a value is not finite.
pub fn kkt_residuals(
    problem: &Problem,
    xs: &[Vec<f64>],
    us: &[Vec<f64>],
    lambdas: &[Vec<f64>],
    nus: &[Vec<f64>],
) -> Result<KktResiduals> {
    problem.check_trajectory(xs, us)?;
    problem.check_multipliers(Some(lambdas), Some(nus))?;
    let n = problem.horizon();
    check_dim("lambdas (N + 1)", n + 1, lambdas.len())?;
    let mut data = ProblemData::new(problem, 1)?;
    data.evaluate(problem, xs, us);
    data.compute_derivatives(problem, xs, us);
    let mut res = KktResiduals {
        initial: norm_inf(data.init.value()),
        ..Default::default()
    };
    let mut gx: Vec<Vec<f64>> = (0..=n).map(|t| vec![0.0; problem.space(t).ndx()]).collect();
    let mut gu: Vec<Vec<f64>> = (0..n).map(|t| vec![0.0; problem.nu(t)]).collect();
    data.lagrangian_gradient(problem, lambdas, nus, &mut gx, &mut gu);
    res.stationarity = gx.iter().chain(gu.iter()).fold(0.0, |a, g| a.max(norm_inf(g)));
    for t in 0..=n {
        if t < n {
            res.dynamics = res.dynamics.max(norm_inf(data.stages[t].dyn_value()));
        }
        constraint_residuals(problem.constraints(t), data.constraint_data(t), &nus[t], &mut res);
    }
    Ok(res)
}

//! Options of ALTRO, named as the paper and its reference implementation name them.

use std::time::Duration;

use crate::error::{Error, Result};
use crate::solvers::ddp::{DdpOptions, DdpVariant};
use crate::solvers::log::LogSink;

/// Options of [`super::Altro`].
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct AltroOptions {
    /// Largest constraint violation `c_max` of a converged solution (default `1e-6`; the
    /// paper's experiments use `1e-8`).
    pub constraint_tolerance: f64,
    /// The inner iLQR of the last outer iteration stops when the expected decrease of a
    /// full step is below this (default `1e-6`).
    pub cost_tolerance: f64,
    /// The same test for the inner solves before the constraints are met (default `1e-3`):
    /// coarse inner solves while the multipliers are far from optimal.
    pub cost_tolerance_intermediate: f64,
    /// Initial penalty `μ` of every constraint (Algorithm 1, line 2), multiplied by the
    /// constraint's scale (default 1).
    pub penalty_initial: f64,
    /// Penalty scaling `φ > 1` of (18) (default 10).
    pub penalty_scaling: f64,
    /// Largest penalty (default `1e8`).
    pub penalty_max: f64,
    /// Multipliers are clamped to `[-dual_max, dual_max]` (default `1e8`).
    pub dual_max: f64,
    /// Outer (multiplier update) iterations at most (default 30).
    pub iterations_outer: usize,
    /// Iterations of each inner iLQR solve at most (default 300).
    pub iterations_inner: usize,
    /// Backward pass on Cholesky factors (III-A; default false).
    pub square_root: bool,
    /// Finish with the objective-weighted Newton projection of Algorithm 2 (default true):
    /// AL-iLQR stops at `projected_newton_tolerance`, the projection takes the solution to
    /// `constraint_tolerance`.
    pub projected_newton: bool,
    /// Constraint tolerance of the AL-iLQR stage when the projection follows (default
    /// `1e-3`, the paper's coarse tolerance).
    pub projected_newton_tolerance: f64,
    /// Newton steps of the projection at most (default 30).
    pub projected_newton_steps: usize,
    /// Start from the guess's states, made feasible by slack controls (III-B; default
    /// false: the states are the rollout of the guess's controls). Explicit dynamics; on
    /// a Lie group the slack is a tangent vector at `f(x, u)`.
    pub infeasible_start: bool,
    /// Weight `R_s` of the slack cost `½R_s|s|²` (32) (default 1).
    pub slack_weight: f64,
    /// Regularisation and line search of the inner iLQR (the DDP of
    /// [`crate::solvers::ddp`], variant DDP; its `th_stop`, `max_iters`, `square_root`,
    /// `log` and `max_time` are set by ALTRO).
    pub inner: DdpOptions,
    /// Wall-time budget (default none).
    pub max_time: Option<Duration>,
    /// Where the iteration log goes (default nowhere): one line per outer iteration.
    pub log: LogSink,
}

impl Default for AltroOptions {
    fn default() -> Self {
        Self {
            constraint_tolerance: 1e-6,
            cost_tolerance: 1e-6,
            cost_tolerance_intermediate: 1e-3,
            penalty_initial: 1.0,
            penalty_scaling: 10.0,
            penalty_max: 1e8,
            dual_max: 1e8,
            iterations_outer: 30,
            iterations_inner: 300,
            square_root: false,
            projected_newton: true,
            projected_newton_tolerance: 1e-3,
            projected_newton_steps: 30,
            infeasible_start: false,
            slack_weight: 1.0,
            inner: DdpOptions::new(DdpVariant::Ddp),
            max_time: None,
            log: LogSink::Silent,
        }
    }
}

impl AltroOptions {
    /// These options changed by `f`: `AltroOptions::default().with(|o| o.square_root = true)`.
    pub fn with(mut self, f: impl FnOnce(&mut Self)) -> Self {
        f(&mut self);
        self
    }

    /// Checks every option's range.
    ///
    /// # Errors
    /// Names the offending option and its valid range.
    pub fn validate(&self) -> Result<()> {
        let pos = crate::error::check_positive;
        pos("constraint_tolerance", self.constraint_tolerance)?;
        pos("cost_tolerance", self.cost_tolerance)?;
        pos("cost_tolerance_intermediate", self.cost_tolerance_intermediate)?;
        pos("penalty_initial", self.penalty_initial)?;
        pos("penalty_max", self.penalty_max)?;
        pos("dual_max", self.dual_max)?;
        pos("projected_newton_tolerance", self.projected_newton_tolerance)?;
        pos("slack_weight", self.slack_weight)?;
        if !(self.penalty_scaling.is_finite() && self.penalty_scaling > 1.0) {
            return Err(Error::option("penalty_scaling", "must be finite and greater than 1"));
        }
        if self.penalty_initial > self.penalty_max {
            return Err(Error::option("penalty_initial", "must be at most penalty_max"));
        }
        if self.iterations_outer == 0 || self.iterations_inner == 0 {
            return Err(Error::option(
                "iterations_outer / iterations_inner",
                "must be at least 1",
            ));
        }
        if self.inner.variant != DdpVariant::Ddp {
            return Err(Error::option("inner.variant", "ALTRO's inner solver is iLQR (ddp)"));
        }
        self.inner.validate()
    }
}

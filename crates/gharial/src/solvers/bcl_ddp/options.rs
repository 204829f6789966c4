//! Options of BCL-DDP, with documented defaults.

use std::time::Duration;

use crate::error::{Error, Result};
use crate::solvers::ddp::{DdpOptions, DdpVariant};
use crate::solvers::log::LogSink;

/// How the multipliers depend on the state (El Kazdadi et al. 2021, III).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Multipliers {
    /// Globally constant multipliers `λ_t` (III-A): the augmented Lagrangian (22), the
    /// update (24).
    #[default]
    Constant,
    /// Locally affine multipliers `λ_t(x) = λ_t + Λ_t (x ⊖ x_t)` (25) (III-B): the
    /// augmented Lagrangian (26), the Q-function terms (27), the update (28) with the
    /// feedback gains; the multipliers' origin follows each accepted step.
    Affine,
}

/// How the penalty `μ` grows when the constraints did not decrease enough.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PenaltyUpdate {
    /// `μ ← k μ` with `k` = [`BclDdpOptions::penalty_factor`] (Alg. 1).
    #[default]
    Factor,
    /// The adaptive rate of II-C ("imposing a desired convergence rate"): with `c'` the
    /// violation at the last multiplier update (initially at the guess), the rate
    /// `φ = μ |h| / c'` and the penalty `μ ← φ^{1/(1-β)}` that gives the rate
    /// `μ^{-β}`, `β` = [`BclDdpOptions::adaptive_beta`], kept within
    /// `[k μ, max_growth μ]` (the growth cap of IV-A, `μ_{n+1} < 10⁶ μ_n`).
    Adaptive,
}

/// When the multipliers and the penalty change.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Schedule {
    /// The bound-constrained Lagrangian (Alg. 1, 2): only once the augmented Lagrangian
    /// is minimised to `ω`; the multipliers if the violation is below `η`, else the
    /// penalty.
    #[default]
    Bcl,
    /// After every DDP iteration, the multiplier update and `μ ← k μ` (the strategy of
    /// ALTRO's first stage; Fig. 4 of the paper shows it failing). For comparisons.
    EveryIteration,
}

/// Options of [`super::BclDdp`].
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct BclDdpOptions {
    /// Tolerance on the constraint violation `|h|_∞` and on the control gradient of the
    /// Lagrangian `|∇_u L|_∞` (default `1e-6`).
    pub tol: f64,
    /// DDP iterations (backward passes followed by a line search or an outer update) at
    /// most (default 500).
    pub max_iters: usize,
    /// Initial penalty `μ_0` (default 10).
    pub mu_init: f64,
    /// Largest penalty: an increase stops there, and one asked at this value stops the
    /// solve as [`crate::solvers::Status::Stalled`] (default `1e12`).
    pub mu_max: f64,
    /// Initial constraint tolerance `η_0` of Alg. 1 (default `0.1`).
    pub eta_init: f64,
    /// Initial gradient tolerance `ω_0` of Alg. 1 (default `0.1`).
    pub omega_init: f64,
    /// Exponent `α` of Alg. 1: `η ← η / μ^α` after a multiplier update (default 0.9).
    pub bcl_alpha: f64,
    /// Constant or affine multipliers (default constant).
    pub multipliers: Multipliers,
    /// Penalty growth (default the fixed factor).
    pub penalty: PenaltyUpdate,
    /// The factor `k > 1` of a penalty increase (default 10).
    pub penalty_factor: f64,
    /// `β ∈ (0, 1)` of the adaptive penalty: the desired rate `μ^{-β}` (default 0.5).
    pub adaptive_beta: f64,
    /// Cap of the adaptive penalty's growth in one update (default `1e6`, the paper's).
    pub max_growth: f64,
    /// When the multipliers and penalty change (default the BCL rules).
    pub schedule: Schedule,
    /// The inner DDP: its variant (DDP, the paper's single shooting, the default; or
    /// FDDP, multiple shooting as in III-C), regularisation, line search, threads and
    /// implicit solves. Its `tol`, `th_stop`, `max_iters`, `max_time` and `log` are not
    /// used.
    pub ddp: DdpOptions,
    /// Wall-time budget (default none).
    pub max_time: Option<Duration>,
    /// Where the iteration log goes (default nowhere).
    pub log: LogSink,
}

impl Default for BclDdpOptions {
    fn default() -> Self {
        Self {
            tol: 1e-6,
            max_iters: 500,
            mu_init: 10.0,
            mu_max: 1e12,
            eta_init: 0.1,
            omega_init: 0.1,
            bcl_alpha: 0.9,
            multipliers: Multipliers::Constant,
            penalty: PenaltyUpdate::Factor,
            penalty_factor: 10.0,
            adaptive_beta: 0.5,
            max_growth: 1e6,
            schedule: Schedule::Bcl,
            ddp: DdpOptions::new(DdpVariant::Ddp),
            max_time: None,
            log: LogSink::Silent,
        }
    }
}

impl BclDdpOptions {
    /// These options changed by `f` (the struct is `#[non_exhaustive]`:
    /// `BclDdpOptions::default().with(|o| o.tol = 1e-8)`).
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
        pos("tol", self.tol)?;
        pos("eta_init", self.eta_init)?;
        pos("omega_init", self.omega_init)?;
        if self.max_iters == 0 {
            return Err(Error::option("max_iters", "must be at least 1"));
        }
        if !(self.mu_init.is_finite() && self.mu_init >= 1.0) {
            return Err(Error::option(
                "mu_init",
                "must be finite and at least 1 (Alg. 1 divides the tolerances by powers of mu)",
            ));
        }
        if !(self.mu_max.is_finite() && self.mu_max >= self.mu_init) {
            return Err(Error::option("mu_max", "must be finite and at least mu_init"));
        }
        for (name, v) in [("bcl_alpha", self.bcl_alpha), ("adaptive_beta", self.adaptive_beta)] {
            if !(v > 0.0 && v < 1.0) {
                return Err(Error::option(name, "must be in (0, 1)"));
            }
        }
        for (name, v) in [("penalty_factor", self.penalty_factor), ("max_growth", self.max_growth)] {
            if !(v.is_finite() && v > 1.0) {
                return Err(Error::option(name, "must be finite and greater than 1"));
            }
        }
        if self.max_growth < self.penalty_factor {
            return Err(Error::option("max_growth", "must be at least penalty_factor"));
        }
        if !matches!(self.ddp.variant, DdpVariant::Ddp | DdpVariant::Fddp) {
            return Err(Error::option(
                "ddp.variant",
                format!(
                    "the inner solver of bcl-ddp is ddp or fddp, not {}",
                    self.ddp.variant.name()
                ),
            ));
        }
        if self.ddp.hessian != crate::solvers::HessianApprox::GaussNewton {
            return Err(Error::option(
                "ddp.hessian",
                "bcl-ddp implements the Gauss-Newton Hessian only",
            ));
        }
        self.ddp.validate()
    }
}

//! Options of ProxNLP: ProxDDP's names and defaults where the concept is the same.

use std::time::Duration;

use crate::error::Result;
use crate::solvers::HessianApprox;
use crate::solvers::linesearch::LinesearchOptions;
use crate::solvers::log::LogSink;
use crate::solvers::proxddp::{ProxDdpOptions, StepAcceptance};

/// How ProxNLP solves its primal-dual Newton system (both by LDLᵀ with the multiplier
/// rows first and the inertia read off `D`; see [`super`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum KktSolver {
    /// The whole matrix, densely (at most [`super::MAX_KKT_DIM`] rows).
    Dense,
    /// faer's sparse LDLᵀ, the primal variables in AMD order, the symbolic factorization
    /// made once in `setup` (for optimal control problems and other sparse NLPs).
    Sparse,
    /// Sparse when the system has more than [`super::AUTO_SPARSE_DIM`] rows and its
    /// derivative blocks fill at most a tenth of it, dense otherwise (default).
    #[default]
    Auto,
}

/// Options of [`super::ProxNlp`]; each field other than `kkt` has the name, meaning and default of the
/// [`ProxDdpOptions`] field of the same name.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct ProxNlpOptions {
    /// Target tolerance on the primal and dual residuals (default `1e-6`).
    pub tol: f64,
    /// Initial augmented-Lagrangian penalty `mu_0` (default `1e-2`).
    pub mu_init: f64,
    /// Factor applied to `mu` when the primal residual misses its BCL tolerance
    /// (default `0.01`).
    pub mu_update_factor: f64,
    /// Lower bound on `mu` (default `1e-8`).
    pub mu_lower_bound: f64,
    /// BCL exponent `α_ω` (default 1).
    pub bcl_alpha_omega: f64,
    /// BCL exponent `α_η` (default 0.9).
    pub bcl_alpha_eta: f64,
    /// BCL exponent `β_ω` (default 1).
    pub bcl_beta_omega: f64,
    /// BCL exponent `β_η` (default 0.1).
    pub bcl_beta_eta: f64,
    /// Maximum number of Newton iterations (default 300).
    pub max_iters: usize,
    /// Maximum number of augmented-Lagrangian (outer) iterations (default 100).
    pub max_al_iters: usize,
    /// Step acceptance (default: the filter, whose first step of each subproblem is taken
    /// whole so that semi-smooth Newton steps cross the kinks of the merit function).
    pub step_acceptance: StepAcceptance,
    /// Averaging weight of the nonmonotone line search (default 0.85).
    pub nonmonotone_eta: f64,
    /// Hessian approximation (default Gauss-Newton: the cost Hessian alone).
    pub hessian: HessianApprox,
    /// Armijo line-search options.
    pub linesearch: LinesearchOptions,
    /// First nonzero primal regularisation (default `1e-9`).
    pub preg_min: f64,
    /// Largest primal regularisation before giving up (default `1e9`).
    pub preg_max: f64,
    /// Growth factor of the primal regularisation (default 10).
    pub preg_increase: f64,
    /// Shrink factor of the primal regularisation after a successful step (default 1/3).
    pub preg_decrease: f64,
    /// The subproblem counts as solved to round-off when the merit slope along the Newton
    /// direction is below `dphi_thresh · max(1, |merit|)` (default `1e-13`).
    pub dphi_thresh: f64,
    /// Penalty scale of the initial-condition and dynamics blocks of an optimal control
    /// problem solved through [`super::ProxNlpOcp`] (ProxDDP's `dyn_al_scale`, default
    /// `1e-3`); generic NLPs give each block its own scale.
    pub dyn_al_scale: f64,
    /// Wall-time budget; the best iterate so far is returned when it runs out.
    pub max_time: Option<Duration>,
    /// Where the iteration table and the outer-loop updates are written (default:
    /// nowhere).
    pub log: LogSink,
    /// How the Newton system is solved (default [`KktSolver::Auto`]).
    pub kkt: KktSolver,
}

impl Default for ProxNlpOptions {
    fn default() -> Self {
        Self::from(&ProxDdpOptions::default())
    }
}

impl From<&ProxDdpOptions> for ProxNlpOptions {
    /// The ProxDDP options that ProxNLP shares (tolerance, penalty schedule, BCL
    /// exponents, limits, Hessian, line search, regularisation, time budget, log); the
    /// KKT solve is [`KktSolver::Auto`].
    fn from(o: &ProxDdpOptions) -> Self {
        Self {
            tol: o.tol,
            mu_init: o.mu_init,
            mu_update_factor: o.mu_update_factor,
            mu_lower_bound: o.mu_lower_bound,
            bcl_alpha_omega: o.bcl_alpha_omega,
            bcl_alpha_eta: o.bcl_alpha_eta,
            bcl_beta_omega: o.bcl_beta_omega,
            bcl_beta_eta: o.bcl_beta_eta,
            max_iters: o.max_iters,
            max_al_iters: o.max_al_iters,
            step_acceptance: o.step_acceptance,
            nonmonotone_eta: o.nonmonotone_eta,
            hessian: o.hessian,
            linesearch: o.linesearch,
            preg_min: o.preg_min,
            preg_max: o.preg_max,
            preg_increase: o.preg_increase,
            preg_decrease: o.preg_decrease,
            dphi_thresh: o.dphi_thresh,
            dyn_al_scale: o.dyn_al_scale,
            max_time: o.max_time,
            log: o.log.clone(),
            kkt: KktSolver::default(),
        }
    }
}

impl ProxNlpOptions {
    /// These options changed by `f` (`ProxNlpOptions::default().with(|o| o.tol = 1e-9)`).
    pub fn with(mut self, f: impl FnOnce(&mut Self)) -> Self {
        f(&mut self);
        self
    }

    /// Checks every option's range: the ranges of the ProxDDP options of the same names.
    ///
    /// # Errors
    /// Names the offending option and its valid range.
    pub fn validate(&self) -> Result<()> {
        ProxDdpOptions::default()
            .with(|o| {
                o.tol = self.tol;
                o.mu_init = self.mu_init;
                o.mu_update_factor = self.mu_update_factor;
                o.mu_lower_bound = self.mu_lower_bound;
                o.bcl_alpha_omega = self.bcl_alpha_omega;
                o.bcl_alpha_eta = self.bcl_alpha_eta;
                o.bcl_beta_omega = self.bcl_beta_omega;
                o.bcl_beta_eta = self.bcl_beta_eta;
                o.max_iters = self.max_iters;
                o.max_al_iters = self.max_al_iters;
                o.linesearch = self.linesearch;
                o.nonmonotone_eta = self.nonmonotone_eta;
                o.preg_min = self.preg_min;
                o.preg_max = self.preg_max;
                o.preg_increase = self.preg_increase;
                o.preg_decrease = self.preg_decrease;
                o.dphi_thresh = self.dphi_thresh;
                o.dyn_al_scale = self.dyn_al_scale;
            })
            .validate()
    }
}

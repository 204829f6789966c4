//! Options of the ProxDDP solver, with documented defaults.

use std::time::Duration;

use crate::error::{Error, Result};
use crate::solvers::linesearch::LinesearchOptions;

/// How the trial point of a step is built (paper section IV-C).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Rollout {
    /// The SQP step itself: `x ⊕ α δx`, `u + α δu`, multipliers `+ α δ` (eq. (50)).
    #[default]
    Linear,
    /// A closed-loop rollout of the nonlinear dynamics with the Riccati gains (eq. (51));
    /// implicit dynamics are solved for the next state with Newton-Raphson.
    Nonlinear,
}

/// How a step is accepted (globalisation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum StepAcceptance {
    /// Armijo backtracking on the merit function.
    Linesearch,
    /// Armijo backtracking against the Zhang-Hager average of past merit values.
    NonmonotoneLinesearch,
    /// Filter on (merit, primal infeasibility) (the default): the first step of each
    /// subproblem is taken whole, so that semi-smooth Newton steps can cross the kinks
    /// of the augmented Lagrangian where constraints become active.
    #[default]
    Filter,
}

/// Which merit function the step acceptance uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Merit {
    /// The primal-dual augmented Lagrangian (17), searched over `(x, u, λ, ν)`.
    #[default]
    PrimalDual,
    /// The primal augmented Lagrangian (35), searched over `(x, u)`; multipliers follow
    /// the step.
    Primal,
}

pub use crate::solvers::HessianApprox;

/// How the Newton step treats the dynamics `f(x, u, y) = 0`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DynamicsStep {
    /// [`Exact`](Self::Exact) on problems without path or terminal constraints,
    /// [`Proximal`](Self::Proximal) otherwise (the default). A solve that starts with the
    /// exact step switches to the proximal one for its remaining iterations at the first
    /// exact step that does not descend the merit (co-states far from their estimates
    /// `λ_e + f / mu_d`, as on a floating base without contacts), where `Exact` alone
    /// regularises until the line search fails.
    #[default]
    Auto,
    /// The proximal step of the paper, (42): the dynamics rows carry the dual
    /// regularisation `mu_d = dyn_al_scale · mu`, so a step leaves a residual
    /// `mu_d (λ⁺ - λ_e)` even on linear dynamics.
    Proximal,
    /// The dynamics rows without regularisation (the LQ solve does not need it: `df/dy`
    /// is invertible): a step satisfies the linearised dynamics exactly, so one iteration
    /// solves an unconstrained LQ problem to round-off. With constraints the step no
    /// longer matches the proximal merit's model, which slows some problems down.
    Exact,
}

/// Options of [`super::ProxDdp`].
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct ProxDdpOptions {
    /// Target tolerance on the primal (53) and dual (52) residuals (default `1e-6`).
    pub tol: f64,
    /// Initial augmented-Lagrangian penalty `mu_0` (default `1e-2`).
    pub mu_init: f64,
    /// Factor applied to `mu` when the primal residual misses its BCL tolerance
    /// (default `0.01`).
    pub mu_update_factor: f64,
    /// Lower bound on `mu` (default `1e-8`).
    pub mu_lower_bound: f64,
    /// Scale of the dynamics and initial-condition penalty relative to `mu`
    /// (appendix C; default `1e-3`, the paper's value for its acrobot and aligator's
    /// default). A small scale keeps the LQ step close to exact on the dynamics rows, so
    /// that a linear model is feasible after one step; measured against a scale of 1:
    /// quadrotor 108 → 81 iterations, quadrotor-slalom 173 → 103, pendulum 24 → 19,
    /// peers-lqr 2 → 1.
    pub dyn_al_scale: f64,
    /// BCL exponent of the inner tolerance `omega` after a successful outer step
    /// (`α_ω` of Algorithm 2, default 1).
    pub bcl_alpha_omega: f64,
    /// BCL exponent of the primal tolerance `eta` after a successful outer step
    /// (`α_η`, default 0.9, Conn, Gould and Toint's value): with a large penalty
    /// (`mu_init = 0.1` or 1), a smaller exponent keeps `eta` loose for many outer steps
    /// while the subproblems are solved ever more accurately (`omega` shrinks by `mu`
    /// each time), and `mu` is not decreased when the infeasibility stalls. The factor
    /// `mu^α_η` is bounded below by `1e-2` (small penalties).
    pub bcl_alpha_eta: f64,
    /// BCL exponent of `omega` after a failed outer step (`β_ω`, default 1).
    pub bcl_beta_omega: f64,
    /// BCL exponent of `eta` after a failed outer step (`β_η`, default 0.1).
    pub bcl_beta_eta: f64,
    /// Maximum number of Newton iterations (default 300).
    pub max_iters: usize,
    /// Maximum number of augmented-Lagrangian (outer) iterations (default 100).
    pub max_al_iters: usize,
    /// Forward pass (default linear).
    pub rollout: Rollout,
    /// Step acceptance (default: filter).
    pub step_acceptance: StepAcceptance,
    /// Merit function (default primal-dual).
    pub merit: Merit,
    /// Hessian approximation (default Gauss-Newton).
    pub hessian: HessianApprox,
    /// How the Newton step treats the dynamics (default [`DynamicsStep::Auto`]).
    pub dynamics_step: DynamicsStep,
    /// Line-search options.
    pub linesearch: LinesearchOptions,
    /// Averaging weight of the nonmonotone line search (default 0.85).
    pub nonmonotone_eta: f64,
    /// First nonzero primal regularisation tried when the Newton system has the wrong
    /// inertia or the step is not a descent direction (default `1e-9`).
    pub preg_min: f64,
    /// Largest primal regularisation before giving up (default `1e9`).
    pub preg_max: f64,
    /// Growth factor of the primal regularisation (default 10).
    pub preg_increase: f64,
    /// Shrink factor of the primal regularisation after a successful step (default 1/3).
    pub preg_decrease: f64,
    /// Newton iterations of the implicit-dynamics solve in the nonlinear rollout
    /// (default 20) and its tolerance (default `1e-12`).
    pub implicit_newton_iters: usize,
    /// Tolerance of the implicit-dynamics Newton solve (default `1e-12`).
    pub implicit_newton_tol: f64,
    /// The subproblem counts as solved when the merit slope along the Newton direction
    /// is below `dphi_thresh · max(1, |merit|)` (round-off level; default `1e-13`).
    pub dphi_thresh: f64,
    /// Watchdog (Chamberlain et al. 1982, as in IPOPT): after this many consecutive
    /// shortened steps (`α < 1`) in one subproblem, full steps are taken tentatively, so
    /// that Newton steps are not cut short by the curvature of the merit function (the
    /// Maratos effect). 0 disables it (default 10, as IPOPT).
    pub watchdog_trigger: usize,
    /// Tentative full steps of a watchdog phase (default 3): the phase succeeds when a
    /// full step reaches the Armijo decrease of the merit relative to the point the phase
    /// started from; otherwise that point is restored and searched as usual, and the
    /// trigger of the subproblem doubles.
    pub watchdog_trials: usize,
    /// Active-set prediction of the step: at most this many further semi-smooth Newton
    /// iterations on each LQ subproblem after the Newton step, each one LQ solve with the
    /// constraint rows linearised at the previous step's full-step constraint values
    /// instead of at the current point, until the step solves the subproblem with the
    /// projections onto the constraint sets (for polyhedral sets, the primal-dual
    /// active-set method: until the active set stops changing). The Newton step sees a
    /// bound only once it is active at the current point; the prediction sees the bounds
    /// the full step reaches, so that the step stops at them instead of overshooting.
    /// A predicted step that is not a descent direction for the merit function is
    /// replaced by the Newton step. 0 disables it (default 0; at most
    /// [`ACTIVE_SET_ITERS_MAX`]).
    pub active_set_iters: usize,
    /// Wall-time budget, checked between iterations (an iteration that has started
    /// finishes); the best iterate so far is returned when it runs out.
    pub max_time: Option<Duration>,
    /// Whether a solve that ends at `max_iters` right after a step evaluates the
    /// derivatives and residuals at the point it returns (default true). Off, it returns
    /// [`Status::MaxIterations`](crate::solvers::Status::MaxIterations) with the residuals
    /// of the point before the last step and saves one derivative evaluation: for
    /// receding horizons, whose next cycle evaluates the shifted problem anyway
    /// ([`crate::mpc::MpcOptions::final_residuals`]).
    pub final_residuals: bool,
    /// Threads for stage-wise evaluation (default 1).
    pub num_threads: usize,
    /// Where the iteration table and the outer-loop updates are written (default:
    /// nowhere).
    pub log: crate::solvers::log::LogSink,
}

/// The largest [`ProxDdpOptions::active_set_iters`]: each iteration is an LQ solve, and
/// for cones (whose active set need not settle in finitely many steps) the count is the
/// only bound.
pub const ACTIVE_SET_ITERS_MAX: usize = 100;

impl Default for ProxDdpOptions {
    fn default() -> Self {
        Self {
            tol: 1e-6,
            mu_init: 1e-2,
            mu_update_factor: 0.01,
            mu_lower_bound: 1e-8,
            dyn_al_scale: 1e-3,
            bcl_alpha_omega: 1.0,
            bcl_alpha_eta: 0.9,
            bcl_beta_omega: 1.0,
            bcl_beta_eta: 0.1,
            max_iters: 300,
            max_al_iters: 100,
            rollout: Rollout::Linear,
            step_acceptance: StepAcceptance::Filter,
            merit: Merit::PrimalDual,
            hessian: HessianApprox::GaussNewton,
            dynamics_step: DynamicsStep::Auto,
            linesearch: LinesearchOptions::default(),
            nonmonotone_eta: 0.85,
            preg_min: 1e-9,
            preg_max: 1e9,
            preg_increase: 10.0,
            preg_decrease: 1.0 / 3.0,
            implicit_newton_iters: 20,
            implicit_newton_tol: 1e-12,
            dphi_thresh: 1e-13,
            watchdog_trigger: 10,
            watchdog_trials: 3,
            active_set_iters: 0,
            max_time: None,
            final_residuals: true,
            num_threads: 1,
            log: crate::solvers::log::LogSink::Silent,
        }
    }
}

impl ProxDdpOptions {
    /// These options changed by `f` (the struct is `#[non_exhaustive]`, so that new
    /// options do not break users: `ProxDdpOptions::default().with(|o| o.tol = 1e-8)`).
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
        pos("mu_init", self.mu_init)?;
        pos("mu_lower_bound", self.mu_lower_bound)?;
        pos("dyn_al_scale", self.dyn_al_scale)?;
        pos("preg_min", self.preg_min)?;
        pos("preg_max", self.preg_max)?;
        pos("implicit_newton_tol", self.implicit_newton_tol)?;
        pos("dphi_thresh", self.dphi_thresh)?;
        if !(self.mu_update_factor > 0.0 && self.mu_update_factor < 1.0) {
            return Err(Error::option("mu_update_factor", "must be in (0, 1)"));
        }
        if self.mu_lower_bound > self.mu_init {
            return Err(Error::option("mu_lower_bound", "must not exceed mu_init"));
        }
        for (name, v) in [
            ("bcl_alpha_omega", self.bcl_alpha_omega),
            ("bcl_alpha_eta", self.bcl_alpha_eta),
            ("bcl_beta_omega", self.bcl_beta_omega),
            ("bcl_beta_eta", self.bcl_beta_eta),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::option(name, "must be finite and non-negative"));
            }
        }
        if self.max_iters == 0 {
            return Err(Error::option("max_iters", "must be at least 1"));
        }
        if self.max_al_iters == 0 {
            return Err(Error::option("max_al_iters", "must be at least 1"));
        }
        if !(self.preg_increase.is_finite() && self.preg_increase > 1.0) {
            return Err(Error::option("preg_increase", "must be finite and greater than 1"));
        }
        if !(self.preg_decrease > 0.0 && self.preg_decrease < 1.0) {
            return Err(Error::option("preg_decrease", "must be in (0, 1)"));
        }
        if self.preg_min > self.preg_max {
            return Err(Error::option("preg_min", "must not exceed preg_max"));
        }
        if !(0.0..=1.0).contains(&self.nonmonotone_eta) {
            return Err(Error::option("nonmonotone_eta", "must be in [0, 1]"));
        }
        if self.active_set_iters > ACTIVE_SET_ITERS_MAX {
            return Err(Error::option(
                "active_set_iters",
                format!("must be at most {ACTIVE_SET_ITERS_MAX}"),
            ));
        }
        if self.num_threads == 0 {
            return Err(Error::option("num_threads", "must be at least 1"));
        }
        self.linesearch.validate()
    }
}

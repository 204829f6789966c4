//! Options of the DDP family, with documented defaults (crocoddyl's where it has one).

use std::time::Duration;

use crate::error::{Error, Result};
use crate::problem::ImplicitSolve;
use crate::solvers::HessianApprox;
use crate::solvers::boxqp::BoxQpOptions;
use crate::solvers::log::LogSink;

/// Which member of the DDP family runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DdpVariant {
    /// DDP / iLQR: single shooting, every trial a rollout from `x_0` (Tassa et al. 2012).
    Ddp,
    /// Feasibility-driven DDP (Mastalli et al. 2020): multiple shooting, gaps closed in
    /// proportion to the step, infeasible initial guesses.
    #[default]
    Fddp,
    /// DDP with control bounds: projected-Newton box QP on `Q_uu` in the backward pass,
    /// clamped controls in the rollout (Tassa, Mansard and Todorov 2014).
    BoxDdp,
    /// FDDP with control bounds (Mastalli et al. 2022).
    BoxFddp,
    /// Stagewise SQP, Gauss-Newton multiple shooting (Jordana et al. 2023, GNMS): the
    /// step of the LQ subproblem by a linear rollout, a filter line search on cost and
    /// gaps, the KKT residual (20) as stopping test.
    Sqp,
}

impl DdpVariant {
    /// Every variant, in the order of [`DdpVariant::name`]'s documentation.
    pub const ALL: [DdpVariant; 5] = [
        DdpVariant::Ddp,
        DdpVariant::Fddp,
        DdpVariant::BoxDdp,
        DdpVariant::BoxFddp,
        DdpVariant::Sqp,
    ];

    /// The solver name: `ddp`, `fddp`, `box-ddp`, `box-fddp`, `sqp`.
    pub fn name(self) -> &'static str {
        match self {
            DdpVariant::Ddp => "ddp",
            DdpVariant::Fddp => "fddp",
            DdpVariant::BoxDdp => "box-ddp",
            DdpVariant::BoxFddp => "box-fddp",
            DdpVariant::Sqp => "sqp",
        }
    }

    /// The variant of a solver name (see [`DdpVariant::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|v| v.name() == name)
    }

    /// Whether gaps are kept open and closed in proportion to the step (FDDP).
    pub fn multiple_shooting(self) -> bool {
        matches!(self, DdpVariant::Fddp | DdpVariant::BoxFddp)
    }

    /// Whether the step is the LQ subproblem's, applied by a linear rollout, with a
    /// filter line search and the KKT stopping test (SQP).
    pub fn linear_rollout(self) -> bool {
        self == DdpVariant::Sqp
    }

    /// Whether control bounds are handled (box-DDP, box-FDDP).
    pub fn control_bounds(self) -> bool {
        matches!(self, DdpVariant::BoxDdp | DdpVariant::BoxFddp)
    }
}

/// Options of [`super::Ddp`].
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct DdpOptions {
    /// Which solver of the family (default FDDP).
    pub variant: DdpVariant,
    /// Tolerance: the solve has converged when the gaps are closed and the expected cost
    /// decrease of a full step, `|Δ₁ + ½Δ₂|`, is below `tol² N` (crocoddyl's `th_stop`
    /// with the mapping of aligator's crocoddyl benchmark); for SQP, when the KKT residual
    /// (20) is below `tol`. Default `1e-6`.
    pub tol: f64,
    /// A threshold on `|Δ₁ + ½Δ₂|` used instead of `tol² N` (crocoddyl's `th_stop`).
    pub th_stop: Option<f64>,
    /// Iterations at most (default 300).
    pub max_iters: usize,
    /// Hessian of the backward pass: Gauss-Newton (iLQR, the default) or with the
    /// dynamics' second derivatives weighted by the next value gradient, `V_x'·f_zz`
    /// (classical DDP, Tassa et al. 2012), added while the gaps are closed. The exact
    /// terms need explicit dynamics with vector-Hessian products onto a vector space (the
    /// dual-number adapter [`crate::autodiff::AutoDiff::explicit_dynamics`], or a model's
    /// own `vhp`); `setup` refuses other problems, and SQP takes Gauss-Newton only.
    pub hessian: HessianApprox,
    /// Initial Levenberg-Marquardt regularisation, added to `Q_uu` and `V_xx`
    /// (default 0: exact steps while `Q_uu` is positive definite, so that one step solves
    /// an LQ problem exactly; crocoddyl starts at `1e-9`).
    pub reg_init: f64,
    /// Smallest nonzero regularisation: the first increase from 0 goes to it, a decrease
    /// below it goes to 0 (default `1e-9`).
    pub reg_min: f64,
    /// Largest regularisation; reaching it stops the solve (default `1e9`).
    pub reg_max: f64,
    /// Convergence is declared only while the regularisation is at most this (default
    /// `1e-6`): a heavily regularised step is short, and its small expected decrease says
    /// nothing about optimality. Below `tol² N` with a larger regularisation, the solve
    /// stops as [`crate::solvers::Status::Stalled`].
    pub reg_converged: f64,
    /// Factor of a regularisation increase (default 10).
    pub reg_increase: f64,
    /// Divisor of a regularisation decrease (default 10).
    pub reg_decrease: f64,
    /// The regularisation decreases after a step longer than this (default 0.5).
    pub step_decrease_reg: f64,
    /// The regularisation increases after a step at most this long (default 0.01).
    pub step_increase_reg: f64,
    /// Step lengths tried: `1, 1/2, ..., 2^-(linesearch_steps - 1)` (default 10).
    pub linesearch_steps: usize,
    /// Armijo fraction of the expected decrease a step must achieve (default 0.1).
    pub th_accept: f64,
    /// FDDP only: a step whose expected change is an increase (`ΔV_exp < 0`, while gaps
    /// close) is accepted if the cost grows less than this multiple of it (default 2).
    pub th_accept_neg: f64,
    /// Any descent step is accepted when `|Δ₁|` is below this (default `1e-12`).
    pub th_grad: f64,
    /// Gaps of the initial guess up to this size count as closed (default `1e-12`).
    pub gap_tol: f64,
    /// SQP, and FDDP with `filter_linesearch`: the filter's memory, the number of past
    /// (cost, gap) pairs a trial must not be dominated by (default 1: better cost or
    /// smaller gaps than the current point).
    pub filter_size: usize,
    /// FDDP and box-FDDP: accept trials by the filter of SQP's line search instead of
    /// crocoddyl's Armijo rules ("FDDP (filter LS)" of Jordana et al. 2023; default
    /// false).
    pub filter_linesearch: bool,
    /// The box QP of the box variants.
    pub box_qp: BoxQpOptions,
    /// Backward pass on Cholesky factors of the value Hessians (ALTRO's square-root pass,
    /// [`crate::lq::RiccatiSolver::backward_square_root`]) instead of the plain Riccati
    /// recursion (default false). DDP, FDDP and SQP on vector-space states with explicit
    /// dynamics.
    pub square_root: bool,
    /// Newton-Raphson solve of implicit dynamics in the rollouts.
    pub implicit: ImplicitSolve,
    /// Wall-time budget (default none).
    pub max_time: Option<Duration>,
    /// Threads of the stage-wise derivative evaluation (default 1).
    pub num_threads: usize,
    /// Where the iteration log goes (default nowhere).
    pub log: LogSink,
}

impl Default for DdpOptions {
    fn default() -> Self {
        Self {
            variant: DdpVariant::default(),
            tol: 1e-6,
            th_stop: None,
            max_iters: 300,
            hessian: HessianApprox::GaussNewton,
            reg_init: 0.0,
            reg_min: 1e-9,
            reg_max: 1e9,
            reg_converged: 1e-6,
            reg_increase: 10.0,
            reg_decrease: 10.0,
            step_decrease_reg: 0.5,
            step_increase_reg: 0.01,
            linesearch_steps: 10,
            th_accept: 0.1,
            th_accept_neg: 2.0,
            th_grad: 1e-12,
            gap_tol: 1e-12,
            filter_size: 1,
            filter_linesearch: false,
            box_qp: BoxQpOptions::default(),
            square_root: false,
            implicit: ImplicitSolve::default(),
            max_time: None,
            num_threads: 1,
            log: LogSink::Silent,
        }
    }
}

impl DdpOptions {
    /// These options changed by `f` (the struct is `#[non_exhaustive]`, so that new
    /// options do not break users: `DdpOptions::default().with(|o| o.tol = 1e-8)`).
    pub fn with(mut self, f: impl FnOnce(&mut Self)) -> Self {
        f(&mut self);
        self
    }

    /// Default options of `variant`.
    pub fn new(variant: DdpVariant) -> Self {
        Self {
            variant,
            ..Self::default()
        }
    }

    /// Checks every option's range.
    ///
    /// # Errors
    /// Names the offending option and its valid range.
    pub fn validate(&self) -> Result<()> {
        let pos = crate::error::check_positive;
        pos("tol", self.tol)?;
        if let Some(t) = self.th_stop {
            pos("th_stop", t)?;
        }
        pos("reg_min", self.reg_min)?;
        pos("reg_max", self.reg_max)?;
        pos("reg_converged", self.reg_converged)?;
        if !(self.reg_init == 0.0 || (self.reg_min <= self.reg_init && self.reg_init <= self.reg_max)) {
            return Err(Error::option("reg_init", "must be 0 or within [reg_min, reg_max]"));
        }
        for (name, v) in [("reg_increase", self.reg_increase), ("reg_decrease", self.reg_decrease)] {
            if !(v.is_finite() && v > 1.0) {
                return Err(Error::option(name, "must be finite and greater than 1"));
            }
        }
        for (name, v) in [
            ("step_decrease_reg", self.step_decrease_reg),
            ("step_increase_reg", self.step_increase_reg),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return Err(Error::option(name, "must be in [0, 1]"));
            }
        }
        if !(1..=60).contains(&self.linesearch_steps) {
            return Err(Error::option("linesearch_steps", "must be in 1..=60"));
        }
        if !(self.th_accept > 0.0 && self.th_accept < 1.0) {
            return Err(Error::option("th_accept", "must be in (0, 1)"));
        }
        pos("th_accept_neg", self.th_accept_neg)?;
        for (name, v) in [("th_grad", self.th_grad), ("gap_tol", self.gap_tol)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::option(name, "must be finite and nonnegative"));
            }
        }
        if self.max_iters == 0 {
            return Err(Error::option("max_iters", "must be at least 1"));
        }
        if !(1..=1000).contains(&self.filter_size) {
            return Err(Error::option("filter_size", "must be in 1..=1000"));
        }
        if self.filter_linesearch && !self.variant.multiple_shooting() {
            return Err(Error::option(
                "filter_linesearch",
                "is an option of fddp and box-fddp (sqp always filters; ddp's trials have no gaps)",
            ));
        }
        if self.square_root && self.variant.control_bounds() {
            return Err(Error::option(
                "square_root",
                "is not available for the box variants (their control law is the box QP)",
            ));
        }
        if self.num_threads == 0 {
            return Err(Error::option("num_threads", "must be at least 1"));
        }
        if self.implicit.max_iters == 0 || !(self.implicit.tol > 0.0 && self.implicit.tol.is_finite()) {
            return Err(Error::option(
                "implicit",
                "needs max_iters >= 1 and a positive finite tol",
            ));
        }
        self.box_qp.validate()
    }
}

//! Solvers and what they share: the result type, status, iteration history, initial
//! guesses, callbacks, line searches and the filter.
//!
//! Every solver follows the same life cycle: `setup(&problem)` allocates its workspace
//! for the problem's dimensions, `solve(&problem, &guess)` runs without allocating and
//! returns a [`Solution`] whose [`Status`] says how it stopped. The last accepted iterate
//! is always kept, so a solution can warm-start the next solve.

pub mod admm;
pub mod altro;
pub mod bcl_ddp;
pub mod boxqp;
pub mod csqp;
pub mod ddp;
pub mod filter;
pub mod linesearch;
pub mod log;
mod options;
pub mod proxddp;
pub(crate) mod skeleton;

use std::fmt;
use std::time::Duration;

use faer::{Col, Mat};

use crate::error::Result;
use crate::problem::Problem;

pub use options::SolverOptions;

/// Which Hessian of the Lagrangian builds the Newton (or DDP) system.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum HessianApprox {
    /// Cost Hessians only (Gauss-Newton; iLQR for the DDP family).
    #[default]
    GaussNewton,
    /// Cost Hessians plus the multiplier-weighted second derivatives (ProxDDP (37d-37i))
    /// of the dynamics and constraints that provide vector-Hessian products; for the DDP
    /// family the dynamics' second derivatives weighted by the value gradient (classical
    /// DDP).
    Exact,
}

/// How a solver stopped (more variants may come with new solvers).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum Status {
    /// Not solved yet.
    #[default]
    NotStarted,
    /// Primal and dual residuals are below the tolerance.
    Converged,
    /// The iteration limit was reached.
    MaxIterations,
    /// The line search found no acceptable step.
    LinesearchFailure,
    /// A non-finite value appeared in the model evaluation or the step; the last good
    /// iterate is returned.
    NonFinite,
    /// The primal regularisation needed to make the Newton system solvable exceeded its
    /// upper bound.
    RegularizationFailure,
    /// The wall-time budget was exhausted; the best iterate so far is returned.
    TimeBudget,
    /// Steps no longer make progress: for ProxDDP the residuals are at the round-off
    /// floor of the arithmetic (about `ε |x| / mu`), above the requested tolerance; for
    /// the DDP family only heavily regularised (short) steps decrease the cost.
    Stalled,
    /// A callback asked the solver to stop; the last accepted iterate is returned.
    Interrupted,
    /// The constraints look infeasible: the subproblem at the smallest penalty was solved
    /// repeatedly with a primal residual above its target (ProxDDP, ProxNLP).
    Infeasible,
}

impl Status {
    /// Whether the solver converged.
    pub fn converged(&self) -> bool {
        *self == Status::Converged
    }

    /// The machine-readable name (`max_iterations`, ...) of the JSON outputs and of
    /// Python's `Results.status`; [`fmt::Display`] gives the words of the text outputs.
    pub fn name(&self) -> &'static str {
        match self {
            Status::NotStarted => "not_started",
            Status::Converged => "converged",
            Status::MaxIterations => "max_iterations",
            Status::LinesearchFailure => "linesearch_failure",
            Status::NonFinite => "non_finite",
            Status::RegularizationFailure => "regularization_failure",
            Status::TimeBudget => "time_budget",
            Status::Stalled => "stalled",
            Status::Interrupted => "interrupted",
            Status::Infeasible => "infeasible",
        }
    }
}

impl fmt::Display for Status {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = match self {
            Status::NotStarted => "not started",
            Status::Converged => "converged",
            Status::MaxIterations => "maximum iterations reached",
            Status::LinesearchFailure => "line search failure",
            Status::NonFinite => "non-finite values",
            Status::RegularizationFailure => "regularization failure",
            Status::TimeBudget => "time budget exhausted",
            Status::Stalled => "stalled",
            Status::Interrupted => "stopped by a callback",
            Status::Infeasible => "locally infeasible",
        };
        f.write_str(s)
    }
}

/// One row of the iteration history (the columns of the iteration table).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct IterationRecord {
    /// Iteration number (Newton steps taken before this row).
    pub iter: usize,
    /// Accepted step length.
    pub alpha: f64,
    /// Inner (subproblem) criterion, e.g. ProxDDP (19).
    pub inner_crit: f64,
    /// Primal residual (dynamics and constraint violation), e.g. ProxDDP (53).
    pub prim_err: f64,
    /// Dual residual (Lagrangian gradient), e.g. ProxDDP (52).
    pub dual_err: f64,
    /// Primal regularisation used in the Newton system.
    pub preg: f64,
    /// Total cost.
    pub cost: f64,
    /// Directional derivative of the merit function along the step.
    pub dphi0: f64,
    /// Merit function value after the step.
    pub merit: f64,
    /// Merit change `merit(α) - merit(0)`.
    pub dmerit: f64,
    /// Augmented-Lagrangian (outer) iteration.
    pub al_iter: usize,
    /// Augmented-Lagrangian penalty parameter.
    pub mu: f64,
    /// DDP family: `|Δ₁ + ½Δ₂|`, the expected cost decrease of the full step (the
    /// stopping criterion).
    pub stop: f64,
    /// DDP family: expected cost decrease of the accepted step, `α(Δ₁ + ½αΔ₂)`.
    pub expected_decrease: f64,
    /// DDP family: actual cost decrease of the accepted step.
    pub decrease: f64,
}

/// The result of a solve: trajectory, multipliers, gains, status and history.
///
/// Multiplier conventions: the Lagrangian is
/// `J + λ_0ᵀ r_0(x_0) + Σ_t λ_{t+1}ᵀ f_t(x_t, u_t, x_{t+1}) + Σ_t ν_tᵀ h_t(x_t, u_t) + ν_Nᵀ h_N(x_N)`
/// with `f_t = φ(x_t, u_t) ⊖ x_{t+1}` for explicit dynamics, so `λ_{t+1}` is the
/// co-state (the gradient of the cost-to-go at `x_{t+1}`).
#[derive(Debug, Clone, Default)]
pub struct Solution {
    /// States `x_0..x_N`.
    pub xs: Vec<Vec<f64>>,
    /// Controls `u_0..u_{N-1}`.
    pub us: Vec<Vec<f64>>,
    /// Co-states: `λ_0` (initial condition), then `λ_{t+1}` (dynamics of stage `t`).
    pub lambdas: Vec<Vec<f64>>,
    /// Path-constraint multipliers `ν_0..ν_{N-1}` stacked per stage, then the terminal `ν_N`.
    pub nus: Vec<Vec<f64>>,
    /// Feedforward gains `k_t` of the last backward pass.
    pub feedforward: Vec<Col<f64>>,
    /// Feedback gains `K_t` (`nu x ndx`) of the last backward pass: `δu = k + K δx`.
    pub feedback: Vec<Mat<f64>>,
    /// How the solver stopped.
    pub status: Status,
    /// Newton / DDP iterations taken.
    pub iterations: usize,
    /// Outer (augmented-Lagrangian) iterations.
    pub al_iterations: usize,
    /// Final primal residual.
    pub prim_err: f64,
    /// Final dual residual.
    pub dual_err: f64,
    /// Final total cost.
    pub cost: f64,
    /// Final augmented-Lagrangian penalty parameter (0 for unconstrained solvers).
    pub mu: f64,
    /// Wall time of the solve.
    pub solve_time: Duration,
    /// One record per iteration, the first [`HISTORY_LIMIT`] at most (capacity
    /// reserved at setup).
    pub history: Vec<IterationRecord>,
}

/// The most iteration records a [`Solution`] keeps: the history is allocated at setup,
/// so an iteration limit of `usize::MAX` ("until converged") must not size it.
pub const HISTORY_LIMIT: usize = 10_000;

impl Solution {
    /// A zero solution shaped for `problem`, with `history_capacity` history rows
    /// reserved ([`HISTORY_LIMIT`] at most).
    pub fn new(problem: &Problem, history_capacity: usize) -> Self {
        let n = problem.horizon();
        let xs = (0..=n).map(|t| vec![0.0; problem.space(t).nx()]).collect();
        let us = (0..n).map(|t| vec![0.0; problem.nu(t)]).collect();
        let mut lambdas = vec![vec![0.0; problem.nc0()]];
        lambdas.extend((0..n).map(|t| vec![0.0; problem.space(t + 1).ndx()]));
        let mut nus: Vec<Vec<f64>> = problem.stages().iter().map(|s| vec![0.0; s.nc()]).collect();
        nus.push(vec![0.0; problem.terminal_constraints().iter().map(|c| c.nr()).sum()]);
        let feedforward = (0..n).map(|t| Col::zeros(problem.nu(t))).collect();
        let feedback = (0..n)
            .map(|t| Mat::zeros(problem.nu(t), problem.space(t).ndx()))
            .collect();
        Self {
            xs,
            us,
            lambdas,
            nus,
            feedforward,
            feedback,
            history: Vec::with_capacity(history_capacity.min(HISTORY_LIMIT)),
            ..Default::default()
        }
    }
}

/// A starting point: states and controls, optionally multipliers (warm start).
///
/// States need not satisfy the dynamics: multiple-shooting solvers start from
/// dynamically infeasible guesses.
#[derive(Debug, Clone, Copy)]
pub struct InitialGuess<'a> {
    /// States `x_0..x_N`.
    pub xs: &'a [Vec<f64>],
    /// Controls `u_0..u_{N-1}`.
    pub us: &'a [Vec<f64>],
    /// Co-states, as in [`Solution::lambdas`] (zero if absent).
    pub lambdas: Option<&'a [Vec<f64>]>,
    /// Path multipliers, as in [`Solution::nus`] (zero if absent).
    pub nus: Option<&'a [Vec<f64>]>,
}

impl<'a> InitialGuess<'a> {
    /// A primal guess without multipliers.
    pub fn primal(xs: &'a [Vec<f64>], us: &'a [Vec<f64>]) -> Self {
        Self {
            xs,
            us,
            lambdas: None,
            nus: None,
        }
    }

    /// The full primal-dual point of a previous solution (warm start).
    pub fn from_solution(s: &'a Solution) -> Self {
        Self {
            xs: &s.xs,
            us: &s.us,
            lambdas: Some(&s.lambdas),
            nus: Some(&s.nus),
        }
    }

    /// Checks sizes and finiteness against `problem`.
    ///
    /// # Errors
    /// Names the first offending entry.
    pub fn check(&self, problem: &Problem) -> Result<()> {
        problem.check_trajectory(self.xs, self.us)?;
        problem.check_multipliers(self.lambdas, self.nus)
    }
}

/// Called by solvers after every iteration; return `false` to stop the solve (the
/// status is then that of the last iteration's checks, `MaxIterations` if none applied).
pub trait Callback {
    /// Receives the record of the iteration just finished.
    fn on_iteration(&mut self, record: &IterationRecord) -> bool;
}

/// What every solver offers, so that the command-line tool, the benchmarks, the
/// catalogue and receding-horizon control can pick one by name and drive it the same way.
pub trait Solver: Send {
    /// The solver's name (one of [`SolverOptions::names`]).
    fn name(&self) -> &'static str;

    /// Validates the options and allocates every buffer for `problem`'s dimensions.
    ///
    /// # Errors
    /// If an option is out of range or the solver cannot solve this kind of problem.
    fn setup(&mut self, problem: &Problem) -> Result<()>;

    /// Solves `problem` from `guess` (without allocating), calling `callback` after every
    /// iteration; a callback returning `false` stops the solve with
    /// [`Status::Interrupted`].
    ///
    /// # Errors
    /// If `setup` was not called for a problem of these dimensions, or the guess has a
    /// wrong size or a non-finite value.
    fn solve_with(
        &mut self,
        problem: &Problem,
        guess: InitialGuess<'_>,
        callback: Option<&mut dyn Callback>,
    ) -> Result<&Solution>;

    /// The solution of the last solve.
    fn solution(&self) -> &Solution;

    /// Solves `problem` from `guess` without a callback (see [`Solver::solve_with`]).
    /// Algorithmic outcomes (convergence, iteration limit, line-search failure, ...) are
    /// reported in [`Solution::status`].
    ///
    /// # Errors
    /// As [`Solver::solve_with`].
    fn solve(&mut self, problem: &Problem, guess: InitialGuess<'_>) -> Result<&Solution> {
        self.solve_with(problem, guess, None)
    }

    /// As [`Solver::solve`], calling `callback` after every iteration.
    ///
    /// # Errors
    /// As [`Solver::solve_with`].
    fn solve_with_callback(
        &mut self,
        problem: &Problem,
        guess: InitialGuess<'_>,
        callback: &mut dyn Callback,
    ) -> Result<&Solution> {
        self.solve_with(problem, guess, Some(callback))
    }

    /// The solver's iteration table (the columns of [`Solution::history`] it fills).
    fn table(&self) -> log::Table;

    /// Sets the iteration limit and the wall-time budget of each solve (the per-cycle
    /// budget of receding-horizon control); call before `setup`, which sizes the
    /// iteration history for `max_iters`.
    fn set_limits(&mut self, max_iters: usize, max_time: Option<Duration>);

    /// Whether a solve that ends at its iteration limit right after a step evaluates the
    /// derivatives and residuals at the point it returns (see
    /// [`crate::mpc::MpcOptions::final_residuals`]); solvers that always do ignore it.
    fn set_final_residuals(&mut self, on: bool) {
        let _ = on;
    }

    /// As `setup`, and prepares the receding horizon of [`crate::mpc`]: the workspace
    /// also holds the data of the stages of `queue`, which enter the horizon in turn
    /// through [`Solver::shift`].
    ///
    /// # Errors
    /// As `setup`, and if a stage of the horizon or the queue has other state or control
    /// sizes than stage 0, or a queued stage is one the solver cannot handle.
    fn setup_receding(&mut self, problem: &Problem, queue: &[crate::problem::StageModel]) -> Result<()>;

    /// Moves the workspace one knot along after [`Problem::shift`] took the stage
    /// `queue[slot]` of [`Solver::setup_receding`] into the horizon (and put the stage
    /// that left into `queue[slot]`), or after [`Problem::rotate`] for `slot = None`,
    /// without allocating. The solution's path multipliers move with their stages; the
    /// new last stage's are zero.
    ///
    /// # Errors
    /// If `setup_receding` was not called or `slot` is out of range.
    fn shift(&mut self, problem: &Problem, slot: Option<usize>) -> Result<()>;
}

/// A boxed solver is a solver (a solver chosen by name at run time).
impl<S: Solver + ?Sized> Solver for Box<S> {
    fn name(&self) -> &'static str {
        (**self).name()
    }
    fn setup(&mut self, problem: &Problem) -> Result<()> {
        (**self).setup(problem)
    }
    fn solve_with(
        &mut self,
        problem: &Problem,
        guess: InitialGuess<'_>,
        callback: Option<&mut dyn Callback>,
    ) -> Result<&Solution> {
        (**self).solve_with(problem, guess, callback)
    }
    fn solution(&self) -> &Solution {
        (**self).solution()
    }
    fn table(&self) -> log::Table {
        (**self).table()
    }
    fn set_limits(&mut self, max_iters: usize, max_time: Option<Duration>) {
        (**self).set_limits(max_iters, max_time)
    }
    fn set_final_residuals(&mut self, on: bool) {
        (**self).set_final_residuals(on)
    }
    fn setup_receding(&mut self, problem: &Problem, queue: &[crate::problem::StageModel]) -> Result<()> {
        (**self).setup_receding(problem, queue)
    }
    fn shift(&mut self, problem: &Problem, slot: Option<usize>) -> Result<()> {
        (**self).shift(problem, slot)
    }
}

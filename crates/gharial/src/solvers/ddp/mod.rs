//! The DDP family on gharial's problems: DDP / iLQR, FDDP, box-DDP and box-FDDP, as
//! crocoddyl implements them (`SolverDDP`, `SolverFDDP`, `SolverBoxDDP`,
//! `SolverBoxFDDP`), and the stagewise SQP of Jordana et al. (2023) (mim_solvers'
//! `SolverSQP`), on the shared LQ kernels.
//!
//! Each iteration is a backward pass, a line search on the step length and a
//! regularisation update:
//! - *Backward pass*: the LQ subproblem of the current point (cost Hessians, dynamics
//!   Jacobians, and the gaps while they are open) solved by the Riccati recursion of
//!   [`crate::lq`] with the Levenberg-Marquardt regularisation `ρ` added to `Q_uu` and to
//!   the value Hessians `V_xx` (crocoddyl's `preg`). A `Q_uu` that is not positive
//!   definite raises `ρ` tenfold and repeats the pass. Box variants replace the stage
//!   solve of bounded stages by the projected-Newton box QP ([`crate::solvers::boxqp`]):
//!   `k` its solution, `K = -H_ff⁻¹ Q_fx` on the free controls (Tassa et al. 2014).
//!   With [`crate::solvers::HessianApprox::Exact`] and closed gaps, each stage's
//!   Q-function Hessian gets `V_x'·f_zz` (classical DDP) from the next value gradient
//!   before the stage's gains are computed.
//! - *Expected improvement* of the step `α`: `ΔV_exp = α(Δ₁ + ½αΔ₂)` with
//!   `Δ₁ = -Σ Q_uᵀk`, `Δ₂ = -Σ kᵀ(Q_uu + ρ)k` for DDP; FDDP adds the gap terms of
//!   Mastalli et al. (2020), (19)-(20): `Δ₁ += -Σ V_xᵀ fs + Δ_v`, `Δ₂ += Σ fsᵀV_xx fs - 2Δ_v`,
//!   `V_x = p + P fs`, `Δ_v = Σ fsᵀ P (x̃ ⊖ x)` of the trial.
//! - *Line search*: `α = 1, 1/2, ..., 2⁻⁹`; the trial rolls the dynamics out with
//!   `ũ = u + αk + K(x̃ ⊖ x)` (clamped into the bounds for the box variants), FDDP keeping
//!   the part `1 - α` of the gaps while they are open. It is accepted if
//!   `ΔV_exp ≥ 0` and `ΔV > 0.1 ΔV_exp` (or `|Δ₁| < 1e-12`, or, for DDP, while the guess
//!   is infeasible), or for FDDP if `ΔV_exp < 0` and `ΔV > 2 ΔV_exp`.
//! - *Regularisation*: divided by 10 after a step longer than 1/2 (to 0 below `1e-9`),
//!   multiplied by 10 (from 0 to `1e-9`) after one of at most 1/100 or none; reaching its
//!   upper bound stops the solve. It starts at 0, so that steps are exact while `Q_uu` is
//!   positive definite (crocoddyl starts and stays at `1e-9` or above).
//!
//! The solve has converged when the gaps are closed and the expected decrease of the
//! full step `|Δ₁ + ½Δ₂|` is below `tol² N` (crocoddyl's `th_stop`); it is checked after the
//! backward pass, before a step is taken, so a converged solve reports one iteration fewer
//! than crocoddyl, which checks after the step it takes with that direction.
//!
//! *SQP* (Gauss-Newton multiple shooting) shares the backward pass with FDDP's gaps and
//! the regularisation, and differs in three places: the step is the LQ subproblem's
//! solution `(δx, δu, λ⁺)` by a linear rollout of the gains through the linearised
//! dynamics and gaps; the trial `x ⊕ αδx, u + αδu` is accepted by a filter on (cost,
//! 1-norm of the gaps) (Section V-C; with the default memory of 1: if it lowers the cost
//! or the gaps); and the solve has converged when the KKT residual (20),
//! `max(|∇L|_∞, |gaps|_∞)` at the point with the co-states `λ⁺ = V_xx δx + V_x` of the
//! step from it ((21); mim_solvers' `checkKKTConditions`), is below `tol`. With the
//! Gauss-Newton Hessian its dual part is the Hessian times the step, so the test stops
//! where the next step is small, at mim_solvers' iteration (the co-states of the step
//! that reached the point would pass it one or two steps earlier, with costs off by
//! about the tolerance times the multipliers).
//!
//! DDP, FDDP and SQP refuse problems with constraints; the box variants accept bounds on the
//! controls only (recognised among the path constraints as [`crate::constraints::ConstraintSet::box_bounds`] describes), anything else is refused with an error naming the
//! constraint. All need a fixed initial state.

pub(crate) mod augmented;
mod bounds;
mod options;
pub(crate) mod workspace;

pub use bounds::{StageBounds, control_bounds};
pub use options::{DdpOptions, DdpVariant};

use std::time::Instant;

use workspace::{Expected, Workspace};

use crate::error::Result;
use crate::lq::LqError;
use crate::problem::{Problem, StageModel};
use crate::solvers::log::{COST, Column, Format, ITER, Table};
use crate::solvers::skeleton::{Signature, follow_shift, not_receding, push_record, solution_for, write_gains};
use crate::solvers::{Callback, InitialGuess, IterationRecord, Solution, Status};

/// The solve stalls when the expected decrease of the full step is at most this many
/// roundings of the cost (`ε (1 + |J|)`), above the tolerance.
const ROUNDOFF_STOP: f64 = 16.0;

/// The DDP family's iteration table.
pub const TABLE: Table = Table(COLUMNS);

const COLUMNS: &[Column] = &[
    ITER,
    Column {
        name: "alpha",
        width: 9,
        format: Format::Sci(3),
        value: |r| r.alpha,
        meaning: "step length (the last one tried when no step was accepted)",
    },
    COST,
    Column {
        name: "stop",
        width: 10,
        format: Format::Sci(3),
        value: |r| r.stop,
        meaning: "|D1 + D2/2|: expected cost decrease of the full step (converged below tol^2 N with closed gaps)",
    },
    Column {
        name: "dV_exp",
        width: 10,
        format: Format::Sci(3),
        value: |r| r.expected_decrease,
        meaning: "expected cost decrease of the step, alpha (D1 + alpha D2 / 2)",
    },
    Column {
        name: "dV",
        width: 10,
        format: Format::Sci(3),
        value: |r| r.decrease,
        meaning: "actual cost decrease of the step",
    },
    Column {
        name: "gaps",
        width: 10,
        format: Format::Sci(3),
        value: |r| r.prim_err,
        meaning: "largest dynamics gap (infinity norm) at the start of the step",
    },
    Column {
        name: "|Q_u|",
        width: 10,
        format: Format::Sci(3),
        value: |r| r.dual_err,
        meaning: "largest control gradient of the Q-function (clamped controls left out)",
    },
    Column {
        name: "reg",
        width: 9,
        format: Format::Sci(2),
        value: |r| r.preg,
        meaning: "Levenberg-Marquardt regularisation of Q_uu and V_xx",
    },
];

/// DDP / iLQR, FDDP, box-DDP or box-FDDP ([`DdpOptions::variant`]).
///
/// ```text
/// let mut solver = Ddp::new(DdpOptions::new(DdpVariant::Fddp));
/// solver.setup(&problem)?;                                   // allocates
/// let sol = solver.solve(&problem, InitialGuess::primal(&xs, &us))?;  // does not
/// ```
pub struct Ddp {
    /// Options; changes take effect at the next `setup`.
    pub options: DdpOptions,
    ws: Option<Box<Workspace>>,
    solution: Solution,
    signature: Signature,
}

impl std::fmt::Debug for Ddp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ddp")
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

/// The outcome of a line search.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Step {
    /// Accepted step length, or the last one tried.
    pub alpha: f64,
    /// Cost (merit) of the accepted trial.
    pub cost: Option<f64>,
    /// Expected decrease of the step.
    pub expected: f64,
    /// Actual decrease of the step.
    pub decrease: f64,
}

/// Residuals and stopping criterion after a backward pass.
#[derive(Debug, Clone, Copy, Default)]
struct Measures {
    gaps: f64,
    dual: f64,
    stop: f64,
}

impl Ddp {
    /// A solver with the given options (nothing allocated until `setup`).
    pub fn new(options: DdpOptions) -> Self {
        Self {
            options,
            ws: None,
            solution: Solution::default(),
            signature: Signature::default(),
        }
    }

    /// Validates the options, checks that the problem is one this variant solves, and
    /// allocates every buffer for its dimensions.
    ///
    /// # Errors
    /// If an option is out of range, or the problem has constraints the variant does not
    /// handle (any for DDP and FDDP, anything but control bounds for the box variants) or
    /// no fixed initial state.
    pub fn setup(&mut self, problem: &Problem) -> Result<()> {
        self.setup_with(problem, None)
    }

    fn setup_with(&mut self, problem: &Problem, queue: Option<&[StageModel]>) -> Result<()> {
        self.options.validate()?;
        self.signature = Signature::default();
        self.ws = Some(Box::new(Workspace::new(problem, &self.options, queue, None)?));
        self.solution = solution_for(problem, self.options.max_iters, queue)?;
        self.signature = Signature::of(problem);
        Ok(())
    }

    /// See [`Solver::shift`](crate::solvers::Solver::shift).
    fn shift_workspace(&mut self, problem: &Problem, slot: Option<usize>) -> Result<()> {
        let name = self.options.variant.name();
        let ws = self.ws.as_mut().ok_or_else(|| not_receding(name))?;
        ws.shift(slot)?;
        follow_shift(problem, &mut self.solution, &mut self.signature);
        Ok(())
    }

    fn run(
        &mut self,
        problem: &Problem,
        guess: InitialGuess<'_>,
        mut callback: Option<&mut dyn Callback>,
    ) -> Result<&Solution> {
        let name = self.options.variant.name();
        self.signature.check(problem, name)?;
        guess.check(problem)?;
        let start = Instant::now();
        let opts = &self.options;
        let ws = self.ws.as_mut().expect("checked by the signature");
        let sol = &mut self.solution;
        sol.history.clear();
        if opts.log.is_active() {
            opts.log.line(format_args!("{}", TABLE.header()));
        }
        let th_stop = if opts.variant.linear_rollout() {
            opts.tol
        } else {
            opts.tol * opts.tol * problem.horizon().max(1) as f64
        };
        let mut lp = Loop {
            th_stop: opts.th_stop.unwrap_or(th_stop),
            reg: opts.reg_init,
            iter: 0,
            m: Measures::default(),
            rebuild: true,
        };
        let status = if ws.load_guess(problem, &guess, opts.gap_tol)? {
            loop {
                if let Some(s) = lp.iteration(ws, problem, opts, sol, start, &mut callback) {
                    break s;
                }
            }
        } else {
            Status::NonFinite
        };
        write_solution(sol, ws, status, lp.iter, lp.m);
        sol.solve_time = start.elapsed();
        Ok(&self.solution)
    }
}

/// The state of the loop of one solve.
struct Loop {
    th_stop: f64,
    reg: f64,
    iter: usize,
    m: Measures,
    /// Whether the knots must be rebuilt (a step was taken).
    rebuild: bool,
}

impl Loop {
    /// The stopping test on the measures of now (`applies`: the point qualifies, e.g. it
    /// is feasible): converged, or stalled when the regularisation is still raised.
    fn converged(&self, opts: &DdpOptions, applies: bool) -> Option<Status> {
        let status = if self.reg <= opts.reg_converged {
            Status::Converged
        } else {
            Status::Stalled
        };
        (applies && self.m.stop < self.th_stop).then_some(status)
    }

    /// The backward pass and the stopping tests at the current point (for SQP, the KKT
    /// test (20) with the co-states of the step the pass gives, as mim_solvers does).
    /// Returns the model of the step's decrease, or the status that ends the solve.
    fn direction(
        &mut self,
        ws: &mut Workspace,
        problem: &Problem,
        opts: &DdpOptions,
        start: Instant,
    ) -> std::result::Result<Expected, Status> {
        let sqp = opts.variant.linear_rollout();
        let (e, dual) = backward(ws, problem, opts, &mut self.reg, self.rebuild)?;
        self.m = if sqp {
            let (dual, stop) = if ws.linear_step() {
                ws.kkt(problem)
            } else {
                (f64::INFINITY, f64::INFINITY)
            };
            Measures {
                gaps: ws.max_gap(),
                dual,
                stop,
            }
        } else {
            Measures {
                gaps: ws.max_gap(),
                dual,
                stop: (e.dg + 0.5 * e.dq).abs(),
            }
        };
        // A point whose controls break their bounds (a guess) is not a solution, however
        // small the unconstrained step's decrease: the step's rollout clamps them.
        let within = ws.controls_within_bounds();
        if let Some(s) = self.converged(opts, (ws.feasible || sqp) && within) {
            return Err(s);
        }
        // The full step cannot change the cost by more than its rounding: a tolerance
        // below that floor is out of reach.
        if !sqp && ws.feasible && within && self.m.stop <= ROUNDOFF_STOP * f64::EPSILON * (1.0 + ws.cost.abs()) {
            return Err(Status::Stalled);
        }
        if opts.max_time.is_some_and(|b| start.elapsed() >= b) {
            return Err(Status::TimeBudget);
        }
        if self.iter >= opts.max_iters {
            return Err(Status::MaxIterations);
        }
        Ok(e)
    }

    /// One iteration: backward pass and stopping tests ([`Loop::direction`]), line search,
    /// regularisation update, callback. Returns a status when the solve stops.
    fn iteration(
        &mut self,
        ws: &mut Workspace,
        problem: &Problem,
        opts: &DdpOptions,
        sol: &mut Solution,
        start: Instant,
        callback: &mut Option<&mut dyn Callback>,
    ) -> Option<Status> {
        let e = match self.direction(ws, problem, opts, start) {
            Ok(e) => e,
            Err(s) => return Some(s),
        };
        let sqp = opts.variant.linear_rollout();
        let cost = ws.cost;
        let step = if sqp {
            filter_line_search(ws, problem, opts)
        } else {
            line_search(ws, problem, e, opts)
        };
        let record = IterationRecord {
            iter: self.iter,
            alpha: step.alpha,
            prim_err: self.m.gaps,
            dual_err: self.m.dual,
            preg: self.reg,
            cost,
            stop: self.m.stop,
            expected_decrease: step.expected,
            decrease: step.decrease,
            ..Default::default()
        };
        push_record(sol, record, &opts.log, &TABLE);
        self.iter += 1;
        ws.end_iteration();
        self.rebuild = step.cost.is_some();
        if let Some(c) = step.cost
            && !ws.accept(problem, c, step.alpha, opts.gap_tol)
        {
            return Some(Status::NonFinite);
        }
        if !update_reg(&mut self.reg, &step, opts) {
            return Some(Status::RegularizationFailure);
        }
        if let Some(cb) = callback.as_mut()
            && !cb.on_iteration(&record)
        {
            return Some(Status::Interrupted);
        }
        None
    }
}

/// The backward pass at the current point (knots rebuilt after a step, else only the
/// regularisation changed), raising the regularisation until it succeeds; then the
/// expected improvement and the dual residual.
pub(crate) fn backward(
    ws: &mut Workspace,
    problem: &Problem,
    opts: &DdpOptions,
    reg: &mut f64,
    rebuild: bool,
) -> std::result::Result<(Expected, f64), Status> {
    if rebuild {
        ws.build_lq(problem, *reg);
    }
    loop {
        ws.set_reg(*reg);
        match ws.backward(problem, *reg, &opts.box_qp) {
            Ok(()) => return Ok(ws.expected(*reg)),
            Err(LqError::NonFinite { .. }) => return Err(Status::NonFinite),
            Err(_) => {
                if !increase_reg(reg, opts) {
                    return Err(Status::RegularizationFailure);
                }
            }
        }
    }
}

/// Backtracking on the step length with crocoddyl's acceptance rules (module docs), or
/// with SQP's filter (`filter_linesearch`).
pub(crate) fn line_search(ws: &mut Workspace, problem: &Problem, e: Expected, opts: &DdpOptions) -> Step {
    let multiple_shooting = opts.variant.multiple_shooting();
    let mut step = Step {
        alpha: 1.0,
        cost: None,
        expected: 0.0,
        decrease: 0.0,
    };
    if opts.filter_linesearch {
        let gap = ws.gap_l1();
        ws.filter.push(ws.cost, gap);
    }
    for i in 0..opts.linesearch_steps {
        step.alpha = 0.5_f64.powi(i as i32);
        let Some(c) = ws.trial(problem, step.alpha, opts) else {
            continue;
        };
        let (d1, d2) = ws.model(e);
        let a = step.alpha;
        step.expected = a * (d1 + 0.5 * a * d2);
        step.decrease = ws.cost - c;
        let accept = if opts.filter_linesearch {
            let g = ws.trial_gap_l1(problem);
            ws.filter.accepts(c, g)
        } else if step.expected >= 0.0 {
            d1.abs() < opts.th_grad
                || (!ws.feasible && !multiple_shooting)
                || step.decrease > opts.th_accept * step.expected
        } else {
            multiple_shooting && step.decrease > opts.th_accept_neg * step.expected
        };
        if accept {
            step.cost = Some(c);
            return step;
        }
    }
    step
}

/// SQP's line search (Jordana et al. 2023, V-C) on the LQ step of
/// [`Workspace::linear_step`] (none if it failed): `α = 1, 1/2, ...` until the trial's
/// (cost, gap 1-norm) is not dominated by the filter's pairs, which include the current
/// point's.
fn filter_line_search(ws: &mut Workspace, problem: &Problem, opts: &DdpOptions) -> Step {
    let mut step = Step {
        alpha: 1.0,
        cost: None,
        expected: 0.0,
        decrease: 0.0,
    };
    if !ws.has_step() {
        return step;
    }
    let gap = ws.gap_l1();
    ws.filter.push(ws.cost, gap);
    for i in 0..opts.linesearch_steps {
        step.alpha = 0.5_f64.powi(i as i32);
        let Some((c, g)) = ws.linear_trial(problem, step.alpha) else {
            continue;
        };
        if ws.filter.accepts(c, g) {
            step.cost = Some(c);
            step.decrease = ws.cost - c;
            return step;
        }
    }
    step
}

/// Levenberg-Marquardt update after a line search; `false` when the regularisation
/// reaches its upper bound.
pub(crate) fn update_reg(reg: &mut f64, step: &Step, opts: &DdpOptions) -> bool {
    if step.cost.is_some() && step.alpha > opts.step_decrease_reg {
        *reg /= opts.reg_decrease;
        if *reg < opts.reg_min {
            *reg = 0.0;
        }
    }
    if step.cost.is_none() || step.alpha <= opts.step_increase_reg {
        return increase_reg(reg, opts);
    }
    true
}

/// Raises the regularisation (from 0 to `reg_min`); `false` when it reaches `reg_max`.
fn increase_reg(reg: &mut f64, opts: &DdpOptions) -> bool {
    *reg = (*reg * opts.reg_increase).max(opts.reg_min).min(opts.reg_max);
    *reg < opts.reg_max
}

fn write_solution(sol: &mut Solution, ws: &mut Workspace, status: Status, iter: usize, m: Measures) {
    crate::solvers::skeleton::copy_trajectory(&mut sol.xs, &ws.xs);
    crate::solvers::skeleton::copy_trajectory(&mut sol.us, &ws.us);
    if status != Status::NonFinite {
        ws.multipliers(&mut sol.lambdas, &mut sol.nus);
        write_gains(sol, ws.riccati.stages());
    }
    sol.status = status;
    sol.iterations = iter;
    sol.al_iterations = 0;
    sol.prim_err = ws.max_gap();
    sol.dual_err = m.dual;
    sol.cost = ws.cost;
    sol.mu = 0.0;
}

impl crate::solvers::Solver for Ddp {
    fn name(&self) -> &'static str {
        self.options.variant.name()
    }
    fn setup(&mut self, problem: &Problem) -> Result<()> {
        Ddp::setup(self, problem)
    }
    fn solve_with(
        &mut self,
        problem: &Problem,
        guess: InitialGuess<'_>,
        callback: Option<&mut dyn Callback>,
    ) -> Result<&Solution> {
        self.run(problem, guess, callback)
    }
    fn solution(&self) -> &Solution {
        &self.solution
    }
    fn table(&self) -> Table {
        TABLE
    }
    fn set_limits(&mut self, max_iters: usize, max_time: Option<std::time::Duration>) {
        self.options.max_iters = max_iters;
        self.options.max_time = max_time;
    }
    fn setup_receding(&mut self, problem: &Problem, queue: &[StageModel]) -> Result<()> {
        self.setup_with(problem, Some(queue))
    }
    fn shift(&mut self, problem: &Problem, slot: Option<usize>) -> Result<()> {
        self.shift_workspace(problem, slot)
    }
}

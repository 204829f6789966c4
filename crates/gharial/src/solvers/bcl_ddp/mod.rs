//! BCL-DDP: equality-constrained DDP by an augmented Lagrangian with the
//! bound-constrained Lagrangian globalisation (El Kazdadi, Carpentier and Ponce 2021,
//! "Equality Constrained Differential Dynamic Programming").
//!
//! The problem is (1)-(3) with equality constraints `h_t(x_t, u_t) = 0` (21) at the
//! stages and `h_N(x_N) = 0` at the terminal knot. For fixed multipliers `λ` and penalty
//! `μ` (a weight: large is stiff) DDP minimises the augmented Lagrangian
//! ```text
//! L_μ(x, u, λ) = Σ_t ℓ_t + λ_t(x_t)ᵀ h_t + μ/2 |h_t|²  + ℓ_N + λ_N(x_N)ᵀ h_N + μ/2 |h_N|²   (22), (26)
//! ```
//! with constant multipliers `λ_t(x) = λ_t` (III-A) or affine ones
//! `λ_t(x) = λ_t + Λ_t (x ⊖ x_t)` (25) (III-B, [`Multipliers`]). The DDP iterations are
//! those of [`crate::solvers::ddp`] (the backward pass on the Riccati kernels of
//! [`crate::lq`], the Levenberg-Marquardt regularisation, the line search and its
//! rollouts) on the augmented problem:
//! - the knots carry the constraint rows of (18), `h_x δx + h_u δu + h + λ/μ - ν/μ = 0`,
//!   which the Riccati recursion eliminates without forming `μ h_uᵀh_u`: the result is
//!   the augmented Q-function (23) (Gauss-Newton: without the `h_xx` terms) solved in the
//!   better-conditioned form (18);
//! - with affine multipliers the knots' cost blocks get the terms of (27),
//!   `Q_xx += h_xᵀΛ + Λᵀh_x`, `Q_xu += Λᵀh_u`, `Q_x += Λᵀh`, the line search evaluates the
//!   multipliers at the trial's `δx`, and an accepted step moves their origin,
//!   `λ ← λ + Λ δx`;
//! - the line search's merit is `L_μ`, its expected decrease that of the condensed (23).
//!
//! # Alg. 1 / Alg. 2 (the outer loop)
//! ```text
//! given λ (0 or the warm start), μ_0, η_0, ω_0, k > 1, α ∈ (0, 1)
//! repeat
//!     backward pass (23)/(27) at (x, u): gains k, K and |∇_u L_μ|_∞ (the Q_u of (23))
//!     if |∇_u L_μ| ≤ tol and |h| ≤ tol: λ ← λ + μ h (24)/(28); converged
//!     if |∇_u L_μ| < ω:                               (L_μ minimised)
//!         if |h| < η:  λ ← λ + μ h, Λ ← Λ + μ (h_x + h_u K) (24)/(28);
//!                      η ← η / μ^α;  ω ← ω / μ         (not below tol)
//!         else:        μ ← k μ, or the adaptive rate ([`PenaltyUpdate`])
//!     else: forward pass (12) with line search on L_μ, regularisation update
//! ```
//! The test on the gradient comes after the backward pass at the current point rather
//! than after the step (Alg. 2 tests the point the step reached, whose gradient the next
//! backward pass gives): the iterates are the same. An outer update counts as an
//! iteration (its row has `alpha = 0`). [`Schedule::EveryIteration`] replaces the BCL
//! rules by the multiplier update and `μ ← k μ` after every step, the strategy Fig. 4
//! shows failing.
//!
//! The solution's `nus` are the multipliers `λ` of the constraints (after the final
//! update: those of the KKT conditions), its `lambdas` the co-states of the last LQ
//! step, `mu` the final penalty, `al_iterations` the number of multiplier updates,
//! `prim_err` the larger of the violation and the dynamics gaps, `dual_err` the control
//! gradient of the Lagrangian.
//!
//! BCL-DDP refuses constraints whose set is not the equality set (naming them) and needs
//! a fixed initial state. The affine multipliers need `h_u` of full rank to be
//! meaningful (III-B): "constraints of the form `h(x) = 0` cannot be directly handled by
//! this method"; state-only constraints (`h_u = 0`, the terminal ones) keep constant
//! multipliers (`Λ = 0`) under [`Multipliers::Affine`].

mod options;

pub use options::{BclDdpOptions, Multipliers, PenaltyUpdate, Schedule};

use std::time::Instant;

use crate::error::{Error, Result};
use crate::problem::{InitialCondition, Problem, StageModel};
use crate::solvers::ddp::augmented::Augmented;
use crate::solvers::ddp::workspace::Workspace;
use crate::solvers::ddp::{Step, backward, line_search, update_reg};
use crate::solvers::log::{COST, Column, Format, ITER, Table};
use crate::solvers::skeleton::{Signature, copy_trajectory, push_record, solution_for, write_gains};
use crate::solvers::{Callback, InitialGuess, IterationRecord, Solution, Status};

/// The solver's name.
const NAME: &str = "bcl-ddp";

/// BCL-DDP's iteration table.
pub const TABLE: Table = Table(COLUMNS);

const COLUMNS: &[Column] = &[
    ITER,
    Column {
        name: "alpha",
        width: 9,
        format: Format::Sci(3),
        value: |r| r.alpha,
        meaning: "step length (0 for an outer update of the multipliers or the penalty)",
    },
    COST,
    Column {
        name: "merit",
        width: 13,
        format: Format::Sci(6),
        value: |r| r.merit,
        meaning: "augmented Lagrangian L_mu (22)/(26) at the start of the step",
    },
    Column {
        name: "|grad|",
        width: 10,
        format: Format::Sci(3),
        value: |r| r.dual_err,
        meaning: "control gradient of the augmented Lagrangian (Q_u of (23)), infinity norm",
    },
    Column {
        name: "omega",
        width: 9,
        format: Format::Sci(2),
        value: |r| r.inner_crit,
        meaning: "gradient tolerance of the inner minimisation (Alg. 1)",
    },
    Column {
        name: "viol",
        width: 10,
        format: Format::Sci(3),
        value: |r| r.prim_err,
        meaning: "constraint violation |h|_inf (and dynamics gaps) at the start of the step",
    },
    Column {
        name: "eta",
        width: 9,
        format: Format::Sci(2),
        value: |r| r.stop,
        meaning: "constraint tolerance of a multiplier update (Alg. 1)",
    },
    Column {
        name: "mu",
        width: 9,
        format: Format::Sci(2),
        value: |r| r.mu,
        meaning: "penalty of the augmented Lagrangian",
    },
    Column {
        name: "al_it",
        width: 6,
        format: Format::Count,
        value: |r| r.al_iter as f64,
        meaning: "multiplier updates so far",
    },
    Column {
        name: "reg",
        width: 9,
        format: Format::Sci(2),
        value: |r| r.preg,
        meaning: "Levenberg-Marquardt regularisation of Q_uu and V_xx",
    },
];

/// BCL-DDP (module documentation).
///
/// ```text
/// let mut solver = BclDdp::new(BclDdpOptions::default());
/// solver.setup(&problem)?;                                   // allocates
/// let sol = solver.solve(&problem, InitialGuess::primal(&xs, &us))?;  // does not
/// ```
pub struct BclDdp {
    /// Options; changes take effect at the next `setup`.
    pub options: BclDdpOptions,
    ws: Option<Box<Workspace>>,
    solution: Solution,
    signature: Signature,
}

impl std::fmt::Debug for BclDdp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BclDdp")
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

impl BclDdp {
    /// A solver with the given options (nothing allocated until `setup`).
    pub fn new(options: BclDdpOptions) -> Self {
        Self {
            options,
            ws: None,
            solution: Solution::default(),
            signature: Signature::default(),
        }
    }

    /// Validates the options, checks the problem (equality constraints only, a fixed
    /// initial state) and allocates every buffer for its dimensions.
    ///
    /// # Errors
    /// If an option is out of range, a constraint's set is not the equality set (the
    /// error names it), or the initial state is not fixed.
    pub fn setup(&mut self, problem: &Problem) -> Result<()> {
        self.options.validate()?;
        self.signature = Signature::default();
        if !matches!(problem.initial_condition(), InitialCondition::Fixed(_)) {
            return Err(Error::InvalidModel(format!(
                "{NAME} needs a fixed initial state x_0 (the problem has a general initial constraint)"
            )));
        }
        let affine = self.options.multipliers == Multipliers::Affine;
        let al = Augmented::new(problem, affine, NAME)?;
        self.ws = Some(Box::new(Workspace::new(problem, &self.options.ddp, None, Some(al))?));
        self.solution = solution_for(problem, self.options.max_iters, None)?;
        self.signature = Signature::of(problem);
        Ok(())
    }

    fn run(
        &mut self,
        problem: &Problem,
        guess: InitialGuess<'_>,
        mut callback: Option<&mut dyn Callback>,
    ) -> Result<&Solution> {
        self.signature.check(problem, NAME)?;
        guess.check(problem)?;
        let start = Instant::now();
        let opts = &self.options;
        let ws = self.ws.as_mut().expect("checked by the signature");
        let sol = &mut self.solution;
        sol.history.clear();
        if opts.log.is_active() {
            opts.log.line(format_args!("{}", TABLE.header()));
        }
        ws.al_mut().reset(guess.nus, opts.mu_init);
        let mut lp = Outer::new(opts);
        let status = if ws.load_guess(problem, &guess, opts.ddp.gap_tol)? {
            lp.read_point(ws);
            lp.c_ref = lp.viol;
            loop {
                if let Some(s) = lp.iteration(ws, problem, opts, sol, start, &mut callback) {
                    break s;
                }
            }
        } else {
            Status::NonFinite
        };
        lp.write_solution(sol, ws, status);
        sol.solve_time = start.elapsed();
        Ok(&self.solution)
    }
}

impl Workspace {
    /// The augmented-Lagrangian terms (BCL-DDP's workspace always has them).
    fn al_mut(&mut self) -> &mut Augmented {
        self.al.as_mut().expect("BCL-DDP's workspace has its augmented terms")
    }
}

/// The state of one solve: the DDP iteration's and Alg. 1's.
struct Outer {
    reg: f64,
    iter: usize,
    rebuild: bool,
    /// Alg. 1's tolerances `η`, `ω`.
    eta: f64,
    omega: f64,
    /// Violation at the last multiplier update (at the guess before the first): the `c'`
    /// of the adaptive penalty.
    c_ref: f64,
    al_iter: usize,
    /// Cost, violation (with the gaps) and gradient of the current point.
    cost: f64,
    viol: f64,
    grad: f64,
}

impl Outer {
    fn new(opts: &BclDdpOptions) -> Self {
        Self {
            reg: opts.ddp.reg_init,
            iter: 0,
            rebuild: true,
            eta: opts.eta_init,
            omega: opts.omega_init,
            c_ref: 0.0,
            al_iter: 0,
            cost: 0.0,
            viol: 0.0,
            grad: 0.0,
        }
    }

    /// Reads the cost and violation of the current point from the data's last
    /// evaluation (which must be the current point's).
    fn read_point(&mut self, ws: &Workspace) {
        let knots = ws.xs.len();
        self.cost = ws.data.cost;
        self.viol = Augmented::violation(&ws.data, knots).max(ws.max_gap());
    }

    /// One iteration: backward pass, convergence test, then an outer update of Alg. 1
    /// or a DDP step. Returns a status when the solve stops.
    fn iteration(
        &mut self,
        ws: &mut Workspace,
        problem: &Problem,
        opts: &BclDdpOptions,
        sol: &mut Solution,
        start: Instant,
        callback: &mut Option<&mut dyn Callback>,
    ) -> Option<Status> {
        let (e, grad) = match backward(ws, problem, &opts.ddp, &mut self.reg, self.rebuild) {
            Ok(e) => e,
            Err(s) => return Some(s),
        };
        self.grad = grad;
        self.rebuild = false;
        let minimised = ws.feasible && grad < self.omega.max(opts.tol);
        if minimised && grad <= opts.tol && self.viol <= opts.tol {
            // The KKT multipliers λ + μ h (24)/(28).
            self.update_multipliers(ws, problem);
            return Some(Status::Converged);
        }
        if opts.max_time.is_some_and(|b| start.elapsed() >= b) {
            return Some(Status::TimeBudget);
        }
        if self.iter >= opts.max_iters {
            return Some(Status::MaxIterations);
        }
        let mut record = self.record(ws);
        if minimised && opts.schedule == Schedule::Bcl {
            record.alpha = 0.0;
            push_record(sol, record, &opts.log, &TABLE);
            self.iter += 1;
            if !self.outer_update(ws, problem, opts) {
                return Some(Status::Stalled);
            }
        } else {
            let step = line_search(ws, problem, e, &opts.ddp);
            record.alpha = step.alpha;
            record.expected_decrease = step.expected;
            record.decrease = step.decrease;
            push_record(sol, record, &opts.log, &TABLE);
            if let Some(s) = self.take_step(ws, problem, opts, &step) {
                return Some(s);
            }
        }
        if let Some(cb) = callback.as_mut()
            && !cb.on_iteration(&record)
        {
            return Some(Status::Interrupted);
        }
        None
    }

    /// The record of an iteration from the current point (step fields left to the caller).
    fn record(&self, ws: &mut Workspace) -> IterationRecord {
        IterationRecord {
            iter: self.iter,
            inner_crit: self.omega,
            prim_err: self.viol,
            dual_err: self.grad,
            preg: self.reg,
            cost: self.cost,
            merit: ws.cost,
            al_iter: self.al_iter,
            mu: ws.al_mut().mu,
            stop: self.eta,
            ..Default::default()
        }
    }

    /// After a line search: the accepted trial becomes the current point, the
    /// regularisation changes, and with [`Schedule::EveryIteration`] the multipliers and
    /// the penalty too.
    fn take_step(
        &mut self,
        ws: &mut Workspace,
        problem: &Problem,
        opts: &BclDdpOptions,
        step: &Step,
    ) -> Option<Status> {
        self.iter += 1;
        ws.end_iteration();
        if let Some(c) = step.cost {
            if !ws.accept(problem, c, step.alpha, opts.ddp.gap_tol) {
                return Some(Status::NonFinite);
            }
            self.read_point(ws);
            self.rebuild = true;
        }
        if !update_reg(&mut self.reg, step, &opts.ddp) {
            return Some(Status::RegularizationFailure);
        }
        if opts.schedule == Schedule::EveryIteration {
            self.update_multipliers(ws, problem);
            let mu = opts.penalty_factor * ws.al_mut().mu;
            if !self.raise_penalty(ws, problem, mu, opts) {
                return Some(Status::Stalled);
            }
        }
        None
    }

    /// Alg. 1's outer step at a minimiser of `L_μ`: the multiplier update and tighter
    /// tolerances if the violation is below `η`, else a larger penalty. `false` when the
    /// penalty would exceed its upper bound.
    fn outer_update(&mut self, ws: &mut Workspace, problem: &Problem, opts: &BclDdpOptions) -> bool {
        let mu = ws.al_mut().mu;
        if self.viol < self.eta {
            self.update_multipliers(ws, problem);
            self.c_ref = self.viol;
            self.eta = (self.eta / mu.powf(opts.bcl_alpha)).max(opts.tol);
            self.omega = (self.omega / mu).max(opts.tol);
            return true;
        }
        let k = opts.penalty_factor;
        let next = match opts.penalty {
            PenaltyUpdate::Factor => k * mu,
            PenaltyUpdate::Adaptive => {
                // II-C: c' = (φ/μ) c'_prev, and φ/μ⁺ = μ⁺^{-β}.
                let phi = mu * self.viol / self.c_ref.max(f64::MIN_POSITIVE);
                phi.powf(1.0 / (1.0 - opts.adaptive_beta))
                    .clamp(k * mu, opts.max_growth * mu)
            }
        };
        self.raise_penalty(ws, problem, next, opts)
    }

    /// The multiplier update (24)/(28) at the current point, whose values the data is
    /// made to hold again (it may hold a rejected trial); the merit follows.
    fn update_multipliers(&mut self, ws: &mut Workspace, problem: &Problem) {
        ws.data.evaluate(problem, &ws.xs, &ws.us);
        let al = ws.al.as_mut().expect("BCL-DDP's workspace has its augmented terms");
        al.update(&ws.data, ws.riccati.stages());
        self.al_iter += 1;
        self.refresh_merit(ws);
    }

    /// Sets the penalty to `mu`, at most `mu_max`, and the merit; `false` (nothing
    /// changed) if the penalty is at `mu_max` already.
    fn raise_penalty(&mut self, ws: &mut Workspace, problem: &Problem, mu: f64, opts: &BclDdpOptions) -> bool {
        if ws.al_mut().mu >= opts.mu_max {
            return false;
        }
        ws.data.evaluate(problem, &ws.xs, &ws.us);
        ws.al_mut().mu = mu.min(opts.mu_max);
        self.refresh_merit(ws);
        true
    }

    /// The merit of the current point (the data holds its values) with the current
    /// multipliers and penalty; the knots are rebuilt at the next backward pass.
    fn refresh_merit(&mut self, ws: &mut Workspace) {
        let cost = ws.data.cost;
        let al = ws.al.as_mut().expect("BCL-DDP's workspace has its augmented terms");
        ws.cost = cost + al.value(&ws.data, None);
        self.rebuild = true;
    }

    fn write_solution(&self, sol: &mut Solution, ws: &mut Workspace, status: Status) {
        copy_trajectory(&mut sol.xs, &ws.xs);
        copy_trajectory(&mut sol.us, &ws.us);
        if status != Status::NonFinite {
            ws.multipliers(&mut sol.lambdas, &mut sol.nus);
            write_gains(sol, ws.riccati.stages());
        }
        let al = ws.al_mut();
        copy_trajectory(&mut sol.nus, &al.lambda);
        sol.mu = al.mu;
        sol.status = status;
        sol.iterations = self.iter;
        sol.al_iterations = self.al_iter;
        sol.prim_err = self.viol;
        sol.dual_err = self.grad;
        sol.cost = self.cost;
    }
}

impl crate::solvers::Solver for BclDdp {
    fn name(&self) -> &'static str {
        NAME
    }
    fn setup(&mut self, problem: &Problem) -> Result<()> {
        BclDdp::setup(self, problem)
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
    fn setup_receding(&mut self, _problem: &Problem, _queue: &[StageModel]) -> Result<()> {
        Err(Error::InvalidModel(format!(
            "{NAME} does not support receding horizons (use proxddp, fddp or csqp)"
        )))
    }
    fn shift(&mut self, _problem: &Problem, _slot: Option<usize>) -> Result<()> {
        Err(crate::solvers::skeleton::not_receding(NAME))
    }
}

//! ALTRO (Howell, Jackson and Manchester 2019): AL-iLQR, the augmented-Lagrangian
//! iterative LQR of the paper's Algorithm 1, with the square-root backward pass of
//! Section III-A.
//!
//! # Algorithm 1 (AL-iLQR)
//!
//! ```text
//! initialise λ = 0 (or the warm start's multipliers), μ = penalty_initial · scale, φ
//! while c_max > constraint_tolerance:
//!     minimise the augmented Lagrangian L_A = J + Σ ψ(c) by iLQR (inner solve)
//!     update λ by (17), μ ← min(φ μ, penalty_max) by (18)
//! ```
//!
//! - *Augmented Lagrangian* (5)-(6): every path and terminal constraint `c(x, u) ∈ K`
//!   with a projection onto `K` (equalities, inequalities, boxes, cones) enters the stage
//!   cost as the PHR term of the module `al_cost` (for `{0}` and `R_-` exactly the paper's
//!   `λᵀc + ½cᵀI_μc` with the active set (6)); one penalty per constraint.
//! - *Inner solve*: the DDP of [`crate::solvers::ddp`] (variant `ddp`: single shooting,
//!   Levenberg-Marquardt regularisation, backtracking line search, its backward pass (7)-(16)
//!   on the LQ kernels of [`crate::lq`], or with [`AltroOptions::square_root`] the
//!   square-root pass (19)-(29) of [`crate::lq::RiccatiSolver::backward_square_root`]) on
//!   a copy of the problem whose costs are the augmented Lagrangians and which has no
//!   constraint. It stops when the expected decrease of a full step is below
//!   `cost_tolerance_intermediate`, or a hundredth of `μ c_max²` if smaller (the
//!   decrease the last multiplier update asks for; our choice, as a threshold on the
//!   expected decrease does not scale with the penalty), and `cost_tolerance` once the
//!   constraints are met.
//! - *Updates*: after each inner solve, `λ ← μ(y - proj_K(y))` with `y = c + λ/μ` (17)
//!   and `μ ← min(φμ, penalty_max)` (18).
//!
//! The initial states are the rollout of the guess's controls from `x_0` (Algorithm 4,
//! line 6), or with the infeasible start the guess's states (line 4).
//!
//! The solve has converged when `c_max ≤ constraint_tolerance` after an inner solve that
//! converged to `cost_tolerance`. Without the projection the returned `nus` are the
//! multipliers `λ`, `lambdas` the co-states of the inner solve's last backward pass; after
//! a converged projection both are the multipliers of the projected point, from the
//! projection's KKT system with the cost gradient (module `projection`), which certify
//! its stationarity. It stops as `Stalled` when an inner solve with every penalty at
//! `penalty_max` does not move the point while the constraints are violated: the
//! augmented Lagrangian is stationary there for any multiplier (the violated
//! constraints' gradients vanish, as at a symmetric start).
//!
//! - *Infeasible start* (III-B, [`AltroOptions::infeasible_start`]): slack controls `s`
//!   with `x_{k+1} = f(x_k, u_k) ⊕ s_k` ((30); `+` on vector spaces) start from the guess's states with the slacks
//!   (31) that make them feasible; the cost `½R_s|s|²` (32) and the constraint `s = 0` join
//!   the augmented Lagrangian, and the projection closes what is left of the gaps.
//! - *Projection* (Algorithm 2, [`AltroOptions::projected_newton`]): module `projection`.
//!
//! Minimum-time problems (III-C) are built at the problem level
//! ([`crate::problem::MinimumTime`]: the time step as a control), which ALTRO solves as any
//! other problem.

mod al_cost;
mod options;
mod projection;
mod slack;

pub use options::AltroOptions;

use std::sync::Arc;
use std::time::Instant;

use al_cost::AlCost;

use crate::dynamics::Dynamics;
use crate::error::{Error, Result};
use crate::functions::StageFunctionData;
use crate::problem::{Problem, ProblemData, StageModel};
use crate::solvers::ddp::Ddp;
use crate::solvers::log::{COST, Column, Format, ITER, Table};
use crate::solvers::skeleton::{Signature, copy_trajectory, push_record, solution_for};
use crate::solvers::{Callback, InitialGuess, IterationRecord, Solution, Solver, Status};

/// ALTRO's iteration table: one line per outer iteration.
pub const TABLE: Table = Table(COLUMNS);

const COLUMNS: &[Column] = &[
    ITER,
    Column {
        name: "al_iter",
        width: 7,
        format: Format::Count,
        value: |r| r.al_iter as f64,
        meaning: "outer iteration (multiplier and penalty update)",
    },
    COST,
    Column {
        name: "c_max",
        width: 10,
        format: Format::Sci(3),
        value: |r| r.prim_err,
        meaning: "largest constraint violation after the inner solve",
    },
    Column {
        name: "stop",
        width: 10,
        format: Format::Sci(3),
        value: |r| r.stop,
        meaning: "expected decrease of the inner solve's last full step",
    },
    Column {
        name: "mu_max",
        width: 9,
        format: Format::Sci(2),
        value: |r| r.mu,
        meaning: "largest penalty",
    },
];

/// ALTRO's AL-iLQR ([`AltroOptions`]; module docs).
///
/// ```text
/// let mut solver = Altro::new(AltroOptions::default());
/// solver.setup(&problem)?;                                   // allocates
/// let sol = solver.solve(&problem, InitialGuess::primal(&xs, &us))?;  // does not
/// ```
pub struct Altro {
    /// Options; changes take effect at the next `setup`.
    pub options: AltroOptions,
    ws: Option<Box<Workspace>>,
    solution: Solution,
    signature: Signature,
}

impl std::fmt::Debug for Altro {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Altro")
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

/// Everything `solve` uses, allocated in `setup`.
struct Workspace {
    /// The problem with augmented-Lagrangian costs and no constraint.
    aug: Problem,
    /// Its costs, stage by stage then the terminal one (for λ and μ).
    costs: Vec<Arc<AlCost>>,
    inner: Ddp,
    /// Evaluation of the original problem (its cost).
    data: ProblemData,
    /// Constraint evaluations, per cost.
    fdata: Vec<Vec<StageFunctionData>>,
    y: Vec<f64>,
    e: Vec<f64>,
    xs: Vec<Vec<f64>>,
    /// Controls of the augmented problem (with the slack controls of III-B after the
    /// problem's own), and the problem's own.
    us: Vec<Vec<f64>>,
    us_orig: Vec<Vec<f64>>,
    no_u: Vec<f64>,
    /// Cost of the original problem at the current point.
    cost: f64,
    projection: projection::Projection,
}

impl Workspace {
    fn new(problem: &Problem, opts: &AltroOptions) -> Result<Self> {
        if opts.infeasible_start && !explicit(problem) {
            return Err(Error::option(
                "infeasible_start",
                "needs explicit dynamics (the slack controls move the next state)",
            ));
        }
        let mut costs = Vec::with_capacity(problem.horizon() + 1);
        let mut stages = Vec::with_capacity(problem.horizon());
        for s in problem.stages() {
            let cons = s.constraints().to_vec();
            let (cost, dynamics) = match &s.dynamics {
                Dynamics::Explicit(d) if opts.infeasible_start => (
                    AlCost::with_slack(s.cost.clone(), cons, s.space_next().ndx(), opts.slack_weight),
                    Dynamics::Explicit(Arc::new(slack::SlackDynamics::new(d.clone()))),
                ),
                _ => (AlCost::new(s.cost.clone(), cons), s.dynamics.clone()),
            };
            let c = Arc::new(cost);
            stages.push(StageModel::new(c.clone(), dynamics)?);
            costs.push(c);
        }
        let term = Arc::new(AlCost::new(
            problem.terminal_cost().clone(),
            problem.terminal_constraints().to_vec(),
        ));
        costs.push(term.clone());
        let aug = Problem::with_initial(problem.initial_condition().clone(), stages, term)?;
        let mut inner = Ddp::new(opts.inner.clone().with(|o| {
            o.max_iters = opts.iterations_inner;
            o.square_root = opts.square_root;
            o.th_stop = Some(opts.cost_tolerance_intermediate);
            o.log = crate::solvers::log::LogSink::Silent;
        }));
        inner.setup(&aug)?;
        let nr = problem
            .stages()
            .iter()
            .flat_map(|s| s.constraints())
            .chain(problem.terminal_constraints())
            .map(|c| c.nr())
            .max()
            .unwrap_or(0);
        let sol = Solution::new(problem, 0);
        let aug_us = Solution::new(&aug, 0).us;
        Ok(Self {
            fdata: costs.iter().map(|c| c.create_function_data()).collect(),
            costs,
            aug,
            inner,
            data: ProblemData::new(problem, 1)?,
            y: vec![0.0; nr],
            e: vec![0.0; nr],
            xs: sol.xs,
            us: aug_us,
            us_orig: sol.us,
            no_u: Vec::new(),
            cost: 0.0,
            projection: projection::Projection::new(problem, vector_spaces(problem))?,
        })
    }

    /// Sets `λ` from the warm start's `nus` (or 0) and `μ` to its initial value.
    fn init_multipliers(&mut self, nus: Option<&[Vec<f64>]>, opts: &AltroOptions) {
        for (t, c) in self.costs.iter().enumerate() {
            for i in 0..c.lambda.len() {
                c.lambda.set(i, nus.and_then(|n| n[t].get(i).copied()).unwrap_or(0.0));
            }
            let cons = c.constraints();
            for i in 0..c.mu.len() {
                c.mu.set(i, opts.penalty_initial * cons.get(i).map_or(1.0, |k| k.scale));
            }
        }
    }

    /// The starting point (Algorithm 4, lines 3-7): the guess's controls; with the
    /// infeasible start, its states and the slack controls (31) `s_k = x̃_{k+1} ⊖ f(x̃_k, u_k)`
    /// that make them feasible; otherwise the states simulated from `x_0`.
    fn start(&mut self, problem: &Problem, guess: &InitialGuess<'_>, infeasible: bool) -> Result<()> {
        copy_trajectory(&mut self.xs, guess.xs);
        copy_trajectory(&mut self.us_orig, guess.us);
        if let Some(x0) = problem.x0() {
            self.xs[0].copy_from_slice(x0);
            // The augmented problem was built with the x_0 of the setup.
            self.aug.set_x0(x0)?;
        }
        for (u, g) in self.us.iter_mut().zip(guess.us) {
            u[..g.len()].copy_from_slice(g);
            u[g.len()..].fill(0.0);
        }
        if !infeasible {
            return self.data.rollout(problem, &mut self.xs, guess.us).map_err(|e| match e {
                Error::NonFinite { what } => Error::non_finite(format!(
                    "{what}: the guess's controls do not roll out from x_0 (the infeasible start, option \
                     `infeasible_start`, starts from the guess's states instead)"
                )),
                e => e,
            });
        }
        self.data.evaluate(problem, &self.xs, guess.us);
        for (t, (u, g)) in self.us.iter_mut().zip(guess.us).enumerate() {
            let f = self.data.stages[t]
                .xnext()
                .expect("explicit dynamics (checked in setup)");
            problem.stages()[t]
                .space_next()
                .difference(f, &self.xs[t + 1], &mut u[g.len()..]);
        }
        Ok(())
    }

    /// The problem's own controls from the augmented ones.
    fn sync_controls(&mut self) {
        for (o, u) in self.us_orig.iter_mut().zip(&self.us) {
            let n = o.len();
            o.copy_from_slice(&u[..n]);
        }
    }

    /// The largest constraint violation at the current point; with `update`, also the
    /// multiplier update (17) (clamped to `dual_max`).
    fn constraints(&mut self, update: bool, dual_max: f64) -> f64 {
        let n = self.us.len();
        let mut viol: f64 = 0.0;
        for (t, c) in self.costs.iter().enumerate() {
            let u = if t < n { &self.us[t][..] } else { &self.no_u[..] };
            let v = c.update_multipliers(&self.xs[t], u, &mut self.fdata[t], &mut self.y, &mut self.e, update);
            viol = crate::linalg::max_nan(viol, v);
            if update {
                for i in 0..c.lambda.len() {
                    c.lambda.set(i, c.lambda.get(i).clamp(-dual_max, dual_max));
                }
            }
        }
        viol
    }

    /// `μ ← min(φμ, μ_max)` (18); returns the largest penalty.
    fn scale_penalties(&mut self, opts: &AltroOptions) -> f64 {
        let mut m: f64 = 0.0;
        for c in &self.costs {
            for i in 0..c.mu.len() {
                let mu = (c.mu.get(i) * opts.penalty_scaling).min(opts.penalty_max);
                c.mu.set(i, mu);
                m = m.max(mu);
            }
        }
        m
    }

    /// The inner iLQR on the augmented Lagrangian from the current point, to the expected
    /// decrease `th`; the current point becomes its solution. Returns its status, its last
    /// expected decrease and its iterations.
    fn inner_solve(&mut self, th: f64, budget: Option<std::time::Duration>) -> Result<(Status, f64, usize)> {
        self.inner.options.th_stop = Some(th);
        self.inner.options.max_time = budget;
        let s = self.inner.solve(&self.aug, InitialGuess::primal(&self.xs, &self.us))?;
        copy_trajectory(&mut self.xs, &s.xs);
        copy_trajectory(&mut self.us, &s.us);
        Ok((s.status, s.history.last().map_or(0.0, |r| r.stop), s.iterations))
    }

    fn max_penalty(&self) -> f64 {
        let mut m: f64 = 0.0;
        for c in &self.costs {
            m = c.mu.iter().fold(m, f64::max);
        }
        m
    }
}

/// How far above the projection's tolerance a stuck AL-iLQR point is still handed to
/// the projection.
const HANDOFF: f64 = 2.0;

/// Whether every stage has explicit dynamics.
fn explicit(problem: &Problem) -> bool {
    problem
        .stages()
        .iter()
        .all(|s| matches!(s.dynamics, crate::dynamics::Dynamics::Explicit(_)))
}

/// Whether every knot's LQ has `E = -I` (explicit dynamics on vector spaces).
fn vector_spaces(problem: &Problem) -> bool {
    problem
        .stages()
        .iter()
        .all(|s| matches!(s.dynamics, crate::dynamics::Dynamics::Explicit(_)) && s.space_next().is_vector_space())
}

impl Altro {
    /// A solver with the given options (nothing allocated until `setup`).
    pub fn new(options: AltroOptions) -> Self {
        Self {
            options,
            ws: None,
            solution: Solution::default(),
            signature: Signature::default(),
        }
    }

    /// Validates the options and allocates everything for `problem`'s dimensions: the
    /// augmented problem and its inner iLQR.
    ///
    /// # Errors
    /// If an option is out of range, or the inner solver refuses the augmented problem
    /// (no fixed initial state; the square-root pass on a manifold state or implicit
    /// dynamics).
    pub fn setup(&mut self, problem: &Problem) -> Result<()> {
        self.options.validate()?;
        self.signature = Signature::default();
        self.ws = Some(Box::new(Workspace::new(problem, &self.options)?));
        self.solution = solution_for(problem, self.options.iterations_outer, None)?;
        self.signature = Signature::of(problem);
        Ok(())
    }

    fn run(
        &mut self,
        problem: &Problem,
        guess: InitialGuess<'_>,
        mut callback: Option<&mut dyn Callback>,
    ) -> Result<&Solution> {
        self.signature.check(problem, "altro")?;
        guess.check(problem)?;
        let start = Instant::now();
        let opts = &self.options;
        let ws = self.ws.as_mut().expect("checked by the signature");
        let sol = &mut self.solution;
        sol.history.clear();
        if opts.log.is_active() {
            opts.log.line(format_args!("{}", TABLE.header()));
        }
        ws.start(problem, &guess, opts.infeasible_start)?;
        ws.init_multipliers(guess.nus, opts);
        let (mut status, inner_iters, mut viol) = outer_loop(ws, problem, opts, sol, &mut callback, start)?;
        let projected = status == Status::Converged && opts.projected_newton;
        if projected {
            (status, viol) = project(ws, problem, opts, sol, inner_iters);
        }
        write_solution(sol, ws, status, inner_iters, viol);
        if projected && status == Status::Converged {
            // The AL multipliers are those of the point before the projection.
            ws.projection.multipliers(
                problem,
                &mut ws.data,
                &ws.costs,
                &ws.xs,
                &ws.us_orig,
                &mut sol.lambdas,
                &mut sol.nus,
            );
        }
        sol.solve_time = start.elapsed();
        Ok(&self.solution)
    }
}

/// Algorithm 1's outer loop: inner iLQR solves on the augmented Lagrangian, multiplier
/// and penalty updates (17)-(18), one table row each. Returns the status, the inner
/// iterations and the last constraint violation.
fn outer_loop(
    ws: &mut Workspace,
    problem: &Problem,
    opts: &AltroOptions,
    sol: &mut Solution,
    callback: &mut Option<&mut dyn Callback>,
    start: Instant,
) -> Result<(Status, usize, f64)> {
    let tol = if opts.projected_newton {
        opts.projected_newton_tolerance.max(opts.constraint_tolerance)
    } else {
        opts.constraint_tolerance
    };
    let (mut inner_iters, mut viol) = (0, f64::INFINITY);
    for outer in 0..opts.iterations_outer {
        let last = viol <= tol;
        let th = if last {
            opts.cost_tolerance
        } else {
            inner_tolerance(opts, viol, ws.max_penalty())
        };
        let budget = opts.max_time.map(|b| b.saturating_sub(start.elapsed()));
        let (inner_status, stop, iters) = ws.inner_solve(th, budget)?;
        inner_iters += iters;
        if inner_status == Status::NonFinite {
            return Ok((Status::NonFinite, inner_iters, viol));
        }
        viol = ws.constraints(false, opts.dual_max);
        if viol.is_nan() {
            return Ok((Status::NonFinite, inner_iters, viol));
        }
        ws.sync_controls();
        ws.cost = ws.data.evaluate(problem, &ws.xs, &ws.us_orig);
        let record = IterationRecord {
            iter: inner_iters,
            al_iter: outer,
            cost: ws.cost,
            prim_err: viol,
            stop,
            mu: ws.max_penalty(),
            ..Default::default()
        };
        push_record(sol, record, &opts.log, &TABLE);
        if let Some(status) = outer_stop(opts, inner_status, viol, tol, last, start) {
            return Ok((status, inner_iters, viol));
        }
        // With every penalty at its largest, an inner solve that does not move the point
        // leaves nothing to change but multipliers that already failed to move it: the
        // augmented Lagrangian is stationary at a violated point (the constraints'
        // gradients vanish there, as at the hanging pendulum's symmetric start).
        if iters == 0 && viol > tol && ws.max_penalty() >= opts.penalty_max {
            return Ok((Status::Stalled, inner_iters, viol));
        }
        // (17)-(18), unless the constraints are met and only the cost tolerance is not.
        if viol > tol {
            ws.constraints(true, opts.dual_max);
            ws.scale_penalties(opts);
        }
        if let Some(cb) = callback.as_mut()
            && !cb.on_iteration(&record)
        {
            return Ok((Status::Interrupted, inner_iters, viol));
        }
    }
    Ok((Status::MaxIterations, inner_iters, viol))
}

/// Whether the outer loop ends after an inner solve that ended with `inner_status` at the
/// violation `viol` (`last`: it ran with the final cost tolerance), and with which status.
fn outer_stop(
    opts: &AltroOptions,
    inner_status: Status,
    viol: f64,
    tol: f64,
    last: bool,
    start: Instant,
) -> Option<Status> {
    // The inner solve converged to cost_tolerance when it ran with it.
    let inner_ok = last && matches!(inner_status, Status::Converged | Status::Stalled);
    if viol <= tol && inner_ok {
        return Some(Status::Converged);
    }
    // An inner solve that can no longer step (its line search or regularisation gave
    // up) near the projection's tolerance: the penalties would only grow while the point
    // stays, so the projection (Algorithm 3) takes it from here.
    let stuck = matches!(inner_status, Status::RegularizationFailure | Status::LinesearchFailure);
    if stuck && opts.projected_newton && viol <= HANDOFF * tol {
        return Some(Status::Converged);
    }
    opts.max_time
        .is_some_and(|b| start.elapsed() >= b)
        .then_some(Status::TimeBudget)
}

/// Algorithm 2 from the AL-iLQR solution: the status and the violation reached (a row of
/// the table with `al_iter` one past the last outer iteration).
fn project(
    ws: &mut Workspace,
    problem: &Problem,
    opts: &AltroOptions,
    sol: &mut Solution,
    iters: usize,
) -> (Status, f64) {
    let v = ws.projection.run(
        problem,
        &mut ws.data,
        &ws.costs,
        &mut ws.xs,
        &mut ws.us_orig,
        opts.constraint_tolerance,
        opts.projected_newton_steps,
    );
    ws.cost = ws.data.evaluate(problem, &ws.xs, &ws.us_orig);
    let record = IterationRecord {
        iter: iters,
        al_iter: sol.history.len(),
        cost: ws.cost,
        prim_err: v,
        mu: ws.max_penalty(),
        ..Default::default()
    };
    push_record(sol, record, &opts.log, &TABLE);
    let status = if v <= opts.constraint_tolerance {
        Status::Converged
    } else {
        Status::Stalled
    };
    (status, v)
}

/// The inner tolerance before the constraints are met: `cost_tolerance_intermediate`, but
/// at most a hundredth of `μ c_max²`, the expected decrease of the step that the last
/// multiplier update asks for (`δλ = μc` against a Hessian of size `μ`), so that the inner
/// solve takes that step however large the penalty (a fixed threshold on the expected
/// decrease stops the inner solve before it moves once `μ` is large).
fn inner_tolerance(opts: &AltroOptions, viol: f64, mu: f64) -> f64 {
    let step = if viol.is_finite() {
        1e-2 * mu * viol * viol
    } else {
        f64::INFINITY
    };
    opts.cost_tolerance_intermediate.min(step).max(opts.cost_tolerance)
}

fn write_solution(sol: &mut Solution, ws: &mut Workspace, status: Status, iters: usize, viol: f64) {
    copy_trajectory(&mut sol.xs, &ws.xs);
    copy_trajectory(&mut sol.us, &ws.us_orig);
    let inner = ws.inner.solution();
    copy_trajectory(&mut sol.lambdas, &inner.lambdas);
    // The gains of the problem's own controls (the slack controls' rows dropped).
    for (f, g) in sol.feedforward.iter_mut().zip(&inner.feedforward) {
        let n = f.nrows();
        f.copy_from(g.subrows(0, n));
    }
    for (f, g) in sol.feedback.iter_mut().zip(&inner.feedback) {
        let n = f.nrows();
        f.copy_from(g.subrows(0, n));
    }
    for (t, c) in ws.costs.iter().enumerate() {
        c.lambda.read(&mut sol.nus[t]);
    }
    sol.status = status;
    sol.iterations = iters;
    sol.al_iterations = sol.history.len();
    sol.prim_err = viol;
    sol.dual_err = inner.dual_err;
    sol.cost = ws.cost;
    sol.mu = ws.max_penalty();
}

impl Solver for Altro {
    fn name(&self) -> &'static str {
        "altro"
    }
    fn setup(&mut self, problem: &Problem) -> Result<()> {
        Altro::setup(self, problem)
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
    /// `max_iters` bounds each inner iLQR solve (`iterations_inner`).
    fn set_limits(&mut self, max_iters: usize, max_time: Option<std::time::Duration>) {
        self.options.iterations_inner = max_iters;
        self.options.max_time = max_time;
    }
    fn setup_receding(&mut self, _problem: &Problem, _queue: &[StageModel]) -> Result<()> {
        Err(Error::InvalidModel(
            "altro does not implement receding horizons (use proxddp or the ddp family)".into(),
        ))
    }
    fn shift(&mut self, _problem: &Problem, _slot: Option<usize>) -> Result<()> {
        Err(Error::InvalidModel(
            "altro::shift: altro does not implement receding horizons".into(),
        ))
    }
}

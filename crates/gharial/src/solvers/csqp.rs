//! CSQP (Jordana et al. 2023): stagewise SQP with path and terminal constraints, each QP
//! subproblem solved by the stagewise ADMM of [`crate::solvers::admm`].
//!
//! Each iteration linearises the problem at the current point (Gauss-Newton cost
//! Hessians, dynamics Jacobians and gaps, constraint Jacobians) into the QP
//! ```text
//! min  Σ ℓ-model(δx, δu)   s.t.  linearised dynamics with the gaps,
//!      lo - h(x, u) ≤ h_x δx + h_u δu ≤ hi - h(x, u)
//! ```
//! (written for a box; in general `h(x, u) + h_x δx + h_u δu ∈ C` for the constraint's
//! closed convex set `C`: equalities, orthants, boxes, second-order cones such as
//! friction cones, and their products; penalties such as L1 are refused), solves it by
//! ADMM, whose projection is `proj_C(· + h) - h`, and takes the step `x ⊕ α δx, u + α δu` with SQP's filter line search on (cost,
//! 1-norm of the gaps and constraint violations). The QP's co-states and constraint
//! multipliers are the multipliers of the next KKT test (an iteration whose step the
//! filter rejects keeps the point, and its warm-started QP continues the ADMM iterations
//! of the same subproblem): the solve has converged when
//! `max(|∇L|_∞, |gaps|_∞, |violation|_∞)` is below `tol` (the paper's (20) with the
//! constraints).
//!
//! The reported gains `k_t`, `K_t` (the MPC feedback policy's) are those of the last QP
//! with its active rows as equalities and its inactive rows dropped
//! ([`AdmmQp::active_set_factor`], one more Riccati factorization per solve): box-DDP's
//! gains on control bounds. mim_solvers reports the gains of the ADMM's penalised LQ
//! instead, which grow with the penalty `ρ`.

use std::time::{Duration, Instant};

use super::admm::{AdmmOptions, AdmmQp, RowSets, clamp};
use super::log::{COST, Column, Format, ITER, LogSink, Table};
use super::skeleton::{
    ConstraintEntry, Receding, Signature, SqpFilter, constraint_index, copy_stage_model, fill_constraint_index,
    pad_constraint_rows, push_record,
};
use super::{Callback, InitialGuess, IterationRecord, Solution, Solver, Status};
use crate::error::{Error, Result};
use crate::linalg::{max_nan, norm_inf, slice, slice_mut};
use crate::lq::LqProblem;
use crate::problem::{Problem, ProblemData, StageData, StageModel};

/// Smallest and largest regularisation of a singular QP ([`Workspace::solve_qp_regularized`]).
const REG_MIN: f64 = 1e-9;
const REG_MAX: f64 = 1e9;

/// Options of [`Csqp`].
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct CsqpOptions {
    /// KKT tolerance (default 1e-6).
    pub tol: f64,
    /// SQP iterations at most (default 300).
    pub max_iters: usize,
    /// The QP solver (default: mim_solvers' `eps_abs = eps_rel = 1e-4`, 1000 iterations).
    pub admm: AdmmOptions,
    /// Keep ADMM's `z`, duals and `ρ` from one SQP iteration to the next (default true;
    /// false resets them, the paper's MPC setting keeps `ρ`).
    pub warm_qp: bool,
    /// Step lengths tried: `1, 1/2, ..., 2^-(linesearch_steps - 1)` (default 10).
    pub linesearch_steps: usize,
    /// Line searches in a row that may find no acceptable step before the solve stops as
    /// [`Status::LinesearchFailure`] (default 5). With `warm_qp` a failed search keeps the
    /// point and the next QP continues the ADMM iterations of the same subproblem (an
    /// inexact QP step can fail near a solution); without it the first failure stops.
    pub max_linesearch_failures: usize,
    /// The filter's memory (default 1).
    pub filter_size: usize,
    /// Wall-time budget (default none).
    pub max_time: Option<Duration>,
    /// Threads of the stage-wise evaluation and derivatives (default 1).
    pub num_threads: usize,
    /// Where the iteration log goes (default nowhere).
    pub log: LogSink,
}

impl Default for CsqpOptions {
    fn default() -> Self {
        Self {
            tol: 1e-6,
            max_iters: 300,
            admm: AdmmOptions::default(),
            warm_qp: true,
            linesearch_steps: 10,
            max_linesearch_failures: 5,
            filter_size: 1,
            max_time: None,
            num_threads: 1,
            log: LogSink::default(),
        }
    }
}

impl CsqpOptions {
    /// The options after `f` changed them (builder style).
    pub fn with(mut self, f: impl FnOnce(&mut Self)) -> Self {
        f(&mut self);
        self
    }

    /// Checks every option's range.
    ///
    /// # Errors
    /// Names the offending option.
    pub fn validate(&self) -> Result<()> {
        crate::error::check_positive("tol", self.tol)?;
        if self.max_iters == 0 {
            return Err(Error::option("max_iters", "must be at least 1"));
        }
        if !(1..=60).contains(&self.linesearch_steps) {
            return Err(Error::option("linesearch_steps", "must be in 1..=60"));
        }
        if self.max_linesearch_failures == 0 {
            return Err(Error::option("max_linesearch_failures", "must be at least 1"));
        }
        if !(1..=1000).contains(&self.filter_size) {
            return Err(Error::option("filter_size", "must be in 1..=1000"));
        }
        if self.num_threads == 0 {
            return Err(Error::option("num_threads", "must be at least 1"));
        }
        self.admm.validate()
    }
}

/// The iteration table of CSQP.
pub const TABLE: Table = Table(&[
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
        name: "KKT",
        width: 10,
        format: Format::Sci(3),
        value: |r| r.stop,
        meaning: "max(|grad L|, gaps, constraint violation) at the start of the step",
    },
    Column {
        name: "infeas",
        width: 10,
        format: Format::Sci(3),
        value: |r| r.prim_err,
        meaning: "largest gap or constraint violation (infinity norm)",
    },
    Column {
        name: "qp_iters",
        width: 9,
        format: Format::Count,
        value: |r| r.inner_crit,
        meaning: "ADMM iterations of the step's QP",
    },
    Column {
        name: "rho",
        width: 9,
        format: Format::Sci(2),
        value: |r| r.mu,
        meaning: "ADMM penalty at the end of the step's QP",
    },
]);

/// Everything a CSQP solve uses, allocated at setup.
struct Workspace {
    data: ProblemData,
    lq: LqProblem,
    admm: AdmmQp,
    xs: Vec<Vec<f64>>,
    us: Vec<Vec<f64>>,
    xs_try: Vec<Vec<f64>>,
    us_try: Vec<Vec<f64>>,
    /// Co-states and path multipliers of the last QP.
    lams: Vec<Vec<f64>>,
    nus: Vec<Vec<f64>>,
    /// Scratch of the projections (the largest constraint's rows).
    w: Vec<f64>,
    out: Vec<f64>,
    /// Per knot row: the bounds `lo - h, hi - h` of the QP's rows of box-shaped sets
    /// (boxes, orthants, equalities), whether the row's set is one (by its first row).
    lo: Vec<Vec<f64>>,
    hi: Vec<Vec<f64>>,
    boxed: Vec<Vec<bool>>,
    /// Per knot: `Some(end)` when every set of the knot is box-shaped, its rows `0..end`
    /// (projected by one clamp).
    all_boxed: Vec<Option<usize>>,
    /// Entries of `cons` of each knot: `knot_entries[t]..knot_entries[t + 1]`.
    knot_entries: Vec<usize>,
    gx: Vec<Vec<f64>>,
    gu: Vec<Vec<f64>>,
    cons: Vec<ConstraintEntry>,
    filter: SqpFilter,
    cost: f64,
    /// Regularisation of the next QP (0 unless a QP's Hessian was singular).
    reg: f64,
    /// Whether the current solve has solved a QP (whose gains it reports).
    qp_solved: bool,
    /// Receding horizon: the data of the queued stages, slot by slot.
    spare: Vec<StageData>,
    receding: bool,
}

/// Measures of the current point.
#[derive(Debug, Clone, Copy, Default)]
struct Infeasibility {
    /// Largest gap or violation.
    max: f64,
    /// Sum of the 1-norms of the gaps and violations.
    l1: f64,
}

impl Workspace {
    /// The workspace of `problem`; with `queue`, also for a receding horizon through the
    /// stages queued to enter it ([`Workspace::shift`]).
    fn new(problem: &Problem, opts: &CsqpOptions, queue: Option<&[StageModel]>) -> Result<Self> {
        let receding = queue.map(|q| Receding::of(problem, q)).transpose()?;
        let queue = queue.unwrap_or(&[]);
        let n = problem.horizon();
        let queued = queue.iter().flat_map(|s| s.constraints());
        let mut max_nr = 0;
        for (i, c) in (0..=n).flat_map(|t| problem.constraints(t)).chain(queued).enumerate() {
            let far = |v: f64| c.set.violation(&vec![v; c.nr()]) > 0.0;
            if !(far(1e6) || far(-1e6)) {
                return Err(Error::InvalidModel(format!(
                    "csqp handles constraint sets: constraint `{}` (number {i}) has a penalty, not a set \
                     (use proxddp)",
                    c.name
                )));
            }
            max_nr = max_nr.max(c.nr());
        }
        let mut cons = constraint_index(problem);
        let lq = super::skeleton::lq_for(problem, true, receding.map(|r| r.max_nc));
        let admm = AdmmQp::new(&lq, opts.admm)?;
        let rows: Vec<Vec<f64>> = lq.knots.iter().map(|k| vec![0.0; k.nc]).collect();
        let mut s = Solution::new(problem, 0);
        if let Some(r) = receding {
            r.reserve_index(problem, &mut cons);
            r.reserve_rows(&mut s.nus, n);
        }
        let mut ws = Self {
            data: ProblemData::new(problem, opts.num_threads)?,
            lq,
            admm,
            xs_try: s.xs.clone(),
            us_try: s.us.clone(),
            gx: (0..=n).map(|t| vec![0.0; problem.space(t).ndx()]).collect(),
            gu: s.us.clone(),
            xs: s.xs,
            us: s.us,
            lams: s.lambdas,
            nus: s.nus,
            w: vec![0.0; max_nr],
            out: vec![0.0; max_nr],
            boxed: rows.iter().map(|r| vec![false; r.len()]).collect(),
            all_boxed: vec![None; rows.len()],
            lo: rows.clone(),
            hi: rows,
            knot_entries: vec![0; n + 2],
            cons,
            filter: SqpFilter::new(opts.filter_size),
            cost: 0.0,
            reg: 0.0,
            qp_solved: false,
            spare: queue.iter().map(StageData::new).collect(),
            receding: receding.is_some(),
        };
        ws.index_knots(problem);
        Ok(ws)
    }

    /// The entries of each knot in the constraint index.
    fn index_knots(&mut self, problem: &Problem) {
        for t in 0..=problem.horizon() {
            self.knot_entries[t + 1] = self.knot_entries[t] + problem.constraints(t).len();
        }
    }

    /// Receding horizon, after [`Problem::shift`] took the queued stage `slot` (`None`:
    /// after [`Problem::rotate`]): the stage data and path multipliers move one knot
    /// earlier, the constraint index and the inert rows of the padded LQ knots follow the
    /// new stages. Allocates nothing.
    fn shift(&mut self, problem: &Problem, slot: Option<usize>) -> Result<()> {
        if !self.receding || slot.is_some_and(|s| s >= self.spare.len()) {
            return Err(Error::InvalidModel(format!(
                "csqp::shift: slot {slot:?} of a queue of {} stages (was setup_receding called?)",
                self.spare.len()
            )));
        }
        self.data.shift(slot.map(|s| &mut self.spare[s]));
        let n = problem.horizon();
        super::skeleton::shift_rows(&mut self.nus, n, problem.stages()[n - 1].nc());
        fill_constraint_index(problem, &mut self.cons);
        self.index_knots(problem);
        for (t, knot) in self.lq.knots[..n].iter_mut().enumerate() {
            pad_constraint_rows(knot, problem.stages()[t].nc());
        }
        Ok(())
    }

    /// The guess as the current point, evaluated with derivatives; `false` if a value is
    /// not finite.
    fn load(&mut self, problem: &Problem, guess: &InitialGuess<'_>) -> bool {
        super::skeleton::copy_trajectory(&mut self.xs, guess.xs);
        super::skeleton::copy_trajectory(&mut self.us, guess.us);
        let zero = |v: &mut Vec<Vec<f64>>| v.iter_mut().for_each(|x| x.fill(0.0));
        match guess.lambdas {
            Some(l) => super::skeleton::copy_trajectory(&mut self.lams, l),
            None => zero(&mut self.lams),
        }
        match guess.nus {
            Some(v) => super::skeleton::copy_trajectory(&mut self.nus, v),
            None => zero(&mut self.nus),
        }
        self.filter.clear();
        self.data.start_solve();
        self.cost = self.data.evaluate(problem, &self.xs, &self.us);
        self.cost.is_finite() && self.derivatives(problem)
    }

    /// Derivatives at the point of the last evaluation; `false` if one is not finite.
    fn derivatives(&mut self, problem: &Problem) -> bool {
        self.data.compute_derivatives(problem, &self.xs, &self.us);
        self.data.stages.iter().all(|s| {
            crate::linalg::all_finite(s.dyn_jx.as_ref())
                && crate::linalg::all_finite(s.dyn_ju.as_ref())
                && s.cost.lx().iter().chain(s.cost.lu()).all(|v| v.is_finite())
        })
    }

    /// Gaps and constraint violations of the data's last evaluation.
    fn infeasibility(&mut self, problem: &Problem) -> Infeasibility {
        let mut m = Infeasibility::default();
        let mut add = |v: f64| {
            m.max = max_nan(m.max, v.abs());
            m.l1 += v.abs();
        };
        self.data.init.value().iter().for_each(|v| add(*v));
        for sd in &self.data.stages {
            sd.dyn_value().iter().for_each(|v| add(*v));
        }
        for e in &self.cons {
            let c = &problem.constraints(e.t)[e.k];
            add(crate::constraints::violation_or_nan(
                c.set.as_ref(),
                self.data.constraint_data(e.t)[e.k].value(),
            ));
        }
        m
    }

    /// The QP of the current point (its knots; the sets are applied by [`ShiftedSets`]).
    fn build_qp(&mut self, problem: &Problem) {
        let n = problem.horizon();
        crate::linalg::copy(self.lq.G0.as_mut(), self.data.init.jx.as_ref());
        slice_mut(&mut self.lq.g0).copy_from_slice(self.data.init.value());
        for t in 0..=n {
            let knot = &mut self.lq.knots[t];
            if t < n {
                let sd = &self.data.stages[t];
                copy_stage_model(knot, sd, true, true);
                slice_mut(&mut knot.q).copy_from_slice(sd.cost.lx());
                slice_mut(&mut knot.r).copy_from_slice(sd.cost.lu());
                slice_mut(&mut knot.f).copy_from_slice(sd.dyn_value());
            } else {
                crate::linalg::copy(knot.Q.as_mut(), self.data.terminal_cost.lxx.as_ref());
                slice_mut(&mut knot.q).copy_from_slice(self.data.terminal_cost.lx());
            }
        }
        for e in &self.cons {
            let (t, off) = (e.t, e.rows.start);
            let c = &problem.constraints(t)[e.k];
            let nr = c.nr();
            let d = &self.data.constraint_data(t)[e.k];
            let knot = &mut self.lq.knots[t];
            crate::linalg::copy(knot.C.as_mut().subrows_mut(off, nr), d.jx.as_ref());
            if knot.nu > 0 {
                crate::linalg::copy(knot.D.as_mut().subrows_mut(off, nr), d.ju.as_ref());
            }
            // A box-shaped set's shifted bounds, for a projection by clamping.
            let r = e.rows.clone();
            let (lo, hi) = (&mut self.lo[t][r.clone()], &mut self.hi[t][r]);
            if nr > 0 && c.set.box_bounds(lo, hi) {
                self.boxed[t][off] = true;
                for ((l, u), h) in lo.iter_mut().zip(hi.iter_mut()).zip(d.value()) {
                    (*l, *u) = (*l - h, *u - h);
                }
            } else if nr > 0 {
                self.boxed[t][off] = false;
            }
        }
        for (t, all) in self.all_boxed.iter_mut().enumerate() {
            let entries = &self.cons[self.knot_entries[t]..self.knot_entries[t + 1]];
            let boxed = entries.iter().all(|e| e.rows.is_empty() || self.boxed[t][e.rows.start]);
            *all = boxed.then(|| entries.iter().map(|e| e.rows.end).max().unwrap_or(0));
        }
    }

    /// The QP of [`Workspace::build_qp`] by the ADMM, its rows' values in their shifted
    /// sets (warm-started from the last QP with `warm`).
    fn solve_qp(&mut self, problem: &Problem, warm: bool) -> Result<()> {
        let mut sets = ShiftedSets {
            problem,
            data: &self.data,
            cons: &self.cons,
            knot_entries: &self.knot_entries,
            lo: &self.lo,
            hi: &self.hi,
            boxed: &self.boxed,
            all_boxed: &self.all_boxed,
            w: &mut self.w,
            out: &mut self.out,
        };
        self.admm.solve_sets(&mut self.lq, &mut sets, warm).map(|_| ())
    }

    /// [`Workspace::solve_qp`], regularised when the QP's Hessian is singular (a zero
    /// control weight): `reg` from 1e-9, ten times larger per failed factorization up to
    /// 1e9, then ten times smaller per QP solved, as SQP's schedule. Returns whether a
    /// QP was solved.
    fn solve_qp_regularized(&mut self, problem: &Problem, warm: bool) -> bool {
        loop {
            self.admm.set_regularization(self.reg);
            if self.solve_qp(problem, warm).is_ok() {
                self.reg = if self.reg > REG_MIN { 0.1 * self.reg } else { 0.0 };
                self.qp_solved = true;
                return true;
            }
            self.reg = (10.0 * self.reg).max(REG_MIN);
            if self.reg > REG_MAX {
                self.reg = 0.0;
                return false;
            }
        }
    }

    /// The gains of the last QP's active set, or at a guess that is a solution with its
    /// multipliers (zero when neither, or the active rows are dependent).
    fn write_gains(&mut self, sol: &mut Solution, status: Status) {
        let (cons, entries, boxed) = (&self.cons, &self.knot_entries, &self.boxed);
        let row_in_box = |t: usize, i: usize| entry_of_row(cons, entries, t, i).is_some_and(|e| boxed[t][e.rows.start]);
        let factored = if self.qp_solved {
            self.admm.active_set_factor(&mut self.lq, &row_in_box).is_ok()
        } else {
            // Converged at the guess (a warm start at a solution): its own multipliers.
            status == Status::Converged
                && self
                    .admm
                    .active_set_factor_at(&mut self.lq, &self.nus, &row_in_box)
                    .is_ok()
        };
        if factored {
            super::skeleton::write_gains(sol, self.admm.stages());
        } else {
            sol.feedforward.iter_mut().for_each(|k| k.fill(0.0));
            sol.feedback.iter_mut().for_each(|kk| kk.fill(0.0));
        }
    }

    /// The KKT residual with the multipliers of the last QP.
    fn kkt(&mut self, problem: &Problem, infeasibility: f64) -> f64 {
        self.data
            .lagrangian_gradient(problem, &self.lams, &self.nus, &mut self.gx, &mut self.gu);
        let dual = self.gx.iter().chain(&self.gu).map(|g| norm_inf(g)).fold(0.0, max_nan);
        max_nan(dual, infeasibility)
    }

    /// Takes the QP's multipliers as the current ones.
    fn take_multipliers(&mut self) {
        let sol = self.admm.solution();
        for (l, s) in self.lams.iter_mut().zip(&sol.lambdas) {
            l.copy_from_slice(slice(s));
        }
        // A padded knot's inert rows (receding horizon) come after the stage's own.
        for (v, y) in self.nus.iter_mut().zip(self.admm.multipliers()) {
            let rows = v.len();
            v.copy_from_slice(&y[..rows]);
        }
    }

    /// The trial `x ⊕ α δx, u + α δu`, evaluated: its cost and infeasibility.
    fn trial(&mut self, problem: &Problem, alpha: f64) -> Option<(f64, Infeasibility)> {
        let trial = super::skeleton::LinearTrial {
            xs: &self.xs,
            us: &self.us,
            step: self.admm.solution(),
        };
        trial.write(problem, alpha, &mut self.gx, &mut self.xs_try, &mut self.us_try);
        let cost = self.data.evaluate(problem, &self.xs_try, &self.us_try);
        let inf = self.infeasibility(problem);
        (cost.is_finite() && inf.l1.is_finite()).then_some((cost, inf))
    }
}

/// The CSQP solver (module documentation).
pub struct Csqp {
    /// Options; changes take effect at the next `setup`.
    pub options: CsqpOptions,
    ws: Option<Box<Workspace>>,
    solution: Solution,
    signature: Signature,
}

impl std::fmt::Debug for Csqp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Csqp")
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

impl Csqp {
    /// A solver with the given options (nothing allocated until `setup`).
    pub fn new(options: CsqpOptions) -> Self {
        Self {
            options,
            ws: None,
            solution: Solution::default(),
            signature: Signature::default(),
        }
    }

    /// Validates the options and allocates every buffer for `problem`.
    ///
    /// # Errors
    /// If an option is out of range or a constraint's set is not an equality, orthant or
    /// box.
    pub fn setup(&mut self, problem: &Problem) -> Result<()> {
        self.setup_with(problem, None)
    }

    fn setup_with(&mut self, problem: &Problem, queue: Option<&[StageModel]>) -> Result<()> {
        self.options.validate()?;
        self.signature = Signature::default();
        self.ws = Some(Box::new(Workspace::new(problem, &self.options, queue)?));
        self.solution = super::skeleton::solution_for(problem, self.options.max_iters, queue)?;
        self.signature = Signature::of(problem);
        Ok(())
    }

    fn run(
        &mut self,
        problem: &Problem,
        guess: InitialGuess<'_>,
        callback: Option<&mut dyn Callback>,
    ) -> Result<&Solution> {
        self.signature.check(problem, "csqp")?;
        guess.check(problem)?;
        let start = Instant::now();
        let opts = &self.options;
        let ws = self.ws.as_mut().expect("checked by the signature");
        let sol = &mut self.solution;
        sol.history.clear();
        if opts.log.is_active() {
            opts.log.line(format_args!("{}", TABLE.header()));
        }
        ws.qp_solved = false;
        let (status, iters, kkt, inf) = if ws.load(problem, &guess) {
            iterate(ws, problem, opts, sol, start, callback)
        } else {
            (Status::NonFinite, 0, f64::NAN, Infeasibility::default())
        };
        ws.write_gains(sol, status);
        super::skeleton::copy_trajectory(&mut sol.xs, &ws.xs);
        super::skeleton::copy_trajectory(&mut sol.us, &ws.us);
        super::skeleton::copy_trajectory(&mut sol.lambdas, &ws.lams);
        super::skeleton::copy_trajectory(&mut sol.nus, &ws.nus);
        sol.status = status;
        sol.iterations = iters;
        sol.prim_err = inf.max;
        sol.dual_err = kkt;
        sol.cost = ws.cost;
        sol.solve_time = start.elapsed();
        Ok(&self.solution)
    }
}

/// The SQP iterations; returns the status, the iterations, the last KKT residual and
/// infeasibility.
fn iterate(
    ws: &mut Workspace,
    problem: &Problem,
    opts: &CsqpOptions,
    sol: &mut Solution,
    start: Instant,
    mut callback: Option<&mut dyn Callback>,
) -> (Status, usize, f64, Infeasibility) {
    // The data's last evaluation is the current point.
    let mut inf = ws.infeasibility(problem);
    ws.reg = 0.0;
    let mut warm = false;
    let mut failures = 0;
    for iter in 0.. {
        ws.build_qp(problem);
        let kkt = ws.kkt(problem, inf.max);
        let stop = |s| (s, iter, kkt, inf);
        if kkt.is_nan() {
            return stop(Status::NonFinite);
        }
        if kkt <= opts.tol {
            return stop(Status::Converged);
        }
        if opts.max_time.is_some_and(|b| start.elapsed() >= b) {
            return stop(Status::TimeBudget);
        }
        if iter >= opts.max_iters {
            return stop(Status::MaxIterations);
        }
        if !ws.solve_qp_regularized(problem, warm) {
            return stop(Status::RegularizationFailure);
        }
        warm = opts.warm_qp;
        ws.take_multipliers();
        ws.filter.push(ws.cost, inf.l1);
        let mut record = IterationRecord {
            iter,
            cost: ws.cost,
            stop: kkt,
            prim_err: inf.max,
            inner_crit: ws.admm.iterations() as f64,
            mu: ws.admm.rho(),
            ..Default::default()
        };
        let accepted = filter_line_search(ws, problem, opts, &mut record.alpha);
        push_record(sol, record, &opts.log, &TABLE);
        match accepted {
            Some((c, t)) => {
                std::mem::swap(&mut ws.xs, &mut ws.xs_try);
                std::mem::swap(&mut ws.us, &mut ws.us_try);
                (ws.cost, inf) = (c, t);
                ws.admm.follow_step(record.alpha);
                failures = 0;
            }
            // An inexact QP step can fail the filter near the solution; the next QP,
            // warm-started, continues the ADMM iterations on the same subproblem.
            None if opts.warm_qp && failures + 1 < opts.max_linesearch_failures => {
                failures += 1;
                ws.cost = ws.data.evaluate(problem, &ws.xs, &ws.us);
                inf = ws.infeasibility(problem);
            }
            None => return (Status::LinesearchFailure, iter + 1, kkt, inf),
        }
        if !ws.derivatives(problem) {
            return (Status::NonFinite, iter + 1, kkt, inf);
        }
        if let Some(cb) = callback.as_mut()
            && !cb.on_iteration(&record)
        {
            return (Status::Interrupted, iter + 1, kkt, inf);
        }
    }
    unreachable!("the loop returns")
}

/// The constraint whose rows hold row `i` of knot `t` (`knot_entries` indexes `cons` by
/// knot).
fn entry_of_row<'a>(
    cons: &'a [ConstraintEntry],
    knot_entries: &[usize],
    t: usize,
    i: usize,
) -> Option<&'a ConstraintEntry> {
    cons[knot_entries[t]..knot_entries[t + 1]]
        .iter()
        .find(|e| e.rows.contains(&i))
}

/// The sets of the QP's rows at the current point: row block `δh` of constraint `h ∈ C`
/// lies in `C - h(x, u)` (for a box `[lo, hi]`, the box `[lo - h, hi - h]`).
struct ShiftedSets<'a> {
    problem: &'a Problem,
    data: &'a ProblemData,
    cons: &'a [ConstraintEntry],
    knot_entries: &'a [usize],
    lo: &'a [Vec<f64>],
    hi: &'a [Vec<f64>],
    boxed: &'a [Vec<bool>],
    all_boxed: &'a [Option<usize>],
    w: &'a mut [f64],
    out: &'a mut [f64],
}

impl RowSets for ShiftedSets<'_> {
    fn is_equality(&self, t: usize, i: usize) -> bool {
        entry_of_row(self.cons, self.knot_entries, t, i)
            .is_some_and(|e| self.problem.constraints(t)[e.k].set.is_equality())
    }

    fn project(&mut self, t: usize, v: &mut [f64]) {
        if let Some(end) = self.all_boxed[t] {
            clamp(&mut v[..end], &self.lo[t][..end], &self.hi[t][..end]);
            return;
        }
        for e in &self.cons[self.knot_entries[t]..self.knot_entries[t + 1]] {
            let r = e.rows.clone();
            if r.is_empty() {
                continue;
            }
            if self.boxed[t][r.start] {
                clamp(&mut v[r.clone()], &self.lo[t][r.clone()], &self.hi[t][r]);
                continue;
            }
            let c = &self.problem.constraints(t)[e.k];
            let (nr, r) = (c.nr(), e.rows.clone());
            let h = self.data.constraint_data(t)[e.k].value();
            let (w, out) = (&mut self.w[..nr], &mut self.out[..nr]);
            for ((wi, vi), hi) in w.iter_mut().zip(&v[r.clone()]).zip(h) {
                *wi = vi + hi;
            }
            c.set.project(w, 1.0, out);
            for ((vi, oi), hi) in v[r].iter_mut().zip(out.iter()).zip(h) {
                *vi = oi - hi;
            }
        }
    }
}

/// Step lengths `1, 1/2, ...` (the last tried in `alpha`) until a trial passes the
/// filter; its cost and infeasibility.
fn filter_line_search(
    ws: &mut Workspace,
    problem: &Problem,
    opts: &CsqpOptions,
    alpha: &mut f64,
) -> Option<(f64, Infeasibility)> {
    for i in 0..opts.linesearch_steps {
        *alpha = 0.5_f64.powi(i as i32);
        if let Some((c, t)) = ws.trial(problem, *alpha)
            && ws.filter.accepts(c, t.l1)
        {
            return Some((c, t));
        }
    }
    None
}

impl Solver for Csqp {
    fn name(&self) -> &'static str {
        "csqp"
    }
    fn setup(&mut self, problem: &Problem) -> Result<()> {
        Csqp::setup(self, problem)
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
    fn set_limits(&mut self, max_iters: usize, max_time: Option<Duration>) {
        self.options.max_iters = max_iters;
        self.options.max_time = max_time;
    }
    fn setup_receding(&mut self, problem: &Problem, queue: &[StageModel]) -> Result<()> {
        self.setup_with(problem, Some(queue))
    }
    fn shift(&mut self, problem: &Problem, slot: Option<usize>) -> Result<()> {
        let ws = self.ws.as_mut().ok_or_else(|| super::skeleton::not_receding("csqp"))?;
        ws.shift(problem, slot)?;
        super::skeleton::follow_shift(problem, &mut self.solution, &mut self.signature);
        Ok(())
    }
}

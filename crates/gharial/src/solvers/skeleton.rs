//! What every solver's loop shares: the check that `solve` gets the problem `setup` was
//! made for, the LQ subproblem shaped for a problem and filled from its derivatives,
//! trajectory copies, the iteration record and the solution's gains.

use faer::Mat;

use super::log::{LogSink, Table};
use super::{IterationRecord, Solution};
use crate::error::{Error, Result};
use crate::linalg::slice_mut;
use crate::lq::{LqKnot, LqProblem, RiccatiStage};
use crate::problem::{Problem, StageData, StageModel};

/// Dimensions `(nx, ndx, nu, nc)` of every knot, then `(nc0, 0, 0, 0)`: what `setup`
/// allocated for.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(crate) struct Signature(Vec<(usize, usize, usize, usize)>);

fn knot_dims(problem: &Problem) -> impl Iterator<Item = (usize, usize, usize, usize)> + '_ {
    let n = problem.horizon();
    (0..=n + 1).map(move |t| {
        if t < n {
            let st = &problem.stages()[t];
            (st.space().nx(), st.space().ndx(), st.nu(), st.nc())
        } else if t == n {
            let sp = problem.space(n);
            let ncn = problem.terminal_constraints().iter().map(|c| c.nr()).sum();
            (sp.nx(), sp.ndx(), 0, ncn)
        } else {
            (problem.nc0(), 0, 0, 0)
        }
    })
}

impl Signature {
    /// The signature of `problem` (allocates; for `setup`).
    pub(crate) fn of(problem: &Problem) -> Self {
        Self(knot_dims(problem).collect())
    }

    /// Rewrites the signature for `problem` in place (after a receding-horizon shift,
    /// which keeps the number of knots).
    pub(crate) fn refresh(&mut self, problem: &Problem) {
        for (a, b) in self.0.iter_mut().zip(knot_dims(problem)) {
            *a = b;
        }
    }

    /// Checks, without allocating, that `problem` has the dimensions `setup` saw;
    /// `solver` names the caller in the error.
    pub(crate) fn check(&self, problem: &Problem, solver: &str) -> Result<()> {
        if self.0.is_empty() {
            return Err(Error::InvalidModel(format!("{solver}::solve called before setup")));
        }
        if !knot_dims(problem).eq(self.0.iter().copied()) {
            return Err(Error::InvalidModel(format!(
                "{solver}::solve: the problem's dimensions differ from those given to setup"
            )));
        }
        Ok(())
    }
}

/// One constraint in the walk over all constraints of a problem: knot `t` (`t = N` for
/// the terminal constraints), index `k` among the knot's constraints, and its rows in the
/// knot's stacked constraint vector (and multipliers).
#[derive(Debug, Clone)]
pub(crate) struct ConstraintEntry {
    pub t: usize,
    pub k: usize,
    pub rows: std::ops::Range<usize>,
}

/// Every path and terminal constraint of `problem`, knot by knot, in order (allocates;
/// for `setup`): a walk over all constraints is one loop over this index.
pub(crate) fn constraint_index(problem: &Problem) -> Vec<ConstraintEntry> {
    let mut index = Vec::new();
    fill_constraint_index(problem, &mut index);
    index
}

/// Rewrites `index` as [`constraint_index`] (without allocating when its capacity
/// suffices, as after [`Receding::reserve_index`]).
pub(crate) fn fill_constraint_index(problem: &Problem, index: &mut Vec<ConstraintEntry>) {
    index.clear();
    for t in 0..=problem.horizon() {
        let mut off = 0;
        for (k, c) in problem.constraints(t).iter().enumerate() {
            index.push(ConstraintEntry {
                t,
                k,
                rows: off..off + c.nr(),
            });
            off += c.nr();
        }
    }
}

/// What a solver prepares for a receding horizon ([`crate::mpc`]): the largest stage
/// among the horizon and the stages queued to enter it. Every running knot's buffers of
/// constraint size are reserved for `max_nc` rows, so that shifts resize them in place.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Receding {
    /// Most stacked constraint rows of one stage.
    pub max_nc: usize,
    /// Most constraints of one stage.
    pub max_constraints: usize,
}

impl Receding {
    /// Checks that the horizon and `queue` can cycle (every stage with the state and
    /// control sizes of stage 0, on both sides) and measures them.
    ///
    /// # Errors
    /// Names the first stage whose sizes differ.
    pub(crate) fn of(problem: &Problem, queue: &[StageModel]) -> Result<Self> {
        let s0 = &problem.stages()[0];
        let dims = |s: &StageModel| {
            let (a, b) = (s.space(), s.space_next());
            (a.nx(), a.ndx(), s.nu(), b.nx(), b.ndx())
        };
        let (nx, ndx, nu, _, _) = dims(s0);
        let want = (nx, ndx, nu, nx, ndx);
        let stages = problem.stages().iter().map(|s| ("stage", s));
        let mut max = Self {
            max_nc: 0,
            max_constraints: 0,
        };
        for (i, (kind, s)) in stages.chain(queue.iter().map(|s| ("queued stage", s))).enumerate() {
            if dims(s) != want {
                let i = if kind == "stage" { i } else { i - problem.horizon() };
                return Err(Error::InvalidModel(format!(
                    "receding horizon: {kind} {i} has sizes (nx, ndx, nu, next nx, next ndx) = {:?}, \
                     stage 0 {want:?}: every stage must have the same",
                    dims(s)
                )));
            }
            max.max_nc = max.max_nc.max(s.nc());
            max.max_constraints = max.max_constraints.max(s.constraints().len());
        }
        Ok(max)
    }

    /// Reserves `index` for every shift of a horizon of `n` stages.
    pub(crate) fn reserve_index(&self, problem: &Problem, index: &mut Vec<ConstraintEntry>) {
        let n = problem.horizon();
        let total = n * self.max_constraints + problem.terminal_constraints().len();
        index.reserve_exact(total.saturating_sub(index.len()));
    }

    /// Reserves the running entries (`0..n`) of per-knot rows for `max_nc` rows.
    pub(crate) fn reserve_rows(&self, rows: &mut [Vec<f64>], n: usize) {
        for r in &mut rows[..n] {
            r.reserve_exact(self.max_nc.saturating_sub(r.len()));
        }
    }
}

/// The solution buffers of a solver set up for `problem` with room for the history of
/// `max_iters` iterations; with `queue`, the path multipliers reserved for the stages of a
/// receding horizon ([`Receding`]).
pub(crate) fn solution_for(problem: &Problem, max_iters: usize, queue: Option<&[StageModel]>) -> Result<Solution> {
    let mut sol = Solution::new(problem, max_iters.saturating_add(1));
    if let Some(q) = queue {
        Receding::of(problem, q)?.reserve_rows(&mut sol.nus, problem.horizon());
    }
    Ok(sol)
}

/// After a solver's workspace followed a receding-horizon shift: its solution's path
/// multipliers and its setup signature follow the problem too.
pub(crate) fn follow_shift(problem: &Problem, solution: &mut Solution, signature: &mut Signature) {
    let n = problem.horizon();
    shift_rows(&mut solution.nus, n, problem.stages()[n - 1].nc());
    signature.refresh(problem);
}

/// The error of a shift asked of solver `name` before `setup_receding`.
pub(crate) fn not_receding(name: &str) -> Error {
    Error::InvalidModel(format!("{name}::shift called before setup_receding"))
}

/// After a shift of a horizon of `n` stages: the running entries of per-knot rows move
/// one knot earlier and the last gets `nc_tail` zero rows (in place within the capacity
/// of [`Receding::reserve_rows`]); the terminal entry stays.
pub(crate) fn shift_rows(rows: &mut [Vec<f64>], n: usize, nc_tail: usize) {
    rows[..n].rotate_left(1);
    let tail = &mut rows[n - 1];
    tail.clear();
    tail.resize(nc_tail, 0.0);
}

/// An LQ problem with the knot dimensions of `problem`; `constraint_rows` says whether
/// the knots carry the rows of the path and terminal constraints (ProxDDP) or none (the
/// DDP family). With `padded_nc`, every running knot has that many constraint rows, the
/// ones beyond its stage's inert ([`pad_constraint_rows`]): a receding horizon then
/// changes the stages' constraints without changing the LQ problem's dimensions.
pub(crate) fn lq_for(problem: &Problem, constraint_rows: bool, padded_nc: Option<usize>) -> LqProblem {
    let n = problem.horizon();
    let knots = (0..=n)
        .map(|t| {
            let nc = match (constraint_rows, padded_nc) {
                (false, _) => 0,
                (true, Some(pad)) if t < n => pad,
                (true, _) => problem.constraints(t).iter().map(|c| c.nr()).sum(),
            };
            let nx_next = if t < n { problem.space(t + 1).ndx() } else { 0 };
            let mut knot = LqKnot::new(problem.space(t).ndx(), problem.nu(t), nc, nx_next);
            if constraint_rows {
                pad_constraint_rows(&mut knot, problem.constraints(t).iter().map(|c| c.nr()).sum());
            }
            knot
        })
        .collect();
    let (nc0, ndx0) = (problem.nc0(), problem.space(0).ndx());
    LqProblem {
        knots,
        G0: Mat::zeros(nc0, ndx0),
        g0: faer::Col::zeros(nc0),
        mu0: 0.0,
    }
}

/// Makes the constraint rows `from..` of `knot` inert: zero Jacobians and offset, unit
/// dual regularisation, so that their multipliers are zero and nothing else changes.
pub(crate) fn pad_constraint_rows(knot: &mut LqKnot, from: usize) {
    let rows = knot.nc - from;
    knot.C.as_mut().subrows_mut(from, rows).fill(0.0);
    knot.D.as_mut().subrows_mut(from, rows).fill(0.0);
    for i in from..knot.nc {
        knot.d[i] = 0.0;
        knot.mu_c[i] = 1.0;
    }
}

/// Copies the cost Hessian blocks of a stage (`Q`, `S`, `R`) if `hessian` and its
/// dynamics Jacobians (`A`, `B`, `E`) if `dynamics` into its knot. `E` is copied only
/// when it is not `-I`, the value knots are made with and that nothing else writes.
pub(crate) fn copy_stage_model(knot: &mut LqKnot, sd: &StageData, hessian: bool, dynamics: bool) {
    if hessian {
        crate::linalg::copy(knot.Q.as_mut(), sd.cost.lxx.as_ref());
        crate::linalg::copy(knot.S.as_mut(), sd.cost.lxu.as_ref());
        crate::linalg::copy(knot.R.as_mut(), sd.cost.luu.as_ref());
    }
    if dynamics {
        crate::linalg::copy(knot.A.as_mut(), sd.dyn_jx.as_ref());
        crate::linalg::copy(knot.B.as_mut(), sd.dyn_ju.as_ref());
        if !sd.dyn_jy_is_minus_identity {
            crate::linalg::copy(knot.E.as_mut(), sd.dyn_jy.as_ref());
        }
    }
}

/// Which derivative blocks of a stage its knot holds in place of its own storage (see
/// [`exchange_stage_model`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Loan {
    /// The cost Hessian blocks `Q, S, R`.
    pub hessian: bool,
    /// The dynamics Jacobians `A, B`.
    pub dynamics: bool,
    /// The dynamics Jacobian `E` (never `-I`: those knots keep their own).
    pub e: bool,
}

impl Loan {
    /// Whether any block is on loan.
    pub fn any(self) -> bool {
        self.hessian || self.dynamics || self.e
    }
}

/// Exchanges the storage of the blocks of `loan` between a stage's data and its knot:
/// the knot then holds the stage's derivatives without a copy, and the stage data the
/// knot's former buffers. A second call with the same `loan` gives every buffer back.
pub(crate) fn exchange_stage_model(knot: &mut LqKnot, sd: &mut StageData, loan: Loan) {
    if loan.hessian {
        std::mem::swap(&mut knot.Q, &mut sd.cost.lxx);
        std::mem::swap(&mut knot.S, &mut sd.cost.lxu);
        std::mem::swap(&mut knot.R, &mut sd.cost.luu);
    }
    if loan.dynamics {
        std::mem::swap(&mut knot.A, &mut sd.dyn_jx);
        std::mem::swap(&mut knot.B, &mut sd.dyn_ju);
    }
    if loan.e {
        std::mem::swap(&mut knot.E, &mut sd.dyn_jy);
    }
}

/// The trial point of a step `α` of an LQ solution `step` (SQP's linear rollout):
/// `x̃_t = x_t ⊕ α δx_t` (with `dx` as scratch) and `ũ_t = u_t + α δu_t`.
pub(crate) struct LinearTrial<'a> {
    pub xs: &'a [Vec<f64>],
    pub us: &'a [Vec<f64>],
    pub step: &'a crate::lq::LqSolution,
}

impl LinearTrial<'_> {
    /// Writes the trial of step length `alpha` into `xs_try`, `us_try`.
    pub(crate) fn write(
        &self,
        problem: &Problem,
        alpha: f64,
        dx: &mut [Vec<f64>],
        xs_try: &mut [Vec<f64>],
        us_try: &mut [Vec<f64>],
    ) {
        for t in 0..self.xs.len() {
            let v = &mut dx[t];
            for (vi, d) in v.iter_mut().zip(crate::linalg::slice(&self.step.xs[t])) {
                *vi = alpha * d;
            }
            problem.space(t).integrate(&self.xs[t], v, &mut xs_try[t]);
        }
        for (t, u) in us_try.iter_mut().enumerate() {
            for (j, ui) in u.iter_mut().enumerate() {
                *ui = self.us[t][j] + alpha * self.step.us[t][j];
            }
        }
    }
}

/// `dst = src` entry by entry (trajectories of equal shapes).
pub(crate) fn copy_trajectory(dst: &mut [Vec<f64>], src: &[Vec<f64>]) {
    for (a, b) in dst.iter_mut().zip(src) {
        a.copy_from_slice(b);
    }
}

/// Appends `record` to the history (up to its reserved capacity) and logs its row.
pub(crate) fn push_record(sol: &mut Solution, record: IterationRecord, log: &LogSink, table: &Table) {
    if sol.history.len() < sol.history.capacity() {
        sol.history.push(record);
    }
    if log.is_active() {
        log.line(format_args!("{}", table.row(&record)));
    }
}

/// Writes the gains `k_t`, `K_t` of a backward pass into the solution.
pub(crate) fn write_gains(sol: &mut Solution, stages: &[RiccatiStage]) {
    for (t, (k, kk)) in sol.feedforward.iter_mut().zip(sol.feedback.iter_mut()).enumerate() {
        let st = &stages[t];
        slice_mut(k).copy_from_slice(st.k());
        kk.copy_from(st.K());
    }
}

/// The filter of SQP's line search (Jordana et al. 2023, V-C): the (cost, gap) pairs of
/// the last iterates; a trial is accepted unless one of them is at least as good in both.
#[derive(Debug)]
pub(crate) struct SqpFilter {
    pairs: Vec<(f64, f64)>,
    len: usize,
    next: usize,
}

impl SqpFilter {
    pub fn new(size: usize) -> Self {
        Self {
            pairs: vec![(0.0, 0.0); size],
            len: 0,
            next: 0,
        }
    }

    /// Forgets every pair (a new solve).
    pub fn clear(&mut self) {
        self.len = 0;
        self.next = 0;
    }

    /// Remembers the pair of an iterate, forgetting the oldest when full.
    pub fn push(&mut self, cost: f64, gap: f64) {
        self.pairs[self.next] = (cost, gap);
        self.next = (self.next + 1) % self.pairs.len();
        self.len = (self.len + 1).min(self.pairs.len());
    }

    /// Whether no remembered pair dominates `(cost, gap)`.
    pub fn accepts(&self, cost: f64, gap: f64) -> bool {
        let n = self.pairs.len();
        (0..self.len).all(|i| {
            let (c, g) = self.pairs[(self.next + n - 1 - i) % n];
            !(c <= cost && g <= gap)
        })
    }
}

/// Outer updates forced by stalled subproblems (the primal-dual augmented-Lagrangian
/// loops of ProxDDP and ProxNLP): the solve stops as stalled after more than three
/// consecutive forced updates that did not halve the residual they started from.
#[derive(Debug, Clone, Copy)]
pub(crate) struct StallCount {
    updates: usize,
    err: f64,
}

impl Default for StallCount {
    fn default() -> Self {
        Self {
            updates: 0,
            err: f64::INFINITY,
        }
    }
}

impl StallCount {
    /// Counts an outer update with residual `err` (forced by a stall if `stalled`, which
    /// resets the count otherwise); `true` when the solve should stop as stalled.
    pub(crate) fn update(&mut self, stalled: bool, err: f64) -> bool {
        if !stalled {
            *self = Self::default();
            return false;
        }
        if err < 0.5 * self.err {
            self.err = err;
            self.updates = 0;
        }
        self.updates += 1;
        self.updates > 3
    }
}

/// Failed outer updates at the smallest penalty (the primal-dual augmented-Lagrangian
/// loops of ProxDDP and ProxNLP): the subproblem at `mu_lower_bound` solved three times
/// in a row with a primal residual above its target declares the constraints (locally)
/// infeasible.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct InfeasibleCount(usize);

impl InfeasibleCount {
    /// Counts an outer update that met its primal target (`success`, which resets the
    /// count) or not, at a penalty at its lower bound or not; `true` when the solve
    /// should stop as infeasible.
    pub(crate) fn update(&mut self, success: bool, at_min_penalty: bool) -> bool {
        if success {
            self.0 = 0;
        } else if at_min_penalty {
            self.0 += 1;
        }
        self.0 >= 3
    }
}

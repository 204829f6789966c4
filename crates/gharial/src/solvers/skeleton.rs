//! What every solver's loop shares: the check that `solve` gets the problem `setup` was
//! made for, the LQ subproblem shaped for a problem and filled from its derivatives,
//! trajectory copies, the iteration record and the solution's gains.

use faer::Mat;

use super::log::{LogSink, Table};
use super::{IterationRecord, Solution};
use crate::error::{Error, Result};
use crate::linalg::slice_mut;
use crate::lq::{LqKnot, LqProblem, RiccatiStage};
use crate::problem::{Problem, StageData};

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
    index
}

/// An LQ problem with the knot dimensions of `problem`; `constraint_rows` says whether
/// the knots carry the rows of the path and terminal constraints (ProxDDP) or none (the
/// DDP family).
pub(crate) fn lq_for(problem: &Problem, constraint_rows: bool) -> LqProblem {
    let n = problem.horizon();
    let knots = (0..=n)
        .map(|t| {
            let nc = if constraint_rows {
                problem.constraints(t).iter().map(|c| c.nr()).sum()
            } else {
                0
            };
            let nx_next = if t < n { problem.space(t + 1).ndx() } else { 0 };
            LqKnot::new(problem.space(t).ndx(), problem.nu(t), nc, nx_next)
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

/// Copies the cost Hessian blocks of a stage (`Q`, `S`, `R`) and, unless `keep_dynamics`,
/// its dynamics Jacobians (`A`, `B`, `E`) into its knot. `E` is copied only when it is
/// not `-I`, the value knots are made with and that nothing else writes.
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

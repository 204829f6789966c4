//! The ProxNLP solver: setup, the checks of a solve, and the loop (outer BCL update of
//! Algorithm 2, Newton direction with inertia correction, Armijo line search on the
//! primal-dual merit function).

use std::time::{Duration, Instant};

use super::kkt::NonFiniteStep;
use super::options::ProxNlpOptions;
use super::problem::Nlp;
use super::workspace::{Residuals, Workspace};
use crate::error::{Error, Result, check_dim, check_finite};
use crate::solvers::filter::Filter;
use crate::solvers::linesearch::{LinesearchResult, Nonmonotone, armijo};
use crate::solvers::proxddp::{StepAcceptance, TABLE};
use crate::solvers::skeleton::{InfeasibleCount, StallCount};
use crate::solvers::{Callback, HISTORY_LIMIT, IterationRecord, Status};

/// Smallest factor of the primal tolerance `eta` after a successful outer step (as
/// ProxDDP).
const MIN_ETA_FACTOR: f64 = 1e-2;

/// Trials of the filter may be at most this factor more infeasible than the initial
/// point (or than 1), as in IPOPT and ProxDDP.
const THETA_MAX_FACTOR: f64 = 1e4;

/// The result of a ProxNLP solve.
#[derive(Debug, Clone, Default)]
pub struct NlpSolution {
    /// The last accepted point `x`.
    pub x: Vec<f64>,
    /// Its multipliers `ν`, stacked block after block (Lagrangian `f + νᵀ c`).
    pub multipliers: Vec<f64>,
    /// How the solver stopped.
    pub status: Status,
    /// Newton iterations taken.
    pub iterations: usize,
    /// Outer (augmented-Lagrangian) iterations.
    pub al_iterations: usize,
    /// Final primal residual (53).
    pub prim_err: f64,
    /// Final dual residual (52).
    pub dual_err: f64,
    /// Final cost.
    pub cost: f64,
    /// Final penalty parameter.
    pub mu: f64,
    /// Wall time of the solve.
    pub solve_time: Duration,
    /// One record per iteration (ProxDDP's table, [`crate::solvers::proxddp::TABLE`]),
    /// the first [`HISTORY_LIMIT`] at most.
    pub history: Vec<IterationRecord>,
}

/// The ProxNLP solver: ProxDDP's primal-dual augmented-Lagrangian method on a generic
/// [`Nlp`], with the Newton system solved densely or sparsely
/// ([`ProxNlpOptions::kkt`]).
///
/// ```text
/// let mut solver = ProxNlp::new(ProxNlpOptions::default());
/// solver.setup(&nlp)?;                          // allocates
/// let sol = solver.solve(&nlp, &x0, None)?;     // does not
/// ```
pub struct ProxNlp {
    /// Options; changes take effect at the next `setup`.
    pub options: ProxNlpOptions,
    ws: Option<Box<Workspace>>,
    /// `(nx, ndx, block sizes)` of the problem given to `setup`.
    signature: (usize, usize, Vec<usize>),
    solution: NlpSolution,
    filter: Filter,
}

impl std::fmt::Debug for ProxNlp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ProxNlp")
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

impl ProxNlp {
    /// A solver with the given options (nothing allocated until `setup`).
    pub fn new(options: ProxNlpOptions) -> Self {
        Self {
            options,
            ws: None,
            signature: (0, 0, Vec::new()),
            solution: NlpSolution::default(),
            filter: Filter::new(1, 1e-5, 1e-5),
        }
    }

    /// Validates the options and the problem's blocks and allocates every buffer.
    ///
    /// # Errors
    /// If an option is out of range, or a block's set requires another dimension than
    /// the block has (named), or a block's scale is not positive and finite, or the
    /// derivative blocks of the problem's data do not fit its dimensions, or the dense
    /// system would have more than [`MAX_KKT_DIM`](super::MAX_KKT_DIM) rows.
    pub fn setup(&mut self, nlp: &dyn Nlp) -> Result<()> {
        self.options.validate()?;
        self.ws = None;
        for k in 0..nlp.num_blocks() {
            let b = nlp.block(k);
            if let Some(d) = b.set.dim() {
                check_dim(format!("ProxNlp: set of `{}`", nlp.block_name(k)), b.nr, d)?;
            }
            if !(b.scale.is_finite() && b.scale > 0.0) {
                return Err(Error::InvalidModel(format!(
                    "ProxNlp: scale of `{}` must be positive and finite",
                    nlp.block_name(k)
                )));
            }
        }
        let sp = nlp.space();
        self.signature = (
            sp.nx(),
            sp.ndx(),
            (0..nlp.num_blocks()).map(|k| nlp.block(k).nr).collect(),
        );
        check_sparsity(nlp)?;
        let ws = Workspace::new(nlp, &self.options)?;
        let cap = self.options.max_iters.min(HISTORY_LIMIT);
        self.solution = NlpSolution {
            x: vec![0.0; sp.nx()],
            multipliers: vec![0.0; ws.nc],
            history: Vec::with_capacity(cap),
            ..Default::default()
        };
        self.ws = Some(Box::new(ws));
        self.filter = Filter::new(self.options.max_iters.saturating_add(1), 1e-5, 1e-5);
        Ok(())
    }

    /// How the Newton system is solved (dense or sparse, its size), `None` before `setup`.
    pub fn kkt_stats(&self) -> Option<super::KktStats> {
        self.ws.as_ref().map(|ws| ws.kkt.stats())
    }

    /// The solution of the last solve.
    pub fn solution(&self) -> &NlpSolution {
        &self.solution
    }

    /// Solves `nlp` from `x0` (and multipliers `nu0`, zero if absent) without
    /// allocating. Algorithmic outcomes are reported in [`NlpSolution::status`].
    ///
    /// # Errors
    /// If `setup` was not called for a problem of these dimensions, or `x0` / `nu0` has a
    /// wrong size, a non-finite value, or `x0` is not a point of the space.
    pub fn solve(&mut self, nlp: &dyn Nlp, x0: &[f64], nu0: Option<&[f64]>) -> Result<&NlpSolution> {
        self.solve_with(nlp, x0, nu0, None)
    }

    /// As [`ProxNlp::solve`], calling `callback` after every iteration (returning
    /// `false` stops the solve with [`Status::Interrupted`]).
    ///
    /// # Errors
    /// As [`ProxNlp::solve`].
    pub fn solve_with(
        &mut self,
        nlp: &dyn Nlp,
        x0: &[f64],
        nu0: Option<&[f64]>,
        callback: Option<&mut dyn Callback>,
    ) -> Result<&NlpSolution> {
        self.check(nlp, x0, nu0)?;
        let ws = self.ws.as_mut().expect("checked by the signature");
        ws.load(x0, nu0);
        let mut cx = Context {
            nlp,
            opts: &self.options,
            ws,
            filter: &mut self.filter,
        };
        run(&mut cx, &mut self.solution, callback);
        Ok(&self.solution)
    }

    /// Checks, without allocating, that `nlp` has the dimensions `setup` saw and that the
    /// starting point is valid.
    fn check(&self, nlp: &dyn Nlp, x0: &[f64], nu0: Option<&[f64]>) -> Result<()> {
        let (nx, ndx, blocks) = &self.signature;
        let sp = nlp.space();
        let same = self.ws.is_some()
            && sp.nx() == *nx
            && sp.ndx() == *ndx
            && nlp.num_blocks() == blocks.len()
            && blocks.iter().enumerate().all(|(k, &nr)| nlp.block(k).nr == nr);
        if !same {
            return Err(Error::InvalidModel(
                "ProxNlp::solve: setup was not called for a problem of these dimensions".into(),
            ));
        }
        check_dim("ProxNlp::solve: x0", *nx, x0.len())?;
        check_finite("ProxNlp::solve: x0", x0)?;
        if !sp.is_valid(x0) {
            return Err(Error::InvalidModel(
                "ProxNlp::solve: x0 is not a point of the variable space".into(),
            ));
        }
        if let Some(nu) = nu0 {
            check_dim("ProxNlp::solve: multipliers", blocks.iter().sum(), nu.len())?;
            check_finite("ProxNlp::solve: multipliers", nu)?;
        }
        Ok(())
    }
}

/// Checks that the derivative blocks of `nlp`'s data fit its dimensions: one Jacobian
/// block per constraint block, every column set within the tangent space.
fn check_sparsity(nlp: &dyn Nlp) -> Result<()> {
    let data = nlp.create_data();
    let (sp, ndx) = (&data.sparsity, nlp.space().ndx());
    let inside = |c: &super::Columns| c.iter().all(|j| j < ndx);
    let rows_fit = (0..nlp.num_blocks()).all(|k| data.jac.get(k).is_some_and(|m| m.nrows() == nlp.block(k).nr));
    if sp.jacobian.len() != nlp.num_blocks()
        || !rows_fit
        || data.hess.len() != sp.hessian.len()
        || !sp.jacobian.iter().chain(&sp.hessian).all(inside)
    {
        return Err(Error::InvalidModel(format!(
            "ProxNlp: the derivative blocks of the data ({} Jacobian blocks, {} Hessian terms) \
             do not fit the problem ({} constraint blocks, {ndx} tangent columns)",
            sp.jacobian.len(),
            sp.hessian.len(),
            nlp.num_blocks()
        )));
    }
    Ok(())
}

/// What the loop needs besides its state.
struct Context<'a> {
    nlp: &'a dyn Nlp,
    opts: &'a ProxNlpOptions,
    ws: &'a mut Workspace,
    filter: &'a mut Filter,
}

/// The state of the loop of one solve.
struct State {
    mu: f64,
    eta: f64,
    omega: f64,
    preg: f64,
    iter: usize,
    al_iter: usize,
    status: Status,
    res: Residuals,
    cost: f64,
    /// Round-off handling, as ProxDDP: when the merit slope is at round-off level the
    /// full step is taken; when such steps stop reducing the inner criterion, the outer
    /// loop takes over.
    stalled: bool,
    roundoff_inner: f64,
    /// Consecutive outer updates forced by stalls.
    stalls: StallCount,
    /// Consecutive failed outer steps at the smallest penalty.
    infeasible: InfeasibleCount,
    nonmonotone: Nonmonotone,
}

/// The reference of the nonmonotone line search (plain Armijo for the other modes).
fn nonmonotone(opts: &ProxNlpOptions) -> Nonmonotone {
    Nonmonotone::new(match opts.step_acceptance {
        StepAcceptance::NonmonotoneLinesearch => opts.nonmonotone_eta,
        _ => 0.0,
    })
}

/// The factor of the BCL tolerance updates, `min(mu, 0.1)` (as ProxDDP).
fn bcl_rate(mu: f64) -> f64 {
    mu.min(0.1)
}

/// Solves from the point loaded in the workspace, writing `sol`.
fn run(cx: &mut Context<'_>, sol: &mut NlpSolution, mut callback: Option<&mut dyn Callback>) {
    let start = Instant::now();
    sol.history.clear();
    if cx.opts.log.is_active() {
        cx.opts.log.line(format_args!("{}", TABLE.header()));
    }
    let mut st = State::start(cx);
    while st.status != Status::NonFinite {
        if let Some(s) = st.check(cx, start) {
            st.status = s;
            break;
        }
        if st.res.inner <= st.omega || st.stalled {
            if let Some(s) = st.outer_update(cx) {
                st.status = s;
                break;
            }
            continue;
        }
        if st.iter >= cx.opts.max_iters {
            st.status = Status::MaxIterations;
            break;
        }
        let dphi0 = match st.newton_direction(cx) {
            Ok(d) => d,
            Err(s) => {
                st.status = s;
                break;
            }
        };
        let Some((ls, phi0)) = st.search(cx, dphi0) else {
            continue;
        };
        if let Some(s) = st.end_iteration(cx, sol, &ls, phi0, dphi0, &mut callback) {
            st.status = s;
            break;
        }
    }
    st.write(cx, sol);
    sol.solve_time = start.elapsed();
}

impl State {
    /// Penalty, tolerances (the failure update of Algorithm 2 from `omega_0 = eta_0 = 1`)
    /// and the evaluation of the starting point.
    fn start(cx: &mut Context<'_>) -> Self {
        let opts = cx.opts;
        let mu = opts.mu_init;
        let (status, cost) = match cx.ws.evaluate_current(cx.nlp) {
            Some(c) => (Status::MaxIterations, c),
            None => (Status::NonFinite, f64::NAN),
        };
        cx.filter.clear();
        let (_, theta0) = cx.ws.current_merit(cx.nlp, mu);
        cx.filter.set_theta_max(THETA_MAX_FACTOR * theta0.max(1.0));
        Self {
            mu,
            eta: bcl_rate(mu).powf(opts.bcl_beta_eta).max(opts.tol),
            omega: bcl_rate(mu).powf(opts.bcl_beta_omega).max(opts.tol),
            preg: 0.0,
            iter: 0,
            al_iter: 0,
            status,
            res: Residuals::default(),
            cost,
            stalled: false,
            roundoff_inner: f64::INFINITY,
            stalls: StallCount::default(),
            infeasible: InfeasibleCount::default(),
            nonmonotone: nonmonotone(opts),
        }
    }

    /// Residuals at the current point and the stops they decide.
    fn check(&mut self, cx: &mut Context<'_>, start: Instant) -> Option<Status> {
        let opts = cx.opts;
        self.res = cx.ws.estimates_and_residuals(cx.nlp, self.mu);
        let res = self.res;
        if !(res.prim.is_finite() && res.dual.is_finite()) {
            return Some(Status::NonFinite);
        }
        cx.ws.record_best(res.prim.max(res.dual));
        if res.prim <= opts.tol && res.dual <= opts.tol && res.comp <= opts.tol {
            return Some(Status::Converged);
        }
        opts.max_time
            .is_some_and(|b| start.elapsed() >= b)
            .then_some(Status::TimeBudget)
    }

    /// The outer update of Algorithm 2 (lines 9-24): multipliers accepted or penalty
    /// decreased, tolerances updated. Returns a status when the solve stops.
    fn outer_update(&mut self, cx: &mut Context<'_>) -> Option<Status> {
        let opts = cx.opts;
        if self.stalls.update(self.stalled, self.res.prim.max(self.res.dual)) {
            return Some(Status::Stalled);
        }
        self.stalled = false;
        self.al_iter += 1;
        let success = self.res.prim <= self.eta;
        if opts.log.is_active() {
            let verdict = if success {
                "multipliers accepted"
            } else {
                "mu decreased"
            };
            let (p, e) = (self.res.prim, self.eta);
            opts.log.line(format_args!(
                "  outer {}: prim_err {p:.3e} vs eta {e:.3e} -> {verdict}",
                self.al_iter
            ));
        }
        if self.infeasible.update(success, self.mu <= opts.mu_lower_bound) {
            return Some(Status::Infeasible);
        }
        if success {
            cx.ws.accept_multipliers();
            self.omega *= bcl_rate(self.mu).powf(opts.bcl_alpha_omega);
            self.eta *= bcl_rate(self.mu).powf(opts.bcl_alpha_eta).max(MIN_ETA_FACTOR);
        } else {
            self.mu = (self.mu * opts.mu_update_factor).max(opts.mu_lower_bound);
            self.omega *= bcl_rate(self.mu).powf(opts.bcl_beta_omega);
            self.eta *= bcl_rate(self.mu).powf(opts.bcl_beta_eta);
        }
        self.omega = self.omega.max(opts.tol);
        self.eta = self.eta.max(opts.tol);
        // The merit function changed: past values and filter entries no longer apply.
        cx.filter.clear();
        self.nonmonotone = nonmonotone(opts);
        (self.al_iter >= opts.max_al_iters).then_some(Status::MaxIterations)
    }

    /// The Newton step with inertia correction, regularised until it is a descent
    /// direction of the merit; returns the slope `dφ(0)`.
    fn newton_direction(&mut self, cx: &mut Context<'_>) -> std::result::Result<f64, Status> {
        let opts = cx.opts;
        cx.ws.build_system(cx.nlp, opts, self.mu);
        loop {
            let ok = match cx.ws.solve_system(cx.nlp, self.mu, self.preg) {
                Ok(ok) => ok,
                Err(NonFiniteStep) => return Err(Status::NonFinite),
            };
            let d = if ok {
                cx.ws.merit_slope(cx.nlp, self.mu)
            } else {
                f64::INFINITY
            };
            if ok && d.is_nan() {
                return Err(Status::NonFinite);
            }
            if ok && (d <= 0.0 || self.preg >= opts.preg_max) {
                return Ok(d);
            }
            // Wrong inertia or not a descent direction: regularise the primal block.
            self.preg = (self.preg * opts.preg_increase).max(opts.preg_min);
            if self.preg > opts.preg_max {
                return Err(Status::RegularizationFailure);
            }
        }
    }

    /// The step acceptance: the full step at round-off level, the filter or Armijo
    /// backtracking on the merit (17) otherwise. `None` when the subproblem stalled at
    /// round-off.
    fn search(&mut self, cx: &mut Context<'_>, dphi0: f64) -> Option<(LinesearchResult, f64)> {
        let (opts, mu) = (cx.opts, self.mu);
        let (phi0, theta0) = cx.ws.current_merit(cx.nlp, mu);
        let roundoff = dphi0.abs() <= opts.dphi_thresh * phi0.abs().max(1.0);
        if roundoff {
            if self.res.inner > 0.5 * self.roundoff_inner {
                self.stalled = true;
                self.roundoff_inner = f64::INFINITY;
                return None;
            }
            self.roundoff_inner = self.res.inner;
            let (phi, _) = cx.ws.trial(cx.nlp, 1.0, mu);
            let ls = LinesearchResult {
                alpha: 1.0,
                phi,
                accepted: phi.is_finite(),
                trials: 1,
            };
            return Some((ls, phi0));
        }
        self.roundoff_inner = f64::INFINITY;
        let (ws, nlp) = (&mut *cx.ws, cx.nlp);
        let ls = match opts.step_acceptance {
            StepAcceptance::Filter => {
                // Within the outer loop's feasibility target, the merit alone decides.
                cx.filter.set_theta_min(self.eta);
                let mut f = |a: f64| ws.trial(nlp, a, mu);
                cx.filter.search(&mut f, (phi0, theta0), dphi0, None, &opts.linesearch)
            }
            StepAcceptance::Linesearch | StepAcceptance::NonmonotoneLinesearch => {
                let reference = self.nonmonotone.reference(phi0);
                armijo(
                    |a| ws.trial(nlp, a, mu).0,
                    phi0,
                    dphi0,
                    reference,
                    None,
                    &opts.linesearch,
                )
            }
        };
        Some((ls, phi0))
    }

    /// After the step acceptance: a rejected step raises the regularisation; an accepted
    /// one becomes the current point, and the callback may stop the solve.
    fn end_iteration(
        &mut self,
        cx: &mut Context<'_>,
        sol: &mut NlpSolution,
        ls: &LinesearchResult,
        phi0: f64,
        dphi0: f64,
        callback: &mut Option<&mut dyn Callback>,
    ) -> Option<Status> {
        let opts = cx.opts;
        let record = IterationRecord {
            iter: self.iter,
            alpha: ls.alpha,
            inner_crit: self.res.inner,
            prim_err: self.res.prim,
            dual_err: self.res.dual,
            preg: self.preg,
            cost: self.cost,
            dphi0,
            merit: ls.phi,
            dmerit: ls.phi - phi0,
            al_iter: self.al_iter,
            mu: self.mu,
            ..Default::default()
        };
        if sol.history.len() < sol.history.capacity() {
            sol.history.push(record);
        }
        if opts.log.is_active() {
            opts.log.line(format_args!("{}", TABLE.row(&record)));
        }
        self.iter += 1;
        if !ls.accepted {
            self.preg = (self.preg * opts.preg_increase).max(opts.preg_min);
            return (self.preg > opts.preg_max).then_some(Status::LinesearchFailure);
        }
        self.cost = cx.ws.accept_trial(cx.nlp);
        self.nonmonotone.update(ls.phi);
        self.preg *= opts.preg_decrease;
        if self.preg < opts.preg_min {
            self.preg = 0.0;
        }
        if let Some(cb) = callback.as_mut()
            && !cb.on_iteration(&record)
        {
            self.res = cx.ws.estimates_and_residuals(cx.nlp, self.mu);
            return Some(Status::Interrupted);
        }
        None
    }

    /// Writes the solution (the best point instead of the current one when the time
    /// budget ran out).
    fn write(&mut self, cx: &mut Context<'_>, sol: &mut NlpSolution) {
        let ws = &mut *cx.ws;
        if self.status == Status::TimeBudget && ws.best_err < self.res.prim.max(self.res.dual) {
            self.cost = ws.restore_best(cx.nlp).unwrap_or(f64::NAN);
            self.res = ws.estimates_and_residuals(cx.nlp, self.mu);
        }
        sol.x.copy_from_slice(&ws.cur.x);
        sol.multipliers.copy_from_slice(&ws.cur.nu);
        sol.status = self.status;
        sol.iterations = self.iter;
        sol.al_iterations = self.al_iter;
        sol.prim_err = self.res.prim;
        sol.dual_err = self.res.dual;
        sol.cost = self.cost;
        sol.mu = self.mu;
    }
}

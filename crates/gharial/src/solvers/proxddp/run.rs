//! ProxDDP's solve loop: the outer (BCL) update of Algorithm 2, the Newton direction
//! with inertia correction and active-set prediction, the step acceptance (line search,
//! filter, watchdog, round-off handling) and the end of an iteration, each a function on
//! the loop's [`State`].

use std::time::Instant;

use super::TABLE;
use super::options::{ProxDdpOptions, Rollout, StepAcceptance};
use super::workspace::{Residuals, Workspace};
use crate::lq::LqError;
use crate::problem::Problem;
use crate::solvers::filter::Filter;
use crate::solvers::linesearch::{LinesearchResult, Nonmonotone, armijo};
use crate::solvers::skeleton::{InfeasibleCount, StallCount, copy_trajectory, push_record, write_gains};
use crate::solvers::{Callback, InitialGuess, IterationRecord, Solution, Status};

/// Trials of the filter may be at most this factor more infeasible than the initial
/// point (or than 1), as in IPOPT.
const THETA_MAX_FACTOR: f64 = 1e4;

/// Smallest factor of the primal tolerance `eta` after a successful outer step: with
/// small penalties (`mu = 1e-6`), `mu^α_η` would ask one multiplier update for a
/// hundred-thousand-fold smaller infeasibility, and a miss at round-off level (the
/// nonlinear rollout's floor is about `eps |x| / mu`) would decrease `mu` needlessly.
const MIN_ETA_FACTOR: f64 = 1e-2;

/// What the solve needs besides the loop state: the problem, the options, the workspace
/// and the filter.
pub(super) struct Context<'a> {
    pub problem: &'a Problem,
    pub opts: &'a ProxDdpOptions,
    pub ws: &'a mut Workspace,
    pub filter: &'a mut Filter,
}

/// The state of the loop of one solve.
struct State {
    mu: f64,
    mu_d: f64,
    eta: f64,
    omega: f64,
    preg: f64,
    iter: usize,
    al_iter: usize,
    status: Status,
    res: Residuals,
    cost: f64,
    theta_max: f64,
    // Round-off handling: when the merit slope along the Newton direction is at
    // round-off level, merit values cannot rank step lengths and the full step is
    // taken; when such steps stop reducing the inner criterion, the subproblem is
    // solved as accurately as the arithmetic allows and the outer loop takes over.
    stalled: bool,
    roundoff_inner: f64,
    /// Consecutive outer updates forced by stalls.
    stalls: StallCount,
    /// Consecutive failed outer updates at the smallest penalty.
    infeasible: InfeasibleCount,
    watchdog: Watchdog,
    nonmonotone: Nonmonotone,
}

/// How the step acceptance ended.
enum Search {
    /// A line search ran (accepted or not), from the merit `phi0` with slope `dphi0`.
    Done { ls: LinesearchResult, phi0: f64 },
    /// Back to the top of the loop (a round-off stall, or a failed watchdog phase).
    Again,
}

/// Solves from `guess` (checked by the caller), writing `sol`.
pub(super) fn solve(
    cx: &mut Context<'_>,
    guess: &InitialGuess<'_>,
    sol: &mut Solution,
    mut callback: Option<&mut dyn Callback>,
) {
    let start = Instant::now();
    cx.ws.load_guess(guess);
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
            match st.outer_update(cx) {
                Some(s) => {
                    st.status = s;
                    break;
                }
                None => continue,
            }
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
        let (ls, phi0) = match st.accept_step(cx, dphi0) {
            Ok(Search::Done { ls, phi0 }) => (ls, phi0),
            Ok(Search::Again) => continue,
            Err(s) => {
                st.status = s;
                break;
            }
        };
        let record = st.record(&ls, phi0, dphi0);
        if let Some(s) = st.end_iteration(cx, sol, record, &ls, &mut callback) {
            st.status = s;
            break;
        }
    }
    if st.iter == 0 && st.status == Status::Converged {
        st.gains_at_start(cx);
    }
    st.write(cx, sol);
    sol.solve_time = start.elapsed();
}

impl State {
    /// The state before the first iteration: penalty, tolerances, the evaluation of the
    /// guess and the filter's infeasibility bound.
    fn start(cx: &mut Context<'_>) -> Self {
        let opts = cx.opts;
        let mu = opts.mu_init;
        let mu_d = opts.dyn_al_scale * mu;
        cx.filter.clear();
        cx.ws.reset_dynamics_step();
        let (status, cost) = match cx.ws.evaluate_current(cx.problem) {
            Some(c) => (Status::MaxIterations, c),
            None => (Status::NonFinite, f64::NAN),
        };
        // Upper bound on the infeasibility of accepted trials (IPOPT's θ_max).
        cx.ws.trial.copy_from(&cx.ws.cur);
        let (_, theta_init) = cx.ws.trial_merit(cx.problem, opts.merit, mu, mu_d);
        let theta_max = THETA_MAX_FACTOR * theta_init.max(1.0);
        cx.filter.set_theta_max(theta_max);
        Self {
            mu,
            mu_d,
            // Initial tolerances: the failure update of Algorithm 2 from omega_0 = eta_0 = 1.
            eta: bcl_rate(mu).powf(opts.bcl_beta_eta).max(opts.tol),
            omega: bcl_rate(mu).powf(opts.bcl_beta_omega).max(opts.tol),
            preg: 0.0,
            iter: 0,
            al_iter: 0,
            status,
            res: Residuals::default(),
            cost,
            theta_max,
            stalled: false,
            roundoff_inner: f64::INFINITY,
            stalls: StallCount::default(),
            infeasible: InfeasibleCount::default(),
            watchdog: Watchdog::new(opts.watchdog_trigger),
            nonmonotone: nonmonotone(opts),
        }
    }

    /// Residuals (52)-(53) at the current point, and the stops they decide: non-finite
    /// values, convergence, the time budget.
    fn check(&mut self, cx: &mut Context<'_>, start: Instant) -> Option<Status> {
        let opts = cx.opts;
        self.res = cx.ws.estimates_and_residuals(cx.problem, self.mu, self.mu_d);
        let res = &self.res;
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

    /// The outer update of Algorithm 2 (lines 9-24) once the subproblem is solved (or
    /// stalled): multipliers accepted or penalty decreased, tolerances updated. Returns a
    /// status when the solve stops.
    fn outer_update(&mut self, cx: &mut Context<'_>) -> Option<Status> {
        let opts = cx.opts;
        if self.stalls.update(self.stalled, self.res.prim.max(self.res.dual)) {
            return Some(Status::Stalled);
        }
        self.stalled = false;
        self.al_iter += 1;
        let success = self.res.prim <= self.eta;
        if opts.log.is_active() {
            opts.log.line(format_args!(
                "  outer {}: prim_err {:.3e} {} eta {:.3e} -> {}",
                self.al_iter,
                self.res.prim,
                if success { "<=" } else { ">" },
                self.eta,
                if success {
                    "multipliers accepted"
                } else {
                    "mu decreased"
                }
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
            self.mu_d = opts.dyn_al_scale * self.mu;
            self.omega *= bcl_rate(self.mu).powf(opts.bcl_beta_omega);
            self.eta *= bcl_rate(self.mu).powf(opts.bcl_beta_eta);
        }
        self.omega = self.omega.max(opts.tol);
        self.eta = self.eta.max(opts.tol);
        // The merit function changed: past values and filter entries no longer apply.
        cx.filter.clear();
        self.watchdog = Watchdog::new(opts.watchdog_trigger);
        self.nonmonotone = nonmonotone(opts);
        (self.al_iter >= opts.max_al_iters).then_some(Status::MaxIterations)
    }

    /// The Newton step: LQ subproblem (42)-(46) with inertia correction, refined by the
    /// active-set prediction when enabled, regularised until it is a descent direction
    /// of the merit; returns the merit slope `dφ(0)` along it.
    fn newton_direction(&mut self, cx: &mut Context<'_>) -> Result<f64, Status> {
        let d = self.newton_step(cx);
        cx.ws.return_loans();
        d
    }

    /// [`newton_direction`](Self::newton_direction) with the stage data's derivative
    /// blocks still lent to the knots.
    fn newton_step(&mut self, cx: &mut Context<'_>) -> Result<f64, Status> {
        let (ws, problem, opts) = (&mut *cx.ws, cx.problem, cx.opts);
        let (mu, mu_d) = (self.mu, self.mu_d);
        ws.build_lq(problem, opts, mu, mu_d);
        // Whether the step may be refined by the active-set prediction (only within the
        // outer loop's feasibility target, where the linearisation of the subproblem is
        // trusted as the filter trusts the merit), and whether the knots hold its
        // constraint rows.
        let mut predict = opts.active_set_iters > 0 && self.res.prim <= self.eta;
        let mut predicted = false;
        loop {
            match ws.riccati.backward(&ws.lq, self.preg) {
                Ok(()) => {}
                Err(LqError::NonFinite { .. }) => return Err(Status::NonFinite),
                Err(_) => {
                    self.preg = (self.preg * opts.preg_increase).max(opts.preg_min);
                    if self.preg > opts.preg_max {
                        return Err(Status::RegularizationFailure);
                    }
                    continue;
                }
            }
            if ws.riccati.forward(&ws.lq, &mut ws.step).is_err() {
                return Err(Status::NonFinite);
            }
            if predict {
                predict = false;
                match predict_active_set(ws, problem, opts.active_set_iters, mu, self.preg) {
                    Some(p) => predicted = p,
                    // The knots hold the Newton step's rows again: solve them.
                    None => continue,
                }
            }
            ws.prepare_model(problem);
            let d = ws.model_slope(problem, opts.merit, mu, mu_d, 0.0);
            if predicted && (d >= 0.0 || d.is_nan()) {
                // Not a descent direction for the merit: back to the Newton step.
                ws.set_constraint_rows(problem, mu, false);
                predicted = false;
                continue;
            }
            if !d.is_finite() {
                return Err(Status::NonFinite);
            }
            // Not a descent direction: the proximal step if the exact one was taken by
            // default, else regularise the primal block and retry.
            if d > 0.0 && ws.fall_back_to_proximal() {
                ws.build_lq(problem, opts, mu, mu_d);
                continue;
            }
            if d > 0.0 && self.preg < opts.preg_max {
                self.preg = (self.preg * opts.preg_increase).max(opts.preg_min);
                continue;
            }
            return Ok(d);
        }
    }

    /// The step acceptance along the Newton direction: the merit at the current point,
    /// the round-off test, the watchdog, then the filter or the line search.
    fn accept_step(&mut self, cx: &mut Context<'_>, dphi0: f64) -> Result<Search, Status> {
        let (problem, opts) = (cx.problem, cx.opts);
        let (mu, mu_d) = (self.mu, self.mu_d);
        cx.ws.trial.copy_from(&cx.ws.cur);
        let (phi0, theta0) = cx.ws.trial_merit(problem, opts.merit, mu, mu_d);
        let roundoff = dphi0.abs() <= opts.dphi_thresh * phi0.abs().max(1.0);
        if roundoff {
            if self.res.inner > 0.5 * self.roundoff_inner {
                self.stalled = true;
                self.roundoff_inner = f64::INFINITY;
                return Ok(Search::Again);
            }
            self.roundoff_inner = self.res.inner;
        } else {
            self.roundoff_inner = f64::INFINITY;
        }
        let alpha_model = (!roundoff).then(|| {
            cx.ws
                .model_step(problem, opts.merit, mu, mu_d, dphi0, opts.linesearch.alpha_min)
        });
        if !roundoff && self.watchdog.phase.is_none() && self.watchdog.due() {
            cx.ws.watch.copy_from(&cx.ws.cur);
            self.watchdog.phase = Some(WatchdogPhase {
                phi: phi0,
                dphi: dphi0,
                left: opts.watchdog_trials,
            });
        }
        let ls = match (opts.step_acceptance, self.watchdog.phase) {
            (_, Some(w)) if !roundoff => match self.watchdog_step(cx, w)? {
                Some(ls) => ls,
                None => return Ok(Search::Again),
            },
            _ if roundoff => {
                let (phi, _) = trial(cx, 1.0, mu, mu_d);
                LinesearchResult {
                    alpha: 1.0,
                    phi,
                    accepted: phi.is_finite(),
                    trials: 1,
                }
            }
            (StepAcceptance::Filter, _) => {
                // Within the outer loop's feasibility target, the merit alone decides.
                cx.filter.set_theta_min(self.eta);
                let mut f = |a: f64| trial_of(cx.ws, problem, opts, a, mu, mu_d);
                cx.filter
                    .search(&mut f, (phi0, theta0), dphi0, alpha_model, &opts.linesearch)
            }
            (StepAcceptance::Linesearch | StepAcceptance::NonmonotoneLinesearch, _) => {
                let reference = self.nonmonotone.reference(phi0);
                let f = |a: f64| trial_of(cx.ws, problem, opts, a, mu, mu_d).0;
                armijo(f, phi0, dphi0, reference, alpha_model, &opts.linesearch)
            }
        };
        Ok(Search::Done { ls, phi0 })
    }

    /// A tentative full step of a watchdog phase: `Some` with the step taken, `None` when
    /// the phase failed and the point it started from is the current one again.
    fn watchdog_step(&mut self, cx: &mut Context<'_>, w: WatchdogPhase) -> Result<Option<LinesearchResult>, Status> {
        let opts = cx.opts;
        let (phi, theta) = trial(cx, 1.0, self.mu, self.mu_d);
        let bounded = phi.is_finite() && theta.is_finite() && theta <= self.theta_max;
        if bounded && phi <= w.phi + opts.linesearch.c1 * w.dphi.min(0.0) {
            // The phase succeeded: the merit decreased enough from its start.
            self.watchdog.succeed();
        } else if bounded && w.left > 0 {
            self.watchdog.phase = Some(WatchdogPhase { left: w.left - 1, ..w });
        } else {
            // The phase failed: back to its starting point, searched as usual.
            std::mem::swap(&mut cx.ws.cur, &mut cx.ws.watch);
            self.watchdog.fail();
            // The merit values of the tentative steps no longer apply.
            self.nonmonotone.reset(w.phi);
            self.cost = cx.ws.evaluate_current(cx.problem).ok_or(Status::NonFinite)?;
            return Ok(None);
        }
        Ok(Some(LinesearchResult {
            alpha: 1.0,
            phi,
            accepted: true,
            trials: 1,
        }))
    }

    /// The row of the iteration table.
    fn record(&self, ls: &LinesearchResult, phi0: f64, dphi0: f64) -> IterationRecord {
        IterationRecord {
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
        }
    }

    /// After the step acceptance: a rejected step raises the regularisation; an accepted
    /// one becomes the current point (with its derivatives), and the callback may stop
    /// the solve. Returns a status when the solve stops.
    fn end_iteration(
        &mut self,
        cx: &mut Context<'_>,
        sol: &mut Solution,
        record: IterationRecord,
        ls: &LinesearchResult,
        callback: &mut Option<&mut dyn Callback>,
    ) -> Option<Status> {
        let opts = cx.opts;
        if !ls.accepted {
            // Restore the data of the current point, then retry with a larger primal
            // regularisation (a step closer to steepest descent), up to its bound.
            cx.ws.evaluate_current(cx.problem);
            push_record(sol, record, &opts.log, &TABLE);
            self.preg = (self.preg * opts.preg_increase).max(opts.preg_min);
            if self.preg > opts.preg_max {
                return Some(Status::LinesearchFailure);
            }
            self.iter += 1;
            return None;
        }
        // The last trial evaluated is the accepted one.
        cx.ws.accept_trial();
        self.watchdog.count(ls.alpha);
        self.iter += 1;
        self.nonmonotone.update(ls.phi);
        self.preg *= opts.preg_decrease;
        if self.preg < opts.preg_min {
            self.preg = 0.0;
        }
        push_record(sol, record, &opts.log, &TABLE);
        if let Some(cb) = callback.as_mut()
            && !cb.on_iteration(&record)
        {
            self.cost = cx.ws.evaluate_current(cx.problem).unwrap_or(f64::NAN);
            self.res = cx.ws.estimates_and_residuals(cx.problem, self.mu, self.mu_d);
            return Some(Status::Interrupted);
        }
        if !opts.final_residuals && self.iter >= opts.max_iters {
            self.cost = cx.ws.accepted_cost().unwrap_or(f64::NAN);
            return Some(Status::MaxIterations);
        }
        match cx.ws.derivatives_at_accepted(cx.problem) {
            Some(c) => {
                self.cost = c;
                None
            }
            None => Some(Status::NonFinite),
        }
    }

    /// A solve that converges at its guess (a warm start at a solution) has taken no
    /// backward pass: one at the guess gives the gains the solution reports (the MPC
    /// policy's feedback).
    fn gains_at_start(&mut self, cx: &mut Context<'_>) {
        let (ws, problem, opts) = (&mut *cx.ws, cx.problem, cx.opts);
        ws.build_lq(problem, opts, self.mu, self.mu_d);
        // A failed factorization leaves the gains at zero, as before any pass.
        let _ = ws.riccati.backward(&ws.lq, self.preg);
        ws.return_loans();
    }

    /// Writes the solution: the best point instead of the current one when the time
    /// budget ran out, the gains of the last backward pass.
    fn write(&mut self, cx: &mut Context<'_>, sol: &mut Solution) {
        let ws = &mut *cx.ws;
        if self.status == Status::TimeBudget && ws.best_err < self.res.prim.max(self.res.dual) {
            std::mem::swap(&mut ws.cur, &mut ws.best);
            self.cost = ws.evaluate_current(cx.problem).unwrap_or(f64::NAN);
            self.res = ws.estimates_and_residuals(cx.problem, self.mu, self.mu_d);
        }
        copy_trajectory(&mut sol.xs, &ws.cur.xs);
        copy_trajectory(&mut sol.us, &ws.cur.us);
        copy_trajectory(&mut sol.lambdas, &ws.cur.lams);
        copy_trajectory(&mut sol.nus, &ws.cur.nus);
        if let Ok(stages) = ws.riccati.stages(&ws.lq) {
            write_gains(sol, stages);
        }
        sol.status = self.status;
        sol.iterations = self.iter;
        sol.al_iterations = self.al_iter;
        sol.prim_err = self.res.prim;
        sol.dual_err = self.res.dual;
        sol.cost = self.cost;
        sol.mu = self.mu;
    }
}

/// The trial point of step length `alpha` and its merit and infeasibility `(φ, θ)`
/// (`NaN` if the rollout fails or a value is not finite).
fn trial(cx: &mut Context<'_>, alpha: f64, mu: f64, mu_d: f64) -> (f64, f64) {
    trial_of(cx.ws, cx.problem, cx.opts, alpha, mu, mu_d)
}

fn trial_of(
    ws: &mut Workspace,
    problem: &Problem,
    opts: &ProxDdpOptions,
    alpha: f64,
    mu: f64,
    mu_d: f64,
) -> (f64, f64) {
    let ok = match opts.rollout {
        Rollout::Linear => {
            ws.linear_trial(problem, alpha);
            true
        }
        Rollout::Nonlinear => ws.nonlinear_trial(problem, opts, alpha, mu_d),
    };
    if !ok {
        return (f64::NAN, f64::NAN);
    }
    let c = ws.data.evaluate(problem, &ws.trial.xs, &ws.trial.us);
    if !c.is_finite() {
        return (f64::NAN, f64::NAN);
    }
    ws.trial_merit(problem, opts.merit, mu, mu_d)
}

/// The reference of the nonmonotone line search (plain Armijo for the other modes).
fn nonmonotone(opts: &ProxDdpOptions) -> Nonmonotone {
    Nonmonotone::new(match opts.step_acceptance {
        StepAcceptance::NonmonotoneLinesearch => opts.nonmonotone_eta,
        _ => 0.0,
    })
}

/// The active-set prediction of the step (see [`ProxDdpOptions::active_set_iters`]):
/// up to `iters` further semi-smooth Newton iterations on the subproblem whose Newton
/// step is in `ws.step`, each an LQ solve with the constraint rows linearised at the
/// previous iterate. Returns whether the knots and the step are those of the prediction,
/// or `None` if an LQ solve failed: the knots then have the rows of the Newton step back,
/// and the step must be solved again.
fn predict_active_set(ws: &mut Workspace, problem: &Problem, iters: usize, mu: f64, preg: f64) -> Option<bool> {
    for k in 0..=iters {
        if !ws.predict_active_set(problem, mu) {
            return Some(k > 0);
        }
        if k == iters || ws.riccati.backward(&ws.lq, preg).is_err() || ws.riccati.forward(&ws.lq, &mut ws.step).is_err()
        {
            break;
        }
    }
    ws.set_constraint_rows(problem, mu, false);
    None
}

/// The factor of the BCL tolerance updates: `min(mu, 0.1)`, as `min(mu_k, gamma_1)` in
/// Conn, Gould and Toint's bound-constrained Lagrangian method. With the penalty alone,
/// `mu >= 1` would leave the tolerances unchanged after a successful outer step, and the
/// outer loop could update the multipliers forever without a Newton step.
fn bcl_rate(mu: f64) -> f64 {
    mu.min(0.1)
}

/// A watchdog phase: the merit and slope at its starting point (kept in
/// `Workspace::watch`), and the tentative full steps left.
#[derive(Debug, Clone, Copy)]
struct WatchdogPhase {
    phi: f64,
    dphi: f64,
    left: usize,
}

/// The watchdog of one subproblem (see [`ProxDdpOptions::watchdog_trigger`]).
#[derive(Debug)]
struct Watchdog {
    /// Shortened steps that start a phase (0: never).
    trigger: usize,
    /// Consecutive shortened steps.
    shortened: usize,
    phase: Option<WatchdogPhase>,
}

impl Watchdog {
    fn new(trigger: usize) -> Self {
        Self {
            trigger,
            shortened: 0,
            phase: None,
        }
    }

    fn due(&self) -> bool {
        self.trigger > 0 && self.shortened >= self.trigger
    }

    /// Counts an accepted step of length `alpha` outside a phase.
    fn count(&mut self, alpha: f64) {
        if self.phase.is_none() {
            self.shortened = if alpha < 1.0 { self.shortened + 1 } else { 0 };
        }
    }

    fn succeed(&mut self) {
        self.phase = None;
        self.shortened = 0;
    }

    fn fail(&mut self) {
        self.phase = None;
        self.shortened = 0;
        self.trigger = self.trigger.saturating_mul(2);
    }
}

//! ProxDDP: the primal-dual augmented-Lagrangian DDP of Jallet et al. (2023),
//! `../shared/papers/proxddp-jallet-2023.md`.
//!
//! The outer loop is the bound-constrained-Lagrangian (BCL) schedule of Algorithm 2: an
//! inner loop of semi-smooth Newton steps on the proximal KKT operator (38) runs until
//! the inner criterion (19) is below `omega`; then either the multipliers are accepted
//! (primal residual below `eta`) or the penalty `mu` shrinks, and the tolerances follow.
//! Each Newton step is the LQ subproblem (42)-(46), (65) solved by the proximal Riccati
//! recursion of [`crate::lq`], followed by a linear (50) or nonlinear (51) rollout and
//! a line search (or filter) on the primal-dual merit function (17).
//!
//! Beyond the paper: per-constraint AL scaling and a separate dynamics scaling
//! (appendix C), a general initial constraint (65), implicit dynamics in the nonlinear
//! rollout (Newton-Raphson), warm starts from any primal-dual point, an exact-Hessian
//! option, a filter with a correct dominance test, a watchdog against the Maratos effect
//! (tentative full steps after repeated short ones, as in IPOPT), and a wall-time budget.

mod options;
mod workspace;

pub use options::{ACTIVE_SET_ITERS_MAX, HessianApprox, Merit, ProxDdpOptions, Rollout, StepAcceptance};

use std::time::Instant;

use workspace::{Residuals, Workspace};

use crate::error::Result;
use crate::lq::LqError;
use crate::problem::Problem;
use crate::solvers::filter::Filter;
use crate::solvers::linesearch::{LinesearchResult, Nonmonotone, armijo};
use crate::solvers::log::{Column, Format, Table};
use crate::solvers::skeleton::{Signature, push_record, write_gains};
use crate::solvers::{Callback, InitialGuess, IterationRecord, Solution, Status};

/// Trials of the filter may be at most this factor more infeasible than the initial
/// point (or than 1), as in IPOPT.
const THETA_MAX_FACTOR: f64 = 1e4;

/// Smallest factor of the primal tolerance `eta` after a successful outer step: with
/// small penalties (`mu = 1e-6`), `mu^α_η` would ask one multiplier update for a
/// hundred-thousand-fold smaller infeasibility, and a miss at round-off level (the
/// nonlinear rollout's floor is about `eps |x| / mu`) would decrease `mu` needlessly.
const MIN_ETA_FACTOR: f64 = 1e-2;

/// ProxDDP's iteration table.
pub const TABLE: Table = Table(COLUMNS);

/// The columns of ProxDDP's iteration table.
const COLUMNS: &[Column] = &[
    Column {
        name: "iter",
        width: 5,
        format: Format::Count,
        value: |r| r.iter as f64,
        meaning: "Newton steps taken before this row",
    },
    Column {
        name: "alpha",
        width: 9,
        format: Format::Sci(3),
        value: |r| r.alpha,
        meaning: "accepted step length (1: the full Newton step)",
    },
    Column {
        name: "inner_crit",
        width: 10,
        format: Format::Sci(3),
        value: |r| r.inner_crit,
        meaning: "criterion of the current subproblem (19); the outer loop updates the multipliers or the penalty when it falls below its tolerance omega",
    },
    Column {
        name: "prim_err",
        width: 10,
        format: Format::Sci(3),
        value: |r| r.prim_err,
        meaning: "primal residual: dynamics gaps and constraint violations (53)",
    },
    Column {
        name: "dual_err",
        width: 10,
        format: Format::Sci(3),
        value: |r| r.dual_err,
        meaning: "dual residual: gradient of the Lagrangian (52)",
    },
    Column {
        name: "preg",
        width: 9,
        format: Format::Sci(2),
        value: |r| r.preg,
        meaning: "primal regularisation added to the Newton system (0 when none was needed)",
    },
    Column {
        name: "cost",
        width: 13,
        format: Format::Sci(6),
        value: |r| r.cost,
        meaning: "total cost at the start of the step",
    },
    Column {
        name: "dphi0",
        width: 10,
        format: Format::Sci(3),
        value: |r| r.dphi0,
        meaning: "slope of the merit function along the step at alpha = 0 (negative: descent)",
    },
    Column {
        name: "merit",
        width: 13,
        format: Format::Sci(6),
        value: |r| r.merit,
        meaning: "merit function after the step ((17), or (35) with the primal merit)",
    },
    Column {
        name: "dM",
        width: 10,
        format: Format::Sci(3),
        value: |r| r.dmerit,
        meaning: "change of the merit function over the step",
    },
    Column {
        name: "al",
        width: 4,
        format: Format::Count,
        value: |r| r.al_iter as f64,
        meaning: "augmented-Lagrangian (outer) iterations so far",
    },
    Column {
        name: "mu",
        width: 9,
        format: Format::Sci(2),
        value: |r| r.mu,
        meaning: "augmented-Lagrangian penalty parameter",
    },
];

/// The ProxDDP solver.
///
/// ```text
/// let mut solver = ProxDdp::new(ProxDdpOptions::default());
/// solver.setup(&problem)?;                                   // allocates
/// let sol = solver.solve(&problem, InitialGuess::primal(&xs, &us))?;  // does not
/// ```
pub struct ProxDdp {
    /// Options; changes take effect at the next `setup`.
    pub options: ProxDdpOptions,
    ws: Option<Box<Workspace>>,
    solution: Solution,
    signature: Signature,
    filter: Filter,
}

impl std::fmt::Debug for ProxDdp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ProxDdp")
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

impl ProxDdp {
    /// A solver with the given options (nothing allocated until `setup`).
    pub fn new(options: ProxDdpOptions) -> Self {
        Self {
            options,
            ws: None,
            solution: Solution::default(),
            signature: Signature::default(),
            filter: Filter::new(1, 1e-5, 1e-5),
        }
    }

    /// Validates the options and allocates every buffer for `problem`'s dimensions.
    ///
    /// # Errors
    /// If an option is out of range.
    pub fn setup(&mut self, problem: &Problem) -> Result<()> {
        self.options.validate()?;
        self.ws = Some(Box::new(Workspace::new(problem, &self.options)?));
        self.solution = Solution::new(problem, self.options.max_iters.saturating_add(1));
        self.signature = Signature::of(problem);
        self.filter = Filter::new(self.options.max_iters.saturating_add(1), 1e-5, 1e-5);
        Ok(())
    }

    /// The solution of the last solve.
    pub fn solution(&self) -> &Solution {
        &self.solution
    }

    /// Solves `problem` from `guess`.
    ///
    /// # Errors
    /// If `setup` was not called for a problem of these dimensions, or the guess has a
    /// wrong size or a non-finite value. Algorithmic outcomes (convergence, iteration
    /// limit, line-search failure, ...) are reported in [`Solution::status`].
    pub fn solve(&mut self, problem: &Problem, guess: InitialGuess<'_>) -> Result<&Solution> {
        self.run(problem, guess, None)
    }

    /// As [`ProxDdp::solve`], calling `callback` after every iteration.
    ///
    /// # Errors
    /// As [`ProxDdp::solve`].
    pub fn solve_with_callback(
        &mut self,
        problem: &Problem,
        guess: InitialGuess<'_>,
        callback: &mut dyn Callback,
    ) -> Result<&Solution> {
        self.run(problem, guess, Some(callback))
    }

    fn run(
        &mut self,
        problem: &Problem,
        guess: InitialGuess<'_>,
        mut callback: Option<&mut dyn Callback>,
    ) -> Result<&Solution> {
        self.signature.check(problem, "ProxDdp")?;
        guess.check(problem)?;
        let opts = &self.options;
        let ws = self.ws.as_mut().expect("checked above");
        let filter = &mut self.filter;
        let sol = &mut self.solution;
        let start = Instant::now();

        ws.load_guess(&guess);
        filter.clear();
        let mut nonmonotone = Nonmonotone::new(match opts.step_acceptance {
            options::StepAcceptance::NonmonotoneLinesearch => opts.nonmonotone_eta,
            _ => 0.0,
        });
        let mut mu = opts.mu_init;
        let mut mu_d = opts.dyn_al_scale * mu;
        // Initial tolerances: the failure update of Algorithm 2 from omega_0 = eta_0 = 1.
        let mut eta = bcl_rate(mu).powf(opts.bcl_beta_eta).max(opts.tol);
        let mut omega = bcl_rate(mu).powf(opts.bcl_beta_omega).max(opts.tol);
        let mut preg = 0.0;
        let mut iter = 0;
        let mut al_iter = 0;
        let mut status = Status::MaxIterations;
        let mut res = Residuals::default();
        // Round-off handling: when the merit slope along the Newton direction is at
        // round-off level, merit values cannot rank step lengths and the full step is
        // taken; when such steps stop reducing the inner criterion, the subproblem is
        // solved as accurately as the arithmetic allows and the outer loop takes over.
        let mut stalled = false;
        let mut roundoff_inner = f64::INFINITY;
        // Consecutive outer updates forced by stalls, and the residual before them.
        let mut stall_updates = 0;
        let mut stall_err = f64::INFINITY;
        sol.history.clear();
        if opts.log.is_active() {
            opts.log.line(format_args!("{}", TABLE.header()));
        }

        let mut cost = match ws.evaluate_current(problem) {
            Some(c) => c,
            None => {
                status = Status::NonFinite;
                f64::NAN
            }
        };
        // Upper bound on the infeasibility of accepted trials (IPOPT's θ_max).
        ws.trial.copy_from(&ws.cur);
        let (_, theta_init) = ws.trial_merit(problem, opts.merit, mu, mu_d);
        let theta_max = THETA_MAX_FACTOR * theta_init.max(1.0);
        filter.set_theta_max(theta_max);
        let mut watchdog = Watchdog::new(opts.watchdog_trigger);
        'outer: while status != Status::NonFinite {
            res = ws.estimates_and_residuals(problem, mu, mu_d);
            if !(res.prim.is_finite() && res.dual.is_finite()) {
                status = Status::NonFinite;
                break;
            }
            ws.record_best(res.prim.max(res.dual));
            if res.prim <= opts.tol && res.dual <= opts.tol && res.comp <= opts.tol {
                status = Status::Converged;
                break;
            }
            if opts.max_time.is_some_and(|b| start.elapsed() >= b) {
                status = Status::TimeBudget;
                break;
            }
            if res.inner <= omega || stalled {
                if stalled {
                    let err = res.prim.max(res.dual);
                    if err < 0.5 * stall_err {
                        stall_err = err;
                        stall_updates = 0;
                    }
                    stall_updates += 1;
                    if stall_updates > 3 {
                        status = Status::Stalled;
                        break;
                    }
                } else {
                    stall_updates = 0;
                    stall_err = f64::INFINITY;
                }
                stalled = false;
                // Outer update of Algorithm 2 (lines 9-24).
                al_iter += 1;
                let success = res.prim <= eta;
                if opts.log.is_active() {
                    opts.log.line(format_args!(
                        "  outer {al_iter}: prim_err {:.3e} {} eta {eta:.3e} -> {}",
                        res.prim,
                        if success { "<=" } else { ">" },
                        if success {
                            "multipliers accepted"
                        } else {
                            "mu decreased"
                        }
                    ));
                }
                if success {
                    ws.accept_multipliers();
                    omega *= bcl_rate(mu).powf(opts.bcl_alpha_omega);
                    eta *= bcl_rate(mu).powf(opts.bcl_alpha_eta).max(MIN_ETA_FACTOR);
                } else {
                    mu = (mu * opts.mu_update_factor).max(opts.mu_lower_bound);
                    mu_d = opts.dyn_al_scale * mu;
                    omega *= bcl_rate(mu).powf(opts.bcl_beta_omega);
                    eta *= bcl_rate(mu).powf(opts.bcl_beta_eta);
                }
                omega = omega.max(opts.tol);
                eta = eta.max(opts.tol);
                // The merit function changed: past values and filter entries no longer apply.
                filter.clear();
                watchdog = Watchdog::new(opts.watchdog_trigger);
                nonmonotone = Nonmonotone::new(match opts.step_acceptance {
                    options::StepAcceptance::NonmonotoneLinesearch => opts.nonmonotone_eta,
                    _ => 0.0,
                });
                if al_iter >= opts.max_al_iters {
                    status = Status::MaxIterations;
                    break;
                }
                continue;
            }
            if iter >= opts.max_iters {
                status = Status::MaxIterations;
                break;
            }

            // Newton step: LQ subproblem (42)-(46), with inertia correction.
            ws.build_lq(problem, opts, mu, mu_d);
            // Whether the step may be refined by the active-set prediction (only within
            // the outer loop's feasibility target, where the linearisation of the
            // subproblem is trusted as the filter trusts the merit), and whether the knots
            // hold its constraint rows.
            let mut predict = opts.active_set_iters > 0 && res.prim <= eta;
            let mut predicted = false;
            let dphi0 = loop {
                match ws.riccati.backward(&ws.lq, preg) {
                    Ok(()) => {}
                    Err(LqError::NonFinite { .. }) => {
                        status = Status::NonFinite;
                        break 'outer;
                    }
                    Err(_) => {
                        preg = (preg * opts.preg_increase).max(opts.preg_min);
                        if preg > opts.preg_max {
                            status = Status::RegularizationFailure;
                            break 'outer;
                        }
                        continue;
                    }
                }
                if ws.riccati.forward(&ws.lq, &mut ws.step).is_err() {
                    status = Status::NonFinite;
                    break 'outer;
                }
                if predict {
                    predict = false;
                    match predict_active_set(ws, problem, opts.active_set_iters, mu, preg) {
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
                    status = Status::NonFinite;
                    break 'outer;
                }
                // Not a descent direction: regularise the primal block and retry.
                if d > 0.0 && preg < opts.preg_max {
                    preg = (preg * opts.preg_increase).max(opts.preg_min);
                    continue;
                }
                break d;
            };

            // Merit at the current point.
            ws.trial.copy_from(&ws.cur);
            let (phi0, theta0) = ws.trial_merit(problem, opts.merit, mu, mu_d);
            let roundoff = dphi0.abs() <= opts.dphi_thresh * phi0.abs().max(1.0);
            if roundoff {
                if res.inner > 0.5 * roundoff_inner {
                    stalled = true;
                    roundoff_inner = f64::INFINITY;
                    continue;
                }
                roundoff_inner = res.inner;
            } else {
                roundoff_inner = f64::INFINITY;
            }
            let alpha_model =
                (!roundoff).then(|| ws.model_step(problem, opts.merit, mu, mu_d, dphi0, opts.linesearch.alpha_min));
            if !roundoff && watchdog.phase.is_none() && watchdog.due() {
                ws.watch.copy_from(&ws.cur);
                watchdog.phase = Some(WatchdogPhase {
                    phi: phi0,
                    dphi: dphi0,
                    left: opts.watchdog_trials,
                });
            }
            let mut trial = |alpha: f64| -> (f64, f64) {
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
            };
            let ls = match (opts.step_acceptance, watchdog.phase) {
                (_, Some(w)) if !roundoff => {
                    let (phi, theta) = trial(1.0);
                    let bounded = phi.is_finite() && theta.is_finite() && theta <= theta_max;
                    if bounded && phi <= w.phi + opts.linesearch.c1 * w.dphi.min(0.0) {
                        // The phase succeeded: the merit decreased enough from its start.
                        watchdog.succeed();
                    } else if bounded && w.left > 0 {
                        watchdog.phase = Some(WatchdogPhase { left: w.left - 1, ..w });
                    } else {
                        // The phase failed: back to its starting point, searched as usual.
                        std::mem::swap(&mut ws.cur, &mut ws.watch);
                        watchdog.fail();
                        // The merit values of the tentative steps no longer apply.
                        nonmonotone.reset(w.phi);
                        match ws.evaluate_current(problem) {
                            Some(c) => cost = c,
                            None => {
                                status = Status::NonFinite;
                                break;
                            }
                        }
                        continue;
                    }
                    LinesearchResult {
                        alpha: 1.0,
                        phi,
                        accepted: true,
                        trials: 1,
                    }
                }
                _ if roundoff => {
                    let (phi, _) = trial(1.0);
                    LinesearchResult {
                        alpha: 1.0,
                        phi,
                        accepted: phi.is_finite(),
                        trials: 1,
                    }
                }
                (StepAcceptance::Filter, _) => {
                    // Within the outer loop's feasibility target, the merit alone decides.
                    filter.set_theta_min(eta);
                    filter.search(&mut trial, (phi0, theta0), dphi0, alpha_model, &opts.linesearch)
                }
                (StepAcceptance::Linesearch | StepAcceptance::NonmonotoneLinesearch, _) => {
                    let reference = nonmonotone.reference(phi0);
                    armijo(|a| trial(a).0, phi0, dphi0, reference, alpha_model, &opts.linesearch)
                }
            };
            let record = IterationRecord {
                iter,
                alpha: ls.alpha,
                inner_crit: res.inner,
                prim_err: res.prim,
                dual_err: res.dual,
                preg,
                cost,
                dphi0,
                merit: ls.phi,
                dmerit: ls.phi - phi0,
                al_iter,
                mu,
                ..Default::default()
            };
            if !ls.accepted {
                // Restore the data of the current point, then retry with a larger primal
                // regularisation (a step closer to steepest descent), up to its bound.
                ws.evaluate_current(problem);
                push_record(sol, record, &opts.log, &TABLE);
                preg = (preg * opts.preg_increase).max(opts.preg_min);
                if preg > opts.preg_max {
                    status = Status::LinesearchFailure;
                    break;
                }
                iter += 1;
                continue;
            }
            // The last trial evaluated is the accepted one.
            ws.accept_trial();
            watchdog.count(ls.alpha);
            iter += 1;
            nonmonotone.update(ls.phi);
            preg *= opts.preg_decrease;
            if preg < opts.preg_min {
                preg = 0.0;
            }
            push_record(sol, record, &opts.log, &TABLE);
            if let Some(cb) = callback.as_mut()
                && !cb.on_iteration(&record)
            {
                cost = ws.evaluate_current(problem).unwrap_or(f64::NAN);
                res = ws.estimates_and_residuals(problem, mu, mu_d);
                status = Status::Interrupted;
                break;
            }
            match ws.derivatives_at_accepted(problem) {
                Some(c) => cost = c,
                None => {
                    status = Status::NonFinite;
                    break;
                }
            }
        }

        if status == Status::TimeBudget && ws.best_err < res.prim.max(res.dual) {
            std::mem::swap(&mut ws.cur, &mut ws.best);
            cost = ws.evaluate_current(problem).unwrap_or(f64::NAN);
            res = ws.estimates_and_residuals(problem, mu, mu_d);
        }
        // Write the solution.
        for (a, b) in sol.xs.iter_mut().zip(&ws.cur.xs) {
            a.copy_from_slice(b);
        }
        for (a, b) in sol.us.iter_mut().zip(&ws.cur.us) {
            a.copy_from_slice(b);
        }
        for (a, b) in sol.lambdas.iter_mut().zip(&ws.cur.lams) {
            a.copy_from_slice(b);
        }
        for (a, b) in sol.nus.iter_mut().zip(&ws.cur.nus) {
            a.copy_from_slice(b);
        }
        if let Ok(stages) = ws.riccati.stages(&ws.lq) {
            write_gains(sol, stages);
        }
        sol.status = status;
        sol.iterations = iter;
        sol.al_iterations = al_iter;
        sol.prim_err = res.prim;
        sol.dual_err = res.dual;
        sol.cost = cost;
        sol.mu = mu;
        sol.solve_time = start.elapsed();
        Ok(&self.solution)
    }
}

impl crate::solvers::Solver for ProxDdp {
    fn name(&self) -> &'static str {
        "proxddp"
    }
    fn setup(&mut self, problem: &Problem) -> Result<()> {
        ProxDdp::setup(self, problem)
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

//! ProxDDP's workspace: iterates, multipliers, estimates, the LQ subproblem, and the
//! per-iteration computations (residuals, Newton system, merit, rollouts). Everything is
//! allocated in [`Workspace::new`]; no method allocates.

use faer::prelude::ReborrowMut;
use faer::{Accum, MatRef};

use super::options::{DynamicsStep, HessianApprox, Merit, ProxDdpOptions, Rollout};
use crate::costs::CostData;
use crate::dynamics::Dynamics;
use crate::error::{Error, Result};
use crate::linalg::{matvec, matvec_t, norm_inf, slice, slice_mut};
use crate::lq::{LqKnot, LqProblem, LqSolution, LqSolver, RiccatiOptions};
use crate::problem::{DynamicsData, ImplicitSolve, Problem, ProblemData, StageData, StageModel, add_jy_product};
use crate::solvers::InitialGuess;
use crate::solvers::skeleton::{
    ConstraintEntry, Loan, Receding, constraint_index, copy_stage_model, copy_trajectory, exchange_stage_model,
    fill_constraint_index, pad_constraint_rows, shift_rows,
};

/// The active-set prediction stops when the step solves the piecewise-linear constraint
/// rows of its subproblem to this fraction of the change `J δz` it makes in the
/// constraint values: for polyhedral sets the residual is at round-off level once the
/// active set is right, and otherwise at least the overshoot of a bound the step
/// crosses; a smaller overshoot would not shorten the step measurably.
const ACTIVE_SET_TOL: f64 = 1e-3;

/// A primal-dual point `(xs, us, λs, νs)`.
#[derive(Debug, Clone)]
pub(super) struct Point {
    pub xs: Vec<Vec<f64>>,
    pub us: Vec<Vec<f64>>,
    pub lams: Vec<Vec<f64>>,
    pub nus: Vec<Vec<f64>>,
}

impl Point {
    fn new(problem: &Problem) -> Self {
        let s = crate::solvers::Solution::new(problem, 0);
        Self {
            xs: s.xs,
            us: s.us,
            lams: s.lambdas,
            nus: s.nus,
        }
    }

    pub fn copy_from(&mut self, o: &Point) {
        for (a, b) in self.xs.iter_mut().zip(&o.xs) {
            a.copy_from_slice(b);
        }
        for (a, b) in self.us.iter_mut().zip(&o.us) {
            a.copy_from_slice(b);
        }
        for (a, b) in self.lams.iter_mut().zip(&o.lams) {
            a.copy_from_slice(b);
        }
        for (a, b) in self.nus.iter_mut().zip(&o.nus) {
            a.copy_from_slice(b);
        }
    }
}

/// Residuals at the current point, ProxDDP (19), (52), (53).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Residuals {
    /// Primal residual (53).
    pub prim: f64,
    /// Dual residual (52).
    pub dual: f64,
    /// Inner criterion (19).
    pub inner: f64,
    /// Complementarity of the current multipliers, `|h - proj_C(h + ν)|` (the natural
    /// residual of `ν ∈ N_C(h)`, as [`crate::problem::kkt_residuals`]): (53) measures
    /// feasibility against the outer multipliers `ν_e` and (52) stationarity with `ν`,
    /// so a point can meet both while `ν` pushes on an inactive constraint.
    pub comp: f64,
}

pub(super) struct Workspace {
    /// Current iterate.
    pub cur: Point,
    /// Trial iterate of the line search.
    pub trial: Point,
    /// Best iterate (smallest max(prim, dual)) for the time budget.
    pub best: Point,
    /// The point a watchdog phase started from (restored if the phase fails).
    pub watch: Point,
    pub best_err: f64,
    /// Outer multipliers `λ_e`, `ν_e` (Algorithm 2).
    pub lams_e: Vec<Vec<f64>>,
    pub nus_e: Vec<Vec<f64>>,
    /// First-order estimates `λ⁺`, `ν⁺` (39).
    pub lams_p: Vec<Vec<f64>>,
    pub nus_p: Vec<Vec<f64>>,
    /// Effective constraint multipliers of the Newton system's gradient,
    /// `ν⁺ - J_N (ν⁺ - ν)`.
    nus_g: Vec<Vec<f64>>,
    /// Multiplier estimates `ν̂ = N(z) / mu` at the shifted constraint values `z` of the
    /// constraint rows (`ν⁺` for the Newton step, see [`Workspace::predict_active_set`]).
    nus_hat: Vec<Vec<f64>>,
    /// Change of `nus_g` when the constraint rows are rebuilt.
    dnus_g: Vec<Vec<f64>>,
    /// Per-knot scratch of constraint size.
    zbuf: Vec<Vec<f64>>,
    wbuf: Vec<Vec<f64>>,
    /// Projections of the complementarity residual, per knot.
    pbuf: Vec<Vec<f64>>,
    /// Lagrangian gradient per knot.
    gx: Vec<Vec<f64>>,
    gu: Vec<Vec<f64>>,
    /// Its part that the constraint multipliers leave alone.
    gf: GradientPart,
    /// Scratch of state tangent size per knot (`x_t^α ⊖ x_t`, Jacobian-vector products).
    dxbuf: Vec<Vec<f64>>,
    /// Scratch of state representation size per knot.
    ybuf: Vec<Vec<f64>>,
    /// Linearised changes `J δz` of the initial, dynamics and constraint residuals along
    /// the step, and the cost slope and curvature (the local model of the merit).
    lin_init: Vec<f64>,
    lin_dyn: Vec<Vec<f64>>,
    lin_cons: Vec<Vec<f64>>,
    cost_slope: f64,
    cost_curv: f64,
    tbuf: Vec<Vec<f64>>,
    /// Smallest constraint scale of the problem (1 without constraints): the smallest
    /// constraint penalty of the Newton system is `min_scale * mu`.
    min_scale: f64,
    /// Whether the knots hold the constant blocks of this solve (cost Hessians and
    /// dynamics Jacobians that the models declare constant), so that `build_lq` need
    /// not copy them again.
    knot_constants: bool,
    /// The derivative blocks each knot holds on loan from its stage data while a Newton
    /// step is computed ([`build_lq`](Self::build_lq) to
    /// [`return_loans`](Self::return_loans)): exchanged buffers instead of copies.
    loans: Vec<Loan>,
    /// Every path and terminal constraint, in knot order: one walk over all of them.
    cons: Vec<ConstraintEntry>,
    /// Whether the Newton step treats the dynamics exactly ([`DynamicsStep`]); with
    /// `Auto`, until the exact step fails to descend the merit in a solve.
    exact_dynamics: bool,
    /// `DynamicsStep::Auto` chose the exact step for this problem.
    auto_exact: bool,
    pub lq: LqProblem,
    pub step: LqSolution,
    pub riccati: LqSolver,
    pub data: ProblemData,
    /// Receding horizon: the data of the queued stages (slot by slot), and the capacity
    /// reserved for them.
    spare: Vec<StageData>,
    receding: Option<Receding>,
}

impl Workspace {
    /// The workspace of `problem`; with `queue`, also for a receding horizon through
    /// the stages queued to enter it ([`Workspace::shift`]).
    pub fn new(problem: &Problem, opts: &ProxDdpOptions, queue: Option<&[StageModel]>) -> Result<Self> {
        let receding = queue.map(|q| Receding::of(problem, q)).transpose()?;
        let queue = queue.unwrap_or(&[]);
        let n = problem.horizon();
        let cur = Point::new(problem);
        let ncs: Vec<usize> = (0..=n)
            .map(|t| problem.constraints(t).iter().map(|c| c.nr()).sum())
            .collect();
        let ndxs: Vec<usize> = (0..=n).map(|t| problem.space(t).ndx()).collect();
        let nc0 = problem.nc0();
        let lq = crate::solvers::skeleton::lq_for(problem, true, receding.map(|r| r.max_nc));
        let data = ProblemData::new(problem, opts.num_threads)?;
        let riccati = LqSolver::with_team(
            &lq,
            RiccatiOptions {
                rollout_gains: true,
                refinement_steps: 1,
            },
            opts.num_threads,
            data.team().cloned(),
        )?;
        let step = LqSolution::new(&lq);
        let queued = queue.iter().flat_map(|s| s.constraints());
        let constraints = (0..=n).flat_map(|t| problem.constraints(t)).chain(queued);
        let min_scale = constraints.map(|c| c.scale).fold(1.0_f64, f64::min);
        let vecs = |sizes: &[usize]| sizes.iter().map(|&k| vec![0.0; k]).collect::<Vec<_>>();
        let nus_sizes: Vec<usize> = ncs.clone();
        let auto_exact = opts.dynamics_step == DynamicsStep::Auto
            && (0..=n).all(|t| problem.constraints(t).is_empty())
            && queue.iter().all(|s| s.constraints().is_empty());
        let mut ws = Self {
            trial: cur.clone(),
            best: cur.clone(),
            watch: cur.clone(),
            best_err: f64::INFINITY,
            lams_e: cur.lams.clone(),
            nus_e: cur.nus.clone(),
            lams_p: cur.lams.clone(),
            nus_p: cur.nus.clone(),
            nus_g: cur.nus.clone(),
            nus_hat: cur.nus.clone(),
            dnus_g: cur.nus.clone(),
            zbuf: vecs(&nus_sizes),
            wbuf: vecs(&nus_sizes),
            pbuf: vecs(&nus_sizes),
            gx: vecs(&ndxs),
            gu: (0..n).map(|t| vec![0.0; problem.nu(t)]).collect(),
            gf: GradientPart::new(problem, &cur.lams),
            dxbuf: vecs(&ndxs),
            ybuf: (0..=n).map(|t| vec![0.0; problem.space(t).nx()]).collect(),
            lin_init: vec![0.0; nc0],
            lin_dyn: (1..=n).map(|t| vec![0.0; ndxs[t]]).collect(),
            lin_cons: vecs(&nus_sizes),
            cost_slope: 0.0,
            cost_curv: 0.0,
            tbuf: vecs(&ndxs),
            min_scale,
            knot_constants: false,
            loans: vec![Loan::default(); n],
            cons: constraint_index(problem),
            exact_dynamics: auto_exact || opts.dynamics_step == DynamicsStep::Exact,
            auto_exact,
            lq,
            step,
            riccati,
            data,
            cur,
            spare: queue.iter().map(StageData::new).collect(),
            receding,
        };
        if let Some(r) = receding {
            r.reserve_index(problem, &mut ws.cons);
            for rows in ws.stage_rows() {
                r.reserve_rows(rows, n);
            }
        }
        Ok(ws)
    }

    /// Every per-knot buffer of constraint size: one list for reserving and shifting.
    fn stage_rows(&mut self) -> [&mut Vec<Vec<f64>>; 13] {
        [
            &mut self.cur.nus,
            &mut self.trial.nus,
            &mut self.best.nus,
            &mut self.watch.nus,
            &mut self.nus_e,
            &mut self.nus_p,
            &mut self.nus_g,
            &mut self.nus_hat,
            &mut self.dnus_g,
            &mut self.zbuf,
            &mut self.wbuf,
            &mut self.pbuf,
            &mut self.lin_cons,
        ]
    }

    /// Receding horizon, after [`Problem::shift`] took the queued stage `slot`: the
    /// stage data and the buffers of constraint size move one knot earlier (the data of
    /// the stage that left goes to `slot`), the constraint index and the inert rows of
    /// the padded LQ knots follow the new stages. Allocates nothing.
    ///
    /// # Errors
    /// If the workspace was not made for a receding horizon or `slot` is out of range.
    pub fn shift(&mut self, problem: &Problem, slot: Option<usize>) -> Result<()> {
        if self.receding.is_none() || slot.is_some_and(|s| s >= self.spare.len()) {
            return Err(Error::InvalidModel(format!(
                "ProxDdp::shift: slot {slot:?} of a queue of {} stages (was setup_receding called?)",
                self.spare.len()
            )));
        }
        self.data.shift(slot.map(|s| &mut self.spare[s]));
        self.gf.valid = false;
        let n = problem.horizon();
        let nc_tail = problem.stages()[n - 1].nc();
        for rows in self.stage_rows() {
            shift_rows(rows, n, nc_tail);
        }
        fill_constraint_index(problem, &mut self.cons);
        for (t, knot) in self.lq.knots[..n].iter_mut().enumerate() {
            pad_constraint_rows(knot, problem.stages()[t].nc());
        }
        self.knot_constants = false;
        Ok(())
    }

    /// Loads a guess; missing multipliers are zero. `λ_e`, `ν_e` start at the guess.
    ///
    /// The constant derivative blocks are written anew unless the solve continues a
    /// receding horizon ([`ProblemData::start_solve`]).
    pub fn load_guess(&mut self, guess: &InitialGuess<'_>) {
        self.data.start_solve();
        self.gf.valid = false;
        self.knot_constants = false;
        for (a, b) in self.cur.xs.iter_mut().zip(guess.xs) {
            a.copy_from_slice(b);
        }
        for (a, b) in self.cur.us.iter_mut().zip(guess.us) {
            a.copy_from_slice(b);
        }
        match guess.lambdas {
            Some(l) => {
                for (a, b) in self.cur.lams.iter_mut().zip(l) {
                    a.copy_from_slice(b);
                }
            }
            None => self.cur.lams.iter_mut().for_each(|v| v.fill(0.0)),
        }
        match guess.nus {
            Some(l) => {
                for (a, b) in self.cur.nus.iter_mut().zip(l) {
                    a.copy_from_slice(b);
                }
            }
            None => self.cur.nus.iter_mut().for_each(|v| v.fill(0.0)),
        }
        for (a, b) in self.lams_e.iter_mut().zip(&self.cur.lams) {
            a.copy_from_slice(b);
        }
        for (a, b) in self.nus_e.iter_mut().zip(&self.cur.nus) {
            a.copy_from_slice(b);
        }
        self.best_err = f64::INFINITY;
    }

    /// Accepts the current multipliers as the outer ones (BCL success).
    pub fn accept_multipliers(&mut self) {
        for (a, b) in self.lams_e.iter_mut().zip(&self.cur.lams) {
            a.copy_from_slice(b);
        }
        for (a, b) in self.nus_e.iter_mut().zip(&self.cur.nus) {
            a.copy_from_slice(b);
        }
    }

    /// Evaluates values and first derivatives at the current point; returns the cost,
    /// or `None` if a value is not finite.
    pub fn evaluate_current(&mut self, problem: &Problem) -> Option<f64> {
        self.return_loans();
        self.gf.valid = false;
        let c = self.data.evaluate(problem, &self.cur.xs, &self.cur.us);
        if !self.values_finite() || !c.is_finite() {
            return None;
        }
        self.data.compute_derivatives(problem, &self.cur.xs, &self.cur.us);
        Some(c)
    }

    /// After [`accept_trial`](Self::accept_trial): `data` holds the values of the accepted
    /// trial, the last point evaluated, so only the first derivatives are computed;
    /// returns the cost, or `None` if a value is not finite.
    pub fn derivatives_at_accepted(&mut self, problem: &Problem) -> Option<f64> {
        self.return_loans();
        self.gf.valid = false;
        let c = self.accepted_cost()?;
        self.data.compute_derivatives(problem, &self.cur.xs, &self.cur.us);
        Some(c)
    }

    /// After [`accept_trial`](Self::accept_trial): the cost of the accepted trial, or
    /// `None` if a value is not finite.
    pub fn accepted_cost(&self) -> Option<f64> {
        let c = self.data.cost;
        (self.values_finite() && c.is_finite()).then_some(c)
    }

    fn values_finite(&self) -> bool {
        let d = &self.data;
        d.init.value().iter().all(|v| v.is_finite())
            && d.stages.iter().all(|s| {
                s.dyn_value().iter().all(|v| v.is_finite())
                    && s.constraints.iter().all(|c| c.value().iter().all(|v| v.is_finite()))
            })
            && d.terminal_constraints
                .iter()
                .all(|c| c.value().iter().all(|v| v.is_finite()))
    }

    /// Multiplier estimates (39) and the residuals (19), (52), (53) at the current point
    /// for penalty `mu` (dynamics penalty `mu_d`).
    pub fn estimates_and_residuals(&mut self, problem: &Problem, mu: f64, mu_d: f64) -> Residuals {
        let n = problem.horizon();
        let mut prim: f64 = 0.0;
        let mut inner: f64 = 0.0;
        // Initial condition and dynamics: λ⁺ = λ_e + f / mu_d.
        let init = self.data.init.value();
        for i in 0..init.len() {
            self.lams_p[0][i] = self.lams_e[0][i] + init[i] / mu_d;
            prim = prim.max(init[i].abs());
            inner = inner.max((mu_d * (self.lams_p[0][i] - self.cur.lams[0][i])).abs());
        }
        for t in 0..n {
            let f = self.data.stages[t].dyn_value();
            for i in 0..f.len() {
                self.lams_p[t + 1][i] = self.lams_e[t + 1][i] + f[i] / mu_d;
                prim = prim.max(f[i].abs());
                inner = inner.max((mu_d * (self.lams_p[t + 1][i] - self.cur.lams[t + 1][i])).abs());
            }
        }
        // Constraints: z = h + mu_i ν_e, ν⁺ = (z - proj_C(z)) / mu_i; the primal measure
        // (53) is |[h + mu ν_e]_- - h| = mu_i |ν_e - ν⁺|.
        for e in &self.cons {
            let (t, off) = (e.t, e.rows.start);
            let (c, d) = (&problem.constraints(t)[e.k], &self.data.constraint_data(t)[e.k]);
            let nr = c.nr();
            let mu_i = c.scale * mu;
            let h = d.value();
            let z = &mut self.zbuf[t][off..off + nr];
            shifted_value(z, h, &self.nus_e[t][off..off + nr], mu_i);
            let np = &mut self.nus_p[t][off..off + nr];
            c.set.normal_cone_project(z, mu_i, np);
            for i in 0..nr {
                np[i] /= mu_i;
                prim = prim.max((mu_i * (self.nus_e[t][off + i] - np[i])).abs());
                inner = inner.max((mu_i * (np[i] - self.cur.nus[t][off + i])).abs());
            }
        }
        self.lagrangian_gradient(problem, false);
        let dual = self
            .gx
            .iter()
            .chain(self.gu.iter())
            .fold(0.0_f64, |a, g| a.max(norm_inf(g)));
        Residuals {
            prim,
            dual,
            inner: inner.max(dual),
            comp: self.complementarity(problem),
        }
    }

    /// `max |h - proj_C(h + ν)|` over all constraints at the current point.
    fn complementarity(&mut self, problem: &Problem) -> f64 {
        let mut comp: f64 = 0.0;
        for e in &self.cons {
            let (t, off) = (e.t, e.rows.start);
            let (c, d) = (&problem.constraints(t)[e.k], &self.data.constraint_data(t)[e.k]);
            let (h, nr) = (d.value(), c.nr());
            let w = &mut self.wbuf[t][off..off + nr];
            for i in 0..nr {
                w[i] = h[i] + self.cur.nus[t][off + i];
            }
            let p = &mut self.pbuf[t][off..off + nr];
            c.set.project(w, 1.0, p);
            for i in 0..nr {
                comp = comp.max((h[i] - p[i]).abs());
            }
        }
        comp
    }

    /// Fills the LQ knots with the Newton system (42)-(46), (65) at the current point.
    pub fn build_lq(&mut self, problem: &Problem, opts: &ProxDdpOptions, mu: f64, mu_d: f64) {
        self.return_loans();
        let n = problem.horizon();
        self.effective_multipliers(problem, mu, false);
        self.lagrangian_gradient(problem, true);
        if opts.hessian == HessianApprox::Exact {
            self.data
                .compute_second_order(problem, &self.cur.xs, &self.cur.us, &self.lams_p, &self.nus_p);
        }
        // Initial condition (65); without the proximal term, the residual itself.
        crate::linalg::copy(self.lq.G0.as_mut(), self.data.init.jx.as_ref());
        let exact = self.exact_dynamics;
        for i in 0..self.lq.g0.nrows() {
            self.lq.g0[i] = if exact {
                self.data.init.value()[i]
            } else {
                mu_d * (self.lams_p[0][i] - self.cur.lams[0][i])
            };
        }
        self.lq.mu0 = if exact { 0.0 } else { mu_d };
        // The Riccati recursion determines the step to about ε / mu relative (module docs
        // of `crate::lq`, "Accuracy"); one refinement step restores ε but costs about a
        // third of the forward and backward passes. Refine only when ε / mu could reach
        // a hundredth of the tolerance. Only the constraint rows count: the dynamics
        // penalty enters the recursion as `(I + mu_d P')⁻¹ P'`, exact as `mu_d → 0`.
        let refine = f64::EPSILON / (self.min_scale * mu) > 1e-2 * opts.tol;
        self.riccati.set_refinement_steps(usize::from(refine));
        // The gains of the next co-state (50c) serve the nonlinear rollout only.
        self.riccati.set_rollout_gains(opts.rollout == Rollout::Nonlinear);
        // Blocks that are constant during the solve and that nothing else writes stay in
        // the knots from the first build: A, B of constant dynamics Jacobians, and
        // Q, S, R of constant cost Hessians unless the exact Hessian adds to them. The
        // other blocks are lent (the exact Hessian's Q, S, R copied: it adds to them).
        let keep = self.knot_constants;
        let exact_hessian = opts.hessian == HessianApprox::Exact;
        let keep_hessian = keep && !exact_hessian;
        for t in 0..=n {
            let knot = &mut self.lq.knots[t];
            slice_mut(&mut knot.q).copy_from_slice(&self.gx[t]);
            if t < n {
                let sd = &mut self.data.stages[t];
                let stage = &problem.stages()[t];
                let (h_const, d_const) = (
                    stage.cost.hessian_is_constant(),
                    stage.dynamics.jacobians_are_constant(),
                );
                let loan = Loan {
                    hessian: !h_const && !exact_hessian,
                    dynamics: !d_const,
                    e: !d_const && !sd.dyn_jy_is_minus_identity,
                };
                let kept_hessian = keep_hessian && h_const;
                copy_stage_model(knot, sd, !(loan.hessian || kept_hessian), d_const && !keep);
                exchange_stage_model(knot, sd, loan);
                self.loans[t] = loan;
                let sd = &self.data.stages[t];
                slice_mut(&mut knot.r).copy_from_slice(&self.gu[t]);
                for i in 0..knot.nx_next {
                    knot.f[i] = if exact {
                        sd.dyn_value()[i]
                    } else {
                        mu_d * (self.lams_p[t + 1][i] - self.cur.lams[t + 1][i])
                    };
                }
                knot.mu_dyn = if exact { 0.0 } else { mu_d };
            } else if !(keep_hessian && problem.terminal_cost().hessian_is_constant()) {
                crate::linalg::copy(knot.Q.as_mut(), self.data.terminal_cost.lxx.as_ref());
            }
        }
        self.constraint_rows(problem, mu, false);
        if opts.hessian == HessianApprox::Exact {
            self.add_second_order(problem);
        }
        self.knot_constants = true;
    }

    /// The Lagrangian gradient (24) at the current derivatives and co-states into `gx`,
    /// `gu`, with the effective constraint multipliers `nus_g` or the current ones; its
    /// multiplier-free part is computed once for both while the derivatives and the
    /// co-states stay the same.
    fn lagrangian_gradient(&mut self, problem: &Problem, effective: bool) {
        let gf = &mut self.gf;
        if !(gf.valid && gf.lams == self.cur.lams) {
            self.data
                .lagrangian_gradient_forward(problem, &self.cur.lams, &mut gf.x, &mut gf.u);
            copy_trajectory(&mut gf.lams, &self.cur.lams);
            gf.valid = true;
        }
        copy_trajectory(&mut self.gx, &gf.x);
        copy_trajectory(&mut self.gu, &gf.u);
        let nus = if effective { &self.nus_g } else { &self.cur.nus };
        self.data
            .add_lagrangian_rest(problem, &self.cur.lams, nus, &mut self.gx, &mut self.gu);
    }

    /// Gives the stage data back the derivative blocks lent to the knots by
    /// [`build_lq`](Self::build_lq) (the knots' own buffers return to them). While the
    /// LQ solver still reads the knots (the gains of a parallel pass, computed when the
    /// solution is written), the blocks are copied into the knots' buffers as well.
    pub fn return_loans(&mut self) {
        let copy = self.riccati.reads_problem_later();
        for (t, loan) in self.loans.iter_mut().enumerate() {
            if loan.any() {
                let (knot, sd) = (&mut self.lq.knots[t], &mut self.data.stages[t]);
                exchange_stage_model(knot, sd, *loan);
                if copy {
                    copy_stage_model(knot, sd, loan.hessian, loan.dynamics);
                }
                *loan = Loan::default();
            }
        }
    }

    /// Back to the dynamics step of the options, at the start of a solve.
    pub fn reset_dynamics_step(&mut self) {
        if self.auto_exact {
            self.exact_dynamics = true;
        }
    }

    /// With [`DynamicsStep::Auto`], replaces the exact dynamics step by the proximal one
    /// (42) for the rest of the solve; `true` if it did. The exact step solves the
    /// linearised dynamics with the current co-states, which need not descend the
    /// proximal merit when they are far from the estimates `λ_e + f / mu_d` (a floating
    /// base without contacts); the proximal step is its Newton step and descends it.
    pub fn fall_back_to_proximal(&mut self) -> bool {
        let switch = self.auto_exact && self.exact_dynamics;
        if switch {
            self.exact_dynamics = false;
        }
        switch
    }

    /// The shifted constraint values `z` of the constraint rows, the estimates
    /// `ν̂ = N(z) / mu` and the effective multipliers `ν_g = ν̂ - J_N (ν̂ - ν)` of the
    /// Newton system's gradient, `J_N` the Jacobian of the normal-cone projection `N` at
    /// `z`. For the Newton step (`predicted = false`) `z = h + mu ν_e` and `ν̂ = ν⁺` (39);
    /// for sets whose `J_N` is a projector (equality, orthant, box) `ν_g = J_N ν`, the
    /// active multipliers of (46). With `predicted`, `z = h + mu ν_e + J δz` is the
    /// linearised value at the full step `δz`, whose `J δz` is in `lin_cons` (see
    /// [`Workspace::predict_active_set`]).
    fn effective_multipliers(&mut self, problem: &Problem, mu: f64, predicted: bool) {
        for e in &self.cons {
            let (t, off) = (e.t, e.rows.start);
            let (c, d) = (&problem.constraints(t)[e.k], &self.data.constraint_data(t)[e.k]);
            let nr = c.nr();
            let mu_i = c.scale * mu;
            let h = d.value();
            let z = &mut self.zbuf[t][off..off + nr];
            shifted_value(z, h, &self.nus_e[t][off..off + nr], mu_i);
            if predicted {
                for (zi, bi) in z.iter_mut().zip(&self.lin_cons[t][off..off + nr]) {
                    *zi += bi;
                }
            }
            let nh = &mut self.nus_hat[t][off..off + nr];
            c.set.normal_cone_project(z, mu_i, nh);
            let w = &mut self.wbuf[t][off..off + nr];
            for i in 0..nr {
                nh[i] /= mu_i;
                w[i] = nh[i] - self.cur.nus[t][off + i];
            }
            c.set.apply_normal_cone_jacobian_vec(z, mu_i, w);
            for i in 0..nr {
                self.nus_g[t][off + i] = nh[i] - w[i];
            }
        }
    }

    /// Constraint rows of the knots at the `z` and `ν̂` of
    /// [`effective_multipliers`](Self::effective_multipliers): `C = J_N h_x`,
    /// `D = J_N h_u`, `mu_c = mu_i` and `d = mu_i (ν̂ - ν)`, less `J_N J δz` when
    /// `predicted` (the rows then linearise `N` at the full step instead of at the
    /// current point).
    fn constraint_rows(&mut self, problem: &Problem, mu: f64, predicted: bool) {
        let n = problem.horizon();
        for e in &self.cons {
            let (t, off) = (e.t, e.rows.start);
            let knot = &mut self.lq.knots[t];
            let k = e.k;
            let (c, d) = (&problem.constraints(t)[k], &self.data.constraint_data(t)[k]);
            let nr = c.nr();
            let mu_i = c.scale * mu;
            let z = &self.zbuf[t][off..off + nr];
            let mut crows = knot.C.as_mut().subrows_mut(off, nr);
            if t < n && self.data.stages[t].constraint_jx_is_zero(k) {
                crate::linalg::fill(crows.rb_mut(), 0.0);
            } else {
                crate::linalg::copy(crows.rb_mut(), d.jx.as_ref());
                c.set.apply_normal_cone_jacobian(z, mu_i, crows);
            }
            if knot.nu > 0 {
                let mut drows = knot.D.as_mut().subrows_mut(off, nr);
                crate::linalg::copy(drows.rb_mut(), d.ju.as_ref());
                c.set.apply_normal_cone_jacobian(z, mu_i, drows);
            }
            for i in 0..nr {
                knot.d[off + i] = mu_i * (self.nus_hat[t][off + i] - self.cur.nus[t][off + i]);
                knot.mu_c[off + i] = mu_i;
            }
            if predicted {
                let w = &mut self.wbuf[t][off..off + nr];
                w.copy_from_slice(&self.lin_cons[t][off..off + nr]);
                c.set.apply_normal_cone_jacobian_vec(z, mu_i, w);
                for i in 0..nr {
                    knot.d[off + i] -= w[i];
                }
            }
        }
    }

    /// Linearised changes `J δz` of the path and terminal constraints along the step,
    /// into `lin_cons`.
    fn constraint_step(&mut self, problem: &Problem) {
        let n = problem.horizon();
        let st = &self.step;
        for e in &self.cons {
            let (t, off) = (e.t, e.rows.start);
            let k = e.k;
            let cd = &self.data.constraint_data(t)[k];
            let nr = cd.value.nrows();
            let b = &mut self.lin_cons[t][off..off + nr];
            if t < n && self.data.stages[t].constraint_jx_is_zero(k) {
                b.fill(0.0);
            } else {
                matvec(b, Accum::Replace, cd.jx.as_ref(), slice(&st.xs[t]), 1.0);
            }
            if t < n {
                matvec(b, Accum::Add, cd.ju.as_ref(), slice(&st.us[t]), 1.0);
            }
        }
    }

    /// One iteration of the active-set prediction of the step (see
    /// [`ProxDdpOptions::active_set_iters`]). The LQ subproblem with the normal-cone
    /// projections kept in its constraint rows, `N(h + mu ν_e + J δz) - mu (ν + δν) = 0`
    /// with the stationarity and dynamics rows of (42), is a piecewise-linear system in
    /// the step `δ`; the Newton step is one semi-smooth Newton iteration on it from
    /// `δ = 0`. This checks whether the step in `self.step` solves the constraint rows at
    /// its own `z = h + mu ν_e + J δz`; if not, it rebuilds the constraint rows (and the
    /// gradient terms of the effective multipliers) with `N` linearised at that `z`, so
    /// that the next LQ solve gives the next semi-smooth Newton iterate on the same
    /// subproblem (same derivatives, same multiplier estimates). For polyhedral sets, where
    /// `N` is piecewise affine, these are the iterations of the primal-dual active-set
    /// method, which stop when the active set does.
    ///
    /// Returns whether the rows were rebuilt (`false`: the step already solves them, up
    /// to [`ACTIVE_SET_TOL`] relative to the change `J δz` of the constraint values).
    pub fn predict_active_set(&mut self, problem: &Problem, mu: f64) -> bool {
        self.constraint_step(problem);
        let mut res: f64 = 0.0;
        let mut scale: f64 = 0.0;
        for e in &self.cons {
            let (t, off) = (e.t, e.rows.start);
            let dnu = slice(&self.step.nus[t]);
            let (c, d) = (&problem.constraints(t)[e.k], &self.data.constraint_data(t)[e.k]);
            let nr = c.nr();
            let mu_i = c.scale * mu;
            let h = d.value();
            let b = &self.lin_cons[t][off..off + nr];
            let z = &mut self.zbuf[t][off..off + nr];
            shifted_value(z, h, &self.nus_e[t][off..off + nr], mu_i);
            for (zi, bi) in z.iter_mut().zip(b) {
                *zi += bi;
            }
            let w = &mut self.wbuf[t][off..off + nr];
            c.set.normal_cone_project(z, mu_i, w);
            for i in 0..nr {
                let nu_next = mu_i * (self.cur.nus[t][off + i] + dnu[off + i]);
                res = res.max((w[i] - nu_next).abs());
                scale = scale.max(b[i].abs());
            }
        }
        if res <= ACTIVE_SET_TOL * scale {
            return false;
        }
        self.set_constraint_rows(problem, mu, true);
        true
    }

    /// Rebuilds the constraint rows and the gradient terms of the effective multipliers,
    /// at the current point (`predicted = false`: the rows of [`build_lq`](Self::build_lq))
    /// or at the full step (see [`predict_active_set`](Self::predict_active_set)).
    pub fn set_constraint_rows(&mut self, problem: &Problem, mu: f64, predicted: bool) {
        for (a, b) in self.dnus_g.iter_mut().zip(&self.nus_g) {
            a.copy_from_slice(b);
        }
        self.effective_multipliers(problem, mu, predicted);
        // The gradient of the knots is the Lagrangian's at ν_g: q += h_xᵀ Δν_g,
        // r += h_uᵀ Δν_g.
        let n = problem.horizon();
        for (d, g) in self.dnus_g.iter_mut().zip(&self.nus_g) {
            for (a, b) in d.iter_mut().zip(g) {
                *a = b - *a;
            }
        }
        for e in &self.cons {
            let (t, k) = (e.t, e.k);
            let knot = &mut self.lq.knots[t];
            let cd = &self.data.constraint_data(t)[k];
            let dn = &self.dnus_g[t][e.rows.clone()];
            if !(t < n && self.data.stages[t].constraint_jx_is_zero(k)) {
                matvec_t(slice_mut(&mut knot.q), Accum::Add, cd.jx.as_ref(), dn, 1.0);
            }
            if t < n {
                matvec_t(slice_mut(&mut knot.r), Accum::Add, cd.ju.as_ref(), dn, 1.0);
            }
        }
        self.constraint_rows(problem, mu, predicted);
    }

    /// Adds the multiplier-weighted second derivatives (37d)-(37i) to the knots. Cross
    /// terms between consecutive states of implicit dynamics (`f_xy`, `f_uy`) have no
    /// place in the knot structure and are left out; `f_yy` joins the next knot's `Q`.
    fn add_second_order(&mut self, problem: &Problem) {
        let n = problem.horizon();
        for t in 0..n {
            let (left, right) = self.lq.knots.split_at_mut(t + 1);
            let knot = &mut left[t];
            let sd = &self.data.stages[t];
            match &sd.dynamics {
                DynamicsData::Explicit(d) => {
                    knot.Q += &d.vhp_xx;
                    knot.S += &d.vhp_xu;
                    knot.R += &d.vhp_uu;
                }
                DynamicsData::Implicit(d) => {
                    knot.Q += &d.vhp_xx;
                    knot.S += &d.vhp_xu;
                    knot.R += &d.vhp_uu;
                    right[0].Q += &d.vhp_yy;
                }
            }
            for cd in &sd.constraints {
                knot.Q += &cd.vhp_xx;
                knot.S += &cd.vhp_xu;
                knot.R += &cd.vhp_uu;
            }
        }
        let last = &mut self.lq.knots[n];
        for cd in &self.data.terminal_constraints {
            last.Q += &cd.vhp_xx;
        }
        if problem.nc0() > 0 && self.data.init.vhp_xx.nrows() > 0 {
            self.lq.knots[0].Q += &self.data.init.vhp_xx;
        }
    }

    /// Prepares the local model of the merit function along the step `d = (δz, δλ, δν)`:
    /// the cost slope `∇J·δz` and curvature `δzᵀ ∇²J δz`, and the linearised changes
    /// `J δz` of the initial, dynamics and constraint residuals. The model keeps every
    /// term of the merit function but replaces each residual by its linearisation, so
    /// along the line it is a convex piecewise quadratic in `α` whose kinks are where
    /// constraints change activity.
    pub fn prepare_model(&mut self, problem: &Problem) {
        let n = problem.horizon();
        let st = &self.step;
        let mut slope = 0.0;
        let mut curv = 0.0;
        for t in 0..=n {
            let (c, [lxx, lxu, luu]) = if t < n {
                let c = &self.data.stages[t].cost;
                (c, hessian_blocks(self.loans[t], &self.lq.knots[t], c))
            } else {
                let c = &self.data.terminal_cost;
                (c, [c.lxx.as_ref(), c.lxu.as_ref(), c.luu.as_ref()])
            };
            let dx = slice(&st.xs[t]);
            slope += dot(c.lx(), dx);
            let hx = &mut self.tbuf[t];
            matvec(hx, Accum::Replace, lxx, dx, 1.0);
            if t < n {
                let du = slice(&st.us[t]);
                slope += dot(c.lu(), du);
                matvec(hx, Accum::Add, lxu, du, 2.0);
                let hu = &mut self.gu[t];
                matvec(hu, Accum::Replace, luu, du, 1.0);
                curv += dot(hu, du);
            }
            curv += dot(hx, dx);
        }
        self.cost_slope = slope;
        self.cost_curv = curv;
        matvec(
            &mut self.lin_init,
            Accum::Replace,
            self.data.init.jx.as_ref(),
            slice(&st.xs[0]),
            1.0,
        );
        for t in 0..n {
            let sd = &self.data.stages[t];
            let [jx, ju, jy] = dynamics_blocks(self.loans[t], &self.lq.knots[t], sd);
            let a = &mut self.lin_dyn[t];
            matvec(a, Accum::Replace, jx, slice(&st.xs[t]), 1.0);
            matvec(a, Accum::Add, ju, slice(&st.us[t]), 1.0);
            add_jy_product(a, jy, sd.dyn_jy_block, slice(&st.xs[t + 1]));
        }
        self.constraint_step(problem);
    }

    /// Derivative at `α` of the local model of the merit function along the step (see
    /// [`Workspace::prepare_model`]); at `α = 0` it is the exact directional derivative
    /// `dφ(0)` of the merit function.
    pub fn model_slope(&mut self, problem: &Problem, merit: Merit, mu: f64, mu_d: f64, alpha: f64) -> f64 {
        self.cost_slope
            + alpha * self.cost_curv
            + self.equality_slope(problem, merit, mu_d, alpha)
            + self.constraint_slope(problem, merit, mu, alpha, false).0
    }

    /// The part of [`model_slope`](Self::model_slope) from the initial condition and the
    /// dynamics: an affine function of `α`.
    fn equality_slope(&self, problem: &Problem, merit: Merit, mu_d: f64, alpha: f64) -> f64 {
        let n = problem.horizon();
        let st = &self.step;
        let mut d = 0.0;
        // An equality row with residual f, linearised change a, multiplier l and step dl:
        // primal-dual (17): (1/mu)(f + αa + mu(λ_e - l(α)/2))² + (mu/4) l(α)²;
        // primal (35): (1/2mu)(f + αa + mu λ_e)².
        let eq_slope = |f: f64, a: f64, le: f64, l: f64, dl: f64| match merit {
            Merit::PrimalDual => {
                let la = l + alpha * dl;
                let r = f + alpha * a + mu_d * (le - 0.5 * la);
                2.0 / mu_d * r * (a - 0.5 * mu_d * dl) + 0.5 * mu_d * la * dl
            }
            Merit::Primal => (f + alpha * a + mu_d * le) * a / mu_d,
        };
        let init = self.data.init.value();
        for i in 0..init.len() {
            d += eq_slope(
                init[i],
                self.lin_init[i],
                self.lams_e[0][i],
                self.cur.lams[0][i],
                st.lambdas[0][i],
            );
        }
        for t in 0..n {
            let f = self.data.stages[t].dyn_value();
            let m = f.len();
            let a = &self.lin_dyn[t][..m];
            let (le, l) = (&self.lams_e[t + 1][..m], &self.cur.lams[t + 1][..m]);
            let dl = &slice(&st.lambdas[t + 1])[..m];
            for i in 0..m {
                d += eq_slope(f[i], a[i], le[i], l[i], dl[i]);
            }
        }
        d
    }

    /// The part of [`model_slope`](Self::model_slope) from the path and terminal
    /// constraints, and its derivative in `α` on the current piece (the active
    /// curvature, 0 unless `with_curv`). With `z(α)` affine, the slope is `Σ (2/mu) N(z)·z'` plus an affine
    /// multiplier term, so its derivative is `Σ (2/mu) (J_N z')·z'` plus a constant:
    /// piecewise constant for polyhedral sets, smooth between kinks for cones.
    fn constraint_slope(
        &mut self,
        problem: &Problem,
        merit: Merit,
        mu: f64,
        alpha: f64,
        with_curv: bool,
    ) -> (f64, f64) {
        let st = &self.step;
        let mut d = 0.0;
        let mut dd = 0.0;
        // Constraints: with w(α) the shifted, linearised residual, the merit term is
        // 2 e(w) + (mu/4)|ν(α)|² (primal-dual (17)) or e(w) (primal (35)), e the Moreau
        // envelope of the set, whose gradient is N(w) / mu with N the normal-cone
        // projection.
        for e in &self.cons {
            let (t, off) = (e.t, e.rows.start);
            let (c, cd) = (&problem.constraints(t)[e.k], &self.data.constraint_data(t)[e.k]);
            let nr = c.nr();
            let mu_i = c.scale * mu;
            let h = &cd.value()[..nr];
            let b = &self.lin_cons[t][off..off + nr];
            let z = &mut self.zbuf[t][off..off + nr];
            let w = &mut self.wbuf[t][off..off + nr];
            let nu_e = &self.nus_e[t][off..off + nr];
            match merit {
                Merit::PrimalDual => {
                    let nu_c = &self.cur.nus[t][off..off + nr];
                    let dnu = &slice(&st.nus[t])[off..off + nr];
                    for i in 0..nr {
                        let nu_a = nu_c[i] + alpha * dnu[i];
                        z[i] = h[i] + alpha * b[i] + mu_i * (nu_e[i] - 0.5 * nu_a);
                    }
                    c.set.normal_cone_project(z, mu_i, w);
                    for i in 0..nr {
                        let nu_a = nu_c[i] + alpha * dnu[i];
                        d += 2.0 / mu_i * w[i] * (b[i] - 0.5 * mu_i * dnu[i]) + 0.5 * mu_i * nu_a * dnu[i];
                    }
                    if with_curv {
                        // z' = b - (mu/2) δν, reusing w for J_N z'.
                        for i in 0..nr {
                            w[i] = b[i] - 0.5 * mu_i * dnu[i];
                        }
                        c.set.apply_normal_cone_jacobian_vec(z, mu_i, w);
                        for i in 0..nr {
                            dd += 2.0 / mu_i * w[i] * (b[i] - 0.5 * mu_i * dnu[i]) + 0.5 * mu_i * dnu[i] * dnu[i];
                        }
                    }
                }
                Merit::Primal => {
                    for i in 0..nr {
                        z[i] = h[i] + alpha * b[i] + mu_i * nu_e[i];
                    }
                    c.set.normal_cone_project(z, mu_i, w);
                    for i in 0..nr {
                        d += w[i] * b[i] / mu_i;
                    }
                    if with_curv {
                        // z' = b.
                        w.copy_from_slice(b);
                        c.set.apply_normal_cone_jacobian_vec(z, mu_i, w);
                        for i in 0..nr {
                            dd += w[i] * b[i] / mu_i;
                        }
                    }
                }
            }
        }
        (d, dd)
    }

    /// Step length minimising the local model of the merit function on `(0, 1]`: the
    /// root of its nondecreasing derivative `g`, where the constraints that the step
    /// activates stop the decrease (a backtracking search from `α = 1` approaches it
    /// only geometrically). `dphi0 = g(0)` must be negative.
    ///
    /// The result is that of bisecting `g` on `[0, 1]` to relative width `1e-3` (the
    /// right end of the final interval), but most midpoints are decided without
    /// evaluating `g`: a bracket `g(a) ≤ 0 < g(b)` of the root decides every midpoint
    /// outside `(a, b)` by monotonicity. The bracket is shrunk by Newton steps on the
    /// piece of the last evaluated point (with the derivative of `g` there, the active
    /// curvature), which land on the root once they reach its piece since `g` is
    /// piecewise linear for polyhedral sets; a Newton step that leaves the bracket, or a
    /// bracket that has not halved since the last Newton step, evaluates the midpoint
    /// itself as plain bisection does.
    pub fn model_step(
        &mut self,
        problem: &Problem,
        merit: Merit,
        mu: f64,
        mu_d: f64,
        dphi0: f64,
        alpha_min: f64,
    ) -> f64 {
        // The smooth part of the slope (cost and equality rows) is affine in α: two
        // evaluations give it for every α.
        let e0 = self.equality_slope(problem, merit, mu_d, 0.0);
        let e1 = self.equality_slope(problem, merit, mu_d, 1.0);
        let (c0, c1) = (self.cost_slope + e0, self.cost_curv + (e1 - e0));
        let slope = |ws: &mut Self, alpha: f64| {
            let (d, dd) = ws.constraint_slope(problem, merit, mu, alpha, true);
            (c0 + alpha * c1 + d, c1 + dd)
        };
        let (mut g, mut dg) = slope(self, 1.0);
        if g <= 0.0 {
            return 1.0;
        }
        // g vanishes at the root up to the rounding of its terms, a small multiple of
        // its rise over [0, 1]; a point with |g| below this is taken as the root.
        let g_tol = 1e-12 * (g - dphi0);
        let (mut a, mut b, mut alpha) = (0.0_f64, 1.0_f64, 1.0_f64);
        let mut root: Option<f64> = None;
        let mut width_at_newton = f64::INFINITY;
        let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
        while hi - lo > 1e-3 * hi.max(alpha_min) {
            let mid = 0.5 * (lo + hi);
            // Whether g(mid) ≤ 0.
            let left = loop {
                if mid <= a {
                    break true;
                }
                if mid >= b {
                    break false;
                }
                if let Some(r) = root {
                    break mid <= r;
                }
                let newton = alpha - g / dg;
                alpha = if dg > 0.0 && newton > a && newton < b && b - a <= 0.5 * width_at_newton {
                    width_at_newton = b - a;
                    newton
                } else {
                    width_at_newton = f64::INFINITY;
                    mid
                };
                (g, dg) = slope(self, alpha);
                if g <= 0.0 {
                    a = alpha;
                } else {
                    b = alpha;
                }
                if g.abs() <= g_tol {
                    root = Some(alpha);
                }
            };
            if left {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        hi.max(alpha_min)
    }

    /// Merit function and infeasibility at the trial point, whose values have just been
    /// evaluated into `self.data` (the primal-dual AL (17) or the primal AL (35)).
    pub fn trial_merit(&mut self, problem: &Problem, merit: Merit, mu: f64, mu_d: f64) -> (f64, f64) {
        let n = problem.horizon();
        let mut m = self.data.cost;
        let mut theta: f64 = 0.0;
        let eq_term = |f: f64, le: f64, l: f64| match merit {
            Merit::PrimalDual => {
                let a = f + mu_d * (le - 0.5 * l);
                a * a / mu_d + 0.25 * mu_d * l * l
            }
            Merit::Primal => {
                let a = f + mu_d * le;
                0.5 * a * a / mu_d
            }
        };
        let init = self.data.init.value();
        for i in 0..init.len() {
            m += eq_term(init[i], self.lams_e[0][i], self.trial.lams[0][i]);
            theta = theta.max(init[i].abs());
        }
        for t in 0..n {
            let f = self.data.stages[t].dyn_value();
            for i in 0..f.len() {
                m += eq_term(f[i], self.lams_e[t + 1][i], self.trial.lams[t + 1][i]);
                theta = theta.max(f[i].abs());
            }
        }
        for e in &self.cons {
            let (t, off) = (e.t, e.rows.start);
            let (c, cd) = (&problem.constraints(t)[e.k], &self.data.constraint_data(t)[e.k]);
            let nr = c.nr();
            let mu_i = c.scale * mu;
            let h = &cd.value()[..nr];
            theta = theta.max(c.set.violation(h));
            let z = &mut self.zbuf[t][off..off + nr];
            let w = &mut self.wbuf[t][off..off + nr];
            let nu_e = &self.nus_e[t][off..off + nr];
            match merit {
                Merit::PrimalDual => {
                    // 2 e(w) + (mu/4)|ν|² with e the Moreau envelope of the set:
                    // 2 g(proj(w)) + |N(w)|² / mu.
                    let nu_t = &self.trial.nus[t][off..off + nr];
                    for i in 0..nr {
                        z[i] = h[i] + mu_i * (nu_e[i] - 0.5 * nu_t[i]);
                    }
                    c.set.project(z, mu_i, w);
                    m += 2.0 * c.set.penalty(w);
                    for i in 0..nr {
                        let r = z[i] - w[i];
                        let v = nu_t[i];
                        m += r * r / mu_i + 0.25 * mu_i * v * v;
                    }
                }
                Merit::Primal => {
                    for i in 0..nr {
                        z[i] = h[i] + mu_i * nu_e[i];
                    }
                    c.set.project(z, mu_i, w);
                    m += c.set.penalty(w);
                    for i in 0..nr {
                        let r = z[i] - w[i];
                        m += 0.5 * r * r / mu_i;
                    }
                }
            }
        }
        (m, theta)
    }

    /// Trial point of the linear rollout (50): `x ⊕ α δx`, `u + α δu`, multipliers
    /// `+ α δ`.
    pub fn linear_trial(&mut self, problem: &Problem, alpha: f64) {
        let n = problem.horizon();
        let st = &self.step;
        for t in 0..=n {
            let v = &mut self.dxbuf[t];
            for (vi, s) in v.iter_mut().zip(slice(&st.xs[t])) {
                *vi = alpha * s;
            }
            problem.space(t).integrate(&self.cur.xs[t], v, &mut self.trial.xs[t]);
            for (i, nu) in self.trial.nus[t].iter_mut().enumerate() {
                *nu = self.cur.nus[t][i] + alpha * st.nus[t][i];
            }
            for (i, l) in self.trial.lams[t].iter_mut().enumerate() {
                *l = self.cur.lams[t][i] + alpha * st.lambdas[t][i];
            }
        }
        for t in 0..n {
            for (i, u) in self.trial.us[t].iter_mut().enumerate() {
                *u = self.cur.us[t][i] + alpha * st.us[t][i];
            }
        }
    }

    /// Trial point of the nonlinear rollout (51): the feedback gains act on
    /// `x_t^α ⊖ x_t` and the next state solves the shifted dynamics of the subproblem
    /// (see [`Workspace::next_state`]). Returns `false` if the rollout fails (non-finite
    /// state or an implicit solve that does not converge).
    pub fn nonlinear_trial(&mut self, problem: &Problem, opts: &ProxDdpOptions, alpha: f64, mu_d: f64) -> bool {
        let n = problem.horizon();
        // (51a), (51b)
        {
            let st = &self.step;
            let v = &mut self.dxbuf[0];
            for (vi, s) in v.iter_mut().zip(slice(&st.xs[0])) {
                *vi = alpha * s;
            }
            problem.space(0).integrate(&self.cur.xs[0], v, &mut self.trial.xs[0]);
            for (i, l) in self.trial.lams[0].iter_mut().enumerate() {
                *l = self.cur.lams[0][i] + alpha * st.lambdas[0][i];
            }
        }
        for t in 0..=n {
            self.trial_deviation(problem, t, alpha);
            self.feedback(t, n, alpha);
            if t < n && !self.next_state(problem, opts, t, alpha, mu_d) {
                return false;
            }
        }
        true
    }

    /// `e = x_t^α ⊖ x_t` into `dxbuf[t]`, measured from the linear prediction
    /// `x̂ = x_t ⊕ α δx_t` as `e = (x_t^α ⊖ x̂) + α δx_t`: the same on vector spaces, and on
    /// spaces with angles (SO(2), SO(3)) it does not wrap by a full turn when the step
    /// turns a joint by more than π, which would feed a 2π error through the gains.
    fn trial_deviation(&mut self, problem: &Problem, t: usize, alpha: f64) {
        let space = problem.space(t);
        let xhat = &mut self.ybuf[t];
        let v = &mut self.dxbuf[t];
        for (vi, s) in v.iter_mut().zip(slice(&self.step.xs[t])) {
            *vi = alpha * s;
        }
        space.integrate(&self.cur.xs[t], v, xhat);
        space.difference(xhat, &self.trial.xs[t], v);
        for (vi, s) in v.iter_mut().zip(slice(&self.step.xs[t])) {
            *vi += alpha * s;
        }
    }

    /// (51c) and the path multipliers of knot `t` from the deviation `e` in `dxbuf[t]`.
    fn feedback(&mut self, t: usize, n: usize, alpha: f64) {
        let stage = self.riccati.stage(t);
        let e = &self.dxbuf[t];
        if t < n {
            let (k, kk) = (stage.k(), stage.K());
            let u = &mut self.trial.us[t];
            for i in 0..u.len() {
                u[i] = self.cur.us[t][i] + alpha * k[i];
            }
            matvec(u, Accum::Add, kk, e, 1.0);
        }
        let (zeta, zz) = (stage.zeta(), stage.Z());
        let nu = &mut self.trial.nus[t];
        for i in 0..nu.len() {
            nu[i] = self.cur.nus[t][i] + alpha * zeta[i];
        }
        matvec(nu, Accum::Add, zz, e, 1.0);
    }

    /// (51d) the next co-state, and (51e) the next state, with the part `1 - α` of the
    /// current shifted gap `g = f + mu_d (λ_e - λ)` (the knot's `f`) kept, as FDDP keeps
    /// its gaps: the next state solves `f(x^α, u^α, y) = s` with
    /// `s = mu_d (λ^α - λ_e) + (1 - α) g`, so that `α = 0` gives the current point back
    /// and, on linear dynamics, the rollout equals the linear step (50).
    fn next_state(&mut self, problem: &Problem, opts: &ProxDdpOptions, t: usize, alpha: f64, mu_d: f64) -> bool {
        let Some((xi, xxi)) = self.riccati.stage(t).lambda_next_gains() else {
            return false;
        };
        let lam = &mut self.trial.lams[t + 1];
        for i in 0..lam.len() {
            lam[i] = self.cur.lams[t + 1][i] + alpha * xi[i];
        }
        matvec(lam, Accum::Add, xxi, &self.dxbuf[t], 1.0);
        let s = &mut self.tbuf[t + 1];
        let g = &self.lq.knots[t].f;
        for i in 0..s.len() {
            let proximal = if self.exact_dynamics {
                0.0
            } else {
                mu_d * (self.trial.lams[t + 1][i] - self.lams_e[t + 1][i])
            };
            s[i] = proximal + (1.0 - alpha) * g[i];
        }
        let stage_model = &problem.stages()[t];
        let (xs_lo, xs_hi) = self.trial.xs.split_at_mut(t + 1);
        let (x, y) = (&xs_lo[t], &mut xs_hi[0]);
        if matches!(stage_model.dynamics, Dynamics::Implicit(_)) {
            // Newton-Raphson on f(x, u, y) - s = 0 from y = x_{t+1} ⊕ α δx_{t+1}.
            let v = &mut self.dxbuf[t + 1];
            for (vi, st) in v.iter_mut().zip(slice(&self.step.xs[t + 1])) {
                *vi = alpha * st;
            }
            stage_model.space_next().integrate(&self.cur.xs[t + 1], v, y);
        }
        let solve = ImplicitSolve {
            max_iters: opts.implicit_newton_iters,
            tol: opts.implicit_newton_tol,
        };
        self.data.stages[t].solve_next_state(stage_model, x, &self.trial.us[t], Some(s), y, solve)
    }

    /// Makes the trial point the current one.
    pub fn accept_trial(&mut self) {
        std::mem::swap(&mut self.cur, &mut self.trial);
    }

    /// Keeps a copy of the current point if it is the best so far.
    pub fn record_best(&mut self, err: f64) {
        if err < self.best_err {
            self.best_err = err;
            self.best.copy_from(&self.cur);
        }
    }
}

/// The part of the Lagrangian gradient (24) that the constraint multipliers leave alone,
/// `∇ℓ + f_xᵀ λ` and `∇_u ℓ + f_uᵀ λ` per knot
/// ([`ProblemData::lagrangian_gradient_forward`]), at the co-states `lams` and, while
/// `valid`, the current derivatives: shared by the residuals' gradient and the Newton
/// system's.
#[derive(Debug)]
struct GradientPart {
    x: Vec<Vec<f64>>,
    u: Vec<Vec<f64>>,
    lams: Vec<Vec<f64>>,
    valid: bool,
}

impl GradientPart {
    /// Storage for `problem`, co-states shaped like `lams`; not valid yet.
    fn new(problem: &Problem, lams: &[Vec<f64>]) -> Self {
        let n = problem.horizon();
        Self {
            x: (0..=n).map(|t| vec![0.0; problem.space(t).ndx()]).collect(),
            u: (0..n).map(|t| vec![0.0; problem.nu(t)]).collect(),
            lams: lams.to_vec(),
            valid: false,
        }
    }
}

/// The cost Hessian blocks `[lxx, lxu, luu]` of a stage: in its cost data `c`, or in
/// its knot while they are lent.
fn hessian_blocks<'a>(loan: Loan, knot: &'a LqKnot, c: &'a CostData) -> [MatRef<'a, f64>; 3] {
    if loan.hessian {
        [knot.Q.as_ref(), knot.S.as_ref(), knot.R.as_ref()]
    } else {
        [c.lxx.as_ref(), c.lxu.as_ref(), c.luu.as_ref()]
    }
}

/// The dynamics Jacobians `[f_x, f_u, f_y]` of a stage, wherever they are.
fn dynamics_blocks<'a>(loan: Loan, knot: &'a LqKnot, sd: &'a StageData) -> [MatRef<'a, f64>; 3] {
    let (jx, ju) = if loan.dynamics {
        (knot.A.as_ref(), knot.B.as_ref())
    } else {
        (sd.dyn_jx.as_ref(), sd.dyn_ju.as_ref())
    };
    [jx, ju, if loan.e { knot.E.as_ref() } else { sd.dyn_jy.as_ref() }]
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The shifted constraint value `z = h + mu_i ν_e` of the multiplier estimates (39).
fn shifted_value(z: &mut [f64], h: &[f64], nu_e: &[f64], mu_i: f64) {
    for ((zi, hi), ni) in z.iter_mut().zip(h).zip(nu_e) {
        *zi = hi + mu_i * ni;
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use faer::Mat;

    use super::*;
    use crate::constraints::{BoxConstraint, ConstraintSet, EqualityConstraintSet, SecondOrderCone};
    use crate::costs::QuadraticCost;
    use crate::dynamics::LinearDiscreteDynamics;
    use crate::functions::{ControlError, StateError, Unary};
    use crate::lq::random::SplitMix64;
    use crate::problem::{StageConstraint, StageModel};
    use crate::spaces::VectorSpace;

    const NX: usize = 3;
    const NU: usize = 3;
    const N: usize = 5;

    /// A random linear-quadratic problem with the set on every control, and for the
    /// equality set also the terminal state pinned.
    fn problem(set: Arc<dyn ConstraintSet>, rng: &mut SplitMix64) -> Problem {
        let sp = VectorSpace::new(NX);
        let a = Mat::from_fn(NX, NX, |i, j| {
            f64::from(u8::from(i == j)) + 0.3 * rng.uniform(-1.0, 1.0)
        });
        let b = Mat::from_fn(NX, NU, |_, _| rng.uniform(-1.0, 1.0));
        let c: Vec<f64> = (0..NX).map(|_| rng.uniform(-0.1, 0.1)).collect();
        let dynamics = Dynamics::Explicit(Arc::new(
            LinearDiscreteDynamics::new(a.as_ref(), b.as_ref(), &c).unwrap(),
        ));
        let q = Mat::<f64>::identity(NX, NX);
        let r = Mat::<f64>::identity(NU, NU);
        let s = Mat::<f64>::zeros(NX, NU);
        let qv: Vec<f64> = (0..NX).map(|_| rng.uniform(-1.0, 1.0)).collect();
        let rv: Vec<f64> = (0..NU).map(|_| rng.uniform(-1.0, 1.0)).collect();
        let cost = Arc::new(QuadraticCost::new(q.as_ref(), s.as_ref(), r.as_ref(), &qv, &rv).unwrap());
        let mut stage = StageModel::new(cost, dynamics).unwrap();
        let f = Arc::new(ControlError::new(&sp, &[0.0; NU]).unwrap());
        let equality = set.is_equality();
        stage.add_constraint(StageConstraint::new("u", f, set)).unwrap();
        let term = Arc::new(QuadraticCost::terminal(q.as_ref(), &qv).unwrap());
        let mut p = Problem::new(&[0.5; NX], vec![stage; N], term).unwrap();
        if equality {
            let xt: Vec<f64> = (0..NX).map(|_| rng.uniform(-1.0, 1.0)).collect();
            let f = Arc::new(Unary::new(Arc::new(StateError::new(Arc::new(sp), &xt).unwrap()), 0));
            p.add_terminal_constraint(StageConstraint::new("x_N", f, Arc::new(EqualityConstraintSet)))
                .unwrap();
        }
        p
    }

    fn fill(v: &mut [f64], rng: &mut SplitMix64) {
        v.iter_mut().for_each(|x| *x = rng.uniform(-1.0, 1.0));
    }

    fn scale_step(st: &mut LqSolution, s: f64) {
        for c in st
            .xs
            .iter_mut()
            .chain(&mut st.us)
            .chain(&mut st.lambdas)
            .chain(&mut st.nus)
        {
            slice_mut(c).iter_mut().for_each(|x| *x *= s);
        }
    }

    /// Root of the model slope on `[0, hi]` by bisection to absolute width 1e-13.
    fn fine_root(ws: &mut Workspace, p: &Problem, merit: Merit, mu: f64, mu_d: f64, mut hi: f64) -> f64 {
        let mut lo = 0.0;
        while hi - lo > 1e-13 {
            let mid = 0.5 * (lo + hi);
            if ws.model_slope(p, merit, mu, mu_d, mid) <= 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        hi
    }

    /// A workspace of `p` at a random point, estimates and step, the step turned into a
    /// descent direction for `merit` and scaled so that the model slope's root lands at a
    /// random point of (0.1, 0.9).
    fn random_descent(p: &Problem, merit: Merit, (mu, mu_d): (f64, f64), rng: &mut SplitMix64) -> Workspace {
        let mut ws = Workspace::new(p, &ProxDdpOptions::default(), None).unwrap();
        let cur = &mut ws.cur;
        for v in cur
            .xs
            .iter_mut()
            .chain(&mut cur.us)
            .chain(&mut cur.lams)
            .chain(&mut cur.nus)
        {
            fill(v, rng);
        }
        for v in ws.lams_e.iter_mut().chain(&mut ws.nus_e) {
            fill(v, rng);
        }
        ws.evaluate_current(p).unwrap();
        let st = &mut ws.step;
        for c in st
            .xs
            .iter_mut()
            .chain(&mut st.us)
            .chain(&mut st.lambdas)
            .chain(&mut st.nus)
        {
            fill(slice_mut(c), rng);
        }
        ws.prepare_model(p);
        if ws.model_slope(p, merit, mu, mu_d, 0.0) > 0.0 {
            scale_step(&mut ws.step, -1.0);
            ws.prepare_model(p);
        }
        assert!(ws.model_slope(p, merit, mu, mu_d, 0.0) < 0.0, "not a descent step");
        let mut top = 1.0;
        while ws.model_slope(p, merit, mu, mu_d, top) <= 0.0 {
            top *= 2.0;
        }
        let r0 = fine_root(&mut ws, p, merit, mu, mu_d, top);
        scale_step(&mut ws.step, r0 / rng.uniform(0.1, 0.9));
        ws.prepare_model(p);
        ws
    }

    /// Plain bisection of the model slope on (0, 1), every midpoint evaluated, to the
    /// model step's relative accuracy: the upper end.
    fn bisection(ws: &mut Workspace, p: &Problem, merit: Merit, (mu, mu_d): (f64, f64), alpha_min: f64) -> f64 {
        let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
        while hi - lo > 1e-3 * hi.max(alpha_min) {
            let mid = 0.5 * (lo + hi);
            if ws.model_slope(p, merit, mu, mu_d, mid) <= 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        hi
    }

    /// Whether the model's curvature differs at the two ends of (0, 1): a kink inside.
    fn has_kink(ws: &mut Workspace, p: &Problem, merit: Merit, (mu, mu_d): (f64, f64)) -> bool {
        let h = 1e-7;
        let mut curv = |a: f64| (ws.model_slope(p, merit, mu, mu_d, a + h) - ws.model_slope(p, merit, mu, mu_d, a)) / h;
        let (k0, k1) = (curv(0.0), curv(1.0 - h));
        (k1 - k0).abs() > 1e-4 * k0.abs().max(k1.abs())
    }

    /// The model step against plain bisection of the full model slope (every midpoint
    /// evaluated) and against the root to 1e-13, and the active curvature against
    /// central differences, at random points and steps scaled so
    /// that the root lies inside (0, 1), with the constraint activity changing along the
    /// step for the box and the cone.
    /// A damped rigid body in the plane, `v̇ = u - v / 10` on the tangent bundle of SE(2):
    /// a non-abelian group, so that `E ≠ -I` off the dynamics and the state cost's
    /// Hessian is not constant.
    #[derive(Debug)]
    struct Se2Body(Arc<dyn crate::spaces::Manifold>);

    impl crate::dynamics::Ode for Se2Body {
        fn space(&self) -> &Arc<dyn crate::spaces::Manifold> {
            &self.0
        }
        fn nu(&self) -> usize {
            3
        }
        fn evaluate(&self, x: &[f64], u: &[f64], data: &mut crate::dynamics::OdeData) {
            let xdot = data.xdot_mut();
            for i in 0..3 {
                xdot[i] = x[4 + i];
                xdot[3 + i] = u[i] - 0.1 * x[4 + i];
            }
        }
        fn jacobians(&self, _x: &[f64], _u: &[f64], data: &mut crate::dynamics::OdeData) {
            data.jx.fill(0.0);
            data.ju.fill(0.0);
            for i in 0..3 {
                data.jx[(i, 3 + i)] = 1.0;
                data.jx[(3 + i, 3 + i)] = -0.1;
                data.ju[(3 + i, i)] = 1.0;
            }
        }
    }

    fn se2_problem(n: usize) -> Problem {
        use crate::costs::QuadraticStateCost;
        use crate::dynamics::SemiImplicitEuler;
        use crate::spaces::{Manifold, SE2, TangentBundle};
        let se2: Arc<dyn Manifold> = Arc::new(SE2);
        let space: Arc<dyn Manifold> = Arc::new(TangentBundle::new(se2.clone()));
        let ode = Arc::new(Se2Body(space.clone()));
        let dynamics = Dynamics::Explicit(Arc::new(SemiImplicitEuler::new(ode, se2, 0.05).unwrap()));
        let x_ref = [0.5, -0.2, 0.0, 1.0, 0.0, 0.0, 0.0];
        let w = [1.0, 1.0, 2.0, 0.1, 0.1, 0.1];
        let cost = Arc::new(QuadraticStateCost::diagonal(space.clone(), &x_ref, &w, 3).unwrap());
        let stage = StageModel::new(cost, dynamics).unwrap();
        let term = Arc::new(QuadraticStateCost::diagonal(space.clone(), &x_ref, &[10.0; 6], 0).unwrap());
        let mut x0 = vec![0.0; 7];
        space.neutral(&mut x0);
        Problem::new(&x0, vec![stage; n], term).unwrap()
    }

    /// The Newton system's Lagrangian gradient reuses the residuals' multiplier-free part
    /// only while the derivatives and the co-states are those it was computed at: it
    /// equals a whole evaluation bit for bit after the residuals, after a change of the
    /// co-states and after new derivatives.
    #[test]
    fn the_shared_gradient_part_follows_the_co_states_and_the_derivatives() {
        let (n, mut rng) = (4, SplitMix64::new(7));
        let p = se2_problem(n);
        let opts = ProxDdpOptions::default();
        let mut ws = Workspace::new(&p, &opts, None).unwrap();
        let random_point = |ws: &mut Workspace, rng: &mut SplitMix64| {
            for t in 0..=n {
                let v: Vec<f64> = (0..6).map(|_| rng.uniform(-1.0, 1.0)).collect();
                let mut x0 = vec![0.0; 7];
                p.space(t).neutral(&mut x0);
                p.space(t).integrate(&x0, &v, &mut ws.cur.xs[t]);
            }
            for v in ws.cur.us.iter_mut().chain(&mut ws.cur.lams) {
                fill(v, rng);
            }
        };
        let expect = |ws: &mut Workspace| {
            ws.return_loans();
            let (mut gx, mut gu) = (ws.gx.clone(), ws.gu.clone());
            ws.data
                .lagrangian_gradient(&p, &ws.cur.lams, &ws.nus_g, &mut gx, &mut gu);
            assert_eq!((&ws.gx, &ws.gu), (&gx, &gu));
        };
        random_point(&mut ws, &mut rng);
        ws.evaluate_current(&p).unwrap();
        ws.estimates_and_residuals(&p, 1e-2, 1e-3);
        ws.build_lq(&p, &opts, 1e-2, 1e-3);
        expect(&mut ws);
        for v in &mut ws.cur.lams {
            fill(v, &mut rng);
        }
        ws.build_lq(&p, &opts, 1e-2, 1e-3);
        expect(&mut ws);
        ws.estimates_and_residuals(&p, 1e-2, 1e-3);
        let lams = ws.cur.lams.clone();
        random_point(&mut ws, &mut rng);
        ws.evaluate_current(&p).unwrap();
        ws.cur.lams = lams;
        ws.build_lq(&p, &opts, 1e-2, 1e-3);
        expect(&mut ws);
    }

    /// `build_lq` lends the stage data's derivative blocks to the knots instead of
    /// copying them: the knots hold the blocks of an independent evaluation, also after a
    /// second build at the same point (the proximal fallback's), and the stage data has
    /// them back afterwards. The exact Hessian, which the knots add to, is copied.
    #[test]
    fn knots_borrow_the_derivative_blocks_and_give_them_back() {
        let (n, mut rng) = (4, SplitMix64::new(91));
        let p = se2_problem(n);
        for hessian in [HessianApprox::GaussNewton, HessianApprox::Exact] {
            let opts = ProxDdpOptions {
                hessian,
                ..ProxDdpOptions::default()
            };
            let mut ws = Workspace::new(&p, &opts, None).unwrap();
            for t in 0..=n {
                let v: Vec<f64> = (0..6).map(|_| rng.uniform(-1.0, 1.0)).collect();
                let mut x0 = vec![0.0; 7];
                p.space(t).neutral(&mut x0);
                p.space(t).integrate(&x0, &v, &mut ws.cur.xs[t]);
            }
            for u in &mut ws.cur.us {
                fill(u, &mut rng);
            }
            let mut fresh = ProblemData::new(&p, 1).unwrap();
            fresh.evaluate(&p, &ws.cur.xs, &ws.cur.us);
            fresh.compute_derivatives(&p, &ws.cur.xs, &ws.cur.us);
            ws.evaluate_current(&p).unwrap();
            for build in 0..2 {
                ws.build_lq(&p, &opts, 1e-2, 1e-3);
                for t in 0..n {
                    let (f, knot) = (&fresh.stages[t], &ws.lq.knots[t]);
                    let lent_hessian = hessian == HessianApprox::GaussNewton;
                    let want = Loan {
                        hessian: lent_hessian,
                        dynamics: true,
                        e: true,
                    };
                    assert_eq!(ws.loans[t], want, "{hessian:?} build {build} knot {t}");
                    if lent_hessian {
                        assert_eq!((&knot.Q, &knot.S, &knot.R), (&f.cost.lxx, &f.cost.lxu, &f.cost.luu));
                    }
                    assert_eq!((&knot.A, &knot.B, &knot.E), (&f.dyn_jx, &f.dyn_ju, &f.dyn_jy));
                    assert!(f.dyn_jy != -Mat::<f64>::identity(6, 6), "E = -I: no loan tested");
                }
            }
            ws.return_loans();
            for (t, (d, f)) in ws.data.stages.iter().zip(&fresh.stages).enumerate() {
                assert_eq!(ws.loans[t], Loan::default());
                assert_eq!(
                    (&d.cost.lxx, &d.cost.lxu, &d.cost.luu),
                    (&f.cost.lxx, &f.cost.lxu, &f.cost.luu)
                );
                assert_eq!((&d.dyn_jx, &d.dyn_ju, &d.dyn_jy), (&f.dyn_jx, &f.dyn_ju, &f.dyn_jy));
            }
        }
    }

    #[test]
    fn model_step_matches_bisection_of_the_model_slope() {
        let mut rng = SplitMix64::new(17);
        let sets: [(&str, Arc<dyn ConstraintSet>); 3] = [
            ("box", Arc::new(BoxConstraint::new(&[-0.3; NU], &[0.3; NU]).unwrap())),
            ("equality", Arc::new(EqualityConstraintSet)),
            ("cone", Arc::new(SecondOrderCone::new(NU).unwrap())),
        ];
        let (mu, mu_d, alpha_min) = (0.05, 0.05, 1e-8);
        for (name, set) in sets {
            let mut kinked = 0;
            for trial in 0..12 {
                let p = problem(set.clone(), &mut rng);
                let merit = if trial % 2 == 0 {
                    Merit::PrimalDual
                } else {
                    Merit::Primal
                };
                let mut ws = random_descent(&p, merit, (mu, mu_d), &mut rng);
                let dphi0 = ws.model_slope(&p, merit, mu, mu_d, 0.0);
                let got = ws.model_step(&p, merit, mu, mu_d, dphi0, alpha_min);
                let hi = bisection(&mut ws, &p, merit, (mu, mu_d), alpha_min);
                assert_eq!(got, hi, "{name} trial {trial}: model step differs from bisection");
                let root = fine_root(&mut ws, &p, merit, mu, mu_d, 1.0);
                assert!(
                    root <= got + 1e-12 && got - root <= 1e-3 * got,
                    "{name} trial {trial}: root {root} outside the bisection interval ending at {got}"
                );
                // The active curvature against central differences of the slope.
                for _ in 0..5 {
                    let (a, h) = (rng.uniform(0.0, 1.0), 1e-6);
                    let (d, dd) = ws.constraint_slope(&p, merit, mu, a, true);
                    let fd = (ws.constraint_slope(&p, merit, mu, a + h, false).0
                        - ws.constraint_slope(&p, merit, mu, a - h, false).0)
                        / (2.0 * h);
                    assert!(
                        (dd - fd).abs() <= 1e-5 * (1.0 + dd.abs() + d.abs()),
                        "{name} trial {trial}: curvature {dd} vs finite difference {fd} at {a}"
                    );
                }
                if has_kink(&mut ws, &p, merit, (mu, mu_d)) {
                    kinked += 1;
                }
            }
            if name != "equality" {
                assert!(kinked >= 6, "{name}: only {kinked} of 12 trials have kinks in (0, 1)");
            }
        }
    }
}

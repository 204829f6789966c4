//! The DDP family's workspace: iterates, gaps, the LQ subproblem and its Riccati solver,
//! the box QPs, and the per-iteration computations (backward pass, expected improvement,
//! rollout). Everything is allocated in [`Workspace::new`]; no method allocates.

use faer::{Accum, Mat};

use super::augmented::Augmented;
use super::bounds::ControlBounds;
use super::options::{DdpOptions, DdpVariant};
use crate::dynamics::Dynamics;
use crate::error::{Error, Result};
use crate::linalg::{dot, matvec, norm_inf, slice, slice_mut};
use crate::lq::{LqError, LqProblem, LqSolution, RiccatiSolver, RiccatiStage};
use crate::problem::{DynamicsData, InitialCondition, Problem, ProblemData, StageData, StageModel};
use crate::solvers::boxqp::{BoxQp, BoxQpOptions};
use crate::solvers::skeleton::{Receding, SqpFilter, copy_stage_model, copy_trajectory, lq_for};
use crate::solvers::{HessianApprox, InitialGuess};

/// The terms of the expected improvement of FDDP (Mastalli et al. 2020, (19)-(20)) that do
/// not depend on the trial: `Δ_g` and `Δ_q` (crocoddyl's `dg`, `dq`).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Expected {
    pub dg: f64,
    pub dq: f64,
}

pub(crate) struct Workspace {
    variant: DdpVariant,
    /// Whether the backward pass is the square-root one.
    square_root: bool,
    /// Current iterate.
    pub xs: Vec<Vec<f64>>,
    pub us: Vec<Vec<f64>>,
    /// Trial iterate of the line search.
    pub xs_try: Vec<Vec<f64>>,
    pub us_try: Vec<Vec<f64>>,
    /// Gaps `fs_t` in the tangent space at `x_t`: `fs_0 = x̂_0 ⊖ x_0`,
    /// `fs_{t+1} = f_t(x_t, u_t, x_{t+1}) = φ(x_t, u_t) ⊖ x_{t+1}` (crocoddyl's `fs`).
    fs: Vec<Vec<f64>>,
    /// Whether the gaps are closed (and left out of the backward pass).
    pub feasible: bool,
    /// `P_t fs_t`.
    pfs: Vec<Vec<f64>>,
    /// `x̃_t ⊖ x_t` of the last trial.
    dx: Vec<Vec<f64>>,
    /// Kept part `(1 - α) fs_{t+1}` of the gaps in a multiple-shooting trial.
    shift: Vec<Vec<f64>>,
    x0: Vec<f64>,
    /// Regularisation currently on the diagonals of the knots' `Q`.
    knot_reg: f64,
    /// Whether the knots' `Q` were built with `knot_reg` on their diagonals (not shifted
    /// to it by [`Workspace::set_reg`], which can round differently).
    knots_built: bool,
    /// Whether the LQ matrices are the same at every point of this solve (a
    /// linear-quadratic problem without an augmented Lagrangian).
    lq_constant: bool,
    /// With `lq_constant`: the regularisation of the Riccati factorization that the
    /// solver holds for the knots' matrices, which the next backward pass at that
    /// regularisation reuses (its vector part alone).
    factored_reg: Option<f64>,
    pub lq: LqProblem,
    pub riccati: RiccatiSolver,
    /// Solution of the LQ subproblem (for the co-states of the solution).
    pub lq_sol: LqSolution,
    pub data: ProblemData,
    pub(super) bounds: Option<ControlBounds>,
    qps: Vec<BoxQp>,
    /// Whether the box QP gave the gains of stage `t` in the last backward pass.
    qp_used: Vec<bool>,
    /// Per stage: `Q_uu + ρI`, the QP solution `k`, the gain `K`, relative bounds.
    hbuf: Vec<Mat<f64>>,
    kbuf: Vec<Vec<f64>>,
    gain_buf: Vec<Mat<f64>>,
    dlb: Vec<Vec<f64>>,
    dub: Vec<Vec<f64>>,
    /// Scratch of control size.
    wu: Vec<f64>,
    /// Scratch of control size: the augmented control gradient `Q_u^c` (23).
    wq: Vec<f64>,
    /// BCL-DDP: the augmented-Lagrangian terms of equality constraints (the merit is then
    /// the augmented Lagrangian and the knots carry the constraint rows).
    pub al: Option<Augmented>,
    pub cost: f64,
    /// Whether an iteration of this solve has ended (the box QP is used from the second).
    iterated: bool,
    /// Receding horizon: the data of the queued stages, slot by slot.
    spare: Vec<StageData>,
    /// SQP: the co-states of the last LQ step (the multipliers of the KKT test), the
    /// Lagrangian gradient, empty path multipliers, and the filter.
    lams: Vec<Vec<f64>>,
    /// SQP: whether `lams` are the co-states of the last backward pass's step (it was
    /// rolled out).
    lams_current: bool,
    gx: Vec<Vec<f64>>,
    gu: Vec<Vec<f64>>,
    no_nus: Vec<Vec<f64>>,
    /// Scratch of the initial gap of a trial.
    wu_x0: Vec<f64>,
    pub filter: SqpFilter,
    /// Exact Hessian: whether the backward pass adds `V_x'·f_zz`, and the next value
    /// gradients `V_x'` at the zero step that weigh it.
    exact: bool,
    vx_next: Vec<Vec<f64>>,
}

/// Checks that the exact Hessian `V_x'·f_zz` (classical DDP) is available on every stage
/// of the horizon and the queue: explicit dynamics with vector-Hessian products onto a
/// vector space (where the next co-state is the value gradient `p + P f` of the knot); SQP
/// takes the Gauss-Newton Hessian only.
fn check_exact_hessian(problem: &Problem, queue: &[StageModel], variant: DdpVariant) -> Result<()> {
    let name = variant.name();
    if variant == DdpVariant::Sqp {
        return Err(Error::option(
            "hessian",
            format!("{name} implements the Gauss-Newton Hessian only"),
        ));
    }
    for (t, stage) in problem.stages().iter().chain(queue).enumerate() {
        let why = match &stage.dynamics {
            Dynamics::Implicit(_) => "its dynamics are implicit",
            Dynamics::Explicit(m) if !m.has_vhp() => "its dynamics provide no vector-Hessian product",
            Dynamics::Explicit(_) if !stage.space_next().is_vector_space() => "its next state is not in a vector space",
            Dynamics::Explicit(_) => continue,
        };
        return Err(Error::option(
            "hessian",
            format!(
                "{name} with the exact Hessian: stage {t} cannot give V_x'·f_zz because {why} (use the Gauss-Newton Hessian)"
            ),
        ));
    }
    Ok(())
}

/// Refuses constraints (DDP and FDDP handle none), in the horizon or the queue.
fn check_unconstrained(problem: &Problem, queue: &[StageModel], name: &str) -> Result<()> {
    let queued = queue.iter().enumerate().map(|(i, s)| (format!("queued stage {i}"), s));
    let mut stages = problem
        .stages()
        .iter()
        .enumerate()
        .map(|(t, s)| (format!("stage {t}"), s))
        .chain(queued);
    if let Some((what, s)) = stages.find(|(_, s)| s.nc() > 0) {
        return Err(Error::InvalidModel(format!(
            "{name} does not handle constraints: {what} has constraint `{}` (use box-ddp or \
             box-fddp for bounds on the controls, proxddp for general constraints)",
            s.constraints()[0].name
        )));
    }
    if let Some(c) = problem.terminal_constraints().first() {
        return Err(Error::InvalidModel(format!(
            "{name} does not handle constraints: terminal constraint `{}` (use proxddp)",
            c.name
        )));
    }
    Ok(())
}

/// The square-root pass needs `E = -I`: explicit dynamics on vector spaces, in the
/// horizon and the queue.
fn check_square_root(problem: &Problem, queue: &[StageModel], name: &str) -> Result<()> {
    let stages = problem.stages().iter().chain(queue);
    for (t, s) in stages.enumerate() {
        let explicit = matches!(s.dynamics, crate::dynamics::Dynamics::Explicit(_));
        if !explicit || !s.space_next().is_vector_space() {
            return Err(Error::option(
                "square_root",
                format!(
                    "{name} with the square-root pass needs explicit dynamics on vector spaces \
                     (stage {t} has implicit dynamics or a manifold state)"
                ),
            ));
        }
    }
    Ok(())
}

impl Workspace {
    /// The workspace of `problem`; with `queue`, also for a receding horizon through
    /// the stages queued to enter it ([`Workspace::shift`]); with `al`, for BCL-DDP (whose
    /// [`Augmented::new`] checked that the constraints are equalities).
    pub fn new(
        problem: &Problem,
        opts: &DdpOptions,
        queue: Option<&[StageModel]>,
        al: Option<Augmented>,
    ) -> Result<Self> {
        let variant = opts.variant;
        let name = variant.name();
        let InitialCondition::Fixed(x0) = problem.initial_condition() else {
            return Err(Error::InvalidModel(format!(
                "{name} needs a fixed initial state x_0 (the problem has a general initial constraint)"
            )));
        };
        let bounds = checked_bounds(problem, opts, queue, al.is_some())?;
        let queue = queue.unwrap_or(&[]);
        let exact = opts.hessian == HessianApprox::Exact;
        let n = problem.horizon();
        let s = crate::solvers::Solution::new(problem, 0);
        let ndxs: Vec<usize> = (0..=n).map(|t| problem.space(t).ndx()).collect();
        let vecs = |sizes: &[usize]| sizes.iter().map(|&k| vec![0.0; k]).collect::<Vec<_>>();
        let nus: Vec<usize> = (0..n).map(|t| problem.nu(t)).collect();
        let lq = lq_for(problem, al.is_some(), None);
        let riccati = if opts.square_root {
            check_square_root(problem, queue, name)?;
            RiccatiSolver::with_square_root(&lq)?
        } else {
            RiccatiSolver::new(&lq)?
        };
        let lq_sol = LqSolution::new(&lq);
        Ok(Self {
            variant,
            square_root: opts.square_root,
            xs_try: s.xs.clone(),
            us_try: s.us.clone(),
            xs: s.xs,
            us: s.us,
            fs: vecs(&ndxs),
            feasible: false,
            pfs: vecs(&ndxs),
            dx: vecs(&ndxs),
            shift: vecs(&ndxs[1..]),
            x0: x0.clone(),
            knot_reg: 0.0,
            knots_built: false,
            lq_constant: false,
            factored_reg: None,
            lq,
            riccati,
            lq_sol,
            data: ProblemData::new(problem, opts.num_threads)?,
            bounds,
            qps: nus.iter().map(|&m| BoxQp::new(m)).collect(),
            qp_used: vec![false; n],
            hbuf: nus.iter().map(|&m| Mat::zeros(m, m)).collect(),
            kbuf: vecs(&nus),
            gain_buf: (0..n).map(|t| Mat::zeros(nus[t], ndxs[t])).collect(),
            dlb: vecs(&nus),
            dub: vecs(&nus),
            wu: vec![0.0; nus.iter().copied().max().unwrap_or(0)],
            wq: vec![0.0; nus.iter().copied().max().unwrap_or(0)],
            al,
            cost: 0.0,
            iterated: false,
            spare: queue.iter().map(StageData::new).collect(),
            lams: crate::solvers::Solution::new(problem, 0).lambdas,
            lams_current: false,
            gx: vecs(&ndxs),
            gu: vecs(&nus),
            no_nus: (0..=n)
                .map(|t| vec![0.0; problem.constraints(t).iter().map(|c| c.nr()).sum()])
                .collect(),
            wu_x0: vec![0.0; problem.space(0).ndx()],
            filter: SqpFilter::new(opts.filter_size),
            exact,
            vx_next: vecs(&ndxs[1..]),
        })
    }

    /// Receding horizon, after [`Problem::shift`] took the queued stage `slot`: the
    /// stage data and control bounds move one knot earlier (those of the stage that left
    /// go to `slot`). Allocates nothing.
    ///
    /// # Errors
    /// If `slot` is out of range of the queue given to [`Workspace::new`].
    pub fn shift(&mut self, slot: Option<usize>) -> Result<()> {
        if slot.is_some_and(|s| s >= self.spare.len()) {
            return Err(Error::InvalidModel(format!(
                "{}::shift: slot {slot:?} of a queue of {} stages (was setup_receding called?)",
                self.variant.name(),
                self.spare.len()
            )));
        }
        self.data.shift(slot.map(|s| &mut self.spare[s]));
        if let Some(b) = &mut self.bounds {
            b.shift(slot);
        }
        Ok(())
    }

    /// Loads a guess, evaluates it with first derivatives and reads its gaps and control
    /// bounds; returns `false` if a value is not finite.
    ///
    /// # Errors
    /// If the control bounds of a stage are empty.
    pub fn load_guess(&mut self, problem: &Problem, guess: &InitialGuess<'_>, gap_tol: f64) -> Result<bool> {
        copy_trajectory(&mut self.xs, guess.xs);
        copy_trajectory(&mut self.us, guess.us);
        match guess.lambdas {
            Some(l) => copy_trajectory(&mut self.lams, l),
            None => self.lams.iter_mut().for_each(|l| l.fill(0.0)),
        }
        self.lams_current = false;
        self.filter.clear();
        if let InitialCondition::Fixed(x0) = problem.initial_condition() {
            // The initial state may have moved since setup (MPC).
            self.x0.copy_from_slice(x0);
        }
        self.kbuf.iter_mut().for_each(|k| k.fill(0.0));
        self.iterated = false;
        self.lq_constant = self.al.is_none() && problem.has_constant_derivatives();
        self.factored_reg = None;
        self.data.start_solve();
        self.cost = self.data.evaluate(problem, &self.xs, &self.us);
        if let Some(al) = &mut self.al {
            self.cost += al.value(&self.data, None);
        }
        if !self.values_finite() {
            return Ok(false);
        }
        if let Some(b) = &mut self.bounds {
            b.refresh(problem, &self.data, &self.us)?;
        }
        self.data.compute_derivatives(problem, &self.xs, &self.us);
        self.read_gaps(problem);
        self.feasible = self.max_gap() <= gap_tol;
        Ok(true)
    }

    /// Whether the cost, the dynamics residuals and the states are finite.
    fn values_finite(&self) -> bool {
        self.cost.is_finite()
            && self
                .data
                .stages
                .iter()
                .all(|s| s.dyn_value().iter().all(|v| v.is_finite()))
            && self.data.init.value().iter().all(|v| v.is_finite())
    }

    /// The gaps of the current point from the data of its evaluation.
    fn read_gaps(&mut self, problem: &Problem) {
        problem.space(0).difference(&self.xs[0], &self.x0, &mut self.fs[0]);
        for (f, sd) in self.fs[1..].iter_mut().zip(&self.data.stages) {
            f.copy_from_slice(sd.dyn_value());
        }
    }

    /// Whether the current controls lie within their bounds (always without bounds).
    pub fn controls_within_bounds(&self) -> bool {
        let Some(b) = &self.bounds else {
            return true;
        };
        self.us.iter().enumerate().all(|(t, u)| {
            !b.bounded(t)
                || u.iter()
                    .zip(&b.lb[t])
                    .zip(&b.ub[t])
                    .all(|((v, lo), hi)| lo <= v && v <= hi)
        })
    }

    /// Largest gap (infinity norm) of the current point.
    pub fn max_gap(&self) -> f64 {
        self.fs.iter().map(|f| norm_inf(f)).fold(0.0, f64::max)
    }

    /// Fills the LQ knots at the current point: cost derivatives, dynamics Jacobians, the
    /// gaps unless they are closed, and the regularisation `reg` on `Q` (`V_xx`).
    pub fn build_lq(&mut self, problem: &Problem, reg: f64) {
        let n = problem.horizon();
        crate::linalg::copy(self.lq.G0.as_mut(), self.data.init.jx.as_ref());
        let g0 = slice_mut(&mut self.lq.g0);
        if self.feasible {
            g0.fill(0.0);
        } else {
            g0.copy_from_slice(self.data.init.value());
        }
        for t in 0..=n {
            let knot = &mut self.lq.knots[t];
            if t < n {
                let sd = &self.data.stages[t];
                copy_stage_model(knot, sd, true, true);
                slice_mut(&mut knot.q).copy_from_slice(sd.cost.lx());
                slice_mut(&mut knot.r).copy_from_slice(sd.cost.lu());
                let f = slice_mut(&mut knot.f);
                if self.feasible {
                    f.fill(0.0);
                } else {
                    f.copy_from_slice(sd.dyn_value());
                }
            } else {
                crate::linalg::copy(knot.Q.as_mut(), self.data.terminal_cost.lxx.as_ref());
                slice_mut(&mut knot.q).copy_from_slice(self.data.terminal_cost.lx());
            }
            if let Some(al) = &self.al {
                al.fill_knot(t, knot, self.data.constraint_data(t));
            }
            for i in 0..knot.nx {
                knot.Q[(i, i)] += reg;
            }
        }
        self.knot_reg = reg;
        self.knots_built = true;
    }

    /// Changes the regularisation on the knots' `Q` to `reg`.
    pub fn set_reg(&mut self, reg: f64) {
        let delta = reg - self.knot_reg;
        if delta == 0.0 {
            return;
        }
        self.knots_built = false;
        for knot in &mut self.lq.knots {
            for i in 0..knot.nx {
                knot.Q[(i, i)] += delta;
            }
        }
        self.knot_reg = reg;
    }

    /// Backward pass with the regularisation `reg` on `Q_uu`: the Riccati recursion, with
    /// the box QP as the control law of the bounded stages from the second iteration on,
    /// while the gaps are closed. The first step from a guess is the unconstrained one,
    /// clamped in the rollout (crocoddyl's behaviour from a guess it is not told is
    /// feasible): from far away, box-QP steps whose feedback the rollout clamps heavily
    /// are short. With the exact Hessian and closed gaps, each stage's Q-function gets
    /// the dynamics' second derivatives weighted by the next value gradient before its
    /// control law. While gaps are open the step is Gauss-Newton: the co-state
    /// `p + P f` that would weigh them grows with the regularisation on `P`, and a
    /// regularised pass could then never make `Q_uu` positive definite.
    pub fn backward(
        &mut self,
        problem: &Problem,
        reg: f64,
        qp_opts: &BoxQpOptions,
    ) -> std::result::Result<(), LqError> {
        self.lams_current = false;
        if self.square_root {
            self.qp_used.fill(false);
            return self.riccati.backward_square_root(&self.lq, reg);
        }
        let use_qp = self.feasible && self.iterated && self.bounds.is_some();
        let exact = self.exact && self.feasible;
        let factored_reg = self.factored_reg.take();
        if !use_qp {
            self.qp_used.fill(false);
            if !exact {
                return self.riccati_pass(reg, factored_reg);
            }
        }
        let bounds = self.bounds.as_ref().filter(|_| use_qp);
        let (qps, qp_used, us) = (&mut self.qps, &mut self.qp_used, &self.us);
        let (hbuf, kbuf, gain_buf) = (&mut self.hbuf, &mut self.kbuf, &mut self.gain_buf);
        let (dlb, dub) = (&mut self.dlb, &mut self.dub);
        let mut exact = exact.then_some((&mut self.data, &self.xs, &mut self.vx_next, &self.no_nus));
        let n = us.len();
        self.riccati.backward_with(&self.lq, |knot, st, next| {
            let t = st.index();
            if let (Some((data, xs, vx, nus)), Some(next)) = (exact.as_mut(), next) {
                add_dynamics_hessian(problem, data, st, next.1, (xs, us), &mut vx[t], &nus[t])?;
            }
            match bounds.filter(|b| t < n && b.bounded(t)) {
                None => {
                    if t < n {
                        qp_used[t] = false;
                    }
                    st.solve_kkt(knot, next.map(|p| p.0), reg)?;
                    st.solve_kkt_vectors(knot, next)
                }
                Some(bounds) => {
                    qp_used[t] = true;
                    for j in 0..us[t].len() {
                        dlb[t][j] = bounds.lb[t][j] - us[t][j];
                        dub[t][j] = bounds.ub[t][j] - us[t][j];
                    }
                    box_law(
                        st,
                        &mut qps[t],
                        &mut hbuf[t],
                        &mut kbuf[t],
                        &mut gain_buf[t],
                        &dlb[t],
                        &dub[t],
                        reg,
                        qp_opts,
                    )
                }
            }
        })
    }

    /// `Δ_g`, `Δ_q` of the expected improvement from the last backward pass with
    /// regularisation `reg`; with box QPs, the gradient `Q_u` of clamped controls is left
    /// out (crocoddyl zeroes it). Also returns the dual residual `max_t |Q_u|_∞`.
    pub fn expected(&mut self, reg: f64) -> (Expected, f64) {
        let stages = self.riccati.stages();
        let n = self.us.len();
        let mut e = Expected::default();
        let mut dual: f64 = 0.0;
        for t in 0..n {
            let st = &stages[t];
            let k = st.k();
            let knot = &self.lq.knots[t];
            let qu = if knot.nc > 0 {
                // The constraint rows' part of the augmented Q-function (23); `qu` is
                // its control gradient.
                let (dg, dq) = Augmented::condensed(knot, st, &mut self.wq[..k.len()]);
                e.dg += dg;
                e.dq += dq;
                &self.wq[..k.len()]
            } else {
                st.Q_u()
            };
            let w = &mut self.wu[..k.len()];
            matvec(w, Accum::Replace, st.Q_uu(), k, 1.0);
            e.dg -= dot(st.Q_u(), k);
            for j in 0..k.len() {
                if !self.qp_used[t] || self.qps[t].is_free(j) {
                    dual = dual.max(qu[j].abs());
                }
            }
            e.dq -= dot(w, k) + reg * dot(k, k);
        }
        if !self.feasible {
            for t in 0..=n {
                let st = &stages[t];
                matvec(&mut self.pfs[t], Accum::Replace, st.P(), &self.fs[t], 1.0);
                let (fs, pfs) = (&self.fs[t], &self.pfs[t]);
                if self.variant.multiple_shooting() {
                    e.dg -= dot(st.p(), fs) + dot(pfs, fs);
                    e.dq += dot(fs, pfs);
                }
            }
        }
        (e, dual)
    }

    /// The plain Riccati pass at regularisation `reg`: its vector part alone when the
    /// solver holds the factorization of these very matrices (`factored_reg`, on a
    /// linear-quadratic problem), the whole pass otherwise.
    fn riccati_pass(&mut self, reg: f64, factored_reg: Option<f64>) -> std::result::Result<(), LqError> {
        let same_matrices = self.lq_constant && self.knots_built;
        if same_matrices && factored_reg == Some(reg) {
            self.factored_reg = factored_reg;
            return self.riccati.backward_vectors(&self.lq);
        }
        self.riccati.backward(&self.lq, reg)?;
        self.factored_reg = same_matrices.then_some(reg);
        Ok(())
    }

    /// `(Δ₁, Δ₂)` of the last trial: FDDP's `Δ₁ = Δ_g + Δ_v`, `Δ₂ = Δ_q - 2Δ_v` with
    /// `Δ_v = Σ fs_tᵀ P_t (x̃_t ⊖ x_t)` while gaps are open, else `(Δ_g, Δ_q)`.
    pub fn model(&self, e: Expected) -> (f64, f64) {
        if self.feasible || !self.variant.multiple_shooting() {
            return (e.dg, e.dq);
        }
        // crocoddyl's dv = -Σ fsᵀ P (x ⊖ x̃), with x ⊖ x̃ = -(x̃ ⊖ x).
        let dv: f64 = self.pfs.iter().zip(&self.dx).map(|(p, d)| dot(p, d)).sum();
        (e.dg + dv, e.dq - 2.0 * dv)
    }

    /// The trial of step length `alpha` (crocoddyl's forward pass): controls
    /// `ũ = u + αk + K(x̃ ⊖ x)` (clamped into the bounds), next states by the dynamics,
    /// keeping the part `1 - α` of the gaps for FDDP while they are open; evaluates it and
    /// returns its cost, or `None` if the rollout fails or a value is not finite.
    pub fn trial(&mut self, problem: &Problem, alpha: f64, opts: &DdpOptions) -> Option<f64> {
        let n = problem.horizon();
        let keep_gaps = self.variant.multiple_shooting() && !self.feasible && alpha < 1.0;
        if keep_gaps {
            let v = &mut self.dx[0];
            for (vi, f) in v.iter_mut().zip(&self.fs[0]) {
                *vi = (alpha - 1.0) * f;
            }
            problem.space(0).integrate(&self.x0, v, &mut self.xs_try[0]);
        } else {
            self.xs_try[0].copy_from_slice(&self.x0);
        }
        let stages = self.riccati.stages();
        for (t, stage) in problem.stages().iter().enumerate() {
            let space = problem.space(t);
            space.difference(&self.xs[t], &self.xs_try[t], &mut self.dx[t]);
            let st = &stages[t];
            let u = &mut self.us_try[t];
            for (j, ui) in u.iter_mut().enumerate() {
                *ui = self.us[t][j] + alpha * st.k()[j];
            }
            matvec(u, Accum::Add, st.K(), &self.dx[t], 1.0);
            if let Some(b) = &self.bounds {
                for (j, ui) in u.iter_mut().enumerate() {
                    *ui = ui.max(b.lb[t][j]).min(b.ub[t][j]);
                }
            }
            let s = if keep_gaps {
                for (si, f) in self.shift[t].iter_mut().zip(&self.fs[t + 1]) {
                    *si = (1.0 - alpha) * f;
                }
                Some(&self.shift[t][..])
            } else {
                None
            };
            let (lo, hi) = self.xs_try.split_at_mut(t + 1);
            let y = &mut hi[0];
            if matches!(stage.dynamics, crate::dynamics::Dynamics::Implicit(_)) {
                // Newton-Raphson starts from the current state.
                y.copy_from_slice(&self.xs[t + 1]);
            }
            if !self.data.stages[t].rollout_step(stage, &lo[t], u, s, y, opts.implicit) {
                return None;
            }
        }
        problem
            .space(n)
            .difference(&self.xs[n], &self.xs_try[n], &mut self.dx[n]);
        let mut cost = self.data.evaluate_after_rollout(problem, &self.xs_try, &self.us_try);
        if let Some(al) = &mut self.al {
            cost += al.value(&self.data, Some(&self.dx));
        }
        cost.is_finite().then_some(cost)
    }

    /// SQP: the step of the LQ subproblem of the last backward pass (linear rollout of its
    /// gains through the linearised dynamics and gaps), into the LQ solution; its
    /// co-states become the multipliers of the next KKT test. `false` if it fails.
    pub fn linear_step(&mut self) -> bool {
        if self.riccati.forward(&self.lq, &mut self.lq_sol).is_err() {
            return false;
        }
        for (l, s) in self.lams.iter_mut().zip(&self.lq_sol.lambdas) {
            l.copy_from_slice(slice(s));
        }
        self.lams_current = true;
        true
    }

    /// SQP: whether the LQ step of the last backward pass was rolled out
    /// ([`Workspace::linear_step`]).
    pub fn has_step(&self) -> bool {
        self.lams_current
    }

    /// SQP's KKT residual (20) at the current point: the largest entry of the
    /// Lagrangian's gradient with the co-states of the last LQ step (returned first), and
    /// the residual, which also takes the gaps.
    pub fn kkt(&mut self, problem: &Problem) -> (f64, f64) {
        self.data
            .lagrangian_gradient(problem, &self.lams, &self.no_nus, &mut self.gx, &mut self.gu);
        let dual = self.gx.iter().chain(&self.gu).map(|g| norm_inf(g)).fold(0.0, f64::max);
        (dual, dual.max(self.max_gap()))
    }

    /// The sum of the gaps' 1-norms of the current point (SQP's filter measure).
    pub fn gap_l1(&self) -> f64 {
        self.fs.iter().flatten().map(|v| v.abs()).sum()
    }

    /// SQP's trial of step length `alpha`: `x̃ = x ⊕ α δx`, `ũ = u + α δu` from
    /// [`Workspace::linear_step`], evaluated; returns its cost and the 1-norm of its gaps,
    /// or `None` if a value is not finite.
    pub fn linear_trial(&mut self, problem: &Problem, alpha: f64) -> Option<(f64, f64)> {
        let trial = crate::solvers::skeleton::LinearTrial {
            xs: &self.xs,
            us: &self.us,
            step: &self.lq_sol,
        };
        trial.write(problem, alpha, &mut self.dx, &mut self.xs_try, &mut self.us_try);
        let cost = self.data.evaluate(problem, &self.xs_try, &self.us_try);
        if !self.values_finite() {
            return None;
        }
        Some((cost, self.trial_gap_l1(problem)))
    }

    /// The 1-norm of the gaps of the last trial (from the data's last evaluation).
    pub fn trial_gap_l1(&mut self, problem: &Problem) -> f64 {
        problem.space(0).difference(&self.xs_try[0], &self.x0, &mut self.wu_x0);
        let mut gap = self.wu_x0.iter().map(|v| v.abs()).sum::<f64>();
        for sd in &self.data.stages {
            gap += sd.dyn_value().iter().map(|v| v.abs()).sum::<f64>();
        }
        gap
    }

    /// Marks the end of an iteration (accepted step or not).
    pub fn end_iteration(&mut self) {
        self.iterated = true;
    }

    /// Makes the last trial (the data's last evaluation) the current point: derivatives,
    /// gaps; `alpha` is its step length. Returns `false` if a derivative is not finite.
    pub fn accept(&mut self, problem: &Problem, cost: f64, alpha: f64, gap_tol: f64) -> bool {
        std::mem::swap(&mut self.xs, &mut self.xs_try);
        std::mem::swap(&mut self.us, &mut self.us_try);
        self.cost = cost;
        if let Some(al) = &mut self.al {
            al.move_origin(&self.dx);
        }
        // A single-shooting trial is a rollout; a multiple-shooting one closes the gaps
        // at the full step (crocoddyl: `setCandidate(.., was_feasible || α == 1)`); SQP
        // reads them.
        self.feasible = !self.variant.multiple_shooting() || self.feasible || alpha == 1.0;
        self.data.compute_derivatives(problem, &self.xs, &self.us);
        self.read_gaps(problem);
        if self.variant.linear_rollout() {
            self.feasible = self.max_gap() <= gap_tol;
        }
        self.lq_derivatives_finite()
    }

    fn lq_derivatives_finite(&self) -> bool {
        self.data.stages.iter().all(|s| {
            crate::linalg::all_finite(s.dyn_jx.as_ref())
                && crate::linalg::all_finite(s.dyn_ju.as_ref())
                && s.cost.lx().iter().chain(s.cost.lu()).all(|v| v.is_finite())
        })
    }

    /// The co-states `λ` of the last backward pass (its LQ solution) and, with bounds, the
    /// multipliers of the bound rows, written into `lambdas` and `nus`.
    pub fn multipliers(&mut self, lambdas: &mut [Vec<f64>], nus: &mut [Vec<f64>]) {
        if self.lams_current {
            crate::solvers::skeleton::copy_trajectory(lambdas, &self.lams);
        } else if self.riccati.forward(&self.lq, &mut self.lq_sol).is_ok() {
            for (l, s) in lambdas.iter_mut().zip(&self.lq_sol.lambdas) {
                l.copy_from_slice(slice(s));
            }
        }
        nus.iter_mut().for_each(|v| v.fill(0.0));
        if let Some(b) = &mut self.bounds {
            for t in 0..self.us.len() {
                if !(self.qp_used[t] && b.bounded(t)) {
                    continue;
                }
                let qp = &self.qps[t];
                let g = qp.gradient_at_solution();
                // The bounds are on u + k: at the solution the step is about zero.
                b.multipliers(t, &self.us[t], |j| (!qp.is_free(j)).then(|| g[j]), &mut nus[t]);
            }
        }
    }
}

/// Classical DDP's second-order dynamics term of stage `t` (Tassa et al. 2012): with the
/// next value gradient `V_x' = p'` (the gaps are closed; the next state is in a vector
/// space, so `E = -I` and the co-state is `V_x'`), adds
/// `V_x'·[f_xx f_xu; f_ux f_uu]` to the Q-function's Hessian.
fn add_dynamics_hessian(
    problem: &Problem,
    data: &mut ProblemData,
    st: &mut RiccatiStage,
    p: &[f64],
    (xs, us): (&[Vec<f64>], &[Vec<f64>]),
    vx: &mut [f64],
    nu: &[f64],
) -> std::result::Result<(), LqError> {
    let t = st.index();
    vx.copy_from_slice(p);
    let sd = &mut data.stages[t];
    sd.second_order(&problem.stages()[t], &xs[t], &us[t], &xs[t + 1], vx, nu);
    let DynamicsData::Explicit(d) = &sd.dynamics else {
        unreachable!("setup refuses implicit dynamics with the exact Hessian")
    };
    st.add_q_hessian(d.vhp_xx.as_ref(), d.vhp_xu.as_ref(), d.vhp_uu.as_ref())
}

/// Box-DDP's control law at one knot (Tassa et al. 2014, Algorithm 2): the box QP on
/// `Q_uu + ρI`, `Q_u` within the bounds `dlb ≤ k ≤ dub`, warm-started from the last
/// step; `k` its solution, `K = -H_ff⁻¹ Q_fx` on the free controls and 0 on the clamped
/// ones; the value function of these gains.
#[allow(clippy::too_many_arguments)]
fn box_law(
    st: &mut RiccatiStage,
    qp: &mut BoxQp,
    h: &mut Mat<f64>,
    k: &mut [f64],
    gain: &mut Mat<f64>,
    dlb: &[f64],
    dub: &[f64],
    reg: f64,
    opts: &BoxQpOptions,
) -> std::result::Result<(), LqError> {
    crate::linalg::copy(h.as_mut(), st.Q_uu());
    for i in 0..h.nrows() {
        h[(i, i)] += reg;
    }
    let r = qp.solve(h.as_ref(), st.Q_u(), dlb, dub, k, opts);
    if r.is_err() {
        return Err(LqError::Singular {
            knot: st.index(),
            system: "box-QP Hessian Q_uu + reg I on the free controls",
        });
    }
    crate::linalg::copy(gain.as_mut(), st.Q_xu().transpose());
    qp.apply_free_inverse_negated(gain.as_mut());
    st.value_from_gains(k, gain.as_ref())
}

/// The checks of [`Workspace::new`] on what the variant `opts.variant` takes (a queue for
/// receding horizons, constraints, the exact Hessian), and its control bounds.
fn checked_bounds(
    problem: &Problem,
    opts: &DdpOptions,
    queue: Option<&[StageModel]>,
    has_al: bool,
) -> Result<Option<ControlBounds>> {
    let (variant, name) = (opts.variant, opts.variant.name());
    if let Some(q) = queue {
        Receding::of(problem, q)?;
    }
    let queue = queue.unwrap_or(&[]);
    let bounds = if variant.control_bounds() {
        Some(ControlBounds::new(problem, queue, name)?)
    } else {
        if !has_al {
            check_unconstrained(problem, queue, name)?;
        }
        None
    };
    if opts.hessian == HessianApprox::Exact {
        check_exact_hessian(problem, queue, variant)?;
        if opts.square_root {
            return Err(Error::option(
                "square_root",
                format!("{name}: the square-root pass takes the Gauss-Newton Hessian only"),
            ));
        }
    }
    Ok(bounds)
}

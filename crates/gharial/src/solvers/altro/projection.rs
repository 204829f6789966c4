//! The objective-weighted Newton projection of ALTRO (Algorithm 2, with the line search of
//! Algorithm 3): from the coarse AL-iLQR solution, Newton steps onto the manifold of the
//! dynamics and the active constraints, in the metric of the objective's Hessian `H`.
//!
//! One step solves `min ½δYᵀHδY s.t. DδY = -d` (Algorithm 3, line 4:
//! `δY = -H⁻¹Dᵀ(DH⁻¹Dᵀ)⁻¹d`), which is an LQ problem with the structure of the horizon:
//! the knots hold the cost Hessians (no gradient), the dynamics Jacobians with the gaps as
//! offsets, and the active constraint rows with a tiny regularisation (`mu_c = 1e-10`, a
//! penalty of `1e10`, which the square-root pass carries without loss; III-A). It is solved
//! by the LQ kernels instead of forming `DH⁻¹Dᵀ` (the "sequential" implementation the
//! paper mentions). Active rows: those where the normal-cone projection at
//! `y = c + λ/μ` (the AL multipliers) is the identity (equalities, bounds at which the
//! multiplier pushes), with the target `c = proj_K(y)`, and those violated at the current
//! point, with the target `proj_K(c)`. The step is taken with
//! `α = 1, 1/2, ...` until the violation `v = max(|gaps|, c_max)` decreases
//! (Algorithm 3), and the Jacobians are relinearised at every step (the paper reuses
//! them while the convergence rate `log v⁺/log v` stays high).

use std::sync::Arc;

use super::al_cost::AlCost;
use crate::constraints::ConstraintSet;
use crate::linalg::{self, slice, slice_mut};
use crate::lq::{LqProblem, LqSolution, RiccatiSolver};
use crate::problem::{Problem, ProblemData};
use crate::solvers::skeleton::{LinearTrial, copy_stage_model, copy_trajectory, lq_for};

/// Regularisation of the active rows in the projection's LQ problem.
const MU_ACTIVE: f64 = 1e-10;

/// Range of the primal regularisation of the projection's metric when `H` alone fails.
const PREG_MIN: f64 = 1e-9;
const PREG_MAX: f64 = 1e-3;

/// Workspace of the projection, allocated in `setup`.
pub(super) struct Projection {
    lq: LqProblem,
    riccati: RiccatiSolver,
    step: LqSolution,
    /// Whether every knot has `E = -I` (the square-root pass applies).
    square_root: bool,
    xs_try: Vec<Vec<f64>>,
    us_try: Vec<Vec<f64>>,
    dx: Vec<Vec<f64>>,
    y: Vec<f64>,
    p: Vec<f64>,
    pc: Vec<f64>,
    unit: Vec<f64>,
    probe: Vec<f64>,
}

impl Projection {
    pub(super) fn new(problem: &Problem, square_root: bool) -> crate::Result<Self> {
        let lq = lq_for(problem, true, None);
        let nr = (0..=problem.horizon())
            .flat_map(|t| problem.constraints(t).iter().map(|c| c.nr()))
            .max()
            .unwrap_or(0);
        let sol = crate::solvers::Solution::new(problem, 0);
        Ok(Self {
            riccati: RiccatiSolver::with_square_root(&lq)?,
            step: LqSolution::new(&lq),
            lq,
            square_root,
            dx: sol.xs.iter().map(|x| vec![0.0; x.len().max(1)]).collect(),
            xs_try: sol.xs.clone(),
            us_try: sol.us,
            y: vec![0.0; nr],
            p: vec![0.0; nr],
            pc: vec![0.0; nr],
            unit: vec![0.0; nr],
            probe: vec![0.0; 2 * nr],
        })
    }

    /// Projects `(xs, us)` until the violation is at most `tol` or `max_steps` steps were
    /// taken or a step fails; returns the violation reached. `costs` hold the AL
    /// multipliers and penalties that decide the active set.
    pub(super) fn run(
        &mut self,
        problem: &Problem,
        data: &mut ProblemData,
        costs: &[Arc<AlCost>],
        xs: &mut [Vec<f64>],
        us: &mut [Vec<f64>],
        tol: f64,
        max_steps: usize,
    ) -> f64 {
        data.evaluate(problem, xs, us);
        let mut v = violation(problem, data);
        for _ in 0..max_steps {
            if v <= tol || !v.is_finite() {
                break;
            }
            data.compute_derivatives(problem, xs, us);
            self.fill(problem, data, costs, false);
            if self.solve_lq().is_err() {
                break;
            }
            // Algorithm 3: halve the step until the violation decreases.
            let mut accepted = false;
            let mut alpha = 1.0;
            for _ in 0..10 {
                let trial = LinearTrial {
                    xs,
                    us,
                    step: &self.step,
                };
                trial.write(problem, alpha, &mut self.dx, &mut self.xs_try, &mut self.us_try);
                data.evaluate(problem, &self.xs_try, &self.us_try);
                let v_try = violation(problem, data);
                if v_try < v {
                    v = v_try;
                    accepted = true;
                    break;
                }
                alpha *= 0.5;
            }
            if !accepted {
                data.evaluate(problem, xs, us);
                break;
            }
            copy_trajectory(xs, &self.xs_try);
            copy_trajectory(us, &self.us_try);
        }
        v
    }

    /// The multipliers of the projected point `(xs, us)`: the projection's KKT system with
    /// the cost gradient `g` added, `min ½δYᵀHδY + gᵀδY s.t. DδY = -d`, whose multipliers
    /// `(λ, ν)` (the dynamics co-states and the active rows'; 0 on the inactive rows)
    /// satisfy `g + Dᵀ(λ, ν) = -HδY`: at a feasible point that the AL-iLQR solution put
    /// next to the optimum, `δY` is the small step left to it, so that `(λ, ν)` certify
    /// stationarity to `|HδY|` (the multipliers of the SQP step on the active set). The
    /// step itself is discarded. Returns false, leaving `lambdas` and `nus`, if the
    /// LQ solve fails.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn multipliers(
        &mut self,
        problem: &Problem,
        data: &mut ProblemData,
        costs: &[Arc<AlCost>],
        xs: &[Vec<f64>],
        us: &[Vec<f64>],
        lambdas: &mut [Vec<f64>],
        nus: &mut [Vec<f64>],
    ) -> bool {
        data.evaluate(problem, xs, us);
        data.compute_derivatives(problem, xs, us);
        self.fill(problem, data, costs, true);
        if self.solve_lq().is_err() {
            return false;
        }
        for (l, s) in lambdas.iter_mut().zip(&self.step.lambdas) {
            l.copy_from_slice(slice(s));
        }
        for (n, s) in nus.iter_mut().zip(&self.step.nus) {
            n.copy_from_slice(slice(s));
        }
        true
    }

    /// The backward and forward passes of the projection's LQ problem into `step`. The
    /// metric is the objective's Hessian `H`; where the plain pass loses its inertia with
    /// it (the square-root pass needs `E = -I`: not on Lie groups), `H + ρI` for the
    /// smallest `ρ = 1e-9, 1e-8, ..., 1e-3` that passes (any positive-definite metric
    /// gives a projection onto the same constraint manifold).
    fn solve_lq(&mut self) -> Result<(), crate::lq::LqError> {
        let mut rho = 0.0;
        loop {
            let pass = if self.square_root {
                self.riccati.backward_square_root(&self.lq, rho)
            } else {
                self.riccati.backward(&self.lq, rho)
            };
            match pass {
                Ok(()) => break,
                Err(e) if rho >= PREG_MAX => return Err(e),
                Err(_) => rho = if rho == 0.0 { PREG_MIN } else { 10.0 * rho },
            }
        }
        self.riccati.forward(&self.lq, &mut self.step)
    }

    /// The knots of one projection step at the point of `data`'s last derivatives; with
    /// `gradient`, the cost gradient as the linear terms (otherwise none: Algorithm 3).
    fn fill(&mut self, problem: &Problem, data: &ProblemData, costs: &[Arc<AlCost>], gradient: bool) {
        let n = problem.horizon();
        linalg::copy(self.lq.G0.as_mut(), data.init.jx.as_ref());
        slice_mut(&mut self.lq.g0).copy_from_slice(slice(&data.init.value));
        for t in 0..=n {
            let knot = &mut self.lq.knots[t];
            if t < n {
                let sd = &data.stages[t];
                copy_stage_model(knot, sd, true, true);
                slice_mut(&mut knot.f).copy_from_slice(sd.dyn_value());
            } else {
                linalg::copy(knot.Q.as_mut(), data.terminal_cost.lxx.as_ref());
            }
            let (q, r) = match (gradient, data.stages.get(t)) {
                (false, _) => (None, None),
                (true, Some(sd)) => (Some(sd.cost.lx()), Some(sd.cost.lu())),
                (true, None) => (Some(data.terminal_cost.lx()), None),
            };
            match q {
                Some(g) => slice_mut(&mut knot.q).copy_from_slice(g),
                None => slice_mut(&mut knot.q).fill(0.0),
            }
            match r {
                Some(g) => slice_mut(&mut knot.r).copy_from_slice(g),
                None => slice_mut(&mut knot.r).fill(0.0),
            }
            let mut row = 0;
            for (k, (c, cd)) in problem.constraints(t).iter().zip(data.constraint_data(t)).enumerate() {
                let m = c.nr();
                let mu = costs[t].mu.get(k);
                let (y, p, unit) = (&mut self.y[..m], &mut self.p[..m], &mut self.unit[..m]);
                let pc = &mut self.pc[..m];
                let cv = slice(&cd.value);
                for i in 0..m {
                    y[i] = cv[i] + costs[t].lambda_of(k, i) / mu;
                }
                c.set.project(y, 1.0 / mu, p);
                c.set.project(cv, 1.0 / mu, pc);
                for i in 0..m {
                    unit.fill(0.0);
                    unit[i] = 1.0;
                    c.set.apply_normal_cone_jacobian_vec(y, 1.0 / mu, unit);
                    // Active: pushed by its multiplier (target proj_K(y)), or violated at
                    // the current point (target proj_K(c)).
                    // With the gradient, also the rows on the boundary: the AL multipliers
                    // of a coarse solve may not know yet that they are active.
                    let boundary = gradient && on_boundary(c.set.as_ref(), cv, i, &mut self.probe[..2 * m]);
                    if unit[i] <= 0.5 && (cv[i] != pc[i] || boundary) {
                        p[i] = pc[i];
                        unit[i] = 1.0;
                    }
                    let active = unit[i] > 0.5;
                    for j in 0..knot.nx {
                        knot.C[(row + i, j)] = if active { cd.jx[(i, j)] } else { 0.0 };
                    }
                    for j in 0..knot.nu {
                        knot.D[(row + i, j)] = if active { cd.ju[(i, j)] } else { 0.0 };
                    }
                    knot.d[row + i] = if active { cv[i] - p[i] } else { 0.0 };
                    knot.mu_c[row + i] = if active { MU_ACTIVE } else { 1.0 };
                }
                row += m;
            }
        }
    }
}

/// Distance at which a row counts as on the boundary of its set (see `on_boundary`).
const BOUNDARY_PROBE: f64 = 1e-5;

/// Whether row `i` of `c` is on the boundary of `set`: moving it by `±BOUNDARY_PROBE`
/// puts it where the normal-cone Jacobian of the projection is the identity in that row
/// (outside the set). `scratch` holds twice the rows.
fn on_boundary(set: &dyn ConstraintSet, c: &[f64], i: usize, scratch: &mut [f64]) -> bool {
    let (probe, v) = scratch.split_at_mut(c.len());
    for side in [1.0, -1.0] {
        probe.copy_from_slice(c);
        probe[i] += side * BOUNDARY_PROBE;
        v.fill(0.0);
        v[i] = 1.0;
        set.apply_normal_cone_jacobian_vec(probe, 1.0, v);
        if v[i] > 0.5 {
            return true;
        }
    }
    false
}

/// `max(|gaps|_∞, c_max)` at the point of `data`'s last evaluation.
pub(super) fn violation(problem: &Problem, data: &ProblemData) -> f64 {
    let mut v = linalg::norm_inf(slice(&data.init.value));
    for sd in &data.stages {
        v = linalg::max_nan(v, linalg::norm_inf(sd.dyn_value()));
    }
    for t in 0..=problem.horizon() {
        for (c, cd) in problem.constraints(t).iter().zip(data.constraint_data(t)) {
            v = linalg::max_nan(
                v,
                crate::constraints::violation_or_nan(c.set.as_ref(), slice(&cd.value)),
            );
        }
    }
    v
}

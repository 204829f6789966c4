//! Evaluation of a [`Problem`]: values, first and second derivatives of every stage,
//! serial or stage-parallel (a team of threads, `crate::team`), with identical results.

use std::sync::Arc;

use faer::{Accum, Col, Mat, MatRef};

use super::{InitialCondition, Problem, StageConstraint, StageModel};
use crate::costs::CostData;
use crate::dynamics::{Dynamics, ExplicitDynamicsData, ImplicitDynamics, ImplicitDynamicsData};
use crate::error::{Error, Result, check_dim, check_finite};
use crate::functions::StageFunctionData;
use crate::linalg::{identity_block, matmul_identity_block, matvec_t, slice, slice_mut};
use crate::spaces::{Arg, Manifold};
use crate::team::{PassKind, Team, for_each_indexed};

/// What the dynamics model of a stage writes.
// One per stage, allocated once: the size difference between the variants is irrelevant.
#[allow(clippy::large_enum_variant)]
#[derive(Debug)]
pub enum DynamicsData {
    /// Data of an explicit model `y = φ(x, u)`; `xnext` holds `φ(x, u)`.
    Explicit(ExplicitDynamicsData),
    /// Data of an implicit model `f(x, u, y) = 0`.
    Implicit(ImplicitDynamicsData),
}

/// Everything an evaluation of stage `t` writes.
///
/// The dynamics are always exposed in implicit form `f(x, u, y)` with values in the
/// tangent space of `y`: for explicit dynamics `f = φ(x, u) ⊖ y`, so that every solver
/// reads the same fields.
#[derive(Debug)]
pub struct StageData {
    /// Cost value and derivatives.
    pub cost: CostData,
    /// The dynamics model's own data.
    pub dynamics: DynamicsData,
    /// `f(x, u, y)` (`ndx_next`).
    pub dyn_value: Col<f64>,
    /// `df/dx` (`ndx_next x ndx`).
    pub dyn_jx: Mat<f64>,
    /// `df/du` (`ndx_next x nu`).
    pub dyn_ju: Mat<f64>,
    /// `df/dy` (`ndx_next x ndx_next`); `-I` for explicit dynamics on vector spaces.
    pub dyn_jy: Mat<f64>,
    /// Whether `dyn_jy` is `-I` at every point (explicit dynamics on a vector space), so
    /// that products with it reduce to negations.
    pub dyn_jy_is_minus_identity: bool,
    /// `dyn_jy` is `-I` outside its leading `dyn_jy_block × dyn_jy_block` block: the next
    /// space's [`nonlinear_dim`](crate::spaces::Manifold::nonlinear_dim) for explicit
    /// dynamics (0 when `dyn_jy = -I`), `ndx_next` (no structure) for implicit ones.
    pub dyn_jy_block: usize,
    /// One data object per path constraint, in the stage's order.
    pub constraints: Vec<StageFunctionData>,
    /// Per path constraint: whether its `jx` is constant and zero (a constraint on the
    /// controls only), so that products with it can be skipped.
    constraint_jx_zero: Vec<bool>,
    /// `d(φ ⊖ y)/dφ` for explicit dynamics (scratch; not written at a closed gap).
    jdiff_phi: Mat<f64>,
    /// Whether the last derivatives were taken at a closed gap, `y = φ(x, u)` bit for
    /// bit: `d(φ ⊖ y)/dφ = I` and `E = -I` there.
    pub(crate) gap_closed: bool,
    /// Scratch for the co-state mapped through `jdiff_phi`.
    lambda_phi: Vec<f64>,
    /// Scratch of the next-state solve ([`StageData::solve_next_state`]).
    next: NextStateScratch,
    /// The [`ProblemData`] generation in which the derivative blocks that this stage's
    /// models declare constant were written (`None`: never): they hold their values if
    /// it is the current one. It travels with the data when the horizon shifts, as the
    /// data travel with their models.
    constants_generation: Option<u64>,
}

/// Settings of the Newton-Raphson solve of implicit dynamics for the next state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImplicitSolve {
    /// Newton iterations at most.
    pub max_iters: usize,
    /// Converged when `|f(x, u, y) - s|_∞ <= tol (1 + |s|_∞)`.
    pub tol: f64,
}

impl Default for ImplicitSolve {
    fn default() -> Self {
        Self {
            max_iters: 20,
            tol: 1e-12,
        }
    }
}

/// Buffers of [`StageData::solve_next_state`]: the negated shift, and for implicit
/// dynamics the LU factorization of `df/dy`, the Newton step and the updated state.
#[derive(Debug)]
struct NextStateScratch {
    shift: Vec<f64>,
    lu: Option<crate::linalg::Lu>,
    step: Vec<f64>,
    ynew: Vec<f64>,
}

/// Step halvings at most per Newton iteration of [`NextStateScratch::newton`].
const MAX_HALVINGS: usize = 10;

impl NextStateScratch {
    /// Newton-Raphson for `f(x, u, y) = s` (`-s` in `shift`) from `y`, damped: a step is
    /// halved (up to [`MAX_HALVINGS`] times) until it decreases `|f - s|²`, so that a full
    /// step far outside the model's linearisation (stiff contact dynamics and a large
    /// `dt`) cannot carry `y` to a spurious root; full steps that decrease it are taken
    /// as they are. `false` without convergence within `solve`. The data hold the
    /// evaluation at the returned `y`.
    fn newton(
        &mut self,
        m: &dyn ImplicitDynamics,
        d: &mut ImplicitDynamicsData,
        sn: &dyn Manifold,
        (x, u): (&[f64], &[f64]),
        y: &mut [f64],
        solve: ImplicitSolve,
    ) -> bool {
        let lu = self.lu.as_mut().expect("LU allocated for implicit stages");
        let tol = solve.tol * (1.0 + crate::linalg::norm_inf(&self.shift));
        let (mut err, mut sq) = shifted_residual(m, d, &self.shift, (x, u), y);
        for _ in 0..solve.max_iters {
            if !err.is_finite() {
                return false;
            }
            if err <= tol {
                return true;
            }
            m.jacobians(x, u, y, d);
            if lu.factor(d.jy.as_ref()).is_err() {
                return false;
            }
            self.step.copy_from_slice(d.value());
            lu.solve_in_place(crate::linalg::as_mat_mut(&mut self.step));
            self.step.iter_mut().for_each(|v| *v = -*v);
            let mut accepted = false;
            for _ in 0..=MAX_HALVINGS {
                sn.integrate(y, &self.step, &mut self.ynew);
                let (e, q) = shifted_residual(m, d, &self.shift, (x, u), &self.ynew);
                if q < sq {
                    y.copy_from_slice(&self.ynew);
                    (err, sq, accepted) = (e, q, true);
                    break;
                }
                self.step.iter_mut().for_each(|v| *v *= 0.5);
            }
            if !accepted {
                return false;
            }
        }
        false
    }
}

/// `f(x, u, y) + shift` in the data's value (`shift = -s`), and its largest entry and
/// squared norm (NaN when not finite).
fn shifted_residual(
    m: &dyn ImplicitDynamics,
    d: &mut ImplicitDynamicsData,
    shift: &[f64],
    (x, u): (&[f64], &[f64]),
    y: &[f64],
) -> (f64, f64) {
    m.evaluate(x, u, y, d);
    let (mut err, mut sq): (f64, f64) = (0.0, 0.0);
    for (ri, si) in d.value_mut().iter_mut().zip(shift) {
        *ri += si;
        err = err.max(ri.abs());
        sq += *ri * *ri;
    }
    if !sq.is_finite() {
        return (f64::NAN, f64::NAN);
    }
    (err, sq)
}

impl StageData {
    /// Whether the state Jacobian of path constraint `k` is constant and zero (known
    /// after the first [`ProblemData::compute_derivatives`]).
    pub fn constraint_jx_is_zero(&self, k: usize) -> bool {
        self.constraint_jx_zero[k]
    }

    /// The data of `stage`, allocated once (for receding horizons: the data of a stage
    /// that will enter the horizon, see [`ProblemData::shift`]).
    /// Models of the stage that ask for the same shared data get one object
    /// ([`crate::functions::shared_data`]).
    pub fn new(stage: &StageModel) -> Self {
        crate::functions::with_shared_data(|| Self::create(stage))
    }

    fn create(stage: &StageModel) -> Self {
        let (s, sn) = (stage.space(), stage.space_next());
        let (ndx, ndx2, nu) = (s.ndx(), sn.ndx(), stage.nu());
        let dynamics = match &stage.dynamics {
            Dynamics::Explicit(d) => DynamicsData::Explicit(d.create_data()),
            Dynamics::Implicit(d) => DynamicsData::Implicit(d.create_data()),
        };
        let mut dyn_jy = Mat::zeros(ndx2, ndx2);
        for i in 0..ndx2 {
            dyn_jy[(i, i)] = -1.0;
        }
        let dyn_jy_is_minus_identity = matches!(stage.dynamics, Dynamics::Explicit(_)) && sn.is_vector_space();
        let dyn_jy_block = match stage.dynamics {
            Dynamics::Explicit(_) if dyn_jy_is_minus_identity => 0,
            Dynamics::Explicit(_) => sn.nonlinear_dim(),
            Dynamics::Implicit(_) => ndx2,
        };
        Self {
            cost: stage.cost.create_data(),
            dynamics,
            dyn_value: Col::zeros(ndx2),
            dyn_jx: Mat::zeros(ndx2, ndx),
            dyn_ju: Mat::zeros(ndx2, nu),
            dyn_jy,
            dyn_jy_is_minus_identity,
            dyn_jy_block,
            constraints: stage.constraints().iter().map(|c| c.func.create_data()).collect(),
            constraint_jx_zero: vec![false; stage.constraints().len()],
            jdiff_phi: Mat::identity(ndx2, ndx2),
            gap_closed: false,
            lambda_phi: vec![0.0; ndx2],
            next: NextStateScratch {
                shift: vec![0.0; ndx2],
                lu: matches!(stage.dynamics, Dynamics::Implicit(_)).then(|| crate::linalg::Lu::new(ndx2, 1)),
                step: vec![0.0; ndx2],
                ynew: vec![0.0; sn.nx()],
            },
            constants_generation: None,
        }
    }

    /// The next state of a rollout: `y` with `f(x, u, y) = s` (the shifted dynamics of
    /// multiple-shooting steps; `s = None` for a plain rollout, `s = 0`). Explicit dynamics give
    /// `y = φ(x, u) ⊕ (-s)` directly; implicit dynamics are solved by Newton-Raphson from
    /// the `y` passed in. Returns `false` if the state is not finite or the Newton
    /// iterations do not converge. This is the one solve of the dynamics for the next
    /// state that every solver's rollout and [`ProblemData::rollout`] use.
    pub fn solve_next_state(
        &mut self,
        stage: &StageModel,
        x: &[f64],
        u: &[f64],
        s: Option<&[f64]>,
        y: &mut [f64],
        solve: ImplicitSolve,
    ) -> bool {
        let sn = stage.space_next();
        let scratch = &mut self.next;
        match s {
            Some(s) => {
                for (n, si) in scratch.shift.iter_mut().zip(s) {
                    *n = -*si;
                }
            }
            None => scratch.shift.fill(0.0),
        }
        match (&stage.dynamics, &mut self.dynamics) {
            (Dynamics::Explicit(m), DynamicsData::Explicit(d)) => {
                m.forward(x, u, d);
                if s.is_some() {
                    // φ ⊖ y = s  ⇔  y = φ ⊕ (-s)
                    sn.integrate(d.xnext(), &scratch.shift, y);
                } else {
                    y.copy_from_slice(d.xnext());
                }
            }
            (Dynamics::Implicit(m), DynamicsData::Implicit(d)) => {
                if !scratch.newton(m.as_ref(), d, sn.as_ref(), (x, u), y, solve) {
                    return false;
                }
            }
            _ => unreachable!("stage data created for another dynamics kind"),
        }
        y.iter().all(|v| v.is_finite())
    }

    /// One stage of a rollout: the next state `y` as in [`StageData::solve_next_state`],
    /// then the dynamics residual at `(x, u, y)` as [`ProblemData::evaluate`] writes it,
    /// with explicit dynamics evaluated once. Returns `false` as `solve_next_state` does;
    /// finish the evaluation of the trajectory (costs and constraints, stage-parallel)
    /// with [`ProblemData::evaluate_after_rollout`].
    pub fn rollout_step(
        &mut self,
        stage: &StageModel,
        x: &[f64],
        u: &[f64],
        s: Option<&[f64]>,
        y: &mut [f64],
        solve: ImplicitSolve,
    ) -> bool {
        if !self.solve_next_state(stage, x, u, s, y, solve) {
            return false;
        }
        match (&stage.dynamics, &self.dynamics) {
            (Dynamics::Explicit(_), DynamicsData::Explicit(d)) => {
                // φ(x, u) is in the data already: only the residual f = φ ⊖ y is left.
                stage
                    .space_next()
                    .difference(y, d.xnext(), slice_mut(&mut self.dyn_value));
            }
            _ => self.evaluate_dynamics(stage, x, u, y),
        }
        true
    }

    /// `f(x, u, y)` as a slice.
    pub fn dyn_value(&self) -> &[f64] {
        slice(&self.dyn_value)
    }

    /// For explicit dynamics, `φ(x, u)` (the next state of a nonlinear rollout).
    pub fn xnext(&self) -> Option<&[f64]> {
        match &self.dynamics {
            DynamicsData::Explicit(d) => Some(d.xnext()),
            DynamicsData::Implicit(_) => None,
        }
    }

    fn evaluate(&mut self, stage: &StageModel, x: &[f64], u: &[f64], y: &[f64]) -> f64 {
        self.evaluate_dynamics(stage, x, u, y);
        self.evaluate_cost_and_constraints(stage, x, u)
    }

    /// Cost and constraint values at `(x, u)`; returns the cost.
    fn evaluate_cost_and_constraints(&mut self, stage: &StageModel, x: &[f64], u: &[f64]) -> f64 {
        stage.cost.evaluate(x, u, &mut self.cost);
        for (c, cd) in stage.constraints().iter().zip(self.constraints.iter_mut()) {
            c.func.evaluate(x, u, cd);
        }
        self.cost.value
    }

    /// The dynamics residual `f(x, u, y)` (21b).
    fn evaluate_dynamics(&mut self, stage: &StageModel, x: &[f64], u: &[f64], y: &[f64]) {
        match (&stage.dynamics, &mut self.dynamics) {
            (Dynamics::Explicit(m), DynamicsData::Explicit(d)) => {
                m.forward(x, u, d);
                // (21b) for explicit dynamics: f = φ(x, u) ⊖ y.
                stage
                    .space_next()
                    .difference(y, d.xnext(), slice_mut(&mut self.dyn_value));
            }
            (Dynamics::Implicit(m), DynamicsData::Implicit(d)) => {
                m.evaluate(x, u, y, d);
                slice_mut(&mut self.dyn_value).copy_from_slice(slice(&d.value));
            }
            _ => unreachable!("stage data created for another dynamics kind"),
        }
    }

    /// With `reuse`, the blocks that the models declare constant hold the values of an
    /// earlier call and only the varying ones are computed.
    fn derivatives(&mut self, stage: &StageModel, x: &[f64], u: &[f64], y: &[f64], reuse: bool) {
        stage.cost.derivatives_reusing(x, u, &mut self.cost, reuse);
        for ((c, cd), zero) in stage
            .constraints()
            .iter()
            .zip(self.constraints.iter_mut())
            .zip(self.constraint_jx_zero.iter_mut())
        {
            let constant = c.func.jacobians_are_constant();
            if !(reuse && constant) {
                c.func.jacobians(x, u, cd);
                *zero = constant && crate::linalg::norm_max(cd.jx.as_ref()) == 0.0;
            }
        }
        if reuse && stage.dynamics.jacobians_are_constant() {
            return;
        }
        match (&stage.dynamics, &mut self.dynamics) {
            (Dynamics::Explicit(m), DynamicsData::Explicit(d)) => {
                m.jacobians(x, u, d);
                let sn = stage.space_next();
                // `y ⊖ y = 0` for every `y` and the retraction's differential at 0 is the
                // identity, so at a closed gap the difference's Jacobians are exactly `I`
                // (in `φ`) and `-I` (in `y`): `E = -I`, the Riccati stage's fast path.
                self.gap_closed = !sn.is_vector_space() && y == d.xnext();
                if sn.is_vector_space() || self.gap_closed {
                    crate::linalg::copy(self.dyn_jx.as_mut(), d.jx.as_ref());
                    crate::linalg::copy(self.dyn_ju.as_mut(), d.ju.as_ref());
                    if self.gap_closed {
                        crate::spaces::set_identity(self.dyn_jy.as_mut(), -1.0);
                    }
                } else {
                    // f = φ ⊖ y: df/dx = J_φ φ_x, df/du = J_φ φ_u, df/dy = d(φ ⊖ y)/dy;
                    // J_φ is the identity outside the space's nonlinear block.
                    // Only its block: the rest stays the identity written at creation.
                    let k = sn.nonlinear_dim();
                    let block = self.jdiff_phi.as_mut().submatrix_mut(0, 0, k, k);
                    sn.jdifference_block(y, d.xnext(), Arg::Second, block);
                    let jp = self.jdiff_phi.as_ref();
                    debug_assert!(identity_block(jp, 1.0) <= k, "{sn:?}: nonlinear_dim");
                    matmul_identity_block(self.dyn_jx.as_mut(), jp, d.jx.as_ref(), k);
                    matmul_identity_block(self.dyn_ju.as_mut(), jp, d.ju.as_ref(), k);
                    // Its block too: outside it `dyn_jy` is the `-I` written at creation
                    // (or by a closed gap).
                    let block = self.dyn_jy.as_mut().submatrix_mut(0, 0, k, k);
                    sn.jdifference_block(y, d.xnext(), Arg::First, block);
                }
            }
            (Dynamics::Implicit(m), DynamicsData::Implicit(d)) => {
                m.jacobians(x, u, y, d);
                crate::linalg::copy(self.dyn_jx.as_mut(), d.jx.as_ref());
                crate::linalg::copy(self.dyn_ju.as_mut(), d.ju.as_ref());
                crate::linalg::copy(self.dyn_jy.as_mut(), d.jy.as_ref());
            }
            _ => unreachable!("stage data created for another dynamics kind"),
        }
    }

    pub(crate) fn second_order(
        &mut self,
        stage: &StageModel,
        x: &[f64],
        u: &[f64],
        y: &[f64],
        lambda: &[f64],
        nu: &[f64],
    ) {
        match (&stage.dynamics, &mut self.dynamics) {
            (Dynamics::Explicit(m), DynamicsData::Explicit(d)) => {
                if m.has_vhp() {
                    // λᵀ(φ ⊖ y) ≈ (J_φᵀ λ)ᵀ ψ to second order in (x, u); exact when y = φ.
                    if stage.space_next().is_vector_space() || self.gap_closed {
                        self.lambda_phi.copy_from_slice(lambda);
                    } else {
                        matvec_t(
                            &mut self.lambda_phi,
                            Accum::Replace,
                            self.jdiff_phi.as_ref(),
                            lambda,
                            1.0,
                        );
                    }
                    m.vhp(x, u, &self.lambda_phi, d);
                }
            }
            (Dynamics::Implicit(m), DynamicsData::Implicit(d)) => {
                if m.has_vhp() {
                    m.vhp(x, u, y, lambda, d);
                }
            }
            _ => unreachable!("stage data created for another dynamics kind"),
        }
        let mut off = 0;
        for (c, cd) in stage.constraints().iter().zip(self.constraints.iter_mut()) {
            let nr = c.nr();
            if c.func.has_vhp() {
                c.func.vhp(x, u, &nu[off..off + nr], cd);
            }
            off += nr;
        }
    }
}

/// Everything an evaluation of a [`Problem`] writes, allocated once.
pub struct ProblemData {
    /// Stage data, `t = 0..N`.
    pub stages: Vec<StageData>,
    /// Terminal cost data.
    pub terminal_cost: CostData,
    /// Terminal constraint data.
    pub terminal_constraints: Vec<StageFunctionData>,
    /// Initial constraint: value `x_0 ⊖ x̂` (or `ω(x_0)`) and its Jacobian `jx`.
    pub init: StageFunctionData,
    /// Total cost of the last evaluation.
    pub cost: f64,
    /// Whether the terminal models' constant derivative blocks have been written since
    /// the data was made or last invalidated.
    constants_written: bool,
    /// Incremented by every invalidation of the constant blocks: a stage's data holds
    /// its models' blocks if they were written in the current generation (which also
    /// covers the data of queued stages, outside `stages` when invalidated).
    generation: u64,
    /// Whether the horizon shifted since the last [`ProblemData::start_solve`]: the next
    /// solve continues the receding horizon on the same, shifted problem.
    continuing: bool,
    team: Option<Arc<Team>>,
    /// The kinds of stage passes ([`StagePass`]).
    kinds: [PassKind; 4],
}

impl std::fmt::Debug for ProblemData {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ProblemData")
            .field("horizon", &self.stages.len())
            .field("cost", &self.cost)
            .field("threads", &self.num_threads())
            .finish()
    }
}

/// The kinds of stage-wise passes, each with its own record of whether it is worth
/// sharing ([`PassKind`]).
#[derive(Clone, Copy)]
enum StagePass {
    Evaluate,
    Costs,
    Derivatives,
    SecondDerivatives,
}

fn constraint_data(cs: &[StageConstraint]) -> Vec<StageFunctionData> {
    cs.iter().map(|c| c.func.create_data()).collect()
}

impl ProblemData {
    /// Allocates the data of `problem` (and faer's packing buffer of the calling thread,
    /// so that the first solve allocates nothing); stages are evaluated on `num_threads`
    /// threads (1: serial, in the calling thread), at most the available parallelism
    /// ([`crate::pool_threads`]); results are the same for every thread count.
    ///
    /// # Errors
    /// If `num_threads` is 0 or the thread pool cannot be created.
    pub fn new(problem: &Problem, num_threads: usize) -> Result<Self> {
        if num_threads == 0 {
            return Err(Error::option("num_threads", "must be at least 1"));
        }
        let team = Team::for_threads(num_threads).map_err(|e| Error::option("num_threads", e))?;
        crate::linalg::reserve_packing_buffer();
        let s0 = problem.space(0);
        let init = match problem.initial_condition() {
            InitialCondition::Fixed(_) => {
                StageFunctionData::new(s0.ndx(), 0, s0.ndx(), crate::functions::no_workspace())
            }
            InitialCondition::Constraint(f) => StageFunctionData::new(f.ndx(), 0, f.nr(), f.create_workspace()),
        };
        Ok(Self {
            stages: problem.stages().iter().map(StageData::new).collect(),
            terminal_cost: problem.terminal_cost().create_data(),
            terminal_constraints: constraint_data(problem.terminal_constraints()),
            init,
            cost: 0.0,
            constants_written: false,
            generation: 0,
            continuing: false,
            team,
            kinds: Default::default(),
        })
    }

    /// Data of the constraints of knot `t`: the path constraints for `t < N`, the
    /// terminal constraints for `t = N`.
    pub fn constraint_data(&self, t: usize) -> &[StageFunctionData] {
        if t < self.stages.len() {
            &self.stages[t].constraints
        } else {
            &self.terminal_constraints
        }
    }

    /// Number of threads used for stage-wise work.
    pub fn num_threads(&self) -> usize {
        self.team.as_ref().map_or(1, |t| t.size())
    }

    /// The threads of the stage-wise passes (none: serial), for the parts of a solver
    /// that share them.
    pub(crate) fn team(&self) -> Option<&Arc<Team>> {
        self.team.as_ref()
    }

    /// Runs `f(t, stage_data)` for every stage, on the team when there is one.
    fn for_each_stage(&mut self, kind: StagePass, f: impl Fn(usize, &mut StageData) + Send + Sync) {
        let kind = &self.kinds[kind as usize];
        for_each_indexed(self.team.as_deref(), kind, &mut self.stages, f);
    }

    /// Evaluates costs, dynamics residuals `f(x_t, u_t, x_{t+1})`, constraint values and
    /// the initial residual at `(xs, us)`; returns the total cost. Sizes are not checked
    /// here (see [`Problem::check_trajectory`]).
    pub fn evaluate(&mut self, problem: &Problem, xs: &[Vec<f64>], us: &[Vec<f64>]) -> f64 {
        let stages = problem.stages();
        self.for_each_stage(StagePass::Evaluate, |t, sd| {
            sd.evaluate(&stages[t], &xs[t], &us[t], &xs[t + 1]);
        });
        self.evaluate_terminal(problem, xs)
    }

    /// After a rollout whose steps ([`StageData::rollout_step`]) wrote the dynamics
    /// residuals: the stages' costs and constraint values (a stage-parallel pass), then as
    /// [`ProblemData::evaluate_terminal`]; returns the total cost.
    pub fn evaluate_after_rollout(&mut self, problem: &Problem, xs: &[Vec<f64>], us: &[Vec<f64>]) -> f64 {
        let stages = problem.stages();
        self.for_each_stage(StagePass::Costs, |t, sd| {
            sd.evaluate_cost_and_constraints(&stages[t], &xs[t], &us[t]);
        });
        self.evaluate_terminal(problem, xs)
    }

    /// The part of [`ProblemData::evaluate`] after the stages: terminal cost and
    /// constraints, the initial residual and the total cost (returned).
    pub fn evaluate_terminal(&mut self, problem: &Problem, xs: &[Vec<f64>]) -> f64 {
        let n = problem.horizon();
        problem.terminal_cost().evaluate(&xs[n], &[], &mut self.terminal_cost);
        for (c, cd) in problem
            .terminal_constraints()
            .iter()
            .zip(self.terminal_constraints.iter_mut())
        {
            c.func.evaluate(&xs[n], &[], cd);
        }
        match problem.initial_condition() {
            InitialCondition::Fixed(x0) => problem.space(0).difference(x0, &xs[0], self.init.value_mut()),
            InitialCondition::Constraint(f) => f.evaluate(&xs[0], &mut self.init),
        }
        // Summed in stage order so that serial and parallel runs agree bit for bit.
        self.cost = self.stages.iter().map(|s| s.cost.value).sum::<f64>() + self.terminal_cost.value;
        self.cost
    }

    /// Computes first derivatives (and cost Hessians) at the point of the last
    /// [`ProblemData::evaluate`].
    ///
    /// Blocks that the models declare constant ([`crate::costs::Cost::hessian_is_constant`],
    /// `jacobians_are_constant` of dynamics and functions) are written by the first call
    /// on a stage's data only and kept by later ones (also across
    /// [`ProblemData::shift`], where each stage's data moves with its models): call
    /// [`ProblemData::invalidate_constant_derivatives`] before passing a problem with
    /// other models or after changing their parameters.
    pub fn compute_derivatives(&mut self, problem: &Problem, xs: &[Vec<f64>], us: &[Vec<f64>]) {
        let (stages, generation) = (problem.stages(), self.generation);
        self.for_each_stage(StagePass::Derivatives, |t, sd| {
            let reuse = sd.constants_generation == Some(generation);
            sd.derivatives(&stages[t], &xs[t], &us[t], &xs[t + 1], reuse);
            sd.constants_generation = Some(generation);
        });
        let reuse = self.constants_written;
        let n = stages.len();
        let terminal_cost = problem.terminal_cost();
        terminal_cost.derivatives_reusing(&xs[n], &[], &mut self.terminal_cost, reuse);
        for (c, cd) in problem
            .terminal_constraints()
            .iter()
            .zip(self.terminal_constraints.iter_mut())
        {
            if !(reuse && c.func.jacobians_are_constant()) {
                c.func.jacobians(&xs[n], &[], cd);
            }
        }
        self.constants_written = true;
        match problem.initial_condition() {
            InitialCondition::Fixed(x0) => problem
                .space(0)
                .jdifference(x0, &xs[0], Arg::Second, self.init.jx.as_mut()),
            InitialCondition::Constraint(f) => f.jacobian(&xs[0], &mut self.init),
        }
    }

    /// Receding horizon, after [`Problem::shift`]: moves the stage data one knot earlier
    /// and makes `incoming` (the data of the stage that entered, made by
    /// [`StageData::new`] for it) the last; `incoming` receives the data of the stage
    /// that left. Without `incoming` (after [`Problem::rotate`]) the data of stage 0
    /// becomes the last. Each stage's data moves with its models and keeps their
    /// constant derivative blocks; the next [`ProblemData::start_solve`] keeps them too.
    pub fn shift(&mut self, incoming: Option<&mut StageData>) {
        match incoming {
            Some(d) => super::shift_in(&mut self.stages, d),
            None => self.stages.rotate_left(1),
        }
        self.continuing = true;
    }

    /// Makes the next [`ProblemData::compute_derivatives`] write every block again,
    /// including those the models declare constant.
    pub fn invalidate_constant_derivatives(&mut self) {
        self.constants_written = false;
        self.continuing = false;
        self.generation += 1;
    }

    /// Called by the solvers as a solve loads its guess. A problem given to a solve may
    /// have other models than the last one (of the same dimensions) or parameters changed
    /// in place, so the constant derivative blocks are written anew
    /// ([`invalidate_constant_derivatives`](Self::invalidate_constant_derivatives)),
    /// except in a solve that continues a receding horizon ([`ProblemData::shift`] since
    /// the last call): there every stage's data kept its models' blocks, and only the
    /// data of a stage that entered for the first time writes them (the MPC cycle's
    /// control costs, effort limits and constant Hessian sums are not formed again).
    pub fn start_solve(&mut self) {
        if !self.continuing {
            self.invalidate_constant_derivatives();
        }
        self.continuing = false;
    }

    /// Computes the multiplier-weighted second derivatives of dynamics and constraints
    /// (for exact-Hessian solvers) at the point of the last
    /// [`ProblemData::compute_derivatives`]: `lambdas[t + 1]` weighs the dynamics of
    /// stage `t`, `nus[t]` (stacked over the stage's constraints) its path constraints,
    /// `nus[N]` the terminal constraints, `lambdas[0]` the initial constraint.
    pub fn compute_second_order(
        &mut self,
        problem: &Problem,
        xs: &[Vec<f64>],
        us: &[Vec<f64>],
        lambdas: &[Vec<f64>],
        nus: &[Vec<f64>],
    ) {
        let stages = problem.stages();
        self.for_each_stage(StagePass::SecondDerivatives, |t, sd| {
            sd.second_order(&stages[t], &xs[t], &us[t], &xs[t + 1], &lambdas[t + 1], &nus[t]);
        });
        let n = stages.len();
        let mut off = 0;
        for (c, cd) in problem
            .terminal_constraints()
            .iter()
            .zip(self.terminal_constraints.iter_mut())
        {
            let nr = c.nr();
            if c.func.has_vhp() {
                c.func.vhp(&xs[n], &[], &nus[n][off..off + nr], cd);
            }
            off += nr;
        }
        if let InitialCondition::Constraint(f) = problem.initial_condition()
            && f.has_vhp()
        {
            f.vhp(&xs[0], &lambdas[0], &mut self.init);
        }
    }

    /// Gradient of the Lagrangian
    /// `J + λ_0ᵀ r_0 + Σ λ_{t+1}ᵀ f_t + Σ ν_tᵀ h_t + ν_Nᵀ h_N` with respect to every
    /// state (`gx[t]`, `t = 0..=N`) and control (`gu[t]`, `t < N`), from the derivatives
    /// of the last [`ProblemData::compute_derivatives`] (ProxDDP (24)):
    /// [`lagrangian_gradient_forward`](Self::lagrangian_gradient_forward) then
    /// [`add_lagrangian_rest`](Self::add_lagrangian_rest).
    pub fn lagrangian_gradient(
        &self,
        problem: &Problem,
        lambdas: &[Vec<f64>],
        nus: &[Vec<f64>],
        gx: &mut [Vec<f64>],
        gu: &mut [Vec<f64>],
    ) {
        self.lagrangian_gradient_forward(problem, lambdas, gx, gu);
        self.add_lagrangian_rest(problem, lambdas, nus, gx, gu);
    }

    /// The cost gradient and the next co-state's terms of the Lagrangian gradient (24),
    /// `∇_x ℓ_t + f_xᵀ λ_{t+1}` and `∇_u ℓ_t + f_uᵀ λ_{t+1}` (`∇ℓ_N` at `N`): the part the
    /// constraint multipliers do not change.
    pub fn lagrangian_gradient_forward(
        &self,
        problem: &Problem,
        lambdas: &[Vec<f64>],
        gx: &mut [Vec<f64>],
        gu: &mut [Vec<f64>],
    ) {
        let n = problem.horizon();
        for (t, sd) in self.stages.iter().enumerate() {
            gx[t].copy_from_slice(sd.cost.lx());
            gu[t].copy_from_slice(sd.cost.lu());
            matvec_t(&mut gx[t], Accum::Add, sd.dyn_jx.as_ref(), &lambdas[t + 1], 1.0);
            matvec_t(&mut gu[t], Accum::Add, sd.dyn_ju.as_ref(), &lambdas[t + 1], 1.0);
        }
        gx[n].copy_from_slice(self.terminal_cost.lx());
    }

    /// Adds the constraints' terms `h_xᵀ ν`, `h_uᵀ ν` and the entering co-state's
    /// `f_yᵀ λ_t` (`r_0ᵀ λ_0` at 0) to the output of
    /// [`lagrangian_gradient_forward`](Self::lagrangian_gradient_forward), in the order of
    /// one pass (the same sums).
    pub fn add_lagrangian_rest(
        &self,
        problem: &Problem,
        lambdas: &[Vec<f64>],
        nus: &[Vec<f64>],
        gx: &mut [Vec<f64>],
        gu: &mut [Vec<f64>],
    ) {
        let n = problem.horizon();
        for t in 0..=n {
            let g = &mut gx[t];
            if t < n {
                let sd = &self.stages[t];
                let mut off = 0;
                for (k, (c, cd)) in problem.stages()[t]
                    .constraints()
                    .iter()
                    .zip(&sd.constraints)
                    .enumerate()
                {
                    let v = &nus[t][off..off + c.nr()];
                    if !sd.constraint_jx_zero[k] {
                        matvec_t(g, Accum::Add, cd.jx.as_ref(), v, 1.0);
                    }
                    matvec_t(&mut gu[t], Accum::Add, cd.ju.as_ref(), v, 1.0);
                    off += c.nr();
                }
            } else {
                let mut off = 0;
                for (c, cd) in problem.terminal_constraints().iter().zip(&self.terminal_constraints) {
                    matvec_t(g, Accum::Add, cd.jx.as_ref(), &nus[n][off..off + c.nr()], 1.0);
                    off += c.nr();
                }
            }
            // The co-state entering from the previous stage, or the initial condition.
            if t == 0 {
                matvec_t(g, Accum::Add, self.init.jx.as_ref(), &lambdas[0], 1.0);
            } else {
                let sd = &self.stages[t - 1];
                add_jy_t_product(g, sd.dyn_jy.as_ref(), sd.dyn_jy_block, &lambdas[t]);
            }
        }
    }

    /// Rolls the dynamics out from `xs[0]` under the controls `us`, writing `xs[1..]` (an
    /// initial guess that is dynamically feasible). Implicit dynamics are solved by
    /// Newton-Raphson from the states passed in (or the neutral point where those are
    /// not valid).
    ///
    /// # Errors
    /// If the numbers or sizes of the states and controls do not fit the problem, `xs[0]`
    /// or a control is not finite, a state becomes non-finite or an implicit solve does
    /// not converge.
    pub fn rollout(&mut self, problem: &Problem, xs: &mut [Vec<f64>], us: &[Vec<f64>]) -> Result<()> {
        let n = problem.horizon();
        check_dim("rollout: number of states xs (N + 1)", n + 1, xs.len())?;
        check_dim("rollout: number of controls us (N)", n, us.len())?;
        for (t, x) in xs.iter().enumerate() {
            check_dim(format_args!("rollout: xs[{t}] size"), problem.space(t).nx(), x.len())?;
        }
        for (t, u) in us.iter().enumerate() {
            check_dim(format_args!("rollout: us[{t}] size"), problem.nu(t), u.len())?;
            check_finite(format_args!("rollout: us[{t}]"), u)?;
        }
        check_finite("rollout: xs[0]", &xs[0])?;
        for (t, stage) in problem.stages().iter().enumerate() {
            let (done, rest) = xs.split_at_mut(t + 1);
            let y = &mut rest[0];
            if !stage.space_next().is_valid(y) {
                // An implicit solve starts from the state guess; where that is no point of
                // the space, from x_t (near the solution for a small step), or the
                // neutral point between spaces of other sizes.
                if stage.space().nx() == y.len() && stage.space_next().is_valid(&done[t]) {
                    y.copy_from_slice(&done[t]);
                } else {
                    stage.space_next().neutral(y);
                }
            }
            if !self.stages[t].solve_next_state(stage, &done[t], &us[t], None, y, ImplicitSolve::default()) {
                return Err(Error::non_finite(format!(
                    "rollout: state x[{}] (non-finite, or the implicit dynamics of stage {t} did not converge)",
                    t + 1
                )));
            }
        }
        Ok(())
    }
}

/// `g += f_yᵀ λ` for an `f_y` that is `-I` outside its leading `k × k` block
/// ([`StageData::dyn_jy_block`]): the products of its first `k` columns, negations for
/// the others. The same sums as the whole product (up to the sign of zeros), without
/// reading the identity part.
pub(crate) fn add_jy_t_product(g: &mut [f64], jy: MatRef<'_, f64>, k: usize, lambda: &[f64]) {
    if k > 0 {
        matvec_t(&mut g[..k], Accum::Add, jy.subcols(0, k), lambda, 1.0);
    }
    for (gi, li) in g[k..].iter_mut().zip(&lambda[k..]) {
        *gi -= li;
    }
}

/// `a += f_y δy` for the same `f_y` as [`add_jy_t_product`]: the block's product on the
/// first `k` entries, negations for the others (the same sums as the whole product).
pub(crate) fn add_jy_product(a: &mut [f64], jy: MatRef<'_, f64>, k: usize, dy: &[f64]) {
    if k > 0 {
        crate::linalg::matvec(&mut a[..k], Accum::Add, jy.submatrix(0, 0, k, k), &dy[..k], 1.0);
    }
    for (ai, yi) in a[k..].iter_mut().zip(&dy[k..]) {
        *ai -= yi;
    }
}

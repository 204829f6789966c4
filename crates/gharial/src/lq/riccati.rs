//! The serial proximal Riccati solver.

use faer::prelude::ReborrowMut;
use faer::{Col, Mat, MatRef};

use super::sqrt::SqrtKnot;
use super::stage::{ExtraGains, RiccatiStage, StageScratch};
use super::{
    KnotDims, KnotVectors, LqError, LqKnot, LqProblem, LqSolution, LqVectors, blame, check_regularisation,
    check_same_dims,
};
use crate::linalg::{self, BunchKaufman, FactorError, Inertia, slice, slice_mut};

/// Options of [`RiccatiSolver`].
#[derive(Debug, Clone, Copy, Default)]
pub struct RiccatiOptions {
    /// Also compute the gains of `x_{t+1}` and `λ_{t+1}` (50b-c), needed by linear and
    /// nonlinear rollouts (51) that follow the co-states. Costs about one `nx³` product
    /// per knot. Default `false`.
    pub rollout_gains: bool,
    /// Steps of iterative refinement in [`RiccatiSolver::forward`]: each computes the KKT
    /// residual of the solution and solves for its correction with the factorizations of
    /// the backward pass (one vector pass and one rollout, about a fifth of a backward
    /// pass). The recursion loses accuracy like `ε/mu` in the multipliers (the value
    /// function grows like `1/mu` in constrained directions); one step brings the
    /// residuals back to about `ε` (the dense solver's) for `mu` down to `1e-10`.
    /// Default 0.
    pub refinement_steps: usize,
}

/// The proximal Riccati solver of the ProxDDP paper (module docs of [`crate::lq`]).
///
/// [`new`](Self::new) allocates everything for the problem's dimensions; then
/// [`backward`](Self::backward), [`backward_vectors`](Self::backward_vectors) and
/// [`forward`](Self::forward) allocate nothing. After a backward pass, [`stage`](Self::stage)
/// gives each knot's gains, Q-function and value function. With small `mu` set
/// [`RiccatiOptions::refinement_steps`] to 1 or 2 when the multipliers matter (module
/// docs, "Accuracy").
///
/// ```
/// use gharial::lq::{LqSolution, RiccatiSolver, random};
/// let problem = random::peers_problem(4, 2, 2, 10, 42, 1e-8).problem;
/// let mut solver = RiccatiSolver::new(&problem).unwrap();
/// let mut sol = LqSolution::new(&problem);
/// solver.backward(&problem, 0.0).unwrap();
/// solver.forward(&problem, &mut sol).unwrap();
/// let res = gharial::lq::dense::kkt_residuals(&problem, &sol).unwrap();
/// assert!(res.max() < 1e-6);
/// ```
#[derive(Debug)]
pub struct RiccatiSolver {
    dims: Vec<KnotDims>,
    nc0: usize,
    stages: Vec<RiccatiStage>,
    scratch: StageScratch,
    initial: InitialStage,
    refinement: Option<Refinement>,
    /// Whether the stages hold storage for the rollout gains.
    rollout_storage: bool,
    factored: bool,
    /// Storage of the square-root pass, if allocated ([`RiccatiSolver::with_square_root`]).
    sqrt: Vec<SqrtKnot>,
    /// Whether the last backward pass was the square-root one (its stages hold no stage
    /// KKT factorization: no vector pass, no refinement).
    square_root_factored: bool,
}

/// Storage of iterative refinement: the residual and the correction.
#[derive(Debug)]
struct Refinement {
    steps: usize,
    residual: LqVectors,
    delta: LqSolution,
}

impl RiccatiSolver {
    /// Allocates a solver for problems with the dimensions of `problem`.
    pub fn new(problem: &LqProblem) -> Result<Self, LqError> {
        Self::with_options(problem, RiccatiOptions::default())
    }

    /// Allocates a solver with the given options.
    pub fn with_options(problem: &LqProblem, options: RiccatiOptions) -> Result<Self, LqError> {
        problem.check_shapes()?;
        let dims = problem.dims();
        let extra = if options.rollout_gains {
            ExtraGains::Rollout
        } else {
            ExtraGains::None
        };
        let stages = dims
            .iter()
            .enumerate()
            .map(|(t, d)| RiccatiStage::new(t, d.nx, d.nu, d.nc, d.nx_next, extra, 0))
            .collect();
        let refinement = (options.refinement_steps > 0).then(|| Refinement {
            steps: options.refinement_steps,
            residual: LqVectors::new(problem),
            delta: LqSolution::new(problem),
        });
        Ok(Self {
            initial: InitialStage::new(dims[0].nx, problem.nc0()),
            scratch: StageScratch::new(&dims),
            refinement,
            rollout_storage: options.rollout_gains,
            nc0: problem.nc0(),
            dims,
            stages,
            factored: false,
            sqrt: Vec::new(),
            square_root_factored: false,
        })
    }

    /// Allocates a solver that can also run the square-root backward pass
    /// ([`backward_square_root`](Self::backward_square_root)).
    pub fn with_square_root(problem: &LqProblem) -> Result<Self, LqError> {
        let mut s = Self::new(problem)?;
        s.sqrt = s
            .dims
            .iter()
            .map(|d| SqrtKnot::new(d.nx, d.nu, d.nc, d.nx_next))
            .collect();
        Ok(s)
    }

    /// The square-root backward pass of ALTRO (Howell et al. 2019, III-A; module `sqrt`
    /// of [`crate::lq`]) with the regularisation `primal_reg` on `Q_uu`: the value
    /// Hessians propagated as Cholesky factors `P_t = S_tᵀS_t` by QR of stacked factors,
    /// then the factorization of the initial stage. Afterwards [`stage`](Self::stage)
    /// gives the same quantities as after [`backward`](Self::backward) (gains, Q-function
    /// and value function, formed from the factors) and [`forward`](Self::forward) rolls
    /// them out; [`square_root_factor`](Self::square_root_factor) gives `S_t`.
    ///
    /// # Errors
    /// [`LqError::Unsupported`] for a knot with `E ≠ -I`, `mu_dyn > 0` or a constraint row
    /// with `mu_c = 0`; [`LqError::Singular`] when `Q_uu + ρI` is singular (a larger `ρ`
    /// helps) or a cost Hessian is not positive semidefinite; [`LqError::Option`] if the
    /// solver was not built by [`with_square_root`](Self::with_square_root).
    pub fn backward_square_root(&mut self, problem: &LqProblem, primal_reg: f64) -> Result<(), LqError> {
        self.factored = false;
        self.square_root_factored = false;
        if self.sqrt.len() != self.stages.len() {
            return Err(LqError::Option {
                name: "square_root",
                reason: "the solver was not built by RiccatiSolver::with_square_root",
            });
        }
        check_same_dims(problem, &self.dims, self.nc0)?;
        check_primal_reg(primal_reg)?;
        check_regularisation(problem)?;
        let n = self.stages.len();
        for t in (0..n).rev() {
            let (head, rest) = self.sqrt.split_at_mut(t + 1);
            let st = &mut self.stages[t];
            super::sqrt::step(st, &mut head[t], &problem.knots[t], rest.first(), primal_reg)
                .map_err(|e| st.blame(problem, e))?;
        }
        self.initial.factor(problem, self.stages[0].P())?;
        self.factored = true;
        self.square_root_factored = true;
        Ok(())
    }

    /// The factor `S_t` (`P_t = S_tᵀS_t`, upper triangular) of the last square-root pass.
    pub fn square_root_factor(&self, t: usize) -> Option<MatRef<'_, f64>> {
        self.square_root_factored.then(|| self.sqrt[t].s())
    }

    /// Backward pass with the primal regularisation `primal_reg ≥ 0` added to every
    /// `Q_uu`: matrix and vector parts, then the factorization of the initial stage.
    pub fn backward(&mut self, problem: &LqProblem, primal_reg: f64) -> Result<(), LqError> {
        self.factored = false;
        self.square_root_factored = false;
        check_same_dims(problem, &self.dims, self.nc0)?;
        check_primal_reg(primal_reg)?;
        check_regularisation(problem)?;
        sweep(
            &mut self.stages,
            &mut self.scratch,
            problem,
            0,
            None,
            None,
            Pass::Full { primal_reg },
        )?;
        self.initial.factor(problem, self.stages[0].P())?;
        self.factored = true;
        Ok(())
    }

    /// Vector part of the backward pass alone: after a [`backward`](Self::backward), when
    /// only `q, r, f, d, g0` changed, recomputes `k, ζ, p` (and the rollout feedforward
    /// terms) with the factorizations already computed.
    pub fn backward_vectors(&mut self, problem: &LqProblem) -> Result<(), LqError> {
        if !self.factored || self.square_root_factored {
            return Err(LqError::NotFactored);
        }
        check_same_dims(problem, &self.dims, self.nc0)?;
        check_regularisation(problem)?;
        self.vectors_unchecked(problem)
    }

    /// [`backward_vectors`](Self::backward_vectors) then [`forward`](Self::forward)
    /// without their checks of the problem's shapes and regularisations: for a caller
    /// that re-solves, many times, the problem of its last (checked) backward pass with
    /// new vectors `q, r, f, d, g0` (an ADMM's x-updates), where the checks would cost as
    /// much as the vector pass of a small knot.
    /// With `outputs = Outputs::Primal` only the states and controls of `sol` are written
    /// (its co-states and multipliers keep stale values): for iterations that use `x`, `u`
    /// only, before a last [`forward`](Self::forward) that writes everything.
    pub(crate) fn resolve_vectors(
        &mut self,
        problem: &LqProblem,
        sol: &mut LqSolution,
        outputs: Outputs,
    ) -> Result<(), LqError> {
        if !self.factored || self.square_root_factored {
            return Err(LqError::NotFactored);
        }
        self.vectors_unchecked(problem)?;
        self.forward_unchecked(problem, sol, outputs)
    }

    fn vectors_unchecked(&mut self, problem: &LqProblem) -> Result<(), LqError> {
        sweep(
            &mut self.stages,
            &mut self.scratch,
            problem,
            0,
            None,
            None,
            Pass::Vectors,
        )
    }

    /// Backward pass with a custom control law: at each knot (from the last) the solver
    /// computes the Q-function, then calls `law(knot, stage)`, which must set the value
    /// function of the stage, e.g. with [`RiccatiStage::value_from_gains`] (or with
    /// [`RiccatiStage::solve_kkt`] and [`RiccatiStage::solve_kkt_vectors`]). Ends with the
    /// factorization of the initial stage, so that [`forward`](Self::forward) rolls the
    /// custom gains out.
    pub fn backward_with<F>(&mut self, problem: &LqProblem, mut law: F) -> Result<(), LqError>
    where
        F: FnMut(&LqKnot, &mut RiccatiStage, Option<(MatRef<'_, f64>, &[f64])>) -> Result<(), LqError>,
    {
        self.factored = false;
        self.square_root_factored = false;
        check_same_dims(problem, &self.dims, self.nc0)?;
        check_regularisation(problem)?;
        let n = self.stages.len();
        for t in (0..n).rev() {
            let (head, rest) = self.stages.split_at_mut(t + 1);
            let st = &mut head[t];
            let next = rest.first().map(|s| (s.P(), s.p()));
            let knot = &problem.knots[t];
            st.q_function(knot, next.map(|n| n.0), &mut self.scratch)
                .map_err(|e| st.blame(problem, e))?;
            st.q_function_vectors(knot, KnotVectors::of(knot), next);
            law(knot, st, next).map_err(|e| st.blame(problem, e))?;
        }
        self.initial.factor(problem, self.stages[0].P())?;
        self.factored = true;
        Ok(())
    }

    /// Forward pass (50): solves the initial stage (65), then rolls the gains out,
    /// writing the primal-dual solution into `sol` (allocated by [`LqSolution::new`]).
    pub fn forward(&mut self, problem: &LqProblem, sol: &mut LqSolution) -> Result<(), LqError> {
        if !self.factored {
            return Err(LqError::NotFactored);
        }
        check_same_dims(problem, &self.dims, self.nc0)?;
        sol.check_dims(problem)?;
        self.forward_unchecked(problem, sol, Outputs::All)
    }

    fn forward_unchecked(
        &mut self,
        problem: &LqProblem,
        sol: &mut LqSolution,
        outputs: Outputs,
    ) -> Result<(), LqError> {
        self.initial.solve(
            problem,
            slice(&problem.g0),
            self.stages[0].p(),
            slice_mut(&mut sol.xs[0]),
            slice_mut(&mut sol.lambdas[0]),
        )?;
        rollout_all(&mut self.stages, problem, sol, outputs)?;
        if let Some(r) = self.refinement.as_mut().filter(|_| !self.square_root_factored) {
            for _ in 0..r.steps {
                r.residual.set_kkt_residual(problem, sol)?;
                self.stages.iter_mut().for_each(RiccatiStage::save_vector_part);
                sweep(
                    &mut self.stages,
                    &mut self.scratch,
                    problem,
                    0,
                    Some(&r.residual),
                    None,
                    Pass::Vectors,
                )?;
                self.initial.solve(
                    problem,
                    slice(&r.residual.g0),
                    self.stages[0].p(),
                    slice_mut(&mut r.delta.xs[0]),
                    slice_mut(&mut r.delta.lambdas[0]),
                )?;
                rollout_all(&mut self.stages, problem, &mut r.delta, Outputs::All)?;
                sol.add(&r.delta);
                self.stages.iter_mut().for_each(RiccatiStage::add_saved_vector_part);
            }
        }
        Ok(())
    }

    /// Sets the number of iterative refinement steps of [`forward`](Self::forward) (see
    /// [`RiccatiOptions::refinement_steps`]); no effect on a solver created without
    /// refinement, whose storage for it was not allocated.
    pub(crate) fn set_refinement_steps(&mut self, steps: usize) {
        if let Some(r) = &mut self.refinement {
            r.steps = steps;
        }
    }

    /// Turns the computation of the rollout gains (50b-c) in the next backward passes on
    /// or off; no effect on a solver created without [`RiccatiOptions::rollout_gains`],
    /// whose storage for them was not allocated.
    pub(crate) fn set_rollout_gains(&mut self, on: bool) {
        let extra = if on && self.rollout_storage {
            ExtraGains::Rollout
        } else {
            ExtraGains::None
        };
        self.stages.iter_mut().for_each(|st| st.set_extra(extra));
    }

    /// The per-knot workspaces: Q-function, gains and value function of every knot after
    /// a backward pass.
    pub fn stages(&self) -> &[RiccatiStage] {
        &self.stages
    }

    /// The workspace of knot `t`.
    pub fn stage(&self, t: usize) -> &RiccatiStage {
        &self.stages[t]
    }

    /// The workspace of knot `t`, mutable (for its KKT solves).
    pub(crate) fn stage_mut(&mut self, t: usize) -> &mut RiccatiStage {
        &mut self.stages[t]
    }

    /// The initial stage (65) for the value gradient `p0` of knot 0: `x_0` and `λ_0`.
    pub(crate) fn solve_initial(
        &mut self,
        problem: &LqProblem,
        p0: &[f64],
        x0: &mut [f64],
        lambda0: &mut [f64],
    ) -> Result<(), LqError> {
        self.initial.solve(problem, slice(&problem.g0), p0, x0, lambda0)
    }
}

pub(crate) fn check_primal_reg(primal_reg: f64) -> Result<(), LqError> {
    if primal_reg.is_finite() && primal_reg >= 0.0 {
        Ok(())
    } else {
        Err(LqError::Option {
            name: "primal_reg",
            reason: "must be finite and nonnegative",
        })
    }
}

/// Which parts of the backward recursion a sweep computes.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Pass {
    /// Matrix and vector parts.
    Full {
        /// Primal regularisation of `Q_uu`.
        primal_reg: f64,
    },
    /// Vector part only, with the factorizations of the last full pass.
    Vectors,
}

/// Backward sweep over consecutive knots `stages[i] <-> problem.knots[offset + i]`, with
/// the knots' vectors or those of `rhs`. `tail` is the value function after the last of
/// them (`None` when it is the problem's last knot).
pub(crate) fn sweep(
    stages: &mut [RiccatiStage],
    scratch: &mut StageScratch,
    problem: &LqProblem,
    offset: usize,
    rhs: Option<&LqVectors>,
    tail: Option<(MatRef<'_, f64>, &[f64])>,
    pass: Pass,
) -> Result<(), LqError> {
    let n = stages.len();
    for i in (0..n).rev() {
        let (head, rest) = stages.split_at_mut(i + 1);
        let st = &mut head[i];
        let next = match rest.first() {
            Some(s) => Some((s.P(), s.p())),
            None => tail,
        };
        let knot = &problem.knots[offset + i];
        let v = match rhs {
            Some(r) => r.knot(offset + i),
            None => KnotVectors::of(knot),
        };
        let res = match pass {
            Pass::Full { primal_reg } => st
                .q_function(knot, next.map(|n| n.0), scratch)
                .and_then(|()| {
                    st.q_function_vectors(knot, v, next);
                    st.solve_kkt_with_feedforward(knot, next.map(|n| n.0), primal_reg, v.d)
                })
                .and_then(|()| st.solve_kkt_vectors_solved(knot, next)),
            Pass::Vectors => {
                st.q_function_vectors(knot, v, next);
                st.solve_kkt_vectors_with(knot, v.d, next)
            }
        };
        res.map_err(|e| st.blame(problem, e))?;
    }
    Ok(())
}

/// What a rollout writes besides the states `x` and controls `u`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Outputs {
    /// Also the co-states `λ` and the constraint multipliers `ν`.
    All,
    /// `x` and `u` only.
    Primal,
}

/// Forward rollout over consecutive knots `stages[i] <-> knots[i]`, from the state already in
/// `xs[0]`: writes `xs[1..]`, `us`, `nus` and `lambdas[i]` (the co-state after stage `i`)
/// for all stages but the last, whose next state and co-state go to `last` (empty slices
/// at the problem's last knot). `tail` is the value function after the last stage.
pub(crate) fn rollout(
    stages: &mut [RiccatiStage],
    knots: &[LqKnot],
    tail: Option<(MatRef<'_, f64>, &[f64])>,
    xs: &mut [Col<f64>],
    us: &mut [Col<f64>],
    nus: &mut [Col<f64>],
    lambdas: &mut [Col<f64>],
    last: (&mut [f64], &mut [f64]),
    outputs: Outputs,
) -> Result<(), LqError> {
    let n = stages.len();
    let (last_x, last_lambda) = last;
    for i in 0..n {
        let (head, rest) = stages.split_at_mut(i + 1);
        let st = &mut head[i];
        let next = match rest.first() {
            Some(s) => Some((s.P(), s.p())),
            None => tail,
        };
        let (xs_head, xs_rest) = xs.split_at_mut(i + 1);
        let (x_next, lambda_next): (&mut [f64], &mut [f64]) = if i + 1 < n {
            (slice_mut(&mut xs_rest[0]), slice_mut(&mut lambdas[i]))
        } else {
            (&mut *last_x, &mut *last_lambda)
        };
        st.forward_step(
            &knots[i],
            slice(&xs_head[i]),
            slice_mut(&mut us[i]),
            slice_mut(&mut nus[i]),
            next,
            x_next,
            lambda_next,
            outputs,
        );
        let costates = if outputs == Outputs::All { &lambda_next[..] } else { &[] };
        if !x_next.iter().chain(costates).sum::<f64>().is_finite() {
            return Err(LqError::NonFinite {
                knot: st.index(),
                field: "forward pass state",
            });
        }
    }
    Ok(())
}

/// [`rollout`] over a whole problem's knots into `sol`, from `sol.xs[0]`.
pub(crate) fn rollout_all(
    stages: &mut [RiccatiStage],
    problem: &LqProblem,
    sol: &mut LqSolution,
    outputs: Outputs,
) -> Result<(), LqError> {
    rollout(
        stages,
        &problem.knots,
        None,
        &mut sol.xs,
        &mut sol.us,
        &mut sol.nus,
        &mut sol.lambdas[1..],
        (&mut [], &mut []),
        outputs,
    )
}

/// The initial stage (49)/(65): `[[P_0, G0ᵀ], [G0, -mu0 I]] [x_0; λ_0] = -[p_0; g0]`,
/// factored by Bunch-Kaufman (robust when `mu0 = 0`).
#[derive(Debug)]
pub(crate) struct InitialStage {
    nx: usize,
    nc0: usize,
    kkt: Mat<f64>,
    bk: BunchKaufman,
    rhs: Col<f64>,
}

impl InitialStage {
    pub(crate) fn new(nx: usize, nc0: usize) -> Self {
        Self {
            nx,
            nc0,
            kkt: Mat::zeros(nx + nc0, nx + nc0),
            bk: BunchKaufman::with_max_rhs(nx + nc0, 1),
            rhs: Col::zeros(nx + nc0),
        }
    }

    /// Factors the initial KKT matrix with the value Hessian `P0` of knot 0.
    pub(crate) fn factor(&mut self, problem: &LqProblem, P0: MatRef<'_, f64>) -> Result<(), LqError> {
        let (nx, nc0) = (self.nx, self.nc0);
        let mut k = self.kkt.as_mut();
        linalg::copy(k.rb_mut().submatrix_mut(0, 0, nx, nx), P0);
        linalg::copy(k.rb_mut().submatrix_mut(nx, 0, nc0, nx), problem.G0.as_ref());
        for i in 0..nc0 {
            k[(nx + i, nx + i)] = -problem.mu0;
        }
        let expected = Inertia {
            positive: nx,
            negative: nc0,
            zero: 0,
        };
        match self.bk.factor(self.kkt.as_ref(), 0.0) {
            Ok(got) if got == expected => Ok(()),
            Ok(got) => Err(LqError::Inertia {
                knot: 0,
                system: "initial KKT",
                expected,
                got,
            }),
            Err(FactorError::NonFinite) => Err(blame(
                problem,
                0,
                LqError::NonFinite {
                    knot: 0,
                    field: "initial KKT",
                },
            )),
            Err(FactorError::Singular { .. }) => Err(LqError::Singular {
                knot: 0,
                system: "initial KKT",
            }),
        }
    }

    /// Solves for `x_0` and `λ_0` given the offset `g0` and the value gradient `p0` of
    /// knot 0; a non-finite result is blamed on the problem's data if possible.
    pub(crate) fn solve(
        &mut self,
        problem: &LqProblem,
        g0: &[f64],
        p0: &[f64],
        x0: &mut [f64],
        lambda0: &mut [f64],
    ) -> Result<(), LqError> {
        let nx = self.nx;
        let r = slice_mut(&mut self.rhs);
        for i in 0..nx {
            r[i] = -p0[i];
        }
        for (ri, gi) in r[nx..].iter_mut().zip(g0) {
            *ri = -gi;
        }
        self.bk.solve_in_place(self.rhs.as_mut().as_mat_mut());
        let r = slice(&self.rhs);
        x0.copy_from_slice(&r[..nx]);
        lambda0.copy_from_slice(&r[nx..]);
        if r.iter().sum::<f64>().is_finite() {
            Ok(())
        } else {
            Err(blame(
                problem,
                0,
                LqError::NonFinite {
                    knot: 0,
                    field: "initial state",
                },
            ))
        }
    }
}

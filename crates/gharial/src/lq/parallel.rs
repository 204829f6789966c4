//! The parallel proximal Riccati solver (see [`ParallelRiccatiSolver`]).

use faer::prelude::ReborrowMut;
use faer::{Accum, Col, Mat, MatRef};
use std::sync::Arc;

use super::riccati::{InitialStage, Outputs, Pass, check_primal_reg, rollout, sweep};
use super::stage::{ExtraGains, RiccatiStage, StageScratch};
use super::{KnotDims, LqError, LqKnot, LqProblem, LqSolution, LqVectors, check_regularisation, check_same_dims};
use crate::linalg::{self, BunchKaufman, FactorError, col_of, col_of_mut, matmul, matvec, matvec_t, slice, slice_mut};
use crate::team::{PassKind, Team};

/// Relative cost of a knot of a parameterised leg with respect to a plain knot, used to
/// balance the legs' lengths (the parameter adds `Tᵀ Γ̃`, `H_uu` and the `Ω` update).
const PARAM_COST: f64 = 1.6;

/// The proximal Riccati solver with the horizon split into legs solved on a team of
/// threads; the same interface and solution as
/// [`RiccatiSolver`](super::RiccatiSolver).
///
/// # Legs
///
/// Leg `j` covers knots `s_j..=e_j`; for every leg but the last, the boundary co-state
/// `θ_j = λ_b` of the dynamics of knot `e_j` (into `x_b`, `b = e_j + 1`, the first state of
/// the next leg) is an unknown parameter. The terms of the Lagrangian that belong to leg
/// `j` are its knots' terms plus `θᵀ(A x_e + B u_e + f) - ½ mu_dyn |θ|²`; `x_b` and the
/// term `θᵀE x_b` belong to the next leg's side of the boundary. For fixed `θ` and a given
/// first state `x_s`, the leg's stationary value is the quadratic
/// ```text
/// W_j(x_s, θ) = ½ x_sᵀ P_s x_s + x_sᵀ Γ_s θ + ½ θᵀ Ω_s θ + p_sᵀ x_s + ω_sᵀ θ + const.
/// ```
/// It is computed by the serial recursion of [`crate::lq`] started from the leg-end value
/// `V(x') = -(Eᵀθ)ᵀ x'` (that is `P' = 0`, `p' = 0` and a `θ`-block `Γ_{e+1} = -E_eᵀ`,
/// `Ω_{e+1} = 0`, `ω_{e+1} = 0`), carrying the `θ` columns along:
/// ```text
/// Γ̃ = (I + P'G)⁻¹ Γ'                      Γ_t = Tᵀ Γ̃,  T = Ã + B̃K
/// Ω_t = Ω' - Γ'ᵀ G Γ̃ - (B̃ᵀΓ̃)ᵀ H_uu (B̃ᵀΓ̃),  H_uu = [I 0] K_stage⁻¹ [I; 0]
/// ω_t = ω' + Γ̃ᵀ (B̃k + f̃) - Γ'ᵀ G p̃
/// ```
/// (`Γ_t = C_tᵀΓ'` with the state gain `C_t` of (50b): the co-state sensitivity is carried
/// back by the closed loop.) The last leg has no parameter: it is the serial recursion.
///
/// # Condensed system
///
/// With `V_b` the value at the next leg's first state (`P_b`, `p_b`), the boundary
/// conditions are stationarity in `x_b` and the boundary dynamics row, by the envelope
/// theorem `∂W_j/∂θ + E x_b = 0`:
/// ```text
/// [P_b  Eᵀ ] [x_b]     [p_b      ]   [0   ]
/// [E    Ω_s] [θ  ] = - [ω_s      ] - [Γ_sᵀ] x_s
/// ```
/// solved from the last boundary to the first (a Riccati recursion over the legs, with a
/// Bunch-Kaufman factorization of size `2 nx` per boundary); each step gives the true value
/// at `x_s`, `P̂_s = P_s + Γ_s G_θ`, `p̂_s = p_s + Γ_s g_θ`, which is the `P_b` of the
/// previous boundary; the first one feeds the initial stage. The forward pass solves the
/// initial stage, walks the boundaries forward (`x_b`, `θ`), then on threads recomputes
/// each leg's vector part with `p' = -Eᵀθ` and rolls the leg out from its `x_s`.
///
/// The solution equals the serial solver's up to rounding. The per-knot gains of a leg's
/// last knots are those of the leg (conditional on `θ`), not the serial ones: use the
/// serial solver when the gains themselves are needed (nonlinear rollouts).
///
/// # Cost, accuracy, allocation
///
/// A parameterised knot costs about 1.6 plain ones (`Tᵀ Γ̃`, `H_uu`, the `Ω` update), so
/// the last leg is made longer; with 2 threads the work is about 1.23 times the serial
/// solver's, for an ideal speed-up of about 1.6. The condensed system inherits the
/// `1/mu` scale of the value function: without refinement the solution agrees with the
/// serial one to about `ε/mu`, with `refinement_steps` as well as the serial one does. The
/// solver allocates nothing after construction.
pub struct ParallelRiccatiSolver {
    team: Option<Arc<Team>>,
    /// The legs' backward passes.
    backward_pass: PassKind,
    /// The legs' forward passes.
    forward_pass: PassKind,
    dims: Vec<KnotDims>,
    nc0: usize,
    legs: Vec<Leg>,
    boundaries: Vec<Boundary>,
    initial: InitialStage,
    refinement: Option<(usize, LqVectors, LqSolution)>,
    factored: bool,
}

impl std::fmt::Debug for ParallelRiccatiSolver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ParallelRiccatiSolver")
            .field("threads", &self.team.as_ref().map_or(1, |t| t.size()))
            .field(
                "legs",
                &self.legs.iter().map(|l| (l.start, l.stages.len())).collect::<Vec<_>>(),
            )
            .finish()
    }
}

/// One leg: knots `start..start + stages.len()`.
#[derive(Debug)]
struct Leg {
    start: usize,
    stages: Vec<RiccatiStage>,
    scratch: StageScratch,
    param: Option<LegParam>,
    result: Result<(), LqError>,
}

/// The boundary co-state parameter of a leg (all legs but the last).
#[derive(Debug)]
struct LegParam {
    /// `P' = 0` after the leg's last knot.
    zero_P: Mat<f64>,
    /// `p'` after the leg's last knot: 0 in the backward pass, `-Eᵀθ` in the forward pass.
    tail_p: Col<f64>,
    /// `Γ_t` for the leg's knots and `Γ_{e+1} = -E_eᵀ` (one more than the knots).
    gamma: Vec<Mat<f64>>,
    /// `Γ̃_t = (I + P'G)⁻¹ Γ_{t+1}` (used when `mu_dyn > 0`).
    gamma_tilde: Vec<Mat<f64>>,
    /// `Ω_s` and `ω_s` at the leg's first knot.
    omega: Mat<f64>,
    omega_vec: Col<f64>,
    /// Scratch: `B̃ᵀΓ̃`, `H_uu B̃ᵀΓ̃`, `K⁻¹ [I; 0]`, `G Γ̃`, `G p̃`.
    bg: Mat<f64>,
    hbg: Mat<f64>,
    kinv: Mat<f64>,
    ggt: Mat<f64>,
    gp: Col<f64>,
    /// State and co-state after the last knot computed by the leg's rollout (unused: the
    /// condensed system gives them to the next leg).
    x_end: Col<f64>,
    lambda_end: Col<f64>,
}

/// The condensed system at the boundary after leg `j`.
#[derive(Debug)]
struct Boundary {
    /// First knot of the next leg (`b`), and first knot of leg `j` (`s`).
    b: usize,
    s: usize,
    kkt: Mat<f64>,
    bk: BunchKaufman,
    /// `[g | G]` with `[x_b; θ] = g + G x_s` (`2 nθ x (1 + nx_s)`).
    gains: Mat<f64>,
    /// `P̂_s`, `p̂_s`: the value at leg `j`'s first state.
    hat_P: Mat<f64>,
    hat_p: Col<f64>,
    /// Saved vector part (`g`, `p̂_s`) for iterative refinement.
    saved: Vec<f64>,
}

impl Leg {
    /// The leg of knots `s..end` (`end` is the next leg's first knot, or the horizon's
    /// length for the last leg).
    fn new(dims: &[KnotDims], s: usize, end: usize) -> Self {
        let n_knots = dims.len();
        let ntheta = if end < n_knots { dims[end].nx } else { 0 };
        // Parameterised legs need the closed loop T = Ã + B̃K.
        let extra = if end < n_knots {
            ExtraGains::ClosedLoop
        } else {
            ExtraGains::None
        };
        let stages = (s..end)
            .map(|t| {
                let d = dims[t];
                RiccatiStage::new(t, d.nx, d.nu, d.nc, d.nx_next, extra, d.nx_next.max(ntheta) + 1)
            })
            .collect();
        Leg {
            start: s,
            stages,
            scratch: StageScratch::new(&dims[s..end]),
            param: (end < n_knots).then(|| LegParam::new(dims, s, end, ntheta)),
            result: Ok(()),
        }
    }
}

impl LegParam {
    /// The parameter storage of the leg `s..end` with a boundary co-state of size `ntheta`.
    fn new(dims: &[KnotDims], s: usize, end: usize, ntheta: usize) -> Self {
        let (max_nu, max_nk, max_ny) = (s..end).fold((0, 0, 0), |(a, b, c), t| {
            (
                a.max(dims[t].nu),
                b.max(dims[t].nu + dims[t].nc),
                c.max(dims[t].nx_next),
            )
        });
        LegParam {
            zero_P: Mat::zeros(ntheta, ntheta),
            tail_p: Col::zeros(ntheta),
            gamma: (s..=end).map(|t| Mat::zeros(dims[t].nx, ntheta)).collect(),
            gamma_tilde: (s..end).map(|t| Mat::zeros(dims[t].nx_next, ntheta)).collect(),
            omega: Mat::zeros(ntheta, ntheta),
            omega_vec: Col::zeros(ntheta),
            bg: Mat::zeros(max_nu, ntheta),
            hbg: Mat::zeros(max_nu, ntheta),
            kinv: Mat::zeros(max_nk, max_nu),
            ggt: Mat::zeros(max_ny, ntheta),
            gp: Col::zeros(max_ny),
            x_end: Col::zeros(ntheta),
            lambda_end: Col::zeros(ntheta),
        }
    }
}

impl Boundary {
    /// The condensed system between the leg starting at `s` and the next, starting at `b`.
    fn new(dims: &[KnotDims], s: usize, b: usize) -> Self {
        let (ntheta, nxs) = (dims[b].nx, dims[s].nx);
        Boundary {
            b,
            s,
            kkt: Mat::zeros(2 * ntheta, 2 * ntheta),
            bk: BunchKaufman::with_max_rhs(2 * ntheta, 1 + nxs),
            gains: Mat::zeros(2 * ntheta, 1 + nxs),
            hat_P: Mat::zeros(nxs, nxs),
            hat_p: Col::zeros(nxs),
            saved: vec![0.0; 2 * ntheta + nxs],
        }
    }
}

/// The team of `num_threads` threads of an LQ solver that has none to share
/// ([`Team::for_threads`]), its error as the LQ solvers report it.
pub(crate) fn team_for(num_threads: usize) -> Result<Option<Arc<Team>>, LqError> {
    Team::for_threads(num_threads).map_err(|_| LqError::Option {
        name: "num_threads",
        reason: "a thread could not be started",
    })
}

impl ParallelRiccatiSolver {
    /// Allocates a solver for problems with the dimensions of `problem`, split into
    /// `num_threads` legs (fewer for short horizons) run on a team of at most the available
    /// parallelism ([`crate::pool_threads`]). The legs, not the threads, fix the
    /// arithmetic, so results do not depend on the machine. Its options are those of the
    /// serial solver except the rollout gains, which the legs do not give for the whole
    /// horizon (`refinement_steps` applies).
    ///
    /// # Errors
    /// If `num_threads` is 0, the problem's shapes are inconsistent or a thread cannot be
    /// started.
    pub fn new(problem: &LqProblem, num_threads: usize, refinement_steps: usize) -> Result<Self, LqError> {
        Self::with_team(problem, num_threads, refinement_steps, team_for(num_threads)?)
    }

    /// As [`ParallelRiccatiSolver::new`], on the threads of `team` (a solver's stage-wise
    /// passes and its LQ passes share one team; `None`: the calling thread only).
    pub(crate) fn with_team(
        problem: &LqProblem,
        num_threads: usize,
        refinement_steps: usize,
        team: Option<Arc<Team>>,
    ) -> Result<Self, LqError> {
        if num_threads == 0 {
            return Err(LqError::Option {
                name: "num_threads",
                reason: "must be at least 1",
            });
        }
        problem.check_shapes()?;
        let dims = problem.dims();
        let n_knots = dims.len();
        let n_legs = num_threads.min(n_knots);
        // Parameterised legs of length L, the last of length PARAM_COST * L.
        let lp = ((n_knots as f64) / (n_legs as f64 - 1.0 + PARAM_COST)).floor().max(1.0) as usize;
        let mut starts: Vec<usize> = (0..n_legs).map(|j| j * lp).collect();
        starts.retain(|&s| s < n_knots);
        let legs: Vec<Leg> = starts
            .iter()
            .enumerate()
            .map(|(j, &s)| Leg::new(&dims, s, starts.get(j + 1).copied().unwrap_or(n_knots)))
            .collect();
        let boundaries = legs
            .windows(2)
            .map(|w| Boundary::new(&dims, w[0].start, w[1].start))
            .collect();
        let refinement =
            (refinement_steps > 0).then(|| (refinement_steps, LqVectors::new(problem), LqSolution::new(problem)));
        Ok(Self {
            team,
            backward_pass: PassKind::default(),
            forward_pass: PassKind::default(),
            initial: InitialStage::new(dims[0].nx, problem.nc0()),
            nc0: problem.nc0(),
            dims,
            legs,
            boundaries,
            refinement,
            factored: false,
        })
    }

    /// Number of legs the horizon is split into.
    pub fn num_legs(&self) -> usize {
        self.legs.len()
    }

    /// Sets the number of iterative refinement steps of [`forward`](Self::forward); no
    /// effect on a solver created without refinement, whose storage was not allocated.
    pub(crate) fn set_refinement_steps(&mut self, steps: usize) {
        if let Some(r) = &mut self.refinement {
            r.0 = steps;
        }
    }

    /// Backward pass with primal regularisation `primal_reg` (see
    /// [`RiccatiSolver::backward`](super::RiccatiSolver::backward)): legs on threads, then
    /// the condensed system and the initial stage.
    pub fn backward(&mut self, problem: &LqProblem, primal_reg: f64) -> Result<(), LqError> {
        self.factored = false;
        check_same_dims(problem, &self.dims, self.nc0)?;
        check_primal_reg(primal_reg)?;
        check_regularisation(problem)?;
        self.legs_backward(problem, None, Pass::Full { primal_reg })?;
        self.condensed_matrices(problem)?;
        self.condensed_vectors();
        self.factored = true;
        Ok(())
    }

    /// Vector part of the backward pass alone (see
    /// [`RiccatiSolver::backward_vectors`](super::RiccatiSolver::backward_vectors)).
    pub fn backward_vectors(&mut self, problem: &LqProblem) -> Result<(), LqError> {
        if !self.factored {
            return Err(LqError::NotFactored);
        }
        check_same_dims(problem, &self.dims, self.nc0)?;
        check_regularisation(problem)?;
        self.legs_backward(problem, None, Pass::Vectors)?;
        self.condensed_vectors();
        Ok(())
    }

    /// Forward pass: initial stage, boundaries, then the legs' rollouts on threads; then
    /// the refinement steps if any.
    pub fn forward(&mut self, problem: &LqProblem, sol: &mut LqSolution) -> Result<(), LqError> {
        if !self.factored {
            return Err(LqError::NotFactored);
        }
        check_same_dims(problem, &self.dims, self.nc0)?;
        sol.check_dims(problem)?;
        self.solve_forward(problem, None, sol)?;
        if let Some((steps, mut residual, mut delta)) = self.refinement.take() {
            let mut res = Ok(());
            for _ in 0..steps {
                self.save_vector_parts();
                res = residual
                    .set_kkt_residual(problem, sol)
                    .and_then(|()| self.legs_backward(problem, Some(&residual), Pass::Vectors))
                    .and_then(|()| {
                        self.condensed_vectors();
                        self.solve_forward(problem, Some(&residual), &mut delta)
                    });
                if res.is_err() {
                    break;
                }
                sol.add(&delta);
                self.add_saved_vector_parts();
            }
            self.refinement = Some((steps, residual, delta));
            res?;
        }
        Ok(())
    }

    /// The legs' backward passes on the team, with the knots' vectors or those of `rhs`.
    fn legs_backward(&mut self, problem: &LqProblem, rhs: Option<&LqVectors>, pass: Pass) -> Result<(), LqError> {
        let f = |leg: &mut Leg| leg.result = leg.backward(problem, rhs, pass);
        match &self.team {
            Some(team) => team.for_each(&self.backward_pass, self.legs.iter_mut(), f),
            None => self.legs.iter_mut().for_each(f),
        }
        first_error(&mut self.legs)
    }

    /// Factors the condensed systems from the last boundary to the first, then the
    /// initial stage; computes the feedback columns `G` and `P̂_s`.
    fn condensed_matrices(&mut self, problem: &LqProblem) -> Result<(), LqError> {
        for j in (0..self.boundaries.len()).rev() {
            let (done, rest) = self.boundaries.split_at_mut(j + 1);
            let bd = &mut done[j];
            let leg = &self.legs[j];
            let param = leg.param.as_ref().expect("legs before a boundary are parameterised");
            let tail_P = match rest.first() {
                Some(next) => next.hat_P.as_ref(),
                None => self.legs[j + 1].stages[0].P(),
            };
            let e_knot = &problem.knots[bd.b - 1];
            let nt = tail_P.nrows();
            let nxs = leg.stages[0].dims().0;
            let mut k = bd.kkt.as_mut();
            linalg::copy(k.rb_mut().submatrix_mut(0, 0, nt, nt), tail_P);
            linalg::copy(k.rb_mut().submatrix_mut(nt, 0, nt, nt), e_knot.E.as_ref());
            linalg::copy(k.rb_mut().submatrix_mut(nt, nt, nt, nt), param.omega.as_ref());
            match bd.bk.factor(bd.kkt.as_ref(), 0.0) {
                Ok(inertia) if inertia.zero == 0 => {}
                Err(FactorError::NonFinite) => {
                    return Err(LqError::NonFinite {
                        knot: bd.b,
                        field: "condensed boundary system",
                    });
                }
                _ => {
                    return Err(LqError::Singular {
                        knot: bd.b,
                        system: "condensed boundary system",
                    });
                }
            }
            // Feedback columns -[0; Γ_sᵀ].
            let mut g = bd.gains.as_mut().submatrix_mut(0, 1, 2 * nt, nxs);
            g.rb_mut().submatrix_mut(0, 0, nt, nxs).fill(0.0);
            linalg::copy_transposed(g.rb_mut().submatrix_mut(nt, 0, nt, nxs), param.gamma[0].as_ref());
            for jj in 0..nxs {
                for i in nt..2 * nt {
                    g[(i, jj)] = -g[(i, jj)];
                }
            }
            bd.bk.solve_in_place(g);
            // P̂_s = P_s + Γ_s G_θ.
            linalg::copy(bd.hat_P.as_mut(), leg.stages[0].P());
            matmul(
                bd.hat_P.as_mut(),
                Accum::Add,
                param.gamma[0].as_ref(),
                bd.gains.as_ref().submatrix(nt, 1, nt, nxs),
                1.0,
            );
            linalg::symmetrize(bd.hat_P.as_mut());
        }
        let P0 = match self.boundaries.first() {
            Some(bd) => bd.hat_P.as_ref(),
            None => self.legs[0].stages[0].P(),
        };
        self.initial.factor(problem, P0)
    }

    /// Feedforward column `g` and `p̂_s` of every boundary, from the last to the first.
    fn condensed_vectors(&mut self) {
        for j in (0..self.boundaries.len()).rev() {
            let (done, rest) = self.boundaries.split_at_mut(j + 1);
            let bd = &mut done[j];
            let leg = &self.legs[j];
            let param = leg.param.as_ref().expect("legs before a boundary are parameterised");
            let tail_p = match rest.first() {
                Some(next) => slice(&next.hat_p),
                None => self.legs[j + 1].stages[0].p(),
            };
            let nt = tail_p.len();
            {
                let g = col_of_mut(&mut bd.gains, 0);
                for i in 0..nt {
                    g[i] = -tail_p[i];
                    g[nt + i] = -param.omega_vec[i];
                }
            }
            bd.bk.solve_in_place(bd.gains.as_mut().subcols_mut(0, 1));
            let hp = slice_mut(&mut bd.hat_p);
            hp.copy_from_slice(leg.stages[0].p());
            matvec(
                hp,
                Accum::Add,
                param.gamma[0].as_ref(),
                &col_of(&bd.gains, 0)[nt..],
                1.0,
            );
        }
    }

    /// Initial stage, boundaries forward, then each leg's vector part with its `θ` and
    /// its rollout, on the pool. With `rhs`, solves for the vectors of `rhs` instead of
    /// the problem's (a refinement correction).
    fn solve_forward(
        &mut self,
        problem: &LqProblem,
        rhs: Option<&LqVectors>,
        sol: &mut LqSolution,
    ) -> Result<(), LqError> {
        let (p0, g0) = match (self.boundaries.first(), rhs) {
            (Some(bd), r) => (slice(&bd.hat_p), r.map_or(slice(&problem.g0), |r| slice(&r.g0))),
            (None, r) => (
                self.legs[0].stages[0].p(),
                r.map_or(slice(&problem.g0), |r| slice(&r.g0)),
            ),
        };
        self.initial.solve(
            problem,
            g0,
            p0,
            slice_mut(&mut sol.xs[0]),
            slice_mut(&mut sol.lambdas[0]),
        )?;
        for (j, bd) in self.boundaries.iter().enumerate() {
            // [x_b; θ] = g + G x_s.
            let nt = bd.gains.nrows() / 2;
            let (xs_head, xs_rest) = sol.xs.split_at_mut(bd.b);
            let xb = slice_mut(&mut xs_rest[0]);
            let lb = slice_mut(&mut sol.lambdas[bd.b]);
            let g = col_of(&bd.gains, 0);
            xb.copy_from_slice(&g[..nt]);
            lb.copy_from_slice(&g[nt..]);
            let xs = slice(&xs_head[bd.s]);
            let fb = bd.gains.as_ref().subcols(1, xs.len());
            matvec(xb, Accum::Add, fb.subrows(0, nt), xs, 1.0);
            matvec(lb, Accum::Add, fb.subrows(nt, nt), xs, 1.0);
            // The leg's tail: p' = -Eᵀθ.
            let param = self.legs[j]
                .param
                .as_mut()
                .expect("legs before a boundary are parameterised");
            matvec_t(
                slice_mut(&mut param.tail_p),
                Accum::Replace,
                problem.knots[bd.b - 1].E.as_ref(),
                slice(&sol.lambdas[bd.b]),
                -1.0,
            );
        }
        let LqSolution { xs, us, lambdas, nus } = sol;
        let pieces = LegPieces {
            legs: &mut self.legs,
            xs,
            us,
            nus,
            lambdas: &mut lambdas[1..],
        };
        let f = |p: LegPiece<'_>| forward_leg(p, problem, rhs);
        match &self.team {
            Some(team) => team.for_each(&self.forward_pass, pieces, f),
            None => pieces.for_each(f),
        }
        first_error(&mut self.legs)
    }

    fn save_vector_parts(&mut self) {
        for leg in &mut self.legs {
            leg.stages.iter_mut().for_each(RiccatiStage::save_vector_part);
        }
        for bd in &mut self.boundaries {
            let g = col_of(&bd.gains, 0);
            let n = g.len();
            bd.saved[..n].copy_from_slice(g);
            bd.saved[n..].copy_from_slice(slice(&bd.hat_p));
        }
    }

    fn add_saved_vector_parts(&mut self) {
        for leg in &mut self.legs {
            leg.stages.iter_mut().for_each(RiccatiStage::add_saved_vector_part);
        }
        for bd in &mut self.boundaries {
            let n = bd.gains.nrows();
            for (a, b) in col_of_mut(&mut bd.gains, 0).iter_mut().zip(&bd.saved[..n]) {
                *a += b;
            }
            for (a, b) in slice_mut(&mut bd.hat_p).iter_mut().zip(&bd.saved[n..]) {
                *a += b;
            }
        }
    }
}

impl Leg {
    /// The leg's backward pass (with `p' = 0` after a parameterised leg), then the
    /// parameter's recursion.
    fn backward(&mut self, problem: &LqProblem, rhs: Option<&LqVectors>, pass: Pass) -> Result<(), LqError> {
        if let Some(param) = &mut self.param {
            param.tail_p.fill(0.0);
        }
        let tail = self.param.as_ref().map(|p| (p.zero_P.as_ref(), slice(&p.tail_p)));
        sweep(
            &mut self.stages,
            &mut self.scratch,
            problem,
            self.start,
            rhs,
            tail,
            pass,
        )?;
        if let Some(param) = &mut self.param {
            param.propagate(&mut self.stages, problem, self.start, pass);
        }
        Ok(())
    }
}

impl LegParam {
    /// Carries `Γ`, `Ω` (matrix pass) and `ω` back through the leg's knots (module docs).
    fn propagate(&mut self, stages: &mut [RiccatiStage], problem: &LqProblem, start: usize, pass: Pass) {
        let n = stages.len();
        let full = matches!(pass, Pass::Full { .. });
        if full {
            let e = &problem.knots[start + n - 1].E;
            linalg::copy_transposed(self.gamma[n].as_mut(), e.as_ref());
            linalg::negate(self.gamma[n].as_mut());
            self.omega.fill(0.0);
        }
        self.omega_vec.fill(0.0);
        for i in (0..n).rev() {
            self.propagate_knot(&mut stages[i], &problem.knots[start + i], i, full);
        }
        if full {
            linalg::symmetrize(self.omega.as_mut());
        }
    }

    /// One knot `i` of [`propagate`](Self::propagate): `Γ̃`, then `Ω`, `Γ_i` (matrix
    /// pass) and `ω`.
    fn propagate_knot(&mut self, st: &mut RiccatiStage, knot: &LqKnot, i: usize, full: bool) {
        let (nx, nu, _, ny) = st.dims();
        let nt = self.zero_P.nrows();
        let mu = st.mu_dyn();
        // Γ̃ = (I + P'G)⁻¹ Γ'.
        if full && mu > 0.0 {
            linalg::copy(self.gamma_tilde[i].as_mut(), self.gamma[i + 1].as_ref());
            st.prox_solve_in_place(self.gamma_tilde[i].as_mut());
        }
        if mu > 0.0 {
            self.g_products(st, i, full);
        }
        if full {
            // Ω -= Γ'ᵀ G Γ̃.
            if mu > 0.0 {
                matmul(
                    self.omega.as_mut(),
                    Accum::Add,
                    self.gamma[i + 1].as_ref().transpose(),
                    self.ggt.as_ref().submatrix(0, 0, ny, nt),
                    -1.0,
                );
            }
            if nu > 0 {
                self.subtract_control_curvature(st, knot, i);
            }
            // Γ_t = Tᵀ Γ̃.
            let (head, rest) = self.gamma.split_at_mut(i + 1);
            let gt = tilde(&rest[0], &self.gamma_tilde[i], mu);
            let t = st.z_gains().submatrix(0, 1, ny, nx);
            matmul(head[i].as_mut(), Accum::Replace, t.transpose(), gt, 1.0);
        }
        // ω += Γ̃ᵀ t0 - Γ'ᵀ G p̃.
        let gt = tilde(&self.gamma[i + 1], &self.gamma_tilde[i], mu);
        let w = slice_mut(&mut self.omega_vec);
        matvec_t(w, Accum::Add, gt, st.z_feedforward(), 1.0);
        if mu > 0.0 {
            matvec_t(w, Accum::Add, self.gamma[i + 1].as_ref(), &slice(&self.gp)[..ny], -1.0);
        }
    }

    /// `G Γ̃` (matrix pass) and `G p̃` at knot `i` (`G = mu I` when `E = -I`).
    fn g_products(&mut self, st: &RiccatiStage, i: usize, full: bool) {
        let (ny, nt, mu) = (st.dims().3, self.zero_P.nrows(), st.mu_dyn());
        let gt = self.gamma_tilde[i].as_ref();
        let mut ggt = self.ggt.as_mut().submatrix_mut(0, 0, ny, nt);
        let gpv = &mut slice_mut(&mut self.gp)[..ny];
        if st.e_is_minus_identity() {
            if full {
                for j in 0..nt {
                    for r in 0..ny {
                        ggt[(r, j)] = mu * gt[(r, j)];
                    }
                }
            }
            for (a, b) in gpv.iter_mut().zip(st.ptilde_vec()) {
                *a = mu * b;
            }
        } else {
            if full {
                matmul(ggt, Accum::Replace, st.g(), gt, 1.0);
            }
            matvec(gpv, Accum::Replace, st.g(), st.ptilde_vec(), 1.0);
        }
    }

    /// `Ω -= (B̃ᵀΓ̃)ᵀ H_uu (B̃ᵀΓ̃)` at knot `i`, `H_uu` from `K⁻¹[I; 0]`.
    fn subtract_control_curvature(&mut self, st: &mut RiccatiStage, knot: &LqKnot, i: usize) {
        let (_, nu, nc, _) = st.dims();
        let nt = self.zero_P.nrows();
        let gt = tilde(&self.gamma[i + 1], &self.gamma_tilde[i], st.mu_dyn());
        let bt = st.b_tilde(knot);
        let mut bg = self.bg.as_mut().submatrix_mut(0, 0, nu, nt);
        matmul(bg.rb_mut(), Accum::Replace, bt.transpose(), gt, 1.0);
        let mut kinv = self.kinv.as_mut().submatrix_mut(0, 0, nu + nc, nu);
        kinv.fill(0.0);
        for r in 0..nu {
            kinv[(r, r)] = 1.0;
        }
        st.kkt_solve_in_place(kinv.rb_mut());
        let huu = self.kinv.as_ref().submatrix(0, 0, nu, nu);
        let bg = self.bg.as_ref().submatrix(0, 0, nu, nt);
        let mut hbg = self.hbg.as_mut().submatrix_mut(0, 0, nu, nt);
        matmul(hbg.rb_mut(), Accum::Replace, huu, bg, 1.0);
        matmul(self.omega.as_mut(), Accum::Add, bg.transpose(), hbg.as_ref(), -1.0);
    }
}

/// `Γ̃ = (I + P'G)⁻¹ Γ'` when the dynamics have a proximal term (`mu > 0`), `Γ'` itself
/// otherwise.
fn tilde<'a>(gamma_next: &'a Mat<f64>, gamma_tilde: &'a Mat<f64>, mu: f64) -> MatRef<'a, f64> {
    if mu > 0.0 {
        gamma_tilde.as_ref()
    } else {
        gamma_next.as_ref()
    }
}

/// A leg with the parts of the solution it writes: `xs, us, nus` from its first knot,
/// `lambdas[i]` the co-state after its knot `i`.
struct LegPiece<'a> {
    leg: &'a mut Leg,
    xs: &'a mut [Col<f64>],
    us: &'a mut [Col<f64>],
    nus: &'a mut [Col<f64>],
    lambdas: &'a mut [Col<f64>],
}

/// The legs not handed out yet, with the solution from the first one's first knot on;
/// yields one [`LegPiece`] at a time (for the team's threads to take in turn).
struct LegPieces<'a> {
    legs: &'a mut [Leg],
    xs: &'a mut [Col<f64>],
    us: &'a mut [Col<f64>],
    nus: &'a mut [Col<f64>],
    lambdas: &'a mut [Col<f64>],
}

impl<'a> Iterator for LegPieces<'a> {
    type Item = LegPiece<'a>;

    fn next(&mut self) -> Option<LegPiece<'a>> {
        let (leg, rest) = std::mem::take(&mut self.legs).split_first_mut()?;
        // The last leg takes what is left of every array.
        let len = rest.first().map_or(usize::MAX, |next| next.start - leg.start);
        fn cut<'b>(v: &mut &'b mut [Col<f64>], len: usize) -> &'b mut [Col<f64>] {
            let all = std::mem::take(v);
            let (head, tail) = all.split_at_mut(len.min(all.len()));
            *v = tail;
            head
        }
        let (xs, us, nus) = (cut(&mut self.xs, len), cut(&mut self.us, len), cut(&mut self.nus, len));
        let lambdas = cut(&mut self.lambdas, len);
        self.legs = rest;
        Some(LegPiece {
            leg,
            xs,
            us,
            nus,
            lambdas,
        })
    }
}

/// One leg's vector part with its `θ` (for parameterised legs) and its rollout.
fn forward_leg(piece: LegPiece<'_>, problem: &LqProblem, rhs: Option<&LqVectors>) {
    let LegPiece {
        leg,
        xs,
        us,
        nus,
        lambdas,
    } = piece;
    leg.result = (|| {
        let n = leg.stages.len();
        match &mut leg.param {
            Some(param) => {
                let tail = Some((param.zero_P.as_ref(), slice(&param.tail_p)));
                sweep(
                    &mut leg.stages,
                    &mut leg.scratch,
                    problem,
                    leg.start,
                    rhs,
                    tail,
                    Pass::Vectors,
                )?;
                rollout(
                    &mut leg.stages,
                    &problem.knots[leg.start..leg.start + n],
                    tail,
                    xs,
                    us,
                    nus,
                    &mut lambdas[..n - 1],
                    (slice_mut(&mut param.x_end), slice_mut(&mut param.lambda_end)),
                    Outputs::All,
                )
            }
            // The last leg's vector part does not depend on θ: it is the backward pass's.
            None => rollout(
                &mut leg.stages,
                &problem.knots[leg.start..leg.start + n],
                None,
                xs,
                us,
                nus,
                &mut lambdas[..n - 1],
                (&mut [], &mut []),
                Outputs::All,
            ),
        }
    })();
}

/// The error of the last failing leg (the serial recursion reports the latest knot
/// first), resetting every leg's result.
fn first_error(legs: &mut [Leg]) -> Result<(), LqError> {
    let mut out = Ok(());
    for leg in legs.iter_mut().rev() {
        let r = std::mem::replace(&mut leg.result, Ok(()));
        if out.is_ok() {
            out = r;
        }
    }
    out
}

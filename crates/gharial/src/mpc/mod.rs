//! Receding-horizon control (model-predictive control) with any solver of the
//! [`Solver`] trait.
//!
//! A cycle measures the state `x`, solves the horizon from it with a budget of
//! iterations and wall time, warm-started from the last solution shifted by one stage,
//! and applies the feedback policy of ProxDDP (57),
//! `u(t) = u_0 + K_0 (x(t) ⊖ x_0)`, between cycles at any rate ([`Mpc::control`]).
//! Between cycles [`Mpc::shift`] moves the horizon one stage along: the stages rotate in
//! place, the stage that leaves goes to the back of the queue and the next queued stage
//! becomes the last (a periodic schedule of contact phases, say); the solver's workspace
//! rotates with them, so that nothing is allocated after [`Mpc::new`], even when the
//! new last stage has other constraints than the one that left. Parameters of the
//! stages (targets, weights) move in place through their handles ([`crate::param`]);
//! [`Mpc::shift`] names the stage object that became the last, so that its targets can
//! be set for its time.
//!
//! ```text
//! let mut mpc = Mpc::new(problem, ProxDdp::new(opts), queue, guess, MpcOptions::default())?;
//! loop {
//!     mpc.solve(&x)?;                    // one cycle: x measured
//!     let id = mpc.shift()?;             // stage object `id` entered at the end
//!     set_targets(id, t + N dt);
//!     while waiting { mpc.control(&x, &mut u)?; apply(u); }
//! }
//! ```

pub mod simulate;

use std::sync::Arc;
use std::time::Duration;

pub use simulate::{ClosedLoop, CycleRecord, DiscretePlant, Plant, Push, Record, Stopped, simulate};

use faer::Mat;

use crate::error::{Error, Result, check_dim, check_finite};
use crate::problem::{Problem, StageModel};
use crate::solvers::{InitialGuess, Solution, Solver, skeleton};
use crate::spaces::Manifold;

/// The per-cycle budget of [`Mpc`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct MpcOptions {
    /// Solver iterations per cycle (1: the real-time iteration of the ProxDDP paper's
    /// MPC experiments).
    pub max_iters: usize,
    /// Wall-time budget per cycle (`None`: iterations only).
    pub max_time: Option<Duration>,
    /// Whether a cycle that ends at `max_iters` evaluates the derivatives and residuals
    /// at the plan it returns (default true). The next cycle evaluates the shifted
    /// problem anyway, so they serve only the reported status, `prim_err` and `dual_err`:
    /// off, a cycle saves one derivative evaluation of the horizon, ends as
    /// `MaxIterations` with the residuals of the point before its last step, and returns
    /// the same plan, cost and feedback gains. Solvers without the option always
    /// evaluate them.
    pub final_residuals: bool,
}

impl Default for MpcOptions {
    fn default() -> Self {
        Self {
            max_iters: 1,
            max_time: None,
            final_residuals: true,
        }
    }
}

impl MpcOptions {
    /// The options after `f` changed them (builder style).
    pub fn with(mut self, f: impl FnOnce(&mut Self)) -> Self {
        f(&mut self);
        self
    }
}

/// The warm start of the next cycle: the last solution, shifted by one stage, with its
/// feedback gains (the policy of a cycle that takes no iteration).
#[derive(Debug)]
struct Guess {
    xs: Vec<Vec<f64>>,
    us: Vec<Vec<f64>>,
    lambdas: Vec<Vec<f64>>,
    nus: Vec<Vec<f64>>,
    feedback: Vec<Mat<f64>>,
}

impl Guess {
    fn view(&self) -> InitialGuess<'_> {
        InitialGuess {
            xs: &self.xs,
            us: &self.us,
            lambdas: Some(&self.lambdas),
            nus: Some(&self.nus),
        }
    }

    /// Copies `sol` (of the same problem) into the guess.
    fn load(&mut self, sol: &Solution) {
        skeleton::copy_trajectory(&mut self.xs, &sol.xs);
        skeleton::copy_trajectory(&mut self.us, &sol.us);
        skeleton::copy_trajectory(&mut self.lambdas, &sol.lambdas);
        skeleton::copy_trajectory(&mut self.nus, &sol.nus);
        for (k, s) in self.feedback.iter_mut().zip(&sol.feedback) {
            k.copy_from(s);
        }
    }

    /// Moves everything one stage earlier; the last state, control and co-state repeat,
    /// the new last stage's path multipliers (`nc_tail` rows) are zero. The initial
    /// co-state `λ_0` takes `λ_1` when both live in the state tangent space.
    fn shift(&mut self, nc_tail: usize) {
        shift_vectors(&mut self.xs);
        shift_vectors(&mut self.us);
        if self.lambdas[0].len() == self.lambdas[1].len() {
            shift_vectors(&mut self.lambdas);
        } else {
            shift_vectors(&mut self.lambdas[1..]);
        }
        let n = self.us.len();
        skeleton::shift_rows(&mut self.nus, n, nc_tail);
        repeat_last_after_shift(&mut self.feedback, |a, b| a.copy_from(b));
    }
}

/// `v[t] = v[t + 1]` for all but the last entry, which keeps its value (entries of equal
/// sizes, copied by `copy`; no allocation).
fn repeat_last_after_shift<T>(v: &mut [T], copy: impl Fn(&mut T, &T)) {
    let n = v.len();
    if n < 2 {
        return;
    }
    v.rotate_left(1);
    let (head, tail) = v.split_at_mut(n - 1);
    copy(&mut tail[0], &head[n - 2]);
}

/// [`repeat_last_after_shift`] of vectors.
fn shift_vectors(v: &mut [Vec<f64>]) {
    repeat_last_after_shift(v, |a, b| a.copy_from_slice(b));
}

/// The feedback policy of ProxDDP (57), `u(x) = u_0 + K_0 (x ⊖ x_0)`, of the last cycle
/// (before the first, the initial guess's first control without feedback).
#[derive(Debug, Clone)]
pub struct Policy {
    space: Arc<dyn Manifold>,
    /// The first state of the last solution.
    pub x0: Vec<f64>,
    /// The first control of the last solution.
    pub u0: Vec<f64>,
    /// The first feedback gain of the last solution (`nu x ndx`).
    pub k0: Mat<f64>,
    dx: Vec<f64>,
}

impl Policy {
    /// The policy before the first cycle: the guess's first control, no feedback.
    fn new(problem: &Problem, guess: &Guess) -> Self {
        let space = problem.space(0).clone();
        let (ndx, nu) = (space.ndx(), problem.nu(0));
        Self {
            x0: guess.xs[0].clone(),
            u0: guess.us[0].clone(),
            k0: Mat::zeros(nu, ndx),
            dx: vec![0.0; ndx],
            space,
        }
    }

    /// The policy of `sol` with the gain `k0`.
    fn load(&mut self, sol: &Solution, k0: &Mat<f64>) {
        self.x0.copy_from_slice(&sol.xs[0]);
        self.u0.copy_from_slice(&sol.us[0]);
        self.k0.copy_from(k0);
    }

    /// Writes `u(x) = u_0 + K_0 (x ⊖ x_0)` into `u`.
    ///
    /// # Errors
    /// If `x` or `u` has the wrong size, or `x` is not finite or not on the state space.
    pub fn control(&mut self, x: &[f64], u: &mut [f64]) -> Result<()> {
        check_dim("policy: state x", self.space.nx(), x.len())?;
        check_dim("policy: control u", self.u0.len(), u.len())?;
        check_finite("policy: state x", x)?;
        if !self.space.is_valid(x) {
            return Err(Error::InvalidModel(
                "policy: x is not a valid point of the state space".into(),
            ));
        }
        self.space.difference(&self.x0, x, &mut self.dx);
        u.copy_from_slice(&self.u0);
        crate::linalg::matvec(u, faer::Accum::Add, self.k0.as_ref(), &self.dx, 1.0);
        Ok(())
    }
}

/// A receding-horizon controller: a problem, a solver set up for it and the stages
/// queued to enter it (module documentation).
pub struct Mpc<S: Solver> {
    problem: Problem,
    solver: S,
    queue: Vec<StageModel>,
    /// The queue slot whose stage enters next.
    head: usize,
    /// Which stage object sits at each knot and in each queue slot: the horizon's
    /// stages are numbered `0..N` and the queue's `N..N + Q` at construction.
    knot_ids: Vec<usize>,
    queue_ids: Vec<usize>,
    guess: Guess,
    solved: bool,
    cycles: usize,
    policy: Policy,
}

impl<S: Solver> std::fmt::Debug for Mpc<S> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Mpc")
            .field("solver", &self.solver.name())
            .field("horizon", &self.problem.horizon())
            .field("queue", &self.queue.len())
            .field("cycles", &self.cycles)
            .finish_non_exhaustive()
    }
}

impl<S: Solver> Mpc<S> {
    /// A controller for `problem` with `solver`, the stages of `queue` entering the
    /// horizon in turn after the first shift (empty: the stage that leaves comes back at
    /// the end, a time-invariant or periodic horizon), starting from `guess`. Allocates
    /// everything the cycles need.
    ///
    /// # Errors
    /// If `max_iters` is 0, the guess does not fit the problem, the stages do not all
    /// have the sizes of stage 0, or the solver refuses the problem or a queued stage.
    pub fn new(
        problem: Problem,
        mut solver: S,
        queue: Vec<StageModel>,
        guess: InitialGuess<'_>,
        options: MpcOptions,
    ) -> Result<Self> {
        crate::error::check_positive("max_iters", options.max_iters as f64)?;
        guess.check(&problem)?;
        solver.set_limits(options.max_iters, options.max_time);
        solver.set_final_residuals(options.final_residuals);
        solver.setup_receding(&problem, &queue)?;
        let shaped = Solution::new(&problem, 0);
        let mut g = Guess {
            xs: guess.xs.to_vec(),
            us: guess.us.to_vec(),
            lambdas: shaped.lambdas,
            nus: shaped.nus,
            feedback: shaped.feedback,
        };
        if let Some(l) = guess.lambdas {
            skeleton::copy_trajectory(&mut g.lambdas, l);
        }
        if let Some(v) = guess.nus {
            skeleton::copy_trajectory(&mut g.nus, v);
        }
        let n = problem.horizon();
        skeleton::Receding::of(&problem, &queue)?.reserve_rows(&mut g.nus, n);
        Ok(Self {
            policy: Policy::new(&problem, &g),
            knot_ids: (0..n).collect(),
            queue_ids: (n..n + queue.len()).collect(),
            problem,
            solver,
            queue,
            head: 0,
            guess: g,
            solved: false,
            cycles: 0,
        })
    }

    /// One cycle: solves the horizon from the measured state `x` within the budget,
    /// warm-started from the shifted last solution (or the initial guess), and updates
    /// the policy. The solution's [`Solution::status`] says how the solve stopped; the
    /// policy follows its last accepted iterate whatever the status. A cycle that takes
    /// no iteration (a time budget spent before the first) has no gains of its own: the
    /// policy's `K_0` is then the last solution's gain of the same knot (`K_1` before the
    /// shift; zero before any solution).
    ///
    /// # Errors
    /// If `x` has the wrong size, is not finite or not on the state space, or the
    /// solver reports an error (the controller is then unchanged but for `x_0`).
    pub fn solve(&mut self, x: &[f64]) -> Result<&Solution> {
        self.problem.set_x0(x)?;
        self.guess.xs[0].copy_from_slice(x);
        let sol = self.solver.solve(&self.problem, self.guess.view())?;
        // A converged solve reports gains at its point (a pass at the guess when it took
        // no iteration); a budget spent before the first iteration leaves none.
        let k0 = if sol.iterations == 0 && !sol.status.converged() {
            &self.guess.feedback[0]
        } else {
            &sol.feedback[0]
        };
        self.policy.load(sol, k0);
        self.solved = true;
        Ok(self.solver.solution())
    }

    /// Moves the horizon one stage along (module documentation) and prepares the warm
    /// start of the next cycle; returns the number of the stage object that became the
    /// last stage (horizon stages are `0..N`, queued ones `N..`, in their order at
    /// construction), so that its parameters can be set for its time.
    ///
    /// # Errors
    /// If the solver cannot follow the shift (see [`Solver::shift`]); then nothing moved.
    pub fn shift(&mut self) -> Result<usize> {
        if self.solved {
            self.guess.load(self.solver.solution());
        }
        let slot = if self.queue.is_empty() {
            self.problem.rotate()?;
            None
        } else {
            self.problem.shift(&mut self.queue[self.head])?;
            Some(self.head)
        };
        if let Err(e) = self.solver.shift(&self.problem, slot) {
            self.undo_problem_shift(slot);
            return Err(e);
        }
        let n = self.problem.horizon();
        self.guess.shift(self.problem.stages()[n - 1].nc());
        match slot {
            Some(s) => crate::problem::shift_in(&mut self.knot_ids, &mut self.queue_ids[s]),
            None => self.knot_ids.rotate_left(1),
        }
        if !self.queue.is_empty() {
            self.head = (self.head + 1) % self.queue.len();
        }
        self.solved = false;
        self.cycles += 1;
        Ok(self.knot_ids[n - 1])
    }

    /// Puts the problem's stages back after a shift the solver refused.
    fn undo_problem_shift(&mut self, slot: Option<usize>) {
        let stages = self.problem.stages_mut();
        match slot {
            Some(s) => {
                let n = stages.len();
                std::mem::swap(&mut stages[n - 1], &mut self.queue[s]);
                stages.rotate_right(1);
            }
            None => stages.rotate_right(1),
        }
    }

    /// Changes the per-cycle budget ([`MpcOptions::max_iters`], [`MpcOptions::max_time`])
    /// from the next cycle on (a real-time loop adapting to the time left).
    ///
    /// # Errors
    /// If `max_iters` is 0.
    pub fn set_budget(&mut self, max_iters: usize, max_time: Option<std::time::Duration>) -> Result<()> {
        crate::error::check_positive("max_iters", max_iters as f64)?;
        self.solver.set_limits(max_iters, max_time);
        Ok(())
    }

    /// The feedback control `u(x) = u_0 + K_0 (x ⊖ x_0)` of the last cycle (57), at any
    /// state `x` between cycles.
    ///
    /// # Errors
    /// As [`Policy::control`].
    pub fn control(&mut self, x: &[f64], u: &mut [f64]) -> Result<()> {
        self.policy.control(x, u)
    }

    /// The feedback policy of the last cycle.
    pub fn policy(&self) -> &Policy {
        &self.policy
    }

    /// The problem over the current horizon.
    pub fn problem(&self) -> &Problem {
        &self.problem
    }

    /// The solver.
    pub fn solver(&self) -> &S {
        &self.solver
    }

    /// The solution of the last cycle.
    pub fn solution(&self) -> &Solution {
        self.solver.solution()
    }

    /// The stage object at each knot (numbers as returned by [`Mpc::shift`]).
    pub fn stage_ids(&self) -> &[usize] {
        &self.knot_ids
    }

    /// Number of shifts so far.
    pub fn cycles(&self) -> usize {
        self.cycles
    }
}

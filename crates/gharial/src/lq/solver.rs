//! One interface for the LQ solvers of the nonlinear solvers: the serial Riccati
//! recursion, or the parallel one when more than one thread is asked for.

use super::{LqError, LqProblem, LqSolution, ParallelRiccatiSolver, RiccatiOptions, RiccatiSolver, RiccatiStage};

/// The serial [`RiccatiSolver`], and with `num_threads > 1` a [`ParallelRiccatiSolver`]
/// that takes the backward and forward passes.
///
/// The parallel legs do not give the per-knot gains of the whole horizon (those of a
/// leg's last knots are conditional on its boundary co-state), so the serial solver runs
/// whenever the gains are needed: when the rollout gains are on (nonlinear rollouts read
/// them at every step), and once more in [`LqSolver::stages`] after a parallel pass. The
/// two give the same solution up to rounding.
#[derive(Debug)]
pub struct LqSolver {
    serial: RiccatiSolver,
    parallel: Option<ParallelRiccatiSolver>,
    rollout_gains: bool,
    /// The primal regularisation of the last parallel backward pass whose gains the
    /// serial solver does not hold yet.
    pending: Option<f64>,
}

impl LqSolver {
    /// Allocates the solvers for problems with the dimensions of `problem`: the serial one
    /// with `options`, and for `num_threads > 1` the parallel one with as many legs.
    ///
    /// # Errors
    /// As [`RiccatiSolver::with_options`] and [`ParallelRiccatiSolver::new`].
    pub fn new(problem: &LqProblem, options: RiccatiOptions, num_threads: usize) -> Result<Self, LqError> {
        Self::with_team(problem, options, num_threads, super::parallel::team_for(num_threads)?)
    }

    /// As [`LqSolver::new`], the parallel solver on the threads of `team` (shared with the
    /// solver's stage-wise passes).
    pub(crate) fn with_team(
        problem: &LqProblem,
        options: RiccatiOptions,
        num_threads: usize,
        team: Option<std::sync::Arc<crate::team::Team>>,
    ) -> Result<Self, LqError> {
        let parallel = if num_threads > 1 {
            Some(ParallelRiccatiSolver::with_team(
                problem,
                num_threads,
                options.refinement_steps,
                team,
            )?)
        } else {
            None
        };
        Ok(Self {
            serial: RiccatiSolver::with_options(problem, options)?,
            parallel,
            rollout_gains: options.rollout_gains,
            pending: None,
        })
    }

    /// Whether the next passes run on the parallel solver.
    pub fn is_parallel(&self) -> bool {
        self.parallel.is_some() && !self.rollout_gains
    }

    /// Backward pass with the primal regularisation `primal_reg` (see
    /// [`RiccatiSolver::backward`]).
    pub fn backward(&mut self, problem: &LqProblem, primal_reg: f64) -> Result<(), LqError> {
        match (&mut self.parallel, self.rollout_gains) {
            (Some(par), false) => {
                self.pending = None;
                par.backward(problem, primal_reg)?;
                self.pending = Some(primal_reg);
                Ok(())
            }
            _ => {
                self.pending = None;
                self.serial.backward(problem, primal_reg)
            }
        }
    }

    /// Forward pass of the last backward pass (see [`RiccatiSolver::forward`]).
    pub fn forward(&mut self, problem: &LqProblem, sol: &mut LqSolution) -> Result<(), LqError> {
        match (&mut self.parallel, self.pending) {
            (Some(par), Some(_)) => par.forward(problem, sol),
            _ => self.serial.forward(problem, sol),
        }
    }

    /// Sets the iterative refinement steps of both solvers.
    pub(crate) fn set_refinement_steps(&mut self, steps: usize) {
        self.serial.set_refinement_steps(steps);
        if let Some(par) = &mut self.parallel {
            par.set_refinement_steps(steps);
        }
    }

    /// Turns the rollout gains on or off (on: the serial solver takes the passes).
    pub(crate) fn set_rollout_gains(&mut self, on: bool) {
        self.serial.set_rollout_gains(on);
        self.rollout_gains = on;
    }

    /// Whether [`stages`](Self::stages) still reads the problem: a parallel backward pass
    /// whose per-knot gains the serial solver has not computed yet.
    pub(crate) fn reads_problem_later(&self) -> bool {
        self.pending.is_some()
    }

    /// The serial solver's knot `t` after a serial backward pass (rollout gains on).
    pub fn stage(&self, t: usize) -> &RiccatiStage {
        self.serial.stage(t)
    }

    /// The per-knot gains and value functions of the last backward pass on `problem`:
    /// after a parallel pass, a serial backward pass computes them first.
    ///
    /// # Errors
    /// As [`RiccatiSolver::backward`].
    pub fn stages(&mut self, problem: &LqProblem) -> Result<&[RiccatiStage], LqError> {
        if let Some(reg) = self.pending.take() {
            self.serial.backward(problem, reg)?;
        }
        Ok(self.serial.stages())
    }
}

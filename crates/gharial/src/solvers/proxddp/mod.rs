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
mod run;
mod workspace;

pub use options::{ACTIVE_SET_ITERS_MAX, DynamicsStep, HessianApprox, Merit, ProxDdpOptions, Rollout, StepAcceptance};

use workspace::Workspace;

use crate::error::Result;
use crate::problem::{Problem, StageModel};
use crate::solvers::filter::Filter;
use crate::solvers::log::{COST, Column, Format, ITER, Table};
use crate::solvers::skeleton::{Signature, follow_shift, not_receding, solution_for};
use crate::solvers::{Callback, InitialGuess, Solution};

/// ProxDDP's iteration table.
pub const TABLE: Table = Table(COLUMNS);

/// The columns of ProxDDP's iteration table.
const COLUMNS: &[Column] = &[
    ITER,
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
    COST,
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
        self.setup_with(problem, None)
    }

    fn setup_with(&mut self, problem: &Problem, queue: Option<&[StageModel]>) -> Result<()> {
        self.options.validate()?;
        self.signature = Signature::default();
        self.ws = Some(Box::new(Workspace::new(problem, &self.options, queue)?));
        self.solution = solution_for(problem, self.options.max_iters, queue)?;
        self.signature = Signature::of(problem);
        self.filter = Filter::new(self.options.max_iters.saturating_add(1), 1e-5, 1e-5);
        Ok(())
    }

    /// See [`Solver::shift`](crate::solvers::Solver::shift).
    fn shift_workspace(&mut self, problem: &Problem, slot: Option<usize>) -> Result<()> {
        let ws = self.ws.as_mut().ok_or_else(|| not_receding("ProxDdp"))?;
        ws.shift(problem, slot)?;
        follow_shift(problem, &mut self.solution, &mut self.signature);
        Ok(())
    }

    fn run(
        &mut self,
        problem: &Problem,
        guess: InitialGuess<'_>,
        callback: Option<&mut dyn Callback>,
    ) -> Result<&Solution> {
        self.signature.check(problem, "ProxDdp")?;
        guess.check(problem)?;
        let mut cx = run::Context {
            problem,
            opts: &self.options,
            ws: self.ws.as_mut().expect("checked by the signature"),
            filter: &mut self.filter,
        };
        run::solve(&mut cx, &guess, &mut self.solution, callback);
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
    fn set_limits(&mut self, max_iters: usize, max_time: Option<std::time::Duration>) {
        self.options.max_iters = max_iters;
        self.options.max_time = max_time;
    }
    fn set_final_residuals(&mut self, on: bool) {
        self.options.final_residuals = on;
    }
    fn setup_receding(&mut self, problem: &Problem, queue: &[StageModel]) -> Result<()> {
        self.setup_with(problem, Some(queue))
    }
    fn shift(&mut self, problem: &Problem, slot: Option<usize>) -> Result<()> {
        self.shift_workspace(problem, slot)
    }
}

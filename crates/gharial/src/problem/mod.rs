//! The optimal control problem every solver consumes, and its evaluation.
//!
//! ```text
//! minimise    Σ_{t<N} ℓ_t(x_t, u_t) + ℓ_N(x_N)
//! subject to  x_0 = x̂               (or a general initial constraint ω(x_0) = 0)
//!             f_t(x_t, u_t, x_{t+1}) = 0                       (dynamics, paper (21b))
//!             h_{t,i}(x_t, u_t) ∈ C_{t,i}                       (path constraints)
//!             h_{N,i}(x_N) ∈ C_{N,i}                            (terminal constraints)
//! ```
//! A [`Problem`] is a description (models are shared, immutable `Arc`s); a
//! [`ProblemData`] holds everything an evaluation writes and is created once per
//! problem, so that solvers evaluate values and derivatives without allocating.

mod data;
mod kkt;
pub mod minimum_time;

pub(crate) use data::add_jy_product;
pub use data::{DynamicsData, ImplicitSolve, ProblemData, StageData};
pub use kkt::{KktResiduals, kkt_residuals};
pub use minimum_time::{ContinuousStage, MinimumTime};

use std::sync::Arc;

use crate::constraints::ConstraintSet;
use crate::costs::Cost;
use crate::dynamics::Dynamics;
use crate::error::{Error, Result, check_dim, check_finite};
use crate::functions::{StageFunction, UnaryFunction};
use crate::spaces::Manifold;

/// A constraint `h(x, u) ∈ C` with a name and its augmented-Lagrangian scale.
#[derive(Clone)]
pub struct StageConstraint {
    /// Name used in messages and reports.
    pub name: String,
    /// The residual `h(x, u)`.
    pub func: Arc<dyn StageFunction>,
    /// The set `C`.
    pub set: Arc<dyn ConstraintSet>,
    /// Per-constraint AL scaling (ProxDDP appendix C): the penalty parameter of this
    /// constraint is `scale · mu`. Default 1.
    pub scale: f64,
}

impl StageConstraint {
    /// A constraint with scale 1.
    pub fn new(name: impl Into<String>, func: Arc<dyn StageFunction>, set: Arc<dyn ConstraintSet>) -> Self {
        Self {
            name: name.into(),
            func,
            set,
            scale: 1.0,
        }
    }

    /// Sets the AL scale (must be positive and finite; checked when added to a stage).
    pub fn with_scale(mut self, scale: f64) -> Self {
        self.scale = scale;
        self
    }

    /// Number of rows.
    pub fn nr(&self) -> usize {
        self.func.nr()
    }

    fn validate(&self, what: &str, space: &dyn Manifold, nu: usize) -> Result<()> {
        let w = format!("{what} constraint `{}`", self.name);
        check_dim(format_args!("{w}: state size nx"), space.nx(), self.func.nx())?;
        check_dim(
            format_args!("{w}: state tangent size ndx"),
            space.ndx(),
            self.func.ndx(),
        )?;
        check_dim(format_args!("{w}: control size nu"), nu, self.func.nu())?;
        if let Some(d) = self.set.dim() {
            check_dim(format_args!("{w}: set dimension"), self.func.nr(), d)?;
        }
        if !(self.scale.is_finite() && self.scale > 0.0) {
            return Err(Error::InvalidModel(format!(
                "{w}: scale must be positive and finite, got {}",
                crate::error::Num(self.scale)
            )));
        }
        Ok(())
    }
}

/// One stage `t < N`: cost, dynamics and path constraints on `(x_t, u_t)`.
#[derive(Clone)]
pub struct StageModel {
    /// Running cost `ℓ_t(x, u)`.
    pub cost: Arc<dyn Cost>,
    /// Dynamics linking `x_t`, `u_t` and `x_{t+1}`.
    pub dynamics: Dynamics,
    constraints: Vec<StageConstraint>,
}

impl StageModel {
    /// A stage with the given cost and dynamics and no constraint.
    ///
    /// # Errors
    /// If the cost and dynamics dimensions disagree.
    pub fn new(cost: Arc<dyn Cost>, dynamics: Dynamics) -> Result<Self> {
        let s = dynamics.space();
        check_dim("stage cost: state size nx", s.nx(), cost.nx())?;
        check_dim("stage cost: state tangent size ndx", s.ndx(), cost.ndx())?;
        check_dim("stage cost: control size nu", dynamics.nu(), cost.nu())?;
        Ok(Self {
            cost,
            dynamics,
            constraints: Vec::new(),
        })
    }

    /// Adds a path constraint `h(x, u) ∈ C`.
    ///
    /// # Errors
    /// If its dimensions disagree with the stage.
    pub fn add_constraint(&mut self, c: StageConstraint) -> Result<()> {
        c.validate("stage", self.space().as_ref(), self.nu())?;
        self.constraints.push(c);
        Ok(())
    }

    /// Builder form of [`StageModel::add_constraint`].
    ///
    /// # Errors
    /// If its dimensions disagree with the stage.
    pub fn with_constraint(mut self, c: StageConstraint) -> Result<Self> {
        self.add_constraint(c)?;
        Ok(self)
    }

    /// The path constraints.
    pub fn constraints(&self) -> &[StageConstraint] {
        &self.constraints
    }

    /// State space of `x_t`.
    pub fn space(&self) -> &Arc<dyn Manifold> {
        self.dynamics.space()
    }

    /// State space of `x_{t+1}`.
    pub fn space_next(&self) -> &Arc<dyn Manifold> {
        self.dynamics.space_next()
    }

    /// Control size.
    pub fn nu(&self) -> usize {
        self.dynamics.nu()
    }

    /// Total number of constraint rows.
    pub fn nc(&self) -> usize {
        self.constraints.iter().map(|c| c.nr()).sum()
    }
}

/// How the first state is constrained.
#[derive(Clone)]
pub enum InitialCondition {
    /// `x_0 = x̂`, enforced through the residual `x_0 ⊖ x̂` (paper (49)).
    Fixed(Vec<f64>),
    /// A general constraint `ω(x_0) = 0` (paper appendix C, (65)); with zero rows `x_0`
    /// is free.
    Constraint(Arc<dyn UnaryFunction>),
}

/// An optimal control problem: initial condition, stages, terminal cost and
/// constraints.
#[derive(Clone)]
pub struct Problem {
    init: InitialCondition,
    stages: Vec<StageModel>,
    terminal_cost: Arc<dyn Cost>,
    terminal_constraints: Vec<StageConstraint>,
}

impl Problem {
    /// A problem with `x_0 = x0`.
    ///
    /// # Errors
    /// If there is no stage, dimensions of consecutive stages or of the terminal cost
    /// disagree, or `x0` has the wrong size, is not finite or not on the state manifold.
    pub fn new(x0: &[f64], stages: Vec<StageModel>, terminal_cost: Arc<dyn Cost>) -> Result<Self> {
        Self::with_initial(InitialCondition::Fixed(x0.to_vec()), stages, terminal_cost)
    }

    /// A problem with a general initial condition.
    ///
    /// # Errors
    /// As [`Problem::new`].
    pub fn with_initial(init: InitialCondition, stages: Vec<StageModel>, terminal_cost: Arc<dyn Cost>) -> Result<Self> {
        if stages.is_empty() {
            return Err(Error::InvalidModel("a problem needs at least one stage".into()));
        }
        for t in 0..stages.len() - 1 {
            let (a, b) = (stages[t].space_next(), stages[t + 1].space());
            check_dim(
                format_args!("stage {t}: next-state size nx vs stage {}", t + 1),
                b.nx(),
                a.nx(),
            )?;
            check_dim(
                format_args!("stage {t}: next-state tangent size ndx vs stage {}", t + 1),
                b.ndx(),
                a.ndx(),
            )?;
        }
        let last = stages[stages.len() - 1].space_next().clone();
        check_dim("terminal cost: state size nx", last.nx(), terminal_cost.nx())?;
        check_dim("terminal cost: state tangent size ndx", last.ndx(), terminal_cost.ndx())?;
        check_dim("terminal cost: control size nu (must be 0)", 0, terminal_cost.nu())?;
        let p = Self {
            init,
            stages,
            terminal_cost,
            terminal_constraints: Vec::new(),
        };
        p.validate_init()?;
        Ok(p)
    }

    fn validate_init(&self) -> Result<()> {
        let s = self.stages[0].space();
        match &self.init {
            InitialCondition::Fixed(x0) => check_x0(s.as_ref(), x0)?,
            InitialCondition::Constraint(f) => {
                check_dim("initial constraint: state size nx", s.nx(), f.nx())?;
                check_dim("initial constraint: state tangent size ndx", s.ndx(), f.ndx())?;
            }
        }
        Ok(())
    }

    /// Adds a terminal constraint `h(x_N) ∈ C` (its function has `nu = 0`).
    ///
    /// # Errors
    /// If its dimensions disagree with the final state.
    pub fn add_terminal_constraint(&mut self, c: StageConstraint) -> Result<()> {
        let space = self.stages[self.stages.len() - 1].space_next().clone();
        c.validate("terminal", space.as_ref(), 0)?;
        self.terminal_constraints.push(c);
        Ok(())
    }

    /// Builder form of [`Problem::add_terminal_constraint`].
    ///
    /// # Errors
    /// If its dimensions disagree with the final state.
    pub fn with_terminal_constraint(mut self, c: StageConstraint) -> Result<Self> {
        self.add_terminal_constraint(c)?;
        Ok(self)
    }

    /// Replaces the fixed initial state (receding-horizon use).
    ///
    /// # Errors
    /// If the problem has a general initial constraint, or `x0` has the wrong size, is
    /// not finite or not on the state manifold (as [`Problem::new`]); the problem is
    /// then unchanged.
    pub fn set_x0(&mut self, x0: &[f64]) -> Result<()> {
        match &mut self.init {
            InitialCondition::Fixed(v) => {
                check_x0(self.stages[0].space().as_ref(), x0)?;
                v.copy_from_slice(x0);
                Ok(())
            }
            InitialCondition::Constraint(_) => Err(Error::InvalidModel(
                "set_x0 on a problem with a general initial constraint".into(),
            )),
        }
    }

    /// The fixed initial state, if the initial condition is `x_0 = x̂`.
    pub fn x0(&self) -> Option<&[f64]> {
        match &self.init {
            InitialCondition::Fixed(v) => Some(v),
            InitialCondition::Constraint(_) => None,
        }
    }

    /// The initial condition.
    pub fn initial_condition(&self) -> &InitialCondition {
        &self.init
    }

    /// Number of initial-constraint rows.
    pub fn nc0(&self) -> usize {
        match &self.init {
            InitialCondition::Fixed(_) => self.stages[0].space().ndx(),
            InitialCondition::Constraint(f) => f.nr(),
        }
    }

    /// The stages `0..N`.
    pub fn stages(&self) -> &[StageModel] {
        &self.stages
    }

    /// Mutable access to the stages (e.g. to add constraints after construction).
    pub fn stages_mut(&mut self) -> &mut [StageModel] {
        &mut self.stages
    }

    /// Receding horizon: moves every stage one knot earlier and makes `incoming` the
    /// last stage; `incoming` receives the stage that left the horizon (stage 0), so that
    /// the models cycle without allocation. The initial state is unchanged (see
    /// [`Problem::set_x0`]).
    ///
    /// # Errors
    /// If `incoming` differs from stage 0 in its state or control sizes, or its state
    /// spaces do not fit at the end of the horizon (next to the last stage and the
    /// terminal cost); the problem is then unchanged.
    pub fn shift(&mut self, incoming: &mut StageModel) -> Result<()> {
        self.check_incoming(incoming)?;
        shift_in(&mut self.stages, incoming);
        Ok(())
    }

    /// Checks that `incoming` can follow the last stage and replace stage 0.
    fn check_incoming(&self, incoming: &StageModel) -> Result<()> {
        let first = &self.stages[0];
        let last = self.stages[self.stages.len() - 1].space_next();
        let dims = [
            ("state size nx", first.space().nx(), incoming.space().nx()),
            ("state tangent size ndx", first.space().ndx(), incoming.space().ndx()),
            ("control size nu", first.nu(), incoming.nu()),
            (
                "state size nx at the end of the horizon",
                last.nx(),
                incoming.space().nx(),
            ),
            (
                "state tangent size ndx at the end of the horizon",
                last.ndx(),
                incoming.space().ndx(),
            ),
            ("next-state size nx", last.nx(), incoming.space_next().nx()),
            ("next-state tangent size ndx", last.ndx(), incoming.space_next().ndx()),
        ];
        for (what, expected, got) in dims {
            check_dim(format_args!("shift: incoming stage {what}"), expected, got)?;
        }
        Ok(())
    }

    /// Receding horizon without a queue: moves every stage one knot earlier and makes
    /// stage 0 the last (a time-invariant or periodic horizon).
    ///
    /// # Errors
    /// As [`Problem::shift`] with stage 0 as the incoming stage.
    pub fn rotate(&mut self) -> Result<()> {
        self.check_incoming(&self.stages[0])?;
        self.stages.rotate_left(1);
        Ok(())
    }

    /// Whether every derivative the LQ subproblems are built from is the same at every
    /// point: dynamics with constant Jacobians into vector spaces, cost Hessians and
    /// constraint Jacobians the models declare constant, and a fixed initial state on a
    /// vector space (a linear-quadratic problem). The matrices of the LQ subproblem then
    /// change only with the solver's regularisation, and its factorization can be kept
    /// from one iteration to the next.
    pub fn has_constant_derivatives(&self) -> bool {
        let jacobians_constant = |cs: &[StageConstraint]| cs.iter().all(|c| c.func.jacobians_are_constant());
        matches!(self.init, InitialCondition::Fixed(_))
            && self.stages[0].space().is_vector_space()
            && self.stages.iter().all(|s| {
                s.dynamics.jacobians_are_constant()
                    && s.cost.hessian_is_constant()
                    && jacobians_constant(&s.constraints)
            })
            && self.terminal_cost.hessian_is_constant()
            && jacobians_constant(&self.terminal_constraints)
    }

    /// Horizon length `N` (number of stages).
    pub fn horizon(&self) -> usize {
        self.stages.len()
    }

    /// The terminal cost `ℓ_N`.
    pub fn terminal_cost(&self) -> &Arc<dyn Cost> {
        &self.terminal_cost
    }

    /// The terminal constraints.
    pub fn terminal_constraints(&self) -> &[StageConstraint] {
        &self.terminal_constraints
    }

    /// The constraints of knot `t`: the path constraints of stage `t` for `t < N`, the
    /// terminal constraints for `t = N`.
    pub fn constraints(&self, t: usize) -> &[StageConstraint] {
        if t < self.stages.len() {
            self.stages[t].constraints()
        } else {
            &self.terminal_constraints
        }
    }

    /// Space of state `x_t`, `t = 0..=N`.
    pub fn space(&self, t: usize) -> &Arc<dyn Manifold> {
        if t < self.stages.len() {
            self.stages[t].space()
        } else {
            self.stages[self.stages.len() - 1].space_next()
        }
    }

    /// Control size of stage `t` (0 for `t = N`).
    pub fn nu(&self, t: usize) -> usize {
        if t < self.stages.len() { self.stages[t].nu() } else { 0 }
    }

    /// Checks a trajectory guess: `N + 1` finite, valid states and `N` finite controls
    /// of the right sizes.
    ///
    /// # Errors
    /// Names the first offending entry.
    pub fn check_trajectory(&self, xs: &[Vec<f64>], us: &[Vec<f64>]) -> Result<()> {
        let n = self.horizon();
        check_dim("number of states xs (N + 1)", n + 1, xs.len())?;
        check_dim("number of controls us (N)", n, us.len())?;
        for (t, x) in xs.iter().enumerate() {
            let s = self.space(t);
            check_dim(format_args!("xs[{t}] size"), s.nx(), x.len())?;
            check_finite(format_args!("xs[{t}]"), x)?;
            if !s.is_valid(x) {
                return Err(Error::InvalidModel(format!(
                    "xs[{t}] is not a valid point of its state space"
                )));
            }
        }
        for (t, u) in us.iter().enumerate() {
            check_dim(format_args!("us[{t}] size"), self.nu(t), u.len())?;
            check_finite(format_args!("us[{t}]"), u)?;
        }
        Ok(())
    }

    /// Checks the sizes and finiteness of multipliers, laid out as in
    /// [`crate::solvers::Solution`] (`None`: absent).
    ///
    /// # Errors
    /// Names the first offending entry.
    pub fn check_multipliers(&self, lambdas: Option<&[Vec<f64>]>, nus: Option<&[Vec<f64>]>) -> Result<()> {
        let n = self.horizon();
        if let Some(l) = lambdas {
            check_dim("number of co-states lambdas (N + 1)", n + 1, l.len())?;
            check_dim("lambdas[0] size (initial constraint rows)", self.nc0(), l[0].len())?;
            for t in 0..n {
                check_dim(
                    format_args!("lambdas[{}] size", t + 1),
                    self.space(t + 1).ndx(),
                    l[t + 1].len(),
                )?;
            }
            for (t, v) in l.iter().enumerate() {
                check_finite(format_args!("lambdas[{t}]"), v)?;
            }
        }
        if let Some(v) = nus {
            check_dim("number of path multipliers nus (N + 1)", n + 1, v.len())?;
            for (t, s) in self.stages().iter().enumerate() {
                check_dim(format_args!("nus[{t}] size"), s.nc(), v[t].len())?;
            }
            let ncn: usize = self.terminal_constraints().iter().map(|c| c.nr()).sum();
            check_dim(format_args!("nus[{n}] size (terminal constraints)"), ncn, v[n].len())?;
            for (t, s) in v.iter().enumerate() {
                check_finite(format_args!("nus[{t}]"), s)?;
            }
        }
        Ok(())
    }
}

/// Moves every item one place earlier and swaps the last with `incoming` (which receives
/// the first): the receding-horizon shift of stages and of their data.
pub(crate) fn shift_in<T>(items: &mut [T], incoming: &mut T) {
    items.rotate_left(1);
    let n = items.len();
    std::mem::swap(&mut items[n - 1], incoming);
}

/// Checks a fixed initial state: size, finiteness, and that it lies on the manifold.
fn check_x0(space: &dyn Manifold, x0: &[f64]) -> Result<()> {
    check_dim("initial state x0", space.nx(), x0.len())?;
    check_finite("initial state x0", x0)?;
    if !space.is_valid(x0) {
        return Err(Error::InvalidModel(
            "initial state x0 is not a valid point of the state space (e.g. a quaternion of norm other than 1)".into(),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests;

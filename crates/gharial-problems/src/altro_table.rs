//! Problems of ALTRO's Table I (Howell et al. 2019, §IV-A) with the data of the authors'
//! problem definitions: the 1D block move and the Dubins car's parallel park, three
//! obstacles and escape.
//!
//! # Models
//! - *Block move*: the double integrator `ṗ = v`, `v̇ = u` on `R²`.
//! - *Dubins car*: `ẋ = v cos θ`, `ẏ = v sin θ`, `θ̇ = ω` on `R³` (the heading a plain
//!   coordinate, as in the authors' model), controls `(v, ω)`.
//!
//! Both integrated by RK4 (the authors use RK3). Every problem has the quadratic
//! objective `½ Σ dt ((x − x_f)ᵀQ(x − x_f) + uᵀRu) + ½ (x_N − x_f)ᵀQ_f(x_N − x_f)` and
//! the goal `x_N = x_f` as a terminal equality.
//!
//! | problem | N, T | Q, R, Q_f | constraints | guess |
//! |---|---|---|---|---|
//! | `block-move` | 21, 2 s | I, 0.1 I, I | `|u| ≤ 1.5` | `u = 0.01`, rollout |
//! | `car-parallel-park` | 101, 3 s | 1e-2 I, 1e-2 I, 100 I | `|x| ≤ 0.25`, `-0.001 ≤ y ≤ 1.001`, `|u| ≤ 2` | `u = 0.1`, rollout |
//! | `car-3-obstacles` | 101, 5 s | I, 0.1 I, 100 I | outside three discs of radius 0.1 at (0.25, 0.25), (0.5, 0.5), (0.75, 0.75) | `u = 0.01`, rollout |
//! | `car-escape` | 101, 3 s | 1e-3 I, 1e-2 I, 100 I | outside 170 discs of radius 0.5 that draw two rooms and a door, `|u| ≤ 5` | states interpolated through 6 poses, `u = 1` |
//!
//! Discs and state bounds are kept on the stages `1..N−1`, control bounds on every stage;
//! discs by `r² − |p − c|² ≤ 0`. The escape's guess
//! violates the dynamics (the paper's infeasible start, §III-B); a rollout of its
//! controls runs through the walls.

use std::sync::Arc;

use gharial::Result;
use gharial::autodiff::{AutoDiff, AutoOdeFn, AutoStageFn, ManifoldScalar};
use gharial::constraints::{BoxConstraint, NegativeOrthant};
use gharial::costs::{CostStack, QuadraticControlCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, ExplicitRungeKutta};
use gharial::functions::{ControlError, Slice, StageFunction, StateError, Unary};
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::solvers::proxddp::ProxDdpOptions;
use gharial::spaces::{Manifold, VectorSpace};

use crate::lqr::terminal_state;
use crate::{Example, rollout};

/// The double integrator `ṗ = v`, `v̇ = u`.
struct DoubleIntegrator;

impl AutoOdeFn for DoubleIntegrator {
    fn nx(&self) -> usize {
        2
    }
    fn nu(&self) -> usize {
        1
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], xdot: &mut [D]) {
        xdot[0] = x[1];
        xdot[1] = u[0];
    }
}

/// The Dubins car `(ẋ, ẏ, θ̇) = (v cos θ, v sin θ, ω)`.
struct DubinsCar;

impl AutoOdeFn for DubinsCar {
    fn nx(&self) -> usize {
        3
    }
    fn nu(&self) -> usize {
        2
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], xdot: &mut [D]) {
        xdot[0] = u[0] * x[2].cos();
        xdot[1] = u[0] * x[2].sin();
        xdot[2] = u[1];
    }
}

/// `r_i² − |p − c_i|² ≤ 0` for discs `(c_x, c_y, r)`, `p` the first two state
/// coordinates.
struct Discs(Vec<[f64; 3]>);

impl AutoStageFn for Discs {
    fn nx(&self) -> usize {
        3
    }
    fn nu(&self) -> usize {
        2
    }
    fn nr(&self) -> usize {
        self.0.len()
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], _u: &[D], out: &mut [D]) {
        for (o, &[cx, cy, r]) in out.iter_mut().zip(&self.0) {
            let (dx, dy) = (x[0] - cx, x[1] - cy);
            *o = -(dx * dx + dy * dy) + r * r;
        }
    }
}

/// The numbers of one problem of the table.
struct Spec {
    name: &'static str,
    horizon: usize,
    duration: f64,
    /// Diagonals of Q, R, Q_f.
    weights: [f64; 3],
    x0: Vec<f64>,
    xf: Vec<f64>,
    /// Constant guess of the controls.
    u_guess: f64,
    description: &'static str,
}

impl Spec {
    fn dt(&self) -> f64 {
        self.duration / self.horizon as f64
    }

    /// The problem with the control constraints `controls` on every running stage, the
    /// state constraints `states` on every running stage but the first (which cannot
    /// move `x_0`), and the goal constraint.
    fn problem(
        &self,
        ode: Arc<AutoDiff<impl AutoOdeFn + 'static>>,
        controls: &[StageConstraint],
        states: &[StageConstraint],
    ) -> Result<Problem> {
        let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(self.x0.len()));
        let nu = ode.inner().nu();
        let dt = self.dt();
        let [q, r, qf] = self.weights;
        let dynamics = Dynamics::Explicit(Arc::new(ExplicitRungeKutta::rk4(ode, dt)?));
        let nx = self.x0.len();
        let cost = CostStack::new(space.as_ref(), nu)
            .with(
                "x",
                Arc::new(QuadraticStateCost::diagonal(
                    space.clone(),
                    &self.xf,
                    &vec![q * dt; nx],
                    nu,
                )?),
                1.0,
            )?
            .with(
                "u",
                Arc::new(QuadraticControlCost::diagonal(
                    space.as_ref(),
                    &vec![0.0; nu],
                    &vec![r * dt; nu],
                )?),
                1.0,
            )?;
        let mut first = StageModel::new(Arc::new(cost), dynamics)?;
        for c in controls {
            first.add_constraint(c.clone())?;
        }
        let mut stage = first.clone();
        for c in states {
            stage.add_constraint(c.clone())?;
        }
        let mut stages = vec![stage; self.horizon];
        stages[0] = first;
        let terminal = Arc::new(QuadraticStateCost::diagonal(space.clone(), &self.xf, &vec![qf; nx], 0)?);
        Problem::new(&self.x0, stages, terminal)?.with_terminal_constraint(terminal_state(space, &self.xf)?)
    }

    /// The example from `problem`, with the controls' constant guess and `xs0` (`None`:
    /// their rollout).
    fn example(&self, problem: Problem, xs0: Option<Vec<Vec<f64>>>) -> Result<Example> {
        let us0 = vec![vec![self.u_guess; problem.nu(0)]; self.horizon];
        let xs0 = match xs0 {
            Some(xs) => xs,
            None => rollout(&problem, &us0)?,
        };
        Ok(Example {
            name: self.name,
            problem,
            xs0,
            us0,
            dt: Some(self.dt()),
            proxddp: ProxDdpOptions::default().with(|o| {
                o.tol = 1e-8;
                o.max_iters = 500;
            }),
            description: self.description,
        })
    }
}

/// Bounds `lower ≤ u ≤ upper` on the controls.
fn control_bounds(nx: usize, lower: &[f64], upper: &[f64]) -> Result<StageConstraint> {
    let space = VectorSpace::new(nx);
    let f = Arc::new(ControlError::new(&space, &vec![0.0; lower.len()])?);
    Ok(StageConstraint::new(
        "u_box",
        f,
        Arc::new(BoxConstraint::new(lower, upper)?),
    ))
}

/// `block-move` (module documentation).
///
/// # Errors
/// Never for these fixed numbers.
pub fn block_move() -> Result<Example> {
    let spec = Spec {
        name: "block-move",
        horizon: 20,
        duration: 2.0,
        weights: [1.0, 0.1, 1.0],
        x0: vec![0.0, 0.0],
        xf: vec![1.0, 0.0],
        u_guess: 0.01,
        description: "ALTRO Table I: double integrator moved one unit in 2 s, |u| <= 1.5, goal constraint",
    };
    let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(2));
    let ode = Arc::new(AutoDiff::ode(space, DoubleIntegrator)?);
    let problem = spec.problem(ode, &[control_bounds(2, &[-1.5], &[1.5])?], &[])?;
    spec.example(problem, None)
}

fn car_ode() -> Result<Arc<AutoDiff<DubinsCar>>> {
    Ok(Arc::new(AutoDiff::ode(Arc::new(VectorSpace::new(3)), DubinsCar)?))
}

/// The disc constraint on the car's position.
fn discs(discs: Vec<[f64; 3]>) -> Result<StageConstraint> {
    let f: Arc<dyn StageFunction> = Arc::new(AutoDiff::stage(Arc::new(VectorSpace::new(3)), Discs(discs))?);
    Ok(StageConstraint::new("discs", f, Arc::new(NegativeOrthant)))
}

/// `car-parallel-park` (module documentation).
///
/// # Errors
/// Never for these fixed numbers.
pub fn parallel_park() -> Result<Example> {
    let spec = Spec {
        name: "car-parallel-park",
        horizon: 100,
        duration: 3.0,
        weights: [1e-2, 1e-2, 100.0],
        x0: vec![0.0; 3],
        xf: vec![0.0, 1.0, 0.0],
        u_guess: 0.1,
        description: "ALTRO Table I: Dubins car moved one unit sideways in 3 s, |x| <= 0.25, \
                      -0.001 <= y <= 1.001, |u| <= 2, goal constraint",
    };
    let space = Arc::new(VectorSpace::new(3));
    let position = Arc::new(Slice::new(
        Arc::new(Unary::new(Arc::new(StateError::new(space, &[0.0; 3])?), 2)),
        &[0, 1],
    )?);
    let walls = StageConstraint::new(
        "x_box",
        position,
        Arc::new(BoxConstraint::new(&[-0.25, -0.001], &[0.25, 1.001])?),
    );
    let problem = spec.problem(car_ode()?, &[control_bounds(3, &[-2.0; 2], &[2.0; 2])?], &[walls])?;
    spec.example(problem, None)
}

/// `car-3-obstacles` (module documentation).
///
/// # Errors
/// Never for these fixed numbers.
pub fn three_obstacles() -> Result<Example> {
    let spec = Spec {
        name: "car-3-obstacles",
        horizon: 100,
        duration: 5.0,
        weights: [1.0, 0.1, 100.0],
        x0: vec![0.0; 3],
        xf: vec![1.0, 1.0, 0.0],
        u_guess: 0.01,
        description: "ALTRO Table I: Dubins car to (1, 1) in 5 s around three discs of radius 0.1 on the diagonal, \
                      goal constraint",
    };
    let obstacles = discs(vec![[0.25, 0.25, 0.1], [0.5, 0.5, 0.1], [0.75, 0.75, 0.1]])?;
    let problem = spec.problem(car_ode()?, &[], &[obstacles])?;
    spec.example(problem, None)
}

/// The escape's walls: discs of radius 0.5 along the lines of the authors' map.
fn escape_walls() -> Vec<[f64; 3]> {
    let line = |from: [f64; 2], to: [f64; 2], n: usize| {
        (0..n).map(move |i| {
            let s = i as f64 / (n - 1) as f64;
            [from[0] + s * (to[0] - from[0]), from[1] + s * (to[1] - from[1]), 0.5]
        })
    };
    line([0.0, 0.0], [0.0, 5.0], 30)
        .chain(line([5.0, 0.0], [5.0, 5.0], 30))
        .chain(line([10.0, 0.0], [10.0, 5.0], 30))
        .chain(line([0.0, 0.0], [10.0, 0.0], 50))
        .chain(line([0.0, 5.0], [3.0, 5.0], 15))
        .chain(line([5.0, 5.0], [8.0, 5.0], 15))
        .collect()
}

/// The escape's guess: the states interpolated linearly in time through six poses.
fn escape_guess(horizon: usize) -> Vec<Vec<f64>> {
    const POSES: [[f64; 3]; 6] = [
        [2.5, 2.5, 0.0],
        [4.0, 5.0, 0.785],
        [5.0, 6.25, 0.0],
        [7.5, 6.25, -0.261],
        [9.0, 5.0, -1.57],
        [7.5, 2.5, 0.0],
    ];
    (0..=horizon)
        .map(|t| {
            let s = t as f64 / horizon as f64 * (POSES.len() - 1) as f64;
            let k = (s.floor() as usize).min(POSES.len() - 2);
            let w = s - k as f64;
            (0..3).map(|i| (1.0 - w) * POSES[k][i] + w * POSES[k + 1][i]).collect()
        })
        .collect()
}

/// `car-escape` (module documentation).
///
/// # Errors
/// Never for these fixed numbers.
pub fn escape() -> Result<Example> {
    let spec = Spec {
        name: "car-escape",
        horizon: 100,
        duration: 3.0,
        weights: [1e-3, 1e-2, 100.0],
        x0: vec![2.5, 2.5, 0.0],
        xf: vec![7.5, 2.5, 0.0],
        u_guess: 1.0,
        description: "ALTRO Table I: Dubins car from one room to the next through a door in 3 s, 170 wall discs, \
                      |u| <= 5, goal constraint; guess: states interpolated through 6 poses (infeasible)",
    };
    let bounds = control_bounds(3, &[-5.0; 2], &[5.0; 2])?;
    let problem = spec.problem(car_ode()?, &[bounds], &[discs(escape_walls())?])?;
    spec.example(problem, Some(escape_guess(spec.horizon)))
}

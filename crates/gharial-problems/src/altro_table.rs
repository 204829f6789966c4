//! Problems of ALTRO's Table I (Howell et al. 2019, §IV-A) with the data of the authors'
//! problem definitions: the 1D block move and the Dubins car's parallel park, three
//! obstacles and escape; and the robot arm with obstacles, on the UR5 of
//! [`crate::peer_robots`] (the paper uses a 7-DoF Kuka).
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
//! | `car-parallel-park-min-time` | 101, from 3 s | as `car-parallel-park`, per unit of time | as `car-parallel-park`; the step `h = τ²` a control in `[1e-3, 0.2]`, equal steps, `R_min_time = 2` ([`MinimumTime`], ALTRO §III-C) | `u = 0.1`, `h = 0.03`, rollout |
//! | `car-escape` | 101, 3 s | 1e-3 I, 1e-2 I, 100 I | outside 170 discs of radius 0.5 that draw two rooms and a door, `|u| ≤ 5` | states interpolated through 6 poses, `u = 1` |
//!
//! `arm-obstacles` (N = 80, T = 2 s, dt = 25 ms, the peer harness's UR5 dynamics):
//! from `q_a = (0, −1, 1, −0.5, −0.5, 0)` at rest to `q_b = (1.5, −1.4, 1.6, −0.5, −0.5, 0)`
//! at rest (terminal equality), cost `½ Σ dt (1e-2 ‖v‖² + 1e-3 ‖u‖²) + ½ ‖x_N − x_b‖²`,
//! the URDF's effort limits `|u| ≤ (150, 150, 150, 28, 28, 28)` on every stage and the
//! tool (`tool0`) outside two spheres of radius 0.12 m on the stages `1..N−1`, by
//! `r² − |p(q) − c|² ≤ 0` on a [`FrameTranslationResidual`]. The centres
//! ([`ARM_CENTRES`]) are the tool's positions at `t = N/3` and `2N/3` of the optimal
//! motion without the spheres ([`arm_free`]), raised by 2 cm. Guess: gravity
//! compensation `g(q_a)` at every node, rolled out (the arm holds still). ProxDDP
//! converges to 1e-6 in 161 iterations (0.8 s in the test profile), the tool touching
//! both spheres, the torques at least 21 N m inside their limits.
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
use gharial::dynamics::{Dynamics, ExplicitRungeKutta, Ode, RkMethod};
use gharial::functions::{ControlError, Slice, StageFunction, StageFunctionData, StateError, Unary, Workspace};
use gharial::problem::{ContinuousStage, MinimumTime, Problem, StageConstraint, StageModel};
use gharial::solvers::altro::AltroOptions;
use gharial::solvers::proxddp::ProxDdpOptions;
use gharial::spaces::{Manifold, VectorSpace};

use gharial_robotics::residuals::{FrameTranslationResidual, effort_limits};
use gharial_robotics::{Actuation, gravity_compensation};

use crate::lqr::terminal_state;
use crate::peer_robots::{Robot, Weights};
use crate::robots::UR5_URDF;
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
pub(crate) struct Spec {
    pub(crate) name: &'static str,
    pub(crate) horizon: usize,
    pub(crate) duration: f64,
    /// Diagonals of Q, R, Q_f.
    pub(crate) weights: [f64; 3],
    pub(crate) x0: Vec<f64>,
    pub(crate) xf: Vec<f64>,
    /// Constant guess of the controls.
    pub(crate) u_guess: f64,
    pub(crate) description: &'static str,
}

impl Spec {
    pub(crate) fn dt(&self) -> f64 {
        self.duration / self.horizon as f64
    }

    /// The running cost `½ scale ((x − x_f)ᵀQ(x − x_f) + uᵀRu)` (`scale = dt`, or 1 for
    /// the cost per unit of time of a minimum-time problem).
    fn running_cost(&self, space: &Arc<dyn Manifold>, nu: usize, scale: f64) -> Result<CostStack> {
        let [q, r, _] = self.weights;
        let nx = self.x0.len();
        CostStack::new(space.as_ref(), nu)
            .with(
                "x",
                Arc::new(QuadraticStateCost::diagonal(
                    space.clone(),
                    &self.xf,
                    &vec![q * scale; nx],
                    nu,
                )?),
                1.0,
            )?
            .with(
                "u",
                Arc::new(QuadraticControlCost::diagonal(
                    space.as_ref(),
                    &vec![0.0; nu],
                    &vec![r * scale; nu],
                )?),
                1.0,
            )
    }

    /// The terminal cost `½ (x_N − x_f)ᵀQ_f(x_N − x_f)` and the goal `x_N = x_f`.
    fn terminal(&self, space: &Arc<dyn Manifold>) -> Result<(Arc<QuadraticStateCost>, StageConstraint)> {
        let qf = self.weights[2];
        let cost = QuadraticStateCost::diagonal(space.clone(), &self.xf, &vec![qf; self.x0.len()], 0)?;
        Ok((Arc::new(cost), terminal_state(space.clone(), &self.xf)?))
    }

    /// The problem with the control constraints `controls` on every running stage, the
    /// state constraints `states` on every running stage but the first (which cannot
    /// move `x_0`), and the goal constraint.
    pub(crate) fn problem(
        &self,
        ode: Arc<dyn Ode>,
        controls: &[StageConstraint],
        states: &[StageConstraint],
    ) -> Result<Problem> {
        let space = ode.space().clone();
        let nu = ode.nu();
        let dynamics = Dynamics::Explicit(Arc::new(ExplicitRungeKutta::rk4(ode, self.dt())?));
        let cost = self.running_cost(&space, nu, self.dt())?;
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
        let (terminal, goal) = self.terminal(&space)?;
        Problem::new(&self.x0, stages, terminal)?.with_terminal_constraint(goal)
    }

    /// The time-penalised version of [`Spec::problem`] (ALTRO §III-C,
    /// [`MinimumTime`]): the same constraints and goal, the running cost per unit of time
    /// weighted by the steps, the total time weighted by `mt.r_min_time`.
    pub(crate) fn min_time_problem(
        &self,
        ode: Arc<dyn Ode>,
        controls: &[StageConstraint],
        states: &[StageConstraint],
        mt: &MinimumTime,
    ) -> Result<Problem> {
        let space = ode.space().clone();
        let first = ContinuousStage {
            cost: Arc::new(self.running_cost(&space, ode.nu(), 1.0)?),
            ode,
            constraints: controls.to_vec(),
        };
        let mut stage = first.clone();
        stage.constraints.extend_from_slice(states);
        let mut stages = vec![stage; self.horizon];
        stages[0] = first;
        let (terminal, goal) = self.terminal(&space)?;
        mt.problem(&self.x0, &stages, terminal, &[goal])
    }

    /// The example from `problem`, with the controls' constant guess and `xs0` (`None`:
    /// their rollout).
    pub(crate) fn example(&self, problem: Problem, xs0: Option<Vec<Vec<f64>>>) -> Result<Example> {
        let us0 = vec![vec![self.u_guess; problem.nu(0)]; self.horizon];
        self.example_from(problem, us0, xs0)
    }

    /// The example of the time-penalised `problem`: the constant controls with the step
    /// `h = T / N` as `τ = √h`, and their rollout.
    pub(crate) fn min_time_example(&self, problem: Problem) -> Result<Example> {
        let us = vec![vec![self.u_guess; problem.nu(0) - 1]; self.horizon];
        self.example_from(problem, MinimumTime::controls(&us, self.dt()), None)
    }

    /// The example from `problem`, the guess `us0` and `xs0` (`None`: the rollout).
    fn example_from(&self, problem: Problem, us0: Vec<Vec<f64>>, xs0: Option<Vec<Vec<f64>>>) -> Result<Example> {
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
pub(crate) fn control_bounds(nx: usize, lower: &[f64], upper: &[f64]) -> Result<StageConstraint> {
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
    let (spec, controls, walls) = parallel_park_parts("car-parallel-park")?;
    let problem = spec.problem(car_ode()?, &controls, &walls)?;
    spec.example(problem, None)
}

/// Step bounds and time weight of `car-parallel-park-min-time`: `h ∈ [1e-3, 0.2]`,
/// `R_min_time = 2` (the authors' `parallelpark_mintime.jl`: `min_dt`, `max_dt`,
/// `R_minimum_time`).
pub const PARK_MIN_TIME: [f64; 3] = [1e-3, 0.2, 2.0];

/// `car-parallel-park-min-time` (module documentation): `car-parallel-park` with the
/// step as a control, started from its fixed step `T / N = 0.03`.
///
/// # Errors
/// Never for these fixed numbers.
pub fn parallel_park_min_time() -> Result<Example> {
    let (spec, controls, walls) = parallel_park_parts("car-parallel-park-min-time")?;
    let [h_min, h_max, r] = PARK_MIN_TIME;
    let mt = MinimumTime::new(h_min, h_max, r, RkMethod::Rk4)?;
    let problem = spec.min_time_problem(car_ode()?, &controls, &walls, &mt)?;
    let mut ex = spec.min_time_example(problem)?;
    ex.description = "ALTRO Table I: parallel park time-penalised, the step h = tau^2 a control in [1e-3, 0.2], \
                      R_min_time = 2, equal steps; started from T = 3 s";
    ex.proxddp.tol = 1e-6;
    crate::altro_systems::nonmonotone(&mut ex, 1e-2, gharial::solvers::proxddp::Rollout::Linear);
    Ok(ex)
}

/// The parallel park's numbers, control bounds and walls.
fn parallel_park_parts(name: &'static str) -> Result<(Spec, Vec<StageConstraint>, Vec<StageConstraint>)> {
    let spec = Spec {
        name,
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
    Ok((spec, vec![control_bounds(3, &[-2.0; 2], &[2.0; 2])?], vec![walls]))
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

/// `r² − |f(x, u)|² ≤ 0` for a function `f` of three rows (a frame's position minus a
/// sphere's centre, [`FrameTranslationResidual`]): the frame stays outside the sphere of
/// radius `r`. Jacobians `−2 fᵀ ∂f`.
struct OutsideSphere {
    f: Arc<dyn StageFunction>,
    radius: f64,
}

impl StageFunction for OutsideSphere {
    fn nx(&self) -> usize {
        self.f.nx()
    }
    fn ndx(&self) -> usize {
        self.f.ndx()
    }
    fn nu(&self) -> usize {
        self.f.nu()
    }
    fn nr(&self) -> usize {
        1
    }
    fn create_workspace(&self) -> Workspace {
        Box::new(self.f.create_data())
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let inner = inner_data(&mut data.ws);
        self.f.evaluate(x, u, inner);
        let d2: f64 = (0..3).map(|i| inner.value[i] * inner.value[i]).sum();
        data.value[0] = self.radius * self.radius - d2;
    }
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let inner = inner_data(&mut data.ws);
        self.f.evaluate(x, u, inner);
        self.f.jacobians(x, u, inner);
        for j in 0..data.jx.ncols() {
            data.jx[(0, j)] = -2.0 * (0..3).map(|i| inner.value[i] * inner.jx[(i, j)]).sum::<f64>();
        }
        for j in 0..data.ju.ncols() {
            data.ju[(0, j)] = -2.0 * (0..3).map(|i| inner.value[i] * inner.ju[(i, j)]).sum::<f64>();
        }
    }
}

fn inner_data(ws: &mut Workspace) -> &mut StageFunctionData {
    ws.downcast_mut()
        .expect("OutsideSphere's workspace is its inner function's data")
}

/// Start and goal configurations of `arm-obstacles`: the shoulder pans by 1.5 rad while
/// the arm lifts.
const ARM_QA: [f64; 6] = [0.0, -1.0, 1.0, -0.5, -0.5, 0.0];
const ARM_QB: [f64; 6] = [1.5, -1.4, 1.6, -0.5, -0.5, 0.0];
/// `arm-obstacles`: horizon and step.
const ARM_HORIZON: usize = 80;
const ARM_DT: f64 = 0.025;
/// The radius of `arm-obstacles`' spheres (m).
pub const ARM_RADIUS: f64 = 0.12;

/// The centres of `arm-obstacles`' spheres: the tool's positions at `t = N/3` and
/// `t = 2N/3` on the optimal motion without spheres ([`arm_free`], ProxDDP to 1e-8), raised
/// by 2 cm so that that motion passes through them off-centre.
pub const ARM_CENTRES: [[f64; 3]; 2] = [
    [
        -0.221_943_250_194_536_56,
        0.193_634_599_703_607_8,
        0.304_243_987_353_880_8,
    ],
    [
        -0.243_523_758_242_498_28,
        0.034_337_858_126_948_24,
        0.206_955_017_244_865,
    ],
];

/// `arm-obstacles` (module documentation): the UR5 moved from `ARM_QA` to `ARM_QB` at
/// rest in 2 s with two spheres kept away from its tool, within the URDF's torque
/// limits; the controls start at gravity compensation at `ARM_QA`.
///
/// # Errors
/// Never for these fixed numbers.
pub fn arm_obstacles() -> Result<Example> {
    arm_problem(true)
}

/// `arm-obstacles` without its spheres (the motion the spheres are placed on).
///
/// # Errors
/// Never for these fixed numbers.
pub fn arm_free() -> Result<Example> {
    arm_problem(false)
}

fn arm_problem(spheres: bool) -> Result<Example> {
    let robot = Robot::load_with_dt(UR5_URDF, ARM_DT)?;
    let nu = robot.nu();
    let xa: Vec<f64> = ARM_QA.iter().copied().chain([0.0; 6]).collect();
    let xb: Vec<f64> = ARM_QB.iter().copied().chain([0.0; 6]).collect();
    let running = Weights {
        q: 0.0,
        v: 1e-2,
        u: 1e-3,
        ee: 0.0,
    };
    let terminal = Weights {
        q: 1.0,
        v: 1.0,
        u: 0.0,
        ee: 0.0,
    };
    let cost = robot.cost(&xb, &running, None, nu, ARM_DT)?;
    let mut stage = StageModel::new(Arc::new(cost), robot.dynamics.clone())?;
    let dofs: Vec<usize> = (0..nu).collect();
    stage.add_constraint(effort_limits(&robot.space, &dofs)?)?;
    let mut stages = vec![stage.clone(); ARM_HORIZON];
    for (k, c) in ARM_CENTRES.iter().enumerate().filter(|_| spheres) {
        let r = FrameTranslationResidual::new(&robot.space, "tool0", c)?;
        let f = Arc::new(OutsideSphere {
            f: Arc::new(Unary::new(Arc::new(r), nu)),
            radius: ARM_RADIUS,
        });
        let obstacle = StageConstraint::new(format!("sphere {k}"), f, Arc::new(NegativeOrthant));
        for s in &mut stages[1..] {
            s.add_constraint(obstacle.clone())?;
        }
    }
    let terminal = robot.cost(&xb, &terminal, None, 0, 1.0)?;
    let space: Arc<dyn Manifold> = robot.space.clone();
    let problem =
        Problem::new(&xa, stages, Arc::new(terminal))?.with_terminal_constraint(terminal_state(space, &xb)?)?;
    let g = gravity_compensation(robot.space.model(), &Actuation::full(robot.space.model()), &ARM_QA)?;
    let us0 = vec![g; ARM_HORIZON];
    let xs0 = rollout(&problem, &us0)?;
    Ok(Example {
        name: "arm-obstacles",
        problem,
        xs0,
        us0,
        dt: Some(ARM_DT),
        proxddp: ProxDdpOptions::default().with(|o| {
            o.tol = 1e-6;
            o.max_iters = 500;
        }),
        description: "ALTRO Table I robot arm with obstacles, on the UR5: from one configuration to another at rest in \
                      2 s, the tool outside two spheres of radius 0.12, URDF torque limits, goal constraint; \
                      controls start at gravity compensation",
    })
}

/// ALTRO's settings for the catalogue problems whose result in the paper needs more than
/// its defaults: the car escape and the quadrotor maze start from states that violate
/// the dynamics and need the infeasible start (III-B); the escape with the authors'
/// penalties and tolerances (`penalty_initial` 10, `penalty_scaling` 100,
/// `constraint_tolerance` 1e-8, 20 outer iterations), the maze with `penalty_initial` 0.1
/// and `cost_tolerance_intermediate` 1e-2. `None` for the other problems (ALTRO's
/// defaults).
pub fn recommended_altro(name: &str) -> Option<AltroOptions> {
    let defaults = AltroOptions::default();
    match name {
        "car-escape" => Some(defaults.with(|o| {
            o.infeasible_start = true;
            o.penalty_initial = 10.0;
            o.penalty_scaling = 100.0;
            o.cost_tolerance_intermediate = 1e-3;
            o.constraint_tolerance = 1e-8;
            o.iterations_outer = 20;
        })),
        "quadrotor-maze" => Some(defaults.with(|o| {
            o.infeasible_start = true;
            o.penalty_initial = 0.1;
            o.cost_tolerance_intermediate = 1e-2;
        })),
        _ => None,
    }
}

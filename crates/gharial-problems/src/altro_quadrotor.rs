//! ALTRO's Table I quadrotor problems (Howell et al. 2019, §IV-A 7): `quadrotor-line`
//! (60 m along y in 5 s) and `quadrotor-maze` (the same flight through a maze of
//! cylinders between a floor and a ceiling), with the authors' data
//! (TrajectoryOptimization.jl, `problems/quadrotor.jl` and `problems/quadrotor_maze.jl`,
//! model `dynamics/quadrotor.jl`).
//!
//! # Model
//! The rigid body of [`crate::quadrotor`] ([`QuadrotorOde`]: state `(p, q, v, ω)` on
//! `SE(3) × R⁶`, the attitude a unit quaternion on its manifold, velocities in the body
//! frame) with the authors' parameters: mass 0.5 kg, inertia `diag(0.0023, 0.0023,
//! 0.004)`, arm 0.175 m, yaw moment 0.0245 per unit thrust (the authors' rotor order
//! turns it the other way: `yaw_ratio = -0.0245`), `g = 9.81`. The authors write the
//! linear velocity in the world frame and the quaternion in `R⁴`; with equal weights on
//! its three components the velocity cost is the same in either frame, and the
//! attitude weight applies to the rotation's tangent (log) error. RK4 (the authors: RK3),
//! `N = 100`, `T = 5 s`.
//!
//! # Problems
//! `x₀ = (0, 0, 10)`, `x_f = (0, 60, 10)`, identity attitude, at rest. Cost
//! `½ Σ dt (|x ⊖ x_f|²_Q + 1e-4 |u|²) + ½ 1000 |x_N ⊖ x_f|²`, `Q = 1e-3` except `1e-2` on
//! the attitude. Goal: position and velocities of `x_N` (not the attitude). Guess: the
//! hover thrust `0.5 · 9.81 / 4` on every rotor.
//! - `quadrotor-line`: thrusts `u ≥ 0`; the guess rolled out.
//! - `quadrotor-maze`: thrusts `0 ≤ u ≤ 100`; on the stages `1..N−1` the walls
//!   `|x| ≤ 25`, floor and ceiling `0 ≤ z ≤ 20`, and 44 vertical cylinders of radius 2
//!   kept 2 m away from the quadrotor's position (`(2 + 2)² − |p_xy − c|² ≤ 0`): two rows
//!   of five at y = 10 and y = 50 with a gap in the middle, four at y = 30 in the middle,
//!   and ten along each side wall. Guess: the states interpolated linearly through seven
//!   positions `(0, 0, 10)`, `(0, 15, 10)`, `(−12.5, 20, 10)`, `(−20, 30, 10)`,
//!   `(−12.5, 40, 10)`, `(0, 45, 10)`, `(0, 60, 10)` (the authors' infeasible start),
//!   identity attitude, at rest.
//!
//! `quadrotor-line` is in the catalogue: ALTRO converges to 1e-8 with `penalty_initial =
//! 0.1` and `cost_tolerance_intermediate = 1e-2` (97 iterations; from the default penalty
//! 1 it stalls at 3e-5), ProxDDP at the settings below reaches a feasible point of the
//! same cost (2e-5 relative) whose dual residual stalls above 1e-8 (measured).
//! `quadrotor-maze` ([`maze`]) is solved as the paper does, by ALTRO's infeasible start
//! from the guess through the seven points (slack controls in SE(3) × R⁶'s tangent
//! space), with `penalty_initial = 0.1` and `cost_tolerance_intermediate = 1e-2`: 223
//! iterations to a violation of 4e-12, collision-free (0.9-1.2 s release on this
//! machine; Table I: 33 s). From the hover rollout without it, AL-iLQR converged too here
//! (the paper's found no collision-free path), in 2245 iterations to a costlier local
//! optimum (3.47 against 2.42).

use std::sync::Arc;

use gharial::Result;
use gharial::autodiff::{AutoDiff, AutoUnaryFn, ManifoldScalar};
use gharial::constraints::{EqualityConstraintSet, NegativeOrthant};
use gharial::costs::{CostStack, QuadraticControlCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, ExplicitRungeKutta};
use gharial::functions::{ControlError, Unary};
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::solvers::proxddp::{Merit, ProxDdpOptions, Rollout, StepAcceptance};

use crate::quadrotor::{QuadrotorOde, at, space};
use crate::{Example, rollout};

/// Horizon.
pub const HORIZON: usize = 100;
/// Duration (s).
pub const DURATION: f64 = 5.0;

/// The authors' quadrotor (module documentation).
pub fn model() -> QuadrotorOde {
    QuadrotorOde {
        mass: 0.5,
        inertia: [0.0023, 0.0023, 0.004],
        arm: 0.175,
        yaw_ratio: -0.0245,
        gravity: 9.81,
    }
}

/// `(p − p_f, v, ω)`: the goal without the attitude.
struct Goal([f64; 3]);

impl AutoUnaryFn for Goal {
    fn nx(&self) -> usize {
        13
    }
    fn nr(&self) -> usize {
        9
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], out: &mut [D]) {
        for i in 0..3 {
            out[i] = x[i] - self.0[i];
        }
        out[3..9].copy_from_slice(&x[7..13]);
    }
}

/// The maze: `(x − 25, −25 − x, z − 20, −z)` and `(r + R)² − |p_xy − c|²` per cylinder,
/// all `≤ 0`.
struct Maze(Vec<[f64; 2]>);

/// Radius of the maze's cylinders plus the quadrotor's (m).
pub const MAZE_CLEARANCE: f64 = 4.0;

impl AutoUnaryFn for Maze {
    fn nx(&self) -> usize {
        13
    }
    fn nr(&self) -> usize {
        4 + self.0.len()
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], out: &mut [D]) {
        out[0] = x[0] - 25.0;
        out[1] = -x[0] - 25.0;
        out[2] = x[2] - 20.0;
        out[3] = -x[2];
        for (o, c) in out[4..].iter_mut().zip(&self.0) {
            let (dx, dy) = (x[0] - c[0], x[1] - c[1]);
            *o = -(dx * dx + dy * dy) + MAZE_CLEARANCE * MAZE_CLEARANCE;
        }
    }
}

/// The centres of the maze's cylinders (module documentation).
pub fn maze_cylinders() -> Vec<[f64; 2]> {
    let line = |from: [f64; 2], to: [f64; 2], n: usize| {
        (0..n).map(move |i| {
            let s = i as f64 / (n - 1) as f64;
            [from[0] + s * (to[0] - from[0]), from[1] + s * (to[1] - from[1])]
        })
    };
    line([-25.0, 10.0], [-10.0, 10.0], 5)
        .chain(line([10.0, 10.0], [25.0, 10.0], 5))
        .chain(line([-5.0, 30.0], [5.0, 30.0], 4))
        .chain(line([-25.0, 50.0], [-10.0, 50.0], 5))
        .chain(line([10.0, 50.0], [25.0, 50.0], 5))
        .chain(line([-25.0, 14.0], [-25.0, 46.0], 10))
        .chain(line([25.0, 14.0], [25.0, 46.0], 10))
        .collect()
}

/// The maze's guess: positions interpolated linearly in time through the seven points.
fn maze_guess() -> Vec<Vec<f64>> {
    const POINTS: [[f64; 3]; 7] = [
        [0.0, 0.0, 10.0],
        [0.0, 15.0, 10.0],
        [-12.5, 20.0, 10.0],
        [-20.0, 30.0, 10.0],
        [-12.5, 40.0, 10.0],
        [0.0, 45.0, 10.0],
        [0.0, 60.0, 10.0],
    ];
    (0..=HORIZON)
        .map(|t| {
            let s = t as f64 / HORIZON as f64 * (POINTS.len() - 1) as f64;
            let k = (s.floor() as usize).min(POINTS.len() - 2);
            let w = s - k as f64;
            at(std::array::from_fn(|i| (1.0 - w) * POINTS[k][i] + w * POINTS[k + 1][i]))
        })
        .collect()
}

/// `quadrotor-line` (module documentation).
///
/// # Errors
/// Never for these fixed numbers.
pub fn line() -> Result<Example> {
    build(false)
}

/// `quadrotor-maze` (module documentation).
///
/// # Errors
/// Never for these fixed numbers.
pub fn maze() -> Result<Example> {
    build(true)
}

fn build(with_maze: bool) -> Result<Example> {
    let space = space();
    let dt = DURATION / HORIZON as f64;
    let ode = model();
    let hover = ode.hover_thrust();
    let ode = Arc::new(AutoDiff::ode(space.clone(), ode)?);
    let dynamics = Dynamics::Explicit(Arc::new(ExplicitRungeKutta::rk4(ode, dt)?));
    let xf = at([0.0, 60.0, 10.0]);
    let first = StageModel::new(Arc::new(running_cost(&space, &xf, dt)?), dynamics)?;
    let u_max = if with_maze { 100.0 } else { f64::INFINITY };
    let thrust = StageConstraint::new(
        "thrust",
        Arc::new(ControlError::new(space.as_ref(), &[0.0; NU])?),
        Arc::new(gharial::constraints::BoxConstraint::new(&[0.0; NU], &[u_max; NU])?),
    );
    let mut stages = vec![first.with_constraint(thrust)?; HORIZON];
    if with_maze {
        let maze = Arc::new(Unary::new(
            Arc::new(AutoDiff::unary(space.clone(), Maze(maze_cylinders()))?),
            NU,
        ));
        let c = StageConstraint::new("maze", maze, Arc::new(NegativeOrthant));
        for s in &mut stages[1..] {
            s.add_constraint(c.clone())?;
        }
    }
    let terminal = Arc::new(QuadraticStateCost::diagonal(space.clone(), &xf, &[1000.0; 12], 0)?);
    let goal = Arc::new(Unary::new(
        Arc::new(AutoDiff::unary(space.clone(), Goal([0.0, 60.0, 10.0]))?),
        0,
    ));
    let problem = Problem::new(&at([0.0, 0.0, 10.0]), stages, terminal)?
        .with_terminal_constraint(StageConstraint::new("goal", goal, Arc::new(EqualityConstraintSet)))?;
    example(problem, with_maze, hover, dt)
}

/// Thrust inputs.
const NU: usize = 4;

/// `dt · ½ (1e-3 |x - x_f|² (1e-2 on the orientation) + 1e-4 |u|²)`.
fn running_cost(space: &Arc<dyn gharial::spaces::Manifold>, xf: &[f64], dt: f64) -> Result<CostStack> {
    let mut w = vec![1e-3 * dt; 12];
    w[3..6].fill(1e-2 * dt);
    let control = QuadraticControlCost::diagonal(space.as_ref(), &[0.0; NU], &[1e-4 * dt; NU])?;
    CostStack::new(space.as_ref(), NU)
        .with(
            "x",
            Arc::new(QuadraticStateCost::diagonal(space.clone(), xf, &w, NU)?),
            1.0,
        )?
        .with("u", Arc::new(control), 1.0)
}

/// The catalogue entry: the maze starts from its interpolated (infeasible) guess, the line
/// from the hover rollout; ProxDDP's settings for both.
fn example(problem: Problem, with_maze: bool, hover: f64, dt: f64) -> Result<Example> {
    let us0 = vec![vec![hover; NU]; HORIZON];
    let (name, xs0, description) = if with_maze {
        (
            "quadrotor-maze",
            maze_guess(),
            "ALTRO Table I quadrotor maze: 60 m through 44 cylinders in 5 s, |x| <= 25, 0 <= z <= 20, \
             0 <= u <= 100, goal position and velocities; guess interpolated through 7 positions (infeasible)",
        )
    } else {
        (
            "quadrotor-line",
            rollout(&problem, &us0)?,
            "ALTRO Table I quadrotor line: 60 m along y in 5 s, u >= 0, goal position and velocities; hover guess",
        )
    };
    Ok(Example {
        name,
        problem,
        xs0,
        us0,
        dt: Some(dt),
        proxddp: ProxDdpOptions::default().with(|o| {
            o.tol = 1e-8;
            o.mu_init = 0.1;
            o.rollout = Rollout::Nonlinear;
            o.step_acceptance = StepAcceptance::NonmonotoneLinesearch;
            o.merit = Merit::Primal;
            o.max_iters = 800;
        }),
        description,
    })
}

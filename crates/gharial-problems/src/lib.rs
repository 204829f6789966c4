//! # gharial-problems
//!
//! A catalogue of named, parameterised trajectory optimization problems for gharial:
//! the examples of the ProxDDP paper (Jallet et al., 2023, section V) and the LQR and
//! robot families of the peer benchmark harness. Each problem comes with its initial guess, its time
//! step and the ProxDDP settings recommended for it (those of the paper where it gives
//! them).
//!
//! ```
//! use gharial::solvers::{InitialGuess, Solver};
//! use gharial::solvers::proxddp::ProxDdp;
//!
//! let ex = gharial_problems::build("lqr-bounds-term").unwrap();
//! let mut solver = ProxDdp::new(ex.proxddp.clone());
//! solver.setup(&ex.problem).unwrap();
//! let sol = solver.solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0)).unwrap();
//! assert!(sol.status.converged());
//! ```
//!
//! | name | module | state | N | dt |
//! |---|---|---|---|---|
//! | `lqr`, `lqr-bounds`, `lqr-term`, `lqr-bounds-term` | [`lqr`] | R³ | 20 | — |
//! | `clqr` | [`lqr`] | R⁴ | 100 | — |
//! | `pendulum` | [`pendulum`] | SO(2) × R | 200 | 10 ms |
//! | `cartpole` | [`cartpole`] | R² × R² | 500 | 10 ms |
//! | `acrobot`, `acrobot-bounds` | [`acrobot`] | SO(2)² × R² | 200 | 5 ms |
//! | `se2-car` | [`se2_car`] | SE(2) | 40 | 50 ms |
//! | `quadrotor`, `quadrotor-slalom` | [`quadrotor`] | SE(3) × R⁶ | 60 | 33 ms |
//! | `peers-lqr`, `peers-lqr-box`, `peers-lqr-box-term` | [`peers`] | R⁸ | 100 | — |
//! | `ur5`, `ur5-box` | [`peer_robots`] | UR5 phase space (R¹²) | 100 | 10 ms |
//! | `double-pendulum`, `double-pendulum-box`, `double-pendulum-box-term` | [`peer_robots`] | R⁴ | 100 | 10 ms |
//! | `ur5-circle`, `ur5-circle-joint-bound`, `ur5-circle-half-space` | [`ur5_circle`] | UR5 phase space (R¹²) | 10 | 50 ms |
//! | `ur10-ballistic` | [`ur10_ballistic`] | UR10 and mug (R²⁵, ndx 24; mug held, then flying) | 200 | 10 ms |
//! | `solo-jump` | [`solo_jump`] | Solo-12 phase space (nx = 37, ndx = 36) | 60 | 20 ms |
//! | `ecddp-cartpole`, `ecddp-cartpole-advanced` | [`ecddp`] | R² × R² | 200 | 10 ms |
//! | `ecddp-ur5` | [`ecddp`] | UR5 phase space (R¹²) | 200 | 10 ms |
//! | `solo-com-circle` | [`solo_com_circle`] | Solo-12 phase space (nx = 37, ndx = 36) | 250 | 20 ms |
//! | `block-move` | [`altro_table`] | R² | 20 | 100 ms |
//! | `car-parallel-park`, `car-escape` | [`altro_table`] | R³ | 100 | 30 ms |
//! | `car-3-obstacles` | [`altro_table`] | R³ | 100 | 50 ms |
//! | `arm-obstacles` | [`altro_table`] | UR5 phase space (R¹²) | 80 | 25 ms |
//! | `car-parallel-park-min-time` | [`altro_table`] | R³ × R (step) | 100 | 30 ms at start |
//! | `altro-pendulum` | [`altro_systems`] | R² | 30 | 150 ms |
//! | `altro-pendulum-min-time` | [`altro_systems`] | R² × R (step) | 30 | 150 ms at start |
//! | `altro-acrobot`, `altro-cartpole` | [`altro_systems`] | R⁴ | 100 | 50 ms |
//! | `quadrotor-line` | [`altro_quadrotor`] | SE(3) × R⁶ | 100 | 50 ms |
//!
//! Every module documents its model, its numbers and the results measured with
//! ProxDDP.

pub mod acrobot;
pub mod altro_quadrotor;
pub mod altro_systems;
pub mod altro_table;
pub mod cartpole;
pub mod ecddp;
pub mod figures;
pub mod lqr;
pub mod mpc;
pub mod peer_robots;
pub mod peers;
pub mod pendulum;
pub mod profiles;
pub mod quadrotor;
pub mod robots;
pub mod scenes;
pub mod se2_car;
pub mod solo_com_circle;
pub mod solo_jump;
pub mod solo_stance;
pub mod solo_walk;
pub mod ur10_ballistic;
pub mod ur5_circle;

use gharial::problem::{Problem, ProblemData};
use gharial::solvers::SolverOptions;
use gharial::solvers::proxddp::ProxDdpOptions;
use gharial::{Error, Result};

/// A catalogue entry: the name accepted by [`build`] and a one-line summary.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ProblemInfo {
    /// Name accepted by [`build`].
    pub name: &'static str,
    /// One-line summary.
    pub summary: &'static str,
}

/// A built example: the problem, an initial guess and the recommended solver settings.
#[derive(Clone)]
pub struct Example {
    /// Catalogue name.
    pub name: &'static str,
    /// The optimal control problem.
    pub problem: Problem,
    /// Initial state guess `x_0..x_N` (the rollout of `us0` unless documented otherwise).
    pub xs0: Vec<Vec<f64>>,
    /// Initial control guess `u_0..u_{N-1}`.
    pub us0: Vec<Vec<f64>>,
    /// Time step of the discretisation (`None` for discrete-time problems).
    pub dt: Option<f64>,
    /// Recommended ProxDDP settings (the paper's where it gives them).
    pub proxddp: ProxDdpOptions,
    /// A few lines describing the problem.
    pub description: &'static str,
}

impl Example {
    /// The options of the solver `name` (one of [`SolverOptions::names`]) for this
    /// problem: ProxDDP's are the recommended [`Example::proxddp`], ProxNLP's the ones of
    /// those it shares (`ProxNlpOptions::from`), ALTRO's the authors' where the paper's
    /// result needs them ([`altro_table::recommended_altro`]), BCL-DDP's the authors' on
    /// the ECDDP problems ([`ecddp::recommended_bcl`]), the other solvers' their defaults.
    ///
    /// # Errors
    /// If `name` is not a solver's name (the message lists the valid names).
    pub fn options(&self, name: &str) -> Result<SolverOptions> {
        match SolverOptions::from_name(name)? {
            SolverOptions::ProxDdp(_) => Ok(SolverOptions::ProxDdp(self.proxddp.clone())),
            SolverOptions::ProxNlp(_) => Ok(SolverOptions::ProxNlp((&self.proxddp).into())),
            SolverOptions::Altro(defaults) => Ok(SolverOptions::Altro(
                altro_table::recommended_altro(self.name).unwrap_or(defaults),
            )),
            SolverOptions::BclDdp(defaults) => Ok(SolverOptions::BclDdp(
                ecddp::recommended_bcl(self.name).unwrap_or(defaults),
            )),
            defaults => Ok(defaults),
        }
    }
}

impl std::fmt::Debug for Example {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Example")
            .field("name", &self.name)
            .field("horizon", &self.problem.horizon())
            .field("dt", &self.dt)
            .field("proxddp", &self.proxddp)
            .finish_non_exhaustive()
    }
}

static CATALOGUE: &[ProblemInfo] = &[
    ProblemInfo {
        name: "lqr",
        summary: "3-state / 3-control LQR of the ProxDDP paper (Fig. 3), N = 20, unconstrained",
    },
    ProblemInfo {
        name: "lqr-bounds",
        summary: "paper LQR with control bounds |u|_inf <= 0.15",
    },
    ProblemInfo {
        name: "lqr-term",
        summary: "paper LQR with the terminal equality x_N = (0.1, 0.1, 0.1)",
    },
    ProblemInfo {
        name: "lqr-bounds-term",
        summary: "paper LQR with control bounds and terminal equality (Fig. 3)",
    },
    ProblemInfo {
        name: "clqr",
        summary: "random seeded 4-state / 2-control LQR, N = 100, |u|_inf <= 0.3",
    },
    ProblemInfo {
        name: "pendulum",
        summary: "pendulum swing-up on SO(2) x R, dt = 10 ms, torque limits +-20, terminal tip constraint (Fig. 4)",
    },
    ProblemInfo {
        name: "cartpole",
        summary: "cart-pole swing-up, dt = 10 ms, T = 5 s, force limits +-6, terminal tip position (0, 1) (Fig. 5)",
    },
    ProblemInfo {
        name: "acrobot",
        summary: "acrobot swing-up on SO(2)^2 x R^2, RK2, dt = 5 ms, terminal state constraint (Fig. 6)",
    },
    ProblemInfo {
        name: "acrobot-bounds",
        summary: "acrobot swing-up with torque limits and a quadratic terminal cost (Fig. 7)",
    },
    ProblemInfo {
        name: "se2-car",
        summary: "kinematic car on SE(2), N = 40, dt = 0.05, parking at the origin",
    },
    ProblemInfo {
        name: "quadrotor",
        summary: "quadrotor on SE(3) x R^6 through two waypoints with thrust limits (Fig. 10)",
    },
    ProblemInfo {
        name: "quadrotor-slalom",
        summary: "quadrotor slaloming between two cylinders, linear rollout (Fig. 11)",
    },
    ProblemInfo {
        name: "peers-lqr",
        summary: "peer-harness LQR family: nx = 8, nu = 4, N = 100, seed 42, unconstrained",
    },
    ProblemInfo {
        name: "peers-lqr-box",
        summary: "peer-harness LQR with control bounds |u|_inf <= 0.05",
    },
    ProblemInfo {
        name: "peers-lqr-box-term",
        summary: "peer-harness LQR with control bounds and x_N = 0",
    },
    ProblemInfo {
        name: "ur5",
        summary: "peer-harness UR5 reaching (ABA, semi-implicit Euler, dt = 10 ms, N = 100), end effector to (0.3, 0.5, 0.5)",
    },
    ProblemInfo {
        name: "ur5-box",
        summary: "peer-harness UR5 reaching with torque limits (60, 60, 25, 10, 10, 10) N m",
    },
    ProblemInfo {
        name: "double-pendulum",
        summary: "peer-harness double-pendulum swing-up (ABA, semi-implicit Euler, dt = 10 ms, N = 100)",
    },
    ProblemInfo {
        name: "double-pendulum-box",
        summary: "peer-harness double-pendulum swing-up with torque limits |u| <= 0.6",
    },
    ProblemInfo {
        name: "double-pendulum-box-term",
        summary: "peer-harness double-pendulum swing-up with torque limits and x_N = 0",
    },
    ProblemInfo {
        name: "ur5-circle",
        summary: "UR5 end-effector circle tracking (stagewise-SQP paper's MPC task), first horizon: N = 10, dt = 50 ms",
    },
    ProblemInfo {
        name: "ur5-circle-joint-bound",
        summary: "UR5 circle tracking with the first joint bounded |q1| <= 0.05 rad",
    },
    ProblemInfo {
        name: "ur5-circle-half-space",
        summary: "UR5 circle tracking with the tool in a half-space y <= y_max that cuts the circle",
    },
    ProblemInfo {
        name: "ur10-ballistic",
        summary: "UR10 throws a held mug (6D constraint until t_c = 0.81 s) to land at (3.4, -0.2, 0) at T = 2 s, torque limits (Figs. 8, 9)",
    },
    ProblemInfo {
        name: "solo-jump",
        summary: "Solo-12 whole-body jump (Fig. 12, 15): stance, flight from 0.4 s, landing at 0.9 s with feet heights z = 0, dt = 20 ms, N = 60",
    },
    ProblemInfo {
        name: "solo-com-circle",
        summary: "Solo-12 on four feet, CoM on a horizontal circle (r = 6.5 cm, 0.2 Hz), friction cones mu = 0.8 (stagewise-SQP paper, Figs. 4-5), dt = 20 ms, N = 250",
    },
    ProblemInfo {
        name: "block-move",
        summary: "ALTRO Table I: double integrator moved one unit, |u| <= 1.5, goal constraint, N = 20, dt = 0.1",
    },
    ProblemInfo {
        name: "car-parallel-park",
        summary: "ALTRO Table I: Dubins car moved one unit sideways inside a box, |u| <= 2, goal constraint, N = 100, T = 3 s",
    },
    ProblemInfo {
        name: "car-3-obstacles",
        summary: "ALTRO Table I: Dubins car to (1, 1) around three discs, goal constraint, N = 100, T = 5 s",
    },
    ProblemInfo {
        name: "car-escape",
        summary: "ALTRO Table I: Dubins car out of a room through a door (170 wall discs), |u| <= 5, interpolated infeasible guess, N = 100, T = 3 s",
    },
    ProblemInfo {
        name: "arm-obstacles",
        summary: "ALTRO Table I robot arm with obstacles, on the UR5: configuration to configuration at rest, tool outside two spheres, URDF torque limits, N = 80, T = 2 s",
    },
    ProblemInfo {
        name: "car-parallel-park-min-time",
        summary: "ALTRO Table I: parallel park time-penalised, the step a control in [1e-3, 0.2], R_min_time = 2, N = 100",
    },
    ProblemInfo {
        name: "altro-pendulum",
        summary: "ALTRO Table I: pendulum swing-up (authors' model), |u| <= 3, goal constraint, N = 30, T = 4.5 s",
    },
    ProblemInfo {
        name: "altro-pendulum-min-time",
        summary: "ALTRO Table I: pendulum time-penalised, the step a control in [1e-3, 0.2], R_min_time = 1, N = 30",
    },
    ProblemInfo {
        name: "altro-acrobot",
        summary: "ALTRO Table I: acrobot swing-up by the elbow torque, |u| <= 15, goal constraint, N = 100, T = 5 s",
    },
    ProblemInfo {
        name: "altro-cartpole",
        summary: "ALTRO Table I: cart-pole swing-up (authors' model), |u| <= 3, goal constraint, N = 100, T = 5 s",
    },
    ProblemInfo {
        name: "quadrotor-line",
        summary: "ALTRO Table I: quadrotor (SE(3) x R^6) flying 60 m along y in 5 s, u >= 0, goal constraint, N = 100",
    },
    ProblemInfo {
        name: "quadrotor-maze",
        summary: "ALTRO Table I: the quadrotor through 44 cylinders between walls, floor and ceiling, 0 <= u <= 100, \
                  goal constraint, N = 100; guess: positions through 7 points (infeasible: take ALTRO's infeasible start)",
    },
    ProblemInfo {
        name: "ecddp-cartpole",
        summary: "ECDDP cart-pole swing-up (El Kazdadi et al. 2021, Figs. 1-4): force norm, terminal configuration upright, N = 200, dt = 10 ms",
    },
    ProblemInfo {
        name: "ecddp-cartpole-advanced",
        summary: "ecddp-cartpole with the terminal configuration constraint written on the last control (ECDDP (29))",
    },
    ProblemInfo {
        name: "ecddp-ur5",
        summary: "ECDDP UR5 (Fig. 6): the tool through three targets at t = 0.66, 1.33 and 2 s (equalities), N = 200, dt = 10 ms",
    },
];

/// Every problem [`build`] knows, in catalogue order.
pub fn catalogue() -> &'static [ProblemInfo] {
    CATALOGUE
}

/// Builds the example called `name` (see [`catalogue`]).
///
/// # Errors
/// If `name` is not in the catalogue (the message lists the valid names), or a model
/// fails to build (a bug: every catalogue entry is tested).
pub fn build(name: &str) -> Result<Example> {
    match name {
        "lqr" => lqr::paper(lqr::LqrVariant::Plain),
        "lqr-bounds" => lqr::paper(lqr::LqrVariant::Bounds),
        "lqr-term" => lqr::paper(lqr::LqrVariant::Terminal),
        "lqr-bounds-term" => lqr::paper(lqr::LqrVariant::BoundsTerminal),
        "clqr" => lqr::clqr(),
        "pendulum" => pendulum::build(),
        "cartpole" => cartpole::build(),
        "acrobot" => acrobot::build(acrobot::AcrobotVariant::TerminalConstraint),
        "acrobot-bounds" => acrobot::build(acrobot::AcrobotVariant::Bounds),
        "se2-car" => se2_car::build(),
        "quadrotor" => quadrotor::build(quadrotor::QuadrotorVariant::ThrustLimits),
        "quadrotor-slalom" => quadrotor::build(quadrotor::QuadrotorVariant::Slalom),
        "peers-lqr" => peers::build(&peers::PeersLqrParams::default(), peers::PeersVariant::Lqr),
        "peers-lqr-box" => peers::build(&peers::PeersLqrParams::default(), peers::PeersVariant::Box),
        "peers-lqr-box-term" => peers::build(&peers::PeersLqrParams::default(), peers::PeersVariant::BoxTerminal),
        "ur5" => peer_robots::ur5(peer_robots::Ur5Variant::Reach),
        "ur5-box" => peer_robots::ur5(peer_robots::Ur5Variant::Box),
        "double-pendulum" => peer_robots::double_pendulum(peer_robots::PendulumVariant::SwingUp),
        "double-pendulum-box" => peer_robots::double_pendulum(peer_robots::PendulumVariant::Box),
        "double-pendulum-box-term" => peer_robots::double_pendulum(peer_robots::PendulumVariant::BoxTerminal),
        "ur5-circle" => ur5_circle::build(ur5_circle::CircleVariant::Free),
        "ur5-circle-joint-bound" => ur5_circle::build(ur5_circle::CircleVariant::JointBound),
        "ur5-circle-half-space" => ur5_circle::build(ur5_circle::CircleVariant::HalfSpace),
        "ur10-ballistic" => ur10_ballistic::build(),
        "solo-jump" => solo_jump::build(),
        "solo-com-circle" => solo_com_circle::build(solo_com_circle::HORIZON),
        "block-move" => altro_table::block_move(),
        "car-parallel-park" => altro_table::parallel_park(),
        "car-3-obstacles" => altro_table::three_obstacles(),
        "car-escape" => altro_table::escape(),
        "arm-obstacles" => altro_table::arm_obstacles(),
        "car-parallel-park-min-time" => altro_table::parallel_park_min_time(),
        "altro-pendulum" => altro_systems::pendulum(),
        "altro-pendulum-min-time" => altro_systems::pendulum_min_time(),
        "altro-acrobot" => altro_systems::acrobot(),
        "altro-cartpole" => altro_systems::cartpole(),
        "quadrotor-line" => altro_quadrotor::line(),
        "quadrotor-maze" => altro_quadrotor::maze(),
        "ecddp-cartpole" => ecddp::cartpole(false),
        "ecddp-cartpole-advanced" => ecddp::cartpole(true),
        "ecddp-ur5" => ecddp::ur5(),
        _ => Err(Error::InvalidModel(format!(
            "unknown problem `{name}`; valid names: {}",
            CATALOGUE.iter().map(|p| p.name).collect::<Vec<_>>().join(", ")
        ))),
    }
}

/// States `x_0..x_N` of the rollout of `us` from the problem's fixed `x0`.
///
/// # Errors
/// If the problem has no fixed initial state, a stage has implicit dynamics or the
/// rollout diverges.
pub fn rollout(problem: &Problem, us: &[Vec<f64>]) -> Result<Vec<Vec<f64>>> {
    let x0 = problem
        .x0()
        .ok_or_else(|| Error::InvalidModel("rollout needs a fixed initial state".into()))?;
    let mut xs = vec![x0.to_vec(); problem.horizon() + 1];
    let mut data = ProblemData::new(problem, 1)?;
    data.rollout(problem, &mut xs, us)?;
    Ok(xs)
}

/// `M⁻¹ b` for a symmetric 2x2 mass matrix `M = [m0 m1; m1 m2]` (the two-degree-of-freedom
/// models: cart-pole, acrobot), generic over the scalar.
pub(crate) fn solve2<D: gharial::autodiff::ManifoldScalar>(m: &[D; 3], b: &[D; 2]) -> [D; 2] {
    let det = m[0] * m[2] - m[1] * m[1];
    [(m[2] * b[0] - m[1] * b[1]) / det, (m[0] * b[1] - m[1] * b[0]) / det]
}

/// States `x_0..x_N` of a straight swing-up from hanging (`θ = π`) to upright (`θ = 0`),
/// `θ_t = π (1 - t/N)`, `θ̇_t = -π/(N dt)` except at rest at both ends, written by
/// `state(θ, θ̇)`: a dynamically infeasible initial guess for the swing-up problems.
pub(crate) fn swing_guess(n: usize, dt: f64, state: impl Fn(f64, f64) -> Vec<f64>) -> Vec<Vec<f64>> {
    let pi = std::f64::consts::PI;
    let omega = -pi / (n as f64 * dt);
    (0..=n)
        .map(|t| {
            let w = if t == 0 || t == n { 0.0 } else { omega };
            state(pi * (1.0 - t as f64 / n as f64), w)
        })
        .collect()
}

/// Total cost of `(xs, us)` for `problem`.
///
/// # Errors
/// If the trajectory has a wrong size or a non-finite value.
pub fn total_cost(problem: &Problem, xs: &[Vec<f64>], us: &[Vec<f64>]) -> Result<f64> {
    problem.check_trajectory(xs, us)?;
    let mut data = ProblemData::new(problem, 1)?;
    Ok(data.evaluate(problem, xs, us))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ProxDDP (and ProxNLP) get the problem's recommended settings, the other solvers their
    /// defaults.
    #[test]
    fn options_by_solver_name() {
        let ex = build("cartpole").unwrap();
        assert_ne!(format!("{:?}", ex.proxddp), format!("{:?}", ProxDdpOptions::default()));
        for &name in SolverOptions::names() {
            let options = ex.options(name).unwrap();
            assert_eq!(options.name(), name);
            let expected = match name {
                "proxddp" => SolverOptions::ProxDdp(ex.proxddp.clone()),
                "proxnlp" => SolverOptions::ProxNlp((&ex.proxddp).into()),
                _ => SolverOptions::from_name(name).unwrap(),
            };
            assert_eq!(format!("{options:?}"), format!("{expected:?}"));
        }
        let e = ex.options("ipopt").unwrap_err().to_string();
        assert!(e.contains("unknown solver `ipopt`"), "{e}");
    }

    /// ALTRO on the car escape and the quadrotor maze starts from the problems' states
    /// (infeasible start) with the authors' penalties; elsewhere its defaults.
    #[test]
    fn altro_takes_the_recommended_settings_where_there_are_some() {
        use gharial::solvers::altro::AltroOptions;
        for (name, penalty, tol) in [("car-escape", 10.0, 1e-8), ("quadrotor-maze", 0.1, 1e-6)] {
            let ex = build(name).unwrap();
            let SolverOptions::Altro(o) = ex.options("altro").unwrap() else {
                panic!("{name}: not ALTRO's options");
            };
            assert!(o.infeasible_start, "{name}");
            assert_eq!((o.penalty_initial, o.constraint_tolerance), (penalty, tol), "{name}");
        }
        let ex = build("block-move").unwrap();
        let expected = SolverOptions::Altro(AltroOptions::default());
        assert_eq!(format!("{:?}", ex.options("altro").unwrap()), format!("{expected:?}"));
    }
}

//! The experiments of El Kazdadi, Carpentier and Ponce (2021), "Equality Constrained
//! Differential Dynamic Programming" (ECDDP), section IV, for
//! [`gharial::solvers::bcl_ddp`].
//!
//! # Cart-pole (IV-A, Figs. 1-4): `ecddp-cartpole`, `ecddp-cartpole-advanced`
//! "The upright position must be reached, while minimizing the total norm of the
//! applied force." The paper gives no numbers; those of the authors' example
//! (`ddp-pinocchio`, the cart-pendulum `(1, 1, 1)`, horizon 200, `dt = 0.01`, a target
//! configuration, `mu_init = 1e2`) are used: the cart-pole of [`crate::cartpole`] with a
//! cart of 1 kg and a point mass of 1 kg at `l = 1 m`, semi-implicit Euler, `dt = 10 ms`,
//! `N = 200` (T = 2 s),
//! ```text
//! ℓ(x, u) = ½ dt F²,   ℓ_N = 0,   q_N = (y_N, θ_N) = (0, 0)  (upright, cart back at 0)
//! ```
//! from `x0 = (0, π, 0, 0)` (hanging; the authors' convention has `θ = 0` hanging and the
//! target 3.14), guess `F = 0` and its rollout (the pole hangs still). The constraint is the terminal
//! equality on the configuration; `ecddp-cartpole-advanced` writes it on the last stage
//! instead, `h(x, u) = q(f(x, u)) - q*` by (29) (the authors advance it in time the same
//! way), so that it depends on the control and the affine multipliers of III-B have a
//! policy to act on. Results: the tests `tests/ecddp.rs` and the crate README.
//!
//! # UR5 reaching three targets (IV-B, Fig. 6): `ecddp-ur5`
//! "The system dynamics are integrated over 2 seconds, with a discretization step of
//! `dt = 0.01s` [...] the robot must reach the given targets sequentially at three
//! consecutive time instants." The UR5 of [`crate::peer_robots`] (ABA, semi-implicit
//! Euler, `τ = u`), `N = 200`, from the harness's posture `q0 = (0, -1, 1, -0.5, -0.5, 0)`
//! at rest; the tool (`tool0`) at [`UR5_TARGETS`] at the knots [`UR5_TARGET_KNOTS`]
//! (`t = 2/3 s, 4/3 s, 2 s`; the paper does not give the instants, the targets nor the
//! cost): three equality constraints on the state; the cost is the harness's running
//! regularisation without its end-effector term,
//! `dt · ½ (1e-2 |q - q0|² + 0.1 |v|² + 1e-4 |u|²)`, and `½ (1e-2 |q - q0|² + |v|²)` at
//! the end; guess `u = g(q0)` and its rollout (which stays at `x0`).

use std::sync::Arc;

use gharial::Result;
use gharial::autodiff::{AutoDiff, AutoOdeFn, AutoStageFn, ManifoldScalar};
use gharial::constraints::EqualityConstraintSet;
use gharial::costs::{ConstantCost, CostStack, QuadraticControlCost};
use gharial::dynamics::{Dynamics, SemiImplicitEuler};
use gharial::functions::{StageFunction, Unary};
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::solvers::bcl_ddp::BclDdpOptions;
use gharial::solvers::proxddp::{ProxDdpOptions, Rollout};
use gharial::spaces::{Manifold, VectorSpace};
use gharial_robotics::residuals::FrameTranslationResidual;
use gharial_robotics::{Actuation, gravity_compensation};

use crate::Example;
use crate::cartpole::CartpoleOde;
use crate::peer_robots::{Robot, Weights};
use crate::robots::UR5_URDF;

/// Time step of both experiments (s).
pub const DT: f64 = 0.01;
/// Horizon of both experiments (T = 2 s).
pub const HORIZON: usize = 200;
/// The UR5's targets for the tool.
pub const UR5_TARGETS: [[f64; 3]; 3] = [[0.3, 0.5, 0.5], [0.5, 0.1, 0.6], [0.4, -0.3, 0.3]];
/// The knots at which the UR5 reaches its targets (the last the terminal knot).
pub const UR5_TARGET_KNOTS: [usize; 3] = [66, 133, 200];

/// The cart-pole of the authors' example: cart 1 kg, point mass 1 kg at 1 m.
fn cartpole_ode() -> CartpoleOde {
    CartpoleOde::with_pole(1.0, 1.0, 1.0, 0.0)
}

/// `q(f(x, u)) - q*`: the configuration after one semi-implicit Euler step of the
/// cart-pole (`v⁺ = v + dt a(x, u)`, `q⁺ = q + dt v⁺`) minus the target (29).
#[derive(Debug, Clone)]
pub struct AdvancedConfigurationError {
    ode: CartpoleOde,
    dt: f64,
    target: [f64; 2],
}

impl AutoStageFn for AdvancedConfigurationError {
    fn nx(&self) -> usize {
        4
    }
    fn nu(&self) -> usize {
        1
    }
    fn nr(&self) -> usize {
        2
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], out: &mut [D]) {
        let mut xdot = [D::from(0.0); 4];
        self.ode.eval(x, u, &mut xdot);
        for i in 0..2 {
            let v_next = x[2 + i] + xdot[2 + i] * self.dt;
            out[i] = x[i] + v_next * self.dt - self.target[i];
        }
    }
}

/// The configuration error `q - q*` of the cart-pole.
#[derive(Debug, Clone, Copy)]
struct ConfigurationError {
    target: [f64; 2],
}

impl gharial::autodiff::AutoUnaryFn for ConfigurationError {
    fn nx(&self) -> usize {
        4
    }
    fn nr(&self) -> usize {
        2
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], out: &mut [D]) {
        out[0] = x[0] - self.target[0];
        out[1] = x[1] - self.target[1];
    }
}

/// Builds `ecddp-cartpole` (`advanced = false`) or `ecddp-cartpole-advanced` (module
/// documentation).
///
/// # Errors
/// Never for these fixed numbers.
pub fn cartpole(advanced: bool) -> Result<Example> {
    let ode = cartpole_ode();
    let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(4));
    let dynamics = Dynamics::Explicit(Arc::new(SemiImplicitEuler::new(
        Arc::new(ode.clone()),
        Arc::new(VectorSpace::new(2)),
        DT,
    )?));
    let cost = CostStack::new(space.as_ref(), 1).with(
        "force",
        Arc::new(QuadraticControlCost::diagonal(space.as_ref(), &[0.0], &[DT])?),
        1.0,
    )?;
    let stage = StageModel::new(Arc::new(cost), dynamics)?;
    let mut stages = vec![stage; HORIZON];
    let target = [0.0, 0.0];
    let x0 = [0.0, std::f64::consts::PI, 0.0, 0.0];
    let term_cost = Arc::new(ConstantCost::zero(space.as_ref(), 0));
    let (name, description) = if advanced {
        let h = AutoDiff::stage(space.clone(), AdvancedConfigurationError { ode, dt: DT, target })?;
        let c = StageConstraint::new("q_N", Arc::new(h), Arc::new(EqualityConstraintSet));
        let last = stages.pop().expect("N > 0").with_constraint(c)?;
        stages.push(last);
        (
            "ecddp-cartpole-advanced",
            "ECDDP cart-pole swing-up (Figs. 1-4) with the configuration constraint on the last control (29)",
        )
    } else {
        (
            "ecddp-cartpole",
            "ECDDP cart-pole swing-up (Figs. 1-4): N = 200, dt = 10 ms, force norm, terminal configuration upright",
        )
    };
    let mut problem = Problem::new(&x0, stages, term_cost)?;
    if !advanced {
        let h = AutoDiff::unary(space.clone(), ConfigurationError { target })?;
        problem.add_terminal_constraint(StageConstraint::new(
            "q_N",
            Arc::new(Unary::new(Arc::new(h), 0)),
            Arc::new(EqualityConstraintSet),
        ))?;
    }
    let us0 = vec![vec![0.0]; HORIZON];
    let xs0 = crate::rollout(&problem, &us0)?;
    let mut ex = Example {
        name,
        problem,
        xs0,
        us0,
        dt: Some(DT),
        proxddp: ProxDdpOptions::default(),
        description,
    };
    let mu_init = ex.proxddp.mu_init;
    crate::altro_systems::nonmonotone(&mut ex, mu_init, Rollout::Linear);
    ex.proxddp.tol = CARTPOLE_PROXDDP_TOL;
    Ok(ex)
}

/// ProxDDP's tolerance on the cart-pole (absolute residuals, forces of tens of newtons,
/// cost 90.5): with 1e-6 its dual residual stalls at 3-4e-6 after about 800 iterations
/// (measured, every rollout, step acceptance and `mu_init` 0.1); with 1e-5 and the
/// nonmonotone line search on the primal merit it converges in about 480 (the defaults:
/// about 780) to the optimum within 2e-7 relative.
pub const CARTPOLE_PROXDDP_TOL: f64 = 1e-5;

/// The BCL-DDP settings of the authors' example for the ECDDP problems (`mu_init = 1e2`
/// and the penalty factor of Fig. 2, `μ ← 100 μ`); `None` for other problems.
pub fn recommended_bcl(name: &str) -> Option<BclDdpOptions> {
    matches!(name, "ecddp-cartpole" | "ecddp-cartpole-advanced" | "ecddp-ur5").then(|| {
        BclDdpOptions::default().with(|o| {
            o.mu_init = 100.0;
            o.penalty_factor = 100.0;
        })
    })
}

/// Builds `ecddp-ur5` (module documentation).
///
/// # Errors
/// Never for these fixed numbers.
pub fn ur5() -> Result<Example> {
    let robot = Robot::load(UR5_URDF)?;
    let nq = robot.space.nq();
    let q0 = [0.0, -1.0, 1.0, -0.5, -0.5, 0.0];
    let x0: Vec<f64> = q0.iter().copied().chain([0.0; 6]).collect();
    let nu = robot.nu();
    let running = Weights {
        q: 1e-2,
        v: 1e-1,
        u: 1e-4,
        ee: 0.0,
    };
    let terminal = Weights {
        q: 1e-2,
        v: 1.0,
        u: 0.0,
        ee: 0.0,
    };
    let stage = StageModel::new(
        Arc::new(robot.cost(&x0, &running, None, nu, DT)?),
        robot.dynamics.clone(),
    )?;
    let target_row = |k: usize, nu: usize| -> Result<StageConstraint> {
        let r = FrameTranslationResidual::new(&robot.space, "tool0", &UR5_TARGETS[k])?;
        let f: Arc<dyn StageFunction> = Arc::new(Unary::new(Arc::new(r), nu));
        Ok(StageConstraint::new(
            format!("target_{}", k + 1),
            f,
            Arc::new(EqualityConstraintSet),
        ))
    };
    let mut stages = vec![stage; HORIZON];
    for (k, &t) in UR5_TARGET_KNOTS[..2].iter().enumerate() {
        stages[t] = stages[t].clone().with_constraint(target_row(k, nu)?)?;
    }
    let term = robot.cost(&x0, &terminal, None, 0, 1.0)?;
    let mut problem = Problem::new(&x0, stages, Arc::new(term))?;
    problem.add_terminal_constraint(target_row(2, 0)?)?;
    let g = gravity_compensation(robot.space.model(), &Actuation::full(robot.space.model()), &x0[..nq])?;
    let us0 = vec![g; HORIZON];
    Ok(Example {
        name: "ecddp-ur5",
        xs0: crate::rollout(&problem, &us0)?,
        problem,
        us0,
        dt: Some(DT),
        proxddp: ProxDdpOptions::default(),
        description: "ECDDP UR5 (Fig. 6): tool0 through three targets at t = 0.66, 1.33 and 2 s, N = 200, dt = 10 ms",
    })
}

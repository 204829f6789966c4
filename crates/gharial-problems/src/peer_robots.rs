//! The robot problems of the peer benchmark harness, bit for bit as its README
//! ("Problems") specifies them: UR5 reaching (`ur5`, `ur5-box`) and the double-pendulum
//! swing-up (`double-pendulum`, `double-pendulum-box`, `double-pendulum-box-term`;
//! the harness calls them `pendulum*`).
//!
//! Both robots come from example-robot-data 5.0.0 (the URDFs of
//! `gharial-multibody/tests/data/robots`, byte-identical to the harness's), fixed base,
//! fully actuated (`τ = u`), without armature. The dynamics are ABA with the
//! semi-implicit Euler step `v⁺ = v + dt a`, `q⁺ = q + dt v⁺` (dt = 0.01, N = 100), and the
//! initial guess is gravity compensation at `q0` for every control, rolled out.
//!
//! | problem | running cost `dt · [...]` | terminal cost | constraints |
//! |---|---|---|---|
//! | `ur5` | ½ (1e-2 ‖q − q0‖² + 1e-1 ‖v‖² + 1e-4 ‖u‖² + 10 ‖p(q) − p*‖²) | ½ (1e-2 ‖q − q0‖² + ‖v‖² + 1000 ‖p(q) − p*‖²) | – |
//! | `ur5-box` | as `ur5` | as `ur5` | \|u\| ≤ (60, 60, 25, 10, 10, 10) |
//! | `double-pendulum` | ½ (1e-2 ‖q‖² + 1e-2 ‖v‖² + 1e-1 ‖u‖²) | ½ (100 ‖q‖² + 100 ‖v‖²) | – |
//! | `double-pendulum-box` | as above | as above | \|u\| ≤ 0.6 |
//! | `double-pendulum-box-term` | as above | as above | \|u\| ≤ 0.6, x_N = 0 |
//!
//! with `p(q)` the world position of the UR5's `tool0` frame, `p* = (0.3, 0.5, 0.5)`,
//! `q0 = (0, −1, 1, −0.5, −0.5, 0)`, `x0 = (q0, 0)`; the pendulum starts hanging,
//! `x0 = (π, 0, 0, 0)`, towards upright at rest. The harness's reference initial costs
//! are 119.39574497820068 (UR5) and 493.52956807647496 (pendulum); the tests check them
//! to 1e-12 relative. Recommended settings, the harness's: `mu_init = 1e-5` with the
//! linear rollout for the UR5, `mu_init = 1e-2` with the nonlinear rollout for the
//! pendulum, the filter for both.

use std::sync::Arc;

use gharial::costs::{CostStack, QuadraticControlCost, QuadraticResidualCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, SemiImplicitEuler};
use gharial::functions::Unary;
use gharial::problem::{Problem, StageModel};
use gharial::solvers::proxddp::{ProxDdpOptions, Rollout};
use gharial::spaces::Manifold;
use gharial::{Error, Result};
use gharial_multibody::{Model, RootJoint};
use gharial_robotics::residuals::FrameTranslationResidual;
use gharial_robotics::{Actuation, MultibodyFreeFwdDynamics, MultibodyPhaseSpace, gravity_compensation};

use crate::Example;
use crate::lqr::terminal_state;
use crate::robots::{DOUBLE_PENDULUM_URDF, UR5_URDF};

/// Time step and horizon of every robot problem of the harness.
const DT: f64 = 0.01;
const HORIZON: usize = 100;

/// Which UR5 problem.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ur5Variant {
    /// Unconstrained reaching.
    Reach,
    /// Reaching with the control box.
    Box,
}

/// Which double-pendulum problem.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PendulumVariant {
    /// Unconstrained swing-up.
    SwingUp,
    /// Swing-up with the control box.
    Box,
    /// Swing-up with the control box and the terminal equality `x_N = 0`.
    BoxTerminal,
}

/// Weights of the quadratic terms of a stage (`wq`, `wv`, `wu`, `wee`).
pub(crate) struct Weights {
    pub q: f64,
    pub v: f64,
    pub u: f64,
    pub ee: f64,
}

/// A fixed-base robot of the harness: its model, phase space and the pieces every
/// problem shares.
pub(crate) struct Robot {
    pub space: Arc<MultibodyPhaseSpace>,
    pub dynamics: Dynamics,
}

impl Robot {
    pub(crate) fn load(urdf: &str) -> Result<Self> {
        Self::load_with_dt(urdf, DT)
    }

    /// The robot with the semi-implicit Euler step `dt`.
    pub(crate) fn load_with_dt(urdf: &str, dt: f64) -> Result<Self> {
        let model = Model::from_urdf_str(urdf, RootJoint::Fixed)
            .map_err(|e| Error::InvalidModel(format!("robot model: {e}")))?;
        let model = Arc::new(model);
        let space = Arc::new(MultibodyPhaseSpace::new(model.clone()));
        let ode = Arc::new(MultibodyFreeFwdDynamics::new(space.clone(), Actuation::full(&model))?);
        let step = SemiImplicitEuler::new(ode, space.configuration().clone(), dt)?;
        Ok(Self {
            space,
            dynamics: Dynamics::Explicit(Arc::new(step)),
        })
    }

    pub(crate) fn nu(&self) -> usize {
        self.space.nv()
    }

    /// `scale · ½ (wq ‖q − q_ref‖² + wv ‖v‖² + wu ‖u‖² + wee ‖p_ee(q) − p*‖²)`; the
    /// control term only when `nu > 0`, the end-effector term only with `ee`.
    pub(crate) fn cost(
        &self,
        x_ref: &[f64],
        w: &Weights,
        ee: Option<(&str, &[f64])>,
        nu: usize,
        scale: f64,
    ) -> Result<CostStack> {
        let (space, nv): (Arc<dyn Manifold>, usize) = (self.space.clone(), self.space.nv());
        let state_w: Vec<f64> = (0..2 * nv).map(|i| if i < nv { w.q } else { w.v }).collect();
        let mut cost = CostStack::new(space.as_ref(), nu).with(
            "state",
            Arc::new(QuadraticStateCost::diagonal(space.clone(), x_ref, &state_w, nu)?),
            scale,
        )?;
        if nu > 0 {
            let control = QuadraticControlCost::diagonal(space.as_ref(), &vec![0.0; nu], &vec![w.u; nu])?;
            cost = cost.with("control", Arc::new(control), scale)?;
        }
        if let Some((frame, target)) = ee {
            let r = FrameTranslationResidual::new(&self.space, frame, target)?;
            let f = Arc::new(Unary::new(Arc::new(r), nu));
            cost = cost.with("ee", Arc::new(QuadraticResidualCost::diagonal(f, &[w.ee; 3])?), scale)?;
        }
        Ok(cost)
    }

    /// The problem from `x0` with the given running and terminal costs, the guess
    /// `u_t = g(q0)` and its rollout.
    fn problem(&self, x0: &[f64], running: CostStack, terminal: CostStack) -> Result<(Problem, Vec<Vec<f64>>)> {
        let stage = StageModel::new(Arc::new(running), self.dynamics.clone())?;
        let problem = Problem::new(x0, vec![stage; HORIZON], Arc::new(terminal))?;
        let nq = self.space.nq();
        let g = gravity_compensation(self.space.model(), &Actuation::full(self.space.model()), &x0[..nq])?;
        Ok((problem, vec![g; HORIZON]))
    }
}

/// The UR5 reaching problem of the harness (module documentation).
///
/// # Errors
/// Never for these fixed numbers (constructors are fallible in general).
pub fn ur5(variant: Ur5Variant) -> Result<Example> {
    let q0 = [0.0, -1.0, 1.0, -0.5, -0.5, 0.0];
    let x0: Vec<f64> = q0.iter().copied().chain([0.0; 6]).collect();
    ur5_from(variant, &x0)
}

/// The UR5 reaching problem from the state `x0 = (q0, v0)`, its state regularised towards
/// `(q0, 0)` (for the harness's `x0`, [`ur5`]).
///
/// # Errors
/// If `x0` is not a UR5 state (12 numbers).
pub(crate) fn ur5_from(variant: Ur5Variant, x0: &[f64]) -> Result<Example> {
    let robot = Robot::load(UR5_URDF)?;
    let nq = robot.space.nq();
    let mut x_ref = x0.to_vec();
    x_ref.get_mut(nq..).into_iter().flatten().for_each(|v| *v = 0.0);
    let target = [0.3, 0.5, 0.5];
    let nu = robot.nu();
    let ee = Some(("tool0", &target[..]));
    let running = Weights {
        q: 1e-2,
        v: 1e-1,
        u: 1e-4,
        ee: 10.0,
    };
    let terminal = Weights {
        q: 1e-2,
        v: 1.0,
        u: 0.0,
        ee: 1000.0,
    };
    let (mut problem, us0) = robot.problem(
        x0,
        robot.cost(&x_ref, &running, ee, nu, DT)?,
        robot.cost(&x_ref, &terminal, ee, 0, 1.0)?,
    )?;
    let (name, description) = match variant {
        Ur5Variant::Reach => (
            "ur5",
            "Peer-harness UR5 reaching: tool0 to (0.3, 0.5, 0.5) in 1 s; reference optimal cost 0.338866186487.",
        ),
        Ur5Variant::Box => {
            let umax = [60.0, 60.0, 25.0, 10.0, 10.0, 10.0];
            let lower: Vec<f64> = umax.iter().map(|u| -u).collect();
            for stage in problem.stages_mut() {
                stage.add_constraint(box_on_u(robot.space.as_ref(), &lower, &umax)?)?;
            }
            (
                "ur5-box",
                "Peer-harness UR5 reaching with |u| <= (60, 60, 25, 10, 10, 10); reference optimal cost 0.35494324600.",
            )
        }
    };
    example(name, description, problem, us0, 1e-5, Rollout::Linear)
}

/// The double-pendulum swing-up of the harness (module documentation).
///
/// # Errors
/// Never for these fixed numbers (constructors are fallible in general).
pub fn double_pendulum(variant: PendulumVariant) -> Result<Example> {
    let robot = Robot::load(DOUBLE_PENDULUM_URDF)?;
    let x0 = [std::f64::consts::PI, 0.0, 0.0, 0.0];
    let target = [0.0; 4];
    let nu = robot.nu();
    let running = Weights {
        q: 1e-2,
        v: 1e-2,
        u: 1e-1,
        ee: 0.0,
    };
    let terminal = Weights {
        q: 100.0,
        v: 100.0,
        u: 0.0,
        ee: 0.0,
    };
    let (mut problem, us0) = robot.problem(
        &x0,
        robot.cost(&target, &running, None, nu, DT)?,
        robot.cost(&target, &terminal, None, 0, 1.0)?,
    )?;
    if variant != PendulumVariant::SwingUp {
        for stage in problem.stages_mut() {
            stage.add_constraint(box_on_u(robot.space.as_ref(), &[-0.6; 2], &[0.6; 2])?)?;
        }
    }
    if variant == PendulumVariant::BoxTerminal {
        problem.add_terminal_constraint(terminal_state(robot.space.clone(), &target)?)?;
    }
    let (name, description) = match variant {
        PendulumVariant::SwingUp => (
            "double-pendulum",
            "Peer-harness double-pendulum swing-up from hanging to upright in 1 s; reference optimal cost 0.0842906371.",
        ),
        PendulumVariant::Box => (
            "double-pendulum-box",
            "Peer-harness double-pendulum swing-up with |u| <= 0.6; reference optimal cost 0.0848427549.",
        ),
        PendulumVariant::BoxTerminal => (
            "double-pendulum-box-term",
            "Peer-harness double-pendulum swing-up with |u| <= 0.6 and x_N = 0; reference optimal cost 0.08484701.",
        ),
    };
    example(name, description, problem, us0, 1e-2, Rollout::Nonlinear)
}

/// The box `lower <= u <= upper` on the controls.
fn box_on_u(space: &dyn Manifold, lower: &[f64], upper: &[f64]) -> Result<gharial::problem::StageConstraint> {
    let f = Arc::new(gharial::functions::ControlError::new(space, &vec![0.0; lower.len()])?);
    let set = Arc::new(gharial::constraints::BoxConstraint::new(lower, upper)?);
    Ok(gharial::problem::StageConstraint::new("u_box", f, set))
}

/// The example with the rolled-out guess and the harness's ProxDDP settings.
fn example(
    name: &'static str,
    description: &'static str,
    problem: Problem,
    us0: Vec<Vec<f64>>,
    mu_init: f64,
    rollout: Rollout,
) -> Result<Example> {
    let xs0 = crate::rollout(&problem, &us0)?;
    Ok(Example {
        name,
        problem,
        xs0,
        us0,
        dt: Some(DT),
        proxddp: ProxDdpOptions::default().with(|o| {
            o.mu_init = mu_init;
            o.rollout = rollout;
            o.max_iters = 500;
        }),
        description,
    })
}

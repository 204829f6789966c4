//! Randomised instance families of the unconstrained benchmark of the stagewise-SQP
//! paper (Jordana et al. 2023, §VI-A, Fig. 1: the fraction of instances solved as a
//! function of the iteration budget), on the robots gharial has.
//!
//! Each family draws its random numbers from one [`SplitMix64`] stream seeded by the
//! caller, instance after instance, so `family(name, seed, n)` is a prefix of
//! `family(name, seed, m)` for `n ≤ m`. What is randomised follows the paper's benchmark
//! scripts (StagewiseSQP, `rollout_benchmark.py`, `taichi_benchmark.py`): the initial
//! state, at rest, or for the humanoid the end-effector goal. Every instance is
//! warm-started as in the paper, with the quasi-static controls and the constant state
//! guess `x_t = x0` (gaps open where `x0` is not an equilibrium).
//!
//! | family | paper's problem | model | N, dt | randomised |
//! |---|---|---|---|---|
//! | `reach` | Kuka reaching (nx 14, nu 7) | the harness's UR5 ([`crate::peer_robots`], `ur5`): tool0 to (0.3, 0.5, 0.5), state regularised towards `(q0, 0)` | 100, 10 ms | `q0_i ~ U(-π, π)` (the UR5's limits are ±2π: every configuration once), `v0 = 0` |
//! | `quadrotor` | Quadrotor pose (nx 13, nu 4) | [`crate::quadrotor::QuadrotorOde`] (Hector), explicit Euler, the paper's costs (below) | 33, 30 ms | position `U(-1, 1)³`, attitude uniform on SO(3), twist 0 |
//! | `pendulum` | Double-pendulum swing-up (nx 4, nu 1) | the harness's double pendulum (URDF), first joint actuated (crocoddyl's `actLink = 1`), semi-implicit Euler, crocoddyl's costs (below) | 100, 10 ms | `q0 = (U(-π, π), 0)`, `v0 = 0` |
//! | `humanoid` | Humanoid taichi (Talos, nx 77, nu 32) | the Unitree G1 (29 joints, nx 71, nu 29) on its right foot (6D contact, Baumgarte `Kd = 50`), semi-implicit Euler, costs below | 30, 30 ms | left-foot goal: its neutral placement moved by `(U(-0.1, 0.2), U(0, 0.1), U(0.05, 0.2))` m |
//!
//! Quadrotor costs (crocoddyl's `quadrotor.py` of the paper's benchmark): running
//! `dt · [1e-6 · ½ |x ⊖ x_0|²_W + 1e-6 · ½ |u|² + 1e-2 · ½ |p ⊖ p*|²]` with
//! `W = diag(0.1 (position), 1000 (attitude), 1000 (twist))`, `x_0` the origin at rest
//! and `p ⊖ p*` the SE(3) error of the pose to `p* = (1, 0, 1)`, identity attitude;
//! terminal `3 · ½ |p ⊖ p*|²`. Guess: the hover thrust `m g / 4` on every rotor.
//!
//! Pendulum costs (the paper's script): running `1e-4 · ½ u² + 1e-5 · ½ |r(x)|²_W`,
//! terminal `100 · ½ |r(x)|²_W`, with crocoddyl's goal residual
//! `r = (sin q₁, sin q₂, 1 − cos q₁, 1 − cos q₂, v₁, v₂)` and `W = diag(1, 1, 1, 1, 0.1, 0.1)`.
//! Guess: the first joint's gravity torque at `q0`.
//!
//! Humanoid costs: running `dt · [½ |x ⊖ x0|²_W + 1e-4 · ½ |u − u0|² + ½ |log6(M*⁻¹ M_left)|²]`
//! with `W` 0 on the base pose, 0.1 on the joints and velocities; terminal
//! `½ |x ⊖ x0|²_W + 100 · ½ |log6(M*⁻¹ M_left)|²`; `x0` the G1's neutral configuration at
//! rest, `u0` its quasi-static torques on the right foot. Unlike the paper's taichi it
//! has one phase (no double-support phase first) and no state-limit barriers.

use std::sync::Arc;

use gharial::autodiff::AutoDiff;
use gharial::costs::{CostStack, QuadraticControlCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, ExplicitRungeKutta};
use gharial::lq::random::SplitMix64;
use gharial::problem::{Problem, StageModel};
use gharial::solvers::proxddp::{ProxDdpOptions, Rollout};
use gharial::solvers::{Callback, IterationRecord, Solution};
use gharial::{Error, Result};

use gharial::autodiff::{AutoUnaryFn, ManifoldScalar};
use gharial::costs::QuadraticResidualCost;
use gharial::dynamics::SemiImplicitEuler;
use gharial::functions::Unary;
use gharial::spaces::Manifold;
use gharial_multibody::spatial::{Se3, Vec3};
use gharial_multibody::{Model, ReferenceFrame, RootJoint, forward_kinematics_placements, neutral};
use gharial_robotics::residuals::FramePlacementResidual;
use gharial_robotics::{
    Actuation, ContactSpec, MultibodyConstraintFwdDynamics, MultibodyFreeFwdDynamics, MultibodyPhaseSpace,
    contacts_at_frames, gravity_compensation, set_contact_references,
};

use crate::peer_robots::{Ur5Variant, ur5_from};
use crate::quadrotor::{QuadrotorOde, at, space};
use crate::robots::{DOUBLE_PENDULUM_URDF, G1_URDF};
use crate::{Example, ProblemInfo};

/// Most instances [`family`] builds at once (a larger count is an error, not an
/// allocation).
pub const MAX_COUNT: usize = 10_000;

/// The families [`family`] knows.
pub static FAMILIES: &[ProblemInfo] = &[
    ProblemInfo {
        name: "reach",
        summary: "UR5 end-effector reaching from a random configuration at rest (the paper's Kuka task)",
    },
    ProblemInfo {
        name: "quadrotor",
        summary: "quadrotor pose task on SE(3) from a random pose at rest (N = 33, dt = 30 ms)",
    },
    ProblemInfo {
        name: "pendulum",
        summary: "double-pendulum swing-up from a random first-joint angle at rest",
    },
    ProblemInfo {
        name: "humanoid",
        summary: "G1 humanoid on its right foot moving its left foot to a random placement (the paper's taichi)",
    },
];

/// Time step and horizon of the `quadrotor` family (the paper's benchmark script).
const QUAD_DT: f64 = 0.03;
const QUAD_HORIZON: usize = 33;

/// `count` instances of the family `name` (see [`FAMILIES`]) drawn from `seed`.
///
/// # Errors
/// If `name` is unknown (the message lists the families) or `count` exceeds
/// [`MAX_COUNT`].
pub fn family(name: &str, seed: u64, count: usize) -> Result<Vec<Example>> {
    if count > MAX_COUNT {
        return Err(Error::InvalidModel(format!(
            "family `{name}`: {count} instances asked, at most {MAX_COUNT}"
        )));
    }
    let build: fn(&mut SplitMix64) -> Result<Example> = match name {
        "reach" => reach,
        "quadrotor" => quadrotor,
        "pendulum" => pendulum,
        "humanoid" => humanoid,
        _ => {
            return Err(Error::InvalidModel(format!(
                "unknown family `{name}`; valid names: {}",
                FAMILIES.iter().map(|f| f.name).collect::<Vec<_>>().join(", ")
            )));
        }
    };
    let mut rng = SplitMix64::new(seed);
    (0..count).map(|_| build(&mut rng)).collect()
}

/// The profile's test as a solver callback: remembers the first iteration whose KKT
/// residual `max(prim_err, dual_err)` is at most `tol`, and stops the solve there.
#[derive(Debug, Clone, Copy)]
pub struct FirstKkt {
    tol: f64,
    first: Option<usize>,
}

impl FirstKkt {
    /// A watch for the test at `tol`.
    pub fn new(tol: f64) -> Self {
        Self { tol, first: None }
    }

    /// The iteration at which the solve that ended in `sol` passed the test: the first
    /// watched row that did, else its final point if it does (a solve can stop before
    /// stepping from a point, e.g. a stall at round-off, and the callback never sees it).
    pub fn solved_at(&self, sol: &Solution) -> Option<usize> {
        self.first
            .or_else(|| (sol.prim_err.max(sol.dual_err) <= self.tol).then_some(sol.iterations))
    }
}

impl Callback for FirstKkt {
    fn on_iteration(&mut self, record: &IterationRecord) -> bool {
        if record.prim_err.max(record.dual_err) <= self.tol {
            self.first = Some(record.iter);
        }
        self.first.is_none()
    }
}

/// The paper's warm start: the constant state guess `x_t = x0`.
fn constant_guess(mut ex: Example) -> Example {
    let x0 = ex.xs0[0].clone();
    ex.xs0.fill(x0);
    ex
}

fn reach(rng: &mut SplitMix64) -> Result<Example> {
    let pi = std::f64::consts::PI;
    let mut x0 = vec![0.0; 12];
    x0[..6].iter_mut().for_each(|q| *q = rng.uniform(-pi, pi));
    let mut ex = ur5_from(Ur5Variant::Reach, &x0)?;
    ex.name = "reach";
    ex.description = "UR5 reaching: tool0 to (0.3, 0.5, 0.5) in 1 s from a random configuration at rest.";
    Ok(constant_guess(ex))
}

/// Time step and horizon of the `pendulum` family (the harness's and the paper's).
const PENDULUM_DT: f64 = 0.01;
const PENDULUM_HORIZON: usize = 100;

/// Crocoddyl's double-pendulum goal residual
/// `(sin q₁, sin q₂, 1 − cos q₁, 1 − cos q₂, v₁, v₂)`: zero upright at rest.
#[derive(Debug, Clone, Copy)]
struct UprightResidual;

impl AutoUnaryFn for UprightResidual {
    fn nx(&self) -> usize {
        4
    }
    fn nr(&self) -> usize {
        6
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], out: &mut [D]) {
        for i in 0..2 {
            out[i] = x[i].sin();
            out[2 + i] = -x[i].cos() + 1.0;
            out[4 + i] = x[2 + i];
        }
    }
}

fn pendulum(rng: &mut SplitMix64) -> Result<Example> {
    let pi = std::f64::consts::PI;
    let x0 = vec![rng.uniform(-pi, pi), 0.0, 0.0, 0.0];
    let model = Model::from_urdf_str(DOUBLE_PENDULUM_URDF, RootJoint::Fixed)
        .map_err(|e| Error::InvalidModel(format!("double pendulum: {e}")))?;
    let model = Arc::new(model);
    let phase = Arc::new(MultibodyPhaseSpace::new(model.clone()));
    let space: Arc<dyn Manifold> = phase.clone();
    let ode = Arc::new(MultibodyFreeFwdDynamics::new(
        phase.clone(),
        Actuation::dofs(&model, &[0])?,
    )?);
    let step = SemiImplicitEuler::new(ode, phase.configuration().clone(), PENDULUM_DT)?;
    let nu = 1;
    let goal = |weight: f64, nu: usize| -> Result<Arc<QuadraticResidualCost>> {
        let r = Arc::new(Unary::new(
            Arc::new(AutoDiff::unary(space.clone(), UprightResidual)?),
            nu,
        ));
        let w: Vec<f64> = [1.0, 1.0, 1.0, 1.0, 0.1, 0.1].iter().map(|w| weight * w).collect();
        Ok(Arc::new(QuadraticResidualCost::diagonal(r, &w)?))
    };
    let running = CostStack::new(space.as_ref(), nu)
        .with(
            "u_reg",
            Arc::new(QuadraticControlCost::diagonal(space.as_ref(), &[0.0], &[1e-4])?),
            1.0,
        )?
        .with("x_goal", goal(1e-5, nu)?, 1.0)?;
    let terminal = CostStack::new(space.as_ref(), 0).with("x_goal", goal(100.0, 0)?, 1.0)?;
    let stage = StageModel::new(Arc::new(running), Dynamics::Explicit(Arc::new(step)))?;
    let problem = Problem::new(&x0, vec![stage; PENDULUM_HORIZON], Arc::new(terminal))?;
    // The quasi-static guess: the first joint's gravity torque at `q0`.
    let g = gravity_compensation(&model, &Actuation::full(&model), &x0[..2])?;
    Ok(Example {
        name: "pendulum",
        problem,
        xs0: vec![x0; PENDULUM_HORIZON + 1],
        us0: vec![vec![g[0]]; PENDULUM_HORIZON],
        dt: Some(PENDULUM_DT),
        proxddp: ProxDdpOptions::default().with(|o| {
            o.mu_init = 1e-2;
            o.rollout = Rollout::Nonlinear;
            o.max_iters = 500;
        }),
        description: "Double-pendulum (first joint actuated) swing-up to upright at rest in 1 s from a random \
                      first-joint angle; crocoddyl's goal residual.",
    })
}

/// A unit quaternion `(x, y, z, w)` uniform on SO(3) (Shoemake's method).
fn random_quaternion(rng: &mut SplitMix64) -> [f64; 4] {
    let tau = 2.0 * std::f64::consts::PI;
    let (u1, u2, u3) = (rng.uniform(0.0, 1.0), rng.uniform(0.0, 1.0), rng.uniform(0.0, 1.0));
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    [
        a * (tau * u2).sin(),
        a * (tau * u2).cos(),
        b * (tau * u3).sin(),
        b * (tau * u3).cos(),
    ]
}

fn quadrotor(rng: &mut SplitMix64) -> Result<Example> {
    let mut x0 = at([rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0)]);
    x0[3..7].copy_from_slice(&random_quaternion(rng));
    let space = space();
    let nu = 4;
    let ode = QuadrotorOde::hector()?;
    let hover = ode.hover_thrust();
    let ode = Arc::new(AutoDiff::ode(space.clone(), ode)?);
    let dynamics = Dynamics::Explicit(Arc::new(ExplicitRungeKutta::euler(ode, QUAD_DT)?));
    let target = at([1.0, 0.0, 1.0]);
    let pose = |w: f64| -> Vec<f64> { (0..12).map(|i| if i < 6 { w } else { 0.0 }).collect() };
    let reg: Vec<f64> = (0..12)
        .map(|i| 1e-6 * QUAD_DT * if i < 3 { 0.1 } else { 1000.0 })
        .collect();
    let running = CostStack::new(space.as_ref(), nu)
        .with(
            "x_reg",
            Arc::new(QuadraticStateCost::diagonal(space.clone(), &at([0.0; 3]), &reg, nu)?),
            1.0,
        )?
        .with(
            "u_reg",
            Arc::new(QuadraticControlCost::diagonal(
                space.as_ref(),
                &[0.0; 4],
                &[1e-6 * QUAD_DT; 4],
            )?),
            1.0,
        )?
        .with(
            "pose",
            Arc::new(QuadraticStateCost::diagonal(
                space.clone(),
                &target,
                &pose(1e-2 * QUAD_DT),
                nu,
            )?),
            1.0,
        )?;
    let terminal = QuadraticStateCost::diagonal(space.clone(), &target, &pose(3.0), 0)?;
    let stage = StageModel::new(Arc::new(running), dynamics)?;
    let problem = Problem::new(&x0, vec![stage; QUAD_HORIZON], Arc::new(terminal))?;
    Ok(Example {
        name: "quadrotor",
        problem,
        xs0: vec![x0; QUAD_HORIZON + 1],
        us0: vec![vec![hover; nu]; QUAD_HORIZON],
        dt: Some(QUAD_DT),
        proxddp: ProxDdpOptions::default().with(|o| {
            o.mu_init = 0.1;
            o.rollout = Rollout::Nonlinear;
            o.max_iters = 300;
        }),
        description: "Quadrotor pose task: (1, 0, 1), identity attitude, from a random pose at rest; \
                      Euler, dt = 0.03, N = 33.",
    })
}

/// Time step and horizon of the `humanoid` family.
const HUMANOID_DT: f64 = 0.03;
const HUMANOID_HORIZON: usize = 30;
/// The stance and the swing foot of the `humanoid` family.
const STANCE_FOOT: &str = "right_ankle_roll_link";
const SWING_FOOT: &str = "left_ankle_roll_link";

/// The world placement of frame `name` at configuration `q`.
fn frame_placement(model: &Model, name: &str, q: &[f64]) -> Result<Se3> {
    let error = |e: gharial_multibody::Error| Error::InvalidModel(format!("humanoid: frame {name}: {e}"));
    let id = model.frame_id(name).map_err(error)?;
    let mut data = model.create_data();
    forward_kinematics_placements(model, &mut data, q).map_err(error)?;
    let frame = &model.frames()[id];
    Ok(data.joint_placement(frame.parent_joint).compose(&frame.placement))
}

fn humanoid(rng: &mut SplitMix64) -> Result<Example> {
    let model = Model::from_urdf_str(G1_URDF, RootJoint::FreeFlyer)
        .map_err(|e| Error::InvalidModel(format!("humanoid: G1 model: {e}")))?;
    let q0 = neutral(&model);
    let mut target = frame_placement(&model, SWING_FOOT, &q0)?;
    target.translation += Vec3::new(rng.uniform(-0.1, 0.2), rng.uniform(0.0, 0.1), rng.uniform(0.05, 0.2));
    let model = Arc::new(model);
    let phase = Arc::new(MultibodyPhaseSpace::new(model.clone()));
    let space: Arc<dyn Manifold> = phase.clone();
    let actuation = Arc::new(Actuation::floating_base(&model)?);
    let spec = ContactSpec::frame(ReferenceFrame::Local).with_gains(0.0, 50.0);
    let mut contacts = contacts_at_frames(&model, &[STANCE_FOOT], spec)?;
    set_contact_references(&model, &mut contacts, &q0)?;
    let ode = Arc::new(MultibodyConstraintFwdDynamics::new(
        phase.clone(),
        actuation.clone(),
        contacts,
    )?);
    let u0 = ode.quasi_static_torque(&q0)?.u;
    let step = SemiImplicitEuler::new(ode, phase.configuration().clone(), HUMANOID_DT)?;
    let (nv, nu) = (model.nv(), actuation.nu());
    let x0: Vec<f64> = q0.iter().copied().chain(std::iter::repeat_n(0.0, nv)).collect();
    let foot = |weight: f64, nu: usize| -> Result<Arc<QuadraticResidualCost>> {
        let r = FramePlacementResidual::new(&phase, SWING_FOOT, &target)?;
        Ok(Arc::new(QuadraticResidualCost::diagonal(
            Arc::new(Unary::new(Arc::new(r), nu)),
            &[weight; 6],
        )?))
    };
    // Base pose free, joints 1e-1, velocities 1e-1 (running, times dt).
    let x_weights: Vec<f64> = (0..2 * nv).map(|i| if i < 6 { 0.0 } else { 1e-1 }).collect();
    let x_reg = |scale: f64, nu: usize| -> Result<Arc<QuadraticStateCost>> {
        let w: Vec<f64> = x_weights.iter().map(|w| scale * w).collect();
        Ok(Arc::new(QuadraticStateCost::diagonal(space.clone(), &x0, &w, nu)?))
    };
    let running = CostStack::new(space.as_ref(), nu)
        .with("x_reg", x_reg(HUMANOID_DT, nu)?, 1.0)?
        .with(
            "u_reg",
            Arc::new(QuadraticControlCost::diagonal(
                space.as_ref(),
                &u0,
                &vec![1e-4 * HUMANOID_DT; nu],
            )?),
            1.0,
        )?
        .with("foot", foot(HUMANOID_DT, nu)?, 1.0)?;
    let terminal = CostStack::new(space.as_ref(), 0)
        .with("x_reg", x_reg(1.0, 0)?, 1.0)?
        .with("foot", foot(100.0, 0)?, 1.0)?;
    let stage = StageModel::new(Arc::new(running), Dynamics::Explicit(Arc::new(step)))?;
    let problem = Problem::new(&x0, vec![stage; HUMANOID_HORIZON], Arc::new(terminal))?;
    Ok(Example {
        name: "humanoid",
        problem,
        xs0: vec![x0; HUMANOID_HORIZON + 1],
        us0: vec![u0; HUMANOID_HORIZON],
        dt: Some(HUMANOID_DT),
        proxddp: ProxDdpOptions::default().with(|o| {
            o.mu_init = 1e-2;
            o.rollout = Rollout::Linear;
            o.max_iters = 300;
        }),
        description: "G1 humanoid on its right foot (6D contact) moves its left foot to a random placement; \
                      semi-implicit Euler, dt = 0.03, N = 30.",
    })
}

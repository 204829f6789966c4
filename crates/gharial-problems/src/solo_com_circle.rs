//! Solo-12 standing on its four feet while its centre of mass tracks a horizontal
//! circle, with friction cones: the constrained multi-contact example of the
//! stagewise-SQP paper (Jordana et al., 2023, §V-B1, Figs. 4 and 5).
//!
//! **The paper's setting**: 250 nodes of 20 ms, the CoM on a circle of 13 cm diameter,
//! the contact forces in their Coulomb cones `‖F_T‖ ≤ μ F_N` with `μ = 0.8`, CSQP with
//! QP tolerances 1e-6 and termination tolerance 1e-4. The numbers below are those of
//! the authors' public example (`mim_solvers`, `examples/solo12.py`).
//!
//! **Model** (every stage): the Solo-12 of [`crate::solo_walk`] (example-robot-data
//! 5.0.0, free-flyer base, `nq = 19`, `nv = 18`, twelve actuated joints) in the
//! standing posture `straight_standing` lowered onto the ground, rigid 3D point
//! contacts at the four feet (LOCAL_WORLD_ALIGNED) solved exactly
//! ([`MultibodyConstraintFwdDynamics`]) with the Baumgarte gains of `solo_walk`,
//! `Kp = 0`, `Kd = 1/Δt` (the authors' example has no Baumgarte term; with `Kd = 1/Δt`
//! the contact velocity is damped to zero in one step instead of drifting),
//! semi-implicit Euler `v⁺ = v + Δt a`, `q⁺ = q ⊕ Δt v⁺`.
//!
//! **The circle** ([`com_target`]): `c*(t) = c0 + r (sin ωt, cos ωt − 1, 0)`, in the
//! horizontal plane of the standing CoM height, radius `r` = [`RADIUS`] = 6.5 cm,
//! `ω` = [`OMEGA`] = 2π · 0.2 rad/s (one turn in 5 s, the 250 nodes; 8.2 cm/s), starting
//! at `c0` = (the mean of the feet's `x, y`, the CoM height of the standing posture)
//! and turning clockwise seen from above (towards +x first). Stage `t` and the terminal
//! node track `c*(t Δt)`, each through its own [`CenterOfMassTranslationResidual`].
//!
//! **Cost** (`½ w ‖·‖²`; running terms times `Δt`, the terminal ones not):
//!
//! | term | running | terminal |
//! |---|---|---|
//! | state `x ⊖ x0`: base translation | 0 | 0 |
//! | state: base rotation | 0.1 · 500² | 0.1 Δt · 500² |
//! | state: joint positions | 0.1 · 0.01² | 0.1 Δt · 0.01² |
//! | state: base linear and angular velocity | 0.1 · 10² | 0.1 Δt · 10² |
//! | state: joint velocities | 0.1 | 0.1 Δt |
//! | control `u − u_qs`, the quasi-static torque of the standing robot | [`W_CONTROL`] = 1e-3 | – |
//! | CoM `c(q) − c*(t)` | [`W_COM`] = 1e5 | 1e5 |
//!
//! (The authors regularise `u` around zero; here around `u_qs`.) **Constraints** on every running stage: the friction cones of the four feet
//! ([`FrictionConeResidual`] stacked with one contact solve,
//! [`StackedContactResidual`], in a [`ConstraintSetProduct`] of four
//! [`SecondOrderCone`]s), and optionally the URDF's effort limits
//! ([`CircleParams::torque_limits`]; 1000 N m in this URDF, never reached).
//!
//! **Guess** (the authors'): the standing state `x0` at every node and `u_qs` at every
//! stage. It is not the rollout of `u_qs`: the standing equilibrium is unstable, and
//! the rollout's rounding errors grow until it diverges (non-finite at node 181).
//!
//! **Results**: the cones bind. On the catalogue's 250 nodes the hind-left foot's force
//! lies on its cone over stages 53-82 and the front-left foot's over stages 83-197
//! (`‖f_t‖ / f_n = 0.8`); with regularisation around zero torque instead (the authors'
//! choice) they bind as well. On the tests' first 80 nodes (`tests/solo_com_circle.rs`)
//! the hind-left cone binds over stages 53-79 and, at tolerance 1e-8, CSQP (6
//! iterations) and ProxDDP (17) reach the same cost (0.1470166, to 1.2e-7 relative), the
//! CoM within 0.03 mm of the circle at every node. Release runs of the 250 nodes: the
//! crate README.

use std::sync::Arc;

use gharial::constraints::{ConstraintSet, ConstraintSetProduct, SecondOrderCone};
use gharial::costs::{CostStack, QuadraticControlCost, QuadraticResidualCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, SemiImplicitEuler};
use gharial::functions::Unary;
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::solvers::proxddp::{ProxDdpOptions, Rollout};
use gharial::spaces::Manifold;
use gharial::{Error, Result};
use gharial_multibody::center_of_mass;
use gharial_robotics::MultibodyConstraintFwdDynamics;
use gharial_robotics::residuals::{
    CenterOfMassTranslationResidual, FrictionCone, FrictionConeResidual, StackedContactResidual, effort_limits,
};

use crate::Example;
use crate::solo_walk::{Phase, Solo, feet_positions};

/// Time step (s), the paper's.
pub const DT: f64 = 0.02;
/// Number of running stages of the catalogue entry (5 s), the paper's.
pub const HORIZON: usize = 250;
/// Largest accepted horizon (one stage object per node).
pub const MAX_HORIZON: usize = 100_000;
/// Friction coefficient, the paper's.
pub const MU: f64 = 0.8;
/// Radius of the CoM circle (m), the authors'.
pub const RADIUS: f64 = 0.065;
/// Angular speed on the circle (rad/s), the authors' `2π · 0.2`.
pub const OMEGA: f64 = 2.0 * std::f64::consts::PI * 0.2;
/// Weight of the state regularisation (times the squared per-coordinate scales).
pub const W_STATE: f64 = 0.1;
/// Weight of the control regularisation.
pub const W_CONTROL: f64 = 1e-3;
/// Weight of the CoM tracking.
pub const W_COM: f64 = 1e5;

/// The numbers of the problem; the default is the catalogue's `solo-com-circle`.
#[derive(Debug, Clone, PartialEq)]
pub struct CircleParams {
    /// Number of running stages `N` (default [`HORIZON`]).
    pub horizon: usize,
    /// Friction coefficient of the cones (default [`MU`]).
    pub mu: f64,
    /// The URDF's effort limits as a box on the controls (default off).
    pub torque_limits: bool,
}

impl Default for CircleParams {
    fn default() -> Self {
        Self {
            horizon: HORIZON,
            mu: MU,
            torque_limits: false,
        }
    }
}

impl CircleParams {
    fn validate(&self) -> Result<()> {
        if !(1..=MAX_HORIZON).contains(&self.horizon) {
            return Err(Error::option(
                "solo_com_circle: horizon",
                format!("must be in 1..={MAX_HORIZON}, got {}", self.horizon),
            ));
        }
        if !(self.mu.is_finite() && self.mu > 0.0) {
            return Err(Error::option(
                "solo_com_circle: mu",
                format!("must be finite and positive, got {}", self.mu),
            ));
        }
        Ok(())
    }
}

/// The problem with the models it is built from.
pub struct CircleSetup {
    /// The optimal control problem.
    pub problem: Problem,
    /// The standing state `x0 = (q0, 0)`.
    pub x0: Vec<f64>,
    /// The quasi-static torque of the standing robot (control reference and guess).
    pub u_stand: Vec<f64>,
    /// The start and centre height of the circle, `c0` (module documentation).
    pub c0: [f64; 3],
    /// The four-feet contact dynamics of every stage (forces in the order of
    /// [`crate::solo_walk::FEET`]).
    pub dynamics: Arc<MultibodyConstraintFwdDynamics>,
    /// The friction coefficient of the cones.
    pub mu: f64,
}

impl std::fmt::Debug for CircleSetup {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CircleSetup")
            .field("horizon", &self.problem.horizon())
            .field("c0", &self.c0)
            .field("mu", &self.mu)
            .finish_non_exhaustive()
    }
}

/// The CoM target `c*(t) = c0 + r (sin ωt, cos ωt − 1, 0)` at time `t` (s).
pub fn com_target(c0: [f64; 3], t: f64) -> [f64; 3] {
    let (s, c) = (OMEGA * t).sin_cos();
    [c0[0] + RADIUS * s, c0[1] + RADIUS * (c - 1.0), c0[2]]
}

/// The state weights of the module documentation (tangent order: base translation,
/// base rotation, joints; then the velocities), without the factor [`W_STATE`].
fn state_weights(nv: usize) -> Vec<f64> {
    let mut w = vec![0.0; 2 * nv];
    w[3..6].fill(500.0_f64.powi(2));
    w[6..nv].fill(0.01_f64.powi(2));
    w[nv..nv + 6].fill(10.0_f64.powi(2));
    w[nv + 6..].fill(1.0);
    w
}

/// `½ ‖c(q) − c*‖²` for stages with `nu` controls.
fn com_cost(solo: &Solo, target: [f64; 3], nu: usize) -> Result<Arc<QuadraticResidualCost>> {
    let r = CenterOfMassTranslationResidual::new(&solo.space, &target)?;
    Ok(Arc::new(QuadraticResidualCost::diagonal(
        Arc::new(Unary::new(Arc::new(r), nu)),
        &[1.0; 3],
    )?))
}

/// The friction cones of the four feet, with one contact solve.
fn friction_cones(dynamics: &Arc<MultibodyConstraintFwdDynamics>, mu: f64) -> Result<StageConstraint> {
    let n = dynamics.contacts().len();
    let cones = (0..n)
        .map(|k| FrictionConeResidual::new(dynamics.clone(), k, FrictionCone::vertical(mu)?))
        .collect::<Result<Vec<_>>>()?;
    let blocks = (0..n)
        .map(|_| Ok((Arc::new(SecondOrderCone::new(3)?) as Arc<dyn ConstraintSet>, 3)))
        .collect::<Result<Vec<_>>>()?;
    Ok(StageConstraint::new(
        "friction cones",
        Arc::new(StackedContactResidual::new(cones)?),
        Arc::new(ConstraintSetProduct::new(blocks)?),
    ))
}

/// The problem of `params` (module documentation).
///
/// # Errors
/// If the horizon is not in `1..=MAX_HORIZON` or `mu` is not positive and finite.
pub fn setup(params: &CircleParams) -> Result<CircleSetup> {
    params.validate()?;
    let solo = Solo::load()?;
    let nq = solo.model.nq();
    let dynamics = solo.contact_dynamics(Phase::FourFeet, DT)?;
    let u_stand = dynamics.quasi_static_torque(&solo.x0[..nq])?.u;
    let c0 = circle_start(&solo)?;
    let nu = u_stand.len();
    let space: Arc<dyn Manifold> = solo.space.clone();
    let weights = state_weights(solo.model.nv());
    let step = Dynamics::Explicit(Arc::new(SemiImplicitEuler::new(
        dynamics.clone(),
        solo.space.configuration().clone(),
        DT,
    )?));
    let state = Arc::new(QuadraticStateCost::diagonal(space.clone(), &solo.x0, &weights, nu)?);
    let control = Arc::new(QuadraticControlCost::diagonal(
        space.as_ref(),
        &u_stand,
        &vec![1.0; nu],
    )?);
    let cones = friction_cones(&dynamics, params.mu)?;
    let torque_box = if params.torque_limits {
        let dofs = solo
            .actuation
            .actuated_dofs()
            .ok_or_else(|| Error::InvalidModel("solo_com_circle: the actuation is not a joint selection".into()))?;
        Some(effort_limits(&solo.space, &dofs)?)
    } else {
        None
    };
    let mut stages = Vec::with_capacity(params.horizon);
    for t in 0..params.horizon {
        let cost = CostStack::new(space.as_ref(), nu)
            .with("state", state.clone(), W_STATE * DT)?
            .with("control", control.clone(), W_CONTROL * DT)?
            .with("com", com_cost(&solo, com_target(c0, t as f64 * DT), nu)?, W_COM * DT)?;
        let mut stage = StageModel::new(Arc::new(cost), step.clone())?;
        stage.add_constraint(cones.clone())?;
        if let Some(b) = &torque_box {
            stage.add_constraint(b.clone())?;
        }
        stages.push(stage);
    }
    let terminal_state = Arc::new(QuadraticStateCost::diagonal(space.clone(), &solo.x0, &weights, 0)?);
    let terminal = CostStack::new(space.as_ref(), 0)
        .with("state", terminal_state, W_STATE * DT)?
        .with(
            "com",
            com_cost(&solo, com_target(c0, params.horizon as f64 * DT), 0)?,
            W_COM,
        )?;
    let problem = Problem::new(&solo.x0, stages, Arc::new(terminal))?;
    Ok(CircleSetup {
        problem,
        x0: solo.x0.clone(),
        u_stand,
        c0,
        dynamics,
        mu: params.mu,
    })
}

/// `c0`: the mean of the feet's `x, y` and the CoM height of the standing posture.
fn circle_start(solo: &Solo) -> Result<[f64; 3]> {
    let q0 = &solo.x0[..solo.model.nq()];
    let mut data = solo.model.create_data();
    let feet = feet_positions(&solo.model, &mut data, &solo.feet, q0)?;
    let zeros = vec![0.0; solo.model.nv()];
    let com = center_of_mass(&solo.model, &mut data, q0, &zeros, &zeros)
        .map_err(|e| Error::InvalidModel(format!("solo_com_circle: centre of mass: {e}")))?;
    let mean = |i: usize| feet.iter().map(|p| p[i]).sum::<f64>() / 4.0;
    Ok([mean(0), mean(1), com.z])
}

/// The recommended ProxDDP settings.
pub fn proxddp_options() -> ProxDdpOptions {
    ProxDdpOptions::default().with(|o| {
        o.mu_init = 1e-3;
        o.tol = 1e-5;
        o.rollout = Rollout::Linear;
        o.max_iters = 200;
    })
}

/// The catalogue's `solo-com-circle` with `horizon` nodes ([`HORIZON`] in the
/// catalogue; the circle keeps its speed, so a shorter horizon covers an arc).
///
/// # Errors
/// If the horizon is not in `1..=MAX_HORIZON`.
pub fn build(horizon: usize) -> Result<Example> {
    let s = setup(&CircleParams {
        horizon,
        ..CircleParams::default()
    })?;
    let us0 = vec![s.u_stand.clone(); horizon];
    let xs0 = vec![s.x0.clone(); horizon + 1];
    Ok(Example {
        name: "solo-com-circle",
        problem: s.problem,
        xs0,
        us0,
        dt: Some(DT),
        proxddp: proxddp_options(),
        description: "Solo-12 on four feet, CoM on a horizontal circle of radius 6.5 cm at 0.2 Hz (stagewise-SQP \
                      paper, Figs. 4-5): contact dynamics, friction cones mu = 0.8, dt = 20 ms, N = 250; guess: \
                      the quasi-static torque.",
    })
}

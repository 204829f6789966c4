//! End-effector circle tracking with the UR5: the MPC task of the stagewise-SQP paper
//! (Jordana et al., 2023, §V-A3 and §V-B), as one optimal control problem per MPC cycle
//! whose tracking targets move in place.
//!
//! **The paper's setting** (KUKA LBR iiwa 14, torque control): the end effector tracks a
//! circle (a 3D position task) under state and torque regularisation; OCP nodes of
//! 50 ms, 10 nodes in the horizon; MPC at 500 Hz unconstrained, 100 Hz constrained. With
//! the first joint bounded, `|q_1| ≤ 0.05 rad` (Fig. 3), the average absolute tracking
//! error rises from 3.3 cm to 8.5 cm; with end-effector half-space constraints (Fig. 6,
//! the (y, z)-plane) the trajectory is clipped by the boundary. The authors' public
//! controllers (repository `machines-in-motion/StagewiseSQP`,
//! `kuka_dgh/controllers/circle_ssqp.py` and `circle_cssqp.py`) track
//! `p*(t) = p_des + (0, r sin ωt, r (1 − cos ωt))` with `r = 0.3 m`, `ω = 2 rad/s`: a
//! vertical circle in the plane `x = const`, starting at its lowest point `p_des` and
//! moving towards +y first, with the weights (crocoddyl's `½ w ‖r‖²`, running costs
//! times `dt`) 30 on the translation (running and terminal), 1e-4 on `u − g(q)` and
//! 0.01 · (10, 5, 5, 1, 1, 1, 1; 5, …, 5) on `x − x0`.
//!
//! **Here**: the UR5 of [`crate::peer_robots`] (same URDF, ABA, semi-implicit Euler,
//! fully actuated `τ = u`) with `dt = 50 ms` ([`DT`]) and `N = 10` ([`HORIZON`]). The
//! circle is the authors': radius [`RADIUS`] = 0.3 m, angular speed [`OMEGA`] = 2 rad/s
//! (0.6 m/s, one turn in π s), in the (y, z)-plane through the tool position
//! `p0 = p(q0) ≈ (0.501, 0.109, 0.140)` of the posture [`Q0`]:
//! `p*(t) = c + r (0, sin ωt, −cos ωt)` with centre `c = p0 + (0, 0, r)`, so that
//! `p*(0) = p0` (the circle spans `z ∈ [0.14, 0.74]`, `y ∈ [−0.19, 0.41]` at
//! `x ≈ 0.50`, inside the UR5's reach). Each running stage `t` and the terminal stage
//! track `p*(t0 + t dt)` through their own [`FrameTranslationResidual`] (frame `tool0`),
//! whose target [`CircleTask::set_stage_target`] moves in place; the cost objects are
//! distinct per stage, so that a receding horizon that rotates the stages (the stage
//! object leaving at the front re-enters at the back) moves one reference into each.
//!
//! | term | running stage, `dt · […]` | terminal |
//! |---|---|---|
//! | state `½ Σ_i w_i (x − x0)_i²` | q: 1e-2 · (10, 5, 5, 1, 1, 1), v: 0.05 | q: the same, v: 0.1 (the velocity term) |
//! | control `½ w ‖u − g(q)‖²`, gravity compensation at the current `q` (the authors' `ctrlRegGrav`) | 1e-4 | – |
//! | tracking `½ w ‖p(q) − p*‖²` | 20 | 20 |
//!
//! Chosen with a nominal closed loop (the tests' `closed_loop_tracking`: MPC at 100 Hz,
//! at most 20 ProxDDP iterations per cycle warm-started from the previous solution, the
//! plant the same ABA model integrated at 1 ms, one turn of the circle from `x0`). Mean
//! tracking error `‖p − p*‖` over the turn, unconstrained: 2.6 cm with tracking weight
//! 10, 1.4 cm with 20, 1.0 cm with 30, 0.4 cm with 100. The `JointBound` OCP limits it:
//! its tracking residual stays large (about 0.1 m, the size of the wrist's lever arms),
//! where the Gauss-Newton Hessian misses much of the curvature, and ProxDDP needs 32
//! iterations with weight 10, 40 with 20, does not converge within 200 with 30 and
//! needs 131 with 100. The terminal velocity weight
//! changes the closed-loop errors by less than 0.1 mm between 0.05 and 5. The initial
//! state is `x0 = (q0, 0)`, the control guess gravity compensation `g(q0)` at every node
//! (its rollout stays at `x0`).
//!
//! Variants ([`CircleVariant`]), each constraint on every running stage and on the
//! terminal state. Stage 0 keeps its row too, so that the stage objects stay
//! interchangeable under rotation; it bounds the fixed `x0`, which a measured state can
//! violate (in the closed-loop test, 107 of the 314 cycles of `JointBound` start beyond
//! the bound, by at most 0.005 rad): ProxDDP then cannot meet that row and returns its
//! last iterate at the iteration limit, finite.
//! - `Free`: no constraint;
//! - `JointBound`: `|q_1| ≤ 0.05 rad` ([`JOINT_BOUND`]) on the first joint (the UR5's
//!   shoulder pan, as the iiwa's A1 in the paper), a box on that state coordinate
//!   ([`StateSelection`]). The UR5 has no second joint that can swing the arm sideways
//!   (the iiwa's third joint can); only the wrist moves the tool in y;
//! - `HalfSpace`: `y ≤ y_max = c_y + r/2` ([`CircleTask::y_max`]) on the tool position,
//!   `M p(q) + b ≤ 0` with `M = (0, 1, 0)`, `b = −y_max`, a [`LinearComposition`] of the
//!   frame translation. The reference leaves the half-space for `ωt ∈ (π/6, 5π/6)` (from
//!   t ≈ 0.26 s, inside the first horizon), so that even a perfect tracker has a mean
//!   error of `r (√3 − π/3) / (2π) ≈ 3.27 cm` over a turn. (Fig. 6a cuts the circle
//!   through its centre on the side reached last, which the first OCP never sees.)
//!
//! Results (tests `tests/ur5_circle.rs`; ProxDDP with [`proxddp_options`], tol 1e-6):
//!
//! | variant | first OCP: iterations (AL) | closed loop: mean error | closed loop: constraint |
//! |---|---|---|---|
//! | `Free` | 6 (1) | 1.4 cm | max \|q_1\| 0.53 rad, max y − y_max 0.14 m |
//! | `JointBound` | 40 (1) | 11.2 cm | max \|q_1\| 0.055 rad |
//! | `HalfSpace` | 19 (1) | 4.4 cm | max y − y_max 5 mm |
//!
//! The closed-loop constraint values exceed the bounds by a few millimetres because the
//! OCP predicts with 50 ms steps what the plant does at 1 ms and bounds only the knots.
//!
//! With [`gharial::mpc`] instead (test `closed_loop_with_the_mpc_module`: one cycle per node,
//! at most 10 iterations, the stages rotating, the feedback policy on the plant at 1 ms
//! between cycles; after each shift the stage object that entered gets
//! `set_stage_target(id, t0 + (N − 1) dt)` and the terminal stage `t0 + N dt`), the `Free`
//! task tracks one turn to 2.0 cm on average.
//!
//! The catalogue entries `ur5-circle`, `ur5-circle-joint-bound` and
//! `ur5-circle-half-space` ([`build`]) are the first OCP of the horizon
//! ([`CircleTask::set_horizon`]`(0.0)`), with ProxDDP at `mu_init = 1e-5` (as the
//! peer UR5 problems), the linear rollout and the filter.

use std::f64::consts::FRAC_PI_2;
use std::sync::Arc;

use faer::Mat;
use gharial::constraints::{BoxConstraint, NegativeOrthant};
use gharial::costs::{CostStack, QuadraticResidualCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, SemiImplicitEuler};
use gharial::functions::{LinearComposition, StageFunctionData, Unary, UnaryFunction};
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::solvers::proxddp::{ProxDdpOptions, Rollout};
use gharial::spaces::Manifold;
use gharial::{Error, Result};
use gharial_multibody::{Model, RootJoint};
use gharial_robotics::residuals::{FrameTranslationResidual, GravityCompensationResidual, StateSelection};
use gharial_robotics::{Actuation, MultibodyFreeFwdDynamics, MultibodyPhaseSpace, gravity_compensation};

use crate::Example;
use crate::robots::UR5_URDF;

/// The tracked frame.
const FRAME: &str = "tool0";

/// Time step of the OCP nodes (s), the paper's.
pub const DT: f64 = 0.05;

/// Number of running stages, the paper's.
pub const HORIZON: usize = 10;

/// Initial posture `q0` (rad); the circle starts at its tool position.
pub const Q0: [f64; 6] = [0.0, -1.2, 1.8, -1.5, -FRAC_PI_2, 0.0];

/// Radius of the circle (m), the authors' demo.
pub const RADIUS: f64 = 0.3;

/// Angular speed on the circle (rad/s), the authors' demo.
pub const OMEGA: f64 = 2.0;

/// Bound on the first joint of the `JointBound` variant (rad), the paper's.
pub const JOINT_BOUND: f64 = 0.05;

/// Which constraints the task has.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CircleVariant {
    /// Unconstrained tracking.
    Free,
    /// `|q_1| ≤` [`JOINT_BOUND`] on every stage.
    JointBound,
    /// The tool in the half-space `y ≤` [`CircleTask::y_max`] on every stage.
    HalfSpace,
}

/// A circle in the plane `x = c_x`: `p(t) = c + r (0, sin ωt, −cos ωt)`, at its lowest
/// point at `t = 0` and moving towards +y.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Circle {
    /// Centre `c` (m, world).
    pub centre: [f64; 3],
    /// Radius `r` (m).
    pub radius: f64,
    /// Angular speed `ω` (rad/s).
    pub omega: f64,
}

impl Circle {
    /// The point at time `time` (s).
    pub fn point(&self, time: f64) -> [f64; 3] {
        let (sin, cos) = (self.omega * time).sin_cos();
        let [cx, cy, cz] = self.centre;
        [cx, cy + self.radius * sin, cz - self.radius * cos]
    }

    /// `c_y + r/2`, the bound of the half-space of [`CircleVariant::HalfSpace`].
    fn y_max(&self) -> f64 {
        self.centre[1] + 0.5 * self.radius
    }
}

/// Weights of a stage's quadratic terms (module documentation).
struct Weights {
    q: [f64; 6],
    v: f64,
    u: f64,
    ee: f64,
}

/// `1e-2 · (10, 5, 5, 1, 1, 1)`: the authors' posture weights for the UR5's six joints.
const STATE_Q: [f64; 6] = [0.1, 0.05, 0.05, 0.01, 0.01, 0.01];

const RUNNING: Weights = Weights {
    q: STATE_Q,
    v: 0.05,
    u: 1e-4,
    ee: 20.0,
};

const TERMINAL: Weights = Weights {
    q: STATE_Q,
    v: 0.1,
    u: 0.0,
    ee: 20.0,
};

/// The UR5 with the task's time step.
struct Ur5 {
    space: Arc<MultibodyPhaseSpace>,
    actuation: Arc<Actuation>,
    ode: Arc<MultibodyFreeFwdDynamics>,
    dynamics: Dynamics,
}

impl Ur5 {
    fn load() -> Result<Self> {
        Self::from_model(Self::model()?)
    }

    /// The UR5 of the URDF.
    fn model() -> Result<Model> {
        Model::from_urdf_str(UR5_URDF, RootJoint::Fixed)
            .map_err(|e| Error::InvalidModel(format!("ur5_circle: UR5 model: {e}")))
    }

    /// The UR5 carrying a point mass of `payload` kg at its tool frame.
    fn with_payload(payload: f64) -> Result<Self> {
        let model = Self::model()?;
        let tool = &model.frames()[model
            .frame_id(FRAME)
            .map_err(|e| Error::InvalidModel(format!("ur5_circle: {e}")))?];
        let (joint, at) = (tool.parent_joint, tool.placement.translation);
        Self::from_model(crate::mpc::with_point_mass(&model, joint, at, payload)?)
    }

    fn from_model(model: Model) -> Result<Self> {
        let model = Arc::new(model);
        let space = Arc::new(MultibodyPhaseSpace::new(model.clone()));
        let actuation = Arc::new(Actuation::full(&model));
        let ode = Arc::new(MultibodyFreeFwdDynamics::new(space.clone(), actuation.clone())?);
        let step = SemiImplicitEuler::new(ode.clone(), space.configuration().clone(), DT)?;
        Ok(Self {
            space,
            actuation,
            ode,
            dynamics: Dynamics::Explicit(Arc::new(step)),
        })
    }

    /// The robot's dynamics integrated by semi-implicit Euler with step `h`.
    fn step(&self, h: f64) -> Result<SemiImplicitEuler> {
        SemiImplicitEuler::new(self.ode.clone(), self.space.configuration().clone(), h)
    }

    /// `scale · [½ Σ w_i (x − x0)_i² + ½ wu ‖u − g(q)‖² + ½ wee ‖p(q) − p*‖²]` with its own
    /// tracking residual (target `p_ref`); the control term only when `nu > 0`.
    fn cost(
        &self,
        x0: &[f64],
        w: &Weights,
        p_ref: &[f64; 3],
        nu: usize,
        scale: f64,
    ) -> Result<(CostStack, Arc<FrameTranslationResidual>)> {
        let space: Arc<dyn Manifold> = self.space.clone();
        let state_w: Vec<f64> = w.q.iter().copied().chain([w.v; 6]).collect();
        let state = QuadraticStateCost::diagonal(space.clone(), x0, &state_w, nu)?;
        let mut cost = CostStack::new(space.as_ref(), nu).with("state", Arc::new(state), scale)?;
        if nu > 0 {
            let g = GravityCompensationResidual::new(&self.space, self.actuation.clone())?;
            let control = QuadraticResidualCost::diagonal(Arc::new(g), &[w.u; 6])?;
            cost = cost.with("control", Arc::new(control), scale)?;
        }
        let ee = Arc::new(FrameTranslationResidual::new(&self.space, FRAME, p_ref)?);
        let f = Arc::new(Unary::new(ee.clone(), nu));
        cost = cost.with("ee", Arc::new(QuadraticResidualCost::diagonal(f, &[w.ee; 3])?), scale)?;
        Ok((cost, ee))
    }

    /// The tool position `p(q)` of the state `x`.
    fn tool_position(&self, x: &[f64]) -> Result<[f64; 3]> {
        let r = FrameTranslationResidual::new(&self.space, FRAME, &[0.0; 3])?;
        let mut data = StageFunctionData::new(r.ndx(), 0, 3, r.create_workspace());
        r.evaluate(x, &mut data);
        let p = data.value();
        if p.iter().any(|v| !v.is_finite()) {
            return Err(Error::InvalidModel(format!(
                "ur5_circle: tool position at {x:?} failed"
            )));
        }
        Ok([p[0], p[1], p[2]])
    }

    /// `|q_1| ≤ JOINT_BOUND` for stages with `nu` controls.
    fn joint_bound(&self, nu: usize) -> Result<StageConstraint> {
        let (nx, ndx) = (self.space.nx(), self.space.ndx());
        let f = StateSelection::new(nx, ndx, &[(0, 0)])?;
        let set = BoxConstraint::new(&[-JOINT_BOUND], &[JOINT_BOUND])?;
        Ok(StageConstraint::new(
            "q1_bound",
            Arc::new(Unary::new(Arc::new(f), nu)),
            Arc::new(set),
        ))
    }

    /// `y(q) − y_max ≤ 0` on the tool position, for stages with `nu` controls.
    fn half_space(&self, y_max: f64, nu: usize) -> Result<StageConstraint> {
        let p = Arc::new(FrameTranslationResidual::new(&self.space, FRAME, &[0.0; 3])?);
        let m = Mat::from_fn(1, 3, |_, j| if j == 1 { 1.0 } else { 0.0 });
        let f = LinearComposition::new(Arc::new(Unary::new(p, nu)), m.as_ref(), &[-y_max])?;
        Ok(StageConstraint::new(
            "ee_half_space",
            Arc::new(f),
            Arc::new(NegativeOrthant),
        ))
    }
}

/// The circle-tracking OCP of one MPC cycle (module documentation), with in-place
/// handles on the tracking target of every stage.
///
/// The handles are shared with the problem's costs (`Arc`s): moving a target through
/// the task changes the problem, also after `problem` has been moved or cloned
/// (clones of a [`Problem`] share their stage costs).
pub struct CircleTask {
    /// The OCP: [`HORIZON`] running stages of [`DT`] and the terminal stage.
    pub problem: Problem,
    /// Initial state `x0 = (q0, 0)`.
    pub x0: Vec<f64>,
    /// Control guess: gravity compensation `g(q0)` at every node.
    pub us0: Vec<Vec<f64>>,
    variant: CircleVariant,
    circle: Circle,
    /// Tracking residual of each running stage object, by original stage index.
    running: Vec<Arc<FrameTranslationResidual>>,
    terminal: Arc<FrameTranslationResidual>,
}

impl std::fmt::Debug for CircleTask {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CircleTask")
            .field("variant", &self.variant)
            .field("circle", &self.circle)
            .field("horizon", &self.problem.horizon())
            .finish_non_exhaustive()
    }
}

impl CircleTask {
    /// The task of `variant`, its targets set for the horizon starting at `t0 = 0`.
    ///
    /// # Errors
    /// Never for these fixed numbers (constructors are fallible in general).
    pub fn new(variant: CircleVariant) -> Result<Self> {
        let robot = Ur5::load()?;
        let x0: Vec<f64> = Q0.iter().copied().chain([0.0; 6]).collect();
        let p0 = robot.tool_position(&x0)?;
        let circle = Circle {
            centre: [p0[0], p0[1], p0[2] + RADIUS],
            radius: RADIUS,
            omega: OMEGA,
        };
        let nu = robot.space.nv();
        let mut stages = Vec::with_capacity(HORIZON);
        let mut running = Vec::with_capacity(HORIZON);
        for t in 0..HORIZON {
            let (cost, ee) = robot.cost(&x0, &RUNNING, &circle.point(t as f64 * DT), nu, DT)?;
            stages.push(StageModel::new(Arc::new(cost), robot.dynamics.clone())?);
            running.push(ee);
        }
        let (terminal_cost, terminal) = robot.cost(&x0, &TERMINAL, &circle.point(HORIZON as f64 * DT), 0, 1.0)?;
        let mut problem = Problem::new(&x0, stages, Arc::new(terminal_cost))?;
        let y_max = circle.y_max();
        let constraint = |nu: usize| -> Result<Option<StageConstraint>> {
            match variant {
                CircleVariant::Free => Ok(None),
                CircleVariant::JointBound => robot.joint_bound(nu).map(Some),
                CircleVariant::HalfSpace => robot.half_space(y_max, nu).map(Some),
            }
        };
        if let Some(c) = constraint(nu)? {
            for stage in problem.stages_mut() {
                stage.add_constraint(c.clone())?;
            }
        }
        if let Some(c) = constraint(0)? {
            problem.add_terminal_constraint(c)?;
        }
        let g = gravity_compensation(robot.space.model(), &robot.actuation, &Q0)?;
        Ok(Self {
            problem,
            x0,
            us0: vec![g; HORIZON],
            variant,
            circle,
            running,
            terminal,
        })
    }

    /// The variant.
    pub fn variant(&self) -> CircleVariant {
        self.variant
    }

    /// The reference circle.
    pub fn circle(&self) -> &Circle {
        &self.circle
    }

    /// The bound `y_max = c_y + r/2` of the half-space `y ≤ y_max` (the constraint of the
    /// `HalfSpace` variant only).
    pub fn y_max(&self) -> f64 {
        self.circle.y_max()
    }

    /// The reference point `p*(time)` (m, world) at time `time` (s).
    pub fn reference(&self, time: f64) -> [f64; 3] {
        self.circle.point(time)
    }

    /// Sets the target of the running stage object `ring_index` (its index in the
    /// original stage order, whatever knot it sits at after rotations) to `p*(time)`.
    ///
    /// # Errors
    /// If `ring_index ≥ HORIZON`, or `time` is not finite; the targets are then
    /// unchanged.
    pub fn set_stage_target(&self, ring_index: usize, time: f64) -> Result<()> {
        let ee = self.running.get(ring_index).ok_or_else(|| {
            Error::InvalidModel(format!(
                "CircleTask::set_stage_target: stage object {ring_index} out of range (horizon {})",
                self.running.len()
            ))
        })?;
        ee.set_target(&self.checked_reference("set_stage_target", time)?)
    }

    /// Sets the target of the terminal stage to `p*(time)`.
    ///
    /// # Errors
    /// If `time` is not finite; the target is then unchanged.
    pub fn set_terminal_target(&self, time: f64) -> Result<()> {
        self.terminal
            .set_target(&self.checked_reference("set_terminal_target", time)?)
    }

    /// Sets every target for the horizon starting at `t0`: stage object `i` to
    /// `p*(t0 + i dt)`, the terminal stage to `p*(t0 + N dt)`. Valid while the stage
    /// objects are in their original order (before any rotation).
    ///
    /// # Errors
    /// If `t0` is not finite; the targets are then unchanged.
    pub fn set_horizon(&self, t0: f64) -> Result<()> {
        self.checked_reference("set_horizon", t0)?;
        for i in 0..self.running.len() {
            self.set_stage_target(i, t0 + i as f64 * DT)?;
        }
        self.set_terminal_target(t0 + self.running.len() as f64 * DT)
    }

    /// The tracking residual of running stage object `ring_index` (original order).
    pub fn stage_residual(&self, ring_index: usize) -> Option<&Arc<FrameTranslationResidual>> {
        self.running.get(ring_index)
    }

    /// The tracking residual of the terminal stage.
    pub fn terminal_residual(&self) -> &Arc<FrameTranslationResidual> {
        &self.terminal
    }

    /// `p*(time)`, or an error naming `what` if `time` is not finite.
    fn checked_reference(&self, what: &str, time: f64) -> Result<[f64; 3]> {
        if !time.is_finite() {
            return Err(Error::InvalidModel(format!(
                "CircleTask::{what}: time {time} is not finite"
            )));
        }
        Ok(self.reference(time))
    }
}

/// The first OCP of the horizon of `variant` (targets of [`CircleTask::set_horizon`]
/// at `t0 = 0`) as a catalogue example, with the gravity-compensation guess rolled out.
///
/// # Errors
/// Never for these fixed numbers (constructors are fallible in general).
pub fn build(variant: CircleVariant) -> Result<Example> {
    example(&CircleTask::new(variant)?)
}

/// The catalogue example of `task`'s first horizon (its problem shares the task's
/// target handles).
fn example(task: &CircleTask) -> Result<Example> {
    let (name, description) = match task.variant {
        CircleVariant::Free => (
            "ur5-circle",
            "UR5 end-effector circle tracking (r = 0.3 m, 2 rad/s, (y, z)-plane), first MPC horizon: N = 10, dt = 50 ms.",
        ),
        CircleVariant::JointBound => (
            "ur5-circle-joint-bound",
            "UR5 circle tracking, first MPC horizon, with the first joint bounded |q1| <= 0.05 rad.",
        ),
        CircleVariant::HalfSpace => (
            "ur5-circle-half-space",
            "UR5 circle tracking, first MPC horizon, with the tool in the half-space y <= c_y + r/2.",
        ),
    };
    let xs0 = crate::rollout(&task.problem, &task.us0)?;
    Ok(Example {
        name,
        problem: task.problem.clone(),
        xs0,
        us0: task.us0.clone(),
        dt: Some(DT),
        proxddp: proxddp_options(),
        description,
    })
}

/// The plant step of the closed loops (s).
pub const PLANT_DT: f64 = 1e-3;

/// The closed-loop scenario `ur5-circle-mpc*` of `variant` ([`crate::mpc`]): the task's
/// horizon as controller, one MPC cycle per node ([`DT`]) of at most 5 iterations (the
/// SQP paper allows 4-5), the UR5's ABA by semi-implicit Euler at [`PLANT_DT`] as plant;
/// after each shift the stage that entered gets the target of its time and the terminal
/// cost the next. Metrics: mean and largest tool error against the circle at the plant
/// rate, largest `|q_1|` and largest `y - y_max`.
///
/// # Errors
/// Never for these fixed numbers (constructors are fallible in general).
pub fn scenario(variant: CircleVariant) -> Result<crate::mpc::MpcScenario> {
    scenario_with(variant, crate::mpc::Mismatch::default())
}

/// [`scenario`] with a plant that differs from the controller's model by `mismatch` (a
/// payload at the tool frame).
///
/// # Errors
/// If the mismatch is invalid.
pub fn scenario_with(variant: CircleVariant, mismatch: crate::mpc::Mismatch) -> Result<crate::mpc::MpcScenario> {
    mismatch.check()?;
    let task = Arc::new(CircleTask::new(variant)?);
    let robot = Ur5::load()?;
    let plant_robot = if mismatch.payload > 0.0 {
        Ur5::with_payload(mismatch.payload)?
    } else {
        Ur5::load()?
    };
    let plant = Box::new(gharial::mpc::DiscretePlant::new(Arc::new(plant_robot.step(PLANT_DT)?)));
    let name = match variant {
        CircleVariant::Free => "ur5-circle-mpc",
        CircleVariant::JointBound => "ur5-circle-mpc-joint-bound",
        CircleVariant::HalfSpace => "ur5-circle-mpc-half-space",
    };
    let n = task.running.len();
    let shifted = task.clone();
    let measured = task.clone();
    let mut example = example(&task)?;
    example.proxddp = crate::mpc::cycle_proxddp_options(example.proxddp);
    Ok(crate::mpc::MpcScenario {
        name,
        example,
        queue: Vec::new(),
        plant,
        plant_dt: PLANT_DT,
        steps_per_cycle: (DT / PLANT_DT).round() as usize,
        options: gharial::mpc::MpcOptions::default().with(|o| o.max_iters = 5),
        on_shift: Box::new(move |cycle, id, _| {
            let t0 = cycle as f64 * DT;
            shifted.set_stage_target(id, t0 + (n - 1) as f64 * DT)?;
            shifted.set_terminal_target(t0 + n as f64 * DT)
        }),
        metrics: Box::new(move |rec| closed_loop_metrics(&measured, &robot, rec)),
        base_velocity: None,
        pushes: Vec::new(),
    })
}

/// Tool error against the circle at every plant step, largest `|q_1|` and `y - y_max`.
fn closed_loop_metrics(task: &CircleTask, robot: &Ur5, rec: &gharial::mpc::Record) -> Result<Vec<crate::mpc::Metric>> {
    let (mut sum, mut worst, mut q1, mut y_excess) = (0.0, 0.0_f64, 0.0_f64, f64::NEG_INFINITY);
    for (k, x) in rec.xs.iter().enumerate() {
        let p = robot.tool_position(x)?;
        let r = task.reference(k as f64 * PLANT_DT);
        let e = ((p[0] - r[0]).powi(2) + (p[1] - r[1]).powi(2) + (p[2] - r[2]).powi(2)).sqrt();
        sum += e;
        worst = worst.max(e);
        q1 = q1.max(x[0].abs());
        y_excess = y_excess.max(p[1] - task.y_max());
    }
    let metric = |name, value, unit| crate::mpc::Metric { name, value, unit };
    Ok(vec![
        metric("mean tool error", sum / rec.xs.len().max(1) as f64, "m"),
        metric("max tool error", worst, "m"),
        metric("max |q_1|", q1, "rad"),
        metric("max y - y_max", y_excess, "m"),
    ])
}

/// The recommended ProxDDP settings of the task (module documentation).
pub fn proxddp_options() -> ProxDdpOptions {
    ProxDdpOptions::default().with(|o| {
        o.mu_init = 1e-5;
        o.rollout = Rollout::Linear;
        o.max_iters = 200;
    })
}

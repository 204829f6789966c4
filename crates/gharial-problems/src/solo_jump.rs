//! Whole-body jump of the Solo-12 quadruped: the ProxDDP paper's §VII-D (Fig. 12 and
//! Fig. 15).
//!
//! **Model.** The Solo-12 of example-robot-data 5.0.0 (`solo12.urdf` and `solo.srdf` of
//! `gharial-multibody/tests/data/robots`) with a free-flyer base, `nq = 19`, `nv = 18`,
//! twelve actuated joints (`B = [0; I]`, `nu = 12`). The dynamics of each stage are the
//! paper's (56): rigid 3D point contacts at the four feet ([`FEET`], LOCAL_WORLD_ALIGNED)
//! with the Baumgarte acceleration constraint `c̈ = −Kp c − Kd ċ`, solved exactly
//! ([`MultibodyConstraintFwdDynamics`]), or the free dynamics in flight
//! ([`MultibodyFreeFwdDynamics`]), discretised with the semi-implicit Euler step
//! `v⁺ = v + Δt a`, `q⁺ = q ⊕ Δt v⁺`.
//!
//! **Phases** (the paper's three, with the times of the authors' public example
//! `solo_jump.py`): four feet in contact for `t < t0 = 0.4 s` (stages 0-19), flight for
//! `t0 ≤ t < t1 = 0.9 s` (stages 20-44), four feet in contact again from `t1` (stages
//! 45-59); `Δt = 20 ms`, `T = 1.2 s`, `N = 60`. The landing node `x_45` carries the
//! paper's hard constraint `z_c(q(t1)) = 0` on the height of each foot (four equality
//! rows). The ground is the plane `z = 0`: the standing posture `straight_standing` of
//! the SRDF (base at 0.235 m, feet 12.05 mm above `z = 0`) is lowered until its feet
//! touch it, base height 0.22295 m ([`JumpSetup::standing_height`]).
//!
//! **Contact gains.** The paper sets the `xy` position gains of `Kp` to zero and keeps a
//! `z` gain (the authors' example: `Kp = (0, 0, 100)`, `Kd = 50`). The contacts of the
//! multibody crate have one `Kp` and one `Kd` for all axes, as Pinocchio 4's
//! `BaumgarteCorrectorParameters`, so the default here is `Kp = 0`, `Kd = 50`
//! ([`JumpParams::kp`], [`JumpParams::kd`]): the horizontal gains are the paper's, the
//! vertical position gain is zero and the height of the feet at landing is set by the
//! hard constraint. With `Kd Δt = 1` the discrete contact velocity is damped to zero in
//! one step, and the feet drift by less than a millimetre in height over a stance
//! phase (0.3 mm at the solution; test `the_solution_jumps_and_lands`). A nonzero `kp`
//! also pulls every axis of a foot towards its standing position (the contact
//! references); `kp = 100` converges to almost the same jump (58 iterations, cost 0.2902026 instead of
//! 0.2901804; ALIGATOR: 80 iterations, the same cost).
//!
//! **Costs** (½ w ‖·‖², running terms times `Δt`):
//!
//! | term | running | terminal |
//! |---|---|---|
//! | state `x ⊖ x0`: base pose and base velocity | 0 | 0 |
//! | state `x ⊖ x0`: joint positions and joint velocities | 1e-2 | 1e-2 |
//! | control `u − u_qs`, `u_qs` the quasi-static torque of the standing robot | 1e-2 ([`JumpParams::control_weight`]) | – |
//! | fly-high `v_xy(f) e^{−50 z(f)}` of each foot ([`FlyHighResidual`]) | 1/4 | – |
//!
//! The weights are the authors' except the control weight: with their `1e-4` the
//! optimum takes off and lands through single 20 ms impulses (85 N per foot, 30 times
//! the standing load), and ProxDDP stalls at a dual residual of about 1e-3 (300
//! iterations with the step length falling to 4e-3); ALIGATOR 0.19.1's ProxDDP on the
//! same problem (the same model, costs, guess and settings, built with its own API)
//! stalls the same way, with the same first iterates. With `1e-2` both converge to
//! tol 1e-6: gharial in 57 iterations, ALIGATOR in 61, to the same cost
//! (0.2901803958 and 0.2901803959; ALIGATOR at tol 1e-8: 0.29018039536).
//!
//! There is no target for the jump: the flight lasts `t1 − t0 = 0.5 s` and the feet
//! must be back on the ground at `t1`, so the robot has to take off (about 2.4 m/s
//! upwards for a ballistic flight of that length); it crouches, pushes off, its base
//! rises about 0.29 m above the standing height and it lands in place.
//!
//! **Optional constraints** ([`JumpParams`]): the URDF's effort limits (`|u| ≤ 1000 N m`
//! in this URDF, never active; off by default, as in the paper and the authors'
//! example) as a box, and Coulomb friction cones `‖f_t‖ ≤ μ f_n` on the forces of the
//! four feet at every contact stage ([`FrictionConeResidual`] with second-order cones;
//! off by default, the paper has none).
//!
//! **Initial guess** ([`JumpSetup::initial_guess`]): the standing state `x0 = (q0, 0)` at
//! every node and the quasi-static torque `u_qs` at every stage. It is the rollout of
//! `u_qs` up to the take-off only: in flight `u_qs` spins the unloaded legs and the
//! rollout diverges (non-finite by node 36), and a rollout with zero torques in flight
//! falls 1.27 m below the ground, where the fly-high cost overflows. **Solver** ([`proxddp_options`]): ProxDDP with the paper's `μ0 = 1e-4`, the
//! linear rollout (as the authors), the filter, tolerance 1e-6.
//!
//! **Figures**: [`JumpSetup::figures`] writes the data of Fig. 12 (primal and dual
//! residuals per iteration) and of the trajectory plots (base position, feet heights,
//! joint torques and their limits, contact forces of the stance feet) as CSV text
//! ([`JumpFigures`]).

use std::fmt::Write as _;
use std::sync::Arc;

use gharial::constraints::{EqualityConstraintSet, SecondOrderCone};
use gharial::costs::{CostStack, QuadraticControlCost, QuadraticResidualCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, SemiImplicitEuler};
use gharial::functions::{FunctionStack, Slice, StageFunction, Unary};
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::solvers::Solution;
use gharial::solvers::proxddp::{ProxDdpOptions, Rollout};
use gharial::spaces::Manifold;
use gharial::{Error, Result};
use gharial_multibody::{Data, Model, ReferenceFrame, RootJoint, forward_kinematics_placements};
use gharial_robotics::residuals::{
    FlyHighResidual, FrameTranslationResidual, FrictionCone, FrictionConeResidual, effort_limits,
};
use gharial_robotics::{
    Actuation, ContactSpec, MultibodyConstraintFwdDynamics, MultibodyFreeFwdDynamics, MultibodyPhaseSpace,
    set_contact_references,
};

use crate::Example;
use crate::robots::{SOLO_SRDF, SOLO_URDF};

/// The standing posture of the SRDF used for `x0` and the state regularisation.
pub const STANDING: &str = "straight_standing";

/// The feet, in the order of the contact forces.
pub use crate::solo_walk::FEET;

/// Decay rate of the fly-high residual (1/m), the authors'.
const FLY_HIGH_SLOPE: f64 = 50.0;

/// Weight of the state regularisation on the joint positions and velocities, the
/// authors'.
const STATE_WEIGHT: f64 = 1e-2;

/// Largest accepted [`JumpParams::horizon`] (the problem holds one stage per node).
pub const MAX_HORIZON: usize = 100_000;

/// The phase of a stage.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Four feet on the ground before the jump (phase (i)).
    Stance,
    /// No contact (phase (ii)).
    Flight,
    /// Four feet on the ground after the landing (phase (iii)).
    Landing,
}

impl Phase {
    /// 0, 1, 2 for stance, flight, landing (the `phase` column of the figure data).
    pub fn index(self) -> usize {
        match self {
            Phase::Stance => 0,
            Phase::Flight => 1,
            Phase::Landing => 2,
        }
    }

    /// Whether the feet are in contact.
    pub fn in_contact(self) -> bool {
        self != Phase::Flight
    }
}

/// The numbers of the jump (module documentation); the default is the catalogue's
/// `solo-jump`: the paper's and the authors' setting but for the control weight.
#[derive(Debug, Clone, PartialEq)]
pub struct JumpParams {
    /// Time step `Δt` (s; default 0.02).
    pub dt: f64,
    /// Number of stages `N` (default 60).
    pub horizon: usize,
    /// First flight stage, `t0 / Δt` (default 20).
    pub takeoff: usize,
    /// Landing node, `t1 / Δt`: first stage in contact again, where the feet heights are
    /// constrained to zero (default 45).
    pub landing: usize,
    /// Baumgarte position gain `Kp` of every contact axis (default 0, module
    /// documentation).
    pub kp: f64,
    /// Baumgarte velocity gain `Kd` (default 50).
    pub kd: f64,
    /// Friction coefficient of second-order friction cones on the forces of the stance
    /// feet (default `None`: no cone).
    pub friction: Option<f64>,
    /// The URDF's effort limits as a box on the controls of every stage (default off).
    pub torque_limits: bool,
    /// Weight `w_u` of the control regularisation `½ w_u ‖u − u_qs‖²` (default 1e-2;
    /// module documentation).
    pub control_weight: f64,
}

impl Default for JumpParams {
    fn default() -> Self {
        Self {
            dt: 0.02,
            horizon: 60,
            takeoff: 20,
            landing: 45,
            kp: 0.0,
            kd: 50.0,
            friction: None,
            torque_limits: false,
            control_weight: 1e-2,
        }
    }
}

impl JumpParams {
    /// The phase of stage `t` (stages `≥ N` count as landing).
    pub fn phase(&self, t: usize) -> Phase {
        if t < self.takeoff {
            Phase::Stance
        } else if t < self.landing {
            Phase::Flight
        } else {
            Phase::Landing
        }
    }

    fn validate(&self) -> Result<()> {
        if !(self.dt.is_finite() && self.dt > 0.0) {
            return Err(Error::option(
                "JumpParams::dt",
                format!("must be positive, got {}", self.dt),
            ));
        }
        if self.horizon > MAX_HORIZON {
            return Err(Error::option(
                "JumpParams::horizon",
                format!("must be at most {MAX_HORIZON}, got {}", self.horizon),
            ));
        }
        if !(0 < self.takeoff && self.takeoff < self.landing && self.landing < self.horizon) {
            return Err(Error::option(
                "JumpParams",
                format!(
                    "need 0 < takeoff < landing < horizon, got takeoff {}, landing {}, horizon {}",
                    self.takeoff, self.landing, self.horizon
                ),
            ));
        }
        if !(self.control_weight.is_finite() && self.control_weight >= 0.0) {
            return Err(Error::option(
                "JumpParams::control_weight",
                format!("must be finite and non-negative, got {}", self.control_weight),
            ));
        }
        if !(self.kp.is_finite() && self.kp >= 0.0 && self.kd.is_finite() && self.kd >= 0.0) {
            return Err(Error::option(
                "JumpParams::kp, kd",
                format!(
                    "Baumgarte gains must be finite and non-negative, got {}, {}",
                    self.kp, self.kd
                ),
            ));
        }
        if let Some(mu) = self.friction
            && !(mu.is_finite() && mu > 0.0)
        {
            return Err(Error::option(
                "JumpParams::friction",
                format!("must be positive, got {mu}"),
            ));
        }
        Ok(())
    }
}

/// The jump problem with the models it is built from, for the figure data.
pub struct JumpSetup {
    /// The optimal control problem.
    pub problem: Problem,
    /// Initial state `x0 = (q0, 0)`, the standing robot.
    pub x0: Vec<f64>,
    /// The quasi-static torque `u_qs` of the standing robot (control reference and guess).
    pub u_stand: Vec<f64>,
    /// The contact forces of the standing robot that go with `u_qs` (`λ`, 12).
    pub lambda_stand: Vec<f64>,
    params: JumpParams,
    space: Arc<MultibodyPhaseSpace>,
    /// The four-feet contact dynamics of the stance and landing stages.
    contact: Arc<MultibodyConstraintFwdDynamics>,
    /// Frame ids of [`FEET`].
    feet: Vec<usize>,
}

impl std::fmt::Debug for JumpSetup {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JumpSetup")
            .field("params", &self.params)
            .field("horizon", &self.problem.horizon())
            .finish_non_exhaustive()
    }
}

/// The Solo-12 with its ground contacts and the standing state.
struct Solo {
    space: Arc<MultibodyPhaseSpace>,
    actuation: Arc<Actuation>,
    contact: Arc<MultibodyConstraintFwdDynamics>,
    flight: Arc<MultibodyFreeFwdDynamics>,
    /// Frame ids of [`FEET`].
    feet: Vec<usize>,
    x0: Vec<f64>,
}

impl Solo {
    fn load(params: &JumpParams) -> Result<Self> {
        let model_error = |e: gharial_multibody::Error| Error::InvalidModel(format!("solo_jump: Solo-12 model: {e}"));
        let mut model = Model::from_urdf_str(SOLO_URDF, RootJoint::FreeFlyer).map_err(model_error)?;
        model.load_srdf_str(SOLO_SRDF).map_err(model_error)?;
        let mut q0 = model.reference_configuration(STANDING).map_err(model_error)?.to_vec();
        let feet: Vec<usize> = FEET
            .iter()
            .map(|f| model.frame_id(f))
            .collect::<std::result::Result<_, _>>()
            .map_err(model_error)?;
        q0[2] -= feet_heights(&model, &feet, &q0)?.iter().sum::<f64>() / 4.0;
        let model = Arc::new(model);
        let space = Arc::new(MultibodyPhaseSpace::new(model.clone()));
        let actuation = Arc::new(Actuation::floating_base(&model)?);
        let spec = ContactSpec::point(ReferenceFrame::LocalWorldAligned).with_gains(params.kp, params.kd);
        let mut contacts = gharial_robotics::contacts_at_frames(&model, &FEET, spec)?;
        set_contact_references(&model, &mut contacts, &q0)?;
        let contact = Arc::new(MultibodyConstraintFwdDynamics::new(
            space.clone(),
            actuation.clone(),
            contacts,
        )?);
        let flight = Arc::new(MultibodyFreeFwdDynamics::new(space.clone(), actuation.clone())?);
        let x0 = q0.iter().copied().chain(std::iter::repeat_n(0.0, model.nv())).collect();
        Ok(Self {
            space,
            actuation,
            contact,
            flight,
            feet,
            x0,
        })
    }

    fn nu(&self) -> usize {
        self.actuation.nu()
    }

    /// The semi-implicit Euler step of the stance or the flight dynamics.
    fn step(&self, in_contact: bool, dt: f64) -> Result<Dynamics> {
        let config = self.space.configuration().clone();
        let step = if in_contact {
            SemiImplicitEuler::new(self.contact.clone(), config, dt)?
        } else {
            SemiImplicitEuler::new(self.flight.clone(), config, dt)?
        };
        Ok(Dynamics::Explicit(Arc::new(step)))
    }

    /// `½ Σ w_i (x ⊖ x0)_i²` with weight `w` on the joints and zero on the base.
    fn state_cost(&self, w: f64, nu: usize) -> Result<QuadraticStateCost> {
        let nv = self.space.nv();
        let weights: Vec<f64> = (0..2 * nv).map(|i| if i % nv < 6 { 0.0 } else { w }).collect();
        QuadraticStateCost::diagonal(self.space.clone(), &self.x0, &weights, nu)
    }

    /// A running stage's cost (module documentation), times `dt`.
    fn running_cost(&self, u_ref: &[f64], p: &JumpParams) -> Result<CostStack> {
        let dt = p.dt;
        let (space, nu): (Arc<dyn Manifold>, usize) = (self.space.clone(), self.nu());
        let control = QuadraticControlCost::diagonal(space.as_ref(), u_ref, &vec![p.control_weight; nu])?;
        let mut cost = CostStack::new(space.as_ref(), nu)
            .with("state", Arc::new(self.state_cost(STATE_WEIGHT, nu)?), dt)?
            .with("control", Arc::new(control), dt)?;
        for foot in FEET {
            let r = Arc::new(Unary::new(
                Arc::new(FlyHighResidual::new(&self.space, foot, FLY_HIGH_SLOPE)?),
                nu,
            ));
            let fly_high = QuadraticResidualCost::diagonal(r, &[1.0; 2])?;
            cost = cost.with(format!("fly_high_{foot}"), Arc::new(fly_high), 0.25 * dt)?;
        }
        Ok(cost)
    }

    /// The `N` stages of `params`: the running cost around `u_ref`, the contact or
    /// flight step, the landing constraint and the optional cones and torque box.
    fn stages(&self, params: &JumpParams, u_ref: &[f64]) -> Result<Vec<StageModel>> {
        let running = Arc::new(self.running_cost(u_ref, params)?);
        let (contact_step, flight_step) = (self.step(true, params.dt)?, self.step(false, params.dt)?);
        let cones = match params.friction {
            Some(mu) => self.friction_cones(mu)?,
            None => Vec::new(),
        };
        let torque_box = params.torque_limits.then(|| self.torque_box()).transpose()?;
        let mut stages = Vec::with_capacity(params.horizon);
        for t in 0..params.horizon {
            let in_contact = params.phase(t).in_contact();
            let step = if in_contact { &contact_step } else { &flight_step };
            let mut stage = StageModel::new(running.clone(), step.clone())?;
            if t == params.landing {
                stage.add_constraint(self.landing_constraint(self.nu())?)?;
            }
            let cones = cones.iter().filter(|_| in_contact);
            for c in cones.chain(&torque_box) {
                stage.add_constraint(c.clone())?;
            }
            stages.push(stage);
        }
        Ok(stages)
    }

    /// `z_c(q) = 0` for the four feet (the landing constraint), for stages with `nu`
    /// controls.
    fn landing_constraint(&self, nu: usize) -> Result<StageConstraint> {
        let heights = FEET
            .iter()
            .map(|foot| {
                let p = FrameTranslationResidual::new(&self.space, foot, &[0.0; 3])?;
                let z: Arc<dyn StageFunction> = Arc::new(Slice::new(Arc::new(Unary::new(Arc::new(p), nu)), &[2])?);
                Ok(z)
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(StageConstraint::new(
            "landing feet heights",
            Arc::new(FunctionStack::new(heights)?),
            Arc::new(EqualityConstraintSet),
        ))
    }

    /// `‖f_t‖ ≤ μ f_n` for each foot of the contact dynamics.
    fn friction_cones(&self, mu: f64) -> Result<Vec<StageConstraint>> {
        (0..FEET.len())
            .map(|k| {
                let r = FrictionConeResidual::new(self.contact.clone(), k, FrictionCone::vertical(mu)?)?;
                Ok(StageConstraint::new(
                    format!("friction cone {}", FEET[k]),
                    Arc::new(r),
                    Arc::new(SecondOrderCone::new(3)?),
                ))
            })
            .collect()
    }

    /// `|u| ≤ τ_max` from the URDF.
    fn torque_box(&self) -> Result<StageConstraint> {
        let dofs = self
            .actuation
            .actuated_dofs()
            .ok_or_else(|| Error::InvalidModel("solo_jump: the actuation is not a selection of dofs".into()))?;
        effort_limits(&self.space, &dofs)
    }
}

/// World heights of the frames `feet` at configuration `q`.
fn feet_heights(model: &Model, feet: &[usize], q: &[f64]) -> Result<Vec<f64>> {
    let mut data = model.create_data();
    feet_heights_with(model, &mut data, feet, q)
}

/// [`feet_heights`] with a given multibody data.
fn feet_heights_with(model: &Model, data: &mut Data, feet: &[usize], q: &[f64]) -> Result<Vec<f64>> {
    forward_kinematics_placements(model, data, q)
        .map_err(|e| Error::InvalidModel(format!("solo_jump: kinematics of the feet: {e}")))?;
    Ok(feet
        .iter()
        .map(|&f| {
            let frame = &model.frames()[f];
            data.joint_placement(frame.parent_joint)
                .compose(&frame.placement)
                .translation
                .z
        })
        .collect())
}

impl JumpSetup {
    /// The jump of `params` (module documentation).
    ///
    /// # Errors
    /// If the parameters are inconsistent (phases out of order, a non-positive time step
    /// or friction coefficient) or a model fails to build.
    pub fn new(params: &JumpParams) -> Result<Self> {
        params.validate()?;
        let solo = Solo::load(params)?;
        let nq = solo.space.nq();
        let qs = solo.contact.quasi_static_torque(&solo.x0[..nq])?;
        let stages = solo.stages(params, &qs.u)?;
        let terminal =
            CostStack::new(solo.space.as_ref(), 0).with("state", Arc::new(solo.state_cost(STATE_WEIGHT, 0)?), 1.0)?;
        let problem = Problem::new(&solo.x0, stages, Arc::new(terminal))?;
        Ok(Self {
            problem,
            x0: solo.x0,
            u_stand: qs.u,
            lambda_stand: qs.lambda,
            params: params.clone(),
            space: solo.space,
            contact: solo.contact,
            feet: solo.feet,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &JumpParams {
        &self.params
    }

    /// The phase space of the Solo-12.
    pub fn space(&self) -> &Arc<MultibodyPhaseSpace> {
        &self.space
    }

    /// The four-feet contact dynamics of the stance and landing stages (contacts in the
    /// order of [`FEET`]).
    pub fn contact_dynamics(&self) -> &Arc<MultibodyConstraintFwdDynamics> {
        &self.contact
    }

    /// Base height of the standing robot `x0` (m).
    pub fn standing_height(&self) -> f64 {
        self.x0[2]
    }

    /// World heights of the four feet (order of [`FEET`]) at state or configuration `x`.
    ///
    /// # Errors
    /// If the configuration part of `x` is invalid.
    pub fn feet_heights(&self, x: &[f64]) -> Result<Vec<f64>> {
        let nq = self.space.nq();
        if x.len() < nq {
            return Err(Error::dim("JumpSetup::feet_heights: state x", nq, x.len()));
        }
        feet_heights(self.space.model(), &self.feet, &x[..nq])
    }

    /// The initial guess: `x0` at every node, `u_qs` at every stage.
    pub fn initial_guess(&self) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
        let n = self.problem.horizon();
        (vec![self.x0.clone(); n + 1], vec![self.u_stand.clone(); n])
    }

    /// The data of the paper's figures for `solution` as CSV text (module
    /// documentation; columns in [`JumpFigures`]).
    ///
    /// # Errors
    /// If the solution does not fit the problem (sizes) or holds a state at which the
    /// contact dynamics fail.
    pub fn figures(&self, solution: &Solution) -> Result<JumpFigures> {
        self.problem.check_trajectory(&solution.xs, &solution.us)?;
        Ok(JumpFigures {
            convergence: convergence_csv(solution),
            trajectory: self.trajectory_csv(&solution.xs, &solution.us)?,
        })
    }

    /// The trajectory table of [`JumpFigures::trajectory`].
    fn trajectory_csv(&self, xs: &[Vec<f64>], us: &[Vec<f64>]) -> Result<String> {
        let model = self.space.model();
        let joints = actuated_joint_names(model);
        let mut csv = String::from("node,time,phase,base_x,base_y,base_z");
        for foot in FEET {
            let _ = write!(csv, ",z_{foot}");
        }
        for j in &joints {
            let _ = write!(csv, ",u_{j}");
        }
        for j in &joints {
            let _ = write!(csv, ",u_max_{j}");
        }
        for foot in FEET {
            for axis in ["x", "y", "z"] {
                let _ = write!(csv, ",f_{foot}_{axis}");
            }
        }
        csv.push('\n');
        let mut data = model.create_data();
        let forces = self.contact_forces(xs, us)?;
        for (t, x) in xs.iter().enumerate() {
            let phase = self.params.phase(t);
            let _ = write!(csv, "{t},{},{}", t as f64 * self.params.dt, phase.index());
            for v in &x[..3] {
                let _ = write!(csv, ",{v}");
            }
            for z in feet_heights_with(model, &mut data, &self.feet, &x[..self.space.nq()])? {
                let _ = write!(csv, ",{z}");
            }
            match (us.get(t), forces.get(t)) {
                (Some(u), Some(f)) => self.write_stage_columns(&mut csv, u, f),
                _ => csv.push_str(&",".repeat(2 * joints.len() + 3 * FEET.len())),
            }
            csv.push('\n');
        }
        Ok(csv)
    }

    /// The contact forces of the four feet ([`FEET`] order; N, world axes, environment on
    /// the robot; zero in flight) at every stage of `(xs, us)`.
    ///
    /// # Errors
    /// A trajectory that does not fit the problem, or a state at which the contact
    /// dynamics fail.
    pub fn contact_forces(&self, xs: &[Vec<f64>], us: &[Vec<f64>]) -> Result<Vec<Vec<[f64; 3]>>> {
        self.problem.check_trajectory(xs, us)?;
        let mut cdata = self.contact.create_contact_data();
        let mut out = Vec::with_capacity(us.len());
        for (t, (x, u)) in xs.iter().zip(us).enumerate() {
            let mut feet = vec![[0.0; 3]; FEET.len()];
            if self.params.phase(t).in_contact() {
                let lambda = self.contact.contact_forces(x, u, &mut cdata)?;
                for (k, f) in feet.iter_mut().enumerate() {
                    f.copy_from_slice(&lambda[3 * k..3 * k + 3]);
                }
            }
            out.push(feet);
        }
        Ok(out)
    }

    /// Torques, their limits and the contact forces (zero in flight) of one stage.
    fn write_stage_columns(&self, csv: &mut String, u: &[f64], forces: &[[f64; 3]]) {
        let model = self.space.model();
        for v in u {
            let _ = write!(csv, ",{v}");
        }
        for k in 6..model.nv() {
            let _ = write!(csv, ",{}", model.effort_limit[k]);
        }
        for f in forces.iter().flatten() {
            let _ = write!(csv, ",{f}");
        }
    }
}

/// Names of the joints driven by the controls, in control order.
fn actuated_joint_names(model: &Model) -> Vec<String> {
    model
        .joints()
        .iter()
        .zip(model.joint_names())
        .filter(|(j, _)| j.idx_v >= 6 && j.nv > 0)
        .map(|(_, name)| name.clone())
        .collect()
}

/// The convergence table of [`JumpFigures::convergence`].
fn convergence_csv(solution: &Solution) -> String {
    let mut csv = String::from("iter,prim_err,dual_err,mu,al_iter,alpha,cost\n");
    for r in &solution.history {
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{}",
            r.iter, r.prim_err, r.dual_err, r.mu, r.al_iter, r.alpha, r.cost
        );
    }
    csv
}

/// The data of the paper's figures as CSV text (a header line, then one line per row,
/// numbers in Rust's shortest round-trip form).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct JumpFigures {
    /// Fig. 12, one row per iteration of the solver's history:
    /// `iter,prim_err,dual_err,mu,al_iter,alpha,cost`.
    pub convergence: String,
    /// One row per node `t = 0..N`: `node,time,phase` (0 stance, 1 flight, 2 landing),
    /// `base_x,base_y,base_z` (m), `z_<foot>` for the four feet (m), `u_<joint>` the
    /// twelve joint torques (N m) and `u_max_<joint>` their URDF limits, `f_<foot>_<x|y|z>`
    /// the contact forces of the four feet (N, world axes, environment on the robot;
    /// zero in flight) recomputed from the contact dynamics at `(x_t, u_t)`. The torque
    /// and force fields of node `N` are empty.
    pub trajectory: String,
}

/// The recommended ProxDDP settings (module documentation).
pub fn proxddp_options() -> ProxDdpOptions {
    ProxDdpOptions::default().with(|o| {
        o.mu_init = 1e-4;
        o.tol = 1e-6;
        o.rollout = Rollout::Linear;
        o.max_iters = 300;
    })
}

/// The paper's jump ([`JumpParams::default`]) as the catalogue example `solo-jump`.
///
/// # Errors
/// Never for these fixed numbers (constructors are fallible in general).
pub fn build() -> Result<Example> {
    let setup = JumpSetup::new(&JumpParams::default())?;
    let (xs0, us0) = setup.initial_guess();
    Ok(Example {
        name: "solo-jump",
        problem: setup.problem,
        xs0,
        us0,
        dt: Some(setup.params.dt),
        proxddp: proxddp_options(),
        description: "Solo-12 whole-body jump (ProxDDP paper, Fig. 12 and 15): four-feet contact, flight from t0 = 0.4 s, \
                      landing at t1 = 0.9 s with the feet heights constrained to zero; dt = 20 ms, T = 1.2 s.",
    })
}

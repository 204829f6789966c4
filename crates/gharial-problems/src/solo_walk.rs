//! Whole-body trotting of the Solo-12 quadruped in closed loop: the ProxDDP paper's
//! MPC experiment (§VII-E, cost (58) and Table III, Fig. 16).
//!
//! **The paper's setting**: whole-body OCPs of `Δt = 12 ms` over a horizon of 0.48 s
//! (Fig. 16), one ProxDDP iteration per MPC cycle of 12 ms, the Riccati policy (57) at
//! 1 kHz in between, a base velocity command from a gamepad, no predefined foot
//! trajectories, the terrain assumed flat in the prediction while the real one has a
//! slope and bumps.
//!
//! **Model** (each stage): the Solo-12 of example-robot-data 5.0.0 (as
//! [`crate::solo_jump`]: free-flyer base, `nq = 19`, `nv = 18`, twelve actuated joints),
//! rigid 3D point contacts at the stance feet (LOCAL_WORLD_ALIGNED) with the Baumgarte
//! velocity gain `Kd = 1/Δt` (the contact velocity damped to zero in one step) and no
//! position gain (the paper's horizontal gains are zero; the height of a landing foot
//! comes from the impact cost), solved exactly ([`MultibodyConstraintFwdDynamics`]),
//! semi-implicit Euler `v⁺ = v + Δt a`, `q⁺ = q ⊕ Δt v⁺`.
//!
//! **Gait** ([`Gait`]): a periodic trot of `2 (d + s)` nodes: `d` nodes on four feet, `s`
//! nodes on the diagonal pair FL-HR (FR and HL swing), `d` nodes on four feet, `s` nodes
//! on FR-HL; the default `d = 2`, `s = 18` (24 ms and 216 ms, a cycle of 0.48 s = 40
//! nodes). The horizon ([`HORIZON`] = 40 nodes) holds gait nodes `0..N`, the queue of the
//! receding horizon the rest of a whole number of gait periods (empty when `N` is a
//! multiple of the period: the horizon rotates), so that [`gharial::mpc::Mpc::shift`]
//! walks through the gait: at cycle `c`, knot `t` is gait node `c + t`.
//!
//! **Cost** (58), `½ w ‖·‖²`, running terms times `Δt`, in the spirit of Table III:
//!
//! | term | weight |
//! |---|---|
//! | state `x ⊖ x_ref(t)`, `x_ref` the standing posture moved along the command, with the command as base velocity (`ℓ_reg` and `ℓ_base`) | base z, roll, pitch: [`W_BASE_POSE`]; yaw: [`W_YAW`]; joints: [`W_JOINTS`]; base linear velocity: [`W_BASE_VELOCITY`]; base angular velocity: [`W_BASE_RATE`]; joint velocities: [`W_JOINT_VELOCITY`] |
//! | control `u − u_qs`, the quasi-static torque of the standing robot | [`W_CONTROL`] |
//! | contact forces `λ_j − (0, 0, mg/n_c)` of the stance feet | [`W_FORCE`] |
//! | fly-high `v_xy(f) e^{−50 h(f)}` of the swing feet, `h` the height above the estimated ground | [`W_FLY_HIGH`] |
//! | impact: height `z(f)` and velocity `v(f)` of a foot at its touchdown node (not times `Δt`) | [`W_IMPACT`], [`W_IMPACT_VELOCITY`] |
//!
//! The terminal cost is the state term of the last stage's time (not times `Δt`).
//! Constraints (ProxDDP's augmented Lagrangian): Coulomb friction cones
//! `‖f_t‖ ≤ μ f_n` on the forces of the stance feet ([`FrictionConeResidual`], second-order
//! cones, `μ` = [`MU`]) and the URDF's effort limits on every stage. The paper's soft
//! velocity and control bounds are left out (the URDF's limits are never reached).
//!
//! **Plant** ([`WalkPlant`]): the same Solo-12 with the stance feet of the gait at the
//! plant's time (step `k` is in gait node `⌊k / 12⌋`), contact dynamics at 1 ms
//! ([`PLANT_DT`]) by semi-implicit Euler on the configuration manifold, with stiffer
//! Baumgarte terms ([`PLANT_KP`], [`PLANT_KD`]): at touchdown a foot's contact reference
//! is set where the foot is, projected onto the ground, so that a foot landing above or
//! below the ground is pulled onto it. The ground is the plane `z = 0` tilted by `slope`
//! about the y axis (`z = tan(slope) x`: uphill towards +x for a positive slope, so that
//! the feet the controller puts down at `z = 0` land below the ground and are pushed up
//! onto it), unknown to the controller, whose model assumes `z = 0`.
//!
//! **Scenarios** ([`scenario`]): `solo-walk-mpc` (flat, command 0.2 m/s forward) and
//! `solo-walk-mpc-slope` (0.1 rad), one ProxDDP iteration per 12 ms cycle, with the exact
//! dynamics step ([`mpc_proxddp_options`]). The first horizon's guess is the converged
//! solution of the first OCP from the standing state ([`WalkTask::first_plan`], proximal
//! dynamics step). Metrics: base height above the ground under it relative to the
//! standing height (min, max), the mean base velocity over the second
//! half of the run against the command (relative error), the largest friction-cone
//! violation `‖f_t‖ − μ f_n` of the plant's stance forces recomputed at the recorded
//! states and controls.
//!
//! The commanded velocity rises linearly from rest over [`RAMP`] (a step from standing
//! to 0.2 m/s made the first cycles push with forces up to 2 N outside their cones). The
//! impact cost of Table III also penalises the velocity of a landing foot; with that
//! term (weights 1 and 10, [`W_IMPACT_VELOCITY`]) ProxDDP stalls on the first OCP with
//! step lengths near 1e-3 and a dual residual of 0.1 after 300 iterations, so it is
//! off; without it the first OCP converges in 7 iterations.
//!
//! **Terrain** ([`WalkTask::follow_terrain`], called after every shift with the measured
//! state): the controller keeps the last contact point of each foot (the feet in stance
//! at the measured state) and fits the plane `z = a + b x + c y` through the four; the
//! base height target is the standing height above that plane where the base is
//! predicted to be (the measured position moved with the command), its vertical velocity
//! target the command's climb along the plane, a landing foot's height target the
//! plane's height under it, and the swing feet's fly-high cost measures their height
//! above the plane. The contact model itself stays flat (no position gain), and the
//! friction cones vertical.
//!
//! **Results** (`gharial simulate NAME --duration 10`, release build, one thread, 834
//! cycles of one iteration each; the machine shared with other jobs):
//!
//! | scenario | base height / standing | mean velocity, 2nd half | friction cones |
//! |---|---|---|---|
//! | `solo-walk-mpc` | 1.000 – 1.020 | 0.190 m/s (5.1 % below the command) | inside by 1.20 N or more |
//! | `solo-walk-mpc-slope` (0.1 rad uphill) | 1.000 – 1.020 | 0.188 m/s (6.2 % below) | inside by 0.55 N or more |
//! | `--slope 0.2` | 0.993 – 1.012 | 0.183 m/s (8.7 % below) | out by up to 0.19 N |
//! | `--slope -0.05` (downhill) | 1.000 – 1.018 | 0.190 m/s (4.9 % below) | inside by 1.31 N or more |
//! | `--slope -0.1` | 1.000 – 1.017 | 0.190 m/s (5.1 % below) | inside by 1.22 N or more |
//! | `--slope -0.2` | 0.996 – 1.020 | 0.188 m/s (6.0 % below) | inside by 0.91 N or more |
//! | `--speed 0.3` (flat) | 1.000 – 1.029 | 0.286 m/s (4.6 % below) | out by up to 0.59 N |
//!
//! Without the terrain estimate the controller kept the base at its standing height
//! above `z = 0` on the slope while the ground rose 0.19 m, and the base ended 8 cm
//! above the ground (0.365 of the standing height). With the fly-high cost measured
//! from `z = 0` instead of the estimated ground, its factor grew as `e^{50 · 0.1 x}`
//! with the distance `x` walked downhill: the plan kept the swing feet ever higher,
//! they reached their touchdown nodes 3 to 6 cm above the ground and the plant's
//! bilateral contacts pulled them onto it (a force no real ground exerts, out of the
//! cones by 50 N), and the base sank to 0.49 of its height with the velocity 39 % below
//! the command; uphill the term vanished (flat and uphill 0.1 then: 1.000 – 1.034 and
//! 0.935 – 1.001, 4.7 % and 4.1 % below, inside by 0.80 N and 0.16 N; 0.2 rad: 0.846 –
//! 1.000, 5.7 %, out by 0.97 N). With the term active uphill the robot trails the
//! command a little more. The plant's contacts stay bilateral from the scheduled
//! touchdown on, a foot that reaches its touchdown node above the ground pulled onto
//! it; over the 10 s the feet reach it 4.2 to 4.5 mm above flat ground (after the first
//! steps), downhill the front feet 7.9 mm and the hind feet 2.8 mm above, uphill the
//! front feet 0.7 mm below and the hind feet 5 mm above (their height targets are taken
//! under the feet's standing positions, not where they land), and no stance foot's
//! normal force falls below 3.4 N: the plant never pulls. Over the tests' 1.5 s
//! (`tests/solo_walk.rs`) the flat, uphill and downhill (−0.1 rad) scenarios keep the
//! base within 8 % of the standing height, the velocity within 7 % of the command and
//! every stance force inside its cone. Each stage solves the contact dynamics and their
//! derivatives once: its dynamics, its stacked contact-force cost and its stacked
//! friction cones ([`StackedContactResidual`]) share the solve
//! ([`MultibodyConstraintFwdDynamics::shared_contact_data`]); a cycle skips the
//! derivatives at its end ([`MpcOptions::final_residuals`]), which the next cycle's
//! shifted problem would not use.

use std::sync::{Arc, Mutex};

use gharial::constraints::{ConstraintSet, ConstraintSetProduct, SecondOrderCone};
use gharial::costs::{CostStack, QuadraticControlCost, QuadraticResidualCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, SemiImplicitEuler};
use gharial::functions::{Slice, StageFunction, Unary};
use gharial::mpc::{MpcOptions, Plant, Record};
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::solvers::proxddp::{ProxDdp, ProxDdpOptions, Rollout};
use gharial::solvers::{InitialGuess, Solver};
use gharial::spaces::Manifold;
use gharial::{Error, Result};
use gharial_multibody::spatial::Vec3;
use gharial_multibody::{
    ContactData, ContactModel, Data, Model, ReferenceFrame, RootJoint, constraint_dynamics,
    forward_kinematics_placements,
};
use gharial_robotics::residuals::{
    ContactForceResidual, FlyHighResidual, FrameTranslationResidual, FrameVelocityResidual, FrictionCone,
    FrictionConeResidual, StackedContactResidual, effort_limits,
};
use gharial_robotics::{Actuation, ContactSpec, MultibodyConstraintFwdDynamics, MultibodyPhaseSpace};

use crate::Example;
use crate::mpc::{Metric, Mismatch, MpcScenario, with_point_mass};
use crate::robots::{SOLO_SRDF, SOLO_URDF};

/// The standing posture of the SRDF (lowered onto the ground).
pub const STANDING: &str = "straight_standing";

/// The feet, in the order of [`Phase::stance`].
pub const FEET: [&str; 4] = ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"];

/// Time step of the OCP nodes and MPC period (s), the paper's.
pub const DT: f64 = 0.012;
/// Number of running stages (0.48 s), the paper's Fig. 16.
pub const HORIZON: usize = 40;
/// Plant step (s).
pub const PLANT_DT: f64 = 1e-3;
/// Friction coefficient of the cones.
pub const MU: f64 = 0.8;
/// Baumgarte position gain of the plant's contacts (1/s²).
pub const PLANT_KP: f64 = 625.0;
/// Baumgarte velocity gain of the plant's contacts (1/s), critical damping of `PLANT_KP`.
pub const PLANT_KD: f64 = 50.0;
/// The command of `solo-walk-mpc` (m/s, base frame: forward, lateral).
pub const COMMAND: [f64; 2] = [0.2, 0.0];
/// Time over which the commanded velocity rises linearly from zero (s).
pub const RAMP: f64 = 0.3;
/// The slope of `solo-walk-mpc-slope` (rad).
pub const SLOPE: f64 = 0.1;

/// Weight of base height, roll and pitch.
pub const W_BASE_POSE: f64 = 10.0;
/// Weight of the base yaw.
pub const W_YAW: f64 = 1.0;
/// Weight of the joint positions.
pub const W_JOINTS: f64 = 1.0;
/// Weight of the base linear velocity (the command tracking `ℓ_base`).
pub const W_BASE_VELOCITY: f64 = 100.0;
/// Weight of the base angular velocity.
pub const W_BASE_RATE: f64 = 1.0;
/// Weight of the joint velocities.
pub const W_JOINT_VELOCITY: f64 = 1e-2;
/// Weight of the control regularisation `u − u_qs`.
pub const W_CONTROL: f64 = 1e-1;
/// Weight of the contact-force regularisation.
pub const W_FORCE: f64 = 1e-3;
/// Weight of the fly-high term of each swing foot.
pub const W_FLY_HIGH: f64 = 0.5;
/// Weight of a foot's height at its touchdown node.
pub const W_IMPACT: f64 = 100.0;
/// Weight of a foot's velocity at its touchdown node (off: module documentation).
pub const W_IMPACT_VELOCITY: f64 = 0.0;
/// Decay rate of the fly-high residual (1/m), the paper's `γ`.
const FLY_HIGH_SLOPE: f64 = 50.0;

/// The trot schedule (module documentation): `double_support` nodes on four feet, then
/// `single_support` nodes on FL-HR, again four feet, then FR-HL.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Gait {
    /// Nodes on four feet before each diagonal phase.
    pub double_support: usize,
    /// Nodes of each diagonal phase.
    pub single_support: usize,
}

impl Default for Gait {
    fn default() -> Self {
        Self {
            double_support: 2,
            single_support: 18,
        }
    }
}

/// The stance phases of the trot.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// All four feet on the ground.
    FourFeet,
    /// FL and HR on the ground.
    FlHr,
    /// FR and HL on the ground.
    FrHl,
}

impl Phase {
    /// The three phases, in the order of [`Phase::index`].
    pub const ALL: [Phase; 3] = [Phase::FourFeet, Phase::FlHr, Phase::FrHl];

    /// 0, 1, 2.
    pub fn index(self) -> usize {
        self as usize
    }

    /// Which feet (order of [`FEET`]) are in contact.
    pub fn stance(self) -> [bool; 4] {
        match self {
            Phase::FourFeet => [true; 4],
            Phase::FlHr => [true, false, false, true],
            Phase::FrHl => [false, true, true, false],
        }
    }

    /// Indices (into [`FEET`]) of the stance feet.
    pub fn stance_feet(self) -> Vec<usize> {
        self.stance_feet_iter().collect()
    }

    /// The stance feet, without allocation.
    fn stance_feet_iter(self) -> impl Iterator<Item = usize> {
        let s = self.stance();
        (0..4).filter(move |&j| s[j])
    }
}

impl Gait {
    /// Nodes per gait cycle.
    pub fn period(&self) -> usize {
        2 * (self.double_support + self.single_support)
    }

    /// The phase of gait node `node` (periodic).
    pub fn phase(&self, node: usize) -> Phase {
        let (d, s) = (self.double_support, self.single_support);
        let k = node % self.period();
        if k < d || (d + s..2 * d + s).contains(&k) {
            Phase::FourFeet
        } else if k < d + s {
            Phase::FlHr
        } else {
            Phase::FrHl
        }
    }

    /// The feet that land at node `node`: in contact at `node`, not at `node − 1` (none at
    /// node 0, where the robot stands).
    pub fn touchdowns(&self, node: usize) -> [bool; 4] {
        let now = self.phase(node).stance();
        if node == 0 {
            return [false; 4];
        }
        let before = self.phase(node - 1).stance();
        std::array::from_fn(|j| now[j] && !before[j])
    }

    fn validate(&self) -> Result<()> {
        if self.single_support == 0 || self.period() > 10_000 {
            return Err(Error::option(
                "Gait",
                format!("need at least one single-support node and a period of at most 10000 nodes, got {self:?}"),
            ));
        }
        Ok(())
    }
}

/// The Solo-12, its standing state and the contact dynamics of each phase.
pub(crate) struct Solo {
    pub(crate) model: Arc<Model>,
    pub(crate) space: Arc<MultibodyPhaseSpace>,
    pub(crate) actuation: Arc<Actuation>,
    /// Frame ids of [`FEET`].
    pub(crate) feet: [usize; 4],
    pub(crate) x0: Vec<f64>,
}

fn model_error(e: gharial_multibody::Error) -> Error {
    Error::InvalidModel(format!("solo_walk: Solo-12 model: {e}"))
}

impl Solo {
    pub(crate) fn load() -> Result<Self> {
        let mut model = Model::from_urdf_str(SOLO_URDF, RootJoint::FreeFlyer).map_err(model_error)?;
        model.load_srdf_str(SOLO_SRDF).map_err(model_error)?;
        let mut q0 = model.reference_configuration(STANDING).map_err(model_error)?.to_vec();
        let mut feet = [0; 4];
        for (id, name) in feet.iter_mut().zip(FEET) {
            *id = model.frame_id(name).map_err(model_error)?;
        }
        let mut data = model.create_data();
        let z: f64 = feet_positions(&model, &mut data, &feet, &q0)?.iter().map(|p| p.z).sum();
        q0[2] -= z / 4.0;
        let model = Arc::new(model);
        let space = Arc::new(MultibodyPhaseSpace::new(model.clone()));
        let actuation = Arc::new(Actuation::floating_base(&model)?);
        let x0 = q0.iter().copied().chain(std::iter::repeat_n(0.0, model.nv())).collect();
        Ok(Self {
            model,
            space,
            actuation,
            feet,
            x0,
        })
    }

    fn nq(&self) -> usize {
        self.model.nq()
    }

    /// Point contacts at the stance feet of `phase` with gains `kp`, `kd`.
    pub(crate) fn contacts(&self, phase: Phase, kp: f64, kd: f64) -> Result<Vec<ContactModel>> {
        let names: Vec<&str> = phase.stance_feet().iter().map(|&j| FEET[j]).collect();
        let spec = ContactSpec::point(ReferenceFrame::LocalWorldAligned).with_gains(kp, kd);
        gharial_robotics::contacts_at_frames(&self.model, &names, spec)
    }

    /// The contact dynamics of the stance feet of `phase` for nodes of `dt`: no position
    /// gain, the velocity gain `Kd = 1/dt` (the contact velocity damped in one node).
    pub(crate) fn contact_dynamics(&self, phase: Phase, dt: f64) -> Result<Arc<MultibodyConstraintFwdDynamics>> {
        let contacts = self.contacts(phase, 0.0, 1.0 / dt)?;
        Ok(Arc::new(MultibodyConstraintFwdDynamics::new(
            self.space.clone(),
            self.actuation.clone(),
            contacts,
        )?))
    }
}

/// World positions of the frames `feet` at `q`.
pub(crate) fn feet_positions(model: &Model, data: &mut Data, feet: &[usize; 4], q: &[f64]) -> Result<[Vec3; 4]> {
    forward_kinematics_placements(model, data, q).map_err(model_error)?;
    Ok(feet.map(|f| {
        let frame = &model.frames()[f];
        data.joint_placement(frame.parent_joint)
            .compose(&frame.placement)
            .translation
    }))
}

/// The state weights of the module documentation (tangent order: base translation and
/// rotation in the base frame, joints; then the velocities).
fn state_weights(nv: usize) -> Vec<f64> {
    let mut w = vec![0.0; 2 * nv];
    w[2] = W_BASE_POSE;
    w[3] = W_BASE_POSE;
    w[4] = W_BASE_POSE;
    w[5] = W_YAW;
    w[6..nv].fill(W_JOINTS);
    w[nv..nv + 3].fill(W_BASE_VELOCITY);
    w[nv + 3..nv + 6].fill(W_BASE_RATE);
    w[nv + 6..].fill(W_JOINT_VELOCITY);
    w
}

/// The walking task: the stage objects of whole gait periods, their moving state
/// targets, the terminal cost.
pub struct WalkTask {
    /// The gait.
    pub gait: Gait,
    /// The command (m/s, forward and lateral in the base frame).
    pub command: [f64; 2],
    /// The standing state `x0 = (q0, 0)` on the ground.
    pub x0: Vec<f64>,
    /// The quasi-static torque of the standing robot on four feet.
    pub u_stand: Vec<f64>,
    /// The stage objects of gait nodes `0..L`, `L` a whole number of periods `≥ N`.
    stages: Vec<StageModel>,
    /// The state cost of each stage object.
    state_costs: Vec<Arc<QuadraticStateCost>>,
    terminal: Arc<QuadraticStateCost>,
    /// The terrain-following foot terms of each stage object.
    feet_terms: Vec<FeetTerms>,
    /// Scratch for the state target (set in place after each shift).
    x_ref: Mutex<Vec<f64>>,
    /// The controller's estimate of the ground from the feet's contact points.
    terrain: Mutex<Terrain>,
    solo: Solo,
}

/// The controller's estimate of the ground under the robot: the least-squares plane
/// `z = a + b x + c y` through the last contact point of each foot (the feet found in
/// stance at the measured states of the MPC cycles), so that the base height and the
/// landing heights are targeted above the ground walked on rather than above `z = 0`.
struct Terrain {
    /// The last contact point of each foot.
    footholds: [Vec3; 4],
    /// `(a, b, c)`.
    plane: [f64; 3],
    /// Offsets of the feet from the base in the standing posture (x, y).
    feet_offsets: [[f64; 2]; 4],
    /// The measured base position (x, y) and the time of the last update: the targets'
    /// heights are taken where the base is predicted to be, not where the command's
    /// reference is (a robot lagging behind it downhill would be sent into the ground).
    base: [f64; 2],
    time: f64,
    /// Kinematics workspace.
    data: Data,
}

impl Terrain {
    fn new(solo: &Solo) -> Result<Self> {
        let mut data = solo.model.create_data();
        let footholds = feet_positions(&solo.model, &mut data, &solo.feet, &solo.x0[..solo.nq()])?;
        let feet_offsets = footholds.map(|p| [p.x - solo.x0[0], p.y - solo.x0[1]]);
        let mut t = Self {
            footholds,
            plane: [0.0; 3],
            feet_offsets,
            base: [solo.x0[0], solo.x0[1]],
            time: 0.0,
            data,
        };
        t.fit();
        Ok(t)
    }

    /// Height of the estimated ground at `(x, y)`.
    fn height(&self, x: f64, y: f64) -> f64 {
        let [a, b, c] = self.plane;
        a + b * x + c * y
    }

    /// The base position (x, y) predicted at time `t` from the last measured one,
    /// moving with `command`.
    fn base_at(&self, t: f64, command: [f64; 2]) -> [f64; 2] {
        let d = command_ramp(t).1 - command_ramp(self.time).1;
        [self.base[0] + command[0] * d, self.base[1] + command[1] * d]
    }

    /// Records the base position and the contact points of the feet in stance at the
    /// state `x` of time `t`, and refits the plane.
    fn update(&mut self, solo: &Solo, stance: [bool; 4], t: f64, x: &[f64]) -> Result<()> {
        (self.base, self.time) = ([x[0], x[1]], t);
        let p = feet_positions(&solo.model, &mut self.data, &solo.feet, &x[..solo.nq()])?;
        for j in (0..4).filter(|&j| stance[j]) {
            self.footholds[j] = p[j];
        }
        self.fit();
        Ok(())
    }

    /// The least-squares plane through the footholds (normal equations, Cramer's rule);
    /// a level plane at their mean height if they are (nearly) collinear.
    fn fit(&mut self) {
        let (mut m, mut r) = ([[0.0; 3]; 3], [0.0; 3]);
        for p in &self.footholds {
            let row = [1.0, p.x, p.y];
            for i in 0..3 {
                for j in 0..3 {
                    m[i][j] += row[i] * row[j];
                }
                r[i] += row[i] * p.z;
            }
        }
        let det = |m: &[[f64; 3]; 3]| {
            m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
        };
        let d = det(&m);
        if d.abs() < 1e-9 {
            self.plane = [r[0] / 4.0, 0.0, 0.0];
            return;
        }
        for k in 0..3 {
            let mut mk = m;
            for i in 0..3 {
                mk[i][k] = r[i];
            }
            self.plane[k] = det(&mk) / d;
        }
    }
}

impl std::fmt::Debug for WalkTask {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WalkTask")
            .field("gait", &self.gait)
            .field("command", &self.command)
            .field("stage objects", &self.stages.len())
            .finish_non_exhaustive()
    }
}

impl WalkTask {
    /// The task of `gait` and `command` (module documentation).
    ///
    /// # Errors
    /// If the gait is degenerate, the command not finite, or a model fails to build.
    pub fn new(gait: Gait, command: [f64; 2]) -> Result<Self> {
        gait.validate()?;
        gharial::error::check_finite("solo_walk: command", &command)?;
        let solo = Solo::load()?;
        let nq = solo.nq();
        let dynamics: Vec<_> = Phase::ALL
            .iter()
            .map(|&p| solo.contact_dynamics(p, DT))
            .collect::<Result<_>>()?;
        let u_stand = dynamics[0].quasi_static_torque(&solo.x0[..nq])?.u;
        let period = gait.period();
        let len = HORIZON.div_ceil(period) * period;
        let weights = state_weights(solo.model.nv());
        let mut stages = Vec::with_capacity(len);
        let mut state_costs = Vec::with_capacity(len);
        let mut feet_terms = Vec::with_capacity(len);
        for node in 0..len {
            let cost = Arc::new(QuadraticStateCost::diagonal(
                solo.space.clone(),
                &solo.x0,
                &weights,
                u_stand.len(),
            )?);
            let (stage, terms) = stage_model(&solo, &gait, node, &dynamics, &u_stand, cost.clone())?;
            stages.push(stage);
            state_costs.push(cost);
            feet_terms.push(terms);
        }
        let terminal = Arc::new(QuadraticStateCost::diagonal(solo.space.clone(), &solo.x0, &weights, 0)?);
        let task = Self {
            gait,
            command,
            x0: solo.x0.clone(),
            u_stand,
            stages,
            state_costs,
            terminal,
            feet_terms,
            x_ref: Mutex::new(solo.x0.clone()),
            terrain: Mutex::new(Terrain::new(&solo)?),
            solo,
        };
        for node in 0..len {
            task.set_stage_target(node, node as f64 * DT)?;
        }
        task.set_terminal_target(HORIZON as f64 * DT)?;
        Ok(task)
    }

    /// The state target at time `t`: the standing posture moved along the command, its
    /// height above the estimated ground where the base is predicted to be, with the
    /// command (ramped up over [`RAMP`] from rest) as horizontal base velocity and the
    /// vertical velocity that keeps the base at that height along the estimated plane
    /// (the target's base is level: its frame's axes are the world's).
    fn write_target(&self, t: f64, terrain: &Terrain, x_ref: &mut [f64]) {
        let nq = self.solo.nq();
        let (ramp, distance) = command_ramp(t);
        x_ref.copy_from_slice(&self.x0);
        x_ref[0] += self.command[0] * distance;
        x_ref[1] += self.command[1] * distance;
        let [bx, by] = terrain.base_at(t, self.command);
        x_ref[2] = self.x0[2] + terrain.height(bx, by);
        let [_, slope_x, slope_y] = terrain.plane;
        let v = [self.command[0] * ramp, self.command[1] * ramp];
        x_ref[nq] = v[0];
        x_ref[nq + 1] = v[1];
        x_ref[nq + 2] = slope_x * v[0] + slope_y * v[1];
    }

    /// Sets the state target of stage object `id` (gait node `id`) for time `t`.
    ///
    /// # Errors
    /// If `id` is not a stage object of the task.
    pub fn set_stage_target(&self, id: usize, t: f64) -> Result<()> {
        let cost = self.state_costs.get(id).ok_or_else(|| {
            Error::InvalidModel(format!(
                "solo_walk: stage object {id}, the task has {}",
                self.state_costs.len()
            ))
        })?;
        self.set_target(cost, t)?;
        let terrain = self.lock_terrain()?;
        let [bx, by] = terrain.base_at(t, self.command);
        let terms = &self.feet_terms[id];
        for (j, r) in &terms.impacts {
            let [dx, dy] = terrain.feet_offsets[*j];
            r.set_target(&[0.0, 0.0, terrain.height(bx + dx, by + dy)])?;
        }
        for r in &terms.fly_high {
            r.set_ground(&terrain.plane)?;
        }
        Ok(())
    }

    /// Updates the ground estimate from the measured state `x` at gait node `node` (the
    /// feet in stance there touch the ground) and moves the targets of every stage
    /// object of the horizon starting at that node, and the terminal one, onto it.
    ///
    /// # Errors
    /// If `x` is not a state of the robot.
    pub fn follow_terrain(&self, node: usize, x: &[f64]) -> Result<()> {
        gharial::error::check_dim("solo_walk: measured state", self.x0.len(), x.len())?;
        let stance = self.gait.phase(node).stance();
        self.lock_terrain()?.update(&self.solo, stance, node as f64 * DT, x)?;
        let len = self.stages.len();
        for t in 0..HORIZON {
            self.set_stage_target((node + t) % len, (node + t) as f64 * DT)?;
        }
        self.set_terminal_target((node + HORIZON) as f64 * DT)
    }

    /// The terrain estimate (a poisoned lock is an error).
    fn lock_terrain(&self) -> Result<std::sync::MutexGuard<'_, Terrain>> {
        self.terrain
            .lock()
            .map_err(|_| Error::InvalidModel("solo_walk: poisoned terrain estimate".into()))
    }

    /// The estimated ground plane `(a, b, c)` of `z = a + b x + c y`.
    pub fn ground_estimate(&self) -> [f64; 3] {
        self.terrain.lock().map_or([f64::NAN; 3], |t| t.plane)
    }

    /// Sets the terminal state target for time `t`.
    ///
    /// # Errors
    /// Never for finite `t`.
    pub fn set_terminal_target(&self, t: f64) -> Result<()> {
        self.set_target(&self.terminal, t)
    }

    fn set_target(&self, cost: &QuadraticStateCost, t: f64) -> Result<()> {
        let mut x_ref = self
            .x_ref
            .lock()
            .map_err(|_| Error::InvalidModel("solo_walk: poisoned target".into()))?;
        self.write_target(t, &*self.lock_terrain()?, &mut x_ref);
        cost.set_target(&x_ref)
    }

    /// The first horizon (gait nodes `0..N`) and the queue (the rest of the stage objects).
    ///
    /// # Errors
    /// As [`Problem::new`].
    pub fn horizon(&self) -> Result<(Problem, Vec<StageModel>)> {
        let stages = self.stages[..HORIZON].to_vec();
        let problem = Problem::new(&self.x0, stages, self.terminal.clone())?;
        Ok((problem, self.stages[HORIZON..].to_vec()))
    }

    /// The first OCP from the standing state solved by ProxDDP ([`proxddp_options`], at
    /// most `max_iters` iterations) from `x0` and `u_qs` at every node: the guess of the
    /// first MPC cycle (the last iterate, converged or not: see [`FirstPlan::converged`]).
    ///
    /// # Errors
    /// If the solver fails or its iterate is not finite.
    pub fn first_plan(&self, max_iters: usize) -> Result<FirstPlan> {
        let (problem, _) = self.horizon()?;
        let mut solver = ProxDdp::new(proxddp_options().with(|o| o.max_iters = max_iters));
        solver.setup(&problem)?;
        let xs = vec![self.x0.clone(); HORIZON + 1];
        let us = vec![self.u_stand.clone(); HORIZON];
        let sol = solver.solve(&problem, InitialGuess::primal(&xs, &us))?;
        if sol.status == gharial::solvers::Status::NonFinite {
            return Err(Error::InvalidModel("solo_walk: the first OCP diverged".into()));
        }
        Ok(FirstPlan {
            xs: sol.xs.clone(),
            us: sol.us.clone(),
            converged: sol.status.converged(),
            iterations: sol.iterations,
            prim_err: sol.prim_err,
            dual_err: sol.dual_err,
        })
    }

    /// The plant of the task's robot and gait on `ground` (module documentation).
    ///
    /// # Errors
    /// Never for the task's models (constructors are fallible in general).
    pub fn plant(&self, ground: Ground) -> Result<WalkPlant> {
        self.plant_with(ground, Mismatch::default())
    }

    /// The plant on `ground` that differs from the controller's model by `mismatch` (a
    /// payload on the base at its centre of mass).
    ///
    /// # Errors
    /// If the mismatch is invalid.
    pub fn plant_with(&self, ground: Ground, mismatch: Mismatch) -> Result<WalkPlant> {
        WalkPlant::new(&self.solo, self.gait, ground, mismatch, FALLEN * self.standing_height())
    }

    /// Standing base height (m).
    pub fn standing_height(&self) -> f64 {
        self.x0[2]
    }
}

/// The factor `min(1, t / RAMP)` of the commanded velocity at time `t` and its
/// integral (s).
fn command_ramp(t: f64) -> (f64, f64) {
    if t < RAMP {
        (t / RAMP, 0.5 * t * t / RAMP)
    } else {
        (1.0, t - 0.5 * RAMP)
    }
}

/// The first OCP's solution ([`WalkTask::first_plan`]).
#[derive(Debug, Clone, PartialEq)]
pub struct FirstPlan {
    /// States `x_0..x_N`.
    pub xs: Vec<Vec<f64>>,
    /// Controls `u_0..u_{N-1}`.
    pub us: Vec<Vec<f64>>,
    /// Whether ProxDDP converged to its tolerance.
    pub converged: bool,
    /// Iterations taken.
    pub iterations: usize,
    /// Primal residual of the last iterate.
    pub prim_err: f64,
    /// Dual residual of the last iterate.
    pub dual_err: f64,
}

/// The foot terms of a stage that follow the terrain estimate.
#[derive(Default)]
struct FeetTerms {
    /// Impact costs: the foot (index into [`FEET`]) and its translation residual, whose
    /// height target is the estimated ground under the foot.
    impacts: Vec<(usize, Arc<FrameTranslationResidual>)>,
    /// Fly-high residuals of the swing feet, measured from the estimated ground plane.
    fly_high: Vec<Arc<FlyHighResidual>>,
}

/// The stage of gait node `node` (module documentation), its state cost `state`; and its
/// foot terms that follow the terrain.
fn stage_model(
    solo: &Solo,
    gait: &Gait,
    node: usize,
    dynamics: &[Arc<MultibodyConstraintFwdDynamics>],
    u_stand: &[f64],
    state: Arc<QuadraticStateCost>,
) -> Result<(StageModel, FeetTerms)> {
    let phase = gait.phase(node);
    let dyn_ = &dynamics[phase.index()];
    let (space, nu): (Arc<dyn Manifold>, usize) = (solo.space.clone(), u_stand.len());
    let control = QuadraticControlCost::diagonal(space.as_ref(), u_stand, &vec![W_CONTROL; nu])?;
    let mut cost =
        CostStack::new(space.as_ref(), nu)
            .with("state", state, DT)?
            .with("control", Arc::new(control), DT)?;
    let stance = phase.stance_feet();
    let load = solo.model.total_mass() * solo.model.gravity.linear.z.abs() / stance.len() as f64;
    // The stage object of node 0 also serves nodes L, 2L, ... of the rotating horizon (L a
    // whole number of periods), where FL and HR land; at node 0 itself they stand at the
    // fixed initial state, where the impact cost is a constant.
    let touchdowns = gait.touchdowns(node + gait.period());
    let mut terms = FeetTerms::default();
    if W_FORCE > 0.0 {
        // One contact solve for the forces of all stance feet.
        let parts = (0..stance.len())
            .map(|k| ContactForceResidual::new(dyn_.clone(), k, &[0.0, 0.0, load]))
            .collect::<Result<Vec<_>>>()?;
        let r = StackedContactResidual::new(parts)?;
        let c = QuadraticResidualCost::diagonal(Arc::new(r), &vec![W_FORCE; 3 * stance.len()])?;
        cost = cost.with("forces", Arc::new(c), DT)?;
    }
    for j in 0..4 {
        let name = FEET[j];
        let stance_index = stance.iter().position(|&s| s == j);
        if stance_index.is_none() {
            let f = Arc::new(FlyHighResidual::new(&solo.space, name, FLY_HIGH_SLOPE)?);
            terms.fly_high.push(f.clone());
            let c = QuadraticResidualCost::diagonal(Arc::new(Unary::new(f, nu)), &[W_FLY_HIGH; 2])?;
            cost = cost.with(format!("fly_high_{name}"), Arc::new(c), DT)?;
        }
        if touchdowns[j] {
            let r = Arc::new(FrameTranslationResidual::new(&solo.space, name, &[0.0; 3])?);
            terms.impacts.push((j, r.clone()));
            let p = Unary::new(r, nu);
            let z: Arc<dyn StageFunction> = Arc::new(Slice::new(Arc::new(p), &[2])?);
            let c = QuadraticResidualCost::diagonal(z, &[W_IMPACT])?;
            cost = cost.with(format!("impact_{name}"), Arc::new(c), 1.0)?;
        }
        if touchdowns[j] && W_IMPACT_VELOCITY > 0.0 {
            let v = FrameVelocityResidual::new(&solo.space, name, ReferenceFrame::LocalWorldAligned, &[0.0; 6])?;
            let v: Arc<dyn StageFunction> = Arc::new(Slice::new(Arc::new(Unary::new(Arc::new(v), nu)), &[0, 1, 2])?);
            let c = QuadraticResidualCost::diagonal(v, &[W_IMPACT_VELOCITY; 3])?;
            cost = cost.with(format!("impact_velocity_{name}"), Arc::new(c), 1.0)?;
        }
    }
    let step = SemiImplicitEuler::new(dyn_.clone(), solo.space.configuration().clone(), DT)?;
    let mut stage = StageModel::new(Arc::new(cost), Dynamics::Explicit(Arc::new(step)))?;
    // The friction cones of all stance feet, with one contact solve.
    let cones = (0..stance.len())
        .map(|k| FrictionConeResidual::new(dyn_.clone(), k, FrictionCone::vertical(MU)?))
        .collect::<Result<Vec<_>>>()?;
    let blocks = (0..stance.len())
        .map(|_| Ok((Arc::new(SecondOrderCone::new(3)?) as Arc<dyn ConstraintSet>, 3)))
        .collect::<Result<Vec<_>>>()?;
    stage.add_constraint(StageConstraint::new(
        "friction cones",
        Arc::new(StackedContactResidual::new(cones)?),
        Arc::new(ConstraintSetProduct::new(blocks)?),
    ))?;
    let dofs = solo
        .actuation
        .actuated_dofs()
        .ok_or_else(|| Error::InvalidModel("solo_walk: the actuation is not a joint selection".into()))?;
    stage.add_constraint(effort_limits(&solo.space, &dofs)?)?;
    Ok((stage, terms))
}

/// The ground plane `z = tan(slope) x` (module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ground {
    /// Tilt about the y axis (rad).
    pub slope: f64,
}

impl Ground {
    /// Height of the ground at `(x, y)`.
    pub fn height(&self, x: f64, _y: f64) -> f64 {
        self.slope.tan() * x
    }
}

/// The plant (module documentation): the contact dynamics of the stance feet of the gait
/// at the plant's time, the feet held where they landed on the ground.
pub struct WalkPlant {
    model: Arc<Model>,
    space: Arc<dyn Manifold>,
    gait: Gait,
    ground: Ground,
    feet: [usize; 4],
    /// Contacts of each phase (order of [`Phase::ALL`]).
    contacts: Vec<Vec<ContactModel>>,
    cdata: Vec<ContactData>,
    data: Data,
    /// Where each foot is held (world).
    references: [Vec3; 4],
    tau: Vec<f64>,
    dq: Vec<f64>,
    nu: usize,
    /// The base height above the ground (m) below which the robot has fallen.
    fallen_below: f64,
}

/// Largest velocity component (m/s, rad/s) of the plant's state: beyond it the closed
/// loop has diverged (a push the controller cannot absorb drives the joints through
/// thousands of rad/s before the contact problem fails) and the plant stops.
pub const DIVERGED: f64 = 100.0;

/// Fraction of the standing base height below which the plant reports a fall: the base
/// then rests on folded legs or the ground, which the plant (contacts at the feet only)
/// does not model, and the loop stops ([`gharial::mpc::Record::stopped`]).
pub const FALLEN: f64 = 0.25;

impl std::fmt::Debug for WalkPlant {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WalkPlant")
            .field("gait", &self.gait)
            .field("ground", &self.ground)
            .finish_non_exhaustive()
    }
}

/// Plant steps per gait node.
fn steps_per_node() -> usize {
    (DT / PLANT_DT).round() as usize
}

impl WalkPlant {
    fn new(solo: &Solo, gait: Gait, ground: Ground, mismatch: Mismatch, fallen_below: f64) -> Result<Self> {
        mismatch.check()?;
        let model = if mismatch.payload > 0.0 {
            let base = solo.model.joint_id("root_joint").map_err(model_error)?;
            let com = solo.model.inertias()[base].lever();
            Arc::new(with_point_mass(&solo.model, base, com, mismatch.payload)?)
        } else {
            solo.model.clone()
        };
        let contacts: Vec<Vec<ContactModel>> = Phase::ALL
            .iter()
            .map(|&p| solo.contacts(p, PLANT_KP, PLANT_KD))
            .collect::<Result<_>>()?;
        let cdata = contacts
            .iter()
            .map(|c| ContactData::new(&model, c).map_err(model_error))
            .collect::<Result<_>>()?;
        let nv = solo.model.nv();
        Ok(Self {
            data: model.create_data(),
            model,
            space: solo.space.clone(),
            gait,
            ground,
            feet: solo.feet,
            contacts,
            cdata,
            references: [Vec3::zeros(); 4],
            tau: vec![0.0; nv],
            dq: vec![0.0; nv],
            nu: solo.actuation.nu(),
            fallen_below,
        })
    }

    /// The phase at plant step `step`.
    pub fn phase(&self, step: usize) -> Phase {
        self.gait.phase(step / steps_per_node())
    }

    /// Solves the contact dynamics of step `step` at `(x, u)`: at step 0 and whenever a
    /// foot lands, its reference becomes its position projected onto the ground. Returns
    /// the phase; the accelerations and forces are in the phase's contact data.
    fn solve(&mut self, step: usize, x: &[f64], u: &[f64]) -> Result<Phase> {
        let nq = self.model.nq();
        let spn = steps_per_node();
        let node = step / spn;
        let phase = self.gait.phase(node);
        let landing = if step == 0 {
            [true; 4]
        } else if step.is_multiple_of(spn) {
            self.gait.touchdowns(node)
        } else {
            [false; 4]
        };
        if landing.iter().any(|&l| l) {
            let p = feet_positions(&self.model, &mut self.data, &self.feet, &x[..nq])?;
            for j in (0..4).filter(|&j| landing[j]) {
                self.references[j] = Vec3::new(p[j].x, p[j].y, self.ground.height(p[j].x, p[j].y));
            }
        }
        let i = phase.index();
        for (c, j) in self.contacts[i].iter_mut().zip(phase.stance_feet_iter()) {
            c.reference.translation = self.references[j];
        }
        self.tau[..6].fill(0.0);
        self.tau[6..].copy_from_slice(u);
        let (q, v) = x.split_at(nq);
        constraint_dynamics(
            &self.model,
            &mut self.data,
            &self.contacts[i],
            &mut self.cdata[i],
            q,
            v,
            &self.tau,
        )
        .map_err(|e| Error::Simulation(format!("solo_walk plant at step {step}: {e}")))?;
        Ok(phase)
    }

    /// The contact forces of the stance feet of step `step` at `(x, u)` (world axes,
    /// three per stance foot in the order of [`FEET`]), after the steps before it were
    /// taken in order (for the contact references).
    ///
    /// # Errors
    /// If the contact dynamics fail.
    pub fn forces(&mut self, step: usize, x: &[f64], u: &[f64]) -> Result<(Phase, &[f64])> {
        let phase = self.solve(step, x, u)?;
        Ok((phase, self.cdata[phase.index()].lambda()))
    }
}

impl Plant for WalkPlant {
    fn space(&self) -> &Arc<dyn Manifold> {
        &self.space
    }
    fn nu(&self) -> usize {
        self.nu
    }
    fn step(&mut self, step: usize, x: &[f64], u: &[f64], next: &mut [f64]) -> Result<()> {
        let phase = self.solve(step, x, u)?;
        let nq = self.model.nq();
        let ddq = self.cdata[phase.index()].ddq();
        let (q, v) = x.split_at(nq);
        let (q_next, v_next) = next.split_at_mut(nq);
        for k in 0..v.len() {
            v_next[k] = v[k] + PLANT_DT * ddq[k];
            self.dq[k] = PLANT_DT * v_next[k];
        }
        gharial_multibody::integrate(&self.model, q, &self.dq, q_next)
            .map_err(|e| Error::Simulation(format!("solo_walk plant at step {step}: {e}")))?;
        if let Some(i) = v_next.iter().position(|v| v.abs() > DIVERGED) {
            return Err(Error::Simulation(format!(
                "solo_walk plant at step {step}: the closed loop diverged (velocity {i} = {:.3e}, above {DIVERGED})",
                v_next[i]
            )));
        }
        let h = q_next[2] - self.ground.height(q_next[0], q_next[1]);
        if h < self.fallen_below {
            return Err(Error::Simulation(format!(
                "solo_walk plant at step {step}: the robot fell (base {h:.3} m above the ground, below {FALLEN} of the standing height)"
            )));
        }
        Ok(())
    }
}

/// Iterations of the first OCP's solve in [`scenario`].
pub const FIRST_PLAN_ITERS: usize = 100;

/// The recommended ProxDDP settings.
pub fn proxddp_options() -> ProxDdpOptions {
    ProxDdpOptions::default().with(|o| {
        o.mu_init = 1e-3;
        o.tol = 1e-5;
        o.rollout = Rollout::Linear;
        o.max_iters = 100;
    })
}

/// The ProxDDP settings of the MPC cycles: [`proxddp_options`] with the exact dynamics
/// step ([`crate::mpc::cycle_proxddp_options`]; 32.8 M instructions per cycle against
/// 41.6 M with the proximal step, the closed-loop metrics the same to the fourth digit on
/// flat ground, ±0.1 rad, 0.2 rad, `--speed 0.3`, a push and a payload).
pub fn mpc_proxddp_options() -> ProxDdpOptions {
    crate::mpc::cycle_proxddp_options(proxddp_options())
}

/// The closed-loop scenario (module documentation) on ground tilted by `slope` (rad)
/// with base velocity `command` (m/s, forward and lateral): `solo-walk-mpc` is
/// `scenario(0.0, COMMAND)`, `solo-walk-mpc-slope` `scenario(SLOPE, COMMAND)`.
///
/// # Errors
/// If `slope` is not finite or not below 0.5 rad in magnitude, the command is not
/// finite, or the first OCP does not converge.
pub fn scenario(slope: f64, command: [f64; 2]) -> Result<MpcScenario> {
    scenario_with(slope, command, Mismatch::default())
}

/// [`scenario`] with a plant that differs from the controller's model by `mismatch` (a
/// payload on the base at its centre of mass).
///
/// # Errors
/// As [`scenario`], or if the mismatch is invalid.
pub fn scenario_with(slope: f64, command: [f64; 2], mismatch: Mismatch) -> Result<MpcScenario> {
    if !(slope.is_finite() && slope.abs() < 0.5) {
        return Err(Error::option(
            "solo_walk: slope",
            format!("must be finite and below 0.5 rad in magnitude, got {slope}"),
        ));
    }
    let task = Arc::new(WalkTask::new(Gait::default(), command)?);
    let ground = Ground { slope };
    let plant = Box::new(task.plant_with(ground, mismatch)?);
    let (problem, queue) = task.horizon()?;
    let FirstPlan { xs: xs0, us: us0, .. } = task.first_plan(FIRST_PLAN_ITERS)?;
    let name = if slope == 0.0 {
        "solo-walk-mpc"
    } else {
        "solo-walk-mpc-slope"
    };
    let example = Example {
        name,
        problem,
        xs0,
        us0,
        dt: Some(DT),
        proxddp: mpc_proxddp_options(),
        description: "Solo-12 trot (ProxDDP paper, §VII-E): contact dynamics of the stance feet, base velocity command, \
                      friction cones and effort limits, dt = 12 ms, N = 40; guess: the converged first OCP.",
    };
    let shifted = task.clone();
    let measured = task.clone();
    Ok(MpcScenario {
        name,
        example,
        queue,
        plant,
        plant_dt: PLANT_DT,
        steps_per_cycle: steps_per_node(),
        // One iteration per cycle; the residuals at its end would cost a second
        // derivative evaluation of the horizon per cycle and serve only the report.
        options: MpcOptions::default().with(|o| {
            o.max_iters = 1;
            o.final_residuals = false;
        }),
        on_shift: Box::new(move |cycle, _, x| shifted.follow_terrain(cycle, x)),
        metrics: Box::new(move |rec| walk_metrics(&measured, ground, mismatch, rec)),
        base_velocity: Some(task.solo.model.nv()),
        pushes: Vec::new(),
    })
}

/// The metrics of a closed loop (module documentation).
///
/// # Errors
/// If the record is empty or the plant's contact dynamics fail at a recorded state.
pub fn walk_metrics(task: &WalkTask, ground: Ground, mismatch: Mismatch, rec: &Record) -> Result<Vec<Metric>> {
    if rec.us.is_empty() {
        return Err(Error::InvalidModel("solo_walk metrics: empty record".into()));
    }
    let h0 = task.standing_height();
    let (mut h_min, mut h_max) = (f64::INFINITY, f64::NEG_INFINITY);
    for x in &rec.xs {
        let h = (x[2] - ground.height(x[0], x[1])) / h0;
        h_min = h_min.min(h);
        h_max = h_max.max(h);
    }
    let n = rec.xs.len() - 1;
    let (a, b) = (&rec.xs[n / 2], &rec.xs[n]);
    let t = (n - n / 2) as f64 * PLANT_DT;
    let v = [(b[0] - a[0]) / t, (b[1] - a[1]) / t];
    let c = task.command;
    let err = (v[0] - c[0]).hypot(v[1] - c[1]);
    // Relative to the command, or in m/s when standing still is commanded.
    let (err_name, err, err_unit) = if c[0].hypot(c[1]) > 0.0 {
        ("velocity error / command", err / c[0].hypot(c[1]), "1")
    } else {
        ("velocity error (command 0)", err, "m/s")
    };
    let cone = friction_violation(task, ground, mismatch, rec)?;
    let metric = |name, value, unit| Metric { name, value, unit };
    Ok(vec![
        metric("min base height / nominal", h_min, "1"),
        metric("max base height / nominal", h_max, "1"),
        metric("mean forward velocity (2nd half)", v[0], "m/s"),
        metric("mean lateral velocity (2nd half)", v[1], "m/s"),
        metric(err_name, err, err_unit),
        metric("max friction-cone violation", cone, "N"),
    ])
}

/// The largest `‖f_t‖ − μ f_n` of the plant's stance forces at the recorded states and
/// controls (negative: every force strictly inside its cone), replaying the contact
/// references from step 0.
fn friction_violation(task: &WalkTask, ground: Ground, mismatch: Mismatch, rec: &Record) -> Result<f64> {
    let mut plant = task.plant_with(ground, mismatch)?;
    let mut worst = f64::NEG_INFINITY;
    for (k, (x, u)) in rec.xs.iter().zip(&rec.us).enumerate() {
        let (_, f) = plant.forces(k, x, u)?;
        for fj in f.chunks_exact(3) {
            worst = worst.max(fj[0].hypot(fj[1]) - MU * fj[2]);
        }
    }
    Ok(worst)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The plane fit recovers a plane through four footholds exactly, takes the
    /// least-squares plane of points off it, and falls back to a level plane at the mean
    /// height for collinear footholds.
    #[test]
    fn the_terrain_estimate_fits_the_footholds() {
        let solo = Solo::load().unwrap();
        let mut terrain = Terrain::new(&solo).unwrap();
        let plane = |x: f64, y: f64| 0.02 + 0.1 * x - 0.05 * y;
        let xy = [(0.2, 0.15), (0.2, -0.15), (-0.2, 0.15), (-0.2, -0.15)];
        terrain.footholds = xy.map(|(x, y)| Vec3::new(x, y, plane(x, y)));
        terrain.fit();
        for (a, b) in terrain.plane.iter().zip([0.02, 0.1, -0.05]) {
            assert!((a - b).abs() < 1e-12, "{:?}", terrain.plane);
        }
        // One foot 1 cm up: the least-squares plane of a rectangle moves every corner by
        // ±2.5 mm (the residuals alternate in sign around it).
        terrain.footholds[0].z += 0.01;
        terrain.fit();
        for (k, (x, y)) in xy.iter().enumerate() {
            let off = terrain.footholds[k].z - terrain.height(*x, *y);
            assert!((off.abs() - 0.0025).abs() < 1e-12, "{k}: {off}");
        }
        terrain.footholds = [0.0, 0.1, 0.2, 0.3].map(|x| Vec3::new(x, 0.0, x));
        terrain.fit();
        assert!((terrain.plane[0] - 0.15).abs() < 1e-15 && terrain.plane[1..] == [0.0, 0.0]);
    }

    /// The standing robot's estimate is the ground `z = 0`; raising the measured base and
    /// feet by 5 cm raises the base target of every stage by 5 cm.
    #[test]
    fn following_the_terrain_moves_the_base_targets() {
        let task = WalkTask::new(Gait::default(), COMMAND).unwrap();
        let level = task.ground_estimate();
        assert!(level.iter().all(|c| c.abs() < 1e-9), "{level:?}");
        let mut x = task.x0.clone();
        x[2] += 0.05;
        task.follow_terrain(0, &x).unwrap();
        let up = task.ground_estimate();
        assert!(
            (up[0] - 0.05).abs() < 1e-9 && up[1].abs() < 1e-9 && up[2].abs() < 1e-9,
            "{up:?}"
        );
        for cost in &task.state_costs {
            assert!((cost.error().target()[2] - x[2]).abs() < 1e-9);
        }
        assert!(task.follow_terrain(0, &x[1..]).is_err());
    }

    /// On an estimated plane `z = a + b x + c y`, every swing foot's fly-high cost is
    /// measured from that plane, every landing foot's height target is the plane's height
    /// under the foot, and the base velocity target climbs the plane with the command.
    #[test]
    fn the_foot_and_velocity_targets_follow_the_estimated_plane() {
        let task = WalkTask::new(Gait::default(), COMMAND).unwrap();
        let plane = [0.03, -0.1, 0.02];
        let t = 1.0;
        {
            let mut terrain = task.lock_terrain().unwrap();
            terrain.plane = plane;
            terrain.time = t;
        }
        let len = task.stages.len();
        for id in 0..len {
            task.set_stage_target(id, t + id as f64 * DT).unwrap();
        }
        let terrain = task.lock_terrain().unwrap();
        let ground = |x: f64, y: f64| plane[0] + plane[1] * x + plane[2] * y;
        let (mut fly_high, mut impacts) = (0, 0);
        for (id, terms) in task.feet_terms.iter().enumerate() {
            for r in &terms.fly_high {
                assert_eq!(r.ground(), plane);
                fly_high += 1;
            }
            let [bx, by] = terrain.base_at(t + id as f64 * DT, COMMAND);
            for (j, r) in &terms.impacts {
                let [dx, dy] = terrain.feet_offsets[*j];
                assert!((r.target()[2] - ground(bx + dx, by + dy)).abs() < 1e-12);
                impacts += 1;
            }
            let target = task.state_costs[id].error().target();
            let nq = task.solo.nq();
            assert!((target[2] - task.x0[2] - ground(bx, by)).abs() < 1e-12);
            let v = [target[nq], target[nq + 1], target[nq + 2]];
            assert!((v[0] - COMMAND[0]).abs() < 1e-12 && (v[2] - plane[1] * v[0] - plane[2] * v[1]).abs() < 1e-12);
        }
        // Two swing feet on 36 of the 40 nodes; FR and HL land at node 20, FL and HR at node
        // 40, stage object 0.
        assert_eq!((fly_high, impacts), (2 * 36, 4));
    }
}

//! The UR10 ballistic task of the ProxDDP paper (§VII-B, (54), (55), Figs. 8, 9, 13):
//! a UR10 throws a mug so that it lands at `p̂_T`, with no launch velocity given, only a
//! hard terminal constraint on the mug's position (`ur10-ballistic`).
//!
//! # Model
//! The UR10 of example-robot-data 5.0.0 (fixed base, efforts `τ_max` = (330, 330, 150,
//! 54, 54, 54) N m) and a mug on a free-flyer joint: a solid cylinder of 0.3 kg, radius
//! 4 cm, height 10 cm (`I = diag(3.7, 3.7, 2.4) · 10⁻⁴` kg m² about its centre, where the
//! mug frame is). The mug is unactuated: `τ = B u` with `B = [I₆; 0]` on the arm's dofs.
//! The phase space changes at the release:
//! - until `t_c` (stages `0..n_c`), the mug's free flyer is a child of the wrist, placed
//!   at the grasp frame `tool0 · (0, 0, 5 cm)`, and a 6D constraint holds the mug frame to
//!   the grasp frame, `c(q) = log6(q_ob) = 0`, with the Baumgarte gains (55)
//!   ([`MultibodyWeldFwdDynamics`]: `M a + b = B u + S λ`, `Sᵀ a = −Kp c − Kd ċ`);
//! - the last attached stage releases the mug: its next state is the same physical state
//!   in the flight model, where the mug hangs from the world by a translation joint and a
//!   spherical joint (`q_ob = (p, quat)` its world position and orientation, as a free
//!   flyer's, `v_ob = (ṗ, ω)` the world velocity of its centre and its body angular
//!   velocity): the arm and the mug are decoupled, free dynamics (ABA) under gravity.
//!
//! Both models order the configuration `q = (q_a, q_ob)` (as the authors' current
//! example; the paper writes `(q_ob, q_a)`). In the attached phase the constraint
//! Jacobian is constant (`Sᵀ`), so the constraint has no drift. In flight the mug is not
//! on an SE(3) free flyer: the semi-implicit Euler step of a free flyer moves its centre
//! along `exp6` of its body twist, off the parabola by `O(dt ω² |v|)` per unit time, and
//! the optimiser exploits that error (with a free flyer, the solution spins the mug at
//! 19 rad/s and the exact parabola from its release state lands 2.6 m short of the
//! target). With world translations the step `v⁺ = v + dt g`, `p⁺ = p + dt v⁺` is
//! ballistic whatever the spin.
//!
//! # Problem
//! Semi-implicit Euler, `dt = 10 ms`, `N = 200` (`T = 2 s`), attached for the stages
//! `0..=80` (release at `t_c = 0.81 s`), `q_a0 = (0, −120°, 120°, −45°, 0, 0)` at rest with
//! the mug in the hand. Costs, as the authors' example of the paper (proxddp's
//! `examples/ur10_ballistic.py`):
//! ```text
//! running:  dt · ½ (1e-6 ‖q_a − q_a0‖² + 10 ‖v_a‖² + 1e-2 ‖u − τ_0‖²)
//! terminal: ½ (1e-7 ‖q_a − q_a0‖² + ‖v_a‖²)
//! ```
//! with `τ_0` the quasi-static torque of the arm holding the mug (the unnumbered equation
//! after (55): `B u + Sλ = g(q_0)`, [`MultibodyWeldFwdDynamics::quasi_static_torque`]).
//! Constraints: `−τ_max ≤ u ≤ τ_max` at every stage (AL scale 1e-3, as the example) and
//! `p_mug(x_N) = p̂_T = (3.4, −0.2, 0)` (the example's target). The velocity limits are not
//! enforced (Fig. 9). Baumgarte gains `Kp = 1e-3`, `Kd = 2 √Kp` (the authors' current
//! example; the paper's had `Kp = Kd = 0`).
//!
//! Initial guess (cold start): `u_t = τ_0` and the standing state at every node (the
//! flight nodes hold the mug where it was released, at rest: a dynamics gap). ProxDDP
//! settings: `μ_0 = 1e-4` and the linear rollout, as the example, and `tol = 1e-6` (the
//! example's 1e-3 leaves the grasp constraint violated by 1.3e-3 at the release: the
//! dynamics gaps add up over the attached stages, which the small Baumgarte gains do
//! not correct). Measured (tests): converged in 60 iterations (3 AL iterations), primal
//! residual 8e-10, dual 6e-7, cost 28.42; the elbow reaches its torque limit.

use std::fmt::Write as _;
use std::sync::Arc;

use faer::{Accum, Mat};
use gharial::constraints::EqualityConstraintSet;
use gharial::costs::{CostStack, QuadraticControlCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, ExplicitDynamics, ExplicitDynamicsData, SemiImplicitEuler};
use gharial::functions::{StageFunction, StageFunctionData, Unary, Workspace};
use gharial::linalg::{matmul, slice, slice_mut};
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::solvers::Solution;
use gharial::solvers::proxddp::{ProxDdpOptions, Rollout};
use gharial::spaces::Manifold;
use gharial::{Error, Result};
use gharial_multibody::spatial::{Inertia, Mat3, Se3, Vec3};
use gharial_multibody::{
    Data, Frame, FrameType, JointLimits, JointType, Model, ReferenceFrame, RootJoint, forward_kinematics_placements,
    integrate, log3,
};
use gharial_robotics::residuals::{FrameTranslationResidual, FrameVelocityResidual, effort_limits};
use gharial_robotics::{Actuation, MultibodyFreeFwdDynamics, MultibodyPhaseSpace, MultibodyWeldFwdDynamics};

use crate::Example;
use crate::robots::UR10_URDF;

/// Name of the mug's free-flyer joint and of its frame (at the mug's centre).
pub const MUG_JOINT: &str = "mug_joint";
/// Name of the mug frame.
pub const MUG_FRAME: &str = "mug";
/// Number of arm joints (and controls).
const NA: usize = 6;

/// The numbers of the task (module documentation); `Default` gives the catalogue's.
#[derive(Debug, Clone, PartialEq)]
pub struct Ur10BallisticParams {
    /// Time step (s).
    pub dt: f64,
    /// Number of stages `N`.
    pub horizon: usize,
    /// Number of attached stages `n_c` (the mug is released at `t_c = n_c dt`).
    pub contact_stages: usize,
    /// Initial arm configuration (rad), at rest.
    pub q0: [f64; NA],
    /// Target position `p̂_T` of the mug at `t = T` (m).
    pub target: [f64; 3],
    /// Mug mass (kg), radius and height (m) of its solid cylinder.
    pub mug: [f64; 3],
    /// Distance of the grasp frame from `tool0` along its z axis (m).
    pub grasp_offset: f64,
    /// Baumgarte gains `(Kp, Kd)` of the grasp (55).
    pub gains: (f64, f64),
    /// Running weights `(w_q, w_v, w_u)` (scaled by `dt`).
    pub running: [f64; 3],
    /// Terminal weights `(w_q, w_v)`.
    pub terminal: [f64; 2],
    /// Augmented-Lagrangian scale of the torque limits.
    pub torque_scale: f64,
}

impl Default for Ur10BallisticParams {
    fn default() -> Self {
        let kp = 1e-3;
        Self {
            dt: 0.01,
            horizon: 200,
            contact_stages: 81,
            q0: [
                0.0,
                -120f64.to_radians(),
                120f64.to_radians(),
                -45f64.to_radians(),
                0.0,
                0.0,
            ],
            target: [3.4, -0.2, 0.0],
            mug: [0.3, 0.04, 0.1],
            grasp_offset: 0.05,
            gains: (kp, 2.0 * kp.sqrt()),
            running: [1e-6, 10.0, 1e-2],
            terminal: [1e-7, 1.0],
            torque_scale: 1e-3,
        }
    }
}

/// The built task: the two models, the quasi-static torque and the catalogue example.
#[derive(Clone)]
pub struct Ur10Ballistic {
    /// The numbers it was built from.
    pub params: Ur10BallisticParams,
    /// Phase space of the attached phase (mug below the wrist), nodes `0..n_c`.
    pub attached: Arc<MultibodyPhaseSpace>,
    /// Phase space of the flight phase (mug below the world), nodes `n_c..=N`.
    pub flight: Arc<MultibodyPhaseSpace>,
    /// The attached dynamics.
    pub weld: Arc<MultibodyWeldFwdDynamics>,
    /// The quasi-static torque `τ_0` (arm holding the mug at `q_0`).
    pub tau0: Vec<f64>,
    /// Initial state in the attached phase.
    pub x0: Vec<f64>,
    /// The problem, its initial guess and ProxDDP settings.
    pub example: Example,
}

impl std::fmt::Debug for Ur10Ballistic {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ur10Ballistic")
            .field("params", &self.params)
            .field("tau0", &self.tau0)
            .finish_non_exhaustive()
    }
}

/// The catalogue entry `ur10-ballistic` (default numbers).
///
/// # Errors
/// Never for the default numbers (constructors are fallible in general).
pub fn build() -> Result<Example> {
    Ok(Ur10Ballistic::new(Ur10BallisticParams::default())?.example)
}

/// How the mug is attached to the model tree.
#[derive(Clone, Copy)]
enum Mount {
    /// On a free flyer below joint `.0` at placement `.1` (the grasp).
    Held(usize, Se3),
    /// On a translation joint below the world followed by a spherical joint:
    /// `q_ob = (p, quat)` is the world position of its centre and its orientation,
    /// `v_ob = (ṗ, ω)` its world velocity and body angular velocity.
    Flying,
}

/// The UR10 with the mug mounted as `mount`, its body and frame on joint [`MUG_JOINT`].
fn model_with_mug(params: &Ur10BallisticParams, mount: Mount) -> Result<Model> {
    let mb = |e: gharial_multibody::Error| Error::InvalidModel(format!("ur10-ballistic model: {e}"));
    let mut model = Model::from_urdf_str(UR10_URDF, RootJoint::Fixed).map_err(mb)?;
    let add = |model: &mut Model, parent: usize, kind: JointType, placement: Se3, name: &str| {
        let limits = JointLimits::unbounded(&kind);
        model.add_joint(parent, kind, placement, name, limits).map_err(mb)
    };
    let (parent, id) = match mount {
        Mount::Held(parent, grasp) => (parent, add(&mut model, parent, JointType::FreeFlyer, grasp, MUG_JOINT)?),
        Mount::Flying => {
            let t = add(
                &mut model,
                0,
                JointType::Translation,
                Se3::identity(),
                "mug_translation",
            )?;
            (0, add(&mut model, t, JointType::Spherical, Se3::identity(), MUG_JOINT)?)
        }
    };
    let [m, r, h] = params.mug;
    let (ixx, izz) = (m * (3.0 * r * r + h * h) / 12.0, m * r * r / 2.0);
    let inertia = Inertia::from_com(m, Vec3::zeros(), Mat3::from_diagonal(&Vec3::new(ixx, ixx, izz)));
    model.append_body_to_joint(id, &inertia, &Se3::identity()).map_err(mb)?;
    let parent_frame = model
        .frames()
        .iter()
        .position(|f| f.parent_joint == parent)
        .unwrap_or(0);
    model
        .add_frame(Frame {
            name: MUG_FRAME.into(),
            kind: FrameType::Body,
            parent_joint: id,
            parent_frame,
            placement: Se3::identity(),
        })
        .map_err(mb)?;
    Ok(model)
}

/// The two phase spaces of the task and the dynamics of its three kinds of stage.
struct Phases<'a> {
    attached: &'a Arc<MultibodyPhaseSpace>,
    flight: &'a Arc<MultibodyPhaseSpace>,
    hold: Dynamics,
    release: Dynamics,
    fly: Dynamics,
}

impl<'a> Phases<'a> {
    /// The phases' dynamics: the welded mug's and the free flight's semi-implicit Euler
    /// steps, and the release map between them.
    fn new(
        attached: &'a Arc<MultibodyPhaseSpace>,
        flight: &'a Arc<MultibodyPhaseSpace>,
        weld: &Arc<MultibodyWeldFwdDynamics>,
        release: Release,
        dt: f64,
    ) -> Result<Self> {
        let free = Arc::new(MultibodyFreeFwdDynamics::new(
            flight.clone(),
            Actuation::dofs(flight.model(), &ARM_DOFS)?,
        )?);
        let hold = SemiImplicitEuler::new(weld.clone(), attached.configuration().clone(), dt)?;
        let fly = SemiImplicitEuler::new(free, flight.configuration().clone(), dt)?;
        Ok(Self {
            attached,
            flight,
            hold: Dynamics::Explicit(Arc::new(hold)),
            release: Dynamics::Explicit(Arc::new(release)),
            fly: Dynamics::Explicit(Arc::new(fly)),
        })
    }

    /// The problem: held stages, the release stage, flight stages (each with its costs
    /// around `x0` or its flight image `x0_flight` and the torque limits), the terminal
    /// cost and the terminal constraint on the mug's position.
    fn problem(&self, params: &Ur10BallisticParams, x0: &[f64], x0_flight: &[f64], tau0: &[f64]) -> Result<Problem> {
        let nc = params.contact_stages;
        let arm_dofs: Vec<usize> = (0..NA).collect();
        let mut stages = Vec::with_capacity(params.horizon);
        for t in 0..params.horizon {
            let (space, x_ref, dynamics) = match t {
                t if t + 1 < nc => (self.attached, x0, self.hold.clone()),
                t if t + 1 == nc => (self.attached, x0, self.release.clone()),
                _ => (self.flight, x0_flight, self.fly.clone()),
            };
            let cost = running_cost(params, space, x_ref, tau0)?;
            let mut stage = StageModel::new(Arc::new(cost), dynamics)?;
            stage.add_constraint(effort_limits(space, &arm_dofs)?.with_scale(params.torque_scale))?;
            stages.push(stage);
        }
        let terminal = state_cost(self.flight, x0_flight, params.terminal[0], params.terminal[1], 0, 1.0)?;
        let mut problem = Problem::new(x0, stages, Arc::new(terminal))?;
        let mug = FrameTranslationResidual::new(self.flight, MUG_FRAME, &params.target)?;
        let landing: Arc<dyn StageFunction> = Arc::new(Unary::new(Arc::new(mug), 0));
        problem.add_terminal_constraint(StageConstraint::new(
            "mug position",
            landing,
            Arc::new(EqualityConstraintSet),
        ))?;
        Ok(problem)
    }
}

/// The actuated dofs: the arm's.
const ARM_DOFS: [usize; NA] = [0, 1, 2, 3, 4, 5];

/// The phase spaces of the arm with the mug held at the tool (grasp offset along its z)
/// and with the mug flying.
fn phase_spaces(params: &Ur10BallisticParams) -> Result<(Arc<MultibodyPhaseSpace>, Arc<MultibodyPhaseSpace>)> {
    let arm = Model::from_urdf_str(UR10_URDF, RootJoint::Fixed)
        .map_err(|e| Error::InvalidModel(format!("ur10-ballistic model: {e}")))?;
    let tool = arm.frames()[arm.frame_id("tool0").map_err(|e| Error::InvalidModel(e.to_string()))?].clone();
    let grasp = tool
        .placement
        .compose(&Se3::new(Mat3::identity(), Vec3::new(0.0, 0.0, params.grasp_offset)));
    let attached = Arc::new(MultibodyPhaseSpace::new(Arc::new(model_with_mug(
        params,
        Mount::Held(tool.parent_joint, grasp),
    )?)));
    let flight = Arc::new(MultibodyPhaseSpace::new(Arc::new(model_with_mug(
        params,
        Mount::Flying,
    )?)));
    Ok((attached, flight))
}

/// The catalogue entry: the cold start (`x0` held, its flight image after the release,
/// the quasi-static torque) and the paper's settings.
fn example(params: &Ur10BallisticParams, problem: Problem, x0: &[f64], x0_flight: &[f64], tau0: &[f64]) -> Example {
    let nc = params.contact_stages;
    let xs0 = (0..=params.horizon)
        .map(|t| if t < nc { x0.to_vec() } else { x0_flight.to_vec() })
        .collect();
    Example {
        name: "ur10-ballistic",
        problem,
        xs0,
        us0: vec![tau0.to_vec(); params.horizon],
        dt: Some(params.dt),
        proxddp: ProxDdpOptions::default().with(|o| {
            o.tol = 1e-6;
            o.mu_init = 1e-4;
            o.rollout = Rollout::Linear;
            o.max_iters = 300;
        }),
        description: "ProxDDP paper's UR10 ballistic task (VII-B): throw a mug (0.3 kg) held by a 6D \
                      constraint until t_c = 0.81 s so that it lands at (3.4, -0.2, 0) at T = 2 s; torque \
                      limits, terminal position constraint only; cold start from the quasi-static torque.",
    }
}

impl Ur10Ballistic {
    /// Builds the task from `params`.
    ///
    /// # Errors
    /// If the numbers are out of range (`n_c` not in `1..N`, a non-positive step, a mass
    /// or weight not finite and positive): the constructors' errors name the object.
    pub fn new(params: Ur10BallisticParams) -> Result<Self> {
        if !(1..params.horizon).contains(&params.contact_stages) {
            return Err(Error::option(
                "Ur10BallisticParams::contact_stages",
                format!(
                    "must be in 1..{} (the horizon), got {}",
                    params.horizon, params.contact_stages
                ),
            ));
        }
        let (attached, flight) = phase_spaces(&params)?;
        let (kp, kd) = params.gains;
        let weld = Arc::new(MultibodyWeldFwdDynamics::new(
            attached.clone(),
            Actuation::dofs(attached.model(), &ARM_DOFS)?,
            MUG_JOINT,
            kp,
            kd,
        )?);
        let x0: Vec<f64> = params
            .q0
            .iter()
            .copied()
            .chain(rest_pose())
            .chain([0.0; NA + 6])
            .collect();
        let tau0 = weld.quasi_static_torque(&x0[..NA + 7])?.u;
        let release = Release::new(weld.clone(), attached.clone(), flight.clone(), params.dt)?;
        let x0_flight = release.release_state(&x0)?;
        let phases = Phases::new(&attached, &flight, &weld, release, params.dt)?;
        let problem = phases.problem(&params, &x0, &x0_flight, &tau0)?;
        let example = example(&params, problem, &x0, &x0_flight, &tau0);
        Ok(Self {
            params,
            attached,
            flight,
            weld,
            tau0,
            x0,
            example,
        })
    }

    /// The first node of the flight phase (`n_c`): nodes before it are states of
    /// [`Self::attached`], nodes from it on states of [`Self::flight`].
    pub fn release_node(&self) -> usize {
        self.params.contact_stages
    }

    /// The phase space of node `t`.
    pub fn space(&self, t: usize) -> &Arc<MultibodyPhaseSpace> {
        if t < self.release_node() {
            &self.attached
        } else {
            &self.flight
        }
    }

    /// World position of the mug's centre at node `t` in state `x`.
    ///
    /// # Errors
    /// If `x` is not a valid state of node `t`'s space.
    pub fn mug_position(&self, t: usize, x: &[f64]) -> Result<[f64; 3]> {
        let space = self.space(t);
        let model = space.model();
        gharial::error::check_dim(format_args!("ur10-ballistic: state of node {t}"), space.nx(), x.len())?;
        let mut data = model.create_data();
        forward_kinematics_placements(model, &mut data, &x[..space.nq()])
            .map_err(|e| Error::InvalidModel(format!("ur10-ballistic: node {t}: {e}")))?;
        let id = model
            .joint_id(MUG_JOINT)
            .map_err(|e| Error::InvalidModel(e.to_string()))?;
        let p = data.joint_placement(id).translation;
        Ok([p.x, p.y, p.z])
    }

    /// The grasp constraint's violation at an attached state: `max(|c(q)|∞, |ċ|∞)`, with
    /// `c = log6(q_ob)` the mug frame's placement error from the grasp frame and `ċ` its
    /// relative twist.
    ///
    /// # Errors
    /// If `x` is not a valid attached state.
    pub fn grasp_error(&self, x: &[f64]) -> Result<f64> {
        let (c, v) = self.weld.constraint_error(x)?;
        Ok(c.iter().chain(&v).fold(0.0_f64, |m, e| m.max(e.abs())))
    }

    /// The data of the paper's figures for a solution of [`Self::example`], as CSV.
    ///
    /// # Errors
    /// If the solution does not have the problem's horizon or a state is invalid.
    pub fn figure_csv(&self, sol: &Solution) -> Result<FigureCsv> {
        let n = self.params.horizon;
        gharial::error::check_dim("ur10-ballistic figures: states x_0..x_N", n + 1, sol.xs.len())?;
        gharial::error::check_dim("ur10-ballistic figures: controls u_0..u_{N-1}", n, sol.us.len())?;
        let model = self.attached.model();
        let names = &model.joint_names()[1..=NA];
        let mut header = vec!["t".to_string()];
        for what in ["tau", "tau_max", "v", "v_max"] {
            header.extend(names.iter().map(|j| format!("{what}_{j}")));
        }
        header.extend(["mug_x", "mug_y", "mug_z", "attached"].map(String::from));
        let mut trajectory = header.join(",") + "\n";
        let nq = self.attached.nq();
        for (t, x) in sol.xs.iter().enumerate() {
            let mut row = vec![fmt(t as f64 * self.params.dt)];
            let u = sol.us.get(t);
            row.extend((0..NA).map(|j| u.map_or(String::new(), |u| fmt(u[j]))));
            row.extend(model.effort_limit[..NA].iter().map(|&l| fmt(l)));
            row.extend(x[nq..nq + NA].iter().map(|&v| fmt(v)));
            row.extend(model.velocity_limit[..NA].iter().map(|&l| fmt(l)));
            row.extend(self.mug_position(t, x)?.map(fmt));
            row.push(u8::from(t < self.release_node()).to_string());
            trajectory += &(row.join(",") + "\n");
        }
        let mut convergence = "iter,prim_err,dual_err,mu,al_iter\n".to_string();
        for r in &sol.history {
            let _ = writeln!(
                convergence,
                "{},{},{},{},{}",
                r.iter,
                fmt(r.prim_err),
                fmt(r.dual_err),
                fmt(r.mu),
                r.al_iter
            );
        }
        Ok(FigureCsv {
            trajectory,
            convergence,
        })
    }
}

/// Shortest round-trip text of a number.
fn fmt(v: f64) -> String {
    format!("{v:e}")
}

/// The figure data of [`Ur10Ballistic::figure_csv`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FigureCsv {
    /// One row per node `t = 0..=N`: time, the joint torques `tau_<joint>` (empty at
    /// `t = N`) with their limits `tau_max_<joint>` (Fig. 8), the joint velocities
    /// `v_<joint>` with the URDF limits `v_max_<joint>` (Fig. 9), the mug's world position
    /// and whether it is held (1) or flying (0).
    pub trajectory: String,
    /// One row per solver iteration: the primal and dual residuals, `μ` and the AL
    /// iteration.
    pub convergence: String,
}

/// The identity placement of a free flyer, `(0, 0, 0, 0, 0, 0, 1)`.
fn rest_pose() -> [f64; 7] {
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
}

/// `scale · ½ (w_q ‖q_a − q_a,ref‖² + w_v ‖v_a‖²)` (no weight on the mug).
fn state_cost(
    space: &Arc<MultibodyPhaseSpace>,
    x_ref: &[f64],
    wq: f64,
    wv: f64,
    nu: usize,
    scale: f64,
) -> Result<CostStack> {
    let nv = space.nv();
    let w: Vec<f64> = (0..2 * nv)
        .map(|i| match i {
            i if i < NA => wq,
            i if (nv..nv + NA).contains(&i) => wv,
            _ => 0.0,
        })
        .collect();
    let manifold: Arc<dyn Manifold> = space.clone();
    CostStack::new(manifold.as_ref(), nu).with(
        "state",
        Arc::new(QuadraticStateCost::diagonal(manifold.clone(), x_ref, &w, nu)?),
        scale,
    )
}

/// The running cost `dt · ½ (w_q ‖Δq_a‖² + w_v ‖v_a‖² + w_u ‖u − τ_0‖²)`.
fn running_cost(
    params: &Ur10BallisticParams,
    space: &Arc<MultibodyPhaseSpace>,
    x_ref: &[f64],
    tau0: &[f64],
) -> Result<CostStack> {
    let [wq, wv, wu] = params.running;
    let control = QuadraticControlCost::diagonal(space.as_ref(), tau0, &[wu; NA])?;
    state_cost(space, x_ref, wq, wv, NA, params.dt)?.with("control", Arc::new(control), params.dt)
}

/// The last attached stage: the attached step, then the same physical state in the
/// flight model, `φ(q_a, q_ob, v_a, v_ob) = (q_a, (p, R), v_a, (ṗ, ω))` with the mug's
/// world placement `(R, p)`, the world velocity `ṗ` of its centre and its body angular
/// velocity `ω`, all from the attached model's kinematics.
struct Release {
    step: SemiImplicitEuler,
    attached: Arc<MultibodyPhaseSpace>,
    flight: Arc<MultibodyPhaseSpace>,
    flight_manifold: Arc<dyn Manifold>,
    /// The mug's velocity in the attached model: world-aligned (its linear part is the
    /// world velocity of the mug's centre) and local (its angular part is the body's).
    mug_world: Unary,
    mug_local: Unary,
    mug_joint: usize,
}

/// Scratch memory of [`Release`]: the attached step's data, its next state `y`, and what
/// `φ` needs.
struct ReleaseWs {
    step: ExplicitDynamicsData,
    y: Vec<f64>,
    map: MapWs,
}

/// Scratch memory of `φ`.
struct MapWs {
    world: StageFunctionData,
    local: StageFunctionData,
    data: Data,
    /// `dφ` at the attached next state (`ndx × ndx`).
    dphi: Mat<f64>,
    /// The flight configuration at the arm's `q_a` with the mug at the origin, and the
    /// tangent `(0, p, log3(R))` that moves it to the mug's world placement `(R, p)`.
    q_base: Vec<f64>,
    delta: Vec<f64>,
}

impl Release {
    fn new(
        weld: Arc<MultibodyWeldFwdDynamics>,
        attached: Arc<MultibodyPhaseSpace>,
        flight: Arc<MultibodyPhaseSpace>,
        dt: f64,
    ) -> Result<Self> {
        let step = SemiImplicitEuler::new(weld, attached.configuration().clone(), dt)?;
        let velocity = |rf| -> Result<Unary> {
            let r = FrameVelocityResidual::new(&attached, MUG_FRAME, rf, &[0.0; 6])?;
            Ok(Unary::new(Arc::new(r), 0))
        };
        let (mug_world, mug_local) = (
            velocity(ReferenceFrame::LocalWorldAligned)?,
            velocity(ReferenceFrame::Local)?,
        );
        let mug_joint = attached
            .model()
            .joint_id(MUG_JOINT)
            .map_err(|e| Error::InvalidModel(e.to_string()))?;
        Ok(Self {
            step,
            flight_manifold: flight.clone(),
            attached,
            flight,
            mug_world,
            mug_local,
            mug_joint,
        })
    }

    fn create_map_ws(&self) -> MapWs {
        let ndx = self.flight.ndx();
        MapWs {
            world: self.mug_world.create_data(),
            local: self.mug_local.create_data(),
            data: self.attached.model().create_data(),
            dphi: Mat::zeros(ndx, ndx),
            q_base: vec![0.0; self.flight.nq()],
            delta: vec![0.0; self.flight.nv()],
        }
    }

    /// `φ(y)` into `out`.
    fn write_release(&self, y: &[f64], ws: &mut MapWs, out: &mut [f64]) -> Result<()> {
        let (nq, nv) = (self.attached.nq(), self.attached.nv());
        let model = self.attached.model();
        let mb = |e: gharial_multibody::Error| Error::InvalidModel(format!("ur10-ballistic release: {e}"));
        forward_kinematics_placements(model, &mut ws.data, &y[..nq]).map_err(mb)?;
        let o_m = ws.data.joint_placement(self.mug_joint);
        ws.q_base[..NA].copy_from_slice(&y[..NA]);
        ws.q_base[NA..].copy_from_slice(&rest_pose());
        ws.delta[..NA].fill(0.0);
        ws.delta[NA..NA + 3].copy_from_slice(o_m.translation.as_slice());
        ws.delta[NA + 3..].copy_from_slice(log3(&o_m.rotation).as_slice());
        integrate(self.flight.model(), &ws.q_base, &ws.delta, &mut out[..nq]).map_err(mb)?;
        self.mug_world.evaluate(y, &[], &mut ws.world);
        self.mug_local.evaluate(y, &[], &mut ws.local);
        out[nq..nq + NA].copy_from_slice(&y[nq..nq + NA]);
        out[nq + NA..nq + NA + 3].copy_from_slice(&slice(&ws.world.value)[..3]);
        out[nq + NA + 3..nq + nv].copy_from_slice(&slice(&ws.local.value)[3..]);
        gharial::error::check_finite("ur10-ballistic release: flight state", out)
    }

    /// The flight state of an attached state (`φ`).
    fn release_state(&self, y: &[f64]) -> Result<Vec<f64>> {
        let mut out = vec![0.0; self.flight.nx()];
        self.write_release(y, &mut self.create_map_ws(), &mut out)?;
        Ok(out)
    }

    /// `dφ` at `y` into `ws.dphi`: with `J` the mug frame's Jacobian in the attached
    /// model, `δp = (R J)_lin δq`, `δθ = J_ang δq` (the flight model's tangents: world
    /// translation, body rotation) and the velocities' derivatives.
    fn write_release_jacobian(&self, y: &[f64], ws: &mut MapWs) {
        let nv = self.attached.nv();
        self.mug_world.jacobians(y, &[], &mut ws.world);
        self.mug_local.jacobians(y, &[], &mut ws.local);
        let d = &mut ws.dphi;
        d.fill(0.0);
        for i in 0..NA {
            d[(i, i)] = 1.0;
            d[(nv + i, nv + i)] = 1.0;
        }
        for r in 0..6 {
            // Linear rows from the world-aligned velocity, angular rows from the local one.
            let j = if r < 3 { &ws.world.jx } else { &ws.local.jx };
            for k in 0..nv {
                d[(NA + r, k)] = j[(r, nv + k)];
            }
            for k in 0..2 * nv {
                d[(nv + NA + r, k)] = j[(r, k)];
            }
        }
    }
}

/// The workspace of a release data.
///
/// # Panics
/// If the data was created by another model (a programming error).
fn release_ws(ws: &mut Workspace) -> &mut ReleaseWs {
    ws.downcast_mut()
        .expect("dynamics data used with a model that did not create it")
}

impl ExplicitDynamics for Release {
    fn space(&self) -> &Arc<dyn Manifold> {
        self.step.space()
    }

    fn space_next(&self) -> &Arc<dyn Manifold> {
        &self.flight_manifold
    }

    fn nu(&self) -> usize {
        self.step.nu()
    }

    fn create_workspace(&self) -> Workspace {
        Box::new(ReleaseWs {
            step: self.step.create_data(),
            y: vec![0.0; self.attached.nx()],
            map: self.create_map_ws(),
        })
    }

    fn forward(&self, x: &[f64], u: &[f64], data: &mut ExplicitDynamicsData) {
        let ws = release_ws(&mut data.ws);
        self.step.forward(x, u, &mut ws.step);
        ws.y.copy_from_slice(slice(&ws.step.xnext));
        let out = slice_mut(&mut data.xnext);
        if self.write_release(&ws.y, &mut ws.map, out).is_err() {
            out.fill(f64::NAN);
        }
    }

    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut ExplicitDynamicsData) {
        let ws = release_ws(&mut data.ws);
        self.step.jacobians(x, u, &mut ws.step);
        self.write_release_jacobian(&ws.y, &mut ws.map);
        let (dphi, jx, ju) = (ws.map.dphi.as_ref(), ws.step.jx.as_ref(), ws.step.ju.as_ref());
        matmul(data.jx.as_mut(), Accum::Replace, dphi, jx, 1.0);
        matmul(data.ju.as_mut(), Accum::Replace, dphi, ju, 1.0);
    }
}

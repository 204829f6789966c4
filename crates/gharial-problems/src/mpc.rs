//! Receding-horizon scenarios: a controller problem with its queue of stages, a plant at
//! its own rate, the MPC period, the update of time-varying references after each shift,
//! and the metrics of a closed loop; run by `gharial simulate NAME`.
//!
//! | name | problem | plant | MPC period |
//! |---|---|---|---|
//! | `ur5-circle-mpc`, `ur5-circle-mpc-joint-bound`, `ur5-circle-mpc-half-space` | [`crate::ur5_circle`] | UR5 ABA, semi-implicit Euler at 1 ms | 50 ms (one node) |
//! | `solo-walk-mpc`, `solo-walk-mpc-slope` | [`crate::solo_walk`] | Solo-12 contact dynamics of the gait's stance feet, semi-implicit Euler at 1 ms | 12 ms (one node) |
//!
//! **Settings** ([`ScenarioSettings`], [`scenario_with`]): the walking scenarios' slope and
//! speed; **model mismatch** ([`Mismatch`]): the plant may carry a payload
//! the controller does not know of, a point mass on the Solo-12's base at its centre of
//! mass or at the UR5's tool frame. **Pushes** ([`MpcScenario::push_base`]): a change
//! of a floating base's linear velocity at a given time.

use gharial::mpc::{ClosedLoop, Mpc, MpcOptions, Plant, Push, Record, simulate};
use gharial::problem::StageModel;
use gharial::solvers::proxddp::{DynamicsStep, ProxDdpOptions};
use gharial::solvers::{InitialGuess, Solver};
use gharial::{Error, Result};

use gharial_multibody::Model;
use gharial_multibody::spatial::{Inertia, Mat3, Vec3};

use crate::Example;

/// Longest simulated time of a scenario (s): the record keeps every plant state.
pub const MAX_DURATION: f64 = 5000.0;
/// Largest ground tilt of the Solo-12 walking scenarios (rad, either sign).
pub const MAX_SLOPE: f64 = 0.3;
/// Largest forward velocity command of the Solo-12 walking scenarios (m/s, either sign).
pub const MAX_SPEED: f64 = 1.0;
/// Heaviest unmodelled payload (kg).
pub const MAX_PAYLOAD: f64 = 100.0;
/// Largest change of a base velocity component by a push (m/s, either sign).
pub const MAX_PUSH: f64 = 10.0;

/// The per-cycle wall-time budget of `ms` milliseconds (`inf`: none), for
/// [`MpcOptions::max_time`].
///
/// # Errors
/// As [`gharial::error::time_budget`], naming `cycle_budget`.
pub fn cycle_budget_ms(ms: f64) -> Result<Option<std::time::Duration>> {
    gharial::error::time_budget("cycle_budget", ms * 1e-3).map_err(|_| {
        Error::option(
            "cycle_budget",
            format!(
                "must be a positive number of milliseconds (inf: no budget), got {}",
                gharial::error::Num(ms)
            ),
        )
    })
}

/// Fails unless `v` is finite and at most `max` in magnitude.
fn check_within(name: &str, v: f64, max: f64, unit: &str) -> Result<()> {
    if v.is_finite() && v.abs() <= max {
        return Ok(());
    }
    Err(Error::option(
        name,
        format!("must be a finite number within ±{max} {unit}, got {v}"),
    ))
}

/// Differences between the plant and the controller's model (module documentation).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[non_exhaustive]
pub struct Mismatch {
    /// Mass (kg) of a payload the plant carries and the controller does not model: on the
    /// Solo-12's base at its centre of mass, at the UR5's tool frame.
    pub payload: f64,
}

impl Mismatch {
    /// A payload of `mass` kg.
    pub fn payload(mass: f64) -> Self {
        Self { payload: mass }
    }

    /// Fails unless the payload is finite, non-negative and at most [`MAX_PAYLOAD`].
    pub(crate) fn check(&self) -> Result<()> {
        if self.payload.is_finite() && (0.0..=MAX_PAYLOAD).contains(&self.payload) {
            Ok(())
        } else {
            Err(Error::option(
                "payload",
                format!(
                    "must be finite, non-negative and at most {MAX_PAYLOAD} kg, got {}",
                    self.payload
                ),
            ))
        }
    }
}

/// `model` with a point mass `mass` added to the body of `joint` at `at` (joint frame).
pub(crate) fn with_point_mass(model: &Model, joint: usize, at: Vec3, mass: f64) -> Result<Model> {
    let mut model = model.clone();
    let mut body = model.inertias()[joint];
    body += Inertia::from_com(mass, at, Mat3::zeros());
    model
        .set_inertia(joint, body)
        .map_err(|e| Error::InvalidModel(format!("payload: {e}")))?;
    Ok(model)
}

/// A named quantity of a closed loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Metric {
    /// Name (a word or two).
    pub name: &'static str,
    /// Value.
    pub value: f64,
    /// Unit (`m`, `rad`, ...).
    pub unit: &'static str,
}

/// Sets the parameters of the stage object `id` that entered the horizon at `cycle` (and
/// any other time-varying reference) from the measured state `x` of the cycle.
pub type OnShift = Box<dyn FnMut(usize, usize, &[f64]) -> Result<()> + Send>;
/// The metrics of a recorded closed loop.
pub type Metrics = Box<dyn Fn(&Record) -> Result<Vec<Metric>> + Send>;

/// A receding-horizon scenario (module documentation).
pub struct MpcScenario {
    /// Scenario name.
    pub name: &'static str,
    /// The controller's problem over the first horizon, its initial guess and settings.
    pub example: Example,
    /// Stages queued to enter the horizon (empty: the horizon rotates).
    pub queue: Vec<StageModel>,
    /// The plant, one step of `plant_dt`.
    pub plant: Box<dyn Plant>,
    /// The plant's step (s).
    pub plant_dt: f64,
    /// Plant steps per MPC cycle (the stages' time step over `plant_dt`).
    pub steps_per_cycle: usize,
    /// The per-cycle budget.
    pub options: MpcOptions,
    /// Called after every shift with the cycle and the number of the stage object that
    /// entered (see `Mpc::shift`): moves its time-varying references.
    pub on_shift: OnShift,
    /// The metrics of a closed loop.
    pub metrics: Metrics,
    /// Index in the plant's tangent space of the floating base's linear velocity (`None`
    /// for a fixed base): where [`MpcScenario::push_base`] kicks.
    pub base_velocity: Option<usize>,
    /// Kicks of the plant's state during [`MpcScenario::run`].
    pub pushes: Vec<Push>,
}

impl std::fmt::Debug for MpcScenario {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MpcScenario")
            .field("name", &self.name)
            .field("horizon", &self.example.problem.horizon())
            .field("queue", &self.queue.len())
            .field("plant_dt", &self.plant_dt)
            .field("steps_per_cycle", &self.steps_per_cycle)
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

impl MpcScenario {
    /// The controller of the scenario with `solver` (its limits are set from
    /// [`MpcScenario::options`]).
    ///
    /// # Errors
    /// As [`Mpc::new`].
    pub fn controller<S: Solver>(&self, solver: S) -> Result<Mpc<S>> {
        let ex = &self.example;
        let guess = InitialGuess::primal(&ex.xs0, &ex.us0);
        Mpc::new(ex.problem.clone(), solver, self.queue.clone(), guess, self.options)
    }

    /// Runs `mpc` (from [`MpcScenario::controller`]) in closed loop for `duration`
    /// seconds from the problem's initial state.
    ///
    /// # Errors
    /// As [`simulate()`], or if `duration` is not finite or shorter than half a plant
    /// step (no step to simulate).
    pub fn run<S: Solver>(&mut self, mpc: &mut Mpc<S>, duration: f64) -> Result<Record> {
        self.check_duration(duration)?;
        let x0 = self
            .example
            .problem
            .x0()
            .ok_or_else(|| Error::InvalidModel("a scenario needs a fixed initial state".into()))?
            .to_vec();
        let steps = (duration / self.plant_dt).round() as usize;
        let mut settings = ClosedLoop::new(steps, self.steps_per_cycle);
        settings.pushes.clone_from(&self.pushes);
        simulate(mpc, self.plant.as_mut(), &x0, &settings, &mut self.on_shift)
    }

    /// Checks a duration for [`MpcScenario::run`].
    ///
    /// # Errors
    /// If `duration` is not finite, shorter than half a plant step (no step to
    /// simulate) or longer than [`MAX_DURATION`].
    pub fn check_duration(&self, duration: f64) -> Result<()> {
        if duration.is_finite() && duration >= 0.5 * self.plant_dt && duration <= MAX_DURATION {
            return Ok(());
        }
        Err(Error::option(
            "duration",
            format!(
                "must be finite, at least one plant step ({} s) and at most {MAX_DURATION} s, got {duration}",
                self.plant_dt
            ),
        ))
    }

    /// Adds a push at time `time` (s) that changes the floating base's linear velocity by
    /// `dv` (m/s, in the base frame, as the state's velocity).
    ///
    /// # Errors
    /// If the plant has no floating base, `time` is not finite or negative, or a
    /// component of `dv` is not finite or larger than [`MAX_PUSH`] in magnitude.
    pub fn push_base(&mut self, time: f64, dv: [f64; 3]) -> Result<()> {
        let i = self.base_velocity.ok_or_else(|| {
            Error::InvalidModel(format!(
                "scenario {}: the robot has no floating base to push",
                self.name
            ))
        })?;
        if !(time.is_finite() && time >= 0.0) {
            return Err(Error::option(
                "push time",
                format!("must be finite and non-negative, got {time}"),
            ));
        }
        for v in dv {
            check_within("push velocity", v, MAX_PUSH, "m/s")?;
        }
        let mut dx = vec![0.0; self.plant.space().ndx()];
        dx[i..i + 3].copy_from_slice(&dv);
        let step = (time / self.plant_dt).round() as usize;
        self.pushes.push(Push { step, dx });
        Ok(())
    }

    /// The scenario's metrics of a closed loop it ran.
    ///
    /// # Errors
    /// If a metric cannot be evaluated at a recorded state.
    pub fn metrics(&self, record: &Record) -> Result<Vec<Metric>> {
        (self.metrics)(record)
    }
}

/// The scenarios: name and one-line summary.
pub static SCENARIOS: &[(&str, &str)] = &[
    (
        "ur5-circle-mpc",
        "UR5 tracking a 0.3 m circle with its tool (SQP paper's circle task): 50 ms nodes, 10-node horizon",
    ),
    (
        "ur5-circle-mpc-joint-bound",
        "ur5-circle-mpc with |q_1| <= 0.05 rad on the shoulder pan",
    ),
    (
        "ur5-circle-mpc-half-space",
        "ur5-circle-mpc with the tool kept in the half-space y <= c_y + r/2",
    ),
    (
        "solo-walk-mpc",
        "Solo-12 trot at 0.2 m/s (ProxDDP paper, Fig. 16): 12 ms nodes, 40-node horizon, one ProxDDP iteration per cycle",
    ),
    (
        "solo-walk-mpc-slope",
        "solo-walk-mpc on ground tilted by 0.1 rad about y, unknown to the controller",
    ),
];

/// The ProxDDP settings of a scenario's MPC cycles: `options` with the exact dynamics
/// step ([`DynamicsStep::Exact`]). With constraints the catalogue's problems take the
/// proximal step, whose `(I + mu_d P')⁻¹ P'` per stage the exact step skips (a fifth of a
/// Solo-12 trot cycle, a fifth to a third of a constrained UR5 circle cycle); with the
/// gaps of the previous cycle's step about closed the two steps differ by terms of order
/// `mu_d`, and the scenarios' closed-loop metrics agree to the fourth printed digit.
pub fn cycle_proxddp_options(options: ProxDdpOptions) -> ProxDdpOptions {
    options.with(|o| o.dynamics_step = DynamicsStep::Exact)
}

/// The scenario called `name` (see [`SCENARIOS`]).
///
/// # Errors
/// If the name is unknown (the message lists the known ones).
pub fn scenario(name: &str) -> Result<MpcScenario> {
    scenario_with(name, &ScenarioSettings::default())
}

/// The parameters of a scenario beyond its name.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[non_exhaustive]
pub struct ScenarioSettings {
    /// Solo-12 walking only: the ground's tilt about y (rad; default: the scenario's).
    pub slope: Option<f64>,
    /// Solo-12 walking only: the forward velocity command (m/s; default the scenario's).
    pub speed: Option<f64>,
    /// How the plant differs from the controller's model.
    pub mismatch: Mismatch,
}

/// The scenario called `name` with `settings`.
///
/// # Errors
/// If the name is unknown (the message lists the known ones), a walking parameter is
/// given for another scenario, or a setting is invalid or outside its limit
/// ([`MAX_SLOPE`], [`MAX_SPEED`], [`MAX_PAYLOAD`]).
pub fn scenario_with(name: &str, settings: &ScenarioSettings) -> Result<MpcScenario> {
    if let Some(s) = settings.slope {
        check_within("slope", s, MAX_SLOPE, "rad")?;
    }
    if let Some(v) = settings.speed {
        check_within("speed", v, MAX_SPEED, "m/s")?;
    }
    settings.mismatch.check()?;
    use crate::solo_walk::{COMMAND, SLOPE, scenario_with as walk};
    use crate::ur5_circle::{CircleVariant, scenario_with as circle};
    let mismatch = settings.mismatch;
    let walking = |default_slope: f64| {
        let command = [settings.speed.unwrap_or(COMMAND[0]), COMMAND[1]];
        walk(settings.slope.unwrap_or(default_slope), command, mismatch)
    };
    let circle_variant = match name {
        "ur5-circle-mpc" => Some(CircleVariant::Free),
        "ur5-circle-mpc-joint-bound" => Some(CircleVariant::JointBound),
        "ur5-circle-mpc-half-space" => Some(CircleVariant::HalfSpace),
        _ => None,
    };
    if let Some(variant) = circle_variant {
        if settings.slope.is_some() || settings.speed.is_some() {
            return Err(Error::InvalidModel(format!(
                "slope and speed are parameters of solo-walk-mpc, not of {name}"
            )));
        }
        return circle(variant, mismatch);
    }
    match name {
        "solo-walk-mpc" => walking(0.0),
        "solo-walk-mpc-slope" => walking(SLOPE),
        _ => Err(Error::InvalidModel(format!(
            "unknown MPC scenario `{name}` (known: {})",
            SCENARIOS.iter().map(|s| s.0).collect::<Vec<_>>().join(", ")
        ))),
    }
}

#[cfg(test)]
mod tests {
    use gharial_multibody::{Model, RootJoint, center_of_mass, forward_kinematics_placements, update_frame_placements};

    use super::{Mismatch, with_point_mass};
    use crate::robots::UR5_URDF;

    /// A payload at the UR5's tool frame adds its mass and moves the centre of mass to
    /// the mass-weighted mean of the arm's and the tool frame's positions (forward
    /// kinematics), at any configuration.
    #[test]
    fn a_point_mass_moves_the_centre_of_mass_to_the_weighted_mean() {
        let model = Model::from_urdf_str(UR5_URDF, RootJoint::Fixed).unwrap();
        let tool_id = model.frame_id("tool0").unwrap();
        let tool = &model.frames()[tool_id];
        let (joint, at) = (tool.parent_joint, tool.placement.translation);
        let m = 1.7;
        let loaded = with_point_mass(&model, joint, at, m).unwrap();
        // The moving bodies' mass (the centre of mass leaves out the bodies fixed to the
        // world, as Pinocchio's).
        let mass = |md: &Model| md.inertias()[1..].iter().map(|y| y.mass).sum::<f64>();
        assert!((mass(&loaded) - mass(&model) - m).abs() < 1e-12);
        let zero = vec![0.0; model.nv()];
        for q in [[0.0; 6], [0.3, -1.1, 0.7, 2.0, -0.4, 1.3]] {
            let mut data = model.create_data();
            let c = *center_of_mass(&model, &mut data, &q, &zero, &zero).unwrap();
            forward_kinematics_placements(&model, &mut data, &q).unwrap();
            update_frame_placements(&model, &mut data).unwrap();
            let p = data.frame_placement(tool_id).translation;
            let expected = (c * mass(&model) + p * m) / (mass(&model) + m);
            let mut data = loaded.create_data();
            let c_loaded = *center_of_mass(&loaded, &mut data, &q, &zero, &zero).unwrap();
            assert!(
                (c_loaded - expected).norm() < 1e-12,
                "{q:?}: {c_loaded:?} vs {expected:?}"
            );
        }
    }

    #[test]
    fn a_negative_or_non_finite_payload_is_an_error() {
        for m in [-1.0, f64::NAN, f64::INFINITY] {
            let e = Mismatch::payload(m).check().unwrap_err().to_string();
            assert!(e.contains("payload"), "{e}");
        }
        assert!(Mismatch::payload(0.0).check().is_ok());
    }
}

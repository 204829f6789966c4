//! Receding-horizon scenarios: a controller problem with its queue of stages, a plant at
//! its own rate, the MPC period, the update of time-varying references after each shift,
//! and the metrics of a closed loop; run by `gharial simulate NAME`.
//!
//! | name | problem | plant | MPC period |
//! |---|---|---|---|
//! | `ur5-circle-mpc`, `ur5-circle-mpc-joint-bound`, `ur5-circle-mpc-half-space` | [`crate::ur5_circle`] | UR5 ABA, semi-implicit Euler at 1 ms | 50 ms (one node) |
//! | `solo-walk-mpc`, `solo-walk-mpc-slope` | [`crate::solo_walk`] | Solo-12 contact dynamics of the gait's stance feet, semi-implicit Euler at 1 ms | 12 ms (one node) |

use gharial::mpc::{ClosedLoop, Mpc, MpcOptions, Plant, Record, simulate};
use gharial::problem::StageModel;
use gharial::solvers::{InitialGuess, Solver};
use gharial::{Error, Result};

use crate::Example;

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
    /// As [`simulate()`], or if `duration` is not finite and non-negative.
    pub fn run<S: Solver>(&mut self, mpc: &mut Mpc<S>, duration: f64) -> Result<Record> {
        if !(duration.is_finite() && duration >= 0.0) {
            return Err(Error::option("duration", "must be finite and non-negative"));
        }
        let x0 = self
            .example
            .problem
            .x0()
            .ok_or_else(|| Error::InvalidModel("a scenario needs a fixed initial state".into()))?
            .to_vec();
        let steps = (duration / self.plant_dt).round() as usize;
        let settings = ClosedLoop::new(steps, self.steps_per_cycle);
        simulate(mpc, self.plant.as_mut(), &x0, &settings, &mut self.on_shift)
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

/// The scenario called `name` (see [`SCENARIOS`]).
///
/// # Errors
/// If the name is unknown (the message lists the known ones).
pub fn scenario(name: &str) -> Result<MpcScenario> {
    use crate::ur5_circle::{CircleVariant, scenario as circle};
    match name {
        "ur5-circle-mpc" => circle(CircleVariant::Free),
        "ur5-circle-mpc-joint-bound" => circle(CircleVariant::JointBound),
        "ur5-circle-mpc-half-space" => circle(CircleVariant::HalfSpace),
        "solo-walk-mpc" => crate::solo_walk::scenario(0.0, crate::solo_walk::COMMAND),
        "solo-walk-mpc-slope" => crate::solo_walk::scenario(crate::solo_walk::SLOPE, crate::solo_walk::COMMAND),
        _ => Err(Error::InvalidModel(format!(
            "unknown MPC scenario `{name}` (known: {})",
            SCENARIOS.iter().map(|s| s.0).collect::<Vec<_>>().join(", ")
        ))),
    }
}

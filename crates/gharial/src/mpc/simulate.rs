//! Closed-loop simulation: a plant (a discrete model at the simulation rate, e.g. RK4 of
//! a robot's dynamics at 1 ms, possibly another model than the controller's) driven by
//! the feedback policy at every step and by an MPC cycle every `steps_per_cycle` steps,
//! with optional pushes; everything recorded, nothing allocated after the start.

use std::sync::Arc;
use std::time::Duration;

use super::Mpc;
use crate::dynamics::{ExplicitDynamics, ExplicitDynamicsData};
use crate::error::{Error, Result, check_dim, check_finite};
use crate::solvers::{Solver, Status};
use crate::spaces::Manifold;

/// The simulated system, stepped at its own rate.
pub trait Plant: Send {
    /// The plant's state space.
    fn space(&self) -> &Arc<dyn Manifold>;
    /// Control size.
    fn nu(&self) -> usize;
    /// Writes into `next` the state one plant step after `x` under `u`; `step` is the
    /// step's number, for plants that change with time (contact phases, terrain).
    ///
    /// # Errors
    /// If the plant cannot step (e.g. a singular contact problem).
    fn step(&mut self, step: usize, x: &[f64], u: &[f64], next: &mut [f64]) -> Result<()>;
}

/// A discrete model (e.g. an integrator of a robot's dynamics at 1 ms) as a plant.
pub struct DiscretePlant {
    dynamics: Arc<dyn ExplicitDynamics>,
    data: ExplicitDynamicsData,
}

impl std::fmt::Debug for DiscretePlant {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DiscretePlant")
            .field("nx", &self.dynamics.space().nx())
            .field("nu", &self.dynamics.nu())
            .finish()
    }
}

impl DiscretePlant {
    /// The plant stepping `dynamics` (data allocated here).
    pub fn new(dynamics: Arc<dyn ExplicitDynamics>) -> Self {
        Self {
            data: dynamics.create_data(),
            dynamics,
        }
    }
}

impl Plant for DiscretePlant {
    fn space(&self) -> &Arc<dyn Manifold> {
        self.dynamics.space()
    }
    fn nu(&self) -> usize {
        self.dynamics.nu()
    }
    fn step(&mut self, _step: usize, x: &[f64], u: &[f64], next: &mut [f64]) -> Result<()> {
        self.dynamics.forward(x, u, &mut self.data);
        next.copy_from_slice(crate::linalg::slice(&self.data.xnext));
        Ok(())
    }
}

/// A velocity (tangent) kick applied to the plant's state before a step.
#[derive(Debug, Clone, PartialEq)]
pub struct Push {
    /// The plant step before which it applies.
    pub step: usize,
    /// `x ← x ⊕ dx` (`ndx`).
    pub dx: Vec<f64>,
}

/// What to simulate.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct ClosedLoop {
    /// Plant steps to simulate.
    pub steps: usize,
    /// Plant steps per MPC cycle (the MPC period divided by the plant step; the horizon
    /// shifts by one stage per cycle, so the period is the stages' time step).
    pub steps_per_cycle: usize,
    /// Kicks of the plant's state.
    pub pushes: Vec<Push>,
}

impl ClosedLoop {
    /// `steps` plant steps with an MPC cycle every `steps_per_cycle`, no push.
    pub fn new(steps: usize, steps_per_cycle: usize) -> Self {
        Self {
            steps,
            steps_per_cycle,
            pushes: Vec::new(),
        }
    }
}

/// One MPC cycle of a simulation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleRecord {
    /// The plant step at which the cycle ran.
    pub step: usize,
    /// Wall time of the solve.
    pub solve_time: Duration,
    /// Solver iterations.
    pub iterations: usize,
    /// How the solve stopped.
    pub status: Status,
    /// Cost of the plan.
    pub cost: f64,
    /// Primal and dual residuals of the plan.
    pub prim_err: f64,
    /// Dual residual of the plan.
    pub dual_err: f64,
}

/// Why and where a closed loop stopped before its last step.
#[derive(Debug, Clone, PartialEq)]
pub struct Stopped {
    /// The plant step that could not be completed (`xs` holds the states up to it).
    pub step: usize,
    /// The error that stopped the loop (an MPC cycle, `on_shift`, or the plant: a step
    /// it could not take, a non-finite state).
    pub reason: String,
}

/// The recorded closed loop: plant states `xs[0..=steps]`, applied controls
/// `us[0..steps]`, and one record per MPC cycle; a loop that stopped early
/// ([`Record::stopped`]) holds the steps done.
#[derive(Debug, Clone, Default)]
pub struct Record {
    /// Plant states, one per step and the last.
    pub xs: Vec<Vec<f64>>,
    /// Controls applied at each step.
    pub us: Vec<Vec<f64>>,
    /// The MPC cycles.
    pub cycles: Vec<CycleRecord>,
    /// `Some` if the loop stopped before its last step.
    pub stopped: Option<Stopped>,
}

impl Record {
    /// Solve times of the cycles, sorted (for medians and percentiles).
    pub fn sorted_solve_times(&self) -> Vec<Duration> {
        let mut t: Vec<Duration> = self.cycles.iter().map(|c| c.solve_time).collect();
        t.sort();
        t
    }
}

/// Runs `mpc` in closed loop with `plant` from `x0` (module documentation). After every
/// cycle's shift, `on_shift(cycle, stage_id, x)` may set the parameters of the stage
/// object that entered the horizon (see [`Mpc::shift`]), or any time-varying reference,
/// from the measured state `x` the cycle's solve starts from (a terrain estimate, say).
/// The record is allocated before the first step; the loop allocates nothing more.
///
/// When an MPC call, `on_shift` or a plant step fails at step `k`, or the plant's state
/// becomes non-finite, the loop stops there: the record holds the states `xs[0..=k]`, the
/// controls `us[0..k]` and the cycles run, and [`Record::stopped`] says why (a diverging
/// closed loop ends this way, with its history).
///
/// # Errors
/// If the plant does not fit the controller's state and control sizes, `x0` or a push is
/// malformed, or `steps_per_cycle` is 0.
pub fn simulate<S: Solver>(
    mpc: &mut Mpc<S>,
    plant: &mut dyn Plant,
    x0: &[f64],
    settings: &ClosedLoop,
    mut on_shift: impl FnMut(usize, usize, &[f64]) -> Result<()>,
) -> Result<Record> {
    check_closed_loop(mpc, plant, x0, settings)?;
    let space = plant.space().clone();
    let (nx, nu, steps) = (space.nx(), plant.nu(), settings.steps);
    let mut rec = Record {
        xs: vec![vec![0.0; nx]; steps + 1],
        us: vec![vec![0.0; nu]; steps],
        cycles: Vec::with_capacity(steps.div_ceil(settings.steps_per_cycle)),
        stopped: None,
    };
    rec.xs[0].copy_from_slice(x0);
    let mut kicked = vec![0.0; nx];
    for k in 0..steps {
        let mut step = || -> Result<()> {
            if k % settings.steps_per_cycle == 0 {
                if k > 0 {
                    let id = mpc.shift()?;
                    on_shift(rec.cycles.len(), id, &rec.xs[k])?;
                }
                let sol = mpc.solve(&rec.xs[k])?;
                rec.cycles.push(CycleRecord {
                    step: k,
                    solve_time: sol.solve_time,
                    iterations: sol.iterations,
                    status: sol.status,
                    cost: sol.cost,
                    prim_err: sol.prim_err,
                    dual_err: sol.dual_err,
                });
            }
            let (done, next) = rec.xs.split_at_mut(k + 1);
            let x = &mut done[k];
            for p in settings.pushes.iter().filter(|p| p.step == k) {
                space.integrate(x, &p.dx, &mut kicked);
                x.copy_from_slice(&kicked);
            }
            mpc.control(x, &mut rec.us[k])?;
            plant.step(k, x, &rec.us[k], &mut next[0])?;
            check_finite(format_args!("simulate: plant state after step {k}"), &next[0])
        };
        if let Err(e) = step() {
            rec.xs.truncate(k + 1);
            rec.us.truncate(k);
            rec.stopped = Some(Stopped {
                step: k,
                reason: e.to_string(),
            });
            break;
        }
    }
    Ok(rec)
}

/// The checks of [`simulate`]'s inputs.
fn check_closed_loop<S: Solver>(mpc: &Mpc<S>, plant: &dyn Plant, x0: &[f64], settings: &ClosedLoop) -> Result<()> {
    let space = plant.space();
    let (nx, ndx, nu) = (space.nx(), space.ndx(), plant.nu());
    let s0 = mpc.problem().space(0);
    check_dim("simulate: plant state size nx", s0.nx(), nx)?;
    check_dim("simulate: plant state tangent size ndx", s0.ndx(), ndx)?;
    check_dim("simulate: plant control size nu", mpc.problem().nu(0), nu)?;
    check_dim("simulate: x0", nx, x0.len())?;
    check_finite("simulate: x0", x0)?;
    if settings.steps_per_cycle == 0 {
        return Err(Error::option("steps_per_cycle", "must be at least 1"));
    }
    for p in &settings.pushes {
        check_dim(format_args!("simulate: push at step {}", p.step), ndx, p.dx.len())?;
        check_finite(format_args!("simulate: push at step {}", p.step), &p.dx)?;
    }
    Ok(())
}

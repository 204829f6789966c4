//! Solver options as Python attributes: every field of the Rust options structs by name.

use std::time::Duration;

use gharial::nlp::{KktSolver, ProxNlpOptions};
use gharial::solvers::altro::AltroOptions;
use gharial::solvers::bcl_ddp::{BclDdpOptions, Multipliers, PenaltyUpdate, Schedule};
use gharial::solvers::csqp::CsqpOptions;
use gharial::solvers::ddp::DdpOptions;
use gharial::solvers::proxddp::{DynamicsStep, Merit, ProxDdpOptions, Rollout, StepAcceptance};
use gharial::solvers::{HessianApprox, SolverOptions};
use pyo3::IntoPyObjectExt;
use pyo3::prelude::*;

use crate::convert::{err, value_error};

/// A solver's options from `SolverOptions::from_name` or `Example::options`; an unknown
/// solver name is a `ValueError` whose message is the core's reason ("unknown solver
/// `x` (one of ...)").
pub fn solver_options(options: gharial::Result<SolverOptions>) -> PyResult<SolverOptions> {
    options.map_err(|e| match e {
        gharial::Error::InvalidOption { reason, .. } => value_error(reason),
        e => err(e),
    })
}

/// The option `name` of `options`, if the solver has it.
pub fn field<'a>(options: &'a mut SolverOptions, name: &str) -> Option<Field<'a>> {
    match options {
        SolverOptions::ProxDdp(o) => proxddp_field(o, name),
        SolverOptions::Ddp(o) => ddp_field(o, name),
        SolverOptions::Csqp(o) => csqp_field(o, name),
        SolverOptions::BclDdp(o) => bcl_ddp_field(o, name),
        SolverOptions::Altro(o) => altro_field(o, name),
        SolverOptions::ProxNlp(o) => proxnlp_field(o, name),
        _ => None,
    }
}

/// Every option name of the solver of `options`.
pub fn option_names(options: &SolverOptions) -> &'static [&'static str] {
    match options {
        SolverOptions::ProxDdp(_) => PROXDDP,
        SolverOptions::Ddp(_) => DDP,
        SolverOptions::Csqp(_) => CSQP,
        SolverOptions::BclDdp(_) => BCL_DDP,
        SolverOptions::Altro(_) => ALTRO,
        SolverOptions::ProxNlp(_) => PROXNLP,
        _ => &[],
    }
}

/// A mutable reference to one option.
pub enum Field<'a> {
    /// A real number.
    F64(&'a mut f64),
    /// A count.
    Usize(&'a mut usize),
    /// A flag.
    Bool(&'a mut bool),
    /// An optional real number (`None` in Python).
    OptF64(&'a mut Option<f64>),
    /// A wall-time budget in seconds (`None`: no budget).
    Time(&'a mut Option<Duration>),
    /// ProxDDP's rollout.
    Rollout(&'a mut Rollout),
    /// ProxDDP's step acceptance.
    Acceptance(&'a mut StepAcceptance),
    /// ProxDDP's merit function.
    Merit(&'a mut Merit),
    /// ProxDDP's treatment of the dynamics in the Newton step.
    DynamicsStep(&'a mut DynamicsStep),
    /// The Hessian approximation.
    Hessian(&'a mut HessianApprox),
    /// BCL-DDP's multipliers.
    Multipliers(&'a mut Multipliers),
    /// BCL-DDP's penalty update.
    Penalty(&'a mut PenaltyUpdate),
    /// BCL-DDP's schedule.
    Schedule(&'a mut Schedule),
    /// ProxNLP's Newton-system solve.
    Kkt(&'a mut KktSolver),
}

const PROXDDP: &[&str] = &[
    "tol",
    "mu_init",
    "mu_update_factor",
    "mu_lower_bound",
    "dyn_al_scale",
    "bcl_alpha_omega",
    "bcl_alpha_eta",
    "bcl_beta_omega",
    "bcl_beta_eta",
    "max_iters",
    "max_al_iters",
    "rollout",
    "step_acceptance",
    "merit",
    "dynamics_step",
    "hessian",
    "ls_c1",
    "ls_alpha_min",
    "ls_max_trials",
    "nonmonotone_eta",
    "preg_min",
    "preg_max",
    "preg_increase",
    "preg_decrease",
    "implicit_newton_iters",
    "implicit_newton_tol",
    "dphi_thresh",
    "watchdog_trigger",
    "watchdog_trials",
    "active_set_iters",
    "max_time",
    "num_threads",
    "final_residuals",
];

fn proxddp_field<'a>(o: &'a mut ProxDdpOptions, name: &str) -> Option<Field<'a>> {
    Some(match name {
        "tol" => Field::F64(&mut o.tol),
        "mu_init" => Field::F64(&mut o.mu_init),
        "mu_update_factor" => Field::F64(&mut o.mu_update_factor),
        "mu_lower_bound" => Field::F64(&mut o.mu_lower_bound),
        "dyn_al_scale" => Field::F64(&mut o.dyn_al_scale),
        "bcl_alpha_omega" => Field::F64(&mut o.bcl_alpha_omega),
        "bcl_alpha_eta" => Field::F64(&mut o.bcl_alpha_eta),
        "bcl_beta_omega" => Field::F64(&mut o.bcl_beta_omega),
        "bcl_beta_eta" => Field::F64(&mut o.bcl_beta_eta),
        "max_iters" => Field::Usize(&mut o.max_iters),
        "max_al_iters" => Field::Usize(&mut o.max_al_iters),
        "rollout" => Field::Rollout(&mut o.rollout),
        "step_acceptance" => Field::Acceptance(&mut o.step_acceptance),
        "merit" => Field::Merit(&mut o.merit),
        "dynamics_step" => Field::DynamicsStep(&mut o.dynamics_step),
        "hessian" => Field::Hessian(&mut o.hessian),
        "ls_c1" => Field::F64(&mut o.linesearch.c1),
        "ls_alpha_min" => Field::F64(&mut o.linesearch.alpha_min),
        "ls_max_trials" => Field::Usize(&mut o.linesearch.max_trials),
        "nonmonotone_eta" => Field::F64(&mut o.nonmonotone_eta),
        "preg_min" => Field::F64(&mut o.preg_min),
        "preg_max" => Field::F64(&mut o.preg_max),
        "preg_increase" => Field::F64(&mut o.preg_increase),
        "preg_decrease" => Field::F64(&mut o.preg_decrease),
        "implicit_newton_iters" => Field::Usize(&mut o.implicit_newton_iters),
        "implicit_newton_tol" => Field::F64(&mut o.implicit_newton_tol),
        "dphi_thresh" => Field::F64(&mut o.dphi_thresh),
        "watchdog_trigger" => Field::Usize(&mut o.watchdog_trigger),
        "watchdog_trials" => Field::Usize(&mut o.watchdog_trials),
        "active_set_iters" => Field::Usize(&mut o.active_set_iters),
        "max_time" => Field::Time(&mut o.max_time),
        "num_threads" => Field::Usize(&mut o.num_threads),
        "final_residuals" => Field::Bool(&mut o.final_residuals),
        _ => return None,
    })
}

const DDP: &[&str] = &[
    "tol",
    "th_stop",
    "max_iters",
    "hessian",
    "reg_init",
    "reg_min",
    "reg_max",
    "reg_converged",
    "reg_increase",
    "reg_decrease",
    "step_decrease_reg",
    "step_increase_reg",
    "linesearch_steps",
    "th_accept",
    "th_accept_neg",
    "th_grad",
    "gap_tol",
    "filter_size",
    "filter_linesearch",
    "box_qp_max_iters",
    "implicit_newton_iters",
    "implicit_newton_tol",
    "max_time",
    "num_threads",
];

fn ddp_field<'a>(o: &'a mut DdpOptions, name: &str) -> Option<Field<'a>> {
    Some(match name {
        "tol" => Field::F64(&mut o.tol),
        "th_stop" => Field::OptF64(&mut o.th_stop),
        "max_iters" => Field::Usize(&mut o.max_iters),
        "hessian" => Field::Hessian(&mut o.hessian),
        "reg_init" => Field::F64(&mut o.reg_init),
        "reg_min" => Field::F64(&mut o.reg_min),
        "reg_max" => Field::F64(&mut o.reg_max),
        "reg_converged" => Field::F64(&mut o.reg_converged),
        "reg_increase" => Field::F64(&mut o.reg_increase),
        "reg_decrease" => Field::F64(&mut o.reg_decrease),
        "step_decrease_reg" => Field::F64(&mut o.step_decrease_reg),
        "step_increase_reg" => Field::F64(&mut o.step_increase_reg),
        "linesearch_steps" => Field::Usize(&mut o.linesearch_steps),
        "th_accept" => Field::F64(&mut o.th_accept),
        "th_accept_neg" => Field::F64(&mut o.th_accept_neg),
        "th_grad" => Field::F64(&mut o.th_grad),
        "gap_tol" => Field::F64(&mut o.gap_tol),
        "filter_size" => Field::Usize(&mut o.filter_size),
        "filter_linesearch" => Field::Bool(&mut o.filter_linesearch),
        "box_qp_max_iters" => Field::Usize(&mut o.box_qp.max_iters),
        "implicit_newton_iters" => Field::Usize(&mut o.implicit.max_iters),
        "implicit_newton_tol" => Field::F64(&mut o.implicit.tol),
        "max_time" => Field::Time(&mut o.max_time),
        "num_threads" => Field::Usize(&mut o.num_threads),
        _ => return None,
    })
}

const CSQP: &[&str] = &[
    "tol",
    "max_iters",
    "rho_init",
    "admm_alpha",
    "eps_abs",
    "eps_rel",
    "max_qp_iters",
    "rho_update_interval",
    "check_interval",
    "warm_qp",
    "linesearch_steps",
    "max_linesearch_failures",
    "filter_size",
    "max_time",
    "num_threads",
];

const BCL_DDP: &[&str] = &[
    "tol",
    "max_iters",
    "mu_init",
    "mu_max",
    "eta_init",
    "omega_init",
    "bcl_alpha",
    "multipliers",
    "penalty",
    "penalty_factor",
    "adaptive_beta",
    "max_growth",
    "schedule",
    "max_time",
    "num_threads",
];

fn bcl_ddp_field<'a>(o: &'a mut BclDdpOptions, name: &str) -> Option<Field<'a>> {
    Some(match name {
        "tol" => Field::F64(&mut o.tol),
        "max_iters" => Field::Usize(&mut o.max_iters),
        "mu_init" => Field::F64(&mut o.mu_init),
        "mu_max" => Field::F64(&mut o.mu_max),
        "eta_init" => Field::F64(&mut o.eta_init),
        "omega_init" => Field::F64(&mut o.omega_init),
        "bcl_alpha" => Field::F64(&mut o.bcl_alpha),
        "multipliers" => Field::Multipliers(&mut o.multipliers),
        "penalty" => Field::Penalty(&mut o.penalty),
        "penalty_factor" => Field::F64(&mut o.penalty_factor),
        "adaptive_beta" => Field::F64(&mut o.adaptive_beta),
        "max_growth" => Field::F64(&mut o.max_growth),
        "schedule" => Field::Schedule(&mut o.schedule),
        "max_time" => Field::Time(&mut o.max_time),
        "num_threads" => Field::Usize(&mut o.ddp.num_threads),
        _ => return None,
    })
}

const ALTRO: &[&str] = &[
    "tol",
    "max_iters",
    "constraint_tolerance",
    "cost_tolerance",
    "cost_tolerance_intermediate",
    "penalty_initial",
    "penalty_scaling",
    "penalty_max",
    "dual_max",
    "iterations_outer",
    "iterations_inner",
    "square_root",
    "projected_newton",
    "projected_newton_tolerance",
    "projected_newton_steps",
    "infeasible_start",
    "slack_weight",
    "max_time",
    "num_threads",
];

fn altro_field<'a>(o: &'a mut AltroOptions, name: &str) -> Option<Field<'a>> {
    Some(match name {
        // As on the command line: the tolerance is c_max, the limit the outer iterations.
        "tol" | "constraint_tolerance" => Field::F64(&mut o.constraint_tolerance),
        "max_iters" => Field::Usize(&mut o.iterations_outer),
        "cost_tolerance" => Field::F64(&mut o.cost_tolerance),
        "cost_tolerance_intermediate" => Field::F64(&mut o.cost_tolerance_intermediate),
        "penalty_initial" => Field::F64(&mut o.penalty_initial),
        "penalty_scaling" => Field::F64(&mut o.penalty_scaling),
        "penalty_max" => Field::F64(&mut o.penalty_max),
        "dual_max" => Field::F64(&mut o.dual_max),
        "iterations_outer" => Field::Usize(&mut o.iterations_outer),
        "iterations_inner" => Field::Usize(&mut o.iterations_inner),
        "square_root" => Field::Bool(&mut o.square_root),
        "projected_newton" => Field::Bool(&mut o.projected_newton),
        "projected_newton_tolerance" => Field::F64(&mut o.projected_newton_tolerance),
        "projected_newton_steps" => Field::Usize(&mut o.projected_newton_steps),
        "infeasible_start" => Field::Bool(&mut o.infeasible_start),
        "slack_weight" => Field::F64(&mut o.slack_weight),
        "max_time" => Field::Time(&mut o.max_time),
        "num_threads" => Field::Usize(&mut o.inner.num_threads),
        _ => return None,
    })
}

const PROXNLP: &[&str] = &[
    "tol",
    "mu_init",
    "mu_update_factor",
    "mu_lower_bound",
    "dyn_al_scale",
    "bcl_alpha_omega",
    "bcl_alpha_eta",
    "bcl_beta_omega",
    "bcl_beta_eta",
    "max_iters",
    "max_al_iters",
    "step_acceptance",
    "nonmonotone_eta",
    "hessian",
    "ls_c1",
    "ls_alpha_min",
    "ls_max_trials",
    "preg_min",
    "preg_max",
    "preg_increase",
    "preg_decrease",
    "dphi_thresh",
    "max_time",
    "kkt",
];

fn proxnlp_field<'a>(o: &'a mut ProxNlpOptions, name: &str) -> Option<Field<'a>> {
    Some(match name {
        "tol" => Field::F64(&mut o.tol),
        "mu_init" => Field::F64(&mut o.mu_init),
        "mu_update_factor" => Field::F64(&mut o.mu_update_factor),
        "mu_lower_bound" => Field::F64(&mut o.mu_lower_bound),
        "dyn_al_scale" => Field::F64(&mut o.dyn_al_scale),
        "bcl_alpha_omega" => Field::F64(&mut o.bcl_alpha_omega),
        "bcl_alpha_eta" => Field::F64(&mut o.bcl_alpha_eta),
        "bcl_beta_omega" => Field::F64(&mut o.bcl_beta_omega),
        "bcl_beta_eta" => Field::F64(&mut o.bcl_beta_eta),
        "max_iters" => Field::Usize(&mut o.max_iters),
        "max_al_iters" => Field::Usize(&mut o.max_al_iters),
        "step_acceptance" => Field::Acceptance(&mut o.step_acceptance),
        "nonmonotone_eta" => Field::F64(&mut o.nonmonotone_eta),
        "hessian" => Field::Hessian(&mut o.hessian),
        "ls_c1" => Field::F64(&mut o.linesearch.c1),
        "ls_alpha_min" => Field::F64(&mut o.linesearch.alpha_min),
        "ls_max_trials" => Field::Usize(&mut o.linesearch.max_trials),
        "preg_min" => Field::F64(&mut o.preg_min),
        "preg_max" => Field::F64(&mut o.preg_max),
        "preg_increase" => Field::F64(&mut o.preg_increase),
        "preg_decrease" => Field::F64(&mut o.preg_decrease),
        "dphi_thresh" => Field::F64(&mut o.dphi_thresh),
        "max_time" => Field::Time(&mut o.max_time),
        "kkt" => Field::Kkt(&mut o.kkt),
        _ => return None,
    })
}

fn csqp_field<'a>(o: &'a mut CsqpOptions, name: &str) -> Option<Field<'a>> {
    Some(match name {
        "tol" => Field::F64(&mut o.tol),
        "max_iters" => Field::Usize(&mut o.max_iters),
        "rho_init" => Field::F64(&mut o.admm.rho_init),
        "admm_alpha" => Field::F64(&mut o.admm.alpha),
        "eps_abs" => Field::F64(&mut o.admm.eps_abs),
        "eps_rel" => Field::F64(&mut o.admm.eps_rel),
        "max_qp_iters" => Field::Usize(&mut o.admm.max_iters),
        "rho_update_interval" => Field::Usize(&mut o.admm.rho_update_interval),
        "check_interval" => Field::Usize(&mut o.admm.check_interval),
        "warm_qp" => Field::Bool(&mut o.warm_qp),
        "linesearch_steps" => Field::Usize(&mut o.linesearch_steps),
        "max_linesearch_failures" => Field::Usize(&mut o.max_linesearch_failures),
        "filter_size" => Field::Usize(&mut o.filter_size),
        "max_time" => Field::Time(&mut o.max_time),
        "num_threads" => Field::Usize(&mut o.num_threads),
        _ => return None,
    })
}

fn pick<T: Copy>(what: &str, value: &str, table: &[(&str, T)]) -> PyResult<T> {
    table.iter().find(|(n, _)| *n == value).map(|(_, v)| *v).ok_or_else(|| {
        let names: Vec<_> = table.iter().map(|(n, _)| *n).collect();
        value_error(format!("{what}: unknown value `{value}` (one of {})", names.join(", ")))
    })
}

fn name_of<T: PartialEq + Copy>(value: T, table: &[(&'static str, T)]) -> &'static str {
    table.iter().find(|(_, v)| *v == value).map_or("?", |(n, _)| n)
}

const ROLLOUTS: &[(&str, Rollout)] = &[("linear", Rollout::Linear), ("nonlinear", Rollout::Nonlinear)];
const ACCEPTANCES: &[(&str, StepAcceptance)] = &[
    ("filter", StepAcceptance::Filter),
    ("linesearch", StepAcceptance::Linesearch),
    ("nonmonotone", StepAcceptance::NonmonotoneLinesearch),
];
const MERITS: &[(&str, Merit)] = &[("primal-dual", Merit::PrimalDual), ("primal", Merit::Primal)];
const DYNAMICS_STEPS: &[(&str, DynamicsStep)] = &[
    ("auto", DynamicsStep::Auto),
    ("proximal", DynamicsStep::Proximal),
    ("exact", DynamicsStep::Exact),
];
const MULTIPLIERS: &[(&str, Multipliers)] = &[("constant", Multipliers::Constant), ("affine", Multipliers::Affine)];
const PENALTIES: &[(&str, PenaltyUpdate)] = &[("factor", PenaltyUpdate::Factor), ("adaptive", PenaltyUpdate::Adaptive)];
const SCHEDULES: &[(&str, Schedule)] = &[("bcl", Schedule::Bcl), ("every-iteration", Schedule::EveryIteration)];
const KKTS: &[(&str, KktSolver)] = &[
    ("dense", KktSolver::Dense),
    ("sparse", KktSolver::Sparse),
    ("auto", KktSolver::Auto),
];
const HESSIANS: &[(&str, HessianApprox)] = &[
    ("gauss-newton", HessianApprox::GaussNewton),
    ("exact", HessianApprox::Exact),
];

impl Field<'_> {
    /// The value as a Python object.
    pub fn get(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        match self {
            Field::F64(v) => (**v).into_py_any(py),
            Field::Usize(v) => (**v).into_py_any(py),
            Field::Bool(v) => (**v).into_py_any(py),
            Field::OptF64(v) => (**v).into_py_any(py),
            Field::Time(v) => v.map(|d| d.as_secs_f64()).into_py_any(py),
            Field::Rollout(v) => name_of(**v, ROLLOUTS).into_py_any(py),
            Field::Acceptance(v) => name_of(**v, ACCEPTANCES).into_py_any(py),
            Field::Merit(v) => name_of(**v, MERITS).into_py_any(py),
            Field::DynamicsStep(v) => name_of(**v, DYNAMICS_STEPS).into_py_any(py),
            Field::Hessian(v) => name_of(**v, HESSIANS).into_py_any(py),
            Field::Multipliers(v) => name_of(**v, MULTIPLIERS).into_py_any(py),
            Field::Penalty(v) => name_of(**v, PENALTIES).into_py_any(py),
            Field::Schedule(v) => name_of(**v, SCHEDULES).into_py_any(py),
            Field::Kkt(v) => name_of(**v, KKTS).into_py_any(py),
        }
    }

    /// Sets the value from a Python object (`name` for messages).
    pub fn set(&mut self, name: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let bad = |e: PyErr| value_error(format!("option `{name}`: {e}"));
        match self {
            Field::F64(v) => **v = value.extract().map_err(bad)?,
            Field::Usize(v) => **v = value.extract().map_err(bad)?,
            Field::Bool(v) => **v = value.extract().map_err(bad)?,
            Field::OptF64(v) => **v = value.extract().map_err(bad)?,
            Field::Time(v) => {
                let s: Option<f64> = value.extract().map_err(bad)?;
                **v = match s {
                    Some(s) => gharial::error::time_budget(name, s).map_err(|e| value_error(e.to_string()))?,
                    None => None,
                };
            }
            Field::Rollout(v) => **v = pick(name, &value.extract::<String>().map_err(bad)?, ROLLOUTS)?,
            Field::Acceptance(v) => **v = pick(name, &value.extract::<String>().map_err(bad)?, ACCEPTANCES)?,
            Field::Merit(v) => **v = pick(name, &value.extract::<String>().map_err(bad)?, MERITS)?,
            Field::DynamicsStep(v) => **v = pick(name, &value.extract::<String>().map_err(bad)?, DYNAMICS_STEPS)?,
            Field::Hessian(v) => **v = pick(name, &value.extract::<String>().map_err(bad)?, HESSIANS)?,
            Field::Multipliers(v) => **v = pick(name, &value.extract::<String>().map_err(bad)?, MULTIPLIERS)?,
            Field::Penalty(v) => **v = pick(name, &value.extract::<String>().map_err(bad)?, PENALTIES)?,
            Field::Schedule(v) => **v = pick(name, &value.extract::<String>().map_err(bad)?, SCHEDULES)?,
            Field::Kkt(v) => **v = pick(name, &value.extract::<String>().map_err(bad)?, KKTS)?,
        }
        Ok(())
    }
}

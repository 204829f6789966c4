//! The solver chosen by name and its command-line options, declared once and shared by
//! `gharial solve`, `gharial bench solve` and `gharial bench peers`.
//!
//! [`SolverArgs`] holds what the command line says: the solver's name, the options every
//! solver takes ([`CommonArgs`]) and ProxDDP's own ([`ProxDdpArgs`]). [`SolverArgs::check`]
//! refuses an option the chosen solver does not take; [`SolverArgs::config`] applies the
//! options to the solver's starting settings ([`Example::options`]: a problem's recommended
//! ProxDDP settings, the other solvers' defaults) and [`SolverConfig::options`] builds the
//! solver.

use clap::ValueEnum;
use clap::builder::PossibleValue;
use gharial::error::Num;
use gharial::nlp::ProxNlpOptions;
use gharial::solvers::altro::AltroOptions;
use gharial::solvers::bcl_ddp::{BclDdpOptions, Multipliers, PenaltyUpdate, Schedule};
use gharial::solvers::csqp::CsqpOptions;
use gharial::solvers::ddp::{DdpOptions, DdpVariant};
use gharial::solvers::log::Table;
use gharial::solvers::proxddp::{ACTIVE_SET_ITERS_MAX, DynamicsStep, Merit, ProxDdpOptions, Rollout, StepAcceptance};
use gharial::solvers::{HessianApprox, SolverOptions};
use gharial_problems::Example;
use serde_json::{Value, json};

use crate::{count, positive_int, positive_real};

/// A solver of the library, by the name the command line uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolverKind {
    /// ProxDDP.
    ProxDdp,
    /// A member of the DDP family (with SQP).
    Ddp(DdpVariant),
    /// CSQP.
    Csqp,
    /// BCL-DDP.
    BclDdp,
    /// ALTRO.
    Altro,
    /// ProxNLP on the whole problem (dense or sparse KKT).
    ProxNlp,
}

impl SolverKind {
    /// Every solver, in the order `gharial list` shows them.
    pub const ALL: [SolverKind; 10] = [
        SolverKind::ProxDdp,
        SolverKind::Ddp(DdpVariant::Ddp),
        SolverKind::Ddp(DdpVariant::Fddp),
        SolverKind::Ddp(DdpVariant::BoxDdp),
        SolverKind::Ddp(DdpVariant::BoxFddp),
        SolverKind::Ddp(DdpVariant::Sqp),
        SolverKind::Csqp,
        SolverKind::BclDdp,
        SolverKind::Altro,
        SolverKind::ProxNlp,
    ];

    /// The command-line name (`proxddp`, `ddp`, `fddp`, `box-ddp`, `box-fddp`, `sqp`,
    /// `csqp`, `bcl-ddp`, `altro`, `proxnlp`).
    pub fn name(self) -> &'static str {
        match self {
            SolverKind::ProxDdp => "proxddp",
            SolverKind::Csqp => "csqp",
            SolverKind::BclDdp => "bcl-ddp",
            SolverKind::Altro => "altro",
            SolverKind::ProxNlp => "proxnlp",
            SolverKind::Ddp(v) => v.name(),
        }
    }

    /// The name in tables and in the peer harness (`ProxDDP`, `DDP`, `FDDP`, `BoxDDP`,
    /// `BoxFDDP`, as the harness names aligator's and crocoddyl's solvers).
    pub fn label(self) -> &'static str {
        match self {
            SolverKind::ProxDdp => "ProxDDP",
            SolverKind::Ddp(DdpVariant::Ddp) => "DDP",
            SolverKind::Ddp(DdpVariant::Fddp) => "FDDP",
            SolverKind::Ddp(DdpVariant::BoxDdp) => "BoxDDP",
            SolverKind::Ddp(DdpVariant::BoxFddp) => "BoxFDDP",
            SolverKind::Ddp(DdpVariant::Sqp) => "SQP",
            SolverKind::Csqp => "CSQP",
            SolverKind::BclDdp => "BCL-DDP",
            SolverKind::Altro => "ALTRO",
            SolverKind::ProxNlp => "ProxNLP",
        }
    }

    /// One line on the method and the problems it takes.
    pub fn summary(self) -> &'static str {
        match self {
            SolverKind::ProxDdp => "primal-dual augmented-Lagrangian DDP (Jallet et al. 2023); any constraints",
            SolverKind::Ddp(DdpVariant::Ddp) => "DDP / iLQR, single shooting (Tassa et al. 2012); no constraints",
            SolverKind::Ddp(DdpVariant::Fddp) => {
                "feasibility-driven DDP, multiple shooting (Mastalli et al. 2020); no constraints"
            }
            SolverKind::Ddp(DdpVariant::BoxDdp) => {
                "DDP with a projected-Newton box QP (Tassa et al. 2014); control bounds only"
            }
            SolverKind::Ddp(DdpVariant::BoxFddp) => {
                "FDDP with control bounds (Mastalli et al. 2022); control bounds only"
            }
            SolverKind::Ddp(DdpVariant::Sqp) => {
                "stagewise SQP, Gauss-Newton multiple shooting with a filter line search (Jordana et al. 2023); no constraints"
            }
            SolverKind::Csqp => {
                "SQP with QPs by stagewise ADMM (Jordana et al. 2023); equality, orthant, box and second-order-cone constraints"
            }
            SolverKind::BclDdp => {
                "augmented-Lagrangian DDP with the BCL globalisation (El Kazdadi et al. 2021); equality constraints"
            }
            SolverKind::Altro => "AL-iLQR with a Newton projection (Howell et al. 2019); constraints with a projection",
            SolverKind::ProxNlp => {
                "ProxDDP's primal-dual augmented Lagrangian on the whole problem with a dense or sparse KKT (Jallet et al. 2023); any constraints"
            }
        }
    }

    /// The solver's iteration table (asked of a solver with default options).
    pub fn table(self) -> Table {
        self.defaults().build().table()
    }

    /// The solver's default options.
    fn defaults(self) -> SolverOptions {
        SolverOptions::from_name(self.name()).expect(EVERY_KIND_IS_A_SOLVER)
    }

    /// The solver's options on `example` (see [`Example::options`]).
    fn options(self, example: &Example) -> SolverOptions {
        example.options(self.name()).expect(EVERY_KIND_IS_A_SOLVER)
    }

    /// The settings the solver reports, and the command-line options that set them.
    fn fields(self) -> Fields {
        match self {
            SolverKind::ProxDdp => Fields::ProxDdp(PROXDDP_FIELDS),
            SolverKind::Ddp(_) => Fields::Ddp(DDP_FIELDS),
            SolverKind::Csqp => Fields::Csqp(CSQP_FIELDS),
            SolverKind::BclDdp => Fields::BclDdp(BCL_DDP_FIELDS),
            SolverKind::Altro => Fields::Altro(ALTRO_FIELDS),
            SolverKind::ProxNlp => Fields::ProxNlp(PROXNLP_FIELDS),
        }
    }
}

/// Why the library knows the name of every [`SolverKind`] (tested).
const EVERY_KIND_IS_A_SOLVER: &str = "every SolverKind names a solver of the library";

impl ValueEnum for SolverKind {
    fn value_variants<'a>() -> &'a [Self] {
        &Self::ALL
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(PossibleValue::new(self.name()).help(self.summary()))
    }
}

/// Forward pass of ProxDDP.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum RolloutArg {
    /// The SQP step (50).
    Linear,
    /// A closed-loop rollout of the nonlinear dynamics (51).
    Nonlinear,
}

impl From<RolloutArg> for Rollout {
    fn from(r: RolloutArg) -> Self {
        match r {
            RolloutArg::Linear => Rollout::Linear,
            RolloutArg::Nonlinear => Rollout::Nonlinear,
        }
    }
}

/// Step acceptance of ProxDDP.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum AcceptanceArg {
    /// Armijo backtracking on the merit function.
    Linesearch,
    /// Armijo backtracking against the average of past merit values.
    Nonmonotone,
    /// Filter on (merit, primal infeasibility).
    Filter,
}

impl From<AcceptanceArg> for StepAcceptance {
    fn from(a: AcceptanceArg) -> Self {
        match a {
            AcceptanceArg::Linesearch => StepAcceptance::Linesearch,
            AcceptanceArg::Nonmonotone => StepAcceptance::NonmonotoneLinesearch,
            AcceptanceArg::Filter => StepAcceptance::Filter,
        }
    }
}

/// Merit function of ProxDDP's step acceptance.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum MeritArg {
    /// The primal-dual augmented Lagrangian (17).
    PrimalDual,
    /// The primal augmented Lagrangian (35).
    Primal,
}

impl From<MeritArg> for Merit {
    fn from(m: MeritArg) -> Self {
        match m {
            MeritArg::PrimalDual => Merit::PrimalDual,
            MeritArg::Primal => Merit::Primal,
        }
    }
}

/// How ProxDDP's Newton step treats the dynamics.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum DynamicsStepArg {
    /// Exact without path or terminal constraints (until an exact step fails to descend
    /// the merit), proximal otherwise.
    Auto,
    /// The paper's proximal step (42).
    Proximal,
    /// The linearised dynamics solved exactly.
    Exact,
}

impl From<DynamicsStepArg> for DynamicsStep {
    fn from(d: DynamicsStepArg) -> Self {
        match d {
            DynamicsStepArg::Auto => DynamicsStep::Auto,
            DynamicsStepArg::Proximal => DynamicsStep::Proximal,
            DynamicsStepArg::Exact => DynamicsStep::Exact,
        }
    }
}

/// Options every solver takes.
#[derive(clap::Args, Debug, Clone, Default)]
#[command(next_help_heading = "Options of every solver")]
pub struct CommonArgs {
    /// Tolerance (ProxDDP: on the primal and dual residuals; DDP family: the expected
    /// decrease of a full step below tol² N, with the gaps closed).
    #[arg(long, value_parser = positive_real)]
    pub tol: Option<f64>,
    /// Iteration limit (ALTRO: of its outer, augmented-Lagrangian iterations).
    #[arg(long, value_parser = positive_int)]
    pub max_iters: Option<usize>,
    /// Threads for stage-wise evaluation.
    #[arg(long, value_parser = positive_int)]
    pub threads: Option<usize>,
    /// Hessian of the Newton / backward-pass system: `gauss-newton` (cost Hessians only;
    /// iLQR for the DDP family) or `exact` (with the dynamics' and constraints' second
    /// derivatives where the models provide them; classical DDP for the DDP family).
    #[arg(long, value_enum)]
    pub hessian: Option<HessianArg>,
}

/// The values of `--hessian`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum HessianArg {
    /// Cost Hessians only.
    GaussNewton,
    /// With the models' second derivatives.
    Exact,
}

impl From<HessianArg> for HessianApprox {
    fn from(h: HessianArg) -> Self {
        match h {
            HessianArg::GaussNewton => HessianApprox::GaussNewton,
            HessianArg::Exact => HessianApprox::Exact,
        }
    }
}

impl CommonArgs {
    /// Overrides a solver's tolerance, iteration limit and thread count.
    fn apply(&self, tol: &mut f64, max_iters: &mut usize, threads: &mut usize) {
        if let Some(v) = self.tol {
            *tol = v;
        }
        if let Some(v) = self.max_iters {
            *max_iters = v;
        }
        if let Some(v) = self.threads {
            *threads = v;
        }
    }
}

/// ProxDDP's options (overriding the problem's recommended settings).
#[derive(clap::Args, Debug, Clone, Default)]
#[command(next_help_heading = "ProxDDP options (default: the problem's recommended settings)")]
pub struct ProxDdpArgs {
    /// Initial augmented-Lagrangian penalty.
    #[arg(long, value_parser = positive_real)]
    pub mu_init: Option<f64>,
    /// Dynamics penalty relative to the penalty (appendix C of the ProxDDP paper).
    #[arg(long, value_parser = positive_real)]
    pub dyn_al_scale: Option<f64>,
    /// Active-set prediction iterations per step (0: the plain Newton step; at most 100).
    #[arg(long, value_parser = count(0, ACTIVE_SET_ITERS_MAX))]
    pub active_set_iters: Option<usize>,
    /// Forward pass.
    #[arg(long, value_enum)]
    pub rollout: Option<RolloutArg>,
    /// Step acceptance.
    #[arg(long, value_enum)]
    pub step_acceptance: Option<AcceptanceArg>,
    /// Merit function of the step acceptance.
    #[arg(long, value_enum)]
    pub merit: Option<MeritArg>,
    /// How the Newton step treats the dynamics.
    #[arg(long, value_enum)]
    pub dynamics_step: Option<DynamicsStepArg>,
}

impl ProxDdpArgs {
    /// Overrides the settings ProxNLP shares with ProxDDP (same names and meanings).
    fn apply_shared(&self, o: &mut ProxNlpOptions) {
        if let Some(v) = self.mu_init {
            o.mu_init = v;
            o.mu_lower_bound = o.mu_lower_bound.min(v);
        }
        if let Some(v) = self.dyn_al_scale {
            o.dyn_al_scale = v;
        }
        if let Some(v) = self.step_acceptance {
            o.step_acceptance = v.into();
        }
    }

    /// Overrides ProxDDP's settings.
    fn apply(&self, o: &mut ProxDdpOptions) {
        if let Some(v) = self.mu_init {
            o.mu_init = v;
            o.mu_lower_bound = o.mu_lower_bound.min(v);
        }
        if let Some(v) = self.dyn_al_scale {
            o.dyn_al_scale = v;
        }
        if let Some(v) = self.active_set_iters {
            o.active_set_iters = v;
        }
        if let Some(v) = self.rollout {
            o.rollout = v.into();
        }
        if let Some(v) = self.step_acceptance {
            o.step_acceptance = v.into();
        }
        if let Some(v) = self.merit {
            o.merit = v.into();
        }
        if let Some(v) = self.dynamics_step {
            o.dynamics_step = v.into();
        }
    }
}

/// ALTRO's options (overriding its defaults).
#[derive(clap::Args, Debug, Clone, Default)]
#[command(next_help_heading = "ALTRO options")]
pub struct AltroArgs {
    /// Start from the guess's states, the dynamics' violations carried by slack controls
    /// (Howell et al. 2019, III-B), instead of the rollout of the guess's controls.
    #[arg(long)]
    pub infeasible_start: bool,
    /// Backward pass on Cholesky factors (III-A).
    #[arg(long)]
    pub square_root: bool,
    /// AL-iLQR alone, to the constraint tolerance, without the Newton projection of
    /// Algorithm 2.
    #[arg(long)]
    pub no_projection: bool,
    /// Initial penalty of every constraint (times its scale).
    #[arg(long, value_parser = positive_real)]
    pub penalty_initial: Option<f64>,
    /// Penalty scaling factor (> 1).
    #[arg(long, value_parser = positive_real)]
    pub penalty_scaling: Option<f64>,
}

impl AltroArgs {
    /// Overrides ALTRO's settings.
    fn apply(&self, o: &mut AltroOptions) {
        o.infeasible_start |= self.infeasible_start;
        o.square_root |= self.square_root;
        o.projected_newton &= !self.no_projection;
        if let Some(v) = self.penalty_initial {
            o.penalty_initial = v;
        }
        if let Some(v) = self.penalty_scaling {
            o.penalty_scaling = v;
        }
    }
}

/// CSQP's options: its QP solver's (mim_solvers' names).
#[derive(clap::Args, Debug, Clone, Default)]
#[command(next_help_heading = "CSQP options")]
pub struct CsqpArgs {
    /// Absolute tolerance of the ADMM QP solves.
    #[arg(long, value_parser = positive_real)]
    pub eps_abs: Option<f64>,
    /// Relative tolerance of the ADMM QP solves.
    #[arg(long, value_parser = positive_real)]
    pub eps_rel: Option<f64>,
    /// ADMM iterations per QP at most.
    #[arg(long, value_parser = positive_int)]
    pub max_qp_iters: Option<usize>,
}

impl CsqpArgs {
    /// Overrides CSQP's settings.
    fn apply(&self, o: &mut CsqpOptions) {
        if let Some(v) = self.eps_abs {
            o.admm.eps_abs = v;
        }
        if let Some(v) = self.eps_rel {
            o.admm.eps_rel = v;
        }
        if let Some(v) = self.max_qp_iters {
            o.admm.max_iters = v;
        }
    }
}

/// BCL-DDP's multipliers (El Kazdadi et al. 2021, III).
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum MultipliersArg {
    /// Constant multipliers (III-A).
    Constant,
    /// Affine multipliers with feedback (III-B).
    Affine,
}

/// BCL-DDP's penalty growth.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum PenaltyUpdateArg {
    /// `μ ← k μ` (`--penalty-factor k`).
    Factor,
    /// The adaptive rate of II-C with its growth cap.
    Adaptive,
}

/// When BCL-DDP updates multipliers and penalty.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum ScheduleArg {
    /// The bound-constrained Lagrangian rules (Alg. 1).
    Bcl,
    /// After every DDP iteration (Fig. 4's failing strategy, for comparisons).
    EveryIteration,
}

/// BCL-DDP's inner DDP.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum InnerArg {
    /// Single shooting.
    Ddp,
    /// Multiple shooting (III-C).
    Fddp,
}

/// BCL-DDP's options (`--mu-init` is shared with ProxDDP).
#[derive(clap::Args, Debug, Clone, Default)]
#[command(next_help_heading = "BCL-DDP options")]
pub struct BclDdpArgs {
    /// Multipliers.
    #[arg(long, value_enum)]
    pub multipliers: Option<MultipliersArg>,
    /// Penalty growth.
    #[arg(long, value_enum)]
    pub penalty_update: Option<PenaltyUpdateArg>,
    /// Factor `k > 1` of a penalty increase.
    #[arg(long, value_parser = positive_real)]
    pub penalty_factor: Option<f64>,
    /// When multipliers and penalty change.
    #[arg(long, value_enum)]
    pub schedule: Option<ScheduleArg>,
    /// The inner DDP.
    #[arg(long, value_enum)]
    pub inner: Option<InnerArg>,
}

impl BclDdpArgs {
    /// Overrides BCL-DDP's settings (and its initial penalty from `--mu-init`).
    fn apply(&self, mu_init: Option<f64>, o: &mut BclDdpOptions) {
        if let Some(v) = mu_init {
            o.mu_init = v;
        }
        if let Some(v) = self.multipliers {
            o.multipliers = match v {
                MultipliersArg::Constant => Multipliers::Constant,
                MultipliersArg::Affine => Multipliers::Affine,
            };
        }
        if let Some(v) = self.penalty_update {
            o.penalty = match v {
                PenaltyUpdateArg::Factor => PenaltyUpdate::Factor,
                PenaltyUpdateArg::Adaptive => PenaltyUpdate::Adaptive,
            };
        }
        if let Some(v) = self.penalty_factor {
            o.penalty_factor = v;
        }
        if let Some(v) = self.schedule {
            o.schedule = match v {
                ScheduleArg::Bcl => Schedule::Bcl,
                ScheduleArg::EveryIteration => Schedule::EveryIteration,
            };
        }
        if let Some(v) = self.inner {
            o.ddp.variant = match v {
                InnerArg::Ddp => DdpVariant::Ddp,
                InnerArg::Fddp => DdpVariant::Fddp,
            };
        }
    }
}

/// The solver and its options, as the command line gives them.
#[derive(clap::Args, Debug, Clone)]
pub struct SolverArgs {
    /// Solver.
    #[arg(long, value_enum, default_value = "proxddp")]
    pub solver: SolverKind,
    // Options of every solver.
    #[command(flatten)]
    pub common: CommonArgs,
    // ProxDDP's options.
    #[command(flatten)]
    pub proxddp: ProxDdpArgs,
    // ALTRO's options.
    #[command(flatten)]
    pub altro: AltroArgs,
    // CSQP's options.
    #[command(flatten)]
    pub csqp: CsqpArgs,
    // BCL-DDP's options.
    #[command(flatten)]
    pub bcl_ddp: BclDdpArgs,
}

impl SolverArgs {
    /// `solver` with no option given.
    pub fn new(solver: SolverKind) -> Self {
        Self {
            solver,
            common: CommonArgs::default(),
            proxddp: ProxDdpArgs::default(),
            altro: AltroArgs::default(),
            csqp: CsqpArgs::default(),
            bcl_ddp: BclDdpArgs::default(),
        }
    }

    /// Refuses an option given on the command line that the chosen solver does not take.
    ///
    /// # Errors
    /// A message naming the option, the solvers that take it and the chosen solver.
    pub fn check(&self) -> Result<(), String> {
        let takes = |kind: SolverKind, flag: &str| kind.fields().flags().any(|(f, _)| f == flag);
        for kind in SolverKind::ALL {
            for (flag, given) in kind.fields().flags() {
                if given(self) && !takes(self.solver, flag) {
                    let owners: Vec<_> = SolverKind::ALL
                        .into_iter()
                        .filter(|&k| takes(k, flag))
                        .map(SolverKind::name)
                        .collect();
                    return Err(format!(
                        "{flag} is an option of {}; the solver {} does not take it",
                        owners.join(", "),
                        self.solver.name()
                    ));
                }
            }
        }
        Ok(())
    }

    /// The settings of the chosen solver on `example` ([`Example::options`]: ProxDDP
    /// starts from the example's recommended settings, the other solvers from their
    /// defaults); the options given override them.
    pub fn config(&self, example: &Example) -> SolverConfig {
        let mut options = self.solver.options(example);
        match &mut options {
            SolverOptions::ProxDdp(o) => {
                self.common.apply(&mut o.tol, &mut o.max_iters, &mut o.num_threads);
                o.hessian = self.common.hessian.map_or(o.hessian, Into::into);
                self.proxddp.apply(o);
            }
            SolverOptions::Ddp(o) => {
                self.common.apply(&mut o.tol, &mut o.max_iters, &mut o.num_threads);
                o.hessian = self.common.hessian.map_or(o.hessian, Into::into);
            }
            SolverOptions::BclDdp(o) => {
                self.common.apply(&mut o.tol, &mut o.max_iters, &mut o.ddp.num_threads);
                self.bcl_ddp.apply(self.proxddp.mu_init, o);
            }
            // ALTRO's tolerance is its constraint tolerance c_max, its iteration limit the
            // outer (multiplier) iterations.
            SolverOptions::Altro(o) => {
                self.common.apply(
                    &mut o.constraint_tolerance,
                    &mut o.iterations_outer,
                    &mut o.inner.num_threads,
                );
                self.altro.apply(o);
            }
            SolverOptions::ProxNlp(o) => {
                // Dense and single-threaded: --threads is refused by `check`.
                let mut threads = 1;
                self.common.apply(&mut o.tol, &mut o.max_iters, &mut threads);
                o.hessian = self.common.hessian.map_or(o.hessian, Into::into);
                self.proxddp.apply_shared(o);
            }
            SolverOptions::Csqp(o) => {
                self.common.apply(&mut o.tol, &mut o.max_iters, &mut o.num_threads);
                self.csqp.apply(o);
            }
            // A solver without command-line options takes none (`check` refuses them).
            _ => {}
        }
        SolverConfig {
            kind: self.solver,
            options,
        }
    }
}

/// The chosen solver and its settings, from which fresh solvers are built
/// ([`SolverOptions::build`]).
#[derive(Debug, Clone)]
pub struct SolverConfig {
    /// Which solver.
    pub kind: SolverKind,
    /// Its settings.
    pub options: SolverOptions,
}

impl SolverConfig {
    /// The settings line of `gharial solve`: each setting, marked with where it comes
    /// from when it is not the library's default: `[option; default …]` (the command
    /// line) or `[problem; default …]` (the problem's recommended ProxDDP settings).
    pub fn settings_line(&self, example: &Example, args: &SolverArgs) -> String {
        let recommended = settings(&self.kind.options(example));
        let default = settings(&self.kind.defaults());
        settings(&self.options)
            .into_iter()
            .zip(recommended)
            .zip(default)
            .map(|(((name, value, flag), (_, recommended, _)), (_, def, _))| {
                let mark = if flag.is_some_and(|(_, given)| given(args)) {
                    format!(" [option; default {def}]")
                } else if recommended != def {
                    format!(" [problem; default {def}]")
                } else {
                    String::new()
                };
                format!("{name} {value}{mark}")
            })
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The settings as a JSON object (the `settings` of `gharial solve --output`).
    pub fn settings_json(&self) -> Value {
        let object = settings(&self.options)
            .into_iter()
            .map(|(name, value, _)| (name.to_string(), value.json()))
            .collect();
        Value::Object(object)
    }
}

/// A setting's value, as printed and as written to JSON.
#[derive(Debug, Clone, PartialEq)]
enum Setting {
    Real(f64),
    Count(usize),
    Name(String),
}

impl std::fmt::Display for Setting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Setting::Real(v) => write!(f, "{}", Num(*v)),
            Setting::Count(v) => write!(f, "{v}"),
            Setting::Name(s) => f.write_str(s),
        }
    }
}

impl Setting {
    fn json(&self) -> Value {
        match self {
            Setting::Real(v) => json!(v),
            Setting::Count(v) => json!(v),
            Setting::Name(s) => json!(s),
        }
    }
}

/// A command-line option (`--tol`) and whether the command line gives it.
type Flag = (&'static str, fn(&SolverArgs) -> bool);

/// One reported setting of a solver's options `O`: its name (the options' field), its
/// value, and the command-line option that sets it, if any.
struct Field<O> {
    name: &'static str,
    value: fn(&O) -> Setting,
    flag: Option<Flag>,
}

/// The reported settings of one solver.
enum Fields {
    ProxDdp(&'static [Field<ProxDdpOptions>]),
    Ddp(&'static [Field<DdpOptions>]),
    Csqp(&'static [Field<CsqpOptions>]),
    BclDdp(&'static [Field<BclDdpOptions>]),
    Altro(&'static [Field<AltroOptions>]),
    ProxNlp(&'static [Field<ProxNlpOptions>]),
}

impl Fields {
    /// The command-line options of these settings.
    fn flags(&self) -> Box<dyn Iterator<Item = Flag>> {
        match self {
            Fields::ProxDdp(f) => Box::new(f.iter().filter_map(|f| f.flag)),
            Fields::Ddp(f) => Box::new(f.iter().filter_map(|f| f.flag)),
            Fields::Csqp(f) => Box::new(f.iter().filter_map(|f| f.flag)),
            Fields::BclDdp(f) => Box::new(f.iter().filter_map(|f| f.flag)),
            Fields::Altro(f) => Box::new(f.iter().filter_map(|f| f.flag)),
            Fields::ProxNlp(f) => Box::new(f.iter().filter_map(|f| f.flag)),
        }
    }
}

const TOL: Flag = ("--tol", |a| a.common.tol.is_some());
const MAX_ITERS: Flag = ("--max-iters", |a| a.common.max_iters.is_some());
const THREADS: Flag = ("--threads", |a| a.common.threads.is_some());
const HESSIAN: Flag = ("--hessian", |a| a.common.hessian.is_some());

const PROXDDP_FIELDS: &[Field<ProxDdpOptions>] = &[
    Field {
        name: "tol",
        value: |o| Setting::Real(o.tol),
        flag: Some(TOL),
    },
    Field {
        name: "hessian",
        value: |o| Setting::Name(format!("{:?}", o.hessian)),
        flag: Some(HESSIAN),
    },
    Field {
        name: "mu_init",
        value: |o| Setting::Real(o.mu_init),
        flag: Some(("--mu-init", |a| a.proxddp.mu_init.is_some())),
    },
    Field {
        name: "dyn_al_scale",
        value: |o| Setting::Real(o.dyn_al_scale),
        flag: Some(("--dyn-al-scale", |a| a.proxddp.dyn_al_scale.is_some())),
    },
    Field {
        name: "max_iters",
        value: |o| Setting::Count(o.max_iters),
        flag: Some(MAX_ITERS),
    },
    Field {
        name: "rollout",
        value: |o| Setting::Name(format!("{:?}", o.rollout)),
        flag: Some(("--rollout", |a| a.proxddp.rollout.is_some())),
    },
    Field {
        name: "step_acceptance",
        value: |o| Setting::Name(format!("{:?}", o.step_acceptance)),
        flag: Some(("--step-acceptance", |a| a.proxddp.step_acceptance.is_some())),
    },
    Field {
        name: "merit",
        value: |o| Setting::Name(format!("{:?}", o.merit)),
        flag: Some(("--merit", |a| a.proxddp.merit.is_some())),
    },
    Field {
        name: "dynamics_step",
        value: |o| Setting::Name(format!("{:?}", o.dynamics_step)),
        flag: Some(("--dynamics-step", |a| a.proxddp.dynamics_step.is_some())),
    },
    Field {
        name: "active_set_iters",
        value: |o| Setting::Count(o.active_set_iters),
        flag: Some(("--active-set-iters", |a| a.proxddp.active_set_iters.is_some())),
    },
    Field {
        name: "num_threads",
        value: |o| Setting::Count(o.num_threads),
        flag: Some(THREADS),
    },
];

const DDP_FIELDS: &[Field<DdpOptions>] = &[
    Field {
        name: "tol",
        value: |o| Setting::Real(o.tol),
        flag: Some(TOL),
    },
    Field {
        name: "max_iters",
        value: |o| Setting::Count(o.max_iters),
        flag: Some(MAX_ITERS),
    },
    Field {
        name: "hessian",
        value: |o| Setting::Name(format!("{:?}", o.hessian)),
        flag: Some(HESSIAN),
    },
    Field {
        name: "reg_init",
        value: |o| Setting::Real(o.reg_init),
        flag: None,
    },
    Field {
        name: "num_threads",
        value: |o| Setting::Count(o.num_threads),
        flag: Some(THREADS),
    },
];

const ALTRO_FIELDS: &[Field<AltroOptions>] = &[
    Field {
        name: "constraint_tolerance",
        value: |o| Setting::Real(o.constraint_tolerance),
        flag: Some(TOL),
    },
    Field {
        name: "iterations_outer",
        value: |o| Setting::Count(o.iterations_outer),
        flag: Some(MAX_ITERS),
    },
    Field {
        name: "iterations_inner",
        value: |o| Setting::Count(o.iterations_inner),
        flag: None,
    },
    Field {
        name: "penalty_initial",
        value: |o| Setting::Real(o.penalty_initial),
        flag: Some(("--penalty-initial", |a| a.altro.penalty_initial.is_some())),
    },
    Field {
        name: "penalty_scaling",
        value: |o| Setting::Real(o.penalty_scaling),
        flag: Some(("--penalty-scaling", |a| a.altro.penalty_scaling.is_some())),
    },
    Field {
        name: "projected_newton",
        value: |o| Setting::Name(o.projected_newton.to_string()),
        flag: Some(("--no-projection", |a| a.altro.no_projection)),
    },
    Field {
        name: "square_root",
        value: |o| Setting::Name(o.square_root.to_string()),
        flag: Some(("--square-root", |a| a.altro.square_root)),
    },
    Field {
        name: "infeasible_start",
        value: |o| Setting::Name(o.infeasible_start.to_string()),
        flag: Some(("--infeasible-start", |a| a.altro.infeasible_start)),
    },
    Field {
        name: "num_threads",
        value: |o| Setting::Count(o.inner.num_threads),
        flag: Some(THREADS),
    },
];

const BCL_DDP_FIELDS: &[Field<BclDdpOptions>] = &[
    Field {
        name: "tol",
        value: |o| Setting::Real(o.tol),
        flag: Some(TOL),
    },
    Field {
        name: "max_iters",
        value: |o| Setting::Count(o.max_iters),
        flag: Some(MAX_ITERS),
    },
    Field {
        name: "mu_init",
        value: |o| Setting::Real(o.mu_init),
        flag: Some(("--mu-init", |a| a.proxddp.mu_init.is_some())),
    },
    Field {
        name: "multipliers",
        value: |o| Setting::Name(format!("{:?}", o.multipliers)),
        flag: Some(("--multipliers", |a| a.bcl_ddp.multipliers.is_some())),
    },
    Field {
        name: "penalty",
        value: |o| Setting::Name(format!("{:?}", o.penalty)),
        flag: Some(("--penalty-update", |a| a.bcl_ddp.penalty_update.is_some())),
    },
    Field {
        name: "penalty_factor",
        value: |o| Setting::Real(o.penalty_factor),
        flag: Some(("--penalty-factor", |a| a.bcl_ddp.penalty_factor.is_some())),
    },
    Field {
        name: "schedule",
        value: |o| Setting::Name(format!("{:?}", o.schedule)),
        flag: Some(("--schedule", |a| a.bcl_ddp.schedule.is_some())),
    },
    Field {
        name: "inner",
        value: |o| Setting::Name(o.ddp.variant.name().to_string()),
        flag: Some(("--inner", |a| a.bcl_ddp.inner.is_some())),
    },
    Field {
        name: "num_threads",
        value: |o| Setting::Count(o.ddp.num_threads),
        flag: Some(THREADS),
    },
];

const CSQP_FIELDS: &[Field<CsqpOptions>] = &[
    Field {
        name: "tol",
        value: |o| Setting::Real(o.tol),
        flag: Some(TOL),
    },
    Field {
        name: "max_iters",
        value: |o| Setting::Count(o.max_iters),
        flag: Some(MAX_ITERS),
    },
    Field {
        name: "eps_abs",
        value: |o| Setting::Real(o.admm.eps_abs),
        flag: Some(("--eps-abs", |a| a.csqp.eps_abs.is_some())),
    },
    Field {
        name: "eps_rel",
        value: |o| Setting::Real(o.admm.eps_rel),
        flag: Some(("--eps-rel", |a| a.csqp.eps_rel.is_some())),
    },
    Field {
        name: "max_qp_iters",
        value: |o| Setting::Count(o.admm.max_iters),
        flag: Some(("--max-qp-iters", |a| a.csqp.max_qp_iters.is_some())),
    },
    Field {
        name: "num_threads",
        value: |o| Setting::Count(o.num_threads),
        flag: Some(THREADS),
    },
];

const PROXNLP_FIELDS: &[Field<ProxNlpOptions>] = &[
    Field {
        name: "tol",
        value: |o| Setting::Real(o.tol),
        flag: Some(TOL),
    },
    Field {
        name: "max_iters",
        value: |o| Setting::Count(o.max_iters),
        flag: Some(MAX_ITERS),
    },
    Field {
        name: "hessian",
        value: |o| Setting::Name(format!("{:?}", o.hessian)),
        flag: Some(HESSIAN),
    },
    Field {
        name: "mu_init",
        value: |o| Setting::Real(o.mu_init),
        flag: Some(("--mu-init", |a| a.proxddp.mu_init.is_some())),
    },
    Field {
        name: "dyn_al_scale",
        value: |o| Setting::Real(o.dyn_al_scale),
        flag: Some(("--dyn-al-scale", |a| a.proxddp.dyn_al_scale.is_some())),
    },
    Field {
        name: "step_acceptance",
        value: |o| Setting::Name(format!("{:?}", o.step_acceptance)),
        flag: Some(("--step-acceptance", |a| a.proxddp.step_acceptance.is_some())),
    },
];

/// The reported settings of `options`: each field's name, value and command-line option
/// (none for a solver without a field table).
fn settings(options: &SolverOptions) -> Vec<(&'static str, Setting, Option<Flag>)> {
    fn values<O>(fields: &[Field<O>], o: &O) -> Vec<(&'static str, Setting, Option<Flag>)> {
        fields.iter().map(|f| (f.name, (f.value)(o), f.flag)).collect()
    }
    match options {
        SolverOptions::ProxDdp(o) => values(PROXDDP_FIELDS, o),
        SolverOptions::Ddp(o) => values(DDP_FIELDS, o),
        SolverOptions::Csqp(o) => values(CSQP_FIELDS, o),
        SolverOptions::BclDdp(o) => values(BCL_DDP_FIELDS, o),
        SolverOptions::Altro(o) => values(ALTRO_FIELDS, o),
        SolverOptions::ProxNlp(o) => values(PROXNLP_FIELDS, o),
        _ => Vec::new(),
    }
}

/// The columns of every solver's iteration table (for `gharial solve --help`), one
/// section per table, naming the solvers that print it.
pub fn tables_legend() -> String {
    let mut sections: Vec<(Vec<&str>, String)> = Vec::new();
    for kind in SolverKind::ALL {
        let legend = kind.table().legend();
        match sections.iter_mut().find(|(_, l)| *l == legend) {
            Some((names, _)) => names.push(kind.name()),
            None => sections.push((vec![kind.name()], legend)),
        }
    }
    sections
        .iter()
        .map(|(names, legend)| format!("Columns of the iteration table of {}:\n{legend}", names.join(", ")))
        .collect::<Vec<_>>()
        .join("\n\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The command line's solvers are the library's, by the same names in the same order.
    #[test]
    fn every_kind_is_a_solver_of_the_library() {
        let names: Vec<_> = SolverKind::ALL.into_iter().map(SolverKind::name).collect();
        assert_eq!(names, SolverOptions::names());
        for kind in SolverKind::ALL {
            assert_eq!(kind.defaults().name(), kind.name());
        }
    }
}

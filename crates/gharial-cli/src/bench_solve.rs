//! `gharial bench solve` (the catalogue's examples, with any solver) and `gharial bench
//! peers` (the peer harness's problems with every gharial solver that takes them, as
//! JSON lines in the harness's format).
//!
//! Each timed solve starts from the same guess with a freshly constructed and set-up
//! solver (construction and setup are not timed, as in the harness); the median and
//! minimum over the repeats are reported, with the time of one full-horizon model
//! evaluation and derivative pass, to separate model cost from solver cost.

use std::io::Write;
use std::time::Instant;

use gharial::error::Num;
use gharial::problem::{Problem, ProblemData, kkt_residuals};
use gharial::solvers::{InitialGuess, Solution, SolverOptions};
use gharial_problems::peers::{PeersLqrParams, PeersVariant};
use serde_json::json;

use crate::solver_choice::{AcceptanceArg, CommonArgs, ProxDdpArgs, SolverArgs, SolverConfig, SolverKind};
use crate::{HARNESS_PROBLEMS, MAX_DIM, MAX_HORIZON, MAX_REPEATS, count, positive_int, positive_real};

/// Timings of repeated solves of one problem.
pub struct Timing {
    /// The last solution.
    pub solution: Solution,
    /// Median wall time of a solve, ms.
    pub median_ms: f64,
    /// Minimum wall time of a solve, ms.
    pub min_ms: f64,
    /// One evaluation of the whole problem, ms (median of 11).
    pub eval_ms: f64,
    /// One derivative pass over the whole problem, ms (median of 11).
    pub deriv_ms: f64,
    /// Cost of the initial guess.
    pub init_cost: f64,
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Why repeated solves could not be timed.
#[derive(Debug)]
pub enum TimingError {
    /// The solver does not take the problem (its setup refused it).
    Refused(gharial::Error),
    /// The solve failed (e.g. an invalid guess).
    Failed(gharial::Error),
}

impl std::fmt::Display for TimingError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TimingError::Refused(e) | TimingError::Failed(e) => e.fmt(f),
        }
    }
}

/// Solves `problem` `repeats` times from `(xs, us)` with fresh solvers of `config` and
/// times it.
///
/// # Errors
/// If the solver's setup refuses the problem, or the guess is invalid.
pub fn time_solves(
    problem: &Problem,
    xs: &[Vec<f64>],
    us: &[Vec<f64>],
    config: &SolverConfig,
    repeats: usize,
) -> Result<Timing, TimingError> {
    let mut times = Vec::with_capacity(repeats.max(1));
    let mut solution = Solution::default();
    for _ in 0..repeats.max(1) {
        // A freshly constructed and set-up solver per repeat (not timed), as the harness.
        let mut solver = config.options.build();
        solver.setup(problem).map_err(TimingError::Refused)?;
        let t = Instant::now();
        solver
            .solve_with(problem, InitialGuess::primal(xs, us), None)
            .map_err(TimingError::Failed)?;
        times.push(t.elapsed().as_secs_f64() * 1e3);
        solution = solver.solution().clone();
    }
    let min_ms = times.iter().copied().fold(f64::INFINITY, f64::min);
    let median_ms = median(&mut times);
    let mut data = ProblemData::new(problem, 1).map_err(TimingError::Failed)?;
    let init_cost = data.evaluate(problem, xs, us);
    let (mut ev, mut de) = (Vec::new(), Vec::new());
    for _ in 0..11 {
        let t = Instant::now();
        data.evaluate(problem, xs, us);
        ev.push(t.elapsed().as_secs_f64() * 1e3);
        let t = Instant::now();
        data.compute_derivatives(problem, xs, us);
        de.push(t.elapsed().as_secs_f64() * 1e3);
    }
    Ok(Timing {
        solution,
        median_ms,
        min_ms,
        eval_ms: median(&mut ev),
        deriv_ms: median(&mut de),
        init_cost,
    })
}

/// The arguments of `gharial bench solve`.
#[derive(clap::Args, Debug, Clone)]
pub struct ExamplesArgs {
    /// Problems (default: the whole catalogue).
    pub problems: Vec<String>,
    /// Timed solves per problem (at most 10,000).
    #[arg(long, default_value_t = 5, value_parser = count(1, MAX_REPEATS))]
    pub repeats: usize,
    /// Every solver on every problem it takes (instead of `--solver`), then the matrix of
    /// problems by solvers.
    #[arg(long, conflicts_with = "solver")]
    pub all_solvers: bool,
    // The solver and its options.
    #[command(flatten)]
    pub solver: SolverArgs,
}

/// One cell of the problems-by-solvers matrix.
enum Outcome {
    /// Solved: status, iterations, median milliseconds, largest KKT residual.
    Solved(String, usize, f64, f64),
    /// The solver does not take the problem.
    Skipped,
    /// The solve failed with an error.
    Failed,
}

/// `gharial bench solve`: iterations, time and time per iteration of every example with
/// the chosen solver (ProxDDP at the example's recommended settings) or every solver,
/// with the options given, and the largest KKT residual of the solution recomputed by
/// [`kkt_residuals`] (the final violation of every constraint and of optimality).
/// Problems a solver does not take are listed as skipped, with the reason.
pub fn examples(args: &ExamplesArgs) -> i32 {
    let kinds: Vec<SolverKind> = if args.all_solvers {
        SolverKind::ALL.to_vec()
    } else {
        vec![args.solver.solver]
    };
    let solvers: Vec<SolverArgs> = kinds
        .iter()
        .map(|&solver| SolverArgs {
            solver,
            ..args.solver.clone()
        })
        .collect();
    if let Some(e) = solvers.iter().find_map(|s| s.check().err()) {
        eprintln!("gharial bench solve: {e}");
        return 2;
    }
    let names: Vec<String> = if args.problems.is_empty() {
        gharial_problems::catalogue()
            .iter()
            .map(|p| p.name.to_string())
            .collect()
    } else {
        args.problems.clone()
    };
    if !args.all_solvers {
        out!("solver {}", args.solver.solver.name());
    }
    print_header();
    let mut code = 0;
    let mut matrix = Vec::new();
    for name in &names {
        let ex = match gharial_problems::build(name) {
            Ok(e) => e,
            Err(e) => {
                eprintln!("gharial bench solve: {e}");
                return 2;
            }
        };
        let mut row = Vec::new();
        for solver in &solvers {
            let outcome = bench_row(name, &ex, solver, args.repeats);
            let fine = match &outcome {
                Outcome::Solved(status, ..) => status == "converged",
                Outcome::Skipped => true,
                Outcome::Failed => false,
            };
            if !fine {
                code = 1;
            }
            row.push(outcome);
            let _ = std::io::stdout().flush();
        }
        matrix.push(row);
    }
    if args.all_solvers {
        print_matrix(&names, &kinds, &matrix);
    }
    code
}

fn print_header() {
    out!(
        "{:<20} {:<8} {:>9} {:>10} {:>6} {:>4} {:>12} {:>10} {:>10} {:>15} {:>15} {:>9} {:>9} {:>9}",
        "problem",
        "solver",
        "rollout",
        "status",
        "iters",
        "al",
        "ms (median)",
        "ms (min)",
        "ms/iter",
        "eval/deriv (ms)",
        "cost",
        "prim",
        "dual",
        "KKT"
    );
}

/// Times `solver` on the example `name` and prints its row.
fn bench_row(name: &str, ex: &gharial_problems::Example, solver: &SolverArgs, repeats: usize) -> Outcome {
    let config = solver.config(ex);
    let label = solver.solver.name();
    let rollout = match &config.options {
        SolverOptions::ProxDdp(o) => format!("{:?}", o.rollout).to_lowercase(),
        _ => "-".to_string(),
    };
    match time_solves(&ex.problem, &ex.xs0, &ex.us0, &config, repeats) {
        Ok(t) => {
            let s = &t.solution;
            let kkt = kkt_residuals(&ex.problem, &s.xs, &s.us, &s.lambdas, &s.nus).map_or(f64::NAN, |k| k.max());
            let status = if s.status.converged() {
                "converged".to_string()
            } else {
                format!("{:?}", s.status)
            };
            out!(
                "{:<20} {:<8} {:>9} {:>10} {:>6} {:>4} {:>12.3} {:>10.3} {:>10.4} {:>7.3}/{:<7.3} {:>15.9e} {:>9.2e} {:>9.2e} {:>9.2e}",
                name,
                label,
                rollout,
                status,
                s.iterations,
                s.al_iterations,
                t.median_ms,
                t.min_ms,
                t.median_ms / s.iterations.max(1) as f64,
                t.eval_ms,
                t.deriv_ms,
                s.cost,
                s.prim_err,
                s.dual_err,
                kkt
            );
            Outcome::Solved(status, s.iterations, t.median_ms, kkt)
        }
        Err(TimingError::Refused(e)) => {
            out!("{name:<20} {label:<8} skipped: {e}");
            Outcome::Skipped
        }
        Err(e) => {
            eprintln!("gharial bench solve {name} ({label}): {e}");
            Outcome::Failed
        }
    }
}

/// The problems-by-solvers matrix: iterations and median time of each converged solve,
/// the status otherwise, `-` where the solver does not take the problem.
fn print_matrix(names: &[String], kinds: &[SolverKind], matrix: &[Vec<Outcome>]) {
    out!("");
    out!("iterations / median ms (KKT residual of unconverged solves); - : not taken");
    let mut head = format!("{:<20}", "problem");
    for k in kinds {
        head.push_str(&format!(" {:>20}", k.name()));
    }
    out!("{head}");
    for (name, row) in names.iter().zip(matrix) {
        let mut line = format!("{name:<20}");
        for cell in row {
            let text = match cell {
                Outcome::Solved(status, it, ms, _) if status == "converged" => format!("{it} / {ms:.2}"),
                Outcome::Solved(status, it, _, kkt) => format!("{status} {it} ({kkt:.0e})"),
                Outcome::Skipped => "-".to_string(),
                Outcome::Failed => "error".to_string(),
            };
            line.push_str(&format!(" {text:>20}"));
        }
        out!("{line}");
    }
}

/// The arguments of `gharial bench peers`, matching the harness's environment.
#[derive(clap::Args, Debug, Clone)]
pub struct PeersArgs {
    /// Harness problem names, comma separated (a name gharial does not have gets a line
    /// with an `error`).
    #[arg(long, value_delimiter = ',', default_values_t = HARNESS_PROBLEMS.iter().map(|s| s.to_string()).collect::<Vec<_>>())]
    pub problems: Vec<String>,
    /// Solvers by their harness names (`ProxDDP`, `ProxDDP_ls`, `ProxDDP_as`, `DDP`,
    /// `FDDP`, `BoxDDP`, `BoxFDDP`, `SQP`, `CSQP`, `BCL-DDP`, `ALTRO`, `ProxNLP`), comma
    /// separated; all of them when absent.
    #[arg(long, value_delimiter = ',')]
    pub solvers: Option<Vec<String>>,
    /// Timed solves per problem and solver (at most 10,000).
    #[arg(long, default_value_t = 5, value_parser = count(1, MAX_REPEATS))]
    pub repeats: usize,
    /// Tolerance.
    #[arg(long, default_value_t = 1e-6, value_parser = positive_real)]
    pub tol: f64,
    /// Iteration limit.
    #[arg(long, default_value_t = 500, value_parser = positive_int)]
    pub max_iters: usize,
    /// Directory where the final trajectories are written
    /// (`<problem>__gharial_<solver>.txt`).
    #[arg(long)]
    pub traj_dir: Option<String>,
    /// Threads for the stage-wise passes of every solver (the harness leaves
    /// crocoddyl's shooting problems at their default, two).
    #[arg(long, default_value_t = 1, value_parser = positive_int)]
    pub threads: usize,
    // The LQR family's parameters.
    #[command(flatten)]
    pub lqr: LqrArgs,
}

/// The parameters of the harness's LQR family.
#[derive(clap::Args, Debug, Clone)]
pub struct LqrArgs {
    /// State size of the LQR family.
    #[arg(long, default_value_t = 8, value_parser = count(1, MAX_DIM))]
    pub lqr_nx: usize,
    /// Control size.
    #[arg(long, default_value_t = 4, value_parser = count(1, MAX_DIM))]
    pub lqr_nu: usize,
    /// Horizon.
    #[arg(long = "lqr-N", default_value_t = 100, value_parser = count(1, MAX_HORIZON))]
    pub lqr_n: usize,
    /// Seed.
    #[arg(long, default_value_t = 42)]
    pub lqr_seed: u64,
    /// Control bound.
    #[arg(long, default_value_t = 0.05, value_parser = positive_real)]
    pub lqr_umax: f64,
}

impl LqrArgs {
    fn params(&self) -> PeersLqrParams {
        PeersLqrParams {
            nx: self.lqr_nx,
            nu: self.lqr_nu,
            horizon: self.lqr_n,
            seed: self.lqr_seed,
            umax: self.lqr_umax,
        }
    }
}

/// Writes a trajectory in the harness's format: lines `x v0 v1 ...`, then `u ...`.
fn write_traj(path: &str, sol: &Solution) -> std::io::Result<()> {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    for x in &sol.xs {
        write!(f, "x")?;
        for v in x {
            write!(f, " {v:.17e}")?;
        }
        writeln!(f)?;
    }
    for u in &sol.us {
        write!(f, "u")?;
        for v in u {
            write!(f, " {v:.17e}")?;
        }
        writeln!(f)?;
    }
    Ok(())
}

/// The example of a harness problem name: the LQR family with the given parameters,
/// the robot problems of the catalogue.
fn harness_problem(name: &str, params: &PeersLqrParams) -> Option<gharial::Result<gharial_problems::Example>> {
    let lqr = |v| Some(gharial_problems::peers::build(params, v));
    match name {
        "lqr" => lqr(PeersVariant::Lqr),
        "lqr_box" => lqr(PeersVariant::Box),
        "lqr_box_term" => lqr(PeersVariant::BoxTerminal),
        "ur5" => Some(gharial_problems::build("ur5")),
        "ur5_box" => Some(gharial_problems::build("ur5-box")),
        "pendulum" => Some(gharial_problems::build("double-pendulum")),
        "pendulum_box" => Some(gharial_problems::build("double-pendulum-box")),
        "pendulum_box_term" => Some(gharial_problems::build("double-pendulum-box-term")),
        _ => None,
    }
}

/// The solvers reported, by the harness's names: `ProxDDP` with the filter (the
/// harness's ProxDDP), `ProxDDP_ls` with the nonmonotone line search, `ProxDDP_as` with
/// the filter and the active-set prediction of the step, then the DDP family (`DDP`,
/// `FDDP`, `BoxDDP`, `BoxFDDP`, as the harness names crocoddyl's) at its defaults; all
/// with the harness's tolerance and iteration limit, on `--threads` threads.
fn peers_solvers(args: &PeersArgs) -> Vec<(&'static str, SolverArgs)> {
    let common = CommonArgs {
        tol: Some(args.tol),
        max_iters: Some(args.max_iters),
        threads: Some(args.threads),
        hessian: None,
    };
    let proxddp = |label, acceptance, active_set_iters| {
        let proxddp = ProxDdpArgs {
            step_acceptance: Some(acceptance),
            active_set_iters: Some(active_set_iters),
            ..Default::default()
        };
        let solver = SolverArgs {
            common: common.clone(),
            proxddp,
            ..SolverArgs::new(SolverKind::ProxDdp)
        };
        (label, solver)
    };
    let mut solvers = vec![
        proxddp("ProxDDP", AcceptanceArg::Filter, 0),
        proxddp("ProxDDP_ls", AcceptanceArg::Nonmonotone, 0),
        proxddp("ProxDDP_as", AcceptanceArg::Filter, 10),
    ];
    for kind in SolverKind::ALL.into_iter().filter(|&k| k != SolverKind::ProxDdp) {
        let solver = SolverArgs {
            common: common.clone(),
            ..SolverArgs::new(kind)
        };
        solvers.push((kind.label(), solver));
    }
    solvers
}

/// The solvers of `all` named in `names` (all when `None`), in the order of `all`; an
/// error naming the valid labels for an unknown name.
fn chosen_solvers(
    all: Vec<(&'static str, SolverArgs)>,
    names: Option<&[String]>,
) -> Result<Vec<(&'static str, SolverArgs)>, String> {
    let Some(names) = names else { return Ok(all) };
    if let Some(unknown) = names.iter().find(|n| !all.iter().any(|(label, _)| label == n)) {
        let valid: Vec<&str> = all.iter().map(|(label, _)| *label).collect();
        return Err(format!("unknown solver `{unknown}`; valid names: {}", valid.join(", ")));
    }
    Ok(all
        .into_iter()
        .filter(|(label, _)| names.iter().any(|n| n == label))
        .collect())
}

/// `gharial bench peers`: one JSON line per (problem, solver), trajectories written for
/// the harness's independent check, all solvers of a problem together. ProxDDP starts
/// from each problem's catalogue settings (the harness's: `mu_init` and rollout per
/// family). A solver other than ProxDDP whose setup refuses a problem (DDP and FDDP take
/// no constraints, the box variants control bounds only) gets no line, as the harness runs crocoddyl's solvers only on
/// the problems they take; the skips and their reasons are noted on standard error. A problem gharial cannot build, or any other failure, gets a line with an
/// `error`.
pub fn peers(args: &PeersArgs) -> i32 {
    // Measured: ProxDDP holds about 40 doubles per entry of (nx + nu)² per stage.
    let lqr = &args.lqr;
    if let Err(e) = crate::check_memory("the LQR family", lqr.lqr_nx + lqr.lqr_nu, lqr.lqr_n + 1, 40.0 * 8.0) {
        eprintln!("gharial bench peers: {e}");
        return 2;
    }
    let solvers = match chosen_solvers(peers_solvers(args), args.solvers.as_deref()) {
        Ok(solvers) => solvers,
        Err(e) => {
            eprintln!("gharial bench peers: {e}");
            return 2;
        }
    };
    let params = lqr.params();
    for name in &args.problems {
        let ex = match harness_problem(name, &params) {
            Some(Ok(e)) => e,
            other => {
                let error = match other {
                    Some(Err(e)) => e.to_string(),
                    _ => format!("gharial has no problem `{name}`"),
                };
                for (solver, _) in &solvers {
                    out!(
                        "{}",
                        json!({"problem": name, "lib": "gharial", "solver": solver, "side": "rust", "error": error})
                    );
                }
                continue;
            }
        };
        for (solver, solver_args) in &solvers {
            let config = solver_args.config(&ex);
            if let Err(reason) = peers_line(args, name, solver, &ex, &config) {
                eprintln!("gharial bench peers: {name}: not run by {solver}: {reason}");
            }
        }
    }
    0
}

/// Times one solver on one harness problem and prints its JSON line; an error if a
/// solver other than ProxDDP refused the problem (no line; the error is the reason).
fn peers_line(
    args: &PeersArgs,
    name: &str,
    solver: &str,
    ex: &gharial_problems::Example,
    config: &SolverConfig,
) -> Result<(), String> {
    let t = match time_solves(&ex.problem, &ex.xs0, &ex.us0, config, args.repeats) {
        Ok(t) => t,
        Err(TimingError::Refused(e)) if config.kind != SolverKind::ProxDdp => return Err(e.to_string()),
        Err(e) => {
            out!(
                "{}",
                json!({"problem": name, "lib": "gharial", "solver": solver, "side": "rust", "error": e.to_string()})
            );
            return Ok(());
        }
    };
    let s = &t.solution;
    if let Some(dir) = &args.traj_dir {
        let path = format!("{dir}/{name}__gharial_{solver}.txt");
        if let Err(e) = write_traj(&path, s) {
            eprintln!("gharial bench peers: cannot write {path}: {e}");
        }
    }
    out!(
        "{}",
        json!({
            "problem": name, "lib": "gharial", "lib_version": env!("CARGO_PKG_VERSION"),
            "solver": solver, "side": "rust",
            "N": ex.problem.horizon(), "nx": ex.problem.space(0).nx(), "nu": ex.problem.nu(0),
            "tol": args.tol, "max_iters": args.max_iters, "repeats": args.repeats,
            "settings": peers_settings(config),
            "iters": s.iterations, "converged": s.status.converged(),
            "prim_res": s.prim_err, "dual_res": s.dual_err,
            "init_cost": t.init_cost, "final_cost": s.cost,
            "time_ms": t.median_ms, "time_ms_min": t.min_ms,
            "time_per_iter_ms": t.median_ms / s.iterations.max(1) as f64,
            "model_eval_ms": t.eval_ms, "model_deriv_ms": t.deriv_ms,
        })
    );
    Ok(())
}

/// The harness's free-form `settings` string of a solver.
fn peers_settings(config: &SolverConfig) -> String {
    match &config.options {
        SolverOptions::ProxDdp(o) => format!(
            "mu_init={:e} rollout={:?} step_acceptance={:?} active_set_iters={} threads={}",
            o.mu_init, o.rollout, o.step_acceptance, o.active_set_iters, o.num_threads
        ),
        SolverOptions::Ddp(o) => format!(
            "tol={} th_stop=tol^2*N variant={} reg_init={} threads={}",
            Num(o.tol),
            o.variant.name(),
            Num(o.reg_init),
            o.num_threads
        ),
        SolverOptions::Csqp(o) => format!(
            "tol={} eps_abs={} eps_rel={} max_qp_iters={} warm_qp={}",
            Num(o.tol),
            Num(o.admm.eps_abs),
            Num(o.admm.eps_rel),
            o.admm.max_iters,
            o.warm_qp
        ),
        _ => String::new(),
    }
}

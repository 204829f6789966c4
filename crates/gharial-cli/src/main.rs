//! The `gharial` command-line tool.

/// `println!` for the tool's output: a closed standard output (`gharial list | head`)
/// ends the process quietly instead of panicking.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        if writeln!(std::io::stdout(), $($arg)*).is_err() {
            std::process::exit(0);
        }
    }};
}

mod bench;
mod bench_solve;
mod solve;

use clap::{Parser, Subcommand, ValueEnum};
use gharial::solvers::proxddp::{Merit, Rollout, StepAcceptance};

#[derive(Parser)]
#[command(name = "gharial", version, about = "Constrained trajectory optimization for robots")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// Forward pass of the solver.
#[derive(Clone, Copy, ValueEnum)]
enum RolloutArg {
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

/// Step acceptance of the solver.
#[derive(Clone, Copy, ValueEnum)]
enum AcceptanceArg {
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

/// Merit function of the step acceptance.
#[derive(Clone, Copy, ValueEnum)]
enum MeritArg {
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

#[derive(Subcommand)]
enum Command {
    /// List the built-in problems and solvers.
    List,
    /// Solve a built-in problem: iteration table, summary, optional JSON output.
    #[command(after_help = solve_help())]
    Solve {
        /// Problem name (see `gharial list`).
        problem: String,
        /// Solver.
        #[arg(long, default_value = "proxddp")]
        solver: String,
        /// Tolerance on the primal and dual residuals.
        #[arg(long, value_parser = positive_real)]
        tol: Option<f64>,
        /// Initial augmented-Lagrangian penalty.
        #[arg(long, value_parser = positive_real)]
        mu_init: Option<f64>,
        /// Dynamics penalty relative to the penalty (appendix C of the ProxDDP paper).
        #[arg(long, value_parser = positive_real)]
        dyn_al_scale: Option<f64>,
        /// Active-set prediction iterations per step (0: the plain Newton step).
        #[arg(long)]
        active_set_iters: Option<usize>,
        /// Iteration limit.
        #[arg(long, value_parser = positive_int)]
        max_iters: Option<usize>,
        /// Forward pass.
        #[arg(long, value_enum)]
        rollout: Option<RolloutArg>,
        /// Step acceptance.
        #[arg(long, value_enum)]
        step_acceptance: Option<AcceptanceArg>,
        /// Merit function of the step acceptance.
        #[arg(long, value_enum)]
        merit: Option<MeritArg>,
        /// Threads for stage-wise evaluation.
        #[arg(long, value_parser = positive_int)]
        threads: Option<usize>,
        /// Print the solver's live log (with outer updates) instead of the table afterwards.
        #[arg(long)]
        verbose: bool,
        /// Write the solution, settings and history to this JSON file.
        #[arg(long)]
        output: Option<String>,
    },
    /// Benchmarks.
    Bench {
        #[command(subcommand)]
        which: BenchCommand,
    },
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Iterations, time per solve and per iteration of the built-in problems.
    Solve {
        /// Problems (default: the whole catalogue).
        problems: Vec<String>,
        /// Timed solves per problem.
        #[arg(long, default_value_t = 5, value_parser = positive_int)]
        repeats: usize,
        /// Forward pass (default: each problem's recommended one).
        #[arg(long, value_enum)]
        rollout: Option<RolloutArg>,
        /// Active-set prediction iterations per step (default: each problem's setting).
        #[arg(long)]
        active_set_iters: Option<usize>,
    },
    /// The LQR family of the peer harness, as JSON lines in its format.
    Peers {
        /// Harness problem names, comma separated (problems other than lqr, lqr_box and
        /// lqr_box_term are skipped).
        #[arg(long, value_delimiter = ',', default_values_t = vec!["lqr".to_string(), "lqr_box".to_string(), "lqr_box_term".to_string()])]
        problems: Vec<String>,
        /// Timed solves per problem and solver.
        #[arg(long, default_value_t = 5, value_parser = positive_int)]
        repeats: usize,
        /// Tolerance.
        #[arg(long, default_value_t = 1e-6, value_parser = positive_real)]
        tol: f64,
        /// Iteration limit.
        #[arg(long, default_value_t = 500, value_parser = positive_int)]
        max_iters: usize,
        /// Directory where the final trajectories are written.
        #[arg(long)]
        traj_dir: Option<String>,
        /// State size of the LQR family.
        #[arg(long, default_value_t = 8, value_parser = positive_int)]
        lqr_nx: usize,
        /// Control size.
        #[arg(long, default_value_t = 4, value_parser = positive_int)]
        lqr_nu: usize,
        /// Horizon.
        #[arg(long = "lqr-N", default_value_t = 100, value_parser = positive_int)]
        lqr_n: usize,
        /// Seed.
        #[arg(long, default_value_t = 42)]
        lqr_seed: u64,
        /// Control bound.
        #[arg(long, default_value_t = 0.05, value_parser = positive_real)]
        lqr_umax: f64,
    },
    /// Proximal Riccati solver (serial and parallel) on the peers' random LQ problems.
    Riccati {
        /// Thread counts to time (1 = the serial solver), comma separated.
        #[arg(long, value_delimiter = ',', default_values_t = vec![1, 2], value_parser = positive_int)]
        threads: Vec<usize>,
        /// Horizons of the main series, comma separated.
        #[arg(long, value_delimiter = ',', default_values_t = vec![16, 32, 64, 128, 256, 512, 1024], value_parser = positive_int)]
        horizons: Vec<usize>,
        /// Dimensions `nx:nu:nc` of the main series.
        #[arg(long, default_value = "36:12:32")]
        dims: String,
        /// Extra cases `nx:nu:nc:N`, comma separated.
        #[arg(long, value_delimiter = ',', default_values_t = vec!["12:6:0:100".to_string(), "4:2:2:100".to_string()])]
        extra: Vec<String>,
        /// Constraint regularisation mu.
        #[arg(long, default_value_t = 1e-8, value_parser = nonnegative_real)]
        mu: f64,
        /// Seed of the problem generator.
        #[arg(long, default_value_t = 42)]
        seed: u64,
        /// Time budget per case and solver, in seconds.
        #[arg(long, default_value_t = 1.0, value_parser = positive_real)]
        budget: f64,
        /// Passes over the case list (the budget is split between them).
        #[arg(long, default_value_t = 4, value_parser = positive_int)]
        rounds: usize,
        /// Iterative refinement steps.
        #[arg(long, default_value_t = 0)]
        refine: usize,
    },
}

/// The part of `gharial solve --help` after the options: the table's columns and the
/// exit codes.
fn solve_help() -> String {
    format!(
        "Columns of the iteration table:\n{}\n\nThe settings line marks values that are not the library's defaults: \
         [problem] for the problem's recommended settings, [option] for the command line.\n\n\
         Exit code: 0 converged, 1 stopped for another reason (the status says which), 2 invalid input.",
        gharial::solvers::IterationRecord::LEGEND
    )
}

/// An integer of at least 1 (counts: threads, repeats, iterations, sizes).
fn positive_int(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(v) if v >= 1 => Ok(v),
        Ok(_) => Err("must be at least 1".into()),
        Err(e) => Err(e.to_string()),
    }
}

/// A finite number greater than 0 (tolerances, penalties, budgets, bounds).
fn positive_real(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        Ok(v) => Err(format!("must be a finite number greater than 0, got {v}")),
        Err(e) => Err(e.to_string()),
    }
}

/// A finite number of at least 0.
fn nonnegative_real(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        Ok(v) => Err(format!("must be a finite number of at least 0, got {v}")),
        Err(e) => Err(e.to_string()),
    }
}

/// `nx:nu:nc` (n = 3) or `nx:nu:nc:N` (n = 4), with `nx >= 1` and `N >= 1`.
fn parse_dims(s: &str, n: usize) -> Result<Vec<usize>, String> {
    let v: Result<Vec<usize>, _> = s.split(':').map(str::parse).collect();
    match v {
        Ok(v) if v.len() == n && v[0] >= 1 && (n < 4 || v[3] >= 1) => Ok(v),
        Ok(v) if v.len() == n => Err(format!("`{s}`: nx and N must be at least 1")),
        _ => Err(format!("expected {n} integers separated by ':', got `{s}`")),
    }
}

fn main() {
    let cli = Cli::parse();
    match cli.command {
        Command::List => solve::list(),
        Command::Solve {
            problem,
            solver,
            tol,
            mu_init,
            dyn_al_scale,
            active_set_iters,
            max_iters,
            rollout,
            step_acceptance,
            merit,
            threads,
            verbose,
            output,
        } => {
            let args = solve::SolveArgs {
                problem,
                solver,
                tol,
                mu_init,
                dyn_al_scale,
                active_set_iters,
                max_iters,
                rollout: rollout.map(Rollout::from),
                step_acceptance: step_acceptance.map(StepAcceptance::from),
                merit: merit.map(Merit::from),
                threads,
                verbose,
                output,
            };
            std::process::exit(solve::run(&args));
        }
        Command::Bench {
            which:
                BenchCommand::Solve {
                    problems,
                    repeats,
                    rollout,
                    active_set_iters,
                },
        } => std::process::exit(bench_solve::examples(
            &problems,
            repeats,
            rollout.map(Rollout::from),
            active_set_iters,
        )),
        Command::Bench {
            which:
                BenchCommand::Peers {
                    problems,
                    repeats,
                    tol,
                    max_iters,
                    traj_dir,
                    lqr_nx,
                    lqr_nu,
                    lqr_n,
                    lqr_seed,
                    lqr_umax,
                },
        } => {
            let args = bench_solve::PeersArgs {
                problems,
                repeats,
                tol,
                max_iters,
                traj_dir,
                params: gharial_problems::peers::PeersLqrParams {
                    nx: lqr_nx,
                    nu: lqr_nu,
                    horizon: lqr_n,
                    seed: lqr_seed,
                    umax: lqr_umax,
                },
            };
            std::process::exit(bench_solve::peers(&args));
        }
        Command::Bench {
            which:
                BenchCommand::Riccati {
                    threads,
                    horizons,
                    dims,
                    extra,
                    mu,
                    seed,
                    budget,
                    rounds,
                    refine,
                },
        } => {
            let parsed = parse_dims(&dims, 3).and_then(|d| {
                let extra = extra
                    .iter()
                    .filter(|e| !e.is_empty())
                    .map(|e| parse_dims(e, 4).map(|v| (v[0], v[1], v[2], v[3])))
                    .collect::<Result<Vec<_>, _>>()?;
                Ok((d, extra))
            });
            let (d, extra) = match parsed {
                Ok(v) => v,
                Err(e) => {
                    eprintln!("gharial bench riccati: {e}");
                    std::process::exit(2);
                }
            };
            bench::run(&bench::RiccatiBench {
                dims: (d[0], d[1], d[2]),
                horizons,
                extra,
                threads,
                mu,
                seed,
                budget,
                rounds,
                refine,
            });
        }
    }
}

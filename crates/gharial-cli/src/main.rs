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
        /// Active-set prediction iterations per step (0: the plain Newton step; at most 100).
        #[arg(long, value_parser = count(0, ACTIVE_SET_ITERS_MAX))]
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
        /// Timed solves per problem (at most 10,000).
        #[arg(long, default_value_t = 5, value_parser = count(1, MAX_REPEATS))]
        repeats: usize,
        /// Forward pass (default: each problem's recommended one).
        #[arg(long, value_enum)]
        rollout: Option<RolloutArg>,
        /// Active-set prediction iterations per step (default: each problem's setting).
        #[arg(long)]
        active_set_iters: Option<usize>,
    },
    /// The problems of the peer harness, as JSON lines in its format.
    Peers {
        /// Harness problem names, comma separated (a name gharial does not have gets a
        /// line with an `error`).
        #[arg(long, value_delimiter = ',', default_values_t = HARNESS_PROBLEMS.iter().map(|s| s.to_string()).collect::<Vec<_>>())]
        problems: Vec<String>,
        /// Timed solves per problem and solver (at most 10,000).
        #[arg(long, default_value_t = 5, value_parser = count(1, MAX_REPEATS))]
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
        #[arg(long, default_value_t = 8, value_parser = count(1, MAX_DIM))]
        lqr_nx: usize,
        /// Control size.
        #[arg(long, default_value_t = 4, value_parser = count(1, MAX_DIM))]
        lqr_nu: usize,
        /// Horizon.
        #[arg(long = "lqr-N", default_value_t = 100, value_parser = count(1, MAX_HORIZON))]
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
        /// Thread counts (legs of the parallel solver) to time (1 = the serial solver),
        /// comma separated.
        #[arg(long, value_delimiter = ',', default_values_t = vec![1, 2], value_parser = count(1, MAX_LEGS))]
        threads: Vec<usize>,
        /// Horizons of the main series, comma separated.
        #[arg(long, value_delimiter = ',', default_values_t = vec![16, 32, 64, 128, 256, 512, 1024], value_parser = count(1, MAX_HORIZON))]
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
        /// Time budget per case and solver, in seconds (at most 3600).
        #[arg(long, default_value_t = 1.0, value_parser = budget)]
        budget: f64,
        /// Passes over the case list (the budget is split between them; at most 1000).
        #[arg(long, default_value_t = 4, value_parser = count(1, MAX_ROUNDS))]
        rounds: usize,
        /// Iterative refinement steps (at most 10).
        #[arg(long, default_value_t = 0, value_parser = count(0, MAX_REFINE))]
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
        gharial::solvers::proxddp::TABLE.legend()
    )
}

/// The peer harness's default problems.
const HARNESS_PROBLEMS: [&str; 8] = [
    "lqr",
    "lqr_box",
    "lqr_box_term",
    "ur5",
    "ur5_box",
    "pendulum",
    "pendulum_box",
    "pendulum_box_term",
];

/// Upper limits of the command line's counts: beyond them a benchmark would run for
/// days or allocate more memory than a machine has, which is a mistake to report, not
/// a job to start.
const MAX_REPEATS: usize = 10_000;
const MAX_ROUNDS: usize = 1_000;
const MAX_REFINE: usize = 10;
const MAX_LEGS: usize = 1_024;
const MAX_DIM: usize = 1_000;
const MAX_HORIZON: usize = 1_000_000;
use gharial::solvers::proxddp::ACTIVE_SET_ITERS_MAX;

/// The memory a benchmark may plan to use.
const MEMORY_BUDGET: f64 = 16.0 * (1u64 << 30) as f64;

/// Refuses a case whose estimated memory exceeds [`MEMORY_BUDGET`]; `bytes_per_entry`
/// is the bytes per knot and per entry of an `n x n` block with `n = nx + nu + nc`.
fn check_memory(what: &str, n: usize, horizon: usize, bytes_per_entry: f64) -> Result<(), String> {
    let bytes = bytes_per_entry * (n * n) as f64 * horizon as f64;
    if bytes <= MEMORY_BUDGET {
        Ok(())
    } else {
        Err(format!(
            "{what}: about {:.0} GiB needed, more than the {:.0} GiB a benchmark may use",
            bytes / (1u64 << 30) as f64,
            MEMORY_BUDGET / (1u64 << 30) as f64
        ))
    }
}

/// An integer in `lo..=hi`.
fn count(lo: usize, hi: usize) -> impl Fn(&str) -> Result<usize, String> + Clone + Send + Sync + 'static {
    move |s: &str| match s.parse::<usize>() {
        Ok(v) if (lo..=hi).contains(&v) => Ok(v),
        Ok(_) => Err(format!("must be between {lo} and {hi}")),
        Err(e) => Err(e.to_string()),
    }
}

/// A time budget in seconds: finite, positive, at most an hour.
fn budget(s: &str) -> Result<f64, String> {
    let v = positive_real(s)?;
    if v <= 3600.0 {
        Ok(v)
    } else {
        Err(format!("must be at most 3600 s, got {v}"))
    }
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
        Ok(v) if v.len() == n && v.iter().take(3).any(|&d| d > MAX_DIM) => {
            Err(format!("`{s}`: nx, nu and nc must be at most {MAX_DIM}"))
        }
        Ok(v) if v.len() == n && n == 4 && v[3] > MAX_HORIZON => Err(format!("`{s}`: N must be at most {MAX_HORIZON}")),
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
            // Measured: ProxDDP holds about 40 doubles per entry of (nx + nu)² per stage.
            if let Err(e) = check_memory("the LQR family", lqr_nx + lqr_nu, lqr_n + 1, 40.0 * 8.0) {
                eprintln!("gharial bench peers: {e}");
                std::process::exit(2);
            }
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
            let parsed = parsed.and_then(|(d, extra)| {
                let cases = horizons
                    .iter()
                    .map(|&n| (d[0], d[1], d[2], n))
                    .chain(extra.iter().copied());
                for (nx, nu, nc, n) in cases {
                    check_memory(&format!("case {nx}:{nu}:{nc}:{n}"), nx + nu + nc, n + 1, 16.0 * 8.0)?;
                }
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

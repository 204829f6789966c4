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
mod bench_profile;
mod bench_solve;
mod plot;
mod simulate;
mod sketch;
mod solve;
mod solver_choice;
mod view;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "gharial", version, about = "Constrained trajectory optimization for robots")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List the built-in problems and solvers.
    List,
    /// Solve a built-in problem: iteration table, summary, optional JSON output.
    Solve(solve::SolveArgs),
    /// Draw the convergence and trajectory plots of a solution file (PNG or SVG).
    Plot(plot::PlotArgs),
    /// Write the 3D viewer page of a solution of a robot problem (one self-contained HTML
    /// file), optionally serving it on localhost.
    View(view::ViewArgs),
    /// Run a receding-horizon scenario in closed loop: cycle times, iterations,
    /// statuses, the scenario's metrics, optional JSON output.
    Simulate(simulate::SimulateArgs),
    /// Benchmarks.
    Bench {
        #[command(subcommand)]
        which: BenchCommand,
    },
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Iterations, time per solve and per iteration of the built-in problems, with any
    /// solver (problems it does not take are listed as skipped).
    Solve(bench_solve::ExamplesArgs),
    /// The problems of the peer harness, as JSON lines in its format: every gharial
    /// solver on the problems it takes.
    Peers(bench_solve::PeersArgs),
    /// The stagewise-SQP paper's Fig. 1: the fraction of a randomised family's instances
    /// each solver solves within an iteration budget, as CSV.
    Profile(bench_profile::ProfileArgs),
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

/// The part of `gharial solve --help` after the options: the tables' columns and the
/// exit codes.
fn solve_help() -> String {
    format!(
        "{}\n\nThe settings line marks values that are not the library's defaults: \
         [problem] for the problem's recommended settings, [option] for the command line.\n\n\
         Exit code: 0 converged, 1 stopped for another reason (the status says which), 2 invalid input \
         (including an option the solver does not take, and a problem it does not take).",
        solver_choice::tables_legend()
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

/// An output file of `gharial <command>`, created before any work (an unwritable output
/// is invalid input: the error, printed, gives exit code 2).
struct Output<'a> {
    path: &'a str,
    file: std::fs::File,
}

impl<'a> Output<'a> {
    /// The file at `path`, if one is asked for.
    fn create(command: &str, path: Option<&'a str>) -> Result<Option<Self>, i32> {
        match path.map(|p| (p, std::fs::File::create(p))) {
            None => Ok(None),
            Some((path, Ok(file))) => Ok(Some(Self { path, file })),
            Some((path, Err(e))) => {
                eprintln!("gharial {command}: cannot write {path}: {e}");
                Err(2)
            }
        }
    }

    /// Writes `doc` as pretty JSON and says so (`what`: the document's name); `false`
    /// (with a message) if the write fails.
    fn write_json(&mut self, command: &str, what: &str, doc: &serde_json::Value) -> bool {
        use std::io::Write as _;
        let text = serde_json::to_string_pretty(doc).expect("JSON of plain numbers");
        match self.file.write_all(text.as_bytes()) {
            Ok(()) => {
                out!("{what:<9} written to {}", self.path);
                true
            }
            Err(e) => {
                eprintln!("gharial {command}: cannot write {}: {e}", self.path);
                false
            }
        }
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
        Command::Solve(args) => std::process::exit(solve::run(&args)),
        Command::Simulate(args) => std::process::exit(simulate::run(&args)),
        Command::Plot(args) => std::process::exit(plot::run(&args)),
        Command::View(args) => std::process::exit(view::run(&args)),
        Command::Bench {
            which: BenchCommand::Solve(args),
        } => std::process::exit(bench_solve::examples(&args)),
        Command::Bench {
            which: BenchCommand::Peers(args),
        } => std::process::exit(bench_solve::peers(&args)),
        Command::Bench {
            which: BenchCommand::Profile(args),
        } => std::process::exit(bench_profile::run(&args)),
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
            let bench = bench::RiccatiBench {
                dims: (d[0], d[1], d[2]),
                horizons,
                extra,
                threads,
                mu,
                seed,
                budget,
                rounds,
                refine,
            };
            if let Err(e) = bench::run(&bench) {
                eprintln!("gharial bench riccati: {e}");
                std::process::exit(2);
            }
        }
    }
}

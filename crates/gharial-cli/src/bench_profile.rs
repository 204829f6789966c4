//! `gharial bench profile`: the stagewise-SQP paper's Fig. 1 (Jordana et al. 2023,
//! §VI-A): the fraction of a randomised family's instances
//! ([`gharial_problems::profiles`]) each solver solves within an iteration budget.
//!
//! Every instance is solved once per solver, by a freshly built and set-up solver, from
//! the instance's warm start, on one thread, with the iteration limit one above the
//! largest budget (so that the point after the last budgeted step is tested too). An
//! instance is solved within a budget `b` when the convergence test passes at a point
//! reached in at most `b` iterations. `--criterion` chooses the test, at `--tol`
//! (default `1e-4`, the paper's):
//! - `kkt` (default: one test for every member of the DDP family, as in the paper):
//!   the residual of the iteration's row, `max(|gaps|_∞, |Q_u|_∞)`, for DDP, FDDP,
//!   FDDP (filter LS) and SQP alike (`Q_u = ∇_u L` with the co-states `v + V γ` of the
//!   backward pass: the paper's (20) without its `∇_x L` part, which these co-states
//!   reduce to a multiple of `Q_u`); their own tests are switched off. ProxDDP and CSQP:
//!   `max(prim_err, dual_err)` of their rows, or their own convergence (a test of the
//!   same residuals). The solve is interrupted once the test passes.
//! - `own`: each solver's own convergence test (the DDP family's: the expected decrease
//!   of a full step below `tol² N` with the gaps closed).
//!
//! Each curve is non-decreasing by construction. `fddp-filter` is FDDP with SQP's filter
//! line search ("FDDP (filter LS)"); as in the paper, the filters of SQP and
//! `fddp-filter` remember as many iterates as the iteration limit (at most 1000) unless
//! `--filter-size` says otherwise.

use std::io::Write;

use clap::ValueEnum;
use gharial::error::Num;
use gharial::solvers::ddp::DdpVariant;
use gharial::solvers::{Callback, InitialGuess, SolverOptions};
use gharial_problems::Example;
use gharial_problems::profiles::{self, FirstKkt, MAX_COUNT};

use crate::count;
use crate::positive_real;
use crate::solver_choice::{CommonArgs, SolverArgs, SolverConfig, SolverKind};

/// Largest iteration budget (the filter's memory is bounded by 1000).
const MAX_BUDGET: usize = 999;

/// Which convergence test decides that an instance is solved (module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Criterion {
    /// The KKT residual of every iteration, the same test for every solver (the paper's).
    Kkt,
    /// Each solver's own convergence test.
    Own,
}

/// A solver of the profile: a solver of the library, or FDDP with the filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ProfileSolver {
    kind: SolverKind,
    filter: bool,
}

impl ProfileSolver {
    /// The command-line name (a solver's name, or `fddp-filter`).
    fn name(self) -> &'static str {
        if self.filter { "fddp-filter" } else { self.kind.name() }
    }

    /// The solver's settings on `ex`: one thread, the iteration limit `max_budget + 1`,
    /// the DDP family's own tests switched off for the KKT criterion.
    fn config(self, ex: &Example, args: &ProfileArgs) -> SolverConfig {
        let max_iters = args.max_budget + 1;
        let solver = SolverArgs {
            common: CommonArgs {
                tol: Some(args.tol),
                max_iters: Some(max_iters),
                threads: Some(1),
                hessian: None,
            },
            ..SolverArgs::new(self.kind)
        };
        let mut config = solver.config(ex);
        if let SolverOptions::Ddp(o) = &mut config.options {
            o.filter_linesearch = self.filter;
            o.filter_size = args.filter_size.unwrap_or(max_iters);
            if args.criterion == Criterion::Kkt {
                o.th_stop = Some(f64::MIN_POSITIVE);
            }
        }
        config
    }
}

/// Parses a solver name of the profile.
fn solver_name(s: &str) -> Result<ProfileSolver, String> {
    if s == "fddp-filter" {
        return Ok(ProfileSolver {
            kind: SolverKind::Ddp(DdpVariant::Fddp),
            filter: true,
        });
    }
    SolverKind::from_str(s, false)
        .map(|kind| ProfileSolver { kind, filter: false })
        .map_err(|_| {
            let names: Vec<_> = SolverKind::ALL.iter().map(|k| k.name()).collect();
            format!("unknown solver `{s}`; valid names: {}, fddp-filter", names.join(", "))
        })
}

/// The arguments of `gharial bench profile`.
#[derive(clap::Args, Debug, Clone)]
pub struct ProfileArgs {
    /// Instance family: reach, quadrotor, pendulum or humanoid.
    pub family: String,
    /// Solvers, comma separated (any solver's name, and fddp-filter).
    #[arg(long, value_delimiter = ',', value_parser = solver_name,
          default_value = "ddp,fddp,fddp-filter,sqp,proxddp")]
    pub solvers: Vec<ProfileSolver>,
    /// Instances (at most 10,000).
    #[arg(long, default_value_t = 100, value_parser = count(1, MAX_COUNT))]
    pub count: usize,
    /// Seed of the instances' initial states.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Largest iteration budget: the curves have the budgets 1..=max-budget (at most 999).
    #[arg(long, default_value_t = 100, value_parser = count(1, MAX_BUDGET))]
    pub max_budget: usize,
    /// Tolerance of the convergence test.
    #[arg(long, default_value_t = 1e-4, value_parser = positive_real)]
    pub tol: f64,
    /// Memory of the filters of SQP and fddp-filter (default: the iteration limit, the
    /// paper's choice; at most 1000).
    #[arg(long, value_parser = count(1, MAX_BUDGET + 1))]
    pub filter_size: Option<usize>,
    /// Convergence test: the KKT residual for every solver, or each solver's own.
    #[arg(long, value_enum, default_value = "kkt")]
    pub criterion: Criterion,
    /// CSV file for the curves (default: standard output).
    #[arg(long)]
    pub output: Option<String>,
    /// Draw the curves into this image file (`.png` or `.svg`).
    #[arg(long)]
    pub plot: Option<String>,
}

/// The iterations each solver took to converge on each instance (`None`: not within
/// the budget), and its total solve time.
struct Outcome {
    iterations: Vec<Option<usize>>,
    seconds: f64,
}

/// Solves every instance with `solver`.
fn run_solver(solver: ProfileSolver, instances: &[Example], args: &ProfileArgs) -> Result<Outcome, String> {
    let mut outcome = Outcome {
        iterations: Vec::with_capacity(instances.len()),
        seconds: 0.0,
    };
    for (i, ex) in instances.iter().enumerate() {
        let mut s = solver.config(ex, args).options.build();
        s.setup(&ex.problem)
            .map_err(|e| format!("{} refuses {} instance {i}: {e}", solver.name(), args.family))?;
        let mut watch = FirstKkt::new(args.tol);
        let callback: Option<&mut dyn Callback> = match args.criterion {
            Criterion::Kkt => Some(&mut watch),
            Criterion::Own => None,
        };
        let solved = match s.solve_with(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0), callback) {
            Ok(sol) => {
                outcome.seconds += sol.solve_time.as_secs_f64();
                let own = sol.status.converged().then_some(sol.iterations);
                let kkt = if args.criterion == Criterion::Kkt {
                    watch.solved_at(sol)
                } else {
                    None
                };
                match (kkt, own) {
                    (Some(a), Some(b)) => Some(a.min(b)),
                    (a, b) => a.or(b),
                }
            }
            Err(e) => {
                eprintln!("gharial bench profile: {} on instance {i}: {e}", solver.name());
                None
            }
        };
        outcome.iterations.push(solved);
    }
    Ok(outcome)
}

/// Fraction of the instances solved within `budget` iterations.
fn fraction(outcome: &Outcome, budget: usize) -> f64 {
    let solved = outcome
        .iterations
        .iter()
        .filter(|i| i.is_some_and(|i| i <= budget))
        .count();
    solved as f64 / outcome.iterations.len().max(1) as f64
}

/// The curves as CSV: `budget` then one column per solver.
fn csv(solvers: &[ProfileSolver], outcomes: &[Outcome], max_budget: usize) -> String {
    let mut text = String::from("budget");
    for s in solvers {
        text.push(',');
        text.push_str(s.name());
    }
    text.push('\n');
    for b in 1..=max_budget {
        text.push_str(&b.to_string());
        for o in outcomes {
            text.push_str(&format!(",{}", fraction(o, b)));
        }
        text.push('\n');
    }
    text
}

/// Draws the curves into `path`; `false` (with a message) if that fails.
fn plot(args: &ProfileArgs, outcomes: &[Outcome], path: &str) -> bool {
    let curves: Vec<gharial_viz::ProfileCurve> = args
        .solvers
        .iter()
        .zip(outcomes)
        .map(|(s, o)| gharial_viz::ProfileCurve {
            label: s.name().to_string(),
            budget: (1..=args.max_budget).map(|b| b as f64).collect(),
            solved: (1..=args.max_budget).map(|b| fraction(o, b)).collect(),
        })
        .collect();
    let title = format!(
        "{} family, {} instances, tol {}",
        args.family,
        args.count,
        Num(args.tol)
    );
    match gharial_viz::profile(&curves, &title, std::path::Path::new(path)) {
        Ok(_) => {
            eprintln!("plot written to {path}");
            true
        }
        Err(e) => {
            eprintln!("gharial bench profile: {e}");
            false
        }
    }
}

/// The summary: the fractions at the paper's marks and the time per solve.
fn print_summary(args: &ProfileArgs, outcomes: &[Outcome]) {
    let marks: Vec<usize> = [1, 5, 10, 20, 50, 100, 200, 500, 1000]
        .into_iter()
        .filter(|&b| b < args.max_budget)
        .chain([args.max_budget])
        .collect();
    out!(
        "family {}, {} instances, seed {}, {:?} test at tol {}: fraction solved within a budget of iterations",
        args.family,
        args.count,
        args.seed,
        args.criterion,
        Num(args.tol)
    );
    let mut header = format!("{:<12}", "solver");
    for b in &marks {
        header.push_str(&format!(" {:>6}", format!("<={b}")));
    }
    out!("{header} {:>12}", "ms/solve");
    for (s, o) in args.solvers.iter().zip(outcomes) {
        let mut line = format!("{:<12}", s.name());
        for &b in &marks {
            line.push_str(&format!(" {:>6.2}", fraction(o, b)));
        }
        out!("{line} {:>12.3}", 1e3 * o.seconds / args.count as f64);
    }
}

/// `gharial bench profile`: exit code 0, 1 if the CSV file cannot be written, 2 for bad
/// input (an unknown family, a solver that refuses the family's problems).
pub fn run(args: &ProfileArgs) -> i32 {
    if let Some(path) = &args.plot
        && !(path.ends_with(".png") || path.ends_with(".svg"))
    {
        eprintln!("gharial bench profile: --plot {path}: the file name must end in .png or .svg");
        return 2;
    }
    let instances = match profiles::family(&args.family, args.seed, args.count) {
        Ok(v) => v,
        Err(e) => {
            eprintln!("gharial bench profile: {e}");
            return 2;
        }
    };
    let mut outcomes = Vec::with_capacity(args.solvers.len());
    for &solver in &args.solvers {
        match run_solver(solver, &instances, args) {
            Ok(o) => outcomes.push(o),
            Err(e) => {
                eprintln!("gharial bench profile: {e}");
                return 2;
            }
        }
    }
    if let Some(path) = &args.plot
        && !plot(args, &outcomes, path)
    {
        return 1;
    }
    let table = csv(&args.solvers, &outcomes, args.max_budget);
    match &args.output {
        Some(path) => {
            if let Err(e) = std::fs::write(path, table) {
                eprintln!("gharial bench profile: cannot write {path}: {e}");
                return 1;
            }
            print_summary(args, &outcomes);
        }
        None => {
            if std::io::stdout().write_all(table.as_bytes()).is_err() {
                return 0;
            }
        }
    }
    0
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::{ProfileArgs, run_solver, solver_name};

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        args: ProfileArgs,
    }

    /// Instance 22 of `pendulum` starts almost upright: FDDP's expected decrease falls
    /// below round-off after two iterations and it stops (`Stalled`) at a point whose
    /// gaps and `|Q_u|` pass the test, which the callback never sees; it counts as solved
    /// there (crocoddyl's FDDP passes the same test after two iterations).
    #[test]
    fn a_final_point_that_passes_the_test_counts() {
        let args = Cli::parse_from(["profile", "pendulum", "--count", "23"]).args;
        let instances = gharial_problems::profiles::family("pendulum", args.seed, 23).unwrap();
        let fddp = solver_name("fddp").unwrap();
        let outcome = run_solver(fddp, &instances[22..], &args).unwrap();
        assert_eq!(outcome.iterations, [Some(2)]);
    }
}

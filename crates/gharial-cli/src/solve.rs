//! `gharial list` and `gharial solve`: build a catalogue problem, solve it, print the
//! iteration table and a summary, and write the solution as JSON.

use std::io::Write;

use gharial::solvers::log::{LogSink, Table};
use gharial::solvers::{InitialGuess, IterationRecord, Solution};
use gharial_problems::Example;
use serde_json::json;

use crate::solver_choice::{SolverArgs, SolverConfig, SolverKind};

/// The arguments of `gharial solve`.
#[derive(clap::Args, Debug, Clone)]
#[command(after_help = crate::solve_help())]
pub struct SolveArgs {
    /// Problem name (see `gharial list`).
    pub problem: String,
    /// Print the solver's live log (ProxDDP: with outer updates) instead of the table
    /// afterwards.
    #[arg(long)]
    pub verbose: bool,
    /// Write the solution, settings and history to this JSON file.
    #[arg(long)]
    pub output: Option<String>,
    /// Draw the convergence and trajectory plots into this directory (created if missing).
    #[arg(long)]
    pub plot: Option<String>,
    /// Image format of `--plot`.
    #[arg(long, value_enum, default_value = "png")]
    pub plot_format: crate::plot::Format,
    /// Write the data of the paper's figures as CSV files into this directory (created if
    /// missing; for the experiments that have them: ur10-ballistic, solo-jump).
    #[arg(long)]
    pub figures: Option<String>,
    // The solver and its options (last: their help headings follow).
    #[command(flatten)]
    pub solver: SolverArgs,
}

/// Prints the solvers and the catalogue.
pub fn list() {
    out!("solvers:");
    for kind in SolverKind::ALL {
        out!("  {:<10} {}", kind.name(), kind.summary());
    }
    out!();
    out!("problems:");
    for p in gharial_problems::catalogue() {
        out!("  {:<20} {}", p.name, p.summary);
    }
    out!();
    out!("closed-loop scenarios (gharial simulate):");
    for (name, summary) in gharial_problems::mpc::SCENARIOS {
        out!("  {name:<28} {summary}");
    }
}

/// Runs `gharial solve`; returns the process exit code.
pub fn run(args: &SolveArgs) -> i32 {
    let (example, mut output) = match prepare(args) {
        Ok(v) => v,
        Err(code) => return code,
    };
    let mut config = args.solver.config(&example);
    if args.verbose {
        config.options.set_log(LogSink::Stderr);
    }
    let p = &example.problem;
    let mut solver = config.options.build();
    // A problem the solver does not take is invalid input: refuse it before printing.
    if let Err(e) = solver.setup(p) {
        eprintln!("gharial solve: {e}");
        return 2;
    }
    out!(
        "problem   {} (N = {}, nx = {}, ndx = {}, nu = {})",
        example.name,
        p.horizon(),
        p.space(0).nx(),
        p.space(0).ndx(),
        p.nu(0)
    );
    out!(
        "solver    {} ({})",
        config.kind.label(),
        config.settings_line(&example, &args.solver)
    );
    let table = solver.table();
    let sol = match solver.solve_with(p, InitialGuess::primal(&example.xs0, &example.us0), None) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("gharial solve: {e}");
            return 2;
        }
    };
    if !args.verbose {
        print_table(table, &sol.history);
    }
    print_summary(config.kind, sol);
    if !write_outputs(args, &example, &config, sol, output.as_mut()) {
        return 1;
    }
    let code = if sol.status.converged() { 0 } else { 1 };
    // Everything is written: exit without freeing the problem and the solver one
    // allocation at a time (seconds for horizons of 10^5 stages).
    std::io::stdout().flush().ok();
    std::process::exit(code)
}

/// Checks the invocation before any work: the solver's options, the problem's name, an
/// output file that can be written and the directories of `--figures` and `--plot`.
/// `Err` holds the exit code (the message is printed).
fn prepare(args: &SolveArgs) -> Result<(Example, Option<crate::Output<'_>>), i32> {
    if let Err(e) = args.solver.check() {
        eprintln!("gharial solve: {e}");
        return Err(2);
    }
    let example = gharial_problems::build(&args.problem).map_err(|e| {
        eprintln!("gharial solve: {e}");
        2
    })?;
    // Unwritable outputs are invalid input: refuse them before the solve.
    let output = crate::Output::create("solve", args.output.as_deref())?;
    // Directories are created if missing, as `gharial plot --out` does.
    for (option, dir) in [("--figures", &args.figures), ("--plot", &args.plot)] {
        if let Some(dir) = dir
            && let Err(e) = std::fs::create_dir_all(dir)
        {
            eprintln!("gharial solve: {option} {dir}: cannot create the directory: {e}");
            return Err(2);
        }
    }
    Ok((example, output))
}

/// Writes the solution's JSON, plots and figure files that were asked for; `false` (with
/// a message) if one of them failed.
fn write_outputs(
    args: &SolveArgs,
    example: &Example,
    config: &SolverConfig,
    sol: &Solution,
    output: Option<&mut crate::Output>,
) -> bool {
    let doc = (output.is_some() || args.plot.is_some()).then(|| solution_json(example, config, sol));
    let written = output
        .zip(doc.as_ref())
        .is_none_or(|(o, doc)| o.write_json("solve", "solution", doc));
    let plotted = args
        .plot
        .as_ref()
        .zip(doc.as_ref())
        .is_none_or(|(dir, doc)| crate::plot::draw_document(doc, dir, args.plot_format));
    let figures = args
        .figures
        .as_ref()
        .is_none_or(|dir| write_figures(example.name, sol, dir));
    written && figures && plotted
}

/// Writes the figure files of `name` into `dir`; `false` (with a message) if that fails.
fn write_figures(name: &str, sol: &Solution, dir: &str) -> bool {
    let files = match gharial_problems::figures::figures(name, sol) {
        None => {
            out!("figures   {name} has no figure data");
            return true;
        }
        Some(Err(e)) => {
            eprintln!("gharial solve: figures: {e}");
            return false;
        }
        Some(Ok(f)) => f,
    };
    for (file, text) in files {
        let path = std::path::Path::new(dir).join(file);
        if let Err(e) = std::fs::write(&path, text) {
            eprintln!("gharial solve: cannot write {}: {e}", path.display());
            return false;
        }
        out!("figure    written to {}", path.display());
    }
    true
}

/// A solver's iteration table (`gharial solve --help` explains the columns).
pub fn print_table(table: Table, history: &[IterationRecord]) {
    out!("{}", table.header());
    for r in history {
        out!("{}", table.row(r));
    }
}

fn print_summary(kind: SolverKind, sol: &Solution) {
    let ms = sol.solve_time.as_secs_f64() * 1e3;
    out!("status    {}", sol.status);
    if kind == SolverKind::ProxDdp {
        out!(
            "iterations {} (augmented-Lagrangian iterations {})",
            sol.iterations,
            sol.al_iterations
        );
    } else {
        out!("iterations {}", sol.iterations);
    }
    out!("cost      {:.10e}", sol.cost);
    out!("residuals primal {:.3e}, dual {:.3e}", sol.prim_err, sol.dual_err);
    out!(
        "time      {ms:.3} ms ({:.4} ms per iteration)",
        ms / (sol.iterations.max(1) as f64)
    );
}

/// The solution, the settings and the history as a JSON document.
pub fn solution_json(example: &Example, config: &SolverConfig, sol: &Solution) -> serde_json::Value {
    let history: Vec<_> = sol
        .history
        .iter()
        .map(|r| {
            json!({
                "iter": r.iter, "alpha": r.alpha, "inner_crit": r.inner_crit, "prim_err": r.prim_err,
                "dual_err": r.dual_err, "preg": r.preg, "cost": r.cost, "dphi0": r.dphi0,
                "merit": r.merit, "dmerit": r.dmerit, "al_iter": r.al_iter, "mu": r.mu,
                "stop": r.stop, "expected_decrease": r.expected_decrease, "decrease": r.decrease,
            })
        })
        .collect();
    let gains: Vec<_> = sol
        .feedback
        .iter()
        .map(|k| {
            (0..k.nrows())
                .map(|i| (0..k.ncols()).map(|j| k[(i, j)]).collect::<Vec<_>>())
                .collect::<Vec<_>>()
        })
        .collect();
    let feedforward: Vec<Vec<f64>> = sol
        .feedforward
        .iter()
        .map(|k| (0..k.nrows()).map(|i| k[i]).collect())
        .collect();
    // The control bounds where the path constraints are bounds on the controls (JSON
    // writes the infinite ones as null).
    let (u_lower, u_upper) = match gharial::solvers::ddp::control_bounds(&example.problem, &sol.xs, &sol.us) {
        Ok((lb, ub)) => (json!(lb), json!(ub)),
        Err(_) => (serde_json::Value::Null, serde_json::Value::Null),
    };
    json!({
        "problem": example.name,
        "solver": config.kind.name(),
        "dt": example.dt,
        "settings": config.settings_json(),
        "status": sol.status.name(),
        "converged": sol.status.converged(),
        "iterations": sol.iterations,
        "al_iterations": sol.al_iterations,
        "cost": sol.cost,
        "prim_err": sol.prim_err,
        "dual_err": sol.dual_err,
        "mu": sol.mu,
        "solve_time_ms": sol.solve_time.as_secs_f64() * 1e3,
        "xs": sol.xs,
        "us": sol.us,
        "lambdas": sol.lambdas,
        "nus": sol.nus,
        "feedforward": feedforward,
        "feedback": gains,
        "history": history,
        "u_lower": u_lower,
        "u_upper": u_upper,
    })
}

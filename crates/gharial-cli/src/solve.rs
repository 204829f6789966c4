//! `gharial list` and `gharial solve`: build a catalogue problem, solve it, print the
//! iteration table and a summary, and write the solution as JSON.

use std::io::Write;

use gharial::error::Num;
use gharial::solvers::proxddp::{Merit, ProxDdp, ProxDdpOptions, Rollout, StepAcceptance};
use gharial::solvers::{InitialGuess, IterationRecord, Solution};
use gharial_problems::Example;
use serde_json::json;

/// Command-line overrides of the recommended solver settings.
#[derive(Debug, Clone, Default)]
pub struct SolveArgs {
    /// Problem name.
    pub problem: String,
    /// Solver name.
    pub solver: String,
    /// Tolerance.
    pub tol: Option<f64>,
    /// Initial AL penalty.
    pub mu_init: Option<f64>,
    /// Dynamics penalty scale.
    pub dyn_al_scale: Option<f64>,
    /// Active-set prediction iterations per step.
    pub active_set_iters: Option<usize>,
    /// Iteration limit.
    pub max_iters: Option<usize>,
    /// Rollout.
    pub rollout: Option<Rollout>,
    /// Step acceptance.
    pub step_acceptance: Option<StepAcceptance>,
    /// Merit function.
    pub merit: Option<Merit>,
    /// Threads for stage-wise evaluation.
    pub threads: Option<usize>,
    /// Live iteration log (with outer updates) instead of the table printed afterwards.
    pub verbose: bool,
    /// Where to write the solution.
    pub output: Option<String>,
}

/// Prints the catalogue and the solvers.
pub fn list() {
    out!("solvers:");
    out!("  proxddp   primal-dual augmented-Lagrangian DDP (Jallet et al. 2023)");
    out!();
    out!("problems:");
    for p in gharial_problems::catalogue() {
        out!("  {:<20} {}", p.name, p.summary);
    }
}

/// The example's recommended options with the command-line overrides applied.
pub fn options(example: &Example, args: &SolveArgs) -> ProxDdpOptions {
    let mut o = example.proxddp.clone();
    if let Some(v) = args.tol {
        o.tol = v;
    }
    if let Some(v) = args.mu_init {
        o.mu_init = v;
        o.mu_lower_bound = o.mu_lower_bound.min(v);
    }
    if let Some(v) = args.dyn_al_scale {
        o.dyn_al_scale = v;
    }
    if let Some(v) = args.active_set_iters {
        o.active_set_iters = v;
    }
    if let Some(v) = args.max_iters {
        o.max_iters = v;
    }
    if let Some(v) = args.rollout {
        o.rollout = v;
    }
    if let Some(v) = args.step_acceptance {
        o.step_acceptance = v;
    }
    if let Some(v) = args.merit {
        o.merit = v;
    }
    if let Some(v) = args.threads {
        o.num_threads = v;
    }
    if args.verbose {
        o.log = gharial::solvers::log::LogSink::Stderr;
    }
    o
}

/// Runs `gharial solve`; returns the process exit code.
pub fn run(args: &SolveArgs) -> i32 {
    if args.solver != "proxddp" {
        eprintln!("gharial solve: unknown solver `{}`; available: proxddp", args.solver);
        return 2;
    }
    let example = match gharial_problems::build(&args.problem) {
        Ok(e) => e,
        Err(e) => {
            eprintln!("gharial solve: {e}");
            return 2;
        }
    };
    // An unwritable output is invalid input: refuse it before the solve.
    let mut output = match args.output.as_deref().map(|p| (p, std::fs::File::create(p))) {
        None => None,
        Some((path, Ok(file))) => Some((path, file)),
        Some((path, Err(e))) => {
            eprintln!("gharial solve: cannot write {path}: {e}");
            return 2;
        }
    };
    let opts = options(&example, args);
    let p = &example.problem;
    out!(
        "problem   {} (N = {}, nx = {}, ndx = {}, nu = {})",
        example.name,
        p.horizon(),
        p.space(0).nx(),
        p.space(0).ndx(),
        p.nu(0)
    );
    out!("solver    ProxDDP ({})", settings_line(&example.proxddp, args, &opts));
    let mut solver = ProxDdp::new(opts.clone());
    if let Err(e) = solver.setup(p) {
        eprintln!("gharial solve: {e}");
        return 2;
    }
    let sol = match solver.solve(p, InitialGuess::primal(&example.xs0, &example.us0)) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("gharial solve: {e}");
            return 2;
        }
    };
    if !args.verbose {
        print_table(&sol.history);
    }
    print_summary(sol);
    if let Some((path, file)) = output.as_mut() {
        let doc = solution_json(&example, &opts, sol);
        let text = serde_json::to_string_pretty(&doc).expect("JSON of plain numbers");
        match file.write_all(text.as_bytes()) {
            Ok(()) => out!("solution  written to {path}"),
            Err(e) => {
                eprintln!("gharial solve: cannot write {path}: {e}");
                return 1;
            }
        }
    }
    let code = if sol.status.converged() { 0 } else { 1 };
    // Everything is written: exit without freeing the problem and the solver one
    // allocation at a time (seconds for horizons of 10^5 stages).
    std::io::stdout().flush().ok();
    std::process::exit(code)
}

/// The solver settings, each marked with where it came from when it is not the
/// library's default: `[problem]` (the problem's recommended settings) or `[option]`
/// (the command line).
fn settings_line(recommended: &ProxDdpOptions, args: &SolveArgs, o: &ProxDdpOptions) -> String {
    type Field = (&'static str, fn(&ProxDdpOptions) -> String, bool);
    let fields: [Field; 9] = [
        ("tol", |o| Num(o.tol).to_string(), args.tol.is_some()),
        ("mu_init", |o| Num(o.mu_init).to_string(), args.mu_init.is_some()),
        (
            "dyn_al_scale",
            |o| Num(o.dyn_al_scale).to_string(),
            args.dyn_al_scale.is_some(),
        ),
        ("max_iters", |o| o.max_iters.to_string(), args.max_iters.is_some()),
        ("rollout", |o| format!("{:?}", o.rollout), args.rollout.is_some()),
        (
            "step acceptance",
            |o| format!("{:?}", o.step_acceptance),
            args.step_acceptance.is_some(),
        ),
        ("merit", |o| format!("{:?}", o.merit), args.merit.is_some()),
        (
            "active-set iters",
            |o| o.active_set_iters.to_string(),
            args.active_set_iters.is_some(),
        ),
        ("threads", |o| o.num_threads.to_string(), args.threads.is_some()),
    ];
    let d = ProxDdpOptions::default();
    fields
        .iter()
        .map(|&(name, get, cli)| {
            let (value, def) = (get(o), get(&d));
            let source = if cli {
                format!(" [option; default {def}]")
            } else if get(recommended) != def {
                format!(" [problem; default {def}]")
            } else {
                String::new()
            };
            format!("{name} {value}{source}")
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The iteration table (the columns of DESIGN.md; `gharial solve --help` explains them).
pub fn print_table(history: &[IterationRecord]) {
    let table = gharial::solvers::proxddp::TABLE;
    out!("{}", table.header());
    for r in history {
        out!("{}", table.row(r));
    }
}

fn print_summary(sol: &Solution) {
    let ms = sol.solve_time.as_secs_f64() * 1e3;
    out!("status    {}", sol.status);
    out!(
        "iterations {} (augmented-Lagrangian iterations {})",
        sol.iterations,
        sol.al_iterations
    );
    out!("cost      {:.10e}", sol.cost);
    out!("residuals primal {:.3e}, dual {:.3e}", sol.prim_err, sol.dual_err);
    out!(
        "time      {ms:.3} ms ({:.4} ms per iteration)",
        ms / (sol.iterations.max(1) as f64)
    );
}

/// The solution, the settings and the history as a JSON document.
pub fn solution_json(example: &Example, opts: &ProxDdpOptions, sol: &Solution) -> serde_json::Value {
    let history: Vec<_> = sol
        .history
        .iter()
        .map(|r| {
            json!({
                "iter": r.iter, "alpha": r.alpha, "inner_crit": r.inner_crit, "prim_err": r.prim_err,
                "dual_err": r.dual_err, "preg": r.preg, "cost": r.cost, "dphi0": r.dphi0,
                "merit": r.merit, "dmerit": r.dmerit, "al_iter": r.al_iter, "mu": r.mu,
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
    json!({
        "problem": example.name,
        "solver": "proxddp",
        "dt": example.dt,
        "settings": {
            "tol": opts.tol, "mu_init": opts.mu_init, "dyn_al_scale": opts.dyn_al_scale,
            "active_set_iters": opts.active_set_iters,
            "max_iters": opts.max_iters,
            "rollout": format!("{:?}", opts.rollout), "step_acceptance": format!("{:?}", opts.step_acceptance),
            "merit": format!("{:?}", opts.merit),
            "num_threads": opts.num_threads,
        },
        "status": sol.status.to_string(),
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
    })
}

//! `gharial bench solve` (every catalogue example) and `gharial bench peers` (the LQR
//! family of the peer harness, as JSON lines in the harness's format).
//!
//! Each timed solve starts from the same guess with a freshly constructed and set-up
//! solver (construction and setup are not timed, as in the harness); the median and
//! minimum over the repeats are reported, with
//! the time of one full-horizon model evaluation and derivative pass, to separate model
//! cost from solver cost.

use std::io::Write;
use std::time::Instant;

use gharial::problem::{Problem, ProblemData, kkt_residuals};
use gharial::solvers::proxddp::{ProxDdp, ProxDdpOptions, Rollout, StepAcceptance};
use gharial::solvers::{InitialGuess, Solution};
use gharial_problems::peers::{PeersLqrParams, PeersVariant};
use serde_json::json;

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

/// Solves `problem` `repeats` times from `(xs, us)` and times it.
///
/// # Errors
/// If setup or the guess is invalid.
pub fn time_solves(
    problem: &Problem,
    xs: &[Vec<f64>],
    us: &[Vec<f64>],
    opts: &ProxDdpOptions,
    repeats: usize,
) -> gharial::Result<Timing> {
    let mut times = Vec::with_capacity(repeats.max(1));
    let mut solution = Solution::default();
    for _ in 0..repeats.max(1) {
        // A freshly constructed and set-up solver per repeat (not timed), as the harness.
        let mut solver = ProxDdp::new(opts.clone());
        solver.setup(problem)?;
        let t = Instant::now();
        solver.solve(problem, InitialGuess::primal(xs, us))?;
        times.push(t.elapsed().as_secs_f64() * 1e3);
        solution = solver.solution().clone();
    }
    let min_ms = times.iter().copied().fold(f64::INFINITY, f64::min);
    let median_ms = median(&mut times);
    let mut data = ProblemData::new(problem, 1)?;
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

/// `gharial bench solve`: iterations, time and time per iteration of every example, at
/// its recommended settings (with `rollout` and `active_set_iters` if given), and the
/// largest KKT residual of the solution recomputed by [`kkt_residuals`].
pub fn examples(names: &[String], repeats: usize, rollout: Option<Rollout>, active_set_iters: Option<usize>) -> i32 {
    let names: Vec<String> = if names.is_empty() {
        gharial_problems::catalogue()
            .iter()
            .map(|p| p.name.to_string())
            .collect()
    } else {
        names.to_vec()
    };
    out!(
        "{:<20} {:>9} {:>10} {:>6} {:>4} {:>12} {:>10} {:>10} {:>15} {:>15} {:>9} {:>9} {:>9}",
        "problem",
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
    let mut code = 0;
    for name in &names {
        let ex = match gharial_problems::build(name) {
            Ok(e) => e,
            Err(e) => {
                eprintln!("gharial bench solve: {e}");
                return 2;
            }
        };
        let mut opts = ex.proxddp.clone();
        if let Some(r) = rollout {
            opts.rollout = r;
        }
        if let Some(k) = active_set_iters {
            opts.active_set_iters = k;
        }
        match time_solves(&ex.problem, &ex.xs0, &ex.us0, &opts, repeats) {
            Ok(t) => {
                let s = &t.solution;
                if !s.status.converged() {
                    code = 1;
                }
                let kkt = kkt_residuals(&ex.problem, &s.xs, &s.us, &s.lambdas, &s.nus).map_or(f64::NAN, |k| k.max());
                out!(
                    "{:<20} {:>9} {:>10} {:>6} {:>4} {:>12.3} {:>10.3} {:>10.4} {:>7.3}/{:<7.3} {:>15.9e} {:>9.2e} {:>9.2e} {:>9.2e}",
                    name,
                    format!("{:?}", opts.rollout).to_lowercase(),
                    if s.status.converged() {
                        "converged".to_string()
                    } else {
                        format!("{:?}", s.status)
                    },
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
            }
            Err(e) => {
                eprintln!("gharial bench solve {name}: {e}");
                code = 1;
            }
        }
        let _ = std::io::stdout().flush();
    }
    code
}

/// Settings of `gharial bench peers`, matching the harness's environment.
pub struct PeersArgs {
    /// Harness problem names (`lqr`, `lqr_box`, `lqr_box_term`, `ur5`, `ur5_box`,
    /// `pendulum`, `pendulum_box`, `pendulum_box_term`; others get an error line).
    pub problems: Vec<String>,
    /// Timed solves per problem and solver.
    pub repeats: usize,
    /// Tolerance.
    pub tol: f64,
    /// Iteration limit.
    pub max_iters: usize,
    /// Directory of the trajectory files (`<problem>__gharial_<solver>.txt`).
    pub traj_dir: Option<String>,
    /// The family's parameters.
    pub params: PeersLqrParams,
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

/// The solver variants reported: `ProxDDP` with the filter (the harness's ProxDDP),
/// `ProxDDP_ls` with the nonmonotone line search, `ProxDDP_as` with the filter and the
/// active-set prediction of the step.
const VARIANTS: [(&str, StepAcceptance, usize); 3] = [
    ("ProxDDP", StepAcceptance::Filter, 0),
    ("ProxDDP_ls", StepAcceptance::NonmonotoneLinesearch, 0),
    ("ProxDDP_as", StepAcceptance::Filter, 10),
];

/// `gharial bench peers`: one JSON line per (problem, solver), trajectories written for
/// the harness's independent check; a problem gharial cannot run gets a line with an
/// `error`. Each problem uses its catalogue settings (the harness's: `mu_init` and
/// rollout per family) with the harness's tolerance and iteration limit.
pub fn peers(args: &PeersArgs) -> i32 {
    for name in &args.problems {
        let ex = match harness_problem(name, &args.params) {
            Some(Ok(e)) => e,
            other => {
                let error = match other {
                    Some(Err(e)) => e.to_string(),
                    _ => format!("gharial has no problem `{name}`"),
                };
                for (solver, _, _) in VARIANTS {
                    out!(
                        "{}",
                        json!({"problem": name, "lib": "gharial", "solver": solver, "side": "rust", "error": error})
                    );
                }
                continue;
            }
        };
        for (solver, acceptance, active_set_iters) in VARIANTS {
            let opts = ProxDdpOptions {
                tol: args.tol,
                max_iters: args.max_iters,
                step_acceptance: acceptance,
                active_set_iters,
                ..ex.proxddp.clone()
            };
            peers_line(args, name, solver, &ex, &opts);
        }
    }
    0
}

/// Times one solver variant on one harness problem and prints its JSON line.
fn peers_line(args: &PeersArgs, name: &str, solver: &str, ex: &gharial_problems::Example, opts: &ProxDdpOptions) {
    let t = match time_solves(&ex.problem, &ex.xs0, &ex.us0, opts, args.repeats) {
        Ok(t) => t,
        Err(e) => {
            out!(
                "{}",
                json!({"problem": name, "lib": "gharial", "solver": solver, "side": "rust", "error": e.to_string()})
            );
            return;
        }
    };
    let s = &t.solution;
    if let Some(dir) = &args.traj_dir {
        let path = format!("{dir}/{name}__gharial_{solver}.txt");
        if let Err(e) = write_traj(&path, s) {
            eprintln!("gharial bench peers: cannot write {path}: {e}");
        }
    }
    let settings = format!(
        "mu_init={:e} rollout={:?} step_acceptance={:?} active_set_iters={}",
        opts.mu_init, opts.rollout, opts.step_acceptance, opts.active_set_iters
    );
    out!(
        "{}",
        json!({
            "problem": name, "lib": "gharial", "lib_version": env!("CARGO_PKG_VERSION"),
            "solver": solver, "side": "rust",
            "N": ex.problem.horizon(), "nx": ex.problem.space(0).nx(), "nu": ex.problem.nu(0),
            "tol": args.tol, "max_iters": args.max_iters, "repeats": args.repeats,
            "settings": settings,
            "iters": s.iterations, "converged": s.status.converged(),
            "prim_res": s.prim_err, "dual_res": s.dual_err,
            "init_cost": t.init_cost, "final_cost": s.cost,
            "time_ms": t.median_ms, "time_ms_min": t.min_ms,
            "time_per_iter_ms": t.median_ms / s.iterations.max(1) as f64,
            "model_eval_ms": t.eval_ms, "model_deriv_ms": t.deriv_ms,
        })
    );
}

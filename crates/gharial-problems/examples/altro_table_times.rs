//! Solve times of ALTRO's Table I problems added with the time-penalised problems (to
//! set against the paper's Table I, measured on another machine): each problem solved
//! by ALTRO at the settings of its test (`tests/altro_swing_min_time.rs`,
//! `tests/altro_quadrotor.rs`), the median of five runs after one warm-up, and by
//! ProxDDP at the catalogue's settings. Run with `--release`.

use gharial::problem::MinimumTime;
use gharial::solvers::altro::AltroOptions;
use gharial::solvers::{InitialGuess, SolverOptions};

fn median_time(ex: &gharial_problems::Example, options: &SolverOptions) -> (f64, usize, f64, f64, String) {
    let mut solver = options.build();
    solver.setup(&ex.problem).expect("setup");
    let mut times = Vec::new();
    let mut last = None;
    for run in 0..6 {
        let t = std::time::Instant::now();
        let sol = solver
            .solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
            .expect("solve")
            .clone();
        if run > 0 {
            times.push(t.elapsed().as_secs_f64());
        }
        last = Some(sol);
    }
    times.sort_by(f64::total_cmp);
    let sol = last.expect("five runs");
    (
        times[times.len() / 2],
        sol.iterations,
        sol.prim_err,
        sol.cost,
        format!("{:?}", sol.status),
    )
}

fn main() {
    let altro = |tol: f64, p0: f64, cti: f64| {
        SolverOptions::Altro(AltroOptions::default().with(|o| {
            o.constraint_tolerance = tol;
            o.penalty_initial = p0;
            o.cost_tolerance_intermediate = cti;
            if p0 == 1.0 {
                // The swing-up and time-penalised tests' accuracy (the quadrotor's test
                // keeps ALTRO's defaults).
                o.cost_tolerance = 1e-10;
                o.projected_newton_tolerance = 1e-6;
            }
        }))
    };
    let rows = [
        ("altro-pendulum", altro(1e-8, 1.0, 1e-3), "65 ms"),
        ("altro-pendulum-min-time", altro(1e-6, 1.0, 1e-3), "848 ms"),
        ("altro-acrobot", altro(1e-8, 1.0, 1e-3), "1.2 s"),
        ("altro-cartpole", altro(1e-8, 1.0, 1e-3), "661 ms"),
        ("car-parallel-park-min-time", altro(1e-6, 1.0, 1e-3), "5.0 s"),
        ("quadrotor-line", altro(1e-8, 0.1, 1e-2), "2.3 s"),
    ];
    println!(
        "| problem | solver | status | iterations | c_max | cost | T (s) | time (median of 5) | Table I (ALTRO) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for (name, options, paper) in rows {
        let ex = gharial_problems::build(name).expect("catalogue");
        for (solver, opts) in [("altro", options), ("proxddp", ex.options("proxddp").expect("proxddp"))] {
            let (t, iters, c, cost, status) = median_time(&ex, &opts);
            let total = if name.ends_with("min-time") {
                format!("{:.4}", MinimumTime::total_time(&solve_us(&ex, &opts)))
            } else {
                "fixed".into()
            };
            println!(
                "| {name} | {solver} | {status} | {iters} | {c:.1e} | {cost:.6} | {total} | {:.1} ms | {} |",
                t * 1e3,
                if solver == "altro" { paper } else { "" }
            );
        }
    }
}

fn solve_us(ex: &gharial_problems::Example, options: &SolverOptions) -> Vec<Vec<f64>> {
    let mut solver = options.build();
    solver.setup(&ex.problem).expect("setup");
    solver
        .solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
        .expect("solve")
        .us
        .clone()
}

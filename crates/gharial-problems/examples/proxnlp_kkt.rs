//! ProxNLP's dense KKT solve against its sparse one on catalogue problems that both take
//! (at most `gharial::nlp::MAX_KKT_DIM` rows). The two solves alternate round by round, so
//! that machine load shifts both alike; prints the system's size and fill, the
//! iterations, median and minimum times and their ratio, and checks that both reach the
//! same cost.
//!
//! ```text
//! cargo run --release -p gharial-problems --example proxnlp_kkt -- [ROUNDS] [NAME...]
//! ```

use std::time::Instant;

use gharial::nlp::{KktSolver, ProxNlpOcp, ProxNlpOptions};
use gharial::solvers::{InitialGuess, Solver};
use gharial_problems::Example;

/// One timed solve: (seconds, iterations, cost).
fn timed(solver: &mut ProxNlpOcp, ex: &Example) -> (f64, usize, f64) {
    let start = Instant::now();
    let sol = solver
        .solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
        .expect("solve");
    assert!(sol.status.converged(), "{}", sol.status);
    (start.elapsed().as_secs_f64(), sol.iterations, sol.cost)
}

fn stats(mut v: Vec<f64>) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    (v[v.len() / 2], v[0])
}

fn compare(name: &str, rounds: usize) {
    let ex = gharial_problems::build(name).expect("catalogue problem");
    let solver = |kkt: KktSolver| {
        let o = ProxNlpOptions::from(&ex.proxddp).with(|o| {
            o.kkt = kkt;
            o.max_iters = 1000;
        });
        let mut s = ProxNlpOcp::new(o);
        s.setup(&ex.problem).expect("setup");
        s
    };
    let mut solvers = [solver(KktSolver::Dense), solver(KktSolver::Sparse)];
    let mut times = [Vec::new(), Vec::new()];
    let mut runs = [(0, 0.0); 2];
    for _ in 0..rounds {
        for (k, s) in solvers.iter_mut().enumerate() {
            let (t, it, cost) = timed(s, &ex);
            times[k].push(t);
            runs[k] = (it, cost);
        }
    }
    let k = solvers[1].kkt_stats().expect("set up");
    println!(
        "{name} (N = {}, {} rows; sparse: {} stored entries, {} in the factor):",
        ex.problem.horizon(),
        k.dim,
        k.nnz,
        k.factor_nnz
    );
    let [(md, nd), (ms, ns)] = times.map(stats);
    for (label, (it, cost), (m, n)) in [("dense ", runs[0], (md, nd)), ("sparse", runs[1], (ms, ns))] {
        println!(
            "  {label}: {it} iterations, cost {cost:.10e}; median {:.2} ms, min {:.2} ms",
            m * 1e3,
            n * 1e3
        );
    }
    let rel = (runs[0].1 - runs[1].1).abs() / runs[0].1.abs().max(1.0);
    println!(
        "  time ratio sparse/dense: median {:.3}, min {:.3}; costs within {rel:.1e}",
        ms / md,
        ns / nd
    );
}

fn main() {
    let mut args = std::env::args().skip(1);
    let rounds: usize = args.next().map_or(5, |a| a.parse().expect("ROUNDS"));
    let names: Vec<String> = args.collect();
    let names = if names.is_empty() {
        ["pendulum", "double-pendulum-box", "quadrotor", "ur5-circle"]
            .map(String::from)
            .to_vec()
    } else {
        names
    };
    for name in &names {
        compare(name, rounds);
    }
}

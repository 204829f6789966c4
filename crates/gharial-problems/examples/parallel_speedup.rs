//! ProxDDP on one thread against two (the parallel Riccati solver and stage-wise
//! evaluation on one team of threads) on long horizons: Solo-12's CoM circle and the peers' LQR with
//! control bounds, N nodes each. Serial and parallel solves alternate round by round, so
//! that machine load shifts both alike; prints iterations, median and minimum times and
//! their ratios.
//!
//! ```text
//! cargo run --release -p gharial-problems --example parallel_speedup -- [N] [ROUNDS]
//! ```

use std::time::Instant;

use gharial::solvers::proxddp::{ProxDdp, Rollout};
use gharial::solvers::{InitialGuess, Solver};
use gharial_problems::Example;
use gharial_problems::peers::{PeersLqrParams, PeersVariant};

/// One timed solve of `ex` with `threads` threads: (seconds, iterations, status).
fn timed(solver: &mut ProxDdp, ex: &Example) -> (f64, usize, String) {
    let start = Instant::now();
    let sol = solver
        .solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
        .expect("solve");
    (
        start.elapsed().as_secs_f64(),
        sol.iterations,
        format!("{:?}", sol.status),
    )
}

fn stats(mut v: Vec<f64>) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    (v[v.len() / 2], v[0])
}

fn compare(name: &str, ex: &Example, rounds: usize) {
    let solver = |threads: usize| {
        let mut o = ex.proxddp.clone();
        o.num_threads = threads;
        o.rollout = Rollout::Linear;
        let mut s = ProxDdp::new(o);
        s.setup(&ex.problem).expect("setup");
        s
    };
    let (mut one, mut two) = (solver(1), solver(2));
    let (mut t1, mut t2) = (Vec::new(), Vec::new());
    let mut runs = (String::new(), String::new());
    for _ in 0..rounds {
        let (s, it, st) = timed(&mut one, ex);
        t1.push(s);
        runs.0 = format!("{it} iterations, {st}");
        let (s, it, st) = timed(&mut two, ex);
        t2.push(s);
        runs.1 = format!("{it} iterations, {st}");
    }
    let ((m1, n1), (m2, n2)) = (stats(t1), stats(t2));
    println!("{name} (N = {}):", ex.problem.horizon());
    println!(
        "  1 thread : {} ; median {:.2} ms, min {:.2} ms",
        runs.0,
        m1 * 1e3,
        n1 * 1e3
    );
    println!(
        "  2 threads: {} ; median {:.2} ms, min {:.2} ms",
        runs.1,
        m2 * 1e3,
        n2 * 1e3
    );
    println!("  time ratio 2/1: median {:.3}, min {:.3}", m2 / m1, n2 / n1);
}

fn main() {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().map_or(512, |a| a.parse().expect("N"));
    let rounds: usize = args.next().map_or(7, |a| a.parse().expect("ROUNDS"));
    let solo = gharial_problems::solo_com_circle::build(n).expect("solo-com-circle");
    compare("solo-com-circle", &solo, rounds);
    let params = PeersLqrParams {
        horizon: n,
        ..Default::default()
    };
    let lqr = gharial_problems::peers::build(&params, PeersVariant::Box).expect("peers-lqr-box");
    compare("peers-lqr-box", &lqr, rounds);
}

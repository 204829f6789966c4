//! Solves every catalogue problem (or those named on the command line) with ProxDDP at
//! its recommended settings and prints iterations, cost, residuals and time.
//!
//! ```sh
//! cargo run --release -p gharial-problems --example solve_all [names...]
//! ```
//! Environment: `MU`, `TOL` and `MAX_ITERS` override `mu_init`, `tol` and `max_iters`;
//! `VERBOSE` prints the iteration tables and the KKT residuals (one solve per rollout);
//! `ROLLOUT=linear` or `ROLLOUT=nonlinear` runs one rollout only; `HESSIAN=exact` uses
//! the exact Hessian of the Lagrangian.

use gharial::problem::kkt_residuals;
use gharial::solvers::InitialGuess;
use gharial::solvers::proxddp::{HessianApprox, ProxDdp, Rollout};

fn main() {
    let names: Vec<String> = std::env::args().skip(1).collect();
    let verbose = std::env::var("VERBOSE").is_ok();
    println!(
        "| problem | rollout | status | iters | AL iters | cost | prim | dual | KKT (max) | time (ms) | ms/iter |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for info in gharial_problems::catalogue() {
        if !names.is_empty() && !names.iter().any(|n| n == info.name) {
            continue;
        }
        let ex = gharial_problems::build(info.name).expect("catalogue entry builds");
        for rollout in [Rollout::Linear, Rollout::Nonlinear] {
            if let Ok(r) = std::env::var("ROLLOUT")
                && !format!("{rollout:?}").eq_ignore_ascii_case(&r)
            {
                continue;
            }
            let mut opts = ex.proxddp.clone();
            opts.rollout = rollout;
            opts.verbose = verbose;
            if let Ok(mu) = std::env::var("MU") {
                opts.mu_init = mu.parse().expect("MU is a number");
            }
            if let Ok(it) = std::env::var("MAX_ITERS") {
                opts.max_iters = it.parse().expect("MAX_ITERS is an integer");
            }
            if std::env::var("HESSIAN").is_ok_and(|h| h.eq_ignore_ascii_case("exact")) {
                opts.hessian = HessianApprox::Exact;
            }
            if let Ok(tol) = std::env::var("TOL") {
                opts.tol = tol.parse().expect("TOL is a number");
            }
            let mut solver = ProxDdp::new(opts);
            solver.setup(&ex.problem).expect("setup");
            // Best of three solves for the time.
            let mut best = f64::INFINITY;
            let mut sol = None;
            for _ in 0..if verbose { 1 } else { 3 } {
                let s = solver
                    .solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
                    .expect("solve")
                    .clone();
                best = best.min(s.solve_time.as_secs_f64() * 1e3);
                sol = Some(s);
            }
            let s = sol.expect("solved");
            let kkt = kkt_residuals(&ex.problem, &s.xs, &s.us, &s.lambdas, &s.nus).expect("kkt");
            if verbose {
                eprintln!("{kkt:?}");
            }
            println!(
                "| {} | {:?} | {} | {} | {} | {:.12} | {:.1e} | {:.1e} | {:.1e} | {:.2} | {:.3} |",
                info.name,
                rollout,
                s.status,
                s.iterations,
                s.al_iterations,
                s.cost,
                s.prim_err,
                s.dual_err,
                kkt.max(),
                best,
                best / s.iterations.max(1) as f64
            );
        }
    }
}

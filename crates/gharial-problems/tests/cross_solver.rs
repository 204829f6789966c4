//! Every solver of the library on every catalogue problem it takes (the cheap ones in a
//! debug build): where several converge on one problem they reach the same optimum. Each
//! solver is picked by name (`SolverOptions::names`) at the problem's settings
//! (`Example::options`), so a new solver joins the comparison when it is registered.

use gharial::problem::kkt_residuals;
use gharial::solvers::{InitialGuess, Solution, SolverOptions};

/// The problems compared: every catalogue entry on which two solvers or more converge,
/// except the long solves (cart-pole, acrobot, quadrotor slalom, UR10, Solo), which have
/// one taker. ALTRO's Table I additions are left out with their reasons (compared in
/// `altro_swing_min_time.rs` instead): `altro-pendulum` has two local optima, ALTRO and
/// ProxDDP each reach another, as on `altro-acrobot`; `altro-cartpole`'s two solves take
/// 200-500 iterations each; the time-penalised `altro-pendulum-min-time` and
/// `car-parallel-park-min-time` converge with ProxDDP and (the park) ALTRO, to optima that
/// agree to 0.5% only (ALTRO's iLQR stops while the steps still move), and ALTRO's
/// park takes 6000 iterations, too long for this debug-build test; `quadrotor-line` and
/// `quadrotor-maze` are compared in `altro_quadrotor.rs` (ProxDDP's dual residual stalls on
/// the line; the maze's guess is infeasible, for ALTRO's infeasible start).
const PROBLEMS: [&str; 20] = [
    "lqr",
    "lqr-bounds",
    "lqr-term",
    "lqr-bounds-term",
    "clqr",
    "pendulum",
    "se2-car",
    "quadrotor",
    "peers-lqr",
    "peers-lqr-box",
    "peers-lqr-box-term",
    "ur5",
    "ur5-box",
    "double-pendulum",
    "double-pendulum-box",
    "double-pendulum-box-term",
    "ur5-circle",
    "ur5-circle-joint-bound",
    "ur5-circle-half-space",
    "block-move",
];

/// Relative agreement of the optimal costs: every solver stops at a KKT residual of about
/// its tolerance (1e-6 by default), which moves the cost by about as much.
const COST_RTOL: f64 = 2e-6;

/// The converged solutions of every solver that takes `name`, with the solver's name.
fn converged(name: &str) -> Vec<(&'static str, Solution)> {
    let ex = gharial_problems::build(name).unwrap();
    let mut out = Vec::new();
    for &solver_name in SolverOptions::names() {
        let mut options = ex.options(solver_name).unwrap();
        if let SolverOptions::Altro(o) = &mut options {
            // ALTRO stops its inner iLQR on an absolute expected decrease (1e-6 by
            // default, 4e-5 of the se2-car's cost): compare it at the others' accuracy.
            o.cost_tolerance = 1e-10;
            // The projection (Algorithm 2) makes the AL-iLQR point feasible without moving
            // it towards the optimum: its stationarity is that of the AL-iLQR point,
            // about the coarse tolerance (1e-3 by default; 3e-4 on ur5-circle-joint-bound).
            o.projected_newton_tolerance = 1e-6;
        }
        let mut solver = options.build();
        if solver.setup(&ex.problem).is_err() {
            continue; // the solver does not take the problem (refusals are tested elsewhere)
        }
        let sol = solver
            .solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
            .unwrap();
        if sol.status.converged() {
            out.push((solver_name, sol.clone()));
        }
    }
    out
}

#[test]
fn every_solver_that_converges_reaches_the_same_optimum() {
    let mut report = Vec::new();
    for name in PROBLEMS {
        let ex = gharial_problems::build(name).unwrap();
        let sols = converged(name);
        let names: Vec<_> = sols.iter().map(|(s, _)| *s).collect();
        assert!(sols.len() >= 2, "{name}: converged only {names:?}");
        for (solver, s) in &sols {
            let kkt = kkt_residuals(&ex.problem, &s.xs, &s.us, &s.lambdas, &s.nus).unwrap();
            assert!(kkt.max() < 1e-4, "{name} / {solver}: {kkt:?}");
        }
        let (first, reference) = &sols[0];
        let mut worst: f64 = 0.0;
        for (solver, s) in &sols[1..] {
            let rel = (s.cost - reference.cost).abs() / reference.cost.abs().max(1e-12);
            worst = worst.max(rel);
            assert!(
                rel < COST_RTOL,
                "{name}: {solver} cost {} vs {first} {} (relative {rel:.1e})",
                s.cost,
                reference.cost
            );
        }
        report.push(format!("{name}: {names:?}, costs within {worst:.1e}"));
    }
    eprintln!("{}", report.join("\n"));
}

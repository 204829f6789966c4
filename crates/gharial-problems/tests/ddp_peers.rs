//! The DDP family on the peer harness's problems against the peers' results (crocoddyl
//! 3.2.1 and aligator 0.19.1, from the harness's quiet-machine run): iterations and final
//! costs.
//!
//! crocoddyl checks convergence after the step of an iteration, with the direction of that
//! iteration; gharial checks it before the step, so on a converged solve it reports one
//! iteration fewer (the step it skips is the one whose expected decrease is below the
//! tolerance).

use gharial::solvers::Solver;
use gharial::solvers::ddp::{Ddp, DdpOptions, DdpVariant};
use gharial::solvers::{InitialGuess, Solution, Status};

fn solve(name: &str, variant: DdpVariant) -> Solution {
    let ex = gharial_problems::build(name).unwrap();
    let mut opts = DdpOptions::new(variant);
    opts.max_iters = 500;
    let mut solver = Ddp::new(opts);
    solver.setup(&ex.problem).unwrap();
    solver
        .solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
        .unwrap()
        .clone()
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// DDP and FDDP: crocoddyl's iterations ±1 and its cost to 1e-8.
#[test]
fn ddp_and_fddp_match_crocoddyl_on_the_harness_problems() {
    // (catalogue name, crocoddyl DDP iterations and cost, FDDP iterations and cost)
    let cases = [
        ("peers-lqr", (2, 6.248581777225142), (2, 6.248581777225142)),
        ("ur5", (7, 0.33886618648725525), (7, 0.33886618648725525)),
        ("double-pendulum", (11, 0.08429063710422653), (12, 0.08429063709752813)),
    ];
    for (name, ddp, fddp) in cases {
        for (variant, (iters, cost)) in [(DdpVariant::Ddp, ddp), (DdpVariant::Fddp, fddp)] {
            let sol = solve(name, variant);
            let what = format!("{name} {}", variant.name());
            assert_eq!(sol.status, Status::Converged, "{what}");
            assert!(
                sol.iterations.abs_diff(iters) <= 1,
                "{what}: {} iterations, crocoddyl {iters}",
                sol.iterations
            );
            assert!(rel(sol.cost, cost) < 1e-8, "{what}: cost {} vs {cost}", sol.cost);
            assert!(sol.prim_err == 0.0, "{what}: gaps {}", sol.prim_err);
        }
    }
}

/// Box-DDP and box-FDDP converge where crocoddyl's BoxFDDP does (`lqr_box`, `ur5_box`),
/// to the optimum of crocoddyl (lqr_box) and of aligator's ProxDDP (ur5_box: crocoddyl's
/// box QP stops at a gradient of 1e-5 and ends 2e-8 above it).
#[test]
fn box_variants_converge_where_crocoddyl_does() {
    let cases = [("peers-lqr-box", 6.922115936560473), ("ur5-box", 0.3549432460007217)];
    for (name, cost) in cases {
        for variant in [DdpVariant::BoxDdp, DdpVariant::BoxFddp] {
            let sol = solve(name, variant);
            let what = format!("{name} {}", variant.name());
            assert_eq!(sol.status, Status::Converged, "{what}");
            assert!(rel(sol.cost, cost) < 1e-9, "{what}: cost {} vs {cost}", sol.cost);
            assert!(
                sol.iterations <= 25,
                "{what}: {} iterations (crocoddyl 4 and 25)",
                sol.iterations
            );
        }
    }
}

/// `pendulum_box` (bang-bang torques): crocoddyl's BoxFDDP fails (22 iterations, cost
/// 171); the box variants here stop without claiming convergence, at a feasible point
/// of lower cost than the guess, where only heavily regularised steps still decrease
/// the cost (ProxDDP solves it: `proxddp` tests).
#[test]
fn box_variants_on_the_pendulum_with_tight_bounds_stop_without_claiming_convergence() {
    let ex = gharial_problems::build("double-pendulum-box").unwrap();
    let init = gharial_problems::total_cost(&ex.problem, &ex.xs0, &ex.us0).unwrap();
    for variant in [DdpVariant::BoxDdp, DdpVariant::BoxFddp] {
        let sol = solve("double-pendulum-box", variant);
        assert_ne!(sol.status, Status::Converged, "{}", variant.name());
        assert!(sol.cost < 1e-2 * init && sol.prim_err == 0.0, "{}", variant.name());
        assert!(sol.us.iter().flatten().all(|u| u.abs() <= 0.6), "{}", variant.name());
    }
}

/// SQP against mim_solvers' SQP (0.3.0, default filter line search, harness run with
/// `termination_tolerance = 1e-6`): the same iterates and the same KKT test, so the same
/// number of steps (the bound is one either way) and the same final cost (mim's
/// final costs; to 1e-9 relative) and, on the pendulum, its final KKT residual (4.418e-7)
/// and gaps (6.58e-9).
#[test]
fn sqp_takes_the_steps_of_mim_solvers_on_the_harness_problems() {
    let cases = [
        ("peers-lqr", 1, 6.248581777225141),
        ("ur5", 6, 0.3388661864889561),
        ("double-pendulum", 11, 0.08429063715535973),
    ];
    for (name, iters, cost) in cases {
        let sol = solve(name, DdpVariant::Sqp);
        assert_eq!(sol.status, Status::Converged, "{name}");
        assert!(
            sol.iterations.abs_diff(iters) <= 1,
            "{name}: {} iterations, mim_solvers {iters}",
            sol.iterations
        );
        assert!(rel(sol.cost, cost) < 1e-9, "{name}: cost {} vs {cost}", sol.cost);
        if name == "double-pendulum" {
            assert!(rel(sol.dual_err, 4.418373804430942e-7) < 1e-3, "{}", sol.dual_err);
            assert!(rel(sol.prim_err, 6.579e-9) < 1e-3, "{}", sol.prim_err);
        }
    }
}

/// FDDP with the filter line search of SQP ("FDDP (filter LS)" of the SQP paper):
/// crocoddyl's FDDP optimum on the harness problems, from the same guesses; the option
/// is refused for DDP, whose trials have no gaps.
#[test]
fn fddp_with_the_filter_line_search_reaches_crocoddyls_optimum() {
    let cases = [
        ("peers-lqr", 6.248581777225142),
        ("ur5", 0.33886618648725525),
        ("double-pendulum", 0.08429063709752813),
    ];
    for (name, cost) in cases {
        let ex = gharial_problems::build(name).unwrap();
        let opts = DdpOptions::new(DdpVariant::Fddp).with(|o| {
            o.filter_linesearch = true;
            o.max_iters = 500;
        });
        let mut solver = Ddp::new(opts);
        solver.setup(&ex.problem).unwrap();
        let sol = solver
            .solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
            .unwrap();
        assert_eq!(sol.status, Status::Converged, "{name}");
        assert!(rel(sol.cost, cost) < 1e-8, "{name}: cost {} vs {cost}", sol.cost);
        eprintln!("{name}: FDDP (filter LS) {} iterations", sol.iterations);
    }
    let ddp = DdpOptions::new(DdpVariant::Ddp).with(|o| o.filter_linesearch = true);
    let ex = gharial_problems::build("peers-lqr").unwrap();
    let err = Ddp::new(ddp).setup(&ex.problem).unwrap_err().to_string();
    assert!(err.contains("filter_linesearch"), "{err}");
}

/// CSQP (ADMM at mim_solvers' defaults, eps_abs = eps_rel = 1e-4, warm-started) on the
/// harness's constrained problems: converged to the KKT tolerance 1e-6 at the constrained
/// optimum of aligator's ProxDDP (to 1e-6 relative), in at most mim_solvers' CSQP
/// iterations (5, 37, 55, 11; it fails on `pendulum_box_term` after 500).
#[test]
fn csqp_converges_on_the_harness_constrained_problems() {
    use gharial::solvers::csqp::{Csqp, CsqpOptions};
    let cases = [
        ("peers-lqr-box", 6.922115864443983, 5),
        ("peers-lqr-box-term", 6.922417055326476, 37),
        ("ur5-box", 0.3549432460007217, 55),
        ("double-pendulum-box", 0.08484275536174778, 11),
        ("double-pendulum-box-term", 0.08484701247338439, 50),
    ];
    for (name, cost, iters) in cases {
        let ex = gharial_problems::build(name).unwrap();
        let mut solver = Csqp::new(CsqpOptions::default().with(|o| o.max_iters = 500));
        solver.setup(&ex.problem).unwrap();
        let sol = solver
            .solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
            .unwrap();
        assert_eq!(sol.status, Status::Converged, "{name}");
        assert!(rel(sol.cost, cost) < 1e-6, "{name}: cost {} vs {cost}", sol.cost);
        assert!(sol.iterations <= iters, "{name}: {} iterations", sol.iterations);
        assert!(sol.prim_err <= 1e-6, "{name}: infeasibility {}", sol.prim_err);
    }
}

/// CSQP from the acrobot's rest guess: the linearised terminal constraint and the QP's
/// iteration limit leave steps the filter rejects; the solve stops after
/// `max_linesearch_failures` failed searches in a row (the point kept, its status
/// `LinesearchFailure`) instead of re-solving the same QP up to `max_iters`, which it does
/// when the limit is raised.
#[test]
fn csqp_stops_after_repeated_line_search_failures() {
    use gharial::solvers::csqp::{Csqp, CsqpOptions};
    let ex = gharial_problems::build("acrobot").unwrap();
    let guess = InitialGuess::primal(&ex.xs0, &ex.us0);
    let run = |failures: usize| {
        let mut solver = Csqp::new(CsqpOptions::default().with(|o| {
            o.max_iters = 20;
            o.max_linesearch_failures = failures;
        }));
        solver.setup(&ex.problem).unwrap();
        let sol = solver.solve(&ex.problem, guess).unwrap().clone();
        (sol.status, sol.iterations, sol.cost)
    };
    let (status, iters, cost) = run(5);
    assert_eq!(status, Status::LinesearchFailure);
    assert!(iters < 20, "{iters} iterations");
    assert!(cost.is_finite());
    let (status, iters, _) = run(1000);
    assert_eq!(status, Status::MaxIterations);
    assert_eq!(iters, 20);
}

/// CSQP reports the feedback gains of its last QP's active set (the MPC policy (57)
/// reads `K_0`), checked against two other algorithms at their common optimum: FDDP
/// on `ur5` (no constraint rows: the same LQ); box-FDDP on `ur5-box` (three torques at
/// their bounds at the first knots, none at mid-horizon), whose projected-Newton box QP
/// zeroes the clamped rows; ProxDDP, whose gains come from its own stage KKT with the
/// active rows' multipliers, on `ur5-box`, `double-pendulum-box-term` (a terminal
/// equality) and `ur5-circle-half-space` (a constraint on the states only). The ADMM's
/// own penalised factorization gave `ur5-box` a first-knot gain three times box-FDDP's.
#[test]
fn csqp_reports_the_gains_of_its_last_qp() {
    let gains = |name: &str, solver: &str| -> Vec<faer::Mat<f64>> {
        let ex = gharial_problems::build(name).unwrap();
        let mut s = match solver {
            "fddp" | "box-fddp" => {
                let variant = if solver == "fddp" {
                    DdpVariant::Fddp
                } else {
                    DdpVariant::BoxFddp
                };
                return solve(name, variant).feedback;
            }
            _ => ex.options(solver).unwrap().build(),
        };
        s.setup(&ex.problem).unwrap();
        let sol = s.solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0)).unwrap();
        assert_eq!(sol.status, Status::Converged, "{name} / {solver}");
        sol.feedback.clone()
    };
    let cases = [
        ("ur5", "fddp", 1e-5),
        ("ur5-box", "box-fddp", 1e-4),
        ("ur5-box", "proxddp", 1e-4),
        // ProxDDP's penalty on the terminal equality moves its gains by about 1e-4.
        ("double-pendulum-box-term", "proxddp", 1e-3),
        ("ur5-circle-half-space", "proxddp", 1e-4),
    ];
    for (name, other, rtol) in cases {
        let (k_csqp, k_other) = (gains(name, "csqp"), gains(name, other));
        for t in [0, 1, k_csqp.len() / 2] {
            let (a, b) = (&k_csqp[t], &k_other[t]);
            let diff = (a - b).norm_l2() / b.norm_l2();
            assert!(
                b.norm_l2() > 0.1 && diff < rtol,
                "{name} knot {t} vs {other}: |K| {} vs {}, relative difference {diff:.1e}",
                a.norm_l2(),
                b.norm_l2()
            );
        }
    }
}

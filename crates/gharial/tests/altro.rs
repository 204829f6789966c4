//! ALTRO's AL-iLQR on constrained linear-quadratic problems, against independent
//! references: the optimal costs of the Clarabel QP solver (box-constrained LQs), the
//! dense KKT solve (terminal equality), and ProxDDP's optimum on the same problems.

#[path = "support/lq_ocp.rs"]
mod lq_ocp;

use gharial::lq::dense;
use gharial::problem::Problem;
use gharial::solvers::altro::{Altro, AltroOptions};
use gharial::solvers::proxddp::{ProxDdp, ProxDdpOptions};
use gharial::solvers::{InitialGuess, Solution, Solver, SolverOptions, Status};
use lq_ocp::*;

fn altro(p: &Problem, opts: AltroOptions) -> Solution {
    let (xs, us) = zero_guess(p);
    let mut solver = Altro::new(opts);
    solver.setup(p).unwrap();
    solver.solve(p, InitialGuess::primal(&xs, &us)).unwrap().clone()
}

/// AL-iLQR alone to a tight tolerance: the multipliers converge, so the primal optimum
/// is reached (the projection only restores feasibility).
fn tight() -> AltroOptions {
    AltroOptions::default().with(|o| {
        o.constraint_tolerance = 1e-8;
        o.cost_tolerance = 1e-12;
        o.projected_newton = false;
    })
}

fn traj_diff(a: &[Vec<f64>], b: &[Vec<f64>]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| x.iter().zip(y).map(|(p, q)| (p - q).abs()))
        .fold(0.0, f64::max)
}

#[test]
fn box_constrained_lq_has_the_optimal_cost_of_an_independent_qp_solver() {
    let cases = qp_reference_cases();
    for case in cases.iter().filter(|c| c.seed < 40) {
        let (seed, reference) = (case.seed, case.clarabel_cost);
        let p = ocp(&case.lq, Some(case.umax), case.target.as_deref());
        let prox = {
            let (xs, us) = zero_guess(&p);
            let mut s = ProxDdp::new(ProxDdpOptions::default().with(|o| o.tol = 1e-9));
            s.setup(&p).unwrap();
            s.solve(&p, InitialGuess::primal(&xs, &us)).unwrap().clone()
        };
        assert_eq!(prox.status, Status::Converged);
        // Plain and square-root passes, and the infeasible start from the zero states
        // (slack controls, III-B).
        for (square_root, infeasible) in [(false, false), (true, false), (false, true)] {
            let sol = altro(
                &p,
                tight().with(|o| {
                    o.square_root = square_root;
                    o.infeasible_start = infeasible;
                }),
            );
            assert_eq!(
                sol.status,
                Status::Converged,
                "seed {seed} sqrt {square_root} {infeasible}"
            );
            assert!(sol.prim_err <= 1e-8);
            let rel = (sol.cost - reference).abs() / reference.abs().max(1.0);
            assert!(rel < 1e-6, "seed {seed}: cost {} vs QP {reference} ({rel:e})", sol.cost);
            // The same optimum as ProxDDP's (the constraints are met to 1e-8, so the
            // trajectories agree to about that over the conditioning of the problem).
            let d = traj_diff(&sol.us, &prox.us).max(traj_diff(&sol.xs, &prox.xs));
            assert!(
                d < 1e-5,
                "seed {seed} sqrt {square_root} {infeasible}: |ALTRO - ProxDDP| = {d:e}"
            );
        }
    }
}

#[test]
fn terminal_equality_lq_reaches_the_dense_kkt_solution() {
    for seed in [1, 2, 3] {
        let lq = random_lq(4, 2, 15, seed);
        let target = reachable_target(&lq, 1.0);
        let p = ocp(&lq, None, Some(&target));
        let reference = dense::solve(&exact_lq(&lq, Some(&target))).unwrap();
        let sol = altro(&p, tight());
        assert_eq!(sol.status, Status::Converged, "seed {seed}");
        let d = max_diff(&sol.xs, &reference.xs).max(max_diff(&sol.us, &reference.us));
        assert!(d < 1e-6, "seed {seed}: {d:e}");
        // The multipliers of the terminal constraint are the AL's λ (17).
        let n = p.horizon();
        let dn = max_diff(&sol.nus[n..], &reference.nus[n..]);
        assert!(dn < 1e-4 * (1.0 + reference.nus[n].norm_max()), "seed {seed}: {dn:e}");
        // Square-root and plain backward passes: the same iterates to round-off.
        let s2 = altro(&p, tight().with(|o| o.square_root = true));
        assert_eq!(s2.status, Status::Converged);
        assert!(traj_diff(&s2.us, &sol.us) < 1e-7);
    }
}

#[test]
fn the_projection_takes_a_coarse_solution_to_the_constraint_tolerance() {
    let cases = qp_reference_cases();
    for case in cases.iter().filter(|c| c.seed < 40 && c.target.is_some()) {
        let p = ocp(&case.lq, Some(case.umax), case.target.as_deref());
        let opts = AltroOptions::default().with(|o| {
            o.constraint_tolerance = 1e-10;
            o.projected_newton_tolerance = 1e-3;
        });
        let sol = altro(&p, opts);
        assert_eq!(sol.status, Status::Converged, "seed {}", case.seed);
        assert!(sol.prim_err <= 1e-10, "seed {}: {:e}", case.seed, sol.prim_err);
        // The last row is the projection's; the AL stage stopped at the coarse tolerance.
        let h = &sol.history;
        assert!(h[h.len() - 2].prim_err > 1e-10 && h[h.len() - 2].prim_err <= 1e-3);
        let rel = (sol.cost - case.clarabel_cost).abs() / case.clarabel_cost.abs().max(1.0);
        assert!(rel < 1e-2, "seed {}: {rel:e}", case.seed);
    }
}

#[test]
fn a_warm_start_from_the_solution_converges_at_once() {
    let case = &qp_reference_cases()[0];
    let p = ocp(&case.lq, Some(case.umax), case.target.as_deref());
    let (xs, us) = zero_guess(&p);
    let mut solver = Altro::new(tight());
    solver.setup(&p).unwrap();
    let cold = solver.solve(&p, InitialGuess::primal(&xs, &us)).unwrap().clone();
    assert_eq!(cold.status, Status::Converged);
    let warm = solver.solve(&p, InitialGuess::from_solution(&cold)).unwrap().clone();
    assert_eq!(warm.status, Status::Converged);
    assert!(
        warm.al_iterations < cold.al_iterations,
        "{} vs {}",
        warm.al_iterations,
        cold.al_iterations
    );
    assert!(warm.iterations < cold.iterations);
    assert!((warm.cost - cold.cost).abs() < 1e-8 * cold.cost.abs().max(1.0));
}

/// A solver set up once follows a new `x_0` of the problem (its augmented problem once
/// kept the first one): the same solution as a fresh solver, from `x_0`.
#[test]
fn a_reused_solver_follows_a_new_initial_state() {
    let case = &qp_reference_cases()[0];
    let mut p = ocp(&case.lq, Some(case.umax), None);
    for projected_newton in [false, true] {
        let opts = tight().with(|o| o.projected_newton = projected_newton);
        let mut reused = Altro::new(opts.clone());
        reused.setup(&p).unwrap();
        let (xs, us) = zero_guess(&p);
        reused.solve(&p, InitialGuess::primal(&xs, &us)).unwrap();
        let x1: Vec<f64> = case.lq.x0.iter().map(|v| v + 0.3).collect();
        p.set_x0(&x1).unwrap();
        let again = reused.solve(&p, InitialGuess::primal(&xs, &us)).unwrap().clone();
        let fresh = altro(&p, opts);
        assert_eq!(again.xs[0], x1);
        assert!(traj_diff(&again.xs, &fresh.xs) < 1e-9, "{projected_newton}");
        assert!((again.cost - fresh.cost).abs() < 1e-9 * fresh.cost.abs().max(1.0));
        p.set_x0(&case.lq.x0).unwrap();
    }
}

#[test]
fn altro_is_built_by_name_and_refuses_bad_options() {
    let opts = SolverOptions::from_name("altro").unwrap();
    assert_eq!(opts.name(), "altro");
    let lq = random_lq(3, 1, 5, 4);
    let p = ocp(&lq, Some(1.0), None);
    let mut s = opts.build();
    s.setup(&p).unwrap();
    for bad in [
        AltroOptions::default().with(|o| o.penalty_scaling = 1.0),
        AltroOptions::default().with(|o| o.constraint_tolerance = 0.0),
        AltroOptions::default().with(|o| o.penalty_initial = f64::NAN),
        AltroOptions::default().with(|o| o.iterations_outer = 0),
    ] {
        let mut s = Altro::new(bad);
        assert!(s.setup(&p).is_err());
    }
    let mut s = Altro::new(AltroOptions::default());
    let (xs, mut us) = zero_guess(&p);
    assert!(
        s.solve(&p, InitialGuess::primal(&xs, &us)).is_err(),
        "solve before setup"
    );
    // A non-finite guess is an error or a NonFinite status, never a panic or a NaN result.
    s.setup(&p).unwrap();
    us[2][0] = f64::NAN;
    match s.solve(&p, InitialGuess::primal(&xs, &us)) {
        Err(_) => {}
        Ok(sol) => assert_eq!(sol.status, Status::NonFinite),
    }
}

#[test]
fn the_square_root_pass_is_refused_on_implicit_dynamics() {
    let lq = random_lq(3, 1, 5, 4);
    let (p, _) = implicit_euler_ocp(&lq, 0.1);
    let mut s = Altro::new(AltroOptions::default().with(|o| o.square_root = true));
    let e = s.setup(&p).unwrap_err().to_string();
    assert!(e.contains("square_root") && e.contains("explicit dynamics"), "{e}");
    // Without it ALTRO solves the implicit problem.
    let mut s = Altro::new(tight());
    s.setup(&p).unwrap();
    let (xs, us) = zero_guess(&p);
    let sol = s.solve(&p, InitialGuess::primal(&xs, &us)).unwrap();
    assert_eq!(sol.status, Status::Converged);
}

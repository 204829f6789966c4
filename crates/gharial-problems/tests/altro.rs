//! ALTRO on catalogue problems: the cart-pole of Fig. 1 (the constraint tolerance 1e-8 is
//! reached with the projection of Algorithm 2, not by AL-iLQR alone in a bounded number of
//! outer iterations).

use gharial::solvers::altro::{Altro, AltroOptions};
use gharial::solvers::{InitialGuess, Solution, Solver, Status};

fn solve(ex: &gharial_problems::Example, opts: AltroOptions) -> Solution {
    let mut s = Altro::new(opts);
    s.setup(&ex.problem).unwrap();
    s.solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
        .unwrap()
        .clone()
}

#[test]
fn cartpole_reaches_the_constraint_tolerance_only_with_the_projection() {
    let ex = gharial_problems::cartpole::build_state_target().unwrap();
    let with = solve(
        &ex,
        AltroOptions::default().with(|o| {
            o.constraint_tolerance = 1e-8;
        }),
    );
    eprintln!(
        "with projection: {:?} c_max {:e} cost {} iters {} outer {} time {:?}",
        with.status, with.prim_err, with.cost, with.iterations, with.al_iterations, with.solve_time
    );
    let without = solve(
        &ex,
        AltroOptions::default().with(|o| {
            o.constraint_tolerance = 1e-8;
            o.projected_newton = false;
            o.iterations_outer = 20;
        }),
    );
    eprintln!(
        "without: {:?} c_max {:e} cost {} iters {} outer {} time {:?}",
        without.status, without.prim_err, without.cost, without.iterations, without.al_iterations, without.solve_time
    );
    // Measured: with the projection, c_max 1.8e-15 after 4 AL-iLQR outer iterations (158
    // iLQR iterations, the coarse stage stopping at 4.7e-4) and one projection; without,
    // c_max stalls between 1.6e-8 and 1.2e-7 from the 10th outer iteration on (penalty at
    // its maximum 1e8), 322 iLQR iterations in 20 outer ones.
    assert_eq!(with.status, Status::Converged);
    assert!(with.prim_err <= 1e-8);
    assert!(with.al_iterations <= 10, "{}", with.al_iterations);
    assert_ne!(without.status, Status::Converged);
    assert!(without.prim_err > 1e-8, "{:e}", without.prim_err);
    let tail = &without.history[10..];
    assert!(
        tail.iter().all(|r| r.prim_err > 1e-8),
        "AL-iLQR alone stalls above the tolerance"
    );
    // The square-root backward pass (III-A) gives the same solution.
    let sqrt = solve(
        &ex,
        AltroOptions::default().with(|o| {
            o.constraint_tolerance = 1e-8;
            o.square_root = true;
        }),
    );
    eprintln!(
        "square root: {:?} c_max {:e} cost {} iters {} time {:?}",
        sqrt.status, sqrt.prim_err, sqrt.cost, sqrt.iterations, sqrt.solve_time
    );
    assert_eq!(sqrt.status, Status::Converged);
    assert!((sqrt.cost - with.cost).abs() < 1e-6 * with.cost);
    // Both trajectories swing the pole up (θ from π to 0) within the force limits.
    for s in [&with, &without] {
        assert!(s.us.iter().all(|u| u[0].abs() <= 6.0 + 1e-7));
        assert!(s.xs.last().unwrap()[1].abs() < 1e-6);
    }
}

/// The infeasible start (III-B) on the catalogue cart-pole with the tip constraint: from
/// the rollout of the zero-force guess the pole hangs, where the tip constraint's
/// Jacobian leaves no direction to swing up, and AL-iLQR stays there; started from the
/// guess's swing-up states with slack controls it converges. (AL-iLQR alone, to 1e-6:
/// the tip's height is at its maximum at the solution, where the constraint's Jacobian
/// vanishes, so the Newton projection of Algorithm 2 does not apply.)
#[test]
fn cartpole_tip_needs_the_infeasible_start() {
    let ex = gharial_problems::cartpole::build().unwrap();
    let opts = AltroOptions::default().with(|o| {
        o.constraint_tolerance = 1e-6;
        o.projected_newton = false;
        o.iterations_outer = 15;
    });
    let rollout = solve(&ex, opts.clone());
    let infeasible = solve(&ex, opts.with(|o| o.infeasible_start = true));
    for (name, s) in [("rollout", &rollout), ("infeasible start", &infeasible)] {
        eprintln!(
            "{name}: {:?} c_max {:e} cost {} iters {} outer {} time {:?}",
            s.status, s.prim_err, s.cost, s.iterations, s.al_iterations, s.solve_time
        );
    }
    assert_ne!(rollout.status, Status::Converged);
    assert!(rollout.prim_err > 1.0, "{:e}", rollout.prim_err);
    assert_eq!(infeasible.status, Status::Converged);
    assert!(infeasible.prim_err <= 1e-6);
    assert!(infeasible.us.iter().all(|u| u[0].abs() <= 6.0 + 1e-7));
}

/// After the projection, the returned multipliers are those of the projected point: the
/// KKT residuals, recomputed from the problem alone, certify it (they were the AL
/// multipliers of the point before the projection, stationarity 0.036 on `lqr-bounds`).
#[test]
fn multipliers_after_the_projection_certify_stationarity() {
    for name in ["lqr-bounds", "lqr-bounds-term", "block-move"] {
        let ex = gharial_problems::build(name).unwrap();
        let sol = solve(&ex, AltroOptions::default().with(|o| o.cost_tolerance = 1e-10));
        let kkt = gharial::problem::kkt_residuals(&ex.problem, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
        eprintln!("{name}: {:?} {kkt:?}", sol.status);
        assert_eq!(sol.status, Status::Converged, "{name}");
        assert!(kkt.max() < 1e-6, "{name}: {kkt:?}");
    }
}

/// From the hanging pendulum at rest (the catalogue's guess), the terminal tip constraint
/// is violated by the whole swing (2 m) and its gradient vanishes by symmetry: the
/// augmented Lagrangian is stationary for every multiplier and penalty. ALTRO stops as
/// `Stalled` once the penalties are at their largest instead of running out its outer
/// iterations, at the guess; the constraint Jacobian there, recomputed here, is zero in
/// the violated row. (ProxDDP, whose step also moves the multipliers, swings it up.)
#[test]
fn a_stationary_violated_start_stalls() {
    let ex = gharial_problems::build("pendulum").unwrap();
    let opts = AltroOptions::default();
    let sol = solve(&ex, opts.clone());
    assert_eq!(sol.status, Status::Stalled);
    assert_eq!(sol.iterations, 0);
    assert!(sol.al_iterations < opts.iterations_outer, "{}", sol.al_iterations);
    assert!((sol.prim_err - 2.0).abs() < 1e-9, "{}", sol.prim_err);
    let mut data = gharial::problem::ProblemData::new(&ex.problem, 1).unwrap();
    data.evaluate(&ex.problem, &sol.xs, &sol.us);
    data.compute_derivatives(&ex.problem, &sol.xs, &sol.us);
    let n = ex.problem.horizon();
    let (c, cd) = (&ex.problem.constraints(n)[0], &data.constraint_data(n)[0]);
    let mut worst_row = (0, 0.0_f64);
    for i in 0..c.nr() {
        if cd.value()[i].abs() > worst_row.1 {
            worst_row = (i, cd.value()[i].abs());
        }
    }
    let row = cd.jx.as_ref().row(worst_row.0);
    let gradient = (0..row.ncols()).map(|j| row[j].abs()).fold(0.0, f64::max);
    assert!(worst_row.1 > 1.9 && gradient < 1e-12, "{worst_row:?} {gradient:e}");
}

/// The Solo-12 centre-of-mass circle's guess (the standing state and the quasi-static
/// torques at every node) does not roll out over its 5 s (the state is non-finite by
/// node 181): ALTRO's start refuses it with an error that names the infeasible start.
#[test]
fn a_guess_that_does_not_roll_out_is_an_error_naming_the_infeasible_start() {
    let ex = gharial_problems::build("solo-com-circle").unwrap();
    let mut s = Altro::new(AltroOptions::default());
    s.setup(&ex.problem).unwrap();
    let err = s
        .solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
        .unwrap_err();
    assert!(matches!(err, gharial::Error::NonFinite { .. }), "{err}");
    let msg = err.to_string();
    assert!(msg.contains("rollout") && msg.contains("infeasible_start"), "{msg}");
}

//! ProxDDP on linear-quadratic problems, against independent references: the dense KKT
//! solve of the exact (unregularised) problem for equality constraints, and the
//! solver-independent KKT residuals of the returned solution.

#[path = "support/lq_ocp.rs"]
mod lq_ocp;

use std::sync::Arc;

use faer::{Col, Mat};
use gharial::constraints::EqualityConstraintSet;
use gharial::costs::QuadraticCost;
use gharial::dynamics::{Dynamics, LinearDiscreteDynamics};
use gharial::functions::{StateError, Unary};
use gharial::lq::{dense, random::SplitMix64};
use gharial::problem::{Problem, StageConstraint, StageModel, kkt_residuals};
use gharial::solvers::Solver;
use gharial::solvers::proxddp::{ProxDdp, ProxDdpOptions, Rollout, StepAcceptance};
use gharial::solvers::{InitialGuess, Status};
use gharial::spaces::{Manifold, VectorSpace};
use lq_ocp::*;

fn solve(p: &Problem, opts: ProxDdpOptions, xs: &[Vec<f64>], us: &[Vec<f64>]) -> gharial::solvers::Solution {
    let mut solver = ProxDdp::new(opts);
    solver.setup(p).unwrap();
    solver.solve(p, InitialGuess::primal(xs, us)).unwrap().clone()
}

#[test]
fn equality_constrained_lq_reaches_the_dense_kkt_solution() {
    for (seed, (nx, nu, n)) in [(1, (3, 2, 10)), (2, (5, 3, 25)), (3, (8, 4, 40)), (4, (2, 1, 5))] {
        let lq = random_lq(nx, nu, n, seed);
        let target: Vec<f64> = (0..nx).map(|i| 0.1 * i as f64).collect();
        for x_target in [None, Some(target.as_slice())] {
            let p = ocp(&lq, None, x_target);
            let reference = dense::solve(&exact_lq(&lq, x_target)).unwrap();
            for rollout in [Rollout::Linear, Rollout::Nonlinear] {
                let (xs, us) = zero_guess(&p);
                // The nonlinear rollout recomputes the co-states from the gains, whose
                // feedback part grows like 1/mu: with mu = 1e-6 its accuracy floor is
                // about eps |x| / mu, a few 1e-9 here.
                let tol = if rollout == Rollout::Linear { 1e-10 } else { 1e-8 };
                let opts = ProxDdpOptions::default().with(|o| {
                    o.rollout = rollout;
                    o.tol = tol;
                    o.mu_init = 1e-6;
                });
                let sol = solve(&p, opts, &xs, &us);
                assert_eq!(
                    sol.status,
                    Status::Converged,
                    "seed {seed} {rollout:?}: {:?}",
                    sol.status
                );
                let scale = 1.0 + reference.xs.iter().map(|c| c.norm_max()).fold(0.0, f64::max);
                let dx = max_diff(&sol.xs, &reference.xs) / scale;
                let du = max_diff(&sol.us, &reference.us) / scale;
                let dl = max_diff(&sol.lambdas, &reference.lambdas) / scale;
                let bound = 100.0 * tol;
                assert!(
                    dx < bound && du < bound && dl < 10.0 * bound,
                    "seed {seed} {rollout:?}: {dx:e} {du:e} {dl:e}"
                );
                if x_target.is_some() {
                    let dn = (0..nx)
                        .map(|i| (sol.nus[n][i] - reference.nus[n][i]).abs())
                        .fold(0.0, f64::max);
                    assert!(dn / scale < 10.0 * bound, "terminal multiplier {dn:e}");
                }
                let kkt = kkt_residuals(&p, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
                assert!(kkt.max() < 10.0 * tol, "{kkt:?}");
            }
        }
    }
}

/// With `mu_init >= 1` the BCL tolerances must still shrink after successful outer
/// steps (by `min(mu, 0.1)`); with the penalty alone as the factor they stayed at 1 and
/// the outer loop updated the multipliers without Newton steps until `max_al_iters`.
#[test]
fn a_large_initial_penalty_still_reaches_the_dense_kkt_solution() {
    let lq = random_lq(4, 2, 20, 7);
    let target = [0.1, -0.2, 0.0, 0.3];
    let p = ocp(&lq, None, Some(&target));
    let reference = dense::solve(&exact_lq(&lq, Some(&target))).unwrap();
    for mu_init in [1.0, 10.0] {
        let (xs, us) = zero_guess(&p);
        let opts = ProxDdpOptions::default().with(|o| {
            o.mu_init = mu_init;
            o.tol = 1e-9;
        });
        let sol = solve(&p, opts, &xs, &us);
        assert_eq!(sol.status, Status::Converged, "mu_init {mu_init}");
        assert!(sol.iterations < 60, "mu_init {mu_init}: {} iterations", sol.iterations);
        let scale = 1.0 + reference.xs.iter().map(|c| c.norm_max()).fold(0.0, f64::max);
        let dx = max_diff(&sol.xs, &reference.xs) / scale;
        let du = max_diff(&sol.us, &reference.us) / scale;
        assert!(dx < 1e-7 && du < 1e-7, "mu_init {mu_init}: {dx:e} {du:e}");
    }
}

#[test]
fn box_constrained_lq_satisfies_the_kkt_conditions_for_every_step_acceptance() {
    let lq = random_lq(4, 2, 30, 7);
    let p = ocp(&lq, Some(0.3), None);
    for acc in [
        StepAcceptance::Linesearch,
        StepAcceptance::NonmonotoneLinesearch,
        StepAcceptance::Filter,
    ] {
        for rollout in [Rollout::Linear, Rollout::Nonlinear] {
            let (xs, us) = zero_guess(&p);
            let opts = ProxDdpOptions::default().with(|o| {
                o.rollout = rollout;
                o.step_acceptance = acc;
            });
            let sol = solve(&p, opts, &xs, &us);
            assert_eq!(sol.status, Status::Converged, "{acc:?} {rollout:?}");
            let kkt = kkt_residuals(&p, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
            assert!(kkt.max() < 1e-6, "{acc:?} {rollout:?}: {kkt:?}");
            assert!(
                sol.us.iter().flatten().any(|u| (u.abs() - 0.3).abs() < 1e-7),
                "the box is active"
            );
        }
    }
}

/// The point mass against its control box, every control of a knot at its bound at the
/// optimum (the cases of the box-DDP test), for ProxDDP's default options and its
/// active-set prediction: converged to the KKT conditions inside the box. The first
/// case once ended in a regularisation failure (a 2x2 pivot of an earlier initial-stage
/// factorization read as one of the next).
#[test]
fn box_constrained_point_mass_with_every_control_of_a_knot_clamped() {
    for (n, x0, w) in clamped_point_mass_cases() {
        let p = ocp(&point_mass(n, x0, w), Some(2.0), None);
        for active_set_iters in [0, 10] {
            let what = format!("N = {n}, x0 = {x0:?}, active_set_iters = {active_set_iters}");
            let (xs, us) = zero_guess(&p);
            let opts = ProxDdpOptions::default().with(|o| o.active_set_iters = active_set_iters);
            let sol = solve(&p, opts, &xs, &us);
            assert_eq!(sol.status, Status::Converged, "{what}");
            let kkt = kkt_residuals(&p, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
            assert!(kkt.max() < 1e-5, "{what}: {kkt:?}");
            assert!(sol.us.iter().flatten().all(|u| u.abs() <= 2.0 + 1e-6), "{what}");
        }
    }
}

#[test]
fn warm_start_from_a_converged_solution_takes_at_most_two_iterations() {
    let lq = random_lq(4, 2, 30, 11);
    let target = reachable_target(&lq, 0.5);
    let p = ocp(&lq, Some(0.5), Some(&target));
    let (xs, us) = zero_guess(&p);
    let mut solver = ProxDdp::new(ProxDdpOptions::default());
    solver.setup(&p).unwrap();
    let first = solver.solve(&p, InitialGuess::primal(&xs, &us)).unwrap().clone();
    assert_eq!(first.status, Status::Converged);
    let second = solver.solve(&p, InitialGuess::from_solution(&first)).unwrap();
    assert_eq!(second.status, Status::Converged);
    assert!(second.iterations <= 2, "{} iterations", second.iterations);
}

#[test]
fn box_constrained_lq_has_the_optimal_cost_of_an_independent_qp_solver() {
    let cases = qp_reference_cases();
    assert_eq!(cases.iter().filter(|c| c.seed < 40).count(), 6);
    for case in cases.iter().filter(|c| c.seed < 40) {
        let (seed, reference) = (case.seed, case.clarabel_cost);
        let p = ocp(&case.lq, Some(case.umax), case.target.as_deref());
        for rollout in [Rollout::Linear, Rollout::Nonlinear] {
            let (xs, us) = zero_guess(&p);
            // The nonlinear rollout's round-off floor is about eps |x| / mu (see above).
            let tol = if rollout == Rollout::Linear { 1e-9 } else { 1e-8 };
            let opts = ProxDdpOptions::default().with(|o| {
                o.rollout = rollout;
                o.tol = tol;
            });
            let sol = solve(&p, opts, &xs, &us);
            assert_eq!(sol.status, Status::Converged, "seed {seed} {rollout:?}");
            let rel = (sol.cost - reference).abs() / reference.abs().max(1.0);
            assert!(
                rel < 1e-6,
                "seed {seed} {rollout:?}: cost {} vs QP {reference} ({rel:e})",
                sol.cost
            );
        }
    }
}

/// The active-set prediction on box-constrained LQ problems: the linearisation of the
/// subproblem is exact, so the predicted step solves each subproblem (fixed multipliers
/// and penalty) with the box in it, where the Newton step sees only the bounds active at
/// the current point. Both reach the optimal cost of the independent QP solver; the
/// prediction in fewer iterations.
#[test]
fn active_set_prediction_reaches_the_box_constrained_optimum_in_fewer_iterations() {
    let cases = qp_reference_cases();
    assert_eq!(cases.iter().filter(|c| c.seed > 40).count(), 3);
    for case in cases.iter().filter(|c| c.seed > 40) {
        let (seed, reference) = (case.seed, case.clarabel_cost);
        let p = ocp(&case.lq, Some(case.umax), None);
        let (xs, us) = zero_guess(&p);
        let iterations = [0, 10].map(|active_set_iters| {
            let opts = ProxDdpOptions::default().with(|o| {
                o.active_set_iters = active_set_iters;
                o.tol = 1e-9;
            });
            let sol = solve(&p, opts, &xs, &us);
            assert_eq!(sol.status, Status::Converged, "seed {seed} K {active_set_iters}");
            let rel = (sol.cost - reference).abs() / reference.abs().max(1.0);
            assert!(
                rel < 1e-6,
                "seed {seed} K {active_set_iters}: cost {} vs QP {reference} ({rel:e})",
                sol.cost
            );
            let kkt = kkt_residuals(&p, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
            assert!(kkt.max() < 1e-8, "seed {seed} K {active_set_iters}: {kkt:?}");
            sol.iterations
        });
        assert!(
            iterations[1] < iterations[0],
            "seed {seed}: {} iterations with the prediction, {} without",
            iterations[1],
            iterations[0]
        );
    }
}

#[test]
fn dynamically_infeasible_state_guess_converges() {
    let lq = random_lq(5, 2, 40, 31);
    let p = ocp(&lq, Some(0.4), None);
    let mut rng = SplitMix64::new(99);
    let xs: Vec<Vec<f64>> = (0..=lq.n)
        .map(|_| (0..lq.nx).map(|_| rng.uniform(-2.0, 2.0)).collect())
        .collect();
    let us: Vec<Vec<f64>> = (0..lq.n)
        .map(|_| (0..lq.nu).map(|_| rng.uniform(-1.0, 1.0)).collect())
        .collect();
    for rollout in [Rollout::Linear, Rollout::Nonlinear] {
        let sol = solve(
            &p,
            ProxDdpOptions::default().with(|o| {
                o.rollout = rollout;
            }),
            &xs,
            &us,
        );
        assert_eq!(sol.status, Status::Converged, "{rollout:?}");
        let kkt = kkt_residuals(&p, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
        assert!(kkt.max() < 1e-6, "{rollout:?}: {kkt:?}");
    }
}

#[test]
fn general_initial_constraint_matches_the_dense_kkt_solution() {
    // Only the first state coordinate is fixed (paper (65)): G0 = e_0ᵀ, g0 = -0.5.
    use gharial::functions::LinearUnaryFunction;
    use gharial::problem::InitialCondition;
    let lq = random_lq(4, 2, 15, 41);
    let g0 = Mat::from_fn(1, lq.nx, |_, j| if j == 0 { 1.0 } else { 0.0 });
    let init = Arc::new(LinearUnaryFunction::new(g0.as_ref(), &[-0.5]).unwrap());
    let base = ocp(&lq, None, None);
    let p = Problem::with_initial(
        InitialCondition::Constraint(init),
        base.stages().to_vec(),
        base.terminal_cost().clone(),
    )
    .unwrap();
    let mut exact = exact_lq(&lq, None);
    exact.G0 = g0;
    exact.g0 = Col::from_fn(1, |_| -0.5);
    let reference = dense::solve(&exact).unwrap();
    for rollout in [Rollout::Linear, Rollout::Nonlinear] {
        let (xs, us) = zero_guess(&p);
        let opts = ProxDdpOptions::default().with(|o| {
            o.rollout = rollout;
            o.tol = 1e-9;
            o.mu_init = 1e-6;
        });
        let sol = solve(&p, opts, &xs, &us);
        assert_eq!(sol.status, Status::Converged, "{rollout:?}");
        assert!(max_diff(&sol.xs, &reference.xs) < 1e-7, "{rollout:?}");
        assert!(max_diff(&sol.us, &reference.us) < 1e-7, "{rollout:?}");
        assert!((sol.xs[0][0] - 0.5).abs() < 1e-8);
    }
}

#[test]
fn implicit_dynamics_match_the_dense_kkt_solution() {
    let lq = random_lq(3, 2, 20, 51);
    let (p, exact) = implicit_euler_ocp(&lq, 0.1);
    let reference = dense::solve(&exact).unwrap();
    for rollout in [Rollout::Linear, Rollout::Nonlinear] {
        let (xs, us) = zero_guess(&p);
        let opts = ProxDdpOptions::default().with(|o| {
            o.rollout = rollout;
            o.tol = 1e-9;
            o.mu_init = 1e-6;
        });
        let sol = solve(&p, opts, &xs, &us);
        assert_eq!(sol.status, Status::Converged, "{rollout:?}");
        assert!(max_diff(&sol.xs, &reference.xs) < 1e-7, "{rollout:?}");
        assert!(max_diff(&sol.us, &reference.us) < 1e-7, "{rollout:?}");
        assert!(max_diff(&sol.lambdas, &reference.lambdas) < 1e-6, "{rollout:?}");
    }
}

#[test]
fn constraint_and_dynamics_scalings_do_not_change_the_solution() {
    let lq = random_lq(4, 2, 25, 61);
    let target = reachable_target(&lq, 0.3);
    let base = ocp(&lq, Some(0.3), Some(&target));
    let reference = {
        let (xs, us) = zero_guess(&base);
        solve(
            &base,
            ProxDdpOptions::default().with(|o| {
                o.tol = 1e-9;
                o.dyn_al_scale = 1.0;
            }),
            &xs,
            &us,
        )
    };
    assert_eq!(reference.status, Status::Converged);
    // Scale the box by 10 and the terminal constraint by 0.1, and the dynamics by 1e-3.
    let mut p = base.clone();
    for st in p.stages_mut() {
        let c = st.constraints()[0].clone().with_scale(10.0);
        *st = StageModel::new(st.cost.clone(), st.dynamics.clone())
            .unwrap()
            .with_constraint(c)
            .unwrap();
    }
    let mut q = Problem::new(&lq.x0, p.stages().to_vec(), p.terminal_cost().clone()).unwrap();
    q.add_terminal_constraint(base.terminal_constraints()[0].clone().with_scale(0.1))
        .unwrap();
    let (xs, us) = zero_guess(&q);
    let opts = ProxDdpOptions::default().with(|o| {
        o.tol = 1e-9;
        o.dyn_al_scale = 1e-3;
    });
    let sol = solve(&q, opts, &xs, &us);
    assert_eq!(sol.status, Status::Converged);
    let dx: f64 = sol
        .xs
        .iter()
        .zip(&reference.xs)
        .flat_map(|(a, b)| a.iter().zip(b).map(|(p, q)| (p - q).abs()))
        .fold(0.0, f64::max);
    let du: f64 = sol
        .us
        .iter()
        .zip(&reference.us)
        .flat_map(|(a, b)| a.iter().zip(b).map(|(p, q)| (p - q).abs()))
        .fold(0.0, f64::max);
    assert!(dx < 1e-7 && du < 1e-7, "{dx:e} {du:e}");
}

#[test]
fn invalid_options_and_inputs_give_errors() {
    let lq = random_lq(3, 1, 5, 71);
    let p = ocp(&lq, Some(0.5), None);
    let (xs, us) = zero_guess(&p);
    for (opts, name) in [
        (
            ProxDdpOptions::default().with(|o| {
                o.tol = 0.0;
            }),
            "tol",
        ),
        (
            ProxDdpOptions::default().with(|o| {
                o.mu_init = f64::NAN;
            }),
            "mu_init",
        ),
        (
            ProxDdpOptions::default().with(|o| {
                o.mu_update_factor = 1.5;
            }),
            "mu_update_factor",
        ),
        (
            ProxDdpOptions::default().with(|o| {
                o.max_iters = 0;
            }),
            "max_iters",
        ),
        (
            ProxDdpOptions::default().with(|o| {
                o.num_threads = 0;
            }),
            "num_threads",
        ),
    ] {
        let e = ProxDdp::new(opts).setup(&p).err().unwrap();
        assert!(e.to_string().contains(name), "{e}");
    }
    // Solve before setup, on a problem of other dimensions, with a bad guess.
    let mut solver = ProxDdp::new(ProxDdpOptions::default());
    assert!(solver.solve(&p, InitialGuess::primal(&xs, &us)).is_err());
    solver.setup(&p).unwrap();
    let other = ocp(&random_lq(3, 1, 6, 71), Some(0.5), None);
    let (xo, uo) = zero_guess(&other);
    assert!(solver.solve(&other, InitialGuess::primal(&xo, &uo)).is_err());
    let mut bad = xs.clone();
    bad[2][1] = f64::NAN;
    let e = solver.solve(&p, InitialGuess::primal(&bad, &us)).err().unwrap();
    assert!(e.to_string().contains("xs[2]"), "{e}");
    let short = &us[..3];
    assert!(solver.solve(&p, InitialGuess::primal(&xs, short)).is_err());
}

#[test]
fn time_budget_and_callbacks_stop_the_solve_with_a_usable_iterate() {
    let lq = random_lq(4, 2, 30, 81);
    let p = ocp(&lq, Some(0.2), None);
    let (xs, us) = zero_guess(&p);
    let opts = ProxDdpOptions::default().with(|o| {
        o.max_time = Some(std::time::Duration::ZERO);
    });
    let sol = solve(&p, opts, &xs, &us);
    assert_eq!(sol.status, Status::TimeBudget);
    assert!(sol.xs.iter().flatten().all(|v| v.is_finite()));

    struct StopAfter(usize);
    impl gharial::solvers::Callback for StopAfter {
        fn on_iteration(&mut self, r: &gharial::solvers::IterationRecord) -> bool {
            r.iter + 1 < self.0
        }
    }
    let mut solver = ProxDdp::new(ProxDdpOptions::default());
    solver.setup(&p).unwrap();
    let sol = solver
        .solve_with_callback(&p, InitialGuess::primal(&xs, &us), &mut StopAfter(2))
        .unwrap();
    assert_eq!(sol.iterations, 2);
    assert_eq!(sol.history.len(), 2);
    assert_eq!(sol.status, Status::Interrupted);
    // The stopped iterate warm-starts a full solve.
    let warm = sol.clone();
    let sol = solver.solve(&p, InitialGuess::from_solution(&warm)).unwrap();
    assert_eq!(sol.status, Status::Converged);
}

/// Contradictory constraints (`u = 3` and a box `|u| <= 1` on the same controls, or
/// `u = 3` and `u = -3`) stop as infeasible once the subproblem at the smallest penalty
/// stays infeasible (ProxNLP's rule), long before the outer-iteration limit, with a
/// finite iterate.
#[test]
fn contradictory_constraints_stop_as_infeasible() {
    use gharial::constraints::BoxConstraint;
    use gharial::functions::ControlError;
    let lq = point_mass(5, [1.0; 4], 1.0);
    for second in [(-3.0, None), (0.0, Some(1.0))] {
        let mut p = ocp(&lq, None, None);
        let sp = space(&lq);
        let mut stage = p.stages()[0].clone();
        let eq = Arc::new(ControlError::new(sp.as_ref(), &[3.0, 3.0]).unwrap());
        stage
            .add_constraint(StageConstraint::new("u = 3", eq, Arc::new(EqualityConstraintSet)))
            .unwrap();
        let f = Arc::new(ControlError::new(sp.as_ref(), &[second.0; 2]).unwrap());
        let set: Arc<dyn gharial::constraints::ConstraintSet> = match second.1 {
            None => Arc::new(EqualityConstraintSet),
            Some(m) => Arc::new(BoxConstraint::new(&[-m; 2], &[m; 2]).unwrap()),
        };
        stage.add_constraint(StageConstraint::new("second", f, set)).unwrap();
        p = Problem::new(&lq.x0, vec![stage; 5], p.terminal_cost().clone()).unwrap();
        let (xs, us) = zero_guess(&p);
        let sol = solve(&p, ProxDdpOptions::default(), &xs, &us);
        assert_eq!(sol.status, Status::Infeasible, "{second:?}");
        assert!(sol.al_iterations < ProxDdpOptions::default().max_al_iters, "{second:?}");
        assert!(sol.xs.iter().chain(&sol.us).flatten().all(|v| v.is_finite()));
    }
}

#[test]
fn diverging_problems_return_a_status_and_finite_values() {
    // A cost unbounded below in u (R = -I): no minimiser exists.
    let mut lq = random_lq(3, 2, 10, 91);
    lq.r = Mat::from_fn(2, 2, |i, j| if i == j { -1.0 } else { 0.0 });
    let p = ocp(&lq, None, None);
    let (xs, us) = zero_guess(&p);
    let sol = solve(
        &p,
        ProxDdpOptions::default().with(|o| {
            o.max_iters = 30;
        }),
        &xs,
        &us,
    );
    assert_ne!(sol.status, Status::Converged);
    assert!(
        sol.xs.iter().chain(&sol.us).flatten().all(|v| v.is_finite()),
        "{:?}",
        sol.status
    );
    assert!(sol.cost.is_finite());

    // A guess at which the model evaluates to NaN: reported, guess returned unchanged.
    let lq = random_lq(3, 1, 5, 92);
    let p = ocp(&lq, None, None);
    let (mut xs, us) = zero_guess(&p);
    xs[3][0] = 1e200;
    let sol = solve(&p, ProxDdpOptions::default(), &xs, &us);
    assert_eq!(sol.status, Status::NonFinite);
    assert_eq!(sol.xs, xs);
}

/// `h(x) = x_0² + x_1² - r²` (stay in a disc), with exact second derivatives through
/// hyper-dual numbers.
struct Disc {
    radius: f64,
}

impl gharial::autodiff::AutoStageFn for Disc {
    fn nx(&self) -> usize {
        4
    }
    fn nu(&self) -> usize {
        2
    }
    fn nr(&self) -> usize {
        1
    }
    fn eval<D: gharial::autodiff::ManifoldScalar>(&self, x: &[D], _u: &[D], out: &mut [D]) {
        out[0] = x[0] * x[0] + x[1] * x[1] - D::from(self.radius * self.radius);
    }
}

#[test]
fn exact_and_gauss_newton_hessians_reach_the_same_kkt_point() {
    // A planar double integrator steered towards (2, 1) while staying in the unit disc:
    // the curvature of the active disc constraint enters the exact Hessian only.
    use gharial::autodiff::AutoDiff;
    use gharial::constraints::NegativeOrthant;
    use gharial::solvers::proxddp::HessianApprox;
    let dt = 0.1;
    let a = Mat::from_fn(4, 4, |i, j| {
        if i == j {
            1.0
        } else if j == i + 2 {
            dt
        } else {
            0.0
        }
    });
    let b = Mat::from_fn(4, 2, |i, j| if i == j + 2 { dt } else { 0.0 });
    let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(4));
    let dynamics = Dynamics::Explicit(Arc::new(
        LinearDiscreteDynamics::new(a.as_ref(), b.as_ref(), &[0.0; 4]).unwrap(),
    ));
    let q = Mat::from_fn(4, 4, |i, j| if i == j && i < 2 { 1.0 } else { 0.0 });
    let qv = [-1.2, -0.4, 0.0, 0.0];
    let cost = Arc::new(
        QuadraticCost::new(
            q.as_ref(),
            Mat::zeros(4, 2).as_ref(),
            Mat::<f64>::identity(2, 2).as_ref(),
            &qv,
            &[0.0; 2],
        )
        .unwrap(),
    );
    let disc = Arc::new(AutoDiff::stage(space, Disc { radius: 1.0 }).unwrap());
    let stage = StageModel::new(cost, dynamics)
        .unwrap()
        .with_constraint(StageConstraint::new("disc", disc, Arc::new(NegativeOrthant)))
        .unwrap();
    let term = Arc::new(QuadraticCost::terminal(q.as_ref(), &qv).unwrap());
    let p = Problem::new(&[0.0, 0.0, 0.0, 0.0], vec![stage; 30], term).unwrap();
    let (xs, us) = zero_guess(&p);
    let mut sols = Vec::new();
    for hessian in [HessianApprox::Exact, HessianApprox::GaussNewton] {
        let opts = ProxDdpOptions::default().with(|o| {
            o.hessian = hessian;
            o.tol = 1e-8;
        });
        let sol = solve(&p, opts, &xs, &us);
        assert_eq!(sol.status, Status::Converged, "{hessian:?}");
        let kkt = kkt_residuals(&p, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
        assert!(kkt.max() < 1e-7, "{hessian:?}: {kkt:?}");
        // The disc is active at the end of the horizon (x_N itself is not constrained).
        let end = &sol.xs[29];
        assert!((end[0] * end[0] + end[1] * end[1] - 1.0).abs() < 1e-6, "{end:?}");
        sols.push(sol);
    }
    let dx = max_diff(
        &sols[0].xs,
        &sols[1]
            .xs
            .iter()
            .map(|v| Col::from_fn(v.len(), |i| v[i]))
            .collect::<Vec<_>>(),
    );
    assert!(dx < 1e-6, "{dx:e}");
    // Newton with the constraint curvature converges at least as fast as Gauss-Newton
    // (both counts are dominated by the outer penalty updates).
    assert!(
        sols[0].iterations <= sols[1].iterations,
        "exact {} vs Gauss-Newton {}",
        sols[0].iterations,
        sols[1].iterations
    );
}

/// A pendulum on `SO(2) × R`, `θ = 0` hanging: `ẋ = (ω, -g sin θ + u)`.
struct SwingPendulum;

impl gharial::autodiff::AutoOdeFn for SwingPendulum {
    fn nx(&self) -> usize {
        3
    }
    fn nu(&self) -> usize {
        1
    }
    fn eval<D: gharial::autodiff::ManifoldScalar>(&self, x: &[D], u: &[D], xdot: &mut [D]) {
        xdot[0] = x[2];
        xdot[1] = x[1] * (-9.81) + u[0];
    }
}

/// Swing-up of [`SwingPendulum`] from hanging at rest to upright at rest in `n` RK2
/// steps of `dt`, control cost `w_u dt u²`, terminal equality constraint; the guess is
/// `u = 0` (the pendulum stays hanging).
fn swing_up(n: usize, dt: f64, w_u: f64) -> (Problem, Vec<Vec<f64>>, Vec<Vec<f64>>) {
    use gharial::autodiff::AutoDiff;
    use gharial::costs::{ConstantCost, QuadraticControlCost};
    use gharial::dynamics::ExplicitRungeKutta;
    use gharial::spaces::{CartesianProduct, SO2};
    let space: Arc<dyn Manifold> = Arc::new(CartesianProduct::new(vec![
        Arc::new(SO2::new()),
        Arc::new(VectorSpace::new(1)),
    ]));
    let ode = Arc::new(AutoDiff::ode(space.clone(), SwingPendulum).unwrap());
    let dynamics = Dynamics::Explicit(Arc::new(ExplicitRungeKutta::rk2(ode, dt).unwrap()));
    let cost = Arc::new(QuadraticControlCost::diagonal(space.as_ref(), &[0.0], &[w_u * dt]).unwrap());
    let stage = StageModel::new(cost, dynamics).unwrap();
    let x0 = [1.0, 0.0, 0.0];
    let upright = [-1.0, 0.0, 0.0];
    let term = Arc::new(ConstantCost::zero(space.as_ref(), 0));
    let f = Arc::new(Unary::new(Arc::new(StateError::new(space, &upright).unwrap()), 0));
    let p = Problem::new(&x0, vec![stage; n], term)
        .unwrap()
        .with_terminal_constraint(StageConstraint::new("x_N", f, Arc::new(EqualityConstraintSet)))
        .unwrap();
    let xs = vec![x0.to_vec(); n + 1];
    let us = vec![vec![0.0]; n];
    (p, xs, us)
}

#[test]
fn swing_up_with_a_stiff_dynamics_penalty_converges_without_exploding_iterates() {
    // With a stiff dynamics penalty (scale 1e-3) the first Newton steps of the swing-up
    // ask for several turns and their rollouts are far worse than the current point; the
    // filter must not accept such trials, even right after a penalty update emptied it
    // (before it did, the nonlinear rollout wandered and hit the iteration limit).
    let (p, xs, us) = swing_up(100, 0.02, 1e-3);
    for rollout in [Rollout::Nonlinear, Rollout::Linear] {
        let opts = ProxDdpOptions::default().with(|o| {
            o.mu_init = 1e-3;
            o.dyn_al_scale = 1e-3;
            o.rollout = rollout;
            o.max_iters = 200;
        });
        let sol = solve(&p, opts, &xs, &us);
        let worst = sol
            .history
            .iter()
            .filter(|r| r.merit.is_finite())
            .fold(0.0_f64, |m, r| m.max(r.merit));
        let first = sol.history.first().map(|r| r.merit - r.dmerit).unwrap();
        assert!(
            worst < 1e4 * first,
            "{rollout:?}: accepted merit {worst:e} from {first:e}"
        );
        assert_eq!(sol.status, Status::Converged, "{rollout:?}");
        let kkt = kkt_residuals(&p, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
        assert!(kkt.max() < 1e-5, "{rollout:?}: {kkt:?}");
        // Upright at the end.
        assert!((sol.xs[100][0] + 1.0).abs() < 1e-6);
    }
}

/// Bitwise equality of two solutions (iterates, multipliers, iteration counts).
fn assert_same_solution(a: &gharial::solvers::Solution, b: &gharial::solvers::Solution, what: &str) {
    assert_eq!((a.status, a.iterations), (b.status, b.iterations), "{what}");
    assert_eq!((&a.xs, &a.us), (&b.xs, &b.us), "{what}: primal");
    assert_eq!((&a.lambdas, &a.nus), (&b.lambdas, &b.nus), "{what}: multipliers");
}

/// The LQ knots keep the constant cost Hessians and dynamics Jacobians during a solve;
/// a second solve with the same solver must write them anew, whether the problem is
/// unchanged, has other models of the same dimensions, or has parameters changed in
/// place (a named cost stack's weight, a tracking target).
#[test]
fn reused_solver_matches_a_fresh_one_when_models_or_weights_change() {
    use gharial::costs::{CostStack, QuadraticControlCost, QuadraticStateCost};
    let lq = random_lq(4, 2, 20, 21);
    let target = reachable_target(&lq, 0.5);
    let p = ocp(&lq, Some(0.5), Some(&target));
    let (xs, us) = zero_guess(&p);
    let mut solver = ProxDdp::new(ProxDdpOptions::default());
    solver.setup(&p).unwrap();
    let first = solver.solve(&p, InitialGuess::primal(&xs, &us)).unwrap().clone();
    assert_eq!(first.status, Status::Converged);
    let again = solver.solve(&p, InitialGuess::primal(&xs, &us)).unwrap().clone();
    assert_same_solution(&again, &first, "same problem");
    // Other dynamics and costs of the same dimensions, given to the same solver.
    let other = ocp(&random_lq(4, 2, 20, 22), Some(0.5), Some(&target));
    let reused = solver.solve(&other, InitialGuess::primal(&xs, &us)).unwrap().clone();
    assert_same_solution(
        &reused,
        &solve(&other, ProxDdpOptions::default(), &xs, &us),
        "other models",
    );
    assert_ne!(reused.us, first.us);
    // Parameters changed in place between solves of one problem.
    let sp = space(&lq);
    let x_cost = Arc::new(QuadraticStateCost::diagonal(sp.clone(), &[0.0; 4], &[1.0, 2.0, 1.0, 0.5], 2).unwrap());
    let u_cost = Arc::new(QuadraticControlCost::diagonal(sp.as_ref(), &[0.1, -0.1], &[0.3, 0.2]).unwrap());
    let stack = Arc::new(
        CostStack::new(sp.as_ref(), 2)
            .with("x", x_cost.clone(), 1.0)
            .unwrap()
            .with("u", u_cost.clone(), 1.0)
            .unwrap(),
    );
    let mut q = ocp(&lq, Some(0.5), None);
    for (t, st) in q.stages_mut().iter_mut().enumerate() {
        st.cost = if t % 2 == 0 { stack.clone() } else { u_cost.clone() };
    }
    let mut solver = ProxDdp::new(ProxDdpOptions::default());
    solver.setup(&q).unwrap();
    let before = solver.solve(&q, InitialGuess::primal(&xs, &us)).unwrap().clone();
    stack.set_weight("u", 5.0).unwrap();
    u_cost.set_target(&[0.2, 0.3]).unwrap();
    x_cost.set_target(&[0.1, 0.0, -0.1, 0.2]).unwrap();
    let after = solver.solve(&q, InitialGuess::primal(&xs, &us)).unwrap().clone();
    assert_same_solution(
        &after,
        &solve(&q, ProxDdpOptions::default(), &xs, &us),
        "changed weights",
    );
    assert_eq!(after.status, Status::Converged);
    let kkt = kkt_residuals(&q, &after.xs, &after.us, &after.lambdas, &after.nus).unwrap();
    assert!(kkt.max() < 1e-6, "{kkt:?}");
    assert_ne!(before.us, after.us);
}

/// On an unconstrained LQ one ProxDDP iteration is the exact KKT point: without
/// constraints the Newton step treats the dynamics without the proximal term
/// (`DynamicsStep::Auto`); the proximal step of the paper leaves a residual of the order
/// of `mu_d |λ|`.
#[test]
fn one_iteration_solves_an_unconstrained_lq_exactly() {
    use gharial::solvers::proxddp::DynamicsStep;
    for (seed, (nx, nu, n)) in [(21, (3, 2, 10)), (22, (6, 3, 40)), (23, (8, 4, 100))] {
        let lq = random_lq(nx, nu, n, seed);
        let p = ocp(&lq, None, None);
        let reference = dense::solve(&exact_lq(&lq, None)).unwrap();
        for rollout in [Rollout::Linear, Rollout::Nonlinear] {
            let (xs, us) = zero_guess(&p);
            let sol = solve(&p, ProxDdpOptions::default().with(|o| o.rollout = rollout), &xs, &us);
            let what = format!("seed {seed} {rollout:?}");
            assert_eq!(sol.status, Status::Converged, "{what}");
            assert_eq!(sol.iterations, 1, "{what}");
            assert!(sol.prim_err < 1e-13, "{what}: dynamics residual {:e}", sol.prim_err);
            assert!(max_diff(&sol.xs, &reference.xs) < 1e-10, "{what}");
            assert!(max_diff(&sol.us, &reference.us) < 1e-10, "{what}");
            let proximal = ProxDdpOptions::default().with(|o| {
                o.rollout = rollout;
                o.dynamics_step = DynamicsStep::Proximal;
            });
            let prox = solve(&p, proximal, &xs, &us);
            assert_eq!(prox.status, Status::Converged, "{what}");
            assert!(
                prox.prim_err > 1e3 * sol.prim_err.max(1e-16),
                "{what}: {:e}",
                prox.prim_err
            );
        }
    }
}

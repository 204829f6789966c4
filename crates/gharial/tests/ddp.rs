//! The DDP family (DDP, FDDP, box-DDP, box-FDDP) on linear-quadratic problems and a small
//! nonlinear one (the exact Hessian), against
//! independent references: the dense KKT solve of the exact problem, the Clarabel optimum
//! of box-constrained problems, finite-difference Newton steps, and the solver-independent
//! KKT residuals of the result.

#[path = "support/lq_ocp.rs"]
mod lq_ocp;
#[path = "support/pendulum.rs"]
mod pendulum;

use std::sync::Arc;

use faer::{Col, Mat};
use gharial::constraints::{BoxConstraint, NegativeOrthant};
use gharial::costs::QuadraticCost;
use gharial::dynamics::{Dynamics, ExplicitDynamics, ExplicitDynamicsData};
use gharial::functions::{StateError, Unary};
use gharial::lq::dense;
use gharial::problem::{Problem, StageConstraint, StageModel, kkt_residuals};
use gharial::solvers::ddp::{Ddp, DdpOptions, DdpVariant};
use gharial::solvers::{Callback, InitialGuess, IterationRecord, Solution, Solver, Status};
use gharial::spaces::Manifold;
use lq_ocp::*;

fn solve(p: &Problem, opts: DdpOptions, xs: &[Vec<f64>], us: &[Vec<f64>]) -> Solution {
    let mut solver = Ddp::new(opts);
    solver.setup(p).unwrap();
    solver.solve(p, InitialGuess::primal(xs, us)).unwrap().clone()
}

fn rollout(p: &Problem, us: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let (mut xs, _) = zero_guess(p);
    let gharial::problem::InitialCondition::Fixed(x0) = p.initial_condition() else {
        unreachable!()
    };
    xs[0].copy_from_slice(x0);
    gharial::problem::ProblemData::new(p, 1)
        .unwrap()
        .rollout(p, &mut xs, us)
        .unwrap();
    xs
}

/// On an unconstrained LQ one step of every variant is the exact KKT point, from a
/// rolled-out guess and (the multiple-shooting variants keep the gaps) from states that
/// violate the dynamics; the convergence check then stops the solve.
#[test]
fn one_step_solves_an_unconstrained_lq_exactly() {
    for (seed, (nx, nu, n)) in [(1, (3, 2, 10)), (2, (5, 3, 25)), (3, (8, 4, 40)), (4, (2, 1, 5))] {
        let lq = random_lq(nx, nu, n, seed);
        let p = ocp(&lq, None, None);
        let reference = dense::solve(&exact_lq(&lq, None)).unwrap();
        let (zeros, us) = zero_guess(&p);
        let feasible = rollout(&p, &us);
        for variant in DdpVariant::ALL {
            for (guess, xs) in [("rollout", &feasible), ("infeasible", &zeros)] {
                let sol = solve(&p, DdpOptions::new(variant), xs, &us);
                let what = format!("seed {seed} {} from the {guess} guess", variant.name());
                assert_eq!(sol.status, Status::Converged, "{what}");
                assert_eq!(sol.iterations, 1, "{what}");
                assert!(max_diff(&sol.xs, &reference.xs) < 1e-9, "{what}");
                assert!(max_diff(&sol.us, &reference.us) < 1e-9, "{what}");
                // The co-states of the last backward pass, at the solution.
                assert!(max_diff(&sol.lambdas, &reference.lambdas) < 1e-8, "{what}");
                let kkt = kkt_residuals(&p, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
                assert!(kkt.max() < 1e-9, "{what}: {kkt:?}");
            }
        }
    }
}

/// Linear dynamics that do not declare their Jacobians constant: the solvers then factor
/// the LQ anew at every backward pass.
struct Undeclared(Arc<dyn ExplicitDynamics>);

impl ExplicitDynamics for Undeclared {
    fn space(&self) -> &Arc<dyn Manifold> {
        self.0.space()
    }
    fn nu(&self) -> usize {
        self.0.nu()
    }
    fn create_workspace(&self) -> gharial::functions::Workspace {
        self.0.create_workspace()
    }
    fn forward(&self, x: &[f64], u: &[f64], data: &mut ExplicitDynamicsData) {
        self.0.forward(x, u, data)
    }
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut ExplicitDynamicsData) {
        self.0.jacobians(x, u, data)
    }
}

/// On a linear-quadratic problem the backward passes after the first keep its
/// factorization while the regularisation stays (their vector part alone): every variant
/// returns, bit for bit, what it returns when the dynamics hide that their Jacobians are
/// constant, from feasible and infeasible guesses, with and without regularisation.
#[test]
fn kept_factorizations_change_no_result_on_linear_quadratic_problems() {
    let lq = random_lq(6, 3, 30, 7);
    let p = ocp(&lq, None, None);
    let mut q = p.clone();
    for stage in q.stages_mut() {
        let Dynamics::Explicit(d) = &stage.dynamics else {
            unreachable!()
        };
        stage.dynamics = Dynamics::Explicit(Arc::new(Undeclared(d.clone())));
    }
    assert!(p.has_constant_derivatives() && !q.has_constant_derivatives());
    assert!(!pendulum::euler_swing_up(5, [0.0, 0.0]).has_constant_derivatives());
    let (zeros, us) = zero_guess(&p);
    let feasible = rollout(&p, &us);
    for variant in DdpVariant::ALL {
        for reg_init in [0.0, 1e-3] {
            for xs in [&feasible, &zeros] {
                let opts = DdpOptions::new(variant).with(|o| {
                    o.reg_init = reg_init;
                    o.tol = 1e-12;
                });
                let (a, b) = (solve(&p, opts.clone(), xs, &us), solve(&q, opts, xs, &us));
                let what = format!("{} reg_init {reg_init}", variant.name());
                assert_eq!((a.status, a.iterations), (b.status, b.iterations), "{what}");
                assert_eq!((&a.xs, &a.us, &a.lambdas), (&b.xs, &b.us, &b.lambdas), "{what}");
                assert_eq!(a.feedforward, b.feedforward, "{what}");
                assert_eq!(a.cost.to_bits(), b.cost.to_bits(), "{what}");
            }
        }
    }
}

/// Implicit dynamics (implicit Euler of a linear ODE): the exact LQ has `E ≠ -I`, and the
/// rollouts solve for the next state by Newton-Raphson.
#[test]
fn implicit_dynamics_reach_the_dense_kkt_solution() {
    let lq = random_lq(3, 2, 20, 51);
    let (p, exact) = implicit_euler_ocp(&lq, 0.1);
    let reference = dense::solve(&exact).unwrap();
    let (xs, us) = zero_guess(&p);
    for variant in [DdpVariant::Ddp, DdpVariant::Fddp, DdpVariant::Sqp] {
        let sol = solve(&p, DdpOptions::new(variant), &xs, &us);
        assert_eq!(sol.status, Status::Converged, "{}", variant.name());
        assert!(max_diff(&sol.xs, &reference.xs) < 1e-8, "{}", variant.name());
        assert!(max_diff(&sol.us, &reference.us) < 1e-8, "{}", variant.name());
        assert!(max_diff(&sol.lambdas, &reference.lambdas) < 1e-7, "{}", variant.name());
    }
}

/// The box variants on the box-constrained LQ problems of the Clarabel reference (those
/// without a terminal constraint, which they refuse): the optimal cost, and the KKT
/// conditions with the bound multipliers they report.
#[test]
fn box_variants_reach_the_optimum_of_an_independent_qp_solver() {
    let cases: Vec<QpCase> = qp_reference_cases()
        .into_iter()
        .filter(|c| c.target.is_none())
        .collect();
    assert!(cases.len() >= 3);
    for case in &cases {
        let p = ocp(&case.lq, Some(case.umax), None);
        let (zeros, us) = zero_guess(&p);
        let xs = rollout(&p, &us);
        // The unconstrained optimum, whose controls break the bounds: not a solution
        // (box-DDP and box-FDDP reported it converged after 0 iterations).
        let free = ocp(&case.lq, None, None);
        let unbounded = solve(&free, DdpOptions::new(DdpVariant::Ddp), &xs, &us);
        assert!(
            unbounded.us.iter().flatten().any(|u| u.abs() > case.umax),
            "seed {}",
            case.seed
        );
        for variant in [DdpVariant::BoxDdp, DdpVariant::BoxFddp] {
            for (guess, xs, us) in [
                ("rollout", &xs, &us),
                ("infeasible", &zeros, &us),
                ("unbounded optimum", &unbounded.xs, &unbounded.us),
            ] {
                let what = format!("seed {} {} from the {guess} guess", case.seed, variant.name());
                let mut opts = DdpOptions::new(variant);
                opts.tol = 1e-8;
                let sol = solve(&p, opts, xs, us);
                assert_eq!(sol.status, Status::Converged, "{what}");
                let rel = (sol.cost - case.clarabel_cost).abs() / case.clarabel_cost.abs().max(1.0);
                assert!(
                    rel < 1e-9,
                    "{what}: cost {} vs QP {} ({rel:e})",
                    sol.cost,
                    case.clarabel_cost
                );
                let kkt = kkt_residuals(&p, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
                assert!(kkt.max() < 1e-6, "{what}: {kkt:?}");
                let limit = case.umax * (1.0 + 1e-15);
                assert!(sol.us.iter().flatten().all(|u| u.abs() <= limit), "{what}");
            }
        }
    }
}

/// Bounds written as `u - umax ≤ 0` and `-u - umax ≤ 0` (two orthant constraints with
/// negative coefficients) are the same box.
#[test]
fn bounds_from_orthant_constraints_and_negative_coefficients() {
    let lq = random_lq(3, 2, 15, 8);
    let umax = 0.2;
    let boxed = ocp(&lq, Some(umax), None);
    let mut stage = boxed.stages()[0].clone();
    let mut plain = StageModel::new(stage.cost.clone(), stage.dynamics.clone()).unwrap();
    for sign in [1.0, -1.0] {
        let a = Mat::<f64>::zeros(2, 3);
        let b = Mat::from_fn(2, 2, |i, j| if i == j { sign } else { 0.0 });
        let f = Arc::new(gharial::functions::LinearFunction::new(a.as_ref(), b.as_ref(), &[-umax, -umax]).unwrap());
        plain
            .add_constraint(StageConstraint::new("u_half", f, Arc::new(NegativeOrthant)))
            .unwrap();
    }
    stage = plain;
    let p = Problem::new(&lq.x0, vec![stage; 15], boxed.terminal_cost().clone()).unwrap();
    let (_, us) = zero_guess(&p);
    let xs = rollout(&p, &us);
    let a = solve(&boxed, DdpOptions::new(DdpVariant::BoxFddp), &xs, &us);
    let b = solve(&p, DdpOptions::new(DdpVariant::BoxFddp), &xs, &us);
    assert_eq!(b.status, Status::Converged);
    assert!(
        max_diff(
            &a.us,
            &b.us.iter().map(|u| Col::from_fn(2, |i| u[i])).collect::<Vec<_>>()
        ) < 1e-10
    );
    let kkt = kkt_residuals(&p, &b.xs, &b.us, &b.lambdas, &b.nus).unwrap();
    assert!(kkt.max() < 1e-6, "{kkt:?}");
}

/// `control_bounds` reads the box of the half-space pair above (written with negative
/// coefficients) as the box itself, leaves unbounded problems at infinity, and refuses a
/// bound on the state.
#[test]
fn control_bounds_read_the_boxes_of_the_path_constraints() {
    let lq = random_lq(3, 2, 6, 8);
    let umax = 0.2;
    let boxed = ocp(&lq, Some(umax), None);
    let (_, us) = zero_guess(&boxed);
    let xs = rollout(&boxed, &us);
    let (lb, ub) = gharial::solvers::ddp::control_bounds(&boxed, &xs, &us).unwrap();
    assert_eq!((lb.len(), ub.len()), (6, 6));
    assert!(lb.iter().flatten().all(|&v| v == -umax) && ub.iter().flatten().all(|&v| v == umax));
    let free = ocp(&lq, None, None);
    let (lb, ub) = gharial::solvers::ddp::control_bounds(&free, &xs, &us).unwrap();
    assert!(lb.iter().flatten().all(|&v| v == f64::NEG_INFINITY) && ub.iter().flatten().all(|&v| v == f64::INFINITY));
    let mut stage = free.stages()[0].clone();
    let f = Arc::new(Unary::new(Arc::new(StateError::new(space(&lq), &[0.0; 3]).unwrap()), 2));
    let set = Arc::new(BoxConstraint::new(&[-1.0; 3], &[1.0; 3]).unwrap());
    stage.add_constraint(StageConstraint::new("x_box", f, set)).unwrap();
    let p = Problem::new(&lq.x0, vec![stage; 6], free.terminal_cost().clone()).unwrap();
    let err = gharial::solvers::ddp::control_bounds(&p, &xs, &us)
        .unwrap_err()
        .to_string();
    assert!(err.contains("x_box"), "{err}");
    assert!(gharial::solvers::ddp::control_bounds(&boxed, &xs[..3], &us).is_err());
}

/// Problems a variant cannot solve are refused at setup with an error naming the reason.
#[test]
fn unsupported_problems_are_refused_with_a_clear_error() {
    let lq = random_lq(3, 2, 10, 5);
    let boxed = ocp(&lq, Some(0.3), None);
    for variant in [DdpVariant::Ddp, DdpVariant::Fddp, DdpVariant::Sqp] {
        let err = Ddp::new(DdpOptions::new(variant))
            .setup(&boxed)
            .unwrap_err()
            .to_string();
        assert!(err.contains("u_box") && err.contains("box-ddp"), "{err}");
    }
    let terminal = ocp(&lq, Some(0.3), Some(&[0.0; 3]));
    let err = Ddp::new(DdpOptions::new(DdpVariant::BoxFddp))
        .setup(&terminal)
        .unwrap_err()
        .to_string();
    assert!(err.contains("terminal"), "{err}");
    // A bound on the state is not a control bound.
    let mut stage = ocp(&lq, None, None).stages()[0].clone();
    let f = Arc::new(Unary::new(Arc::new(StateError::new(space(&lq), &[0.0; 3]).unwrap()), 2));
    let set = Arc::new(BoxConstraint::new(&[-1.0; 3], &[1.0; 3]).unwrap());
    stage.add_constraint(StageConstraint::new("x_box", f, set)).unwrap();
    let term = Arc::new(QuadraticCost::terminal(lq.qf.as_ref(), &lq.qfv).unwrap());
    let p = Problem::new(&lq.x0, vec![stage; 10], term).unwrap();
    let err = Ddp::new(DdpOptions::new(DdpVariant::BoxDdp))
        .setup(&p)
        .unwrap_err()
        .to_string();
    assert!(err.contains("x_box") && err.contains("state"), "{err}");
    // Options out of range.
    let mut opts = DdpOptions::new(DdpVariant::Fddp);
    opts.reg_increase = 1.0;
    let err = Ddp::new(opts).setup(&boxed).unwrap_err().to_string();
    assert!(err.contains("reg_increase"), "{err}");
}

/// Wrong inputs are errors, not panics; a solve before setup too.
#[test]
fn bad_guesses_and_missing_setup_are_errors() {
    let lq = random_lq(3, 2, 10, 6);
    let p = ocp(&lq, None, None);
    let (mut xs, us) = zero_guess(&p);
    let mut solver = Ddp::new(DdpOptions::default());
    assert!(solver.solve(&p, InitialGuess::primal(&xs, &us)).is_err());
    solver.setup(&p).unwrap();
    xs[3][1] = f64::NAN;
    let err = solver
        .solve(&p, InitialGuess::primal(&xs, &us))
        .unwrap_err()
        .to_string();
    assert!(err.contains("xs[3]"), "{err}");
    xs[3].pop();
    assert!(solver.solve(&p, InitialGuess::primal(&xs, &us)).is_err());
    let other = ocp(&random_lq(4, 2, 10, 6), None, None);
    let (xo, uo) = zero_guess(&other);
    assert!(solver.solve(&other, InitialGuess::primal(&xo, &uo)).is_err());
}

/// A warm start from the solution converges at once; a callback's stop is its own
/// status; the solver answers to the `Solver` trait by name.
#[test]
fn warm_start_callbacks_and_the_solver_trait() {
    let lq = random_lq(4, 2, 30, 9);
    let p = ocp(&lq, Some(0.2), None);
    let (_, us) = zero_guess(&p);
    let xs = rollout(&p, &us);
    let mut solver: Box<dyn Solver> = Box::new(Ddp::new(DdpOptions::new(DdpVariant::BoxFddp)));
    assert_eq!(solver.name(), "box-fddp");
    solver.setup(&p).unwrap();
    let first = solver
        .solve_with(&p, InitialGuess::primal(&xs, &us), None)
        .unwrap()
        .clone();
    assert_eq!(first.status, Status::Converged);
    assert!(first.iterations >= 2);
    let again = solver
        .solve_with(&p, InitialGuess::from_solution(&first), None)
        .unwrap();
    assert_eq!(again.status, Status::Converged);
    assert!(again.iterations <= 1, "{} iterations", again.iterations);
    struct StopAfterOne;
    impl Callback for StopAfterOne {
        fn on_iteration(&mut self, _: &IterationRecord) -> bool {
            false
        }
    }
    let stopped = solver
        .solve_with(&p, InitialGuess::primal(&xs, &us), Some(&mut StopAfterOne))
        .unwrap();
    assert_eq!(stopped.status, Status::Interrupted);
    assert_eq!(stopped.iterations, 1);
    assert!(stopped.cost < first.history[0].cost);
    assert_eq!(stopped.history.len(), 1);
    assert_eq!(DdpVariant::from_name("box-fddp"), Some(DdpVariant::BoxFddp));
    assert_eq!(DdpVariant::from_name("proxddp"), None);
}

/// A tolerance below the round-off floor of the cost stops the solve as stalled
/// instead of iterating to the limit.
#[test]
fn an_unreachable_tolerance_stalls_instead_of_iterating_forever() {
    let lq = random_lq(4, 2, 20, 12);
    let p = ocp(&lq, None, None);
    let (_, us) = zero_guess(&p);
    let xs = rollout(&p, &us);
    for tol in [1e-20, 1e-300] {
        let mut opts = DdpOptions::new(DdpVariant::Fddp);
        opts.tol = tol;
        opts.max_iters = 100_000;
        let sol = solve(&p, opts, &xs, &us);
        assert_eq!(sol.status, Status::Stalled, "tol {tol:e}");
        assert!(sol.iterations <= 3, "tol {tol:e}: {} iterations", sol.iterations);
    }
}

fn exact(variant: DdpVariant) -> DdpOptions {
    DdpOptions::new(variant).with(|o| o.hessian = gharial::solvers::HessianApprox::Exact)
}

/// With one stage, classical DDP's step is Newton's step on `u ↦ ℓ(x_0, u) + ℓ_N(φ(x_0, u))`
/// (the Q-function is the whole objective): checked against the Newton step of finite
/// differences of the cost; iLQR's Gauss-Newton step, which leaves out `V_x'·φ_uu`, is not.
#[test]
fn exact_ddp_takes_the_newton_step_of_a_one_stage_problem() {
    let p = pendulum::euler_swing_up(1, [2.5, 1.0]);
    let u0 = -0.5;
    let objective = |u: f64| {
        let us = vec![vec![u]];
        let xs = rollout(&p, &us);
        gharial::problem::ProblemData::new(&p, 1)
            .unwrap()
            .evaluate(&p, &xs, &us)
    };
    // Newton step from central differences, Richardson-extrapolated in the step h.
    let newton_fd = |h: f64| {
        let (jm, j0, jp) = (objective(u0 - h), objective(u0), objective(u0 + h));
        u0 - ((jp - jm) / (2.0 * h)) / ((jp - 2.0 * j0 + jm) / (h * h))
    };
    let newton = (4.0 * newton_fd(5e-3) - newton_fd(1e-2)) / 3.0;
    let us = vec![vec![u0]];
    let xs = rollout(&p, &us);
    let step = |opts: DdpOptions| solve(&p, opts.with(|o| o.max_iters = 1), &xs, &us).us[0][0];
    let ddp = step(exact(DdpVariant::Ddp));
    assert!(
        (ddp - newton).abs() < 1e-8 * (1.0 + newton.abs()),
        "DDP {ddp} vs Newton {newton}"
    );
    let ilqr = step(DdpOptions::new(DdpVariant::Ddp));
    assert!((ilqr - newton).abs() > 1e-3, "iLQR {ilqr} vs Newton {newton}");
}

/// On the swing-up, DDP (from a rollout) and FDDP (from states off it) with the exact
/// Hessian converge to the optimum their Gauss-Newton versions reach from the same guess:
/// the KKT point of the problem (solver-independent residuals).
#[test]
fn exact_ddp_and_fddp_reach_the_gauss_newton_optimum() {
    let p = pendulum::euler_swing_up(60, [0.0, 0.0]);
    let us = vec![vec![0.0]; 60];
    let xs = rollout(&p, &us);
    let ddp = solve(&p, DdpOptions::new(DdpVariant::Ddp), &xs, &us);
    // Near that optimum (the problem has several local ones): states off its trajectory
    // (gaps of about 0.05) and controls 10 % smaller.
    let xs_off: Vec<Vec<f64>> = (ddp.xs.iter().enumerate())
        .map(|(t, x)| vec![x[0] + 0.05 * (t as f64).sin(), x[1]])
        .collect();
    let us_off: Vec<Vec<f64>> = ddp.us.iter().map(|u| vec![0.9 * u[0]]).collect();
    let tight = |o: DdpOptions| o.with(|o| o.tol = 1e-7);
    for (variant, xs, us) in [(DdpVariant::Ddp, &xs, &us), (DdpVariant::Fddp, &xs_off, &us_off)] {
        let reference = solve(&p, tight(DdpOptions::new(variant)), xs, us);
        let sol = solve(&p, tight(exact(variant)), xs, us);
        for s in [&reference, &sol] {
            assert_eq!(s.status, Status::Converged, "{variant:?}");
            let kkt = kkt_residuals(&p, &s.xs, &s.us, &s.lambdas, &s.nus).unwrap();
            assert!(kkt.max() < 1e-5, "{variant:?}: {kkt:?}");
        }
        let rel = (sol.cost - reference.cost).abs() / reference.cost;
        assert!(rel < 1e-8, "{variant:?}: cost {} vs {}", sol.cost, reference.cost);
        for (a, b) in sol.us.iter().zip(&reference.us) {
            assert!((a[0] - b[0]).abs() < 1e-4, "{variant:?}: {a:?} vs {b:?}");
        }
        eprintln!(
            "{variant:?}: exact Hessian {} iterations, Gauss-Newton {}, cost {}",
            sol.iterations, reference.iterations, sol.cost
        );
    }
}

/// The exact Hessian is refused where it is not available: SQP, dynamics without
/// vector-Hessian products, implicit dynamics.
#[test]
fn exact_hessian_is_refused_where_it_is_not_available() {
    let nonlinear = pendulum::euler_swing_up(5, [0.0, 0.0]);
    let mut sqp = Ddp::new(exact(DdpVariant::Sqp));
    let e = sqp.setup(&nonlinear).unwrap_err().to_string();
    assert!(e.contains("Gauss-Newton"), "{e}");
    let lq = random_lq(3, 2, 5, 11);
    let (implicit, _) = implicit_euler_ocp(&lq, 0.1);
    let e = Ddp::new(exact(DdpVariant::Fddp))
        .setup(&implicit)
        .unwrap_err()
        .to_string();
    assert!(e.contains("stage 0") && e.contains("implicit"), "{e}");
    // An integrator over an ODE gives no vector-Hessian product.
    let ode = ode_problem();
    let e = Ddp::new(exact(DdpVariant::Ddp)).setup(&ode).unwrap_err().to_string();
    assert!(e.contains("stage 0") && e.contains("vector-Hessian"), "{e}");
}

/// A pendulum ODE integrated by RK4 (hand-written, without second derivatives).
fn ode_problem() -> Problem {
    use gharial::costs::QuadraticStateCost;
    use gharial::dynamics::{Dynamics, ExplicitRungeKutta};
    use gharial::spaces::{Manifold, VectorSpace};
    let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(2));
    let ode = Arc::new(pendulum::Pendulum { space: space.clone() });
    let phi = Dynamics::Explicit(Arc::new(ExplicitRungeKutta::rk4(ode, 0.05).unwrap()));
    let cost = Arc::new(QuadraticStateCost::diagonal(space.clone(), &[0.0, 0.0], &[1.0, 1.0], 1).unwrap());
    let term = Arc::new(QuadraticStateCost::diagonal(space, &[0.0, 0.0], &[1.0, 1.0], 0).unwrap());
    Problem::new(&[0.1, 0.0], vec![StageModel::new(cost, phi).unwrap(); 4], term).unwrap()
}

/// The point mass of [`point_mass`] pushed against its control box: with
/// `x0 = (1, 1, 1, 1)` both controls of the first knot sit at their bound at the optimum
/// (the free set of the box QP is empty), and with the horizons and starts below at
/// several knots. Both box variants converge there to a point that satisfies the KKT
/// conditions (a convex QP: the optimum) with the controls inside the box.
#[test]
fn box_variants_converge_with_every_control_of_a_knot_clamped() {
    for (n, x0, w) in clamped_point_mass_cases() {
        let p = ocp(&point_mass(n, x0, w), Some(2.0), None);
        let (_, us) = zero_guess(&p);
        let xs = rollout(&p, &us);
        for variant in [DdpVariant::BoxDdp, DdpVariant::BoxFddp] {
            let what = format!("{} N = {n}, x0 = {x0:?}", variant.name());
            let sol = solve(&p, DdpOptions::new(variant), &xs, &us);
            assert_eq!(sol.status, Status::Converged, "{what}");
            let kkt = kkt_residuals(&p, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
            assert!(kkt.max() < 1e-6, "{what}: {kkt:?}");
            assert!(sol.us.iter().flatten().all(|u| u.abs() <= 2.0), "{what}");
        }
    }
}

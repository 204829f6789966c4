use super::*;
use crate::autodiff::{AutoDiff, AutoOdeFn, ManifoldScalar};
use crate::check::{
    CheckOptions, DualCheckOptions, check_cost, check_cost_dual, check_explicit_dynamics, check_stage_function,
};
use crate::costs::{CostStack, QuadraticControlCost, QuadraticStateCost};
use crate::functions::testing::{TestOde, random_vec, rng};
use crate::functions::{ControlError, StateError, Unary};
use crate::solvers::proxddp::{ProxDdp, ProxDdpOptions};
use crate::solvers::{InitialGuess, Solver};
use crate::spaces::SO2;
use num_dual::HyperDual64;

/// A damped pendulum on `SO(2) × R`, `x = (cos θ, sin θ, θ̇)`.
struct Pendulum;

impl AutoOdeFn for Pendulum {
    fn nx(&self) -> usize {
        3
    }
    fn nu(&self) -> usize {
        1
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], xdot: &mut [D]) {
        xdot[0] = x[2];
        xdot[1] = x[1] * 9.81 - x[2] * 0.1 + u[0];
    }
}

fn pendulum_space() -> Arc<dyn Manifold> {
    Arc::new(CartesianProduct::pair(
        Arc::new(SO2::new()),
        Arc::new(VectorSpace::new(1)),
    ))
}

/// A continuous stage of `ode` with the cost `½ |x ⊖ x_ref|² + ½ 0.3 |u|²` and the
/// control bounds `|u| ≤ 2`.
fn continuous(ode: Arc<dyn Ode>, x_ref: &[f64]) -> ContinuousStage {
    let space = ode.space().clone();
    let nu = ode.nu();
    let cost = CostStack::new(space.as_ref(), nu)
        .with(
            "x",
            Arc::new(QuadraticStateCost::diagonal(space.clone(), x_ref, &vec![1.0; space.ndx()], nu).unwrap()),
            1.0,
        )
        .unwrap()
        .with(
            "u",
            Arc::new(QuadraticControlCost::diagonal(space.as_ref(), &vec![0.0; nu], &vec![0.3; nu]).unwrap()),
            1.0,
        )
        .unwrap();
    let u_box = StageConstraint::new(
        "u_box",
        Arc::new(ControlError::new(space.as_ref(), &vec![0.0; nu]).unwrap()),
        Arc::new(BoxConstraint::new(&vec![-2.0; nu], &vec![2.0; nu]).unwrap()),
    );
    ContinuousStage {
        ode,
        cost: Arc::new(cost),
        constraints: vec![u_box],
    }
}

fn test_odes() -> Vec<(Arc<dyn Ode>, Vec<f64>)> {
    let pendulum: Arc<dyn Ode> = Arc::new(AutoDiff::ode(pendulum_space(), Pendulum).unwrap());
    let theta: f64 = 0.7;
    vec![
        (Arc::new(TestOde::new()), vec![0.3, -0.2, 0.5]),
        (pendulum, vec![theta.cos(), theta.sin(), 0.4]),
    ]
}

/// The augmented step equals the integrator's own step of length `h = τ²` (the time
/// scaling is exact), and `δ_{k+1} = τ_k`.
#[test]
fn augmented_step_is_the_integrator_step_of_length_tau_squared() {
    for (ode, x) in test_odes() {
        for method in [RkMethod::Euler, RkMethod::Rk2, RkMethod::Rk4] {
            let mt = MinimumTime::new(1e-3, 0.5, 1.0, method).unwrap();
            let space = MinimumTime::augmented_space(ode.space());
            let stage = mt.stage(&continuous(ode.clone(), &x), 1, &space).unwrap();
            let Dynamics::Explicit(d) = &stage.dynamics else {
                panic!("explicit")
            };
            let tau: f64 = 0.23;
            let u: Vec<f64> = (0..ode.nu()).map(|i| 0.4 - 0.3 * i as f64).collect();
            let xa: Vec<f64> = x.iter().copied().chain([0.9]).collect();
            let ua: Vec<f64> = u.iter().copied().chain([tau]).collect();
            let mut data = d.create_data();
            d.forward(&xa, &ua, &mut data);
            let reference = ExplicitRungeKutta::new(ode.clone(), tau * tau, method).unwrap();
            let mut rdata = reference.create_data();
            reference.forward(&x, &u, &mut rdata);
            let y = data.xnext();
            for (a, b) in y.iter().zip(rdata.xnext()) {
                assert!((a - b).abs() < 1e-14, "{method:?}: {a} vs {b}");
            }
            assert_eq!(y[x.len()], tau);
        }
    }
}

/// Jacobians of the dynamics, constraints and costs of an augmented stage against
/// finite differences, at random points, on a vector space and on `SO(2) × R`.
#[test]
fn augmented_stage_derivatives_match_finite_differences() {
    let mut g = rng(171);
    for (ode, x) in test_odes() {
        let mt = MinimumTime::new(1e-3, 0.5, 2.5, RkMethod::Rk4).unwrap();
        let space = MinimumTime::augmented_space(ode.space());
        let stage = mt.stage(&continuous(ode.clone(), &x), 3, &space).unwrap();
        assert_eq!(stage.constraints().len(), 3, "u_box, time_step, equal_time_steps");
        let Dynamics::Explicit(d) = &stage.dynamics else {
            panic!("explicit")
        };
        for _ in 0..3 {
            let mut xa = vec![0.0; space.nx()];
            let dx = random_vec(&mut g, space.ndx(), 0.5);
            let mut base = x.clone();
            base.push(0.2);
            space.integrate(&base, &dx, &mut xa);
            let mut ua = random_vec(&mut g, ode.nu() + 1, 0.5);
            ua[ode.nu()] = 0.2 + 0.1 * ua[ode.nu()];
            check_explicit_dynamics(d.as_ref(), &xa, &ua, CheckOptions::default()).assert_ok();
            check_cost(stage.cost.as_ref(), space.as_ref(), &xa, &ua, CheckOptions::default()).assert_ok();
            for c in stage.constraints() {
                let lambda = random_vec(&mut g, c.nr(), 1.0);
                check_stage_function(
                    c.func.as_ref(),
                    space.as_ref(),
                    &xa,
                    &ua,
                    Some(&lambda),
                    CheckOptions::default(),
                )
                .assert_ok();
            }
        }
    }
}

/// The time-weighted cost `τ² (ℓ + R)` against hyper-dual numbers of its formula, with
/// `ℓ = ½ |x - x_ref|² + ½ 0.3 |u|²` on `R³`.
#[test]
fn time_weighted_cost_matches_hyper_dual_numbers() {
    let (ode, x_ref) = test_odes().remove(0);
    let r_min_time = 2.5;
    let mt = MinimumTime::new(1e-3, 0.5, r_min_time, RkMethod::Rk4).unwrap();
    let space = MinimumTime::augmented_space(ode.space());
    let stage = mt.stage(&continuous(ode.clone(), &x_ref), 0, &space).unwrap();
    assert_eq!(
        stage.constraints().len(),
        2,
        "no equal-step constraint on the first stage"
    );
    let mut g = rng(172);
    for _ in 0..3 {
        let xa = random_vec(&mut g, 4, 1.0);
        let ua = random_vec(&mut g, 3, 1.0);
        let reference = |x: &[HyperDual64], u: &[HyperDual64]| {
            let mut l = HyperDual64::from(0.0);
            for i in 0..3 {
                l += (x[i] - x_ref[i]) * (x[i] - x_ref[i]) * 0.5;
            }
            for ui in &u[..2] {
                l += *ui * *ui * 0.15;
            }
            u[2] * u[2] * (l + r_min_time)
        };
        let rep = check_cost_dual(
            stage.cost.as_ref(),
            space.as_ref(),
            &xa,
            &ua,
            reference,
            DualCheckOptions::default(),
        );
        assert!(rep.passed(), "{rep:?}");
    }
}

#[test]
fn bad_settings_and_mismatched_stages_are_errors() {
    for (h_min, h_max, r) in [
        (0.0, 1.0, 1.0),
        (0.2, 0.1, 1.0),
        (0.1, f64::INFINITY, 1.0),
        (0.1, 0.2, -1.0),
        (0.1, 0.2, f64::NAN),
    ] {
        let e = MinimumTime::new(h_min, h_max, r, RkMethod::Rk4)
            .unwrap_err()
            .to_string();
        assert!(e.contains("MinimumTime"), "{e}");
    }
    let (ode, x) = test_odes().remove(0);
    let mt = MinimumTime::new(1e-3, 0.5, 1.0, RkMethod::Rk4).unwrap();
    let mut stage = continuous(ode.clone(), &x);
    let other = VectorSpace::new(3);
    stage.cost = Arc::new(QuadraticControlCost::diagonal(&other, &[0.0], &[1.0]).unwrap());
    let space = MinimumTime::augmented_space(ode.space());
    let Err(e) = mt.stage(&stage, 4, &space) else {
        panic!("a mismatched cost is refused")
    };
    let e = e.to_string();
    assert!(e.contains("minimum-time stage 4") && e.contains("nu"), "{e}");
    let e = mt.problem(&x, &[], Arc::new(crate::costs::ConstantCost::zero(&other, 0)), &[]);
    assert!(e.is_err());
}

/// The double integrator `p̈ = u`, `|u| ≤ 1`, from rest at 0 to rest at 1: the minimum
/// time is 2 (full thrust to the midpoint, full brake after), which RK4 integrates
/// exactly on a grid of an even number of equal steps. With a small running cost and a
/// large time weight the steps settle at `h = 2/N` within the regularisation's effect.
#[test]
fn double_integrator_reaches_the_analytic_minimum_time() {
    struct DoubleIntegrator;
    impl AutoOdeFn for DoubleIntegrator {
        fn nx(&self) -> usize {
            2
        }
        fn nu(&self) -> usize {
            1
        }
        fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], xdot: &mut [D]) {
            xdot[0] = x[1];
            xdot[1] = u[0];
        }
    }
    let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(2));
    let ode: Arc<dyn Ode> = Arc::new(AutoDiff::ode(space.clone(), DoubleIntegrator).unwrap());
    let n = 20;
    let cost = Arc::new(QuadraticControlCost::diagonal(space.as_ref(), &[0.0], &[1e-4]).unwrap());
    let u_box = StageConstraint::new(
        "u_box",
        Arc::new(ControlError::new(space.as_ref(), &[0.0]).unwrap()),
        Arc::new(BoxConstraint::new(&[-1.0], &[1.0]).unwrap()),
    );
    let stage = ContinuousStage {
        ode,
        cost,
        constraints: vec![u_box],
    };
    let goal = StageConstraint::new(
        "goal",
        Arc::new(Unary::new(
            Arc::new(StateError::new(space.clone(), &[1.0, 0.0]).unwrap()),
            0,
        )),
        Arc::new(EqualityConstraintSet),
    );
    let mt = MinimumTime::new(1e-3, 0.5, 10.0, RkMethod::Rk4).unwrap();
    let terminal = Arc::new(crate::costs::ConstantCost::zero(space.as_ref(), 0));
    let problem = mt.problem(&[0.0, 0.0], &vec![stage; n], terminal, &[goal]).unwrap();
    let us = MinimumTime::controls(&vec![vec![0.0]; n], 0.15);
    let mut xs = vec![vec![0.0; 3]; n + 1];
    crate::problem::ProblemData::new(&problem, 1)
        .unwrap()
        .rollout(&problem, &mut xs, &us)
        .unwrap();
    let mut solver = ProxDdp::new(ProxDdpOptions::default().with(|o| {
        o.tol = 1e-8;
        o.max_iters = 300;
    }));
    solver.setup(&problem).unwrap();
    let sol = solver.solve(&problem, InitialGuess::primal(&xs, &us)).unwrap();
    assert!(sol.status.converged(), "{:?}", sol.status);
    let steps = MinimumTime::steps(&sol.us);
    let total = MinimumTime::total_time(&sol.us);
    eprintln!("double integrator: T = {total}, {} iterations", sol.iterations);
    for h in &steps {
        assert!((h - steps[0]).abs() < 1e-7, "{steps:?}");
    }
    // The control regularisation (1e-4 against a time weight of 10) lengthens the
    // motion by far less than 0.5%.
    assert!((2.0 - 1e-6..2.0 * 1.005).contains(&total), "T = {total}");
    let x_n = sol.xs.last().unwrap();
    assert!((x_n[0] - 1.0).abs() < 1e-7 && x_n[1].abs() < 1e-7, "{x_n:?}");
    // Bang-bang: full thrust then full brake, up to the one or two switching steps.
    let saturated = sol.us.iter().filter(|u| u[0].abs() > 1.0 - 1e-3).count();
    assert!(saturated >= n - 2, "{saturated} of {n} steps saturated");
}

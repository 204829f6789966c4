//! Tests of problem construction and evaluation with small hand-written models.

use std::sync::Arc;

use super::*;
use crate::costs::CostData;
use crate::dynamics::{ExplicitDynamics, ExplicitDynamicsData};
use crate::functions::StageFunctionData;
use crate::spaces::VectorSpace;

/// y = x + dt * (x2, sin(x1) + u) on R^2: a pendulum-like nonlinear map.
struct Pend {
    space: Arc<dyn Manifold>,
}

impl ExplicitDynamics for Pend {
    fn space(&self) -> &Arc<dyn Manifold> {
        &self.space
    }
    fn nu(&self) -> usize {
        1
    }
    fn forward(&self, x: &[f64], u: &[f64], d: &mut ExplicitDynamicsData) {
        let dt = 0.1;
        let y = d.xnext_mut();
        y[0] = x[0] + dt * x[1];
        y[1] = x[1] + dt * (x[0].sin() + u[0]);
    }
    fn jacobians(&self, x: &[f64], _u: &[f64], d: &mut ExplicitDynamicsData) {
        let dt = 0.1;
        d.jx.fill(0.0);
        d.jx[(0, 0)] = 1.0;
        d.jx[(0, 1)] = dt;
        d.jx[(1, 0)] = dt * x[0].cos();
        d.jx[(1, 1)] = 1.0;
        d.ju.fill(0.0);
        d.ju[(1, 0)] = dt;
    }
}

/// ½|x|² + ½|u|².
struct Quad {
    nu: usize,
}

impl Cost for Quad {
    fn nx(&self) -> usize {
        2
    }
    fn ndx(&self) -> usize {
        2
    }
    fn nu(&self) -> usize {
        self.nu
    }
    fn evaluate(&self, x: &[f64], u: &[f64], d: &mut CostData) {
        d.value = 0.5 * (x.iter().map(|v| v * v).sum::<f64>() + u.iter().map(|v| v * v).sum::<f64>());
    }
    fn derivatives(&self, x: &[f64], u: &[f64], d: &mut CostData) {
        for i in 0..2 {
            d.lx[i] = x[i];
            d.lxx[(i, i)] = 1.0;
        }
        for i in 0..self.nu {
            d.lu[i] = u[i];
            d.luu[(i, i)] = 1.0;
        }
    }
}

/// h(x, u) = u (for box-like constraints).
struct Ctrl;

impl StageFunction for Ctrl {
    fn nx(&self) -> usize {
        2
    }
    fn ndx(&self) -> usize {
        2
    }
    fn nu(&self) -> usize {
        1
    }
    fn nr(&self) -> usize {
        1
    }
    fn evaluate(&self, _x: &[f64], u: &[f64], d: &mut StageFunctionData) {
        d.value[0] = u[0];
    }
    fn jacobians(&self, _x: &[f64], _u: &[f64], d: &mut StageFunctionData) {
        d.jx.fill(0.0);
        d.ju[(0, 0)] = 1.0;
    }
}

#[derive(Debug)]
struct AnySet;

impl ConstraintSet for AnySet {
    fn penalty(&self, _z: &[f64]) -> f64 {
        0.0
    }
    fn project(&self, z: &[f64], _mu: f64, out: &mut [f64]) {
        out.copy_from_slice(z);
    }
    fn apply_projection_jacobian(&self, _z: &[f64], _mu: f64, _m: faer::MatMut<'_, f64>) {}
    fn apply_normal_cone_jacobian(&self, _z: &[f64], _mu: f64, mut m: faer::MatMut<'_, f64>) {
        m.fill(0.0);
    }
    fn violation(&self, _z: &[f64]) -> f64 {
        0.0
    }
}

fn problem(n: usize) -> Problem {
    let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(2));
    let dynamics = Dynamics::Explicit(Arc::new(Pend { space: space.clone() }));
    let stage = StageModel::new(Arc::new(Quad { nu: 1 }), dynamics)
        .unwrap()
        .with_constraint(StageConstraint::new("u", Arc::new(Ctrl), Arc::new(AnySet)))
        .unwrap();
    Problem::new(&[1.0, 0.0], vec![stage; n], Arc::new(Quad { nu: 0 })).unwrap()
}

fn trajectory(n: usize) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let xs = (0..=n)
        .map(|t| vec![(t as f64 * 0.3).cos(), (t as f64 * 0.7).sin()])
        .collect();
    let us = (0..n).map(|t| vec![0.1 * t as f64 - 0.5]).collect();
    (xs, us)
}

#[test]
fn evaluation_matches_direct_formulas() {
    let n = 7;
    let p = problem(n);
    let (xs, us) = trajectory(n);
    let mut d = ProblemData::new(&p, 1).unwrap();
    let cost = d.evaluate(&p, &xs, &us);
    let expect: f64 = (0..n)
        .map(|t| 0.5 * (xs[t][0].powi(2) + xs[t][1].powi(2) + us[t][0].powi(2)))
        .sum::<f64>()
        + 0.5 * (xs[n][0].powi(2) + xs[n][1].powi(2));
    assert!((cost - expect).abs() < 1e-14);
    for t in 0..n {
        // f = φ(x, u) - y
        let phi = [xs[t][0] + 0.1 * xs[t][1], xs[t][1] + 0.1 * (xs[t][0].sin() + us[t][0])];
        for i in 0..2 {
            assert!((d.stages[t].dyn_value()[i] - (phi[i] - xs[t + 1][i])).abs() < 1e-15);
        }
        assert_eq!(d.stages[t].constraints[0].value()[0], us[t][0]);
    }
    assert_eq!(d.init.value(), &[xs[0][0] - 1.0, xs[0][1]]);
    d.compute_derivatives(&p, &xs, &us);
    let jy = &d.stages[0].dyn_jy;
    assert_eq!((jy[(0, 0)], jy[(1, 1)], jy[(0, 1)]), (-1.0, -1.0, 0.0));
    assert!((d.stages[2].dyn_jx[(1, 0)] - 0.1 * xs[2][0].cos()).abs() < 1e-15);
    assert_eq!(d.init.jx[(0, 0)], 1.0);
}

#[test]
fn parallel_evaluation_is_bit_identical() {
    let n = 33;
    let p = problem(n);
    let (xs, us) = trajectory(n);
    let mut serial = ProblemData::new(&p, 1).unwrap();
    let mut par = ProblemData::new(&p, 2).unwrap();
    assert_eq!(par.num_threads(), crate::pool_threads(2));
    // More threads than cores are not created.
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    assert_eq!(ProblemData::new(&p, 1000).unwrap().num_threads(), cores.min(1000));
    let (c1, c2) = (serial.evaluate(&p, &xs, &us), par.evaluate(&p, &xs, &us));
    assert_eq!(c1.to_bits(), c2.to_bits());
    serial.compute_derivatives(&p, &xs, &us);
    par.compute_derivatives(&p, &xs, &us);
    for t in 0..n {
        let (a, b) = (&serial.stages[t], &par.stages[t]);
        assert_eq!(a.dyn_value(), b.dyn_value());
        assert_eq!(a.dyn_jx, b.dyn_jx);
        assert_eq!(a.cost.lxx, b.cost.lxx);
    }
}

#[test]
fn rollout_is_feasible() {
    let n = 10;
    let p = problem(n);
    let (mut xs, us) = trajectory(n);
    let mut d = ProblemData::new(&p, 1).unwrap();
    xs[0] = vec![1.0, 0.0];
    d.rollout(&p, &mut xs, &us).unwrap();
    d.evaluate(&p, &xs, &us);
    for t in 0..n {
        assert!(d.stages[t].dyn_value().iter().all(|v| v.abs() < 1e-15));
    }
}

/// A rollout by steps, its costs and constraints evaluated afterwards in a stage pass (on
/// one and two threads), writes what `evaluate` writes on the rolled-out trajectory, bit
/// for bit.
#[test]
fn rollout_steps_then_costs_equal_a_full_evaluation() {
    let n = 12;
    let p = problem(n);
    let (mut xs, us) = trajectory(n);
    for threads in [1, 2] {
        let mut d = ProblemData::new(&p, threads).unwrap();
        for (t, stage) in p.stages().iter().enumerate() {
            let (lo, hi) = xs.split_at_mut(t + 1);
            let solve = ImplicitSolve::default();
            assert!(d.stages[t].rollout_step(stage, &lo[t], &us[t], None, &mut hi[0], solve));
        }
        let cost = d.evaluate_after_rollout(&p, &xs, &us);
        let mut full = ProblemData::new(&p, 1).unwrap();
        assert_eq!(cost.to_bits(), full.evaluate(&p, &xs, &us).to_bits());
        for t in 0..n {
            let (a, b) = (&d.stages[t], &full.stages[t]);
            assert_eq!(a.dyn_value(), b.dyn_value());
            assert!(
                a.dyn_value().iter().all(|v| v.abs() < 1e-15),
                "the steps close the gaps"
            );
            assert_eq!(a.cost.value.to_bits(), b.cost.value.to_bits());
            assert_eq!(a.constraints[0].value(), b.constraints[0].value());
        }
    }
}

#[test]
fn invalid_problems_are_rejected_with_named_errors() {
    let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(2));
    let dynamics = Dynamics::Explicit(Arc::new(Pend { space: space.clone() }));
    // Cost with the wrong control size.
    let e = StageModel::new(Arc::new(Quad { nu: 2 }), dynamics.clone())
        .err()
        .unwrap();
    assert!(e.to_string().contains("control size"), "{e}");
    let stage = StageModel::new(Arc::new(Quad { nu: 1 }), dynamics).unwrap();
    // Wrong x0 size, non-finite x0, no stage, terminal cost with controls.
    let e = Problem::new(&[1.0], vec![stage.clone()], Arc::new(Quad { nu: 0 }))
        .err()
        .unwrap();
    assert!(e.to_string().contains("x0"), "{e}");
    let e = Problem::new(&[f64::NAN, 0.0], vec![stage.clone()], Arc::new(Quad { nu: 0 }))
        .err()
        .unwrap();
    assert!(matches!(e, Error::NonFinite { .. }));
    assert!(Problem::new(&[1.0, 0.0], vec![], Arc::new(Quad { nu: 0 })).is_err());
    let e = Problem::new(&[1.0, 0.0], vec![stage.clone()], Arc::new(Quad { nu: 1 }))
        .err()
        .unwrap();
    assert!(e.to_string().contains("terminal cost"), "{e}");
    // A terminal constraint must not depend on controls; a bad scale is refused.
    let mut p = Problem::new(&[1.0, 0.0], vec![stage.clone()], Arc::new(Quad { nu: 0 })).unwrap();
    let e = p
        .add_terminal_constraint(StageConstraint::new("u", Arc::new(Ctrl), Arc::new(AnySet)))
        .err()
        .unwrap();
    assert!(e.to_string().contains("terminal constraint `u`"), "{e}");
    let mut s = stage;
    let e = s
        .add_constraint(StageConstraint::new("u", Arc::new(Ctrl), Arc::new(AnySet)).with_scale(-1.0))
        .err()
        .unwrap();
    assert!(e.to_string().contains("scale"), "{e}");
    // Trajectory checks name the entry.
    let (xs, mut us) = trajectory(1);
    us[0][0] = f64::INFINITY;
    let e = p.check_trajectory(&xs, &us).err().unwrap();
    assert!(e.to_string().contains("us[0]"), "{e}");
    assert!(ProblemData::new(&p, 0).is_err());
}

#[test]
fn kkt_stationarity_in_u_is_the_single_shooting_gradient() {
    // On a dynamically feasible trajectory with co-states from the adjoint recursion
    // λ_N = ∇ℓ_N, λ_t = ℓ_x + A_tᵀ λ_{t+1}, the x-stationarity vanishes and ∇_u L is the
    // gradient of the rolled-out cost, which we compare with central differences.
    let n = 6;
    let p = problem(n);
    let (mut xs, us) = trajectory(n);
    let mut d = ProblemData::new(&p, 1).unwrap();
    xs[0] = vec![1.0, 0.0];
    d.rollout(&p, &mut xs, &us).unwrap();
    d.evaluate(&p, &xs, &us);
    d.compute_derivatives(&p, &xs, &us);
    let mut lambdas = vec![vec![0.0; 2]; n + 1];
    let mut next = d.terminal_cost.lx().to_vec();
    for t in (0..n).rev() {
        lambdas[t + 1] = next.clone();
        let sd = &d.stages[t];
        let mut l = sd.cost.lx().to_vec();
        crate::linalg::matvec_t(&mut l, faer::Accum::Add, sd.dyn_jx.as_ref(), &next, 1.0);
        next = l;
    }
    lambdas[0] = next.iter().map(|v| -v).collect();
    let nus = vec![vec![0.0; 1]; n].into_iter().chain([vec![]]).collect::<Vec<_>>();
    let kkt = kkt_residuals(&p, &xs, &us, &lambdas, &nus).unwrap();
    assert!(kkt.dynamics < 1e-15 && kkt.initial < 1e-15 && kkt.constraints == 0.0);

    let rolled_cost = |us: &[Vec<f64>]| {
        let mut xs = vec![vec![1.0, 0.0]; n + 1];
        let mut d = ProblemData::new(&p, 1).unwrap();
        d.rollout(&p, &mut xs, us).unwrap();
        d.evaluate(&p, &xs, us)
    };
    let mut grad_max: f64 = 0.0;
    for t in 0..n {
        let mut up = us.clone();
        up[t][0] += 1e-6;
        let mut um = us.clone();
        um[t][0] -= 1e-6;
        grad_max = grad_max.max(((rolled_cost(&up) - rolled_cost(&um)) / 2e-6).abs());
    }
    assert!(grad_max > 0.1);
    assert!(
        (kkt.stationarity - grad_max).abs() < 1e-7,
        "{} vs {grad_max}",
        kkt.stationarity
    );
}

#[test]
fn lagrangian_gradient_matches_the_jacobian_products() {
    let n = 6;
    let p = problem(n);
    let (xs, us) = trajectory(n);
    let mut d = ProblemData::new(&p, 1).unwrap();
    d.evaluate(&p, &xs, &us);
    d.compute_derivatives(&p, &xs, &us);
    // Explicit dynamics on a vector space: df/dy = -I is used as a negation.
    assert!(d.stages.iter().all(|s| s.dyn_jy_is_minus_identity));
    let lambdas: Vec<Vec<f64>> = (0..=n)
        .map(|t| vec![0.3 * t as f64 - 1.0, 0.7 - 0.2 * t as f64])
        .collect();
    let nus: Vec<Vec<f64>> = (0..=n)
        .map(|t| vec![0.1 * t as f64 + 0.4; p.constraints(t).iter().map(|c| c.nr()).sum()])
        .collect();
    let mut gx = vec![vec![0.0; 2]; n + 1];
    let mut gu = vec![vec![0.0; 1]; n];
    d.lagrangian_gradient(&p, &lambdas, &nus, &mut gx, &mut gu);
    // Reference: every product written out entry by entry with the stored Jacobians.
    for t in 0..=n {
        for i in 0..2 {
            let mut g = if t < n {
                d.stages[t].cost.lx()[i]
            } else {
                d.terminal_cost.lx()[i]
            };
            if t < n {
                let sd = &d.stages[t];
                g += (0..2).map(|k| sd.dyn_jx[(k, i)] * lambdas[t + 1][k]).sum::<f64>();
                g += sd.constraints[0].jx[(0, i)] * nus[t][0];
            }
            g += if t == 0 {
                (0..2).map(|k| d.init.jx[(k, i)] * lambdas[0][k]).sum::<f64>()
            } else {
                (0..2)
                    .map(|k| d.stages[t - 1].dyn_jy[(k, i)] * lambdas[t][k])
                    .sum::<f64>()
            };
            assert!((gx[t][i] - g).abs() < 1e-14, "gx[{t}][{i}] = {} vs {g}", gx[t][i]);
        }
        if t < n {
            let sd = &d.stages[t];
            let g = sd.cost.lu()[0]
                + (0..2).map(|k| sd.dyn_ju[(k, 0)] * lambdas[t + 1][k]).sum::<f64>()
                + sd.constraints[0].ju[(0, 0)] * nus[t][0];
            assert!((gu[t][0] - g).abs() < 1e-14);
        }
    }
}

/// A problem whose every model declares constant derivative blocks: quadratic and
/// tracking costs, linear dynamics (explicit, and implicit through
/// `ExplicitAsImplicit`), affine path and terminal constraints.
fn constant_blocks_problem(seed: u64, n: usize) -> Problem {
    use crate::costs::{QuadraticControlCost, QuadraticCost, QuadraticStateCost};
    use crate::dynamics::{ExplicitAsImplicit, LinearDiscreteDynamics};
    use crate::functions::testing::{random_mat, random_vec, rng};
    use crate::functions::{ControlError, LinearFunction, StateError, Unary};
    let (nx, nu) = (3, 2);
    let mut g = rng(seed);
    let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(nx));
    let stages = (0..n)
        .map(|t| {
            let lin = Arc::new(
                LinearDiscreteDynamics::new(
                    random_mat(&mut g, nx, nx, 1.0).as_ref(),
                    random_mat(&mut g, nx, nu, 1.0).as_ref(),
                    &random_vec(&mut g, nx, 1.0),
                )
                .unwrap(),
            );
            let dynamics = if t % 2 == 0 {
                Dynamics::Explicit(lin)
            } else {
                Dynamics::Implicit(Arc::new(ExplicitAsImplicit::new(lin)))
            };
            let cost: Arc<dyn Cost> = if t % 3 == 0 {
                Arc::new(
                    QuadraticControlCost::diagonal(space.as_ref(), &random_vec(&mut g, nu, 1.0), &[0.5, 2.0]).unwrap(),
                )
            } else {
                let w = random_mat(&mut g, nx + nu, nx + nu, 1.0);
                let h = w.transpose() * &w;
                Arc::new(
                    QuadraticCost::new(
                        h.as_ref().submatrix(0, 0, nx, nx),
                        h.as_ref().submatrix(0, nx, nx, nu),
                        h.as_ref().submatrix(nx, nx, nu, nu),
                        &random_vec(&mut g, nx, 1.0),
                        &random_vec(&mut g, nu, 1.0),
                    )
                    .unwrap(),
                )
            };
            let affine = LinearFunction::new(
                random_mat(&mut g, 2, nx, 1.0).as_ref(),
                random_mat(&mut g, 2, nu, 1.0).as_ref(),
                &random_vec(&mut g, 2, 1.0),
            )
            .unwrap();
            let u_err = ControlError::new(space.as_ref(), &random_vec(&mut g, nu, 1.0)).unwrap();
            StageModel::new(cost, dynamics)
                .unwrap()
                .with_constraint(StageConstraint::new("affine", Arc::new(affine), Arc::new(AnySet)))
                .unwrap()
                .with_constraint(StageConstraint::new("u", Arc::new(u_err), Arc::new(AnySet)))
                .unwrap()
        })
        .collect();
    let x_ref = random_vec(&mut g, nx, 1.0);
    let term = Arc::new(QuadraticStateCost::diagonal(space.clone(), &x_ref, &[1.0, 2.0, 3.0], 0).unwrap());
    let x_err = Unary::new(Arc::new(StateError::new(space, &x_ref).unwrap()), 0);
    Problem::new(&random_vec(&mut g, nx, 1.0), stages, term)
        .unwrap()
        .with_terminal_constraint(StageConstraint::new("x_N", Arc::new(x_err), Arc::new(AnySet)))
        .unwrap()
}

/// Every derivative block of `a` and `b`, bit for bit.
fn assert_same_derivatives(a: &ProblemData, b: &ProblemData, what: &str) {
    for (t, (sa, sb)) in a.stages.iter().zip(&b.stages).enumerate() {
        let (ca, cb) = (&sa.cost, &sb.cost);
        assert_eq!((ca.lx(), ca.lu()), (cb.lx(), cb.lu()), "{what}: stage {t} gradient");
        assert_eq!(
            (&ca.lxx, &ca.lxu, &ca.luu),
            (&cb.lxx, &cb.lxu, &cb.luu),
            "{what}: stage {t} Hessian"
        );
        assert_eq!(
            (&sa.dyn_jx, &sa.dyn_ju, &sa.dyn_jy),
            (&sb.dyn_jx, &sb.dyn_ju, &sb.dyn_jy),
            "{what}: stage {t} dynamics"
        );
        for (k, (da, db)) in sa.constraints.iter().zip(&sb.constraints).enumerate() {
            assert_eq!((&da.jx, &da.ju), (&db.jx, &db.ju), "{what}: stage {t} constraint {k}");
        }
    }
    let (ta, tb) = (&a.terminal_cost, &b.terminal_cost);
    assert_eq!((ta.lx(), &ta.lxx), (tb.lx(), &tb.lxx), "{what}: terminal cost");
    for (da, db) in a.terminal_constraints.iter().zip(&b.terminal_constraints) {
        assert_eq!(&da.jx, &db.jx, "{what}: terminal constraint");
    }
}

#[test]
fn constant_blocks_kept_across_points_equal_a_fresh_evaluation() {
    let n = 6;
    let p = constant_blocks_problem(70, n);
    for st in p.stages() {
        assert!(st.cost.hessian_is_constant() && st.dynamics.jacobians_are_constant());
        assert!(st.constraints().iter().all(|c| c.func.jacobians_are_constant()));
    }
    assert!(p.terminal_cost().hessian_is_constant());
    let mut g = crate::functions::testing::rng(72);
    let mut point = |k: usize, m: usize| -> Vec<Vec<f64>> {
        (0..m)
            .map(|_| crate::functions::testing::random_vec(&mut g, k, 1.0))
            .collect()
    };
    let (xs, us, xs2, us2) = (point(3, n + 1), point(2, n), point(3, n + 1), point(2, n));
    // Derivatives at a first point, then at a second one, keeping the constant blocks.
    let mut kept = ProblemData::new(&p, 1).unwrap();
    kept.evaluate(&p, &xs, &us);
    kept.compute_derivatives(&p, &xs, &us);
    kept.evaluate(&p, &xs2, &us2);
    kept.compute_derivatives(&p, &xs2, &us2);
    let mut fresh = ProblemData::new(&p, 1).unwrap();
    fresh.evaluate(&p, &xs2, &us2);
    fresh.compute_derivatives(&p, &xs2, &us2);
    assert_same_derivatives(&kept, &fresh, "kept blocks");
    // The control constraint's state Jacobian is known to be zero, the affine one's not;
    // the Lagrangian gradient that skips the zero block equals the full products.
    for sd in &kept.stages {
        assert!(!sd.constraint_jx_is_zero(0) && sd.constraint_jx_is_zero(1));
    }
    let lambdas = point(3, n + 1);
    let nus: Vec<Vec<f64>> = (0..=n)
        .map(|t| {
            (0..p.constraints(t).iter().map(|c| c.nr()).sum())
                .map(|i| 0.3 * i as f64 - 0.2)
                .collect()
        })
        .collect();
    let (mut gx, mut gu) = (vec![vec![0.0; 3]; n + 1], vec![vec![0.0; 2]; n]);
    kept.lagrangian_gradient(&p, &lambdas, &nus, &mut gx, &mut gu);
    for t in 0..n {
        let sd = &kept.stages[t];
        for i in 0..3 {
            let mut g = sd.cost.lx()[i] + (0..3).map(|k| sd.dyn_jx[(k, i)] * lambdas[t + 1][k]).sum::<f64>();
            let mut off = 0;
            for cd in &sd.constraints {
                g += (0..cd.jx.nrows()).map(|k| cd.jx[(k, i)] * nus[t][off + k]).sum::<f64>();
                off += cd.jx.nrows();
            }
            g += if t == 0 {
                (0..3).map(|k| kept.init.jx[(k, i)] * lambdas[0][k]).sum::<f64>()
            } else {
                (0..3)
                    .map(|k| kept.stages[t - 1].dyn_jy[(k, i)] * lambdas[t][k])
                    .sum::<f64>()
            };
            assert!(
                (gx[t][i] - g).abs() < 1e-13 * (1.0 + g.abs()),
                "gx[{t}][{i}] = {} vs {g}",
                gx[t][i]
            );
        }
    }
    // Other models of the same dimensions: after invalidation, every block is new.
    let q = constant_blocks_problem(71, n);
    kept.invalidate_constant_derivatives();
    kept.evaluate(&q, &xs, &us);
    kept.compute_derivatives(&q, &xs, &us);
    let mut fresh = ProblemData::new(&q, 1).unwrap();
    fresh.evaluate(&q, &xs, &us);
    fresh.compute_derivatives(&q, &xs, &us);
    assert_same_derivatives(&kept, &fresh, "other models");
}

#[test]
fn constant_blocks_travel_with_the_stage_data_through_shifts() {
    // Stages of distinct constant models (explicit and implicit dynamics alternate), a
    // rotation, then a shift that brings in a stage of other models with fresh data: a
    // solve that continues the horizon keeps the blocks of the data that moved with their
    // models and writes those of the entering data, and every block equals a fresh
    // evaluation of the shifted problem; a solve that does not continue writes them all.
    let n = 5;
    let mut p = constant_blocks_problem(80, n);
    let mut incoming = constant_blocks_problem(81, 1).stages()[0].clone();
    let mut incoming_data = StageData::new(&incoming);
    let mut g = crate::functions::testing::rng(82);
    let mut point = |k: usize, m: usize| -> Vec<Vec<f64>> {
        (0..m)
            .map(|_| crate::functions::testing::random_vec(&mut g, k, 1.0))
            .collect()
    };
    let fresh = |p: &Problem, xs: &[Vec<f64>], us: &[Vec<f64>]| {
        let mut d = ProblemData::new(p, 1).unwrap();
        d.evaluate(p, xs, us);
        d.compute_derivatives(p, xs, us);
        d
    };
    let mut kept = ProblemData::new(&p, 1).unwrap();
    let (xs, us) = (point(3, n + 1), point(2, n));
    kept.start_solve();
    kept.evaluate(&p, &xs, &us);
    kept.compute_derivatives(&p, &xs, &us);
    // A mark in a constant block (the control constraint's `ju` of stage 2): kept as it
    // is by the derivative passes of continuing solves, wherever the data goes.
    kept.stages[2].constraints[1].ju[(0, 0)] = 42.0;
    let cycles: [Option<&mut StageModel>; 2] = [None, Some(&mut incoming)];
    for (k, model) in cycles.into_iter().enumerate() {
        let entering = match model {
            None => {
                p.rotate().unwrap();
                None
            }
            Some(m) => {
                p.shift(m).unwrap();
                Some(&mut incoming_data)
            }
        };
        kept.shift(entering);
        kept.start_solve();
        let (xs, us) = (point(3, n + 1), point(2, n));
        kept.evaluate(&p, &xs, &us);
        kept.compute_derivatives(&p, &xs, &us);
        assert_eq!(
            kept.stages[1 - k].constraints[1].ju[(0, 0)],
            42.0,
            "cycle {k}: the mark moved along"
        );
        // Its true value (the control error's `ju` is the identity) for the comparison.
        kept.stages[1 - k].constraints[1].ju[(0, 0)] = 1.0;
        assert_same_derivatives(&kept, &fresh(&p, &xs, &us), &format!("cycle {k}"));
        kept.stages[1 - k].constraints[1].ju[(0, 0)] = 42.0;
    }
    // Not a continuation: every block is written again, the mark too.
    kept.start_solve();
    let (xs, us) = (point(3, n + 1), point(2, n));
    kept.evaluate(&p, &xs, &us);
    kept.compute_derivatives(&p, &xs, &us);
    assert_same_derivatives(&kept, &fresh(&p, &xs, &us), "new solve");
    // The data that left the horizon (held outside it through that invalidation, with a
    // mark) enters again with its model: written again too.
    incoming_data.constraints[1].ju[(0, 0)] = 42.0;
    p.shift(&mut incoming).unwrap();
    kept.shift(Some(&mut incoming_data));
    kept.start_solve();
    let (xs, us) = (point(3, n + 1), point(2, n));
    kept.evaluate(&p, &xs, &us);
    kept.compute_derivatives(&p, &xs, &us);
    assert_same_derivatives(&kept, &fresh(&p, &xs, &us), "queued data after a new solve");
}

/// y = x ⊕ u on SO(2).
struct Turn {
    space: Arc<dyn Manifold>,
}

impl ExplicitDynamics for Turn {
    fn space(&self) -> &Arc<dyn Manifold> {
        &self.space
    }
    fn nu(&self) -> usize {
        1
    }
    fn forward(&self, x: &[f64], u: &[f64], d: &mut ExplicitDynamicsData) {
        self.space.integrate(x, u, d.xnext_mut());
    }
    fn jacobians(&self, _x: &[f64], _u: &[f64], d: &mut ExplicitDynamicsData) {
        d.jx[(0, 0)] = 1.0;
        d.ju[(0, 0)] = 1.0;
    }
}

#[test]
fn set_x0_rejects_what_new_rejects_and_keeps_the_old_state() {
    let space: Arc<dyn Manifold> = Arc::new(crate::spaces::SO2);
    let dynamics = Dynamics::Explicit(Arc::new(Turn { space: space.clone() }));
    let cost = Arc::new(crate::costs::QuadraticControlCost::diagonal(space.as_ref(), &[0.0], &[1.0]).unwrap());
    let terminal = Arc::new(crate::costs::QuadraticStateCost::diagonal(space.clone(), &[1.0, 0.0], &[1.0], 0).unwrap());
    let stage = StageModel::new(cost, dynamics).unwrap();
    // Off the unit circle: refused by `new` and by `set_x0` alike.
    let off = [3.0, 0.0];
    let e = Problem::new(&off, vec![stage.clone()], terminal.clone()).err().unwrap();
    assert!(e.to_string().contains("not a valid point"), "{e}");
    let mut p = Problem::new(&[1.0, 0.0], vec![stage], terminal).unwrap();
    let e = p.set_x0(&off).err().unwrap();
    assert!(e.to_string().contains("not a valid point"), "{e}");
    assert!(p.set_x0(&[0.0, f64::NAN]).is_err());
    assert!(p.set_x0(&[1.0]).is_err());
    assert_eq!(p.x0(), Some(&[1.0, 0.0][..]));
    p.set_x0(&[0.0, 1.0]).unwrap();
    assert_eq!(p.x0(), Some(&[0.0, 1.0][..]));
}

/// Wrong numbers or sizes of states and controls, and non-finite controls, are errors
/// that name the entry (they once indexed out of bounds).
#[test]
fn rollout_checks_its_inputs() {
    let p = problem(3);
    let mut d = ProblemData::new(&p, 1).unwrap();
    let xs = || vec![vec![1.0, 0.0]; 4];
    type Case = (Vec<Vec<f64>>, Vec<Vec<f64>>, &'static str);
    let cases: [Case; 6] = [
        (xs(), vec![vec![0.0]; 2], "number of controls"),
        (xs(), vec![vec![0.0]; 4], "number of controls"),
        (xs(), vec![vec![0.0, 0.0]; 3], "us[0] size"),
        (vec![vec![1.0, 0.0]; 3], vec![vec![0.0]; 3], "number of states"),
        (xs(), vec![vec![0.0], vec![f64::NAN], vec![0.0]], "us[1]"),
        (vec![vec![f64::INFINITY, 0.0]; 4], vec![vec![0.0]; 3], "xs[0]"),
    ];
    for (mut xs, us, what) in cases {
        let e = d.rollout(&p, &mut xs, &us).err().unwrap();
        assert!(e.to_string().contains(what), "{what}: {e}");
    }
    d.rollout(&p, &mut xs(), &vec![vec![0.0]; 3]).unwrap();
}

#[test]
fn rollout_solves_implicit_dynamics() {
    use crate::dynamics::{ImplicitEuler, LinearOde};
    // ẋ = A x + B u, implicit Euler: x⁺ = (I - dt A)⁻¹ (x + dt B u).
    let a = faer::Mat::from_fn(2, 2, |i, j| [[0.0, 1.0], [-2.0, -0.3]][i][j]);
    let b = faer::Mat::from_fn(2, 1, |i, _| if i == 1 { 1.0 } else { 0.0 });
    let ode = Arc::new(LinearOde::new(a.as_ref(), b.as_ref(), &[0.0, 0.0]).unwrap());
    let dt = 0.1;
    let dynamics = Dynamics::Implicit(Arc::new(ImplicitEuler::new(ode, dt).unwrap()));
    let stage = StageModel::new(Arc::new(Quad { nu: 1 }), dynamics).unwrap();
    let p = Problem::new(&[1.0, 0.0], vec![stage; 5], Arc::new(Quad { nu: 0 })).unwrap();
    let us: Vec<Vec<f64>> = (0..5).map(|t| vec![0.1 * t as f64]).collect();
    let mut xs = vec![vec![1.0, 0.0]; 6];
    ProblemData::new(&p, 1).unwrap().rollout(&p, &mut xs, &us).unwrap();
    let mut x = [1.0, 0.0];
    for t in 0..5 {
        // (I - dt A) x⁺ = x + dt B u, solved by Cramer's rule.
        let m = [[1.0, -dt], [2.0 * dt, 1.0 + 0.3 * dt]];
        let r = [x[0], x[1] + dt * us[t][0]];
        let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        x = [
            (r[0] * m[1][1] - m[0][1] * r[1]) / det,
            (m[0][0] * r[1] - m[1][0] * r[0]) / det,
        ];
        assert!(
            (xs[t + 1][0] - x[0]).abs() < 1e-12 && (xs[t + 1][1] - x[1]).abs() < 1e-12,
            "t = {t}"
        );
    }
}

/// At a closed gap (`y = φ(x, u)` bit for bit) the Jacobians of `f = φ ⊖ y` are taken
/// without the Lie-group Jacobians of `⊖` (`E = -I`): they agree with central finite
/// differences of `f` in the tangent coordinates of `x`, `u` and `y`, as at an open gap.
#[test]
fn closed_gap_jacobians_match_finite_differences() {
    use crate::dynamics::{ExplicitRungeKutta, RkMethod};
    let mut g = crate::functions::testing::rng(17);
    for (name, ode) in crate::dynamics::manifold_tests::models() {
        let space = ode.space().clone();
        let (nx, ndx, nu) = (space.nx(), space.ndx(), ode.nu());
        let rk = Arc::new(ExplicitRungeKutta::new(ode, 0.05, RkMethod::Rk4).unwrap());
        let cost = Arc::new(crate::costs::ConstantCost::new(space.as_ref(), nu, 0.0).unwrap());
        let stage = StageModel::new(cost, Dynamics::Explicit(rk.clone())).unwrap();
        let x0 = crate::dynamics::manifold_tests::random_point(space.as_ref(), &mut g);
        let p = Problem::new(
            &x0,
            vec![stage],
            Arc::new(crate::costs::ConstantCost::new(space.as_ref(), 0, 0.0).unwrap()),
        )
        .unwrap();
        let us = vec![(0..nu).map(|i| 0.3 - 0.2 * i as f64).collect::<Vec<_>>()];
        let mut rd = rk.create_data();
        rk.forward(&x0, &us[0], &mut rd);
        let phi = rd.xnext().to_vec();
        let mut y_open = vec![0.0; nx];
        space.integrate(&phi, &vec![1e-3; ndx], &mut y_open);
        for (y, closed) in [(phi.clone(), true), (y_open, false)] {
            let xs = vec![x0.clone(), y.clone()];
            let mut d = ProblemData::new(&p, 1).unwrap();
            d.evaluate(&p, &xs, &us);
            d.compute_derivatives(&p, &xs, &us);
            let s = &d.stages[0];
            assert_eq!(s.gap_closed, closed, "{name}");
            // `E = -I` outside its leading block, which the structured products rely on.
            let k = s.dyn_jy_block;
            assert_eq!(
                k,
                if s.dyn_jy_is_minus_identity {
                    0
                } else {
                    space.nonlinear_dim()
                }
            );
            for c in 0..ndx {
                for r in (0..ndx).filter(|&r| r >= k || c >= k) {
                    let want = if r == c { -1.0 } else { 0.0 };
                    assert_eq!(s.dyn_jy[(r, c)], want, "{name} closed {closed} E ({r}, {c})");
                }
            }
            // f(x ⊕ δx, u + δu, y ⊕ δy) by central differences, column by column.
            let f = |dx: &[f64], du: &[f64], dy: &[f64]| {
                let (mut xp, mut yp) = (vec![0.0; nx], vec![0.0; nx]);
                space.integrate(&x0, dx, &mut xp);
                space.integrate(&y, dy, &mut yp);
                let up: Vec<f64> = us[0].iter().zip(du).map(|(a, b)| a + b).collect();
                let mut dd = rk.create_data();
                rk.forward(&xp, &up, &mut dd);
                let mut out = vec![0.0; ndx];
                space.difference(&yp, dd.xnext(), &mut out);
                out
            };
            let h = 1e-6;
            for (which, n, jac) in [(0, ndx, &s.dyn_jx), (1, nu, &s.dyn_ju), (2, ndx, &s.dyn_jy)] {
                for c in 0..n {
                    let mut args = [vec![0.0; ndx], vec![0.0; nu], vec![0.0; ndx]];
                    args[which][c] = h;
                    let fp = f(&args[0], &args[1], &args[2]);
                    args[which][c] = -h;
                    let fm = f(&args[0], &args[1], &args[2]);
                    for r in 0..ndx {
                        let fd = (fp[r] - fm[r]) / (2.0 * h);
                        assert!(
                            (jac[(r, c)] - fd).abs() < 1e-7,
                            "{name} closed {closed} arg {which} ({r}, {c}): {} vs {fd}",
                            jac[(r, c)]
                        );
                    }
                }
            }
        }
    }
}

/// The products with an `f_y` that is `-I` outside a leading block give the whole
/// products' values, for every block size and on both sides of the fixed-size kernels'
/// range (16 rows).
#[test]
fn structured_jy_products_equal_the_whole_products() {
    use crate::functions::testing::{random_mat, random_vec, rng};
    use crate::linalg::{matvec, matvec_t};
    use faer::{Accum, Mat};
    let mut g = rng(5);
    for n in [9, 20, 36] {
        for k in [0, 1, 3, 4, 6, n] {
            let b = random_mat(&mut g, k, k, 1.0);
            let jy = Mat::from_fn(n, n, |i, j| {
                if i < k && j < k {
                    b[(i, j)]
                } else if i == j {
                    -1.0
                } else {
                    0.0
                }
            });
            let (x, y0) = (random_vec(&mut g, n, 1.0), random_vec(&mut g, n, 1.0));
            let (mut whole, mut parts) = (y0.clone(), y0.clone());
            matvec_t(&mut whole, Accum::Add, jy.as_ref(), &x, 1.0);
            data::add_jy_t_product(&mut parts, jy.as_ref(), k, &x);
            assert_eq!(whole, parts, "transposed, n = {n}, k = {k}");
            let (mut whole, mut parts) = (y0.clone(), y0);
            matvec(&mut whole, Accum::Add, jy.as_ref(), &x, 1.0);
            data::add_jy_product(&mut parts, jy.as_ref(), k, &x);
            assert_eq!(whole, parts, "n = {n}, k = {k}");
        }
    }
}

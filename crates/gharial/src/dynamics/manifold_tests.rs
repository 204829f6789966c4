//! Integrators on manifolds: SO(2) x R, the tangent bundle of SO(3) and SE(3).
//!
//! The ODEs are written once generic over the scalar and wrapped by
//! [`AutoDiff`](crate::autodiff::AutoDiff); each integrator is compared with
//! finite differences and with dual-number derivatives of the same scheme written
//! generically with the spaces' own `⊕` and `⊖`.

use std::sync::Arc;

use super::*;
use crate::autodiff::{AutoDiff, AutoOdeFn, ManifoldScalar};
use crate::check::{
    CheckOptions, DualCheckOptions, check_explicit_dynamics, check_explicit_dynamics_dual, check_implicit_dynamics,
    check_implicit_dynamics_dual, check_ode, check_ode_dual,
};
use crate::functions::testing::rng;
use crate::spaces::lie::{cross, qconj, qrot};
use crate::spaces::{CartesianProduct, SE3, SO2, SO3, TangentBundle, VectorSpace};

/// A damped pendulum on `SO(2) x R`: `x = (cos θ, sin θ, ω)`, `ẋ = (ω, -2 sin θ - 0.1 ω + u)`.
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
        xdot[1] = x[1] * (-2.0) - x[2] * 0.1 + u[0];
    }
}

/// A rigid body on `T SO(3)`: `x = (q, ω)` (body angular velocity), torque `u`,
/// `ω̇ = I⁻¹ (u + c × Rᵀ g - ω × I ω)`.
struct RigidBody;

const INERTIA: [f64; 3] = [1.0, 2.0, 3.0];

impl AutoOdeFn for RigidBody {
    fn nx(&self) -> usize {
        7
    }
    fn nu(&self) -> usize {
        3
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], xdot: &mut [D]) {
        let q = [x[0], x[1], x[2], x[3]];
        let w = [x[4], x[5], x[6]];
        let g_body = qrot(&qconj(&q), &[D::from(0.0), D::from(0.0), D::from(-9.81)]);
        let torque = cross(&[D::from(0.1), D::from(-0.2), D::from(0.3)], &g_body);
        let iw = [w[0] * INERTIA[0], w[1] * INERTIA[1], w[2] * INERTIA[2]];
        let gyro = cross(&w, &iw);
        for i in 0..3 {
            xdot[i] = w[i];
            xdot[3 + i] = (u[i] + torque[i] - gyro[i]) * (1.0 / INERTIA[i]);
        }
    }
}

/// A body on SE(3) driven by a state-dependent body twist `(v, w)`.
struct Drift;

impl AutoOdeFn for Drift {
    fn nx(&self) -> usize {
        7
    }
    fn nu(&self) -> usize {
        2
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], xdot: &mut [D]) {
        xdot[0] = u[0] + x[1] * 0.2;
        xdot[1] = (x[0] * 0.7).sin() * 0.3;
        xdot[2] = x[5] * 0.5;
        xdot[3] = u[1] * x[2];
        xdot[4] = x[3] * 0.4 - x[0] * 0.1;
        xdot[5] = u[0] * 0.6 + x[6] * 0.2;
    }
}

pub(crate) fn models() -> Vec<(&'static str, Arc<dyn Ode>)> {
    let so2_r: Arc<dyn Manifold> = Arc::new(CartesianProduct::pair(Arc::new(SO2), Arc::new(VectorSpace::new(1))));
    let tso3: Arc<dyn Manifold> = Arc::new(TangentBundle::new(Arc::new(SO3)));
    vec![
        ("SO(2) x R", Arc::new(AutoDiff::ode(so2_r, Pendulum).unwrap())),
        ("T SO(3)", Arc::new(AutoDiff::ode(tso3, RigidBody).unwrap())),
        ("SE(3)", Arc::new(AutoDiff::ode(Arc::new(SE3), Drift).unwrap())),
    ]
}

/// The ODE of model `k`, generic.
fn ode_eval<D: ManifoldScalar>(k: usize, x: &[D], u: &[D], xdot: &mut [D]) {
    match k {
        0 => Pendulum.eval(x, u, xdot),
        1 => RigidBody.eval(x, u, xdot),
        _ => Drift.eval(x, u, xdot),
    }
}

fn tableau(method: RkMethod) -> (Vec<f64>, Vec<f64>) {
    match method {
        RkMethod::Euler => (vec![0.0], vec![1.0]),
        RkMethod::Rk2 => (vec![0.0, 0.5], vec![0.0, 1.0]),
        RkMethod::Rk4 => (
            vec![0.0, 0.5, 0.5, 1.0],
            vec![1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0],
        ),
    }
}

/// The Runge-Kutta step of the module documentation, generic over the scalar.
fn rk_ref<D: ManifoldScalar>(k: usize, space: &dyn Manifold, dt: f64, method: RkMethod, x: &[D], u: &[D], y: &mut [D]) {
    let (a, b) = tableau(method);
    let (nx, ndx) = (space.nx(), space.ndx());
    let zero = D::from(0.0);
    let mut ks = vec![vec![zero; ndx]; b.len()];
    ode_eval(k, x, u, &mut ks[0]);
    let mut xi = vec![zero; nx];
    for i in 1..b.len() {
        let w: Vec<D> = ks[i - 1].iter().map(|&v| v * (dt * a[i])).collect();
        D::integrate(space, x, &w, &mut xi);
        let (prev, rest) = ks.split_at_mut(i);
        let _ = prev;
        ode_eval(k, &xi, u, &mut rest[0]);
    }
    let v: Vec<D> = (0..ndx)
        .map(|j| (0..b.len()).fold(zero, |acc, i| acc + ks[i][j] * (dt * b[i])))
        .collect();
    D::integrate(space, x, &v, y);
}

pub(crate) fn random_point(space: &dyn Manifold, g: &mut rand::rngs::SmallRng) -> Vec<f64> {
    let mut x = vec![0.0; space.nx()];
    space.random(g, &mut x);
    x
}

#[test]
fn odes_on_manifolds_match_their_references() {
    let mut g = rng(100);
    for (k, (name, ode)) in models().into_iter().enumerate() {
        for _ in 0..3 {
            let x = random_point(ode.space().as_ref(), &mut g);
            let u = crate::functions::testing::random_vec(&mut g, ode.nu(), 1.0);
            check_ode(ode.as_ref(), &x, &u, CheckOptions::default()).assert_ok();
            let rep = check_ode_dual(
                ode.as_ref(),
                &x,
                &u,
                |x, u, out| ode_eval(k, x, u, out),
                DualCheckOptions::default(),
            );
            assert!(rep.passed(), "{name}: {rep:?}");
        }
    }
}

#[test]
fn runge_kutta_on_manifolds_matches_finite_differences_and_dual_numbers() {
    let mut g = rng(101);
    for (k, (name, ode)) in models().into_iter().enumerate() {
        let space = ode.space().clone();
        for method in [RkMethod::Euler, RkMethod::Rk2, RkMethod::Rk4] {
            let dt = 0.05;
            let d = ExplicitRungeKutta::new(ode.clone(), dt, method).unwrap();
            for _ in 0..3 {
                let x = random_point(space.as_ref(), &mut g);
                let u = crate::functions::testing::random_vec(&mut g, ode.nu(), 1.0);
                let rep = check_explicit_dynamics(&d, &x, &u, CheckOptions::default());
                assert!(rep.passed(), "{name} {method:?}: {rep:?}");
                let rep = check_explicit_dynamics_dual(
                    &d,
                    &x,
                    &u,
                    |x, u, y| rk_ref(k, space.as_ref(), dt, method, x, u, y),
                    DualCheckOptions::default(),
                );
                assert!(rep.passed(), "{name} {method:?}: {rep:?}");
            }
        }
    }
}

/// Final state after `n` steps of `d` from `x0`.
fn rollout(d: &dyn ExplicitDynamics, x0: &[f64], u: &[f64], n: usize) -> Vec<f64> {
    let mut data = d.create_data();
    let mut x = x0.to_vec();
    for _ in 0..n {
        d.forward(&x, u, &mut data);
        x.copy_from_slice(data.xnext());
    }
    x
}

/// Global errors at `t = 1` for `n = 20, 40, 80, 160`, against RK4 with `n = 5120`.
fn global_errors(ode: &Arc<dyn Ode>, method: RkMethod, x0: &[f64], u: &[f64]) -> Vec<f64> {
    let space = ode.space().clone();
    let fine = rollout(
        &ExplicitRungeKutta::rk4(ode.clone(), 1.0 / 5120.0).unwrap(),
        x0,
        u,
        5120,
    );
    let mut d = vec![0.0; space.ndx()];
    [20, 40, 80, 160]
        .iter()
        .map(|&n| {
            let y = rollout(
                &ExplicitRungeKutta::new(ode.clone(), 1.0 / n as f64, method).unwrap(),
                x0,
                u,
                n,
            );
            space.difference(&fine, &y, &mut d);
            crate::linalg::norm_inf(&d)
        })
        .collect()
}

fn assert_ratios(what: &str, errs: &[f64], expected: f64) {
    eprintln!("{what}: {errs:?}");
    for w in errs.windows(2) {
        let r = w[0] / w[1];
        assert!(
            (r / expected - 1.0).abs() < 0.15,
            "{what}: ratio {r}, expected {expected}: {errs:?}"
        );
    }
}

#[test]
fn orders_of_accuracy_on_manifolds() {
    let models = models();
    // SO(2) x R: the velocities commute, the classical orders hold.
    let (x0, u) = ([0.6f64.cos(), 0.6f64.sin(), 0.5], [0.3]);
    for (method, order) in [(RkMethod::Euler, 1), (RkMethod::Rk2, 2), (RkMethod::Rk4, 4)] {
        let errs = global_errors(&models[0].1, method, &x0, &u);
        assert_ratios(&format!("SO(2) x R {method:?} global errors"), &errs, 2f64.powi(order));
    }
    // T SO(3): without dexp⁻¹ corrections RK4 is of order 2 (module documentation).
    let q = SO3::exp(&[0.3, -0.2, 0.5]);
    let x0 = [q[0], q[1], q[2], q[3], 1.0, -2.0, 0.5];
    let u = [0.1, 0.0, -0.2];
    let errs = global_errors(&models[1].1, RkMethod::Rk2, &x0, &u);
    assert_ratios("T SO(3) Rk2 global errors", &errs, 4.0);
    let errs = global_errors(&models[1].1, RkMethod::Rk4, &x0, &u);
    assert_ratios("T SO(3) Rk4 global errors", &errs, 4.0);
}

/// Semi-implicit Euler on `T SO(3)` with configuration space SO(3), generic.
fn sie_ref<D: ManifoldScalar>(dt: f64, x: &[D], u: &[D], y: &mut [D]) {
    let mut f = [D::from(0.0); 6];
    RigidBody.eval(x, u, &mut f);
    let v: Vec<D> = (0..3).map(|i| x[4 + i] + f[3 + i] * dt).collect();
    let dq: Vec<D> = v.iter().map(|&vi| vi * dt).collect();
    D::integrate(&SO3, &x[..4], &dq, &mut y[..4]);
    y[4..].copy_from_slice(&v);
}

#[test]
fn semi_implicit_euler_on_the_tangent_bundle_of_so3() {
    let ode = models().swap_remove(1).1;
    let dt = 0.05;
    let d = SemiImplicitEuler::new(ode.clone(), Arc::new(SO3), dt).unwrap();
    let mut g = rng(102);
    for _ in 0..4 {
        let x = random_point(ode.space().as_ref(), &mut g);
        let u = crate::functions::testing::random_vec(&mut g, 3, 1.0);
        check_explicit_dynamics(&d, &x, &u, CheckOptions::default()).assert_ok();
        let rep = check_explicit_dynamics_dual(&d, &x, &u, |x, u, y| sie_ref(dt, x, u, y), DualCheckOptions::default());
        assert!(rep.passed(), "{rep:?}");
    }
}

/// The implicit residuals of [`super::implicit`], generic.
fn implicit_ref<D: ManifoldScalar>(
    k: usize,
    space: &dyn Manifold,
    dt: f64,
    midpoint: bool,
    x: &[D],
    u: &[D],
    y: &[D],
    out: &mut [D],
) {
    let (nx, ndx) = (space.nx(), space.ndx());
    let zero = D::from(0.0);
    let mut d = vec![zero; ndx];
    D::difference(space, x, y, &mut d);
    let mut f = vec![zero; ndx];
    if midpoint {
        let half: Vec<D> = d.iter().map(|&v| v * 0.5).collect();
        let mut xm = vec![zero; nx];
        D::integrate(space, x, &half, &mut xm);
        ode_eval(k, &xm, u, &mut f);
    } else {
        ode_eval(k, y, u, &mut f);
    }
    for i in 0..ndx {
        out[i] = f[i] * dt - d[i];
    }
}

#[test]
fn implicit_integrators_on_manifolds() {
    let mut g = rng(103);
    for (k, (name, ode)) in models().into_iter().enumerate() {
        let space = ode.space().clone();
        let dt = 0.05;
        let euler = ImplicitEuler::new(ode.clone(), dt).unwrap();
        let mid = ImplicitMidpoint::new(ode.clone(), dt).unwrap();
        let rk: Arc<dyn ExplicitDynamics> = Arc::new(ExplicitRungeKutta::rk4(ode.clone(), dt).unwrap());
        let as_implicit = ExplicitAsImplicit::new(rk.clone());
        for _ in 0..3 {
            let x = random_point(space.as_ref(), &mut g);
            let u = crate::functions::testing::random_vec(&mut g, ode.nu(), 1.0);
            // A next state near x, as in a solver.
            let mut y = vec![0.0; space.nx()];
            let v = crate::functions::testing::random_vec(&mut g, space.ndx(), 0.3);
            space.integrate(&x, &v, &mut y);
            for (model, midpoint) in [(&euler as &dyn ImplicitDynamics, false), (&mid, true)] {
                let rep = check_implicit_dynamics(model, &x, &u, &y, CheckOptions::default());
                assert!(rep.passed(), "{name} midpoint = {midpoint}: {rep:?}");
                let rep = check_implicit_dynamics_dual(
                    model,
                    &x,
                    &u,
                    &y,
                    |x, u, y, out| implicit_ref(k, space.as_ref(), dt, midpoint, x, u, y, out),
                    DualCheckOptions::default(),
                );
                assert!(rep.passed(), "{name} midpoint = {midpoint}: {rep:?}");
            }
            let rep = check_implicit_dynamics(&as_implicit, &x, &u, &y, CheckOptions::default());
            assert!(rep.passed(), "{name} explicit as implicit: {rep:?}");
            let rep = check_implicit_dynamics_dual(
                &as_implicit,
                &x,
                &u,
                &y,
                |x, u, y, out| {
                    let mut phi = vec![num_dual::Dual64::from(0.0); space.nx()];
                    rk_ref(k, space.as_ref(), dt, RkMethod::Rk4, x, u, &mut phi);
                    space.difference_dual(y, &phi, out);
                },
                DualCheckOptions::default(),
            );
            assert!(rep.passed(), "{name} explicit as implicit: {rep:?}");
        }
    }
}

#[test]
fn implicit_residuals_on_so2_vanish_to_the_expected_order() {
    let ode = models().swap_remove(0).1;
    let (x0, u) = ([0.6f64.cos(), 0.6f64.sin(), 0.5], [0.3]);
    for (midpoint, order) in [(false, 2), (true, 3)] {
        let res: Vec<f64> = [0.1, 0.05, 0.025, 0.0125]
            .iter()
            .map(|&dt| {
                // The exact flow over dt, from a fine RK4 rollout.
                let n = 512;
                let y = rollout(
                    &ExplicitRungeKutta::rk4(ode.clone(), dt / n as f64).unwrap(),
                    &x0,
                    &u,
                    n,
                );
                let model: Box<dyn ImplicitDynamics> = if midpoint {
                    Box::new(ImplicitMidpoint::new(ode.clone(), dt).unwrap())
                } else {
                    Box::new(ImplicitEuler::new(ode.clone(), dt).unwrap())
                };
                let mut data = model.create_data();
                model.evaluate(&x0, &u, &y, &mut data);
                crate::linalg::norm_inf(data.value())
            })
            .collect();
        assert_ratios(
            &format!("SO(2) x R implicit residuals, midpoint = {midpoint}"),
            &res,
            2f64.powi(order),
        );
    }
}

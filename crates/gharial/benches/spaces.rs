//! Cost of the group operations and Jacobians of the spaces, and of the automatic
//! derivatives (`cargo bench -p gharial --features bench --bench spaces`).

use std::hint::black_box;
use std::sync::Arc;

use criterion::{Criterion, criterion_group, criterion_main};
use faer::Mat;
use gharial::autodiff::{AutoCostFn, AutoDiff, AutoDynamicsFn, ManifoldScalar};
use gharial::costs::Cost;
use gharial::dynamics::ExplicitDynamics;
use gharial::spaces::{Arg, CartesianProduct, Manifold, SE3, SO3, VectorSpace};
use rand::SeedableRng;

fn spaces(c: &mut Criterion) {
    let cases: Vec<(&str, Arc<dyn Manifold>)> = vec![
        ("R12", Arc::new(VectorSpace::new(12))),
        ("SO3", Arc::new(SO3)),
        ("SE3", Arc::new(SE3)),
        (
            "SE3xR12",
            Arc::new(CartesianProduct::pair(Arc::new(SE3), Arc::new(VectorSpace::new(12)))),
        ),
    ];
    let mut rng = rand::rngs::SmallRng::seed_from_u64(1);
    for (name, m) in cases {
        let (nx, ndx) = (m.nx(), m.ndx());
        let (mut x, mut y) = (vec![0.0; nx], vec![0.0; nx]);
        m.random(&mut rng, &mut x);
        let v: Vec<f64> = (0..ndx).map(|i| 0.3 - 0.05 * i as f64).collect();
        m.integrate(&x, &v, &mut y);
        let mut out = vec![0.0; nx];
        let mut d = vec![0.0; ndx];
        let mut j = Mat::<f64>::zeros(ndx, ndx);
        let mut g = c.benchmark_group(name);
        g.bench_function("integrate", |b| {
            b.iter(|| m.integrate(black_box(&x), black_box(&v), &mut out))
        });
        g.bench_function("difference", |b| {
            b.iter(|| m.difference(black_box(&x), black_box(&y), &mut d))
        });
        g.bench_function("jintegrate(v)", |b| {
            b.iter(|| m.jintegrate(black_box(&x), black_box(&v), Arg::Second, j.as_mut()))
        });
        g.bench_function("jdifference(x0)", |b| {
            b.iter(|| m.jdifference(black_box(&x), black_box(&y), Arg::First, j.as_mut()))
        });
        g.finish();
    }
}

/// `ℓ = Σ_i (x_i - i/10)² sin(x_{i+1}) + |u|⁴` on SE(3) x R^6 with 6 controls.
struct NonlinearCost;

impl AutoCostFn for NonlinearCost {
    fn nx(&self) -> usize {
        13
    }
    fn nu(&self) -> usize {
        6
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D]) -> D {
        let mut l = D::from(0.0);
        for i in 0..x.len() - 1 {
            let e = x[i] - 0.1 * i as f64;
            l += e * e * x[i + 1].sin();
        }
        let uu = u.iter().fold(D::from(0.0), |a, &ui| a + ui * ui);
        l + uu * uu
    }
}

/// `y = x ⊕ dt (u, u × p)` on SE(3).
struct Step;

impl AutoDynamicsFn for Step {
    fn nx(&self) -> usize {
        7
    }
    fn nu(&self) -> usize {
        3
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], y: &mut [D]) {
        let v = [
            u[0] * 0.1,
            u[1] * 0.1,
            u[2] * 0.1,
            (u[1] * x[2] - u[2] * x[1]) * 0.1,
            (u[2] * x[0] - u[0] * x[2]) * 0.1,
            (u[0] * x[1] - u[1] * x[0]) * 0.1,
        ];
        D::integrate(&SE3, x, &v, y);
    }
}

fn autodiff(c: &mut Criterion) {
    let space: Arc<dyn Manifold> = Arc::new(CartesianProduct::pair(Arc::new(SE3), Arc::new(VectorSpace::new(6))));
    let cost = AutoDiff::cost(space.clone(), NonlinearCost).unwrap();
    let mut x = vec![0.0; 13];
    space.random(&mut rand::rngs::SmallRng::seed_from_u64(2), &mut x);
    let u = [0.1, -0.2, 0.3, 0.4, -0.5, 0.6];
    let mut data = cost.create_data();
    let mut g = c.benchmark_group("autodiff");
    g.bench_function("cost (ndx 12, nu 6) gradient + Hessian", |b| {
        b.iter(|| cost.derivatives(black_box(&x), black_box(&u), &mut data))
    });
    let se3: Arc<dyn Manifold> = Arc::new(SE3);
    let dynamics = AutoDiff::explicit_dynamics(se3.clone(), se3, Step).unwrap();
    let x = SE3::exp(&[0.1, 0.2, 0.3, 0.4, -0.5, 0.6]);
    let u = [0.3, -0.1, 0.2];
    let lambda = [1.0, 0.5, -0.5, 0.2, 0.1, -1.0];
    let mut data = dynamics.create_data();
    dynamics.forward(&x, &u, &mut data);
    g.bench_function("SE3 dynamics (nu 3) Jacobians", |b| {
        b.iter(|| dynamics.jacobians(black_box(&x), black_box(&u), &mut data))
    });
    g.bench_function("SE3 dynamics (nu 3) vector-Hessian product", |b| {
        b.iter(|| dynamics.vhp(black_box(&x), black_box(&u), black_box(&lambda), &mut data))
    });
    g.finish();
}

criterion_group!(benches, spaces, autodiff);
criterion_main!(benches);

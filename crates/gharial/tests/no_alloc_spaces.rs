//! The group operations, Jacobians and the automatic-differentiation adapters do not
//! allocate after setup (`create_data`), counted with a global allocator.

use std::sync::Arc;

use faer::Mat;
use gharial::autodiff::{AutoCostFn, AutoDiff, AutoDynamicsFn, AutoStageFn, ManifoldScalar};
use gharial::costs::Cost;
use gharial::dynamics::ExplicitDynamics;
use gharial::functions::StageFunction;
use gharial::spaces::{Arg, CartesianProduct, Manifold, SE2, SE3, SO2, SO3, TangentBundle, VectorSpace};
use rand::SeedableRng;

#[path = "support/counting_alloc.rs"]
mod counting_alloc;

#[global_allocator]
static GLOBAL: counting_alloc::Counting = counting_alloc::Counting;

use counting_alloc::local_allocations_during as allocations;

#[test]
fn space_operations_do_not_allocate() {
    // The counter sees allocations.
    assert!(allocations(|| drop(std::hint::black_box(vec![0u8; 16]))) >= 1);
    let spaces: Vec<Arc<dyn Manifold>> = vec![
        Arc::new(VectorSpace::new(4)),
        Arc::new(SO2),
        Arc::new(SO3),
        Arc::new(SE2),
        Arc::new(SE3),
        Arc::new(CartesianProduct::new(vec![
            Arc::new(SE3),
            Arc::new(VectorSpace::new(6)),
        ])),
        Arc::new(TangentBundle::new(Arc::new(CartesianProduct::pair(
            Arc::new(SO3),
            Arc::new(SE2),
        )))),
    ];
    for m in &spaces {
        let (nx, ndx) = (m.nx(), m.ndx());
        let (mut x, mut y, mut z) = (vec![0.0; nx], vec![0.0; nx], vec![0.0; nx]);
        let mut rng = rand::rngs::SmallRng::seed_from_u64(3);
        m.random(&mut rng, &mut x);
        let v: Vec<f64> = (0..ndx).map(|i| 0.1 * (i as f64 + 1.0)).collect();
        let mut d = vec![0.0; ndx];
        let mut j = Mat::<f64>::zeros(ndx, ndx);
        let mut t = Mat::<f64>::zeros(ndx, 5);
        let (mut tm, mut tmi) = (Mat::<f64>::zeros(nx, ndx), Mat::<f64>::zeros(ndx, nx));
        let n = allocations(|| {
            for _ in 0..10 {
                m.integrate(&x, &v, &mut y);
                m.difference(&x, &y, &mut d);
                m.interpolate(&x, &y, 0.3, &mut z);
                for arg in [Arg::First, Arg::Second] {
                    m.jintegrate(&x, &v, arg, j.as_mut());
                    m.jdifference(&x, &y, arg, j.as_mut());
                    let k = m.nonlinear_dim();
                    m.jdifference_block(&x, &y, arg, j.as_mut().submatrix_mut(0, 0, k, k));
                    m.jintegrate_transport(&x, &v, arg, t.as_mut());
                }
                m.tangent_map(&x, tm.as_mut());
                m.tangent_map_inverse(&x, tmi.as_mut());
                m.normalize(&mut z);
                assert!(m.is_valid(&z));
            }
        });
        assert_eq!(n, 0, "{m:?} allocated {n} times");
    }
}

struct Residual;

impl AutoStageFn for Residual {
    fn nx(&self) -> usize {
        7
    }
    fn nu(&self) -> usize {
        2
    }
    fn nr(&self) -> usize {
        3
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], out: &mut [D]) {
        out[0] = x[0] * x[3] + u[0].sin();
        out[1] = x[4] * x[6] - x[5] * u[1];
        out[2] = x[1].exp() * u[0] * u[1];
    }
}

struct Cost2;

impl AutoCostFn for Cost2 {
    fn nx(&self) -> usize {
        7
    }
    fn nu(&self) -> usize {
        2
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D]) -> D {
        x[0] * x[0] + x[6] * x[3] + u[0] * u[1] * x[2]
    }
}

/// `y = x ⊕ (u0, 0, 0, 0, 0, u1)` on SE(3), written with the representation.
struct Push;

impl AutoDynamicsFn for Push {
    fn nx(&self) -> usize {
        7
    }
    fn nu(&self) -> usize {
        2
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], y: &mut [D]) {
        let (s, c) = (u[1] * 0.5).sin_cos();
        let (qx, qy, qz, qw) = (x[3], x[4], x[5], x[6]);
        y[0] = x[0] + u[0] * (-(qy * qy + qz * qz) * 2.0 + 1.0);
        y[1] = x[1] + u[0] * (qx * qy + qz * qw) * 2.0;
        y[2] = x[2] + u[0] * (qx * qz - qy * qw) * 2.0;
        y[3] = qx * c + qy * s;
        y[4] = qy * c - qx * s;
        y[5] = qz * c + qw * s;
        y[6] = qw * c - qz * s;
    }
}

#[test]
fn autodiff_adapters_do_not_allocate_after_setup() {
    let space: Arc<dyn Manifold> = Arc::new(SE3);
    let x = SE3::exp(&[0.1, 0.2, 0.3, 0.4, -0.5, 0.6]);
    let u = [0.7, -0.2];

    let f = AutoDiff::stage(space.clone(), Residual).unwrap();
    let mut data = f.create_data();
    let n = allocations(|| {
        f.evaluate(&x, &u, &mut data);
        f.jacobians(&x, &u, &mut data);
        f.vhp(&x, &u, &[1.0, -2.0, 0.5], &mut data);
    });
    assert_eq!(n, 0, "stage function allocated {n} times");

    let c = AutoDiff::cost(space.clone(), Cost2).unwrap();
    let mut data = c.create_data();
    let n = allocations(|| {
        c.evaluate(&x, &u, &mut data);
        c.derivatives(&x, &u, &mut data);
    });
    assert_eq!(n, 0, "cost allocated {n} times");

    let d = AutoDiff::explicit_dynamics(space.clone(), space.clone(), Push).unwrap();
    let mut data = d.create_data();
    let n = allocations(|| {
        d.forward(&x, &u, &mut data);
        d.jacobians(&x, &u, &mut data);
        d.vhp(&x, &u, &[1.0, 0.0, -1.0, 0.5, 0.2, 0.1], &mut data);
    });
    assert_eq!(n, 0, "dynamics allocated {n} times");
}

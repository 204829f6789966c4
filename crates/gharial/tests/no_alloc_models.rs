//! The modelling layer (functions, costs, dynamics, constraint sets) does not allocate
//! after `create_data`, counted with a global allocator.

use std::sync::Arc;

use faer::Mat;
use gharial::constraints::{
    BoxConstraint, ConstraintSet, ConstraintSetProduct, EqualityConstraintSet, L1Penalty, NegativeOrthant,
    SecondOrderCone,
};
use gharial::costs::{
    ConstantCost, Cost, CostStack, LogBarrierCost, QuadraticControlCost, QuadraticCost, QuadraticResidualCost,
    QuadraticStateCost,
};
use gharial::dynamics::{
    ExplicitAsImplicit, ExplicitDynamics, ExplicitRungeKutta, ImplicitDynamics, ImplicitEuler, ImplicitMidpoint,
    LinearDiscreteDynamics, LinearOde, Ode, SemiImplicitEuler,
};
use gharial::functions::{
    ControlError, FunctionStack, LinearComposition, LinearFunction, Slice, StageFunction, StageFunctionData,
    StateError, Unary,
};
use gharial::spaces::{Manifold, VectorSpace};

#[path = "support/counting_alloc.rs"]
mod counting_alloc;

#[global_allocator]
static GLOBAL: counting_alloc::Counting = counting_alloc::Counting;

use counting_alloc::allocations;

fn vals(n: usize, s: f64) -> Vec<f64> {
    (0..n).map(|i| s * (((i * 7) % 11) as f64 / 5.0 - 1.0)).collect()
}

fn mat(r: usize, c: usize, s: f64) -> Mat<f64> {
    Mat::from_fn(r, c, |i, j| s * ((((i * 5 + j * 3) % 13) as f64) / 6.0 - 1.0))
}

/// `r(x, u) = [x_0 u_0; sin(x_1)]` with a vector-Hessian product.
struct Bilinear {
    nx: usize,
    nu: usize,
}

impl StageFunction for Bilinear {
    fn nx(&self) -> usize {
        self.nx
    }
    fn ndx(&self) -> usize {
        self.nx
    }
    fn nu(&self) -> usize {
        self.nu
    }
    fn nr(&self) -> usize {
        2
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        data.value_mut()[0] = x[0] * u[0];
        data.value_mut()[1] = x[1].sin();
    }
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        data.jx.fill(0.0);
        data.ju.fill(0.0);
        data.jx[(0, 0)] = u[0];
        data.ju[(0, 0)] = x[0];
        data.jx[(1, 1)] = x[1].cos();
    }
    fn has_vhp(&self) -> bool {
        true
    }
    fn vhp(&self, x: &[f64], _u: &[f64], lambda: &[f64], data: &mut StageFunctionData) {
        data.vhp_xx.fill(0.0);
        data.vhp_xu.fill(0.0);
        data.vhp_uu.fill(0.0);
        data.vhp_xu[(0, 0)] = lambda[0];
        data.vhp_xx[(1, 1)] = -lambda[1] * x[1].sin();
    }
}

#[test]
fn functions_and_costs_do_not_allocate() {
    assert!(allocations(|| drop(std::hint::black_box(vec![0u8; 16]))) >= 1);
    for (nx, nu) in [(3, 2), (24, 12)] {
        let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(nx));
        let (x, u, lam) = (vals(nx, 0.7), vals(nu, 0.4), vals(nx + 4, 0.9));
        let bil: Arc<dyn StageFunction> = Arc::new(Bilinear { nx, nu });
        let lin: Arc<dyn StageFunction> = Arc::new(
            LinearFunction::new(mat(nx, nx, 1.0).as_ref(), mat(nx, nu, 1.0).as_ref(), &vals(nx, 1.0)).unwrap(),
        );
        let state: Arc<dyn StageFunction> = Arc::new(Unary::new(
            Arc::new(StateError::new(space.clone(), &vals(nx, 0.2)).unwrap()),
            nu,
        ));
        let functions: Vec<Arc<dyn StageFunction>> = vec![
            bil.clone(),
            lin.clone(),
            state.clone(),
            Arc::new(ControlError::new(space.as_ref(), &vals(nu, 0.1)).unwrap()),
            Arc::new(Slice::new(lin.clone(), &[1, 0, 2]).unwrap()),
            Arc::new(LinearComposition::new(bil.clone(), mat(nx, 2, 1.0).as_ref(), &vals(nx, 1.0)).unwrap()),
            Arc::new(FunctionStack::new(vec![bil.clone(), lin.clone()]).unwrap()),
        ];
        for f in &functions {
            let mut d = f.create_data();
            let l = &lam[..f.nr()];
            let n = allocations(|| {
                f.evaluate(&x, &u, &mut d);
                f.jacobians(&x, &u, &mut d);
                f.vhp(&x, &u, l, &mut d);
            });
            assert_eq!(n, 0, "stage function with nr = {} (nx = {nx})", f.nr());
        }

        let w = mat(nx, nx, 1.0);
        let costs: Vec<Arc<dyn Cost>> = vec![
            Arc::new(
                QuadraticCost::new(w.as_ref(), mat(nx, nu, 1.0).as_ref(), mat(nu, nu, 1.0).as_ref(), &x, &u).unwrap(),
            ),
            Arc::new(QuadraticStateCost::new(space.clone(), &vals(nx, 0.3), w.as_ref(), nu).unwrap()),
            Arc::new(QuadraticStateCost::diagonal(space.clone(), &vals(nx, 0.3), &vals(nx, 1.0), nu).unwrap()),
            Arc::new(QuadraticControlCost::diagonal(space.as_ref(), &vals(nu, 0.3), &vals(nu, 1.0)).unwrap()),
            Arc::new(
                QuadraticResidualCost::new(lin.clone(), w.as_ref())
                    .unwrap()
                    .exact_hessian(true),
            ),
            Arc::new(
                QuadraticResidualCost::diagonal(bil.clone(), &[1.0, 2.0])
                    .unwrap()
                    .exact_hessian(true),
            ),
            Arc::new(LogBarrierCost::new(bil.clone(), 0.5, 1e-2).unwrap().exact_hessian(true)),
            Arc::new(ConstantCost::new(space.as_ref(), nu, 1.0).unwrap()),
        ];
        let mut stack = CostStack::new(space.as_ref(), nu);
        for (k, c) in costs.iter().enumerate() {
            stack = stack.with(format!("c{k}"), c.clone(), 0.5).unwrap();
        }
        let stack = Arc::new(stack);
        for c in costs.iter().chain([&(stack.clone() as Arc<dyn Cost>)]) {
            let mut d = c.create_data();
            let n = allocations(|| {
                c.evaluate(&x, &u, &mut d);
                c.derivatives(&x, &u, &mut d);
            });
            assert_eq!(n, 0, "cost (nx = {nx})");
        }
        assert_eq!(allocations(|| stack.set_weight("c3", 2.0).unwrap()), 0);
        let control = QuadraticControlCost::diagonal(space.as_ref(), &vals(nu, 0.3), &vals(nu, 1.0)).unwrap();
        let u_ref = vals(nu, 0.2);
        assert_eq!(allocations(|| control.set_target(&u_ref).unwrap()), 0);
        let barrier = LogBarrierCost::new(bil.clone(), 0.5, 1e-2).unwrap();
        assert_eq!(allocations(|| barrier.set_weight(0.25).unwrap()), 0);
    }
}

#[test]
fn dynamics_do_not_allocate() {
    for (nx, nu) in [(4, 2), (24, 12)] {
        let ode: Arc<dyn Ode> =
            Arc::new(LinearOde::new(mat(nx, nx, 0.3).as_ref(), mat(nx, nu, 1.0).as_ref(), &vals(nx, 1.0)).unwrap());
        let config: Arc<dyn Manifold> = Arc::new(VectorSpace::new(nx / 2));
        let explicit: Vec<Arc<dyn ExplicitDynamics>> = vec![
            Arc::new(
                LinearDiscreteDynamics::new(mat(nx, nx, 1.0).as_ref(), mat(nx, nu, 1.0).as_ref(), &vals(nx, 1.0))
                    .unwrap(),
            ),
            Arc::new(ExplicitRungeKutta::euler(ode.clone(), 0.1).unwrap()),
            Arc::new(ExplicitRungeKutta::rk2(ode.clone(), 0.1).unwrap()),
            Arc::new(ExplicitRungeKutta::rk4(ode.clone(), 0.1).unwrap()),
            Arc::new(SemiImplicitEuler::new(ode.clone(), config, 0.1).unwrap()),
        ];
        let (x, u, y) = (vals(nx, 0.7), vals(nu, 0.4), vals(nx, -0.3));
        for d in &explicit {
            let mut data = d.create_data();
            let n = allocations(|| {
                d.forward(&x, &u, &mut data);
                d.jacobians(&x, &u, &mut data);
            });
            assert_eq!(n, 0, "explicit dynamics (nx = {nx})");
        }
        let implicit: Vec<Arc<dyn ImplicitDynamics>> = vec![
            Arc::new(ImplicitEuler::new(ode.clone(), 0.1).unwrap()),
            Arc::new(ImplicitMidpoint::new(ode.clone(), 0.1).unwrap()),
            Arc::new(ExplicitAsImplicit::new(explicit[3].clone())),
        ];
        for d in &implicit {
            let mut data = d.create_data();
            let n = allocations(|| {
                d.evaluate(&x, &u, &y, &mut data);
                d.jacobians(&x, &u, &y, &mut data);
            });
            assert_eq!(n, 0, "implicit dynamics (nx = {nx})");
        }
    }
}

#[test]
fn constraint_sets_do_not_allocate() {
    let sets: Vec<(Arc<dyn ConstraintSet>, usize)> = vec![
        (Arc::new(EqualityConstraintSet), 3),
        (Arc::new(NegativeOrthant), 4),
        (Arc::new(BoxConstraint::new(&[-0.5; 4], &[0.5; 4]).unwrap()), 4),
        (Arc::new(SecondOrderCone::new(4).unwrap()), 4),
        (Arc::new(L1Penalty::new(0.5).unwrap()), 5),
    ];
    let product = ConstraintSetProduct::new(sets.clone()).unwrap();
    let all: Vec<(&dyn ConstraintSet, usize)> = sets
        .iter()
        .map(|(s, n)| (s.as_ref(), *n))
        .chain([(&product as &dyn ConstraintSet, 20)])
        .collect();
    // Moving bounds and weights between solves.
    let boxed = BoxConstraint::new(&[-0.5; 4], &[0.5; 4]).unwrap();
    let l1 = L1Penalty::new(0.5).unwrap();
    assert_eq!(
        allocations(|| {
            boxed.set_bounds(&[-1.0; 4], &[1.0; 4]).unwrap();
            l1.set_weight(0.7).unwrap();
        }),
        0
    );
    for (set, n) in all {
        for scale in [0.3, 3.0] {
            let z = vals(n, scale);
            let mut out = vec![0.0; n];
            let mut m = mat(n, 7, 1.0);
            let count = allocations(|| {
                set.project(&z, 0.1, &mut out);
                set.normal_cone_project(&z, 0.1, &mut out);
                set.apply_projection_jacobian(&z, 0.1, m.as_mut());
                set.apply_normal_cone_jacobian(&z, 0.1, m.as_mut());
                std::hint::black_box(set.penalty(&z) + set.violation(&z));
            });
            assert_eq!(count, 0, "{set:?}");
        }
    }
}

/// A rigid body on the tangent bundle of SO(3), written once for every scalar.
struct Gyro;

impl gharial::autodiff::AutoOdeFn for Gyro {
    fn nx(&self) -> usize {
        7
    }
    fn nu(&self) -> usize {
        3
    }
    fn eval<D: gharial::autodiff::ManifoldScalar>(&self, x: &[D], u: &[D], xdot: &mut [D]) {
        let i = [1.0, 2.0, 3.0];
        let w = [x[4], x[5], x[6]];
        let iw = [w[0] * i[0], w[1] * i[1], w[2] * i[2]];
        let gyro = [
            w[1] * iw[2] - w[2] * iw[1],
            w[2] * iw[0] - w[0] * iw[2],
            w[0] * iw[1] - w[1] * iw[0],
        ];
        for k in 0..3 {
            xdot[k] = w[k];
            xdot[3 + k] = (u[k] - gyro[k] + x[k] * 0.1) * (1.0 / i[k]);
        }
    }
}

#[test]
fn models_on_lie_groups_do_not_allocate() {
    use gharial::autodiff::AutoDiff;
    use gharial::spaces::{SE3, SO3, TangentBundle};
    use rand::SeedableRng;
    let mut rng = rand::rngs::SmallRng::seed_from_u64(5);
    let tso3: Arc<dyn Manifold> = Arc::new(TangentBundle::new(Arc::new(SO3)));
    let se3: Arc<dyn Manifold> = Arc::new(SE3);
    let ode: Arc<dyn Ode> = Arc::new(AutoDiff::ode(tso3.clone(), Gyro).unwrap());
    let (mut x, mut y) = (vec![0.0; 7], vec![0.0; 7]);
    tso3.random(&mut rng, &mut x);
    tso3.random(&mut rng, &mut y);
    let u = vals(3, 0.5);
    let explicit: Vec<Arc<dyn ExplicitDynamics>> = vec![
        Arc::new(ExplicitRungeKutta::rk4(ode.clone(), 0.05).unwrap()),
        Arc::new(SemiImplicitEuler::new(ode.clone(), Arc::new(SO3), 0.05).unwrap()),
    ];
    for d in &explicit {
        let mut data = d.create_data();
        let n = allocations(|| {
            d.forward(&x, &u, &mut data);
            d.jacobians(&x, &u, &mut data);
        });
        assert_eq!(n, 0, "explicit dynamics on T SO(3)");
    }
    let implicit: Vec<Arc<dyn ImplicitDynamics>> = vec![
        Arc::new(ImplicitEuler::new(ode.clone(), 0.05).unwrap()),
        Arc::new(ImplicitMidpoint::new(ode.clone(), 0.05).unwrap()),
        Arc::new(ExplicitAsImplicit::new(explicit[0].clone())),
    ];
    for d in &implicit {
        let mut data = d.create_data();
        let n = allocations(|| {
            d.evaluate(&x, &u, &y, &mut data);
            d.jacobians(&x, &u, &y, &mut data);
        });
        assert_eq!(n, 0, "implicit dynamics on T SO(3)");
    }
    let (mut p, mut p_ref) = (vec![0.0; 7], vec![0.0; 7]);
    se3.random(&mut rng, &mut p);
    se3.random(&mut rng, &mut p_ref);
    let cost = QuadraticStateCost::diagonal(se3.clone(), &p_ref, &vals(6, 1.0), 2).unwrap();
    let mut d = cost.create_data();
    let n = allocations(|| {
        cost.evaluate(&p, &[0.1, 0.2], &mut d);
        cost.derivatives(&p, &[0.1, 0.2], &mut d);
    });
    assert_eq!(n, 0, "state cost on SE(3)");
    let mut target = p_ref.clone();
    se3.integrate(&p_ref, &vals(6, 0.1), &mut target);
    assert_eq!(allocations(|| cost.set_target(&target).unwrap()), 0);
}

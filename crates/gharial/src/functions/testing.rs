//! Test models with hand-written derivatives, written a second time generically over
//! dual numbers, and the dual-number reference derivatives the tests compare with.

use std::sync::Arc;

use faer::Mat;
use num_dual::{Dual64, DualNum, HyperDual64};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use super::{StageFunction, StageFunctionData};
use crate::check::{
    DualCheckOptions, check_stage_function_dual, check_stage_function_vhp_dual, dual_stage_jacobians,
    hyper_cost_derivatives, rel_error,
};
use crate::dynamics::{Ode, OdeData};
use crate::spaces::{Manifold, VectorSpace};

/// Spaces of the manifold tests: SO(2) x R, SE(2), SE(3), the tangent bundle of SO(3).
pub(crate) fn lie_spaces() -> Vec<Arc<dyn Manifold>> {
    use crate::spaces::{CartesianProduct, SE2, SE3, SO2, SO3, TangentBundle};
    vec![
        Arc::new(CartesianProduct::pair(Arc::new(SO2), Arc::new(VectorSpace::new(1)))),
        Arc::new(SE2),
        Arc::new(SE3),
        Arc::new(TangentBundle::new(Arc::new(SO3))),
    ]
}

/// A seeded generator.
pub(crate) fn rng(seed: u64) -> SmallRng {
    SmallRng::seed_from_u64(seed)
}

/// A vector with entries uniform in `[-scale, scale]`.
pub(crate) fn random_vec(rng: &mut SmallRng, n: usize, scale: f64) -> Vec<f64> {
    (0..n).map(|_| rng.random_range(-scale..=scale)).collect()
}

/// A matrix with entries uniform in `[-scale, scale]`.
pub(crate) fn random_mat(rng: &mut SmallRng, r: usize, c: usize, scale: f64) -> Mat<f64> {
    Mat::from_fn(r, c, |_, _| rng.random_range(-scale..=scale))
}

/// `[x; u]`.
pub(crate) fn concat<T: Copy>(x: &[T], u: &[T]) -> Vec<T> {
    x.iter().chain(u).copied().collect()
}

/// Jacobian of `g` at `z` (a plain vector) by the dual-number passes of the checker.
pub(crate) fn dual_jacobian(z: &[f64], g: impl Fn(&[Dual64]) -> Vec<Dual64>) -> Mat<f64> {
    let space = VectorSpace::new(z.len());
    let nr = g(&z.iter().map(|&v| Dual64::from(v)).collect::<Vec<_>>()).len();
    dual_stage_jacobians(&space, z, &[], nr, |z, _, out| out.copy_from_slice(&g(z))).jx
}

/// Panics unless `rel_error(a, b) <= tol`.
#[track_caller]
pub(crate) fn assert_close(name: &str, a: &Mat<f64>, b: &Mat<f64>, tol: f64) {
    let e = rel_error(a, b);
    assert!(
        e <= tol,
        "{name}: relative error {e:e} > {tol:e}\nanalytic {a:?}\nreference {b:?}"
    );
}

/// The test residual `r: R³ x R² → R³`, generic over the scalar.
pub(crate) fn test_fn<D: DualNum<Primitive = f64> + Copy>(x: &[D], u: &[D]) -> Vec<D> {
    let e = (x[2] * 0.3).exp();
    vec![
        x[0].sin() * u[0] + x[1],
        x[1] * x[1] + x[0] * u[1] - x[2],
        e * u[0].cos() + x[0] * x[1] * u[1],
    ]
}

/// [`test_fn`] as a stage function with hand-written Jacobians and vector-Hessian
/// products.
pub(crate) struct TestFunction;

impl TestFunction {
    /// The Hessians of the three outputs in the variables `(x0, x1, x2, u0, u1)`.
    fn hessians(x: &[f64], u: &[f64]) -> [Mat<f64>; 3] {
        let mut h = [Mat::zeros(5, 5), Mat::zeros(5, 5), Mat::zeros(5, 5)];
        let mut set = |k: usize, i: usize, j: usize, v: f64| {
            h[k][(i, j)] = v;
            h[k][(j, i)] = v;
        };
        set(0, 0, 0, -x[0].sin() * u[0]);
        set(0, 0, 3, x[0].cos());
        set(1, 1, 1, 2.0);
        set(1, 0, 4, 1.0);
        let e = (0.3 * x[2]).exp();
        set(2, 2, 2, 0.09 * e * u[0].cos());
        set(2, 2, 3, -0.3 * e * u[0].sin());
        set(2, 3, 3, -e * u[0].cos());
        set(2, 0, 1, u[1]);
        set(2, 0, 4, x[1]);
        set(2, 1, 4, x[0]);
        h
    }
}

impl StageFunction for TestFunction {
    fn nx(&self) -> usize {
        3
    }
    fn ndx(&self) -> usize {
        3
    }
    fn nu(&self) -> usize {
        2
    }
    fn nr(&self) -> usize {
        3
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        data.value_mut().copy_from_slice(&test_fn(x, u));
    }
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let e = (0.3 * x[2]).exp();
        let jx = [
            [x[0].cos() * u[0], 1.0, 0.0],
            [u[1], 2.0 * x[1], -1.0],
            [x[1] * u[1], x[0] * u[1], 0.3 * e * u[0].cos()],
        ];
        let ju = [[x[0].sin(), 0.0], [0.0, x[0]], [-e * u[0].sin(), x[0] * x[1]]];
        for i in 0..3 {
            for j in 0..3 {
                data.jx[(i, j)] = jx[i][j];
            }
            for j in 0..2 {
                data.ju[(i, j)] = ju[i][j];
            }
        }
    }
    fn has_vhp(&self) -> bool {
        true
    }
    fn vhp(&self, x: &[f64], u: &[f64], lambda: &[f64], data: &mut StageFunctionData) {
        let h = Self::hessians(x, u);
        let s = Mat::from_fn(5, 5, |i, j| (0..3).map(|k| lambda[k] * h[k][(i, j)]).sum::<f64>());
        data.vhp_xx.copy_from(s.as_ref().submatrix(0, 0, 3, 3));
        data.vhp_xu.copy_from(s.as_ref().submatrix(0, 3, 3, 2));
        data.vhp_uu.copy_from(s.as_ref().submatrix(3, 3, 2, 2));
    }
}

/// The test ODE on `R³` with two controls, generic over the scalar.
pub(crate) fn test_ode<D: DualNum<Primitive = f64> + Copy>(x: &[D], u: &[D]) -> Vec<D> {
    vec![x[1], -x[0].sin() - x[1] * 0.1 + u[0], x[2].cos() * u[1] + x[0] * x[1]]
}

/// [`test_ode`] with hand-written Jacobians.
pub(crate) struct TestOde {
    space: Arc<dyn Manifold>,
}

impl TestOde {
    /// The ODE on `R³`.
    pub(crate) fn new() -> Self {
        Self {
            space: Arc::new(VectorSpace::new(3)),
        }
    }
}

impl Ode for TestOde {
    fn space(&self) -> &Arc<dyn Manifold> {
        &self.space
    }
    fn nu(&self) -> usize {
        2
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        data.xdot_mut().copy_from_slice(&test_ode(x, u));
    }
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        let jx = [
            [0.0, 1.0, 0.0],
            [-x[0].cos(), -0.1, 0.0],
            [x[1], x[0], -x[2].sin() * u[1]],
        ];
        let ju = [[0.0, 0.0], [1.0, 0.0], [0.0, x[2].cos()]];
        for i in 0..3 {
            for j in 0..3 {
                data.jx[(i, j)] = jx[i][j];
            }
            for j in 0..2 {
                data.ju[(i, j)] = ju[i][j];
            }
        }
    }
}

/// Checks the value, Jacobians and vector-Hessian products of a stage function on a
/// vector space with the dual-number checker, against the same map written
/// generically (`g1`, `g2` take `z = [x; u]`).
#[track_caller]
pub(crate) fn dual_check_stage(
    f: &dyn StageFunction,
    x: &[f64],
    u: &[f64],
    lambda: &[f64],
    g1: impl Fn(&[Dual64]) -> Vec<Dual64>,
    g2: impl Fn(&[HyperDual64]) -> Vec<HyperDual64>,
    tol: f64,
) {
    let space = VectorSpace::new(x.len());
    let opts = DualCheckOptions { tol };
    let rep = check_stage_function_dual(
        f,
        &space,
        x,
        u,
        |x, u, out| out.copy_from_slice(&g1(&concat(x, u))),
        opts,
    );
    assert!(rep.passed(), "{rep:?}");
    let rep = check_stage_function_vhp_dual(
        f,
        &space,
        x,
        u,
        lambda,
        |x, u, out| out.copy_from_slice(&g2(&concat(x, u))),
        opts,
    );
    assert!(rep.passed(), "{rep:?}");
}

/// Checks the value, gradient and (if `check_hessian`) Hessian of a cost on a vector
/// space against hyper-dual derivatives of the same map written generically (`s` takes
/// `z = [x; u]`).
#[track_caller]
pub(crate) fn dual_check_cost(
    c: &dyn crate::costs::Cost,
    x: &[f64],
    u: &[f64],
    s: impl Fn(&[HyperDual64]) -> HyperDual64,
    check_hessian: bool,
    tol: f64,
) {
    let space = VectorSpace::new(x.len());
    let r = hyper_cost_derivatives(&space, x, u, |x, u| s(&concat(x, u)));
    let mut d = c.create_data();
    c.evaluate(x, u, &mut d);
    c.derivatives(x, u, &mut d);
    let col = |v: &[f64]| Mat::from_fn(v.len(), 1, |i, _| v[i]);
    assert_close("value", &col(&[d.value]), &col(&[r.value]), tol);
    assert_close("lx", &col(d.lx()), &col(&r.lx), tol);
    assert_close("lu", &col(d.lu()), &col(&r.lu), tol);
    if check_hessian {
        assert_close("lxx", &d.lxx, &r.lxx, tol);
        assert_close("lxu", &d.lxu, &r.lxu, tol);
        assert_close("luu", &d.luu, &r.luu, tol);
    }
}

/// A linear ODE on `R⁴` with a closed-form flow: two damped rotations
/// `A = diag(A_1, A_2)`, `A_k = [[-a_k, w_k], [-w_k, -a_k]]`, driven by `B u + c`.
pub(crate) struct RotationOde {
    pub(crate) ode: Arc<crate::dynamics::LinearOde>,
    blocks: [(f64, f64); 2],
}

impl RotationOde {
    pub(crate) fn new() -> Self {
        let blocks = [(0.3, 1.1), (0.05, 2.0)];
        let mut a = Mat::zeros(4, 4);
        for (k, &(ak, wk)) in blocks.iter().enumerate() {
            let o = 2 * k;
            a[(o, o)] = -ak;
            a[(o, o + 1)] = wk;
            a[(o + 1, o)] = -wk;
            a[(o + 1, o + 1)] = -ak;
        }
        let b = Mat::from_fn(4, 2, |i, j| ((i + 2 * j) % 3) as f64 - 1.0);
        let c = [0.2, -0.1, 0.0, 0.4];
        let ode = crate::dynamics::LinearOde::new(a.as_ref(), b.as_ref(), &c).unwrap();
        Self {
            ode: Arc::new(ode),
            blocks,
        }
    }

    /// `x(t) = e^{At} x0 + A⁻¹ (e^{At} - I) g` with `g = B u + c`, block by block.
    pub(crate) fn exact(&self, x0: &[f64], u: &[f64], t: f64) -> Vec<f64> {
        let (b, c) = (self.ode.b(), self.ode.c());
        let g: Vec<f64> = (0..4)
            .map(|i| c[i] + (0..u.len()).map(|j| b[(i, j)] * u[j]).sum::<f64>())
            .collect();
        let mut out = vec![0.0; 4];
        for (k, &(a, w)) in self.blocks.iter().enumerate() {
            let o = 2 * k;
            let e = (-a * t).exp();
            let (s, co) = (w * t).sin_cos();
            let exp = [[e * co, e * s], [-e * s, e * co]];
            let n = a * a + w * w;
            let inv = [[-a / n, -w / n], [w / n, -a / n]];
            // (e^{At} - I) g, then A⁻¹ of it.
            let mut eg = [0.0; 2];
            for i in 0..2 {
                eg[i] = exp[i][0] * g[o] + exp[i][1] * g[o + 1] - g[o + i];
            }
            for i in 0..2 {
                out[o + i] = exp[i][0] * x0[o] + exp[i][1] * x0[o + 1] + inv[i][0] * eg[0] + inv[i][1] * eg[1];
            }
        }
        out
    }
}

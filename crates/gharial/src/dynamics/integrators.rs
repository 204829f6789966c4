//! Explicit integrators turning an [`Ode`] into discrete [`ExplicitDynamics`]:
//! Euler, RK2 (midpoint), RK4 ([`ExplicitRungeKutta`]) and semi-implicit Euler
//! ([`SemiImplicitEuler`]).
//!
//! # Conventions on manifolds
//! An [`Ode`] returns `ẋ = f(x, u)` as the coordinates of a tangent vector *at `x`*, in
//! the basis used by `integrate`: the exact flow satisfies
//! `x(t + h) = x(t) ⊕ (h f(x(t), u) + O(h²))`. On a Lie group with the right (local)
//! perturbation `x ⊕ v = x · exp(v)` this is the body (right-trivialised) velocity; on a
//! vector space, the usual derivative. The ODE's Jacobian `f_x` ([`OdeData::jx`]) is the
//! derivative of these coordinates along tangent perturbations `x ⊕ δ` (what
//! `check_ode` checks).
//!
//! # Runge-Kutta schemes
//! Each stage point moves from `x` along the previous stage velocity:
//! ```text
//! k_1 = f(x, u)
//! k_i = f(x ⊕ w_i, u),   w_i = dt a_i k_{i-1}       (i = 2..s)
//! y   = x ⊕ v,           v   = dt Σ_i b_i k_i
//! ```
//! with Euler: `s = 1`, `b = (1)`; RK2 (explicit midpoint): `a_2 = 1/2`, `b = (0, 1)`;
//! RK4: `a = (1/2, 1/2, 1)`, `b = (1, 2, 2, 1)/6`. On vector spaces these are the
//! classical methods, of orders 1, 2 and 4. On a manifold the stage velocities are
//! combined as coordinate vectors, without the `dexp⁻¹` corrections of Runge-Kutta-
//! Munthe-Kaas methods (the [`crate::spaces::Manifold`] trait does not provide them):
//! the local error of those missing terms is `O(dt³)`, so RK4 is of order 2 on
//! non-commutative groups (e.g. SO(3), SE(3)) and keeps order 4 where the velocities
//! commute (vector spaces, SO(2)).
//!
//! Jacobians follow by the chain rule through `jintegrate` (tangent conventions):
//! ```text
//! dx_i/dx = J⊕x(x, w_i) + J⊕v(x, w_i) dt a_i dk_{i-1}/dx,   dk_i/dx = f_x(x_i) dx_i/dx
//! dx_i/du =               J⊕v(x, w_i) dt a_i dk_{i-1}/du,   dk_i/du = f_x(x_i) dx_i/du + f_u(x_i)
//! dy/dx   = J⊕x(x, v) + J⊕v(x, v) dt Σ b_i dk_i/dx,         dy/du   = J⊕v(x, v) dt Σ b_i dk_i/du
//! ```

use std::sync::Arc;

use faer::{Accum, Mat};
use rand::SeedableRng;
use rand::rngs::SmallRng;

use super::{ExplicitDynamics, ExplicitDynamicsData, Ode, OdeData};
use crate::functions::Workspace;
use crate::functions::util::{add_scaled, check_dt, copy_scaled, downcast};
use crate::linalg::{matmul, slice_mut};
use crate::spaces::{Arg, Manifold};
use crate::{Error, Result};

/// The explicit Runge-Kutta methods of [`ExplicitRungeKutta`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RkMethod {
    /// Forward Euler, order 1: `y = x ⊕ dt f(x, u)`.
    Euler,
    /// Explicit midpoint, order 2: `y = x ⊕ dt f(x ⊕ (dt/2) f(x, u), u)`.
    Rk2,
    /// Classical fourth-order Runge-Kutta.
    Rk4,
}

impl RkMethod {
    /// `(a, b)`: `a[i]` scales the increment of stage `i` (`a[0]` is unused), `b` the
    /// final combination.
    fn tableau(self) -> (&'static [f64], &'static [f64]) {
        match self {
            RkMethod::Euler => (&[0.0], &[1.0]),
            RkMethod::Rk2 => (&[0.0, 0.5], &[0.0, 1.0]),
            RkMethod::Rk4 => (&[0.0, 0.5, 0.5, 1.0], &[1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0]),
        }
    }
}

/// Explicit Runge-Kutta discretisation `y = φ(x, u)` of an ODE with time step `dt`
/// (see the module documentation for the scheme on manifolds).
#[derive(Clone)]
pub struct ExplicitRungeKutta {
    ode: Arc<dyn Ode>,
    dt: f64,
    method: RkMethod,
}

impl std::fmt::Debug for ExplicitRungeKutta {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ExplicitRungeKutta")
            .field("method", &self.method)
            .field("dt", &self.dt)
            .field("space", self.ode.space())
            .finish_non_exhaustive()
    }
}

struct RkWs {
    stages: Vec<OdeData>,
    /// Stage points `x_i = x ⊕ w_i` (index 0 unused: `x_1 = x`).
    points: Vec<Vec<f64>>,
    /// Stage increments `w_i` (index 0 unused).
    incs: Vec<Vec<f64>>,
    /// `v = dt Σ b_i k_i`.
    v: Vec<f64>,
    /// `dx_i/dx`, `dx_i/du`.
    dpx: Mat<f64>,
    dpu: Mat<f64>,
    /// `dk_i/dx`, `dk_i/du` of the last stage.
    dkx: Mat<f64>,
    dku: Mat<f64>,
    /// `Σ b_i dk_i/dx`, `Σ b_i dk_i/du`.
    sx: Mat<f64>,
    su: Mat<f64>,
    tx: Mat<f64>,
}

impl ExplicitRungeKutta {
    /// Discretises `ode` with step `dt` by `method`.
    ///
    /// # Errors
    /// If `dt` is not finite and positive.
    pub fn new(ode: Arc<dyn Ode>, dt: f64, method: RkMethod) -> Result<Self> {
        check_dt("ExplicitRungeKutta", dt)?;
        Ok(Self { ode, dt, method })
    }

    /// Forward Euler.
    ///
    /// # Errors
    /// As [`ExplicitRungeKutta::new`].
    pub fn euler(ode: Arc<dyn Ode>, dt: f64) -> Result<Self> {
        Self::new(ode, dt, RkMethod::Euler)
    }

    /// Explicit midpoint (RK2).
    ///
    /// # Errors
    /// As [`ExplicitRungeKutta::new`].
    pub fn rk2(ode: Arc<dyn Ode>, dt: f64) -> Result<Self> {
        Self::new(ode, dt, RkMethod::Rk2)
    }

    /// Classical RK4.
    ///
    /// # Errors
    /// As [`ExplicitRungeKutta::new`].
    pub fn rk4(ode: Arc<dyn Ode>, dt: f64) -> Result<Self> {
        Self::new(ode, dt, RkMethod::Rk4)
    }

    /// The time step.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// The method.
    pub fn method(&self) -> RkMethod {
        self.method
    }

    /// The ODE.
    pub fn ode(&self) -> &Arc<dyn Ode> {
        &self.ode
    }
}

impl ExplicitDynamics for ExplicitRungeKutta {
    fn space(&self) -> &Arc<dyn Manifold> {
        self.ode.space()
    }
    fn nu(&self) -> usize {
        self.ode.nu()
    }
    fn create_workspace(&self) -> Workspace {
        let s = self.method.tableau().1.len();
        let (nx, ndx, nu) = (self.space().nx(), self.space().ndx(), self.nu());
        Box::new(RkWs {
            stages: (0..s).map(|_| self.ode.create_data()).collect(),
            points: (0..s).map(|_| vec![0.0; nx]).collect(),
            incs: (0..s).map(|_| vec![0.0; ndx]).collect(),
            v: vec![0.0; ndx],
            dpx: Mat::zeros(ndx, ndx),
            dpu: Mat::zeros(ndx, nu),
            dkx: Mat::zeros(ndx, ndx),
            dku: Mat::zeros(ndx, nu),
            sx: Mat::zeros(ndx, ndx),
            su: Mat::zeros(ndx, nu),
            tx: Mat::zeros(ndx, ndx),
        })
    }

    fn forward(&self, x: &[f64], u: &[f64], data: &mut ExplicitDynamicsData) {
        let space = self.space().as_ref();
        let (a, b) = self.method.tableau();
        let ws: &mut RkWs = downcast(&mut data.ws);
        let dt = self.dt;
        self.ode.evaluate(x, u, &mut ws.stages[0]);
        for i in 1..b.len() {
            let (prev, rest) = ws.stages.split_at_mut(i);
            for (w, k) in ws.incs[i].iter_mut().zip(prev[i - 1].xdot()) {
                *w = dt * a[i] * k;
            }
            space.integrate(x, &ws.incs[i], &mut ws.points[i]);
            self.ode.evaluate(&ws.points[i], u, &mut rest[0]);
        }
        ws.v.fill(0.0);
        for (bi, st) in b.iter().zip(&ws.stages) {
            for (v, k) in ws.v.iter_mut().zip(st.xdot()) {
                *v += dt * bi * k;
            }
        }
        space.integrate(x, &ws.v, slice_mut(&mut data.xnext));
    }

    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut ExplicitDynamicsData) {
        let space = self.space().as_ref();
        let (a, b) = self.method.tableau();
        let ws: &mut RkWs = downcast(&mut data.ws);
        let dt = self.dt;
        // Stage 1: x_1 = x.
        self.ode.jacobians(x, u, &mut ws.stages[0]);
        ws.dkx.copy_from(&ws.stages[0].jx);
        ws.dku.copy_from(&ws.stages[0].ju);
        copy_scaled(ws.sx.as_mut(), b[0], ws.dkx.as_ref());
        copy_scaled(ws.su.as_mut(), b[0], ws.dku.as_ref());
        for i in 1..b.len() {
            let (w, p) = (&ws.incs[i], &ws.points[i]);
            // dx_i/dx and dx_i/du.
            copy_scaled(ws.tx.as_mut(), dt * a[i], ws.dkx.as_ref());
            space.jintegrate_transport(x, w, Arg::Second, ws.tx.as_mut());
            space.jintegrate(x, w, Arg::First, ws.dpx.as_mut());
            add_scaled(ws.dpx.as_mut(), 1.0, ws.tx.as_ref());
            copy_scaled(ws.dpu.as_mut(), dt * a[i], ws.dku.as_ref());
            space.jintegrate_transport(x, w, Arg::Second, ws.dpu.as_mut());
            // dk_i = f_x(x_i) dx_i (+ f_u(x_i) for u).
            let st = &mut ws.stages[i];
            self.ode.jacobians(p, u, st);
            matmul(ws.dkx.as_mut(), Accum::Replace, st.jx.as_ref(), ws.dpx.as_ref(), 1.0);
            ws.dku.copy_from(&st.ju);
            matmul(ws.dku.as_mut(), Accum::Add, st.jx.as_ref(), ws.dpu.as_ref(), 1.0);
            add_scaled(ws.sx.as_mut(), b[i], ws.dkx.as_ref());
            add_scaled(ws.su.as_mut(), b[i], ws.dku.as_ref());
        }
        // y = x ⊕ v with v = dt Σ b_i k_i.
        copy_scaled(ws.tx.as_mut(), dt, ws.sx.as_ref());
        space.jintegrate_transport(x, &ws.v, Arg::Second, ws.tx.as_mut());
        space.jintegrate(x, &ws.v, Arg::First, data.jx.as_mut());
        add_scaled(data.jx.as_mut(), 1.0, ws.tx.as_ref());
        copy_scaled(data.ju.as_mut(), dt, ws.su.as_ref());
        space.jintegrate_transport(x, &ws.v, Arg::Second, data.ju.as_mut());
    }
}

/// Semi-implicit (symplectic) Euler for second-order systems.
///
/// The ODE's state is `x = (q, v)` on `Q × R^nv`, laid out as `[q (nq); v (nv)]` with
/// tangent `[dq (nv); dv (nv)]`, where `Q` is the configuration space given at
/// construction (`nv = Q.ndx()`) and `v` is the configuration velocity in `Q`'s tangent
/// coordinates (e.g. the tangent bundle of `Q`). Only the acceleration, the last `nv`
/// entries `a(x, u)` of `ẋ`, is used; the first block of `ẋ` is assumed to be `v`.
/// The step is
/// ```text
/// v' = v + dt a(q, v, u),      q' = q ⊕ dt v'
/// ```
/// with Jacobians `dv'/d(x, u) = [0 I] + dt a_{x}`, `dt a_u` and
/// `dq'/dx = J⊕q(q, dt v') [I 0] + J⊕v(q, dt v') dt dv'/dx`, `dq'/du = J⊕v dt dv'/du`.
#[derive(Clone)]
pub struct SemiImplicitEuler {
    ode: Arc<dyn Ode>,
    config: Arc<dyn Manifold>,
    dt: f64,
}

impl std::fmt::Debug for SemiImplicitEuler {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SemiImplicitEuler")
            .field("dt", &self.dt)
            .field("configuration", &self.config)
            .finish_non_exhaustive()
    }
}

struct SieWs {
    ode: OdeData,
    /// `dt v'`.
    dq: Vec<f64>,
    /// `J⊕q(q, dt v')`.
    jq: Mat<f64>,
}

impl SemiImplicitEuler {
    /// Semi-implicit Euler with step `dt` for `ode`, whose state space must be
    /// `configuration × R^nv` as described on the type.
    ///
    /// # Errors
    /// If `dt` is not finite and positive, or the ODE's space does not have the sizes
    /// `nx = nq + nv`, `ndx = 2 nv`, or does not integrate as `(q ⊕ dq, v + dv)` (checked
    /// on a few sample points).
    pub fn new(ode: Arc<dyn Ode>, configuration: Arc<dyn Manifold>, dt: f64) -> Result<Self> {
        check_dt("SemiImplicitEuler", dt)?;
        let (space, config) = (ode.space().clone(), configuration);
        let (nq, nv) = (config.nx(), config.ndx());
        let what = format!("SemiImplicitEuler: state space {space:?} must be (q, v) in {config:?} x R^{nv}");
        crate::error::check_dim(format!("{what}; nx"), nq + nv, space.nx())?;
        crate::error::check_dim(format!("{what}; ndx"), 2 * nv, space.ndx())?;
        Self::check_product(space.as_ref(), config.as_ref())
            .map_err(|e| Error::InvalidModel(format!("{what}: {e}")))?;
        Ok(Self { ode, config, dt })
    }

    /// Checks `x ⊕ δ = (q ⊕ δq, v + δv)` on sample points.
    fn check_product(space: &dyn Manifold, config: &dyn Manifold) -> std::result::Result<(), String> {
        let (nq, nv) = (config.nx(), config.ndx());
        let mut rng = SmallRng::seed_from_u64(0x5e1e);
        let (mut x, mut y) = (vec![0.0; nq + nv], vec![0.0; nq + nv]);
        let mut yq = vec![0.0; nq];
        for trial in 0..3 {
            space.random(&mut rng, &mut x);
            let delta: Vec<f64> = (0..2 * nv)
                .map(|i| 0.3 * (((i + trial) % 5) as f64 - 2.0) / 2.0)
                .collect();
            space.integrate(&x, &delta, &mut y);
            config.integrate(&x[..nq], &delta[..nv], &mut yq);
            let err_q = (0..nq).fold(0.0_f64, |m, i| m.max((y[i] - yq[i]).abs()));
            let err_v = (0..nv).fold(0.0_f64, |m, i| m.max((y[nq + i] - x[nq + i] - delta[nv + i]).abs()));
            if err_q.max(err_v) > 1e-9 {
                return Err(format!(
                    "integrate does not act as (q ⊕ dq, v + dv) (mismatch {:e})",
                    err_q.max(err_v)
                ));
            }
        }
        Ok(())
    }

    /// The time step.
    pub fn dt(&self) -> f64 {
        self.dt
    }
}

impl ExplicitDynamics for SemiImplicitEuler {
    fn space(&self) -> &Arc<dyn Manifold> {
        self.ode.space()
    }
    fn nu(&self) -> usize {
        self.ode.nu()
    }
    fn create_workspace(&self) -> Workspace {
        let nv = self.config.ndx();
        Box::new(SieWs {
            ode: self.ode.create_data(),
            dq: vec![0.0; nv],
            // `J⊕q = I` on a vector space, set once.
            jq: Mat::identity(nv, nv),
        })
    }

    fn forward(&self, x: &[f64], u: &[f64], data: &mut ExplicitDynamicsData) {
        let (nq, nv, dt) = (self.config.nx(), self.config.ndx(), self.dt);
        let ws: &mut SieWs = downcast(&mut data.ws);
        self.ode.evaluate(x, u, &mut ws.ode);
        let acc = &ws.ode.xdot()[nv..];
        let y = slice_mut(&mut data.xnext);
        for i in 0..nv {
            let v_next = x[nq + i] + dt * acc[i];
            y[nq + i] = v_next;
            ws.dq[i] = dt * v_next;
        }
        self.config.integrate(&x[..nq], &ws.dq, &mut y[..nq]);
    }

    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut ExplicitDynamicsData) {
        let (nq, nv, dt) = (self.config.nx(), self.config.ndx(), self.dt);
        let ws: &mut SieWs = downcast(&mut data.ws);
        self.ode.acceleration_jacobians(x, u, &mut ws.ode);
        let (ax, au) = (ws.ode.jx.as_ref().subrows(nv, nv), ws.ode.ju.as_ref().subrows(nv, nv));
        let (mut jq_rows, mut jv_rows) = data.jx.as_mut().split_at_row_mut(nv);
        // dv'/dx = [0 I] + dt a_x.
        copy_scaled(jv_rows.as_mut(), dt, ax);
        for i in 0..nv {
            jv_rows[(i, nv + i)] += 1.0;
        }
        // dq'/dx = J⊕q [I 0] + J⊕v dt dv'/dx.
        copy_scaled(jq_rows.as_mut(), dt, jv_rows.as_ref());
        let q = &x[..nq];
        self.config
            .jintegrate_transport(q, &ws.dq, Arg::Second, jq_rows.as_mut());
        if !self.config.is_vector_space() {
            self.config.jintegrate(q, &ws.dq, Arg::First, ws.jq.as_mut());
        }
        add_scaled(jq_rows.submatrix_mut(0, 0, nv, nv), 1.0, ws.jq.as_ref());
        let (mut uq_rows, mut uv_rows) = data.ju.as_mut().split_at_row_mut(nv);
        copy_scaled(uv_rows.as_mut(), dt, au);
        copy_scaled(uq_rows.as_mut(), dt * dt, au);
        self.config
            .jintegrate_transport(q, &ws.dq, Arg::Second, uq_rows.as_mut());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{
        CheckOptions, DualCheckOptions, check_explicit_dynamics, check_explicit_dynamics_dual, check_ode,
    };
    use crate::dynamics::LinearOde;
    use crate::functions::testing::{RotationOde, TestOde, concat, random_vec, rng, test_ode};
    use crate::spaces::VectorSpace;
    use num_dual::{Dual64, DualNum};

    /// The classical tableaux, written out independently of [`RkMethod::tableau`].
    fn classical(method: RkMethod) -> (Vec<f64>, Vec<f64>) {
        match method {
            RkMethod::Euler => (vec![0.0], vec![1.0]),
            RkMethod::Rk2 => (vec![0.0, 0.5], vec![0.0, 1.0]),
            RkMethod::Rk4 => (
                vec![0.0, 0.5, 0.5, 1.0],
                vec![1.0 / 6.0, 2.0 / 6.0, 2.0 / 6.0, 1.0 / 6.0],
            ),
        }
    }

    /// One Runge-Kutta step of the test ODE on `R³`, generic over the scalar.
    fn rk_ref<D: DualNum<Primitive = f64> + Copy>(z: &[D], dt: f64, method: RkMethod) -> Vec<D> {
        let (x, u) = (&z[..3], &z[3..]);
        let (a, b) = classical(method);
        let mut ks = vec![test_ode(x, u)];
        for i in 1..b.len() {
            let xi: Vec<D> = (0..3).map(|j| x[j] + ks[i - 1][j] * (dt * a[i])).collect();
            ks.push(test_ode(&xi, u));
        }
        (0..3)
            .map(|j| (0..b.len()).fold(x[j], |acc, i| acc + ks[i][j] * (dt * b[i])))
            .collect()
    }

    #[test]
    fn runge_kutta_matches_finite_differences_and_dual_numbers() {
        let ode: Arc<dyn Ode> = Arc::new(TestOde::new());
        let mut g = rng(70);
        for method in [RkMethod::Euler, RkMethod::Rk2, RkMethod::Rk4] {
            let dt = 0.1;
            let d = ExplicitRungeKutta::new(ode.clone(), dt, method).unwrap();
            for _ in 0..4 {
                let (x, u) = (random_vec(&mut g, 3, 1.0), random_vec(&mut g, 2, 1.0));
                check_ode(ode.as_ref(), &x, &u, CheckOptions::default()).assert_ok();
                check_explicit_dynamics(&d, &x, &u, CheckOptions::default()).assert_ok();
                let reference = |x: &[Dual64], u: &[Dual64], y: &mut [Dual64]| {
                    y.copy_from_slice(&rk_ref(&concat(x, u), dt, method));
                };
                let rep = check_explicit_dynamics_dual(&d, &x, &u, reference, DualCheckOptions::default());
                assert!(rep.passed(), "{method:?}: {rep:?}");
            }
        }
        assert!(ExplicitRungeKutta::rk4(ode.clone(), 0.0).is_err());
        let err = ExplicitRungeKutta::euler(ode, f64::NAN).unwrap_err();
        assert!(err.to_string().contains("ExplicitRungeKutta dt"), "{err}");
    }

    /// Global error at `t = 1` of `n` steps of `step` against the exact flow.
    fn global_error(d: &dyn ExplicitDynamics, exact: &[f64], x0: &[f64], u: &[f64], n: usize) -> f64 {
        let mut data = d.create_data();
        let mut x = x0.to_vec();
        for _ in 0..n {
            d.forward(&x, u, &mut data);
            x.copy_from_slice(data.xnext());
        }
        (0..x.len()).fold(0.0_f64, |m, i| m.max((x[i] - exact[i]).abs()))
    }

    #[test]
    fn runge_kutta_orders_of_accuracy_on_a_linear_ode() {
        let rot = RotationOde::new();
        let (x0, u) = ([1.0, -0.5, 0.3, 0.8], [0.7, -0.2]);
        let exact = rot.exact(&x0, &u, 1.0);
        for (method, order) in [(RkMethod::Euler, 1), (RkMethod::Rk2, 2), (RkMethod::Rk4, 4)] {
            let errs: Vec<f64> = [10, 20, 40, 80]
                .iter()
                .map(|&n| {
                    let d = ExplicitRungeKutta::new(rot.ode.clone(), 1.0 / n as f64, method).unwrap();
                    global_error(&d, &exact, &x0, &u, n)
                })
                .collect();
            let expected = 2f64.powi(order);
            eprintln!("{method:?}: global errors at t = 1 for n = 10, 20, 40, 80: {errs:?}");
            for w in errs.windows(2) {
                let ratio = w[0] / w[1];
                assert!(
                    (ratio / expected - 1.0).abs() < 0.12,
                    "{method:?}: error ratio {ratio} (expected {expected}), errors {errs:?}"
                );
            }
        }
    }

    /// `ẋ = (v, a)` on `R² x R²` with `a = -sin(q) - 0.2 v + u q₁`, generic.
    fn pendulum<D: DualNum<Primitive = f64> + Copy>(x: &[D], u: &[D]) -> Vec<D> {
        vec![
            x[2],
            x[3],
            -x[0].sin() - x[2] * 0.2 + u[0] * x[1],
            -x[1].sin() * 2.0 - x[3] * 0.2 + u[0] * x[0].cos(),
        ]
    }

    struct Pendulum(Arc<dyn Manifold>);

    impl Ode for Pendulum {
        fn space(&self) -> &Arc<dyn Manifold> {
            &self.0
        }
        fn nu(&self) -> usize {
            1
        }
        fn evaluate(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
            data.xdot_mut().copy_from_slice(&pendulum(x, u));
        }
        fn jacobians(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
            data.jx.fill(0.0);
            data.jx[(0, 2)] = 1.0;
            data.jx[(1, 3)] = 1.0;
            data.jx[(2, 0)] = -x[0].cos();
            data.jx[(2, 1)] = u[0];
            data.jx[(2, 2)] = -0.2;
            data.jx[(3, 1)] = -2.0 * x[1].cos();
            data.jx[(3, 0)] = -u[0] * x[0].sin();
            data.jx[(3, 3)] = -0.2;
            data.ju[(0, 0)] = 0.0;
            data.ju[(1, 0)] = 0.0;
            data.ju[(2, 0)] = x[1];
            data.ju[(3, 0)] = x[0].cos();
        }
    }

    /// An ODE moved onto another space of the same tangent size (for validation tests).
    struct OnSpace(Arc<dyn Ode>, Arc<dyn Manifold>);

    impl Ode for OnSpace {
        fn space(&self) -> &Arc<dyn Manifold> {
            &self.1
        }
        fn nu(&self) -> usize {
            self.0.nu()
        }
        fn evaluate(&self, _x: &[f64], u: &[f64], data: &mut OdeData) {
            self.0.evaluate(&[0.0; 6], u, data)
        }
        fn jacobians(&self, _x: &[f64], u: &[f64], data: &mut OdeData) {
            self.0.jacobians(&[0.0; 6], u, data)
        }
    }

    fn sie_ref<D: DualNum<Primitive = f64> + Copy>(z: &[D], dt: f64) -> Vec<D> {
        let (x, u) = (&z[..4], &z[4..]);
        let f = pendulum(x, u);
        let v = [x[2] + f[2] * dt, x[3] + f[3] * dt];
        vec![x[0] + v[0] * dt, x[1] + v[1] * dt, v[0], v[1]]
    }

    #[test]
    fn semi_implicit_euler_matches_finite_differences_and_dual_numbers() {
        let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(4));
        let config: Arc<dyn Manifold> = Arc::new(VectorSpace::new(2));
        let ode: Arc<dyn Ode> = Arc::new(Pendulum(space.clone()));
        let dt = 0.05;
        let d = SemiImplicitEuler::new(ode.clone(), config.clone(), dt).unwrap();
        let mut g = rng(71);
        for _ in 0..4 {
            let (x, u) = (random_vec(&mut g, 4, 1.0), random_vec(&mut g, 1, 1.0));
            check_ode(ode.as_ref(), &x, &u, CheckOptions::default()).assert_ok();
            check_explicit_dynamics(&d, &x, &u, CheckOptions::default()).assert_ok();
            let reference =
                |x: &[Dual64], u: &[Dual64], y: &mut [Dual64]| y.copy_from_slice(&sie_ref(&concat(x, u), dt));
            let rep = check_explicit_dynamics_dual(&d, &x, &u, reference, DualCheckOptions::default());
            assert!(rep.passed(), "{rep:?}");
        }
    }

    #[test]
    fn semi_implicit_euler_is_first_order_and_validates_its_space() {
        // q̈ = -K q - C q̇ + B u + c as a first-order linear ODE on (q, v).
        let mut a = Mat::zeros(4, 4);
        a[(0, 2)] = 1.0;
        a[(1, 3)] = 1.0;
        let (k, c) = ([[2.0, 0.3], [0.3, 1.0]], [[0.1, 0.0], [0.0, 0.2]]);
        for i in 0..2 {
            for j in 0..2 {
                a[(2 + i, j)] = -k[i][j];
                a[(2 + i, 2 + j)] = -c[i][j];
            }
        }
        let b = Mat::from_fn(4, 1, |i, _| if i >= 2 { 1.0 } else { 0.0 });
        let ode: Arc<dyn Ode> = Arc::new(LinearOde::new(a.as_ref(), b.as_ref(), &[0.0; 4]).unwrap());
        let config: Arc<dyn Manifold> = Arc::new(VectorSpace::new(2));
        // Reference: RK4 with a much smaller step.
        let (x0, u) = ([1.0, -0.5, 0.2, 0.1], [0.3]);
        let fine = ExplicitRungeKutta::rk4(ode.clone(), 1.0 / 2000.0).unwrap();
        let mut exact = vec![0.0; 4];
        {
            let mut data = fine.create_data();
            let mut x = x0.to_vec();
            for _ in 0..2000 {
                fine.forward(&x, &u, &mut data);
                x.copy_from_slice(data.xnext());
            }
            exact.copy_from_slice(&x);
        }
        let errs: Vec<f64> = [20, 40, 80]
            .iter()
            .map(|&n| {
                let d = SemiImplicitEuler::new(ode.clone(), config.clone(), 1.0 / n as f64).unwrap();
                global_error(&d, &exact, &x0, &u, n)
            })
            .collect();
        eprintln!("semi-implicit Euler: global errors at t = 1 for n = 20, 40, 80: {errs:?}");
        for w in errs.windows(2) {
            assert!((w[0] / w[1] / 2.0 - 1.0).abs() < 0.12, "errors {errs:?}");
        }

        // Wrong sizes, and a space of the right sizes that is not Q x R^nv: SE(3)
        // (translation, quaternion) has nx = 7, ndx = 6 like (SO(3), R³).
        let err = SemiImplicitEuler::new(ode.clone(), Arc::new(VectorSpace::new(3)), 0.1).unwrap_err();
        assert!(err.to_string().contains("SemiImplicitEuler: state space"), "{err}");
        let se3: Arc<dyn Manifold> = Arc::new(crate::spaces::SE3);
        let bad: Arc<dyn Ode> =
            Arc::new(LinearOde::new(Mat::zeros(6, 6).as_ref(), Mat::zeros(6, 0).as_ref(), &[0.0; 6]).unwrap());
        let bad = Arc::new(OnSpace(bad, se3));
        let err = SemiImplicitEuler::new(bad, Arc::new(crate::spaces::SO3), 0.1).unwrap_err();
        assert!(err.to_string().contains("does not act as (q ⊕ dq, v + dv)"), "{err}");
        assert!(SemiImplicitEuler::new(ode, config, -1.0).is_err());
    }
}

//! Implicit integrators, written as [`ImplicitDynamics`] `f(x, u, y) = 0`:
//! implicit Euler and implicit midpoint; and [`ExplicitAsImplicit`], which presents
//! explicit dynamics in implicit form.
//!
//! The ODE velocity follows the conventions of [`super::integrators`] (coordinates of a
//! tangent vector in the basis of `integrate`). The residuals have the sign of the
//! explicit form `φ(x, u) ⊖ y`, so that `f_y ≈ -I` for every dynamics model and the
//! co-states `λ` have the same meaning whichever form a model is written in:
//! ```text
//! implicit Euler     f(x, u, y) = dt ẋ(y, u)     - (y ⊖ x)
//! implicit midpoint  f(x, u, y) = dt ẋ(x_m, u)   - (y ⊖ x),   x_m = x ⊕ ½ (y ⊖ x)
//! explicit           f(x, u, y) = φ(x, u) ⊖ y
//! ```
//! On vector spaces these are `x + dt ẋ(y) - y`, `x + dt ẋ((x + y)/2) - y` and
//! `φ(x, u) - y`. Implicit Euler is first order (local residual `O(dt²)` on exact
//! solutions) and the midpoint rule second order (`O(dt³)`), on vector spaces.
//!
//! Jacobians, with `d = y ⊖ x`, `Jd_x = jdifference(x, y, First)`,
//! `Jd_y = jdifference(x, y, Second)`:
//! ```text
//! implicit Euler     f_x = -Jd_x,                         f_y = dt ẋ_x(y) - Jd_y,                        f_u = dt ẋ_u(y)
//! implicit midpoint  f_x = dt ẋ_x(x_m) dx_m/dx - Jd_x,    f_y = dt ẋ_x(x_m) J⊕v(x, d/2) Jd_y / 2 - Jd_y, f_u = dt ẋ_u(x_m)
//!                    dx_m/dx = J⊕x(x, d/2) + J⊕v(x, d/2) Jd_x / 2
//! ```

use std::sync::Arc;

use faer::{Accum, Mat};

use super::{ExplicitDynamics, ExplicitDynamicsData, ImplicitDynamics, ImplicitDynamicsData, Ode, OdeData};
use crate::Result;
use crate::functions::Workspace;
use crate::functions::util::{add_scaled, check_dt, copy_scaled, downcast, scale};
use crate::linalg::{matmul, slice_mut};
use crate::spaces::{Arg, Manifold};

/// Implicit (backward) Euler: `f(x, u, y) = dt ẋ(y, u) - (y ⊖ x)`.
#[derive(Clone)]
pub struct ImplicitEuler {
    ode: Arc<dyn Ode>,
    dt: f64,
}

impl std::fmt::Debug for ImplicitEuler {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ImplicitEuler")
            .field("dt", &self.dt)
            .field("space", self.ode.space())
            .finish_non_exhaustive()
    }
}

struct EulerWs {
    ode: OdeData,
    d: Vec<f64>,
}

impl ImplicitEuler {
    /// Implicit Euler with step `dt`.
    ///
    /// # Errors
    /// If `dt` is not finite and positive.
    pub fn new(ode: Arc<dyn Ode>, dt: f64) -> Result<Self> {
        check_dt("ImplicitEuler", dt)?;
        Ok(Self { ode, dt })
    }
}

impl ImplicitDynamics for ImplicitEuler {
    fn space(&self) -> &Arc<dyn Manifold> {
        self.ode.space()
    }
    fn nu(&self) -> usize {
        self.ode.nu()
    }
    fn create_workspace(&self) -> Workspace {
        Box::new(EulerWs {
            ode: self.ode.create_data(),
            d: vec![0.0; self.space().ndx()],
        })
    }
    fn evaluate(&self, x: &[f64], u: &[f64], y: &[f64], data: &mut ImplicitDynamicsData) {
        let ws: &mut EulerWs = downcast(&mut data.ws);
        self.ode.evaluate(y, u, &mut ws.ode);
        self.space().difference(x, y, &mut ws.d);
        let f = slice_mut(&mut data.value);
        for (i, fi) in f.iter_mut().enumerate() {
            *fi = self.dt * ws.ode.xdot()[i] - ws.d[i];
        }
    }
    fn jacobians(&self, x: &[f64], u: &[f64], y: &[f64], data: &mut ImplicitDynamicsData) {
        let ws: &mut EulerWs = downcast(&mut data.ws);
        let space = self.space();
        self.ode.jacobians(y, u, &mut ws.ode);
        space.jdifference(x, y, Arg::First, data.jx.as_mut());
        scale(data.jx.as_mut(), -1.0);
        space.jdifference(x, y, Arg::Second, data.jy.as_mut());
        for j in 0..data.jy.ncols() {
            for i in 0..data.jy.nrows() {
                data.jy[(i, j)] = self.dt * ws.ode.jx[(i, j)] - data.jy[(i, j)];
            }
        }
        copy_scaled(data.ju.as_mut(), self.dt, ws.ode.ju.as_ref());
    }
}

/// Implicit midpoint rule: `f(x, u, y) = dt ẋ(x ⊕ ½(y ⊖ x), u) - (y ⊖ x)`.
#[derive(Clone)]
pub struct ImplicitMidpoint {
    ode: Arc<dyn Ode>,
    dt: f64,
}

impl std::fmt::Debug for ImplicitMidpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ImplicitMidpoint")
            .field("dt", &self.dt)
            .field("space", self.ode.space())
            .finish_non_exhaustive()
    }
}

struct MidpointWs {
    ode: OdeData,
    /// `d = y ⊖ x`.
    d: Vec<f64>,
    /// `d / 2`.
    half: Vec<f64>,
    /// `x_m = x ⊕ d/2`.
    xm: Vec<f64>,
    /// `jdifference(x, y, ·)`.
    jd: Mat<f64>,
    /// `dx_m/dx` or `dx_m/dy`.
    jm: Mat<f64>,
    /// `J⊕x(x, d/2)`.
    ji: Mat<f64>,
}

impl ImplicitMidpoint {
    /// Implicit midpoint with step `dt`.
    ///
    /// # Errors
    /// If `dt` is not finite and positive.
    pub fn new(ode: Arc<dyn Ode>, dt: f64) -> Result<Self> {
        check_dt("ImplicitMidpoint", dt)?;
        Ok(Self { ode, dt })
    }
}

impl ImplicitDynamics for ImplicitMidpoint {
    fn space(&self) -> &Arc<dyn Manifold> {
        self.ode.space()
    }
    fn nu(&self) -> usize {
        self.ode.nu()
    }
    fn create_workspace(&self) -> Workspace {
        let (nx, ndx) = (self.space().nx(), self.space().ndx());
        Box::new(MidpointWs {
            ode: self.ode.create_data(),
            d: vec![0.0; ndx],
            half: vec![0.0; ndx],
            xm: vec![0.0; nx],
            jd: Mat::zeros(ndx, ndx),
            jm: Mat::zeros(ndx, ndx),
            ji: Mat::zeros(ndx, ndx),
        })
    }
    fn evaluate(&self, x: &[f64], u: &[f64], y: &[f64], data: &mut ImplicitDynamicsData) {
        let ws: &mut MidpointWs = downcast(&mut data.ws);
        let space = self.space();
        space.difference(x, y, &mut ws.d);
        for (h, d) in ws.half.iter_mut().zip(&ws.d) {
            *h = 0.5 * d;
        }
        space.integrate(x, &ws.half, &mut ws.xm);
        self.ode.evaluate(&ws.xm, u, &mut ws.ode);
        let f = slice_mut(&mut data.value);
        for (i, fi) in f.iter_mut().enumerate() {
            *fi = self.dt * ws.ode.xdot()[i] - ws.d[i];
        }
    }
    fn jacobians(&self, x: &[f64], u: &[f64], y: &[f64], data: &mut ImplicitDynamicsData) {
        let ws: &mut MidpointWs = downcast(&mut data.ws);
        let (space, dt) = (self.space(), self.dt);
        self.ode.jacobians(&ws.xm, u, &mut ws.ode);
        // x: dx_m/dx = J⊕x(x, d/2) + J⊕v(x, d/2) Jd_x / 2;  f_x = dt ẋ_x dx_m/dx - Jd_x.
        space.jdifference(x, y, Arg::First, ws.jd.as_mut());
        copy_scaled(ws.jm.as_mut(), 0.5, ws.jd.as_ref());
        space.jintegrate_transport(x, &ws.half, Arg::Second, ws.jm.as_mut());
        space.jintegrate(x, &ws.half, Arg::First, ws.ji.as_mut());
        add_scaled(ws.jm.as_mut(), 1.0, ws.ji.as_ref());
        copy_scaled(data.jx.as_mut(), -1.0, ws.jd.as_ref());
        matmul(data.jx.as_mut(), Accum::Add, ws.ode.jx.as_ref(), ws.jm.as_ref(), dt);
        // y: dx_m/dy = J⊕v(x, d/2) Jd_y / 2;  f_y = dt ẋ_x dx_m/dy - Jd_y.
        space.jdifference(x, y, Arg::Second, ws.jd.as_mut());
        copy_scaled(ws.jm.as_mut(), 0.5, ws.jd.as_ref());
        space.jintegrate_transport(x, &ws.half, Arg::Second, ws.jm.as_mut());
        copy_scaled(data.jy.as_mut(), -1.0, ws.jd.as_ref());
        matmul(data.jy.as_mut(), Accum::Add, ws.ode.jx.as_ref(), ws.jm.as_ref(), dt);
        copy_scaled(data.ju.as_mut(), dt, ws.ode.ju.as_ref());
    }
}

/// Explicit dynamics in implicit form: `f(x, u, y) = φ(x, u) ⊖ y`
/// (`= difference(y, φ(x, u))`), with `f_x = Jd₂ φ_x`, `f_u = Jd₂ φ_u`, `f_y = Jd₁`
/// where `Jd₁`, `Jd₂` are `jdifference(y, φ(x, u), First / Second)`.
///
/// Useful to run implicit-dynamics code paths on explicit models (and to test them).
#[derive(Clone)]
pub struct ExplicitAsImplicit {
    dynamics: Arc<dyn ExplicitDynamics>,
}

impl std::fmt::Debug for ExplicitAsImplicit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ExplicitAsImplicit")
            .field("space", self.dynamics.space())
            .field("space_next", self.dynamics.space_next())
            .finish_non_exhaustive()
    }
}

struct AsImplicitWs {
    ed: ExplicitDynamicsData,
    jd: Mat<f64>,
}

impl ExplicitAsImplicit {
    /// Wraps explicit dynamics.
    pub fn new(dynamics: Arc<dyn ExplicitDynamics>) -> Self {
        Self { dynamics }
    }
}

impl ImplicitDynamics for ExplicitAsImplicit {
    fn space(&self) -> &Arc<dyn Manifold> {
        self.dynamics.space()
    }
    fn space_next(&self) -> &Arc<dyn Manifold> {
        self.dynamics.space_next()
    }
    fn nu(&self) -> usize {
        self.dynamics.nu()
    }
    fn create_workspace(&self) -> Workspace {
        let ndx_next = self.space_next().ndx();
        Box::new(AsImplicitWs {
            ed: self.dynamics.create_data(),
            jd: Mat::zeros(ndx_next, ndx_next),
        })
    }
    fn evaluate(&self, x: &[f64], u: &[f64], y: &[f64], data: &mut ImplicitDynamicsData) {
        let ws: &mut AsImplicitWs = downcast(&mut data.ws);
        self.dynamics.forward(x, u, &mut ws.ed);
        self.space_next()
            .difference(y, ws.ed.xnext(), slice_mut(&mut data.value));
    }
    fn jacobians(&self, x: &[f64], u: &[f64], y: &[f64], data: &mut ImplicitDynamicsData) {
        let ws: &mut AsImplicitWs = downcast(&mut data.ws);
        let sn = self.space_next();
        self.dynamics.jacobians(x, u, &mut ws.ed);
        sn.jdifference(y, ws.ed.xnext(), Arg::Second, ws.jd.as_mut());
        matmul(data.jx.as_mut(), Accum::Replace, ws.jd.as_ref(), ws.ed.jx.as_ref(), 1.0);
        matmul(data.ju.as_mut(), Accum::Replace, ws.jd.as_ref(), ws.ed.ju.as_ref(), 1.0);
        sn.jdifference(y, ws.ed.xnext(), Arg::First, data.jy.as_mut());
    }
    /// On a vector space of next states `f = φ(x, u) - y`: `φ_x`, `φ_u` and `-I`.
    fn jacobians_are_constant(&self) -> bool {
        self.dynamics.jacobians_are_constant() && self.space_next().is_vector_space()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{CheckOptions, DualCheckOptions, check_implicit_dynamics, check_implicit_dynamics_dual};
    use crate::dynamics::ExplicitRungeKutta;
    use crate::functions::testing::{RotationOde, TestOde, assert_close, concat, random_vec, rng, test_ode};
    use num_dual::{Dual64, DualNum};

    type DualResidual = fn(&[Dual64], f64) -> Vec<Dual64>;

    /// The implicit residuals on `R³`, generic: `z = [x; u; y]`.
    fn euler_ref<D: DualNum<Primitive = f64> + Copy>(z: &[D], dt: f64) -> Vec<D> {
        let (x, u, y) = (&z[..3], &z[3..5], &z[5..]);
        let f = test_ode(y, u);
        (0..3).map(|i| f[i] * dt - (y[i] - x[i])).collect()
    }

    fn midpoint_ref<D: DualNum<Primitive = f64> + Copy>(z: &[D], dt: f64) -> Vec<D> {
        let (x, u, y) = (&z[..3], &z[3..5], &z[5..]);
        let xm: Vec<D> = (0..3).map(|i| (x[i] + y[i]) * 0.5).collect();
        let f = test_ode(&xm, u);
        (0..3).map(|i| f[i] * dt - (y[i] - x[i])).collect()
    }

    #[test]
    fn implicit_integrators_match_finite_differences_and_dual_numbers() {
        let ode: Arc<dyn Ode> = Arc::new(TestOde::new());
        let dt = 0.1;
        let euler = ImplicitEuler::new(ode.clone(), dt).unwrap();
        let mid = ImplicitMidpoint::new(ode.clone(), dt).unwrap();
        let models: [(&dyn ImplicitDynamics, DualResidual); 2] = [(&euler, euler_ref), (&mid, midpoint_ref)];
        let mut g = rng(80);
        for (model, reference) in models {
            for _ in 0..4 {
                let (x, u, y) = (
                    random_vec(&mut g, 3, 1.0),
                    random_vec(&mut g, 2, 1.0),
                    random_vec(&mut g, 3, 1.0),
                );
                check_implicit_dynamics(model, &x, &u, &y, CheckOptions::default()).assert_ok();
                let rep = check_implicit_dynamics_dual(
                    model,
                    &x,
                    &u,
                    &y,
                    |x, u, y, out| out.copy_from_slice(&reference(&concat(&concat(x, u), y), dt)),
                    DualCheckOptions::default(),
                );
                assert!(rep.passed(), "{rep:?}");
            }
        }
        let err = ImplicitMidpoint::new(ode.clone(), 0.0).unwrap_err();
        assert!(err.to_string().contains("ImplicitMidpoint dt"), "{err}");
        assert!(ImplicitEuler::new(ode, f64::INFINITY).is_err());
    }

    #[test]
    fn implicit_residuals_vanish_on_exact_solutions_to_the_expected_order() {
        let rot = RotationOde::new();
        let (x0, u) = ([1.0, -0.5, 0.3, 0.8], [0.7, -0.2]);
        // Local residual on the exact flow: O(dt²) for Euler, O(dt³) for the midpoint rule.
        for (name, order) in [("euler", 2), ("midpoint", 3)] {
            let res: Vec<f64> = [0.1, 0.05, 0.025, 0.0125]
                .iter()
                .map(|&dt| {
                    let model: Box<dyn ImplicitDynamics> = if name == "euler" {
                        Box::new(ImplicitEuler::new(rot.ode.clone(), dt).unwrap())
                    } else {
                        Box::new(ImplicitMidpoint::new(rot.ode.clone(), dt).unwrap())
                    };
                    let y = rot.exact(&x0, &u, dt);
                    let mut data = model.create_data();
                    model.evaluate(&x0, &u, &y, &mut data);
                    crate::linalg::norm_inf(data.value())
                })
                .collect();
            let expected = 2f64.powi(order);
            eprintln!("{name}: residuals on the exact flow for dt = 0.1 / 2^k: {res:?}");
            for w in res.windows(2) {
                assert!(
                    (w[0] / w[1] / expected - 1.0).abs() < 0.12,
                    "{name}: residual ratio {} (expected {expected}), residuals {res:?}",
                    w[0] / w[1]
                );
            }
        }
    }

    #[test]
    fn explicit_as_implicit_is_phi_minus_y() {
        let ode: Arc<dyn Ode> = Arc::new(TestOde::new());
        let rk: Arc<dyn ExplicitDynamics> = Arc::new(ExplicitRungeKutta::rk4(ode, 0.1).unwrap());
        let imp = ExplicitAsImplicit::new(rk.clone());
        let (mut di, mut de) = (imp.create_data(), rk.create_data());
        let mut g = rng(81);
        for _ in 0..4 {
            let (x, u, y) = (
                random_vec(&mut g, 3, 1.0),
                random_vec(&mut g, 2, 1.0),
                random_vec(&mut g, 3, 1.0),
            );
            check_implicit_dynamics(&imp, &x, &u, &y, CheckOptions::default()).assert_ok();
            imp.evaluate(&x, &u, &y, &mut di);
            imp.jacobians(&x, &u, &y, &mut di);
            rk.forward(&x, &u, &mut de);
            rk.jacobians(&x, &u, &mut de);
            for i in 0..3 {
                assert!((di.value()[i] - (de.xnext()[i] - y[i])).abs() < 1e-15);
                assert_eq!(di.jy[(i, i)], -1.0);
            }
            assert_close("jx", &di.jx, &de.jx, 1e-15);
            assert_close("ju", &di.ju, &de.ju, 1e-15);
        }
    }
}

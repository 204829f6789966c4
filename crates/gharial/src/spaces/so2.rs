//! The rotation group SO(2), represented by `(cos θ, sin θ)`.
//!
//! ```text
//! x ⊕ v     = (cos θ cos v - sin θ sin v, sin θ cos v + cos θ sin v)   (angle θ + v)
//! x1 ⊖ x0   = atan2(c0 s1 - s0 c1, c0 c1 + s0 s1) ∈ (-π, π]
//! ```
//! The group is commutative, so every Jacobian is `±1`: `d(x ⊕ v)/dx = d(x ⊕ v)/dv = 1`,
//! `d(x1 ⊖ x0)/dx1 = 1`, `d(x1 ⊖ x0)/dx0 = -1`. The result of `⊕` is renormalised to
//! first order, as in Pinocchio.

use faer::MatMut;
use rand::RngCore;

use super::{Arg, Manifold, Scalar, forward_group_ops, is_unit, set_identity};

/// SO(2): planar rotations as unit complex numbers `(cos θ, sin θ)`; `nx = 2`, `ndx = 1`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SO2;

impl SO2 {
    /// The rotation group SO(2).
    pub fn new() -> Self {
        Self
    }

    /// The point of angle `theta`.
    pub fn from_angle(theta: f64) -> [f64; 2] {
        let (s, c) = theta.sin_cos();
        [c, s]
    }

    fn integrate_t<T: Scalar>(&self, x: &[T], v: &[T], out: &mut [T]) {
        debug_assert!(x.len() == 2 && v.len() == 1 && out.len() == 2);
        let (s, c) = v[0].sin_cos();
        let a = x[0] * c - x[1] * s;
        let b = x[1] * c + x[0] * s;
        let k = (-(a * a + b * b) + 3.0) * 0.5;
        out[0] = a * k;
        out[1] = b * k;
    }

    fn difference_t<T: Scalar>(&self, x0: &[T], x1: &[T], out: &mut [T]) {
        debug_assert!(x0.len() == 2 && x1.len() == 2 && out.len() == 1);
        let s = x0[0] * x1[1] - x0[1] * x1[0];
        let c = x0[0] * x1[0] + x0[1] * x1[1];
        out[0] = s.atan2(c);
    }
}

impl Manifold for SO2 {
    fn nx(&self) -> usize {
        2
    }

    fn ndx(&self) -> usize {
        1
    }

    fn neutral(&self, out: &mut [f64]) {
        out[0] = 1.0;
        out[1] = 0.0;
    }

    fn random(&self, rng: &mut dyn RngCore, out: &mut [f64]) {
        use rand::Rng;
        let theta = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
        out.copy_from_slice(&Self::from_angle(theta));
    }

    forward_group_ops!();

    fn interpolate(&self, x0: &[f64], x1: &[f64], t: f64, out: &mut [f64]) {
        let mut d = [0.0];
        self.difference_t(x0, x1, &mut d);
        d[0] *= t;
        self.integrate_t(x0, &d, out);
    }

    fn jintegrate(&self, _x: &[f64], _v: &[f64], _arg: Arg, j: MatMut<'_, f64>) {
        set_identity(j, 1.0);
    }

    fn jdifference(&self, _x0: &[f64], _x1: &[f64], arg: Arg, j: MatMut<'_, f64>) {
        set_identity(j, if arg == Arg::First { -1.0 } else { 1.0 });
    }

    fn jintegrate_transport(&self, _x: &[f64], _v: &[f64], _arg: Arg, _m: MatMut<'_, f64>) {}

    fn tangent_map(&self, x: &[f64], mut j: MatMut<'_, f64>) {
        j[(0, 0)] = -x[1];
        j[(1, 0)] = x[0];
    }

    fn tangent_map_inverse(&self, x: &[f64], mut j: MatMut<'_, f64>) {
        j[(0, 0)] = -x[1];
        j[(0, 1)] = x[0];
    }

    fn normalize(&self, x: &mut [f64]) {
        let n = x[0].hypot(x[1]);
        x[0] /= n;
        x[1] /= n;
    }

    fn is_valid(&self, x: &[f64]) -> bool {
        x.len() == 2 && x.iter().all(|v| v.is_finite()) && is_unit(x[0] * x[0] + x[1] * x[1])
    }
}

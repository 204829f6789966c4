//! The rigid motions of the plane SE(2), represented by `(x, y, cos θ, sin θ)`, with
//! tangent vectors `v = (ρ_x, ρ_y, ω)` (linear velocity in the local frame, angular
//! velocity), as Pinocchio's planar joint.
//!
//! With `J = [[0, -1], [1, 0]]`, `a = sin ω / ω`, `b = (1 - cos ω) / ω`, `h = ω / 2`:
//! ```text
//! exp(ρ, ω)   = (R(ω), V(ω) ρ),   V(ω) = a I + b J
//! log(R, t)   = (V(ω)⁻¹ t, ω),    ω = atan2(R₁₀, R₀₀),   V⁻¹ = h cot(h) I - h J
//! (R, t) ⊕ v  = (R R(ω), t + R V(ω) ρ)
//! J_r(v)      = [[R(ω)ᵀ V(ω), R(ω)ᵀ (a' ρ + b' J ρ)], [0, 1]]
//! Ad(R, t)⁻¹  = [[Rᵀ, J Rᵀ t], [0, 1]]
//! ```
//! (`a'`, `b'` the derivatives in `ω`; `R(ω)ᵀ V(ω) = V(-ω)`.) `J_r` follows from
//! `exp(v + δ) = exp(v) exp(J_r δ)` to first order; its inverse is block triangular.
//! The coefficients use their Taylor series for small `ω`.

use faer::MatMut;
use rand::RngCore;

use super::lie::{self, arr};
use super::{Arg, Manifold, Scalar, forward_group_ops, is_unit, transport, write_dense};

/// SE(2): planar rigid motions `(x, y, cos θ, sin θ)`; `nx = 4`, `ndx = 3`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SE2;

type M3 = [[f64; 3]; 3];

impl SE2 {
    /// The group SE(2).
    pub fn new() -> Self {
        Self
    }

    /// The point with translation `(x, y)` and angle `theta`.
    pub fn from_pose(x: f64, y: f64, theta: f64) -> [f64; 4] {
        let (s, c) = theta.sin_cos();
        [x, y, c, s]
    }

    fn integrate_t<T: Scalar>(&self, x: &[T], v: &[T], out: &mut [T]) {
        debug_assert!(x.len() == 4 && v.len() == 3 && out.len() == 4);
        let w = v[2];
        let (a, alpha, cw, sw) = lie::sinc_alpha(w);
        let b = w * alpha;
        let (tx, ty) = (v[0] * a - v[1] * b, v[0] * b + v[1] * a);
        let (c, s) = (x[2], x[3]);
        out[0] = x[0] + c * tx - s * ty;
        out[1] = x[1] + s * tx + c * ty;
        let (rc, rs) = (c * cw - s * sw, s * cw + c * sw);
        let k = (-(rc * rc + rs * rs) + 3.0) * 0.5;
        out[2] = rc * k;
        out[3] = rs * k;
    }

    fn difference_t<T: Scalar>(&self, x0: &[T], x1: &[T], out: &mut [T]) {
        debug_assert!(x0.len() == 4 && x1.len() == 4 && out.len() == 3);
        let (c0, s0) = (x0[2], x0[3]);
        let (dx, dy) = (x1[0] - x0[0], x1[1] - x0[1]);
        let (tx, ty) = (c0 * dx + s0 * dy, c0 * dy - s0 * dx);
        let w = (c0 * x1[3] - s0 * x1[2]).atan2(c0 * x1[2] + s0 * x1[3]);
        let hc = lie::half_cot(w * w);
        let h = w * 0.5;
        out[0] = hc * tx + h * ty;
        out[1] = hc * ty - h * tx;
        out[2] = w;
    }

    /// `J_r(v)`.
    fn jr(v: &[f64; 3]) -> M3 {
        let [px, py, w] = *v;
        let k = lie::so3_coeffs(w * w);
        let (a, b) = (k.sinc, w * k.alpha);
        let (da, db) = (w * k.d_sinc, k.alpha + w * w * k.d_alpha);
        // n = a' ρ + b' J ρ, then m = R(ω)ᵀ n.
        let (nx, ny) = (da * px - db * py, da * py + db * px);
        let (sw, cw) = w.sin_cos();
        [[a, b, cw * nx + sw * ny], [-b, a, cw * ny - sw * nx], [0.0, 0.0, 1.0]]
    }

    /// `J_r(v)⁻¹ = [[M⁻¹, -M⁻¹ m], [0, 1]]` for `J_r(v) = [[M, m], [0, 1]]`, with
    /// `M⁻¹ = V(ω)⁻ᵀ = [[h cot h, -h], [h, h cot h]]`.
    fn jr_inv(v: &[f64; 3]) -> M3 {
        let j = Self::jr(v);
        let (hc, h) = (lie::half_cot(v[2] * v[2]), 0.5 * v[2]);
        let (mx, my) = (j[0][2], j[1][2]);
        [
            [hc, -h, -(hc * mx - h * my)],
            [h, hc, -(h * mx + hc * my)],
            [0.0, 0.0, 1.0],
        ]
    }

    /// `Ad(exp(v))⁻¹ = [[R(ω)ᵀ, J V(-ω) ρ], [0, 1]]`.
    fn ad_inv_exp(v: &[f64; 3]) -> M3 {
        let [px, py, w] = *v;
        let k = lie::so3_coeffs(w * w);
        let (a, b) = (k.sinc, w * k.alpha);
        let (mx, my) = (a * px + b * py, a * py - b * px);
        let (sw, cw) = w.sin_cos();
        [[cw, sw, -my], [-sw, cw, mx], [0.0, 0.0, 1.0]]
    }

    fn jintegrate_m3(v: &[f64], arg: Arg) -> M3 {
        let v: [f64; 3] = arr(v);
        match arg {
            Arg::First => Self::ad_inv_exp(&v),
            Arg::Second => Self::jr(&v),
        }
    }

    fn jdifference_m3(x0: &[f64], x1: &[f64], arg: Arg) -> M3 {
        let mut d = [0.0; 3];
        Self.difference_t(x0, x1, &mut d);
        match arg {
            Arg::Second => Self::jr_inv(&d),
            Arg::First => Self::jr_inv(&d.map(|v| -v)).map(|row| row.map(|v| -v)),
        }
    }
}

impl Manifold for SE2 {
    fn nx(&self) -> usize {
        4
    }

    fn ndx(&self) -> usize {
        3
    }

    fn neutral(&self, out: &mut [f64]) {
        out.copy_from_slice(&[0.0, 0.0, 1.0, 0.0]);
    }

    fn random(&self, rng: &mut dyn RngCore, out: &mut [f64]) {
        use rand::Rng;
        let x = rng.random_range(-1.0..=1.0);
        let y = rng.random_range(-1.0..=1.0);
        let theta = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
        out.copy_from_slice(&Self::from_pose(x, y, theta));
    }

    forward_group_ops!();

    fn interpolate(&self, x0: &[f64], x1: &[f64], t: f64, out: &mut [f64]) {
        let mut d = [0.0; 3];
        self.difference_t(x0, x1, &mut d);
        self.integrate_t(x0, &d.map(|v| t * v), out);
    }

    fn jintegrate(&self, _x: &[f64], v: &[f64], arg: Arg, j: MatMut<'_, f64>) {
        write_dense(&Self::jintegrate_m3(v, arg), j);
    }

    fn jdifference(&self, x0: &[f64], x1: &[f64], arg: Arg, j: MatMut<'_, f64>) {
        write_dense(&Self::jdifference_m3(x0, x1, arg), j);
    }

    fn jintegrate_transport(&self, _x: &[f64], v: &[f64], arg: Arg, m: MatMut<'_, f64>) {
        transport(&Self::jintegrate_m3(v, arg), m);
    }

    fn tangent_map(&self, x: &[f64], mut j: MatMut<'_, f64>) {
        let (c, s) = (x[2], x[3]);
        j.fill(0.0);
        j[(0, 0)] = c;
        j[(0, 1)] = -s;
        j[(1, 0)] = s;
        j[(1, 1)] = c;
        j[(2, 2)] = -s;
        j[(3, 2)] = c;
    }

    fn tangent_map_inverse(&self, x: &[f64], mut j: MatMut<'_, f64>) {
        let (c, s) = (x[2], x[3]);
        j.fill(0.0);
        j[(0, 0)] = c;
        j[(0, 1)] = s;
        j[(1, 0)] = -s;
        j[(1, 1)] = c;
        j[(2, 2)] = -s;
        j[(2, 3)] = c;
    }

    fn normalize(&self, x: &mut [f64]) {
        let n = x[2].hypot(x[3]);
        x[2] /= n;
        x[3] /= n;
    }

    fn is_valid(&self, x: &[f64]) -> bool {
        x.len() == 4 && x.iter().all(|v| v.is_finite()) && is_unit(x[2] * x[2] + x[3] * x[3])
    }
}

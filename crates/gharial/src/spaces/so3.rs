//! The rotation group SO(3), represented by a unit quaternion `q = (x, y, z, w)`
//! (Hamilton convention, as Eigen and Pinocchio).
//!
//! With `θ = |ω|` and `W = [ω]×`:
//! ```text
//! exp(ω)   = (sin(θ/2) ω / θ, cos(θ/2))                     x ⊕ ω = q ⊗ exp(ω)
//! log(q)   = 2 atan2(|q_v|, w) q_v / |q_v|   (q in the hemisphere w ≥ 0, θ ∈ [0, π])
//! R(ω)     = I + (sin θ / θ) W + ((1 - cos θ) / θ²) W²
//! J_r(ω)   = I - ((1 - cos θ) / θ²) W + ((θ - sin θ) / θ³) W²
//! J_r⁻¹(ω) = I + ½ W + γ W²,   γ = (1 - (θ/2) cot(θ/2)) / θ²
//! ```
//! (Sola et al., "A micro Lie theory", the SO(3) example), so that
//! `d(x ⊕ ω)/dx = R(ω)ᵀ`, `d(x ⊕ ω)/dω = J_r(ω)`, `d(x1 ⊖ x0)/dx1 = J_r⁻¹(d)` and
//! `d(x1 ⊖ x0)/dx0 = -J_r⁻¹(-d)`. Every ratio is evaluated from its Taylor series in
//! `θ²` for small angles. The result of `⊕` is put in the hemisphere of `x` and
//! renormalised to first order, as in Pinocchio. `γ` stays finite up to `θ = π`,
//! where `log` itself is discontinuous (the two rotation vectors `±π n`).

use faer::MatMut;
use rand::RngCore;

use super::lie::{self, M3, arr};
use super::{Arg, Manifold, Scalar, forward_group_ops, is_unit, transport, write_dense, write3};

/// SO(3): 3D rotations as unit quaternions `(x, y, z, w)`; `nx = 4`, `ndx = 3`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SO3;

impl SO3 {
    /// The rotation group SO(3).
    pub fn new() -> Self {
        Self
    }

    /// The quaternion of the rotation vector `omega` (`exp(omega)`).
    pub fn exp(omega: &[f64; 3]) -> [f64; 4] {
        lie::exp3(omega)
    }

    /// The rotation vector of a quaternion (`log(q)`, angle in `[0, π]`).
    pub fn log(q: &[f64; 4]) -> [f64; 3] {
        lie::log3(q)
    }

    /// The rotation matrix (row-major) of a unit quaternion.
    pub fn rotation_matrix(q: &[f64; 4]) -> [[f64; 3]; 3] {
        lie::quat_to_rot(q)
    }

    fn integrate_t<T: Scalar>(&self, x: &[T], v: &[T], out: &mut [T]) {
        debug_assert!(x.len() == 4 && v.len() == 3 && out.len() == 4);
        let q: [T; 4] = arr(x);
        let mut r = lie::qmul(&q, &lie::exp3(&arr(v)));
        lie::qfinish(&q, &mut r);
        out.copy_from_slice(&r);
    }

    fn difference_t<T: Scalar>(&self, x0: &[T], x1: &[T], out: &mut [T]) {
        debug_assert!(x0.len() == 4 && x1.len() == 4 && out.len() == 3);
        let p = lie::qmul(&lie::qconj(&arr(x0)), &arr(x1));
        out.copy_from_slice(&lie::log3(&p));
    }

    fn jintegrate_m3(v: &[f64], arg: Arg) -> M3 {
        let v: [f64; 3] = arr(v);
        let k = lie::so3_coeffs(lie::dot3(&v, &v));
        match arg {
            // R(v)ᵀ = R(-v)
            Arg::First => lie::poly_skew(&v, -k.sinc, k.alpha),
            Arg::Second => lie::poly_skew(&v, -k.alpha, k.beta),
        }
    }

    fn jdifference_m3(x0: &[f64], x1: &[f64], arg: Arg) -> M3 {
        let mut d = [0.0; 3];
        Self.difference_t(x0, x1, &mut d);
        let g = lie::gamma(lie::dot3(&d, &d));
        match arg {
            Arg::Second => lie::poly_skew(&d, 0.5, g),
            Arg::First => {
                let m = lie::poly_skew(&d, -0.5, g);
                m.map(|row| row.map(|v| -v))
            }
        }
    }
}

/// The tangent map of a unit quaternion: `d(q ⊗ exp(ω))/dω` at `ω = 0`, `4 x 3`:
/// `½ [w I + [q_v]×; -q_vᵀ]`.
pub(crate) fn quat_tangent_map(q: &[f64], j: &mut MatMut<'_, f64>, r0: usize, c0: usize) {
    let (x, y, z, w) = (q[0], q[1], q[2], q[3]);
    let m = [
        [0.5 * w, -0.5 * z, 0.5 * y],
        [0.5 * z, 0.5 * w, -0.5 * x],
        [-0.5 * y, 0.5 * x, 0.5 * w],
    ];
    write3(j, r0, c0, &m);
    j[(r0 + 3, c0)] = -0.5 * x;
    j[(r0 + 3, c0 + 1)] = -0.5 * y;
    j[(r0 + 3, c0 + 2)] = -0.5 * z;
}

/// The inverse tangent map of a unit quaternion: `d log(q⁻¹ ⊗ p)/dp` at `p = q`,
/// `3 x 4`: `2 [w I - [q_v]×, -q_v]`.
pub(crate) fn quat_tangent_map_inverse(q: &[f64], j: &mut MatMut<'_, f64>, r0: usize, c0: usize) {
    let (x, y, z, w) = (q[0], q[1], q[2], q[3]);
    let m = [
        [2.0 * w, 2.0 * z, -2.0 * y],
        [-2.0 * z, 2.0 * w, 2.0 * x],
        [2.0 * y, -2.0 * x, 2.0 * w],
    ];
    write3(j, r0, c0, &m);
    j[(r0, c0 + 3)] = -2.0 * x;
    j[(r0 + 1, c0 + 3)] = -2.0 * y;
    j[(r0 + 2, c0 + 3)] = -2.0 * z;
}

/// A uniformly distributed unit quaternion (Shoemake, "Uniform random rotations",
/// Graphics Gems III, 1992).
pub(crate) fn random_quaternion(rng: &mut dyn RngCore) -> [f64; 4] {
    use rand::Rng;
    let (u1, u2, u3): (f64, f64, f64) = (rng.random(), rng.random(), rng.random());
    let tau = 2.0 * std::f64::consts::PI;
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    let (s2, c2) = (tau * u2).sin_cos();
    let (s3, c3) = (tau * u3).sin_cos();
    [a * s2, a * c2, b * s3, b * c3]
}

/// Divides a quaternion by its norm.
pub(crate) fn normalize_quaternion(q: &mut [f64]) {
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    for v in q.iter_mut() {
        *v /= n;
    }
}

impl Manifold for SO3 {
    fn nx(&self) -> usize {
        4
    }

    fn ndx(&self) -> usize {
        3
    }

    fn neutral(&self, out: &mut [f64]) {
        out.copy_from_slice(&[0.0, 0.0, 0.0, 1.0]);
    }

    fn random(&self, rng: &mut dyn RngCore, out: &mut [f64]) {
        out.copy_from_slice(&random_quaternion(rng));
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
        quat_tangent_map(x, &mut j, 0, 0);
    }

    fn tangent_map_inverse(&self, x: &[f64], mut j: MatMut<'_, f64>) {
        quat_tangent_map_inverse(x, &mut j, 0, 0);
    }

    fn normalize(&self, x: &mut [f64]) {
        normalize_quaternion(x);
    }

    fn is_valid(&self, x: &[f64]) -> bool {
        x.len() == 4 && x.iter().all(|v| v.is_finite()) && is_unit(x.iter().map(|v| v * v).sum())
    }
}

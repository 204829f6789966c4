//! The rigid motions of space SE(3), represented by `(p, q)`: translation `p` and unit
//! quaternion `q = (x, y, z, w)`, as Pinocchio's free-flyer joint. Tangent vectors are
//! `v = (ρ, ω)`: linear then angular velocity, both in the local frame.
//!
//! With `θ = |ω|`, `W = [ω]×`, `α = (1 - cos θ) / θ²`, `β = (θ - sin θ) / θ³` and
//! `γ = (1 - (θ/2) cot(θ/2)) / θ²`:
//! ```text
//! exp(ρ, ω)   = (V(ω) ρ, exp(ω)),    V(ω) = J_l(ω) = I + α W + β W²
//! log(p, q)   = (V(ω)⁻¹ p, ω),       ω = log(q),   V⁻¹ = I - ½ W + γ W²
//! (p, q) ⊕ v  = (p + R(q) V(ω) ρ, q ⊗ exp(ω))
//! J_r(ρ, ω)   = [[J_r(ω), R(ω)ᵀ D(ρ, ω)], [0, J_r(ω)]],   D = ∂(V(ω) ρ)/∂ω
//! Ad(R, p)⁻¹  = [[Rᵀ, -Rᵀ [p]×], [0, Rᵀ]]
//! ```
//! `J_r` follows from `exp(v + δ) = exp(v) exp(J_r δ)` to first order (translation
//! `V(ω + δω)(ρ + δρ)`, rotation `R(ω) exp(J_r(ω) δω)`). It is equivalent to the
//! closed form of Sola et al. ("A micro Lie theory", appendix on SE(3)) but needs only
//! the derivatives of `α` and `β`:
//! `D = -α [ρ]× + (α'/θ) (ω×ρ) ωᵀ + β ((ω·ρ) I + ω ρᵀ - 2 ρ ωᵀ) + (β'/θ) (ω×(ω×ρ)) ωᵀ`.
//! `J_r⁻¹` is block triangular: `[[J_r(ω)⁻¹, -J_r(ω)⁻¹ Rᵀ D J_r(ω)⁻¹], [0, J_r(ω)⁻¹]]`.
//! The quaternion of `⊕` is put in the hemisphere of `q` and renormalised to first
//! order, as in Pinocchio.

use faer::MatMut;
use rand::RngCore;

use super::lie::{self, M3, arr};
use super::so3::{normalize_quaternion, quat_tangent_map, quat_tangent_map_inverse, random_quaternion};
use super::{Arg, Manifold, Scalar, forward_group_ops, is_unit, transport, write_dense, write3};

/// SE(3): rigid motions `(p, q)` with `q = (x, y, z, w)`; `nx = 7`, `ndx = 6`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SE3;

type M6 = [[f64; 6]; 6];

fn blocks(a: &M3, b: &M3, d: &M3) -> M6 {
    let mut m = [[0.0; 6]; 6];
    for i in 0..3 {
        for k in 0..3 {
            m[i][k] = a[i][k];
            m[i][k + 3] = b[i][k];
            m[i + 3][k + 3] = d[i][k];
        }
    }
    m
}

impl SE3 {
    /// The group SE(3).
    pub fn new() -> Self {
        Self
    }

    /// `exp(v)` for `v = (ρ, ω)`, as `(p, q)` (`nx = 7`).
    pub fn exp(v: &[f64; 6]) -> [f64; 7] {
        let (p, q) = lie::se3_exp(&arr(&v[..3]), &arr(&v[3..]));
        [p[0], p[1], p[2], q[0], q[1], q[2], q[3]]
    }

    /// `log(x)` for `x = (p, q)`, as `(ρ, ω)`.
    pub fn log(x: &[f64; 7]) -> [f64; 6] {
        let (r, w) = lie::se3_log(&arr(&x[..3]), &arr(&x[3..]));
        [r[0], r[1], r[2], w[0], w[1], w[2]]
    }

    fn integrate_t<T: Scalar>(&self, x: &[T], v: &[T], out: &mut [T]) {
        debug_assert!(x.len() == 7 && v.len() == 6 && out.len() == 7);
        let q: [T; 4] = arr(&x[3..]);
        let (t, qv) = lie::se3_exp(&arr(&v[..3]), &arr(&v[3..]));
        let rt = lie::qrot(&q, &t);
        for i in 0..3 {
            out[i] = x[i] + rt[i];
        }
        let mut r = lie::qmul(&q, &qv);
        lie::qfinish(&q, &mut r);
        out[3..].copy_from_slice(&r);
    }

    fn difference_t<T: Scalar>(&self, x0: &[T], x1: &[T], out: &mut [T]) {
        debug_assert!(x0.len() == 7 && x1.len() == 7 && out.len() == 6);
        let q0c = lie::qconj(&arr(&x0[3..]));
        let t = lie::qrot(&q0c, &[x1[0] - x0[0], x1[1] - x0[1], x1[2] - x0[2]]);
        let q = lie::qmul(&q0c, &arr(&x1[3..]));
        let (r, w) = lie::se3_log(&t, &q);
        out[..3].copy_from_slice(&r);
        out[3..].copy_from_slice(&w);
    }

    /// `(J_r(ω), R(ω)ᵀ D(ρ, ω))`, the diagonal and upper-right blocks of `J_r(v)`.
    fn jr_blocks(v: &[f64; 6]) -> (M3, M3, lie::So3Coeffs) {
        let (rho, w): ([f64; 3], [f64; 3]) = (arr(&v[..3]), arr(&v[3..]));
        let k = lie::so3_coeffs(lie::dot3(&w, &w));
        let jr = lie::poly_skew(&w, -k.alpha, k.beta);
        let rt = lie::poly_skew(&w, -k.sinc, k.alpha);
        let q = lie::mul3(&rt, &lie::dv_dw(&rho, &w, &k));
        (jr, q, k)
    }

    fn jr(v: &[f64; 6]) -> M6 {
        let (jr, q, _) = Self::jr_blocks(v);
        blocks(&jr, &q, &jr)
    }

    fn jr_inv(v: &[f64; 6]) -> M6 {
        let (_, q, k) = Self::jr_blocks(v);
        let w: [f64; 3] = arr(&v[3..]);
        let ji = lie::poly_skew(&w, 0.5, k.gamma);
        let b = lie::mul3(&lie::mul3(&ji, &q), &ji).map(|row| row.map(|x| -x));
        blocks(&ji, &b, &ji)
    }

    /// `Ad(exp(v))⁻¹ = [[R(ω)ᵀ, -[J_r(ω) ρ]× R(ω)ᵀ], [0, R(ω)ᵀ]]` (since
    /// `R(ω)ᵀ V(ω) = J_r(ω)`).
    fn ad_inv_exp(v: &[f64; 6]) -> M6 {
        let (rho, w): ([f64; 3], [f64; 3]) = (arr(&v[..3]), arr(&v[3..]));
        let k = lie::so3_coeffs(lie::dot3(&w, &w));
        let rt = lie::poly_skew(&w, -k.sinc, k.alpha);
        let jr = lie::poly_skew(&w, -k.alpha, k.beta);
        let jrho: [f64; 3] = std::array::from_fn(|i| jr[i][0] * rho[0] + jr[i][1] * rho[1] + jr[i][2] * rho[2]);
        let b = lie::mul3(&lie::skew(&jrho), &rt).map(|row| row.map(|x| -x));
        blocks(&rt, &b, &rt)
    }

    fn jintegrate_m6(v: &[f64], arg: Arg) -> M6 {
        let v: [f64; 6] = arr(v);
        match arg {
            Arg::First => Self::ad_inv_exp(&v),
            Arg::Second => Self::jr(&v),
        }
    }

    fn jdifference_m6(x0: &[f64], x1: &[f64], arg: Arg) -> M6 {
        let mut d = [0.0; 6];
        Self.difference_t(x0, x1, &mut d);
        match arg {
            Arg::Second => Self::jr_inv(&d),
            Arg::First => Self::jr_inv(&d.map(|v| -v)).map(|row| row.map(|v| -v)),
        }
    }
}

impl Manifold for SE3 {
    fn nx(&self) -> usize {
        7
    }

    fn ndx(&self) -> usize {
        6
    }

    fn neutral(&self, out: &mut [f64]) {
        out.copy_from_slice(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
    }

    fn random(&self, rng: &mut dyn RngCore, out: &mut [f64]) {
        use rand::Rng;
        for o in out[..3].iter_mut() {
            *o = rng.random_range(-1.0..=1.0);
        }
        out[3..].copy_from_slice(&random_quaternion(rng));
    }

    forward_group_ops!();

    fn interpolate(&self, x0: &[f64], x1: &[f64], t: f64, out: &mut [f64]) {
        let mut d = [0.0; 6];
        self.difference_t(x0, x1, &mut d);
        self.integrate_t(x0, &d.map(|v| t * v), out);
    }

    fn jintegrate(&self, _x: &[f64], v: &[f64], arg: Arg, j: MatMut<'_, f64>) {
        write_dense(&Self::jintegrate_m6(v, arg), j);
    }

    fn jdifference(&self, x0: &[f64], x1: &[f64], arg: Arg, j: MatMut<'_, f64>) {
        write_dense(&Self::jdifference_m6(x0, x1, arg), j);
    }

    fn jintegrate_transport(&self, _x: &[f64], v: &[f64], arg: Arg, m: MatMut<'_, f64>) {
        transport(&Self::jintegrate_m6(v, arg), m);
    }

    fn tangent_map(&self, x: &[f64], mut j: MatMut<'_, f64>) {
        j.fill(0.0);
        write3(&mut j, 0, 0, &lie::quat_to_rot(&arr(&x[3..])));
        quat_tangent_map(&x[3..], &mut j, 3, 3);
    }

    fn tangent_map_inverse(&self, x: &[f64], mut j: MatMut<'_, f64>) {
        j.fill(0.0);
        write3(&mut j, 0, 0, &lie::transpose3(&lie::quat_to_rot(&arr(&x[3..]))));
        quat_tangent_map_inverse(&x[3..], &mut j, 3, 3);
    }

    fn normalize(&self, x: &mut [f64]) {
        normalize_quaternion(&mut x[3..]);
    }

    fn is_valid(&self, x: &[f64]) -> bool {
        x.len() == 7 && x.iter().all(|v| v.is_finite()) && is_unit(x[3..].iter().map(|v| v * v).sum())
    }
}

//! Math shared by the Lie groups: quaternions, the SO(3) and SE(3) exponential and
//! logarithm written once for every [`Scalar`], and the `f64` closed forms of their
//! Jacobians.
//!
//! Every coefficient that is a ratio of vanishing quantities at `θ = 0` is evaluated
//! from its Taylor series in `x = θ²` when `θ² < SMALL_SQ`, and from its closed form
//! otherwise. The series are in `θ²` (not `θ`), so they are smooth functions of the
//! rotation vector: dual numbers differentiate through them exactly, also at `θ = 0`
//! where `θ = sqrt(θ²)` itself is not differentiable. With six terms and `θ² < 1e-2`
//! the truncation error is below `1e-20`; above the threshold the closed forms lose at
//! most `~1e-16 / θ²` relative accuracy to cancellation, and every such coefficient
//! multiplies a term of order `θ²` or higher, so Jacobian entries stay accurate to a
//! few `1e-16`.

use super::Scalar;

/// `θ²` below which the Taylor series are used.
pub(crate) const SMALL_SQ: f64 = 1e-2;

/// Series coefficients, in powers of `x = θ²`.
mod series {
    /// `sin θ / θ`.
    pub const SINC: [f64; 6] = [
        1.0,
        -1.0 / 6.0,
        1.0 / 120.0,
        -1.0 / 5040.0,
        1.0 / 362880.0,
        -1.0 / 39916800.0,
    ];
    /// `(1 - cos θ) / θ²`.
    pub const ALPHA: [f64; 6] = [
        1.0 / 2.0,
        -1.0 / 24.0,
        1.0 / 720.0,
        -1.0 / 40320.0,
        1.0 / 3628800.0,
        -1.0 / 479001600.0,
    ];
    /// `(θ - sin θ) / θ³`.
    pub const BETA: [f64; 6] = [
        1.0 / 6.0,
        -1.0 / 120.0,
        1.0 / 5040.0,
        -1.0 / 362880.0,
        1.0 / 39916800.0,
        -1.0 / 6227020800.0,
    ];
    /// `(1 - (θ/2) cot(θ/2)) / θ² = Σ |B_2n| θ^(2n-2) / (2n)!`.
    pub const GAMMA: [f64; 6] = [
        1.0 / 12.0,
        1.0 / 720.0,
        1.0 / 30240.0,
        1.0 / 1209600.0,
        1.0 / 47900160.0,
        691.0 / 1307674368000.0,
    ];
    /// `(d/dθ sinc) / θ = (cos θ - sinc) / θ²`.
    pub const DSINC: [f64; 6] = [
        -1.0 / 3.0,
        1.0 / 30.0,
        -1.0 / 840.0,
        1.0 / 45360.0,
        -1.0 / 3991680.0,
        1.0 / 518918400.0,
    ];
    /// `(d/dθ alpha) / θ = (sinc - 2 alpha) / θ²`.
    pub const DALPHA: [f64; 6] = [
        -1.0 / 12.0,
        1.0 / 180.0,
        -1.0 / 6720.0,
        1.0 / 453600.0,
        -1.0 / 47900160.0,
        1.0 / 7264857600.0,
    ];
    /// `(d/dθ beta) / θ = (alpha - 3 beta) / θ²`.
    pub const DBETA: [f64; 6] = [
        -1.0 / 60.0,
        1.0 / 1260.0,
        -1.0 / 60480.0,
        1.0 / 4989600.0,
        -1.0 / 622702080.0,
        1.0 / 108972864000.0,
    ];
    /// `sin(θ/2) / θ`.
    pub const SINC_HALF: [f64; 6] = [
        1.0 / 2.0,
        -1.0 / 48.0,
        1.0 / 3840.0,
        -1.0 / 645120.0,
        1.0 / 185794560.0,
        -1.0 / 81749606400.0,
    ];
    /// `cos(θ/2)`.
    pub const COS_HALF: [f64; 6] = [
        1.0,
        -1.0 / 8.0,
        1.0 / 384.0,
        -1.0 / 46080.0,
        1.0 / 10321920.0,
        -1.0 / 3715891200.0,
    ];
    /// `atan(t) / t`, in powers of `t²` (used for `t² < 1e-2`).
    pub const ATAN_OVER: [f64; 9] = [
        1.0,
        -1.0 / 3.0,
        1.0 / 5.0,
        -1.0 / 7.0,
        1.0 / 9.0,
        -1.0 / 11.0,
        1.0 / 13.0,
        -1.0 / 15.0,
        1.0 / 17.0,
    ];
}

/// `Σ c_k x^k` by Horner's rule.
#[inline]
pub(crate) fn poly<T: Scalar>(x: T, c: &[f64]) -> T {
    let mut r = T::from(c[c.len() - 1]);
    for &ck in c[..c.len() - 1].iter().rev() {
        r = r * x + ck;
    }
    r
}

/// Copies the first `N` entries of a slice into an array.
#[inline]
pub(crate) fn arr<T: Copy, const N: usize>(s: &[T]) -> [T; N] {
    std::array::from_fn(|i| s[i])
}

#[inline]
pub(crate) fn dot3<T: Scalar>(a: &[T; 3], b: &[T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
pub(crate) fn cross<T: Scalar>(a: &[T; 3], b: &[T; 3]) -> [T; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Hamilton product `a ⊗ b` of quaternions stored `(x, y, z, w)`.
#[inline]
pub(crate) fn qmul<T: Scalar>(a: &[T; 4], b: &[T; 4]) -> [T; 4] {
    [
        a[3] * b[0] + b[3] * a[0] + a[1] * b[2] - a[2] * b[1],
        a[3] * b[1] + b[3] * a[1] + a[2] * b[0] - a[0] * b[2],
        a[3] * b[2] + b[3] * a[2] + a[0] * b[1] - a[1] * b[0],
        a[3] * b[3] - a[0] * b[0] - a[1] * b[1] - a[2] * b[2],
    ]
}

/// Conjugate (the inverse of a unit quaternion).
#[inline]
pub(crate) fn qconj<T: Scalar>(q: &[T; 4]) -> [T; 4] {
    [-q[0], -q[1], -q[2], q[3]]
}

/// `R(q) v` for a unit quaternion: `v + 2 w (q_v × v) + 2 q_v × (q_v × v)`.
#[inline]
pub(crate) fn qrot<T: Scalar>(q: &[T; 4], v: &[T; 3]) -> [T; 3] {
    let qv = [q[0], q[1], q[2]];
    let t = cross(&qv, v);
    let t = [t[0] * 2.0, t[1] * 2.0, t[2] * 2.0];
    let u = cross(&qv, &t);
    [
        v[0] + q[3] * t[0] + u[0],
        v[1] + q[3] * t[1] + u[1],
        v[2] + q[3] * t[2] + u[2],
    ]
}

/// Puts `q` in the hemisphere of `reference` (`q ← -q` if `q · reference < 0`), then
/// applies the first-order renormalisation `q ← q (3 - |q|²) / 2`, exact to first
/// order in the norm error and the identity on unit quaternions.
#[inline]
pub(crate) fn qfinish<T: Scalar>(reference: &[T; 4], q: &mut [T; 4]) {
    let d = reference[0] * q[0] + reference[1] * q[1] + reference[2] * q[2] + reference[3] * q[3];
    let n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    let s = (-n2 + 3.0) * 0.5;
    let s = if d.re() < 0.0 { -s } else { s };
    for qi in q.iter_mut() {
        *qi *= s;
    }
}

/// Quaternion of the rotation `exp([ω]×)`: `(sin(θ/2) ω / θ, cos(θ/2))`.
#[inline]
pub(crate) fn exp3<T: Scalar>(w: &[T; 3]) -> [T; 4] {
    let t2 = dot3(w, w);
    let (k, c) = if t2.re() < SMALL_SQ {
        (poly(t2, &series::SINC_HALF), poly(t2, &series::COS_HALF))
    } else {
        let t = t2.sqrt();
        let (s, c) = (t * 0.5).sin_cos();
        (s / t, c)
    };
    [w[0] * k, w[1] * k, w[2] * k, c]
}

/// Rotation vector of a quaternion, with angle in `[0, π]`: the quaternion is first
/// put in the hemisphere `w ≥ 0`, then `ω = 2 atan2(|q_v|, w) q_v / |q_v|`. Invariant
/// under positive scaling of `q`.
#[inline]
pub(crate) fn log3<T: Scalar>(q: &[T; 4]) -> [T; 3] {
    let q = if q[3].re() < 0.0 {
        [-q[0], -q[1], -q[2], -q[3]]
    } else {
        *q
    };
    let s2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
    let w = q[3];
    // atan2(s, w) / s = atan(t) / (t w) with t = s / w, smooth in t² near the identity.
    let k = if s2.re() < SMALL_SQ * w.re() * w.re() {
        poly(s2 / (w * w), &series::ATAN_OVER) * 2.0 / w
    } else {
        let s = s2.sqrt();
        s.atan2(w) * 2.0 / s
    };
    [q[0] * k, q[1] * k, q[2] * k]
}

/// `γ(θ²) = (1 - (θ/2) cot(θ/2)) / θ²`, the coefficient of `[ω]×²` in `J_r⁻¹(ω)` and
/// `V⁻¹(ω)`.
#[inline]
pub(crate) fn gamma<T: Scalar>(t2: T) -> T {
    if t2.re() < SMALL_SQ {
        poly(t2, &series::GAMMA)
    } else {
        let h = t2.sqrt() * 0.5;
        let (s, c) = h.sin_cos();
        (-(h * c / s) + 1.0) / t2
    }
}

/// `(θ/2) cot(θ/2) = 1 - θ² γ(θ²)`, for the SE(2) logarithm.
#[inline]
pub(crate) fn half_cot<T: Scalar>(t2: T) -> T {
    if t2.re() < SMALL_SQ {
        -(t2 * poly(t2, &series::GAMMA)) + 1.0
    } else {
        let h = t2.sqrt() * 0.5;
        let (s, c) = h.sin_cos();
        h * c / s
    }
}

/// `sin θ / θ`, `(1 - cos θ) / θ²`, `cos θ` and `sin θ` of `θ²` and `θ` (for SE(2),
/// where the angle is a coordinate and `θ` is known with its sign).
#[inline]
pub(crate) fn sinc_alpha<T: Scalar>(theta: T) -> (T, T, T, T) {
    let t2 = theta * theta;
    let (sh, ch) = (theta * 0.5).sin_cos();
    let (s, c) = (sh * ch * 2.0, -(sh * sh * 2.0) + 1.0);
    if t2.re() < SMALL_SQ {
        (poly(t2, &series::SINC), poly(t2, &series::ALPHA), c, s)
    } else {
        (s / theta, sh * sh * 2.0 / t2, c, s)
    }
}

/// SE(3) exponential `exp6(ρ, ω) = (R, t)` as (translation `t = V(ω) ρ`, quaternion of
/// `R = exp([ω]×)`), with `V(ω) = I + α [ω]× + β [ω]×²`.
#[inline]
pub(crate) fn se3_exp<T: Scalar>(rho: &[T; 3], w: &[T; 3]) -> ([T; 3], [T; 4]) {
    let t2 = dot3(w, w);
    let (k, c, alpha, beta) = if t2.re() < SMALL_SQ {
        (
            poly(t2, &series::SINC_HALF),
            poly(t2, &series::COS_HALF),
            poly(t2, &series::ALPHA),
            poly(t2, &series::BETA),
        )
    } else {
        let t = t2.sqrt();
        let (sh, ch) = (t * 0.5).sin_cos();
        let sin = sh * ch * 2.0;
        (sh / t, ch, sh * sh * 2.0 / t2, (t - sin) / (t2 * t))
    };
    let wr = cross(w, rho);
    let wwr = cross(w, &wr);
    let t = [
        rho[0] + wr[0] * alpha + wwr[0] * beta,
        rho[1] + wr[1] * alpha + wwr[1] * beta,
        rho[2] + wr[2] * alpha + wwr[2] * beta,
    ];
    (t, [w[0] * k, w[1] * k, w[2] * k, c])
}

/// SE(3) logarithm of (translation `t`, quaternion `q`): `ω = log3(q)`,
/// `ρ = V⁻¹(ω) t = t - ½ ω × t + γ ω × (ω × t)`.
#[inline]
pub(crate) fn se3_log<T: Scalar>(t: &[T; 3], q: &[T; 4]) -> ([T; 3], [T; 3]) {
    let w = log3(q);
    let g = gamma(dot3(&w, &w));
    let wt = cross(&w, t);
    let wwt = cross(&w, &wt);
    (
        [
            t[0] - wt[0] * 0.5 + wwt[0] * g,
            t[1] - wt[1] * 0.5 + wwt[1] * g,
            t[2] - wt[2] * 0.5 + wwt[2] * g,
        ],
        w,
    )
}

// ---------------------------------------------------------------------------------
// f64 closed forms for the Jacobians.

/// A 3x3 matrix, row-major.
pub(crate) type M3 = [[f64; 3]; 3];

/// The coefficients of the SO(3) Jacobians at `θ² = |ω|²`, each a smooth function of
/// `θ²`: `sinc`, `alpha`, `beta` as in [`se3_exp`], `gamma` as in [`gamma`], and the
/// derivatives `d_* = (d/dθ *) / θ`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct So3Coeffs {
    pub sinc: f64,
    pub alpha: f64,
    pub beta: f64,
    pub gamma: f64,
    pub d_sinc: f64,
    pub d_alpha: f64,
    pub d_beta: f64,
}

pub(crate) fn so3_coeffs(t2: f64) -> So3Coeffs {
    if t2 < SMALL_SQ {
        So3Coeffs {
            sinc: poly(t2, &series::SINC),
            alpha: poly(t2, &series::ALPHA),
            beta: poly(t2, &series::BETA),
            gamma: poly(t2, &series::GAMMA),
            d_sinc: poly(t2, &series::DSINC),
            d_alpha: poly(t2, &series::DALPHA),
            d_beta: poly(t2, &series::DBETA),
        }
    } else {
        let t = t2.sqrt();
        let (sh, ch) = (0.5 * t).sin_cos();
        let (s, c) = (2.0 * sh * ch, 1.0 - 2.0 * sh * sh);
        let sinc = s / t;
        let alpha = 2.0 * sh * sh / t2;
        let beta = (t - s) / (t2 * t);
        So3Coeffs {
            sinc,
            alpha,
            beta,
            gamma: (1.0 - 0.5 * t * ch / sh) / t2,
            d_sinc: (c - sinc) / t2,
            d_alpha: (sinc - 2.0 * alpha) / t2,
            d_beta: (alpha - 3.0 * beta) / t2,
        }
    }
}

pub(crate) const I3: M3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// `[v]×`, so that `[v]× u = v × u`.
#[inline]
pub(crate) fn skew(v: &[f64; 3]) -> M3 {
    [[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]]
}

#[inline]
pub(crate) fn mul3(a: &M3, b: &M3) -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j]))
}

#[inline]
pub(crate) fn transpose3(a: &M3) -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| a[j][i]))
}

/// `I + a A + b A²` for `A = [v]×`.
#[inline]
pub(crate) fn poly_skew(v: &[f64; 3], a: f64, b: f64) -> M3 {
    let s = skew(v);
    let s2 = mul3(&s, &s);
    std::array::from_fn(|i| std::array::from_fn(|j| I3[i][j] + a * s[i][j] + b * s2[i][j]))
}

/// Rotation matrix of a unit quaternion.
pub(crate) fn quat_to_rot(q: &[f64; 4]) -> M3 {
    let [x, y, z, w] = *q;
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - z * w),
            2.0 * (x * z + y * w),
        ],
        [
            2.0 * (x * y + z * w),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - x * w),
        ],
        [
            2.0 * (x * z - y * w),
            2.0 * (y * z + x * w),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// `D(ρ, ω) = ∂(V(ω) ρ)/∂ω`, with `V(ω) ρ = ρ + α ω×ρ + β ω×(ω×ρ)`:
/// `D = -α [ρ]× + d_α (ω×ρ) ωᵀ + β ((ω·ρ) I + ω ρᵀ - 2 ρ ωᵀ) + d_β (ω×(ω×ρ)) ωᵀ`.
pub(crate) fn dv_dw(rho: &[f64; 3], w: &[f64; 3], k: &So3Coeffs) -> M3 {
    let wr = cross(w, rho);
    let wwr = cross(w, &wr);
    let wdr = dot3(w, rho);
    let sr = skew(rho);
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let id = if i == j { wdr } else { 0.0 };
            -k.alpha * sr[i][j]
                + k.d_alpha * wr[i] * w[j]
                + k.beta * (id + w[i] * rho[j] - 2.0 * rho[i] * w[j])
                + k.d_beta * wwr[i] * w[j]
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The series agree with the closed forms where the closed forms are accurate
    /// (θ² = 0.05, 0.1: the next series term is below 1e-17 there).
    #[test]
    fn series_match_closed_forms() {
        for t2 in [0.05, 0.1] {
            let t: f64 = f64::sqrt(t2);
            let (s, c) = t.sin_cos();
            let sinc = s / t;
            let alpha = (1.0 - c) / t2;
            let beta = (t - s) / (t2 * t);
            let h = 0.5 * t;
            let tt = 0.1 * t;
            let expect = [
                (poly(t2, &series::SINC), sinc),
                (poly(t2, &series::ALPHA), alpha),
                (poly(t2, &series::BETA), beta),
                (poly(t2, &series::GAMMA), (1.0 - h / h.tan()) / t2),
                (poly(t2, &series::DSINC), (c - sinc) / t2),
                (poly(t2, &series::DALPHA), (sinc - 2.0 * alpha) / t2),
                (poly(t2, &series::DBETA), (alpha - 3.0 * beta) / t2),
                (poly(t2, &series::SINC_HALF), h.sin() / t),
                (poly(t2, &series::COS_HALF), h.cos()),
                (poly(tt * tt, &series::ATAN_OVER), tt.atan() / tt),
            ];
            for (k, (a, b)) in expect.iter().enumerate() {
                // The closed forms lose up to ~1e-16 / θ⁴ to cancellation here.
                assert!(
                    (a - b).abs() < 1e-11 * b.abs(),
                    "coefficient {k} at θ² = {t2}: {a} vs {b}"
                );
            }
        }
    }
}

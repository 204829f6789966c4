//! Exponential and logarithm maps of SO(3) and SE(3) and their right Jacobians.
//!
//! `exp6` is the coupled SE(3) exponential: `exp6([ρ, φ]) = (exp3(φ), V(φ) ρ)` with
//! `V(φ) = I + a(θ)[φ]× + b(θ)[φ]×²`, `a = (1 − cos θ)/θ²`, `b = (θ − sin θ)/θ³`.
//! Right Jacobians satisfy `exp(ξ + δ) ≈ exp(ξ) exp(J(ξ) δ)`.

use crate::spatial::{Mat3, Motion, Se3, Vec3, skew};
use nalgebra::{Quaternion, Rotation3, UnitQuaternion};

/// Coefficients of the SO(3)/SE(3) series, as functions of θ:
/// `a = (1 − cos θ)/θ²`, `b = (θ − sin θ)/θ³`, `da = a'(θ)/θ`, `db = b'(θ)/θ`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Coeffs {
    pub a: f64,
    pub b: f64,
    pub da: f64,
    pub db: f64,
}

pub(crate) fn coeffs(theta2: f64) -> Coeffs {
    if theta2 < 1.0 {
        // Alternating Taylor series in t = θ²; 10 terms give full double precision for θ < 1.
        let (mut a, mut b, mut da, mut db) = (0.0, 0.0, 0.0, 0.0);
        let mut p = 1.0; // (−t)^k
        let mut p_prev = 0.0; // (−t)^(k−1)
        let mut f2 = 2.0; // (2k+2)!
        let mut f3 = 6.0; // (2k+3)!
        for k in 0..10 {
            a += p / f2;
            b += p / f3;
            if k >= 1 {
                // (−1)^k 2k t^(k−1) = −2k (−t)^(k−1)
                let q = -2.0 * k as f64 * p_prev;
                da += q / f2;
                db += q / f3;
            }
            p_prev = p;
            p *= -theta2;
            let n = (2 * k) as f64;
            f2 *= (n + 3.0) * (n + 4.0);
            f3 *= (n + 4.0) * (n + 5.0);
        }
        Coeffs { a, b, da, db }
    } else {
        let t = theta2.sqrt();
        let s = t.sin();
        let omc = 2.0 * (0.5 * t).sin().powi(2);
        let tms = t - s;
        Coeffs {
            a: omc / theta2,
            b: tms / (theta2 * t),
            da: (t * s - 2.0 * omc) / (theta2 * theta2),
            db: (omc * t - 3.0 * tms) / (theta2 * theta2 * t),
        }
    }
}

/// `c(θ) = 1/θ² − (1 + cos θ)/(2 θ sin θ)`, the coefficient of `[φ]×²` in `Jlog3`.
pub(crate) fn log_coeff(theta2: f64) -> f64 {
    if theta2 < 1e-2 {
        1.0 / 12.0 + theta2 / 720.0 + theta2 * theta2 / 30240.0 + theta2 * theta2 * theta2 / 1209600.0
    } else {
        let t = theta2.sqrt();
        let (sh, ch) = (0.5 * t).sin_cos();
        1.0 / theta2 - ch / (2.0 * t * sh)
    }
}

/// Rotation matrix `exp([φ]×)`.
pub fn exp3(phi: &Vec3) -> Mat3 {
    let t2 = phi.norm_squared();
    let k = coeffs(t2);
    let sinc = if t2 < 1e-12 {
        1.0 - t2 / 6.0
    } else {
        t2.sqrt().sin() / t2.sqrt()
    };
    let w = skew(phi);
    Mat3::identity() + w * sinc + w * w * k.a
}

/// Unit quaternion of `exp([φ]×)`.
pub fn exp3_quat(phi: &Vec3) -> UnitQuaternion<f64> {
    let t2 = phi.norm_squared();
    let t = t2.sqrt();
    let (s, c) = (0.5 * t).sin_cos();
    let f = if t < 1e-6 { 0.5 - t2 / 48.0 } else { s / t };
    UnitQuaternion::new_unchecked(Quaternion::new(c, f * phi.x, f * phi.y, f * phi.z))
}

/// Logarithm of a unit quaternion, angle in [0, π].
pub fn log3_quat(q: &Quaternion<f64>) -> Vec3 {
    let (mut w, mut v) = (q.w, q.imag());
    if w < 0.0 {
        w = -w;
        v = -v;
    }
    let n = v.norm();
    let f = if n < 1e-8 {
        let r = n / w;
        2.0 / w * (1.0 - r * r / 3.0)
    } else {
        2.0 * n.atan2(w) / n
    };
    v * f
}

/// Logarithm of a rotation matrix, angle in [0, π]. The quaternion comes from the closed
/// form for a rotation matrix (nalgebra's `from_rotation_matrix`, a few ns; `from_matrix`
/// iterates to the nearest rotation of any matrix and costs ~2 µs).
pub fn log3(r: &Mat3) -> Vec3 {
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*r));
    log3_quat(q.quaternion())
}

/// Right Jacobian of `exp3`: `I − a [φ]× + b [φ]×²`.
pub fn jexp3(phi: &Vec3) -> Mat3 {
    let k = coeffs(phi.norm_squared());
    let w = skew(phi);
    Mat3::identity() - w * k.a + w * w * k.b
}

/// Right Jacobian of `log3` at `exp3(φ)`: `I + ½[φ]× + c [φ]×²` (inverse of `jexp3(φ)`).
pub fn jlog3(phi: &Vec3) -> Mat3 {
    let c = log_coeff(phi.norm_squared());
    let w = skew(phi);
    Mat3::identity() + w * 0.5 + w * w * c
}

/// Coupled SE(3) exponential of a twist `ξ = [ρ, φ]`.
pub fn exp6(xi: &Motion) -> Se3 {
    let phi = &xi.angular;
    let k = coeffs(phi.norm_squared());
    let w = skew(phi);
    let v = Mat3::identity() + w * k.a + w * w * k.b;
    Se3::new(exp3(phi), v * xi.linear)
}

/// SE(3) logarithm, rotation angle in [0, π].
pub fn log6(m: &Se3) -> Motion {
    let phi = log3(&m.rotation);
    log6_with_phi(m, phi)
}

/// SE(3) logarithm given the rotation part's logarithm.
pub(crate) fn log6_with_phi(m: &Se3, phi: Vec3) -> Motion {
    let c = log_coeff(phi.norm_squared());
    let w = skew(&phi);
    let vinv = Mat3::identity() - w * 0.5 + w * w * c;
    Motion::new(vinv * m.translation, phi)
}

/// Right Jacobian of `exp6` as blocks: `[[Jr(φ), B], [0, Jr(φ)]]`.
/// Returns `(Jr, B)`.
pub fn jexp6_blocks(xi: &Motion) -> (Mat3, Mat3) {
    let rho = &xi.linear;
    let phi = &xi.angular;
    let k = coeffs(phi.norm_squared());
    let w = skew(phi);
    let jr = Mat3::identity() - w * k.a + w * w * k.b;
    // B = Rᵀ ∂(V(φ) ρ)/∂φ
    let pr = phi.cross(rho);
    let ppr = phi.cross(&pr);
    let dv = -skew(rho) * k.a - (skew(&pr) + w * skew(rho)) * k.b
        + pr * phi.transpose() * k.da
        + ppr * phi.transpose() * k.db;
    let r = exp3(phi);
    (jr, r.transpose() * dv)
}

/// Right Jacobian of `log6` at `M = exp6(ξ)`, as blocks `[[Jl, C], [0, Jl]]`,
/// with `Jl = jlog3(φ)` and `C = −Jl B Jl`. Returns `(Jl, C)`.
pub fn jlog6_blocks(xi: &Motion) -> (Mat3, Mat3) {
    let (_, b) = jexp6_blocks(xi);
    let jl = jlog3(&xi.angular);
    (jl, -(jl * b * jl))
}

/// Adjoint of the inverse of `exp6(ξ)` acting on motions: `Ad(exp6(ξ))⁻¹` as blocks
/// `[[Rᵀ, −Rᵀ[p]×], [0, Rᵀ]]`; returns `(Rᵀ, −Rᵀ[p]×)`.
pub(crate) fn ad_inv_blocks(m: &Se3) -> (Mat3, Mat3) {
    let rt = m.rotation.transpose();
    (rt, -(rt * skew(&m.translation)))
}

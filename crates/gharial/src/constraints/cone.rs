//! The second-order (Lorentz) cone.

use faer::MatMut;

use super::ConstraintSet;
use crate::{Error, Result};

/// The second-order cone `K = {z = (t, s) : ‖s‖ ≤ t}` of dimension `n`, with the scalar
/// part **first**: `t = z_0`, `s = z_{1..n}`.
///
/// Projection (with `ρ = ‖s‖`):
/// ```text
/// ρ ≤ t      proj(z) = z                          (inside)
/// ρ ≤ -t     proj(z) = 0                          (in the polar cone -K)
/// otherwise  proj(z) = (t + ρ)/2 · (1, s/ρ)
/// ```
/// Generalised Jacobian `P(z)`: `I` for `ρ < t`, `0` for `ρ ≤ -t` (including `z = 0`),
/// and otherwise, with `n̂ = s/ρ`,
/// ```text
/// P = ½ [ 1   n̂ᵀ                          ]
///       [ n̂   (1 + t/ρ) I - (t/ρ) n̂ n̂ᵀ   ]
/// ```
/// applied column by column without forming it. `penalty` is 0 on `K` (up to a relative
/// rounding tolerance of `1e-14`, so projected points count as feasible), `+∞` outside. The cone is self-dual, so the
/// normal-cone projection `z - proj(z)` is the projection onto `-K`.
#[derive(Debug, Clone, Copy)]
pub struct SecondOrderCone {
    n: usize,
}

/// Where `z` lies relative to the cone.
enum Region {
    Inside,
    Polar,
    /// Boundary projection, with `(t, ρ)`.
    Boundary(f64, f64),
}

impl SecondOrderCone {
    /// The cone of dimension `n ≥ 1` (`n = 1` is `{t ≥ 0}`).
    ///
    /// # Errors
    /// If `n = 0`.
    pub fn new(n: usize) -> Result<Self> {
        if n == 0 {
            return Err(Error::InvalidModel(
                "SecondOrderCone: dimension must be at least 1".into(),
            ));
        }
        Ok(Self { n })
    }

    fn region(z: &[f64]) -> Region {
        let t = z[0];
        let rho = z[1..].iter().map(|v| v * v).sum::<f64>().sqrt();
        if rho < t {
            Region::Inside
        } else if rho <= -t {
            Region::Polar
        } else {
            Region::Boundary(t, rho)
        }
    }

    /// `m ← P m` (`complement = false`) or `m ← (I - P) m` (`true`) in the boundary
    /// region, column by column.
    fn apply_boundary(z: &[f64], t: f64, rho: f64, mut m: MatMut<'_, f64>, complement: bool) {
        let n = z.len();
        let r = t / rho;
        for j in 0..m.ncols() {
            let c0 = m[(0, j)];
            let beta = (1..n).map(|i| z[i] * m[(i, j)]).sum::<f64>() / rho;
            let p0 = 0.5 * (c0 + beta);
            m[(0, j)] = if complement { c0 - p0 } else { p0 };
            for i in 1..n {
                let nh = z[i] / rho;
                let ci = m[(i, j)];
                let pi = 0.5 * (c0 * nh + (1.0 + r) * ci - r * nh * beta);
                m[(i, j)] = if complement { ci - pi } else { pi };
            }
        }
    }
}

impl ConstraintSet for SecondOrderCone {
    fn dim(&self) -> Option<usize> {
        Some(self.n)
    }
    fn penalty(&self, z: &[f64]) -> f64 {
        // Membership up to rounding, so that projected points count as feasible.
        let rho = z[1..].iter().map(|v| v * v).sum::<f64>().sqrt();
        if rho <= z[0] + 1e-14 * rho { 0.0 } else { f64::INFINITY }
    }
    fn project(&self, z: &[f64], _mu: f64, out: &mut [f64]) {
        let t = z[0];
        let rho = z[1..].iter().map(|v| v * v).sum::<f64>().sqrt();
        if rho <= t {
            out.copy_from_slice(z);
        } else if rho <= -t {
            out.fill(0.0);
        } else {
            let alpha = 0.5 * (t + rho);
            out[0] = alpha;
            for i in 1..z.len() {
                out[i] = alpha * z[i] / rho;
            }
        }
    }
    fn apply_projection_jacobian(&self, z: &[f64], _mu: f64, mut m: MatMut<'_, f64>) {
        match Self::region(z) {
            Region::Inside => {}
            Region::Polar => crate::linalg::fill(m.as_mut(), 0.0),
            Region::Boundary(t, rho) => Self::apply_boundary(z, t, rho, m, false),
        }
    }
    fn apply_normal_cone_jacobian(&self, z: &[f64], _mu: f64, mut m: MatMut<'_, f64>) {
        match Self::region(z) {
            Region::Inside => crate::linalg::fill(m.as_mut(), 0.0),
            Region::Polar => {}
            Region::Boundary(t, rho) => Self::apply_boundary(z, t, rho, m, true),
        }
    }
    fn violation(&self, z: &[f64]) -> f64 {
        // |z - proj(z)|_∞ without a buffer.
        let t = z[0];
        let rho = z[1..].iter().map(|v| v * v).sum::<f64>().sqrt();
        if rho <= t {
            0.0
        } else if rho <= -t {
            crate::linalg::norm_inf(z)
        } else {
            let alpha = 0.5 * (t + rho);
            let mut v = (t - alpha).abs();
            for &s in &z[1..] {
                v = v.max((s - alpha * s / rho).abs());
            }
            v
        }
    }
}

//! The L1 penalty as a "set".

use faer::MatMut;

use super::ConstraintSet;
use crate::param::ParamVec;
use crate::{Error, Result};

/// The nonsmooth penalty `g(z) = w Σ_i |z_i|` (`w ≥ 0`), used like a constraint set
/// by the augmented-Lagrangian solvers.
///
/// With the proximal parameter `mu`:
/// ```text
/// project(z)              = prox_{mu g}(z) = sign(z) max(|z| - mu w, 0)   (soft threshold)
/// normal_cone_project(z)  = z - prox_{mu g}(z) = clamp(z, -mu w, mu w)
/// P_ii                    = [|z_i| > mu w]
/// ```
/// so the multiplier estimate `(z - prox(z)) / mu = clamp(z / mu, -w, w)` is a
/// subgradient of `g` (Moreau: `z = prox_{mu g}(z) + mu prox_{g*/mu}(z/mu)`, `g*` the
/// indicator of `[-w, w]ⁿ`). A penalty is never violated: `violation = 0`, and
/// `penalty(z) = w Σ |z_i|`.
#[derive(Debug, Clone)]
pub struct L1Penalty {
    weight: ParamVec,
}

fn check_weight(w: f64) -> Result<()> {
    if w.is_finite() && w >= 0.0 {
        Ok(())
    } else {
        Err(Error::option(
            "L1Penalty weight",
            format!("must be finite and >= 0, got {}", crate::error::Num(w)),
        ))
    }
}

impl L1Penalty {
    /// The penalty `w Σ |z_i|`.
    ///
    /// # Errors
    /// If `w` is negative or not finite.
    pub fn new(w: f64) -> Result<Self> {
        check_weight(w)?;
        Ok(Self {
            weight: ParamVec::new(&[w]),
        })
    }

    /// Changes the weight through `&self`.
    ///
    /// # Errors
    /// If `w` is negative or not finite.
    pub fn set_weight(&self, w: f64) -> Result<()> {
        check_weight(w)?;
        self.weight.set(0, w);
        Ok(())
    }

    /// The weight.
    pub fn weight(&self) -> f64 {
        self.weight.get(0)
    }
}

impl ConstraintSet for L1Penalty {
    fn penalty(&self, z: &[f64]) -> f64 {
        self.weight() * z.iter().map(|v| v.abs()).sum::<f64>()
    }
    fn project(&self, z: &[f64], mu: f64, out: &mut [f64]) {
        let k = mu * self.weight();
        for (o, &v) in out.iter_mut().zip(z) {
            *o = v.signum() * (v.abs() - k).max(0.0);
        }
    }
    fn normal_cone_project(&self, z: &[f64], mu: f64, out: &mut [f64]) {
        let k = mu * self.weight();
        for (o, &v) in out.iter_mut().zip(z) {
            *o = v.clamp(-k, k);
        }
    }
    fn apply_projection_jacobian(&self, z: &[f64], mu: f64, mut m: MatMut<'_, f64>) {
        let k = mu * self.weight();
        for i in 0..z.len() {
            if z[i].abs() <= k {
                m.as_mut().row_mut(i).fill(0.0);
            }
        }
    }
    fn apply_normal_cone_jacobian(&self, z: &[f64], mu: f64, mut m: MatMut<'_, f64>) {
        let k = mu * self.weight();
        for i in 0..z.len() {
            if z[i].abs() > k {
                m.as_mut().row_mut(i).fill(0.0);
            }
        }
    }
    fn violation(&self, _z: &[f64]) -> f64 {
        0.0
    }
}

//! Constraint sets `C`: a path constraint reads `h(x, u) ∈ C`.
//!
//! The augmented-Lagrangian solvers only need three operations of a set, all
//! parameterised by the proximal parameter `mu` (indicator sets ignore it; penalty
//! "sets" such as L1 use it as the parameter of their proximal operator):
//! - the projection `proj_C(z)` (for a penalty `g`: `prox_{mu g}(z)`);
//! - the normal-cone projection `z - proj_C(z)`; with `z = h + mu ν_e` the first-order
//!   multiplier estimate is `ν⁺ = (z - proj_C(z)) / mu` (paper eqs. (5), (39));
//! - the generalised Jacobian of the projection, whose complement `I - P(z)` projects
//!   constraint Jacobians onto the active set in the Newton system (eq. (41)-(46)).

use std::fmt::Debug;

use faer::MatMut;

mod cone;
mod l1;
mod product;
mod sets;
#[cfg(test)]
mod tests;

pub use cone::SecondOrderCone;
pub use l1::L1Penalty;
pub use product::ConstraintSetProduct;
pub use sets::{BoxConstraint, EqualityConstraintSet, NegativeOrthant};

/// [`ConstraintSet::violation`] of `z`, or NaN if an entry of `z` is not finite (a set's
/// own `violation` may drop a NaN through `max`): solvers report such points as
/// non-finite instead of feasible.
pub(crate) fn violation_or_nan(set: &dyn ConstraintSet, z: &[f64]) -> f64 {
    if z.iter().all(|v| v.is_finite()) {
        set.violation(z)
    } else {
        f64::NAN
    }
}

/// A closed convex set (or a convex nonsmooth penalty) constraining a residual.
pub trait ConstraintSet: Send + Sync + Debug {
    /// The dimension the set requires, or `None` if it applies to any dimension.
    fn dim(&self) -> Option<usize> {
        None
    }

    /// Whether the set is `{0}`: an equality constraint.
    fn is_equality(&self) -> bool {
        false
    }

    /// Penalty value of `z`: 0 for an indicator set when `z ∈ C` (`+∞` outside), the
    /// penalty value for a nonsmooth penalty (e.g. `Σ |z_i|` for L1).
    fn penalty(&self, z: &[f64]) -> f64;

    /// `out = proj_C(z)` (for penalties, `prox_{mu g}(z)`).
    fn project(&self, z: &[f64], mu: f64, out: &mut [f64]);

    /// `out = z - proj_C(z)`: the projection onto the normal cone.
    fn normal_cone_project(&self, z: &[f64], mu: f64, out: &mut [f64]) {
        self.project(z, mu, out);
        for (o, zi) in out.iter_mut().zip(z) {
            *o = zi - *o;
        }
    }

    /// In place `m ← P(z) m` with `P(z)` an element of the generalised Jacobian of
    /// `proj_C` at `z` (`m` has `z.len()` rows).
    fn apply_projection_jacobian(&self, z: &[f64], mu: f64, m: MatMut<'_, f64>);

    /// In place `m ← (I - P(z)) m`: the Jacobian of the normal-cone projection.
    fn apply_normal_cone_jacobian(&self, z: &[f64], mu: f64, m: MatMut<'_, f64>);

    /// In place `v ← (I - P(z)) v` for one vector: [`apply_normal_cone_jacobian`]
    /// on a single column, which sets with a diagonal Jacobian do without a matrix view.
    ///
    /// [`apply_normal_cone_jacobian`]: ConstraintSet::apply_normal_cone_jacobian
    fn apply_normal_cone_jacobian_vec(&self, z: &[f64], mu: f64, v: &mut [f64]) {
        self.apply_normal_cone_jacobian(z, mu, crate::linalg::as_mat_mut(v));
    }

    /// Violation of `z ∈ C` in the infinity norm: `|z - proj_C(z)|_∞` for indicator
    /// sets (0 for penalties, which are never violated).
    fn violation(&self, z: &[f64]) -> f64;

    /// For a set that is a box `lower ≤ z ≤ upper` (a box, the negative orthant, `{0}`),
    /// writes its bounds (`z.len()` entries each, infinite where unbounded) and returns
    /// `true`; other sets return `false` (the default). Solvers that treat bounds
    /// directly, such as box-DDP, recognise them this way.
    fn box_bounds(&self, lower: &mut [f64], upper: &mut [f64]) -> bool {
        let _ = (lower, upper);
        false
    }
}

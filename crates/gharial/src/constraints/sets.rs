//! Polyhedral sets with diagonal projection Jacobians: `{0}`, the negative orthant and
//! boxes.
//!
//! For these sets the projection acts entry by entry and an element of its generalised
//! Jacobian is a diagonal 0/1 matrix `P(z)`: `P_ii = 1` where the entry is strictly
//! inside its interval, 0 where it is on or beyond a bound (the active set of the
//! paper's eq. (12) includes the boundary).

use faer::MatMut;

use super::ConstraintSet;
use crate::param::ParamVec;
use crate::{Error, Result};

/// Zeroes the rows `i` of `m` where `keep(i)` is false.
fn zero_rows(mut m: MatMut<'_, f64>, keep: impl Fn(usize) -> bool) {
    for i in 0..m.nrows() {
        if !keep(i) {
            m.as_mut().row_mut(i).fill(0.0);
        }
    }
}

/// The equality set `{0}`: `h(x, u) = 0`.
///
/// `proj(z) = 0`, normal-cone projection `z` (so `ν⁺ = ν_e + h / mu`, eq. (39)),
/// `P = 0`, violation `|z|_∞`.
#[derive(Debug, Clone, Copy, Default)]
pub struct EqualityConstraintSet;

impl ConstraintSet for EqualityConstraintSet {
    fn is_equality(&self) -> bool {
        true
    }
    fn penalty(&self, z: &[f64]) -> f64 {
        if z.iter().all(|&v| v == 0.0) {
            0.0
        } else {
            f64::INFINITY
        }
    }
    fn project(&self, _z: &[f64], _mu: f64, out: &mut [f64]) {
        out.fill(0.0);
    }
    fn normal_cone_project(&self, z: &[f64], _mu: f64, out: &mut [f64]) {
        out.copy_from_slice(z);
    }
    fn apply_projection_jacobian(&self, _z: &[f64], _mu: f64, mut m: MatMut<'_, f64>) {
        m.fill(0.0);
    }
    fn apply_normal_cone_jacobian(&self, _z: &[f64], _mu: f64, _m: MatMut<'_, f64>) {}
    fn violation(&self, z: &[f64]) -> f64 {
        crate::linalg::norm_inf(z)
    }
    fn box_bounds(&self, lower: &mut [f64], upper: &mut [f64]) -> bool {
        lower.fill(0.0);
        upper.fill(0.0);
        true
    }
}

/// The negative orthant `{z : z ≤ 0}`: `h(x, u) ≤ 0`.
///
/// `proj(z) = min(z, 0)`, normal-cone projection `max(z, 0)`, `P_ii = [z_i < 0]`,
/// violation `max(0, max_i z_i)`.
#[derive(Debug, Clone, Copy, Default)]
pub struct NegativeOrthant;

impl ConstraintSet for NegativeOrthant {
    fn box_bounds(&self, lower: &mut [f64], upper: &mut [f64]) -> bool {
        lower.fill(f64::NEG_INFINITY);
        upper.fill(0.0);
        true
    }
    fn penalty(&self, z: &[f64]) -> f64 {
        if z.iter().all(|&v| v <= 0.0) {
            0.0
        } else {
            f64::INFINITY
        }
    }
    fn project(&self, z: &[f64], _mu: f64, out: &mut [f64]) {
        for (o, &v) in out.iter_mut().zip(z) {
            *o = v.min(0.0);
        }
    }
    fn normal_cone_project(&self, z: &[f64], _mu: f64, out: &mut [f64]) {
        for (o, &v) in out.iter_mut().zip(z) {
            *o = v.max(0.0);
        }
    }
    fn apply_projection_jacobian(&self, z: &[f64], _mu: f64, m: MatMut<'_, f64>) {
        zero_rows(m, |i| z[i] < 0.0);
    }
    fn apply_normal_cone_jacobian(&self, z: &[f64], _mu: f64, m: MatMut<'_, f64>) {
        zero_rows(m, |i| z[i] >= 0.0);
    }
    fn apply_normal_cone_jacobian_vec(&self, z: &[f64], _mu: f64, v: &mut [f64]) {
        for (vi, &zi) in v.iter_mut().zip(z) {
            if zi < 0.0 {
                *vi = 0.0;
            }
        }
    }
    fn violation(&self, z: &[f64]) -> f64 {
        z.iter().fold(0.0_f64, |a, &v| a.max(v))
    }
}

/// The box `{z : lower ≤ z ≤ upper}` (infinite bounds allowed), with bounds that can
/// move through `&self`.
///
/// `proj(z) = clamp(z, lower, upper)`, `P_ii = [lower_i < z_i < upper_i]`, violation
/// `max_i max(z_i - upper_i, lower_i - z_i, 0)`.
#[derive(Debug, Clone)]
pub struct BoxConstraint {
    lower: ParamVec,
    upper: ParamVec,
}

fn check_bounds(lower: &[f64], upper: &[f64]) -> Result<()> {
    crate::error::check_dim("BoxConstraint upper (size of lower)", lower.len(), upper.len())?;
    for (i, (&l, &u)) in lower.iter().zip(upper).enumerate() {
        if l.is_nan() || u.is_nan() {
            return Err(Error::non_finite(format!("BoxConstraint bounds, entry {i}")));
        }
        if !(l <= u && l < f64::INFINITY && u > f64::NEG_INFINITY) {
            return Err(Error::InvalidModel(format!(
                "BoxConstraint: entry {i} needs lower <= upper with lower < +inf and upper > -inf, got [{}, {}]",
                crate::error::Num(l),
                crate::error::Num(u)
            )));
        }
    }
    Ok(())
}

impl BoxConstraint {
    /// The box `[lower, upper]`.
    ///
    /// # Errors
    /// If the lengths differ, a bound is NaN, `lower_i > upper_i`, `lower_i = +∞` or
    /// `upper_i = -∞`.
    pub fn new(lower: &[f64], upper: &[f64]) -> Result<Self> {
        check_bounds(lower, upper)?;
        Ok(Self {
            lower: ParamVec::new(lower),
            upper: ParamVec::new(upper),
        })
    }

    /// Moves both bounds (through `&self`, e.g. between MPC solves).
    ///
    /// # Errors
    /// As [`BoxConstraint::new`], or if the size changes; the bounds are then unchanged.
    pub fn set_bounds(&self, lower: &[f64], upper: &[f64]) -> Result<()> {
        crate::error::check_dim("BoxConstraint lower", self.lower.len(), lower.len())?;
        check_bounds(lower, upper)?;
        self.lower.write(lower)?;
        self.upper.write(upper)
    }

    /// The lower bounds.
    pub fn lower(&self) -> Vec<f64> {
        self.lower.to_vec()
    }

    /// The upper bounds.
    pub fn upper(&self) -> Vec<f64> {
        self.upper.to_vec()
    }
}

impl BoxConstraint {
    /// The bounds `(lower_i, upper_i)` paired with the entries of `z` (one pass over the
    /// parameter vectors, no index checks).
    fn with_bounds<'a>(&'a self, z: &'a [f64]) -> impl Iterator<Item = (f64, f64, f64)> + 'a {
        debug_assert_eq!(z.len(), self.lower.len());
        self.lower
            .iter()
            .zip(self.upper.iter())
            .zip(z)
            .map(|((l, u), &v)| (l, u, v))
    }

    /// Zeroes the rows `i` of `m` for which `zero(lower_i, upper_i, z_i)`.
    fn zero_rows_where(&self, z: &[f64], mut m: MatMut<'_, f64>, zero: impl Fn(f64, f64, f64) -> bool) {
        for (i, (l, u, v)) in self.with_bounds(z).enumerate() {
            if zero(l, u, v) {
                m.as_mut().row_mut(i).fill(0.0);
            }
        }
    }
}

impl ConstraintSet for BoxConstraint {
    fn dim(&self) -> Option<usize> {
        Some(self.lower.len())
    }
    fn box_bounds(&self, lower: &mut [f64], upper: &mut [f64]) -> bool {
        for ((l, u), (lo, hi)) in lower
            .iter_mut()
            .zip(upper.iter_mut())
            .zip(self.lower.iter().zip(self.upper.iter()))
        {
            *l = lo;
            *u = hi;
        }
        true
    }
    fn penalty(&self, z: &[f64]) -> f64 {
        let inside = self.with_bounds(z).all(|(l, u, v)| l <= v && v <= u);
        if inside { 0.0 } else { f64::INFINITY }
    }
    fn project(&self, z: &[f64], _mu: f64, out: &mut [f64]) {
        for (o, (l, u, v)) in out.iter_mut().zip(self.with_bounds(z)) {
            *o = v.max(l).min(u);
        }
    }
    fn normal_cone_project(&self, z: &[f64], _mu: f64, out: &mut [f64]) {
        for (o, (l, u, v)) in out.iter_mut().zip(self.with_bounds(z)) {
            *o = v - v.max(l).min(u);
        }
    }
    fn apply_projection_jacobian(&self, z: &[f64], _mu: f64, m: MatMut<'_, f64>) {
        self.zero_rows_where(z, m, |l, u, v| !(l < v && v < u));
    }
    fn apply_normal_cone_jacobian(&self, z: &[f64], _mu: f64, m: MatMut<'_, f64>) {
        self.zero_rows_where(z, m, |l, u, v| l < v && v < u);
    }
    fn apply_normal_cone_jacobian_vec(&self, z: &[f64], _mu: f64, v: &mut [f64]) {
        for (vi, (l, u, zi)) in v.iter_mut().zip(self.with_bounds(z)) {
            if l < zi && zi < u {
                *vi = 0.0;
            }
        }
    }
    fn violation(&self, z: &[f64]) -> f64 {
        self.with_bounds(z)
            .fold(0.0_f64, |a, (l, u, v)| a.max(v - u).max(l - v))
    }
}

//! State spaces: manifolds with a representation of size `nx` and a tangent space of
//! size `ndx`.
//!
//! Conventions (the same as Pinocchio's Lie-group conventions):
//! - `integrate(x, v)` is `x ⊕ v`; on a Lie group `x · exp(v)` (right, or local,
//!   perturbation);
//! - `difference(x0, x1)` is `x1 ⊖ x0`, the tangent vector `v` at `x0` with
//!   `x0 ⊕ v = x1`;
//! - Jacobians are `ndx x ndx` and taken with respect to tangent perturbations:
//!   `jintegrate(x, v, Arg::First)` is `d(x ⊕ v)/dx` meaning
//!   `(x ⊕ δ) ⊕ v ≈ (x ⊕ v) ⊕ (J δ)`, and so on for every argument.

use std::fmt::Debug;

use faer::MatMut;
use rand::RngCore;

/// Which argument of a two-argument map a Jacobian is taken with respect to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arg {
    /// The first argument (`x` of `integrate(x, v)`, `x0` of `difference(x0, x1)`).
    First,
    /// The second argument (`v` of `integrate(x, v)`, `x1` of `difference(x0, x1)`).
    Second,
}

/// A smooth manifold with a retraction (`integrate`) and its local inverse (`difference`).
///
/// Implementations are immutable and shared (`Arc<dyn Manifold>`); no method allocates.
pub trait Manifold: Send + Sync + Debug {
    /// Size of the representation of a point.
    fn nx(&self) -> usize;

    /// Dimension of the tangent space.
    fn ndx(&self) -> usize;

    /// Writes the neutral element (identity, origin) into `out` (`nx`).
    fn neutral(&self, out: &mut [f64]);

    /// Writes a random point into `out` (`nx`); vector parts are drawn in `[-1, 1]`.
    fn random(&self, rng: &mut dyn RngCore, out: &mut [f64]);

    /// `out = x ⊕ v` (`x`, `out`: `nx`; `v`: `ndx`). `out` must not alias `x`.
    fn integrate(&self, x: &[f64], v: &[f64], out: &mut [f64]);

    /// `out = x1 ⊖ x0` (`ndx`), so that `integrate(x0, out) == x1`.
    fn difference(&self, x0: &[f64], x1: &[f64], out: &mut [f64]);

    /// Geodesic interpolation `x0 ⊕ (t (x1 ⊖ x0))`; `t = 0` gives `x0`, `t = 1` gives `x1`.
    fn interpolate(&self, x0: &[f64], x1: &[f64], t: f64, out: &mut [f64]);

    /// Jacobian of `x ⊕ v` with respect to `x` or `v` (`ndx x ndx`), written into `j`.
    fn jintegrate(&self, x: &[f64], v: &[f64], arg: Arg, j: MatMut<'_, f64>);

    /// Jacobian of `x1 ⊖ x0` with respect to `x0` or `x1` (`ndx x ndx`), written into `j`.
    fn jdifference(&self, x0: &[f64], x1: &[f64], arg: Arg, j: MatMut<'_, f64>);

    /// In place `m ← jintegrate(x, v, arg) · m` for a matrix `m` with `ndx` rows.
    fn jintegrate_transport(&self, x: &[f64], v: &[f64], arg: Arg, m: MatMut<'_, f64>);

    /// Derivative of `x ⊕ v` with respect to `v` at `v = 0`, in representation
    /// coordinates (`nx x ndx`). Maps tangent directions to representation directions;
    /// used to differentiate functions written on the representation (dual numbers,
    /// finite differences).
    fn tangent_map(&self, x: &[f64], j: MatMut<'_, f64>);

    /// Projects a representation back onto the manifold (e.g. normalises quaternions).
    fn normalize(&self, x: &mut [f64]) {
        let _ = x;
    }

    /// Whether `x` is a finite, valid point (unit quaternions and rotations within
    /// `1e-8`).
    fn is_valid(&self, x: &[f64]) -> bool {
        x.len() == self.nx() && x.iter().all(|v| v.is_finite())
    }

    /// Whether this is a vector space (`nx == ndx`, `⊕` is `+`, all Jacobians identity).
    fn is_vector_space(&self) -> bool {
        false
    }
}

/// The Euclidean space `R^n`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct VectorSpace {
    n: usize,
}

impl VectorSpace {
    /// `R^n`.
    pub fn new(n: usize) -> Self {
        Self { n }
    }
}

impl Manifold for VectorSpace {
    fn nx(&self) -> usize {
        self.n
    }

    fn ndx(&self) -> usize {
        self.n
    }

    fn neutral(&self, out: &mut [f64]) {
        out.fill(0.0);
    }

    fn random(&self, rng: &mut dyn RngCore, out: &mut [f64]) {
        use rand::Rng;
        for o in out.iter_mut() {
            *o = rng.random_range(-1.0..=1.0);
        }
    }

    fn integrate(&self, x: &[f64], v: &[f64], out: &mut [f64]) {
        for i in 0..self.n {
            out[i] = x[i] + v[i];
        }
    }

    fn difference(&self, x0: &[f64], x1: &[f64], out: &mut [f64]) {
        for i in 0..self.n {
            out[i] = x1[i] - x0[i];
        }
    }

    fn interpolate(&self, x0: &[f64], x1: &[f64], t: f64, out: &mut [f64]) {
        for i in 0..self.n {
            out[i] = x0[i] + t * (x1[i] - x0[i]);
        }
    }

    fn jintegrate(&self, _x: &[f64], _v: &[f64], _arg: Arg, mut j: MatMut<'_, f64>) {
        j.fill(0.0);
        j.diagonal_mut().column_vector_mut().fill(1.0);
    }

    fn jdifference(&self, _x0: &[f64], _x1: &[f64], arg: Arg, mut j: MatMut<'_, f64>) {
        j.fill(0.0);
        let s = match arg {
            Arg::First => -1.0,
            Arg::Second => 1.0,
        };
        j.diagonal_mut().column_vector_mut().fill(s);
    }

    fn jintegrate_transport(&self, _x: &[f64], _v: &[f64], _arg: Arg, _m: MatMut<'_, f64>) {}

    fn tangent_map(&self, _x: &[f64], mut j: MatMut<'_, f64>) {
        j.fill(0.0);
        j.diagonal_mut().column_vector_mut().fill(1.0);
    }

    fn is_vector_space(&self) -> bool {
        true
    }
}

//! State spaces: manifolds with a representation of size `nx` and a tangent space of
//! size `ndx`.
//!
//! # Conventions
//!
//! The same as Pinocchio's Lie-group conventions:
//! - `integrate(x, v)` is `x ⊕ v`; on a Lie group `x · exp(v)` (right, or local,
//!   perturbation);
//! - `difference(x0, x1)` is `x1 ⊖ x0 = log(x0⁻¹ x1)`, the tangent vector `v` at `x0`
//!   with `x0 ⊕ v = x1`;
//! - Jacobians are `ndx x ndx` and taken with respect to tangent perturbations:
//!   `jintegrate(x, v, Arg::First)` is `d(x ⊕ v)/dx` meaning
//!   `(x ⊕ δ) ⊕ v ≈ (x ⊕ v) ⊕ (J δ)`, and so on for every argument.
//!
//! On a Lie group with right Jacobian `J_r` (`exp(v + δ) ≈ exp(v) exp(J_r(v) δ)`) and
//! adjoint `Ad`, these Jacobians are (Sola, Deray and Atchuthan, "A micro Lie theory
//! for state estimation in robotics", 2018, the Jacobians of right-⊕ and right-⊖):
//! ```text
//! d(x ⊕ v)/dx   = Ad(exp(v))⁻¹          d(x ⊕ v)/dv   = J_r(v)
//! d(x1 ⊖ x0)/dx1 = J_r(d)⁻¹              d(x1 ⊖ x0)/dx0 = -J_l(d)⁻¹ = -J_r(-d)⁻¹
//! ```
//! with `d = x1 ⊖ x0`. Each group's module gives its `exp`, `log`, `J_r` and `J_r⁻¹`.
//!
//! # Spaces
//!
//! | space | representation `x` | `nx` | `ndx` |
//! |---|---|---|---|
//! | [`VectorSpace`] `R^n` | the vector | n | n |
//! | [`SO2`] | `(cos θ, sin θ)` | 2 | 1 |
//! | [`SO3`] | unit quaternion `(x, y, z, w)` | 4 | 3 |
//! | [`SE2`] | `(x, y, cos θ, sin θ)` | 4 | 3 |
//! | [`SE3`] | `(translation, quaternion (x, y, z, w))` | 7 | 6 (linear, angular; local frame) |
//! | [`CartesianProduct`] | the parts' representations, concatenated | Σ | Σ |
//! | [`TangentBundle`] | `(q, v)`, `v` tangent to the base at `q` | nq + nv | 2 nv |
//!
//! # Scalars
//!
//! The group operations of every space are written once, generic over a [`Scalar`]
//! (`f64` and the dual numbers of `num-dual`). The trait exposes them for `f64`
//! ([`Manifold::integrate`]), first-order dual numbers ([`Manifold::integrate_dual`])
//! and hyper-dual numbers ([`Manifold::integrate_hyper`]): automatic differentiation
//! ([`crate::autodiff`]) and the dual-number derivative checker
//! ([`crate::check`]) evaluate the very code that the solvers run.

use std::fmt::Debug;

use faer::MatMut;
use faer::reborrow::ReborrowMut;
use num_dual::{Dual64, DualNum, HyperDual64};
use rand::RngCore;

pub(crate) mod lie;
mod product;
mod se2;
mod se3;
mod so2;
mod so3;
mod tangent_bundle;

#[cfg(test)]
mod tests;

pub use product::CartesianProduct;
pub use se2::SE2;
pub use se3::SE3;
pub use so2::SO2;
pub use so3::SO3;
pub use tangent_bundle::TangentBundle;

/// A real scalar for code written once for `f64` and for dual numbers:
/// `f64`, [`Dual64`], [`HyperDual64`], `Dual2_64`, nested duals, ...
///
/// Branches must test the real part (`x.re()`), and smooth expressions must be used
/// on both sides of a branch so that derivatives are exact everywhere.
pub trait Scalar: DualNum<Primitive = f64> + Copy + Send + Sync {}

impl<T: DualNum<Primitive = f64> + Copy + Send + Sync> Scalar for T {}

mod sealed {
    pub trait Sealed {}
    impl Sealed for f64 {}
    impl Sealed for num_dual::Dual64 {}
    impl Sealed for num_dual::HyperDual64 {}
}

/// The scalars on which every `dyn Manifold` runs its group operations: `f64`,
/// [`Dual64`] and [`HyperDual64`]. Models differentiated automatically are generic over
/// this trait, so that they can use `⊕` and `⊖` of any space:
///
/// ```
/// use gharial::spaces::{Manifold, ManifoldScalar, SE3};
/// /// One explicit Euler step `y = x ⊕ dt v` on SE(3), for any of the scalars.
/// fn euler<D: ManifoldScalar>(x: &[D], v: &[D], dt: f64, y: &mut [D]) {
///     let dv: [D; 6] = std::array::from_fn(|i| v[i] * dt);
///     D::integrate(&SE3, x, &dv, y);
/// }
/// let mut y = [0.0; 7];
/// euler(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0], &[1.0, 0.0, 0.0, 0.0, 0.0, 0.0], 0.5, &mut y);
/// assert_eq!(y[0], 0.5);
/// ```
pub trait ManifoldScalar: Scalar + sealed::Sealed {
    /// `out = x ⊕ v` on `m` ([`Manifold::integrate`] or its dual versions).
    fn integrate(m: &dyn Manifold, x: &[Self], v: &[Self], out: &mut [Self]);
    /// `out = x1 ⊖ x0` on `m` ([`Manifold::difference`] or its dual versions).
    fn difference(m: &dyn Manifold, x0: &[Self], x1: &[Self], out: &mut [Self]);
}

impl ManifoldScalar for f64 {
    #[inline]
    fn integrate(m: &dyn Manifold, x: &[f64], v: &[f64], out: &mut [f64]) {
        m.integrate(x, v, out)
    }
    #[inline]
    fn difference(m: &dyn Manifold, x0: &[f64], x1: &[f64], out: &mut [f64]) {
        m.difference(x0, x1, out)
    }
}

impl ManifoldScalar for Dual64 {
    #[inline]
    fn integrate(m: &dyn Manifold, x: &[Self], v: &[Self], out: &mut [Self]) {
        m.integrate_dual(x, v, out)
    }
    #[inline]
    fn difference(m: &dyn Manifold, x0: &[Self], x1: &[Self], out: &mut [Self]) {
        m.difference_dual(x0, x1, out)
    }
}

impl ManifoldScalar for HyperDual64 {
    #[inline]
    fn integrate(m: &dyn Manifold, x: &[Self], v: &[Self], out: &mut [Self]) {
        m.integrate_hyper(x, v, out)
    }
    #[inline]
    fn difference(m: &dyn Manifold, x0: &[Self], x1: &[Self], out: &mut [Self]) {
        m.difference_hyper(x0, x1, out)
    }
}

/// Implements the scalar-typed group operations of [`Manifold`] by forwarding to the
/// inherent generic methods `integrate_t` and `difference_t` of the space.
macro_rules! forward_group_ops {
    () => {
        fn integrate(&self, x: &[f64], v: &[f64], out: &mut [f64]) {
            self.integrate_t(x, v, out)
        }
        fn difference(&self, x0: &[f64], x1: &[f64], out: &mut [f64]) {
            self.difference_t(x0, x1, out)
        }
        fn integrate_dual(&self, x: &[num_dual::Dual64], v: &[num_dual::Dual64], out: &mut [num_dual::Dual64]) {
            self.integrate_t(x, v, out)
        }
        fn difference_dual(&self, x0: &[num_dual::Dual64], x1: &[num_dual::Dual64], out: &mut [num_dual::Dual64]) {
            self.difference_t(x0, x1, out)
        }
        fn integrate_hyper(
            &self,
            x: &[num_dual::HyperDual64],
            v: &[num_dual::HyperDual64],
            out: &mut [num_dual::HyperDual64],
        ) {
            self.integrate_t(x, v, out)
        }
        fn difference_hyper(
            &self,
            x0: &[num_dual::HyperDual64],
            x1: &[num_dual::HyperDual64],
            out: &mut [num_dual::HyperDual64],
        ) {
            self.difference_t(x0, x1, out)
        }
    };
}
pub(crate) use forward_group_ops;

/// Which argument of a two-argument map a Jacobian is taken with respect to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arg {
    /// The first argument (`x` of `integrate(x, v)`, `x0` of `difference(x0, x1)`).
    First,
    /// The second argument (`v` of `integrate(x, v)`, `x1` of `difference(x0, x1)`).
    Second,
}

/// Tolerance of [`Manifold::is_valid`] on unit norms.
pub const VALID_TOL: f64 = 1e-8;

/// A smooth manifold with a retraction (`integrate`) and its local inverse (`difference`).
///
/// `difference(x, x) = 0` and the retraction's differential at `v = 0` is the identity,
/// so that `jdifference(x, x)` is `(-I, I)`: problem evaluation uses this at the closed
/// gaps of explicit dynamics instead of calling `jdifference`.
///
/// Implementations are immutable and shared (`Arc<dyn Manifold>`); no method allocates.
/// Slices must have the documented sizes (checked in debug builds only: the methods
/// run in the solvers' inner loops; models validate sizes once at setup).
///
/// To implement a new space, write `integrate` and `difference` once, generic over
/// [`Scalar`], and call them from the `f64`, `_dual` and `_hyper` methods.
pub trait Manifold: Send + Sync + Debug {
    /// Size of the representation of a point.
    fn nx(&self) -> usize;

    /// Dimension of the tangent space.
    fn ndx(&self) -> usize;

    /// Writes the neutral element (identity, origin) into `out` (`nx`).
    fn neutral(&self, out: &mut [f64]);

    /// Writes a random point into `out` (`nx`); vector parts are drawn uniformly in
    /// `[-1, 1]`, rotations uniformly (Haar measure).
    fn random(&self, rng: &mut dyn RngCore, out: &mut [f64]);

    /// `out = x ⊕ v` (`x`, `out`: `nx`; `v`: `ndx`). `out` must not alias `x`.
    fn integrate(&self, x: &[f64], v: &[f64], out: &mut [f64]);

    /// `out = x1 ⊖ x0` (`ndx`), so that `integrate(x0, out) == x1`.
    fn difference(&self, x0: &[f64], x1: &[f64], out: &mut [f64]);

    /// [`Manifold::integrate`] on first-order dual numbers (same code, same results in
    /// the real parts).
    fn integrate_dual(&self, x: &[Dual64], v: &[Dual64], out: &mut [Dual64]);

    /// [`Manifold::difference`] on first-order dual numbers.
    fn difference_dual(&self, x0: &[Dual64], x1: &[Dual64], out: &mut [Dual64]);

    /// [`Manifold::integrate`] on hyper-dual numbers (second derivatives).
    fn integrate_hyper(&self, x: &[HyperDual64], v: &[HyperDual64], out: &mut [HyperDual64]);

    /// [`Manifold::difference`] on hyper-dual numbers.
    fn difference_hyper(&self, x0: &[HyperDual64], x1: &[HyperDual64], out: &mut [HyperDual64]);

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

    /// Derivative of `z ↦ z ⊖ x` at `z = x`, in representation coordinates
    /// (`ndx x nx`): maps a representation direction at `x` to a tangent vector. Used
    /// to differentiate functions whose value lies on the manifold.
    /// `tangent_map_inverse(x) · tangent_map(x) = I`.
    fn tangent_map_inverse(&self, x: &[f64], j: MatMut<'_, f64>);

    /// Projects a representation back onto the manifold (e.g. normalises quaternions).
    fn normalize(&self, x: &mut [f64]) {
        let _ = x;
    }

    /// Whether `x` has size `nx`, is finite and is a valid point (unit quaternions and
    /// rotations within [`VALID_TOL`]).
    fn is_valid(&self, x: &[f64]) -> bool {
        x.len() == self.nx() && x.iter().all(|v| v.is_finite())
    }

    /// Whether this is a vector space (`nx == ndx`, `⊕` is `+`, all Jacobians identity).
    fn is_vector_space(&self) -> bool {
        false
    }

    /// The tangent coordinates `0..k` that hold every non-Euclidean part: at every point
    /// `jintegrate` and `jdifference` are `diag(J_b, ±I)` with `J_b` of size `k × k`
    /// (`-I` for `jdifference` in `x0`), as on a Lie group times vector spaces (a
    /// floating base and its joints: `k = 6`). Costs and dynamics use it to work on the
    /// block alone. Default `ndx` (no structure claimed); `0` on vector spaces.
    /// [`crate::check::check_manifold`] checks the claim.
    fn nonlinear_dim(&self) -> usize {
        self.ndx()
    }

    /// The leading `k × k` block of [`Manifold::jdifference`] (`k` =
    /// [`Manifold::nonlinear_dim`], `j` of that size): all of the Jacobian that is not
    /// `±I`, without writing the rest. The default is `jdifference` itself, right for the
    /// default `nonlinear_dim`; a space that claims a smaller block writes it here.
    fn jdifference_block(&self, x0: &[f64], x1: &[f64], arg: Arg, j: MatMut<'_, f64>) {
        self.jdifference(x0, x1, arg, j);
    }
}

/// Writes `±I` into a square matrix.
#[inline]
pub(crate) fn set_identity(mut j: MatMut<'_, f64>, s: f64) {
    crate::linalg::fill(j.rb_mut(), 0.0);
    j.diagonal_mut().column_vector_mut().fill(s);
}

/// Zeroes a square matrix outside its diagonal blocks, which run between consecutive
/// entries of `bounds` (from 0 to its size): the Jacobians of products, whose parts then
/// write their own blocks (each entry written once).
#[inline]
pub(crate) fn zero_off_diagonal_blocks(mut j: MatMut<'_, f64>, bounds: &[usize]) {
    let n = j.nrows();
    for w in bounds.windows(2) {
        let (lo, hi) = (w[0], w[1]);
        let mut cols = j.rb_mut().subcols_mut(lo, hi - lo);
        crate::linalg::fill(cols.rb_mut().subrows_mut(0, lo), 0.0);
        crate::linalg::fill(cols.subrows_mut(hi, n - hi), 0.0);
    }
}

/// Whether a vector of squared norm `n2` has unit norm within [`VALID_TOL`].
#[inline]
pub(crate) fn is_unit(n2: f64) -> bool {
    (n2.sqrt() - 1.0).abs() <= VALID_TOL
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

    fn integrate_t<T: Scalar>(&self, x: &[T], v: &[T], out: &mut [T]) {
        debug_assert!(x.len() == self.n && v.len() == self.n && out.len() == self.n);
        add_elementwise(x, v, out);
    }

    fn difference_t<T: Scalar>(&self, x0: &[T], x1: &[T], out: &mut [T]) {
        debug_assert!(x0.len() == self.n && x1.len() == self.n && out.len() == self.n);
        sub_elementwise(x0, x1, out);
    }
}

/// `out = x + v`: `⊕` of a vector space (and of products and bundles of them).
#[inline]
fn add_elementwise<T: Scalar>(x: &[T], v: &[T], out: &mut [T]) {
    for ((o, &a), &b) in out.iter_mut().zip(x).zip(v) {
        *o = a + b;
    }
}

/// `out = x1 - x0`: `⊖` of a vector space (and of products and bundles of them).
#[inline]
fn sub_elementwise<T: Scalar>(x0: &[T], x1: &[T], out: &mut [T]) {
    for ((o, &a), &b) in out.iter_mut().zip(x0).zip(x1) {
        *o = b - a;
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

    forward_group_ops!();

    fn interpolate(&self, x0: &[f64], x1: &[f64], t: f64, out: &mut [f64]) {
        for ((o, &a), &b) in out.iter_mut().zip(x0).zip(x1) {
            *o = a + t * (b - a);
        }
    }

    fn jintegrate(&self, _x: &[f64], _v: &[f64], _arg: Arg, j: MatMut<'_, f64>) {
        set_identity(j, 1.0);
    }

    fn jdifference(&self, _x0: &[f64], _x1: &[f64], arg: Arg, j: MatMut<'_, f64>) {
        let s = match arg {
            Arg::First => -1.0,
            Arg::Second => 1.0,
        };
        set_identity(j, s);
    }

    fn jintegrate_transport(&self, _x: &[f64], _v: &[f64], _arg: Arg, _m: MatMut<'_, f64>) {}

    fn tangent_map(&self, _x: &[f64], j: MatMut<'_, f64>) {
        set_identity(j, 1.0);
    }

    fn tangent_map_inverse(&self, _x: &[f64], j: MatMut<'_, f64>) {
        set_identity(j, 1.0);
    }

    fn is_vector_space(&self) -> bool {
        true
    }

    fn nonlinear_dim(&self) -> usize {
        0
    }

    fn jdifference_block(&self, _x0: &[f64], _x1: &[f64], _arg: Arg, _j: MatMut<'_, f64>) {}
}

/// Writes a 3x3 block into `j` at `(r0, c0)`.
#[inline]
pub(crate) fn write3(j: &mut MatMut<'_, f64>, r0: usize, c0: usize, m: &lie::M3) {
    for (i, row) in m.iter().enumerate() {
        for (k, &v) in row.iter().enumerate() {
            j[(r0 + i, c0 + k)] = v;
        }
    }
}

/// In place `m ← J m` for a small dense `J` (`N x N`, row-major) and `m` with `N` rows.
#[inline]
pub(crate) fn transport<const N: usize>(jac: &[[f64; N]; N], mut m: MatMut<'_, f64>) {
    debug_assert_eq!(m.nrows(), N);
    for c in 0..m.ncols() {
        let col: [f64; N] = std::array::from_fn(|i| m[(i, c)]);
        for i in 0..N {
            let mut s = 0.0;
            for k in 0..N {
                s += jac[i][k] * col[k];
            }
            m[(i, c)] = s;
        }
    }
}

/// Writes a small dense `N x N` matrix (row-major) into `j`.
#[inline]
pub(crate) fn write_dense<const N: usize>(jac: &[[f64; N]; N], mut j: MatMut<'_, f64>) {
    for i in 0..N {
        for k in 0..N {
            j[(i, k)] = jac[i][k];
        }
    }
}

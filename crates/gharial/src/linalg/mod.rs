//! The one place where gharial calls faer's products and factorizations.
//!
//! Every dense kernel of the library goes through this module, so that a faer upgrade or
//! a hand-written kernel for tiny sizes (faer has a fixed cost per call that dominates
//! below n = 8) touches this module only. Factorization objects allocate their storage and
//! scratch memory in `new` and never allocate afterwards.
//!
//! One operation family per file: products (`matmul`), Gram products of residual
//! Jacobians (`gram`), matrix-vector products (`matvec`),
//! reductions (`reduce`), copies (`copy`), symmetrization (`symmetric`), the square root
//! of a small positive semidefinite matrix (`psd_sqrt`), views of owned
//! storage (`views`), and the factorizations LLᵀ (`llt`), LDLᵀ (`ldlt`), Bunch-Kaufman
//! (`bunch_kaufman`) and LU (`lu`), the square-root kernels (`qr`: Householder QR's
//! triangular factor, semidefinite Cholesky, triangular solves), the first two with fixed-size kernels up to 12 x 12
//! (`small`), and sparse symmetric matrices (`sparse`: the lower triangle in compressed
//! columns, LDLᵀ without pivoting by faer's sparse Cholesky, the AMD ordering). Products, matrix-vector products, copies and symmetrizations have
//! fixed-size kernels for 1 to 16 rows, with the additions in the order of the generic
//! loops (bit-identical results).
//!
//! # Public surface
//!
//! The module is internal to gharial except for a few items. [`slice()`],
//! [`slice_mut`], [`copy()`], [`negate`], [`matmul()`] and [`matvec()`] are public because
//! the robotics crate (`gharial-robotics`), the problem catalogue (`gharial-problems`) and
//! the Python bindings (`gharial-py`) use them on the owned columns and matrices of
//! gharial's data objects. [`Lu`] (whose errors are [`FactorError`]s) solves small dense
//! systems outside the crate, such as the custom gains of the integration tests of
//! `RiccatiSolver::backward_with`; [`Inertia`] is what
//! [`LqError::Inertia`](crate::lq::LqError::Inertia) reports.

use faer::dyn_stack::{MemBuffer, StackReq};

/// Calls `$f::<N>$args` when `$n` is one of the lengths with a fixed-size kernel (1 to
/// 16) and evaluates to whether it did.
macro_rules! with_fixed_len {
    ($n:expr, $f:ident, $args:tt) => {
        with_fixed_len!(@arms $n, $f, $args, 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16)
    };
    (@arms $n:expr, $f:ident, $args:tt, $($len:literal)*) => {
        match $n {
            $($len => {
                $f::<$len> $args;
                true
            })*
            _ => false,
        }
    };
}

/// The largest dimension of the fixed-size kernels of [`with_small_dim!`].
pub(crate) const SMALL_DIM: usize = 12;

/// Calls `$f::<N>$args` when `$n` is at most [`SMALL_DIM`] and evaluates to `Some` of its result,
/// `None` otherwise. Factorizations and solves up to this dimension use the fixed-size
/// kernels of [`small`] ([`small_factor`](small::small_factor),
/// [`ldlt_solve_fixed`](small::ldlt_solve_fixed),
/// [`llt_solve_fixed`](small::llt_solve_fixed)) instead of faer's blocked code, whose
/// fixed cost per call dominates at these sizes.
macro_rules! with_small_dim {
    ($n:expr, $f:ident, $args:tt) => {
        with_small_dim!(@arms $n, $f, $args, 1 2 3 4 5 6 7 8 9 10 11 12)
    };
    (@arms $n:expr, $f:ident, $args:tt, $($len:literal)*) => {
        match $n {
            $($len => Some($f::<$len> $args),)*
            _ => None,
        }
    };
}

mod bunch_kaufman;
mod copy;
mod gram;
mod ldlt;
mod llt;
mod lu;
mod matmul;
mod matvec;
mod psd_sqrt;
mod qr;
mod reduce;
mod small;
mod sparse;
mod symmetric;
#[cfg(test)]
mod tests;
mod views;

pub use copy::{copy, fill, negate};
pub use lu::Lu;
pub use matmul::matmul;
pub use matvec::matvec;
pub use views::{slice, slice_mut};

pub(crate) use bunch_kaufman::BunchKaufman;
pub(crate) use copy::copy_transposed;
pub(crate) use gram::{GramScratch, GramWeight, scale_rows};
pub(crate) use ldlt::Ldlt;
pub(crate) use llt::Llt;
pub(crate) use matmul::{
    add_sandwich_lower, copy_add_product, identity_block, matmul_identity_block, matmul_loops, matmul_lower_upper_free,
    reserve_packing_buffer,
};
pub(crate) use matvec::matvec_t;
pub(crate) use psd_sqrt::psd_sqrt;
pub(crate) use qr::{householder_r, semidefinite_cholesky_upper, upper_solve, upper_t_solve};
pub(crate) use reduce::{all_finite, any_nonzero, dot, is_zero, max_nan, norm_inf, norm_l1, norm_max, sum_is_finite};
pub(crate) use sparse::{SparseLdlt, SymmetricCsc, amd_order};
pub(crate) use symmetric::{
    add_scaled_lower, fill_lower, identity_plus_scaled_lower, symmetrize, symmetrize_from_lower,
};
#[cfg(test)]
pub(crate) use views::col;
pub(crate) use views::{as_mat, as_mat_mut, col_of, col_of_mut, col_slice_mut};

/// Inertia of a symmetric matrix: numbers of positive, negative and zero eigenvalues.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Inertia {
    /// Number of positive eigenvalues.
    pub positive: usize,
    /// Number of negative eigenvalues.
    pub negative: usize,
    /// Number of (numerically) zero eigenvalues.
    pub zero: usize,
}

/// Why a factorization failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FactorError {
    /// The matrix contains a NaN or an infinity.
    NonFinite,
    /// A pivot was zero (or not positive, for a Cholesky factorization) at this index.
    Singular {
        /// Index of the failing pivot.
        index: usize,
    },
}

/// The scratch memory of a factorization, allocated once in its `new`.
fn stack_buffer(req: StackReq) -> MemBuffer {
    MemBuffer::new(req)
}

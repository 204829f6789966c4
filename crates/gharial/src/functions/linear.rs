//! Affine functions of a vector state and a control: `r(x, u) = A x + B u + c` and
//! `r(x) = A x + c`.
//!
//! The state is a plain vector (`nx = ndx`). For an affine map of a state on a
//! manifold, compose an error with it: `LinearComposition` of a [`super::StateError`]
//! gives `M (x ⊖ x_ref) + b`.

use faer::{Accum, Col, Mat, MatRef};

use super::util::checked_mat;
use super::{StageFunction, StageFunctionData, UnaryFunction};
use crate::Result;
use crate::linalg::{matvec, slice, slice_mut};

/// `r(x, u) = A x + B u + c` with `A: nr x nx`, `B: nr x nu`, `c: nr`.
///
/// Jacobians `A` and `B`; the second derivative is zero (exact, so `has_vhp` is false).
#[derive(Debug, Clone)]
pub struct LinearFunction {
    a: Mat<f64>,
    b: Mat<f64>,
    c: Col<f64>,
}

impl LinearFunction {
    /// `r(x, u) = A x + B u + c`.
    ///
    /// # Errors
    /// If `B` or `c` do not have `A.nrows()` rows, or an entry is not finite.
    pub fn new(a: MatRef<'_, f64>, b: MatRef<'_, f64>, c: &[f64]) -> Result<Self> {
        let nr = a.nrows();
        let a = checked_mat("LinearFunction A", a, None, None)?;
        let b = checked_mat("LinearFunction B", b, Some(nr), None)?;
        let c = super::util::checked_vec("LinearFunction c", c, nr)?;
        Ok(Self {
            a,
            b,
            c: Col::from_fn(nr, |i| c[i]),
        })
    }

    /// The matrix `A`.
    pub fn a(&self) -> MatRef<'_, f64> {
        self.a.as_ref()
    }

    /// The matrix `B`.
    pub fn b(&self) -> MatRef<'_, f64> {
        self.b.as_ref()
    }

    /// The offset `c`.
    pub fn c(&self) -> &[f64] {
        slice(&self.c)
    }
}

impl StageFunction for LinearFunction {
    fn nx(&self) -> usize {
        self.a.ncols()
    }
    fn ndx(&self) -> usize {
        self.a.ncols()
    }
    fn nu(&self) -> usize {
        self.b.ncols()
    }
    fn nr(&self) -> usize {
        self.a.nrows()
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let r = slice_mut(&mut data.value);
        r.copy_from_slice(slice(&self.c));
        matvec(r, Accum::Add, self.a.as_ref(), x, 1.0);
        matvec(r, Accum::Add, self.b.as_ref(), u, 1.0);
    }
    fn jacobians(&self, _x: &[f64], _u: &[f64], data: &mut StageFunctionData) {
        data.jx.copy_from(&self.a);
        data.ju.copy_from(&self.b);
    }
    fn jacobians_are_constant(&self) -> bool {
        true
    }
}

/// `r(x) = A x + c` with `A: nr x nx`, `c: nr`, as a [`UnaryFunction`].
#[derive(Debug, Clone)]
pub struct LinearUnaryFunction {
    a: Mat<f64>,
    c: Col<f64>,
}

impl LinearUnaryFunction {
    /// `r(x) = A x + c`.
    ///
    /// # Errors
    /// If `c` does not have `A.nrows()` entries, or an entry is not finite.
    pub fn new(a: MatRef<'_, f64>, c: &[f64]) -> Result<Self> {
        let nr = a.nrows();
        let a = checked_mat("LinearUnaryFunction A", a, None, None)?;
        let c = super::util::checked_vec("LinearUnaryFunction c", c, nr)?;
        Ok(Self {
            a,
            c: Col::from_fn(nr, |i| c[i]),
        })
    }
}

impl UnaryFunction for LinearUnaryFunction {
    fn nx(&self) -> usize {
        self.a.ncols()
    }
    fn ndx(&self) -> usize {
        self.a.ncols()
    }
    fn nr(&self) -> usize {
        self.a.nrows()
    }
    fn evaluate(&self, x: &[f64], data: &mut StageFunctionData) {
        let r = slice_mut(&mut data.value);
        r.copy_from_slice(slice(&self.c));
        matvec(r, Accum::Add, self.a.as_ref(), x, 1.0);
    }
    fn jacobian(&self, _x: &[f64], data: &mut StageFunctionData) {
        data.jx.copy_from(&self.a);
    }
    fn jacobian_is_constant(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{CheckOptions, check_stage_function};
    use crate::functions::Unary;
    use crate::functions::testing::{random_mat, random_vec, rng};
    use crate::spaces::VectorSpace;

    #[test]
    fn linear_functions_match_their_definition_and_finite_differences() {
        let mut g = rng(20);
        let (a, b, c) = (
            random_mat(&mut g, 4, 3, 1.0),
            random_mat(&mut g, 4, 2, 1.0),
            random_vec(&mut g, 4, 1.0),
        );
        let f = LinearFunction::new(a.as_ref(), b.as_ref(), &c).unwrap();
        let fu = Unary::new(
            std::sync::Arc::new(LinearUnaryFunction::new(a.as_ref(), &c).unwrap()),
            2,
        );
        let space = VectorSpace::new(3);
        let (mut d, mut du) = (f.create_data(), fu.create_data());
        for _ in 0..4 {
            let (x, u) = (random_vec(&mut g, 3, 1.0), random_vec(&mut g, 2, 1.0));
            f.evaluate(&x, &u, &mut d);
            fu.evaluate(&x, &u, &mut du);
            for i in 0..4 {
                let ax: f64 = c[i] + (0..3).map(|k| a[(i, k)] * x[k]).sum::<f64>();
                let bu: f64 = (0..2).map(|k| b[(i, k)] * u[k]).sum();
                assert!((d.value()[i] - ax - bu).abs() < 1e-14);
                assert!((du.value()[i] - ax).abs() < 1e-14);
            }
            check_stage_function(&f, &space, &x, &u, None, CheckOptions::default()).assert_ok();
            check_stage_function(&fu, &space, &x, &u, None, CheckOptions::default()).assert_ok();
        }
        let err = LinearFunction::new(a.as_ref(), random_mat(&mut g, 3, 2, 1.0).as_ref(), &c).unwrap_err();
        assert!(err.to_string().contains("LinearFunction B rows"), "{err}");
        let err = LinearFunction::new(a.as_ref(), b.as_ref(), &c[..2]).unwrap_err();
        assert!(err.to_string().contains("LinearFunction c"), "{err}");
        let mut bad = a.clone();
        bad[(0, 0)] = f64::NAN;
        assert!(LinearUnaryFunction::new(bad.as_ref(), &c).is_err());
    }
}

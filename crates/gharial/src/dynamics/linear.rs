//! Linear models: discrete `y = A x + B u + c` and continuous `ẋ = A x + B u + c`, on
//! vector spaces.

use std::sync::Arc;

use faer::{Accum, Col, Mat, MatRef};

use super::{ExplicitDynamics, ExplicitDynamicsData, Ode, OdeData};
use crate::Result;
use crate::functions::util::{checked_mat, checked_vec};
use crate::linalg::{matvec, slice, slice_mut};
use crate::spaces::{Manifold, VectorSpace};

/// Checked `(A, B, c)` with `A: n_out x n_in`, `B: n_out x nu`, `c: n_out`.
fn checked_abc(
    what: &str,
    a: MatRef<'_, f64>,
    b: MatRef<'_, f64>,
    c: &[f64],
    square: bool,
) -> Result<(Mat<f64>, Mat<f64>, Col<f64>)> {
    let n = a.nrows();
    let a = checked_mat(&format!("{what} A"), a, None, square.then_some(n))?;
    let b = checked_mat(&format!("{what} B"), b, Some(n), None)?;
    let c = checked_vec(&format!("{what} c"), c, n)?;
    Ok((a, b, Col::from_fn(n, |i| c[i])))
}

/// Discrete linear dynamics `y = A x + B u + c` (`A: ny x nx`, `B: ny x nu`), explicit.
///
/// Jacobians `A`, `B`; exact (no second-order term).
#[derive(Debug, Clone)]
pub struct LinearDiscreteDynamics {
    space: Arc<dyn Manifold>,
    space_next: Arc<dyn Manifold>,
    a: Mat<f64>,
    b: Mat<f64>,
    c: Col<f64>,
}

impl LinearDiscreteDynamics {
    /// `y = A x + B u + c` on `R^n`, with a square `A` (`n x n`).
    ///
    /// # Errors
    /// If `A` is not square, `B` or `c` do not have `n` rows, or an entry is not finite.
    pub fn new(a: MatRef<'_, f64>, b: MatRef<'_, f64>, c: &[f64]) -> Result<Self> {
        Self::build(a, b, c, true)
    }

    /// `y = A x + B u + c` from `R^{A.ncols()}` to `R^{A.nrows()}`: a stage whose next
    /// state has another dimension (e.g. a phase change).
    ///
    /// # Errors
    /// If `B` or `c` do not have `A.nrows()` rows, or an entry is not finite.
    pub fn between(a: MatRef<'_, f64>, b: MatRef<'_, f64>, c: &[f64]) -> Result<Self> {
        Self::build(a, b, c, false)
    }

    fn build(a: MatRef<'_, f64>, b: MatRef<'_, f64>, c: &[f64], square: bool) -> Result<Self> {
        let (a, b, c) = checked_abc("LinearDiscreteDynamics", a, b, c, square)?;
        Ok(Self {
            space: Arc::new(VectorSpace::new(a.ncols())),
            space_next: Arc::new(VectorSpace::new(a.nrows())),
            a,
            b,
            c,
        })
    }
}

impl ExplicitDynamics for LinearDiscreteDynamics {
    fn space(&self) -> &Arc<dyn Manifold> {
        &self.space
    }
    fn space_next(&self) -> &Arc<dyn Manifold> {
        &self.space_next
    }
    fn nu(&self) -> usize {
        self.b.ncols()
    }
    fn forward(&self, x: &[f64], u: &[f64], data: &mut ExplicitDynamicsData) {
        let y = slice_mut(&mut data.xnext);
        y.copy_from_slice(slice(&self.c));
        matvec(y, Accum::Add, self.a.as_ref(), x, 1.0);
        matvec(y, Accum::Add, self.b.as_ref(), u, 1.0);
    }
    fn jacobians(&self, _x: &[f64], _u: &[f64], data: &mut ExplicitDynamicsData) {
        crate::linalg::copy(data.jx.as_mut(), self.a.as_ref());
        crate::linalg::copy(data.ju.as_mut(), self.b.as_ref());
    }
    fn jacobians_are_constant(&self) -> bool {
        true
    }
}

/// The linear ODE `ẋ = A x + B u + c` on `R^n` (`A: n x n`).
#[derive(Debug, Clone)]
pub struct LinearOde {
    space: Arc<dyn Manifold>,
    a: Mat<f64>,
    b: Mat<f64>,
    c: Col<f64>,
}

impl LinearOde {
    /// `ẋ = A x + B u + c`.
    ///
    /// # Errors
    /// If `A` is not square, `B` or `c` do not have `A.nrows()` rows, or an entry is not
    /// finite.
    pub fn new(a: MatRef<'_, f64>, b: MatRef<'_, f64>, c: &[f64]) -> Result<Self> {
        let (a, b, c) = checked_abc("LinearOde", a, b, c, true)?;
        Ok(Self {
            space: Arc::new(VectorSpace::new(a.nrows())),
            a,
            b,
            c,
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

    /// The drift `c`.
    pub fn c(&self) -> &[f64] {
        slice(&self.c)
    }
}

impl Ode for LinearOde {
    fn space(&self) -> &Arc<dyn Manifold> {
        &self.space
    }
    fn nu(&self) -> usize {
        self.b.ncols()
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        let xdot = slice_mut(&mut data.xdot);
        xdot.copy_from_slice(slice(&self.c));
        matvec(xdot, Accum::Add, self.a.as_ref(), x, 1.0);
        matvec(xdot, Accum::Add, self.b.as_ref(), u, 1.0);
    }
    fn jacobians(&self, _x: &[f64], _u: &[f64], data: &mut OdeData) {
        crate::linalg::copy(data.jx.as_mut(), self.a.as_ref());
        crate::linalg::copy(data.ju.as_mut(), self.b.as_ref());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{CheckOptions, check_explicit_dynamics, check_ode};
    use crate::functions::testing::{random_mat, random_vec, rng};

    #[test]
    fn linear_models_match_their_definition_and_finite_differences() {
        let mut g = rng(60);
        let (a, b, c) = (
            random_mat(&mut g, 3, 4, 1.0),
            random_mat(&mut g, 3, 2, 1.0),
            random_vec(&mut g, 3, 1.0),
        );
        let err = LinearDiscreteDynamics::new(a.as_ref(), b.as_ref(), &c).unwrap_err();
        assert!(err.to_string().contains("LinearDiscreteDynamics A columns"), "{err}");
        let d = LinearDiscreteDynamics::between(a.as_ref(), b.as_ref(), &c).unwrap();
        assert_eq!((d.space().nx(), d.space_next().nx(), d.nu()), (4, 3, 2));
        let mut data = d.create_data();
        for _ in 0..3 {
            let (x, u) = (random_vec(&mut g, 4, 1.0), random_vec(&mut g, 2, 1.0));
            d.forward(&x, &u, &mut data);
            for i in 0..3 {
                let y = c[i]
                    + (0..4).map(|k| a[(i, k)] * x[k]).sum::<f64>()
                    + (0..2).map(|k| b[(i, k)] * u[k]).sum::<f64>();
                assert!((data.xnext()[i] - y).abs() < 1e-14);
            }
            check_explicit_dynamics(&d, &x, &u, CheckOptions::default()).assert_ok();
        }
        let err = LinearOde::new(a.as_ref(), b.as_ref(), &c).unwrap_err();
        assert!(err.to_string().contains("LinearOde A columns"), "{err}");
        let sq = random_mat(&mut g, 3, 3, 1.0);
        let ode = LinearOde::new(sq.as_ref(), b.as_ref(), &c).unwrap();
        let (x, u) = (random_vec(&mut g, 3, 1.0), random_vec(&mut g, 2, 1.0));
        check_ode(&ode, &x, &u, CheckOptions::default()).assert_ok();
        let err = LinearDiscreteDynamics::between(a.as_ref(), b.as_ref(), &c[..1]).unwrap_err();
        assert!(err.to_string().contains("LinearDiscreteDynamics c"), "{err}");
    }
}

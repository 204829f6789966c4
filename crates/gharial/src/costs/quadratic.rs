//! Quadratic costs on vector spaces and the constant cost.
#![allow(non_snake_case)]

use faer::{Accum, Col, Mat, MatRef};

use super::{Cost, CostData};
use crate::Result;
use crate::functions::Workspace;
use crate::functions::util::{checked_mat, checked_vec, downcast};
use crate::linalg::{matvec, matvec_t, slice, slice_mut};
use crate::spaces::Manifold;

/// `ℓ(x, u) = ½ [x; u]ᵀ [Q S; Sᵀ R] [x; u] + qᵀ x + rᵀ u` for a vector state
/// (`nx = ndx`).
///
/// `Q` and `R` are replaced by their symmetric parts `(Q + Qᵀ)/2`, `(R + Rᵀ)/2` (the
/// cost only depends on those). The Hessian is exact: `ℓ_xx = Q`, `ℓ_xu = S`,
/// `ℓ_uu = R`; the gradient is `ℓ_x = Q x + S u + q`, `ℓ_u = Sᵀ x + R u + r`.
#[derive(Debug, Clone)]
pub struct QuadraticCost {
    Q: Mat<f64>,
    S: Mat<f64>,
    R: Mat<f64>,
    q: Col<f64>,
    r: Col<f64>,
    /// The diagonals of `Q` and `R` when these are diagonal (the usual weights): the
    /// products reduce to entrywise ones, with the same results.
    q_diag: Option<Vec<f64>>,
    r_diag: Option<Vec<f64>>,
    /// Whether `S` is zero (its products are skipped).
    s_zero: bool,
}

/// The diagonal of a square matrix whose off-diagonal entries are all zero.
fn diagonal_of(m: MatRef<'_, f64>) -> Option<Vec<f64>> {
    let n = m.nrows();
    let off_zero = (0..n).all(|j| (0..n).all(|i| i == j || m[(i, j)] == 0.0));
    off_zero.then(|| (0..n).map(|i| m[(i, i)]).collect())
}

/// `y += (alpha x) ∘ d` (`Accum::Add`) or `y = (alpha x) ∘ d` (`Accum::Replace`): the
/// product by a diagonal matrix, in the order of operations of [`matvec`].
fn diag_matvec(y: &mut [f64], accum: Accum, d: &[f64], x: &[f64], alpha: f64) {
    for ((yi, di), xi) in y.iter_mut().zip(d).zip(x) {
        let v = (alpha * xi) * di;
        *yi = if accum == Accum::Replace { v } else { *yi + v };
    }
}

struct QuadraticWs {
    /// `Q x + S u` (`nx`).
    tx: Vec<f64>,
    /// `R u` (`nu`).
    tu: Vec<f64>,
}

impl QuadraticCost {
    /// The stage cost with blocks `Q (nx x nx)`, `S (nx x nu)`, `R (nu x nu)`,
    /// `q (nx)`, `r (nu)`.
    ///
    /// # Errors
    /// If a block has the wrong shape (the error names it) or a non-finite entry.
    pub fn new(Q: MatRef<'_, f64>, S: MatRef<'_, f64>, R: MatRef<'_, f64>, q: &[f64], r: &[f64]) -> Result<Self> {
        let (nx, nu) = (Q.nrows(), R.nrows());
        let mut Q = checked_mat("QuadraticCost Q", Q, Some(nx), Some(nx))?;
        let S = checked_mat("QuadraticCost S", S, Some(nx), Some(nu))?;
        let mut R = checked_mat("QuadraticCost R", R, Some(nu), Some(nu))?;
        let q = checked_vec("QuadraticCost q", q, nx)?;
        let r = checked_vec("QuadraticCost r", r, nu)?;
        crate::linalg::symmetrize(Q.as_mut());
        crate::linalg::symmetrize(R.as_mut());
        Ok(Self {
            q_diag: diagonal_of(Q.as_ref()),
            r_diag: diagonal_of(R.as_ref()),
            s_zero: crate::linalg::norm_max(S.as_ref()) == 0.0,
            Q,
            S,
            R,
            q: Col::from_fn(nx, |i| q[i]),
            r: Col::from_fn(nu, |i| r[i]),
        })
    }

    /// `y (+)= alpha Q x`.
    fn q_times(&self, y: &mut [f64], accum: Accum, x: &[f64], alpha: f64) {
        match &self.q_diag {
            Some(d) => diag_matvec(y, accum, d, x, alpha),
            None => matvec(y, accum, self.Q.as_ref(), x, alpha),
        }
    }

    /// `y (+)= alpha R u`.
    fn r_times(&self, y: &mut [f64], accum: Accum, u: &[f64], alpha: f64) {
        match &self.r_diag {
            Some(d) => diag_matvec(y, accum, d, u, alpha),
            None => matvec(y, accum, self.R.as_ref(), u, alpha),
        }
    }

    /// The terminal cost `½ xᵀ Q x + qᵀ x` (`nu = 0`).
    ///
    /// # Errors
    /// As [`QuadraticCost::new`].
    pub fn terminal(Q: MatRef<'_, f64>, q: &[f64]) -> Result<Self> {
        let nx = Q.nrows();
        Self::new(Q, Mat::zeros(nx, 0).as_ref(), Mat::zeros(0, 0).as_ref(), q, &[])
    }
}

impl Cost for QuadraticCost {
    fn nx(&self) -> usize {
        self.Q.nrows()
    }
    fn ndx(&self) -> usize {
        self.Q.nrows()
    }
    fn nu(&self) -> usize {
        self.R.nrows()
    }
    fn create_workspace(&self) -> Workspace {
        Box::new(QuadraticWs {
            tx: vec![0.0; self.nx()],
            tu: vec![0.0; self.nu()],
        })
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        let ws: &mut QuadraticWs = downcast(&mut data.ws);
        // ℓ = ½ xᵀ(Q x + 2 S u) + ½ uᵀ R u + qᵀ x + rᵀ u.
        self.q_times(&mut ws.tx, Accum::Replace, x, 0.5);
        if !self.s_zero {
            matvec(&mut ws.tx, Accum::Add, self.S.as_ref(), u, 1.0);
        }
        self.r_times(&mut ws.tu, Accum::Replace, u, 0.5);
        let (q, r) = (slice(&self.q), slice(&self.r));
        let vx: f64 = (0..x.len()).map(|i| x[i] * (ws.tx[i] + q[i])).sum();
        let vu: f64 = (0..u.len()).map(|i| u[i] * (ws.tu[i] + r[i])).sum();
        data.value = vx + vu;
    }
    fn derivatives(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        self.gradient(x, u, data);
        crate::linalg::copy(data.lxx.as_mut(), self.Q.as_ref());
        crate::linalg::copy(data.lxu.as_mut(), self.S.as_ref());
        crate::linalg::copy(data.luu.as_mut(), self.R.as_ref());
    }
    fn hessian_is_constant(&self) -> bool {
        true
    }
    fn gradient(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        let lx = slice_mut(&mut data.lx);
        lx.copy_from_slice(slice(&self.q));
        self.q_times(lx, Accum::Add, x, 1.0);
        let lu = slice_mut(&mut data.lu);
        lu.copy_from_slice(slice(&self.r));
        if !self.s_zero {
            matvec(lx, Accum::Add, self.S.as_ref(), u, 1.0);
            matvec_t(lu, Accum::Add, self.S.as_ref(), x, 1.0);
        }
        self.r_times(lu, Accum::Add, u, 1.0);
    }
}

/// The constant cost `ℓ(x, u) = c` (zero derivatives); `c = 0` is "no cost", e.g. no
/// terminal cost.
#[derive(Debug, Clone)]
pub struct ConstantCost {
    nx: usize,
    ndx: usize,
    nu: usize,
    value: f64,
}

impl ConstantCost {
    /// `ℓ = value` for states of `space` and `nu` controls.
    ///
    /// # Errors
    /// If `value` is not finite.
    pub fn new(space: &dyn Manifold, nu: usize, value: f64) -> Result<Self> {
        crate::error::check_finite("ConstantCost value", &[value])?;
        Ok(Self {
            nx: space.nx(),
            ndx: space.ndx(),
            nu,
            value,
        })
    }

    /// `ℓ = 0`.
    pub fn zero(space: &dyn Manifold, nu: usize) -> Self {
        Self {
            nx: space.nx(),
            ndx: space.ndx(),
            nu,
            value: 0.0,
        }
    }
}

impl Cost for ConstantCost {
    fn nx(&self) -> usize {
        self.nx
    }
    fn ndx(&self) -> usize {
        self.ndx
    }
    fn nu(&self) -> usize {
        self.nu
    }
    fn evaluate(&self, _x: &[f64], _u: &[f64], data: &mut CostData) {
        data.value = self.value;
    }
    fn derivatives(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        self.gradient(x, u, data);
        data.lxx.fill(0.0);
        data.lxu.fill(0.0);
        data.luu.fill(0.0);
    }
    fn hessian_is_constant(&self) -> bool {
        true
    }
    fn gradient(&self, _x: &[f64], _u: &[f64], data: &mut CostData) {
        data.lx.fill(0.0);
        data.lu.fill(0.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{CheckOptions, check_cost};
    use crate::functions::testing::{dual_check_cost, random_mat, random_vec, rng};
    use crate::spaces::VectorSpace;
    use num_dual::DualNum;

    /// `½ zᵀ H z + hᵀ z` for `z = [x; u]`, written from the unsymmetrised blocks.
    fn quad_ref<D: DualNum<Primitive = f64> + Copy>(z: &[D], h: &Mat<f64>, lin: &[f64]) -> D {
        let n = z.len();
        let mut v = D::from(0.0);
        for i in 0..n {
            v += z[i] * lin[i];
            for j in 0..n {
                v += z[i] * z[j] * (0.5 * h[(i, j)]);
            }
        }
        v
    }

    #[test]
    fn quadratic_cost_matches_its_formula_and_dual_numbers() {
        let mut g = rng(30);
        let (nx, nu) = (4, 3);
        // Deliberately non-symmetric blocks: the cost depends on their symmetric parts.
        let (q_mat, s, r_mat) = (
            random_mat(&mut g, nx, nx, 1.0),
            random_mat(&mut g, nx, nu, 1.0),
            random_mat(&mut g, nu, nu, 1.0),
        );
        let (q, r) = (random_vec(&mut g, nx, 1.0), random_vec(&mut g, nu, 1.0));
        let cost = QuadraticCost::new(q_mat.as_ref(), s.as_ref(), r_mat.as_ref(), &q, &r).unwrap();
        // H = [[Q, S], [Sᵀ, R]] (not symmetric), lin = [q; r].
        let h = Mat::from_fn(nx + nu, nx + nu, |i, j| match (i < nx, j < nx) {
            (true, true) => q_mat[(i, j)],
            (true, false) => s[(i, j - nx)],
            (false, true) => s[(j, i - nx)],
            (false, false) => r_mat[(i - nx, j - nx)],
        });
        let lin: Vec<f64> = q.iter().chain(&r).copied().collect();
        let space = VectorSpace::new(nx);
        for _ in 0..4 {
            let (x, u) = (random_vec(&mut g, nx, 1.0), random_vec(&mut g, nu, 1.0));
            check_cost(&cost, &space, &x, &u, CheckOptions::default()).assert_ok();
            dual_check_cost(&cost, &x, &u, |z| quad_ref(z, &h, &lin), true, 1e-12);
        }
        let t = QuadraticCost::terminal(q_mat.as_ref(), &q).unwrap();
        assert_eq!(t.nu(), 0);
        let hx = q_mat.clone();
        let x = random_vec(&mut g, nx, 1.0);
        check_cost(&t, &space, &x, &[], CheckOptions::default()).assert_ok();
        dual_check_cost(&t, &x, &[], |z| quad_ref(z, &hx, &q), true, 1e-12);

        let err = QuadraticCost::new(
            q_mat.as_ref(),
            s.as_ref().submatrix(0, 0, nx, 2),
            r_mat.as_ref(),
            &q,
            &r,
        )
        .unwrap_err();
        assert!(err.to_string().contains("QuadraticCost S columns"), "{err}");
        let err = QuadraticCost::new(q_mat.as_ref(), s.as_ref(), r_mat.as_ref(), &q, &r[..1]).unwrap_err();
        assert!(err.to_string().contains("QuadraticCost r"), "{err}");
        let err = QuadraticCost::terminal(s.as_ref(), &q).unwrap_err();
        assert!(err.to_string().contains("QuadraticCost Q columns"), "{err}");
    }

    #[test]
    fn diagonal_weights_and_zero_cross_term_match_the_dense_formula() {
        // The entrywise products of diagonal Q, R and the skipped zero S: against the
        // dense formula with dual numbers, and bit for bit against the dense products on
        // the same matrices (the same cost with its structure flags cleared).
        let mut g = rng(31);
        let (nx, nu) = (5, 3);
        let qd = random_vec(&mut g, nx, 1.0);
        let rd = random_vec(&mut g, nu, 1.0);
        let q_mat = Mat::from_fn(nx, nx, |i, j| if i == j { qd[i].abs() + 0.5 } else { 0.0 });
        let r_mat = Mat::from_fn(nu, nu, |i, j| if i == j { rd[i].abs() + 0.5 } else { 0.0 });
        let s = Mat::<f64>::zeros(nx, nu);
        let (q, r) = (random_vec(&mut g, nx, 1.0), random_vec(&mut g, nu, 1.0));
        let cost = QuadraticCost::new(q_mat.as_ref(), s.as_ref(), r_mat.as_ref(), &q, &r).unwrap();
        assert!(cost.q_diag.is_some() && cost.r_diag.is_some() && cost.s_zero);
        let h = Mat::from_fn(nx + nu, nx + nu, |i, j| match (i < nx, j < nx) {
            (true, true) => q_mat[(i, j)],
            (false, false) => r_mat[(i - nx, j - nx)],
            _ => 0.0,
        });
        let lin: Vec<f64> = q.iter().chain(&r).copied().collect();
        let space = VectorSpace::new(nx);
        let mut dense = cost.clone();
        (dense.q_diag, dense.r_diag, dense.s_zero) = (None, None, false);
        for _ in 0..4 {
            let (x, u) = (random_vec(&mut g, nx, 1.0), random_vec(&mut g, nu, 1.0));
            check_cost(&cost, &space, &x, &u, CheckOptions::default()).assert_ok();
            dual_check_cost(&cost, &x, &u, |z| quad_ref(z, &h, &lin), true, 1e-12);
            let (mut a, mut b) = (cost.create_data(), dense.create_data());
            cost.evaluate(&x, &u, &mut a);
            dense.evaluate(&x, &u, &mut b);
            cost.derivatives(&x, &u, &mut a);
            dense.derivatives(&x, &u, &mut b);
            assert_eq!(a.value, b.value);
            assert_eq!(a.lx(), b.lx());
            assert_eq!(a.lu(), b.lu());
        }
        // A single nonzero off-diagonal entry keeps the dense products.
        let mut q_full = q_mat.clone();
        q_full[(0, 1)] = 0.25;
        let c = QuadraticCost::new(q_full.as_ref(), s.as_ref(), r_mat.as_ref(), &q, &r).unwrap();
        assert!(c.q_diag.is_none() && c.r_diag.is_some());
    }

    #[test]
    fn constant_cost_has_zero_derivatives() {
        let space = VectorSpace::new(2);
        let c = ConstantCost::new(&space, 1, 2.5).unwrap();
        let mut d = c.create_data();
        d.lx.fill(7.0);
        c.evaluate(&[0.3, 0.1], &[1.0], &mut d);
        c.derivatives(&[0.3, 0.1], &[1.0], &mut d);
        assert_eq!(d.value, 2.5);
        assert_eq!(crate::linalg::norm_inf(d.lx()), 0.0);
        check_cost(&c, &space, &[0.3, 0.1], &[1.0], CheckOptions::default()).assert_ok();
        assert!(ConstantCost::new(&space, 0, f64::NAN).is_err());
        assert_eq!(ConstantCost::zero(&space, 0).nu(), 0);
    }
}

//! Functions built from other stage functions of the same `(x, u)`:
//! - [`Slice`]: selected rows `r_S(x, u) = (r_{i})_{i ∈ S}`;
//! - [`LinearComposition`]: `M r(x, u) + b`;
//! - [`FunctionStack`]: `[r_1(x, u); r_2(x, u); ...]`.
//!
//! Second derivatives follow from the inner functions' vector-Hessian products:
//! `d²(λᵀ r_S) = d²((Pᵀλ)ᵀ r)` with `P` the row selection, `d²(λᵀ (M r + b)) =
//! d²((Mᵀλ)ᵀ r)` and `d²(λᵀ [r_1; r_2]) = d²(λ_1ᵀ r_1) + d²(λ_2ᵀ r_2)`.

use std::ops::Range;
use std::sync::Arc;

use faer::{Accum, Col, Mat, MatRef};

use super::util::{add_scaled, checked_mat, checked_vec, downcast};
use super::{StageFunction, StageFunctionData, Workspace};
use crate::linalg::{matmul, matvec, matvec_t, slice};
use crate::{Error, Result};

impl std::fmt::Debug for Slice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Slice")
            .field("rows", &self.rows)
            .finish_non_exhaustive()
    }
}

impl std::fmt::Debug for LinearComposition {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LinearComposition")
            .field("m", &self.m)
            .field("b", &self.b)
            .finish_non_exhaustive()
    }
}

impl std::fmt::Debug for FunctionStack {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FunctionStack")
            .field("offsets", &self.offsets)
            .finish_non_exhaustive()
    }
}

/// Selected rows of another stage function: `r_S(x, u)_k = r(x, u)_{rows[k]}`.
#[derive(Clone)]
pub struct Slice {
    f: Arc<dyn StageFunction>,
    rows: Vec<usize>,
}

struct InnerWs {
    inner: StageFunctionData,
    /// Multiplier seen by the inner function.
    lambda: Vec<f64>,
}

impl Slice {
    /// The rows `rows` (any order, repetitions allowed) of `f`.
    ///
    /// # Errors
    /// If a row index is not below `f.nr()`.
    pub fn new(f: Arc<dyn StageFunction>, rows: &[usize]) -> Result<Self> {
        if let Some(&bad) = rows.iter().find(|&&i| i >= f.nr()) {
            return Err(Error::InvalidModel(format!(
                "Slice: row index {bad} out of range for a function with nr = {}",
                f.nr()
            )));
        }
        Ok(Self { f, rows: rows.to_vec() })
    }

    /// The contiguous rows `range` of `f`.
    ///
    /// # Errors
    /// If the range does not lie within `0..f.nr()`.
    pub fn range(f: Arc<dyn StageFunction>, range: Range<usize>) -> Result<Self> {
        let rows: Vec<usize> = range.collect();
        Self::new(f, &rows)
    }

    /// The selected rows.
    pub fn rows(&self) -> &[usize] {
        &self.rows
    }
}

impl StageFunction for Slice {
    fn nx(&self) -> usize {
        self.f.nx()
    }
    fn ndx(&self) -> usize {
        self.f.ndx()
    }
    fn nu(&self) -> usize {
        self.f.nu()
    }
    fn nr(&self) -> usize {
        self.rows.len()
    }
    fn create_workspace(&self) -> Workspace {
        Box::new(InnerWs {
            inner: self.f.create_data(),
            lambda: vec![0.0; self.f.nr()],
        })
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let ws: &mut InnerWs = downcast(&mut data.ws);
        self.f.evaluate(x, u, &mut ws.inner);
        let r = crate::linalg::slice_mut(&mut data.value);
        for (k, &i) in self.rows.iter().enumerate() {
            r[k] = ws.inner.value[i];
        }
    }
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let ws: &mut InnerWs = downcast(&mut data.ws);
        self.f.jacobians(x, u, &mut ws.inner);
        for (k, &i) in self.rows.iter().enumerate() {
            data.jx.row_mut(k).copy_from(ws.inner.jx.row(i));
            data.ju.row_mut(k).copy_from(ws.inner.ju.row(i));
        }
    }
    fn has_vhp(&self) -> bool {
        self.f.has_vhp()
    }
    fn jacobians_are_constant(&self) -> bool {
        self.f.jacobians_are_constant()
    }
    fn vhp(&self, x: &[f64], u: &[f64], lambda: &[f64], data: &mut StageFunctionData) {
        let ws: &mut InnerWs = downcast(&mut data.ws);
        ws.lambda.fill(0.0);
        for (k, &i) in self.rows.iter().enumerate() {
            ws.lambda[i] += lambda[k];
        }
        self.f.vhp(x, u, &ws.lambda, &mut ws.inner);
        let inner = &ws.inner;
        data.vhp_xx.copy_from(&inner.vhp_xx);
        data.vhp_xu.copy_from(&inner.vhp_xu);
        data.vhp_uu.copy_from(&inner.vhp_uu);
    }
}

/// `r(x, u) = M f(x, u) + b` with `M: nr x f.nr()`, `b: nr`.
#[derive(Clone)]
pub struct LinearComposition {
    f: Arc<dyn StageFunction>,
    m: Mat<f64>,
    b: Col<f64>,
}

impl LinearComposition {
    /// `M f(x, u) + b`.
    ///
    /// # Errors
    /// If `M` does not have `f.nr()` columns, `b` does not have `M.nrows()` entries, or
    /// an entry is not finite.
    pub fn new(f: Arc<dyn StageFunction>, m: MatRef<'_, f64>, b: &[f64]) -> Result<Self> {
        let m = checked_mat("LinearComposition M", m, None, Some(f.nr()))?;
        let b = checked_vec("LinearComposition b", b, m.nrows())?;
        Ok(Self {
            f,
            b: Col::from_fn(m.nrows(), |i| b[i]),
            m,
        })
    }
}

impl StageFunction for LinearComposition {
    fn nx(&self) -> usize {
        self.f.nx()
    }
    fn ndx(&self) -> usize {
        self.f.ndx()
    }
    fn nu(&self) -> usize {
        self.f.nu()
    }
    fn nr(&self) -> usize {
        self.m.nrows()
    }
    fn create_workspace(&self) -> Workspace {
        Box::new(InnerWs {
            inner: self.f.create_data(),
            lambda: vec![0.0; self.f.nr()],
        })
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let ws: &mut InnerWs = downcast(&mut data.ws);
        self.f.evaluate(x, u, &mut ws.inner);
        let r = crate::linalg::slice_mut(&mut data.value);
        r.copy_from_slice(slice(&self.b));
        matvec(r, Accum::Add, self.m.as_ref(), ws.inner.value(), 1.0);
    }
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let ws: &mut InnerWs = downcast(&mut data.ws);
        self.f.jacobians(x, u, &mut ws.inner);
        matmul(
            data.jx.as_mut(),
            Accum::Replace,
            self.m.as_ref(),
            ws.inner.jx.as_ref(),
            1.0,
        );
        matmul(
            data.ju.as_mut(),
            Accum::Replace,
            self.m.as_ref(),
            ws.inner.ju.as_ref(),
            1.0,
        );
    }
    fn has_vhp(&self) -> bool {
        self.f.has_vhp()
    }
    fn jacobians_are_constant(&self) -> bool {
        self.f.jacobians_are_constant()
    }
    fn vhp(&self, x: &[f64], u: &[f64], lambda: &[f64], data: &mut StageFunctionData) {
        let ws: &mut InnerWs = downcast(&mut data.ws);
        matvec_t(&mut ws.lambda, Accum::Replace, self.m.as_ref(), lambda, 1.0);
        self.f.vhp(x, u, &ws.lambda, &mut ws.inner);
        let inner = &ws.inner;
        data.vhp_xx.copy_from(&inner.vhp_xx);
        data.vhp_xu.copy_from(&inner.vhp_xu);
        data.vhp_uu.copy_from(&inner.vhp_uu);
    }
}

/// Stacked functions of the same `(x, u)`: `r = [r_1; r_2; ...]`.
#[derive(Clone)]
pub struct FunctionStack {
    fs: Vec<Arc<dyn StageFunction>>,
    offsets: Vec<usize>,
}

impl FunctionStack {
    /// Stacks `fs` (at least one function, all with the same `nx`, `ndx`, `nu`).
    ///
    /// # Errors
    /// If `fs` is empty or the dimensions differ (the error names the function index).
    pub fn new(fs: Vec<Arc<dyn StageFunction>>) -> Result<Self> {
        let first = fs
            .first()
            .ok_or_else(|| Error::InvalidModel("FunctionStack: no function given".into()))?;
        let (nx, ndx, nu) = (first.nx(), first.ndx(), first.nu());
        let mut offsets = vec![0];
        for (k, f) in fs.iter().enumerate() {
            crate::error::check_dim(format!("FunctionStack: nx of function {k}"), nx, f.nx())?;
            crate::error::check_dim(format!("FunctionStack: ndx of function {k}"), ndx, f.ndx())?;
            crate::error::check_dim(format!("FunctionStack: nu of function {k}"), nu, f.nu())?;
            offsets.push(offsets[k] + f.nr());
        }
        Ok(Self { fs, offsets })
    }

    /// Rows of function `k` in the stacked output.
    pub fn rows_of(&self, k: usize) -> Range<usize> {
        self.offsets[k]..self.offsets[k + 1]
    }
}

impl StageFunction for FunctionStack {
    fn nx(&self) -> usize {
        self.fs[0].nx()
    }
    fn ndx(&self) -> usize {
        self.fs[0].ndx()
    }
    fn nu(&self) -> usize {
        self.fs[0].nu()
    }
    fn nr(&self) -> usize {
        *self.offsets.last().expect("offsets start with 0")
    }
    fn create_workspace(&self) -> Workspace {
        let datas: Vec<StageFunctionData> = self.fs.iter().map(|f| f.create_data()).collect();
        Box::new(datas)
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let datas: &mut Vec<StageFunctionData> = downcast(&mut data.ws);
        let r = crate::linalg::slice_mut(&mut data.value);
        for (k, (f, d)) in self.fs.iter().zip(datas.iter_mut()).enumerate() {
            f.evaluate(x, u, d);
            r[self.rows_of(k)].copy_from_slice(d.value());
        }
    }
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let datas: &mut Vec<StageFunctionData> = downcast(&mut data.ws);
        for (k, (f, d)) in self.fs.iter().zip(datas.iter_mut()).enumerate() {
            f.jacobians(x, u, d);
            let (start, n) = (self.offsets[k], f.nr());
            data.jx.as_mut().subrows_mut(start, n).copy_from(&d.jx);
            data.ju.as_mut().subrows_mut(start, n).copy_from(&d.ju);
        }
    }
    fn has_vhp(&self) -> bool {
        self.fs.iter().any(|f| f.has_vhp())
    }
    fn jacobians_are_constant(&self) -> bool {
        self.fs.iter().all(|f| f.jacobians_are_constant())
    }
    fn vhp(&self, x: &[f64], u: &[f64], lambda: &[f64], data: &mut StageFunctionData) {
        let datas: &mut Vec<StageFunctionData> = downcast(&mut data.ws);
        data.vhp_xx.fill(0.0);
        data.vhp_xu.fill(0.0);
        data.vhp_uu.fill(0.0);
        for (k, (f, d)) in self.fs.iter().zip(datas.iter_mut()).enumerate() {
            if !f.has_vhp() {
                continue;
            }
            f.vhp(x, u, &lambda[self.rows_of(k)], d);
            add_scaled(data.vhp_xx.as_mut(), 1.0, d.vhp_xx.as_ref());
            add_scaled(data.vhp_xu.as_mut(), 1.0, d.vhp_xu.as_ref());
            add_scaled(data.vhp_uu.as_mut(), 1.0, d.vhp_uu.as_ref());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{CheckOptions, check_stage_function};
    use crate::functions::testing::{TestFunction, dual_check_stage, random_mat, random_vec, rng, test_fn};
    use crate::spaces::VectorSpace;
    use num_dual::DualNum;

    fn points(seed: u64) -> Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> {
        let mut g = rng(seed);
        (0..5)
            .map(|_| {
                (
                    random_vec(&mut g, 3, 1.0),
                    random_vec(&mut g, 2, 1.0),
                    random_vec(&mut g, 8, 1.0),
                )
            })
            .collect()
    }

    /// The compositions of this module written generically, as references.
    fn slice_ref<D: DualNum<Primitive = f64> + Copy>(z: &[D], rows: &[usize]) -> Vec<D> {
        let r = test_fn(&z[..3], &z[3..]);
        rows.iter().map(|&i| r[i]).collect()
    }

    fn compose_ref<D: DualNum<Primitive = f64> + Copy>(z: &[D], m: &Mat<f64>, b: &[f64]) -> Vec<D> {
        let r = test_fn(&z[..3], &z[3..]);
        (0..m.nrows())
            .map(|i| (0..3).fold(D::from(b[i]), |acc, k| acc + r[k] * m[(i, k)]))
            .collect()
    }

    fn linear_ref<D: DualNum<Primitive = f64> + Copy>(z: &[D], a: &Mat<f64>, b: &Mat<f64>, c: &[f64]) -> Vec<D> {
        let nx = a.ncols();
        (0..a.nrows())
            .map(|i| {
                let ax = (0..nx).fold(D::from(c[i]), |acc, k| acc + z[k] * a[(i, k)]);
                (0..b.ncols()).fold(ax, |acc, k| acc + z[nx + k] * b[(i, k)])
            })
            .collect()
    }

    #[test]
    fn slice_matches_finite_differences_and_dual_numbers() {
        let f: Arc<dyn StageFunction> = Arc::new(TestFunction);
        let rows = [2, 0, 2];
        let s = Slice::new(f.clone(), &rows).unwrap();
        assert_eq!(s.nr(), 3);
        let space = VectorSpace::new(3);
        for (x, u, l) in points(1) {
            check_stage_function(&s, &space, &x, &u, Some(&l[..3]), CheckOptions::default()).assert_ok();
            dual_check_stage(
                &s,
                &x,
                &u,
                &l[..3],
                |z| slice_ref(z, &rows),
                |z| slice_ref(z, &rows),
                1e-12,
            );
        }
        let r = Slice::range(f.clone(), 1..3).unwrap();
        assert_eq!(r.rows(), &[1, 2]);
        assert!(Slice::new(f.clone(), &[0, 3]).is_err());
        assert!(Slice::range(f, 2..4).is_err());
    }

    #[test]
    fn linear_composition_matches_finite_differences_and_dual_numbers() {
        let mut g = rng(2);
        let m = random_mat(&mut g, 4, 3, 1.0);
        let b = random_vec(&mut g, 4, 1.0);
        let f: Arc<dyn StageFunction> = Arc::new(TestFunction);
        let c = LinearComposition::new(f.clone(), m.as_ref(), &b).unwrap();
        let space = VectorSpace::new(3);
        for (x, u, l) in points(3) {
            check_stage_function(&c, &space, &x, &u, Some(&l[..4]), CheckOptions::default()).assert_ok();
            dual_check_stage(
                &c,
                &x,
                &u,
                &l[..4],
                |z| compose_ref(z, &m, &b),
                |z| compose_ref(z, &m, &b),
                1e-12,
            );
        }
        let err = LinearComposition::new(f.clone(), m.as_ref().submatrix(0, 0, 4, 2), &b).unwrap_err();
        assert!(err.to_string().contains("LinearComposition M columns"), "{err}");
        let err = LinearComposition::new(f, m.as_ref(), &b[..3]).unwrap_err();
        assert!(err.to_string().contains("LinearComposition b"), "{err}");
    }

    #[test]
    fn function_stack_matches_finite_differences_and_dual_numbers() {
        let mut g = rng(4);
        let m = random_mat(&mut g, 2, 3, 1.0);
        let b = random_vec(&mut g, 2, 1.0);
        let f: Arc<dyn StageFunction> = Arc::new(TestFunction);
        let lin = crate::functions::LinearFunction::new(
            random_mat(&mut g, 2, 3, 1.0).as_ref(),
            random_mat(&mut g, 2, 2, 1.0).as_ref(),
            &random_vec(&mut g, 2, 1.0),
        )
        .unwrap();
        let (la, lb, lc) = (lin.a().to_owned(), lin.b().to_owned(), lin.c().to_vec());
        let comp: Arc<dyn StageFunction> = Arc::new(LinearComposition::new(f.clone(), m.as_ref(), &b).unwrap());
        let stack = FunctionStack::new(vec![f.clone(), Arc::new(lin), comp]).unwrap();
        assert_eq!(stack.nr(), 7);
        assert_eq!(stack.rows_of(1), 3..5);
        let reference = |z: &[_]| {
            let mut out = test_fn(&z[..3], &z[3..]);
            out.extend(linear_ref(z, &la, &lb, &lc));
            out.extend(compose_ref(z, &m, &b));
            out
        };
        let reference2 = |z: &[_]| {
            let mut out = test_fn(&z[..3], &z[3..]);
            out.extend(linear_ref(z, &la, &lb, &lc));
            out.extend(compose_ref(z, &m, &b));
            out
        };
        let space = VectorSpace::new(3);
        for (x, u, l) in points(5) {
            check_stage_function(&stack, &space, &x, &u, Some(&l[..7]), CheckOptions::default()).assert_ok();
            dual_check_stage(&stack, &x, &u, &l[..7], reference, reference2, 1e-12);
        }
        assert!(FunctionStack::new(vec![]).is_err());
        let other: Arc<dyn StageFunction> = Arc::new(crate::functions::Unary::new(
            Arc::new(crate::functions::StateError::new(Arc::new(VectorSpace::new(3)), &[0.0; 3]).unwrap()),
            1,
        ));
        let err = FunctionStack::new(vec![f, other]).unwrap_err();
        assert!(err.to_string().contains("nu of function 1"), "{err}");
    }
}

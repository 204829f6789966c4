//! A weighted sum of named costs whose weights can change without reallocation.

use std::sync::Arc;

use faer::reborrow::ReborrowMut;
use faer::{Mat, MatMut};

use super::{Cost, CostData, CostParts, DerivativesMut, HessianMut};
use crate::functions::Workspace;
use crate::functions::util::downcast;
use crate::linalg::{copy, is_zero, symmetrize_from_lower};
use crate::param::ParamVec;
use crate::spaces::Manifold;
use crate::{Error, Result};

/// `ℓ(x, u) = Σ_k w_k ℓ_k(x, u)` over named components.
///
/// Weights live in a [`ParamVec`]: [`CostStack::set_weight`] works through `&self` on a
/// stack shared with a solver, between solves, without touching the solver's data.
/// Components with weight 0 are evaluated but do not contribute (so a component that is
/// switched off cannot inject an infinite value). An empty stack is the zero cost.
#[derive(Clone)]
pub struct CostStack {
    nx: usize,
    ndx: usize,
    nu: usize,
    names: Vec<String>,
    costs: Vec<Arc<dyn Cost>>,
    weights: ParamVec,
}

impl std::fmt::Debug for CostStack {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CostStack")
            .field("names", &self.names)
            .field("weights", &self.weights.to_vec())
            .finish_non_exhaustive()
    }
}

/// The stack's workspace: the components' data, and the weighted sum of the Hessians of
/// its components with constant Hessians.
struct StackWorkspace {
    datas: Vec<CostData>,
    /// Whether each component's data has been through a derivatives call (so that its
    /// constant blocks may be reused: a component of weight 0 is skipped).
    written: Vec<bool>,
    /// `Σ w_k ∇²ℓ_k` over the components with a constant Hessian: `lxx`, `lxu`, `luu`
    /// (lower triangles of the symmetric ones).
    constant: [Mat<f64>; 3],
    /// Which of the blocks of `constant` are nonzero.
    constant_nonzero: [bool; 3],
    /// The weights `constant` was formed with (NaN: not formed yet).
    constant_weights: Vec<f64>,
    /// Where the gradients go while `constant` is formed (`ndx + nu`).
    gradient_scratch: Vec<f64>,
}

fn check_weight(name: &str, w: f64) -> Result<()> {
    if !(w.is_finite() && w >= 0.0) {
        return Err(Error::option(
            format!("CostStack weight of `{name}`"),
            format!("must be finite and >= 0, got {}", crate::error::Num(w)),
        ));
    }
    Ok(())
}

impl CostStack {
    /// An empty stack for states of `space` and `nu` controls (`nu = 0`: terminal).
    pub fn new(space: &dyn Manifold, nu: usize) -> Self {
        Self {
            nx: space.nx(),
            ndx: space.ndx(),
            nu,
            names: Vec::new(),
            costs: Vec::new(),
            weights: ParamVec::new(&[]),
        }
    }

    /// Adds the component `name` with weight `weight` (builder style).
    ///
    /// # Errors
    /// If the name is already used, the weight is negative or not finite, or the
    /// cost's dimensions differ from the stack's (the error names the component).
    pub fn with(mut self, name: impl Into<String>, cost: Arc<dyn Cost>, weight: f64) -> Result<Self> {
        let name = name.into();
        if self.names.contains(&name) {
            return Err(Error::InvalidModel(format!(
                "CostStack: duplicate component name `{name}`"
            )));
        }
        check_weight(&name, weight)?;
        crate::error::check_dim(format!("CostStack component `{name}`: nx"), self.nx, cost.nx())?;
        crate::error::check_dim(format!("CostStack component `{name}`: ndx"), self.ndx, cost.ndx())?;
        crate::error::check_dim(format!("CostStack component `{name}`: nu"), self.nu, cost.nu())?;
        let mut w = self.weights.to_vec();
        w.push(weight);
        self.weights = ParamVec::new(&w);
        self.names.push(name);
        self.costs.push(cost);
        Ok(self)
    }

    fn index(&self, name: &str) -> Result<usize> {
        self.names.iter().position(|n| n == name).ok_or_else(|| {
            Error::InvalidModel(format!(
                "CostStack: no component named `{name}` (have {:?})",
                self.names
            ))
        })
    }

    /// Changes the weight of component `name` (through `&self`, no reallocation).
    ///
    /// # Errors
    /// If there is no such component, or the weight is negative or not finite.
    pub fn set_weight(&self, name: &str, weight: f64) -> Result<()> {
        let k = self.index(name)?;
        check_weight(name, weight)?;
        self.weights.set(k, weight);
        Ok(())
    }

    /// The weight of component `name`.
    ///
    /// # Errors
    /// If there is no such component.
    pub fn weight(&self, name: &str) -> Result<f64> {
        Ok(self.weights.get(self.index(name)?))
    }

    /// The component `name`, if any.
    pub fn get(&self, name: &str) -> Option<&Arc<dyn Cost>> {
        self.index(name).ok().map(|k| &self.costs[k])
    }

    /// Component names, in order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Number of components.
    pub fn len(&self) -> usize {
        self.costs.len()
    }

    /// Whether the stack has no component.
    pub fn is_empty(&self) -> bool {
        self.costs.is_empty()
    }
}

impl Cost for CostStack {
    fn nx(&self) -> usize {
        self.nx
    }
    fn ndx(&self) -> usize {
        self.ndx
    }
    fn nu(&self) -> usize {
        self.nu
    }
    fn create_workspace(&self) -> Workspace {
        let (ndx, nu, n) = (self.ndx, self.nu, self.costs.len());
        Box::new(StackWorkspace {
            datas: self.costs.iter().map(|c| c.create_data()).collect(),
            written: vec![false; n],
            constant: [Mat::zeros(ndx, ndx), Mat::zeros(ndx, nu), Mat::zeros(nu, nu)],
            constant_nonzero: [false; 3],
            constant_weights: vec![f64::NAN; n],
            gradient_scratch: vec![0.0; ndx + nu],
        })
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        let datas = &mut downcast::<StackWorkspace>(&mut data.ws).datas;
        let mut value = 0.0;
        for (k, (c, d)) in self.costs.iter().zip(datas.iter_mut()).enumerate() {
            c.evaluate(x, u, d);
            let w = self.weights.get(k);
            if w != 0.0 {
                value += w * d.value;
            }
        }
        data.value = value;
    }
    fn derivatives(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        self.derivatives_reusing(x, u, data, false);
    }
    /// Every component adds its weighted derivatives straight into the stack's blocks
    /// (lower triangles, mirrored once at the end), which start from the weighted sum of
    /// the Hessians of the components with a constant Hessian. That sum is kept while
    /// their weights stay the same and their data hold their constant blocks (`reuse`),
    /// and these components then add only their gradient; the result is the same to the
    /// bit with or without `reuse`.
    fn derivatives_reusing(&self, x: &[f64], u: &[f64], data: &mut CostData, reuse: bool) {
        let CostParts {
            lx,
            lu,
            mut hessian,
            ws,
        } = data.parts();
        let ws = downcast::<StackWorkspace>(ws);
        // Weights may change between calls (through `&self`): the sum is formed again then.
        let rebuild = !reuse
            || (0..self.costs.len())
                .any(|k| self.costs[k].hessian_is_constant() && ws.constant_weights[k] != self.weights.get(k));
        if rebuild {
            self.form_constant_hessian(x, u, ws, reuse);
        }
        lx.fill(0.0);
        lu.fill(0.0);
        let ([cxx, cxu, cuu], [nxx, nxu, nuu]) = (&ws.constant, ws.constant_nonzero);
        // Whole blocks (fixed-size column copies): the upper triangles of `lxx` and `luu`
        // are mirrored from the lower ones below.
        start_from(hessian.lxx.rb_mut(), cxx, nxx);
        start_from(hessian.lxu.rb_mut(), cxu, nxu);
        start_from(hessian.luu.rb_mut(), cuu, nuu);
        for (k, (c, d)) in self.costs.iter().zip(ws.datas.iter_mut()).enumerate() {
            let w = self.weights.get(k);
            if w == 0.0 {
                continue;
            }
            let is_constant = c.hessian_is_constant();
            let out = DerivativesMut {
                lx: &mut *lx,
                lu: &mut *lu,
                hessian: (!is_constant).then(|| hessian.rb_mut()),
            };
            // Just formed, the constant blocks are there to reuse.
            let reuse_k = ws.written[k] && (reuse || (rebuild && is_constant));
            c.add_derivatives(x, u, d, reuse_k, w, out);
            ws.written[k] = true;
        }
        symmetrize_from_lower(hessian.lxx);
        symmetrize_from_lower(hessian.luu);
    }
}

impl CostStack {
    /// Forms `Σ w_k ∇²ℓ_k` over the components with a constant Hessian (their gradients
    /// go to scratch), with the weights of now.
    fn form_constant_hessian(&self, x: &[f64], u: &[f64], ws: &mut StackWorkspace, reuse: bool) {
        let [cxx, cxu, cuu] = &mut ws.constant;
        crate::linalg::fill(cxx.as_mut(), 0.0);
        crate::linalg::fill(cxu.as_mut(), 0.0);
        crate::linalg::fill(cuu.as_mut(), 0.0);
        for (k, (c, d)) in self.costs.iter().zip(ws.datas.iter_mut()).enumerate() {
            if !c.hessian_is_constant() {
                continue;
            }
            let w = self.weights.get(k);
            ws.constant_weights[k] = w;
            if w == 0.0 {
                continue;
            }
            let (lx, lu) = ws.gradient_scratch.split_at_mut(self.ndx);
            let out = DerivativesMut {
                lx,
                lu,
                hessian: Some(HessianMut::of(cxx, cxu, cuu)),
            };
            c.add_derivatives(x, u, d, reuse && ws.written[k], w, out);
            ws.written[k] = true;
        }
        ws.constant_nonzero = [!is_zero(cxx.as_ref()), !is_zero(cxu.as_ref()), !is_zero(cuu.as_ref())];
    }
}

/// Starts a block of the stack's derivatives from its block of the constant Hessian sum
/// (`nonzero`) or from zero.
fn start_from(mut dst: MatMut<'_, f64>, constant: &Mat<f64>, nonzero: bool) {
    if nonzero {
        copy(dst, constant.as_ref());
    } else {
        crate::linalg::fill(dst.as_mut(), 0.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{CheckOptions, check_cost};
    use crate::costs::{QuadraticControlCost, QuadraticStateCost};
    use crate::functions::testing::{random_vec, rng};
    use crate::spaces::VectorSpace;
    use rand::Rng;

    #[test]
    fn cost_stack_is_the_weighted_sum_and_weights_change_in_place() {
        let mut g = rng(50);
        let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(3));
        let xs: Arc<dyn Cost> = Arc::new(
            QuadraticStateCost::diagonal(space.clone(), &random_vec(&mut g, 3, 1.0), &[1.0, 2.0, 3.0], 2).unwrap(),
        );
        let us: Arc<dyn Cost> =
            Arc::new(QuadraticControlCost::diagonal(space.as_ref(), &random_vec(&mut g, 2, 1.0), &[0.5, 0.1]).unwrap());
        let stack = CostStack::new(space.as_ref(), 2)
            .with("state", xs.clone(), 2.0)
            .unwrap()
            .with("control", us.clone(), 0.3)
            .unwrap();
        assert_eq!(stack.len(), 2);
        assert_eq!(stack.names(), &["state".to_string(), "control".to_string()]);
        let mut d = stack.create_data();
        let (mut dx, mut du) = (xs.create_data(), us.create_data());
        for _ in 0..4 {
            let (x, u) = (random_vec(&mut g, 3, 1.0), random_vec(&mut g, 2, 1.0));
            check_cost(&stack, space.as_ref(), &x, &u, CheckOptions::default()).assert_ok();
            stack.set_weight("control", g.random_range(0.0..2.0)).unwrap();
            let (wx, wu) = (stack.weight("state").unwrap(), stack.weight("control").unwrap());
            stack.evaluate(&x, &u, &mut d);
            stack.derivatives(&x, &u, &mut d);
            xs.evaluate(&x, &u, &mut dx);
            xs.derivatives(&x, &u, &mut dx);
            us.evaluate(&x, &u, &mut du);
            us.derivatives(&x, &u, &mut du);
            assert!((d.value - (wx * dx.value + wu * du.value)).abs() < 1e-14);
            for i in 0..3 {
                assert!((d.lx()[i] - (wx * dx.lx()[i] + wu * du.lx()[i])).abs() < 1e-14);
                for j in 0..3 {
                    assert!((d.lxx[(i, j)] - (wx * dx.lxx[(i, j)] + wu * du.lxx[(i, j)])).abs() < 1e-14);
                }
            }
            for i in 0..2 {
                assert!((d.lu()[i] - (wx * dx.lu()[i] + wu * du.lu()[i])).abs() < 1e-14);
                for j in 0..2 {
                    assert!((d.luu[(i, j)] - (wx * dx.luu[(i, j)] + wu * du.luu[(i, j)])).abs() < 1e-14);
                }
            }
        }
        // A zero weight switches a component off.
        stack.set_weight("state", 0.0).unwrap();
        let (x, u) = ([0.1, 0.2, 0.3], [0.4, 0.5]);
        stack.evaluate(&x, &u, &mut d);
        us.evaluate(&x, &u, &mut du);
        assert_eq!(d.value, stack.weight("control").unwrap() * du.value);
        assert!(stack.get("state").is_some() && stack.get("nope").is_none());

        let err = stack.set_weight("nope", 1.0).unwrap_err();
        assert!(err.to_string().contains("no component named `nope`"), "{err}");
        assert!(stack.set_weight("state", -1.0).is_err());
        assert!(stack.set_weight("state", f64::NAN).is_err());
        let err = stack.clone().with("state", xs.clone(), 1.0).unwrap_err();
        assert!(err.to_string().contains("duplicate"), "{err}");
        let err = CostStack::new(space.as_ref(), 0).with("state", xs, 1.0).unwrap_err();
        assert!(err.to_string().contains("component `state`: nu"), "{err}");
        // Reusing the constant blocks of the components gives the derivatives of a fresh
        // evaluation, at any later point and weights.
        stack.set_weight("state", 1.5).unwrap();
        let mut fresh = stack.create_data();
        for _ in 0..3 {
            let (x, u) = (random_vec(&mut g, 3, 1.0), random_vec(&mut g, 2, 1.0));
            stack.evaluate(&x, &u, &mut d);
            stack.derivatives_reusing(&x, &u, &mut d, true);
            stack.evaluate(&x, &u, &mut fresh);
            stack.derivatives(&x, &u, &mut fresh);
            assert_eq!((d.lx(), d.lu()), (fresh.lx(), fresh.lu()));
            assert!(d.lxx == fresh.lxx && d.lxu == fresh.lxu && d.luu == fresh.luu);
        }
        // An empty stack is the zero cost.
        let empty = CostStack::new(space.as_ref(), 0);
        assert!(empty.is_empty());
        check_cost(&empty, space.as_ref(), &x, &[], CheckOptions::default()).assert_ok();
    }

    /// A stack of every kind of component (constant and varying Hessians, the residual
    /// costs that add into the stack's blocks and costs on the default path, a nested
    /// stack), weights changing between calls and a component switched on after the
    /// first call: its derivatives with `reuse` equal the weighted sum of the components'
    /// own derivatives, written fresh each time.
    /// The components of the mixed stack, with their weights: a nonlinear residual with its
    /// exact Hessian, a linear one (constant Hessian, weight 0), a state cost, a barrier, a
    /// general quadratic and a nested stack.
    fn mixed_components(
        g: &mut rand::rngs::SmallRng,
        space: &Arc<dyn Manifold>,
    ) -> Vec<(&'static str, Arc<dyn Cost>, f64)> {
        use crate::costs::{LogBarrierCost, QuadraticCost, QuadraticResidualCost};
        use crate::functions::testing::{TestFunction, random_mat};
        use crate::functions::{LinearFunction, StageFunction};
        let f: Arc<dyn StageFunction> = Arc::new(TestFunction);
        let w = random_mat(g, 3, 3, 1.0);
        let lin: Arc<dyn StageFunction> = Arc::new(
            LinearFunction::new(
                random_mat(g, 4, 3, 1.0).as_ref(),
                random_mat(g, 4, 2, 1.0).as_ref(),
                &[0.1; 4],
            )
            .unwrap(),
        );
        let q = random_mat(g, 3, 3, 1.0);
        let r = random_mat(g, 2, 2, 1.0);
        let (q, r) = (&q * q.transpose(), &r * r.transpose());
        let quad = QuadraticCost::new(
            q.as_ref(),
            random_mat(g, 3, 2, 0.3).as_ref(),
            r.as_ref(),
            &[0.2; 3],
            &[0.1; 2],
        );
        let control = QuadraticControlCost::diagonal(space.as_ref(), &[0.3, -0.2], &[0.5, 2.0]).unwrap();
        let nested = CostStack::new(space.as_ref(), 2)
            .with("control", Arc::new(control), 0.7)
            .unwrap();
        vec![
            (
                "nonlinear",
                Arc::new(
                    QuadraticResidualCost::new(f.clone(), w.as_ref())
                        .unwrap()
                        .exact_hessian(true),
                ),
                1.3,
            ),
            (
                "linear",
                Arc::new(QuadraticResidualCost::diagonal(lin, &[1.0, 0.0, 2.0, 0.5]).unwrap()),
                0.0,
            ),
            (
                "state",
                Arc::new(QuadraticStateCost::diagonal(space.clone(), &[0.1, 0.2, 0.3], &[1.0, 2.0, 3.0], 2).unwrap()),
                2.0,
            ),
            ("barrier", Arc::new(LogBarrierCost::new(f, 0.4, 0.5).unwrap()), 0.6),
            ("quadratic", Arc::new(quad.unwrap()), 0.9),
            ("nested", Arc::new(nested), 1.1),
        ]
    }

    /// `Σ w_k` times the derivatives of each component computed afresh in its own data,
    /// with the stack's current weights.
    fn weighted_sum(
        stack: &CostStack,
        components: &[(&str, Arc<dyn Cost>, f64)],
        own: &mut [CostData],
        (x, u): (&[f64], &[f64]),
    ) -> CostData {
        let mut sum = CostData::new(3, 2, crate::functions::no_workspace());
        for ((name, c, _), o) in components.iter().zip(own.iter_mut()) {
            let wk = stack.weight(name).unwrap();
            c.evaluate(x, u, o);
            c.derivatives(x, u, o);
            sum.lx += wk * &o.lx;
            sum.lu += wk * &o.lu;
            sum.lxx += wk * &o.lxx;
            sum.lxu += wk * &o.lxu;
            sum.luu += wk * &o.luu;
        }
        sum
    }

    #[test]
    fn mixed_stack_equals_the_weighted_sum_of_fresh_component_derivatives() {
        use crate::functions::testing::assert_close;
        let mut g = rng(51);
        let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(3));
        let components = mixed_components(&mut g, &space);
        assert!(components[1].1.hessian_is_constant() && !components[0].1.hessian_is_constant());
        let mut stack = CostStack::new(space.as_ref(), 2);
        for (name, c, w) in &components {
            stack = stack.with(*name, c.clone(), *w).unwrap();
        }
        let mut d = stack.create_data();
        let mut own: Vec<CostData> = components.iter().map(|(_, c, _)| c.create_data()).collect();
        for step in 0..6 {
            match step {
                2 => stack.set_weight("linear", 0.8).unwrap(),
                4 => stack.set_weight("state", 0.25).unwrap(),
                _ => {}
            }
            let (x, u) = (random_vec(&mut g, 3, 1.0), random_vec(&mut g, 2, 1.0));
            stack.evaluate(&x, &u, &mut d);
            stack.derivatives_reusing(&x, &u, &mut d, step > 0);
            let sum = weighted_sum(&stack, &components, &mut own, (&x, &u));
            let tol = 1e-13;
            assert_close("lx", &d.lx.as_mat().to_owned(), &sum.lx.as_mat().to_owned(), tol);
            assert_close("lu", &d.lu.as_mat().to_owned(), &sum.lu.as_mat().to_owned(), tol);
            assert_close("lxx", &d.lxx, &sum.lxx, tol);
            assert_close("lxu", &d.lxu, &sum.lxu, tol);
            assert_close("luu", &d.luu, &sum.luu, tol);
            assert!(d.lxx == d.lxx.transpose().to_owned() && d.luu == d.luu.transpose().to_owned());
        }
    }
}

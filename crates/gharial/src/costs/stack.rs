//! A weighted sum of named costs whose weights can change without reallocation.

use std::sync::Arc;

use faer::MatMut;
use faer::prelude::ReborrowMut;

use super::{Cost, CostData};
use crate::functions::Workspace;
use crate::functions::util::{add_scaled, downcast};
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
/// its leading components with constant Hessians.
struct StackWorkspace {
    datas: Vec<CostData>,
    prefix: CostData,
    /// The weights the prefix sum was formed with (NaN: not formed yet).
    prefix_weights: Vec<f64>,
}

impl CostStack {
    /// `(lxx, lxu, luu) += Σ w_k ∇²ℓ_k` over the components `range` (in order; weight 0
    /// skipped).
    fn add_hessians(&self, datas: &[CostData], range: std::ops::Range<usize>, out: [MatMut<'_, f64>; 3]) {
        let [mut lxx, mut lxu, mut luu] = out;
        for k in range {
            let w = self.weights.get(k);
            if w == 0.0 {
                continue;
            }
            let d = &datas[k];
            add_scaled(lxx.rb_mut(), w, d.lxx.as_ref());
            add_scaled(lxu.rb_mut(), w, d.lxu.as_ref());
            add_scaled(luu.rb_mut(), w, d.luu.as_ref());
        }
    }
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
        let datas: Vec<CostData> = self.costs.iter().map(|c| c.create_data()).collect();
        let prefix = CostData::new(self.ndx, self.nu, crate::functions::no_workspace());
        Box::new(StackWorkspace {
            datas,
            prefix,
            prefix_weights: vec![f64::NAN; self.costs.len()],
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
    /// Components with a constant Hessian compute only their gradient once their data
    /// hold it (`reuse`), and the weighted sum of the Hessians of the leading such
    /// components is kept from the first call while their weights stay the same (formed
    /// in the same order, so the result is the same to the bit); the Hessians of the other
    /// components are added at every call.
    fn derivatives_reusing(&self, x: &[f64], u: &[f64], data: &mut CostData, reuse: bool) {
        let ws = downcast::<StackWorkspace>(&mut data.ws);
        let constant_prefix = self.costs.iter().take_while(|c| c.hessian_is_constant()).count();
        data.lx.fill(0.0);
        data.lu.fill(0.0);
        for (k, (c, d)) in self.costs.iter().zip(ws.datas.iter_mut()).enumerate() {
            let w = self.weights.get(k);
            if w == 0.0 {
                continue;
            }
            c.derivatives_reusing(x, u, d, reuse);
            add_scaled(data.lx.as_mat_mut(), w, d.lx.as_mat());
            add_scaled(data.lu.as_mat_mut(), w, d.lu.as_mat());
        }
        // Weights may change between calls (through `&self`): the sum is formed again then.
        let same_weights = (0..constant_prefix).all(|k| ws.prefix_weights[k] == self.weights.get(k));
        if !(reuse && same_weights) {
            let p = &mut ws.prefix;
            p.lxx.fill(0.0);
            p.lxu.fill(0.0);
            p.luu.fill(0.0);
            self.add_hessians(
                &ws.datas,
                0..constant_prefix,
                [p.lxx.as_mut(), p.lxu.as_mut(), p.luu.as_mut()],
            );
            for k in 0..constant_prefix {
                ws.prefix_weights[k] = self.weights.get(k);
            }
        }
        crate::linalg::copy(data.lxx.as_mut(), ws.prefix.lxx.as_ref());
        crate::linalg::copy(data.lxu.as_mut(), ws.prefix.lxu.as_ref());
        crate::linalg::copy(data.luu.as_mut(), ws.prefix.luu.as_ref());
        let out = [data.lxx.as_mut(), data.lxu.as_mut(), data.luu.as_mut()];
        self.add_hessians(&ws.datas, constant_prefix..self.costs.len(), out);
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
}

//! Cartesian products `M_1 × ... × M_k` of any spaces.
//!
//! Representations and tangent vectors are the concatenations of the parts', every
//! operation acts part by part, and the Jacobians are block diagonal.

use std::sync::Arc;

use faer::MatMut;
use faer::reborrow::ReborrowMut;
use rand::RngCore;

use super::{Arg, Manifold, ManifoldScalar, forward_group_ops};

/// The Cartesian product of any number of spaces (products of products included).
///
/// ```
/// use std::sync::Arc;
/// use gharial::spaces::{CartesianProduct, Manifold, SE3, VectorSpace};
/// // A floating base with 6 joint positions.
/// let m = CartesianProduct::new(vec![Arc::new(SE3), Arc::new(VectorSpace::new(6))]);
/// assert_eq!((m.nx(), m.ndx()), (13, 12));
/// // The same, built step by step.
/// let m2 = CartesianProduct::empty().times(Arc::new(SE3)).times(Arc::new(VectorSpace::new(6)));
/// assert_eq!((m2.nx(), m2.ndx()), (13, 12));
/// ```
#[derive(Debug, Clone)]
pub struct CartesianProduct {
    parts: Vec<Arc<dyn Manifold>>,
    /// Offsets of the parts in the representation (`parts.len() + 1` entries).
    ox: Vec<usize>,
    /// Offsets of the parts in the tangent space (`parts.len() + 1` entries).
    odx: Vec<usize>,
    vector_space: bool,
    /// The blocks of the parts up to the last with a nonlinear block, in the tangent
    /// space: their starts, then the end of that part's nonlinear block
    /// ([`Manifold::nonlinear_dim`]); `[0]` when no part has one.
    nonlinear_bounds: Vec<usize>,
}

impl CartesianProduct {
    /// The product of `parts`, in order.
    pub fn new(parts: Vec<Arc<dyn Manifold>>) -> Self {
        let mut ox = vec![0];
        let mut odx = vec![0];
        for p in &parts {
            ox.push(ox.last().copied().unwrap_or(0) + p.nx());
            odx.push(odx.last().copied().unwrap_or(0) + p.ndx());
        }
        let vector_space = parts.iter().all(|p| p.is_vector_space());
        let nonlinear_bounds = match parts.iter().rposition(|p| p.nonlinear_dim() > 0) {
            Some(last) => [&odx[..=last], &[odx[last] + parts[last].nonlinear_dim()]].concat(),
            None => vec![0],
        };
        Self {
            parts,
            ox,
            odx,
            vector_space,
            nonlinear_bounds,
        }
    }

    /// The product of no space (a single point, `nx = ndx = 0`), to start a builder chain.
    pub fn empty() -> Self {
        Self::new(Vec::new())
    }

    /// `a × b`.
    pub fn pair(a: Arc<dyn Manifold>, b: Arc<dyn Manifold>) -> Self {
        Self::new(vec![a, b])
    }

    /// `self × part`.
    pub fn times(mut self, part: Arc<dyn Manifold>) -> Self {
        self.parts.push(part);
        Self::new(self.parts)
    }

    /// The parts.
    pub fn parts(&self) -> &[Arc<dyn Manifold>] {
        &self.parts
    }

    /// The representation of part `i` inside the representation `x` of the product.
    pub fn part_x<'a>(&self, x: &'a [f64], i: usize) -> &'a [f64] {
        &x[self.ox[i]..self.ox[i + 1]]
    }

    /// The components of part `i` inside a tangent vector `v` of the product.
    pub fn part_v<'a>(&self, v: &'a [f64], i: usize) -> &'a [f64] {
        &v[self.odx[i]..self.odx[i + 1]]
    }

    fn rx(&self, i: usize) -> std::ops::Range<usize> {
        self.ox[i]..self.ox[i + 1]
    }

    fn rdx(&self, i: usize) -> std::ops::Range<usize> {
        self.odx[i]..self.odx[i + 1]
    }

    fn integrate_t<T: ManifoldScalar>(&self, x: &[T], v: &[T], out: &mut [T]) {
        if self.vector_space {
            return super::add_elementwise(x, v, out);
        }
        for (i, p) in self.parts.iter().enumerate() {
            T::integrate(p.as_ref(), &x[self.rx(i)], &v[self.rdx(i)], &mut out[self.rx(i)]);
        }
    }

    fn difference_t<T: ManifoldScalar>(&self, x0: &[T], x1: &[T], out: &mut [T]) {
        if self.vector_space {
            return super::sub_elementwise(x0, x1, out);
        }
        for (i, p) in self.parts.iter().enumerate() {
            T::difference(p.as_ref(), &x0[self.rx(i)], &x1[self.rx(i)], &mut out[self.rdx(i)]);
        }
    }
}

impl Manifold for CartesianProduct {
    fn nx(&self) -> usize {
        self.ox[self.parts.len()]
    }

    fn ndx(&self) -> usize {
        self.odx[self.parts.len()]
    }

    fn neutral(&self, out: &mut [f64]) {
        for (i, p) in self.parts.iter().enumerate() {
            p.neutral(&mut out[self.rx(i)]);
        }
    }

    fn random(&self, rng: &mut dyn RngCore, out: &mut [f64]) {
        for (i, p) in self.parts.iter().enumerate() {
            p.random(rng, &mut out[self.rx(i)]);
        }
    }

    forward_group_ops!();

    fn interpolate(&self, x0: &[f64], x1: &[f64], t: f64, out: &mut [f64]) {
        for (i, p) in self.parts.iter().enumerate() {
            p.interpolate(&x0[self.rx(i)], &x1[self.rx(i)], t, &mut out[self.rx(i)]);
        }
    }

    fn jintegrate(&self, x: &[f64], v: &[f64], arg: Arg, mut j: MatMut<'_, f64>) {
        super::zero_off_diagonal_blocks(j.rb_mut(), &self.odx);
        for (i, p) in self.parts.iter().enumerate() {
            let (o, n) = (self.odx[i], p.ndx());
            p.jintegrate(
                &x[self.rx(i)],
                &v[self.rdx(i)],
                arg,
                j.rb_mut().submatrix_mut(o, o, n, n),
            );
        }
    }

    fn jdifference(&self, x0: &[f64], x1: &[f64], arg: Arg, mut j: MatMut<'_, f64>) {
        super::zero_off_diagonal_blocks(j.rb_mut(), &self.odx);
        for (i, p) in self.parts.iter().enumerate() {
            let (o, n) = (self.odx[i], p.ndx());
            p.jdifference(
                &x0[self.rx(i)],
                &x1[self.rx(i)],
                arg,
                j.rb_mut().submatrix_mut(o, o, n, n),
            );
        }
    }

    fn jintegrate_transport(&self, x: &[f64], v: &[f64], arg: Arg, mut m: MatMut<'_, f64>) {
        if self.vector_space {
            return;
        }
        for (i, p) in self.parts.iter().enumerate() {
            let (o, n) = (self.odx[i], p.ndx());
            p.jintegrate_transport(&x[self.rx(i)], &v[self.rdx(i)], arg, m.rb_mut().subrows_mut(o, n));
        }
    }

    fn tangent_map(&self, x: &[f64], mut j: MatMut<'_, f64>) {
        crate::linalg::fill(j.as_mut(), 0.0);
        for (i, p) in self.parts.iter().enumerate() {
            let sub = j.rb_mut().submatrix_mut(self.ox[i], self.odx[i], p.nx(), p.ndx());
            p.tangent_map(&x[self.rx(i)], sub);
        }
    }

    fn tangent_map_inverse(&self, x: &[f64], mut j: MatMut<'_, f64>) {
        crate::linalg::fill(j.as_mut(), 0.0);
        for (i, p) in self.parts.iter().enumerate() {
            let sub = j.rb_mut().submatrix_mut(self.odx[i], self.ox[i], p.ndx(), p.nx());
            p.tangent_map_inverse(&x[self.rx(i)], sub);
        }
    }

    fn normalize(&self, x: &mut [f64]) {
        for (i, p) in self.parts.iter().enumerate() {
            p.normalize(&mut x[self.rx(i)]);
        }
    }

    fn is_valid(&self, x: &[f64]) -> bool {
        x.len() == self.nx() && self.parts.iter().enumerate().all(|(i, p)| p.is_valid(&x[self.rx(i)]))
    }

    fn is_vector_space(&self) -> bool {
        self.vector_space
    }

    fn nonlinear_dim(&self) -> usize {
        self.nonlinear_bounds[self.nonlinear_bounds.len() - 1]
    }

    /// The parts up to the last with a nonlinear block, the last one through its own
    /// `jdifference_block`.
    fn jdifference_block(&self, x0: &[f64], x1: &[f64], arg: Arg, mut j: MatMut<'_, f64>) {
        let Some(last) = self.nonlinear_bounds.len().checked_sub(2) else {
            return;
        };
        super::zero_off_diagonal_blocks(j.rb_mut(), &self.nonlinear_bounds);
        for (i, p) in self.parts[..=last].iter().enumerate() {
            let o = self.odx[i];
            let (x0, x1) = (&x0[self.rx(i)], &x1[self.rx(i)]);
            if i == last {
                let n = p.nonlinear_dim();
                p.jdifference_block(x0, x1, arg, j.rb_mut().submatrix_mut(o, o, n, n));
            } else {
                p.jdifference(x0, x1, arg, j.rb_mut().submatrix_mut(o, o, p.ndx(), p.ndx()));
            }
        }
    }
}

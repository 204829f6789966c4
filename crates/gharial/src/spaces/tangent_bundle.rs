//! The tangent bundle `TM` of a space `M`: states `x = (q, v)` made of a point `q` of
//! `M` and a velocity `v` tangent at `q` (the phase space of a mechanical system).
//!
//! ```text
//! (q, v) ⊕ (dq, dv)        = (q ⊕ dq, v + dv)
//! (q1, v1) ⊖ (q0, v0)      = (q1 ⊖ q0, v1 - v0)
//! ```
//! The velocity part is a vector space (velocities are not transported when `q`
//! moves, as in Pinocchio-based phase spaces), so the Jacobians are block diagonal with
//! `M`'s Jacobians and `±I`.

use std::sync::Arc;

use faer::MatMut;
use faer::reborrow::ReborrowMut;
use rand::RngCore;

use super::{Arg, Manifold, ManifoldScalar, forward_group_ops, set_identity};

/// The tangent bundle of a space: `x = (q, v)`, `nx = nq + nv`, `ndx = 2 nv` with
/// `nq = M.nx()`, `nv = M.ndx()`.
#[derive(Debug, Clone)]
pub struct TangentBundle {
    base: Arc<dyn Manifold>,
    /// Whether `M` is a vector space (then `⊕` and `⊖` are `+` and `-` on all of `x`).
    vector_space: bool,
}

impl TangentBundle {
    /// `TM` for `M = base`.
    pub fn new(base: Arc<dyn Manifold>) -> Self {
        let vector_space = base.is_vector_space();
        Self { base, vector_space }
    }

    /// The base space `M`.
    pub fn base(&self) -> &Arc<dyn Manifold> {
        &self.base
    }

    fn integrate_t<T: ManifoldScalar>(&self, x: &[T], v: &[T], out: &mut [T]) {
        if self.vector_space {
            return super::add_elementwise(x, v, out);
        }
        let (nq, nv) = (self.base.nx(), self.base.ndx());
        T::integrate(self.base.as_ref(), &x[..nq], &v[..nv], &mut out[..nq]);
        for i in 0..nv {
            out[nq + i] = x[nq + i] + v[nv + i];
        }
    }

    fn difference_t<T: ManifoldScalar>(&self, x0: &[T], x1: &[T], out: &mut [T]) {
        if self.vector_space {
            return super::sub_elementwise(x0, x1, out);
        }
        let (nq, nv) = (self.base.nx(), self.base.ndx());
        T::difference(self.base.as_ref(), &x0[..nq], &x1[..nq], &mut out[..nv]);
        for i in 0..nv {
            out[nv + i] = x1[nq + i] - x0[nq + i];
        }
    }

    /// The parts of a Jacobian outside the base's block: zero off the diagonal blocks,
    /// `s I` on the velocity block (the base writes its own block).
    fn velocity_block(&self, mut j: MatMut<'_, f64>, s: f64) {
        let nv = self.base.ndx();
        super::zero_off_diagonal_blocks(j.rb_mut(), &[0, nv, 2 * nv]);
        set_identity(j.submatrix_mut(nv, nv, nv, nv), s);
    }
}

impl Manifold for TangentBundle {
    fn nx(&self) -> usize {
        self.base.nx() + self.base.ndx()
    }

    fn ndx(&self) -> usize {
        2 * self.base.ndx()
    }

    fn neutral(&self, out: &mut [f64]) {
        let nq = self.base.nx();
        self.base.neutral(&mut out[..nq]);
        out[nq..].fill(0.0);
    }

    fn random(&self, rng: &mut dyn RngCore, out: &mut [f64]) {
        use rand::Rng;
        let nq = self.base.nx();
        self.base.random(rng, &mut out[..nq]);
        for o in out[nq..].iter_mut() {
            *o = rng.random_range(-1.0..=1.0);
        }
    }

    forward_group_ops!();

    fn interpolate(&self, x0: &[f64], x1: &[f64], t: f64, out: &mut [f64]) {
        let nq = self.base.nx();
        self.base.interpolate(&x0[..nq], &x1[..nq], t, &mut out[..nq]);
        for i in nq..out.len() {
            out[i] = x0[i] + t * (x1[i] - x0[i]);
        }
    }

    fn jintegrate(&self, x: &[f64], v: &[f64], arg: Arg, mut j: MatMut<'_, f64>) {
        let (nq, nv) = (self.base.nx(), self.base.ndx());
        self.velocity_block(j.rb_mut(), 1.0);
        self.base
            .jintegrate(&x[..nq], &v[..nv], arg, j.submatrix_mut(0, 0, nv, nv));
    }

    fn jdifference(&self, x0: &[f64], x1: &[f64], arg: Arg, mut j: MatMut<'_, f64>) {
        let (nq, nv) = (self.base.nx(), self.base.ndx());
        self.velocity_block(j.rb_mut(), if arg == Arg::First { -1.0 } else { 1.0 });
        self.base
            .jdifference(&x0[..nq], &x1[..nq], arg, j.submatrix_mut(0, 0, nv, nv));
    }

    fn jintegrate_transport(&self, x: &[f64], v: &[f64], arg: Arg, m: MatMut<'_, f64>) {
        let (nq, nv) = (self.base.nx(), self.base.ndx());
        self.base
            .jintegrate_transport(&x[..nq], &v[..nv], arg, m.subrows_mut(0, nv));
    }

    fn tangent_map(&self, x: &[f64], mut j: MatMut<'_, f64>) {
        let (nq, nv) = (self.base.nx(), self.base.ndx());
        crate::linalg::fill(j.as_mut(), 0.0);
        self.base.tangent_map(&x[..nq], j.rb_mut().submatrix_mut(0, 0, nq, nv));
        for i in 0..nv {
            j[(nq + i, nv + i)] = 1.0;
        }
    }

    fn tangent_map_inverse(&self, x: &[f64], mut j: MatMut<'_, f64>) {
        let (nq, nv) = (self.base.nx(), self.base.ndx());
        crate::linalg::fill(j.as_mut(), 0.0);
        self.base
            .tangent_map_inverse(&x[..nq], j.rb_mut().submatrix_mut(0, 0, nv, nq));
        for i in 0..nv {
            j[(nv + i, nq + i)] = 1.0;
        }
    }

    fn normalize(&self, x: &mut [f64]) {
        let nq = self.base.nx();
        self.base.normalize(&mut x[..nq]);
    }

    fn is_valid(&self, x: &[f64]) -> bool {
        let nq = self.base.nx();
        x.len() == self.nx() && self.base.is_valid(&x[..nq]) && x[nq..].iter().all(|v| v.is_finite())
    }

    fn is_vector_space(&self) -> bool {
        self.vector_space
    }

    /// The base's: the velocity part is Euclidean.
    fn nonlinear_dim(&self) -> usize {
        self.base.nonlinear_dim()
    }

    fn jdifference_block(&self, x0: &[f64], x1: &[f64], arg: Arg, j: MatMut<'_, f64>) {
        let nq = self.base.nx();
        self.base.jdifference_block(&x0[..nq], &x1[..nq], arg, j);
    }
}

//! Products of sets over consecutive row blocks.

use std::sync::Arc;

use faer::MatMut;

use super::ConstraintSet;
use crate::{Error, Result};

/// `C = C_1 × C_2 × ...`: block `k` of `z` (rows `offsets[k]..offsets[k+1]`) must lie
/// in `C_k`. Every operation acts block by block; penalties add up, violations take
/// the maximum.
#[derive(Debug, Clone)]
pub struct ConstraintSetProduct {
    sets: Vec<Arc<dyn ConstraintSet>>,
    offsets: Vec<usize>,
}

impl ConstraintSetProduct {
    /// The product of `blocks = [(C_k, size_k)]`, in row order.
    ///
    /// # Errors
    /// If a set has a fixed dimension different from its block size (the error names
    /// the block index).
    pub fn new(blocks: Vec<(Arc<dyn ConstraintSet>, usize)>) -> Result<Self> {
        let mut offsets = vec![0];
        let mut sets = Vec::with_capacity(blocks.len());
        for (k, (set, n)) in blocks.into_iter().enumerate() {
            if let Some(d) = set.dim() {
                crate::error::check_dim(format!("ConstraintSetProduct block {k} ({set:?})"), d, n)?;
            }
            offsets.push(offsets[k] + n);
            sets.push(set);
        }
        if sets.is_empty() {
            return Err(Error::InvalidModel("ConstraintSetProduct: no block given".into()));
        }
        Ok(Self { sets, offsets })
    }

    /// Rows of block `k`.
    pub fn rows_of(&self, k: usize) -> std::ops::Range<usize> {
        self.offsets[k]..self.offsets[k + 1]
    }

    fn blocks(&self) -> impl Iterator<Item = (&Arc<dyn ConstraintSet>, std::ops::Range<usize>)> {
        self.sets.iter().enumerate().map(|(k, s)| (s, self.rows_of(k)))
    }
}

impl ConstraintSet for ConstraintSetProduct {
    fn dim(&self) -> Option<usize> {
        self.offsets.last().copied()
    }
    fn is_equality(&self) -> bool {
        self.sets.iter().all(|s| s.is_equality())
    }
    fn penalty(&self, z: &[f64]) -> f64 {
        self.blocks().map(|(s, r)| s.penalty(&z[r])).sum()
    }
    fn project(&self, z: &[f64], mu: f64, out: &mut [f64]) {
        for (s, r) in self.blocks() {
            s.project(&z[r.clone()], mu, &mut out[r]);
        }
    }
    fn normal_cone_project(&self, z: &[f64], mu: f64, out: &mut [f64]) {
        for (s, r) in self.blocks() {
            s.normal_cone_project(&z[r.clone()], mu, &mut out[r]);
        }
    }
    fn apply_projection_jacobian(&self, z: &[f64], mu: f64, mut m: MatMut<'_, f64>) {
        for (s, r) in self.blocks() {
            let rows = m.as_mut().subrows_mut(r.start, r.len());
            s.apply_projection_jacobian(&z[r], mu, rows);
        }
    }
    fn apply_normal_cone_jacobian(&self, z: &[f64], mu: f64, mut m: MatMut<'_, f64>) {
        for (s, r) in self.blocks() {
            let rows = m.as_mut().subrows_mut(r.start, r.len());
            s.apply_normal_cone_jacobian(&z[r], mu, rows);
        }
    }
    fn violation(&self, z: &[f64]) -> f64 {
        self.blocks().fold(0.0_f64, |a, (s, r)| a.max(s.violation(&z[r])))
    }
}

//! The box-constrained QP of box-DDP: `min ½ xᵀH x + qᵀx` subject to `lb ≤ x ≤ ub`, by
//! the projected-Newton method of Tassa, Mansard and Todorov (2014), Algorithm 3.
//!
//! Each iteration splits the variables into *clamped* ones (at a bound, with the gradient
//! `g = H x + q` pushing outwards) and *free* ones, takes the Newton step on the free
//! variables, `δx_f = -H_ff⁻¹ g_f`, and backtracks along the projected arc
//! `clamp(x + α δx)` until the decrease is at least `th_accept` times the linear
//! prediction `gᵀ(x - x_new)`. It stops when the free gradient is below `th_grad` or every
//! variable is clamped. The Cholesky factor of `H_ff` at the solution stays available: box-DDP's
//! feedback gains are `K_f = -H_ff⁻¹ Q_fx` on the free rows and 0 on the clamped ones.
//!
//! Infinite bounds are allowed. Everything is allocated by [`BoxQp::new`].

use faer::{Mat, MatMut, MatRef};

use crate::error::{Error, Result};

/// Options of [`BoxQp`] (crocoddyl's defaults, but for `th_grad`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct BoxQpOptions {
    /// Projected-Newton iterations at most. Default 100.
    pub max_iters: usize,
    /// Sufficient-decrease fraction of the backtracking (in `(0, 0.5)`). Default 0.1.
    pub th_accept: f64,
    /// Converged when the free gradient's infinity norm is at most this, or when a whole
    /// Newton step inside the box kept the free set (then the solution is exact).
    /// Default `1e-12`: an absolute gradient threshold such as crocoddyl's `1e-5` stops
    /// far from the solution when `Q_uu` is small (light control weights).
    pub th_grad: f64,
}

impl Default for BoxQpOptions {
    fn default() -> Self {
        Self {
            max_iters: 100,
            th_accept: 0.1,
            th_grad: 1e-12,
        }
    }
}

impl BoxQpOptions {
    /// Checks the ranges.
    ///
    /// # Errors
    /// Names the offending option.
    pub fn validate(&self) -> Result<()> {
        if self.max_iters == 0 {
            return Err(Error::option("box_qp.max_iters", "must be at least 1"));
        }
        if !(self.th_accept > 0.0 && self.th_accept < 0.5) {
            return Err(Error::option("box_qp.th_accept", "must be in (0, 0.5)"));
        }
        if !(self.th_grad.is_finite() && self.th_grad >= 0.0) {
            return Err(Error::option("box_qp.th_grad", "must be finite and nonnegative"));
        }
        Ok(())
    }
}

/// How a [`BoxQp::solve`] ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoxQpStatus {
    /// The free gradient is below `th_grad`, or every variable is clamped.
    Converged,
    /// The iteration limit was reached, or no step length decreased the objective;
    /// `x` is feasible and the best point found.
    Stopped,
}

/// Why a [`BoxQp::solve`] failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoxQpError {
    /// `H_ff` is not positive definite (or not finite) on the free set.
    NotPositiveDefinite,
}

/// Workspace of the projected-Newton box QP for `n` variables.
#[derive(Debug, Clone)]
pub struct BoxQp {
    n: usize,
    /// Whether variable `i` is free at the solution.
    free: Vec<bool>,
    /// Indices of the free variables, in order (the first `nf` entries).
    free_idx: Vec<usize>,
    nf: usize,
    /// Cholesky factor of `H_ff` (leading `nf x nf` block, lower triangle).
    l: Mat<f64>,
    g: Vec<f64>,
    dx: Vec<f64>,
    x_new: Vec<f64>,
    work: Vec<f64>,
    /// Step length of the last accepted step.
    last_alpha: f64,
}

impl BoxQp {
    /// A workspace for `n` variables.
    pub fn new(n: usize) -> Self {
        Self {
            n,
            free: vec![true; n],
            free_idx: vec![0; n],
            nf: 0,
            l: Mat::zeros(n, n),
            g: vec![0.0; n],
            dx: vec![0.0; n],
            x_new: vec![0.0; n],
            work: vec![0.0; n],
            last_alpha: 0.0,
        }
    }

    /// Number of variables.
    pub fn dim(&self) -> usize {
        self.n
    }

    /// Solves the QP from the warm start in `x` (clamped into the box first), leaving the
    /// solution in `x`. `H` must be symmetric; its lower triangle is read.
    ///
    /// # Errors
    /// If `H_ff` is not positive definite on a free set met on the way.
    pub fn solve(
        &mut self,
        h: MatRef<'_, f64>,
        q: &[f64],
        lb: &[f64],
        ub: &[f64],
        x: &mut [f64],
        opts: &BoxQpOptions,
    ) -> std::result::Result<BoxQpStatus, BoxQpError> {
        let n = self.n;
        debug_assert!(h.nrows() == n && h.ncols() == n && q.len() == n && x.len() == n);
        for i in 0..n {
            x[i] = x[i].min(ub[i]).max(lb[i]);
        }
        // Whether the last step was the whole Newton step, inside the box: then `x`
        // minimises the objective on the face of that free set exactly.
        let mut exact = false;
        for _ in 0..opts.max_iters {
            self.gradient(h, q, x);
            let same_face = self.classify(x, lb, ub);
            let gf = (0..self.nf).fold(0.0_f64, |m, i| m.max(self.g[self.free_idx[i]].abs()));
            if self.nf == 0 || gf <= opts.th_grad || (exact && same_face) {
                self.factor_free(h)?;
                return Ok(BoxQpStatus::Converged);
            }
            self.factor_free(h)?;
            // Newton step on the free variables: δx_f = -H_ff⁻¹ g_f, δx_c = 0.
            self.dx.fill(0.0);
            for i in 0..self.nf {
                self.work[i] = -self.g[self.free_idx[i]];
            }
            self.solve_free_vec();
            for i in 0..self.nf {
                self.dx[self.free_idx[i]] = self.work[i];
            }
            let inside = (0..n).all(|i| x[i] + self.dx[i] >= lb[i] && x[i] + self.dx[i] <= ub[i]);
            if !self.backtrack(h, q, lb, ub, x, opts) {
                self.gradient(h, q, x);
                self.classify(x, lb, ub);
                self.factor_free(h)?;
                return Ok(BoxQpStatus::Stopped);
            }
            exact = inside && self.last_alpha == 1.0;
        }
        self.gradient(h, q, x);
        self.classify(x, lb, ub);
        self.factor_free(h)?;
        Ok(BoxQpStatus::Stopped)
    }

    /// Whether variable `i` is free at the last solution.
    pub fn is_free(&self, i: usize) -> bool {
        self.free[i]
    }

    /// The gradient `H x + q` at the last solution (zero on the free variables up to
    /// `th_grad`; on the clamped ones, minus the bound multipliers).
    pub fn gradient_at_solution(&self) -> &[f64] {
        &self.g
    }

    /// In place `m ← -H_ff⁻¹ m_f` on the free rows of `m` (`n` rows) and `0` on the
    /// clamped rows: with `m = Q_ux`, box-DDP's feedback gain.
    pub fn apply_free_inverse_negated(&mut self, mut m: MatMut<'_, f64>) {
        for j in 0..m.ncols() {
            for i in 0..self.nf {
                self.work[i] = -m[(self.free_idx[i], j)];
            }
            self.solve_free_vec();
            for i in 0..self.n {
                m[(i, j)] = 0.0;
            }
            for i in 0..self.nf {
                m[(self.free_idx[i], j)] = self.work[i];
            }
        }
    }

    fn gradient(&mut self, h: MatRef<'_, f64>, q: &[f64], x: &[f64]) {
        for i in 0..self.n {
            let mut s = q[i];
            for j in 0..self.n {
                s += sym(h, i, j) * x[j];
            }
            self.g[i] = s;
        }
    }

    /// Clamped: at a bound with the gradient pointing out of the box. Returns whether
    /// the free set is the one of the last call.
    fn classify(&mut self, x: &[f64], lb: &[f64], ub: &[f64]) -> bool {
        self.nf = 0;
        let mut same = true;
        for i in 0..self.n {
            let clamped = (x[i] == lb[i] && self.g[i] > 0.0) || (x[i] == ub[i] && self.g[i] < 0.0);
            same &= self.free[i] != clamped;
            self.free[i] = !clamped;
            if !clamped {
                self.free_idx[self.nf] = i;
                self.nf += 1;
            }
        }
        same
    }

    /// Cholesky factorization of `H_ff` into the leading block of `l`.
    fn factor_free(&mut self, h: MatRef<'_, f64>) -> std::result::Result<(), BoxQpError> {
        let nf = self.nf;
        for c in 0..nf {
            for r in c..nf {
                let mut s = sym(h, self.free_idx[r], self.free_idx[c]);
                for k in 0..c {
                    s -= self.l[(r, k)] * self.l[(c, k)];
                }
                if r == c {
                    if !(s > 0.0 && s.is_finite()) {
                        return Err(BoxQpError::NotPositiveDefinite);
                    }
                    self.l[(c, c)] = s.sqrt();
                } else {
                    self.l[(r, c)] = s / self.l[(c, c)];
                }
            }
        }
        Ok(())
    }

    /// `work[..nf] ← H_ff⁻¹ work[..nf]` with the Cholesky factor.
    fn solve_free_vec(&mut self) {
        let nf = self.nf;
        for i in 0..nf {
            let mut s = self.work[i];
            for k in 0..i {
                s -= self.l[(i, k)] * self.work[k];
            }
            self.work[i] = s / self.l[(i, i)];
        }
        for i in (0..nf).rev() {
            let mut s = self.work[i];
            for k in (i + 1)..nf {
                s -= self.l[(k, i)] * self.work[k];
            }
            self.work[i] = s / self.l[(i, i)];
        }
    }

    /// Backtracking along the projected arc; returns whether a step was taken.
    fn backtrack(
        &mut self,
        h: MatRef<'_, f64>,
        q: &[f64],
        lb: &[f64],
        ub: &[f64],
        x: &mut [f64],
        opts: &BoxQpOptions,
    ) -> bool {
        let f_old = objective(h, q, x);
        let mut alpha = 1.0;
        for _ in 0..10 {
            for i in 0..self.n {
                self.x_new[i] = (x[i] + alpha * self.dx[i]).min(ub[i]).max(lb[i]);
            }
            let f_new = objective(h, q, &self.x_new);
            let predicted: f64 = (0..self.n).map(|i| self.g[i] * (x[i] - self.x_new[i])).sum();
            if f_old - f_new > opts.th_accept * predicted {
                x.copy_from_slice(&self.x_new);
                self.last_alpha = alpha;
                return true;
            }
            alpha *= 0.5;
        }
        false
    }
}

/// `H[i, j]` from the lower triangle.
fn sym(h: MatRef<'_, f64>, i: usize, j: usize) -> f64 {
    if i >= j { h[(i, j)] } else { h[(j, i)] }
}

/// `½ xᵀH x + qᵀx`.
fn objective(h: MatRef<'_, f64>, q: &[f64], x: &[f64]) -> f64 {
    let n = x.len();
    let mut f = 0.0;
    for i in 0..n {
        let mut hx = 0.0;
        for j in 0..n {
            hx += sym(h, i, j) * x[j];
        }
        f += x[i] * (0.5 * hx + q[i]);
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lq::random::SplitMix64;

    /// The reference: every assignment of each variable to lower bound, upper bound or
    /// free, solved as an equality-constrained QP, the one meeting the KKT conditions.
    fn enumerate(h: &Mat<f64>, q: &[f64], lb: &[f64], ub: &[f64]) -> Vec<f64> {
        let n = q.len();
        let mut best: Option<(f64, Vec<f64>)> = None;
        for code in 0..3usize.pow(n as u32) {
            let mut c = code;
            let state: Vec<usize> = (0..n)
                .map(|_| {
                    let s = c % 3;
                    c /= 3;
                    s
                })
                .collect();
            let mut x: Vec<f64> = (0..n)
                .map(|i| match state[i] {
                    0 => lb[i],
                    1 => ub[i],
                    _ => 0.0,
                })
                .collect();
            let free: Vec<usize> = (0..n).filter(|&i| state[i] == 2).collect();
            if !free.is_empty() {
                let m = free.len();
                let hff = Mat::from_fn(m, m, |a, b| h[(free[a], free[b])]);
                let mut rhs = Mat::from_fn(m, 1, |a, _| {
                    -q[free[a]]
                        - (0..n)
                            .filter(|j| state[*j] != 2)
                            .map(|j| h[(free[a], j)] * x[j])
                            .sum::<f64>()
                });
                let mut lu = crate::linalg::Lu::new(m, 1);
                lu.factor(hff.as_ref()).expect("positive-definite H");
                lu.solve_in_place(rhs.as_mut());
                for (a, &i) in free.iter().enumerate() {
                    x[i] = rhs[(a, 0)];
                }
            }
            let feasible = (0..n).all(|i| x[i] >= lb[i] - 1e-12 && x[i] <= ub[i] + 1e-12);
            if feasible {
                let f = objective(h.as_ref(), q, &x);
                if best.as_ref().is_none_or(|(fb, _)| f < *fb) {
                    best = Some((f, x));
                }
            }
        }
        best.expect("a feasible assignment").1
    }

    fn random_spd(n: usize, rng: &mut SplitMix64) -> Mat<f64> {
        let a = Mat::from_fn(n, n, |_, _| rng.uniform(-1.0, 1.0));
        let mut h = &a * a.transpose();
        for i in 0..n {
            h[(i, i)] += 0.1;
        }
        h
    }

    #[test]
    fn matches_active_set_enumeration() {
        let mut rng = SplitMix64::new(7);
        let opts = BoxQpOptions {
            th_grad: 1e-12,
            ..Default::default()
        };
        for trial in 0..200 {
            let n = 1 + trial % 5;
            let h = random_spd(n, &mut rng);
            let q: Vec<f64> = (0..n).map(|_| rng.uniform(-3.0, 3.0)).collect();
            let lb: Vec<f64> = (0..n).map(|_| rng.uniform(-1.0, 0.0)).collect();
            let ub: Vec<f64> = (0..n).map(|_| rng.uniform(0.0, 1.0)).collect();
            let mut x: Vec<f64> = (0..n).map(|_| rng.uniform(-2.0, 2.0)).collect();
            let mut qp = BoxQp::new(n);
            let status = qp.solve(h.as_ref(), &q, &lb, &ub, &mut x, &opts).unwrap();
            assert_eq!(status, BoxQpStatus::Converged, "trial {trial}");
            let reference = enumerate(&h, &q, &lb, &ub);
            for i in 0..n {
                assert!(
                    (x[i] - reference[i]).abs() < 1e-9,
                    "trial {trial}: {x:?} vs {reference:?}"
                );
            }
            // KKT: free gradient zero, clamped gradient pointing outwards.
            for i in 0..n {
                let g = qp.gradient_at_solution()[i];
                if qp.is_free(i) {
                    assert!(g.abs() < 1e-9);
                } else {
                    assert!((x[i] == lb[i] && g > 0.0) || (x[i] == ub[i] && g < 0.0));
                }
            }
        }
    }

    #[test]
    fn feedback_is_the_free_inverse() {
        let mut rng = SplitMix64::new(3);
        let n = 4;
        let h = random_spd(n, &mut rng);
        let q = vec![5.0, -0.1, 0.2, -5.0];
        let (lb, ub) = (vec![-1.0; n], vec![1.0; n]);
        let mut x = vec![0.0; n];
        let mut qp = BoxQp::new(n);
        qp.solve(h.as_ref(), &q, &lb, &ub, &mut x, &BoxQpOptions::default())
            .unwrap();
        let free: Vec<usize> = (0..n).filter(|&i| qp.is_free(i)).collect();
        assert!(free.len() < n && !free.is_empty());
        let qux = Mat::from_fn(n, 3, |_, _| rng.uniform(-1.0, 1.0));
        let mut k = qux.clone();
        qp.apply_free_inverse_negated(k.as_mut());
        // H_ff K_f = -Q_fx on the free rows, K = 0 on the clamped rows.
        for j in 0..3 {
            for &a in &free {
                let s: f64 = free.iter().map(|&b| h[(a, b)] * k[(b, j)]).sum();
                assert!((s + qux[(a, j)]).abs() < 1e-12);
            }
            for i in (0..n).filter(|i| !free.contains(i)) {
                assert_eq!(k[(i, j)], 0.0);
            }
        }
    }

    #[test]
    fn infinite_bounds_and_indefinite_hessians() {
        let n = 2;
        let mut h = Mat::zeros(n, n);
        h[(0, 0)] = 2.0;
        h[(1, 1)] = 1.0;
        let q = vec![-4.0, 1.0];
        let lb = vec![f64::NEG_INFINITY, 0.0];
        let ub = vec![f64::INFINITY, f64::INFINITY];
        let mut x = vec![0.0; n];
        let mut qp = BoxQp::new(n);
        let st = qp
            .solve(h.as_ref(), &q, &lb, &ub, &mut x, &BoxQpOptions::default())
            .unwrap();
        assert_eq!(st, BoxQpStatus::Converged);
        assert!((x[0] - 2.0).abs() < 1e-12 && x[1] == 0.0 && !qp.is_free(1));
        h[(0, 0)] = -1.0;
        assert_eq!(
            qp.solve(h.as_ref(), &q, &lb, &ub, &mut x, &BoxQpOptions::default()),
            Err(BoxQpError::NotPositiveDefinite)
        );
    }
}

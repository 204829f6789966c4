//! The reference solver: the whole KKT system of an [`LqProblem`] assembled as one dense
//! matrix and solved by LU with partial pivoting, and the KKT residuals of any solution.
//!
//! Unknowns, in order: `λ_0`, then for each knot `x_t, u_t, ν_t, λ_{t+1}` (no `λ` after
//! the last knot). The rows are the derivatives of the Lagrangian (module docs of
//! [`crate::lq`]) with respect to each unknown:
//! ```text
//! x_t:     Q x + S u + q + Cᵀν + Aᵀλ_{t+1} + E_{t-1}ᵀλ_t   (G0ᵀλ_0 at t = 0)
//! u_t:     Sᵀx + R u + r + Dᵀν + Bᵀλ_{t+1}
//! ν_t:     C x + D u + d - diag(mu_c) ν
//! λ_{t+1}: A x_t + B u_t + E x_{t+1} + f - mu_dyn λ_{t+1}
//! λ_0:     G0 x_0 + g0 - mu0 λ_0
//! ```
//! The matrix is symmetric (a saddle point); its size is the total number of unknowns, so
//! this is meant for tests on problems of up to a few thousand unknowns.

use faer::{Col, Mat};

use super::{LqError, LqProblem, LqSolution, LqVectors};
use crate::linalg::{self, FactorError, Lu};

/// Offsets of the unknowns in the dense KKT system.
#[derive(Debug, Clone)]
pub struct KktLayout {
    /// Offset of `λ_0`.
    pub lambda0: usize,
    /// Offset of `x_t`.
    pub x: Vec<usize>,
    /// Offset of `u_t`.
    pub u: Vec<usize>,
    /// Offset of `ν_t`.
    pub nu: Vec<usize>,
    /// Offset of `λ_{t+1}` (one per knot with dynamics).
    pub lambda: Vec<usize>,
    /// Total number of unknowns.
    pub dim: usize,
}

impl KktLayout {
    /// The layout of `problem`'s unknowns.
    pub fn new(problem: &LqProblem) -> Self {
        let mut off = problem.nc0();
        let mut layout = Self {
            lambda0: 0,
            x: Vec::new(),
            u: Vec::new(),
            nu: Vec::new(),
            lambda: Vec::new(),
            dim: 0,
        };
        for k in &problem.knots {
            layout.x.push(off);
            off += k.nx;
            layout.u.push(off);
            off += k.nu;
            layout.nu.push(off);
            off += k.nc;
            if k.nx_next > 0 {
                layout.lambda.push(off);
                off += k.nx_next;
            }
        }
        layout.dim = off;
        layout
    }
}

/// Assembles the KKT matrix `K` and right-hand side `b` (`K w = b`) of `problem`.
pub fn kkt_system(problem: &LqProblem) -> Result<(Mat<f64>, Col<f64>, KktLayout), LqError> {
    problem.validate()?;
    let l = KktLayout::new(problem);
    let mut k = Mat::<f64>::zeros(l.dim, l.dim);
    let mut b = Col::<f64>::zeros(l.dim);
    // Writes block `m` at (r, c) and its transpose at (c, r).
    let put = |k: &mut Mat<f64>, r: usize, c: usize, m: faer::MatRef<'_, f64>, sym: bool| {
        for j in 0..m.ncols() {
            for i in 0..m.nrows() {
                k[(r + i, c + j)] += m[(i, j)];
                if sym {
                    k[(c + j, r + i)] += m[(i, j)];
                }
            }
        }
    };
    let nc0 = problem.nc0();
    put(&mut k, l.lambda0, l.x[0], problem.G0.as_ref(), true);
    for i in 0..nc0 {
        k[(l.lambda0 + i, l.lambda0 + i)] = -problem.mu0;
        b[l.lambda0 + i] = -problem.g0[i];
    }
    let n = problem.knots.len();
    for (t, kn) in problem.knots.iter().enumerate() {
        let (x, u, nu) = (l.x[t], l.u[t], l.nu[t]);
        put(&mut k, x, x, kn.Q.as_ref(), false);
        put(&mut k, x, u, kn.S.as_ref(), true);
        put(&mut k, u, u, kn.R.as_ref(), false);
        put(&mut k, nu, x, kn.C.as_ref(), true);
        put(&mut k, nu, u, kn.D.as_ref(), true);
        for i in 0..kn.nx {
            b[x + i] = -kn.q[i];
        }
        for i in 0..kn.nu {
            b[u + i] = -kn.r[i];
        }
        for i in 0..kn.nc {
            k[(nu + i, nu + i)] = -kn.mu_c[i];
            b[nu + i] = -kn.d[i];
        }
        if t + 1 < n && kn.nx_next > 0 {
            let lam = l.lambda[t];
            put(&mut k, lam, x, kn.A.as_ref(), true);
            put(&mut k, lam, u, kn.B.as_ref(), true);
            put(&mut k, lam, l.x[t + 1], kn.E.as_ref(), true);
            for i in 0..kn.nx_next {
                k[(lam + i, lam + i)] = -kn.mu_dyn;
                b[lam + i] = -kn.f[i];
            }
        }
    }
    Ok((k, b, l))
}

/// Solves `problem` through its dense KKT system (LU with partial pivoting).
pub fn solve(problem: &LqProblem) -> Result<LqSolution, LqError> {
    let (k, mut b, l) = kkt_system(problem)?;
    let mut lu = Lu::new(l.dim, 1);
    lu.factor(k.as_ref()).map_err(|e| match e {
        FactorError::NonFinite => LqError::NonFinite {
            knot: 0,
            field: "dense KKT",
        },
        FactorError::Singular { .. } => LqError::Singular {
            knot: 0,
            system: "dense KKT",
        },
    })?;
    lu.solve_in_place(b.as_mut().as_mat_mut());
    let mut sol = LqSolution::new(problem);
    let copy = |dst: &mut Col<f64>, off: usize| {
        for i in 0..dst.nrows() {
            dst[i] = b[off + i];
        }
    };
    copy(&mut sol.lambdas[0], l.lambda0);
    for t in 0..problem.knots.len() {
        copy(&mut sol.xs[t], l.x[t]);
        copy(&mut sol.us[t], l.u[t]);
        copy(&mut sol.nus[t], l.nu[t]);
        if t < l.lambda.len() {
            copy(&mut sol.lambdas[t + 1], l.lambda[t]);
        }
    }
    Ok(sol)
}

/// Infinity norms of the residuals of the (regularised) KKT conditions.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct KktResiduals {
    /// Initial constraint and dynamics rows: `|G0 x_0 + g0 - mu0 λ_0|`,
    /// `|A x + B u + E x' + f - mu_dyn λ'|`.
    pub dynamics: f64,
    /// Constraint rows: `|C x + D u + d - diag(mu_c) ν|`.
    pub constraints: f64,
    /// Stationarity rows: the gradients of the Lagrangian in `x_t` and `u_t`.
    pub dual: f64,
}

impl KktResiduals {
    /// The largest of the three.
    pub fn max(&self) -> f64 {
        self.dynamics.max(self.constraints).max(self.dual)
    }
}

/// The KKT residuals of `sol` for `problem` (the residuals of the peer benchmarks,
/// generalised to any `E` and to the `mu` terms of the dynamics and the initial
/// constraint), from [`LqVectors::set_kkt_residual`].
pub fn kkt_residuals(problem: &LqProblem, sol: &LqSolution) -> Result<KktResiduals, LqError> {
    problem.check_shapes()?;
    let mut r = LqVectors::new(problem);
    r.set_kkt_residual(problem, sol)?;
    let inf = |v: &[Col<f64>]| v.iter().map(|c| linalg::norm_inf(linalg::slice(c))).fold(0.0, f64::max);
    Ok(KktResiduals {
        dynamics: inf(&r.f).max(linalg::norm_inf(linalg::slice(&r.g0))),
        constraints: inf(&r.d),
        dual: inf(&r.q).max(inf(&r.r)),
    })
}

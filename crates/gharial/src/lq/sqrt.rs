//! The square-root backward pass (ALTRO paper, Howell et al. 2019, Section III-A): the
//! recursion of the classical Riccati pass carried on upper-triangular Cholesky factors,
//! `P_t = S_tᵀS_t`, `Q_uu = Z_uuᵀZ_uu`, so that no value Hessian is ever formed by a
//! subtraction and none can lose positive definiteness.
//!
//! At knot `t`, with the cost Hessian in the order `(u, x)` factored as `UᵀU` (a Cholesky
//! factorization that accepts semidefinite costs), the stacked matrix
//! ```text
//!       [ diag(mu_c)^-½ [D  C]     ]   constraint rows as penalties (√I_μ c_u, √I_μ c_x)
//!   W = [ S_{t+1} [B  A]           ]   next value function           (S' f_u, S' f_x)
//!       [ U                        ]   cost                          (paper: √ℓ_uu, √ℓ_xx)
//!       [ √ρ I      0              ]   regularisation of Q_uu
//! ```
//! has `WᵀW = [[Q_uu + ρI, Q_ux], [Q_xu, Q_xx]]`, the Q-function Hessian of (7)-(10) of
//! the paper, whose square-root forms (19)-(21) are the blocks of its QR factor: the
//! Householder QR of `W` leaves
//! ```text
//!   R = [ Z_uu  Z_ux ]      Q_uu + ρI = Z_uuᵀZ_uu,  Q_ux = Z_uuᵀZ_ux,
//!       [ 0     S_t  ]      Q_xx = Z_uxᵀZ_ux + S_tᵀS_t,
//! ```
//! so that `K = -Z_uu⁻¹Z_ux`, `k = -Z_uu⁻¹Z_uu⁻ᵀQ_u` ((22)-(23)) and the value Hessian
//! `P_t = Q_xx - Q_xuQ_uu⁻¹Q_ux = S_tᵀS_t` is the trailing block: the factor update of
//! (26)-(29), which the paper writes as a QR followed by a downdate `DD(Z_uu, Z_xx⁻ᵀQ_xu)`, comes out of the same decomposition without a downdate (the
//! elimination of `u` is the Schur complement that the partial QR computes). The value
//! gradient is `p_t = Q_x - Z_uxᵀZ_uu⁻ᵀQ_u`.
//!
//! The affine part is carried in square-root form as well: the value function is kept as
//! `V_t(x) = ½|S_t x + s_t|² + p̂_tᵀx`, `W` gets the column `[diag(mu_c)^-½ d; S'f + s'; 0;
//! 0]` whose transformed entries are `(z_u, s_t)`, and only the cost's linear terms
//! `ĝ = [r; q] + [B A]ᵀp̂'` stay outside the factor. Then `k = -Z_uu⁻¹(z_u + Z_uu⁻ᵀĝ_u)`,
//! `p̂_t = ĝ_x - Z_uxᵀZ_uu⁻ᵀĝ_u` and `p_t = S_tᵀs_t + p̂_t`: the large, penalty-weighted
//! gradients never meet in a subtraction outside the orthogonal transformation.
//!
//! Constraint rows enter as the penalty of the knot's Lagrangian (module docs of
//! [`crate::lq`]): eliminating `ν = diag(mu_c)⁻¹(C x + D u + d)` leaves the cost
//! `½|diag(mu_c)^-½(C x + D u + d)|²`, so each row needs `mu_c > 0`, and a penalty of
//! `1e12` is a row with `mu_c = 1e-12` that the factor carries without squaring. The step
//! accepts knots with `E = -I` and `mu_dyn = 0` (the LQ subproblems of DDP and ALTRO).

use faer::prelude::ReborrowMut;
use faer::{Accum, Col, Mat, MatRef};

use super::stage::RiccatiStage;
use super::{LqError, LqKnot, is_minus_identity};
use crate::linalg::{
    self, householder_r, matmul, matvec_t, semidefinite_cholesky_upper, slice, slice_mut, upper_solve, upper_t_solve,
};

/// Storage of the square-root pass for one knot: the stacked matrix `W`, the factor
/// `S_t` of the value Hessian and the affine part of the value function.
#[derive(Debug)]
pub(super) struct SqrtKnot {
    w: Mat<f64>,
    s: Mat<f64>,
    /// `s_t` and `p̂_t` of `V_t(x) = ½|S_t x + s_t|² + p̂_tᵀx`.
    s_vec: Col<f64>,
    p_hat: Col<f64>,
    /// The gradient `ĝ` of the linear cost terms (`(u, x)` order).
    g: Col<f64>,
}

impl SqrtKnot {
    /// Storage for a knot of dimensions `nx, nu, nc`, next state `ny`.
    pub(super) fn new(nx: usize, nu: usize, nc: usize, ny: usize) -> Self {
        let n = nu + nx;
        Self {
            w: Mat::zeros(n + nc + ny + nu, n + 1),
            s: Mat::zeros(nx, nx),
            s_vec: Col::zeros(nx),
            p_hat: Col::zeros(nx),
            g: Col::zeros(n),
        }
    }

    /// The upper-triangular factor `S_t` of the value Hessian (`P_t = S_tᵀS_t`).
    pub(super) fn s(&self) -> MatRef<'_, f64> {
        self.s.as_ref()
    }
}

/// Refuses what the square-root step does not handle, naming the knot and the field.
fn check_knot(knot: &LqKnot, t: usize) -> Result<(), LqError> {
    if knot.nx_next > 0 && !is_minus_identity(knot.E.as_ref()) {
        return Err(LqError::Unsupported {
            knot: t,
            what: "E must be -I in the square-root pass",
        });
    }
    if knot.mu_dyn != 0.0 {
        return Err(LqError::Unsupported {
            knot: t,
            what: "mu_dyn must be 0 in the square-root pass",
        });
    }
    if (0..knot.nc).any(|i| knot.mu_c[i] <= 0.0 || !knot.mu_c[i].is_finite()) {
        return Err(LqError::Unsupported {
            knot: t,
            what: "constraint rows need mu_c > 0 (penalties) in the square-root pass",
        });
    }
    Ok(())
}

/// One knot of the square-root pass (module docs): fills `W`, triangularises it, and
/// writes the gains, the Q-function, the value function and `S_t` of the knot. `next` is
/// the next knot's storage, `None` at the last knot.
pub(super) fn step(
    st: &mut RiccatiStage,
    sq: &mut SqrtKnot,
    knot: &LqKnot,
    next: Option<&SqrtKnot>,
    reg: f64,
) -> Result<(), LqError> {
    let t = st.index();
    check_knot(knot, t)?;
    let (nx, nu) = (knot.nx, knot.nu);
    let n = nu + nx;
    let rows = fill_stack(sq, knot, next, reg, t)?;
    householder_r(sq.w.as_mut(), rows, n + 1);
    let r = sq.w.as_ref();
    let z_uu = r.submatrix(0, 0, nu, nu);
    let dmax = (0..nu).map(|i| z_uu[(i, i)].abs()).fold(0.0, f64::max);
    if (0..nu).any(|i| z_uu[(i, i)].abs() <= 1e-13 * dmax || !z_uu[(i, i)].is_finite()) {
        return Err(LqError::Singular {
            knot: t,
            system: "square-root factor Z_uu of Q_uu",
        });
    }
    for j in 0..nx {
        for i in 0..nx {
            sq.s[(i, j)] = if i <= j { r[(nu + i, nu + j)] } else { 0.0 };
        }
        sq.s_vec[j] = r[(nu + j, n)];
    }
    linear_gradient(sq, knot, next);
    write_stage(st, sq, knot, reg)
}

/// The stage's results from the triangular factor `R` (module docs): gains (22)-(23),
/// Q-function, value function `P = SᵀS`, `p = Sᵀs + p̂`, multiplier gains.
fn write_stage(st: &mut RiccatiStage, sq: &mut SqrtKnot, knot: &LqKnot, reg: f64) -> Result<(), LqError> {
    let (nx, nu) = (knot.nx, knot.nu);
    let n = nu + nx;
    let parts = st.square_root_parts();
    let r = sq.w.as_ref();
    let (z_uu, z_ux) = (r.submatrix(0, 0, nu, nu), r.submatrix(0, nu, nu, nx));
    // Q-function Hessian RᵀR and gradient Rᵀ[z; s] + ĝ in the stage's (x, u) order,
    // without the regularisation.
    for j in 0..n {
        for i in 0..n {
            let (a, b) = ((i + nu) % n, (j + nu) % n);
            let mut v: f64 = (0..=a.min(b)).map(|k| r[(k, a)] * r[(k, b)]).sum();
            if a == b && a < nu {
                v -= reg;
            }
            parts.qmat[(i, j)] = v;
        }
        let a = (j + nu) % n;
        parts.qvec[j] = (0..=a).map(|k| r[(k, a)] * r[(k, n)]).sum::<f64>() + sq.g[a];
    }
    // w = Z_uu⁻ᵀĝ_u, k = -Z_uu⁻¹(z_u + w) (23), p̂ = ĝ_x - Z_uxᵀw (24).
    let g = slice(&sq.g);
    let ff = linalg::col_of_mut(parts.gains, 0);
    ff[..nu].copy_from_slice(&g[..nu]);
    upper_t_solve(z_uu, nu, &mut ff[..nu]);
    let p_hat = slice_mut(&mut sq.p_hat);
    p_hat.copy_from_slice(&g[nu..]);
    matvec_t(p_hat, Accum::Add, z_ux, &ff[..nu], -1.0);
    for i in 0..nu {
        ff[i] = -(ff[i] + r[(i, n)]);
    }
    upper_solve(z_uu, nu, &mut ff[..nu]);
    for j in 0..nx {
        let col = &mut linalg::col_of_mut(parts.gains, 1 + j)[..nu];
        for i in 0..nu {
            col[i] = -z_ux[(i, j)];
        }
        upper_solve(z_uu, nu, col);
    }
    matmul(parts.P.as_mut(), Accum::Replace, sq.s.transpose(), sq.s.as_ref(), 1.0);
    let p = slice_mut(parts.p);
    p.copy_from_slice(slice(&sq.p_hat));
    matvec_t(p, Accum::Add, sq.s.as_ref(), slice(&sq.s_vec), 1.0);
    slice_mut(parts.f_tilde).copy_from_slice(slice(&knot.f));
    penalty_multiplier_gains(parts.gains, knot);
    let finite = linalg::sum_is_finite(parts.P.as_ref()) && slice(parts.p).iter().sum::<f64>().is_finite();
    if !finite {
        return Err(LqError::NonFinite {
            knot: st.index(),
            field: "square-root value function",
        });
    }
    Ok(())
}

/// Fills `W` and its affine column (module docs) and returns its number of rows.
fn fill_stack(sq: &mut SqrtKnot, knot: &LqKnot, next: Option<&SqrtKnot>, reg: f64, t: usize) -> Result<usize, LqError> {
    let (nx, nu, nc, ny) = (knot.nx, knot.nu, knot.nc, knot.nx_next);
    let n = nu + nx;
    let mut w = sq.w.as_mut();
    // Rows in decreasing order of their likely weight (penalties, next value function,
    // cost, regularisation): Householder QR of a stiff least-squares matrix is accurate
    // when its heavy rows come first (Powell and Reid 1969; Cox and Higham 1998).
    for i in 0..nc {
        let s = knot.mu_c[i].sqrt().recip();
        for j in 0..nu {
            w[(i, j)] = s * knot.D[(i, j)];
        }
        for j in 0..nx {
            w[(i, nu + j)] = s * knot.C[(i, j)];
        }
        w[(i, n)] = s * knot.d[i];
    }
    let mut rows = nc;
    if let Some(nk) = next {
        // S'[B A | f] + [0 0 | s'].
        let mut dyn_rows = w.rb_mut().submatrix_mut(rows, 0, ny, n + 1);
        let s_next = nk.s.as_ref();
        matmul(
            dyn_rows.rb_mut().subcols_mut(0, nu),
            Accum::Replace,
            s_next,
            knot.B.as_ref(),
            1.0,
        );
        matmul(
            dyn_rows.rb_mut().subcols_mut(nu, nx),
            Accum::Replace,
            s_next,
            knot.A.as_ref(),
            1.0,
        );
        let mut aff = dyn_rows.subcols_mut(n, 1);
        linalg::copy(aff.rb_mut(), nk.s_vec.as_ref().as_mat());
        matmul(aff, Accum::Add, s_next, knot.f.as_ref().as_mat(), 1.0);
        rows += ny;
    }
    // Cost Hessian [[R, Sᵀ], [S, Q]] in (u, x) order; its linear terms stay in ĝ.
    let h = |i: usize, j: usize| match (i < nu, j < nu) {
        (true, true) => knot.R[(i, j)],
        (true, false) => knot.S[(j - nu, i)],
        (false, true) => knot.S[(i - nu, j)],
        (false, false) => knot.Q[(i - nu, j - nu)],
    };
    semidefinite_cholesky_upper(n, h, w.rb_mut().submatrix_mut(rows, 0, n, n)).map_err(|_| LqError::Singular {
        knot: t,
        system: "cost Hessian (not positive semidefinite) in the square-root pass",
    })?;
    for i in 0..n {
        w[(rows + i, n)] = 0.0;
    }
    rows += n;
    if reg > 0.0 {
        let s = reg.sqrt();
        for i in 0..nu {
            for j in 0..=n {
                w[(rows + i, j)] = if i == j { s } else { 0.0 };
            }
        }
        rows += nu;
    }
    Ok(rows)
}

/// The gradient of the terms kept out of the factor, in `(u, x)` order, into `sq.g`:
/// `ĝ = [r; q] + [B A]ᵀp̂'`.
fn linear_gradient(sq: &mut SqrtKnot, knot: &LqKnot, next: Option<&SqrtKnot>) {
    let nu = knot.nu;
    let g = slice_mut(&mut sq.g);
    let (gu, gx) = g.split_at_mut(nu);
    gu.copy_from_slice(slice(&knot.r));
    gx.copy_from_slice(slice(&knot.q));
    if let Some(nk) = next {
        matvec_t(gu, Accum::Add, knot.B.as_ref(), slice(&nk.p_hat), 1.0);
        matvec_t(gx, Accum::Add, knot.A.as_ref(), slice(&nk.p_hat), 1.0);
    }
}

/// Multiplier gains of the penalty rows, `ν = diag(mu_c)⁻¹(C x + D u + d)` with
/// `u = k + K x`: `ζ = diag(mu_c)⁻¹(d + D k)`, `Z = diag(mu_c)⁻¹(C + D K)`.
fn penalty_multiplier_gains(gains: &mut Mat<f64>, knot: &LqKnot) {
    let (nx, nu, nc) = (knot.nx, knot.nu, knot.nc);
    for i in 0..nc {
        let inv = knot.mu_c[i].recip();
        let mut z0 = knot.d[i];
        for l in 0..nu {
            z0 += knot.D[(i, l)] * gains[(l, 0)];
        }
        gains[(nu + i, 0)] = inv * z0;
        for j in 0..nx {
            let mut z = knot.C[(i, j)];
            for l in 0..nu {
                z += knot.D[(i, l)] * gains[(l, 1 + j)];
            }
            gains[(nu + i, 1 + j)] = inv * z;
        }
    }
}

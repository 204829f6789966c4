//! Square-root kernels: the triangular factor of a QR decomposition by Householder
//! reflections in place, a Cholesky factorization that accepts semidefinite matrices, and
//! triangular solves with an upper factor. All work in the caller's storage (no
//! allocation); sizes are those of one knot of an LQ problem.

use faer::MatMut;
use faer::prelude::Reborrow;

/// Householder QR of the leading `rows x cols` block of `a`, in place: on return its upper
/// triangle (the first `min(rows, cols)` rows) holds `R` with `QᵀA = R`, so that
/// `RᵀR = AᵀA`; the entries below the diagonal hold the reflectors and are meaningless to
/// the caller. Columns are processed left to right, so the leading block of `R` is the
/// factor of the leading columns of `A` (what a square-root Riccati step relies on).
pub(crate) fn householder_r(mut a: MatMut<'_, f64>, rows: usize, cols: usize) {
    for j in 0..rows.min(cols) {
        let (alpha, sigma) = {
            let c = a.rb().col(j);
            let mut s = 0.0;
            for i in j + 1..rows {
                s += c[i] * c[i];
            }
            (c[j], s)
        };
        if sigma == 0.0 {
            continue;
        }
        // H = I - τ v vᵀ with v = [1; x₂/v₀], sending x to β e₁, β = -sign(α)|x|.
        let norm = (alpha * alpha + sigma).sqrt();
        let beta = if alpha > 0.0 { -norm } else { norm };
        let v0 = alpha - beta;
        let tau = (beta - alpha) / beta;
        for i in j + 1..rows {
            a[(i, j)] /= v0;
        }
        a[(j, j)] = beta;
        for k in j + 1..cols {
            let mut w = a[(j, k)];
            for i in j + 1..rows {
                w += a[(i, j)] * a[(i, k)];
            }
            w *= tau;
            a[(j, k)] -= w;
            for i in j + 1..rows {
                let vi = a[(i, j)];
                a[(i, k)] -= w * vi;
            }
        }
    }
}

/// Upper Cholesky factor `U` (`UᵀU = H`) of the symmetric positive semidefinite `n x n`
/// matrix whose upper triangle `h(i, j)` gives, written into the upper triangle of `u`
/// (the strict lower triangle is zeroed). A pivot below `n ε max_i H_ii` is taken as zero
/// with its row of `U`, so that semidefinite matrices (a cost without weight on some
/// states) are accepted. Returns the index of a pivot that is clearly negative (the matrix
/// is not semidefinite) as an error.
pub(crate) fn semidefinite_cholesky_upper(
    n: usize,
    h: impl Fn(usize, usize) -> f64,
    mut u: MatMut<'_, f64>,
) -> Result<(), usize> {
    let scale = (0..n).map(|i| h(i, i).abs()).fold(0.0, f64::max);
    let tol = (n.max(1) as f64) * f64::EPSILON * scale;
    for j in 0..n {
        for i in j + 1..n {
            u[(i, j)] = 0.0;
        }
        let mut d = h(j, j);
        for i in 0..j {
            d -= u[(i, j)] * u[(i, j)];
        }
        if d <= tol {
            if d < -tol.max(f64::MIN_POSITIVE) * 1e3 || d.is_nan() {
                return Err(j);
            }
            for k in j..n {
                u[(j, k)] = 0.0;
            }
            continue;
        }
        let ujj = d.sqrt();
        u[(j, j)] = ujj;
        for k in j + 1..n {
            let mut s = h(j, k);
            for i in 0..j {
                s -= u[(i, j)] * u[(i, k)];
            }
            u[(j, k)] = s / ujj;
        }
    }
    Ok(())
}

/// Solves `U x = b` in place (`U` the leading `n x n` upper triangle of `u`).
pub(crate) fn upper_solve(u: faer::MatRef<'_, f64>, n: usize, x: &mut [f64]) {
    for i in (0..n).rev() {
        let mut s = x[i];
        for k in i + 1..n {
            s -= u[(i, k)] * x[k];
        }
        x[i] = s / u[(i, i)];
    }
}

/// Solves `Uᵀ x = b` in place (`U` the leading `n x n` upper triangle of `u`).
pub(crate) fn upper_t_solve(u: faer::MatRef<'_, f64>, n: usize, x: &mut [f64]) {
    for i in 0..n {
        let mut s = x[i];
        for k in 0..i {
            s -= u[(k, i)] * x[k];
        }
        x[i] = s / u[(i, i)];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::Mat;

    #[test]
    fn householder_r_gives_the_gram_factor() {
        let (m, n) = (7, 4);
        let a = Mat::<f64>::from_fn(m, n, |i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0 + 0.1 * (i as f64));
        let mut r = a.clone();
        householder_r(r.as_mut(), m, n);
        let mut rt = Mat::<f64>::zeros(n, n);
        for j in 0..n {
            for i in 0..=j {
                rt[(i, j)] = r[(i, j)];
            }
        }
        let g = a.transpose() * &a;
        let h = rt.transpose() * &rt;
        let err = (0..n)
            .flat_map(|i| (0..n).map(move |j| (i, j)))
            .map(|(i, j)| (g[(i, j)] - h[(i, j)]).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-12 * g.norm_max(), "{err}");
    }

    #[test]
    fn semidefinite_cholesky_and_solves() {
        // H = LᵀL with a zero row in L: rank 2 of 3.
        let l = Mat::<f64>::from_fn(3, 3, |i, j| if i == 1 { 0.0 } else { 1.0 + (i + 2 * j) as f64 });
        let h = l.transpose() * &l;
        let mut u = Mat::<f64>::zeros(3, 3);
        semidefinite_cholesky_upper(3, |i, j| h[(i, j)], u.as_mut()).unwrap();
        let back = u.transpose() * &u;
        assert!((&back - &h).norm_max() < 1e-12 * h.norm_max());
        let bad = Mat::<f64>::from_fn(2, 2, |i, j| if i == j { [1.0, -1.0][i] } else { 0.0 });
        assert_eq!(semidefinite_cholesky_upper(2, |i, j| bad[(i, j)], u.as_mut()), Err(1));
        let pd = Mat::<f64>::from_fn(3, 3, |i, j| if i == j { 4.0 } else { 1.0 });
        semidefinite_cholesky_upper(3, |i, j| pd[(i, j)], u.as_mut()).unwrap();
        let b = [1.0, 2.0, 3.0];
        let mut x = b;
        upper_t_solve(u.as_ref(), 3, &mut x);
        upper_solve(u.as_ref(), 3, &mut x);
        for i in 0..3 {
            let r: f64 = (0..3).map(|j| pd[(i, j)] * x[j]).sum();
            assert!((r - b[i]).abs() < 1e-13);
        }
    }
}

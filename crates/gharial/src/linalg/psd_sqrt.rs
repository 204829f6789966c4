//! [`psd_sqrt`]: the symmetric square root of a small symmetric positive semidefinite
//! matrix, by the cyclic Jacobi eigenvalue method (no allocation, no scratch beyond the
//! caller's eigenvector matrix).

use faer::MatMut;

/// Most Jacobi sweeps (each annihilates every off-diagonal entry once); the method
/// converges quadratically, in a handful of sweeps for the small matrices it is used on.
const MAX_SWEEPS: usize = 60;

/// Replaces the symmetric positive semidefinite `a` (`n x n`) by its symmetric square
/// root `V diag(√max(w, 0)) Vᵀ`, where `a = V diag(w) Vᵀ` is computed by cyclic Jacobi
/// rotations into `v` (`n x n`, overwritten). Negative round-off eigenvalues count as 0.
pub(crate) fn psd_sqrt(mut a: MatMut<'_, f64>, mut v: MatMut<'_, f64>) {
    let n = a.nrows();
    debug_assert!(a.ncols() == n && v.nrows() == n && v.ncols() == n);
    for i in 0..n {
        for j in 0..n {
            v[(i, j)] = f64::from(u8::from(i == j));
        }
    }
    for _ in 0..MAX_SWEEPS {
        let (mut off, mut diag) = (0.0, 0.0);
        for i in 0..n {
            diag += a[(i, i)] * a[(i, i)];
            for j in (i + 1)..n {
                off += a[(i, j)] * a[(i, j)];
            }
        }
        if off <= 1e-32 * diag || off == 0.0 {
            break;
        }
        for p in 0..n {
            for q in (p + 1)..n {
                let apq = a[(p, q)];
                if apq == 0.0 {
                    continue;
                }
                // The rotation that zeroes a_pq (Golub & Van Loan, algorithm 8.5.1).
                let tau = (a[(q, q)] - a[(p, p)]) / (2.0 * apq);
                let t = tau.signum() / (tau.abs() + (1.0 + tau * tau).sqrt());
                let t = if tau == 0.0 { 1.0 } else { t };
                let c = 1.0 / (1.0 + t * t).sqrt();
                let s = t * c;
                for k in 0..n {
                    let (akp, akq) = (a[(k, p)], a[(k, q)]);
                    a[(k, p)] = c * akp - s * akq;
                    a[(k, q)] = s * akp + c * akq;
                }
                for k in 0..n {
                    let (apk, aqk) = (a[(p, k)], a[(q, k)]);
                    a[(p, k)] = c * apk - s * aqk;
                    a[(q, k)] = s * apk + c * aqk;
                }
                for k in 0..n {
                    let (vkp, vkq) = (v[(k, p)], v[(k, q)]);
                    v[(k, p)] = c * vkp - s * vkq;
                    v[(k, q)] = s * vkp + c * vkq;
                }
            }
        }
    }
    // `a` is diagonal now: V √D Vᵀ = (V D^¼)(V D^¼)ᵀ.
    for k in 0..n {
        let r = a[(k, k)].max(0.0).sqrt().sqrt();
        for i in 0..n {
            v[(i, k)] *= r;
        }
    }
    for i in 0..n {
        for j in 0..n {
            a[(i, j)] = (0..n).map(|k| v[(i, k)] * v[(j, k)]).sum();
        }
    }
}

#[cfg(test)]
mod tests {
    use faer::Mat;

    use super::*;
    use crate::lq::random::SplitMix64;

    /// The square root squares back to the matrix, on random positive semidefinite
    /// matrices of varied sizes and ranks (and on projectors, whose root is themselves).
    #[test]
    fn square_root_squares_back() {
        let mut rng = SplitMix64::new(5);
        for n in 1..=7 {
            for rank in 0..=n {
                let l = Mat::from_fn(n, rank, |_, _| rng.uniform(-1.0, 1.0));
                let a = &l * l.transpose();
                let mut r = a.clone();
                let mut v = Mat::zeros(n, n);
                psd_sqrt(r.as_mut(), v.as_mut());
                let back = &r * &r;
                let err = (0..n)
                    .flat_map(|i| (0..n).map(move |j| (i, j)))
                    .map(|(i, j)| (back[(i, j)] - a[(i, j)]).abs() + (r[(i, j)] - r[(j, i)]).abs())
                    .fold(0.0, f64::max);
                assert!(err < 1e-12, "n {n} rank {rank}: {err:e}");
            }
        }
        // A projector is its own root.
        let mut p = Mat::from_fn(3, 3, |i, j| if i == j && i < 2 { 1.0 } else { 0.0 });
        let mut v = Mat::zeros(3, 3);
        psd_sqrt(p.as_mut(), v.as_mut());
        assert!((p[(0, 0)] - 1.0).abs() < 1e-15 && p[(2, 2)].abs() < 1e-15);
    }
}

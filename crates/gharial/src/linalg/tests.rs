//! Shared helpers of the tests of the module, and the tests that run every factorization
//! on the same systems.

use faer::{Accum, Mat, MatMut, MatRef};

use super::{BunchKaufman, FactorError, Inertia, Ldlt, Llt, Lu, matmul, norm_max};

pub(super) fn spd(n: usize, seed: u64) -> Mat<f64> {
    let mut s = seed;
    let mut next = || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((s >> 11) as f64) / ((1u64 << 53) as f64) - 0.5
    };
    let l = Mat::from_fn(n, n, |_, _| next());
    let mut a = Mat::<f64>::identity(n, n);
    matmul(a.as_mut(), Accum::Add, l.as_ref(), l.transpose(), 1.0);
    a
}

pub(super) fn residual(a: MatRef<'_, f64>, x: MatRef<'_, f64>, b: MatRef<'_, f64>) -> f64 {
    let mut r = b.to_owned();
    matmul(r.as_mut(), Accum::Add, a, x, -1.0);
    norm_max(r.as_ref())
}

/// Entry-by-entry product, the reference of the kernel tests.
pub(super) fn naive(lhs: MatRef<'_, f64>, rhs: MatRef<'_, f64>) -> Mat<f64> {
    Mat::from_fn(lhs.nrows(), rhs.ncols(), |i, j| {
        (0..lhs.ncols()).map(|l| lhs[(i, l)] * rhs[(l, j)]).sum()
    })
}

pub(super) fn filled(m: usize, n: usize, seed: usize) -> Mat<f64> {
    Mat::from_fn(m, n, |i, j| (((i * 31 + j * 17 + seed * 7) % 23) as f64 - 11.0) / 7.0)
}

/// Solves `a x = b` in place with `solve`, and the strided system whose right-hand
/// sides are the rows of `filled(cols, n, cols)`, and checks both residuals.
pub(super) fn assert_solves_system(
    mut solve: impl FnMut(MatMut<'_, f64>),
    a: MatRef<'_, f64>,
    b: &Mat<f64>,
    cols: usize,
    tol: f64,
) {
    let n = a.nrows();
    let mut x = b.clone();
    solve(x.as_mut());
    assert!(residual(a, x.as_ref(), b.as_ref()) < tol, "n {n}, {cols} columns");
    let bt = filled(cols, n, cols);
    let mut xt = bt.clone();
    solve(xt.as_mut().transpose_mut());
    assert!(residual(a, xt.transpose(), bt.transpose()) < tol, "n {n}, transposed");
}

/// Solves `b` (contiguous right-hand sides) and `btᵀ` (strided ones) in place with
/// `solve` and compares them with the reference solutions `x_ref` and `xt_ref`.
pub(super) fn assert_solves_match(
    mut solve: impl FnMut(MatMut<'_, f64>),
    b: &Mat<f64>,
    bt: &Mat<f64>,
    x_ref: &Mat<f64>,
    xt_ref: &Mat<f64>,
    tol: f64,
    what: &str,
) {
    let mut x = b.clone();
    solve(x.as_mut());
    let mut xt = bt.clone();
    solve(xt.as_mut().transpose_mut());
    let n = b.nrows();
    for j in 0..n {
        for i in 0..b.ncols() {
            assert!((x[(j, i)] - x_ref[(j, i)]).abs() < tol, "{what} solve n {n}");
        }
        for i in 0..bt.nrows() {
            assert!((xt[(i, j)] - xt_ref[(j, i)]).abs() < tol, "{what} strided solve n {n}");
        }
    }
}

#[test]
fn factorizations_solve_random_systems() {
    for n in [1, 2, 5, 13, 40] {
        let a = spd(n, n as u64);
        let b = Mat::from_fn(n, 3, |i, j| (i as f64 + 1.0) * (j as f64 - 1.0) + 0.5);

        let mut f = Llt::new(n);
        f.factor(a.as_ref()).unwrap();
        let mut x = b.clone();
        f.solve_in_place(x.as_mut());
        assert!(residual(a.as_ref(), x.as_ref(), b.as_ref()) < 1e-10);

        let mut f = Ldlt::new(n);
        let inertia = f.factor(a.as_ref()).unwrap();
        assert_eq!(
            inertia,
            Inertia {
                positive: n,
                negative: 0,
                zero: 0
            }
        );
        let mut x = b.clone();
        f.solve_in_place(x.as_mut());
        assert!(residual(a.as_ref(), x.as_ref(), b.as_ref()) < 1e-10);

        // Saddle point [[A, I], [I, 0]]: inertia (n, n, 0).
        let mut k = Mat::<f64>::zeros(2 * n, 2 * n);
        k.as_mut().submatrix_mut(0, 0, n, n).copy_from(a.as_ref());
        for i in 0..n {
            k[(n + i, i)] = 1.0;
            k[(i, n + i)] = 1.0;
        }
        let b2 = Mat::from_fn(2 * n, 2, |i, j| (i * 3 + j) as f64 - 2.0);
        let mut f = BunchKaufman::new(2 * n);
        let inertia = f.factor(k.as_ref(), 1e-13).unwrap();
        assert_eq!(
            inertia,
            Inertia {
                positive: n,
                negative: n,
                zero: 0
            }
        );
        let mut x = b2.clone();
        f.solve_in_place(x.as_mut());
        assert!(residual(k.as_ref(), x.as_ref(), b2.as_ref()) < 1e-9);

        let mut f = Lu::new(2 * n, 2);
        f.factor(k.as_ref()).unwrap();
        let mut x = b2.clone();
        f.solve_in_place(x.as_mut());
        assert!(residual(k.as_ref(), x.as_ref(), b2.as_ref()) < 1e-9);
        let mut x = b2.clone();
        f.solve_transpose_in_place(x.as_mut());
        assert!(residual(k.transpose(), x.as_ref(), b2.as_ref()) < 1e-9);
    }
}

/// The row-wise LU solve against faer's column solve (random matrices, so with row
/// exchanges; a wrong permutation or substitution is off by O(1)), scaled, for the
/// shapes of a Riccati stage's `E` block among others.
#[test]
fn lu_solve_by_rows_equals_the_column_solve() {
    let mut rng = crate::lq::random::SplitMix64::new(11);
    for (n, m) in [(1, 1), (3, 1), (6, 1), (6, 48), (7, 5), (12, 37), (30, 9)] {
        let a = Mat::from_fn(n, n, |i, j| rng.uniform(-1.0, 1.0) + if i == j { 0.5 } else { 0.0 });
        let b = Mat::from_fn(n, m, |_, _| rng.uniform(-1.0, 1.0));
        let mut f = Lu::new(n, m);
        f.factor(a.as_ref()).unwrap();
        let mut x = b.clone();
        f.solve_in_place(x.as_mut());
        let mut y = b.clone();
        let mut rows = vec![f64::NAN; n * m];
        f.solve_rows_in_place(y.as_mut(), -2.0, &mut rows);
        let scale = norm_max(x.as_ref()).max(1.0);
        for i in 0..n {
            for c in 0..m {
                assert!(
                    (y[(i, c)] + 2.0 * x[(i, c)]).abs() < 1e-11 * scale,
                    "{n}x{m} at ({i}, {c})"
                );
            }
        }
    }
}

#[test]
fn singular_and_non_finite_are_reported() {
    let mut f = Llt::new(2);
    let a = Mat::from_fn(2, 2, |i, j| if i == j { -1.0 } else { 0.0 });
    assert!(matches!(f.factor(a.as_ref()), Err(FactorError::Singular { .. })));
    let a = Mat::from_fn(2, 2, |_, _| f64::NAN);
    assert_eq!(f.factor(a.as_ref()), Err(FactorError::NonFinite));
    let mut lu = Lu::new(2, 1);
    let z = Mat::<f64>::zeros(2, 2);
    assert!(matches!(lu.factor(z.as_ref()), Err(FactorError::Singular { .. })));
}

/// Inertia of sparse saddle-point matrices shaped like an OCP's KKT system (banded
/// Hessian, sparse constraint rows with many exact zeros, a small negative diagonal on
/// the multiplier rows) against the signs of faer's eigenvalues.
#[test]
fn bunch_kaufman_inertia_of_sparse_kkt_matrices() {
    let mut rng = crate::lq::random::SplitMix64::new(5);
    for (n, m) in [(12, 8), (40, 30), (120, 96), (130, 86), (200, 150)] {
        for trial in 0..40 {
            let dim = n + m;
            let mut k = Mat::<f64>::zeros(dim, dim);
            for i in 0..n {
                k[(i, i)] = if rng.uniform(0.0, 1.0) < 0.3 {
                    0.0
                } else {
                    rng.uniform(-1.0, 2.0)
                };
                if i + 1 < n && rng.uniform(0.0, 1.0) < 0.5 {
                    let v = rng.uniform(-1.0, 1.0);
                    k[(i, i + 1)] = v;
                    k[(i + 1, i)] = v;
                }
            }
            for r in 0..m {
                let row = n + r;
                for _ in 0..3 {
                    let c = rng.int(0, n);
                    let v = if rng.uniform(0.0, 1.0) < 0.3 {
                        1.0
                    } else {
                        rng.uniform(-1.0, 1.0)
                    };
                    k[(row, c)] = v;
                    k[(c, row)] = v;
                }
                k[(row, row)] = if trial % 2 == 0 { -1e-8 } else { 0.0 };
            }
            let eig = k.as_ref().self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
            let scale = eig.iter().fold(0.0_f64, |a, &b| a.max(b.abs()));
            let tol = 1e-10 * scale;
            if eig.iter().any(|e| e.abs() <= tol) {
                continue; // numerically singular: the inertia is not well defined
            }
            let pos = eig.iter().filter(|&&e| e > 0.0).count();
            let mut f = BunchKaufman::new(dim);
            let inertia = f.factor(k.as_ref(), 1e-13).unwrap();
            assert_eq!(
                (inertia.positive, inertia.negative),
                (pos, dim - pos),
                "n {n} m {m} trial {trial}"
            );
        }
    }
}

/// The Gram kernel adds `aᵀ W a` to the lower triangle and leaves the upper one alone,
/// equal to the entry-by-entry product, for dense matrices (faer's product from a size
/// on), matrices with zero rows, zero columns and identity-like sparsity, a shifted
/// identity, one row, and diagonal weights with zeros: the skipped zeros change nothing.
#[test]
fn gram_lower_add_matches_the_naive_product() {
    use super::{GramScratch, GramWeight};
    for (case, (nr, n)) in [(1, 1), (1, 7), (3, 12), (12, 12), (12, 36), (36, 36), (12, 40), (5, 3)]
        .into_iter()
        .enumerate()
    {
        let mut scratch = GramScratch::new(nr, n);
        for pattern in 0..6 {
            if pattern == 5 && nr > n {
                continue;
            }
            let mut a = filled(nr, n, case + pattern);
            match pattern {
                1 => a.as_mut().row_mut(nr / 2).fill(0.0),
                2 => {
                    for c in (0..n).step_by(3) {
                        a.as_mut().col_mut(c).fill(0.0);
                    }
                }
                3 => a = Mat::from_fn(nr, n, |r, c| if r == c || (r < 3 && c < 3) { a[(r, c)] } else { 0.0 }),
                4 => a.fill(0.0),
                // The identity shifted to the last columns (a velocity error).
                5 => a = Mat::from_fn(nr, n, |r, c| if c == r + n - nr { 1.0 } else { 0.0 }),
                _ => {}
            }
            // A diagonal weight with a zero entry, and a full symmetric one.
            let s: Vec<f64> = (0..nr).map(|r| if r % 4 == 3 { 0.0 } else { 0.5 + r as f64 }).collect();
            let wd = Mat::from_fn(nr, nr, |i, j| if i == j { s[i] } else { 0.0 });
            let f = filled(nr, nr, case);
            let wf = Mat::from_fn(nr, nr, |i, j| f[(i, j)] + f[(j, i)]);
            let b = naive(wf.as_ref(), a.as_ref());
            for (w, weight) in [
                (&wd, GramWeight::Diagonal(&s)),
                (&wf, GramWeight::Product(b.as_ref(), -0.75)),
            ] {
                let alpha = if matches!(weight, GramWeight::Product(..)) {
                    -0.75
                } else {
                    1.0
                };
                let init = filled(n, n, 9 + case);
                let mut dst = init.clone();
                scratch.load(a.as_ref());
                scratch.gram_lower_add(dst.as_mut(), a.as_ref(), weight);
                // And the matrix-vector product of the loaded `a`.
                let gv: Vec<f64> = (0..nr).map(|r| 0.5 - r as f64 / 7.0).collect();
                let mut y: Vec<f64> = (0..n).map(|c| c as f64).collect();
                scratch.matvec_t_add(&mut y, a.as_ref(), &gv, -1.5);
                for c in 0..n {
                    let expected = c as f64 - 1.5 * (0..nr).map(|r| a[(r, c)] * gv[r]).sum::<f64>();
                    assert!(
                        (y[c] - expected).abs() <= 1e-12 * (1.0 + expected.abs()),
                        "aᵀg {nr}x{n}"
                    );
                }
                let zero = (0..n).all(|c| (0..nr).all(|r| a[(r, c)] == 0.0));
                assert_eq!(scratch.is_zero(), zero, "{nr}x{n} pattern {pattern}");
                assert!(zero || pattern != 4);
                let reference = naive(a.transpose(), naive(w.as_ref(), a.as_ref()).as_ref());
                for c in 0..n {
                    for r in 0..n {
                        let expected = if r >= c {
                            init[(r, c)] + alpha * reference[(r, c)]
                        } else {
                            init[(r, c)]
                        };
                        let err = (dst[(r, c)] - expected).abs();
                        assert!(
                            err <= 1e-12 * (1.0 + expected.abs()),
                            "{nr}x{n} pattern {pattern}: ({r}, {c}) {} vs {expected}",
                            dst[(r, c)]
                        );
                    }
                }
            }
        }
    }
}

/// The block structure `diag(m_b, s I)` is found exactly, and the product with it equals
/// the naive one.
#[test]
fn identity_blocks_are_found_and_multiplied() {
    use super::{identity_block, matmul_identity_block};
    let n = 9;
    for k in [0, 1, 4, 9] {
        for s in [1.0, -1.0] {
            let mut m = Mat::from_fn(n, n, |i, j| if i == j { s } else { 0.0 });
            if k > 0 {
                // A block whose last row and column differ from s I in one entry each.
                m[(k - 1, 0)] = 0.5;
                m[(0, k - 1)] += 0.25;
            }
            assert_eq!(identity_block(m.as_ref(), s), k, "k = {k}, s = {s}");
            if s == 1.0 {
                let src = filled(n, 5, k);
                let mut dst = Mat::zeros(n, 5);
                matmul_identity_block(dst.as_mut(), m.as_ref(), src.as_ref(), k);
                let reference = naive(m.as_ref(), src.as_ref());
                assert!((&dst - &reference).norm_max() < 1e-14, "k = {k}");
            }
        }
    }
}

/// `identity_block` against its entrywise definition: signed zeros are zeros, NaN and a
/// changed diagonal entry are not, the last differing row of an early column counts,
/// and a strided view gives the same.
#[test]
fn identity_block_is_its_entrywise_definition() {
    use super::identity_block;
    let entrywise = |m: &Mat<f64>, s: f64| {
        let mut k = 0;
        for j in 0..m.ncols() {
            for i in 0..m.nrows() {
                if m[(i, j)] != if i == j { s } else { 0.0 } {
                    k = k.max(i.max(j) + 1);
                }
            }
        }
        k
    };
    const N: usize = 11;
    let changes: [fn(&mut Mat<f64>); 6] = [
        |_| {},
        |m| m[(4, 9)] = -0.0,
        |m| m[(N - 1, 2)] = f64::NAN,
        |m| m[(5, 5)] = 2.0,
        |m| m[(7, 1)] = 0.1,
        |m| {
            m[(0, 1)] = 3.0;
            m[(8, 8)] = -0.0;
        },
    ];
    for s in [1.0, -1.0] {
        for (c, change) in changes.iter().enumerate() {
            let mut m = Mat::from_fn(N, N, |i, j| if i == j { s } else { 0.0 });
            change(&mut m);
            let expected = entrywise(&m, s);
            assert_eq!(identity_block(m.as_ref(), s), expected, "change {c}, s = {s}");
            let t = m.transpose().to_owned();
            assert_eq!(
                identity_block(t.as_ref().transpose(), s),
                expected,
                "change {c}, s = {s}, strided"
            );
        }
    }
}

/// A random primal-dual matrix shaped like an OCP's, multiplier rows first: `m = (T - 1)
/// b` rows with the diagonal `-mu` coupling stage blocks `t` and `t + 1` of `b` primal
/// variables each, and a block-diagonal Hessian (indefinite when `shift` is negative).
fn banded_kkt(t: usize, b: usize, shift: f64, rng: &mut crate::lq::random::SplitMix64) -> Mat<f64> {
    let (n, m) = (t * b, (t - 1) * b);
    let mut k = Mat::<f64>::zeros(m + n, m + n);
    for s in 0..t {
        for i in 0..b {
            for j in 0..=i {
                let v = rng.uniform(-0.5, 0.5) + if i == j { 1.0 + shift } else { 0.0 };
                let (p, q) = (m + s * b + i, m + s * b + j);
                k[(p, q)] = v;
                k[(q, p)] = v;
            }
        }
    }
    for r in 0..m {
        k[(r, r)] = -1e-3;
        let s = r / b;
        for j in s * b..(s + 2) * b {
            if rng.uniform(0.0, 1.0) < 0.6 {
                let v = rng.uniform(-1.0, 1.0);
                k[(r, m + j)] = v;
                k[(m + j, r)] = v;
            }
        }
    }
    k
}

/// The sparse LDLᵀ of primal-dual matrices, simplicial (small blocks) and supernodal
/// (large blocks): its solution solves the system, and its inertia, on quasi-definite
/// and on indefinite matrices, is that of faer's eigenvalues.
#[test]
fn sparse_ldlt_solves_and_reads_the_inertia_of_kkt_matrices() {
    let mut rng = crate::lq::random::SplitMix64::new(11);
    let mut kinds = [false, false];
    for (t, b) in [(6, 2), (20, 3), (8, 24), (4, 100)] {
        for shift in [2.0, -1.5] {
            let k = banded_kkt(t, b, shift, &mut rng);
            let dim = k.nrows();
            let entries = (0..dim).flat_map(|j| (0..dim).map(move |i| (i, j)));
            let mut a = super::SymmetricCsc::from_entries(dim, entries.filter(|&(i, j)| k[(i, j)] != 0.0));
            for j in 0..dim {
                for i in 0..=j {
                    if let Some(p) = a.position(i, j) {
                        a.values[p] = k[(i, j)];
                    }
                }
            }
            let mut f = super::SparseLdlt::new(&a).unwrap();
            kinds[usize::from(f.is_supernodal())] = true;
            let inertia = f.factor(&a).unwrap();
            let eig = k.as_ref().self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
            let pos = eig.iter().filter(|&&e| e > 0.0).count();
            assert_eq!((inertia.positive, inertia.negative, inertia.zero), (pos, dim - pos, 0));
            let rhs: Vec<f64> = (0..dim).map(|_| rng.uniform(-1.0, 1.0)).collect();
            let mut x = rhs.clone();
            f.solve_in_place(&mut x);
            let mut r = rhs.clone();
            a.mul_add(&mut r, &x, -1.0);
            let scale = norm_max(k.as_ref()) * x.iter().fold(1.0_f64, |a, v| a.max(v.abs()));
            let res = r.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
            assert!(res < 1e-9 * scale, "t {t} b {b} shift {shift}: residual {res:e}");
            // The product agrees with the dense one.
            let mut y = vec![0.0; dim];
            a.mul_add(&mut y, &rhs, 1.0);
            let mut yd = Mat::<f64>::zeros(dim, 1);
            matmul(yd.as_mut(), Accum::Replace, k.as_ref(), super::as_mat(&rhs), 1.0);
            assert!((0..dim).all(|i| (y[i] - yd[(i, 0)]).abs() < 1e-12));
        }
    }
    assert_eq!(kinds, [true, true], "both factorizations exercised");
    // A zero pivot and a non-finite value are reported.
    let mut a = super::SymmetricCsc::from_entries(2, [(0, 1)]);
    a.values.copy_from_slice(&[0.0, 1.0, 0.0]);
    let mut f = super::SparseLdlt::new(&a).unwrap();
    assert!(matches!(f.factor(&a), Err(FactorError::Singular { .. })));
    a.values[0] = f64::NAN;
    assert_eq!(f.factor(&a), Err(FactorError::NonFinite));
}

/// A factorization reuses its storage: a 2x2 pivot of an earlier matrix must not count
/// (or solve) as one of a later matrix factored with 1x1 pivots only. The second matrix
/// is `[[P, I], [I, -0]]` with `P` positive definite (inertia `(n, n)`), the first the
/// same with another `P` that takes a 2x2 pivot.
#[test]
fn bunch_kaufman_refactors_without_stale_pivots() {
    let kkt = |p22: f64| {
        let mut k = Mat::<f64>::zeros(8, 8);
        for (i, v) in [1.1, 1.1, p22, p22].into_iter().enumerate() {
            k[(i, i)] = v;
            k[(4 + i, i)] = 1.0;
            k[(i, 4 + i)] = 1.0;
            k[(4 + i, 4 + i)] = -0.0;
        }
        for (i, j) in [(2, 0), (0, 2), (3, 1), (1, 3)] {
            k[(i, j)] = 0.1;
        }
        k
    };
    let expected = Inertia {
        positive: 4,
        negative: 4,
        zero: 0,
    };
    let mut f = BunchKaufman::new(8);
    let b = Mat::from_fn(8, 1, |i, _| 1.0 + i as f64);
    for p22 in [0.52, 1.02, 0.52] {
        let k = kkt(p22);
        assert_eq!(f.factor(k.as_ref(), 0.0).unwrap(), expected, "P22 = {p22}");
        let mut x = b.clone();
        f.solve_in_place(x.as_mut());
        assert!(residual(k.as_ref(), x.as_ref(), b.as_ref()) < 1e-12, "P22 = {p22}");
    }
}

/// `fill` writes exactly the entries of its view, for the fixed-size column kernels
/// (1 to 16 rows), longer columns and a view with a row stride.
#[test]
fn fill_writes_its_view_only() {
    use faer::reborrow::ReborrowMut;
    for nrows in [1, 3, 6, 12, 16, 17, 36] {
        let mut m = Mat::from_fn(nrows + 4, 9, |i, j| (i * 9 + j) as f64);
        let orig = m.clone();
        super::fill(m.as_mut().submatrix_mut(2, 1, nrows, 7), -2.5);
        for i in 0..nrows + 4 {
            for j in 0..9 {
                let inside = (2..2 + nrows).contains(&i) && (1..8).contains(&j);
                assert_eq!(
                    m[(i, j)],
                    if inside { -2.5 } else { orig[(i, j)] },
                    "{nrows} rows: ({i}, {j})"
                );
            }
        }
        let mut t = orig.clone();
        super::fill(t.as_mut().rb_mut().transpose_mut().submatrix_mut(1, 2, 7, nrows), 0.0);
        for i in 0..nrows + 4 {
            for j in 0..9 {
                let inside = (2..2 + nrows).contains(&i) && (1..8).contains(&j);
                assert_eq!(
                    t[(i, j)],
                    if inside { 0.0 } else { orig[(i, j)] },
                    "transposed {nrows}: ({i}, {j})"
                );
            }
        }
    }
}

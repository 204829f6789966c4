//! Tests of every space: group identities, Jacobians against finite differences and
//! dual numbers at random and near-singular points, exponentials against an
//! independent matrix exponential, and the hyper-dual paths.

use std::sync::Arc;

use faer::Mat;
use num_dual::{Dual64, HyperDual64};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use super::*;
use crate::check::{CheckOptions, DualCheckOptions, check_manifold, check_manifold_dual};

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).fold(0.0, |m, (x, y)| m.max((x - y).abs()))
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// `exp(A)` of a small dense matrix by scaling and squaring of the Taylor series: an
/// independent reference for the closed-form exponentials.
fn expm(a: &Mat<f64>) -> Mat<f64> {
    let n = a.nrows();
    let nrm = crate::linalg::norm_max(a.as_ref()) * n as f64;
    let s = if nrm > 0.25 {
        (nrm / 0.25).log2().ceil() as i32
    } else {
        0
    };
    let a = Mat::from_fn(n, n, |i, j| a[(i, j)] / 2f64.powi(s));
    let mut sum = Mat::<f64>::identity(n, n);
    let mut term = Mat::<f64>::identity(n, n);
    for k in 1..30 {
        term = &term * &a * (1.0 / k as f64);
        sum += &term;
    }
    for _ in 0..s {
        sum = &sum * &sum;
    }
    sum
}

fn hat_so3(w: &[f64]) -> Mat<f64> {
    Mat::from_fn(3, 3, |i, j| lie::skew(&[w[0], w[1], w[2]])[i][j])
}

/// Homogeneous matrix of an SE(3) point `(p, q)`.
fn se3_matrix(x: &[f64]) -> Mat<f64> {
    let r = lie::quat_to_rot(&[x[3], x[4], x[5], x[6]]);
    Mat::from_fn(4, 4, |i, j| match (i, j) {
        (3, 3) => 1.0,
        (3, _) => 0.0,
        (_, 3) => x[i],
        _ => r[i][j],
    })
}

/// Homogeneous matrix of an SE(2) point `(x, y, c, s)`.
fn se2_matrix(x: &[f64]) -> Mat<f64> {
    Mat::from_fn(3, 3, |i, j| match (i, j) {
        (0, 0) | (1, 1) => x[2],
        (0, 1) => -x[3],
        (1, 0) => x[3],
        (0, 2) => x[0],
        (1, 2) => x[1],
        (2, 2) => 1.0,
        _ => 0.0,
    })
}

fn mat_err(a: &Mat<f64>, b: &Mat<f64>) -> f64 {
    let mut d = a.clone();
    d -= b;
    crate::linalg::norm_max(d.as_ref())
}

/// A random tangent vector of norm `r` (or with entries in `[-1.5, 1.5]` if `r < 0`,
/// which keeps every rotation angle below `1.5 √3 < π`).
fn tangent(rng: &mut SmallRng, ndx: usize, r: f64) -> Vec<f64> {
    let v: Vec<f64> = (0..ndx).map(|_| rng.random_range(-1.5..=1.5)).collect();
    if r < 0.0 {
        return v;
    }
    let n = norm(&v).max(1e-300);
    v.iter().map(|x| x * r / n).collect()
}

/// Norms of tangent vectors around the special points of the closed forms: zero, the
/// series thresholds (θ² = 1e-2), and just below π.
const SPECIAL_NORMS: [f64; 9] = [
    0.0,
    1e-12,
    1e-7,
    1e-3,
    0.0999,
    0.1001,
    1.0,
    2.5,
    std::f64::consts::PI - 1e-3,
];

/// All identities and derivative checks of one space.
fn check_space(m: &dyn Manifold, seed: u64, trials: usize) {
    let mut rng = SmallRng::seed_from_u64(seed);
    let (nx, ndx) = (m.nx(), m.ndx());
    let (mut x, mut y, mut z, mut w) = (vec![0.0; nx], vec![0.0; nx], vec![0.0; nx], vec![0.0; nx]);
    let (mut d, mut d2) = (vec![0.0; ndx], vec![0.0; ndx]);
    let zeros = vec![0.0; ndx];

    // Neutral element: valid, e ⊕ v ⊖ e = v, e ⊕ 0 = e.
    let mut e = vec![0.0; nx];
    m.neutral(&mut e);
    assert!(m.is_valid(&e));
    m.integrate(&e, &zeros, &mut y);
    assert!(max_abs_diff(&y, &e) < 1e-15);

    let mut max_fd: f64 = 0.0;
    let mut max_dual: f64 = 0.0;
    for trial in 0..trials {
        m.random(&mut rng, &mut x);
        assert!(m.is_valid(&x), "random point invalid: {x:?}");
        if trial == 0 {
            x.copy_from_slice(&e);
        }
        let special = trial % (SPECIAL_NORMS.len() + 1);
        let r = if special < SPECIAL_NORMS.len() {
            SPECIAL_NORMS[special]
        } else {
            -1.0
        };
        let v = tangent(&mut rng, ndx, r);

        // x ⊕ v is valid, and (x ⊕ v) ⊖ x = v inside the injectivity radius.
        m.integrate(&x, &v, &mut y);
        assert!(m.is_valid(&y));
        m.difference(&x, &y, &mut d);
        let err = max_abs_diff(&d, &v);
        assert!(
            err < 1e-12 * (1.0 + norm(&v)),
            "(x ⊕ v) ⊖ x != v: err {err:e}, |v| = {}",
            norm(&v)
        );

        // e ⊕ v ⊖ e = v.
        m.integrate(&e, &v, &mut z);
        m.difference(&e, &z, &mut d);
        assert!(max_abs_diff(&d, &v) < 1e-12 * (1.0 + norm(&v)));

        // x ⊖ x = 0.
        m.difference(&x, &x, &mut d);
        assert!(norm(&d) < 1e-15, "x ⊖ x = {d:?}");

        // x ⊕ (x1 ⊖ x) = x1 for any x1 (compared on the manifold: q and -q are equal).
        let mut x1 = vec![0.0; nx];
        m.random(&mut rng, &mut x1);
        match trial % 4 {
            // Near the cut locus of log: relative rotation angle π - 1e-3.
            1 => {
                let far = tangent(&mut rng, ndx, std::f64::consts::PI - 1e-3);
                m.integrate(&x, &far, &mut x1);
            }
            // Small and threshold-sized differences x1 ⊖ x.
            2 | 3 => {
                let r = SPECIAL_NORMS[(trial / 4) % SPECIAL_NORMS.len()];
                let near = tangent(&mut rng, ndx, r);
                m.integrate(&x, &near, &mut x1);
            }
            _ => {}
        }
        m.difference(&x, &x1, &mut d);
        m.integrate(&x, &d, &mut z);
        m.difference(&x1, &z, &mut d2);
        assert!(norm(&d2) < 1e-12, "x ⊕ (x1 ⊖ x) != x1: {d2:?}");

        // Interpolation: ends and midpoint.
        m.interpolate(&x, &x1, 0.0, &mut z);
        m.difference(&x, &z, &mut d2);
        assert!(norm(&d2) < 1e-14);
        m.interpolate(&x, &x1, 1.0, &mut z);
        m.difference(&x1, &z, &mut d2);
        assert!(norm(&d2) < 1e-12);
        m.interpolate(&x, &x1, 0.5, &mut z);
        assert!(m.is_valid(&z));
        let mut half = vec![0.0; ndx];
        m.difference(&x, &z, &mut half);
        m.difference(&z, &x1, &mut d2);
        for i in 0..ndx {
            assert!((half[i] - 0.5 * d[i]).abs() < 1e-12, "midpoint: {half:?} vs {d:?}");
            assert!((d2[i] - 0.5 * d[i]).abs() < 1e-12, "midpoint: {d2:?} vs {d:?}");
        }

        // normalize: a perturbed representation becomes valid; normalize is idempotent.
        w.copy_from_slice(&x);
        for wi in w.iter_mut() {
            *wi *= 1.0 + 1e-4 * rng.random_range(-1.0..=1.0);
        }
        m.normalize(&mut w);
        assert!(m.is_valid(&w));
        z.copy_from_slice(&w);
        m.normalize(&mut z);
        assert!(max_abs_diff(&z, &w) < 1e-15);

        // Jacobians against finite differences and dual numbers.
        let fd = check_manifold(m, &x, &v, &x1, CheckOptions::default());
        fd.assert_ok();
        max_fd = max_fd.max(fd.max_error());
        let dual = check_manifold_dual(m, &x, &v, &x1, DualCheckOptions::default());
        dual.assert_ok();
        max_dual = max_dual.max(dual.max_error());

        // tangent_map_inverse · tangent_map = I.
        let (mut tm, mut tmi) = (Mat::zeros(nx, ndx), Mat::zeros(ndx, nx));
        m.tangent_map(&x, tm.as_mut());
        m.tangent_map_inverse(&x, tmi.as_mut());
        let prod = &tmi * &tm;
        assert!(mat_err(&prod, &Mat::identity(ndx, ndx)) < 1e-14);

        check_hyper(m, &x, &v, &x1, &mut rng);
    }
    // Visible with --nocapture; the asserts above carry the tolerances.
    println!("{m:?}: max FD error {max_fd:.1e}, max dual error {max_dual:.1e}");

    // Invalid points.
    assert!(!m.is_valid(&x[..nx.saturating_sub(1)]) || nx == 0);
    if nx > 0 {
        let mut bad = x.clone();
        bad[0] = f64::NAN;
        assert!(!m.is_valid(&bad));
    }
}

/// The hyper-dual `integrate` and `difference` agree with the dual ones at first order,
/// and their second-order parts agree with central differences of the dual ones.
fn check_hyper(m: &dyn Manifold, x: &[f64], v: &[f64], x1: &[f64], rng: &mut SmallRng) {
    let (nx, ndx) = (m.nx(), m.ndx());
    let a: Vec<f64> = (0..ndx).map(|_| rng.random_range(-1.0..=1.0)).collect();
    let b: Vec<f64> = (0..ndx).map(|_| rng.random_range(-1.0..=1.0)).collect();
    let hyp = |s: &[f64], da: &[f64], db: &[f64]| -> Vec<HyperDual64> {
        (0..s.len())
            .map(|i| HyperDual64::new(s[i], da[i], db[i], 0.0))
            .collect()
    };
    let dual = |s: &[f64], da: &[f64]| -> Vec<Dual64> { (0..s.len()).map(|i| Dual64::new(s[i], da[i])).collect() };
    let zx = vec![0.0; nx];
    let zd = vec![0.0; ndx];
    let h = 1e-5;

    // integrate(x, v + ε1 a + ε2 b).
    let mut out_h = vec![HyperDual64::new(0.0, 0.0, 0.0, 0.0); nx];
    m.integrate_hyper(&hyp(x, &zx, &zx), &hyp(v, &a, &b), &mut out_h);
    let mut out_d = vec![Dual64::new(0.0, 0.0); nx];
    let first = |vv: &[f64], out_d: &mut Vec<Dual64>| {
        m.integrate_dual(&dual(x, &zx), &dual(vv, &a), out_d);
        out_d.iter().map(|d| (d.re, d.eps)).collect::<Vec<_>>()
    };
    let base = first(v, &mut out_d);
    let vp: Vec<f64> = (0..ndx).map(|i| v[i] + h * b[i]).collect();
    let vm: Vec<f64> = (0..ndx).map(|i| v[i] - h * b[i]).collect();
    let (fp, fm) = (first(&vp, &mut out_d), first(&vm, &mut out_d));
    for k in 0..nx {
        assert!((out_h[k].re - base[k].0).abs() < 1e-15);
        assert!((out_h[k].eps1 - base[k].1).abs() < 1e-13);
        let fd2 = (fp[k].1 - fm[k].1) / (2.0 * h);
        assert!(
            (out_h[k].eps1eps2 - fd2).abs() < 1e-6,
            "integrate_hyper second order: {} vs {fd2}",
            out_h[k].eps1eps2
        );
    }

    // difference(x, x1 ⊕ (ε1 a + ε2 b)).
    let mut x1h = vec![HyperDual64::new(0.0, 0.0, 0.0, 0.0); nx];
    m.integrate_hyper(&hyp(x1, &zx, &zx), &hyp(&zd, &a, &b), &mut x1h);
    let mut dh = vec![HyperDual64::new(0.0, 0.0, 0.0, 0.0); ndx];
    m.difference_hyper(&hyp(x, &zx, &zx), &x1h, &mut dh);
    let mut dd = vec![Dual64::new(0.0, 0.0); ndx];
    let mut x1d = vec![Dual64::new(0.0, 0.0); nx];
    let mut first = |t: f64| {
        let bt: Vec<f64> = b.iter().map(|bi| t * bi).collect();
        m.integrate_dual(&dual(x1, &zx), &dual(&bt, &a), &mut x1d);
        m.difference_dual(&dual(x, &zx), &x1d, &mut dd);
        dd.iter().map(|d| (d.re, d.eps)).collect::<Vec<_>>()
    };
    let (f0, fp, fm) = (first(0.0), first(h), first(-h));
    for k in 0..ndx {
        assert!((dh[k].re - f0[k].0).abs() < 1e-15);
        assert!((dh[k].eps1 - f0[k].1).abs() < 1e-13);
        let fd2 = (fp[k].1 - fm[k].1) / (2.0 * h);
        assert!(
            (dh[k].eps1eps2 - fd2).abs() < 1e-6,
            "difference_hyper second order: {} vs {fd2}",
            dh[k].eps1eps2
        );
    }
}

#[test]
fn vector_space() {
    check_space(&VectorSpace::new(3), 1, 30);
}

#[test]
fn so2() {
    check_space(&SO2, 2, 60);
}

#[test]
fn so3() {
    check_space(&SO3, 3, 120);
}

#[test]
fn se2() {
    check_space(&SE2, 4, 120);
}

#[test]
fn se3() {
    check_space(&SE3, 5, 120);
}

#[test]
fn se3_times_r6() {
    let m = CartesianProduct::new(vec![Arc::new(SE3), Arc::new(VectorSpace::new(6))]);
    assert_eq!((m.nx(), m.ndx()), (13, 12));
    assert!(!m.is_vector_space());
    check_space(&m, 6, 40);
}

#[test]
fn tangent_bundle_of_so3() {
    let m = TangentBundle::new(Arc::new(SO3));
    assert_eq!((m.nx(), m.ndx()), (7, 6));
    check_space(&m, 7, 60);
}

#[test]
fn product_of_products() {
    let a = CartesianProduct::pair(Arc::new(SO2), Arc::new(SE2));
    let b = CartesianProduct::empty()
        .times(Arc::new(SO3))
        .times(Arc::new(VectorSpace::new(2)));
    let m = CartesianProduct::new(vec![
        Arc::new(a),
        Arc::new(b),
        Arc::new(TangentBundle::new(Arc::new(SE3))),
    ]);
    assert_eq!((m.nx(), m.ndx()), (2 + 4 + 4 + 2 + 7 + 6, 1 + 3 + 3 + 2 + 12));
    check_space(&m, 8, 30);
}

#[test]
fn vector_products_are_vector_spaces() {
    let m = CartesianProduct::pair(Arc::new(VectorSpace::new(2)), Arc::new(VectorSpace::new(3)));
    assert!(m.is_vector_space());
    let bundle = TangentBundle::new(Arc::new(m.clone()));
    assert!(bundle.is_vector_space());
    check_space(&m, 9, 10);
    check_space(&bundle, 11, 10);
    // ⊕ and ⊖ are + and - on every coordinate.
    let spaces: [&dyn Manifold; 2] = [&m, &bundle];
    for space in spaces {
        let n = space.nx();
        let x: Vec<f64> = (0..n).map(|i| 0.3 * i as f64 - 1.0).collect();
        let v: Vec<f64> = (0..n).map(|i| 1.7 - 0.2 * i as f64).collect();
        let (mut sum, mut diff) = (vec![0.0; n], vec![0.0; n]);
        space.integrate(&x, &v, &mut sum);
        space.difference(&x, &v, &mut diff);
        for i in 0..n {
            assert_eq!((sum[i], diff[i]), (x[i] + v[i], v[i] - x[i]));
        }
    }
}

/// `x ⊕ v = x · exp(v)` with `exp` the matrix exponential of the twist, for the four
/// groups (Pinocchio's right-perturbation convention, checked against an independent
/// exponential).
#[test]
fn integrate_is_right_multiplication_by_the_matrix_exponential() {
    let mut rng = SmallRng::seed_from_u64(10);
    for trial in 0..60 {
        let r = if trial < SPECIAL_NORMS.len() {
            SPECIAL_NORMS[trial]
        } else {
            -1.0
        };

        // SO(2).
        let v = tangent(&mut rng, 1, r);
        let mut x = [0.0; 2];
        SO2.random(&mut rng, &mut x);
        let mut y = [0.0; 2];
        SO2.integrate(&x, &v, &mut y);
        let rx = Mat::from_fn(2, 2, |i, j| [[x[0], -x[1]], [x[1], x[0]]][i][j]);
        let ev = expm(&Mat::from_fn(2, 2, |i, j| [[0.0, -v[0]], [v[0], 0.0]][i][j]));
        let ry = Mat::from_fn(2, 2, |i, j| [[y[0], -y[1]], [y[1], y[0]]][i][j]);
        assert!(mat_err(&(&rx * &ev), &ry) < 1e-14);

        // SO(3).
        let v = tangent(&mut rng, 3, r);
        let mut q = [0.0; 4];
        SO3.random(&mut rng, &mut q);
        let mut q2 = [0.0; 4];
        SO3.integrate(&q, &v, &mut q2);
        let rq = Mat::from_fn(3, 3, |i, j| lie::quat_to_rot(&q)[i][j]);
        let rq2 = Mat::from_fn(3, 3, |i, j| lie::quat_to_rot(&q2)[i][j]);
        assert!(mat_err(&(&rq * &expm(&hat_so3(&v))), &rq2) < 1e-14);
        // The result stays in the hemisphere of the input.
        assert!(q.iter().zip(&q2).map(|(a, b)| a * b).sum::<f64>() >= 0.0);

        // SE(2).
        let v = tangent(&mut rng, 3, r);
        let mut x = [0.0; 4];
        SE2.random(&mut rng, &mut x);
        let mut y = [0.0; 4];
        SE2.integrate(&x, &v, &mut y);
        let twist = Mat::from_fn(3, 3, |i, j| match (i, j) {
            (0, 1) => -v[2],
            (1, 0) => v[2],
            (0, 2) => v[0],
            (1, 2) => v[1],
            _ => 0.0,
        });
        assert!(mat_err(&(&se2_matrix(&x) * &expm(&twist)), &se2_matrix(&y)) < 1e-14);

        // SE(3): v = (linear, angular) in the local frame.
        let v = tangent(&mut rng, 6, r);
        let mut x = [0.0; 7];
        SE3.random(&mut rng, &mut x);
        let mut y = [0.0; 7];
        SE3.integrate(&x, &v, &mut y);
        let w = hat_so3(&v[3..]);
        let twist = Mat::from_fn(4, 4, |i, j| match (i, j) {
            (3, _) => 0.0,
            (_, 3) => v[i],
            _ => w[(i, j)],
        });
        assert!(mat_err(&(&se3_matrix(&x) * &expm(&twist)), &se3_matrix(&y)) < 1e-14);
        // exp and log as free functions.
        let v6: [f64; 6] = std::array::from_fn(|i| v[i]);
        let l = SE3::log(&SE3::exp(&v6));
        assert!(max_abs_diff(&l, &v6) < 1e-13);
    }
}

/// `log` returns the rotation of smallest angle, whatever the signs of the
/// quaternions: `q` and `-q` are the same point.
#[test]
fn difference_is_minimal_and_sign_invariant() {
    let mut rng = SmallRng::seed_from_u64(12);
    let neg = |q: &[f64]| q.iter().map(|v| -v).collect::<Vec<f64>>();
    for _ in 0..200 {
        let (mut a, mut b) = ([0.0; 4], [0.0; 4]);
        SO3.random(&mut rng, &mut a);
        SO3.random(&mut rng, &mut b);
        let mut d = [0.0; 3];
        SO3.difference(&a, &b, &mut d);
        assert!(norm(&d) <= std::f64::consts::PI + 1e-15);
        for (p, q) in [(neg(&a), b.to_vec()), (a.to_vec(), neg(&b)), (neg(&a), neg(&b))] {
            let mut d2 = [0.0; 3];
            SO3.difference(&p, &q, &mut d2);
            assert!(max_abs_diff(&d, &d2) < 1e-15);
        }
        let (mut x, mut y) = ([0.0; 7], [0.0; 7]);
        SE3.random(&mut rng, &mut x);
        SE3.random(&mut rng, &mut y);
        let mut d = [0.0; 6];
        SE3.difference(&x, &y, &mut d);
        assert!(norm(&d[3..]) <= std::f64::consts::PI + 1e-15);
        let mut yn = y;
        for v in yn[3..].iter_mut() {
            *v = -*v;
        }
        let mut d2 = [0.0; 6];
        SE3.difference(&x, &yn, &mut d2);
        assert!(max_abs_diff(&d, &d2) < 1e-14);
        let (mut s, mut t) = ([0.0; 4], [0.0; 4]);
        SE2.random(&mut rng, &mut s);
        SE2.random(&mut rng, &mut t);
        let mut d = [0.0; 3];
        SE2.difference(&s, &t, &mut d);
        assert!(d[2].abs() <= std::f64::consts::PI);
    }
}

#[test]
fn random_rotations_are_uniform() {
    // Under the Haar measure E[R] = 0 and E[w²] = 1/4; with 4000 samples each entry of
    // the mean has a standard deviation of about 0.009.
    let mut rng = SmallRng::seed_from_u64(11);
    let n = 4000;
    let mut mean = [[0.0; 3]; 3];
    let mut w2 = 0.0;
    let mut q = [0.0; 4];
    for _ in 0..n {
        SO3.random(&mut rng, &mut q);
        assert!(SO3.is_valid(&q));
        let r = lie::quat_to_rot(&q);
        for i in 0..3 {
            for j in 0..3 {
                mean[i][j] += r[i][j] / n as f64;
            }
        }
        w2 += q[3] * q[3] / n as f64;
    }
    for row in &mean {
        for &m in row {
            assert!(m.abs() < 0.05, "E[R] = {mean:?}");
        }
    }
    assert!((w2 - 0.25).abs() < 0.02, "E[w²] = {w2}");
}

#[test]
fn validity_uses_the_unit_norm_tolerance() {
    let q = [0.0, 0.0, 0.0, 1.0 + 0.5e-8];
    assert!(SO3.is_valid(&q));
    assert!(!SO3.is_valid(&[0.0, 0.0, 0.0, 1.0 + 1e-6]));
    assert!(!SO3.is_valid(&[0.0, 0.0, 1.0]));
    assert!(!SO2.is_valid(&[0.9, 0.0]));
    assert!(!SE2.is_valid(&[0.0, 0.0, 0.0, 0.0]));
    assert!(!SE3.is_valid(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0]));
    let tb = TangentBundle::new(Arc::new(SO3));
    assert!(!tb.is_valid(&[0.0, 0.0, 0.0, 1.0, 0.0, f64::INFINITY, 0.0]));
    assert!(tb.is_valid(&[0.0, 0.0, 0.0, 1.0, 0.0, 5.0, 0.0]));
}

/// Non-unit inputs are pulled back to the unit sphere by `⊕` (first-order
/// renormalisation), and `log` ignores the scale of the quaternion.
#[test]
fn integrate_renormalises_and_log_is_scale_invariant() {
    let q = [0.1, -0.2, 0.3, 0.9];
    let n = norm(&q);
    let q: Vec<f64> = q.iter().map(|v| v / n * (1.0 + 1e-6)).collect();
    let mut out = [0.0; 4];
    SO3.integrate(&q, &[0.01, 0.02, -0.03], &mut out);
    assert!((norm(&out) - 1.0).abs() < 1e-11);
    let w = [0.3, -0.4, 1.2];
    let e = SO3::exp(&w);
    let scaled: [f64; 4] = e.map(|v| 3.0 * v);
    assert!(max_abs_diff(&SO3::log(&scaled), &w) < 1e-15);
}

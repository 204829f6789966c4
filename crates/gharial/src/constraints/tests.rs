//! Properties of every constraint set: projection characterisation, Moreau
//! decomposition, and generalised Jacobians against central finite differences.

use std::sync::Arc;

use faer::Mat;
use rand::Rng;
use rand::rngs::SmallRng;

use super::*;
use crate::functions::testing::{assert_close, random_vec, rng};

const MU: f64 = 0.3;

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn proj(c: &dyn ConstraintSet, z: &[f64]) -> Vec<f64> {
    let mut p = vec![0.0; z.len()];
    c.project(z, MU, &mut p);
    p
}

fn ncp(c: &dyn ConstraintSet, z: &[f64]) -> Vec<f64> {
    let mut p = vec![0.0; z.len()];
    c.normal_cone_project(z, MU, &mut p);
    p
}

type Predicate = Box<dyn Fn(&[f64]) -> bool>;
type Sampler = Box<dyn Fn(&mut SmallRng) -> Vec<f64>>;
type Distance = Box<dyn Fn(&[f64]) -> f64>;

/// An indicator set, an independent membership test and a sampler of its points
/// (including boundary points).
struct Case {
    name: &'static str,
    set: Arc<dyn ConstraintSet>,
    n: usize,
    contains: Predicate,
    sample: Sampler,
    /// Distance of `z` to the set's kinks (where the projection is not differentiable).
    kink_distance: Distance,
}

fn soc_parts(z: &[f64]) -> (f64, f64) {
    (z[0], z[1..].iter().map(|v| v * v).sum::<f64>().sqrt())
}

fn cases() -> Vec<Case> {
    let (lo, up) = (
        vec![-1.0, f64::NEG_INFINITY, 0.2, -0.5],
        vec![0.5, 0.3, f64::INFINITY, -0.5],
    );
    let (lo2, up2) = (lo.clone(), up.clone());
    let (lo3, up3) = (lo.clone(), up.clone());
    let boxed = BoxConstraint::new(&lo, &up).unwrap();
    let soc = SecondOrderCone::new(4).unwrap();
    vec![
        Case {
            name: "equality",
            set: Arc::new(EqualityConstraintSet),
            n: 3,
            contains: Box::new(|y| y.iter().all(|&v| v == 0.0)),
            sample: Box::new(|_| vec![0.0; 3]),
            kink_distance: Box::new(|_| f64::INFINITY),
        },
        Case {
            name: "negative orthant",
            set: Arc::new(NegativeOrthant),
            n: 4,
            contains: Box::new(|y| y.iter().all(|&v| v <= 0.0)),
            sample: Box::new(|g| {
                (0..4)
                    .map(|_| {
                        if g.random_bool(0.3) {
                            0.0
                        } else {
                            -g.random_range(0.0..2.0)
                        }
                    })
                    .collect()
            }),
            kink_distance: Box::new(|z| z.iter().fold(f64::INFINITY, |a, v| a.min(v.abs()))),
        },
        Case {
            name: "box",
            set: Arc::new(boxed),
            n: 4,
            contains: Box::new(move |y| (0..4).all(|i| lo2[i] <= y[i] && y[i] <= up2[i])),
            sample: Box::new(move |g| {
                (0..4)
                    .map(|i| {
                        let (l, u) = (lo3[i].max(-3.0), up3[i].min(3.0));
                        match g.random_range(0..4) {
                            0 => l,
                            1 => u,
                            _ => g.random_range(l..=u),
                        }
                    })
                    .collect()
            }),
            kink_distance: Box::new(move |z| {
                (0..4).fold(f64::INFINITY, |a, i| {
                    a.min((z[i] - lo[i]).abs()).min((z[i] - up[i]).abs())
                })
            }),
        },
        Case {
            name: "second-order cone",
            set: Arc::new(soc),
            n: 4,
            contains: Box::new(|y| {
                let (t, rho) = soc_parts(y);
                rho <= t * (1.0 + 1e-12)
            }),
            sample: Box::new(|g| {
                let s = random_vec(g, 3, 1.0);
                let rho = s.iter().map(|v| v * v).sum::<f64>().sqrt();
                let t = if g.random_bool(0.3) {
                    rho
                } else {
                    rho + g.random_range(0.0..1.0)
                };
                std::iter::once(t).chain(s).collect()
            }),
            kink_distance: Box::new(|z| {
                let (t, rho) = soc_parts(z);
                (rho - t).abs().min((rho + t).abs()).min(rho)
            }),
        },
    ]
}

/// Points around the interesting regions: inside, outside, near the origin.
fn test_points(g: &mut SmallRng, n: usize) -> Vec<Vec<f64>> {
    (0..200)
        .map(|k| random_vec(g, n, if k % 3 == 0 { 0.6 } else { 2.0 }))
        .collect()
}

#[test]
fn projections_are_characterised_by_the_variational_inequality() {
    let mut g = rng(90);
    for case in cases() {
        let c = case.set.as_ref();
        for z in test_points(&mut g, case.n) {
            let p = proj(c, &z);
            assert!(
                (case.contains)(&p),
                "{}: projection {p:?} of {z:?} not in the set",
                case.name
            );
            // Idempotent.
            let pp = proj(c, &p);
            for i in 0..case.n {
                assert!(
                    (pp[i] - p[i]).abs() <= 1e-14 * (1.0 + p[i].abs()),
                    "{}: not idempotent",
                    case.name
                );
            }
            // ⟨z - P z, y - P z⟩ ≤ 0 for every y in C.
            let r: Vec<f64> = z.iter().zip(&p).map(|(a, b)| a - b).collect();
            for _ in 0..20 {
                let y = (case.sample)(&mut g);
                assert!((case.contains)(&y));
                let d: Vec<f64> = y.iter().zip(&p).map(|(a, b)| a - b).collect();
                assert!(dot(&r, &d) <= 1e-12, "{}: VI violated: {}", case.name, dot(&r, &d));
            }
            // Normal-cone projection, penalty and violation agree with the projection.
            let nc = ncp(c, &z);
            let viol = r.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
            for i in 0..case.n {
                assert!((nc[i] - r[i]).abs() <= 1e-14 * (1.0 + z[i].abs()));
            }
            assert!((c.violation(&z) - viol).abs() <= 1e-14 * (1.0 + viol), "{}", case.name);
            assert_eq!(c.penalty(&p), 0.0, "{}", case.name);
            if !(case.contains)(&z) {
                assert_eq!(c.penalty(&z), f64::INFINITY, "{}", case.name);
            }
        }
    }
}

#[test]
fn moreau_decomposition_for_cones() {
    // For a closed convex cone K: z = P_K z + P_{K°} z with P_K z ⊥ P_{K°} z, and the
    // normal-cone projection is the projection onto the polar cone K°.
    let mut g = rng(91);
    let polar_contains: [(&str, Predicate); 3] = [
        ("equality", Box::new(|_| true)),
        ("negative orthant", Box::new(|y| y.iter().all(|&v| v >= 0.0))),
        (
            "second-order cone",
            Box::new(|y| soc_parts(&y.iter().map(|v| -v).collect::<Vec<_>>()).1 <= -y[0] * (1.0 + 1e-12) + 1e-15),
        ),
    ];
    for case in cases() {
        let Some((_, polar)) = polar_contains.iter().find(|(n, _)| *n == case.name) else {
            continue;
        };
        let c = case.set.as_ref();
        for z in test_points(&mut g, case.n) {
            let (p, q) = (proj(c, &z), ncp(c, &z));
            assert!(polar(&q), "{}: {q:?} not in the polar cone", case.name);
            assert!(
                dot(&p, &q).abs() <= 1e-13 * (1.0 + dot(&z, &z)),
                "{}: not orthogonal",
                case.name
            );
            for i in 0..case.n {
                assert!((p[i] + q[i] - z[i]).abs() <= 1e-15 * (1.0 + z[i].abs()) * 4.0);
            }
        }
    }
}

/// Checks `apply_projection_jacobian` and `apply_normal_cone_jacobian` against central
/// differences of `project` and `normal_cone_project` at `z`, on the identity and on a
/// random matrix.
fn check_jacobians(name: &str, c: &dyn ConstraintSet, z: &[f64], g: &mut SmallRng) {
    let n = z.len();
    let eps = 1e-7;
    let fd = |f: &dyn Fn(&[f64]) -> Vec<f64>| {
        let mut j = Mat::zeros(n, n);
        for k in 0..n {
            let (mut zp, mut zm) = (z.to_vec(), z.to_vec());
            zp[k] += eps;
            zm[k] -= eps;
            let (a, b) = (f(&zp), f(&zm));
            for i in 0..n {
                j[(i, k)] = (a[i] - b[i]) / (2.0 * eps);
            }
        }
        j
    };
    let jp = fd(&|zz| proj(c, zz));
    let jn = fd(&|zz| ncp(c, zz));
    let mut p = Mat::<f64>::identity(n, n);
    c.apply_projection_jacobian(z, MU, p.as_mut());
    assert_close(&format!("{name}: projection Jacobian at {z:?}"), &p, &jp, 1e-6);
    let mut q = Mat::<f64>::identity(n, n);
    c.apply_normal_cone_jacobian(z, MU, q.as_mut());
    assert_close(&format!("{name}: normal-cone Jacobian at {z:?}"), &q, &jn, 1e-6);
    // In place on an arbitrary matrix: the same linear map.
    let m = Mat::from_fn(n, 3, |_, _| g.random_range(-1.0..1.0));
    let mut pm = m.clone();
    c.apply_projection_jacobian(z, MU, pm.as_mut());
    assert_close(&format!("{name}: P m"), &pm, &(&p * &m), 1e-14);
    let mut qm = m.clone();
    c.apply_normal_cone_jacobian(z, MU, qm.as_mut());
    assert_close(&format!("{name}: (I - P) m"), &qm, &(&q * &m), 1e-14);
    let mut v: Vec<f64> = (0..n).map(|_| g.random_range(-1.0..1.0)).collect();
    let qv = &q * crate::linalg::col(&v);
    c.apply_normal_cone_jacobian_vec(z, MU, &mut v);
    for i in 0..n {
        assert!(
            (v[i] - qv[i]).abs() <= 1e-14,
            "{name}: (I - P) v row {i}: {} vs {}",
            v[i],
            qv[i]
        );
    }
}

#[test]
fn projection_jacobians_match_finite_differences_away_from_kinks() {
    let mut g = rng(92);
    for case in cases() {
        let mut checked = 0;
        for z in test_points(&mut g, case.n) {
            if (case.kink_distance)(&z) < 1e-3 {
                continue;
            }
            check_jacobians(case.name, case.set.as_ref(), &z, &mut g);
            checked += 1;
        }
        assert!(checked > 100, "{}: only {checked} points checked", case.name);
    }
    // The second-order cone's three regions are all exercised.
    let soc = SecondOrderCone::new(3).unwrap();
    for z in [[2.0, 0.5, -0.3], [-2.0, 0.5, -0.3], [0.1, 1.0, -2.0], [-0.1, 1.0, 2.0]] {
        check_jacobians("soc region", &soc, &z, &mut g);
    }
}

#[test]
fn l1_penalty_is_a_proximal_operator() {
    let w = 0.8;
    let l1 = L1Penalty::new(w).unwrap();
    let k = MU * w;
    let mut g = rng(93);
    let mut checked = 0;
    for z in test_points(&mut g, 5) {
        let (p, q) = (proj(&l1, &z), ncp(&l1, &z));
        for i in 0..5 {
            // Optimality of the prox: (z - p)/mu ∈ w ∂|p|.
            let s = (z[i] - p[i]) / MU;
            if p[i] != 0.0 {
                assert!((s - w * p[i].signum()).abs() < 1e-12);
            } else {
                assert!(s.abs() <= w * (1.0 + 1e-12));
            }
            // Moreau: the normal-cone projection is mu proj_{[-w, w]}(z / mu).
            assert!((q[i] - MU * (z[i] / MU).clamp(-w, w)).abs() < 1e-15);
            assert!((p[i] + q[i] - z[i]).abs() < 1e-15);
        }
        assert!((l1.penalty(&z) - w * z.iter().map(|v| v.abs()).sum::<f64>()).abs() < 1e-14);
        assert_eq!(l1.violation(&z), 0.0);
        if z.iter().all(|v| (v.abs() - k).abs() > 1e-3) {
            check_jacobians("l1", &l1, &z, &mut g);
            checked += 1;
        }
    }
    assert!(checked > 100);
    l1.set_weight(0.0).unwrap();
    assert_eq!(proj(&l1, &[1.0, -2.0]), vec![1.0, -2.0]);
    assert!(l1.set_weight(-1.0).is_err());
    assert!(L1Penalty::new(f64::NAN).is_err());
}

#[test]
fn product_acts_block_by_block() {
    let soc: Arc<dyn ConstraintSet> = Arc::new(SecondOrderCone::new(3).unwrap());
    let boxed: Arc<dyn ConstraintSet> = Arc::new(BoxConstraint::new(&[-1.0, 0.0], &[1.0, 2.0]).unwrap());
    let l1: Arc<dyn ConstraintSet> = Arc::new(L1Penalty::new(0.5).unwrap());
    let eq: Arc<dyn ConstraintSet> = Arc::new(EqualityConstraintSet);
    let blocks = vec![(eq.clone(), 2), (soc.clone(), 3), (boxed.clone(), 2), (l1.clone(), 2)];
    let prod = ConstraintSetProduct::new(blocks.clone()).unwrap();
    assert_eq!(prod.dim(), Some(9));
    assert!(!prod.is_equality());
    let mut g = rng(94);
    for z in test_points(&mut g, 9) {
        let (p, q) = (proj(&prod, &z), ncp(&prod, &z));
        let mut pj = Mat::<f64>::identity(9, 9);
        prod.apply_projection_jacobian(&z, MU, pj.as_mut());
        let mut qj = Mat::<f64>::identity(9, 9);
        prod.apply_normal_cone_jacobian(&z, MU, qj.as_mut());
        let (mut pen, mut viol) = (0.0, 0.0_f64);
        for (k, (set, _)) in blocks.iter().enumerate() {
            let r = prod.rows_of(k);
            let zk = &z[r.clone()];
            assert_eq!(&p[r.clone()], proj(set.as_ref(), zk).as_slice());
            assert_eq!(&q[r.clone()], ncp(set.as_ref(), zk).as_slice());
            let mut pk = Mat::<f64>::identity(r.len(), r.len());
            set.apply_projection_jacobian(zk, MU, pk.as_mut());
            let mut qk = Mat::<f64>::identity(r.len(), r.len());
            set.apply_normal_cone_jacobian(zk, MU, qk.as_mut());
            for i in 0..9 {
                for j in 0..r.len() {
                    let inside = r.contains(&i);
                    let expect_p = if inside { pk[(i - r.start, j)] } else { 0.0 };
                    let expect_q = if inside { qk[(i - r.start, j)] } else { 0.0 };
                    assert_eq!(pj[(i, r.start + j)], expect_p);
                    assert_eq!(qj[(i, r.start + j)], expect_q);
                }
            }
            pen += set.penalty(zk);
            viol = viol.max(set.violation(zk));
        }
        assert_eq!(prod.penalty(&z), pen);
        assert_eq!(prod.violation(&z), viol);
    }
    let all_eq = ConstraintSetProduct::new(vec![(eq.clone(), 1), (eq, 2)]).unwrap();
    assert!(all_eq.is_equality());
    let err = ConstraintSetProduct::new(vec![(soc, 2)]).unwrap_err();
    assert!(err.to_string().contains("ConstraintSetProduct block 0"), "{err}");
    assert!(ConstraintSetProduct::new(vec![]).is_err());
}

#[test]
fn invalid_sets_are_rejected() {
    let err = BoxConstraint::new(&[0.0, 1.0], &[1.0, 0.5]).unwrap_err();
    assert!(err.to_string().contains("entry 1"), "{err}");
    assert!(BoxConstraint::new(&[0.0], &[1.0, 2.0]).is_err());
    assert!(BoxConstraint::new(&[f64::NAN], &[1.0]).is_err());
    assert!(BoxConstraint::new(&[f64::INFINITY], &[f64::INFINITY]).is_err());
    assert!(BoxConstraint::new(&[f64::NEG_INFINITY], &[f64::NEG_INFINITY]).is_err());
    assert!(SecondOrderCone::new(0).is_err());
    // Moving the bounds of a shared box.
    let b = BoxConstraint::new(&[0.0, 0.0], &[1.0, 1.0]).unwrap();
    b.set_bounds(&[-1.0, 0.5], &[0.0, 0.5]).unwrap();
    assert_eq!(proj(&b, &[0.3, 0.0]), vec![0.0, 0.5]);
    assert!(b.set_bounds(&[1.0, 0.0], &[0.0, 0.0]).is_err());
    assert!(b.set_bounds(&[0.0], &[1.0]).is_err());
    assert_eq!((b.lower(), b.upper()), (vec![-1.0, 0.5], vec![0.0, 0.5]));
}

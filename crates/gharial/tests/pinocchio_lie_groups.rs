//! The spaces agree with Pinocchio's Lie groups (`pin.integrate`, `pin.dIntegrate`,
//! `pin.difference`, `pin.dDifference`) on the configuration spaces of a free-flyer
//! (SE(3)), a quadruped (SE(3) x R^12) and a double pendulum with continuous joints
//! (SO(2) x SO(2)). Reference values: `tests/fixtures/pinocchio_lie_groups.json`,
//! extracted from the project's Pinocchio fixtures.

use std::sync::Arc;

use faer::Mat;
use gharial::spaces::{Arg, CartesianProduct, Manifold, SE3, SO2, VectorSpace};
use serde_json::Value;

fn vec_of(v: &Value) -> Vec<f64> {
    v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect()
}

fn mat_of(v: &Value) -> Mat<f64> {
    let rows: Vec<Vec<f64>> = v.as_array().unwrap().iter().map(vec_of).collect();
    Mat::from_fn(rows.len(), rows[0].len(), |i, j| rows[i][j])
}

/// `max|a - b| / max(1, max|b|)`.
fn rel(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let scale = b.iter().fold(1.0_f64, |m, x| m.max(x.abs()));
    a.iter().zip(b).fold(0.0_f64, |m, (x, y)| m.max((x - y).abs())) / scale
}

fn rel_mat(a: &Mat<f64>, b: &Mat<f64>) -> f64 {
    assert_eq!((a.nrows(), a.ncols()), (b.nrows(), b.ncols()));
    let flat = |m: &Mat<f64>| {
        (0..m.nrows())
            .flat_map(|i| (0..m.ncols()).map(move |j| m[(i, j)]))
            .collect::<Vec<_>>()
    };
    rel(&flat(a), &flat(b))
}

fn space(name: &str) -> Arc<dyn Manifold> {
    match name {
        "SE3" => Arc::new(SE3),
        "SE3xR12" => Arc::new(CartesianProduct::pair(Arc::new(SE3), Arc::new(VectorSpace::new(12)))),
        "SO2xSO2" => Arc::new(CartesianProduct::pair(Arc::new(SO2), Arc::new(SO2))),
        _ => panic!("unknown space {name}"),
    }
}

#[test]
fn spaces_match_pinocchio() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/pinocchio_lie_groups.json"
    ))
    .expect("fixture file");
    let doc: Value = serde_json::from_str(&text).unwrap();
    let mut worst: f64 = 0.0;
    let mut count = 0;
    for case in doc["cases"].as_array().unwrap() {
        let m = space(case["space"].as_str().unwrap());
        let (nx, ndx) = (m.nx(), m.ndx());
        for s in case["samples"].as_array().unwrap() {
            let it = &s["integrate"];
            let (q, v) = (vec_of(&it["q"]), vec_of(&it["v"]));
            let mut out = vec![0.0; nx];
            m.integrate(&q, &v, &mut out);
            let mut j = Mat::zeros(ndx, ndx);
            let mut errs = vec![("integrate", rel(&out, &vec_of(&it["result"])))];
            m.jintegrate(&q, &v, Arg::First, j.as_mut());
            errs.push(("dIntegrate/dq", rel_mat(&j, &mat_of(&it["d_dq"]))));
            m.jintegrate(&q, &v, Arg::Second, j.as_mut());
            errs.push(("dIntegrate/dv", rel_mat(&j, &mat_of(&it["d_dv"]))));

            let df = &s["difference"];
            let (q0, q1) = (vec_of(&df["q0"]), vec_of(&df["q1"]));
            let mut d = vec![0.0; ndx];
            m.difference(&q0, &q1, &mut d);
            errs.push(("difference", rel(&d, &vec_of(&df["result"]))));
            m.jdifference(&q0, &q1, Arg::First, j.as_mut());
            errs.push(("dDifference/dq0", rel_mat(&j, &mat_of(&df["d_dq0"]))));
            m.jdifference(&q0, &q1, Arg::Second, j.as_mut());
            errs.push(("dDifference/dq1", rel_mat(&j, &mat_of(&df["d_dq1"]))));

            for (what, e) in errs {
                assert!(e < 1e-12, "{} {what}: relative error {e:e}", case["robot"]);
                worst = worst.max(e);
            }
            count += 1;
        }
    }
    assert_eq!(count, 22);
    println!("largest relative error against Pinocchio: {worst:.1e}");
}

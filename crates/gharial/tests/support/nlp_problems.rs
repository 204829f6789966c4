//! The small NLPs of the ProxNLP tests: the QPs of the Clarabel fixtures
//! (`tests/data/qp_reference.json`), a tilt-limited alignment on SO(3) and the closest
//! point on a capped sphere.
#![allow(dead_code)]

use std::sync::Arc;

use faer::Mat;
use gharial::autodiff::{AutoCostFn, AutoDiff, AutoUnaryFn, ManifoldScalar};
use gharial::constraints::{BoxConstraint, ConstraintSet, EqualityConstraintSet, NegativeOrthant, SecondOrderCone};
use gharial::costs::QuadraticCost;
use gharial::functions::LinearUnaryFunction;
use gharial::nlp::{NlpConstraint, NlpProblem};
use gharial::spaces::{Manifold, SO3, VectorSpace};
use serde_json::Value;

pub fn vec_of(v: &Value) -> Vec<f64> {
    v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect()
}

pub fn mat_of(v: &Value) -> Mat<f64> {
    let rows: Vec<Vec<f64>> = v.as_array().unwrap().iter().map(vec_of).collect();
    Mat::from_fn(rows.len(), rows.first().map_or(0, Vec::len), |i, j| rows[i][j])
}

pub fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

/// The QP `min ½ xᵀPx + qᵀx` of a fixture case as an NLP, blocks mapped to gharial's sets
/// with the multiplier convention the tool writes.
pub fn qp_nlp(case: &Value) -> NlpProblem {
    let p = mat_of(&case["P"]);
    let q = vec_of(&case["q"]);
    let n = q.len();
    let cost = Arc::new(QuadraticCost::terminal(p.as_ref(), &q).unwrap());
    let mut nlp = NlpProblem::new(Arc::new(VectorSpace::new(n)), cost).unwrap();
    for (k, b) in case["blocks"].as_array().unwrap().iter().enumerate() {
        let a = mat_of(&b["A"]);
        let rhs = vec_of(&b["b"]);
        let m = a.nrows();
        let neg: Vec<f64> = rhs.iter().map(|v| -v).collect();
        let (func, set): (LinearUnaryFunction, Arc<dyn ConstraintSet>) = match b["kind"].as_str().unwrap() {
            "eq" => (
                LinearUnaryFunction::new(a.as_ref(), &neg).unwrap(),
                Arc::new(EqualityConstraintSet),
            ),
            "le" => (
                LinearUnaryFunction::new(a.as_ref(), &neg).unwrap(),
                Arc::new(NegativeOrthant),
            ),
            "box" => (
                LinearUnaryFunction::new(a.as_ref(), &vec![0.0; m]).unwrap(),
                Arc::new(BoxConstraint::new(&rhs[..m], &rhs[m..]).unwrap()),
            ),
            "soc" => {
                let minus_a = Mat::from_fn(m, n, |i, j| -a[(i, j)]);
                (
                    LinearUnaryFunction::new(minus_a.as_ref(), &rhs).unwrap(),
                    Arc::new(SecondOrderCone::new(m).unwrap()),
                )
            }
            other => panic!("unknown block kind {other}"),
        };
        nlp.add_constraint(NlpConstraint::new(format!("block {k}"), Arc::new(func), set))
            .unwrap();
    }
    nlp
}

/// `-aᵀ b(q)` with `b(q) = R(q) e_z` the body z axis of the unit quaternion `q = (x, y, z, w)`.
pub struct Alignment {
    pub a: [f64; 3],
}

pub fn body_z<D: ManifoldScalar>(q: &[D]) -> [D; 3] {
    let (x, y, z, w) = (q[0], q[1], q[2], q[3]);
    let two = D::from(2.0);
    [
        two * (x * z + w * y),
        two * (y * z - w * x),
        D::from(1.0) - two * (x * x + y * y),
    ]
}

impl AutoCostFn for Alignment {
    fn nx(&self) -> usize {
        4
    }
    fn nu(&self) -> usize {
        0
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], _u: &[D]) -> D {
        let b = body_z(x);
        -(b[0] * self.a[0] + b[1] * self.a[1] + b[2] * self.a[2])
    }
}

/// `cos β - b_z(q) ≤ 0`: the body z axis at most `β` from the vertical.
pub struct Tilt {
    pub cos_beta: f64,
}

impl AutoUnaryFn for Tilt {
    fn nx(&self) -> usize {
        4
    }
    fn nr(&self) -> usize {
        1
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], out: &mut [D]) {
        out[0] = D::from(self.cos_beta) - body_z(x)[2];
    }
}

/// `|x|² - 1` on R³ (a sphere through an equality constraint).
pub struct Sphere;

impl AutoUnaryFn for Sphere {
    fn nx(&self) -> usize {
        3
    }
    fn nr(&self) -> usize {
        1
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], out: &mut [D]) {
        out[0] = x[0] * x[0] + x[1] * x[1] + x[2] * x[2] - D::from(1.0);
    }
}

/// The QP cases of `tests/data/qp_reference.json`.
pub fn qp_cases() -> Vec<Value> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/qp_reference.json");
    let doc: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    doc["qps"].as_array().unwrap().clone()
}

/// The tilt-limited alignment: on SO(3), turn the body z axis towards
/// `a = (sin γ cos φ, sin γ sin φ, cos γ)` with the tilt limited to `β`
/// (`(γ, β, φ) = TILT_ANGLES`); with its cost and constraint function.
pub fn tilt_problem() -> (
    NlpProblem,
    Arc<dyn gharial::costs::Cost>,
    Arc<dyn gharial::functions::UnaryFunction>,
) {
    let (gamma, beta, phi) = TILT_ANGLES;
    let a = [gamma.sin() * phi.cos(), gamma.sin() * phi.sin(), gamma.cos()];
    let space: Arc<dyn Manifold> = Arc::new(SO3::new());
    let cost = Arc::new(AutoDiff::cost(space.clone(), Alignment { a }).unwrap());
    let tilt = Arc::new(AutoDiff::unary(space.clone(), Tilt { cos_beta: beta.cos() }).unwrap());
    let nlp = NlpProblem::new(space, cost.clone())
        .unwrap()
        .with_constraint(NlpConstraint::new("tilt", tilt.clone(), Arc::new(NegativeOrthant)))
        .unwrap();
    (nlp, cost, tilt)
}

/// `(γ, β, φ)` of [`tilt_problem`].
pub const TILT_ANGLES: (f64, f64, f64) = (1.1, 0.5, 0.7);

/// A start of [`tilt_problem`] tilted away from `a` (rotation about x by 0.3).
pub fn tilt_start() -> [f64; 4] {
    [(0.15_f64).sin(), 0.0, 0.0, (0.15_f64).cos()]
}

/// The point of the unit sphere closest to `a` below the plane `x_3 = h`.
pub fn capped_sphere(a: [f64; 3], h: f64) -> NlpProblem {
    let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(3));
    let cost = Arc::new(QuadraticCost::terminal(Mat::<f64>::identity(3, 3).as_ref(), &[-a[0], -a[1], -a[2]]).unwrap());
    let sphere = Arc::new(AutoDiff::unary(space.clone(), Sphere).unwrap());
    let plane = Arc::new(
        LinearUnaryFunction::new(Mat::from_fn(1, 3, |_, j| f64::from(u8::from(j == 2))).as_ref(), &[-h]).unwrap(),
    );
    NlpProblem::new(space, cost)
        .unwrap()
        .with_constraint(NlpConstraint::new("sphere", sphere, Arc::new(EqualityConstraintSet)))
        .unwrap()
        .with_constraint(NlpConstraint::new("plane", plane, Arc::new(NegativeOrthant)))
        .unwrap()
}

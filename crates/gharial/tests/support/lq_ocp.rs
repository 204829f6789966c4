//! Random linear-quadratic optimal control problems shared by the solver tests, their
//! exact KKT systems (references for the dense solve), and the Clarabel reference cases.
#![allow(dead_code)]

use std::sync::Arc;

use faer::{Col, Mat};
use gharial::constraints::{BoxConstraint, EqualityConstraintSet};
use gharial::costs::QuadraticCost;
use gharial::dynamics::{Dynamics, LinearDiscreteDynamics};
use gharial::functions::{ControlError, StateError, Unary};
use gharial::lq::{LqKnot, LqProblem, random::SplitMix64};
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::spaces::{Manifold, VectorSpace};

/// Data of a random linear-quadratic optimal control problem.
pub struct Lq {
    pub nx: usize,
    pub nu: usize,
    pub n: usize,
    pub a: Mat<f64>,
    pub b: Mat<f64>,
    pub c: Vec<f64>,
    pub q: Mat<f64>,
    pub s: Mat<f64>,
    pub r: Mat<f64>,
    pub qv: Vec<f64>,
    pub rv: Vec<f64>,
    pub qf: Mat<f64>,
    pub qfv: Vec<f64>,
    pub x0: Vec<f64>,
}

pub fn spd(rng: &mut SplitMix64, n: usize, shift: f64) -> Mat<f64> {
    let l = Mat::from_fn(n, n, |_, _| rng.uniform(-1.0, 1.0));
    Mat::from_fn(n, n, |i, j| {
        (0..n).map(|k| l[(i, k)] * l[(j, k)]).sum::<f64>() / n as f64 + if i == j { shift } else { 0.0 }
    })
}

pub fn random_lq(nx: usize, nu: usize, n: usize, seed: u64) -> Lq {
    let mut rng = SplitMix64::new(seed);
    let a = Mat::from_fn(
        nx,
        nx,
        |i, j| if i == j { 1.0 } else { 0.0 } + 0.2 * rng.uniform(-1.0, 1.0) / (nx as f64).sqrt(),
    );
    let b = Mat::from_fn(nx, nu, |_, _| rng.uniform(-1.0, 1.0));
    let c = (0..nx).map(|_| rng.uniform(-0.1, 0.1)).collect();
    let q = spd(&mut rng, nx, 0.1);
    let r = spd(&mut rng, nu, 0.1);
    let s = Mat::from_fn(nx, nu, |_, _| 0.01 * rng.uniform(-1.0, 1.0));
    let qv = (0..nx).map(|_| rng.uniform(-1.0, 1.0)).collect();
    let rv = (0..nu).map(|_| rng.uniform(-1.0, 1.0)).collect();
    let qf = spd(&mut rng, nx, 1.0);
    let qfv = (0..nx).map(|_| rng.uniform(-1.0, 1.0)).collect();
    let x0 = (0..nx).map(|_| rng.uniform(-1.0, 1.0)).collect();
    Lq {
        nx,
        nu,
        n,
        a,
        b,
        c,
        q,
        s,
        r,
        qv,
        rv,
        qf,
        qfv,
        x0,
    }
}

pub fn space(lq: &Lq) -> Arc<dyn Manifold> {
    Arc::new(VectorSpace::new(lq.nx))
}

/// A point mass in the plane, `x = (p, v)`, `u` the acceleration, `dt = 0.1`: running
/// cost `dt (|p|² + 0.1 |v|² + 0.1 |u|²) / 2`, terminal `w_final |x|² / 2`.
pub fn point_mass(n: usize, x0: [f64; 4], w_final: f64) -> Lq {
    let dt = 0.1;
    let diag = |v: &[f64]| Mat::from_fn(v.len(), v.len(), |i, j| if i == j { v[i] } else { 0.0 });
    let mut a = diag(&[1.0; 4]);
    a[(0, 2)] = dt;
    a[(1, 3)] = dt;
    let mut b = Mat::zeros(4, 2);
    b[(2, 0)] = dt;
    b[(3, 1)] = dt;
    Lq {
        nx: 4,
        nu: 2,
        n,
        a,
        b,
        c: vec![0.0; 4],
        q: diag(&[dt, dt, 0.1 * dt, 0.1 * dt]),
        s: Mat::zeros(4, 2),
        r: diag(&[0.1 * dt, 0.1 * dt]),
        qv: vec![0.0; 4],
        rv: vec![0.0; 2],
        qf: diag(&[w_final; 4]),
        qfv: vec![0.0; 4],
        x0: x0.to_vec(),
    }
}

/// Point-mass cases `(N, x0, w_final)` whose optimum under `|u| <= 2` has every control
/// of some knot at its bound (the first knot's with `x0 = (1, 1, 1, 1)`).
pub fn clamped_point_mass_cases() -> [(usize, [f64; 4], f64); 6] {
    [
        (1, [1.0, 1.0, 1.0, 1.0], 1.0),
        (1, [0.0, 0.0, 3.0, 3.0], 1.0),
        (1, [1.0, 1.0, 0.5, 1.0], 1.0),
        (2, [1.0, 1.0, 1.0, 1.0], 1.5),
        (20, [1.0, 1.0, 1.0, 1.0], 1.0),
        (20, [1.0, -1.0, 0.0, 0.0], 100.0),
    ]
}

/// The OCP with optional control bounds and a terminal equality `x_N = x_target`.
pub fn ocp(lq: &Lq, umax: Option<f64>, x_target: Option<&[f64]>) -> Problem {
    let sp = space(lq);
    let dynamics = Dynamics::Explicit(Arc::new(
        LinearDiscreteDynamics::new(lq.a.as_ref(), lq.b.as_ref(), &lq.c).unwrap(),
    ));
    let cost = Arc::new(QuadraticCost::new(lq.q.as_ref(), lq.s.as_ref(), lq.r.as_ref(), &lq.qv, &lq.rv).unwrap());
    let mut stage = StageModel::new(cost, dynamics).unwrap();
    if let Some(m) = umax {
        let f = Arc::new(ControlError::new(sp.as_ref(), &vec![0.0; lq.nu]).unwrap());
        let set = Arc::new(BoxConstraint::new(&vec![-m; lq.nu], &vec![m; lq.nu]).unwrap());
        stage.add_constraint(StageConstraint::new("u_box", f, set)).unwrap();
    }
    let term = Arc::new(QuadraticCost::terminal(lq.qf.as_ref(), &lq.qfv).unwrap());
    let mut p = Problem::new(&lq.x0, vec![stage; lq.n], term).unwrap();
    if let Some(xt) = x_target {
        let f = Arc::new(Unary::new(Arc::new(StateError::new(sp, xt).unwrap()), 0));
        p.add_terminal_constraint(StageConstraint::new("x_N", f, Arc::new(EqualityConstraintSet)))
            .unwrap();
    }
    p
}

/// The exact KKT system of the OCP (no regularisation) as an LQ problem.
pub fn exact_lq(lq: &Lq, x_target: Option<&[f64]>) -> LqProblem {
    let (nx, nu, n) = (lq.nx, lq.nu, lq.n);
    let mut knots = Vec::new();
    for t in 0..n {
        let mut k = LqKnot::new(nx, nu, 0, nx);
        k.Q.copy_from(&lq.q);
        k.S.copy_from(&lq.s);
        k.R.copy_from(&lq.r);
        k.q = Col::from_fn(nx, |i| lq.qv[i]);
        k.r = Col::from_fn(nu, |i| lq.rv[i]);
        k.A.copy_from(&lq.a);
        k.B.copy_from(&lq.b);
        k.f = Col::from_fn(nx, |i| lq.c[i]);
        knots.push(k);
        let _ = t;
    }
    let nc = if x_target.is_some() { nx } else { 0 };
    let mut k = LqKnot::new(nx, 0, nc, 0);
    k.Q.copy_from(&lq.qf);
    k.q = Col::from_fn(nx, |i| lq.qfv[i]);
    if let Some(xt) = x_target {
        for i in 0..nx {
            k.C[(i, i)] = 1.0;
            k.d[i] = -xt[i];
        }
    }
    knots.push(k);
    LqProblem {
        knots,
        G0: Mat::identity(nx, nx),
        g0: Col::from_fn(nx, |i| -lq.x0[i]),
        mu0: 0.0,
    }
}

/// A reachable terminal target: the end of a rollout with controls inside `[-umax/2, umax/2]`.
pub fn reachable_target(lq: &Lq, umax: f64) -> Vec<f64> {
    let mut target = lq.x0.clone();
    for t in 0..lq.n {
        let u: Vec<f64> = (0..lq.nu).map(|i| 0.5 * umax * ((t + i) as f64).sin()).collect();
        target = (0..lq.nx)
            .map(|i| {
                lq.c[i]
                    + (0..lq.nx).map(|j| lq.a[(i, j)] * target[j]).sum::<f64>()
                    + (0..lq.nu).map(|j| lq.b[(i, j)] * u[j]).sum::<f64>()
            })
            .collect();
    }
    target
}

pub fn zero_guess(p: &Problem) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let n = p.horizon();
    let xs = (0..=n).map(|t| vec![0.0; p.space(t).nx()]).collect();
    let us = (0..n).map(|t| vec![0.0; p.nu(t)]).collect();
    (xs, us)
}

pub fn max_diff(a: &[Vec<f64>], b: &[Col<f64>]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| x.iter().zip(y.iter()).map(|(p, q)| (p - q).abs()))
        .fold(0.0, f64::max)
}

/// A case of `tests/data/qp_reference.json`: a random box-constrained LQ problem (and
/// terminal target), and its optimal cost as a dense QP solved by Clarabel, an
/// interior-point solver independent of this library (`tools/qp-reference` writes the
/// file).
pub struct QpCase {
    pub seed: u64,
    pub lq: Lq,
    pub umax: f64,
    pub target: Option<Vec<f64>>,
    pub clarabel_cost: f64,
}

pub fn qp_reference_cases() -> Vec<QpCase> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/qp_reference.json");
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let vec =
        |v: &serde_json::Value| -> Vec<f64> { v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect() };
    let mat = |v: &serde_json::Value| -> Mat<f64> {
        let rows: Vec<Vec<f64>> = v.as_array().unwrap().iter().map(vec).collect();
        Mat::from_fn(rows.len(), rows.first().map_or(0, |r| r.len()), |i, j| rows[i][j])
    };
    let size = |c: &serde_json::Value, k: &str| c[k].as_u64().unwrap() as usize;
    doc["cases"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| QpCase {
            seed: c["seed"].as_u64().unwrap(),
            lq: Lq {
                nx: size(c, "nx"),
                nu: size(c, "nu"),
                n: size(c, "N"),
                a: mat(&c["A"]),
                b: mat(&c["B"]),
                c: vec(&c["c"]),
                q: mat(&c["Q"]),
                s: mat(&c["S"]),
                r: mat(&c["R"]),
                qv: vec(&c["q"]),
                rv: vec(&c["r"]),
                qf: mat(&c["Qf"]),
                qfv: vec(&c["qf"]),
                x0: vec(&c["x0"]),
            },
            umax: c["umax"].as_f64().unwrap(),
            target: (!c["target"].is_null()).then(|| vec(&c["target"])),
            clarabel_cost: c["clarabel_cost"].as_f64().unwrap(),
        })
        .collect()
}

/// The implicit-Euler discretisation of `ẋ = Ac x + Bc u + cc` with `Ac = A - I`,
/// `Bc = B`, `cc = c` of `lq`, and its exact LQ: `f = dt (Ac y + Bc u + cc) - (y - x)`, so
/// `A = I`, `B = dt Bc`, `E = dt Ac - I`, `f = dt cc`.
pub fn implicit_euler_ocp(lq: &Lq, dt: f64) -> (Problem, LqProblem) {
    use gharial::dynamics::{ImplicitEuler, LinearOde};
    let (nx, nu, n) = (lq.nx, lq.nu, lq.n);
    let ac = Mat::from_fn(nx, nx, |i, j| lq.a[(i, j)] - if i == j { 1.0 } else { 0.0 });
    let ode = Arc::new(LinearOde::new(ac.as_ref(), lq.b.as_ref(), &lq.c).unwrap());
    let dynamics = Dynamics::Implicit(Arc::new(ImplicitEuler::new(ode, dt).unwrap()));
    let cost = Arc::new(QuadraticCost::new(lq.q.as_ref(), lq.s.as_ref(), lq.r.as_ref(), &lq.qv, &lq.rv).unwrap());
    let stage = StageModel::new(cost, dynamics).unwrap();
    let term = Arc::new(QuadraticCost::terminal(lq.qf.as_ref(), &lq.qfv).unwrap());
    let p = Problem::new(&lq.x0, vec![stage; n], term).unwrap();
    let mut exact = exact_lq(lq, None);
    for k in exact.knots.iter_mut().take(n) {
        k.A = Mat::identity(nx, nx);
        k.B = Mat::from_fn(nx, nu, |i, j| dt * lq.b[(i, j)]);
        k.E = Mat::from_fn(nx, nx, |i, j| dt * ac[(i, j)] - if i == j { 1.0 } else { 0.0 });
        k.f = Col::from_fn(nx, |i| dt * lq.c[i]);
    }
    (p, exact)
}

//! Random box-constrained LQ optimal control problems and their Clarabel optima, as JSON
//! on standard output (see README.md).

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use gharial::lq::random::SplitMix64;
use serde_json::{Value, json};

/// A random LQ problem: dynamics `x⁺ = A x + B u + c`, stage cost
/// `½ xᵀQx + xᵀSu + ½ uᵀRu + qᵀx + rᵀu`, terminal cost `½ xᵀQf x + qfᵀx`, `x_0 = x0`;
/// matrices row-major.
struct Lq {
    nx: usize,
    nu: usize,
    n: usize,
    a: Vec<Vec<f64>>,
    b: Vec<Vec<f64>>,
    c: Vec<f64>,
    q: Vec<Vec<f64>>,
    s: Vec<Vec<f64>>,
    r: Vec<Vec<f64>>,
    qv: Vec<f64>,
    rv: Vec<f64>,
    qf: Vec<Vec<f64>>,
    qfv: Vec<f64>,
    x0: Vec<f64>,
}

fn mat(rows: usize, cols: usize, mut f: impl FnMut(usize, usize) -> f64) -> Vec<Vec<f64>> {
    (0..rows).map(|i| (0..cols).map(|j| f(i, j)).collect()).collect()
}

/// `L Lᵀ / n + shift I` with `L` uniform in [-1, 1].
fn spd(rng: &mut SplitMix64, n: usize, shift: f64) -> Vec<Vec<f64>> {
    let l = mat(n, n, |_, _| rng.uniform(-1.0, 1.0));
    mat(n, n, |i, j| {
        (0..n).map(|k| l[i][k] * l[j][k]).sum::<f64>() / n as f64 + if i == j { shift } else { 0.0 }
    })
}

fn random_lq(nx: usize, nu: usize, n: usize, seed: u64) -> Lq {
    let mut rng = SplitMix64::new(seed);
    let scale = 0.2 / (nx as f64).sqrt();
    let a = mat(nx, nx, |i, j| if i == j { 1.0 } else { 0.0 } + scale * rng.uniform(-1.0, 1.0));
    let b = mat(nx, nu, |_, _| rng.uniform(-1.0, 1.0));
    let c = (0..nx).map(|_| rng.uniform(-0.1, 0.1)).collect();
    let q = spd(&mut rng, nx, 0.1);
    let r = spd(&mut rng, nu, 0.1);
    let s = mat(nx, nu, |_, _| 0.01 * rng.uniform(-1.0, 1.0));
    let qv = (0..nx).map(|_| rng.uniform(-1.0, 1.0)).collect();
    let rv = (0..nu).map(|_| rng.uniform(-1.0, 1.0)).collect();
    let qf = spd(&mut rng, nx, 1.0);
    let qfv = (0..nx).map(|_| rng.uniform(-1.0, 1.0)).collect();
    let x0 = (0..nx).map(|_| rng.uniform(-1.0, 1.0)).collect();
    Lq { nx, nu, n, a, b, c, q, s, r, qv, rv, qf, qfv, x0 }
}

/// A reachable terminal target: the end of a rollout with controls inside `[-umax/2, umax/2]`.
fn reachable_target(lq: &Lq, umax: f64) -> Vec<f64> {
    let mut x = lq.x0.clone();
    for t in 0..lq.n {
        let u: Vec<f64> = (0..lq.nu).map(|i| 0.5 * umax * ((t + i) as f64).sin()).collect();
        x = (0..lq.nx)
            .map(|i| {
                lq.c[i]
                    + (0..lq.nx).map(|j| lq.a[i][j] * x[j]).sum::<f64>()
                    + (0..lq.nu).map(|j| lq.b[i][j] * u[j]).sum::<f64>()
            })
            .collect();
    }
    x
}

/// Triplets of a sparse matrix.
#[derive(Default)]
struct Triplets {
    i: Vec<usize>,
    j: Vec<usize>,
    v: Vec<f64>,
}

impl Triplets {
    fn push(&mut self, i: usize, j: usize, v: f64) {
        if v != 0.0 {
            self.i.push(i);
            self.j.push(j);
            self.v.push(v);
        }
    }
}

/// The optimal cost of the OCP with `|u_t,i| <= umax` (and `x_N = target`) as a dense QP
/// over `(x_0..x_N, u_0..u_{N-1})`, solved by Clarabel.
fn clarabel_cost(lq: &Lq, umax: f64, target: Option<&[f64]>) -> f64 {
    let (nx, nu, n) = (lq.nx, lq.nu, lq.n);
    let xi = |t: usize, i: usize| t * nx + i;
    let ui = |t: usize, i: usize| (n + 1) * nx + t * nu + i;
    let nz = (n + 1) * nx + n * nu;
    // Upper triangle of P and the linear term.
    let mut p = Triplets::default();
    let mut upper = |i: usize, j: usize, v: f64| {
        if i <= j {
            p.push(i, j, v);
        }
    };
    let mut lin = vec![0.0; nz];
    for t in 0..n {
        for i in 0..nx {
            for j in 0..nx {
                upper(xi(t, i), xi(t, j), lq.q[i][j]);
            }
            for j in 0..nu {
                upper(xi(t, i), ui(t, j), lq.s[i][j]);
            }
            lin[xi(t, i)] = lq.qv[i];
        }
        for i in 0..nu {
            for j in 0..nu {
                upper(ui(t, i), ui(t, j), lq.r[i][j]);
            }
            lin[ui(t, i)] = lq.rv[i];
        }
    }
    for i in 0..nx {
        for j in 0..nx {
            upper(xi(n, i), xi(n, j), lq.qf[i][j]);
        }
        lin[xi(n, i)] = lq.qfv[i];
    }
    let p = CscMatrix::new_from_triplets(nz, nz, p.i, p.j, p.v);
    // Equalities x_0 = x0, x_{t+1} - A x_t - B u_t = c, (x_N = target); then ±u <= umax.
    let (mut a, mut b, mut row) = (Triplets::default(), vec![], 0);
    for i in 0..nx {
        a.push(row, xi(0, i), 1.0);
        b.push(lq.x0[i]);
        row += 1;
    }
    for t in 0..n {
        for i in 0..nx {
            a.push(row, xi(t + 1, i), 1.0);
            for j in 0..nx {
                a.push(row, xi(t, j), -lq.a[i][j]);
            }
            for j in 0..nu {
                a.push(row, ui(t, j), -lq.b[i][j]);
            }
            b.push(lq.c[i]);
            row += 1;
        }
    }
    for (i, &v) in target.unwrap_or(&[]).iter().enumerate() {
        a.push(row, xi(n, i), 1.0);
        b.push(v);
        row += 1;
    }
    let neq = row;
    for t in 0..n {
        for i in 0..nu {
            for sign in [1.0, -1.0] {
                a.push(row, ui(t, i), sign);
                b.push(umax);
                row += 1;
            }
        }
    }
    let a = CscMatrix::new_from_triplets(row, nz, a.i, a.j, a.v);
    let cones = [SupportedConeT::ZeroConeT(neq), SupportedConeT::NonnegativeConeT(row - neq)];
    let settings = DefaultSettings {
        verbose: false,
        tol_gap_abs: 1e-12,
        tol_gap_rel: 1e-12,
        tol_feas: 1e-12,
        ..Default::default()
    };
    let mut solver = DefaultSolver::new(&p, &lin, &a, &b, &cones, settings).expect("a valid QP");
    solver.solve();
    let status = solver.solution.status;
    assert!(matches!(status, SolverStatus::Solved | SolverStatus::AlmostSolved), "{status:?}");
    solver.solution.obj_val
}

fn record(seed: u64, (nx, nu, n): (usize, usize, usize), umax: f64, with_target: bool) -> Value {
    let lq = random_lq(nx, nu, n, seed);
    let target = with_target.then(|| reachable_target(&lq, umax));
    let cost = clarabel_cost(&lq, umax, target.as_deref());
    json!({
        "seed": seed, "nx": nx, "nu": nu, "N": n, "umax": umax, "target": target,
        "A": lq.a, "B": lq.b, "c": lq.c, "Q": lq.q, "S": lq.s, "R": lq.r, "q": lq.qv, "r": lq.rv,
        "Qf": lq.qf, "qf": lq.qfv, "x0": lq.x0,
        "clarabel_cost": cost,
    })
}

/// A constraint block of a small QP: rows `a x` against `b` in a set.
struct Block {
    /// `"eq"`: `a x = b`; `"le"`: `a x <= b`; `"box"`: `b[..m] <= a x <= b[m..]`;
    /// `"soc"`: `b - a x` in the second-order cone (scalar part first).
    kind: &'static str,
    a: Vec<Vec<f64>>,
    b: Vec<f64>,
}

/// `min ½ xᵀPx + qᵀx` subject to the blocks: Clarabel's primal `x`, the multipliers of
/// each block in the convention of gharial's NLPs (Lagrangian `f + νᵀ c` with
/// `c = a x - b` for "eq" and "le", `c = a x` in the box, `c = b - a x` in the cone), and
/// the optimal value.
fn solve_qp(p: &[Vec<f64>], q: &[f64], blocks: &[Block]) -> (Vec<f64>, Vec<Vec<f64>>, f64) {
    let n = q.len();
    let mut pt = Triplets::default();
    for i in 0..n {
        for j in i..n {
            pt.push(i, j, p[i][j]);
        }
    }
    let pm = CscMatrix::new_from_triplets(n, n, pt.i, pt.j, pt.v);
    let (mut a, mut b, mut cones, mut row) = (Triplets::default(), vec![], vec![], 0);
    let mut rows = |a: &mut Triplets, b: &mut Vec<f64>, m: &[Vec<f64>], rhs: &[f64], sign: f64| {
        for (r, v) in m.iter().zip(rhs) {
            for (j, x) in r.iter().enumerate() {
                a.push(row, j, sign * x);
            }
            b.push(sign * v);
            row += 1;
        }
    };
    for blk in blocks {
        let m = blk.a.len();
        match blk.kind {
            "eq" => {
                rows(&mut a, &mut b, &blk.a, &blk.b, 1.0);
                cones.push(SupportedConeT::ZeroConeT(m));
            }
            "le" => {
                rows(&mut a, &mut b, &blk.a, &blk.b, 1.0);
                cones.push(SupportedConeT::NonnegativeConeT(m));
            }
            "box" => {
                rows(&mut a, &mut b, &blk.a, &blk.b[m..], 1.0);
                rows(&mut a, &mut b, &blk.a, &blk.b[..m], -1.0);
                cones.push(SupportedConeT::NonnegativeConeT(2 * m));
            }
            "soc" => {
                rows(&mut a, &mut b, &blk.a, &blk.b, 1.0);
                cones.push(SupportedConeT::SecondOrderConeT(m));
            }
            k => panic!("unknown block kind {k}"),
        }
    }
    let am = CscMatrix::new_from_triplets(row, n, a.i, a.j, a.v);
    let settings = DefaultSettings {
        verbose: false,
        tol_gap_abs: 1e-11,
        tol_gap_rel: 1e-11,
        tol_feas: 1e-11,
        ..Default::default()
    };
    let mut solver = DefaultSolver::new(&pm, q, &am, &b, &cones, settings).expect("a valid QP");
    solver.solve();
    let status = solver.solution.status;
    assert!(matches!(status, SolverStatus::Solved), "{status:?}");
    let z = &solver.solution.z;
    let mut off = 0;
    let mut nus = Vec::new();
    for blk in blocks {
        let m = blk.a.len();
        nus.push(match blk.kind {
            "box" => (0..m).map(|i| z[off + i] - z[off + m + i]).collect(),
            "soc" => z[off..off + m].iter().map(|v| -v).collect(),
            _ => z[off..off + m].to_vec(),
        });
        off += if blk.kind == "box" { 2 * m } else { m };
    }
    (solver.solution.x.clone(), nus, solver.solution.obj_val)
}

/// Small QPs with equality, inequality, box and second-order-cone constraints.
fn qp_cases() -> Vec<Value> {
    let mut rng = SplitMix64::new(77);
    let mut cases = Vec::new();
    let rand_mat = |rng: &mut SplitMix64, r: usize, c: usize| mat(r, c, |_, _| rng.uniform(-1.0, 1.0));
    let eye = |n: usize| mat(n, n, |i, j| if i == j { 1.0 } else { 0.0 });
    // Equality and inequality rows, some active at the optimum.
    let n = 5;
    let p = spd(&mut rng, n, 0.5);
    let q: Vec<f64> = (0..n).map(|_| rng.uniform(-2.0, 2.0)).collect();
    let blocks = vec![
        Block { kind: "eq", a: rand_mat(&mut rng, 2, n), b: vec![0.3, -0.2] },
        Block { kind: "le", a: rand_mat(&mut rng, 4, n), b: vec![0.1, -0.1, 0.2, 0.0] },
    ];
    cases.push(("eq-ineq", p, q, blocks));
    // A box on every variable with the unconstrained optimum outside it.
    let n = 6;
    let p = spd(&mut rng, n, 0.2);
    let q: Vec<f64> = (0..n).map(|_| rng.uniform(-3.0, 3.0)).collect();
    let b = [vec![-0.5; n], vec![0.4; n]].concat();
    cases.push(("box", p, q, vec![Block { kind: "box", a: eye(n), b }]));
    // A second-order cone on three of the variables, whose unconstrained optimum
    // `x_u` lies outside it, plus one equality.
    let n = 4;
    let p = spd(&mut rng, n, 1.0);
    let x_u = [0.2, 1.0, -0.6, 0.3];
    let q: Vec<f64> = (0..n).map(|i| -(0..n).map(|j| p[i][j] * x_u[j]).sum::<f64>()).collect();
    let blocks = vec![
        Block { kind: "soc", a: mat(3, n, |i, j| if i == j { -1.0 } else { 0.0 }), b: vec![0.0; 3] },
        Block { kind: "eq", a: mat(1, n, |_, _| 1.0), b: vec![0.8] },
    ];
    cases.push(("soc", p, q, blocks));
    cases
        .into_iter()
        .map(|(name, p, q, blocks)| {
            let (x, nus, obj) = solve_qp(&p, &q, &blocks);
            let blocks: Vec<Value> = blocks
                .iter()
                .zip(&nus)
                .map(|(b, nu)| json!({"kind": b.kind, "A": b.a, "b": b.b, "clarabel_nu": nu}))
                .collect();
            json!({"name": name, "P": p, "q": q, "blocks": blocks, "clarabel_x": x, "clarabel_obj": obj})
        })
        .collect()
}

fn main() {
    let mut cases = Vec::new();
    for (seed, dims, umax) in [(21, (3, 2, 20), 0.2), (22, (4, 2, 40), 0.3), (23, (6, 3, 30), 0.1)] {
        for with_target in [false, true] {
            cases.push(record(seed, dims, umax, with_target));
        }
    }
    for (seed, dims, umax) in [(41, (3, 2, 20), 0.2), (42, (4, 2, 40), 0.3), (43, (6, 3, 30), 0.1)] {
        cases.push(record(seed, dims, umax, false));
    }
    let doc = json!({
        "about": "random box-constrained LQ problems and their optimal costs, and small QPs (equality, inequality, box, second-order cone) with their optima and multipliers, by Clarabel 0.11 (tools/qp-reference)",
        "cases": cases,
        "qps": qp_cases(),
    });
    println!("{}", serde_json::to_string_pretty(&doc).expect("JSON of plain numbers"));
}

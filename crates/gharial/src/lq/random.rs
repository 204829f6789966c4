//! Random LQ problems.
//!
//! - [`peers_problem`]: the generator of the peer benchmarks (`shared/peers/README.md`,
//!   "Random LQ problems"), draw for draw, so that gharial is timed on exactly the problems
//!   aligator's `gar` solver was timed on.
//! - [`varied_problem`]: a more varied generator for tests: dimensions changing from knot
//!   to knot, a general `E`, rank-deficient constraint blocks, rows without
//!   regularisation, consistent or inconsistent constraints.

use faer::{Accum, Col, Mat};

use super::{LqKnot, LqProblem};
use crate::linalg::{matmul, matvec, slice, slice_mut};

/// The SplitMix64 generator (64-bit state, wrapping arithmetic).
#[derive(Debug, Clone)]
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    /// A generator with state `seed`.
    pub fn new(seed: u64) -> Self {
        Self { state: seed }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// `U(a, b)`: `a + (b - a) u` with `u = (next >> 11) 2⁻⁵³` (exact in double).
    pub fn uniform(&mut self, a: f64, b: f64) -> f64 {
        let u = (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
        a + (b - a) * u
    }

    /// A uniform integer in `lo..=hi` (the bounds in either order).
    pub fn int(&mut self, lo: usize, hi: usize) -> usize {
        let (lo, hi) = (lo.min(hi), lo.max(hi));
        lo + (self.next_u64() % ((hi - lo) as u64 + 1)) as usize
    }

    /// `10^U(log10 lo, log10 hi)`.
    pub fn log_uniform(&mut self, lo: f64, hi: f64) -> f64 {
        10f64.powf(self.uniform(lo.log10(), hi.log10()))
    }
}

/// A problem of the peers' generator and the reference trajectory that satisfies its
/// dynamics and constraints.
#[derive(Debug, Clone)]
pub struct PeersLq {
    /// The problem (`E = -I`, `mu_dyn = 0`, `mu0 = 0`, `mu_c = mu` on every row).
    pub problem: LqProblem,
    /// Reference states `x̄_t`.
    pub xs_ref: Vec<Col<f64>>,
    /// Reference controls `ū_t` (`N` of them).
    pub us_ref: Vec<Col<f64>>,
}

/// The random LQ problem of the peer benchmarks with `nx, nu, nc`, horizon `N`, `seed`,
/// and constraint regularisation `mu`. Sums are taken in index order, as in the peers'
/// Python reference, so every value matches it bit for bit.
pub fn peers_problem(nx: usize, nu: usize, nc: usize, horizon: usize, seed: u64, mu: f64) -> PeersLq {
    let mut rng = SplitMix64::new(seed);
    let mut knots = Vec::with_capacity(horizon + 1);
    let mut xs_ref = Vec::with_capacity(horizon + 1);
    let mut us_ref = Vec::with_capacity(horizon + 1);
    for t in 0..=horizon {
        let nut = if t < horizon { nu } else { 0 };
        let ny = if t < horizon { nx } else { 0 };
        let mut k = LqKnot::new(nx, nut, nc, ny);
        peers_cost(&mut rng, &mut k);
        if t < horizon {
            peers_dynamics(&mut rng, &mut k);
        }
        // 4. constraint rows.
        let sc = 1.0 / ((nx + nut) as f64).sqrt();
        for i in 0..nc {
            for j in 0..nx {
                k.C[(i, j)] = sc * rng.uniform(-1.0, 1.0);
            }
        }
        for i in 0..nc {
            for j in 0..nut {
                k.D[(i, j)] = sc * rng.uniform(-1.0, 1.0);
            }
        }
        k.mu_c = Col::from_fn(nc, |_| mu);
        // 5. reference point.
        xs_ref.push(Col::from_fn(nx, |_| rng.uniform(-1.0, 1.0)));
        us_ref.push(Col::from_fn(nut, |_| rng.uniform(-1.0, 1.0)));
        knots.push(k);
    }
    // Affine terms: the reference trajectory is feasible.
    for t in 0..=horizon {
        let next = xs_ref.get(t + 1);
        peers_affine_terms(&mut knots[t], &xs_ref[t], &us_ref[t], next);
    }
    us_ref.pop();
    let problem = LqProblem {
        knots,
        G0: Mat::identity(nx, nx),
        g0: Col::from_fn(nx, |i| -xs_ref[0][i]),
        mu0: 0.0,
    };
    PeersLq {
        problem,
        xs_ref,
        us_ref,
    }
}

/// Steps 1-2 of the peers' generator: `[Q S; Sᵀ R] = L Lᵀ / n + 0.1 I` (`L` drawn row by
/// row) and the gradients.
fn peers_cost(rng: &mut SplitMix64, k: &mut LqKnot) {
    let (nx, nu) = (k.nx, k.nu);
    let n = nx + nu;
    let l: Vec<f64> = (0..n * n).map(|_| rng.uniform(-1.0, 1.0)).collect();
    let h = |i: usize, j: usize| {
        let mut s = 0.0;
        for m in 0..n {
            s += l[i * n + m] * l[j * n + m];
        }
        s / n as f64 + if i == j { 0.1 } else { 0.0 }
    };
    k.Q = Mat::from_fn(nx, nx, &h);
    k.S = Mat::from_fn(nx, nu, |i, j| h(i, nx + j));
    k.R = Mat::from_fn(nu, nu, |i, j| h(nx + i, nx + j));
    k.q = Col::from_fn(nx, |_| rng.uniform(-1.0, 1.0));
    k.r = Col::from_fn(nu, |_| rng.uniform(-1.0, 1.0));
}

/// Step 3: `A = I + 0.1/√nx U`, `B = [I 0] + 0.1/√nu U`, drawn row by row.
fn peers_dynamics(rng: &mut SplitMix64, k: &mut LqKnot) {
    identity_plus_noise(rng, &mut k.A, 0.1 / (k.nx as f64).sqrt());
    identity_plus_noise(rng, &mut k.B, 0.1 / (k.nu as f64).sqrt());
}

/// `m = [I 0] + s U(-1, 1)`, drawn row by row.
fn identity_plus_noise(rng: &mut SplitMix64, m: &mut Mat<f64>, s: f64) {
    for i in 0..m.nrows() {
        for j in 0..m.ncols() {
            m[(i, j)] = if i == j { 1.0 } else { 0.0 } + s * rng.uniform(-1.0, 1.0);
        }
    }
}

/// `f = x' - A x - B u` and `d = -(C x + D u)`: the reference point satisfies the rows
/// (the peers' loops, in their order of summation).
fn peers_affine_terms(k: &mut LqKnot, x: &Col<f64>, u: &Col<f64>, next: Option<&Col<f64>>) {
    if let Some(x_next) = next.filter(|_| k.nx_next > 0) {
        for i in 0..k.nx {
            k.f[i] = x_next[i] - row_dot(&k.A, i, x) - row_dot(&k.B, i, u);
        }
    }
    for i in 0..k.nc {
        k.d[i] = -(row_dot(&k.C, i, x) + row_dot(&k.D, i, u));
    }
}

/// `m[i, :] · v`, summed in column order.
fn row_dot(m: &Mat<f64>, i: usize, v: &Col<f64>) -> f64 {
    (0..m.ncols()).fold(0.0, |s, j| s + m[(i, j)] * v[j])
}

/// Options of [`varied_problem`]. Ranges are inclusive.
#[derive(Debug, Clone)]
pub struct VariedOptions {
    /// Horizon `N`.
    pub horizon: usize,
    /// Range of the state dimension.
    pub nx: (usize, usize),
    /// Range of the control dimension (the last knot has none).
    pub nu: (usize, usize),
    /// Range of the number of constraint rows.
    pub nc: (usize, usize),
    /// Draw new dimensions at every knot (otherwise once for the whole problem).
    pub vary_dims: bool,
    /// A random well-conditioned `E` instead of `-I`.
    pub general_e: bool,
    /// With `general_e`, the size of the random leading block of `E`, the rest `-I` (the
    /// structure of explicit dynamics on a Lie group times vector spaces); `0`: all of `E`.
    pub e_block: usize,
    /// Rank-deficient constraint blocks `[C D]` (low-rank rows, repeated rows, zero rows).
    pub rank_deficient: bool,
    /// `d`, `f` and `g0` such that a random reference trajectory satisfies every
    /// constraint (bounded multipliers as the regularisation goes to 0).
    pub consistent: bool,
    /// Dynamics regularisation `mu_dyn` (the same at every knot).
    pub mu_dyn: f64,
    /// Range of the constraint regularisations, drawn log-uniformly per row.
    pub mu_c: (f64, f64),
    /// Up to two rows per knot (fewer than `nu`) get `mu_c = 0`, with full-rank `D` rows.
    pub hard_rows: bool,
    /// Rows of the initial constraint: `None` for `G0 = I`, `Some(0)` for a free `x_0`,
    /// `Some(m)` for a random `m x nx_0` block (`m ≤ nx_0`).
    pub initial_rows: Option<usize>,
    /// Regularisation of the initial constraint.
    pub mu0: f64,
}

impl Default for VariedOptions {
    fn default() -> Self {
        Self {
            horizon: 5,
            nx: (3, 3),
            nu: (2, 2),
            nc: (1, 1),
            vary_dims: false,
            general_e: false,
            e_block: 0,
            rank_deficient: false,
            consistent: true,
            mu_dyn: 0.0,
            mu_c: (1e-6, 1e-6),
            hard_rows: false,
            initial_rows: None,
            mu0: 0.0,
        }
    }
}

/// A random LQ problem drawn according to `opts`: stage costs `H = LLᵀ/n + 0.1 I`
/// (strictly convex), dynamics `A = I + 0.3 W/√nx`, `B = W/√nu`, and the options'
/// constraint structure.
pub fn varied_problem(rng: &mut SplitMix64, opts: &VariedOptions) -> LqProblem {
    let dims = varied_dims(rng, opts);
    let n_knots = dims.len();
    let xs_ref: Vec<Col<f64>> = dims
        .iter()
        .map(|d| Col::from_fn(d.0, |_| rng.uniform(-1.0, 1.0)))
        .collect();
    let us_ref: Vec<Col<f64>> = dims
        .iter()
        .map(|d| Col::from_fn(d.1, |_| rng.uniform(-1.0, 1.0)))
        .collect();
    let mut knots = Vec::with_capacity(n_knots);
    for t in 0..n_knots {
        let ny = if t + 1 < n_knots { dims[t + 1].0 } else { 0 };
        knots.push(varied_knot(rng, opts, dims[t], ny));
    }
    for t in 0..n_knots {
        let next = xs_ref.get(t + 1).map(slice);
        affine_terms(rng, opts, &mut knots[t], (slice(&xs_ref[t]), slice(&us_ref[t]), next));
    }
    let (G0, g0) = initial_rows(rng, opts, slice(&xs_ref[0]));
    LqProblem {
        knots,
        G0,
        g0,
        mu0: opts.mu0,
    }
}

/// The `(nx, nu, nc)` of every knot (`nu = 0` at the last), drawn once or per knot.
fn varied_dims(rng: &mut SplitMix64, opts: &VariedOptions) -> Vec<(usize, usize, usize)> {
    let n_knots = opts.horizon + 1;
    let draw = |rng: &mut SplitMix64, r: (usize, usize)| rng.int(r.0, r.1);
    let fixed = (draw(rng, opts.nx), draw(rng, opts.nu), draw(rng, opts.nc));
    let mut dims = Vec::with_capacity(n_knots);
    for t in 0..n_knots {
        let (nx, nu, nc) = if opts.vary_dims {
            (draw(rng, opts.nx), draw(rng, opts.nu), draw(rng, opts.nc))
        } else {
            fixed
        };
        dims.push((nx, if t + 1 < n_knots { nu } else { 0 }, nc));
    }
    dims
}

/// One knot without its affine terms: a positive definite `[Q S; Sᵀ R]` with gradients,
/// the dynamics to a next state of size `ny`, and the constraint rows.
fn varied_knot(rng: &mut SplitMix64, opts: &VariedOptions, (nx, nu, nc): (usize, usize, usize), ny: usize) -> LqKnot {
    let n = nx + nu;
    let mut k = LqKnot::new(nx, nu, nc, ny);
    let l = rand_mat(rng, n, n, 1.0);
    let mut h = Mat::<f64>::zeros(n, n);
    for i in 0..n {
        h[(i, i)] = 0.1;
    }
    matmul(h.as_mut(), Accum::Add, l.as_ref(), l.transpose(), 1.0 / n as f64);
    k.Q = h.as_ref().submatrix(0, 0, nx, nx).to_owned();
    k.S = h.as_ref().submatrix(0, nx, nx, nu).to_owned();
    k.R = h.as_ref().submatrix(nx, nx, nu, nu).to_owned();
    k.q = Col::from_fn(nx, |_| rng.uniform(-1.0, 1.0));
    k.r = Col::from_fn(nu, |_| rng.uniform(-1.0, 1.0));
    if ny > 0 {
        k.A = rand_mat(rng, ny, nx, 0.3 / (nx as f64).sqrt());
        for i in 0..ny.min(nx) {
            k.A[(i, i)] += 1.0;
        }
        k.B = rand_mat(rng, ny, nu, 1.0 / (nu.max(1) as f64).sqrt());
        if opts.general_e {
            let kb = if opts.e_block == 0 { ny } else { opts.e_block.min(ny) };
            let block = rand_mat(rng, kb, kb, 0.3 / (kb as f64).sqrt());
            k.E.as_mut().submatrix_mut(0, 0, kb, kb).copy_from(&block);
            for i in 0..kb {
                k.E[(i, i)] -= 1.0;
            }
        }
        k.mu_dyn = opts.mu_dyn;
    }
    constraint_rows(rng, opts, &mut k);
    k
}

/// The constraint rows `[C D]` and `mu_c` of a knot: hard rows (`mu_c = 0`) first, then
/// the others, possibly rank-deficient (with a repeated and a zero row). Hard rows leave
/// at least one control free: with all controls fixed by constraints the closed loop can
/// be unstable and the value function grow without bound.
fn constraint_rows(rng: &mut SplitMix64, opts: &VariedOptions, k: &mut LqKnot) {
    let (nx, nu, nc) = (k.nx, k.nu, k.nc);
    let n = nx + nu;
    let n_hard = if opts.hard_rows {
        nc.min(nu.saturating_sub(1)).min(2)
    } else {
        0
    };
    let sc = 1.0 / (n as f64).sqrt();
    let mut cd = rand_mat(rng, nc, n, sc);
    if opts.rank_deficient && nc > n_hard {
        let soft = nc - n_hard;
        let rank = rng.int(0, soft.min(n).saturating_sub(1));
        let u = rand_mat(rng, soft, rank, 1.0);
        let v = rand_mat(rng, rank, n, sc);
        let mut low = Mat::<f64>::zeros(soft, n);
        matmul(low.as_mut(), Accum::Replace, u.as_ref(), v.as_ref(), 1.0);
        // A repeated row and a zero row on top of the low-rank block.
        if soft >= 2 {
            let src = cd.as_ref().row(n_hard).to_owned();
            low.as_mut().row_mut(0).copy_from(&src);
            low.as_mut().row_mut(soft - 1).copy_from(&src);
        }
        if soft >= 3 {
            low.as_mut().row_mut(1).fill(0.0);
        }
        cd.as_mut().submatrix_mut(n_hard, 0, soft, n).copy_from(&low);
    }
    k.C = cd.as_ref().submatrix(0, 0, nc, nx).to_owned();
    k.D = cd.as_ref().submatrix(0, nx, nc, nu).to_owned();
    k.mu_c = Col::from_fn(nc, |i| {
        if i < n_hard {
            0.0
        } else {
            rng.log_uniform(opts.mu_c.0, opts.mu_c.1)
        }
    });
}

/// The affine terms `d`, `f` of a knot: consistent with the reference point
/// `(x, u, x_next)` (every row satisfied there), or random.
fn affine_terms(
    rng: &mut SplitMix64,
    opts: &VariedOptions,
    k: &mut LqKnot,
    (x, u, next): (&[f64], &[f64], Option<&[f64]>),
) {
    if !opts.consistent {
        k.d = Col::from_fn(k.nc, |_| rng.uniform(-1.0, 1.0));
        k.f = Col::from_fn(k.nx_next, |_| rng.uniform(-1.0, 1.0));
        return;
    }
    let d = slice_mut(&mut k.d);
    matvec(d, Accum::Replace, k.C.as_ref(), x, -1.0);
    matvec(d, Accum::Add, k.D.as_ref(), u, -1.0);
    if k.nx_next > 0 {
        let f = slice_mut(&mut k.f);
        matvec(f, Accum::Replace, k.A.as_ref(), x, -1.0);
        matvec(f, Accum::Add, k.B.as_ref(), u, -1.0);
        matvec(
            f,
            Accum::Add,
            k.E.as_ref(),
            next.expect("a knot with dynamics has a next state"),
            -1.0,
        );
    }
}

/// The initial constraint `G0 x_0 + g0 = 0`: `x_0` fixed (`G0 = I`) or some random rows,
/// satisfied by `x0_ref` when consistent.
fn initial_rows(rng: &mut SplitMix64, opts: &VariedOptions, x0_ref: &[f64]) -> (Mat<f64>, Col<f64>) {
    let nx0 = x0_ref.len();
    let G0 = match opts.initial_rows {
        None => Mat::identity(nx0, nx0),
        Some(m) => rand_mat(rng, m.min(nx0), nx0, 1.0),
    };
    let mut g0 = Col::<f64>::zeros(G0.nrows());
    if opts.consistent {
        matvec(slice_mut(&mut g0), Accum::Replace, G0.as_ref(), x0_ref, -1.0);
    } else {
        g0 = Col::from_fn(G0.nrows(), |_| rng.uniform(-1.0, 1.0));
    }
    (G0, g0)
}

/// A `rows x cols` matrix with entries `s U(-1, 1)`, drawn column by column.
fn rand_mat(rng: &mut SplitMix64, rows: usize, cols: usize, s: f64) -> Mat<f64> {
    Mat::from_fn(rows, cols, |_, _| s * rng.uniform(-1.0, 1.0))
}

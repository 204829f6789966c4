//! Re-solving a factored LQ problem whose constraint offsets `d` alone changed, by an
//! affine map of them formed from the factorization (the x-updates of the ADMM of
//! [`crate::solvers::admm`], hundreds of solves per factorization).
//!
//! With `mu_dyn = 0` the vector part of the backward recursion (module docs of
//! [`crate::lq`], steps 3-5) is affine in `(p_{t+1}, d_t)`. With `W` the inverse of the
//! stage KKT matrix (45)-(46) (symmetric), the gains `[K; Z] = -W [Q_ux; C]` and
//! `[k; ζ] = -W [Q_u; d]` turn the value gradient (47) `p_t = Q_x + Q_xu k + Cᵀζ` into
//! `Q_x + KᵀQ_u + Zᵀd`, and the Q-function (37) has `Q_x = q + Ãᵀv`, `Q_u = r + B̃ᵀv`,
//! `v = p_{t+1} + P_{t+1} f̃`,
//! so that, for changes `Δ` from the vectors of the factorization,
//! ```text
//! Δp_t = (Ã + B̃K)ᵀ Δp_{t+1} + Zᵀ Δd_t
//! k_t  = k⁰_t + [R S] [Δp_{t+1}; Δd_t],   [R S] = -[W_uu W_ud] [B̃ᵀ 0; 0 I]
//! ```
//! and the rollout (50a) `u_t = K x_t + k_t`, `x_{t+1} = Ã x_t + B̃ u_t + f̃_t`, with the
//! rows' values `g_t = C x_t + D u_t`, is, stacked,
//! ```text
//! [u_t; x_{t+1}; g_t] = [K; Ã + B̃K; C + DK] x_t + w_t,
//! w_t = [k⁰; B̃k⁰ + f̃; Dk⁰] + [I; B̃; D] [R S] [Δp_{t+1}; Δd_t]
//! ```
//! from `x_0` of the initial stage (65). Forming the maps costs one KKT solve with
//! `ny + nc` right-hand sides and a few products per knot; a solve then costs two
//! small matrix-vector products per knot instead of the Q-function's vectors, a KKT solve,
//! the value gradient and the rollout's products. The states and controls equal the full
//! recursion's to round-off.

use faer::prelude::ReborrowMut;
use faer::{Accum, Mat};

use super::riccati::RiccatiSolver;
use super::{LqError, LqKnot, LqProblem, LqSolution};
use crate::linalg::{self, matvec, slice, slice_mut};

/// The maps of one knot.
#[derive(Debug)]
struct OffsetKnot {
    /// `[[I; B̃; D] [R S]; [Ã + B̃K; Z]ᵀ]`: `[w; Δp_t] = [w⁰; 0] + s e`.
    s: Mat<f64>,
    /// `[w⁰; 0]`, `w⁰ = [k⁰; B̃k⁰ + f̃; Dk⁰]`.
    w0: Vec<f64>,
    /// `[K; Ã + B̃K; C + DK]`: `[u; x_{t+1}; g] = fb x + w`.
    fb: Mat<f64>,
    /// KKT right-hand sides, then their solutions (`-[R S]` in the control rows), while
    /// forming.
    rhs: Mat<f64>,
    /// `e = [Δp_{t+1}; Δd_t]`.
    e: Vec<f64>,
    /// `[w; Δp_t]`, then `[u; x_{t+1}; g; Δp_t]`.
    w: Vec<f64>,
    /// `p⁰`, `d⁰` of the factorization.
    p0: Vec<f64>,
    d0: Vec<f64>,
}

impl OffsetKnot {
    fn new(k: &LqKnot) -> Self {
        let (nx, nu, nc, ny) = (k.nx, k.nu, k.nc, k.nx_next);
        Self {
            s: Mat::zeros(nu + ny + nc + nx, ny + nc),
            w0: vec![0.0; nu + ny + nc + nx],
            fb: Mat::zeros(nu + ny + nc, nx),
            rhs: Mat::zeros(nu + nc, ny + nc),
            e: vec![0.0; ny + nc],
            w: vec![0.0; nu + ny + nc + nx],
            p0: vec![0.0; nx],
            d0: vec![0.0; nc],
        }
    }

    /// `fb`, the rows of `Δp_t` in `s` and `p⁰`, `d⁰` from the knot's gains.
    fn form_feedback(&mut self, st: &super::RiccatiStage, knot: &LqKnot) {
        let (nu, nc, ny) = (knot.nu, knot.nc, knot.nx_next);
        let (k, rest) = self.fb.as_mut().split_at_row_mut(nu);
        let (mut a_cl, mut g) = rest.split_at_row_mut(ny);
        linalg::copy(k, st.K());
        linalg::copy(a_cl.rb_mut(), st.a_tilde(knot));
        linalg::copy(g.rb_mut(), knot.C.as_ref());
        if nu > 0 {
            linalg::matmul(a_cl, Accum::Add, st.b_tilde(knot), st.K(), 1.0);
            linalg::matmul(g, Accum::Add, knot.D.as_ref(), st.K(), 1.0);
        }
        let lt = self.s.as_mut().subrows_mut(nu + ny + nc, knot.nx);
        let (a_cl_t, z_t) = lt.split_at_col_mut(ny);
        linalg::copy(a_cl_t, self.fb.as_ref().subrows(nu, ny).transpose());
        linalg::copy(z_t, st.Z().transpose());
        self.p0.copy_from_slice(st.p());
        self.d0.copy_from_slice(slice(&knot.d));
    }

    /// The rows of `w` in `s` and `w⁰` from the knot's KKT factorization and feedforward.
    fn form_feedforward(&mut self, st: &mut super::RiccatiStage, knot: &LqKnot) {
        let (nu, nc, ny) = (knot.nu, knot.nc, knot.nx_next);
        let (k0, w0) = self.w0[..nu + ny + nc].split_at_mut(nu);
        k0.copy_from_slice(st.k());
        w0[..ny].copy_from_slice(&st.f_tilde()[..ny]);
        let (b, d) = (st.b_tilde(knot), knot.D.as_ref());
        if nu == 0 {
            return;
        }
        let (fx, g0) = w0.split_at_mut(ny);
        matvec(fx, Accum::Add, b, k0, 1.0);
        matvec(g0, Accum::Replace, d, k0, 1.0);
        // [R S] = -KKT⁻¹ [B̃ᵀ 0; 0 I], its rows of the controls.
        let mut rhs = self.rhs.as_mut();
        rhs.fill(0.0);
        linalg::copy(rhs.rb_mut().submatrix_mut(0, 0, nu, ny), b.transpose());
        for i in 0..nc {
            rhs[(nu + i, ny + i)] = 1.0;
        }
        st.kkt_solve_in_place(rhs.rb_mut());
        let rs = self.rhs.as_ref().subrows(0, nu);
        let mut s = self.s.as_mut().subrows_mut(0, nu + ny + nc);
        linalg::copy(s.rb_mut().subrows_mut(0, nu), rs);
        let (b, d) = (st.b_tilde(knot), knot.D.as_ref());
        linalg::matmul(s.rb_mut().subrows_mut(nu, ny), Accum::Replace, b, rs, 1.0);
        linalg::matmul(s.rb_mut().subrows_mut(nu + ny, nc), Accum::Replace, d, rs, 1.0);
        linalg::negate(s);
    }
}

/// The affine maps of the module documentation, for problems shaped like the one given to
/// [`OffsetMap::new`]; nothing is allocated after it.
#[derive(Debug)]
pub(crate) struct OffsetMap {
    knots: Vec<OffsetKnot>,
    /// `Δp_0`, then `p_0`.
    p_first: Vec<f64>,
}

impl OffsetMap {
    /// Storage of the maps for problems shaped like `problem` (formed by
    /// [`OffsetMap::form`]).
    pub(crate) fn new(problem: &LqProblem) -> Self {
        Self {
            knots: problem.knots.iter().map(OffsetKnot::new).collect(),
            p_first: vec![0.0; problem.knots.first().map_or(0, |k| k.nx)],
        }
    }

    /// Whether the maps apply to `problem` and pay: `mu_dyn = 0` and at most `nx + nu`
    /// constraint rows at every knot (the maps are dense in the rows, `(ny + nc)²` per
    /// knot, where the recursion's work grows linearly in rows that do not involve the
    /// controls, such as the hundreds of obstacle rows of a car among walls).
    pub(crate) fn applies(problem: &LqProblem) -> bool {
        (problem.knots.iter()).all(|k| k.mu_dyn == 0.0 && k.nc <= k.nx + k.nu)
    }

    /// Forms the maps from the backward pass `solver` just ran on `problem` (whose
    /// vectors are the reference `d⁰`, `k⁰`, `p⁰`).
    pub(crate) fn form(&mut self, solver: &mut RiccatiSolver, problem: &LqProblem) {
        for (t, (ok, knot)) in self.knots.iter_mut().zip(&problem.knots).enumerate() {
            let st = solver.stage_mut(t);
            ok.form_feedback(st, knot);
            ok.form_feedforward(st, knot);
        }
    }

    /// The states and controls of `problem` with its current offsets `d` into `sol` (its
    /// co-states and multipliers are not written) and the rows' values `C x + D u` into
    /// `rows`. `solver` must hold the factorization the maps were formed from.
    pub(crate) fn solve(
        &mut self,
        solver: &mut RiccatiSolver,
        problem: &LqProblem,
        sol: &mut LqSolution,
        rows: &mut [Vec<f64>],
    ) -> Result<(), LqError> {
        self.backward(problem);
        for (p, p0) in self.p_first.iter_mut().zip(&self.knots[0].p0) {
            *p += p0;
        }
        solver.solve_initial(
            problem,
            &self.p_first,
            slice_mut(&mut sol.xs[0]),
            slice_mut(&mut sol.lambdas[0]),
        )?;
        self.rollout(problem, sol, rows)
    }

    /// `Δp_t` and `w_t` from the last knot to the first (`Δp_0` in `p_first`).
    fn backward(&mut self, problem: &LqProblem) {
        for t in (0..self.knots.len()).rev() {
            let knot = &problem.knots[t];
            let (head, rest) = self.knots.split_at_mut(t);
            let ok = &mut rest[0];
            for ((e, d), d0) in ok.e[knot.nx_next..].iter_mut().zip(slice(&knot.d)).zip(&ok.d0) {
                *e = d - d0;
            }
            ok.w.copy_from_slice(&ok.w0);
            matvec(&mut ok.w, Accum::Add, ok.s.as_ref(), &ok.e, 1.0);
            let dp = match head.last_mut() {
                Some(prev) => &mut prev.e[..knot.nx],
                None => &mut self.p_first[..],
            };
            dp.copy_from_slice(&ok.w[ok.w.len() - knot.nx..]);
        }
    }

    /// `[u_t; x_{t+1}; g_t] = fb x_t + w_t` from `x_0` in `sol`.
    fn rollout(&mut self, problem: &LqProblem, sol: &mut LqSolution, rows: &mut [Vec<f64>]) -> Result<(), LqError> {
        for (t, (ok, knot)) in self.knots.iter_mut().zip(&problem.knots).enumerate() {
            let (nu, ny, nc) = (knot.nu, knot.nx_next, knot.nc);
            let w = &mut ok.w[..nu + ny + nc];
            matvec(w, Accum::Add, ok.fb.as_ref(), slice(&sol.xs[t]), 1.0);
            let (u, rest) = w.split_at(nu);
            let (x_next, g) = rest.split_at(ny);
            slice_mut(&mut sol.us[t]).copy_from_slice(u);
            rows[t].copy_from_slice(g);
            if ny > 0 {
                slice_mut(&mut sol.xs[t + 1]).copy_from_slice(x_next);
                if !x_next.iter().sum::<f64>().is_finite() {
                    return Err(LqError::NonFinite {
                        knot: t,
                        field: "forward pass state",
                    });
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use faer::Accum;

    use super::OffsetMap;
    use crate::linalg::{matvec, slice};
    use crate::lq::riccati::Outputs;
    use crate::lq::{LqProblem, LqSolution, RiccatiSolver, random};

    /// Largest difference between the states and controls of two solutions, relative to
    /// the largest entry.
    fn primal_gap(a: &LqSolution, b: &LqSolution) -> f64 {
        let mut gap: f64 = 0.0;
        let mut scale: f64 = 1e-300;
        for (va, vb) in a.xs.iter().zip(&b.xs).chain(a.us.iter().zip(&b.us)) {
            for i in 0..va.nrows() {
                gap = gap.max((va[i] - vb[i]).abs());
                scale = scale.max(va[i].abs());
            }
        }
        gap / scale
    }

    /// New offsets `d` (round `round`): the map's states, controls and rows' values equal
    /// the full recursion's and the dense KKT solution's, and differ from the
    /// factorization's solution.
    fn check_new_offsets(mut problem: LqProblem, label: &str) {
        let mut riccati = RiccatiSolver::new(&problem).unwrap();
        riccati.backward(&problem, 0.0).unwrap();
        let mut map = OffsetMap::new(&problem);
        map.form(&mut riccati, &problem);
        let mut reference = LqSolution::new(&problem);
        riccati.forward(&problem, &mut reference).unwrap();
        for round in 0..3 {
            for (t, knot) in problem.knots.iter_mut().enumerate() {
                for i in 0..knot.nc {
                    knot.d[i] = ((t * 7 + i * 3 + round) % 5) as f64 - 2.0;
                }
            }
            let mut full = LqSolution::new(&problem);
            riccati.resolve_vectors(&problem, &mut full, Outputs::Primal).unwrap();
            let mut fast = LqSolution::new(&problem);
            let mut rows: Vec<Vec<f64>> = problem.knots.iter().map(|k| vec![0.0; k.nc]).collect();
            map.solve(&mut riccati, &problem, &mut fast, &mut rows).unwrap();
            let gap = primal_gap(&full, &fast);
            assert!(gap < 1e-11, "{label}, round {round}: gap {gap:e}");
            // The independent reference: the dense KKT solve of the LQ with the new offsets.
            let dense = crate::lq::dense::solve(&problem).unwrap();
            let gap = primal_gap(&dense, &fast);
            assert!(gap < 1e-9, "{label}, round {round}: dense gap {gap:e}");
            for (t, knot) in problem.knots.iter().enumerate() {
                let mut g = vec![0.0; knot.nc];
                matvec(&mut g, Accum::Replace, knot.C.as_ref(), slice(&full.xs[t]), 1.0);
                matvec(&mut g, Accum::Add, knot.D.as_ref(), slice(&full.us[t]), 1.0);
                for (a, b) in g.iter().zip(&rows[t]) {
                    assert!(
                        (a - b).abs() < 1e-10 * (1.0 + a.abs()),
                        "{label}, knot {t}: rows {a} {b}"
                    );
                }
            }
            let nonzero = |m: faer::MatRef<'_, f64>| (0..m.ncols()).any(|j| (0..m.nrows()).any(|i| m[(i, j)] != 0.0));
            if problem
                .knots
                .iter()
                .any(|k| nonzero(k.C.as_ref()) || nonzero(k.D.as_ref()))
            {
                assert!(
                    primal_gap(&full, &reference) > 1e-6,
                    "{label}: the offsets did not move the solution"
                );
            }
        }
    }

    #[test]
    fn offset_map_on_general_e_varying_dimensions_free_initial_states_and_zero_rows() {
        let mut rng = random::SplitMix64::new(5);
        let cases = [
            (true, false, None, false),
            (false, true, Some(0), false),
            (true, true, Some(2), false),
            (false, false, None, true),
        ];
        for (general_e, vary_dims, initial_rows, rank_deficient) in cases {
            let opts = random::VariedOptions {
                horizon: 8,
                nx: (2, 5),
                nu: (1, 3),
                nc: (0, 6),
                vary_dims,
                general_e,
                initial_rows,
                rank_deficient,
                mu_c: (1e-3, 1e-1),
                ..Default::default()
            };
            let problem = random::varied_problem(&mut rng, &opts);
            let label = format!("E {general_e}, varying {vary_dims}, x0 rows {initial_rows:?}, {rank_deficient}");
            check_new_offsets(problem, &label);
        }
    }

    #[test]
    fn offset_map_applies_without_dynamics_regularisation_and_with_few_rows() {
        let mut problem = random::peers_problem(4, 2, 4, 5, 3, 1e-2).problem;
        assert!(OffsetMap::applies(&problem));
        problem.knots[2].mu_dyn = 1e-6;
        assert!(!OffsetMap::applies(&problem));
        let many_rows = random::peers_problem(4, 2, 7, 5, 3, 1e-2).problem;
        assert!(!OffsetMap::applies(&many_rows));
    }

    #[test]
    fn offset_map_equals_the_full_vector_pass_for_new_offsets() {
        for (nx, nu, nc, seed) in [(4, 2, 2, 1), (8, 4, 3, 7), (3, 1, 0, 11), (6, 3, 6, 42), (3, 2, 5, 9)] {
            check_new_offsets(
                random::peers_problem(nx, nu, nc, 12, seed, 1e-2).problem,
                &format!("nx {nx} nu {nu} nc {nc}"),
            );
        }
    }
}

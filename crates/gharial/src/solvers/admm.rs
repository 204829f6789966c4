//! The stagewise ADMM of Jordana et al. (2023), Section IV: the QP of an LQ problem with
//! two-sided bounds `lo ≤ C δx + D δu ≤ hi` on its constraint rows (equalities where
//! `lo = hi`), solved by the OSQP iteration with the Riccati recursion as its linear
//! solver (the QP subproblem of CSQP).
//!
//! With `G = [C D]` the constraint rows of every knot, the splitting `G δ = z`,
//! `lo ≤ z ≤ hi`, the penalty `ρ` and the relaxation `α`, one iteration is
//! ```text
//! δ⁺  = argmin ½ δᵀ H δ + gᵀ δ + ρ/2 |G δ - z + y/ρ|²  s.t. the LQ's dynamics   (Riccati)
//! ẑ   = α G δ⁺ + (1 - α) z
//! z⁺  = proj_[lo, hi](ẑ + y/ρ)
//! y⁺  = y + ρ (ẑ - z⁺)
//! ```
//! The penalty enters the LQ knots as constraint rows with dual regularisation
//! `mu_c = 1/ρ` and offset `d = y/ρ - z` (the proximal Riccati's rows minimise
//! `|C δx + D δu + d|² / (2 mu_c)`), so the factorisation is redone only when `ρ`
//! changes and the other iterations solve for new vectors only: with `mu_dyn = 0` (every
//! QP of CSQP) and at most `nx + nu` rows per knot by the affine map of the offsets `d`
//! formed with each factorisation
//! (`lq/offsets.rs`: two small matrix-vector products per knot, which also give
//! `G δ`), else by the vector pass and rollout of the Riccati recursion; the converged
//! point's co-states and multipliers come from the full recursion. Equality rows take
//! `1000 ρ` (OSQP's choice). Stopping: `|G δ - z|_∞ ≤ ε_abs + ε_rel max(|G δ|_∞, |z|_∞)`
//! and `ρ |Gᵀ (z - z_prev)|_∞ ≤ ε_abs + ε_rel |Gᵀ y|_∞`, checked every
//! `check_interval` iterations. Every `rho_update_interval`
//! iterations `ρ` is scaled by the square root of the ratio of the normalised primal
//! and dual residuals when that changes it more than fivefold (OSQP's rule).

use faer::Accum;

use crate::error::{Error, Result};
use crate::linalg::{matvec, matvec_t, norm_inf, slice, slice_mut};
use crate::lq::offsets::OffsetMap;
use crate::lq::{LqError, LqProblem, LqSolution, Outputs, RiccatiSolver};

/// Relative size of a multiplier below which [`AdmmQp::active_set_factor`] counts its
/// row inactive (the z-update's rounding leaves `|y| ~ ε |y_prev|` there).
pub const ACTIVE_Y: f64 = 1e-10;

/// Dual regularisation of the active rows in [`AdmmQp::active_set_factor`]: equalities
/// to `O(ACTIVE_MU)` (an exact `0` would leave the rows on the states only, as a
/// terminal target, without a pivot).
pub const ACTIVE_MU: f64 = 1e-9;

/// Options of [`AdmmQp`] (defaults of mim_solvers' CSQP where it has them).
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct AdmmOptions {
    /// Initial penalty `ρ` (default 0.1).
    pub rho_init: f64,
    /// Relaxation `α` in `(0, 2)` (default 1.6).
    pub alpha: f64,
    /// Absolute tolerance (default 1e-4).
    pub eps_abs: f64,
    /// Relative tolerance (default 1e-4).
    pub eps_rel: f64,
    /// Iterations at most (default 1000).
    pub max_iters: usize,
    /// Iterations between penalty updates (default 25; 0: fixed `ρ`).
    pub rho_update_interval: usize,
    /// Iterations between convergence checks (default 25, OSQP's `check_termination`):
    /// a warm-started QP is not stopped after an iteration or two with the loose
    /// residuals of its first steps.
    pub check_interval: usize,
}

impl Default for AdmmOptions {
    fn default() -> Self {
        Self {
            rho_init: 0.1,
            alpha: 1.6,
            eps_abs: 1e-4,
            eps_rel: 1e-4,
            max_iters: 1000,
            rho_update_interval: 25,
            check_interval: 25,
        }
    }
}

impl AdmmOptions {
    /// The options after `f` changed them (builder style).
    pub fn with(mut self, f: impl FnOnce(&mut Self)) -> Self {
        f(&mut self);
        self
    }

    /// Checks every option's range.
    ///
    /// # Errors
    /// Names the offending option.
    pub fn validate(&self) -> Result<()> {
        crate::error::check_positive("rho_init", self.rho_init)?;
        if !(self.alpha > 0.0 && self.alpha < 2.0) {
            return Err(Error::option("alpha", "must be in (0, 2)"));
        }
        for (name, v) in [("eps_abs", self.eps_abs), ("eps_rel", self.eps_rel)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::option(name, "must be finite and nonnegative"));
            }
        }
        if self.eps_abs == 0.0 && self.eps_rel == 0.0 {
            return Err(Error::option("eps_abs", "eps_abs and eps_rel cannot both be 0"));
        }
        if self.max_iters == 0 {
            return Err(Error::option("max_iters", "must be at least 1"));
        }
        if self.check_interval == 0 {
            return Err(Error::option("check_interval", "must be at least 1"));
        }
        Ok(())
    }
}

/// The sets of the constraint rows' values `z`, by their Euclidean projections: boxes
/// ([`AdmmQp::solve`]) or any closed convex sets, e.g. second-order cones
/// ([`AdmmQp::solve_sets`]).
pub trait RowSets {
    /// Whether row `i` of knot `t` is an equality (its penalty is `1000 ρ`).
    fn is_equality(&self, t: usize, i: usize) -> bool;
    /// Projects `v`, the values of the rows of knot `t`, onto their set, in place.
    fn project(&mut self, t: usize, v: &mut [f64]);
}

/// Row bounds `lo ≤ z ≤ hi` as [`RowSets`].
struct Bounds<'a> {
    lo: &'a [Vec<f64>],
    hi: &'a [Vec<f64>],
}

impl RowSets for Bounds<'_> {
    fn is_equality(&self, t: usize, i: usize) -> bool {
        self.lo[t][i] == self.hi[t][i]
    }
    fn project(&mut self, t: usize, v: &mut [f64]) {
        clamp(v, &self.lo[t], &self.hi[t]);
    }
}

/// The projection onto the box `[lo, hi]`, row by row: `v_i ← min(max(v_i, lo_i), hi_i)`.
pub(crate) fn clamp(v: &mut [f64], lo: &[f64], hi: &[f64]) {
    for (vi, (l, u)) in v.iter_mut().zip(lo.iter().zip(hi)) {
        *vi = vi.max(*l).min(*u);
    }
}

/// How an ADMM solve ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AdmmStatus {
    /// Primal and dual residuals within the tolerances.
    Converged,
    /// The iteration limit was reached (the bounds may be contradictory).
    MaxIterations,
}

/// The stagewise ADMM QP solver (module documentation); every buffer allocated in
/// [`AdmmQp::new`].
#[derive(Debug)]
pub struct AdmmQp {
    options: AdmmOptions,
    riccati: RiccatiSolver,
    /// The x-update as an affine map of the offsets `d`, formed with each factorization
    /// when it applies (`OffsetMap::applies`; `use_offsets`).
    offsets: OffsetMap,
    use_offsets: bool,
    sol: LqSolution,
    /// Splitting variable, scaled duals, last `z`, `G δ` per knot.
    z: Vec<Vec<f64>>,
    /// Whether each row is an equality (from the sets of the last solve).
    equality: Vec<Vec<bool>>,
    /// The penalty of each row (`ρ`, `1000 ρ` on equalities), set with the knots' rows.
    rho_rows: Vec<Vec<f64>>,
    /// Whether a knot's `C` is zero (rows on controls only): its products are skipped.
    c_zero: Vec<bool>,
    y: Vec<Vec<f64>>,
    z_prev: Vec<Vec<f64>>,
    gd: Vec<Vec<f64>>,
    /// Scratch of state and control size for `Gᵀ v`.
    tx: Vec<Vec<f64>>,
    tu: Vec<Vec<f64>>,
    rho: f64,
    /// Primal regularisation of the factorizations ([`AdmmQp::set_regularization`]).
    reg: f64,
    iters: usize,
    prim: f64,
    dual: f64,
}

/// Residuals and scales of one iteration.
#[derive(Debug, Clone, Copy)]
struct Residuals {
    prim: f64,
    dual: f64,
    prim_scale: f64,
    dual_scale: f64,
}

impl AdmmQp {
    /// A solver for LQ problems shaped like `lq` (its constraint rows are the rows `G`).
    ///
    /// # Errors
    /// If the options are out of range or the LQ problem is malformed.
    pub fn new(lq: &LqProblem, options: AdmmOptions) -> Result<Self> {
        options.validate()?;
        let riccati = RiccatiSolver::new(lq).map_err(|e| Error::InvalidModel(format!("ADMM: {e}")))?;
        let rows = |k: &crate::lq::LqKnot| vec![0.0; k.nc];
        let z: Vec<Vec<f64>> = lq.knots.iter().map(rows).collect();
        Ok(Self {
            options,
            riccati,
            offsets: OffsetMap::new(lq),
            use_offsets: false,
            sol: LqSolution::new(lq),
            y: z.clone(),
            z_prev: z.clone(),
            equality: z.iter().map(|r| vec![false; r.len()]).collect(),
            rho_rows: z.clone(),
            c_zero: vec![false; lq.knots.len()],
            gd: z.clone(),
            tx: lq.knots.iter().map(|k| vec![0.0; k.nx]).collect(),
            tu: lq.knots.iter().map(|k| vec![0.0; k.nu]).collect(),
            z,
            rho: options.rho_init,
            reg: 0.0,
            iters: 0,
            prim: 0.0,
            dual: 0.0,
        })
    }

    /// Solves the QP of `lq` with `lo ≤ C δx + D δu ≤ hi` row by row (`±∞` for one-sided
    /// rows). The knots' constraint offsets `d` and regularisations `mu_c` are the
    /// solver's (overwritten). With `warm`, starts from the last solve's `z`, `y` and `ρ`
    /// (the MPC settings of the paper, Section VI-B); else from zero and `rho_init`.
    ///
    /// # Errors
    /// If `lo`, `hi` do not fit the rows, `lo > hi` somewhere, or the LQ solve fails
    /// (a singular or non-finite system).
    pub fn solve(&mut self, lq: &mut LqProblem, lo: &[Vec<f64>], hi: &[Vec<f64>], warm: bool) -> Result<AdmmStatus> {
        self.check_bounds(lo, hi)?;
        self.solve_sets(lq, &mut Bounds { lo, hi }, warm)
    }

    /// As [`AdmmQp::solve`] with the rows' values in the sets of `sets` (its projections
    /// must keep each row's length).
    ///
    /// # Errors
    /// If the LQ solve fails (a singular or non-finite system).
    pub fn solve_sets(&mut self, lq: &mut LqProblem, sets: &mut dyn RowSets, warm: bool) -> Result<AdmmStatus> {
        if !warm {
            self.z.iter_mut().chain(self.y.iter_mut()).for_each(|v| v.fill(0.0));
            self.rho = self.options.rho_init;
        }
        for (t, e) in self.equality.iter_mut().enumerate() {
            for (i, ei) in e.iter_mut().enumerate() {
                *ei = sets.is_equality(t, i);
            }
        }
        for (c_zero, knot) in self.c_zero.iter_mut().zip(&lq.knots) {
            // Exact zeros only: a NaN keeps the products, which report it.
            let c = knot.C.as_ref();
            *c_zero = (0..c.ncols()).all(|j| (0..c.nrows()).all(|i| c[(i, j)] == 0.0));
        }
        self.set_rows(lq);
        self.factor(lq)?;
        if lq.knots.iter().all(|k| k.nc == 0) {
            // No constraint rows: the first x-update is the QP's solution.
            self.iters = 1;
            (self.prim, self.dual) = (0.0, 0.0);
            self.x_update(lq, Outputs::All)?;
            return Ok(AdmmStatus::Converged);
        }
        let o = self.options;
        for it in 0..o.max_iters {
            self.iters = it + 1;
            // Co-states and constraint multipliers of the QP only at the end (the last
            // iteration, or the rollout repeated below once converged).
            let last = self.iters == o.max_iters;
            self.x_update(lq, if last { Outputs::All } else { Outputs::Primal })?;
            let check = self.iters.is_multiple_of(o.check_interval) || self.iters == o.max_iters;
            let update = o.rho_update_interval > 0 && self.iters.is_multiple_of(o.rho_update_interval);
            // The residuals (two products with Gᵀ per knot) only where they are used.
            let Some(r) = self.z_y_update(lq, sets, check || update) else {
                continue;
            };
            (self.prim, self.dual) = (r.prim, r.dual);
            if check && r.prim <= o.eps_abs + o.eps_rel * r.prim_scale && r.dual <= o.eps_abs + o.eps_rel * r.dual_scale
            {
                if !last {
                    self.finish(lq)?;
                }
                return Ok(AdmmStatus::Converged);
            }
            if update && self.update_rho(&r) {
                self.set_rows(lq);
                self.factor(lq)?;
            }
        }
        Ok(AdmmStatus::MaxIterations)
    }

    /// The converged point with its co-states and multipliers: by the full recursion after
    /// the offset map's x-updates, else the same rollout (nothing changed since
    /// `x_update`) with everything.
    fn finish(&mut self, lq: &LqProblem) -> Result<()> {
        if self.use_offsets {
            self.riccati.resolve_vectors(lq, &mut self.sol, Outputs::All)
        } else {
            self.riccati.forward(lq, &mut self.sol)
        }
        .map_err(lq_error)
    }

    fn check_bounds(&self, lo: &[Vec<f64>], hi: &[Vec<f64>]) -> Result<()> {
        crate::error::check_dim("ADMM: knots of lo", self.z.len(), lo.len())?;
        crate::error::check_dim("ADMM: knots of hi", self.z.len(), hi.len())?;
        for (t, (l, h)) in lo.iter().zip(hi).enumerate() {
            crate::error::check_dim(format_args!("ADMM: lo[{t}]"), self.z[t].len(), l.len())?;
            crate::error::check_dim(format_args!("ADMM: hi[{t}]"), self.z[t].len(), h.len())?;
            if let Some(i) = (0..l.len()).find(|&i| l[i] > h[i] || l[i].is_nan() || h[i].is_nan()) {
                return Err(Error::InvalidModel(format!(
                    "ADMM: knot {t}, row {i}: empty bounds [{}, {}]",
                    crate::error::Num(l[i]),
                    crate::error::Num(h[i])
                )));
            }
        }
        Ok(())
    }

    /// Sets the rows' penalties `ρ_i` (`1000 ρ` on equality rows) and writes
    /// `mu_c = 1/ρ_i` and `d = y/ρ_i - z` into the knots.
    fn set_rows(&mut self, lq: &mut LqProblem) {
        for (t, knot) in lq.knots.iter_mut().enumerate() {
            for i in 0..knot.nc {
                let rho = if self.equality[t][i] { 1e3 * self.rho } else { self.rho };
                self.rho_rows[t][i] = rho;
                knot.mu_c[i] = 1.0 / rho;
                knot.d[i] = self.y[t][i] / rho - self.z[t][i];
            }
        }
    }

    /// Adds `reg I` to the Hessian of the QPs solved from now on (Levenberg-Marquardt:
    /// their solution is the regularised step; 0 by default), for QPs whose Hessian is
    /// singular on the controls.
    pub fn set_regularization(&mut self, reg: f64) {
        self.reg = reg;
    }

    fn factor(&mut self, lq: &LqProblem) -> Result<()> {
        self.riccati.backward(lq, self.reg).map_err(lq_error)?;
        self.use_offsets = OffsetMap::applies(lq);
        if self.use_offsets {
            self.offsets.form(&mut self.riccati, lq);
        }
        Ok(())
    }

    /// `δ⁺` for the current `z`, `y` (new vectors, same factorisation), and `G δ⁺`; the
    /// QP's co-states and multipliers too with `Outputs::All`.
    fn x_update(&mut self, lq: &mut LqProblem, outputs: Outputs) -> Result<()> {
        for ((knot, y), z) in lq.knots.iter_mut().zip(&self.y).zip(&self.z) {
            let (d, mu_c) = (slice_mut(&mut knot.d), slice(&knot.mu_c));
            for (((di, yi), zi), mi) in d.iter_mut().zip(y).zip(z).zip(mu_c) {
                *di = yi * mi - zi;
            }
        }
        // The knots' shapes and regularisations were checked by the factorisation.
        if self.use_offsets && outputs == Outputs::Primal {
            return (self.offsets)
                .solve(&mut self.riccati, lq, &mut self.sol, &mut self.gd)
                .map_err(lq_error);
        }
        (self.riccati)
            .resolve_vectors(lq, &mut self.sol, outputs)
            .map_err(lq_error)?;
        for (t, knot) in lq.knots.iter().enumerate() {
            let g = &mut self.gd[t];
            if self.c_zero[t] {
                g.fill(0.0);
            } else {
                matvec(g, Accum::Replace, knot.C.as_ref(), slice(&self.sol.xs[t]), 1.0);
            }
            if knot.nu > 0 {
                matvec(g, Accum::Add, knot.D.as_ref(), slice(&self.sol.us[t]), 1.0);
            }
        }
        Ok(())
    }

    /// The relaxed projection and dual update; with `residuals`, the residuals of the
    /// iteration.
    fn z_y_update(&mut self, lq: &LqProblem, sets: &mut dyn RowSets, residuals: bool) -> Option<Residuals> {
        let a = self.options.alpha;
        let mut r = Residuals {
            prim: 0.0,
            dual: 0.0,
            prim_scale: 0.0,
            dual_scale: 0.0,
        };
        let knots = self.z.iter_mut().zip(&mut self.z_prev).zip(&mut self.y);
        for (t, (((z, z_prev), y), (gd, rho))) in knots.zip(self.gd.iter().zip(&self.rho_rows)).enumerate() {
            z_prev.copy_from_slice(z);
            for ((zi, zp), (yi, (gi, ri))) in z.iter_mut().zip(z_prev.iter()).zip(y.iter().zip(gd.iter().zip(rho))) {
                *zi = a * gi + (1.0 - a) * zp + yi / ri;
            }
            sets.project(t, z);
            for ((zi, zp), (yi, (gi, ri))) in z.iter().zip(z_prev.iter()).zip(y.iter_mut().zip(gd.iter().zip(rho))) {
                // ẑ, the relaxed G δ⁺.
                let zh = a * gi + (1.0 - a) * zp;
                *yi += ri * (zh - zi);
            }
            if residuals {
                for ((zi, zp), (gi, ri)) in z.iter().zip(z_prev.iter_mut()).zip(gd.iter().zip(rho)) {
                    r.prim = r.prim.max((gi - zi).abs());
                    r.prim_scale = r.prim_scale.max(gi.abs()).max(zi.abs());
                    *zp = ri * (zi - *zp);
                }
            }
        }
        if !residuals {
            return None;
        }
        // Dual residual ρ Gᵀ(z - z_prev) (z_prev now holds ρ (z - z_prev)) and Gᵀ y.
        for (t, knot) in lq.knots.iter().enumerate() {
            r.dual = r.dual.max(self.transpose_norm(knot, t, false));
            r.dual_scale = r.dual_scale.max(self.transpose_norm(knot, t, true));
        }
        Some(r)
    }

    /// `|Gᵀ v|_∞` at knot `t` for `v = y` (`duals`) or the scaled change of `z`.
    fn transpose_norm(&mut self, knot: &crate::lq::LqKnot, t: usize, duals: bool) -> f64 {
        let v = if duals { &self.y[t] } else { &self.z_prev[t] };
        let mut m = 0.0;
        if !self.c_zero[t] {
            matvec_t(&mut self.tx[t], Accum::Replace, knot.C.as_ref(), v, 1.0);
            m = norm_inf(&self.tx[t]);
        }
        if knot.nu > 0 {
            matvec_t(&mut self.tu[t], Accum::Replace, knot.D.as_ref(), v, 1.0);
            m = m.max(norm_inf(&self.tu[t]));
        }
        m
    }

    /// OSQP's penalty update; `true` if `ρ` changed (refactorisation needed).
    fn update_rho(&mut self, r: &Residuals) -> bool {
        let p = r.prim / r.prim_scale.max(1e-30);
        let d = r.dual / r.dual_scale.max(1e-30);
        if p == 0.0 || d == 0.0 {
            return false;
        }
        let ratio = (p / d).sqrt();
        if !(0.2..=5.0).contains(&ratio) {
            self.rho = (self.rho * ratio).clamp(1e-6, 1e6);
            return true;
        }
        false
    }

    /// After the caller moved its point by `alpha δ` (a step of an SQP iteration), moves
    /// the splitting variable by the same fraction (`z ← (1 - α) z`), so that a warm start
    /// of the next QP, whose variable is `δ - α δ`, starts from the same constraint values;
    /// the duals and `ρ` stay.
    pub fn follow_step(&mut self, alpha: f64) {
        for z in &mut self.z {
            z.iter_mut().for_each(|v| *v *= 1.0 - alpha);
        }
    }

    /// The Riccati stages of the last factorization (after [`AdmmQp::active_set_factor`]:
    /// the gains of the active-set LQ).
    pub fn stages(&self) -> &[crate::lq::RiccatiStage] {
        self.riccati.stages()
    }

    /// Factors the LQ of the last solve with its active rows as equalities (to
    /// [`ACTIVE_MU`]; the active rows of sets that are not boxes, `row_in_box(t, i)`
    /// false, keep the ADMM's penalty: pinning a binding cone's rows would freeze it,
    /// and its exact sensitivity needs the cone's curvature) and without its inactive ones, for the feedback gains `K_t` of the QP's solution (the
    /// sensitivity of its controls to the initial state, as box-DDP's gains): a row is
    /// active when its multiplier `y` is nonzero: above [`ACTIVE_Y`] times the largest
    /// (the z-update leaves `y` at rounding level on a row strictly inside its set). The ADMM's own factorization treats every row as a
    /// penalty `ρ/2 |G δ - z + y/ρ|²`, whose gains stiffen with `ρ` (mim_solvers' CSQP
    /// reports those). Changes the rows of `lq` (the next solve sets them again).
    ///
    /// # Errors
    /// If the factorization fails (active rows nearly dependent at a knot).
    pub fn active_set_factor(&mut self, lq: &mut LqProblem, row_in_box: &dyn Fn(usize, usize) -> bool) -> Result<()> {
        let y_max = self.y.iter().map(|y| norm_inf(y)).fold(0.0, f64::max);
        for (t, (knot, y)) in lq.knots.iter_mut().zip(&self.y).enumerate() {
            for (i, &yi) in y.iter().enumerate().take(knot.nc) {
                if yi.abs() <= ACTIVE_Y * y_max {
                    knot.C.as_mut().row_mut(i).fill(0.0);
                    knot.D.as_mut().row_mut(i).fill(0.0);
                    knot.mu_c[i] = 1.0;
                } else if row_in_box(t, i) {
                    knot.mu_c[i] = ACTIVE_MU;
                } else {
                    knot.mu_c[i] = 1.0 / self.rho_rows[t][i];
                }
                knot.d[i] = 0.0;
            }
        }
        self.riccati.backward(lq, self.reg).map_err(lq_error)
    }

    /// [`AdmmQp::active_set_factor`] with the rows' multipliers `y` given (per knot, a
    /// prefix of its rows; a solve that converged before any QP: the point's own) and the
    /// initial penalty on the rows of other sets.
    pub fn active_set_factor_at(
        &mut self,
        lq: &mut LqProblem,
        y: &[Vec<f64>],
        row_in_box: &dyn Fn(usize, usize) -> bool,
    ) -> Result<()> {
        for ((yk, rk), src) in self.y.iter_mut().zip(&mut self.rho_rows).zip(y) {
            yk.fill(0.0);
            yk[..src.len()].copy_from_slice(src);
            rk.fill(self.options.rho_init);
        }
        self.active_set_factor(lq, row_in_box)
    }

    /// The last solution `δ` (states, controls, co-states).
    pub fn solution(&self) -> &LqSolution {
        &self.sol
    }

    /// The multipliers `y` of the constraint rows (per knot).
    pub fn multipliers(&self) -> &[Vec<f64>] {
        &self.y
    }

    /// Iterations of the last solve.
    pub fn iterations(&self) -> usize {
        self.iters
    }

    /// Primal and dual residuals of the last iteration.
    pub fn residuals(&self) -> (f64, f64) {
        (self.prim, self.dual)
    }

    /// The current penalty `ρ`.
    pub fn rho(&self) -> f64 {
        self.rho
    }
}

fn lq_error(e: LqError) -> Error {
    Error::InvalidModel(format!("ADMM: LQ solve failed: {e}"))
}

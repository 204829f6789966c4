//! Minimum-time and time-penalised problems: the time step as a control (ALTRO, Howell
//! et al. 2019, §III-C).
//!
//! A continuous-time stage ([`ContinuousStage`]: an ODE `ẋ = f(x, u)`, a running cost per
//! unit of time `ℓ(x, u)`, path constraints) becomes a discrete stage on the augmented
//! state `x̃ = (x, δ) ∈ M × R` with the augmented control `ũ = (u, τ)`:
//! ```text
//! h_k       = τ_k²                                    (the step, τ = √h as in the paper)
//! x_{k+1}   = RK_{h_k}(f; x_k, u_k),   δ_{k+1} = τ_k   ((33))
//! ℓ̃_k       = h_k (ℓ(x_k, u_k) + R_min_time)          ((34) with the running cost over h_k)
//! δ_k = τ_k   (k = 1..N-1),   √h_min ≤ τ_k ≤ √h_max
//! ```
//! The equality between consecutive steps is written on the state `δ`, which carries
//! the previous step (the paper's augmentation): a gharial constraint sees one stage's
//! `(x, u)` only. With every `h_k` equal, `Σ_k h_k ℓ` is the usual rectangle rule of the
//! running cost and `R_min_time Σ_k h_k = R_min_time T` penalises the total time.
//!
//! # Why `τ = √h`
//! As in the paper: the time penalty `R τ²` is then a convex quadratic of the control,
//! which is what iLQR's cost model expects, and `h = τ² ≥ 0` whatever the iterate (the
//! bounds hold only at convergence for AL methods). Its Hessian in `τ`, `2 (ℓ + R)`, is
//! positive wherever the running cost is non-negative.
//!
//! # The step inside the integrator
//! An explicit Runge-Kutta step of length `h` on `f` is the step of length 1 on the
//! time-scaled field `h f`: every stage increment `dt a_i k_{i-1}` and the update
//! `dt Σ b_i k_i` are products of the step and the field ([`crate::dynamics::integrators`]).
//! So the integrator is [`ExplicitRungeKutta`] itself with `dt = 1` on [`TimeScaledOde`]
//! `g(x, (u, τ)) = τ² f(x, u)`, whose `τ`-column `2τ f` carries the derivative of the
//! step through every stage. Semi-implicit Euler has no such form (its position update
//! uses the new velocity times the step) and is not offered.

use std::sync::Arc;

use faer::Mat;

use super::{Problem, StageConstraint, StageModel};
use crate::constraints::{BoxConstraint, EqualityConstraintSet};
use crate::costs::{Cost, CostData};
use crate::dynamics::{Dynamics, ExplicitDynamics, ExplicitDynamicsData, ExplicitRungeKutta, Ode, OdeData, RkMethod};
use crate::error::{Error, Num, Result, check_dim};
use crate::functions::util::{copy_scaled, downcast};
use crate::functions::{StageFunction, StageFunctionData, Workspace};
use crate::linalg::slice_mut;
use crate::spaces::{CartesianProduct, Manifold, VectorSpace};

/// The time-scaled field `g(x, (u, τ)) = τ² f(x, u)` of an ODE, with one more control:
/// `g_x = τ² f_x`, `g_u = [τ² f_u, 2τ f]`.
pub struct TimeScaledOde {
    ode: Arc<dyn Ode>,
}

impl TimeScaledOde {
    /// `τ² f` for `f = ode`.
    pub fn new(ode: Arc<dyn Ode>) -> Self {
        Self { ode }
    }
}

impl Ode for TimeScaledOde {
    fn space(&self) -> &Arc<dyn Manifold> {
        self.ode.space()
    }
    fn nu(&self) -> usize {
        self.ode.nu() + 1
    }
    fn create_workspace(&self) -> Workspace {
        Box::new(self.ode.create_data())
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        let nu = self.ode.nu();
        let h = u[nu] * u[nu];
        let inner: &mut OdeData = downcast(&mut data.ws);
        self.ode.evaluate(x, &u[..nu], inner);
        for (g, f) in data.xdot.iter_mut().zip(inner.xdot()) {
            *g = h * f;
        }
    }
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        let nu = self.ode.nu();
        let tau = u[nu];
        let inner: &mut OdeData = downcast(&mut data.ws);
        self.ode.jacobians(x, &u[..nu], inner);
        copy_scaled(data.jx.as_mut(), tau * tau, inner.jx.as_ref());
        copy_scaled(data.ju.as_mut().subcols_mut(0, nu), tau * tau, inner.ju.as_ref());
        for (i, f) in inner.xdot().iter().enumerate() {
            data.ju[(i, nu)] = 2.0 * tau * f;
        }
    }
}

/// The augmented dynamics (33): `x_{k+1} = φ(x_k, (u_k, τ_k))`, `δ_{k+1} = τ_k` on
/// `M × R`, where `φ` is the Runge-Kutta step of length 1 of [`TimeScaledOde`].
struct MinTimeDynamics {
    phi: ExplicitRungeKutta,
    space: Arc<dyn Manifold>,
}

impl ExplicitDynamics for MinTimeDynamics {
    fn space(&self) -> &Arc<dyn Manifold> {
        &self.space
    }
    fn nu(&self) -> usize {
        self.phi.nu()
    }
    fn create_workspace(&self) -> Workspace {
        Box::new(self.phi.create_data())
    }
    fn forward(&self, x: &[f64], u: &[f64], data: &mut ExplicitDynamicsData) {
        let nx = self.phi.space().nx();
        let inner: &mut ExplicitDynamicsData = downcast(&mut data.ws);
        self.phi.forward(&x[..nx], u, inner);
        let y = slice_mut(&mut data.xnext);
        y[..nx].copy_from_slice(inner.xnext());
        y[nx] = u[u.len() - 1];
    }
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut ExplicitDynamicsData) {
        let (nx, ndx) = (self.phi.space().nx(), self.phi.space().ndx());
        let inner: &mut ExplicitDynamicsData = downcast(&mut data.ws);
        self.phi.jacobians(&x[..nx], u, inner);
        data.jx.fill(0.0);
        data.jx.as_mut().submatrix_mut(0, 0, ndx, ndx).copy_from(&inner.jx);
        data.ju.fill(0.0);
        data.ju.as_mut().subrows_mut(0, ndx).copy_from(&inner.ju);
        data.ju[(ndx, u.len() - 1)] = 1.0;
    }
}

/// Copies `src` into the top-left corner of `dst` and zeroes the rest.
fn pad(dst: &mut Mat<f64>, src: &Mat<f64>) {
    dst.fill(0.0);
    dst.as_mut()
        .submatrix_mut(0, 0, src.nrows(), src.ncols())
        .copy_from(src);
}

/// `r̃((x, δ), ũ) = r(x, u)` with `u` the first `r.nu()` entries of `ũ`: a function of the
/// original stage on the augmented one (zero columns for `δ` and `τ`).
struct Lifted {
    f: Arc<dyn StageFunction>,
    /// Controls added after `u` (1 on running stages, 0 for terminal functions).
    extra_u: usize,
}

impl StageFunction for Lifted {
    fn nx(&self) -> usize {
        self.f.nx() + 1
    }
    fn ndx(&self) -> usize {
        self.f.ndx() + 1
    }
    fn nu(&self) -> usize {
        self.f.nu() + self.extra_u
    }
    fn nr(&self) -> usize {
        self.f.nr()
    }
    fn create_workspace(&self) -> Workspace {
        Box::new(self.f.create_data())
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let inner: &mut StageFunctionData = downcast(&mut data.ws);
        self.f.evaluate(&x[..self.f.nx()], &u[..self.f.nu()], inner);
        data.value.copy_from(&inner.value);
    }
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let inner: &mut StageFunctionData = downcast(&mut data.ws);
        self.f.jacobians(&x[..self.f.nx()], &u[..self.f.nu()], inner);
        pad(&mut data.jx, &inner.jx);
        pad(&mut data.ju, &inner.ju);
    }
    fn jacobians_are_constant(&self) -> bool {
        self.f.jacobians_are_constant()
    }
    fn has_vhp(&self) -> bool {
        self.f.has_vhp()
    }
    fn vhp(&self, x: &[f64], u: &[f64], lambda: &[f64], data: &mut StageFunctionData) {
        let inner: &mut StageFunctionData = downcast(&mut data.ws);
        self.f.vhp(&x[..self.f.nx()], &u[..self.f.nu()], lambda, inner);
        pad(&mut data.vhp_xx, &inner.vhp_xx);
        pad(&mut data.vhp_xu, &inner.vhp_xu);
        pad(&mut data.vhp_uu, &inner.vhp_uu);
    }
}

/// A terminal cost on the augmented state: `ℓ̃_N((x, δ)) = ℓ_N(x)`.
struct LiftedTerminalCost(Arc<dyn Cost>);

impl Cost for LiftedTerminalCost {
    fn nx(&self) -> usize {
        self.0.nx() + 1
    }
    fn ndx(&self) -> usize {
        self.0.ndx() + 1
    }
    fn nu(&self) -> usize {
        0
    }
    fn create_workspace(&self) -> Workspace {
        Box::new(self.0.create_data())
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        let inner: &mut CostData = downcast(&mut data.ws);
        self.0.evaluate(&x[..self.0.nx()], u, inner);
        data.value = inner.value;
    }
    fn derivatives(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        let inner: &mut CostData = downcast(&mut data.ws);
        self.0.derivatives(&x[..self.0.nx()], u, inner);
        let ndx = self.0.ndx();
        data.lx.fill(0.0);
        data.lx.as_mut().subrows_mut(0, ndx).copy_from(&inner.lx);
        pad(&mut data.lxx, &inner.lxx);
    }
    fn hessian_is_constant(&self) -> bool {
        self.0.hessian_is_constant()
    }
}

/// The running cost of the augmented stage, `ℓ̃((x, δ), (u, τ)) = τ² (ℓ(x, u) + R)`
/// ((34) and the running cost over the step). With `s = ℓ + R`:
/// ```text
/// ∇_x = τ² ℓ_x,   ∇_u = τ² ℓ_u,   ∇_τ = 2τ s
/// ∇²_xx = τ² ℓ_xx,  ∇²_xu = τ² ℓ_xu,  ∇²_xτ = 2τ ℓ_x,  ∇²_uu = τ² ℓ_uu,  ∇²_uτ = 2τ ℓ_u,  ∇²_ττ = 2 s
/// ```
struct TimeWeightedCost {
    cost: Arc<dyn Cost>,
    r_min_time: f64,
}

impl Cost for TimeWeightedCost {
    fn nx(&self) -> usize {
        self.cost.nx() + 1
    }
    fn ndx(&self) -> usize {
        self.cost.ndx() + 1
    }
    fn nu(&self) -> usize {
        self.cost.nu() + 1
    }
    fn create_workspace(&self) -> Workspace {
        Box::new(self.cost.create_data())
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        let nu = self.cost.nu();
        let inner: &mut CostData = downcast(&mut data.ws);
        self.cost.evaluate(&x[..self.cost.nx()], &u[..nu], inner);
        data.value = u[nu] * u[nu] * (inner.value + self.r_min_time);
    }
    fn derivatives(&self, x: &[f64], u: &[f64], data: &mut CostData) {
        let (ndx, nu) = (self.cost.ndx(), self.cost.nu());
        let tau = u[nu];
        let h = tau * tau;
        let inner: &mut CostData = downcast(&mut data.ws);
        self.cost.derivatives(&x[..self.cost.nx()], &u[..nu], inner);
        let s = inner.value + self.r_min_time;
        data.lx.fill(0.0);
        data.lxx.fill(0.0);
        data.lxu.fill(0.0);
        for i in 0..ndx {
            data.lx[i] = h * inner.lx[i];
            data.lxu[(i, nu)] = 2.0 * tau * inner.lx[i];
        }
        copy_scaled(data.lxx.as_mut().submatrix_mut(0, 0, ndx, ndx), h, inner.lxx.as_ref());
        copy_scaled(data.lxu.as_mut().submatrix_mut(0, 0, ndx, nu), h, inner.lxu.as_ref());
        copy_scaled(data.luu.as_mut().submatrix_mut(0, 0, nu, nu), h, inner.luu.as_ref());
        for j in 0..nu {
            data.lu[j] = h * inner.lu[j];
            data.luu[(j, nu)] = 2.0 * tau * inner.lu[j];
            data.luu[(nu, j)] = 2.0 * tau * inner.lu[j];
        }
        data.lu[nu] = 2.0 * tau * s;
        data.luu[(nu, nu)] = 2.0 * s;
    }
}

/// `τ` (bounds on the step) or `δ - τ` (the equal-step constraint), on the augmented
/// stage: constant Jacobians.
struct StepResidual {
    nx: usize,
    ndx: usize,
    nu: usize,
    /// `δ - τ` when true, `τ` otherwise.
    minus_delta: bool,
}

impl StageFunction for StepResidual {
    fn nx(&self) -> usize {
        self.nx
    }
    fn ndx(&self) -> usize {
        self.ndx
    }
    fn nu(&self) -> usize {
        self.nu
    }
    fn nr(&self) -> usize {
        1
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let tau = u[self.nu - 1];
        data.value[0] = if self.minus_delta { x[self.nx - 1] - tau } else { tau };
    }
    fn jacobians(&self, _x: &[f64], _u: &[f64], data: &mut StageFunctionData) {
        data.jx.fill(0.0);
        data.ju.fill(0.0);
        if self.minus_delta {
            data.jx[(0, self.ndx - 1)] = 1.0;
            data.ju[(0, self.nu - 1)] = -1.0;
        } else {
            data.ju[(0, self.nu - 1)] = 1.0;
        }
    }
    fn jacobians_are_constant(&self) -> bool {
        true
    }
}

/// One stage of a continuous-time problem: what [`MinimumTime`] turns into a discrete
/// stage whose step is a control.
#[derive(Clone)]
pub struct ContinuousStage {
    /// The dynamics `ẋ = f(x, u)`.
    pub ode: Arc<dyn Ode>,
    /// The running cost per unit of time `ℓ(x, u)` (weighted by the step `h` in the
    /// discrete stage).
    pub cost: Arc<dyn Cost>,
    /// Path constraints `c(x, u) ∈ C`.
    pub constraints: Vec<StageConstraint>,
}

/// The minimum-time transformation of §III-C (module documentation): step bounds, the
/// weight of the total time and the integrator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MinimumTime {
    /// Smallest step `h_min > 0`.
    pub h_min: f64,
    /// Largest step `h_max ≥ h_min`.
    pub h_max: f64,
    /// The weight `R_min_time ≥ 0` of the total time `Σ h_k`.
    pub r_min_time: f64,
    /// The explicit Runge-Kutta method of every step.
    pub method: RkMethod,
}

impl MinimumTime {
    /// Step bounds `[h_min, h_max]`, time weight `r_min_time`, integrator `method`.
    ///
    /// # Errors
    /// If `0 < h_min ≤ h_max < ∞` or `0 ≤ r_min_time < ∞` fails.
    pub fn new(h_min: f64, h_max: f64, r_min_time: f64, method: RkMethod) -> Result<Self> {
        if !(h_min > 0.0 && h_min <= h_max && h_max.is_finite()) {
            return Err(Error::option(
                "MinimumTime step bounds",
                format!("need 0 < h_min <= h_max < inf, got [{}, {}]", Num(h_min), Num(h_max)),
            ));
        }
        if !(r_min_time >= 0.0 && r_min_time.is_finite()) {
            return Err(Error::option(
                "MinimumTime r_min_time",
                format!("must be finite and >= 0, got {}", Num(r_min_time)),
            ));
        }
        Ok(Self {
            h_min,
            h_max,
            r_min_time,
            method,
        })
    }

    /// The augmented state space `M × R` (the last coordinate `δ`, the previous `τ`).
    pub fn augmented_space(space: &Arc<dyn Manifold>) -> Arc<dyn Manifold> {
        Arc::new(CartesianProduct::pair(space.clone(), Arc::new(VectorSpace::new(1))))
    }

    /// The discrete stage `k` of `stage` on `space` (from [`MinimumTime::augmented_space`]),
    /// with the equal-step constraint `δ_k = τ_k` when `k ≥ 1`.
    ///
    /// # Errors
    /// If the ODE, cost and constraints disagree on the state or control sizes.
    pub fn stage(&self, stage: &ContinuousStage, k: usize, space: &Arc<dyn Manifold>) -> Result<StageModel> {
        let (ode, nu) = (&stage.ode, stage.ode.nu());
        let what = |s: &str| format!("minimum-time stage {k}: {s}");
        check_dim(what("augmented state size"), ode.space().nx() + 1, space.nx())?;
        check_dim(what("cost control size nu"), nu, stage.cost.nu())?;
        check_dim(what("cost state size nx"), ode.space().nx(), stage.cost.nx())?;
        let phi = ExplicitRungeKutta::new(Arc::new(TimeScaledOde::new(ode.clone())), 1.0, self.method)?;
        let dynamics = Dynamics::Explicit(Arc::new(MinTimeDynamics {
            phi,
            space: space.clone(),
        }));
        let cost = Arc::new(TimeWeightedCost {
            cost: stage.cost.clone(),
            r_min_time: self.r_min_time,
        });
        let mut model = StageModel::new(cost, dynamics)?;
        for c in &stage.constraints {
            model.add_constraint(lift(c, 1))?;
        }
        let step = |minus_delta| {
            Arc::new(StepResidual {
                nx: space.nx(),
                ndx: space.ndx(),
                nu: nu + 1,
                minus_delta,
            })
        };
        let bounds = BoxConstraint::new(&[self.h_min.sqrt()], &[self.h_max.sqrt()])?;
        model.add_constraint(StageConstraint::new("time_step", step(false), Arc::new(bounds)))?;
        if k > 0 {
            model.add_constraint(StageConstraint::new(
                "equal_time_steps",
                step(true),
                Arc::new(EqualityConstraintSet),
            ))?;
        }
        Ok(model)
    }

    /// The minimum-time problem from `x0` through `stages` (one per step), with the
    /// terminal cost and constraints of the original problem on `x_N`. The augmented
    /// initial state is `(x0, 0)` (`δ_0` enters no constraint).
    ///
    /// # Errors
    /// If the sizes disagree (messages name the stage), or `stages` is empty.
    pub fn problem(
        &self,
        x0: &[f64],
        stages: &[ContinuousStage],
        terminal_cost: Arc<dyn Cost>,
        terminal_constraints: &[StageConstraint],
    ) -> Result<Problem> {
        let first = stages
            .first()
            .ok_or_else(|| Error::InvalidModel("a minimum-time problem needs at least one stage".into()))?;
        let space = Self::augmented_space(first.ode.space());
        let models = stages
            .iter()
            .enumerate()
            .map(|(k, s)| self.stage(s, k, &space))
            .collect::<Result<Vec<_>>>()?;
        let x0: Vec<f64> = x0.iter().copied().chain([0.0]).collect();
        let mut problem = Problem::new(&x0, models, Arc::new(LiftedTerminalCost(terminal_cost)))?;
        for c in terminal_constraints {
            problem.add_terminal_constraint(lift(c, 0))?;
        }
        Ok(problem)
    }

    /// The augmented controls `(u_k, √h)` of controls `us` with the constant step `h`.
    pub fn controls(us: &[Vec<f64>], h: f64) -> Vec<Vec<f64>> {
        us.iter()
            .map(|u| u.iter().copied().chain([h.sqrt()]).collect())
            .collect()
    }

    /// The steps `h_k = τ_k²` of augmented controls.
    pub fn steps(us: &[Vec<f64>]) -> Vec<f64> {
        us.iter().map(|u| u.last().map_or(f64::NAN, |t| t * t)).collect()
    }

    /// The total time `Σ h_k` of augmented controls.
    pub fn total_time(us: &[Vec<f64>]) -> f64 {
        Self::steps(us).iter().sum()
    }
}

/// The constraint `c` on the augmented stage (`extra_u` controls after `u`).
fn lift(c: &StageConstraint, extra_u: usize) -> StageConstraint {
    let f = Arc::new(Lifted {
        f: c.func.clone(),
        extra_u,
    });
    StageConstraint::new(c.name.clone(), f, c.set.clone()).with_scale(c.scale)
}

#[cfg(test)]
mod tests;

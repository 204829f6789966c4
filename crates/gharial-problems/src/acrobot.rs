//! `acrobot` and `acrobot-bounds`: swing-up of a double pendulum actuated at the
//! elbow only (ProxDDP paper, Figs. 6 and 7).
//!
//! # Model
//! The two links of `double_pendulum_continuous.urdf` (example-robot-data), both joints
//! rotating about the x axis, `θ = 0` upright, gravity `g = 9.81` along `-z`. Only the
//! y-z components of the URDF's offsets matter for this planar motion:
//!
//! | | mass (kg) | centre of mass (y, z) in the link frame (m) | inertia about x at the CoM (kg m²) |
//! |---|---|---|---|
//! | link 1 | 0.26703 | (2.1727e-6, 0.036012) | 4.0827e-4 |
//! | link 2 | 0.33238 | (1.9371e-10, 0.10088) | 1.1753e-3 |
//!
//! The elbow sits at `j = (0, 0.1)` in the frame of link 1; joint damping is ignored
//! (as in rigid-body forward dynamics). With `φ₁ = θ₁`, `φ₂ = θ₁ + θ₂`, `R(φ)` the
//! rotation of the y-z plane, `k(θ₂) = jᵀ R(θ₂) c₂`, `h = dk/dθ₂`:
//! ```text
//! M(θ₂) = [m₁|c₁|² + I₁ + m₂(|j|² + |c₂|² + 2k) + I₂,   m₂(|c₂|² + k) + I₂;
//!          m₂(|c₂|² + k) + I₂,                          m₂|c₂|² + I₂]
//! C = (m₂ h (2 θ̇₁ θ̇₂ + θ̇₂²), -m₂ h θ̇₁²),   G = ∂V/∂θ,  V = g (m₁ z₁ + m₂ z₂)
//! M θ̈ = (0, τ) - C - G
//! ```
//! State `x = ((cos θ₁, sin θ₁), (cos θ₂, sin θ₂), θ̇₁, θ̇₂) ∈ SO(2)² × R²`, control the
//! elbow torque `τ`. Second-order Runge-Kutta (explicit midpoint), `dt = 5 ms`, N = 200
//! (T = 1 s).
//!
//! # Problems
//! ```text
//! ℓ(x, u) = ½ dt (1e-4 |x ⊖ x*|² + 1e-2 τ²),   x* = ((1, 0), (1, 0), 0, 0)
//! acrobot:         ℓ_N = 0,                  x_N = x*            (Fig. 6)
//! acrobot-bounds:  ℓ_N = ½ 10 |x_N ⊖ x*|²,   |τ| ≤ 0.6            (Fig. 7)
//! ```
//! `x0 = ((-1, 0), (1, 0), 0, 0)` (hanging). Initial guess `τ = 0` and its rollout.
//! Settings: dynamics AL scale `1e-3` (the paper's, and the solver's default), nonlinear
//! rollout (the linear rollout does not converge in 300 iterations on either problem,
//! measured), `mu_init = 1e-3` for
//! `acrobot` (paper) and `1e-1` for `acrobot-bounds`. The torque limit 0.6 N·m is just
//! below the largest torque of the unconstrained optimum (0.615 N·m).
//!
//! `acrobot-bounds` uses aligator's step acceptance, the nonmonotone Armijo line search
//! on the primal augmented Lagrangian (35), and at most 600 iterations: the Newton steps
//! push the torques far past the limits (the semi-smooth Newton model sees only the
//! limits active at the current point), and the monotone rules crawl at step lengths
//! of 1e-3 to 1e-1 until the limits settle. Measured, nonlinear rollout: 118 iterations
//! from `mu_init = 1e-1` and 297 from the paper's `1e-3` (with the default filter on the
//! primal-dual merit: 176 and 407).
//!
//! # Jacobians
//! Hand-written: with `a = M⁻¹ b`, `b = (0, τ) - C - G`,
//! `da/dz = M⁻¹ (db/dz - (dM/dz) a)`; checked against the generic model with dual
//! numbers and against finite differences in the tests.

use std::sync::Arc;

use gharial::Result;
use gharial::autodiff::{AutoOdeFn, ManifoldScalar};
use gharial::costs::{ConstantCost, CostStack, QuadraticControlCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, ExplicitRungeKutta, Ode, OdeData};
use gharial::problem::{Problem, StageModel};
use gharial::solvers::proxddp::{Merit, ProxDdpOptions, Rollout, StepAcceptance};
use gharial::spaces::{CartesianProduct, Manifold, SO2, VectorSpace};

use crate::lqr::{control_box, terminal_state};
use crate::{Example, rollout, solve2};

/// Time step (s).
pub const DT: f64 = 0.005;
/// Horizon (T = 1 s).
pub const HORIZON: usize = 200;
/// Torque limit of `acrobot-bounds` (N·m).
pub const TAU_MAX: f64 = 0.6;

/// The two problems.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AcrobotVariant {
    /// Terminal state constraint, no terminal cost (Fig. 6).
    TerminalConstraint,
    /// Torque limits and a quadratic terminal cost (Fig. 7).
    Bounds,
}

/// `SO(2) × SO(2) × R²`.
pub fn space() -> Arc<dyn Manifold> {
    Arc::new(CartesianProduct::new(vec![
        Arc::new(SO2::new()),
        Arc::new(SO2::new()),
        Arc::new(VectorSpace::new(2)),
    ]))
}

/// The acrobot ODE of the module documentation.
#[derive(Debug, Clone)]
pub struct AcrobotOde {
    space: Arc<dyn Manifold>,
    m1: f64,
    m2: f64,
    /// Centres of mass `(y, z)` of the links in their frames.
    c1: [f64; 2],
    c2: [f64; 2],
    /// Elbow position in the frame of link 1.
    j2: [f64; 2],
    i1: f64,
    i2: f64,
    gravity: f64,
}

/// `R(φ) p` in the y-z plane, with `(cos φ, sin φ) = (c, s)`.
fn rot<D: ManifoldScalar>(c: D, s: D, p: [f64; 2]) -> [D; 2] {
    [c * p[0] - s * p[1], s * p[0] + c * p[1]]
}

/// What the equations of motion need at a state.
struct Terms<D> {
    /// `M` as `(m11, m12, m22)`.
    m: [D; 3],
    /// `b = (0, τ) - C - G`.
    b: [D; 2],
    /// `k(θ₂)` and `h(θ₂) = dk/dθ₂`.
    k: D,
    h: D,
    /// `z` coordinates of `R(φ₁) c₁`, `R(φ₁) j`, `R(φ₂) c₂` (for `dG/dθ`).
    z1: D,
    zj: D,
    z2: D,
}

impl AcrobotOde {
    /// The acrobot of the module documentation.
    pub fn new() -> Self {
        Self {
            space: space(),
            m1: 0.26703,
            m2: 0.33238,
            c1: [2.1727e-6, 0.036012],
            c2: [1.9371e-10, 0.10088],
            j2: [0.0, 0.1],
            i1: 4.0827e-4,
            i2: 1.1753e-3,
            gravity: 9.81,
        }
    }

    fn terms<D: ManifoldScalar>(&self, x: &[D], tau: D) -> Terms<D> {
        let (c1, s1, c2, s2, w1, w2) = (x[0], x[1], x[2], x[3], x[4], x[5]);
        let (m1, m2, g) = (self.m1, self.m2, self.gravity);
        let sq = |p: [f64; 2]| p[0] * p[0] + p[1] * p[1];
        // k = jᵀ R(θ₂) c₂ and h = jᵀ R(θ₂) perp(c₂), perp(p) = (-p_z, p_y).
        let rc2 = rot(c2, s2, self.c2);
        let k = rc2[0] * self.j2[0] + rc2[1] * self.j2[1];
        let rp2 = rot(c2, s2, [-self.c2[1], self.c2[0]]);
        let h = rp2[0] * self.j2[0] + rp2[1] * self.j2[1];
        let m22 = m2 * sq(self.c2) + self.i2;
        let m12 = k * m2 + m22;
        let m11 = k * (2.0 * m2) + (m1 * sq(self.c1) + self.i1 + m2 * sq(self.j2) + m22);
        // cos, sin of φ₂ = θ₁ + θ₂.
        let (cp, sp) = (c1 * c2 - s1 * s2, s1 * c2 + c1 * s2);
        // ∂z(R(φ) p)/∂φ = p_y cos φ - p_z sin φ.
        let dz = |c: D, s: D, p: [f64; 2]| c * p[0] - s * p[1];
        let g2 = dz(cp, sp, self.c2) * (g * m2);
        let g1 = (dz(c1, s1, self.c1) * m1 + dz(c1, s1, self.j2) * m2) * g + g2;
        let cor1 = h * m2 * (w1 * w2 * 2.0 + w2 * w2);
        let cor2 = -(h * m2 * w1 * w1);
        Terms {
            m: [m11, m12, D::from(m22)],
            b: [-cor1 - g1, tau - cor2 - g2],
            k,
            h,
            z1: rot(c1, s1, self.c1)[1],
            zj: rot(c1, s1, self.j2)[1],
            z2: rot(cp, sp, self.c2)[1],
        }
    }
}

impl Default for AcrobotOde {
    fn default() -> Self {
        Self::new()
    }
}

impl AutoOdeFn for AcrobotOde {
    fn nx(&self) -> usize {
        6
    }
    fn nu(&self) -> usize {
        1
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], xdot: &mut [D]) {
        let t = self.terms(x, u[0]);
        let a = solve2(&t.m, &t.b);
        xdot[0] = x[4];
        xdot[1] = x[5];
        xdot[2] = a[0];
        xdot[3] = a[1];
    }
}

impl Ode for AcrobotOde {
    fn space(&self) -> &Arc<dyn Manifold> {
        &self.space
    }
    fn nu(&self) -> usize {
        1
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        self.eval(x, u, data.xdot_mut());
    }
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        let t = self.terms(x, u[0]);
        let a = solve2(&t.m, &t.b);
        let (m2, g) = (self.m2, self.gravity);
        let (w1, w2) = (x[4], x[5]);
        // dG/dθ: ∂²z(R(φ) p)/∂φ² = -z(R(φ) p).
        let dg2 = -g * m2 * t.z2;
        let dg1_dt1 = -g * (self.m1 * t.z1 + m2 * t.zj) + dg2;
        // dh/dθ₂ = -k.
        let dcor1_dt2 = -m2 * t.k * (2.0 * w1 * w2 + w2 * w2);
        let dcor2_dt2 = m2 * t.k * w1 * w1;
        // dM/dθ₂ = [2 m₂ h, m₂ h; m₂ h, 0].
        let (dm11, dm12) = (2.0 * m2 * t.h, m2 * t.h);
        let db_dt1 = [-dg1_dt1, -dg2];
        let db_dt2 = [
            -dcor1_dt2 - dg2 - (dm11 * a[0] + dm12 * a[1]),
            -dcor2_dt2 - dg2 - dm12 * a[0],
        ];
        let db_dw1 = [-2.0 * m2 * t.h * w2, 2.0 * m2 * t.h * w1];
        let db_dw2 = [-2.0 * m2 * t.h * (w1 + w2), 0.0];
        let cols = [
            solve2(&t.m, &db_dt1),
            solve2(&t.m, &db_dt2),
            solve2(&t.m, &db_dw1),
            solve2(&t.m, &db_dw2),
        ];
        let da_du = solve2(&t.m, &[0.0, 1.0]);
        data.jx.fill(0.0);
        data.jx[(0, 2)] = 1.0;
        data.jx[(1, 3)] = 1.0;
        for (j, col) in cols.iter().enumerate() {
            data.jx[(2, j)] = col[0];
            data.jx[(3, j)] = col[1];
        }
        data.ju[(0, 0)] = 0.0;
        data.ju[(1, 0)] = 0.0;
        data.ju[(2, 0)] = da_du[0];
        data.ju[(3, 0)] = da_du[1];
    }
}

/// Builds `acrobot` or `acrobot-bounds` (module documentation).
///
/// # Errors
/// Never for these fixed numbers.
pub fn build(variant: AcrobotVariant) -> Result<Example> {
    let space = space();
    let nu = 1;
    let ode = Arc::new(AcrobotOde::new());
    let dynamics = Dynamics::Explicit(Arc::new(ExplicitRungeKutta::rk2(ode, DT)?));
    let target = [1.0, 0.0, 1.0, 0.0, 0.0, 0.0];
    let cost = CostStack::new(space.as_ref(), nu)
        .with(
            "x_reg",
            Arc::new(QuadraticStateCost::diagonal(
                space.clone(),
                &target,
                &[1e-4 * DT; 4],
                nu,
            )?),
            1.0,
        )?
        .with(
            "u_reg",
            Arc::new(QuadraticControlCost::diagonal(space.as_ref(), &[0.0], &[1e-2 * DT])?),
            1.0,
        )?;
    let mut stage = StageModel::new(Arc::new(cost), dynamics)?;
    let x0 = [-1.0, 0.0, 1.0, 0.0, 0.0, 0.0];
    let (name, description, problem) = match variant {
        AcrobotVariant::TerminalConstraint => {
            let term_cost = Arc::new(ConstantCost::zero(space.as_ref(), 0));
            let problem = Problem::new(&x0, vec![stage; HORIZON], term_cost)?
                .with_terminal_constraint(terminal_state(space.clone(), &target)?)?;
            (
                "acrobot",
                "Acrobot swing-up on SO(2)^2 x R^2 (ProxDDP paper Fig. 6): RK2, dt = 5 ms, N = 200, \
                 terminal constraint x_N = ((1,0),(1,0),0,0).",
                problem,
            )
        }
        AcrobotVariant::Bounds => {
            stage.add_constraint(control_box(space.as_ref(), nu, TAU_MAX, 1.0)?)?;
            let term_cost = Arc::new(QuadraticStateCost::diagonal(space.clone(), &target, &[10.0; 4], 0)?);
            let problem = Problem::new(&x0, vec![stage; HORIZON], term_cost)?;
            (
                "acrobot-bounds",
                "Acrobot swing-up (ProxDDP paper Fig. 7): RK2, dt = 5 ms, N = 200, |tau| <= 0.6, \
                 quadratic terminal cost 10 |x_N - x*|^2 / 2 instead of the terminal constraint.",
                problem,
            )
        }
    };
    let us0 = vec![vec![0.0]; HORIZON];
    let xs0 = rollout(&problem, &us0)?;
    Ok(Example {
        name,
        problem,
        xs0,
        us0,
        dt: Some(DT),
        proxddp: (if variant == AcrobotVariant::Bounds {
            ProxDdpOptions::default().with(|o| {
                o.mu_init = 1e-1;
                o.step_acceptance = StepAcceptance::NonmonotoneLinesearch;
                o.merit = Merit::Primal;
                o.max_iters = 600;
            })
        } else {
            ProxDdpOptions::default().with(|o| {
                o.mu_init = 1e-3;
                o.max_iters = 300;
            })
        })
        .with(|o| {
            o.rollout = Rollout::Nonlinear;
        }),
        description,
    })
}

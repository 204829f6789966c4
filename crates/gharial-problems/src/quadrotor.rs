//! `quadrotor` and `quadrotor-slalom`: a rigid body on SE(3) lifted by four rotors
//! (ProxDDP paper, Figs. 10 and 11; the Hector quadrotor).
//!
//! # Model
//! Mass and inertia of the Hector quadrotor base (`quadrotor_base.urdf`,
//! example-robot-data): `m = 1.477 kg`, `I = diag(0.01152, 0.01152, 0.0218) kg m²`,
//! centre of mass at the base origin. State
//! `x = (p, q, v, ω) ∈ SE(3) × R⁶`: the pose (translation, unit quaternion `(x, y, z, w)`)
//! and the body-frame twist (linear, angular), which is the pose's tangent vector in
//! the local convention of [`SE3`]. Controls: the four rotor thrusts `u` (N), mapped to
//! a body wrench by the rotor geometry (arm `d = 0.1525 m`, moment-to-thrust ratio
//! `κ = c_m / c_f = 1e-6 / 6.6e-5`):
//! ```text
//! f = (0, 0, u₀ + u₁ + u₂ + u₃),
//! τ = (d (u₁ - u₃), d (u₂ - u₀), κ (-u₀ + u₁ - u₂ + u₃))
//! ẋ = (v, ω, f/m + Rᵀ g - ω × v, I⁻¹ (τ - ω × I ω)),   g = (0, 0, -9.81)
//! ```
//! (the Newton-Euler equations of a free body in its own frame). Explicit Euler,
//! `dt = 0.033 s`, N = 60 (T ≈ 2 s). Jacobians by forward-mode dual numbers
//! ([`AutoDiff`]): 16 passes of a model of ~100 flops on SE(3); a hand-written version
//! would mostly repeat the chain rule through the quaternion that the dual numbers
//! already do exactly.
//!
//! # `quadrotor` (thrust limits, Fig. 10)
//! Two waypoints: `p₁ = (0.9, 0.8, 1.0)` until stage `k = ⌊0.7 N⌋ = 42`, then
//! `p₂ = (1.4, -0.6, 1.0)` (identity attitude, zero twist):
//! ```text
//! ℓ_t = ½ dt |x ⊖ x*_t|²_W + ½ dt 1e-2 |u|²,
//! W = diag(4 (position), 1e-2 (attitude), 1e-3 (twist))  for t < k,
//! stage k: W / dt (a waypoint),   t > k: position weight 1
//! ℓ_N = ½ |x ⊖ x*₂|²_W₂,   -4.5 ≤ u_i ≤ 4.5  (AL scale 10)
//! ```
//! No terminal constraint (the paper mentions none for this variant; with
//! `x_N = x*₂` added, ProxDDP stalled with a primal residual of 0.03-0.1, measured).
//! `x0 = (0, 0, 0.2)`, identity attitude, at rest. Initial guess: hover thrust
//! `u_i = m g / 4` and its rollout (the quadrotor hovers at `x0`). Settings:
//! the paper's, `mu_init = 0.1` and nonlinear rollout (46 iterations; linear rollout: 45).
//!
//! # `quadrotor-slalom` (obstacles, Fig. 11)
//! Target `p₃ = (-0.3, 2.5, 1.0)` with `W = diag(1, 1e-2, 1e-3)` at every stage, the same
//! terminal cost towards it, the terminal constraint `x_N = x*₃`, and no thrust limits
//! (as in the paper).
//! Two infinite vertical cylinders of radius 0.2 m at `(-0.5, 0.8)` and `(0.3, 2.1)`;
//! the quadrotor is a sphere of radius `0.35 m` (our bounding sphere of the Hector's
//! frame and rotors), so the smooth inequality for each cylinder is
//! ```text
//! (0.2 + 0.35)² - |p_xy - c|² ≤ 0      (AL scale 0.1)
//! ```
//! plus the floor and ceiling `0 ≤ p_z ≤ 2`. Settings: the paper's, linear rollout and
//! `mu_init = 1` (103 iterations; the nonlinear rollout converges too, in 91).

use std::sync::Arc;

use gharial::Result;
use gharial::autodiff::{AutoDiff, AutoOdeFn, AutoUnaryFn, ManifoldScalar};
use gharial::constraints::NegativeOrthant;
use gharial::costs::{CostStack, QuadraticControlCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, ExplicitRungeKutta};
use gharial::functions::Unary;
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::solvers::proxddp::{ProxDdpOptions, Rollout};
use gharial::spaces::{CartesianProduct, Manifold, SE3, VectorSpace};

use crate::lqr::{control_box, terminal_state};
use crate::robots::HECTOR_URDF;
use crate::{Example, rollout};

/// Time step (s).
pub const DT: f64 = 0.033;
/// Horizon (`⌊2 / 0.033⌋`).
pub const HORIZON: usize = 60;
/// Thrust limit of `quadrotor` (N per rotor).
pub const THRUST_MAX: f64 = 4.5;
/// Radius of the sphere bounding the quadrotor (m).
pub const QUAD_RADIUS: f64 = 0.35;
/// Radius of the cylinders (m).
pub const CYLINDER_RADIUS: f64 = 0.2;
/// Centres `(x, y)` of the cylinders.
pub const CYLINDERS: [[f64; 2]; 2] = [[-0.5, 0.8], [0.3, 2.1]];

/// The two problems.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum QuadrotorVariant {
    /// Two waypoints with thrust limits (Fig. 10).
    ThrustLimits,
    /// Between two cylinders, linear rollout (Fig. 11).
    Slalom,
}

/// `SE(3) × R⁶`.
pub fn space() -> Arc<dyn Manifold> {
    Arc::new(CartesianProduct::pair(
        Arc::new(SE3::new()),
        Arc::new(VectorSpace::new(6)),
    ))
}

/// The quadrotor ODE of the module documentation.
#[derive(Debug, Clone, Copy)]
pub struct QuadrotorOde {
    /// Mass (kg).
    pub mass: f64,
    /// Principal moments of inertia (kg m²).
    pub inertia: [f64; 3],
    /// Rotor arm (m).
    pub arm: f64,
    /// Yaw moment per unit thrust (m).
    pub yaw_ratio: f64,
    /// Gravity (m/s²).
    pub gravity: f64,
}

impl QuadrotorOde {
    /// The Hector quadrotor: mass and inertia of the base link of its URDF, the rotor
    /// geometry of the module documentation.
    ///
    /// # Errors
    /// If the URDF's base inertia is not at the base origin or not diagonal (the ODE
    /// assumes both).
    pub fn hector() -> Result<Self> {
        let model = gharial_multibody::Model::from_urdf_str(HECTOR_URDF, gharial_multibody::RootJoint::FreeFlyer)
            .map_err(|e| gharial::Error::InvalidModel(format!("Hector quadrotor URDF: {e}")))?;
        let body = model.inertias()[1];
        let i = &body.rotational;
        let off_diagonal = [i[(0, 1)], i[(0, 2)], i[(1, 2)]];
        if body.first_moment.norm() != 0.0 || off_diagonal.iter().any(|v| *v != 0.0) {
            return Err(gharial::Error::InvalidModel(
                "Hector quadrotor URDF: the base inertia must be diagonal about the base origin".into(),
            ));
        }
        Ok(Self {
            mass: body.mass,
            inertia: [i[(0, 0)], i[(1, 1)], i[(2, 2)]],
            arm: 0.1525,
            yaw_ratio: 1e-6 / 6.6e-5,
            gravity: 9.81,
        })
    }
}

impl QuadrotorOde {
    /// The rotor thrust that hovers (`m g / 4`).
    pub fn hover_thrust(&self) -> f64 {
        self.mass * self.gravity / 4.0
    }
}

impl AutoOdeFn for QuadrotorOde {
    fn nx(&self) -> usize {
        13
    }
    fn nu(&self) -> usize {
        4
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], xdot: &mut [D]) {
        let (qx, qy, qz, qw) = (x[3], x[4], x[5], x[6]);
        let v = [x[7], x[8], x[9]];
        let w = [x[10], x[11], x[12]];
        // Rᵀ e_z: the third row of the rotation matrix.
        let rz = [
            (qx * qz - qw * qy) * 2.0,
            (qy * qz + qw * qx) * 2.0,
            -(qx * qx + qy * qy) * 2.0 + 1.0,
        ];
        let thrust = u[0] + u[1] + u[2] + u[3];
        let tau = [
            (u[1] - u[3]) * self.arm,
            (u[2] - u[0]) * self.arm,
            (-u[0] + u[1] - u[2] + u[3]) * self.yaw_ratio,
        ];
        let cross = |a: [D; 3], b: [D; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let wv = cross(w, v);
        let iw = [w[0] * self.inertia[0], w[1] * self.inertia[1], w[2] * self.inertia[2]];
        let wiw = cross(w, iw);
        for i in 0..3 {
            xdot[i] = v[i];
            xdot[3 + i] = w[i];
            xdot[6 + i] = rz[i] * (-self.gravity) - wv[i];
            xdot[9 + i] = (tau[i] - wiw[i]) * (1.0 / self.inertia[i]);
        }
        xdot[8] += thrust * (1.0 / self.mass);
    }
}

/// `(r + R)² - |p_xy - c|² ≤ 0`: the sphere of radius `R` around the quadrotor's
/// position stays out of the vertical cylinder of radius `r` and axis through `c`.
#[derive(Debug, Clone, Copy)]
pub struct CylinderClearance {
    /// Axis `(x, y)`.
    pub center: [f64; 2],
    /// `r + R`.
    pub distance: f64,
}

impl AutoUnaryFn for CylinderClearance {
    fn nx(&self) -> usize {
        13
    }
    fn nr(&self) -> usize {
        1
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], out: &mut [D]) {
        let dx = x[0] - self.center[0];
        let dy = x[1] - self.center[1];
        out[0] = -(dx * dx + dy * dy) + self.distance * self.distance;
    }
}

/// `(z - z_max, z_min - z) ≤ 0`.
#[derive(Debug, Clone, Copy)]
pub struct HeightBounds {
    /// Floor.
    pub z_min: f64,
    /// Ceiling.
    pub z_max: f64,
}

impl AutoUnaryFn for HeightBounds {
    fn nx(&self) -> usize {
        13
    }
    fn nr(&self) -> usize {
        2
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], out: &mut [D]) {
        out[0] = x[2] - self.z_max;
        out[1] = -x[2] + self.z_min;
    }
}

/// The state at position `p`, identity attitude, at rest.
pub fn at(p: [f64; 3]) -> Vec<f64> {
    let mut x = vec![0.0; 13];
    x[..3].copy_from_slice(&p);
    x[6] = 1.0;
    x
}

/// Weights `(position, attitude, twist)` of the state cost.
fn weights(position: f64) -> Vec<f64> {
    let mut w = vec![1e-3; 12];
    w[..3].fill(position);
    w[3..6].fill(1e-2);
    w
}

/// Builds `quadrotor` or `quadrotor-slalom` (module documentation).
///
/// # Errors
/// Never for these fixed numbers.
pub fn build(variant: QuadrotorVariant) -> Result<Example> {
    let ode = QuadrotorOde::hector()?;
    let hover = ode.hover_thrust();
    let stages = Stages::new(ode)?;
    let v = match variant {
        QuadrotorVariant::ThrustLimits => waypoints(&stages)?,
        QuadrotorVariant::Slalom => slalom(&stages)?,
    };
    let x0 = at([0.0, 0.0, 0.2]);
    let term_cost = Arc::new(QuadraticStateCost::diagonal(
        stages.space.clone(),
        &v.target,
        &v.w_term,
        0,
    )?);
    let mut problem = Problem::new(&x0, v.stages, term_cost)?;
    if variant == QuadrotorVariant::Slalom {
        problem.add_terminal_constraint(terminal_state(stages.space.clone(), &v.target)?)?;
    }
    let us0 = vec![vec![hover; NU]; HORIZON];
    let xs0 = rollout(&problem, &us0)?;
    Ok(Example {
        name: v.name,
        problem,
        xs0,
        us0,
        dt: Some(DT),
        proxddp: ProxDdpOptions::default().with(|o| {
            o.mu_init = v.mu_init;
            o.rollout = v.rollout;
            o.max_iters = 300;
        }),
        description: v.description,
    })
}

/// Thrust inputs.
const NU: usize = 4;

/// The pieces every stage of both variants shares: the space, the Euler step of the
/// Hector's dynamics and the control regularisation.
struct Stages {
    space: Arc<dyn Manifold>,
    dynamics: Dynamics,
    u_cost: Arc<QuadraticControlCost>,
}

impl Stages {
    fn new(ode: QuadrotorOde) -> Result<Self> {
        let space = space();
        let ode = Arc::new(AutoDiff::ode(space.clone(), ode)?);
        let dynamics = Dynamics::Explicit(Arc::new(ExplicitRungeKutta::euler(ode, DT)?));
        let u_cost = Arc::new(QuadraticControlCost::diagonal(
            space.as_ref(),
            &[0.0; NU],
            &[1e-2 * DT; NU],
        )?);
        Ok(Self {
            space,
            dynamics,
            u_cost,
        })
    }

    /// A stage regularised towards `target` with state weights `w`.
    fn towards(&self, target: &[f64], w: &[f64]) -> Result<StageModel> {
        let cost = CostStack::new(self.space.as_ref(), NU)
            .with(
                "x_reg",
                Arc::new(QuadraticStateCost::diagonal(self.space.clone(), target, w, NU)?),
                1.0,
            )?
            .with("u_reg", self.u_cost.clone(), 1.0)?;
        StageModel::new(Arc::new(cost), self.dynamics.clone())
    }
}

/// What distinguishes the two variants.
struct Variant {
    name: &'static str,
    description: &'static str,
    stages: Vec<StageModel>,
    /// Terminal target and weights.
    target: Vec<f64>,
    w_term: Vec<f64>,
    rollout: Rollout,
    mu_init: f64,
}

/// Fig. 10: two waypoints, the first weighted 4x until 70 % of the horizon, thrust limits.
fn waypoints(s: &Stages) -> Result<Variant> {
    let switch = (0.7 * HORIZON as f64) as usize;
    let (t1, t2) = (at([0.9, 0.8, 1.0]), at([1.4, -0.6, 1.0]));
    let (w1, w2) = (weights(4.0), weights(1.0));
    let mut stages = Vec::with_capacity(HORIZON);
    for t in 0..HORIZON {
        let (target, w): (&[f64], Vec<f64>) = if t < switch {
            (&t1, w1.iter().map(|v| v * DT).collect())
        } else if t == switch {
            (&t1, w1.clone())
        } else {
            (&t2, w2.iter().map(|v| v * DT).collect())
        };
        let stage = s
            .towards(target, &w)?
            .with_constraint(control_box(s.space.as_ref(), NU, THRUST_MAX, 10.0)?)?;
        stages.push(stage);
    }
    Ok(Variant {
        name: "quadrotor",
        description: "Quadrotor on SE(3) x R^6 (ProxDDP paper Fig. 10): two waypoints, thrust limits |u_i| <= 4.5 \
                      (AL scale 10); Euler, dt = 0.033, N = 60.",
        stages,
        target: t2,
        w_term: w2,
        rollout: Rollout::Nonlinear,
        mu_init: 0.1,
    })
}

/// Fig. 11: between two cylinders to a goal, under a ceiling and above the floor.
fn slalom(s: &Stages) -> Result<Variant> {
    let t3 = at([-0.3, 2.5, 1.0]);
    let w = weights(1.0);
    let wdt: Vec<f64> = w.iter().map(|v| v * DT).collect();
    let height = Arc::new(Unary::new(
        Arc::new(AutoDiff::unary(
            s.space.clone(),
            HeightBounds { z_min: 0.0, z_max: 2.0 },
        )?),
        NU,
    ));
    let cylinders = CYLINDERS
        .iter()
        .map(|c| {
            let clearance = CylinderClearance {
                center: *c,
                distance: CYLINDER_RADIUS + QUAD_RADIUS,
            };
            Ok(Arc::new(Unary::new(
                Arc::new(AutoDiff::unary(s.space.clone(), clearance)?),
                NU,
            )))
        })
        .collect::<Result<Vec<_>>>()?;
    let mut stages = Vec::with_capacity(HORIZON);
    for _ in 0..HORIZON {
        let mut stage = s.towards(&t3, &wdt)?;
        stage.add_constraint(StageConstraint::new(
            "height",
            height.clone(),
            Arc::new(NegativeOrthant),
        ))?;
        for (i, c) in cylinders.iter().enumerate() {
            stage.add_constraint(
                StageConstraint::new(format!("cylinder_{i}"), c.clone(), Arc::new(NegativeOrthant)).with_scale(0.1),
            )?;
        }
        stages.push(stage);
    }
    Ok(Variant {
        name: "quadrotor-slalom",
        description: "Quadrotor on SE(3) x R^6 slaloming between two cylinders (ProxDDP paper Fig. 11): sphere / \
                      cylinder clearance inequalities (AL scale 0.1), floor and ceiling, terminal state constraint; \
                      Euler, dt = 0.033, N = 60, linear rollout.",
        stages,
        target: t3,
        w_term: w,
        rollout: Rollout::Linear,
        mu_init: 1.0,
    })
}

//! Solo-12 standing on its four feet and shifting its base sideways, with strongly
//! active friction cones of a small friction coefficient: a small problem whose cones
//! bind at most stages from the first iterate on.
//!
//! **Model** (every stage): the Solo-12 of [`crate::solo_walk`] in the standing state
//! `x0` on the ground, rigid 3D point contacts at the four feet (LOCAL_WORLD_ALIGNED,
//! `Kp = 0`, `Kd = 1/Δt` = 50) solved exactly ([`MultibodyConstraintFwdDynamics`]),
//! semi-implicit Euler with `Δt` = [`DT`], [`HORIZON`] stages.
//!
//! **Cost**: `½ w_x ‖x ⊖ x*‖² Δt + ½ w_u ‖u − u_g‖² Δt` per stage and `½ w_x ‖x ⊖ x*‖²`
//! at the end, with `w_x = 1`, `w_u = 1e-3`, `u_g` the actuated part of the generalised
//! gravity at `x0`, and `x*` = `x0` with the base moved by `dy` along `y`.
//!
//! **Constraints**: on every stage the four friction cones `‖f_t‖ ≤ μ f_n`
//! ([`FrictionConeResidual`] with a [`SecondOrderCone`] each, one constraint per foot).
//!
//! **Guess**: `x0` at every node, `u_g` at every stage.
//!
//! **Results** (`dy` = 2 cm, `μ` = 0.1, `tests/solo_stance.rs`): the cones bind at every
//! stage; CSQP with QP tolerances 1e-8 converges (tolerance 1e-6) in 2 iterations to the
//! cost 4.4380612e-4, ProxDDP with `active_set_iters = 1` to the same cost (2e-8
//! relative). Without the cones the optimum costs 3.981e-4 and its forces leave the
//! cones by up to 1.46 N. ProxDDP's defaults (no active-set prediction) do not converge
//! in 200 iterations: the Newton step ignores the cones that are inactive at the current
//! point, and its full step leaves them far (the cones are narrow, `μ f_n ≈ 0.6` N),
//! so that the merit function accepts only steps of length 1e-3 to 1e-2. CSQP with its
//! default QP tolerances (1e-4, absolute) stops at a cost 6 % higher.

use std::sync::Arc;

use gharial::constraints::SecondOrderCone;
use gharial::costs::{CostStack, QuadraticControlCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, SemiImplicitEuler};
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::spaces::Manifold;
use gharial::{Error, Result};
use gharial_multibody::generalized_gravity;
use gharial_robotics::MultibodyConstraintFwdDynamics;
use gharial_robotics::residuals::{FrictionCone, FrictionConeResidual};

use crate::solo_walk::{Phase, Solo};

/// Time step (s).
pub const DT: f64 = 0.02;
/// Number of running stages.
pub const HORIZON: usize = 10;
/// Weight of the state cost.
pub const W_STATE: f64 = 1.0;
/// Weight of the control cost.
pub const W_CONTROL: f64 = 1e-3;

/// The problem with the models it is built from.
pub struct StanceSetup {
    /// The optimal control problem.
    pub problem: Problem,
    /// The standing state `x0 = (q0, 0)`.
    pub x0: Vec<f64>,
    /// The actuated part of the generalised gravity at `q0` (control reference, guess).
    pub u_grav: Vec<f64>,
    /// The four-feet contact dynamics of every stage.
    pub dynamics: Arc<MultibodyConstraintFwdDynamics>,
}

impl std::fmt::Debug for StanceSetup {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StanceSetup")
            .field("horizon", &self.problem.horizon())
            .finish_non_exhaustive()
    }
}

/// The problem (module documentation) with the base target moved by `dy` (m) and the
/// friction coefficient `mu` (no cones if `None`).
///
/// # Errors
/// If `dy` is not finite or `mu` is not positive and finite.
pub fn setup(dy: f64, mu: Option<f64>) -> Result<StanceSetup> {
    if !dy.is_finite() {
        return Err(Error::option("solo_stance: dy", format!("must be finite, got {dy}")));
    }
    let solo = Solo::load()?;
    let (nq, nv) = (solo.model.nq(), solo.model.nv());
    let dynamics = solo.contact_dynamics(Phase::FourFeet, DT)?;
    let mut data = solo.model.create_data();
    let u_grav = generalized_gravity(&solo.model, &mut data, &solo.x0[..nq])
        .map_err(|e| Error::InvalidModel(format!("solo_stance: generalised gravity: {e}")))?[6..]
        .to_vec();
    let nu = u_grav.len();
    let space: Arc<dyn Manifold> = solo.space.clone();
    let mut target = solo.x0.clone();
    target[1] += dy;
    let step = Dynamics::Explicit(Arc::new(SemiImplicitEuler::new(
        dynamics.clone(),
        solo.space.configuration().clone(),
        DT,
    )?));
    let wx = vec![W_STATE; 2 * nv];
    let state = Arc::new(QuadraticStateCost::diagonal(space.clone(), &target, &wx, nu)?);
    let control = Arc::new(QuadraticControlCost::diagonal(
        space.as_ref(),
        &u_grav,
        &vec![W_CONTROL; nu],
    )?);
    let cones = match mu {
        Some(m) => (0..4)
            .map(|k| {
                Ok(StageConstraint::new(
                    format!("friction cone {k}"),
                    Arc::new(FrictionConeResidual::new(
                        dynamics.clone(),
                        k,
                        FrictionCone::vertical(m)?,
                    )?),
                    Arc::new(SecondOrderCone::new(3)?),
                ))
            })
            .collect::<Result<Vec<_>>>()?,
        None => Vec::new(),
    };
    let mut stages = Vec::with_capacity(HORIZON);
    for _ in 0..HORIZON {
        let cost = CostStack::new(space.as_ref(), nu)
            .with("state", state.clone(), DT)?
            .with("control", control.clone(), DT)?;
        let mut stage = StageModel::new(Arc::new(cost), step.clone())?;
        for c in &cones {
            stage.add_constraint(c.clone())?;
        }
        stages.push(stage);
    }
    let terminal = Arc::new(QuadraticStateCost::diagonal(space, &target, &wx, 0)?);
    let problem = Problem::new(&solo.x0, stages, terminal)?;
    Ok(StanceSetup {
        problem,
        x0: solo.x0.clone(),
        u_grav,
        dynamics,
    })
}

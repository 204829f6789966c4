//! Frame velocity residuals: the spatial velocity of a frame, and the "fly-high"
//! penalty of swing feet.
//!
//! The q-derivatives come from `compute_forward_kinematics_derivatives` and
//! `frame_velocity_derivatives` of the multibody crate, exact in LOCAL and WORLD. In
//! LOCAL_WORLD_ALIGNED the linear part is the velocity of the frame's origin
//! `v_p = v_O + ω × p(q)`, and the multibody crate (as Pinocchio) differentiates it at a
//! fixed point `p`; the residual adds the missing `ω × ∂p/∂q`, where `∂p/∂q` is the
//! linear part of the LWA Jacobian (the v-derivative), so that its Jacobian is the
//! derivative of its value.
//!
//! The residuals of one stage on one model share their kinematic passes: their data,
//! created in the stage's scope (`gharial::functions::with_shared_data`), hold one
//! memoised pass per state instead of one each.

use std::sync::{Arc, Mutex};

use faer::MatMut;
use faer::reborrow::ReborrowMut;
use gharial::functions::{StageFunctionData, UnaryFunction, Workspace, lock, shared_data};
use gharial::linalg::slice_mut;
use gharial::{Error, Result};
use gharial_multibody::spatial::{Motion, Vec3};
use gharial_multibody::{
    Model, ReferenceFrame, compute_forward_kinematics_derivatives, forward_kinematics, frame_velocity,
    frame_velocity_derivatives,
};

use super::{FrameRef, MultibodyWs, StateLayout, VectorTarget, ok_or_nan_mat, ws};
use crate::MultibodyPhaseSpace;

/// The velocity-level kinematics (placements and velocities at zero acceleration, and
/// their derivatives) of one model at one state, shared by the velocity residuals of a
/// stage ([`shared_data`], keyed by the model): the swing feet's fly-high terms of a
/// stage need one pass, not one each. Memoised by the state.
struct VelocityKinematics {
    ws: MultibodyWs,
    /// The state the data hold passes at, and which passes.
    at: Vec<f64>,
    pass: Pass,
}

/// The kinematic passes the shared data hold at their state.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Pass {
    None,
    Forward,
    /// The derivative pass, which includes the forward pass.
    Derivatives,
}

impl VelocityKinematics {
    fn new(model: &Model, nx: usize) -> Self {
        Self {
            ws: MultibodyWs::new(model),
            at: vec![f64::NAN; nx],
            pass: Pass::None,
        }
    }

    /// Makes the data hold at least `pass` at `x`, running it unless they do.
    fn ensure(&mut self, model: &Model, layout: &StateLayout, x: &[f64], pass: Pass) -> gharial_multibody::Result<()> {
        if self.pass >= pass && self.at == x {
            return Ok(());
        }
        self.pass = Pass::None;
        let (w, (q, v)) = (&mut self.ws, (layout.q(x), layout.v(x)));
        match pass {
            Pass::Derivatives => compute_forward_kinematics_derivatives(model, &mut w.data, q, v, &w.zeros)?,
            _ => forward_kinematics(model, &mut w.data, q, v, &w.zeros)?,
        }
        self.at.copy_from_slice(x);
        self.pass = pass;
        Ok(())
    }
}

/// Scratch of [`FrameVelocityResidual`]: the stage's shared velocity kinematics.
struct VelocityWs {
    kin: Arc<Mutex<VelocityKinematics>>,
}

/// The velocity error `r = v_f(q, v) − v_ref` of a frame in LOCAL, WORLD or
/// LOCAL_WORLD_ALIGNED coordinates (ALIGATOR's `FrameVelocityResidual`), `nr = 6`,
/// `[linear, angular]`.
///
/// Jacobian `[∂v_f/∂q, J_f]` (`J_f` the frame Jacobian in the same coordinates).
#[derive(Debug)]
pub struct FrameVelocityResidual {
    model: Arc<Model>,
    layout: StateLayout,
    frame: FrameRef,
    reference_frame: ReferenceFrame,
    target: VectorTarget,
}

impl FrameVelocityResidual {
    /// The residual of frame `frame` in coordinates `reference_frame`, with target
    /// `v_ref` (6, `[linear, angular]`, in the same coordinates).
    ///
    /// # Errors
    /// If the frame is not in the model, or `v_ref` does not have 6 finite entries.
    pub fn new(
        space: &MultibodyPhaseSpace,
        frame: &str,
        reference_frame: ReferenceFrame,
        v_ref: &[f64],
    ) -> Result<Self> {
        Self::build("FrameVelocityResidual", space, frame, reference_frame, v_ref)
    }

    /// [`FrameVelocityResidual::new`] with errors naming `owner`.
    fn build(
        owner: &str,
        space: &MultibodyPhaseSpace,
        frame: &str,
        reference_frame: ReferenceFrame,
        v_ref: &[f64],
    ) -> Result<Self> {
        let model = space.model().clone();
        Ok(Self {
            frame: FrameRef::resolve(&model, owner, frame)?,
            target: VectorTarget::new("FrameVelocityResidual target v_ref", v_ref, 6)?,
            layout: StateLayout::of(space),
            reference_frame,
            model,
        })
    }

    /// Moves the target.
    ///
    /// # Errors
    /// If `v_ref` does not have 6 finite entries; the target is then unchanged.
    pub fn set_target(&self, v_ref: &[f64]) -> Result<()> {
        self.target.set(v_ref)
    }

    /// The current target.
    pub fn target(&self) -> Vec<f64> {
        self.target.get()
    }

    /// The coordinates of the velocity.
    pub fn reference_frame(&self) -> ReferenceFrame {
        self.reference_frame
    }

    /// The frame velocity after a kinematic pass with velocities.
    fn velocity(&self, w: &MultibodyWs) -> gharial_multibody::Result<Motion> {
        frame_velocity(&self.model, &w.data, self.frame.id, self.reference_frame)
    }

    /// Writes `[∂v_f/∂q, ∂v_f/∂v]` into `jx` (6 × 2nv) after the derivative pass.
    fn write_jacobian(&self, w: &MultibodyWs, jx: MatMut<'_, f64>) -> gharial_multibody::Result<()> {
        let (mut dq, mut dv) = jx.split_at_col_mut(self.layout.nv);
        frame_velocity_derivatives(
            &self.model,
            &w.data,
            self.frame.id,
            self.reference_frame,
            dq.rb_mut(),
            dv.rb_mut(),
        )?;
        if self.reference_frame == ReferenceFrame::LocalWorldAligned {
            let omega = self.velocity(w)?.angular;
            for &c in &self.frame.support {
                let dp = Vec3::new(dv[(0, c)], dv[(1, c)], dv[(2, c)]);
                let extra = omega.cross(&dp);
                for i in 0..3 {
                    dq[(i, c)] += extra[i];
                }
            }
        }
        Ok(())
    }
}

impl FrameVelocityResidual {
    /// The stage's shared velocity kinematics (a fresh one outside a stage's scope).
    fn kinematics(&self) -> Arc<Mutex<VelocityKinematics>> {
        let nx = self.layout.nx();
        shared_data(Arc::as_ptr(&self.model) as usize, || {
            VelocityKinematics::new(&self.model, nx)
        })
    }

    /// `v_f − v_ref` into `out` at `x`, NaN if the kinematic pass fails.
    fn write_value(&self, kin: &mut VelocityKinematics, x: &[f64], out: &mut [f64]) {
        let res = kin
            .ensure(&self.model, &self.layout, x, Pass::Forward)
            .and_then(|()| self.velocity(&kin.ws));
        match res {
            Ok(m) => {
                for (i, (o, vi)) in out.iter_mut().zip(m.to_array()).enumerate() {
                    *o = vi - self.target.at(i);
                }
            }
            Err(_) => out.fill(f64::NAN),
        }
    }
}

impl UnaryFunction for FrameVelocityResidual {
    unary_dims!(6);
    fn create_workspace(&self) -> Workspace {
        Box::new(VelocityWs { kin: self.kinematics() })
    }

    fn evaluate(&self, x: &[f64], data: &mut StageFunctionData) {
        let w: &mut VelocityWs = ws(&mut data.ws);
        let mut kin = lock(&w.kin);
        self.write_value(&mut kin, x, slice_mut(&mut data.value));
    }

    fn jacobian(&self, x: &[f64], data: &mut StageFunctionData) {
        let w: &mut VelocityWs = ws(&mut data.ws);
        let mut kin = lock(&w.kin);
        let res = kin
            .ensure(&self.model, &self.layout, x, Pass::Derivatives)
            .and_then(|()| self.write_jacobian(&kin.ws, data.jx.as_mut()));
        ok_or_nan_mat(res, data.jx.as_mut());
    }
}

/// The "fly-high" penalty of a swing foot: `r = v_xy(f) · exp(−slope · h(f))`
/// (ALIGATOR's `FlyHighResidual`, after sobec's), with `v_xy` the horizontal velocity of
/// the frame's origin `p = (x, y, z)` (the first two LOCAL_WORLD_ALIGNED linear
/// coordinates) and `h = z − (a + b x + c y)` its height above the ground plane
/// `(a, b, c)` (`z = 0` unless set: [`FlyHighResidual::set_ground`]); `nr = 2`.
/// Penalising it makes the foot move horizontally only high above the ground.
///
/// Jacobian: `e^{−s h} (∂v_xy/∂x − s v_xy ∂h/∂x)`, `∂h = ∂z − b ∂x − c ∂y`.
#[derive(Debug)]
pub struct FlyHighResidual {
    velocity: FrameVelocityResidual,
    slope: f64,
    ground: VectorTarget,
}

/// Scratch of [`FlyHighResidual`]: the data of its frame-velocity residual.
struct FlyHighWs {
    inner: StageFunctionData,
}

impl FlyHighResidual {
    /// The residual of frame `frame` with decay rate `slope` (1/m).
    ///
    /// # Errors
    /// If the frame is not in the model or `slope` is not finite.
    pub fn new(space: &MultibodyPhaseSpace, frame: &str, slope: f64) -> Result<Self> {
        if !slope.is_finite() {
            return Err(Error::non_finite("FlyHighResidual slope"));
        }
        let velocity = FrameVelocityResidual::build(
            "FlyHighResidual",
            space,
            frame,
            ReferenceFrame::LocalWorldAligned,
            &[0.0; 6],
        )?;
        let ground = VectorTarget::new("FlyHighResidual ground plane", &[0.0; 3], 3)?;
        Ok(Self {
            velocity,
            slope,
            ground,
        })
    }

    /// The decay rate.
    pub fn slope(&self) -> f64 {
        self.slope
    }

    /// Moves the ground plane `z = a + b x + c y`, given as `(a, b, c)`, above which the
    /// foot's height is measured (a swing foot over terrain that is not `z = 0`).
    ///
    /// # Errors
    /// If `plane` does not have 3 finite entries; the plane is then unchanged.
    pub fn set_ground(&self, plane: &[f64]) -> Result<()> {
        self.ground.set(plane)
    }

    /// The ground plane `(a, b, c)`.
    pub fn ground(&self) -> [f64; 3] {
        let g = self.ground.vec3();
        [g.x, g.y, g.z]
    }

    /// `(exp(−slope · h), v_LWA)` after a kinematic pass with velocities, `h` the height
    /// above the ground plane.
    fn factor_and_velocity(&self, inner: &mut StageFunctionData) -> gharial_multibody::Result<(f64, Motion)> {
        let w: &mut VelocityWs = ws(&mut inner.ws);
        let kin = lock(&w.kin);
        let p = self.velocity.frame.placement(&kin.ws.data).translation;
        let [a, b, c] = self.ground();
        let h = p.z - (a + b * p.x + c * p.y);
        Ok(((-self.slope * h).exp(), self.velocity.velocity(&kin.ws)?))
    }
}

impl UnaryFunction for FlyHighResidual {
    fn nx(&self) -> usize {
        self.velocity.nx()
    }
    fn ndx(&self) -> usize {
        self.velocity.ndx()
    }
    fn nr(&self) -> usize {
        2
    }
    fn create_workspace(&self) -> Workspace {
        Box::new(FlyHighWs {
            inner: StageFunctionData::new(self.velocity.ndx(), 0, 6, self.velocity.create_workspace()),
        })
    }

    fn evaluate(&self, x: &[f64], data: &mut StageFunctionData) {
        let w: &mut FlyHighWs = ws(&mut data.ws);
        let out = slice_mut(&mut data.value);
        self.velocity.evaluate(x, &mut w.inner);
        match self.factor_and_velocity(&mut w.inner) {
            Ok((e, v)) => {
                out[0] = e * v.linear.x;
                out[1] = e * v.linear.y;
            }
            Err(_) => out.fill(f64::NAN),
        }
    }

    fn jacobian(&self, x: &[f64], data: &mut StageFunctionData) {
        let w: &mut FlyHighWs = ws(&mut data.ws);
        self.velocity.jacobian(x, &mut w.inner);
        let Ok((e, v)) = self.factor_and_velocity(&mut w.inner) else {
            data.jx.fill(f64::NAN);
            return;
        };
        let (nv, j) = (self.velocity.layout.nv, &w.inner.jx);
        let [_, b, c_y] = self.ground();
        for c in 0..nv {
            // ∂p/∂q is the v-derivative of the LWA linear velocity.
            let dh = j[(2, nv + c)] - b * j[(0, nv + c)] - c_y * j[(1, nv + c)];
            for (i, vi) in [v.linear.x, v.linear.y].into_iter().enumerate() {
                data.jx[(i, c)] = e * (j[(i, c)] - self.slope * vi * dh);
                data.jx[(i, nv + c)] = e * j[(i, nv + c)];
            }
        }
    }
}

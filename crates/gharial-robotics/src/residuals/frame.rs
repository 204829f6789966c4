//! Placement, translation and rotation residuals of frames.
//!
//! A tangent perturbation `q ⊕ δ` moves frame f as `oMf ← oMf exp(J_f δ)`, with
//! `J_f = Ad(oMf⁻¹) J_w` its LOCAL Jacobian (`J_w` the world columns of the dofs that
//! move it). Hence, with `Jlog` the right Jacobians of the logarithms:
//! - placement `log6(M_ref⁻¹ oMf)`: `Jlog6 · J_f`;
//! - rotation `log3(R_refᵀ R_f)`: `Jlog3 · J_f[ang]`;
//! - translation `p_f − p_ref`: `R_f J_f[lin]`, the LOCAL_WORLD_ALIGNED linear rows;
//! - relative placement `log6(M_ref⁻¹ oMa⁻¹ oMb)`: `Jlog6 · Ad(oMb⁻¹) (J_w,b − J_w,a)`,
//!   where the columns of the dofs moving both frames cancel.

use std::sync::Arc;

use faer::MatMut;
use faer::reborrow::ReborrowMut;
use gharial::functions::{StageFunctionData, UnaryFunction, Workspace};
use gharial::linalg::slice_mut;
use gharial::{Error, Result};
use gharial_multibody::spatial::{Mat3, Motion, Se3, Vec3};
use gharial_multibody::{
    Data, Model, compute_joint_jacobians_reusing_placements, forward_kinematics_placements, jlog3, jlog6_blocks, log3,
    log6,
};

use super::{
    FrameRef, MultibodyWs, PlacementTarget, StateLayout, VectorTarget, ok_or_nan, ok_or_nan_mat, put3, put6, ws,
};
use crate::MultibodyPhaseSpace;

/// Placements of the configuration `q`; NaN in `out` on failure.
fn placements(model: &Model, data: &mut Data, q: &[f64], out: &mut [f64]) -> bool {
    ok_or_nan(forward_kinematics_placements(model, data, q), out)
}

/// Placements and Jacobian columns of the configuration `q` (the placements of an
/// `evaluate` at the same point reused: the model is shared, immutable); NaN in `jx` on
/// failure.
fn joint_jacobians(model: &Model, data: &mut Data, q: &[f64], jx: MatMut<'_, f64>) -> bool {
    ok_or_nan_mat(compute_joint_jacobians_reusing_placements(model, data, q), jx)
}

/// Writes `r = log6(...)` of a placement error (`error` gives `(oM, r)` from the
/// placements in the data) into `data.value`.
fn evaluate_log6(model: &Model, q: &[f64], data: &mut StageFunctionData, error: impl Fn(&Data) -> (Se3, Motion)) {
    let w: &mut MultibodyWs = ws(&mut data.ws);
    let out = slice_mut(&mut data.value);
    if placements(model, &mut w.data, q, out) {
        out.copy_from_slice(&error(&w.data).1.to_array());
    }
}

/// The Jacobian `Jlog6(r) Ad(oM⁻¹) Σ sign_k J_k` of a placement error whose motion is
/// the signed sum of the world Jacobian columns `columns` (`(dof, sign)`).
fn log6_jacobian(
    model: &Model,
    q: &[f64],
    data: &mut StageFunctionData,
    error: impl Fn(&Data) -> (Se3, Motion),
    columns: impl Iterator<Item = (usize, f64)>,
) {
    let w: &mut MultibodyWs = ws(&mut data.ws);
    let mut jx = data.jx.as_mut();
    if !joint_jacobians(model, &mut w.data, q, jx.rb_mut()) {
        return;
    }
    let (o_m, xi) = error(&w.data);
    let (jl, c) = jlog6_blocks(&xi);
    jx.fill(0.0);
    for (k, sign) in columns {
        let m = o_m.act_inv_motion(&(*w.data.joint_jacobian_column(k) * sign));
        put6(&mut jx, k, &jlog6_times(&jl, &c, &m));
    }
}

/// `Jlog6 m` with `Jlog6 = [[Jl, C], [0, Jl]]` given by its blocks.
#[inline]
fn jlog6_times(jl: &Mat3, c: &Mat3, m: &Motion) -> Motion {
    Motion::new(jl * m.linear + c * m.angular, jl * m.angular)
}

/// The pose error `r = log6(M_ref⁻¹ oMf(q))` of a frame (ALIGATOR's
/// `FramePlacementResidual`, Crocoddyl's `ResidualModelFramePlacement`), `nr = 6`,
/// `[linear, angular]`.
///
/// Jacobian `[Jlog6(r) J_f, 0]` with `J_f` the frame's LOCAL Jacobian.
#[derive(Debug)]
pub struct FramePlacementResidual {
    model: Arc<Model>,
    layout: StateLayout,
    frame: FrameRef,
    target: PlacementTarget,
}

impl FramePlacementResidual {
    /// The residual of frame `frame` with target placement `m_ref` (in the world).
    ///
    /// # Errors
    /// If the frame is not in the model, or `m_ref` is not finite or its rotation is not
    /// a rotation matrix.
    pub fn new(space: &MultibodyPhaseSpace, frame: &str, m_ref: &Se3) -> Result<Self> {
        let model = space.model().clone();
        Ok(Self {
            frame: FrameRef::resolve(&model, "FramePlacementResidual", frame)?,
            target: PlacementTarget::new("FramePlacementResidual target m_ref", m_ref)?,
            layout: StateLayout::of(space),
            model,
        })
    }

    /// Moves the target (through `&self`, between solves).
    ///
    /// # Errors
    /// As [`FramePlacementResidual::new`]; the target is then unchanged.
    pub fn set_target(&self, m_ref: &Se3) -> Result<()> {
        self.target.set(m_ref)
    }

    /// The current target.
    pub fn target(&self) -> Se3 {
        self.target.get()
    }

    /// Index of the frame in the model.
    pub fn frame_id(&self) -> usize {
        self.frame.id
    }

    /// `(oMf, log6(M_ref⁻¹ oMf))` from the placements in `data`.
    fn error(&self, data: &Data) -> (Se3, Motion) {
        let o_mf = self.frame.placement(data);
        (o_mf, log6(&self.target.get().inv_compose(&o_mf)))
    }
}

impl UnaryFunction for FramePlacementResidual {
    unary_sizes!(6);

    fn evaluate(&self, x: &[f64], data: &mut StageFunctionData) {
        evaluate_log6(&self.model, self.layout.q(x), data, |d| self.error(d));
    }

    fn jacobian(&self, x: &[f64], data: &mut StageFunctionData) {
        let columns = self.frame.support.iter().map(|&k| (k, 1.0));
        log6_jacobian(&self.model, self.layout.q(x), data, |d| self.error(d), columns);
    }
}

/// The position error `r = p_f(q) − p_ref` of a frame's origin in the world (ALIGATOR's
/// `FrameTranslationResidual`), `nr = 3`.
///
/// Jacobian `[R_f J_f[lin], 0]`: the LOCAL_WORLD_ALIGNED linear rows, computed column by
/// column from the world Jacobian of the dofs that move the frame only.
#[derive(Debug)]
pub struct FrameTranslationResidual {
    model: Arc<Model>,
    layout: StateLayout,
    frame: FrameRef,
    target: VectorTarget,
}

impl FrameTranslationResidual {
    /// The residual of frame `frame` with target position `p_ref` (3, world).
    ///
    /// # Errors
    /// If the frame is not in the model, or `p_ref` does not have 3 finite entries.
    pub fn new(space: &MultibodyPhaseSpace, frame: &str, p_ref: &[f64]) -> Result<Self> {
        let model = space.model().clone();
        Ok(Self {
            frame: FrameRef::resolve(&model, "FrameTranslationResidual", frame)?,
            target: VectorTarget::new("FrameTranslationResidual target p_ref", p_ref, 3)?,
            layout: StateLayout::of(space),
            model,
        })
    }

    /// Moves the target.
    ///
    /// # Errors
    /// If `p_ref` does not have 3 finite entries; the target is then unchanged.
    pub fn set_target(&self, p_ref: &[f64]) -> Result<()> {
        self.target.set(p_ref)
    }

    /// The current target.
    pub fn target(&self) -> Vec<f64> {
        self.target.get()
    }

    /// Index of the frame in the model.
    pub fn frame_id(&self) -> usize {
        self.frame.id
    }
}

impl UnaryFunction for FrameTranslationResidual {
    unary_sizes!(3);

    fn evaluate(&self, x: &[f64], data: &mut StageFunctionData) {
        let w: &mut MultibodyWs = ws(&mut data.ws);
        let out = slice_mut(&mut data.value);
        if placements(&self.model, &mut w.data, self.layout.q(x), out) {
            let r = self.frame.placement(&w.data).translation - self.target.vec3();
            out.copy_from_slice(r.as_slice());
        }
    }

    fn jacobian(&self, x: &[f64], data: &mut StageFunctionData) {
        let w: &mut MultibodyWs = ws(&mut data.ws);
        let mut jx = data.jx.as_mut();
        if !joint_jacobians(&self.model, &mut w.data, self.layout.q(x), jx.rb_mut()) {
            return;
        }
        let p = self.frame.placement(&w.data).translation;
        jx.fill(0.0);
        for &k in &self.frame.support {
            put3(&mut jx, 0, k, &w.data.joint_jacobian_column(k).shifted_to(&p).linear);
        }
    }
}

/// The orientation error `r = log3(R_refᵀ R_f(q))` of a frame (Crocoddyl's
/// `ResidualModelFrameRotation`), `nr = 3`. Jacobian `[Jlog3(r) J_f[ang], 0]`.
#[derive(Debug)]
pub struct FrameRotationResidual {
    model: Arc<Model>,
    layout: StateLayout,
    frame: FrameRef,
    /// The target as a placement with zero translation.
    target: PlacementTarget,
}

impl FrameRotationResidual {
    /// The residual of frame `frame` with target orientation `r_ref` (a rotation matrix,
    /// world).
    ///
    /// # Errors
    /// If the frame is not in the model, or `r_ref` is not a finite rotation matrix.
    pub fn new(space: &MultibodyPhaseSpace, frame: &str, r_ref: &Mat3) -> Result<Self> {
        let model = space.model().clone();
        Ok(Self {
            frame: FrameRef::resolve(&model, "FrameRotationResidual", frame)?,
            target: PlacementTarget::new("FrameRotationResidual target r_ref", &Se3::new(*r_ref, Vec3::zeros()))?,
            layout: StateLayout::of(space),
            model,
        })
    }

    /// Moves the target.
    ///
    /// # Errors
    /// If `r_ref` is not a finite rotation matrix; the target is then unchanged.
    pub fn set_target(&self, r_ref: &Mat3) -> Result<()> {
        self.target.set(&Se3::new(*r_ref, Vec3::zeros()))
    }

    /// The current target.
    pub fn target(&self) -> Mat3 {
        self.target.get().rotation
    }

    /// `(R_f, log3(R_refᵀ R_f))`.
    fn error(&self, data: &Data) -> (Mat3, Vec3) {
        let r_f = self.frame.placement(data).rotation;
        (r_f, log3(&(self.target.get().rotation.transpose() * r_f)))
    }
}

impl UnaryFunction for FrameRotationResidual {
    unary_sizes!(3);

    fn evaluate(&self, x: &[f64], data: &mut StageFunctionData) {
        let w: &mut MultibodyWs = ws(&mut data.ws);
        let out = slice_mut(&mut data.value);
        if placements(&self.model, &mut w.data, self.layout.q(x), out) {
            out.copy_from_slice(self.error(&w.data).1.as_slice());
        }
    }

    fn jacobian(&self, x: &[f64], data: &mut StageFunctionData) {
        let w: &mut MultibodyWs = ws(&mut data.ws);
        let mut jx = data.jx.as_mut();
        if !joint_jacobians(&self.model, &mut w.data, self.layout.q(x), jx.rb_mut()) {
            return;
        }
        let (r_f, phi) = self.error(&w.data);
        let jl = jlog3(&phi);
        jx.fill(0.0);
        for &k in &self.frame.support {
            put3(
                &mut jx,
                0,
                k,
                &(jl * (r_f.transpose() * w.data.joint_jacobian_column(k).angular)),
            );
        }
    }
}

/// The relative pose error `r = log6(M_ref⁻¹ oMa(q)⁻¹ oMb(q))` of frame b seen from frame
/// a, `nr = 6`. Jacobian `[Jlog6(r) Ad(oMb⁻¹) (J_w,b − J_w,a), 0]`.
#[derive(Debug)]
pub struct RelativePlacementResidual {
    model: Arc<Model>,
    layout: StateLayout,
    frame_a: FrameRef,
    frame_b: FrameRef,
    /// `(dof, ±1)`: the dofs that move exactly one of the two frames, with the sign of
    /// their world column in `J_w,b − J_w,a`.
    columns: Vec<(usize, f64)>,
    target: PlacementTarget,
}

impl RelativePlacementResidual {
    /// The residual of frame `frame_b` relative to `frame_a` with target `m_ref` (the
    /// placement of b in a).
    ///
    /// # Errors
    /// If a frame is not in the model, the two frames are the same, or `m_ref` is not a
    /// finite placement.
    pub fn new(space: &MultibodyPhaseSpace, frame_a: &str, frame_b: &str, m_ref: &Se3) -> Result<Self> {
        let model = space.model().clone();
        let a = FrameRef::resolve(&model, "RelativePlacementResidual", frame_a)?;
        let b = FrameRef::resolve(&model, "RelativePlacementResidual", frame_b)?;
        if a.id == b.id {
            return Err(Error::InvalidModel(format!(
                "RelativePlacementResidual: frames a and b are both `{frame_a}`"
            )));
        }
        let only = |s: &FrameRef, t: &FrameRef, sign: f64| {
            s.support
                .iter()
                .filter(|k| !t.support.contains(k))
                .map(move |&k| (k, sign))
                .collect::<Vec<_>>()
        };
        let mut columns = only(&b, &a, 1.0);
        columns.extend(only(&a, &b, -1.0));
        Ok(Self {
            target: PlacementTarget::new("RelativePlacementResidual target m_ref", m_ref)?,
            layout: StateLayout::of(space),
            frame_a: a,
            frame_b: b,
            columns,
            model,
        })
    }

    /// Moves the target.
    ///
    /// # Errors
    /// If `m_ref` is not a finite placement; the target is then unchanged.
    pub fn set_target(&self, m_ref: &Se3) -> Result<()> {
        self.target.set(m_ref)
    }

    /// The current target.
    pub fn target(&self) -> Se3 {
        self.target.get()
    }

    /// `(oMb, r)`.
    fn error(&self, data: &Data) -> (Se3, Motion) {
        let (o_ma, o_mb) = (self.frame_a.placement(data), self.frame_b.placement(data));
        let e = self.target.get().inv_compose(&o_ma.inv_compose(&o_mb));
        (o_mb, log6(&e))
    }
}

impl UnaryFunction for RelativePlacementResidual {
    unary_sizes!(6);

    fn evaluate(&self, x: &[f64], data: &mut StageFunctionData) {
        evaluate_log6(&self.model, self.layout.q(x), data, |d| self.error(d));
    }

    fn jacobian(&self, x: &[f64], data: &mut StageFunctionData) {
        let columns = self.columns.iter().copied();
        log6_jacobian(&self.model, self.layout.q(x), data, |d| self.error(d), columns);
    }
}

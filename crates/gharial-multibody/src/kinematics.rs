//! Forward kinematics, frame placements, Jacobians, frame velocities and accelerations.
//!
//! Joint quantities are computed in the world frame: `oMi`, the spatial velocity
//! `ov_i = ov_λ + J_i v_i` and acceleration `oa_i = oa_λ + J_i a_i + ov_λ × J_i v_i`,
//! with the Jacobian columns `J_k = oMi · S_k`.

use crate::data::{Data, LEFT_ABA, LEFT_PLACEMENTS, check_data};
use crate::error::{Error, Result, check_result, check_result_mat, check_vec};
use crate::model::{Model, NONE, ReferenceFrame};
use crate::spatial::{Motion, Se3};
use faer::MatMut;

impl Model {
    /// Last degree of freedom of the support of `joint` (its own last dof, or that of its
    /// nearest ancestor with dofs), or `NONE`.
    #[inline]
    pub(crate) fn last_dof(&self, joint: usize) -> usize {
        let mut j = joint;
        while j != 0 {
            let jm = &self.joints[j];
            if jm.nv > 0 {
                return jm.idx_v + jm.nv - 1;
            }
            j = self.parents[j];
        }
        NONE
    }
}

/// Computes `liMi` and `oMi` of joint `i`.
#[inline]
pub(crate) fn placement_step(model: &Model, data: &mut Data, i: usize, q: &[f64]) {
    let jm = &model.joints[i];
    let li = jm
        .kind
        .placed_transform(&model.placements[i], &q[jm.idx_q..jm.idx_q + jm.nq]);
    data.li_mi[i] = li;
    let p = model.parents[i];
    data.o_mi[i] = if p == 0 { li } else { data.o_mi[p].compose(&li) };
}

/// Computes the world Jacobian columns of joint `i` from `oMi`.
#[inline]
pub(crate) fn jacobian_step(model: &Model, data: &mut Data, i: usize) {
    let jm = &model.joints[i];
    jm.kind
        .world_columns(&data.o_mi[i], &mut data.j[jm.idx_v..jm.idx_v + jm.nv]);
}

/// `Σ_k J_k x_k` over the dofs of joint `i`.
#[inline]
pub(crate) fn joint_motion(model: &Model, data: &Data, i: usize, x: &[f64]) -> Motion {
    let jm = &model.joints[i];
    let mut m = Motion::zero();
    for k in jm.idx_v..jm.idx_v + jm.nv {
        m += data.j[k] * x[k];
    }
    m
}

/// Checks a quantity computed from the root to the leaves (`oMi`, `ov`, `oa`): a NaN or
/// infinity at a joint reaches all its descendants (a non-finite entry of a parent's
/// placement makes a whole row of the child's non-finite, and velocities and
/// accelerations add the parent's), so it is enough to look at the leaves.
fn check_at_leaves<T>(what: &str, model: &Model, items: &[T], finite: impl Fn(&T) -> bool) -> Result<()> {
    if model.leaves.iter().fold(true, |ok, &i| ok & finite(&items[i])) {
        Ok(())
    } else {
        check_result(what, items, finite)
    }
}

/// Checks the placements `oMi` and the Jacobian columns left by a kinematic pass.
pub(crate) fn check_placements_and_jacobian(model: &Model, data: &Data) -> Result<()> {
    check_at_leaves("joint placements oMi", model, &data.o_mi, Se3::is_finite)?;
    check_result("joint Jacobian columns", &data.j, Motion::is_finite)
}

/// [`check_placements_and_jacobian`] and the joint velocities and accelerations.
pub(crate) fn check_kinematics(model: &Model, data: &Data) -> Result<()> {
    check_placements_and_jacobian(model, data)?;
    check_at_leaves("joint velocities", model, &data.ov, Motion::is_finite)?;
    check_at_leaves("joint accelerations", model, &data.oa, Motion::is_finite)
}

/// `m` if it is finite, else an error naming `what`.
fn finite_motion(what: &str, m: Motion) -> Result<Motion> {
    check_result(what, &m.to_array(), |x| x.is_finite())?;
    Ok(m)
}

/// Forward kinematics: placements `oMi`, velocities and accelerations (no gravity) of
/// every joint, and the world Jacobian columns.
///
/// Every algorithm checks its inputs (lengths, finite entries, unit quaternions within
/// [`Model::UNIT_NORM_TOLERANCE`]) and its results: an overflow gives
/// [`Error::NonFiniteResult`], never NaN.
pub fn forward_kinematics(model: &Model, data: &mut Data, q: &[f64], v: &[f64], a: &[f64]) -> Result<()> {
    model.check_configuration("q", q)?;
    check_data(model, data)?;
    check_vec("v", v, model.nv)?;
    check_vec("a", a, model.nv)?;
    for i in 1..model.njoints() {
        placement_step(model, data, i, q);
        jacobian_step(model, data, i);
        let p = model.parents[i];
        let vj = joint_motion(model, data, i, v);
        let aj = joint_motion(model, data, i, a);
        let (ovp, oap) = (data.ov[p], data.oa[p]);
        data.ov[i] = ovp + vj;
        data.oa[i] = oap + aj + ovp.cross(&vj);
    }
    check_kinematics(model, data)
}

/// Placements `oMi` only.
pub fn forward_kinematics_placements(model: &Model, data: &mut Data, q: &[f64]) -> Result<()> {
    model.check_configuration("q", q)?;
    check_data(model, data)?;
    for i in 1..model.njoints() {
        placement_step(model, data, i, q);
    }
    check_at_leaves("joint placements oMi", model, &data.o_mi, Se3::is_finite)?;
    data.last.record(LEFT_PLACEMENTS, &[q]);
    Ok(())
}

/// Placements `oMf` of every frame from the current `oMi`.
pub fn update_frame_placements(model: &Model, data: &mut Data) -> Result<()> {
    check_data(model, data)?;
    for (f, frame) in model.frames.iter().enumerate() {
        data.o_mf[f] = data.o_mi[frame.parent_joint].compose(&frame.placement);
    }
    check_result("frame placements oMf", &data.o_mf, Se3::is_finite)
}

/// Placements `oMi` and world Jacobian columns of every joint.
pub fn compute_joint_jacobians(model: &Model, data: &mut Data, q: &[f64]) -> Result<()> {
    joint_jacobians(model, data, q, false)
}

/// As [`compute_joint_jacobians`], reusing the placements `oMi` that the last algorithm
/// run on `data` left when it computed them at the same `q` (compared bit for bit):
/// [`forward_kinematics_placements`] or [`crate::aba`]. A residual that evaluates the
/// placements and then differentiates at the same point computes them once.
///
/// The model must not have changed since (as when it is shared in an `Arc`).
pub fn compute_joint_jacobians_reusing_placements(model: &Model, data: &mut Data, q: &[f64]) -> Result<()> {
    let reuse = data.last.was(&[LEFT_PLACEMENTS, LEFT_ABA], &[q]);
    joint_jacobians(model, data, q, reuse)
}

fn joint_jacobians(model: &Model, data: &mut Data, q: &[f64], reuse: bool) -> Result<()> {
    model.check_configuration("q", q)?;
    check_data(model, data)?;
    for i in 1..model.njoints() {
        if !reuse {
            placement_step(model, data, i, q);
        }
        jacobian_step(model, data, i);
    }
    check_placements_and_jacobian(model, data)
}

/// Placement of frame `frame` computed from the current `oMi`.
#[inline]
pub(crate) fn frame_placement_of(model: &Model, data: &Data, frame: usize) -> Se3 {
    let fr = &model.frames[frame];
    data.o_mi[fr.parent_joint].compose(&fr.placement)
}

/// Expresses a world motion (reference point at the world origin) in `rf` for a frame
/// with world placement `o_mf`.
#[inline]
pub(crate) fn express_motion(o_mf: &Se3, m: &Motion, rf: ReferenceFrame) -> Motion {
    match rf {
        ReferenceFrame::World => *m,
        ReferenceFrame::Local => o_mf.act_inv_motion(m),
        ReferenceFrame::LocalWorldAligned => m.shifted_to(&o_mf.translation),
    }
}

fn check_out(what: &str, out: &MatMut<'_, f64>, rows: usize, cols: usize) -> Result<()> {
    if out.nrows() != rows || out.ncols() != cols {
        return Err(Error::Invalid(format!(
            "{what}: output is {}x{}, expected {rows}x{cols}",
            out.nrows(),
            out.ncols()
        )));
    }
    Ok(())
}

/// Jacobian (6 × nv) of frame `frame` in `rf`, from the last `compute_joint_jacobians` (or
/// any pass that computes the Jacobian columns). `J v` is the frame velocity in `rf`.
pub fn frame_jacobian(
    model: &Model,
    data: &Data,
    frame: usize,
    rf: ReferenceFrame,
    mut out: MatMut<'_, f64>,
) -> Result<()> {
    model.check_frame(frame)?;
    check_data(model, data)?;
    check_out("frame_jacobian", &out, 6, model.nv)?;
    out.fill(0.0);
    let o_mf = frame_placement_of(model, data, frame);
    support_columns(model, data, model.frames[frame].parent_joint, &o_mf, rf, &mut out);
    check_result_mat("frame Jacobian", out.as_ref())
}

/// Writes the Jacobian columns of the support of `joint`, expressed in `rf` for a frame
/// placed at `o`, into `out` (6 × nv, the other columns untouched).
fn support_columns(model: &Model, data: &Data, joint: usize, o: &Se3, rf: ReferenceFrame, out: &mut MatMut<'_, f64>) {
    let mut k = model.last_dof(joint);
    while k != NONE {
        let col = express_motion(o, &data.j[k], rf).to_array();
        for r in 0..6 {
            out[(r, k)] = col[r];
        }
        k = model.dof_parent[k];
    }
}

/// Jacobian (6 × nv) of joint `joint`'s frame in `rf`.
pub fn joint_jacobian(
    model: &Model,
    data: &Data,
    joint: usize,
    rf: ReferenceFrame,
    mut out: MatMut<'_, f64>,
) -> Result<()> {
    if joint >= model.njoints() {
        return Err(Error::NotFound {
            what: "joint".into(),
            name: joint.to_string(),
        });
    }
    check_out("joint_jacobian", &out, 6, model.nv)?;
    check_data(model, data)?;
    out.fill(0.0);
    let o = data.o_mi[joint];
    support_columns(model, data, joint, &o, rf, &mut out);
    check_result_mat("joint Jacobian", out.as_ref())
}

fn check_joint(data: &Data, joint: usize) -> Result<()> {
    if joint < data.o_mi.len() {
        Ok(())
    } else {
        Err(Error::NotFound {
            what: "joint".into(),
            name: joint.to_string(),
        })
    }
}

/// Spatial velocity of joint `joint` in `rf`, after `forward_kinematics`.
pub fn joint_velocity(data: &Data, joint: usize, rf: ReferenceFrame) -> Result<Motion> {
    check_joint(data, joint)?;
    finite_motion("joint velocity", express_motion(&data.o_mi[joint], &data.ov[joint], rf))
}

/// Spatial acceleration (no gravity) of joint `joint` in `rf`, after `forward_kinematics`.
pub fn joint_acceleration(data: &Data, joint: usize, rf: ReferenceFrame) -> Result<Motion> {
    check_joint(data, joint)?;
    finite_motion(
        "joint acceleration",
        express_motion(&data.o_mi[joint], &data.oa[joint], rf),
    )
}

/// Spatial velocity of frame `frame` in `rf`, after `forward_kinematics`.
pub fn frame_velocity(model: &Model, data: &Data, frame: usize, rf: ReferenceFrame) -> Result<Motion> {
    model.check_frame(frame)?;
    check_data(model, data)?;
    let o_mf = frame_placement_of(model, data, frame);
    finite_motion(
        "frame velocity",
        express_motion(&o_mf, &data.ov[model.frames[frame].parent_joint], rf),
    )
}

/// Spatial acceleration (no gravity) of frame `frame` in `rf`, after `forward_kinematics`.
pub fn frame_acceleration(model: &Model, data: &Data, frame: usize, rf: ReferenceFrame) -> Result<Motion> {
    model.check_frame(frame)?;
    check_data(model, data)?;
    let o_mf = frame_placement_of(model, data, frame);
    finite_motion(
        "frame acceleration",
        express_motion(&o_mf, &data.oa[model.frames[frame].parent_joint], rf),
    )
}

/// Classical acceleration of frame `frame` in `rf`: the spatial acceleration with
/// `ω × v_lin` added to its linear part (in LOCAL and LWA, the acceleration of the frame
/// origin).
pub fn frame_classical_acceleration(model: &Model, data: &Data, frame: usize, rf: ReferenceFrame) -> Result<Motion> {
    let v = frame_velocity(model, data, frame, rf)?;
    let mut a = frame_acceleration(model, data, frame, rf)?;
    a.linear += v.angular.cross(&v.linear);
    finite_motion("frame classical acceleration", a)
}

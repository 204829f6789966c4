//! Analytical derivatives of kinematics, RNEA and ABA (Carpentier & Mansard, "Analytical
//! derivatives of rigid body dynamics algorithms", RSS 2018), in the world frame.
//!
//! For a tangent perturbation of dof c (joint j, parent joint λ), every quantity `x`
//! attached to a body in the subtree of j moves as `∂(oX x)/∂q_c = J_c × (oX x)`. This
//! gives, per dof, the world-frame columns
//! `dVdq_c = ov_λ × J_c`, `dJ_c = ov_j × J_c`, `dAdq_c = oa_λ × J_c + ov_λ × dVdq_c`,
//! `dAdv_c = dJ_c + dVdq_c`, and for a body i in the subtree of j the plain derivatives
//! `∂ov_i/∂q_c = J_c × ov_i + dVdq_c`, `∂oa_i/∂q_c = J_c × oa_i + dAdq_c − ov_i × dVdq_c`,
//! `∂oa_i/∂v_c = dAdv_c − ov_i × J_c`.
//!
//! RNEA: with `Ycrb_i`, the subtree force `F_i`, and the subtree operator
//! `D_i = Σ_k (Ẏ_k + [· ×* h_k]) = [[0, −2[h_f]×], [0, T_i]]` (time derivative of the world
//! inertias plus the momentum cross term), for rows r of joint i and columns c in its
//! support: `∂τ_r/∂q_c = dAdq_c·(Ycrb_i J_r) + dVdq_c·(D_iᵀ J_r)` and for rows r of the
//! strict ancestors of joint i and its columns c:
//! `∂τ_r/∂q_c = J_r·(Ycrb_i dAdq_c + D_i dVdq_c + J_c ×* F_i)`; the same with
//! `(dAdv_c, J_c)` for v and `(J_c, 0)` for a (the CRBA).

use crate::data::{Data, LEFT_ABA, check_data};
use crate::dynamics::{aba_unchecked, factor_mass_matrix, minv_from_factor};
use crate::error::{Error, Result, check_result, check_result_mat, check_results, check_vec};
use crate::kinematics::{
    check_kinematics, express_motion, frame_placement_of, jacobian_step, joint_motion, placement_step,
};
use crate::linalg::{minv_times_tree_sparse, zero_6xn};
use crate::model::{Model, NONE, ReferenceFrame};
use crate::spatial::{Force, Inertia, Mat3, Motion, Se3, Vec3, skew};
use faer::MatMut;

/// `T_k` block of `D_k` for a body with world inertia `y`, velocity `ov` and momentum `oh`:
/// `[ω]× I_o − I_o [ω]× − (h νᵀ + ν hᵀ − 2 (ν·h) 𝟙) − [h_τ]×`. With `X = [ω]× I_o`, the
/// first two terms are `X + Xᵀ` (I_o symmetric): the symmetric part is formed on its upper
/// triangle.
#[inline]
fn t_block(y: &Inertia, ov: &Motion, oh: &Force) -> Mat3 {
    let x = skew(&ov.angular) * y.rotational;
    let h = &y.first_moment;
    let nu = &ov.linear;
    let d = 2.0 * nu.dot(h);
    let s = |i: usize, j: usize| x[(i, j)] + x[(j, i)] - (h[i] * nu[j] + nu[i] * h[j]);
    let (s00, s11, s22) = (s(0, 0) + d, s(1, 1) + d, s(2, 2) + d);
    let (s01, s02, s12) = (s(0, 1), s(0, 2), s(1, 2));
    let w = &oh.angular;
    Mat3::new(
        s00,
        s01 + w.z,
        s02 - w.y,
        s01 - w.z,
        s11,
        s12 + w.x,
        s02 + w.y,
        s12 - w.x,
        s22,
    )
}

/// `D m = [−2 h_f × m_ang, T m_ang]`.
#[inline]
fn d_mul(hf: &Vec3, t: &Mat3, m: &Motion) -> Force {
    Force::new(hf.cross(&m.angular) * -2.0, t * m.angular)
}

/// Forward pass of the kinematic derivatives: `oMi`, `J`, `ov`, `oa` (no gravity) and the
/// per-dof columns `dJ`, `dVdq`, `dAdq`, `dAdv`.
pub fn compute_forward_kinematics_derivatives(
    model: &Model,
    data: &mut Data,
    q: &[f64],
    v: &[f64],
    a: &[f64],
) -> Result<()> {
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
        let ov = ovp + vj;
        data.ov[i] = ov;
        data.oa[i] = oap + aj + ovp.cross(&vj);
        let jm = model.joints[i];
        for k in jm.idx_v..jm.idx_v + jm.nv {
            let jk = data.j[k];
            let dvdq = ovp.cross(&jk);
            let dj = ov.cross(&jk);
            data.dvdq[k] = dvdq;
            data.dadq[k] = oap.cross(&jk) + ovp.cross(&dvdq);
            data.dadv[k] = dj + dvdq;
        }
    }
    check_kinematics(model, data)?;
    check_derivative_columns(data)
}

/// Checks the per-dof derivative columns `dVdq`, `dAdq`, `dAdv`.
fn check_derivative_columns(data: &Data) -> Result<()> {
    check_result("velocity derivative columns dVdq", &data.dvdq, Motion::is_finite)?;
    check_result("acceleration derivative columns dAdq", &data.dadq, Motion::is_finite)?;
    check_result("acceleration derivative columns dAdv", &data.dadv, Motion::is_finite)
}

fn check_6xnv(what: &str, m: &MatMut<'_, f64>, nv: usize) -> Result<()> {
    if m.nrows() != 6 || m.ncols() != nv {
        return Err(Error::Invalid(format!(
            "{what}: output is {}x{}, expected 6x{nv}",
            m.nrows(),
            m.ncols()
        )));
    }
    Ok(())
}

fn put_col(m: &mut MatMut<'_, f64>, c: usize, x: &Motion) {
    let a = x.to_array();
    for r in 0..6 {
        m[(r, c)] = a[r];
    }
}

/// Expresses a derivative column given in the world frame (as a plain derivative of a
/// world quantity, and as the derivative of the quantity seen from the moving body):
/// LOCAL uses `body` (`oMf⁻¹ · body`), WORLD uses `world`, LWA shifts `world` to the
/// frame origin (Pinocchio's convention: the motion of the origin is not differentiated).
#[inline]
fn express_derivative(o_mf: &Se3, rf: ReferenceFrame, body: &Motion, world: &Motion) -> Motion {
    match rf {
        ReferenceFrame::Local => o_mf.act_inv_motion(body),
        ReferenceFrame::World => *world,
        ReferenceFrame::LocalWorldAligned => world.shifted_to(&o_mf.translation),
    }
}

/// Derivatives of the spatial velocity of frame `frame` in `rf` with respect to q and v,
/// after [`compute_forward_kinematics_derivatives`] (6 × nv each). In LWA the q-derivative
/// follows Pinocchio: it omits the term due to the motion of the frame origin.
pub fn frame_velocity_derivatives(
    model: &Model,
    data: &Data,
    frame: usize,
    rf: ReferenceFrame,
    mut dv_dq: MatMut<'_, f64>,
    mut dv_dv: MatMut<'_, f64>,
) -> Result<()> {
    model.check_frame(frame)?;
    check_data(model, data)?;
    check_6xnv("dv_dq", &dv_dq, model.nv)?;
    check_6xnv("dv_dv", &dv_dv, model.nv)?;
    zero_6xn(dv_dq.as_mut());
    zero_6xn(dv_dv.as_mut());
    let o_mf = frame_placement_of(model, data, frame);
    let i = model.frames[frame].parent_joint;
    let ov = data.ov[i];
    let mut c = model.last_dof(i);
    // The columns off the support stay zero: only the written ones can be non-finite
    // (then the whole check, for its error).
    let mut finite = true;
    while c != NONE {
        let jc = data.j[c];
        let dvdq = data.dvdq[c];
        let (q_col, v_col) = (
            express_derivative(&o_mf, rf, &dvdq, &(jc.cross(&ov) + dvdq)),
            express_motion(&o_mf, &jc, rf),
        );
        finite &= q_col.is_finite() && v_col.is_finite();
        put_col(&mut dv_dq, c, &q_col);
        put_col(&mut dv_dv, c, &v_col);
        c = model.dof_parent[c];
    }
    if finite {
        return Ok(());
    }
    check_result_mat("dv_dq", dv_dq.as_ref())?;
    check_result_mat("dv_dv", dv_dv.as_ref())
}

/// Derivatives of the spatial velocity and acceleration of frame `frame` in `rf`, after
/// [`compute_forward_kinematics_derivatives`] (6 × nv each): `dv_dq`, `da_dq`, `da_dv`,
/// `da_da` (`= dv_dv`, the frame Jacobian). LWA q-derivatives as in
/// [`frame_velocity_derivatives`].
pub fn frame_acceleration_derivatives(
    model: &Model,
    data: &Data,
    frame: usize,
    rf: ReferenceFrame,
    mut dv_dq: MatMut<'_, f64>,
    mut da_dq: MatMut<'_, f64>,
    mut da_dv: MatMut<'_, f64>,
    mut da_da: MatMut<'_, f64>,
) -> Result<()> {
    model.check_frame(frame)?;
    check_data(model, data)?;
    for (w, m) in [
        ("dv_dq", &dv_dq),
        ("da_dq", &da_dq),
        ("da_dv", &da_dv),
        ("da_da", &da_da),
    ] {
        check_6xnv(w, m, model.nv)?;
    }
    zero_6xn(dv_dq.as_mut());
    zero_6xn(da_dq.as_mut());
    zero_6xn(da_dv.as_mut());
    zero_6xn(da_da.as_mut());
    let o_mf = frame_placement_of(model, data, frame);
    let i = model.frames[frame].parent_joint;
    let (ov, oa) = (data.ov[i], data.oa[i]);
    let mut c = model.last_dof(i);
    while c != NONE {
        let jc = data.j[c];
        let dvdq = data.dvdq[c];
        put_col(
            &mut dv_dq,
            c,
            &express_derivative(&o_mf, rf, &dvdq, &(jc.cross(&ov) + dvdq)),
        );
        let body_q = data.dadq[c] - ov.cross(&dvdq);
        put_col(
            &mut da_dq,
            c,
            &express_derivative(&o_mf, rf, &body_q, &(jc.cross(&oa) + body_q)),
        );
        let body_v = data.dadv[c] - ov.cross(&jc);
        put_col(&mut da_dv, c, &express_motion(&o_mf, &body_v, rf));
        put_col(&mut da_da, c, &express_motion(&o_mf, &jc, rf));
        c = model.dof_parent[c];
    }
    for (w, m) in [
        ("dv_dq", &dv_dq),
        ("da_dq", &da_dq),
        ("da_dv", &da_dv),
        ("da_da", &da_da),
    ] {
        check_result_mat(w, m.as_ref())?;
    }
    Ok(())
}

/// World-frame velocity pass: `oMi`, `J`, the world inertias `oY`, velocities `ov` and
/// momenta `oh`.
pub(crate) fn velocity_pass(model: &Model, data: &mut Data, q: &[f64], v: &[f64]) {
    for i in 1..model.njoints() {
        placement_step(model, data, i, q);
        jacobian_step(model, data, i);
        let p = model.parents[i];
        let oy = model.inertias[i].transformed(&data.o_mi[i]);
        let ov = data.ov[p] + joint_motion(model, data, i, v);
        data.o_y[i] = oy;
        data.ov[i] = ov;
        data.oh[i] = oy.mul_motion(&ov);
    }
}

/// The forward sweep of [`rnea_derivatives_kernel`]: world accelerations `oa_gf` (gravity
/// included), the subtree quantities' joint terms (`o_ycrb`, `hcrb`, `tcrb`), the body
/// forces `of`, and per dof the columns `dvdq`, `dadq`, `dadv`.
fn rnea_derivatives_forward(model: &Model, data: &mut Data, v: &[f64], a: &[f64]) {
    data.oa_gf[0] = -model.gravity;
    for i in 1..model.njoints() {
        let p = model.parents[i];
        let vj = joint_motion(model, data, i, v);
        let (ovp, oap) = (data.ov[p], data.oa_gf[p]);
        let (ov, oy, oh) = (data.ov[i], data.o_y[i], data.oh[i]);
        let oa = oap + joint_motion(model, data, i, a) + ovp.cross(&vj);
        data.oa_gf[i] = oa;
        data.o_ycrb[i] = oy;
        data.hcrb[i] = oh;
        data.tcrb[i] = t_block(&oy, &ov, &oh);
        data.of[i] = oy.mul_motion(&oa) + ov.cross_force(&oh);
        let jm = model.joints[i];
        for k in jm.idx_v..jm.idx_v + jm.nv {
            let jk = data.j[k];
            let dvdq = ovp.cross(&jk);
            let dj = ov.cross(&jk);
            data.dvdq[k] = dvdq;
            data.dadq[k] = oap.cross(&jk) + ovp.cross(&dvdq);
            data.dadv[k] = dj + dvdq;
        }
    }
}

/// The RNEA derivative recursion at (q, v, a), after a [`velocity_pass`] at (q, v) (or a
/// pass leaving the same quantities, such as the ABA). Writes `dtau_dq`, `dtau_dv` and
/// `M` into `dq`, `dv`, `m` (column-major; only the entries at dof pairs on one path to
/// the root are written, the others must be zero), `tau` into `data.tau`, and leaves `oa_gf`, the subtree quantities and the per-dof columns in `data`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn rnea_derivatives_kernel(
    model: &Model,
    data: &mut Data,
    v: &[f64],
    a: &[f64],
    dq: &mut [f64],
    dv: &mut [f64],
    m: &mut [f64],
) {
    let nv = model.nv;
    let idx = |r: usize, c: usize| c * nv + r;
    rnea_derivatives_forward(model, data, v, a);
    for i in (1..model.njoints()).rev() {
        let jm = model.joints[i];
        let (iv, nvj) = (jm.idx_v, jm.nv);
        let y = data.o_ycrb[i];
        let hf = data.hcrb[i].linear;
        let t = data.tcrb[i];
        let f = data.of[i];
        for r in iv..iv + nvj {
            let jr = data.j[r];
            data.tau[r] = jr.dot(&f) + model.armature[r] * a[r];
            let ar = y.mul_motion(&jr);
            // Dᵀ J_r = [0, 2 h_f × J_r,lin + Tᵀ J_r,ang]
            let br = hf.cross(&jr.linear) * 2.0 + t.tr_mul(&jr.angular);
            let mut c = iv + nvj - 1;
            while c != NONE {
                let k = idx(r, c);
                dq[k] = data.dadq[c].dot(&ar) + data.dvdq[c].angular.dot(&br);
                dv[k] = data.dadv[c].dot(&ar) + data.j[c].angular.dot(&br);
                m[k] = data.j[c].dot(&ar);
                c = model.dof_parent[c];
            }
        }
        let first = model.dof_parent[iv];
        if first != NONE {
            for c in iv..iv + nvj {
                let jc = data.j[c];
                let phi = y.mul_motion(&data.dadq[c]) + d_mul(&hf, &t, &data.dvdq[c]) + jc.cross_force(&f);
                let psi = y.mul_motion(&data.dadv[c]) + d_mul(&hf, &t, &jc);
                let om = y.mul_motion(&jc);
                let mut r = first;
                while r != NONE {
                    let jr = &data.j[r];
                    let k = idx(r, c);
                    dq[k] = jr.dot(&phi);
                    dv[k] = jr.dot(&psi);
                    m[k] = jr.dot(&om);
                    r = model.dof_parent[r];
                }
            }
        }
        let p = model.parents[i];
        if p != 0 {
            data.o_ycrb[p] += y;
            let h = data.hcrb[i];
            data.hcrb[p] += h;
            data.tcrb[p] += t;
            data.of[p] += f;
        }
    }
    for k in 0..nv {
        m[idx(k, k)] += model.armature[k];
    }
}

/// Derivatives of the inverse dynamics at (q, v, a): `dtau_dq`, `dtau_dv` and
/// `dtau_da = M`, read with [`Data::dtau_dq`], [`Data::dtau_dv`], [`Data::mass_matrix`];
/// also computes `tau` ([`Data::tau`]).
pub fn compute_rnea_derivatives(model: &Model, data: &mut Data, q: &[f64], v: &[f64], a: &[f64]) -> Result<()> {
    model.check_configuration("q", q)?;
    check_data(model, data)?;
    check_vec("v", v, model.nv)?;
    check_vec("a", a, model.nv)?;
    velocity_pass(model, data, q, v);
    rnea_derivatives_into_data(model, data, v, a);
    check_results(&rnea_results(data))
}

/// The results of the last RNEA derivatives (`tau`, `dtau_dq`, `dtau_dv`, `M`), named for
/// [`check_results`].
fn rnea_results(data: &Data) -> [(&'static str, &[f64]); 4] {
    [
        ("tau", &data.tau),
        ("dtau_dq", &data.dtau_dq),
        ("dtau_dv", &data.dtau_dv),
        ("mass matrix", &data.m),
    ]
}

/// [`rnea_derivatives_kernel`] into `data.dtau_dq`, `data.dtau_dv`, `data.m`.
fn rnea_derivatives_into_data(model: &Model, data: &mut Data, v: &[f64], a: &[f64]) {
    let mut dq = std::mem::take(&mut data.dtau_dq);
    let mut dv = std::mem::take(&mut data.dtau_dv);
    let mut m = std::mem::take(&mut data.m);
    rnea_derivatives_kernel(model, data, v, a, &mut dq, &mut dv, &mut m);
    data.dtau_dq = dq;
    data.dtau_dv = dv;
    data.m = m;
}

/// Derivatives of the forward dynamics at (q, v, tau): `ddq_dq = −M⁻¹ ∂τ/∂q`,
/// `ddq_dv = −M⁻¹ ∂τ/∂v` (RNEA derivatives at `a = aba(q, v, tau)`, left in
/// [`Data::dtau_dq`], [`Data::dtau_dv`]) and `ddq_dtau = M⁻¹`, read with [`Data::ddq_dq`],
/// [`Data::ddq_dv`], [`Data::minv`]; also computes `ddq` ([`Data::ddq`]) and `M`.
///
/// The ABA leaves the world kinematics the RNEA derivatives need (`oMi`, `J`, `oY`, `ov`,
/// `oh`); `M⁻¹` comes from the tree-sparse `Lᵀ D L` factorization of `M`, and the products
/// with `M⁻¹` visit only the nonzeros of `∂τ/∂q`, `∂τ/∂v` (pairs of dofs on one path to
/// the root).
pub fn compute_aba_derivatives(model: &Model, data: &mut Data, q: &[f64], v: &[f64], tau: &[f64]) -> Result<()> {
    aba_derivatives(model, data, q, v, tau, false)
}

/// As [`compute_aba_derivatives`], reusing the kinematics and `ddq` of the last
/// algorithm run on `data` when it was [`crate::aba`] at the same `(q, v, tau)` (compared
/// bit for bit; otherwise the ABA runs again): a model that evaluates the dynamics and
/// then differentiates them at the same point saves one ABA (about a quarter of the
/// derivatives on the UR5).
///
/// The model must not have changed since that `aba` (as when it is shared in an `Arc`):
/// its inertias, armature and gravity went into the reused results.
pub fn compute_aba_derivatives_reusing_aba(
    model: &Model,
    data: &mut Data,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
) -> Result<()> {
    let reuse = data.last.was(&[LEFT_ABA], &[q, v, tau]);
    aba_derivatives(model, data, q, v, tau, reuse)
}

/// `reuse`: the last algorithm on `data` was an [`crate::aba`] at these very `(q, v, tau)`,
/// which checked them and `ddq`.
fn aba_derivatives(model: &Model, data: &mut Data, q: &[f64], v: &[f64], tau: &[f64], reuse: bool) -> Result<()> {
    check_data(model, data)?;
    if !reuse {
        model.check_configuration("q", q)?;
        check_vec("v", v, model.nv)?;
        check_vec("tau", tau, model.nv)?;
        aba_unchecked(model, data, q, v, tau)?;
    }
    let ddq = std::mem::take(&mut data.ddq);
    rnea_derivatives_into_data(model, data, v, &ddq);
    data.ddq = ddq;
    factor_mass_matrix(model, data)?;
    minv_from_factor(model, data);
    let tree = model.dof_tree(&data.subtree_end);
    minv_times_tree_sparse(&tree, &data.minv, &data.dtau_dq, &mut data.ddq_dq, &mut data.terms);
    minv_times_tree_sparse(&tree, &data.minv, &data.dtau_dv, &mut data.ddq_dv, &mut data.terms);
    let [tau, dtau_dq, dtau_dv, m] = rnea_results(data);
    check_results(&[
        ("ddq", &data.ddq),
        tau,
        dtau_dq,
        dtau_dv,
        m,
        ("inverse mass matrix", &data.minv),
        ("ddq_dq", &data.ddq_dq),
        ("ddq_dv", &data.ddq_dv),
    ])
}

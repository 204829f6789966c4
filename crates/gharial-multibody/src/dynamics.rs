//! Inverse and forward dynamics: RNEA, nonlinear effects, generalized gravity, CRBA, ABA,
//! M⁻¹, centre of mass — all in the world frame (Featherstone, RBDA ch. 5-7).

use crate::data::{Data, LEFT_ABA, check_data};
use crate::error::{Error, Result, check_result, check_result_vec, check_vec};
use crate::kinematics::{jacobian_step, joint_motion, placement_step};
use crate::linalg::{check_pivot, ltdl_factor, ltdl_inverse, small_spd_inverse};
use crate::model::{Model, NONE};
use crate::spatial::{Force, Motion, Sym6, Vec3};
use faer::MatRef;

/// Recursive Newton-Euler pass in the joint frames (Featherstone, RBDA §5.3): with
/// `liMi`, `v_i = liMi⁻¹ v_λ + S_i q̇_i`, `a_i = liMi⁻¹ a_λ + S_i q̈_i + v_i × S_i q̇_i`
/// (gravity as the acceleration `−g` of the universe), `f_i = Y_i a_i + v_i ×* Y_i v_i`,
/// then `τ_i = S_iᵀ f_i` and `f_λ += liMi f_i` from the leaves. `v` or `a` absent means
/// zero. Fills `liMi`, `v`, `a_gf`, `f` and `tau`.
fn rnea_pass(model: &Model, data: &mut Data, q: &[f64], v: Option<&[f64]>, a: Option<&[f64]>) {
    data.a_gf[0] = -model.gravity;
    for i in 1..model.njoints() {
        let jm = &model.joints[i];
        let (iq, iv) = (jm.idx_q, jm.idx_v);
        let li = jm.kind.placed_transform(&model.placements[i], &q[iq..iq + jm.nq]);
        data.li_mi[i] = li;
        let p = model.parents[i];
        let mut ai = li.act_inv_motion(&data.a_gf[p]);
        let mut vi = Motion::zero();
        if let Some(v) = v {
            let vj = &v[iv..iv + jm.nv];
            vi = jm.kind.local_motion(vj);
            if p != 0 {
                vi += li.act_inv_motion(&data.v[p]);
            }
            ai += jm.kind.cross_local_motion(&vi, vj);
        }
        if let Some(a) = a {
            ai += jm.kind.local_motion(&a[iv..iv + jm.nv]);
        }
        let y = &model.inertias[i];
        let h = y.mul_motion(&vi);
        data.v[i] = vi;
        data.a_gf[i] = ai;
        data.f[i] = y.mul_motion(&ai) + vi.cross_force(&h);
    }
    for i in (1..model.njoints()).rev() {
        let jm = &model.joints[i];
        let f = data.f[i];
        jm.kind
            .project_local_force(&f, &mut data.tau[jm.idx_v..jm.idx_v + jm.nv]);
        let p = model.parents[i];
        if p != 0 {
            data.f[p] += data.li_mi[i].act_force(&f);
        }
    }
    if let Some(a) = a {
        for k in 0..model.nv {
            data.tau[k] += model.armature[k] * a[k];
        }
    }
}

/// Inverse dynamics `tau = M(q) a + C(q, v) v + g(q)` (armature included).
pub fn rnea<'d>(model: &Model, data: &'d mut Data, q: &[f64], v: &[f64], a: &[f64]) -> Result<&'d [f64]> {
    model.check_configuration("q", q)?;
    check_data(model, data)?;
    check_vec("v", v, model.nv)?;
    check_vec("a", a, model.nv)?;
    rnea_pass(model, data, q, Some(v), Some(a));
    check_rnea_result(data)?;
    Ok(&data.tau)
}

/// Checks the torques and joint forces of the last [`rnea_pass`].
fn check_rnea_result(data: &Data) -> Result<()> {
    check_result("joint forces", &data.f, Force::is_finite)?;
    check_result_vec("tau", &data.tau)
}

/// Nonlinear effects `C(q, v) v + g(q)`.
pub fn nonlinear_effects<'d>(model: &Model, data: &'d mut Data, q: &[f64], v: &[f64]) -> Result<&'d [f64]> {
    model.check_configuration("q", q)?;
    check_data(model, data)?;
    check_vec("v", v, model.nv)?;
    rnea_pass(model, data, q, Some(v), None);
    check_rnea_result(data)?;
    data.nle.copy_from_slice(&data.tau);
    Ok(&data.nle)
}

/// Generalized gravity `g(q)`.
pub fn generalized_gravity<'d>(model: &Model, data: &'d mut Data, q: &[f64]) -> Result<&'d [f64]> {
    model.check_configuration("q", q)?;
    check_data(model, data)?;
    rnea_pass(model, data, q, None, None);
    check_rnea_result(data)?;
    data.g.copy_from_slice(&data.tau);
    Ok(&data.g)
}

/// Composite-rigid-body algorithm: the full symmetric joint-space inertia matrix
/// (armature on the diagonal).
pub fn crba<'d>(model: &Model, data: &'d mut Data, q: &[f64]) -> Result<MatRef<'d, f64>> {
    model.check_configuration("q", q)?;
    check_data(model, data)?;
    crba_unchecked(model, data, q);
    check_result_vec("mass matrix", &data.m)?;
    Ok(data.mass_matrix())
}

/// Column `c` of the joint-space inertia matrix (and its mirror row) from the composite
/// inertia's force `f = Y_c S_c`: `M[r][c] = S_rᵀ f` for the dof `last` of the joint
/// and its ancestors (tree sparsity; Featherstone's CRBA).
pub(crate) fn mass_matrix_column(model: &Model, data: &mut Data, c: usize, last: usize, f: &Force) {
    let nv = model.nv;
    let mut r = last;
    while r != NONE {
        let mrc = data.j[r].dot(f);
        data.m[c * nv + r] = mrc;
        data.m[r * nv + c] = mrc;
        r = model.dof_parent[r];
    }
}

pub(crate) fn crba_unchecked(model: &Model, data: &mut Data, q: &[f64]) {
    let nv = model.nv;
    for i in 1..model.njoints() {
        placement_step(model, data, i, q);
        jacobian_step(model, data, i);
        data.o_ycrb[i] = model.inertias[i].transformed(&data.o_mi[i]);
    }
    for i in (1..model.njoints()).rev() {
        let jm = model.joints[i];
        let y = data.o_ycrb[i];
        for c in jm.idx_v..jm.idx_v + jm.nv {
            mass_matrix_column(model, data, c, jm.idx_v + jm.nv - 1, &y.mul_motion(&data.j[c]));
        }
        let p = model.parents[i];
        if p != 0 {
            data.o_ycrb[p] += y;
        }
    }
    for k in 0..nv {
        data.m[k * nv + k] += model.armature[k];
    }
}

/// Articulated-body algorithm in the world frame; fills `ddq` and `oa_gf`.
pub(crate) fn aba_unchecked(model: &Model, data: &mut Data, q: &[f64], v: &[f64], tau: &[f64]) -> Result<()> {
    let n = model.njoints();
    for i in 1..n {
        placement_step(model, data, i, q);
        jacobian_step(model, data, i);
        let p = model.parents[i];
        let oy = model.inertias[i].transformed(&data.o_mi[i]);
        data.o_y[i] = oy;
        let vj = joint_motion(model, data, i, v);
        let ovp = data.ov[p];
        let ov = ovp + vj;
        data.ov[i] = ov;
        data.c[i] = ovp.cross(&vj);
        data.ia[i] = Sym6::from_inertia(&oy);
        let oh = oy.mul_motion(&ov);
        data.oh[i] = oh;
        data.pa[i] = ov.cross_force(&oh);
    }
    for i in (1..n).rev() {
        let jm = model.joints[i];
        let (iv, nvj) = (jm.idx_v, jm.nv);
        let ia = data.ia[i];
        let pa = data.pa[i];
        for k in iv..iv + nvj {
            data.u[k] = ia.mul_motion(&data.j[k]);
            data.u_tau[k] = tau[k] - data.j[k].dot(&pa);
        }
        if nvj == 1 {
            let d = data.j[iv].dot(&data.u[iv]) + model.armature[iv];
            if !(d > 0.0 && d.is_finite()) {
                check_pivot(&format!("articulated inertia of joint {}", model.names[i]), iv, d)?;
            }
            data.dinv[i][0][0] = 1.0 / d;
            data.udinv[iv] = data.u[iv] * (1.0 / d);
        } else {
            let mut dm = [[0.0; 6]; 6];
            for r in 0..nvj {
                for c in 0..nvj {
                    dm[r][c] = data.j[iv + r].dot(&data.u[iv + c]);
                }
                dm[r][r] += model.armature[iv + r];
            }
            small_spd_inverse(nvj, &mut dm)?;
            data.dinv[i] = dm;
            for c in 0..nvj {
                let mut x = Force::zero();
                for r in 0..nvj {
                    x += data.u[iv + r] * dm[r][c];
                }
                data.udinv[iv + c] = x;
            }
        }
        let p = model.parents[i];
        if p != 0 {
            let mut ia_a = ia;
            let mut pa_a = pa;
            for k in iv..iv + nvj {
                ia_a.sub_outer(&data.udinv[k], &data.u[k]);
                pa_a += data.udinv[k] * data.u_tau[k];
            }
            pa_a += ia_a.mul_motion(&data.c[i]);
            data.ia[p] += ia_a;
            data.pa[p] += pa_a;
        }
    }
    data.oa_gf[0] = -model.gravity;
    for i in 1..n {
        let jm = model.joints[i];
        let (iv, nvj) = (jm.idx_v, jm.nv);
        let p = model.parents[i];
        let mut oa = data.oa_gf[p] + data.c[i];
        let mut rhs = [0.0; 6];
        for k in 0..nvj {
            rhs[k] = data.u_tau[iv + k] - data.u[iv + k].dot_motion(&oa);
        }
        let dinv = &data.dinv[i];
        for r in 0..nvj {
            let mut s = 0.0;
            for c in 0..nvj {
                s += dinv[r][c] * rhs[c];
            }
            data.ddq[iv + r] = s;
            oa += data.j[iv + r] * s;
        }
        data.oa_gf[i] = oa;
    }
    Ok(())
}

/// Forward dynamics `ddq = M⁻¹ (tau − C v − g)` by the articulated-body algorithm.
pub fn aba<'d>(model: &Model, data: &'d mut Data, q: &[f64], v: &[f64], tau: &[f64]) -> Result<&'d [f64]> {
    model.check_configuration("q", q)?;
    check_data(model, data)?;
    check_vec("v", v, model.nv)?;
    check_vec("tau", tau, model.nv)?;
    aba_unchecked(model, data, q, v, tau)?;
    check_result_vec("ddq", &data.ddq)?;
    data.last.record(LEFT_ABA, &[q, v, tau]);
    Ok(&data.ddq)
}

/// Factorizes `data.m` into `data.l`, `data.d` (`M = Lᵀ D L`).
pub(crate) fn factor_mass_matrix(model: &Model, data: &mut Data) -> Result<()> {
    ltdl_factor(&model.dof_tree(&data.subtree_end), &data.m, &mut data.l, &mut data.d)
}

/// `M⁻¹` from the factorization in `data.l`, `data.d`.
pub(crate) fn minv_from_factor(model: &Model, data: &mut Data) {
    ltdl_inverse(
        &model.dof_tree(&data.subtree_end),
        &data.l,
        &data.d,
        &mut data.minv,
        &mut data.terms,
    );
}

/// Inverse of the joint-space inertia matrix (CRBA and a tree-sparse `Lᵀ D L`
/// factorization).
pub fn compute_minverse<'d>(model: &Model, data: &'d mut Data, q: &[f64]) -> Result<MatRef<'d, f64>> {
    model.check_configuration("q", q)?;
    check_data(model, data)?;
    crba_unchecked(model, data, q);
    factor_mass_matrix(model, data)?;
    minv_from_factor(model, data);
    check_result_vec("inverse mass matrix", &data.minv)?;
    Ok(data.minv())
}

/// Centre of mass of the bodies (universe excluded): position, velocity and
/// acceleration (no gravity) in the world frame. Runs forward kinematics.
pub fn center_of_mass<'d>(model: &Model, data: &'d mut Data, q: &[f64], v: &[f64], a: &[f64]) -> Result<&'d Vec3> {
    crate::kinematics::forward_kinematics(model, data, q, v, a)?;
    let (mut m, mut h, mut mv, mut ma) = (0.0, Vec3::zeros(), Vec3::zeros(), Vec3::zeros());
    for i in 1..model.njoints() {
        let y = model.inertias[i].transformed(&data.o_mi[i]);
        let (ov, oa) = (&data.ov[i], &data.oa[i]);
        let hk = y.first_moment;
        m += y.mass;
        h += hk;
        // Σ m_k ẋ_k with ẋ = v + ω × c, Σ m_k ẍ_k with ẍ = a + α × c + ω × ẋ.
        let mvk = ov.linear * y.mass + ov.angular.cross(&hk);
        mv += mvk;
        ma += oa.linear * y.mass + oa.angular.cross(&hk) + ov.angular.cross(&mvk);
    }
    if m <= 0.0 {
        return Err(Error::Invalid(format!(
            "center_of_mass: model `{}` has no mass",
            model.name
        )));
    }
    data.mass = m;
    data.com = h / m;
    data.vcom = mv / m;
    data.acom = ma / m;
    check_com(data)?;
    Ok(&data.com)
}

/// Jacobian of the centre of mass (3 × nv, world frame); also updates `com`.
pub fn jacobian_center_of_mass<'d>(model: &Model, data: &'d mut Data, q: &[f64]) -> Result<MatRef<'d, f64>> {
    model.check_configuration("q", q)?;
    check_data(model, data)?;
    for i in 1..model.njoints() {
        placement_step(model, data, i, q);
        jacobian_step(model, data, i);
        data.o_ycrb[i] = model.inertias[i].transformed(&data.o_mi[i]);
    }
    for i in (1..model.njoints()).rev() {
        let p = model.parents[i];
        if p != 0 {
            let y = data.o_ycrb[i];
            data.o_ycrb[p] += y;
        }
    }
    let mut total = 0.0;
    let mut h = Vec3::zeros();
    for i in 1..model.njoints() {
        if model.parents[i] == 0 {
            total += data.o_ycrb[i].mass;
            h += data.o_ycrb[i].first_moment;
        }
    }
    if total <= 0.0 {
        return Err(Error::Invalid(format!(
            "jacobian_center_of_mass: model `{}` has no mass",
            model.name
        )));
    }
    for i in 1..model.njoints() {
        let jm = model.joints[i];
        let y = &data.o_ycrb[i];
        for k in jm.idx_v..jm.idx_v + jm.nv {
            let jk = &data.j[k];
            let col = (jk.linear * y.mass + jk.angular.cross(&y.first_moment)) / total;
            data.jcom[3 * k..3 * k + 3].copy_from_slice(col.as_slice());
        }
    }
    data.mass = total;
    data.com = h / total;
    check_com(data)?;
    check_result_vec("centre-of-mass Jacobian", &data.jcom)?;
    Ok(data.jacobian_com())
}

/// Checks the mass and the centre of mass with its velocity and acceleration.
fn check_com(data: &Data) -> Result<()> {
    let (c, v, a) = (&data.com, &data.vcom, &data.acom);
    check_result_vec(
        "centre of mass (mass, com, vcom, acom)",
        &[data.mass, c.x, c.y, c.z, v.x, v.y, v.z, a.x, a.y, a.z],
    )
}

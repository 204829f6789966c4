//! Constrained forward dynamics with rigid 3D (point) and 6D (frame) contacts, and its
//! derivatives.
//!
//! The KKT system `[[M, Jcᵀ], [Jc, 0]] [ddq; −λ] = [τ − nle; −γ]` is solved through the
//! tree-sparse factorization of M and the Cholesky factor of the Delassus matrix
//! `Λ = Jc M⁻¹ Jcᵀ`. The constraint is `g(q, v, ddq) = a_c + K_d v_c + K_p e = 0` (Baumgarte),
//! where `a_c` is the classical acceleration of the contact point (3D) or the spatial
//! acceleration of the contact frame (6D) in the contact's reference frame, `v_c` its
//! velocity and `e` its placement error with respect to `reference` (3D: `p − p_ref`,
//! 6D: `log6(refM⁻¹ oMc)` in LOCAL, rotated to world axes in LWA). λ is the force
//! (3D) or wrench (6D) the environment applies to the robot at the contact origin, in the
//! reference frame.
//!
//! Derivatives differentiate the KKT system: with `r1 = −∂(RNEA(q, v, ddq) − Jcᵀλ)` and
//! `r2 = −∂g`, `∂λ = Λ⁻¹ (r2 − Jc M⁻¹ r1)` and `∂ddq = M⁻¹ r1 + M⁻¹ Jcᵀ ∂λ`
//! (plain derivatives in LOCAL and LWA; q-derivatives along `q ⊕ δ`).

use crate::data::{Data, check_data};
use crate::derivatives::{rnea_derivatives_kernel, velocity_pass};
use crate::dynamics::{factor_mass_matrix, mass_matrix_column, minv_from_factor};
use crate::error::{Error, Result, check_results, check_vec};
use crate::kinematics::{jacobian_step, joint_motion, placement_step};
use crate::lie::{jlog6_blocks, log6};
use crate::linalg::{axpy, cholesky_factor, cholesky_solve, gemm, ltdl_solve_rows, reserve_packing_buffer};
use crate::model::{Model, NONE, ReferenceFrame};
use crate::spatial::{Force, Mat3, Motion, Se3, Vec3};
use faer::MatRef;

/// Kind of rigid contact.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ContactType {
    /// Point contact: the contact point does not accelerate (3 rows).
    Contact3D,
    /// Frame contact: the contact frame does not accelerate (6 rows).
    Contact6D,
}

/// A rigid contact between a point or frame of the robot and the world.
#[derive(Clone, Debug, PartialEq)]
pub struct ContactModel {
    /// 3D or 6D.
    pub kind: ContactType,
    /// Joint the contact frame moves with.
    pub joint: usize,
    /// Placement of the contact frame in the joint frame.
    pub placement: Se3,
    /// `Local` or `LocalWorldAligned`.
    pub reference_frame: ReferenceFrame,
    /// Baumgarte position gain.
    pub kp: f64,
    /// Baumgarte velocity gain.
    pub kd: f64,
    /// World placement the position term is measured against (identity by default).
    pub reference: Se3,
}

impl ContactModel {
    /// Contact at a joint-attached placement.
    pub fn new(
        model: &Model,
        kind: ContactType,
        joint: usize,
        placement: Se3,
        reference_frame: ReferenceFrame,
    ) -> Result<Self> {
        if joint == 0 || joint >= model.njoints() {
            return Err(Error::Invalid(format!(
                "contact: joint {joint} is not a moving joint of the model"
            )));
        }
        if reference_frame == ReferenceFrame::World {
            return Err(Error::Invalid(
                "contact: reference frame must be Local or LocalWorldAligned".into(),
            ));
        }
        Ok(Self {
            kind,
            joint,
            placement,
            reference_frame,
            kp: 0.0,
            kd: 0.0,
            reference: Se3::identity(),
        })
    }

    /// Contact at a frame of the model.
    pub fn from_frame(model: &Model, kind: ContactType, frame: usize, reference_frame: ReferenceFrame) -> Result<Self> {
        model.check_frame(frame)?;
        let fr = &model.frames()[frame];
        Self::new(model, kind, fr.parent_joint, fr.placement, reference_frame)
    }

    /// Number of constraint rows (3 or 6).
    pub fn size(&self) -> usize {
        match self.kind {
            ContactType::Contact3D => 3,
            ContactType::Contact6D => 6,
        }
    }
}

/// Workspace and results of the constrained dynamics for one set of contacts.
#[derive(Clone, Debug)]
pub struct ContactData {
    nc: usize,
    nv: usize,
    /// Hash of the tree of dofs of the model the data was created for.
    dof_tree_hash: u64,
    ncontacts: usize,
    /// Whether the last `constraint_dynamics` call succeeded (its state is the one the
    /// derivatives are taken at).
    solved: bool,
    q: Vec<f64>,
    v: Vec<f64>,
    /// Jc (nc × nv, column-major).
    jc: Vec<f64>,
    /// `G = M⁻¹ Jcᵀ`, stored transposed (nc × nv, column-major: row k of G is contiguous).
    jcminv: Vec<f64>,
    /// Cholesky factor of the Delassus matrix `Λ = Jc M⁻¹ Jcᵀ` (lower, nc × nc).
    delassus: Vec<f64>,
    gamma: Vec<f64>,
    lambda: Vec<f64>,
    ddq: Vec<f64>,
    /// `[P | Q]` (nv × (nv + nc), column-major) with `P = M⁻¹ − G Λ⁻¹ Gᵀ = ∂ddq/∂τ` and
    /// `Q = G Λ⁻¹`.
    pq: Vec<f64>,
    /// `[Qᵀ | Λ⁻¹]` (nc × (nv + nc), column-major).
    qt_linv: Vec<f64>,
    /// `∂τ/∂x − ∂(Jcᵀ λ)/∂x` of the RNEA at the solution (nv × nv, column-major), x = q, v;
    /// only written at dof pairs on one path to the root (zero elsewhere: the dense
    /// products of `kkt_derivatives` rely on it).
    b_dq: Vec<f64>,
    b_dv: Vec<f64>,
    /// `−∂g/∂x` of the constraint function at fixed ddq (nc × nv, column-major).
    r2_dq: Vec<f64>,
    r2_dv: Vec<f64>,
    ddq_dq: Vec<f64>,
    ddq_dv: Vec<f64>,
    dl_dq: Vec<f64>,
    dl_dv: Vec<f64>,
    dl_dtau: Vec<f64>,
    /// `[±b; r2]` ((nv + nc) × nv, column-major), the right-hand side of the products of
    /// `solution_derivatives`.
    stacked: Vec<f64>,
    chain: Vec<usize>,
}

impl ContactData {
    /// Allocates the workspace for these contacts. Fails if a contact is not attached to
    /// a moving joint of the model, if two contacts move with the same joint, or if the
    /// contacts have more rows than the model has degrees of freedom (in both cases
    /// their Delassus matrix would be singular).
    pub fn new(model: &Model, contacts: &[ContactModel]) -> Result<Self> {
        for (k, c) in contacts.iter().enumerate() {
            check_contact(model, k, c)?;
            if let Some(j) = contacts[..k].iter().position(|d| d.joint == c.joint) {
                // Rows of two contacts on one rigid body are the body's twist mapped by
                // 3 + 3 (or more) rows of rank at most 5 (or 6): dependent.
                return Err(Error::Invalid(format!(
                    "contacts {j} and {k} both move with joint `{}`: the rows of two contacts on one rigid body are linearly dependent (the Delassus matrix would be singular); one 6D contact constrains the whole body",
                    model.joint_names()[c.joint]
                )));
            }
        }
        let nc: usize = contacts.iter().map(|c| c.size()).sum();
        let nv = model.nv();
        if nc > nv {
            return Err(Error::Invalid(format!(
                "contacts: {} contacts have {nc} constraint rows, more than the nv = {nv} degrees of freedom of model `{}` (the Delassus matrix would be singular)",
                contacts.len(),
                model.name
            )));
        }
        let mut cdata = Self {
            nc,
            nv,
            dof_tree_hash: model.dof_tree_hash,
            ncontacts: contacts.len(),
            solved: false,
            q: vec![0.0; model.nq()],
            v: vec![0.0; nv],
            jc: vec![0.0; nc * nv],
            jcminv: vec![0.0; nc * nv],
            delassus: vec![0.0; nc * nc],
            gamma: vec![0.0; nc],
            lambda: vec![0.0; nc],
            ddq: vec![0.0; nv],
            pq: vec![0.0; nv * (nv + nc)],
            qt_linv: vec![0.0; nc * (nv + nc)],
            b_dq: vec![0.0; nv * nv],
            b_dv: vec![0.0; nv * nv],
            r2_dq: vec![0.0; nc * nv],
            r2_dv: vec![0.0; nc * nv],
            ddq_dq: vec![0.0; nv * nv],
            ddq_dv: vec![0.0; nv * nv],
            dl_dq: vec![0.0; nc * nv],
            dl_dv: vec![0.0; nc * nv],
            dl_dtau: vec![0.0; nc * nv],
            stacked: vec![0.0; (nv + nc) * nv],
            chain: Vec::with_capacity(nv),
        };
        let cd = &mut cdata;
        reserve_packing_buffer(&mut cd.ddq_dq, &cd.pq, &cd.stacked, (nv, nv + nc, nv));
        Ok(cdata)
    }

    /// Total number of constraint rows.
    pub fn nc(&self) -> usize {
        self.nc
    }

    /// Constrained joint accelerations.
    pub fn ddq(&self) -> &[f64] {
        &self.ddq
    }

    /// Stacked contact forces λ (environment on robot, in each contact's reference frame).
    pub fn lambda(&self) -> &[f64] {
        &self.lambda
    }

    /// Contact force of contact `k` as a 6D wrench (3D contacts: zero torque).
    pub fn contact_force(&self, contacts: &[ContactModel], k: usize) -> Force {
        let off: usize = contacts[..k].iter().map(|c| c.size()).sum();
        let l = &self.lambda[off..off + contacts[k].size()];
        match contacts[k].kind {
            ContactType::Contact3D => Force::new(Vec3::new(l[0], l[1], l[2]), Vec3::zeros()),
            ContactType::Contact6D => Force::new(Vec3::new(l[0], l[1], l[2]), Vec3::new(l[3], l[4], l[5])),
        }
    }

    /// Constraint Jacobian Jc (nc × nv).
    pub fn constraint_jacobian(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.jc, self.nc, self.nv)
    }

    /// ∂ddq/∂q (nv × nv).
    pub fn ddq_dq(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.ddq_dq, self.nv, self.nv)
    }

    /// ∂ddq/∂v (nv × nv).
    pub fn ddq_dv(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.ddq_dv, self.nv, self.nv)
    }

    /// ∂ddq/∂τ (nv × nv).
    pub fn ddq_dtau(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.pq[..self.nv * self.nv], self.nv, self.nv)
    }

    /// ∂λ/∂q (nc × nv).
    pub fn dlambda_dq(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.dl_dq, self.nc, self.nv)
    }

    /// ∂λ/∂v (nc × nv).
    pub fn dlambda_dv(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.dl_dv, self.nc, self.nv)
    }

    /// ∂λ/∂τ (nc × nv).
    pub fn dlambda_dtau(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.dl_dtau, self.nc, self.nv)
    }
}

fn check_sizes(model: &Model, contacts: &[ContactModel], cdata: &ContactData) -> Result<()> {
    let nc: usize = contacts.iter().map(|c| c.size()).sum();
    if nc != cdata.nc
        || contacts.len() != cdata.ncontacts
        || cdata.nv != model.nv()
        || cdata.dof_tree_hash != model.dof_tree_hash
    {
        return Err(Error::Invalid(format!(
            "contact data was created for {} contacts ({} rows, nv = {}, or another tree), called with {} contacts ({} rows, nv = {})",
            cdata.ncontacts,
            cdata.nc,
            cdata.nv,
            contacts.len(),
            nc,
            model.nv()
        )));
    }
    for (k, c) in contacts.iter().enumerate() {
        check_contact(model, k, c)?;
    }
    Ok(())
}

/// Checks that contact `k` is attached to a moving joint and has finite gains and
/// placements.
fn check_contact(model: &Model, k: usize, c: &ContactModel) -> Result<()> {
    if c.joint == 0 || c.joint >= model.njoints() {
        return Err(Error::Invalid(format!(
            "contact {k}: joint {} is not a moving joint of the model",
            c.joint
        )));
    }
    if !(c.kp.is_finite() && c.kd.is_finite() && c.placement.is_finite() && c.reference.is_finite()) {
        return Err(Error::Invalid(format!(
            "contact {k}: the gains kp = {}, kd = {} and the placements must be finite",
            c.kp, c.kd
        )));
    }
    Ok(())
}

/// One pass computing the mass matrix (in `data.m`) and the nonlinear effects (in
/// `data.nle`); leaves the drift accelerations (ddq = 0, gravity included) in `oa_gf`.
pub(crate) fn mass_matrix_and_nle(model: &Model, data: &mut Data, q: &[f64], v: &[f64]) {
    let nv = model.nv;
    data.oa_gf[0] = -model.gravity;
    for i in 1..model.njoints() {
        placement_step(model, data, i, q);
        jacobian_step(model, data, i);
        let p = model.parents[i];
        let oy = model.inertias[i].transformed(&data.o_mi[i]);
        data.o_ycrb[i] = oy;
        let vj = joint_motion(model, data, i, v);
        let ovp = data.ov[p];
        let ov = ovp + vj;
        let oa = data.oa_gf[p] + ovp.cross(&vj);
        data.ov[i] = ov;
        data.oa_gf[i] = oa;
        let oh = oy.mul_motion(&ov);
        data.of[i] = oy.mul_motion(&oa) + ov.cross_force(&oh);
    }
    for i in (1..model.njoints()).rev() {
        let jm = model.joints[i];
        let y = data.o_ycrb[i];
        let f = data.of[i];
        for c in jm.idx_v..jm.idx_v + jm.nv {
            data.nle[c] = data.j[c].dot(&f);
            mass_matrix_column(model, data, c, jm.idx_v + jm.nv - 1, &y.mul_motion(&data.j[c]));
        }
        let p = model.parents[i];
        if p != 0 {
            data.o_ycrb[p] += y;
            data.of[p] += f;
        }
    }
    for k in 0..nv {
        data.m[k * nv + k] += model.armature[k];
    }
}

/// Placement-error twist of a 6D contact (LOCAL coordinates).
fn placement_error(c: &ContactModel, o_mc: &Se3) -> Motion {
    log6(&c.reference.inv_compose(o_mc))
}

/// Constrained forward dynamics: solves for `ddq` and `λ` (read with
/// [`ContactData::ddq`], [`ContactData::lambda`]). Exact KKT solve, no regularization.
#[allow(clippy::too_many_arguments)]
pub fn constraint_dynamics(
    model: &Model,
    data: &mut Data,
    contacts: &[ContactModel],
    cdata: &mut ContactData,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
) -> Result<()> {
    model.check_configuration("q", q)?;
    check_data(model, data)?;
    check_vec("v", v, model.nv)?;
    check_vec("tau", tau, model.nv)?;
    check_sizes(model, contacts, cdata)?;
    let (nv, nc) = (model.nv, cdata.nc);
    cdata.solved = false;
    cdata.q.copy_from_slice(q);
    cdata.v.copy_from_slice(v);
    mass_matrix_and_nle(model, data, q, v);
    factor_mass_matrix(model, data)?;
    // Unconstrained accelerations.
    for k in 0..nv {
        cdata.ddq[k] = tau[k] - data.nle[k];
    }
    ltdl_solve_rows(&model.dof_tree(&data.subtree_end), 1, &data.l, &data.d, &mut cdata.ddq);
    contact_jacobian_and_drift(model, data, contacts, cdata);
    delassus_factor(model, data, cdata)?;
    // λ = −Λ⁻¹ (Jc ddq_free + γ).
    for r in 0..nc {
        cdata.lambda[r] = -cdata.gamma[r];
    }
    for k in 0..nv {
        axpy(-cdata.ddq[k], &cdata.jc[k * nc..(k + 1) * nc], &mut cdata.lambda);
    }
    cholesky_solve(nc, &cdata.delassus, &mut cdata.lambda);
    // ddq = ddq_free + M⁻¹ Jcᵀ λ.
    for k in 0..nv {
        let s: f64 = cdata.jcminv[k * nc..(k + 1) * nc]
            .iter()
            .zip(&cdata.lambda)
            .map(|(a, b)| a * b)
            .sum();
        cdata.ddq[k] += s;
    }
    check_results(&[
        ("constrained ddq", &cdata.ddq),
        ("contact forces lambda", &cdata.lambda),
    ])?;
    data.ddq.copy_from_slice(&cdata.ddq);
    cdata.solved = true;
    Ok(())
}

/// The contact Jacobian `Jc` (columns over each contact's support) and the drift `γ`
/// of the constraint accelerations into `cdata`, after the kinematic pass of the
/// mass matrix.
fn contact_jacobian_and_drift(model: &Model, data: &Data, contacts: &[ContactModel], cdata: &mut ContactData) {
    let nc = cdata.nc;
    cdata.jc.fill(0.0);
    let g = model.gravity;
    let mut off = 0;
    for c in contacts {
        let i = c.joint;
        let o_mc = data.o_mi[i].compose(&c.placement);
        let p = o_mc.translation;
        let rt = o_mc.rotation.transpose();
        let ov = data.ov[i];
        let oa0 = data.oa_gf[i] + g;
        let mut k = model.last_dof(i);
        while k != NONE {
            let col = contact_row(c, &o_mc, &data.j[k]);
            for r in 0..c.size() {
                cdata.jc[k * nc + off + r] = col[r];
            }
            k = model.dof_parent[k];
        }
        let gam = contact_constraint(c, &o_mc, &ov, &oa0, &p, &rt);
        cdata.gamma[off..off + c.size()].copy_from_slice(&gam[..c.size()]);
        off += c.size();
    }
}

/// `Jc M⁻¹` (rows of `M⁻¹ Jcᵀ`), the Delassus matrix `Jc M⁻¹ Jcᵀ` and its Cholesky
/// factor, from the factorization of `M`.
fn delassus_factor(model: &Model, data: &Data, cdata: &mut ContactData) -> Result<()> {
    let (nv, nc) = (model.nv, cdata.nc);
    cdata.jcminv.copy_from_slice(&cdata.jc);
    ltdl_solve_rows(
        &model.dof_tree(&data.subtree_end),
        nc,
        &data.l,
        &data.d,
        &mut cdata.jcminv,
    );
    cdata.delassus.fill(0.0);
    for k in 0..nv {
        let a = &cdata.jcminv[k * nc..(k + 1) * nc];
        let b = &cdata.jc[k * nc..(k + 1) * nc];
        for (bj, &bv) in b.iter().enumerate() {
            if bv != 0.0 {
                axpy(bv, a, &mut cdata.delassus[bj * nc..(bj + 1) * nc]);
            }
        }
    }
    cholesky_factor(nc, &mut cdata.delassus, "Delassus matrix Jc M⁻¹ Jcᵀ")?;
    Ok(())
}

/// Constraint row block (3 or 6 entries) of one world Jacobian column.
#[inline]
fn contact_row(c: &ContactModel, o_mc: &Se3, j: &Motion) -> [f64; 6] {
    let p = &o_mc.translation;
    match (c.kind, c.reference_frame) {
        (ContactType::Contact3D, ReferenceFrame::Local) => {
            let jp = j.shifted_to(p).linear;
            let l = o_mc.rotation.tr_mul(&jp);
            [l.x, l.y, l.z, 0.0, 0.0, 0.0]
        }
        (ContactType::Contact3D, _) => {
            let l = j.shifted_to(p).linear;
            [l.x, l.y, l.z, 0.0, 0.0, 0.0]
        }
        (ContactType::Contact6D, ReferenceFrame::Local) => o_mc.act_inv_motion(j).to_array(),
        (ContactType::Contact6D, _) => j.shifted_to(p).to_array(),
    }
}

/// Value of the constraint function `g = a_c + Kd v_c + Kp e` for body velocity `ov` and
/// spatial acceleration `oa` (world frame, no gravity).
fn contact_constraint(c: &ContactModel, o_mc: &Se3, ov: &Motion, oa: &Motion, p: &Vec3, rt: &Mat3) -> [f64; 6] {
    match c.kind {
        ContactType::Contact3D => {
            let gw = contact3d_world(c, ov, oa, p);
            let g = if c.reference_frame == ReferenceFrame::Local {
                rt * gw
            } else {
                gw
            };
            [g.x, g.y, g.z, 0.0, 0.0, 0.0]
        }
        ContactType::Contact6D => {
            let e = if c.kp != 0.0 {
                placement_error(c, o_mc)
            } else {
                Motion::zero()
            };
            let g = if c.reference_frame == ReferenceFrame::Local {
                o_mc.act_inv_motion(oa) + o_mc.act_inv_motion(ov) * c.kd + e * c.kp
            } else {
                let r = &o_mc.rotation;
                oa.shifted_to(p) + ov.shifted_to(p) * c.kd + Motion::new(r * e.linear, r * e.angular) * c.kp
            };
            g.to_array()
        }
    }
}

/// World-axes 3D constraint: `ẍ + Kd ẋ + Kp (p − p_ref)`.
#[inline]
fn contact3d_world(c: &ContactModel, ov: &Motion, oa: &Motion, p: &Vec3) -> Vec3 {
    let vp = ov.shifted_to(p).linear;
    let ap = oa.shifted_to(p).linear;
    ap + ov.angular.cross(&vp) + vp * c.kd + (p - c.reference.translation) * c.kp
}

/// Derivatives of the constrained dynamics at the point of the last
/// [`constraint_dynamics`] call (same `data` and `cdata`): `ddq_dq`, `ddq_dv`,
/// `ddq_dtau`, `dlambda_dq`, `dlambda_dv`, `dlambda_dtau`. Fails if that call failed or
/// there was none.
pub fn compute_constraint_dynamics_derivatives(
    model: &Model,
    data: &mut Data,
    contacts: &[ContactModel],
    cdata: &mut ContactData,
) -> Result<()> {
    check_sizes(model, contacts, cdata)?;
    check_data(model, data)?;
    if !cdata.solved {
        return Err(Error::Invalid(
            "compute_constraint_dynamics_derivatives: the last constraint_dynamics call with this contact data failed, or there was none"
                .into(),
        ));
    }
    inverse_dynamics_derivatives(model, data, cdata);
    cdata.r2_dq.fill(0.0);
    cdata.r2_dv.fill(0.0);
    let mut off = 0;
    for (ci, c) in contacts.iter().enumerate() {
        let pt = ContactPoint::of(model, data, c);
        support_chain(model, c.joint, &mut cdata.chain);
        let f6 = cdata.contact_force(contacts, ci);
        subtract_force_derivative(model, data, c, &pt, &f6, &cdata.chain, &mut cdata.b_dq);
        let nc = cdata.nc;
        for &cc in &cdata.chain {
            let (gq, gv) = constraint_derivative_columns(data, c, &pt, cc);
            for rrow in 0..c.size() {
                cdata.r2_dq[cc * nc + off + rrow] = -gq[rrow];
                cdata.r2_dv[cc * nc + off + rrow] = -gv[rrow];
            }
        }
        off += c.size();
    }
    solution_derivatives(model, data, cdata)
}

/// `∂τ/∂q`, `∂τ/∂v` of RNEA at the last solve's `(q, v, ddq)` into `cdata.b_dq`,
/// `cdata.b_dv`; the factorization of M from `constraint_dynamics` stays valid (same q).
fn inverse_dynamics_derivatives(model: &Model, data: &mut Data, cdata: &mut ContactData) {
    let q = std::mem::take(&mut cdata.q);
    let v = std::mem::take(&mut cdata.v);
    let mut m = std::mem::take(&mut data.m);
    velocity_pass(model, data, &q, &v);
    rnea_derivatives_kernel(model, data, &v, &cdata.ddq, &mut cdata.b_dq, &mut cdata.b_dv, &mut m);
    data.m = m;
    cdata.q = q;
    cdata.v = v;
}

/// What the derivatives of one contact share over its support: the contact frame's
/// placement and origin, the world velocity and acceleration (gravity included) of its
/// joint, the velocity of the origin, gravity, and for 6D contacts with `Kp ≠ 0` the
/// placement error and the blocks of its `Jlog6`.
struct ContactPoint {
    o_mc: Se3,
    p: Vec3,
    ov: Motion,
    oa: Motion,
    vp: Vec3,
    g: Motion,
    e: Motion,
    jlog: (Mat3, Mat3),
}

impl ContactPoint {
    #[inline]
    fn of(model: &Model, data: &Data, c: &ContactModel) -> Self {
        let o_mc = data.o_mi[c.joint].compose(&c.placement);
        let p = o_mc.translation;
        let (ov, g) = (data.ov[c.joint], model.gravity);
        let e = if c.kind == ContactType::Contact6D && c.kp != 0.0 {
            placement_error(c, &o_mc)
        } else {
            Motion::zero()
        };
        Self {
            o_mc,
            p,
            ov,
            oa: data.oa_gf[c.joint] + g,
            vp: ov.shifted_to(&p).linear,
            g,
            jlog: jlog6_blocks(&e),
            e,
        }
    }
}

/// The degrees of freedom supporting joint `joint`, from the last one up to the root.
#[inline]
fn support_chain(model: &Model, joint: usize, chain: &mut Vec<usize>) {
    chain.clear();
    let mut k = model.last_dof(joint);
    while k != NONE {
        chain.push(k);
        k = model.dof_parent[k];
    }
}

/// Subtracts `∂(Jcᵀ λ)/∂q` of contact `c` (force `f6` in its frame) from `b_dq`, over
/// the support `chain`.
#[inline(always)]
fn subtract_force_derivative(
    model: &Model,
    data: &Data,
    c: &ContactModel,
    pt: &ContactPoint,
    f6: &Force,
    chain: &[usize],
    b_dq: &mut [f64],
) {
    let (nv, p) = (model.nv, pt.p);
    let local = c.reference_frame == ReferenceFrame::Local;
    // World wrench at the world origin and world linear force.
    let (of, flin) = if local {
        let w = pt.o_mc.act_force(f6);
        (w, w.linear)
    } else {
        (Force::new(f6.linear, f6.angular + p.cross(&f6.linear)), f6.linear)
    };
    for &rr in chain {
        let jr = data.j[rr];
        for &cc in chain {
            let jc = data.j[cc];
            let c_below_or_same = model.dof_joint[cc] <= model.dof_joint[rr];
            let mut val = 0.0;
            if local {
                if !c_below_or_same {
                    val = jr.dot(&jc.cross_force(&of));
                }
            } else {
                let jp = jc.shifted_to(&p).linear;
                val = jr.angular.dot(&jp.cross(&flin));
                if c_below_or_same {
                    val -= jr.dot(&jc.cross_force(&of));
                }
            }
            b_dq[cc * nv + rr] -= val;
        }
    }
}

/// Column `cc` of `∂g/∂q` and `∂g/∂v`, the derivatives of contact `c`'s constraint
/// acceleration `g` (its first `c.size()` entries).
#[inline(always)]
fn constraint_derivative_columns(data: &Data, c: &ContactModel, pt: &ContactPoint, cc: usize) -> ([f64; 6], [f64; 6]) {
    let (o_mc, p, ov, oa, vp, g) = (&pt.o_mc, &pt.p, &pt.ov, &pt.oa, &pt.vp, &pt.g);
    let r = &o_mc.rotation;
    let (w, alpha) = (ov.angular, oa.angular);
    let local = c.reference_frame == ReferenceFrame::Local;
    let jc = data.j[cc];
    let dvdq = data.dvdq[cc];
    let dadqk = data.dadq[cc] + g.cross(&jc);
    let dov_q = jc.cross(ov) + dvdq;
    let doa_q = jc.cross(oa) + dadqk - ov.cross(&dvdq);
    let doa_v = data.dadv[cc] - ov.cross(&jc);
    let jp = jc.shifted_to(p).linear;
    match c.kind {
        ContactType::Contact3D => {
            let dvp_q = dov_q.shifted_to(p).linear + w.cross(&jp);
            let dap_q = doa_q.shifted_to(p).linear + alpha.cross(&jp);
            let dx_q = dap_q + dov_q.angular.cross(vp) + w.cross(&dvp_q);
            let mut dq = dx_q + dvp_q * c.kd + jp * c.kp;
            let dx_v = doa_v.shifted_to(p).linear + jc.angular.cross(vp) + w.cross(&jp);
            let mut dv = dx_v + jp * c.kd;
            if local {
                let gw = contact3d_world(c, ov, oa, p);
                dq = r.tr_mul(&(dq + gw.cross(&jc.angular)));
                dv = r.tr_mul(&dv);
            }
            ([dq.x, dq.y, dq.z, 0.0, 0.0, 0.0], [dv.x, dv.y, dv.z, 0.0, 0.0, 0.0])
        }
        ContactType::Contact6D => {
            let (e, (jl, jc_blk)) = (pt.e, pt.jlog);
            let jloc = o_mc.act_inv_motion(&jc);
            let de = Motion::new(jl * jloc.linear + jc_blk * jloc.angular, jl * jloc.angular);
            if local {
                let dq =
                    o_mc.act_inv_motion(&(dadqk - ov.cross(&dvdq))) + o_mc.act_inv_motion(&dvdq) * c.kd + de * c.kp;
                let dv = o_mc.act_inv_motion(&doa_v) + jloc * c.kd;
                (dq.to_array(), dv.to_array())
            } else {
                let mut dq = doa_q.shifted_to(p);
                dq.linear += alpha.cross(&jp);
                let mut dvel = dov_q.shifted_to(p);
                dvel.linear += w.cross(&jp);
                let de_w = Motion::new(
                    jc.angular.cross(&(r * e.linear)) + r * de.linear,
                    jc.angular.cross(&(r * e.angular)) + r * de.angular,
                );
                let dq = dq + dvel * c.kd + de_w * c.kp;
                let dv = doa_v.shifted_to(p) + jc.shifted_to(p) * c.kd;
                (dq.to_array(), dv.to_array())
            }
        }
    }
}

/// From `∂τ` (`b_*`) and `−∂g` (`r2_*`): the derivatives of `ddq` and `λ` through the
/// inverse KKT matrix, `∂ddq/∂τ = P`, `∂λ/∂τ = −Qᵀ`, each checked finite.
fn solution_derivatives(model: &Model, data: &mut Data, cdata: &mut ContactData) -> Result<()> {
    let (nv, nc) = (model.nv, cdata.nc);
    kkt_inverse_blocks(model, data, cdata);
    let cd = &mut *cdata;
    for (b, r2, ddq_dx, dl_dx) in [
        (&cd.b_dq, &cd.r2_dq, &mut cd.ddq_dq, &mut cd.dl_dq),
        (&cd.b_dv, &cd.r2_dv, &mut cd.ddq_dv, &mut cd.dl_dv),
    ] {
        kkt_derivatives((nv, nc), (&cd.pq, &cd.qt_linv), (b, r2), ddq_dx, dl_dx, &mut cd.stacked);
    }
    for (x, y) in cdata.dl_dtau.iter_mut().zip(&cdata.qt_linv[..nc * nv]) {
        *x = -y;
    }
    check_results(&[
        ("ddq_dq", &cdata.ddq_dq),
        ("ddq_dv", &cdata.ddq_dv),
        ("ddq_dtau", &cdata.pq[..nv * nv]),
        ("dlambda_dq", &cdata.dl_dq),
        ("dlambda_dv", &cdata.dl_dv),
        ("dlambda_dtau", &cdata.dl_dtau),
    ])
}

/// The blocks of the inverse KKT matrix at the last `constraint_dynamics`: `M⁻¹` (from
/// the factorization of M), `Λ⁻¹` (from its Cholesky factor), `Qᵀ = Λ⁻¹ Gᵀ`, `Q` and
/// `P = M⁻¹ − Q Gᵀ` (`G = M⁻¹ Jcᵀ`).
fn kkt_inverse_blocks(model: &Model, data: &mut Data, cdata: &mut ContactData) {
    let (nv, nc) = (model.nv, cdata.nc);
    minv_from_factor(model, data);
    let (qt, linv) = cdata.qt_linv.split_at_mut(nc * nv);
    linv.fill(0.0);
    for a in 0..nc {
        let col = &mut linv[a * nc..(a + 1) * nc];
        col[a] = 1.0;
        cholesky_solve(nc, &cdata.delassus, col);
    }
    // `jcminv` is Gᵀ (nc × nv).
    gemm(qt, linv, &cdata.jcminv, (nc, nc, nv), false, 1.0);
    let (p, q) = cdata.pq.split_at_mut(nv * nv);
    for k in 0..nv {
        for a in 0..nc {
            q[a * nv + k] = qt[k * nc + a];
        }
    }
    p.copy_from_slice(&data.minv[..nv * nv]);
    gemm(p, q, &cdata.jcminv, (nv, nc, nv), true, -1.0);
}

/// Derivatives of ddq and λ from `b = ∂τ − ∂(Jcᵀλ)` (nv × nv) and `r2 = −∂g` (nc × nv)
/// with the KKT inverse blocks `[P | Q]` and `[Qᵀ | Λ⁻¹]`: `∂λ = [Qᵀ | Λ⁻¹] [b; r2]`, then
/// `∂ddq = [P | Q] [−b; r2]`, two products on the stacked right-hand side in `s`.
fn kkt_derivatives(
    (nv, nc): (usize, usize),
    (pq, qt_linv): (&[f64], &[f64]),
    (b, r2): (&[f64], &[f64]),
    ddq_dx: &mut [f64],
    dl_dx: &mut [f64],
    s: &mut [f64],
) {
    let n = nv + nc;
    for (c, col) in s.chunks_exact_mut(n).enumerate() {
        col[..nv].copy_from_slice(&b[c * nv..(c + 1) * nv]);
        col[nv..].copy_from_slice(&r2[c * nc..(c + 1) * nc]);
    }
    gemm(dl_dx, qt_linv, s, (nc, n, nv), false, 1.0);
    for col in s.chunks_exact_mut(n) {
        col[..nv].iter_mut().for_each(|x| *x = -*x);
    }
    gemm(ddq_dx, pq, s, (nv, n, nv), false, 1.0);
}

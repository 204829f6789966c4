//! Preallocated workspace and results of the algorithms.
//!
//! Spatial quantities are stored in the world frame (Featherstone's "spatial"
//! formulation, Pinocchio's `WORLD` convention), except those of the local-frame RNEA
//! (`rnea`, `nonlinear_effects`, `generalized_gravity`: joint velocities, accelerations and
//! forces in each joint's own frame, as Pinocchio's `data.v`, `data.a_gf`, `data.f`). Dense matrices are stored as column-major `Vec<f64>` and exposed as faer
//! views.

use crate::error::{Error, Result};
use crate::linalg::{DENSE_TREE_PRODUCT, reserve_packing_buffer};
use crate::model::Model;
use crate::spatial::{Force, Inertia, Mat3, Motion, Se3, Sym6, Vec3};
use faer::MatRef;
use std::sync::atomic::{AtomicU8, Ordering};

/// Workspace of every algorithm for one model; create it with [`Model::create_data`].
/// After creation no algorithm allocates. When an algorithm returns an error, the
/// quantities it writes are unspecified until the next successful call.
#[derive(Clone, Debug)]
pub struct Data {
    pub(crate) nv: usize,
    /// Hash of the tree of dofs of the model the data was created for.
    pub(crate) dof_tree_hash: u64,
    /// Subtree ends of the dofs ([`Model::dof_subtree_ends`]).
    pub(crate) subtree_end: Vec<usize>,
    // Per joint.
    pub(crate) li_mi: Vec<Se3>,
    pub(crate) o_mi: Vec<Se3>,
    pub(crate) ov: Vec<Motion>,
    pub(crate) oa: Vec<Motion>,
    pub(crate) oa_gf: Vec<Motion>,
    pub(crate) o_y: Vec<Inertia>,
    pub(crate) o_ycrb: Vec<Inertia>,
    pub(crate) oh: Vec<Force>,
    pub(crate) of: Vec<Force>,
    /// Joint velocities, accelerations (gravity included) and transmitted forces in each
    /// joint's own frame (the local-frame RNEA).
    pub(crate) v: Vec<Motion>,
    pub(crate) a_gf: Vec<Motion>,
    pub(crate) f: Vec<Force>,
    pub(crate) c: Vec<Motion>,
    pub(crate) ia: Vec<Sym6>,
    pub(crate) pa: Vec<Force>,
    pub(crate) dinv: Vec<[[f64; 6]; 6]>,
    pub(crate) tcrb: Vec<Mat3>,
    pub(crate) hcrb: Vec<Force>,
    // Per degree of freedom.
    pub(crate) j: Vec<Motion>,
    pub(crate) dvdq: Vec<Motion>,
    pub(crate) dadq: Vec<Motion>,
    pub(crate) dadv: Vec<Motion>,
    pub(crate) u: Vec<Force>,
    pub(crate) udinv: Vec<Force>,
    pub(crate) u_tau: Vec<f64>,
    // Per frame.
    pub(crate) o_mf: Vec<Se3>,
    // Results.
    pub(crate) tau: Vec<f64>,
    pub(crate) nle: Vec<f64>,
    pub(crate) g: Vec<f64>,
    pub(crate) ddq: Vec<f64>,
    /// M (n × n, column-major). Like `dtau_dq` and `dtau_dv`, only its entries at dof
    /// pairs on one path to the root are ever written: the others stay zero from the
    /// allocation, so the algorithms do not clear them.
    pub(crate) m: Vec<f64>,
    pub(crate) minv: Vec<f64>,
    pub(crate) dtau_dq: Vec<f64>,
    pub(crate) dtau_dv: Vec<f64>,
    pub(crate) ddq_dq: Vec<f64>,
    pub(crate) ddq_dv: Vec<f64>,
    /// Scratch list of (offset, coefficient) pairs for the tree-sparse kernels.
    pub(crate) terms: Vec<(usize, f64)>,
    pub(crate) l: Vec<f64>,
    pub(crate) d: Vec<f64>,
    pub(crate) jcom: Vec<f64>,
    pub(crate) mass: f64,
    pub(crate) com: Vec3,
    pub(crate) vcom: Vec3,
    pub(crate) acom: Vec3,
    /// What the last algorithm run on this data left in it, for the `_reusing_` variants.
    pub(crate) last: LastRun,
}

/// What the last algorithm run on a [`Data`] left in it: nothing usable (every
/// algorithm clears the record on entry, in `check_data`), the joint placements at `q`
/// (`forward_kinematics_placements`), or the ABA at `(q, v, tau)`; with its inputs.
#[derive(Debug)]
pub(crate) struct LastRun {
    kind: AtomicU8,
    inputs: Vec<f64>,
}

/// Kinds of [`LastRun`].
pub(crate) const LEFT_NOTHING: u8 = 0;
pub(crate) const LEFT_PLACEMENTS: u8 = 1;
pub(crate) const LEFT_ABA: u8 = 2;

impl LastRun {
    fn new(len: usize) -> Self {
        Self {
            kind: AtomicU8::new(LEFT_NOTHING),
            inputs: vec![0.0; len],
        }
    }

    /// Marks the data as overwritten (through `&Data`: atomic, so `Data` stays `Sync`).
    pub(crate) fn clear(&self) {
        self.kind.store(LEFT_NOTHING, Ordering::Relaxed);
    }

    /// Records that `kind` ran successfully on the concatenated `inputs`.
    pub(crate) fn record(&mut self, kind: u8, inputs: &[&[f64]]) {
        let mut k = 0;
        for part in inputs {
            self.inputs[k..k + part.len()].copy_from_slice(part);
            k += part.len();
        }
        self.kind.store(kind, Ordering::Relaxed);
    }

    /// Whether the last run was one of `kinds` on these inputs (bit for bit).
    pub(crate) fn was(&self, kinds: &[u8], inputs: &[&[f64]]) -> bool {
        if !kinds.contains(&self.kind.load(Ordering::Relaxed)) {
            return false;
        }
        let mut k = 0;
        for part in inputs {
            let rec = &self.inputs[k..k + part.len()];
            if !rec.iter().zip(part.iter()).all(|(a, b)| a.to_bits() == b.to_bits()) {
                return false;
            }
            k += part.len();
        }
        true
    }
}

impl Clone for LastRun {
    fn clone(&self) -> Self {
        Self {
            kind: AtomicU8::new(self.kind.load(Ordering::Relaxed)),
            inputs: self.inputs.clone(),
        }
    }
}

/// Checks that `data` was created for a model of the same shape as `model` (the same
/// tree of degrees of freedom: the dof-pair matrices rely on it, see [`Data::m`]), and
/// that the model's public armature vector has its length. Every algorithm starts with
/// it, so it also marks the results of the last `aba` as overwritten.
pub(crate) fn check_data(model: &Model, data: &Data) -> Result<()> {
    if model.armature.len() != model.nv() {
        return Err(Error::Dimension {
            what: format!("model `{}`: armature", model.name),
            expected: model.nv(),
            got: model.armature.len(),
        });
    }
    if data.li_mi.len() != model.njoints()
        || data.nv != model.nv()
        || data.o_mf.len() != model.nframes()
        || data.dof_tree_hash != model.dof_tree_hash
    {
        return Err(Error::Invalid(format!(
            "data was created for a model with {} joints, nv = {}, {} frames (or another tree); model `{}` has {} joints, nv = {}, {} frames",
            data.li_mi.len(),
            data.nv,
            data.o_mf.len(),
            model.name,
            model.njoints(),
            model.nv(),
            model.nframes()
        )));
    }
    data.last.clear();
    Ok(())
}

impl Data {
    /// Allocates the workspace for `model`.
    pub fn new(model: &Model) -> Self {
        let n = model.njoints();
        let nv = model.nv();
        let nf = model.nframes();
        let mut data = Self {
            nv,
            dof_tree_hash: model.dof_tree_hash,
            subtree_end: model.dof_subtree_ends(),
            li_mi: vec![Se3::identity(); n],
            o_mi: vec![Se3::identity(); n],
            ov: vec![Motion::zero(); n],
            oa: vec![Motion::zero(); n],
            oa_gf: vec![Motion::zero(); n],
            o_y: vec![Inertia::zero(); n],
            o_ycrb: vec![Inertia::zero(); n],
            oh: vec![Force::zero(); n],
            of: vec![Force::zero(); n],
            v: vec![Motion::zero(); n],
            a_gf: vec![Motion::zero(); n],
            f: vec![Force::zero(); n],
            c: vec![Motion::zero(); n],
            ia: vec![Sym6::default(); n],
            pa: vec![Force::zero(); n],
            dinv: vec![[[0.0; 6]; 6]; n],
            tcrb: vec![Mat3::zeros(); n],
            hcrb: vec![Force::zero(); n],
            j: vec![Motion::zero(); nv],
            dvdq: vec![Motion::zero(); nv],
            dadq: vec![Motion::zero(); nv],
            dadv: vec![Motion::zero(); nv],
            u: vec![Force::zero(); nv],
            udinv: vec![Force::zero(); nv],
            u_tau: vec![0.0; nv],
            o_mf: vec![Se3::identity(); nf],
            tau: vec![0.0; nv],
            nle: vec![0.0; nv],
            g: vec![0.0; nv],
            ddq: vec![0.0; nv],
            m: vec![0.0; nv * nv],
            minv: vec![0.0; nv * nv],
            dtau_dq: vec![0.0; nv * nv],
            dtau_dv: vec![0.0; nv * nv],
            ddq_dq: vec![0.0; nv * nv],
            ddq_dv: vec![0.0; nv * nv],
            terms: Vec::with_capacity(nv + 1),
            l: vec![0.0; model.dof_anc_start[nv]],
            d: vec![0.0; nv],
            jcom: vec![0.0; 3 * nv],
            last: LastRun::new(model.nq() + 2 * nv),
            mass: 0.0,
            com: Vec3::zeros(),
            vcom: Vec3::zeros(),
            acom: Vec3::zeros(),
        };
        if nv >= DENSE_TREE_PRODUCT {
            reserve_packing_buffer(&mut data.ddq_dq, &data.minv, &data.dtau_dq, (nv, nv, nv));
        }
        data
    }

    /// Placement of joint frame `i` in the world (`oMi`). Panics if the index is out of range.
    pub fn joint_placement(&self, i: usize) -> &Se3 {
        &self.o_mi[i]
    }

    /// Placement of joint `i` in its parent joint frame (`liMi`). Panics if the index is out of range.
    pub fn joint_relative_placement(&self, i: usize) -> &Se3 {
        &self.li_mi[i]
    }

    /// Placement of frame `f` in the world (`oMf`), after `update_frame_placements`. Panics if the index is out of range.
    pub fn frame_placement(&self, f: usize) -> &Se3 {
        &self.o_mf[f]
    }

    /// Joint torques of the last `rnea` (or `compute_rnea_derivatives`).
    pub fn tau(&self) -> &[f64] {
        &self.tau
    }

    /// Nonlinear effects `C(q, v) v + g(q)` of the last `nonlinear_effects`.
    pub fn nle(&self) -> &[f64] {
        &self.nle
    }

    /// Generalized gravity `g(q)` of the last `generalized_gravity`.
    pub fn generalized_gravity(&self) -> &[f64] {
        &self.g
    }

    /// Joint accelerations of the last `aba` (or `compute_aba_derivatives`).
    pub fn ddq(&self) -> &[f64] {
        &self.ddq
    }

    /// Joint-space inertia matrix (full symmetric), after `crba` or the derivatives.
    pub fn mass_matrix(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.m, self.nv, self.nv)
    }

    /// Inverse of the mass matrix, after `compute_minverse` or `compute_aba_derivatives`.
    pub fn minv(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.minv, self.nv, self.nv)
    }

    /// ∂tau/∂q of the last `compute_rnea_derivatives` (or, after `compute_aba_derivatives`,
    /// at the accelerations it computed).
    pub fn dtau_dq(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.dtau_dq, self.nv, self.nv)
    }

    /// ∂tau/∂v of the last `compute_rnea_derivatives` (or, after `compute_aba_derivatives`,
    /// at the accelerations it computed).
    pub fn dtau_dv(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.dtau_dv, self.nv, self.nv)
    }

    /// ∂ddq/∂q of the last `compute_aba_derivatives`.
    pub fn ddq_dq(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.ddq_dq, self.nv, self.nv)
    }

    /// ∂ddq/∂v of the last `compute_aba_derivatives`.
    pub fn ddq_dv(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.ddq_dv, self.nv, self.nv)
    }

    /// Total mass (universe excluded), after `center_of_mass` or `jacobian_center_of_mass`.
    pub fn total_mass(&self) -> f64 {
        self.mass
    }

    /// Centre of mass in the world, after `center_of_mass`.
    pub fn com(&self) -> &Vec3 {
        &self.com
    }

    /// Velocity of the centre of mass, after `center_of_mass` with a velocity.
    pub fn vcom(&self) -> &Vec3 {
        &self.vcom
    }

    /// Acceleration of the centre of mass (no gravity), after `center_of_mass` with an acceleration.
    pub fn acom(&self) -> &Vec3 {
        &self.acom
    }

    /// Jacobian of the centre of mass (3 × nv), after `jacobian_center_of_mass`.
    pub fn jacobian_com(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.jcom, 3, self.nv)
    }

    /// World-frame Jacobian column of degree of freedom `k`, after a kinematic pass. Panics if the index is out of range.
    pub fn joint_jacobian_column(&self, k: usize) -> &Motion {
        &self.j[k]
    }

    /// Spatial force transmitted from the parent to the subtree of joint `i` (gravity
    /// included), in the frame of joint `i` (Pinocchio's `data.f[i]`), after `rnea`,
    /// `nonlinear_effects` or `generalized_gravity`. Panics if `i` is out of range.
    pub fn joint_force_local(&self, i: usize) -> &Force {
        &self.f[i]
    }
}

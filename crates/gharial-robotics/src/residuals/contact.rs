//! Residuals of a contact force `λ_k(x, u)` of the constrained dynamics: tracking,
//! friction cones and the contact wrench cone of a rectangular foot.
//!
//! `λ` is the force (3D contact) or wrench (6D contact, `[force, torque]` about the
//! contact origin) the environment applies to the robot, in the contact's reference
//! frame, from [`MultibodyConstraintFwdDynamics::contact_forces`]; its derivatives come
//! from [`MultibodyConstraintFwdDynamics::contact_force_jacobians`]. A residual is a map
//! `r = m(f)` of the first `nf` entries `f` of `λ_k` (a [`ForceMap`]), so that
//! `∂r/∂x = ∂m/∂f · ∂f/∂x` and `∂r/∂u = ∂m/∂f · ∂f/∂u`.

use std::fmt::Debug;
use std::ops::Range;
use std::sync::Arc;

use faer::reborrow::{Reborrow, ReborrowMut};
use faer::{Accum, Mat, MatMut};
use gharial::functions::{StageFunction, StageFunctionData, Workspace, lock};
use gharial::linalg::{copy, matmul, slice_mut};
use gharial::{Error, Result};
use gharial_multibody::spatial::{Mat3, Vec3};
use gharial_multibody::{ContactModel, ContactType, ReferenceFrame};

use super::{VectorTarget, ws};
use crate::dynamics::{ContactDynamicsData, MultibodyConstraintFwdDynamics, SharedContactData};

/// A differentiable map `r = m(f)` of a contact force or wrench `f`.
pub trait ForceMap: Send + Sync + Debug {
    /// Output size `nr`.
    fn nr(&self) -> usize;
    /// Size `nf` of the part of `λ_k` it reads (3: the force; 6: force and torque).
    fn nf(&self) -> usize;
    /// Writes `m(f)` into `out`.
    fn value(&self, f: &[f64], out: &mut [f64]);
    /// Writes `∂m/∂f` (`nr × nf`) into `d`.
    fn jacobian(&self, f: &[f64], d: MatMut<'_, f64>);
    /// Whether `∂m/∂f` is the identity everywhere (default: false): the residual's
    /// Jacobians are then `λ_k`'s, copied instead of multiplied.
    fn jacobian_is_identity(&self) -> bool {
        false
    }
}

/// The Jacobians of `m(λ_k)` into `jx`, `ju`: `∂m/∂f` (written into `dm` unless the
/// identity) times the rows `rows` of `λ`'s Jacobians in `d`.
fn chain_map<M: ForceMap>(
    map: &M,
    rows: &Range<usize>,
    d: &ContactDynamicsData,
    mut dm: MatMut<'_, f64>,
    (jx, ju): (MatMut<'_, f64>, MatMut<'_, f64>),
) {
    let (r0, nf) = (rows.start, rows.len());
    let (lx, lu) = (d.dlambda_dx().subrows(r0, nf), d.dlambda_du().subrows(r0, nf));
    if map.jacobian_is_identity() {
        copy(jx, lx);
        copy(ju, lu);
        return;
    }
    map.jacobian(&d.lambda()[rows.clone()], dm.rb_mut());
    matmul(jx, Accum::Replace, dm.rb(), lx, 1.0);
    matmul(ju, Accum::Replace, dm.rb(), lu, 1.0);
}

/// A residual `r = m(λ_k(x, u))` of contact `k` of a constrained dynamics (see the
/// module documentation). The named residuals are this type with a given map:
/// [`ContactForceResidual`], [`FrictionConeResidual`], [`SmoothFrictionConeResidual`],
/// [`WrenchConeResidual`].
#[derive(Debug)]
pub struct ContactResidual<M: ForceMap> {
    dynamics: Arc<MultibodyConstraintFwdDynamics>,
    contact: usize,
    /// The rows of `f` in `λ`.
    rows: Range<usize>,
    map: M,
}

/// Contact `contact` of `dynamics`, or an error naming the number of contacts.
fn contact_model(dynamics: &MultibodyConstraintFwdDynamics, contact: usize) -> Result<&ContactModel> {
    dynamics.contacts().get(contact).ok_or_else(|| {
        Error::InvalidModel(format!(
            "contact residual: contact index {contact}, but the dynamics has {} contacts",
            dynamics.contacts().len()
        ))
    })
}

/// Scratch of a [`ContactResidual`]: the constrained dynamics at the last point and
/// `∂m/∂f`.
struct ContactWs {
    dynamics: SharedContactData,
    dm_df: Mat<f64>,
}

impl<M: ForceMap> ContactResidual<M> {
    /// The residual `map(λ_k)` of contact `contact` of `dynamics`.
    ///
    /// # Errors
    /// If `contact` is not a contact of `dynamics`, or the map reads more entries than
    /// the contact has (a torque of a 3D contact).
    pub fn with_map(dynamics: Arc<MultibodyConstraintFwdDynamics>, contact: usize, map: M) -> Result<Self> {
        let size = contact_model(&dynamics, contact)?.size();
        if map.nf() > size {
            return Err(Error::InvalidModel(format!(
                "contact residual: {map:?} reads {} entries of the contact force, contact {contact} has {size}",
                map.nf()
            )));
        }
        let r0 = dynamics.contact_rows(contact).start;
        Ok(Self {
            rows: r0..r0 + map.nf(),
            dynamics,
            contact,
            map,
        })
    }

    /// The constrained dynamics.
    pub fn dynamics(&self) -> &Arc<MultibodyConstraintFwdDynamics> {
        &self.dynamics
    }

    /// The contact index.
    pub fn contact(&self) -> usize {
        self.contact
    }

    /// The map of the force.
    pub fn map(&self) -> &M {
        &self.map
    }
}

impl<M: ForceMap> StageFunction for ContactResidual<M> {
    fn nx(&self) -> usize {
        let s = self.dynamics.phase_space();
        s.nq() + s.nv()
    }
    fn ndx(&self) -> usize {
        2 * self.dynamics.phase_space().nv()
    }
    fn nu(&self) -> usize {
        self.dynamics.actuation().nu()
    }
    fn nr(&self) -> usize {
        self.map.nr()
    }
    fn create_workspace(&self) -> Workspace {
        Box::new(ContactWs {
            dynamics: self.dynamics.shared_contact_data(),
            dm_df: Mat::zeros(self.map.nr(), self.map.nf()),
        })
    }

    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let w: &mut ContactWs = ws(&mut data.ws);
        let out = slice_mut(&mut data.value);
        match self.dynamics.contact_forces(x, u, &mut lock(&w.dynamics)) {
            Ok(lambda) => self.map.value(&lambda[self.rows.clone()], out),
            Err(_) => out.fill(f64::NAN),
        }
    }

    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let w: &mut ContactWs = ws(&mut data.ws);
        let mut d = lock(&w.dynamics);
        if self.dynamics.contact_force_jacobians(x, u, &mut d).is_err() {
            data.jx.fill(f64::NAN);
            data.ju.fill(f64::NAN);
            return;
        }
        let out = (data.jx.as_mut(), data.ju.as_mut());
        chain_map(&self.map, &self.rows, &d, w.dm_df.as_mut(), out);
    }
}

/// The tracking map `m(f) = f − f_ref` of the whole contact force or wrench.
#[derive(Debug)]
pub struct ForceError {
    target: VectorTarget,
}

/// `r = λ_k(x, u) − λ_ref`, `nr` the size of contact k (3 or 6).
pub type ContactForceResidual = ContactResidual<ForceError>;

impl ContactForceResidual {
    /// The force error of contact `contact` of `dynamics` with target `lambda_ref` (3 for a
    /// point contact, 6 for a frame contact, in the contact's reference frame).
    ///
    /// # Errors
    /// If `contact` is not a contact of `dynamics`, or `lambda_ref` has the wrong size or
    /// a non-finite entry.
    pub fn new(dynamics: Arc<MultibodyConstraintFwdDynamics>, contact: usize, lambda_ref: &[f64]) -> Result<Self> {
        let n = contact_model(&dynamics, contact)?.size();
        let map = ForceError {
            target: VectorTarget::new("ContactForceResidual target lambda_ref", lambda_ref, n)?,
        };
        Self::with_map(dynamics, contact, map)
    }

    /// Moves the target.
    ///
    /// # Errors
    /// If `lambda_ref` has the wrong size or a non-finite entry; the target is then
    /// unchanged.
    pub fn set_target(&self, lambda_ref: &[f64]) -> Result<()> {
        self.map.target.set(lambda_ref)
    }

    /// The current target.
    pub fn target(&self) -> Vec<f64> {
        self.map.target.get()
    }
}

impl ForceMap for ForceError {
    fn nr(&self) -> usize {
        self.target.len()
    }
    fn nf(&self) -> usize {
        self.target.len()
    }
    fn value(&self, f: &[f64], out: &mut [f64]) {
        for (i, (o, fi)) in out.iter_mut().zip(f).enumerate() {
            *o = fi - self.target.at(i);
        }
    }
    fn jacobian(&self, _f: &[f64], mut d: MatMut<'_, f64>) {
        d.fill(0.0);
        d.diagonal_mut().column_vector_mut().fill(1.0);
    }
    fn jacobian_is_identity(&self) -> bool {
        true
    }
}

/// The Coulomb friction cone `‖f_t‖ ≤ μ f_n` of a contact force `f` with normal `n`,
/// in the coordinates of the contact's force (`n = e_z` by default: the z axis of a
/// LOCAL contact's frame, or the world vertical for a LOCAL_WORLD_ALIGNED contact).
#[derive(Debug, Clone)]
pub struct FrictionCone {
    mu: f64,
    /// Rows `t1`, `t2`, `n`: an orthonormal basis with the normal last.
    basis: Mat3,
}

impl FrictionCone {
    /// The cone of friction coefficient `mu` (`≥ 0`) around the unit normal `normal`
    /// (normalised here).
    ///
    /// # Errors
    /// If `mu` is negative or not finite, or `normal` is zero or not finite.
    pub fn new(mu: f64, normal: [f64; 3]) -> Result<Self> {
        if !(mu.is_finite() && mu >= 0.0) {
            return Err(Error::InvalidModel(format!(
                "FrictionCone: friction coefficient mu must be finite and nonnegative, got {mu}"
            )));
        }
        let n = Vec3::from(normal);
        let norm = n.norm();
        if !(norm.is_finite() && norm > 1e-12) {
            return Err(Error::InvalidModel(format!(
                "FrictionCone: the normal {normal:?} is zero or not finite"
            )));
        }
        let n = n / norm;
        // The world axis least aligned with n gives a well-conditioned tangent.
        let a = if n.x.abs() < 0.5 { Vec3::x() } else { Vec3::y() };
        let t1 = a.cross(&n).normalize();
        let t2 = n.cross(&t1);
        Ok(Self {
            mu,
            basis: Mat3::from_rows(&[t1.transpose(), t2.transpose(), n.transpose()]),
        })
    }

    /// The cone of friction coefficient `mu` around `e_z`.
    ///
    /// # Errors
    /// If `mu` is negative or not finite.
    pub fn vertical(mu: f64) -> Result<Self> {
        Self::new(mu, [0.0, 0.0, 1.0])
    }

    /// The friction coefficient.
    pub fn mu(&self) -> f64 {
        self.mu
    }

    /// The unit normal.
    pub fn normal(&self) -> [f64; 3] {
        let n = self.basis.row(2);
        [n[0], n[1], n[2]]
    }

    /// `(f·t1, f·t2, f·n)`.
    fn components(&self, f: &[f64]) -> Vec3 {
        self.basis * Vec3::new(f[0], f[1], f[2])
    }
}

/// The cone as a second-order-cone constraint: `m(f) = (μ f_n, f_t1, f_t2)`, to be
/// paired with the core's `SecondOrderCone::new(3)` (scalar part first):
/// `‖f_t‖ ≤ μ f_n`. Linear in `f`.
pub type FrictionConeResidual = ContactResidual<FrictionCone>;

impl FrictionConeResidual {
    /// The second-order-cone residual of the force of contact `contact` (3D or 6D).
    ///
    /// # Errors
    /// As [`ContactResidual::with_map`].
    pub fn new(dynamics: Arc<MultibodyConstraintFwdDynamics>, contact: usize, cone: FrictionCone) -> Result<Self> {
        Self::with_map(dynamics, contact, cone)
    }
}

impl ForceMap for FrictionCone {
    fn nr(&self) -> usize {
        3
    }
    fn nf(&self) -> usize {
        3
    }
    fn value(&self, f: &[f64], out: &mut [f64]) {
        let c = self.components(f);
        out.copy_from_slice(&[self.mu * c.z, c.x, c.y]);
    }
    fn jacobian(&self, _f: &[f64], mut d: MatMut<'_, f64>) {
        let b = &self.basis;
        for j in 0..3 {
            d[(0, j)] = self.mu * b[(2, j)];
            d[(1, j)] = b[(0, j)];
            d[(2, j)] = b[(1, j)];
        }
    }
}

/// The cone as two smooth inequalities for solvers without cone sets (as ALIGATOR's
/// `MultibodyFrictionConeResidual`), to be paired with `NegativeOrthant`:
/// `m(f) = (−f_n, ‖f_t‖_ε − μ f_n) ≤ 0` with `‖f_t‖_ε = sqrt(‖f_t‖² + ε²) − ε`.
///
/// `ε ≥ 0` smooths the norm at `f_t = 0` (it is differentiable there for `ε > 0`); since
/// `‖f_t‖ − ε ≤ ‖f_t‖_ε ≤ ‖f_t‖`, the set is the exact cone at `ε = 0` and slightly
/// larger for `ε > 0`, by at most `ε` in the tangential force. At `ε = 0` and
/// `f_t = 0` the Jacobian uses the zero subgradient of the norm.
#[derive(Debug, Clone)]
pub struct SmoothFrictionCone {
    cone: FrictionCone,
    eps: f64,
}

impl SmoothFrictionCone {
    /// The smooth form of `cone` with smoothing `eps` (force units).
    ///
    /// # Errors
    /// If `eps` is negative or not finite.
    pub fn new(cone: FrictionCone, eps: f64) -> Result<Self> {
        if !(eps.is_finite() && eps >= 0.0) {
            return Err(Error::InvalidModel(format!(
                "SmoothFrictionCone: smoothing eps must be finite and nonnegative, got {eps}"
            )));
        }
        Ok(Self { cone, eps })
    }

    /// `(sqrt(‖f_t‖² + ε²), components)`.
    fn norm(&self, f: &[f64]) -> (f64, Vec3) {
        let c = self.cone.components(f);
        ((c.x * c.x + c.y * c.y + self.eps * self.eps).sqrt(), c)
    }
}

/// `r = (−f_n, ‖f_t‖_ε − μ f_n)` of contact k's force, `nr = 2` (see
/// [`SmoothFrictionCone`]).
pub type SmoothFrictionConeResidual = ContactResidual<SmoothFrictionCone>;

impl SmoothFrictionConeResidual {
    /// The smooth friction-cone residual of the force of contact `contact` (3D or 6D).
    ///
    /// # Errors
    /// As [`ContactResidual::with_map`].
    pub fn new(
        dynamics: Arc<MultibodyConstraintFwdDynamics>,
        contact: usize,
        cone: SmoothFrictionCone,
    ) -> Result<Self> {
        Self::with_map(dynamics, contact, cone)
    }
}

impl ForceMap for SmoothFrictionCone {
    fn nr(&self) -> usize {
        2
    }
    fn nf(&self) -> usize {
        3
    }
    fn value(&self, f: &[f64], out: &mut [f64]) {
        let (s, c) = self.norm(f);
        out[0] = -c.z;
        out[1] = s - self.eps - self.cone.mu * c.z;
    }
    fn jacobian(&self, f: &[f64], mut d: MatMut<'_, f64>) {
        let (s, c) = self.norm(f);
        let (g1, g2) = if s > 0.0 { (c.x / s, c.y / s) } else { (0.0, 0.0) };
        let b = &self.cone.basis;
        for j in 0..3 {
            d[(0, j)] = -b[(2, j)];
            d[(1, j)] = g1 * b[(0, j)] + g2 * b[(1, j)] - self.cone.mu * b[(2, j)];
        }
    }
}

/// The contact wrench cone of a rectangular foot (Caron, Pham and Nakamura, "Stability
/// of surface contacts for humanoid robots: closed-form formulae of the contact wrench
/// cone for rectangular support areas", ICRA 2015): the wrenches `w = (f, τ)` at the
/// centre of a rectangle of half-length `X` (along x) and half-width `Y` (along y),
/// sums of forces at its corners inside the friction pyramids `|f_x|, |f_y| ≤ μ f_z`.
/// `m(w) = A w ≤ 0` with the 17 rows
/// ```text
/// −f_z                                                 (unilateral, implied by the next four)
/// ±f_x − μ f_z,  ±f_y − μ f_z                           (friction)
/// ±τ_x − Y f_z,  ±τ_y − X f_z                           (centre of pressure in the foot)
/// −μ(X+Y) f_z ± (Y f_x − μ τ_x) ± (X f_y − μ τ_y) − τ_z  (τ_z ≥ τ_min, 4 sign pairs)
///  −μ(X+Y) f_z ± (Y f_x + μ τ_x) ± (X f_y + μ τ_y) + τ_z  (τ_z ≤ τ_max, 4 sign pairs)
/// ```
/// in the contact frame's coordinates (a LOCAL 6D contact whose frame is at the centre
/// of the sole, z along the normal).
#[derive(Debug, Clone)]
pub struct WrenchCone {
    a: [[f64; 6]; 17],
}

impl WrenchCone {
    /// The cone of friction coefficient `mu` for a sole of half-length `half_length`
    /// (x) and half-width `half_width` (y).
    ///
    /// # Errors
    /// If a parameter is negative or not finite.
    pub fn new(mu: f64, half_length: f64, half_width: f64) -> Result<Self> {
        for (name, v) in [("mu", mu), ("half_length", half_length), ("half_width", half_width)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::InvalidModel(format!(
                    "WrenchCone: {name} must be finite and nonnegative, got {v}"
                )));
            }
        }
        let (x, y) = (half_length, half_width);
        let mut a = [[0.0; 6]; 17];
        a[0] = [0.0, 0.0, -1.0, 0.0, 0.0, 0.0];
        for (k, s) in [1.0, -1.0].into_iter().enumerate() {
            a[1 + k] = [s, 0.0, -mu, 0.0, 0.0, 0.0];
            a[3 + k] = [0.0, s, -mu, 0.0, 0.0, 0.0];
            a[5 + k] = [0.0, 0.0, -y, s, 0.0, 0.0];
            a[7 + k] = [0.0, 0.0, -x, 0.0, s, 0.0];
        }
        let signs = [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)];
        for (k, (sa, sb)) in signs.into_iter().enumerate() {
            let fz = -mu * (x + y);
            a[9 + k] = [sa * y, sb * x, fz, -sa * mu, -sb * mu, -1.0];
            a[13 + k] = [sa * y, sb * x, fz, sa * mu, sb * mu, 1.0];
        }
        Ok(Self { a })
    }

    /// The 17 × 6 matrix `A`, row by row.
    pub fn matrix(&self) -> &[[f64; 6]; 17] {
        &self.a
    }
}

/// `r = A λ_k ≤ 0` of a LOCAL 6D contact, `nr = 17` (see [`WrenchCone`]).
pub type WrenchConeResidual = ContactResidual<WrenchCone>;

impl WrenchConeResidual {
    /// The wrench-cone residual of the wrench of contact `contact`.
    ///
    /// # Errors
    /// If `contact` is not a 6D contact in LOCAL coordinates of `dynamics` (the sole's
    /// rectangle is fixed in the contact frame).
    pub fn new(dynamics: Arc<MultibodyConstraintFwdDynamics>, contact: usize, cone: WrenchCone) -> Result<Self> {
        let c = contact_model(&dynamics, contact)?;
        if c.kind != ContactType::Contact6D || c.reference_frame != ReferenceFrame::Local {
            return Err(Error::InvalidModel(format!(
                "WrenchConeResidual: contact {contact} is a {:?} contact in {:?} coordinates; the wrench cone needs a 6D contact in Local coordinates",
                c.kind, c.reference_frame
            )));
        }
        Self::with_map(dynamics, contact, cone)
    }
}

impl ForceMap for WrenchCone {
    fn nr(&self) -> usize {
        17
    }
    fn nf(&self) -> usize {
        6
    }
    fn value(&self, f: &[f64], out: &mut [f64]) {
        for (o, row) in out.iter_mut().zip(&self.a) {
            *o = row.iter().zip(f).map(|(a, b)| a * b).sum();
        }
    }
    fn jacobian(&self, _f: &[f64], mut d: MatMut<'_, f64>) {
        for (i, row) in self.a.iter().enumerate() {
            for (j, &v) in row.iter().enumerate() {
                d[(i, j)] = v;
            }
        }
    }
}

/// Several residuals of contacts of one constrained dynamics, stacked in the given order
/// (e.g. the friction cones of all stance feet of a stage): one contact solve, and one
/// contact-force derivative pass, for all of them.
#[derive(Debug)]
pub struct StackedContactResidual<M: ForceMap> {
    parts: Vec<ContactResidual<M>>,
    nr: usize,
}

/// Scratch of a [`StackedContactResidual`]: the constrained dynamics at the last point
/// and `∂m/∂f` of each part.
struct StackedWs {
    dynamics: SharedContactData,
    dm_df: Vec<Mat<f64>>,
}

impl<M: ForceMap> StackedContactResidual<M> {
    /// The stack of `parts`.
    ///
    /// # Errors
    /// If `parts` is empty or its residuals do not share one dynamics model.
    pub fn new(parts: Vec<ContactResidual<M>>) -> Result<Self> {
        let Some(first) = parts.first() else {
            return Err(Error::InvalidModel("StackedContactResidual: no residual given".into()));
        };
        if let Some(k) = parts.iter().position(|p| !Arc::ptr_eq(&p.dynamics, &first.dynamics)) {
            return Err(Error::InvalidModel(format!(
                "StackedContactResidual: residual {k} reads another dynamics model than residual 0"
            )));
        }
        let nr = parts.iter().map(|p| p.map.nr()).sum();
        Ok(Self { parts, nr })
    }

    /// The stacked residuals.
    pub fn parts(&self) -> &[ContactResidual<M>] {
        &self.parts
    }

    fn dynamics(&self) -> &MultibodyConstraintFwdDynamics {
        &self.parts[0].dynamics
    }
}

impl<M: ForceMap> StageFunction for StackedContactResidual<M> {
    fn nx(&self) -> usize {
        self.parts[0].nx()
    }
    fn ndx(&self) -> usize {
        self.parts[0].ndx()
    }
    fn nu(&self) -> usize {
        self.parts[0].nu()
    }
    fn nr(&self) -> usize {
        self.nr
    }
    fn create_workspace(&self) -> Workspace {
        Box::new(StackedWs {
            dynamics: self.dynamics().shared_contact_data(),
            dm_df: self.parts.iter().map(|p| Mat::zeros(p.map.nr(), p.map.nf())).collect(),
        })
    }

    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let w: &mut StackedWs = ws(&mut data.ws);
        let out = slice_mut(&mut data.value);
        let mut d = lock(&w.dynamics);
        let Ok(lambda) = self.dynamics().contact_forces(x, u, &mut d) else {
            out.fill(f64::NAN);
            return;
        };
        let mut off = 0;
        for p in &self.parts {
            let nr = p.map.nr();
            p.map.value(&lambda[p.rows.clone()], &mut out[off..off + nr]);
            off += nr;
        }
    }

    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let w: &mut StackedWs = ws(&mut data.ws);
        let mut d = lock(&w.dynamics);
        if self.dynamics().contact_force_jacobians(x, u, &mut d).is_err() {
            data.jx.fill(f64::NAN);
            data.ju.fill(f64::NAN);
            return;
        }
        let mut off = 0;
        for (p, dm) in self.parts.iter().zip(w.dm_df.iter_mut()) {
            let nr = p.map.nr();
            let out = (
                data.jx.as_mut().subrows_mut(off, nr),
                data.ju.as_mut().subrows_mut(off, nr),
            );
            chain_map(&p.map, &p.rows, &d, dm.as_mut(), out);
            off += nr;
        }
    }
}

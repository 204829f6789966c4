//! Joint position, velocity and effort limits of the model (read from the URDF) as
//! ready-made box constraints on coordinates of the state or the control.
//!
//! Only plain vector coordinates are bounded: the angles and displacements of revolute,
//! prismatic and translation joints (whose tangent perturbation is `q_i + δ_i`), every
//! velocity, and the controls. Quaternions, (cos, sin) pairs and the coordinates of free
//! flyers, spherical and planar joints are skipped, as are limits beyond `1e10` in
//! magnitude (`f64::MAX` is the "no limit" of URDF loaders); a coordinate with one
//! finite limit gets a one-sided bound.

use std::sync::Arc;

use gharial::constraints::BoxConstraint;
use gharial::functions::{StageFunction, StageFunctionData, Unary, UnaryFunction};
use gharial::linalg::slice_mut;
use gharial::problem::StageConstraint;
use gharial::{Error, Result};
use gharial_multibody::{JointType, Model};

use crate::MultibodyPhaseSpace;
use crate::spaces::FINITE_LIMIT;

/// Selected coordinates of the state, `r_k = x[i_k]`, for coordinates whose tangent
/// perturbation is additive (`x ⊕ δ` adds `δ[j_k]` to `x[i_k]`): a constant Jacobian
/// with a 1 at `(k, j_k)`.
#[derive(Debug, Clone)]
pub struct StateSelection {
    nx: usize,
    ndx: usize,
    /// `(representation index i_k, tangent index j_k)`.
    rows: Vec<(usize, usize)>,
}

impl StateSelection {
    /// The selection of `rows` (`(i_k, j_k)`) of states of size `(nx, ndx)`.
    ///
    /// # Errors
    /// If an index is out of range.
    pub fn new(nx: usize, ndx: usize, rows: &[(usize, usize)]) -> Result<Self> {
        if let Some((k, &(i, j))) = rows.iter().enumerate().find(|(_, (i, j))| *i >= nx || *j >= ndx) {
            return Err(Error::InvalidModel(format!(
                "StateSelection: row {k} selects x[{i}] with tangent index {j}, beyond (nx, ndx) = ({nx}, {ndx})"
            )));
        }
        Ok(Self {
            nx,
            ndx,
            rows: rows.to_vec(),
        })
    }

    /// The selected `(representation, tangent)` indices.
    pub fn rows(&self) -> &[(usize, usize)] {
        &self.rows
    }
}

impl UnaryFunction for StateSelection {
    fn nx(&self) -> usize {
        self.nx
    }
    fn ndx(&self) -> usize {
        self.ndx
    }
    fn nr(&self) -> usize {
        self.rows.len()
    }
    fn evaluate(&self, x: &[f64], data: &mut StageFunctionData) {
        for (r, &(i, _)) in slice_mut(&mut data.value).iter_mut().zip(&self.rows) {
            *r = x[i];
        }
    }
    fn jacobian(&self, _x: &[f64], data: &mut StageFunctionData) {
        gharial::linalg::fill(data.jx.as_mut(), 0.0);
        for (k, &(_, j)) in self.rows.iter().enumerate() {
            data.jx[(k, j)] = 1.0;
        }
    }
    fn jacobian_is_constant(&self) -> bool {
        true
    }
}

/// Selected controls, `r_k = u[i_k]` (constant Jacobians, zero in `x`).
#[derive(Debug, Clone)]
pub struct ControlSelection {
    nx: usize,
    ndx: usize,
    nu: usize,
    rows: Vec<usize>,
}

impl ControlSelection {
    /// The controls `rows` of size-`nu` controls, for states of size `(nx, ndx)`.
    ///
    /// # Errors
    /// If an index is not below `nu`.
    pub fn new(nx: usize, ndx: usize, nu: usize, rows: &[usize]) -> Result<Self> {
        if let Some((k, &i)) = rows.iter().enumerate().find(|(_, i)| **i >= nu) {
            return Err(Error::InvalidModel(format!(
                "ControlSelection: row {k} selects u[{i}], beyond nu = {nu}"
            )));
        }
        Ok(Self {
            nx,
            ndx,
            nu,
            rows: rows.to_vec(),
        })
    }

    /// The selected control indices.
    pub fn rows(&self) -> &[usize] {
        &self.rows
    }
}

impl StageFunction for ControlSelection {
    fn nx(&self) -> usize {
        self.nx
    }
    fn ndx(&self) -> usize {
        self.ndx
    }
    fn nu(&self) -> usize {
        self.nu
    }
    fn nr(&self) -> usize {
        self.rows.len()
    }
    fn evaluate(&self, _x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        for (r, &i) in slice_mut(&mut data.value).iter_mut().zip(&self.rows) {
            *r = u[i];
        }
    }
    fn jacobians(&self, _x: &[f64], _u: &[f64], data: &mut StageFunctionData) {
        gharial::linalg::fill(data.jx.as_mut(), 0.0);
        gharial::linalg::fill(data.ju.as_mut(), 0.0);
        for (k, &i) in self.rows.iter().enumerate() {
            data.ju[(k, i)] = 1.0;
        }
    }
    fn jacobians_are_constant(&self) -> bool {
        true
    }
}

/// A limit as a bound: `None` when infinite (beyond [`FINITE_LIMIT`]).
fn finite(l: f64) -> Option<f64> {
    (l.abs() <= FINITE_LIMIT).then_some(l)
}

/// Bounds of the coordinates kept so far, with their indices.
#[derive(Default)]
struct Bounds<T> {
    rows: Vec<T>,
    lower: Vec<f64>,
    upper: Vec<f64>,
}

impl<T> Bounds<T> {
    /// Keeps `row` if one of its limits is finite.
    fn push(&mut self, row: T, lower: f64, upper: f64) {
        let (lo, hi) = (finite(lower), finite(upper));
        if lo.is_some() || hi.is_some() {
            self.rows.push(row);
            self.lower.push(lo.unwrap_or(f64::NEG_INFINITY));
            self.upper.push(hi.unwrap_or(f64::INFINITY));
        }
    }

    /// The box of the kept bounds, or an error naming `what` if none was kept.
    fn into_box(self, what: &str, model: &Model) -> Result<(Vec<T>, BoxConstraint)> {
        if self.rows.is_empty() {
            return Err(Error::InvalidModel(format!(
                "{what}: model `{}` gives no finite limit on the coordinates that can be bounded",
                model.name
            )));
        }
        let set =
            BoxConstraint::new(&self.lower, &self.upper).map_err(|e| Error::InvalidModel(format!("{what}: {e}")))?;
        Ok((self.rows, set))
    }
}

/// The name of the joint of degree of freedom `k`.
fn dof_joint_name(model: &Model, k: usize) -> &str {
    model
        .joints()
        .iter()
        .zip(model.joint_names())
        .find(|(j, _)| (j.idx_v..j.idx_v + j.nv).contains(&k))
        .map_or("?", |(_, n)| n.as_str())
}

/// Checks a symmetric limit `±l` (a velocity or effort limit must not be negative).
fn check_symmetric(what: &str, model: &Model, k: usize, l: f64) -> Result<()> {
    if l.is_nan() || l < 0.0 {
        return Err(Error::InvalidModel(format!(
            "{what}: joint `{}` (dof {k}) has limit {l}, which must be nonnegative",
            dof_joint_name(model, k)
        )));
    }
    Ok(())
}

/// The constraint `lower ≤ q_i ≤ upper` on the coordinates of the revolute, prismatic
/// and translation joints with a finite position limit (`Model::lower_position_limit`,
/// `upper_position_limit`), for stages with `nu` controls.
///
/// # Errors
/// If no such coordinate has a finite limit, or a lower limit exceeds its upper limit.
pub fn position_limits(space: &MultibodyPhaseSpace, nu: usize) -> Result<StageConstraint> {
    let model = space.model();
    let mut b = Bounds::default();
    for j in model.joints() {
        if matches!(
            j.kind,
            JointType::Revolute(_) | JointType::Prismatic(_) | JointType::Translation
        ) {
            for (d, i) in (j.idx_q..j.idx_q + j.nq).enumerate() {
                b.push(
                    (i, j.idx_v + d),
                    model.lower_position_limit[i],
                    model.upper_position_limit[i],
                );
            }
        }
    }
    let (rows, set) = b.into_box("position_limits", model)?;
    let f = StateSelection::new(space.nq() + space.nv(), 2 * space.nv(), &rows)?;
    Ok(StageConstraint::new(
        "position limits",
        Arc::new(Unary::new(Arc::new(f), nu)),
        Arc::new(set),
    ))
}

/// The constraint `|v_k| ≤ v_max,k` on the velocities with a finite limit
/// (`Model::velocity_limit`), for stages with `nu` controls.
///
/// # Errors
/// If no velocity has a finite limit, or a limit is negative.
pub fn velocity_limits(space: &MultibodyPhaseSpace, nu: usize) -> Result<StageConstraint> {
    let (model, nq, nv) = (space.model(), space.nq(), space.nv());
    let mut b = Bounds::default();
    for (k, &l) in model.velocity_limit.iter().enumerate() {
        check_symmetric("velocity_limits", model, k, l)?;
        b.push((nq + k, nv + k), -l, l);
    }
    let (rows, set) = b.into_box("velocity_limits", model)?;
    let f = StateSelection::new(nq + nv, 2 * nv, &rows)?;
    Ok(StageConstraint::new(
        "velocity limits",
        Arc::new(Unary::new(Arc::new(f), nu)),
        Arc::new(set),
    ))
}

/// The constraint `|u_j| ≤ τ_max,k_j` on the controls, control `j` driving degree of
/// freedom `actuated_dofs[j]` (as `Actuation::actuated_dofs` of the dynamics gives
/// them), with the effort limits of the model (`Model::effort_limit`); controls of
/// dofs without a finite limit are left free.
///
/// # Errors
/// If a dof is not below `nv`, no actuated dof has a finite effort limit, or a limit is
/// negative.
pub fn effort_limits(space: &MultibodyPhaseSpace, actuated_dofs: &[usize]) -> Result<StageConstraint> {
    let (model, nv) = (space.model(), space.nv());
    let mut b = Bounds::default();
    for (j, &k) in actuated_dofs.iter().enumerate() {
        if k >= nv {
            return Err(Error::InvalidModel(format!(
                "effort_limits: control {j} drives dof {k}, but model `{}` has nv = {nv}",
                model.name
            )));
        }
        check_symmetric("effort_limits", model, k, model.effort_limit[k])?;
        b.push(j, -model.effort_limit[k], model.effort_limit[k]);
    }
    let (rows, set) = b.into_box("effort_limits", model)?;
    let f = ControlSelection::new(space.nq() + nv, 2 * nv, actuated_dofs.len(), &rows)?;
    Ok(StageConstraint::new("effort limits", Arc::new(f), Arc::new(set)))
}

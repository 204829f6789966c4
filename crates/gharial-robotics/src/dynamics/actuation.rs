//! The actuation matrix `B` (`nv × nu`) of the whole-body dynamics
//! `M(q) q̈ + b(q, v) = B u (+ Jcᵀ λ)` (ProxDDP paper, (54a) and (56a)).

use faer::prelude::ReborrowMut;
use faer::{Accum, Mat, MatMut, MatRef};
use gharial::linalg::{copy, matmul, matvec};
use gharial::{Error, Result};
use gharial_multibody::{JointType, Model};

/// How the controls `u` enter the generalized forces: `τ = B u`.
///
/// Three shapes: full actuation `B = I`, a selection of degrees of freedom (each control
/// drives one dof, e.g. `B = [0; I]` for a robot with an unactuated floating base), or a
/// general dense matrix. Selections are applied by indexing, without products.
#[derive(Debug, Clone)]
pub struct Actuation {
    nv: usize,
    map: Map,
}

#[derive(Debug, Clone)]
enum Map {
    /// `B = I`.
    Identity,
    /// Column `j` of `B` is `e_{dofs[j]}`.
    Select(Vec<usize>),
    /// A dense `nv × nu` matrix.
    Dense(Mat<f64>),
}

impl Actuation {
    /// Full actuation `B = I` (`nu = nv`).
    pub fn full(model: &Model) -> Self {
        Self {
            nv: model.nv(),
            map: Map::Identity,
        }
    }

    /// Underactuated floating base `B = [0; I]`: every degree of freedom but the six of
    /// the free-flyer root joint is actuated (`nu = nv - 6`).
    ///
    /// # Errors
    /// If joint 1 of the model is not a free flyer.
    pub fn floating_base(model: &Model) -> Result<Self> {
        match model.joints().get(1) {
            Some(j) if j.kind == JointType::FreeFlyer && j.idx_v == 0 => {
                Self::dofs(model, &(6..model.nv()).collect::<Vec<_>>())
            }
            _ => Err(Error::InvalidModel(format!(
                "Actuation::floating_base: the first joint of model `{}` is not a free flyer",
                model.name
            ))),
        }
    }

    /// The degrees of freedom of the named joints are actuated, in the given order (one
    /// control per dof).
    ///
    /// # Errors
    /// If a name is not a joint of the model.
    pub fn joints(model: &Model, names: &[&str]) -> Result<Self> {
        let mut dofs = Vec::new();
        for name in names {
            let id = model
                .joint_id(name)
                .map_err(|e| Error::InvalidModel(format!("Actuation::joints: {e} in model `{}`", model.name)))?;
            let j = &model.joints()[id];
            dofs.extend(j.idx_v..j.idx_v + j.nv);
        }
        Self::dofs(model, &dofs)
    }

    /// Control `j` drives degree of freedom `dofs[j]`.
    ///
    /// # Errors
    /// If a dof index is not below `nv`.
    pub fn dofs(model: &Model, dofs: &[usize]) -> Result<Self> {
        let nv = model.nv();
        if let Some((j, &k)) = dofs.iter().enumerate().find(|&(_, &k)| k >= nv) {
            return Err(Error::InvalidModel(format!(
                "Actuation::dofs: control {j} drives dof {k}, but model `{}` has nv = {nv}",
                model.name
            )));
        }
        Ok(Self {
            nv,
            map: Map::Select(dofs.to_vec()),
        })
    }

    /// A general actuation matrix `B` (`nv × nu`).
    ///
    /// # Errors
    /// If `B` does not have `nv` rows or holds a non-finite entry.
    pub fn matrix(model: &Model, b: MatRef<'_, f64>) -> Result<Self> {
        gharial::error::check_dim(
            format_args!("Actuation::matrix: rows of B (nv of model `{}`)", model.name),
            model.nv(),
            b.nrows(),
        )?;
        for j in 0..b.ncols() {
            if let Some(i) = (0..b.nrows()).find(|&i| !b[(i, j)].is_finite()) {
                return Err(Error::non_finite(format!(
                    "Actuation::matrix: B[({i}, {j})] = {}",
                    b[(i, j)]
                )));
            }
        }
        Ok(Self {
            nv: model.nv(),
            map: Map::Dense(b.to_owned()),
        })
    }

    /// Velocity size `nv` (rows of `B`).
    pub fn nv(&self) -> usize {
        self.nv
    }

    /// Control size `nu` (columns of `B`).
    pub fn nu(&self) -> usize {
        match &self.map {
            Map::Identity => self.nv,
            Map::Select(d) => d.len(),
            Map::Dense(b) => b.ncols(),
        }
    }

    /// The actuated dof of each control, for selections (`None` for a dense `B`).
    pub fn actuated_dofs(&self) -> Option<Vec<usize>> {
        match &self.map {
            Map::Identity => Some((0..self.nv).collect()),
            Map::Select(d) => Some(d.clone()),
            Map::Dense(_) => None,
        }
    }

    /// `B` as a dense matrix.
    pub fn to_matrix(&self) -> Mat<f64> {
        match &self.map {
            Map::Identity => Mat::identity(self.nv, self.nv),
            Map::Select(d) => Mat::from_fn(self.nv, d.len(), |i, j| if d[j] == i { 1.0 } else { 0.0 }),
            Map::Dense(b) => b.clone(),
        }
    }

    /// `τ = B u` (`u` of size `nu`, `tau` of size `nv`).
    pub(crate) fn torque(&self, u: &[f64], tau: &mut [f64]) {
        match &self.map {
            Map::Identity => tau.copy_from_slice(u),
            Map::Select(d) => {
                tau.fill(0.0);
                for (&k, &uj) in d.iter().zip(u) {
                    tau[k] += uj;
                }
            }
            Map::Dense(b) => matvec(tau, Accum::Replace, b.as_ref(), u, 1.0),
        }
    }

    /// `out = X B` for `X` with `nv` columns (`out` with `nu` columns): the chain rule
    /// `∂y/∂u = ∂y/∂τ B`.
    pub(crate) fn right_multiply(&self, x: MatRef<'_, f64>, mut out: MatMut<'_, f64>) {
        match &self.map {
            Map::Identity => copy(out, x),
            // Consecutive dofs (a floating base's joints): one block copy.
            Map::Select(d) if d.windows(2).all(|w| w[1] == w[0] + 1) => {
                copy(out, x.subcols(d.first().copied().unwrap_or(0), d.len()))
            }
            Map::Select(d) => {
                for (j, &k) in d.iter().enumerate() {
                    copy(out.rb_mut().col_mut(j).as_mat_mut(), x.col(k).as_mat());
                }
            }
            Map::Dense(b) => matmul(out, Accum::Replace, x, b.as_ref(), 1.0),
        }
    }
}

//! Static inverse dynamics for initial guesses and control regularisation: gravity
//! compensation and the quasi-static torque of a robot in contact (ProxDDP paper,
//! §VII-B: with zero velocity and acceleration the dynamics (54a) reduce to
//! `B u + Jcᵀ λ = g(q)`).
//!
//! Both solve `A z = g(q)` for its minimum-norm solution through a singular value
//! decomposition, and fail with a clear error when the system has no solution (the
//! unactuated coordinates are not balanced). They allocate: call them while building a
//! problem, not in a solver loop.

use faer::Mat;
use gharial::{Error, Result};
use gharial_multibody::{ContactData, ContactModel, Model, constraint_dynamics, generalized_gravity};

use crate::Actuation;

/// Relative accuracy required of `A z = g`: `|A z − g|∞ ≤ FEASIBILITY_TOL · max(1, |g|∞)`.
pub const FEASIBILITY_TOL: f64 = 1e-8;

/// The controls and contact forces that hold a robot at rest.
#[derive(Debug, Clone, PartialEq)]
pub struct QuasiStatic {
    /// Controls `u` (`nu`).
    pub u: Vec<f64>,
    /// Contact forces `λ` (`nc`), stacked in the order of the contacts, each in its
    /// contact's reference frame (the environment's force on the robot).
    pub lambda: Vec<f64>,
}

/// Gravity compensation `u = B⁺ g(q)`: the minimum-norm controls with `B u = g(q)`,
/// which hold the robot at rest at `q` (for `B = I`, `u = g(q)`).
///
/// # Errors
/// If `q` is invalid, `B` does not match the model, or `B u = g(q)` has no solution:
/// gravity acts on a coordinate no control reaches (a floating base with no support;
/// use [`quasi_static_torque`] with the contacts). The error names the dof and its joint.
pub fn gravity_compensation(model: &Model, actuation: &Actuation, q: &[f64]) -> Result<Vec<f64>> {
    static_balance("gravity_compensation", model, actuation, &[], q).map(|s| s.u)
}

/// The quasi-static torque at `q` with `contacts`: the minimum-norm `(u, λ)` with
/// `B u + Jcᵀ λ = g(q)` (ProxDDP paper, §VII-B), e.g. the torques and ground forces of
/// a legged robot standing still. With a fully actuated robot the contact forces share
/// the load with the torques (minimum norm of the pair).
///
/// # Errors
/// If `q` is invalid, `B` does not match the model, a contact is invalid, the contact
/// Jacobian is rank-deficient, or the system has no solution (the contacts cannot
/// support the unactuated coordinates; the error names the dof and its joint).
pub fn quasi_static_torque(
    model: &Model,
    actuation: &Actuation,
    contacts: &[ContactModel],
    q: &[f64],
) -> Result<QuasiStatic> {
    static_balance("quasi_static_torque", model, actuation, contacts, q)
}

/// The minimum-norm `(u, λ)` with `B u + Jcᵀ λ = g(q)`; `what` names the caller.
fn static_balance(
    what: &str,
    model: &Model,
    actuation: &Actuation,
    contacts: &[ContactModel],
    q: &[f64],
) -> Result<QuasiStatic> {
    gharial::error::check_dim(format_args!("{what}: rows of B (nv)"), model.nv(), actuation.nv())?;
    let jc = contact_jacobian(model, contacts, q).map_err(|e| crate::multibody_error(what, e))?;
    static_balance_with_jacobian(what, model, actuation, &jc, q)
}

/// The minimum-norm `(u, λ)` with `B u + Jcᵀ λ = g(q)` for a given constraint Jacobian
/// `Jc` (`nc × nv`); `what` names the caller.
pub(crate) fn static_balance_with_jacobian(
    what: &str,
    model: &Model,
    actuation: &Actuation,
    jc: &Mat<f64>,
    q: &[f64],
) -> Result<QuasiStatic> {
    let nv = model.nv();
    gharial::error::check_dim(format_args!("{what}: rows of B (nv)"), nv, actuation.nv())?;
    gharial::error::check_dim(format_args!("{what}: columns of Jc (nv)"), nv, jc.ncols())?;
    let mut data = model.create_data();
    let g = generalized_gravity(model, &mut data, q)
        .map_err(|e| crate::multibody_error(what, e))?
        .to_vec();
    let (nu, nc) = (actuation.nu(), jc.nrows());
    // A = [B, Jcᵀ] (nv × (nu + nc)).
    let b = actuation.to_matrix();
    let a = Mat::from_fn(nv, nu + nc, |i, j| if j < nu { b[(i, j)] } else { jc[(j - nu, i)] });
    let z = min_norm_solve(&a, &g).map_err(|e| Error::singular(format!("{what}: SVD of [B, Jcᵀ]: {e:?}")))?;
    check_solution(what, model, &a, &z, &g)?;
    Ok(QuasiStatic {
        u: z[..nu].to_vec(),
        lambda: z[nu..].to_vec(),
    })
}

/// The constraint Jacobian `Jc` (`nc × nv`) of `contacts` at `q`, in the contacts'
/// reference frames.
fn contact_jacobian(model: &Model, contacts: &[ContactModel], q: &[f64]) -> gharial_multibody::Result<Mat<f64>> {
    let nv = model.nv();
    let mut cdata = ContactData::new(model, contacts)?;
    if cdata.nc() == 0 {
        return Ok(Mat::zeros(0, nv));
    }
    let mut data = model.create_data();
    let zeros = vec![0.0; nv];
    constraint_dynamics(model, &mut data, contacts, &mut cdata, q, &zeros, &zeros)?;
    Ok(cdata.constraint_jacobian().to_owned())
}

/// The minimum-norm least-squares solution of `A z = g`: `z = V Σ⁺ Uᵀ g`, singular
/// values below `max(m, n) ε σ_max` treated as zero.
fn min_norm_solve(a: &Mat<f64>, g: &[f64]) -> std::result::Result<Vec<f64>, faer::linalg::solvers::SvdError> {
    let (m, n) = (a.nrows(), a.ncols());
    let mut z = vec![0.0; n];
    if n == 0 || m == 0 {
        return Ok(z);
    }
    let svd = a.thin_svd()?;
    let (u, s, v) = (svd.U(), svd.S().column_vector(), svd.V());
    let smax = s[0];
    let cutoff = (m.max(n) as f64) * f64::EPSILON * smax;
    for k in 0..s.nrows() {
        if s[k] <= cutoff {
            break;
        }
        let c = (0..m).map(|i| u[(i, k)] * g[i]).sum::<f64>() / s[k];
        for (j, zj) in z.iter_mut().enumerate() {
            *zj += c * v[(j, k)];
        }
    }
    Ok(z)
}

/// Errors naming the dof of the largest residual if `A z ≠ g` beyond
/// [`FEASIBILITY_TOL`].
fn check_solution(what: &str, model: &Model, a: &Mat<f64>, z: &[f64], g: &[f64]) -> Result<()> {
    let scale = g.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
    let (k, r) = (0..a.nrows())
        .map(|i| (i, (0..a.ncols()).map(|j| a[(i, j)] * z[j]).sum::<f64>() - g[i]))
        .fold(
            (0, 0.0_f64),
            |best, (i, r)| if r.abs() > best.1.abs() { (i, r) } else { best },
        );
    if r.abs() <= FEASIBILITY_TOL * scale {
        return Ok(());
    }
    let joint = model
        .joints()
        .iter()
        .position(|j| (j.idx_v..j.idx_v + j.nv).contains(&k))
        .map_or("?", |id| model.joint_names()[id].as_str());
    Err(Error::InvalidModel(format!(
        "{what}: B u + Jcᵀ λ = g(q) has no solution for model `{}`: gravity g[{k}] = {:.6e} on dof {k} (joint `{joint}`) \
         is left unbalanced by {r:.3e}; no control or contact force acts there (an unactuated, unsupported base?)",
        model.name, g[k]
    )))
}

//! Tracking errors: `r(x) = x ⊖ x_ref` on any manifold and `r(u) = u - u_ref`.
//!
//! Targets are stored in a [`ParamVec`], so that a model shared by a solver (an `Arc`)
//! can still have its target moved between solves, as a receding-horizon controller
//! does at every step, without reallocating the solver's data.

use std::sync::Arc;

use super::util::{downcast, set_identity};
use super::{StageFunction, StageFunctionData, UnaryFunction, Workspace};
use crate::error::{check_dim, check_finite};
use crate::param::ParamVec;
use crate::spaces::{Arg, Manifold};
use crate::{Error, Result};

/// Checks that `x` is a valid point of `space` (size, finiteness, manifold constraints).
/// Does not allocate unless it fails (targets are moved in MPC loops).
pub(crate) fn check_point(space: &dyn Manifold, what: &str, x: &[f64]) -> Result<()> {
    if x.len() != space.nx() {
        return Err(Error::dim(
            format!("{what} (size nx of the state space)"),
            space.nx(),
            x.len(),
        ));
    }
    check_finite(what, x)?;
    if !space.is_valid(x) {
        return Err(Error::InvalidModel(format!("{what} is not a valid point of {space:?}")));
    }
    Ok(())
}

/// The state error `r(x) = x ⊖ x_ref = difference(x_ref, x)` (`nr = ndx`).
///
/// Jacobian: `dr/dx = jdifference(x_ref, x, Arg::Second)` (the identity on vector
/// spaces). Second derivative: `r` is affine on vector spaces, so the vector-Hessian
/// product is exactly zero there. On Lie groups the second derivative of the logarithm
/// is not zero away from `x_ref`, but the [`Manifold`] trait does not expose it; this
/// function reports `has_vhp() == false`, i.e. the Gauss-Newton approximation, which is
/// exact at `x = x_ref` (where the residual that multiplies it in a cost vanishes).
///
/// Use it on stage functions through [`super::Unary`].
#[derive(Debug)]
pub struct StateError {
    space: Arc<dyn Manifold>,
    target: ParamVec,
}

struct StateErrorWs {
    x_ref: Vec<f64>,
}

impl StateError {
    /// `r(x) = x ⊖ x_ref` on `space`.
    ///
    /// # Errors
    /// If `x_ref` has the wrong size, is not finite or is not a valid point of `space`.
    pub fn new(space: Arc<dyn Manifold>, x_ref: &[f64]) -> Result<Self> {
        check_point(space.as_ref(), "StateError target x_ref", x_ref)?;
        Ok(Self {
            target: ParamVec::new(x_ref),
            space,
        })
    }

    /// The state space.
    pub fn space(&self) -> &Arc<dyn Manifold> {
        &self.space
    }

    /// Moves the target (through `&self`: models shared with a solver can be updated
    /// between solves).
    ///
    /// # Errors
    /// As [`StateError::new`]; the target is left unchanged on error.
    pub fn set_target(&self, x_ref: &[f64]) -> Result<()> {
        check_point(self.space.as_ref(), "StateError target x_ref", x_ref)?;
        self.target.write(x_ref)
    }

    /// The current target.
    pub fn target(&self) -> Vec<f64> {
        self.target.to_vec()
    }

    /// The leading `k × k` block of the Jacobian (`k` = the space's
    /// [`Manifold::nonlinear_dim`]) into the corner of `data.jx`, the rest of which it
    /// leaves as it is (`diag(J_b, I)` is the whole Jacobian).
    pub(crate) fn jacobian_block(&self, x: &[f64], data: &mut StageFunctionData) {
        let ws: &mut StateErrorWs = downcast(&mut data.ws);
        self.target.read(&mut ws.x_ref);
        let k = self.space.nonlinear_dim();
        let block = data.jx.as_mut().submatrix_mut(0, 0, k, k);
        self.space.jdifference_block(&ws.x_ref, x, Arg::Second, block);
    }
}

impl UnaryFunction for StateError {
    fn nx(&self) -> usize {
        self.space.nx()
    }
    fn ndx(&self) -> usize {
        self.space.ndx()
    }
    fn nr(&self) -> usize {
        self.space.ndx()
    }
    fn create_workspace(&self) -> Workspace {
        Box::new(StateErrorWs {
            x_ref: vec![0.0; self.space.nx()],
        })
    }
    fn evaluate(&self, x: &[f64], data: &mut StageFunctionData) {
        let ws: &mut StateErrorWs = downcast(&mut data.ws);
        self.target.read(&mut ws.x_ref);
        self.space
            .difference(&ws.x_ref, x, crate::linalg::slice_mut(&mut data.value));
    }
    fn jacobian(&self, x: &[f64], data: &mut StageFunctionData) {
        let ws: &mut StateErrorWs = downcast(&mut data.ws);
        self.target.read(&mut ws.x_ref);
        self.space.jdifference(&ws.x_ref, x, Arg::Second, data.jx.as_mut());
    }
    /// The identity on vector spaces, whatever the target.
    fn jacobian_is_constant(&self) -> bool {
        self.space.is_vector_space()
    }
}

/// The control error `r(x, u) = u - u_ref` (`nr = nu`): `dr/dx = 0`, `dr/du = I`.
#[derive(Debug)]
pub struct ControlError {
    nx: usize,
    ndx: usize,
    target: ParamVec,
}

impl ControlError {
    /// `r(x, u) = u - u_ref` for states of `space` and controls of size `u_ref.len()`.
    ///
    /// # Errors
    /// If `u_ref` is not finite.
    pub fn new(space: &dyn Manifold, u_ref: &[f64]) -> Result<Self> {
        check_finite("ControlError target u_ref", u_ref)?;
        Ok(Self {
            nx: space.nx(),
            ndx: space.ndx(),
            target: ParamVec::new(u_ref),
        })
    }

    /// Moves the target.
    ///
    /// # Errors
    /// If `u_ref` has the wrong size or is not finite; the target is then unchanged.
    pub fn set_target(&self, u_ref: &[f64]) -> Result<()> {
        check_dim("ControlError target u_ref", self.target.len(), u_ref.len())?;
        check_finite("ControlError target u_ref", u_ref)?;
        self.target.write(u_ref)
    }

    /// The current target.
    pub fn target(&self) -> Vec<f64> {
        self.target.to_vec()
    }
}

impl StageFunction for ControlError {
    fn nx(&self) -> usize {
        self.nx
    }
    fn ndx(&self) -> usize {
        self.ndx
    }
    fn nu(&self) -> usize {
        self.target.len()
    }
    fn nr(&self) -> usize {
        self.target.len()
    }
    fn evaluate(&self, _x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        for (i, r) in data.value_mut().iter_mut().enumerate() {
            *r = u[i] - self.target.get(i);
        }
    }
    fn jacobians(&self, _x: &[f64], _u: &[f64], data: &mut StageFunctionData) {
        crate::linalg::fill(data.jx.as_mut(), 0.0);
        set_identity(data.ju.as_mut());
    }
    fn jacobians_are_constant(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{CheckOptions, check_stage_function};
    use crate::functions::Unary;
    use crate::functions::testing::{random_vec, rng};
    use crate::spaces::VectorSpace;

    #[test]
    fn state_error_on_a_vector_space_is_x_minus_target() {
        let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(4));
        let mut g = rng(10);
        let x_ref = random_vec(&mut g, 4, 1.0);
        let e = Arc::new(StateError::new(space.clone(), &x_ref).unwrap());
        let f = Unary::new(e.clone(), 2);
        let mut d = f.create_data();
        for _ in 0..4 {
            let (x, u) = (random_vec(&mut g, 4, 1.0), random_vec(&mut g, 2, 1.0));
            f.evaluate(&x, &u, &mut d);
            for i in 0..4 {
                assert_eq!(d.value()[i], x[i] - x_ref[i]);
            }
            check_stage_function(&f, space.as_ref(), &x, &u, None, CheckOptions::default()).assert_ok();
        }
        // Moving the target through the shared model changes the next evaluation.
        let new_ref = random_vec(&mut g, 4, 1.0);
        e.set_target(&new_ref).unwrap();
        assert_eq!(e.target(), new_ref);
        let x = [0.5; 4];
        f.evaluate(&x, &[0.0; 2], &mut d);
        for i in 0..4 {
            assert_eq!(d.value()[i], 0.5 - new_ref[i]);
        }
        let err = e.set_target(&[0.0; 3]).unwrap_err();
        assert!(err.to_string().contains("StateError target x_ref"), "{err}");
        assert!(e.set_target(&[0.0, f64::NAN, 0.0, 0.0]).is_err());
        assert_eq!(e.target(), new_ref, "a rejected target leaves the old one");
        assert!(StateError::new(space, &[1.0]).is_err());
    }

    #[test]
    fn control_error_is_u_minus_target() {
        let space = VectorSpace::new(3);
        let e = ControlError::new(&space, &[1.0, -2.0]).unwrap();
        let mut d = e.create_data();
        let (x, u) = ([0.1, 0.2, 0.3], [0.5, 0.25]);
        e.evaluate(&x, &u, &mut d);
        assert_eq!(d.value(), &[-0.5, 2.25]);
        check_stage_function(&e, &space, &x, &u, None, CheckOptions::default()).assert_ok();
        e.set_target(&[0.0, 0.0]).unwrap();
        e.evaluate(&x, &u, &mut d);
        assert_eq!(d.value(), &u);
        assert!(e.set_target(&[0.0]).is_err());
        assert!(ControlError::new(&space, &[f64::INFINITY]).is_err());
    }

    #[test]
    fn state_error_on_lie_groups_matches_finite_differences_and_dual_numbers() {
        use crate::check::{DualCheckOptions, check_stage_function_dual};
        use crate::functions::LinearComposition;
        use crate::functions::testing::random_mat;
        use num_dual::Dual64;
        let mut g = rng(11);
        for space in crate::functions::testing::lie_spaces() {
            let (nx, ndx) = (space.nx(), space.ndx());
            let mut x_ref = vec![0.0; nx];
            space.random(&mut g, &mut x_ref);
            let e: Arc<dyn UnaryFunction> = Arc::new(StateError::new(space.clone(), &x_ref).unwrap());
            let f: Arc<dyn StageFunction> = Arc::new(Unary::new(e, 2));
            let m = random_mat(&mut g, 2, ndx, 1.0);
            let b = random_vec(&mut g, 2, 1.0);
            let comp = LinearComposition::new(f.clone(), m.as_ref(), &b).unwrap();
            let x_ref_d: Vec<Dual64> = x_ref.iter().map(|&v| Dual64::from(v)).collect();
            for _ in 0..4 {
                let mut x = vec![0.0; nx];
                space.random(&mut g, &mut x);
                let u = random_vec(&mut g, 2, 1.0);
                check_stage_function(f.as_ref(), space.as_ref(), &x, &u, None, CheckOptions::default()).assert_ok();
                check_stage_function(&comp, space.as_ref(), &x, &u, None, CheckOptions::default()).assert_ok();
                let rep = check_stage_function_dual(
                    f.as_ref(),
                    space.as_ref(),
                    &x,
                    &u,
                    |x, _u, out| space.difference_dual(&x_ref_d, x, out),
                    DualCheckOptions::default(),
                );
                assert!(rep.passed(), "{space:?}: {rep:?}");
                let rep = check_stage_function_dual(
                    &comp,
                    space.as_ref(),
                    &x,
                    &u,
                    |x, _u, out| {
                        let mut d = vec![Dual64::from(0.0); ndx];
                        space.difference_dual(&x_ref_d, x, &mut d);
                        for i in 0..2 {
                            out[i] = (0..ndx).fold(Dual64::from(b[i]), |acc, k| acc + d[k] * m[(i, k)]);
                        }
                    },
                    DualCheckOptions::default(),
                );
                assert!(rep.passed(), "{space:?}: {rep:?}");
            }
        }
    }
}

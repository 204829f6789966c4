//! The configuration space of a multibody model and its phase space, as core
//! [`Manifold`]s.
//!
//! Each joint's configuration is one of the core's spaces, with Pinocchio's
//! representation and tangent conventions (checked against the fixtures'
//! `integrate` / `difference` values):
//!
//! | joint | space | q | v |
//! |---|---|---|---|
//! | revolute, prismatic | R | angle, displacement | rate |
//! | unbounded revolute (URDF `continuous`) | [`SO2`] | (cos θ, sin θ) | θ̇ |
//! | free flyer | [`SE3`] | (x, y, z, qx, qy, qz, qw) | (v, ω) in the base frame |
//! | spherical | [`SO3`] | (qx, qy, qz, qw) | ω in the child frame |
//! | planar | [`SE2`] | (x, y, cos θ, sin θ) | (vx, vy, ω) in the child frame |
//! | translation | R³ | translation | its rate |
//!
//! so that the whole configuration space is their Cartesian product (runs of vector
//! joints merged into one `R^n`), with exact Jacobians and dual-number versions for free.

use std::sync::Arc;

use faer::MatMut;
use gharial::spaces::{Arg, CartesianProduct, Manifold, SE2, SE3, SO2, SO3, TangentBundle, VectorSpace};
use gharial_multibody::{JointType, Model};
use rand::{Rng, RngCore};

/// Limits beyond this magnitude are treated as infinite when drawing random
/// configurations (as Pinocchio's benchmark samplers do with `f64::MAX` limits).
pub(crate) const FINITE_LIMIT: f64 = 1e10;

/// The configuration space of a multibody model: `q` of size `nq`, tangent size `nv`.
///
/// ```
/// use std::sync::Arc;
/// use gharial::spaces::Manifold;
/// use gharial_multibody::{Model, RootJoint};
/// use gharial_robotics::MultibodyConfiguration;
/// let urdf = r#"<robot name="r"><link name="a"/><link name="b"/>
///   <joint name="j" type="revolute"><parent link="a"/><child link="b"/>
///   <limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>"#;
/// let model = Arc::new(Model::from_urdf_str(urdf, RootJoint::FreeFlyer)?);
/// let space = MultibodyConfiguration::new(model);
/// assert_eq!((space.nx(), space.ndx()), (8, 7));
/// # Ok::<(), gharial_multibody::Error>(())
/// ```
#[derive(Clone)]
pub struct MultibodyConfiguration {
    model: Arc<Model>,
    product: CartesianProduct,
    /// `(q index, lower, upper)` of every vector coordinate with finite limits.
    bounded: Vec<(usize, f64, f64)>,
}

impl MultibodyConfiguration {
    /// The configuration space of `model`.
    pub fn new(model: Arc<Model>) -> Self {
        let mut parts: Vec<Arc<dyn Manifold>> = Vec::new();
        let mut run = 0;
        let mut bounded = Vec::new();
        for joint in model.joints() {
            let part: Option<Arc<dyn Manifold>> = match joint.kind {
                JointType::Universe => continue,
                JointType::Revolute(_) | JointType::Prismatic(_) | JointType::Translation => None,
                JointType::RevoluteUnbounded(_) => Some(Arc::new(SO2)),
                JointType::FreeFlyer => Some(Arc::new(SE3)),
                JointType::Spherical => Some(Arc::new(SO3)),
                JointType::Planar => Some(Arc::new(SE2)),
            };
            match part {
                None => {
                    run += joint.nq;
                    for i in joint.idx_q..joint.idx_q + joint.nq {
                        let (lo, hi) = (model.lower_position_limit[i], model.upper_position_limit[i]);
                        if lo.abs() <= FINITE_LIMIT && hi.abs() <= FINITE_LIMIT && lo <= hi {
                            bounded.push((i, lo, hi));
                        }
                    }
                }
                Some(p) => {
                    flush_run(&mut parts, &mut run);
                    parts.push(p);
                }
            }
        }
        flush_run(&mut parts, &mut run);
        Self {
            model,
            product: CartesianProduct::new(parts),
            bounded,
        }
    }

    /// The model.
    pub fn model(&self) -> &Arc<Model> {
        &self.model
    }

    /// The product of the joints' spaces that implements the group operations.
    pub fn product(&self) -> &CartesianProduct {
        &self.product
    }
}

/// The model's name and the sizes: spaces appear in error messages, and the model's own
/// `Debug` output is tens of kilobytes.
impl std::fmt::Debug for MultibodyConfiguration {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MultibodyConfiguration")
            .field("model", &self.model.name)
            .field("nq", &self.nx())
            .field("nv", &self.ndx())
            .finish_non_exhaustive()
    }
}

/// Closes a run of vector coordinates as one `R^n` part.
fn flush_run(parts: &mut Vec<Arc<dyn Manifold>>, run: &mut usize) {
    if *run > 0 {
        parts.push(Arc::new(VectorSpace::new(*run)));
        *run = 0;
    }
}

/// Forwards every [`Manifold`] method but `random` to the field `$inner`.
macro_rules! forward_manifold {
    ($inner:ident) => {
        fn nx(&self) -> usize {
            self.$inner.nx()
        }
        fn ndx(&self) -> usize {
            self.$inner.ndx()
        }
        fn neutral(&self, out: &mut [f64]) {
            self.$inner.neutral(out)
        }
        fn integrate(&self, x: &[f64], v: &[f64], out: &mut [f64]) {
            self.$inner.integrate(x, v, out)
        }
        fn difference(&self, x0: &[f64], x1: &[f64], out: &mut [f64]) {
            self.$inner.difference(x0, x1, out)
        }
        fn integrate_dual(&self, x: &[num_dual::Dual64], v: &[num_dual::Dual64], out: &mut [num_dual::Dual64]) {
            self.$inner.integrate_dual(x, v, out)
        }
        fn difference_dual(&self, x0: &[num_dual::Dual64], x1: &[num_dual::Dual64], out: &mut [num_dual::Dual64]) {
            self.$inner.difference_dual(x0, x1, out)
        }
        fn integrate_hyper(
            &self,
            x: &[num_dual::HyperDual64],
            v: &[num_dual::HyperDual64],
            out: &mut [num_dual::HyperDual64],
        ) {
            self.$inner.integrate_hyper(x, v, out)
        }
        fn difference_hyper(
            &self,
            x0: &[num_dual::HyperDual64],
            x1: &[num_dual::HyperDual64],
            out: &mut [num_dual::HyperDual64],
        ) {
            self.$inner.difference_hyper(x0, x1, out)
        }
        fn interpolate(&self, x0: &[f64], x1: &[f64], t: f64, out: &mut [f64]) {
            self.$inner.interpolate(x0, x1, t, out)
        }
        fn jintegrate(&self, x: &[f64], v: &[f64], arg: Arg, j: MatMut<'_, f64>) {
            self.$inner.jintegrate(x, v, arg, j)
        }
        fn jdifference(&self, x0: &[f64], x1: &[f64], arg: Arg, j: MatMut<'_, f64>) {
            self.$inner.jdifference(x0, x1, arg, j)
        }
        fn jintegrate_transport(&self, x: &[f64], v: &[f64], arg: Arg, m: MatMut<'_, f64>) {
            self.$inner.jintegrate_transport(x, v, arg, m)
        }
        fn tangent_map(&self, x: &[f64], j: MatMut<'_, f64>) {
            self.$inner.tangent_map(x, j)
        }
        fn tangent_map_inverse(&self, x: &[f64], j: MatMut<'_, f64>) {
            self.$inner.tangent_map_inverse(x, j)
        }
        fn normalize(&self, x: &mut [f64]) {
            self.$inner.normalize(x)
        }
        fn is_valid(&self, x: &[f64]) -> bool {
            self.$inner.is_valid(x)
        }
        fn is_vector_space(&self) -> bool {
            self.$inner.is_vector_space()
        }
        fn nonlinear_dim(&self) -> usize {
            self.$inner.nonlinear_dim()
        }
        fn jdifference_block(&self, x0: &[f64], x1: &[f64], arg: Arg, j: MatMut<'_, f64>) {
            self.$inner.jdifference_block(x0, x1, arg, j)
        }
    };
}

impl Manifold for MultibodyConfiguration {
    forward_manifold!(product);

    /// A random configuration: vector coordinates uniform within their finite position
    /// limits (in `[-1, 1]` where a limit is infinite), rotations uniform.
    fn random(&self, rng: &mut dyn RngCore, out: &mut [f64]) {
        self.product.random(rng, out);
        for &(i, lo, hi) in &self.bounded {
            out[i] = if lo < hi { rng.random_range(lo..=hi) } else { lo };
        }
    }
}

/// The phase space of a multibody model: `x = (q, v)`, `nx = nq + nv`, `ndx = 2 nv`,
/// `(q, v) ⊕ (dq, dv) = (q ⊕ dq, v + dv)` (the tangent bundle of
/// [`MultibodyConfiguration`], as ALIGATOR's `MultibodyPhaseSpace`).
#[derive(Clone)]
pub struct MultibodyPhaseSpace {
    configuration: Arc<MultibodyConfiguration>,
    bundle: TangentBundle,
}

impl MultibodyPhaseSpace {
    /// The phase space of `model`.
    pub fn new(model: Arc<Model>) -> Self {
        let configuration = Arc::new(MultibodyConfiguration::new(model));
        let bundle = TangentBundle::new(configuration.clone());
        Self { configuration, bundle }
    }

    /// The model.
    pub fn model(&self) -> &Arc<Model> {
        self.configuration.model()
    }

    /// The configuration space of `q`.
    pub fn configuration(&self) -> &Arc<MultibodyConfiguration> {
        &self.configuration
    }

    /// Configuration size `nq`.
    pub fn nq(&self) -> usize {
        self.configuration.nx()
    }

    /// Velocity size `nv`.
    pub fn nv(&self) -> usize {
        self.configuration.ndx()
    }
}

impl std::fmt::Debug for MultibodyPhaseSpace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MultibodyPhaseSpace")
            .field("model", &self.model().name)
            .field("nq", &self.nq())
            .field("nv", &self.nv())
            .finish_non_exhaustive()
    }
}

impl Manifold for MultibodyPhaseSpace {
    forward_manifold!(bundle);

    fn random(&self, rng: &mut dyn RngCore, out: &mut [f64]) {
        self.bundle.random(rng, out)
    }
}

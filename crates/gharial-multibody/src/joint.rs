//! Joint types: configuration layout, joint transform and motion subspace.
//!
//! Every joint type here has a constant motion subspace `S` in its own (child) frame and
//! no bias acceleration (`c = 0`), and its configuration space is a Lie group with
//! `q ⊕ v` such that `M_J(q ⊕ v) = M_J(q) exp(S v)`.

use crate::spatial::{Force, Mat3, Motion, Se3, Vec3};
use nalgebra::{Quaternion, UnitQuaternion};

/// Axis of a one-degree-of-freedom joint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Axis {
    /// +x.
    X,
    /// +y.
    Y,
    /// +z.
    Z,
    /// Any other unit axis.
    Unaligned(Vec3),
}

impl Axis {
    /// Axis from a nonzero finite direction: aligned only when exactly +x, +y or +z;
    /// otherwise the normalized direction (computed without overflow or underflow for
    /// huge or tiny entries).
    pub fn from_vector(v: Vec3) -> Axis {
        if v == Vec3::x() {
            Axis::X
        } else if v == Vec3::y() {
            Axis::Y
        } else if v == Vec3::z() {
            Axis::Z
        } else {
            let u = v / v.amax();
            Axis::Unaligned(u / u.norm())
        }
    }

    /// The unit vector.
    pub fn vector(&self) -> Vec3 {
        match self {
            Axis::X => Vec3::x(),
            Axis::Y => Vec3::y(),
            Axis::Z => Vec3::z(),
            Axis::Unaligned(v) => *v,
        }
    }
}

/// Joint type.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum JointType {
    /// The universe (joint 0); no degree of freedom.
    Universe,
    /// Revolute joint, q = angle (nq = nv = 1).
    Revolute(Axis),
    /// Unbounded revolute joint (URDF `continuous`), q = (cos θ, sin θ) (nq = 2, nv = 1).
    RevoluteUnbounded(Axis),
    /// Prismatic joint, q = displacement.
    Prismatic(Axis),
    /// Free flyer: q = [x, y, z, qx, qy, qz, qw], v = [v_lin, ω] in the child frame.
    FreeFlyer,
    /// Spherical joint: q = unit quaternion [qx, qy, qz, qw], v = ω in the child frame.
    Spherical,
    /// Planar joint in the xy plane: q = [x, y, cos θ, sin θ], v = [vx, vy, ωz] in the child frame.
    Planar,
    /// Translation joint: q = v = translation (3).
    Translation,
}

impl JointType {
    /// Configuration size.
    pub fn nq(&self) -> usize {
        match self {
            JointType::Universe => 0,
            JointType::Revolute(_) | JointType::Prismatic(_) => 1,
            JointType::RevoluteUnbounded(_) => 2,
            JointType::FreeFlyer => 7,
            JointType::Spherical | JointType::Planar => 4,
            JointType::Translation => 3,
        }
    }

    /// Tangent (velocity) size.
    pub fn nv(&self) -> usize {
        match self {
            JointType::Universe => 0,
            JointType::Revolute(_) | JointType::Prismatic(_) | JointType::RevoluteUnbounded(_) => 1,
            JointType::FreeFlyer => 6,
            JointType::Spherical | JointType::Planar | JointType::Translation => 3,
        }
    }

    /// Pinocchio's short name (`JointModelRX`, `JointModelRUBX`, `JointModelFreeFlyer`, ...).
    pub fn shortname(&self) -> &'static str {
        match self {
            JointType::Universe => "universe",
            JointType::Revolute(Axis::X) => "JointModelRX",
            JointType::Revolute(Axis::Y) => "JointModelRY",
            JointType::Revolute(Axis::Z) => "JointModelRZ",
            JointType::Revolute(Axis::Unaligned(_)) => "JointModelRevoluteUnaligned",
            JointType::RevoluteUnbounded(Axis::X) => "JointModelRUBX",
            JointType::RevoluteUnbounded(Axis::Y) => "JointModelRUBY",
            JointType::RevoluteUnbounded(Axis::Z) => "JointModelRUBZ",
            JointType::RevoluteUnbounded(Axis::Unaligned(_)) => "JointModelRevoluteUnboundedUnaligned",
            JointType::Prismatic(Axis::X) => "JointModelPX",
            JointType::Prismatic(Axis::Y) => "JointModelPY",
            JointType::Prismatic(Axis::Z) => "JointModelPZ",
            JointType::Prismatic(Axis::Unaligned(_)) => "JointModelPrismaticUnaligned",
            JointType::FreeFlyer => "JointModelFreeFlyer",
            JointType::Spherical => "JointModelSpherical",
            JointType::Planar => "JointModelPlanar",
            JointType::Translation => "JointModelTranslation",
        }
    }

    /// The block of the joint's configuration that must have unit norm, as (offset in
    /// the joint's q, length): the quaternion of a free flyer or spherical joint, the
    /// (cos θ, sin θ) pair of an unbounded revolute or planar joint; `None` otherwise.
    pub fn unit_block(&self) -> Option<(usize, usize)> {
        match self {
            JointType::RevoluteUnbounded(_) => Some((0, 2)),
            JointType::FreeFlyer => Some((3, 4)),
            JointType::Spherical => Some((0, 4)),
            JointType::Planar => Some((2, 2)),
            _ => None,
        }
    }

    /// The axis of a one-degree-of-freedom joint given as unaligned, else `None`.
    pub fn unaligned_axis(&self) -> Option<Vec3> {
        match self {
            JointType::Revolute(Axis::Unaligned(a))
            | JointType::RevoluteUnbounded(Axis::Unaligned(a))
            | JointType::Prismatic(Axis::Unaligned(a)) => Some(*a),
            _ => None,
        }
    }

    /// Columns of the motion subspace `S` in the child frame (first `nv` entries used).
    pub fn subspace(&self) -> [Motion; 6] {
        let mut s = [Motion::zero(); 6];
        let e = |k: usize| {
            let mut a = [0.0; 6];
            a[k] = 1.0;
            Motion::from_slice(&a)
        };
        match self {
            JointType::Universe => {}
            JointType::Revolute(a) | JointType::RevoluteUnbounded(a) => s[0] = Motion::new(Vec3::zeros(), a.vector()),
            JointType::Prismatic(a) => s[0] = Motion::new(a.vector(), Vec3::zeros()),
            JointType::FreeFlyer => (0..6).for_each(|k| s[k] = e(k)),
            JointType::Spherical => (0..3).for_each(|k| s[k] = e(3 + k)),
            JointType::Translation => (0..3).for_each(|k| s[k] = e(k)),
            JointType::Planar => {
                s[0] = e(0);
                s[1] = e(1);
                s[2] = e(5);
            }
        }
        s
    }

    /// Joint transform `M_J(q)` (child frame in the joint's placement frame); `q` is the
    /// joint's own configuration (length `nq`).
    #[inline]
    pub fn transform(&self, q: &[f64]) -> Se3 {
        match self {
            JointType::Universe => Se3::identity(),
            JointType::Revolute(a) => {
                let (s, c) = q[0].sin_cos();
                Se3::new(axis_rotation(a, c, s), Vec3::zeros())
            }
            JointType::RevoluteUnbounded(a) => Se3::new(axis_rotation(a, q[0], q[1]), Vec3::zeros()),
            JointType::Prismatic(a) => Se3::new(Mat3::identity(), a.vector() * q[0]),
            JointType::FreeFlyer => Se3::new(quat_matrix(&q[3..7]), Vec3::new(q[0], q[1], q[2])),
            JointType::Spherical => Se3::new(quat_matrix(&q[0..4]), Vec3::zeros()),
            JointType::Planar => Se3::new(axis_rotation(&Axis::Z, q[2], q[3]), Vec3::new(q[0], q[1], 0.0)),
            JointType::Translation => Se3::new(Mat3::identity(), Vec3::new(q[0], q[1], q[2])),
        }
    }
}

impl JointType {
    /// `placement · M_J(q)` (the joint frame in its parent joint frame), with the product
    /// specialised to the joint type: an aligned revolute joint touches two columns of the
    /// rotation, a prismatic joint only the translation.
    #[inline]
    pub(crate) fn placed_transform(&self, placement: &Se3, q: &[f64]) -> Se3 {
        match self {
            JointType::Revolute(a) => {
                let (s, c) = q[0].sin_cos();
                placement_rotated(placement, a, c, s)
            }
            JointType::RevoluteUnbounded(a) => placement_rotated(placement, a, q[0], q[1]),
            JointType::Prismatic(a) => {
                let r = &placement.rotation;
                let d = match a {
                    Axis::X => r.column(0) * q[0],
                    Axis::Y => r.column(1) * q[0],
                    Axis::Z => r.column(2) * q[0],
                    Axis::Unaligned(u) => r * (u * q[0]),
                };
                Se3::new(*r, placement.translation + d)
            }
            _ => placement.compose(&self.transform(q)),
        }
    }

    /// World Jacobian columns `oMi · S_k` of the joint (first `nv` entries of `out`) for
    /// the world placement `o` of its frame.
    #[inline]
    pub(crate) fn world_columns(&self, o: &Se3, out: &mut [Motion]) {
        let r = &o.rotation;
        let p = &o.translation;
        let col = |k: usize| Vec3::new(r[(0, k)], r[(1, k)], r[(2, k)]);
        let angular = |w: Vec3| Motion::new(p.cross(&w), w);
        let linear = |u: Vec3| Motion::new(u, Vec3::zeros());
        let axis = |a: &Axis| match a {
            Axis::X => col(0),
            Axis::Y => col(1),
            Axis::Z => col(2),
            Axis::Unaligned(u) => r * u,
        };
        match self {
            JointType::Universe => {}
            JointType::Revolute(a) | JointType::RevoluteUnbounded(a) => out[0] = angular(axis(a)),
            JointType::Prismatic(a) => out[0] = linear(axis(a)),
            JointType::FreeFlyer => {
                for k in 0..3 {
                    let u = col(k);
                    out[k] = linear(u);
                    out[3 + k] = angular(u);
                }
            }
            JointType::Spherical => (0..3).for_each(|k| out[k] = angular(col(k))),
            JointType::Translation => (0..3).for_each(|k| out[k] = linear(col(k))),
            JointType::Planar => {
                out[0] = linear(col(0));
                out[1] = linear(col(1));
                out[2] = angular(col(2));
            }
        }
    }
}

impl JointType {
    /// Joint velocity `S x` in the joint's own (child) frame for the joint's tangent
    /// coordinates `x` (length `nv`).
    #[inline]
    pub(crate) fn local_motion(&self, x: &[f64]) -> Motion {
        let z = Vec3::zeros();
        match self {
            JointType::Universe => Motion::zero(),
            JointType::Revolute(a) | JointType::RevoluteUnbounded(a) => Motion::new(z, axis_times(a, x[0])),
            JointType::Prismatic(a) => Motion::new(axis_times(a, x[0]), z),
            JointType::FreeFlyer => Motion::from_slice(x),
            JointType::Spherical => Motion::new(z, Vec3::new(x[0], x[1], x[2])),
            JointType::Translation => Motion::new(Vec3::new(x[0], x[1], x[2]), z),
            JointType::Planar => Motion::new(Vec3::new(x[0], x[1], 0.0), Vec3::new(0.0, 0.0, x[2])),
        }
    }

    /// `m × (S x)`, with the product specialised to the joint's motion subspace.
    #[inline]
    pub(crate) fn cross_local_motion(&self, m: &Motion, x: &[f64]) -> Motion {
        match self {
            JointType::Revolute(a) | JointType::RevoluteUnbounded(a) => {
                Motion::new(cross_axis(&m.linear, a, x[0]), cross_axis(&m.angular, a, x[0]))
            }
            JointType::Prismatic(a) => Motion::new(cross_axis(&m.angular, a, x[0]), Vec3::zeros()),
            _ => m.cross(&self.local_motion(x)),
        }
    }

    /// `Sᵀ f` for a force `f` in the joint's own frame, written into `out` (length `nv`).
    #[inline]
    pub(crate) fn project_local_force(&self, f: &Force, out: &mut [f64]) {
        let dot_axis = |u: &Vec3, a: &Axis| match a {
            Axis::X => u.x,
            Axis::Y => u.y,
            Axis::Z => u.z,
            Axis::Unaligned(d) => u.dot(d),
        };
        match self {
            JointType::Universe => {}
            JointType::Revolute(a) | JointType::RevoluteUnbounded(a) => out[0] = dot_axis(&f.angular, a),
            JointType::Prismatic(a) => out[0] = dot_axis(&f.linear, a),
            JointType::FreeFlyer => out[..6].copy_from_slice(&f.to_array()),
            JointType::Spherical => out[..3].copy_from_slice(f.angular.as_slice()),
            JointType::Translation => out[..3].copy_from_slice(f.linear.as_slice()),
            JointType::Planar => {
                out[0] = f.linear.x;
                out[1] = f.linear.y;
                out[2] = f.angular.z;
            }
        }
    }
}

/// `w a` for a unit axis.
#[inline]
fn axis_times(a: &Axis, w: f64) -> Vec3 {
    match a {
        Axis::X => Vec3::new(w, 0.0, 0.0),
        Axis::Y => Vec3::new(0.0, w, 0.0),
        Axis::Z => Vec3::new(0.0, 0.0, w),
        Axis::Unaligned(u) => u * w,
    }
}

/// `u × (w a)` for a unit axis `a`.
#[inline]
fn cross_axis(u: &Vec3, a: &Axis, w: f64) -> Vec3 {
    match a {
        Axis::X => Vec3::new(0.0, u.z * w, -(u.y * w)),
        Axis::Y => Vec3::new(-(u.z * w), 0.0, u.x * w),
        Axis::Z => Vec3::new(u.y * w, -(u.x * w), 0.0),
        Axis::Unaligned(d) => u.cross(&(d * w)),
    }
}

/// `placement · R_axis(c, s)`: only the rotation changes.
#[inline]
fn placement_rotated(placement: &Se3, a: &Axis, c: f64, s: f64) -> Se3 {
    let r = &placement.rotation;
    let rot = match a {
        Axis::X => {
            let (r1, r2) = (r.column(1), r.column(2));
            Mat3::from_columns(&[r.column(0).into_owned(), r1 * c + r2 * s, r2 * c - r1 * s])
        }
        Axis::Y => {
            let (r0, r2) = (r.column(0), r.column(2));
            Mat3::from_columns(&[r0 * c - r2 * s, r.column(1).into_owned(), r0 * s + r2 * c])
        }
        Axis::Z => {
            let (r0, r1) = (r.column(0), r.column(1));
            Mat3::from_columns(&[r0 * c + r1 * s, r1 * c - r0 * s, r.column(2).into_owned()])
        }
        Axis::Unaligned(_) => r * axis_rotation(a, c, s),
    };
    Se3::new(rot, placement.translation)
}

/// Rotation about an axis given cos and sin of the angle.
#[inline]
fn axis_rotation(a: &Axis, c: f64, s: f64) -> Mat3 {
    match a {
        Axis::X => Mat3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c),
        Axis::Y => Mat3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c),
        Axis::Z => Mat3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0),
        Axis::Unaligned(u) => {
            let w = crate::spatial::skew(u);
            Mat3::identity() + w * s + w * w * (1.0 - c)
        }
    }
}

/// Rotation matrix of a quaternion stored as `[x, y, z, w]` (assumed unit).
#[inline]
pub(crate) fn quat_matrix(q: &[f64]) -> Mat3 {
    quat_from_slice(q).to_rotation_matrix().into_inner()
}

/// Unit quaternion from `[x, y, z, w]` (not renormalized).
#[inline]
pub(crate) fn quat_from_slice(q: &[f64]) -> UnitQuaternion<f64> {
    UnitQuaternion::new_unchecked(Quaternion::new(q[3], q[0], q[1], q[2]))
}

/// Model of one joint: type and position of its coordinates in q and v.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointModel {
    /// Joint type.
    pub kind: JointType,
    /// First index in q.
    pub idx_q: usize,
    /// First index in v.
    pub idx_v: usize,
    /// Configuration size.
    pub nq: usize,
    /// Tangent size.
    pub nv: usize,
}

//! Spatial algebra in Pinocchio's `[linear, angular]` order.
//!
//! A motion vector `m = [v, ω]` (velocity of the body point at the reference origin and
//! angular velocity); a force vector `f = [f, τ]` (force and torque about the reference
//! origin). Placements `aMb` map coordinates in frame b to frame a: `x_a = R x_b + p`.

use core::ops::{Add, AddAssign, Mul, Neg, Sub, SubAssign};
use nalgebra::{Matrix3, Vector3};

/// 3D vector of `f64`.
pub type Vec3 = Vector3<f64>;
/// 3×3 matrix of `f64`.
pub type Mat3 = Matrix3<f64>;

/// True when every entry is finite. Branch-free (`x · 0` is 0 for a finite x and NaN
/// otherwise; four independent sums), so that it vectorizes: about one instruction per
/// entry, which keeps the result checks of the algorithms cheap.
#[inline]
pub fn all_finite(x: &[f64]) -> bool {
    let mut acc = [0.0f64; 4];
    add_times_zero(&mut acc, x);
    (acc[0] + acc[1]) + (acc[2] + acc[3]) == 0.0
}

/// The sums of [`all_finite`], `x · 0` added into four accumulators (several slices can
/// share them: one test at the end).
#[inline(always)]
pub(crate) fn add_times_zero(acc: &mut [f64; 4], x: &[f64]) {
    let chunks = x.chunks_exact(4);
    let tail = chunks.remainder();
    for c in chunks {
        for k in 0..4 {
            acc[k] += c[k] * 0.0;
        }
    }
    for (a, v) in acc.iter_mut().zip(tail) {
        *a += v * 0.0;
    }
}

/// [`all_finite`] for the few entries of a fixed-size vector or matrix: one sum, unrolled.
#[inline]
fn few_finite(x: &[f64]) -> bool {
    x.iter().fold(0.0, |s, v| s + v * 0.0) == 0.0
}

/// Skew-symmetric matrix `[a]×` such that `[a]× b = a × b`.
#[inline]
pub fn skew(a: &Vec3) -> Mat3 {
    Mat3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

/// Spatial motion vector (twist): linear part first, then angular part.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Motion {
    /// Linear velocity of the body point at the reference origin.
    pub linear: Vec3,
    /// Angular velocity.
    pub angular: Vec3,
}

/// Spatial force vector (wrench): force first, then torque about the reference origin.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Force {
    /// Force.
    pub linear: Vec3,
    /// Torque about the reference origin.
    pub angular: Vec3,
}

impl Motion {
    /// The zero motion.
    #[inline]
    pub fn zero() -> Self {
        Self::default()
    }

    /// Motion from its linear and angular parts.
    #[inline]
    pub fn new(linear: Vec3, angular: Vec3) -> Self {
        Self { linear, angular }
    }

    /// Motion from the first six entries of a slice `[v, ω]`.
    #[inline]
    pub fn from_slice(s: &[f64]) -> Self {
        Self::new(Vec3::new(s[0], s[1], s[2]), Vec3::new(s[3], s[4], s[5]))
    }

    /// The six coordinates `[v, ω]`.
    #[inline]
    pub fn to_array(&self) -> [f64; 6] {
        [
            self.linear.x,
            self.linear.y,
            self.linear.z,
            self.angular.x,
            self.angular.y,
            self.angular.z,
        ]
    }

    /// Coordinate `k` (0..3 linear, 3..6 angular).
    #[inline]
    pub fn get(&self, k: usize) -> f64 {
        if k < 3 { self.linear[k] } else { self.angular[k - 3] }
    }

    /// Motion cross product `self × m`.
    #[inline]
    pub fn cross(&self, m: &Motion) -> Motion {
        Motion {
            linear: self.angular.cross(&m.linear) + self.linear.cross(&m.angular),
            angular: self.angular.cross(&m.angular),
        }
    }

    /// Dual cross product `self ×* f` acting on a force.
    #[inline]
    pub fn cross_force(&self, f: &Force) -> Force {
        Force {
            linear: self.angular.cross(&f.linear),
            angular: self.angular.cross(&f.angular) + self.linear.cross(&f.linear),
        }
    }

    /// Power pairing `⟨self, f⟩ = v·f + ω·τ`.
    #[inline]
    pub fn dot(&self, f: &Force) -> f64 {
        self.linear.dot(&f.linear) + self.angular.dot(&f.angular)
    }

    /// The same motion with its reference point moved by `-p`: `[v + ω × p, ω]`, i.e.
    /// the twist at the point `p` (coordinates unchanged).
    #[inline]
    pub fn shifted_to(&self, p: &Vec3) -> Motion {
        Motion {
            linear: self.linear + self.angular.cross(p),
            angular: self.angular,
        }
    }

    /// Largest absolute coordinate.
    #[inline]
    pub fn amax(&self) -> f64 {
        self.linear.amax().max(self.angular.amax())
    }
}

impl Force {
    /// The zero force.
    #[inline]
    pub fn zero() -> Self {
        Self::default()
    }

    /// Force from its linear and angular parts.
    #[inline]
    pub fn new(linear: Vec3, angular: Vec3) -> Self {
        Self { linear, angular }
    }

    /// The six coordinates `[f, τ]`.
    #[inline]
    pub fn to_array(&self) -> [f64; 6] {
        [
            self.linear.x,
            self.linear.y,
            self.linear.z,
            self.angular.x,
            self.angular.y,
            self.angular.z,
        ]
    }

    /// Coordinate `k` (0..3 force, 3..6 torque).
    #[inline]
    pub fn get(&self, k: usize) -> f64 {
        if k < 3 { self.linear[k] } else { self.angular[k - 3] }
    }

    /// Pairing with a motion (`f·v + τ·ω`).
    #[inline]
    pub fn dot_motion(&self, m: &Motion) -> f64 {
        m.dot(self)
    }
}

macro_rules! vec6_ops {
    ($t:ty) => {
        impl $t {
            /// True when all six coordinates are finite.
            #[inline]
            pub fn is_finite(&self) -> bool {
                few_finite(self.linear.as_slice()) & few_finite(self.angular.as_slice())
            }
        }

        impl Add for $t {
            type Output = $t;
            #[inline]
            fn add(self, o: $t) -> $t {
                Self {
                    linear: self.linear + o.linear,
                    angular: self.angular + o.angular,
                }
            }
        }
        impl Sub for $t {
            type Output = $t;
            #[inline]
            fn sub(self, o: $t) -> $t {
                Self {
                    linear: self.linear - o.linear,
                    angular: self.angular - o.angular,
                }
            }
        }
        impl AddAssign for $t {
            #[inline]
            fn add_assign(&mut self, o: $t) {
                self.linear += o.linear;
                self.angular += o.angular;
            }
        }
        impl SubAssign for $t {
            #[inline]
            fn sub_assign(&mut self, o: $t) {
                self.linear -= o.linear;
                self.angular -= o.angular;
            }
        }
        impl Neg for $t {
            type Output = $t;
            #[inline]
            fn neg(self) -> $t {
                Self {
                    linear: -self.linear,
                    angular: -self.angular,
                }
            }
        }
        impl Mul<f64> for $t {
            type Output = $t;
            #[inline]
            fn mul(self, s: f64) -> $t {
                Self {
                    linear: self.linear * s,
                    angular: self.angular * s,
                }
            }
        }
    };
}
vec6_ops!(Motion);
vec6_ops!(Force);

/// Rigid placement `aMb = (R, p)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Se3 {
    /// Rotation `aRb`.
    pub rotation: Mat3,
    /// Translation: origin of b in a.
    pub translation: Vec3,
}

impl Default for Se3 {
    fn default() -> Self {
        Self::identity()
    }
}

impl Se3 {
    /// The identity placement.
    #[inline]
    pub fn identity() -> Self {
        Self {
            rotation: Mat3::identity(),
            translation: Vec3::zeros(),
        }
    }

    /// Placement from a rotation and a translation.
    #[inline]
    pub fn new(rotation: Mat3, translation: Vec3) -> Self {
        Self { rotation, translation }
    }

    /// True when the rotation and translation entries are all finite.
    #[inline]
    pub fn is_finite(&self) -> bool {
        few_finite(self.rotation.as_slice()) & few_finite(self.translation.as_slice())
    }

    /// Composition `self * m`.
    #[inline]
    pub fn compose(&self, m: &Se3) -> Se3 {
        Se3 {
            rotation: self.rotation * m.rotation,
            translation: self.translation + self.rotation * m.translation,
        }
    }

    /// `self⁻¹ * m`.
    #[inline]
    pub fn inv_compose(&self, m: &Se3) -> Se3 {
        let rt = self.rotation.transpose();
        Se3 {
            rotation: rt * m.rotation,
            translation: rt * (m.translation - self.translation),
        }
    }

    /// Inverse placement.
    #[inline]
    pub fn inverse(&self) -> Se3 {
        let rt = self.rotation.transpose();
        Se3 {
            rotation: rt,
            translation: -(rt * self.translation),
        }
    }

    /// Maps a point of frame b to frame a.
    #[inline]
    pub fn act_point(&self, x: &Vec3) -> Vec3 {
        self.rotation * x + self.translation
    }

    /// Motion expressed in b to a: `[R v + p × Rω, Rω]`.
    #[inline]
    pub fn act_motion(&self, m: &Motion) -> Motion {
        let w = self.rotation * m.angular;
        Motion {
            linear: self.rotation * m.linear + self.translation.cross(&w),
            angular: w,
        }
    }

    /// Motion expressed in a to b: `[Rᵀ(v − p × ω), Rᵀω]`.
    #[inline]
    pub fn act_inv_motion(&self, m: &Motion) -> Motion {
        let rt = self.rotation.transpose();
        Motion {
            linear: rt * (m.linear - self.translation.cross(&m.angular)),
            angular: rt * m.angular,
        }
    }

    /// Force expressed in b to a: `[R f, Rτ + p × R f]`.
    #[inline]
    pub fn act_force(&self, f: &Force) -> Force {
        let rf = self.rotation * f.linear;
        Force {
            linear: rf,
            angular: self.rotation * f.angular + self.translation.cross(&rf),
        }
    }

    /// Force expressed in a to b: `[Rᵀ f, Rᵀ(τ − p × f)]`.
    #[inline]
    pub fn act_inv_force(&self, f: &Force) -> Force {
        let rt = self.rotation.transpose();
        Force {
            linear: rt * f.linear,
            angular: rt * (f.angular - self.translation.cross(&f.linear)),
        }
    }

    /// 4×4 homogeneous matrix, row-major.
    pub fn to_homogeneous(&self) -> [[f64; 4]; 4] {
        let r = &self.rotation;
        let p = &self.translation;
        [
            [r[(0, 0)], r[(0, 1)], r[(0, 2)], p.x],
            [r[(1, 0)], r[(1, 1)], r[(1, 2)], p.y],
            [r[(2, 0)], r[(2, 1)], r[(2, 2)], p.z],
            [0.0, 0.0, 0.0, 1.0],
        ]
    }
}

/// Rigid-body spatial inertia, stored as mass `m`, first moment `h = m c` and rotational
/// inertia `I_o` about the reference origin. As a 6×6 matrix (Pinocchio order):
/// `[[m I, −[h]×], [[h]×, I_o]]`, with `I_o = I_c − m [c]×²`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inertia {
    /// Mass.
    pub mass: f64,
    /// First moment of mass `m c` about the reference origin.
    pub first_moment: Vec3,
    /// Rotational inertia about the reference origin.
    pub rotational: Mat3,
}

impl Default for Inertia {
    fn default() -> Self {
        Self::zero()
    }
}

impl Inertia {
    /// The zero inertia.
    #[inline]
    pub fn zero() -> Self {
        Self {
            mass: 0.0,
            first_moment: Vec3::zeros(),
            rotational: Mat3::zeros(),
        }
    }

    /// Inertia from the mass, the centre of mass `c` and the rotational inertia `I_c`
    /// about the centre of mass.
    pub fn from_com(mass: f64, com: Vec3, inertia_com: Mat3) -> Self {
        let offset = mass * (Mat3::identity() * com.norm_squared() - com * com.transpose());
        Self {
            mass,
            first_moment: com * mass,
            rotational: inertia_com + offset,
        }
    }

    /// True when the mass, first moment and rotational inertia are all finite.
    pub fn is_finite(&self) -> bool {
        self.mass.is_finite() & few_finite(self.first_moment.as_slice()) & few_finite(self.rotational.as_slice())
    }

    /// Centre of mass (zero for a massless body).
    pub fn lever(&self) -> Vec3 {
        if self.mass > 0.0 {
            self.first_moment / self.mass
        } else {
            Vec3::zeros()
        }
    }

    /// Rotational inertia about the centre of mass.
    pub fn inertia_com(&self) -> Mat3 {
        let c = self.lever();
        self.rotational - self.mass * (Mat3::identity() * c.norm_squared() - c * c.transpose())
    }

    /// The 6×6 matrix, row-major, Pinocchio order.
    pub fn matrix6(&self) -> [[f64; 6]; 6] {
        let mut out = [[0.0; 6]; 6];
        let h = skew(&self.first_moment);
        for i in 0..3 {
            out[i][i] = self.mass;
            for j in 0..3 {
                out[i][3 + j] = -h[(i, j)];
                out[3 + i][j] = h[(i, j)];
                out[3 + i][3 + j] = self.rotational[(i, j)];
            }
        }
        out
    }

    /// Momentum `Y m = [m v − h × ω, h × v + I_o ω]`.
    #[inline]
    pub fn mul_motion(&self, m: &Motion) -> Force {
        Force {
            linear: m.linear * self.mass - self.first_moment.cross(&m.angular),
            angular: self.first_moment.cross(&m.linear) + self.rotational * m.angular,
        }
    }

    /// The inertia expressed in frame a, given in frame b and `aMb = x = (R, p)`:
    /// `h' = R h + m p` and, with `g = R h` and `u = g + m p / 2`,
    /// `I' = R I Rᵀ − [p]×[u]× − [u]×[p]× = R I Rᵀ + 2 (u·p) 𝟙 − u pᵀ − p uᵀ`.
    #[inline]
    pub fn transformed(&self, x: &Se3) -> Inertia {
        let r = &x.rotation;
        let p = &x.translation;
        let g = r * self.first_moment;
        let u = g + p * (0.5 * self.mass);
        let d = 2.0 * u.dot(p);
        // R I Rᵀ, upper triangle only (I symmetric).
        let a = r * self.rotational;
        let e = |i: usize, j: usize| a[(i, 0)] * r[(j, 0)] + a[(i, 1)] * r[(j, 1)] + a[(i, 2)] * r[(j, 2)];
        let s = |i: usize, j: usize| e(i, j) - (u[i] * p[j] + p[i] * u[j]);
        let (xx, yy, zz) = (
            e(0, 0) + d - 2.0 * u[0] * p[0],
            e(1, 1) + d - 2.0 * u[1] * p[1],
            e(2, 2) + d - 2.0 * u[2] * p[2],
        );
        let (xy, xz, yz) = (s(0, 1), s(0, 2), s(1, 2));
        Inertia {
            mass: self.mass,
            first_moment: g + p * self.mass,
            rotational: Mat3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz),
        }
    }
}

impl AddAssign for Inertia {
    #[inline]
    fn add_assign(&mut self, o: Inertia) {
        self.mass += o.mass;
        self.first_moment += o.first_moment;
        self.rotational += o.rotational;
    }
}

/// Symmetric 6×6 operator on motions (articulated-body inertia), stored by 3×3 blocks:
/// `f = A v + B ω`, `τ = Bᵀ v + C ω`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sym6 {
    /// Linear-linear block.
    pub a: Mat3,
    /// Linear-angular block.
    pub b: Mat3,
    /// Angular-angular block.
    pub c: Mat3,
}

impl Default for Sym6 {
    fn default() -> Self {
        Self {
            a: Mat3::zeros(),
            b: Mat3::zeros(),
            c: Mat3::zeros(),
        }
    }
}

impl Sym6 {
    /// The matrix of a rigid inertia.
    #[inline]
    pub fn from_inertia(y: &Inertia) -> Self {
        Self {
            a: Mat3::identity() * y.mass,
            b: -skew(&y.first_moment),
            c: y.rotational,
        }
    }

    /// Product with a motion.
    #[inline]
    pub fn mul_motion(&self, m: &Motion) -> Force {
        Force {
            linear: self.a * m.linear + self.b * m.angular,
            angular: self.b.tr_mul(&m.linear) + self.c * m.angular,
        }
    }

    /// `self -= x yᵀ` for two forces (as 6-vectors) whose outer product is symmetric in
    /// sum (used for `U D⁻¹ Uᵀ`).
    #[inline]
    pub fn sub_outer(&mut self, x: &Force, y: &Force) {
        self.a -= x.linear * y.linear.transpose();
        self.b -= x.linear * y.angular.transpose();
        self.c -= x.angular * y.angular.transpose();
    }
}

impl AddAssign for Sym6 {
    #[inline]
    fn add_assign(&mut self, o: Sym6) {
        self.a += o.a;
        self.b += o.b;
        self.c += o.c;
    }
}

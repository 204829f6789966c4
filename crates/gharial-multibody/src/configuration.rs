//! Configuration-space operations: neutral, random, normalize, integrate, difference and
//! the Jacobians of integrate and difference, joint by joint on the product Lie group.
//!
//! `integrate(q, v) = q ⊕ v` with `M_J(q ⊕ v) = M_J(q) exp(S v)` (the coupled SE(3)
//! exponential for the free flyer), `difference(q0, q1) = q1 ⊖ q0` with
//! `integrate(q0, difference(q0, q1)) = q1`. Jacobians are taken with respect to tangent
//! (right) perturbations `q ⊕ δ`, as in Pinocchio's `dIntegrate` / `dDifference`.

use crate::error::{Error, Result, check_result_mat, check_result_vec, check_vec};
use crate::joint::{JointType, quat_from_slice};
use crate::lie::{
    ad_inv_blocks, exp3, exp3_quat, exp6, jexp3, jexp6_blocks, jlog3, jlog6_blocks, log3_quat, log6_with_phi,
};
use crate::model::{ArgumentPosition, Model};
use crate::spatial::{Mat3, Motion, Se3, Vec3};
use faer::MatMut;
use nalgebra::Quaternion;
use rand::Rng;

/// The neutral configuration: zero angles and displacements, `[1, 0]` for unbounded
/// revolute joints and the identity quaternion `[0, 0, 0, 1]`.
pub fn neutral(model: &Model) -> Vec<f64> {
    let mut q = vec![0.0; model.nq];
    for jm in &model.joints[1..] {
        let qj = &mut q[jm.idx_q..jm.idx_q + jm.nq];
        match jm.kind {
            JointType::RevoluteUnbounded(_) => qj[0] = 1.0,
            JointType::FreeFlyer => qj[6] = 1.0,
            JointType::Spherical => qj[3] = 1.0,
            JointType::Planar => qj[2] = 1.0,
            _ => {}
        }
    }
    q
}

/// Normalizes the quaternions and (cos, sin) pairs of `q` in place (the other entries
/// are left as they are). Fails on a zero block, naming the joint.
pub fn normalize(model: &Model, q: &mut [f64]) -> Result<()> {
    check_vec("q", q, model.nq)?;
    for b in &model.unit_blocks {
        let x = &mut q[b.start..b.start + b.len];
        // Scaled norm: no overflow for huge entries.
        let m = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if m == 0.0 {
            return Err(Error::Invalid(format!(
                "q: joint `{}` has a zero quaternion or (cos, sin) pair, which cannot be normalized",
                model.names[b.joint]
            )));
        }
        let n = m * x.iter().map(|v| (v / m) * (v / m)).sum::<f64>().sqrt();
        x.iter_mut().for_each(|v| *v /= n);
    }
    Ok(())
}

/// Random configuration with every bounded coordinate uniform in `[lower, upper]`;
/// rotations (quaternions, unbounded angles, planar angles) are uniform whatever the
/// bounds. Fails if a needed bound is not finite or `lower > upper`.
pub fn random_configuration<R: Rng + ?Sized>(
    model: &Model,
    rng: &mut R,
    lower: &[f64],
    upper: &[f64],
) -> Result<Vec<f64>> {
    check_vec("lower", lower, model.nq)?;
    check_vec("upper", upper, model.nq)?;
    let mut q = vec![0.0; model.nq];
    let uniform = |rng: &mut R, k: usize| -> Result<f64> {
        let (lo, hi) = (lower[k], upper[k]);
        let span = hi - lo;
        if !(span.is_finite() && span >= 0.0) {
            return Err(Error::Invalid(format!(
                "random configuration: bounds [{lo}, {hi}] of q[{k}] are not a finite interval"
            )));
        }
        Ok(lo + span * rng.random::<f64>())
    };
    for jm in &model.joints[1..] {
        let i = jm.idx_q;
        match jm.kind {
            JointType::Universe => {}
            JointType::Revolute(_) | JointType::Prismatic(_) => q[i] = uniform(rng, i)?,
            JointType::Translation => {
                for k in 0..3 {
                    q[i + k] = uniform(rng, i + k)?;
                }
            }
            JointType::RevoluteUnbounded(_) => {
                let t = std::f64::consts::PI * (2.0 * rng.random::<f64>() - 1.0);
                q[i] = t.cos();
                q[i + 1] = t.sin();
            }
            JointType::Spherical => random_quaternion(rng, &mut q[i..i + 4]),
            JointType::FreeFlyer => {
                for k in 0..3 {
                    q[i + k] = uniform(rng, i + k)?;
                }
                random_quaternion(rng, &mut q[i + 3..i + 7]);
            }
            JointType::Planar => {
                for k in 0..2 {
                    q[i + k] = uniform(rng, i + k)?;
                }
                let t = std::f64::consts::PI * (2.0 * rng.random::<f64>() - 1.0);
                q[i + 2] = t.cos();
                q[i + 3] = t.sin();
            }
        }
    }
    Ok(q)
}

/// Random configuration within the model's position limits.
pub fn random_configuration_within_limits<R: Rng + ?Sized>(model: &Model, rng: &mut R) -> Result<Vec<f64>> {
    random_configuration(model, rng, &model.lower_position_limit, &model.upper_position_limit)
}

/// Uniform unit quaternion (Shoemake), written as `[x, y, z, w]`.
fn random_quaternion<R: Rng + ?Sized>(rng: &mut R, out: &mut [f64]) {
    let (u1, u2, u3): (f64, f64, f64) = (rng.random(), rng.random(), rng.random());
    let tau = 2.0 * std::f64::consts::PI;
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    out[0] = a * (tau * u2).sin();
    out[1] = a * (tau * u2).cos();
    out[2] = b * (tau * u3).sin();
    out[3] = b * (tau * u3).cos();
}

fn write_quat(q: &Quaternion<f64>, out: &mut [f64]) {
    out[0] = q.i;
    out[1] = q.j;
    out[2] = q.k;
    out[3] = q.w;
}

/// Free-flyer placement from `[x, y, z, qx, qy, qz, qw]`.
fn ff_placement(q: &[f64]) -> Se3 {
    Se3::new(
        quat_from_slice(&q[3..7]).to_rotation_matrix().into_inner(),
        Vec3::new(q[0], q[1], q[2]),
    )
}

/// Planar joint as an SE(3) placement.
fn planar_placement(q: &[f64]) -> Se3 {
    JointType::Planar.transform(q)
}

/// Planar tangent vector embedded in se(3).
fn planar_twist(v: &[f64]) -> Motion {
    Motion::new(Vec3::new(v[0], v[1], 0.0), Vec3::new(0.0, 0.0, v[2]))
}

/// `q ⊕ v`, written into `out` (length nq).
pub fn integrate(model: &Model, q: &[f64], v: &[f64], out: &mut [f64]) -> Result<()> {
    model.check_configuration("q", q)?;
    check_vec("v", v, model.nv)?;
    if out.len() != model.nq {
        return Err(Error::Dimension {
            what: "integrate output".into(),
            expected: model.nq,
            got: out.len(),
        });
    }
    integrate_unchecked(model, q, v, out);
    check_result_vec("integrate", out)
}

pub(crate) fn integrate_unchecked(model: &Model, q: &[f64], v: &[f64], out: &mut [f64]) {
    for jm in &model.joints[1..] {
        let (iq, iv) = (jm.idx_q, jm.idx_v);
        let qj = &q[iq..iq + jm.nq];
        let vj = &v[iv..iv + jm.nv];
        let oj = &mut out[iq..iq + jm.nq];
        match jm.kind {
            JointType::Universe => {}
            JointType::Revolute(_) | JointType::Prismatic(_) | JointType::Translation => {
                for k in 0..jm.nq {
                    oj[k] = qj[k] + vj[k];
                }
            }
            JointType::RevoluteUnbounded(_) => {
                let (s, c) = vj[0].sin_cos();
                let (c0, s0) = (qj[0], qj[1]);
                let (c1, s1) = (c0 * c - s0 * s, s0 * c + c0 * s);
                // First-order renormalization of the unit complex number.
                let f = (3.0 - (c1 * c1 + s1 * s1)) / 2.0;
                oj[0] = c1 * f;
                oj[1] = s1 * f;
            }
            JointType::Spherical => {
                let q0 = quat_from_slice(qj);
                let mut r = (q0 * exp3_quat(&Vec3::new(vj[0], vj[1], vj[2]))).into_inner();
                if r.coords.dot(&q0.coords) < 0.0 {
                    r = -r;
                }
                write_quat(&r, oj);
            }
            JointType::FreeFlyer => {
                let q0 = quat_from_slice(&qj[3..7]);
                let xi = Motion::from_slice(vj);
                let e = exp6(&xi);
                let r0 = q0.to_rotation_matrix().into_inner();
                let p = Vec3::new(qj[0], qj[1], qj[2]) + r0 * e.translation;
                let mut r = (q0 * exp3_quat(&xi.angular)).into_inner();
                if r.coords.dot(&q0.coords) < 0.0 {
                    r = -r;
                }
                oj[0] = p.x;
                oj[1] = p.y;
                oj[2] = p.z;
                write_quat(&r, &mut oj[3..7]);
            }
            JointType::Planar => {
                let m0 = planar_placement(qj);
                let e = exp6(&planar_twist(vj));
                let p = m0.translation + m0.rotation * e.translation;
                let (s, c) = vj[2].sin_cos();
                let (c0, s0) = (qj[2], qj[3]);
                oj[0] = p.x;
                oj[1] = p.y;
                oj[2] = c0 * c - s0 * s;
                oj[3] = s0 * c + c0 * s;
            }
        }
    }
}

/// `q1 ⊖ q0`, written into `out` (length nv).
pub fn difference(model: &Model, q0: &[f64], q1: &[f64], out: &mut [f64]) -> Result<()> {
    model.check_configuration("q0", q0)?;
    model.check_configuration("q1", q1)?;
    if out.len() != model.nv {
        return Err(Error::Dimension {
            what: "difference output".into(),
            expected: model.nv,
            got: out.len(),
        });
    }
    difference_unchecked(model, q0, q1, out);
    check_result_vec("difference", out)
}

/// Relative placement `M0⁻¹ M1` of a free flyer and the log of its rotation.
fn ff_relative(q0: &[f64], q1: &[f64]) -> (Se3, Vec3) {
    let (m0, m1) = (ff_placement(q0), ff_placement(q1));
    let dq = quat_from_slice(&q0[3..7]).inverse() * quat_from_slice(&q1[3..7]);
    (m0.inv_compose(&m1), log3_quat(dq.quaternion()))
}

fn planar_relative(q0: &[f64], q1: &[f64]) -> (Se3, Vec3) {
    let m = planar_placement(q0).inv_compose(&planar_placement(q1));
    let angle = (q0[2] * q1[3] - q0[3] * q1[2]).atan2(q0[2] * q1[2] + q0[3] * q1[3]);
    (m, Vec3::new(0.0, 0.0, angle))
}

pub(crate) fn difference_unchecked(model: &Model, q0: &[f64], q1: &[f64], out: &mut [f64]) {
    for jm in &model.joints[1..] {
        let (iq, iv) = (jm.idx_q, jm.idx_v);
        let a = &q0[iq..iq + jm.nq];
        let b = &q1[iq..iq + jm.nq];
        let o = &mut out[iv..iv + jm.nv];
        match jm.kind {
            JointType::Universe => {}
            JointType::Revolute(_) | JointType::Prismatic(_) | JointType::Translation => {
                for k in 0..jm.nq {
                    o[k] = b[k] - a[k];
                }
            }
            JointType::RevoluteUnbounded(_) => o[0] = (a[0] * b[1] - a[1] * b[0]).atan2(a[0] * b[0] + a[1] * b[1]),
            JointType::Spherical => {
                let d = log3_quat((quat_from_slice(a).inverse() * quat_from_slice(b)).quaternion());
                o.copy_from_slice(d.as_slice());
            }
            JointType::FreeFlyer => {
                let (m, phi) = ff_relative(a, b);
                o.copy_from_slice(&log6_with_phi(&m, phi).to_array());
            }
            JointType::Planar => {
                let (m, phi) = planar_relative(a, b);
                let d = log6_with_phi(&m, phi);
                o[0] = d.linear.x;
                o[1] = d.linear.y;
                o[2] = d.angular.z;
            }
        }
    }
}

/// 6×6 matrix from 3×3 blocks `[[a, b], [0, c]]`.
fn blocks6(a: &Mat3, b: &Mat3, c: &Mat3) -> [[f64; 6]; 6] {
    let mut m = [[0.0; 6]; 6];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = a[(i, j)];
            m[i][3 + j] = b[(i, j)];
            m[3 + i][3 + j] = c[(i, j)];
        }
    }
    m
}

fn mul6(x: &[[f64; 6]; 6], y: &[[f64; 6]; 6]) -> [[f64; 6]; 6] {
    let mut m = [[0.0; 6]; 6];
    for i in 0..6 {
        for k in 0..6 {
            let xik = x[i][k];
            if xik != 0.0 {
                for j in 0..6 {
                    m[i][j] += xik * y[k][j];
                }
            }
        }
    }
    m
}

/// Writes the rows/columns `idx` of a 6×6 matrix times `sign` into `out` at `offset`.
fn put6(out: &mut MatMut<'_, f64>, offset: usize, m: &[[f64; 6]; 6], idx: &[usize], sign: f64) {
    for (a, &i) in idx.iter().enumerate() {
        for (b, &j) in idx.iter().enumerate() {
            out[(offset + a, offset + b)] = sign * m[i][j];
        }
    }
}

fn put3(out: &mut MatMut<'_, f64>, offset: usize, m: &Mat3, sign: f64) {
    for a in 0..3 {
        for b in 0..3 {
            out[(offset + a, offset + b)] = sign * m[(a, b)];
        }
    }
}

const FF_IDX: [usize; 6] = [0, 1, 2, 3, 4, 5];
const PLANAR_IDX: [usize; 3] = [0, 1, 5];

fn check_square(what: &str, out: &MatMut<'_, f64>, n: usize) -> Result<()> {
    if out.nrows() != n || out.ncols() != n {
        return Err(Error::Dimension {
            what: format!("{what} output ({}x{})", out.nrows(), out.ncols()),
            expected: n,
            got: out.nrows(),
        });
    }
    Ok(())
}

/// Jacobian of `integrate(q, v)` with respect to q (`Arg0`) or v (`Arg1`), nv × nv.
pub fn dintegrate(model: &Model, q: &[f64], v: &[f64], arg: ArgumentPosition, mut out: MatMut<'_, f64>) -> Result<()> {
    model.check_configuration("q", q)?;
    check_vec("v", v, model.nv)?;
    check_square("dintegrate", &out, model.nv)?;
    out.fill(0.0);
    for jm in &model.joints[1..] {
        let iv = jm.idx_v;
        let vj = &v[iv..iv + jm.nv];
        match jm.kind {
            JointType::Universe => {}
            JointType::Revolute(_)
            | JointType::Prismatic(_)
            | JointType::Translation
            | JointType::RevoluteUnbounded(_) => {
                for k in 0..jm.nv {
                    out[(iv + k, iv + k)] = 1.0;
                }
            }
            JointType::Spherical => {
                let phi = Vec3::new(vj[0], vj[1], vj[2]);
                match arg {
                    ArgumentPosition::Arg0 => put3(&mut out, iv, &exp3(&phi).transpose(), 1.0),
                    ArgumentPosition::Arg1 => put3(&mut out, iv, &jexp3(&phi), 1.0),
                }
            }
            JointType::FreeFlyer | JointType::Planar => {
                let (xi, idx): (Motion, &[usize]) = if jm.kind == JointType::FreeFlyer {
                    (Motion::from_slice(vj), &FF_IDX)
                } else {
                    (planar_twist(vj), &PLANAR_IDX)
                };
                let m = match arg {
                    ArgumentPosition::Arg0 => {
                        let (rt, b) = ad_inv_blocks(&exp6(&xi));
                        blocks6(&rt, &b, &rt)
                    }
                    ArgumentPosition::Arg1 => {
                        let (jr, b) = jexp6_blocks(&xi);
                        blocks6(&jr, &b, &jr)
                    }
                };
                put6(&mut out, iv, &m, idx, 1.0);
            }
        }
    }
    check_result_mat("dintegrate", out.as_ref())
}

/// Jacobian of `difference(q0, q1)` with respect to q0 (`Arg0`) or q1 (`Arg1`), nv × nv.
pub fn ddifference(
    model: &Model,
    q0: &[f64],
    q1: &[f64],
    arg: ArgumentPosition,
    mut out: MatMut<'_, f64>,
) -> Result<()> {
    model.check_configuration("q0", q0)?;
    model.check_configuration("q1", q1)?;
    check_square("ddifference", &out, model.nv)?;
    out.fill(0.0);
    let sign = match arg {
        ArgumentPosition::Arg0 => -1.0,
        ArgumentPosition::Arg1 => 1.0,
    };
    for jm in &model.joints[1..] {
        let (iq, iv) = (jm.idx_q, jm.idx_v);
        let a = &q0[iq..iq + jm.nq];
        let b = &q1[iq..iq + jm.nq];
        match jm.kind {
            JointType::Universe => {}
            JointType::Revolute(_)
            | JointType::Prismatic(_)
            | JointType::Translation
            | JointType::RevoluteUnbounded(_) => {
                for k in 0..jm.nv {
                    out[(iv + k, iv + k)] = sign;
                }
            }
            JointType::Spherical => {
                let rel = quat_from_slice(a).inverse() * quat_from_slice(b);
                let d = log3_quat(rel.quaternion());
                let jl = jlog3(&d);
                match arg {
                    ArgumentPosition::Arg0 => put3(
                        &mut out,
                        iv,
                        &(jl * rel.to_rotation_matrix().into_inner().transpose()),
                        -1.0,
                    ),
                    ArgumentPosition::Arg1 => put3(&mut out, iv, &jl, 1.0),
                }
            }
            JointType::FreeFlyer | JointType::Planar => {
                let ((m, phi), idx): ((Se3, Vec3), &[usize]) = if jm.kind == JointType::FreeFlyer {
                    (ff_relative(a, b), &FF_IDX)
                } else {
                    (planar_relative(a, b), &PLANAR_IDX)
                };
                let d = log6_with_phi(&m, phi);
                let (jl, c) = jlog6_blocks(&d);
                let jlog = blocks6(&jl, &c, &jl);
                let mat = match arg {
                    ArgumentPosition::Arg0 => {
                        let (rt, bb) = ad_inv_blocks(&m);
                        mul6(&jlog, &blocks6(&rt, &bb, &rt))
                    }
                    ArgumentPosition::Arg1 => jlog,
                };
                put6(&mut out, iv, &mat, idx, sign);
            }
        }
    }
    check_result_mat("ddifference", out.as_ref())
}

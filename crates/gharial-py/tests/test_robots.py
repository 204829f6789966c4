"""gharial.robots: models, algorithms, spaces, dynamics and residuals, checked against
independent references (algebraic identities of rigid-body dynamics and central finite
differences in numpy)."""

from pathlib import Path

import numpy as np
import pytest

from gharial import GharialError, robots
from gharial.dynamics import IntegratorSemiImplEuler

DATA = Path(__file__).resolve().parents[2] / "gharial-multibody" / "tests" / "data" / "robots"
FEET = ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"]
EPS = 1e-6


@pytest.fixture(scope="module")
def ur5():
    return robots.load_builtin("ur5")


@pytest.fixture(scope="module")
def solo():
    return robots.load_builtin("solo12")


@pytest.fixture(scope="module")
def pendulum():
    return robots.load_builtin("double_pendulum")


@pytest.fixture(params=["ur5", "solo12", "double_pendulum"])
def model(request):
    return robots.load_builtin(request.param)


def random_state(model, seed, scale=0.5):
    """A configuration `neutral ⊕ δ` (valid on the free flyer) and random v, a."""
    rng = np.random.default_rng(seed)
    q0 = model.reference_configurations.get("straight_standing", model.neutral())
    q = robots.integrate(model, q0, scale * rng.standard_normal(model.nv))
    return q, rng.standard_normal(model.nv), rng.standard_normal(model.nv)


def standing(model):
    return model.reference_configuration("straight_standing")


def fd(f, x, eps=EPS):
    """Central differences of f along the coordinates of a vector x (columns)."""
    cols = []
    for i in range(len(x)):
        e = np.zeros(len(x))
        e[i] = eps
        cols.append((np.asarray(f(x + e)) - np.asarray(f(x - e))) / (2 * eps))
    return np.stack(cols, axis=-1)


def fd_q(model, f, q, eps=EPS):
    """Central differences of f along the tangent perturbations q ⊕ δ."""
    return fd(lambda d: f(robots.integrate(model, q, d)), np.zeros(model.nv), eps)


def fd_space(space, f, x, diff=None, eps=EPS):
    """Central differences of f(x ⊕ δ) (outputs compared by `diff(y0, y)`)."""
    y0 = f(x)
    diff = diff or (lambda a, b: b - a)
    return fd(lambda d: diff(y0, f(space.integrate(x, d))), np.zeros(space.ndx), eps)


def vee(s):
    """The vector of the skew part of a 3x3 matrix."""
    a = 0.5 * (s - s.T)
    return np.array([a[2, 1], a[0, 2], a[1, 0]])


# --- models -----------------------------------------------------------------------


def test_builtin_robots(ur5, solo, pendulum):
    assert {"ur5", "solo12", "double_pendulum"} <= set(robots.builtin_robots())
    assert (ur5.nq, ur5.nv) == (6, 6)
    assert (solo.nq, solo.nv) == (19, 18)
    assert (pendulum.nq, pendulum.nv) == (2, 2)
    assert ur5.joint_names[0] == "universe" and "elbow_joint" in ur5.joint_names
    assert len(ur5.joint_names) == ur5.njoints == 7
    assert len(ur5.frame_names) == ur5.nframes and "tool0" in ur5.frame_names
    assert ur5.frame_names[ur5.frame_id("tool0")] == "tool0"
    assert ur5.joint_names[ur5.joint_id("elbow_joint")] == "elbow_joint"
    assert solo.joint_names[1] == "root_joint"
    assert ur5.total_mass > 0 and solo.total_mass > 0
    np.testing.assert_allclose(ur5.gravity, [0, 0, -9.81])
    assert ur5.lower_position_limit.shape == (6,) and ur5.effort_limit.shape == (6,)
    assert "straight_standing" in solo.reference_configurations
    np.testing.assert_array_equal(solo.neutral()[3:7], [0, 0, 0, 1])
    assert "RobotModel" in repr(ur5)


def test_urdf_file_and_string_match_builtin(ur5, tmp_path):
    xml = (DATA / "ur5_robot.urdf").read_text()
    path = tmp_path / "ur5.urdf"
    path.write_text(xml)
    loaded = [robots.load_urdf(path), robots.load_urdf(str(path)), robots.load_urdf_string(xml)]
    q, v, a = random_state(ur5, 1)
    for m in loaded:
        assert (m.nq, m.nv, m.frame_names) == (ur5.nq, ur5.nv, ur5.frame_names)
        np.testing.assert_array_equal(robots.rnea(m, q, v, a), robots.rnea(ur5, q, v, a))
        np.testing.assert_array_equal(robots.crba(m, q), robots.crba(ur5, q))
        for got, want in zip(robots.frame_placement(m, q, "tool0"), robots.frame_placement(ur5, q, "tool0")):
            np.testing.assert_array_equal(got, want)


def test_free_flyer_and_srdf(tmp_path):
    xml = (DATA / "solo12.urdf").read_text()
    fixed = robots.load_urdf_string(xml)
    free = robots.load_urdf_string(xml, free_flyer=True, srdf=(DATA / "solo.srdf").read_text())
    assert (fixed.nq, free.nq, free.nv) == (12, 19, 18)
    builtin = robots.load_builtin("solo12")
    np.testing.assert_array_equal(free.reference_configuration("straight_standing"), standing(builtin))
    path = tmp_path / "solo.urdf"
    path.write_text(xml)
    from_file = robots.load_urdf(path, free_flyer=True, srdf=DATA / "solo.srdf")
    assert "standing" in from_file.reference_configurations


def test_integrate_difference(model):
    q, v, _ = random_state(model, 2)
    dv = 0.3 * v
    q1 = robots.integrate(model, q, dv)
    np.testing.assert_allclose(robots.difference(model, q, q1), dv, atol=1e-12)
    np.testing.assert_allclose(robots.difference(model, q, q), 0, atol=1e-14)
    if model.nq > model.nv:
        assert abs(np.linalg.norm(q1[3:7]) - 1) < 1e-12


# --- dynamics ---------------------------------------------------------------------


def test_rnea_aba_consistency(model):
    for seed in range(3):
        q, v, a = random_state(model, seed)
        tau = robots.rnea(model, q, v, a)
        np.testing.assert_allclose(robots.aba(model, q, v, tau), a, atol=1e-9)
        z = np.zeros(model.nv)
        np.testing.assert_allclose(robots.nonlinear_effects(model, q, v), robots.rnea(model, q, v, z), atol=1e-10)
        np.testing.assert_allclose(robots.generalized_gravity(model, q), robots.rnea(model, q, z, z), atol=1e-10)


def test_crba_from_rnea(model):
    q, v, a = random_state(model, 3)
    m = robots.crba(model, q)
    assert m.shape == (model.nv, model.nv)
    np.testing.assert_allclose(m, m.T, atol=1e-12)
    assert np.all(np.linalg.eigvalsh(m) > 0)
    z = np.zeros(model.nv)
    g = robots.rnea(model, q, z, z)
    cols = np.stack([robots.rnea(model, q, z, e) - g for e in np.eye(model.nv)], axis=1)
    np.testing.assert_allclose(m, cols, atol=1e-10)
    # M a + b = tau
    np.testing.assert_allclose(
        m @ a + robots.nonlinear_effects(model, q, v), robots.rnea(model, q, v, a), atol=1e-9
    )


def test_rnea_derivatives(model):
    q, v, a = random_state(model, 4)
    dq, dv, m = robots.compute_rnea_derivatives(model, q, v, a)
    np.testing.assert_allclose(dq, fd_q(model, lambda qq: robots.rnea(model, qq, v, a), q), atol=1e-5)
    np.testing.assert_allclose(dv, fd(lambda vv: robots.rnea(model, q, vv, a), v), atol=1e-5)
    np.testing.assert_allclose(m, robots.crba(model, q), atol=1e-10)


def test_aba_derivatives(model):
    q, v, tau = random_state(model, 5)
    dq, dv, minv = robots.compute_aba_derivatives(model, q, v, tau)
    np.testing.assert_allclose(dq, fd_q(model, lambda qq: robots.aba(model, qq, v, tau), q), rtol=1e-5, atol=1e-4)
    np.testing.assert_allclose(dv, fd(lambda vv: robots.aba(model, q, vv, tau), v), rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(minv @ robots.crba(model, q), np.eye(model.nv), atol=1e-9)
    np.testing.assert_allclose(minv, fd(lambda t: robots.aba(model, q, v, t), tau), atol=1e-5)


# --- kinematics -------------------------------------------------------------------


@pytest.mark.parametrize("name, frame", [("ur5", "tool0"), ("solo12", "FL_FOOT"), ("double_pendulum", "link2")])
def test_frame_jacobians(name, frame):
    model = robots.load_builtin(name)
    if frame not in model.frame_names:
        frame = model.frame_names[-1]
    q, _, _ = random_state(model, 6)
    r0, p0 = robots.frame_placement(model, q, frame)
    np.testing.assert_allclose(r0.T @ r0, np.eye(3), atol=1e-12)
    dp = fd_q(model, lambda qq: robots.frame_placement(model, qq, frame)[1], q)
    rot = [robots.frame_placement(model, robots.integrate(model, q, EPS * e), frame)[0] for e in np.eye(model.nv)]
    rot_m = [robots.frame_placement(model, robots.integrate(model, q, -EPS * e), frame)[0] for e in np.eye(model.nv)]
    w_local = np.stack([vee(r0.T @ (rp - rm)) / (2 * EPS) for rp, rm in zip(rot, rot_m)], axis=1)
    w_world = r0 @ w_local
    lwa = robots.frame_jacobian(model, q, frame)
    assert lwa.shape == (6, model.nv)
    np.testing.assert_allclose(lwa, robots.frame_jacobian(model, q, frame, "local_world_aligned"))
    np.testing.assert_allclose(lwa[:3], dp, atol=1e-6)
    np.testing.assert_allclose(lwa[3:], w_world, atol=1e-6)
    local = robots.frame_jacobian(model, q, frame, reference="local")
    np.testing.assert_allclose(local[:3], r0.T @ dp, atol=1e-6)
    np.testing.assert_allclose(local[3:], w_local, atol=1e-6)
    world = robots.frame_jacobian(model, q, frame, "world")
    np.testing.assert_allclose(world[:3], dp - np.cross(w_world.T, p0).T, atol=1e-6)
    np.testing.assert_allclose(world[3:], w_world, atol=1e-6)


def test_center_of_mass(model):
    q, _, _ = random_state(model, 7)
    c = robots.center_of_mass(model, q)
    assert c.shape == (3,)
    jc = robots.jacobian_center_of_mass(model, q)
    assert jc.shape == (3, model.nv)
    np.testing.assert_allclose(jc, fd_q(model, lambda qq: robots.center_of_mass(model, qq), q), atol=1e-6)
    # The gravity torques are the work of gravity on the centre of mass: g(q) = -m Jcᵀ g.
    g = robots.generalized_gravity(model, q)
    np.testing.assert_allclose(g, -model.total_mass * jc.T @ model.gravity, atol=1e-9)


def test_free_flyer_com_follows_base(solo):
    q = standing(solo)
    c = robots.center_of_mass(solo, q)
    moved = q.copy()
    moved[:3] += [1.0, -2.0, 0.5]
    np.testing.assert_allclose(robots.center_of_mass(solo, moved), c + [1.0, -2.0, 0.5], atol=1e-12)


# --- spaces and dynamics ----------------------------------------------------------


def test_spaces(solo):
    space = robots.MultibodyPhaseSpace(solo)
    assert (space.nx, space.ndx, space.nq, space.nv) == (37, 36, 19, 18)
    assert space.model.nq == 19
    config = space.configuration
    assert isinstance(config, robots.MultibodyConfiguration)
    assert (config.nx, config.ndx) == (19, 18)
    assert robots.MultibodyConfiguration(solo).nx == 19
    q, v, _ = random_state(solo, 8)
    np.testing.assert_allclose(config.integrate(q, 0.1 * v), robots.integrate(solo, q, 0.1 * v), atol=1e-14)
    x = np.concatenate([q, v])
    assert space.is_valid(x)
    np.testing.assert_allclose(space.neutral()[:19], solo.neutral())


def semi_implicit_reference(model, b, dt, x, u):
    q, v = x[: model.nq], x[model.nq :]
    vn = v + dt * robots.aba(model, q, v, b @ u)
    return np.concatenate([robots.integrate(model, q, dt * vn), vn])


def check_step_jacobians(step, space, x, u, atol):
    jx, ju = step.jacobians(x, u)
    assert jx.shape == (space.ndx, space.ndx) and ju.shape == (space.ndx, len(u))
    f = lambda xx: step.forward(xx, u)  # noqa: E731
    np.testing.assert_allclose(jx, fd_space(space, f, x, space.difference), atol=atol)
    x0 = step.forward(x, u)
    np.testing.assert_allclose(ju, fd(lambda uu: space.difference(x0, step.forward(x, uu)), u), atol=atol)


def test_free_dynamics_ur5(ur5):
    space = robots.MultibodyPhaseSpace(ur5)
    ode = robots.MultibodyFreeFwdDynamics(space)
    assert ode.nu == 6
    np.testing.assert_array_equal(ode.actuation_matrix, np.eye(6))
    step = IntegratorSemiImplEuler(ode, 0.01)
    q, v, u = random_state(ur5, 9)
    x = np.concatenate([q, v])
    np.testing.assert_allclose(step.forward(x, u), semi_implicit_reference(ur5, np.eye(6), 0.01, x, u), atol=1e-12)
    check_step_jacobians(step, space, x, u, 1e-6)
    # gravity compensation holds the arm still
    g = ode.gravity_compensation(q)
    xs = np.concatenate([q, np.zeros(6)])
    np.testing.assert_allclose(step.forward(xs, g), xs, atol=1e-12)


def test_free_dynamics_general_actuation(pendulum):
    space = robots.MultibodyPhaseSpace(pendulum)
    b = np.array([[1.0], [0.0]])  # acrobot-like: only the first joint
    ode = robots.MultibodyFreeFwdDynamics(space, b)
    assert ode.nu == 1
    step = IntegratorSemiImplEuler(ode, 0.02)
    q, v, _ = random_state(pendulum, 10)
    x, u = np.concatenate([q, v]), np.array([0.7])
    np.testing.assert_allclose(step.forward(x, u), semi_implicit_reference(pendulum, b, 0.02, x, u), atol=1e-12)
    check_step_jacobians(step, space, x, u, 1e-6)


def test_free_dynamics_solo(solo):
    space = robots.MultibodyPhaseSpace(solo)
    ode = robots.MultibodyFreeFwdDynamics(space)
    assert ode.nu == 12
    b = ode.actuation_matrix
    np.testing.assert_array_equal(b, np.vstack([np.zeros((6, 12)), np.eye(12)]))
    step = IntegratorSemiImplEuler(ode, 0.01)
    q, v, _ = random_state(solo, 11)
    u = np.random.default_rng(11).standard_normal(12)
    x = np.concatenate([q, 0.3 * v])
    np.testing.assert_allclose(step.forward(x, u), semi_implicit_reference(solo, b, 0.01, x, u), atol=1e-12)
    check_step_jacobians(step, space, x, u, 1e-5)


def contact_jacobian(model, q):
    return np.vstack([robots.frame_jacobian(model, q, f)[:3] for f in FEET])


def test_contact_dynamics_solo(solo):
    space = robots.MultibodyPhaseSpace(solo)
    q0 = standing(solo)
    ode = robots.MultibodyConstraintFwdDynamics(space, None, FEET)
    assert (ode.nu, ode.nc) == (12, 12)
    dt = 0.01
    step = IntegratorSemiImplEuler(ode, dt)
    rng = np.random.default_rng(12)
    q = robots.integrate(solo, q0, 0.05 * rng.standard_normal(18))
    x, u = np.concatenate([q, np.zeros(18)]), rng.standard_normal(12)
    a = (step.forward(x, u)[19:] - x[19:]) / dt
    jc = contact_jacobian(solo, q)
    lam = ode.contact_forces(x, u)
    b = ode.actuation_matrix
    # M a + b(q, 0) = B u + Jcᵀ λ, and the feet do not accelerate (v = 0, no gains).
    m = robots.crba(solo, q)
    np.testing.assert_allclose(m @ a + robots.generalized_gravity(solo, q), b @ u + jc.T @ lam, atol=1e-8)
    np.testing.assert_allclose(jc @ a, 0, atol=1e-9)
    # Newton on the whole body (v = 0): the contact forces (world axes) and gravity
    # accelerate the centre of mass, Σ λ_k + m g = m c̈ = m Jcom a.
    mass = solo.total_mass
    newton = lam.reshape(4, 3).sum(axis=0) + mass * solo.gravity
    np.testing.assert_allclose(newton, mass * robots.jacobian_center_of_mass(solo, q) @ a, atol=1e-8)


def test_contact_dynamics_jacobians(solo):
    space = robots.MultibodyPhaseSpace(solo)
    q0 = standing(solo)
    ode = robots.MultibodyConstraintFwdDynamics(
        space, np.vstack([np.zeros((6, 12)), np.eye(12)]), FEET, "3d", "local_world_aligned", kp=10.0, kd=5.0, q_ref=q0
    )
    step = IntegratorSemiImplEuler(ode, 0.01)
    rng = np.random.default_rng(13)
    q = robots.integrate(solo, q0, 0.05 * rng.standard_normal(18))
    x, u = np.concatenate([q, 0.2 * rng.standard_normal(18)]), rng.standard_normal(12)
    assert np.all(np.isfinite(step.forward(x, u)))
    check_step_jacobians(step, space, x, u, 1e-5)


def test_contact_dynamics_6d(ur5):
    space = robots.MultibodyPhaseSpace(ur5)
    q, v, u = random_state(ur5, 14)
    x = np.concatenate([q, np.zeros(6)])
    for kind, rows, ref in [("6d", 6, "local"), ("3d", 3, "local"), ("3d", 3, "local_world_aligned")]:
        ode = robots.MultibodyConstraintFwdDynamics(space, None, ["tool0"], contact_type=kind, reference=ref)
        assert (ode.nu, ode.nc) == (6, rows)
        step = IntegratorSemiImplEuler(ode, 0.01)
        a = step.forward(x, u)[6:] / 0.01
        jc = robots.frame_jacobian(ur5, q, "tool0", ref)[:rows]
        np.testing.assert_allclose(jc @ a, 0, atol=1e-8)
        lam = ode.contact_forces(x, u)
        m, g = robots.crba(ur5, q), robots.generalized_gravity(ur5, q)
        np.testing.assert_allclose(m @ a + g, u + jc.T @ lam, atol=1e-8)
        check_step_jacobians(step, space, np.concatenate([q, 0.1 * v]), u, 1e-5)


# --- residuals --------------------------------------------------------------------


def test_frame_translation_residual(ur5):
    space = robots.MultibodyPhaseSpace(ur5)
    target = np.array([0.3, 0.2, 0.5])
    r = robots.FrameTranslationResidual(space, 4, "tool0", target)
    assert (r.nx, r.ndx, r.nu, r.nr) == (12, 12, 4, 3)
    assert r.frame_id == ur5.frame_id("tool0")
    np.testing.assert_array_equal(r.target, target)
    q, v, _ = random_state(ur5, 15)
    x, u = np.concatenate([q, v]), np.zeros(4)
    p = robots.frame_placement(ur5, q, "tool0")[1]
    np.testing.assert_allclose(r(x, u), p - target, atol=1e-14)
    jx, ju = r.jacobians(x, u)
    np.testing.assert_allclose(jx, fd_space(space, lambda xx: r(xx, u), x), atol=1e-6)
    np.testing.assert_allclose(jx[:, :6], robots.frame_jacobian(ur5, q, "tool0")[:3], atol=1e-12)
    np.testing.assert_array_equal(ju, np.zeros((3, 4)))
    r.target = p
    np.testing.assert_allclose(r(x, u), 0, atol=1e-14)
    np.testing.assert_array_equal(r.target, p)


def test_frame_placement_residual(solo):
    space = robots.MultibodyPhaseSpace(solo)
    q, v, _ = random_state(solo, 16)
    rot, p = robots.frame_placement(solo, q, "FL_FOOT")
    r = robots.FramePlacementResidual(space, 12, "FL_FOOT", rot, p)
    assert (r.nr, r.nu, r.ndx) == (6, 12, 36)
    x, u = np.concatenate([q, v]), np.zeros(12)
    np.testing.assert_allclose(r(x, u), 0, atol=1e-12)
    r.target = (np.eye(3), p + [0.1, 0.0, 0.0])
    got_r, got_p = r.target
    np.testing.assert_array_equal(got_r, np.eye(3))
    np.testing.assert_allclose(got_p, p + [0.1, 0, 0])
    jx, ju = r.jacobians(x, u)
    np.testing.assert_allclose(jx, fd_space(space, lambda xx: r(xx, u), x), atol=1e-6)
    np.testing.assert_array_equal(ju, np.zeros((6, 12)))
    # with the target at the frame's own rotation the linear error is the local offset
    r.target = (rot, p + [0.1, 0.0, 0.0])
    np.testing.assert_allclose(r(x, u)[:3], rot.T @ [-0.1, 0, 0], atol=1e-12)


def test_com_residual(solo):
    space = robots.MultibodyPhaseSpace(solo)
    q, v, _ = random_state(solo, 17)
    r = robots.CenterOfMassTranslationResidual(space, 0, [0.0, 0.0, 0.2])
    x, u = np.concatenate([q, v]), np.zeros(0)
    np.testing.assert_allclose(r(x, u), robots.center_of_mass(solo, q) - [0, 0, 0.2], atol=1e-14)
    jx, _ = r.jacobians(x, u)
    np.testing.assert_allclose(jx, fd_space(space, lambda xx: r(xx, u), x), atol=1e-6)
    np.testing.assert_allclose(jx[:, :18], robots.jacobian_center_of_mass(solo, q), atol=1e-12)
    r.target = robots.center_of_mass(solo, q)
    np.testing.assert_allclose(r(x, u), 0, atol=1e-14)


def test_frame_velocity_and_fly_high_residuals(solo):
    space = robots.MultibodyPhaseSpace(solo)
    q, v, _ = random_state(solo, 18, scale=0.2)
    x, u = np.concatenate([q, v]), np.zeros(12)
    v_ref = np.array([0.1, -0.2, 0.3, 0.0, 0.5, -0.1])
    for ref in ["local_world_aligned", "local"]:
        r = robots.FrameVelocityResidual(space, 12, "FL_FOOT", v_ref, ref)
        assert (r.nr, r.nu) == (6, 12)
        np.testing.assert_allclose(r(x, u), robots.frame_jacobian(solo, q, "FL_FOOT", ref) @ v - v_ref, atol=1e-12)
        jx, ju = r.jacobians(x, u)
        np.testing.assert_allclose(jx, fd_space(space, lambda xx: r(xx, u), x), atol=1e-6)
        np.testing.assert_array_equal(ju, np.zeros((6, 12)))
    slope = 30.0
    r = robots.FlyHighResidual(space, 12, "FL_FOOT", slope)
    z = robots.frame_placement(solo, q, "FL_FOOT")[1][2]
    v_xy = (robots.frame_jacobian(solo, q, "FL_FOOT", "local_world_aligned") @ v)[:2]
    np.testing.assert_allclose(r(x, u), v_xy * np.exp(-slope * z), atol=1e-12)
    jx, _ = r.jacobians(x, u)
    np.testing.assert_allclose(jx, fd_space(space, lambda xx: r(xx, u), x), atol=1e-6)


def test_contact_force_and_friction_cone_residuals(solo):
    space = robots.MultibodyPhaseSpace(solo)
    ode = robots.MultibodyConstraintFwdDynamics(space, None, FEET, kd=50.0)
    rng = np.random.default_rng(19)
    q = robots.integrate(solo, standing(solo), 0.05 * rng.standard_normal(18))
    x, u = np.concatenate([q, 0.1 * rng.standard_normal(18)]), rng.standard_normal(12)
    lam = ode.contact_forces(x, u)
    f_ref = np.array([0.0, 0.0, 4.0])
    force = robots.ContactForceResidual(ode, 2, f_ref)
    assert (force.nr, force.nu, force.ndx) == (3, 12, 36)
    np.testing.assert_allclose(force(x, u), lam[6:9] - f_ref, atol=1e-12)
    mu = 0.8
    cone = robots.FrictionConeResidual(ode, 2, mu)
    c = cone(x, u)
    # (μ f_n, f_t): the scalar part first, the tangential part's norm that of λ_xy.
    np.testing.assert_allclose(c[0], mu * lam[8], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(c[1:]), np.linalg.norm(lam[6:8]), atol=1e-12)
    for r in [force, cone]:
        jx, ju = r.jacobians(x, u)
        np.testing.assert_allclose(jx, fd_space(space, lambda xx: r(xx, u), x), atol=1e-5)
        np.testing.assert_allclose(ju, fd(lambda uu: r(x, uu), u), atol=1e-5)
    with pytest.raises(GharialError):
        robots.ContactForceResidual(ode, 4, f_ref)
    with pytest.raises(GharialError):
        robots.FrictionConeResidual(ode, 0, -1.0)


def test_a_friction_cone_problem_solves_from_python(solo):
    """Solo on its four feet asked to move its base 2 cm sideways in 0.2 s: without cones
    the optimum pushes sideways beyond μ = 0.1; with them every force is inside, at a
    higher cost."""
    import gharial
    from gharial import constraints
    from gharial.dynamics import IntegratorSemiImplEuler

    space = robots.MultibodyPhaseSpace(solo)
    ode = robots.MultibodyConstraintFwdDynamics(space, None, FEET, kd=50.0)
    step = IntegratorSemiImplEuler(ode, 0.02)
    x0 = np.concatenate([standing(solo), np.zeros(18)])
    target = x0.copy()
    target[1] += 0.02
    u0 = robots.generalized_gravity(solo, standing(solo))[6:]

    def solve(mu):
        stages = []
        for _ in range(10):
            cost = gharial.CostStack(space, 12)
            cost.addCost("x", gharial.QuadraticStateCost(space, 12, target, np.full(36, 1.0)), 0.02)
            cost.addCost("u", gharial.QuadraticControlCost(space, u0, np.full(12, 1e-3)), 0.02)
            stage = gharial.StageModel(cost, step)
            if mu is not None:
                for k in range(4):
                    stage.addConstraint(robots.FrictionConeResidual(ode, k, mu), constraints.SecondOrderCone(3))
            stages.append(stage)
        terminal = gharial.QuadraticStateCost(space, 0, target, np.full(36, 1.0))
        s = gharial.solver("proxddp", tol=1e-6, max_iters=200, mu_init=1e-3)
        assert s.run(gharial.TrajOptProblem(x0, stages, terminal), [x0] * 11, [u0] * 10), s.results
        lam = [ode.contact_forces(s.results.xs[t], s.results.us[t]).reshape(4, 3) for t in range(10)]
        return max(np.max(np.linalg.norm(f[:, :2], axis=1) - 0.1 * f[:, 2]) for f in lam), s.results.traj_cost

    free, free_cost = solve(None)
    coned, coned_cost = solve(0.1)
    assert free > 0.5 and coned < 1e-5 and coned_cost > free_cost


def test_residuals_are_stage_functions(ur5):
    import gharial

    space = robots.MultibodyPhaseSpace(ur5)
    r = robots.FrameTranslationResidual(space, 6, "tool0", [0, 0, 0])
    assert isinstance(r, gharial.StageFunction)
    x = np.concatenate([ur5.neutral(), np.zeros(6)])
    np.testing.assert_allclose(r[[2]](x, np.zeros(6)), r(x, np.zeros(6))[[2]])


# --- errors -----------------------------------------------------------------------


def plain_value_error(f, *args, match=None, **kwargs):
    with pytest.raises(ValueError, match=match) as info:
        f(*args, **kwargs)
    assert not isinstance(info.value, GharialError), info.value


def test_bad_shapes_and_dtypes(ur5, solo):
    q, v, a = random_state(ur5, 18)
    plain_value_error(robots.rnea, ur5, q[:5], v, a, match="q: expected 6 entries, got 5")
    plain_value_error(robots.rnea, ur5, q, v, np.zeros(7), match="a: expected 6")
    plain_value_error(robots.aba, ur5, q, v, np.zeros((6, 1)), match="tau: expected a 1-D array")
    plain_value_error(robots.crba, ur5, q.astype(complex), match="expected real numbers")
    plain_value_error(robots.crba, ur5, ["a"] * 6, match="expected real numbers")
    plain_value_error(robots.generalized_gravity, solo, np.zeros(18), match="expected 19")
    plain_value_error(robots.integrate, solo, solo.neutral(), np.zeros(19))
    plain_value_error(robots.difference, ur5, q, np.zeros(3))
    plain_value_error(robots.frame_jacobian, ur5, q, "tool0", "body")
    plain_value_error(robots.compute_aba_derivatives, ur5, q, v[:2], a)
    plain_value_error(robots.compute_rnea_derivatives, ur5, q, v, a.astype(bool))
    plain_value_error(robots.center_of_mass, ur5, np.zeros((2, 3)))
    plain_value_error(robots.load_builtin, "r2d2", match="unknown robot")
    space = robots.MultibodyPhaseSpace(solo)
    plain_value_error(robots.MultibodyFreeFwdDynamics, space, np.zeros((12, 12)), match="18 rows")
    plain_value_error(robots.MultibodyConstraintFwdDynamics, space, None, FEET, contact_type="2d")
    plain_value_error(robots.MultibodyConstraintFwdDynamics, space, None, FEET, reference="nowhere")
    plain_value_error(robots.MultibodyConstraintFwdDynamics, space, None, FEET, q_ref=np.zeros(3))
    plain_value_error(robots.FrameTranslationResidual, space, 12, "FL_FOOT", [0, 0])
    plain_value_error(robots.FramePlacementResidual, space, 12, "FL_FOOT", np.eye(2), [0, 0, 0])
    plain_value_error(robots.CenterOfMassTranslationResidual, space, 12, [0, 0, 0j])
    r = robots.FrameTranslationResidual(space, 12, "FL_FOOT", [0, 0, 0])
    with pytest.raises(ValueError):
        r.target = [1, 2]
    np.testing.assert_array_equal(r.target, [0, 0, 0])
    ode = robots.MultibodyConstraintFwdDynamics(space, None, FEET)
    plain_value_error(ode.contact_forces, np.zeros(36), np.zeros(12))


def test_core_errors(ur5, solo):
    q = ur5.neutral()
    for f in (robots.frame_placement, robots.frame_jacobian):
        with pytest.raises(GharialError, match="no_such_frame"):
            f(ur5, q, "no_such_frame")
    with pytest.raises(GharialError, match="nowhere"):
        ur5.frame_id("nowhere")
    with pytest.raises(GharialError):
        ur5.joint_id("nowhere")
    with pytest.raises(GharialError):
        ur5.reference_configuration("nowhere")
    bad = solo.neutral()
    bad[3:7] = [0, 0, 0, 2]  # not a unit quaternion
    with pytest.raises(GharialError):
        robots.rnea(solo, bad, np.zeros(18), np.zeros(18))
    with pytest.raises(GharialError):
        robots.crba(ur5, [np.nan] + [0] * 5)
    space = robots.MultibodyPhaseSpace(solo)
    with pytest.raises(GharialError, match="LEFT_FOOT"):
        robots.MultibodyConstraintFwdDynamics(space, None, ["FL_FOOT", "LEFT_FOOT"])
    with pytest.raises(GharialError):
        robots.MultibodyConstraintFwdDynamics(space, None, FEET, kp=-1.0)
    with pytest.raises(GharialError):
        robots.MultibodyConstraintFwdDynamics(space, None, FEET, reference="world")
    with pytest.raises(GharialError, match="LEFT_FOOT"):
        robots.FrameTranslationResidual(space, 12, "LEFT_FOOT", [0, 0, 0])
    with pytest.raises(GharialError):
        robots.FramePlacementResidual(space, 12, "LEFT_FOOT", np.eye(3), [0, 0, 0])
    with pytest.raises(GharialError):
        robots.FramePlacementResidual(space, 12, "FL_FOOT", 2 * np.eye(3), [0, 0, 0])
    with pytest.raises(GharialError):
        robots.FrameTranslationResidual(space, 12, "FL_FOOT", [0, np.inf, 0])
    with pytest.raises(GharialError):
        robots.MultibodyFreeFwdDynamics(space, np.full((18, 12), np.nan))
    ode = robots.MultibodyConstraintFwdDynamics(space, None, FEET)
    with pytest.raises(GharialError):
        ode.contact_forces(np.concatenate([bad, np.zeros(18)]), np.zeros(12))


@pytest.mark.parametrize(
    "xml",
    [
        "",
        "not xml at all",
        "<robot name='r'><link name='a'/>",
        "<notarobot/>",
        "<robot name='r'><link name='a'/><joint name='j' type='revolute'><parent link='a'/>"
        "<child link='missing'/></joint></robot>",
        "<robot name='r'><link name='a'><inertial><mass value='abc'/></inertial></link></robot>",
        "<robot name='r'><link name='a'><inertial><mass value='-1'/>"
        "<inertia ixx='1' iyy='1' izz='1' ixy='0' ixz='0' iyz='0'/></inertial></link></robot>",
    ],
)
def test_malformed_urdf(xml, tmp_path):
    with pytest.raises(GharialError):
        robots.load_urdf_string(xml)
    path = tmp_path / "bad.urdf"
    path.write_text(xml)
    with pytest.raises(GharialError):
        robots.load_urdf(path)


def test_missing_files(tmp_path):
    with pytest.raises(GharialError):
        robots.load_urdf(tmp_path / "missing.urdf")
    (tmp_path / "ok.urdf").write_text("<robot name='r'><link name='a'/></robot>")
    with pytest.raises(GharialError):
        robots.load_urdf(tmp_path / "ok.urdf", srdf=tmp_path / "missing.srdf")
    with pytest.raises(GharialError):
        robots.load_urdf_string("<robot name='r'><link name='a'/></robot>", srdf="<robot")


# --- end to end -------------------------------------------------------------------


def test_ur5_reach_with_proxddp(ur5):
    import gharial

    space = robots.MultibodyPhaseSpace(ur5)
    ode = robots.MultibodyFreeFwdDynamics(space)
    dt, horizon, nu = 0.02, 40, ode.nu
    step = IntegratorSemiImplEuler(ode, dt)
    q0 = ur5.neutral()
    x0 = np.concatenate([q0, np.zeros(6)])
    target = robots.frame_placement(ur5, robots.integrate(ur5, q0, [0.4, -0.3, 0.5, 0.0, 0.2, 0.0]), "tool0")[1]
    ee = robots.FrameTranslationResidual(space, 0, "tool0", target)  # terminal: nu = 0
    u_ref = robots.generalized_gravity(ur5, q0)
    stages = []
    for _ in range(horizon):
        cost = gharial.CostStack(space, nu)
        cost.addCost("state", gharial.QuadraticStateCost(space, nu, x0, [1e-2] * 6 + [1e-1] * 6), dt)
        cost.addCost("control", gharial.QuadraticControlCost(space, u_ref, [1e-3] * 6), dt)
        stages.append(gharial.StageModel(cost, step))
    terminal = gharial.CostStack(space, 0)
    terminal.addCost("ee", gharial.QuadraticResidualCost(space, ee, [1e3] * 3), 1.0)
    terminal.addCost("still", gharial.QuadraticStateCost(space, 0, x0, [0.0] * 6 + [1.0] * 6), 1.0)
    problem = gharial.TrajOptProblem(x0, stages, terminal)
    solver = gharial.SolverProxDDP(tol=1e-6, max_iters=200)
    assert solver.run(problem), solver.results
    xs, us = np.array(solver.results.xs), np.array(solver.results.us)
    assert xs.shape == (horizon + 1, 12) and us.shape == (horizon, 6)
    for t in range(horizon):
        np.testing.assert_allclose(step.forward(xs[t], us[t]), xs[t + 1], atol=1e-7)
    reached = robots.frame_placement(ur5, xs[-1][:6], "tool0")[1]
    assert np.linalg.norm(reached - target) < 0.02
    assert np.linalg.norm(robots.frame_placement(ur5, q0, "tool0")[1] - target) > 0.2

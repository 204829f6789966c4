"""Models written in Python (cost, stage function, ODE) against finite differences and
against the equivalent Rust models; errors in user code come back as exceptions."""

import numpy as np
import pytest
from conftest import lqr_problem, point_mass

import gharial
from gharial import constraints, dynamics, manifolds

G = 9.81


class Pendulum(dynamics.ODEAbstract):
    """θ'' = -g sin θ + u on R² (angle, rate)."""

    def __init__(self):
        super().__init__(manifolds.VectorSpace(2), 1)

    def forward(self, x, u):
        return np.array([x[1], -G * np.sin(x[0]) + u[0]])

    def jacobians(self, x, u):
        return np.array([[0.0, 1.0], [-G * np.cos(x[0]), 0.0]]), np.array([[0.0], [1.0]])


class QuadCost(gharial.CostAbstract):
    """½ xᵀ Q x + ½ uᵀ R u written in Python."""

    def __init__(self, space, nu, q, r):
        super().__init__(space, nu)
        self.q, self.r = np.diag(q), np.diag(r)

    def evaluate(self, x, u):
        return 0.5 * x @ self.q @ x + 0.5 * u @ self.r @ u

    def derivatives(self, x, u):
        return self.q @ x, self.r @ u, self.q, np.zeros((len(x), len(u))), self.r


class Speed(gharial.StageFunction):
    """r(x, u) = [x0 * x1, u0²]."""

    def __init__(self, space):
        super().__init__(space, 1, 2)

    def evaluate(self, x, u):
        return np.array([x[0] * x[1], u[0] ** 2])

    def jacobians(self, x, u):
        return np.array([[x[1], x[0]], [0.0, 0.0]]), np.array([[0.0], [2 * u[0]]])


def fd_jacobians(f, x, u, h=1e-6):
    y = f(x, u)
    jx = np.column_stack([(f(x + h * e, u) - f(x - h * e, u)) / (2 * h) for e in np.eye(len(x))])
    ju = np.column_stack([(f(x, u + h * e) - f(x, u - h * e)) / (2 * h) for e in np.eye(len(u))])
    return y, jx, ju


@pytest.mark.parametrize("integrator", [dynamics.IntegratorEuler, dynamics.IntegratorRK2, dynamics.IntegratorRK4,
                                        dynamics.IntegratorSemiImplEuler])
def test_python_ode_through_integrators_matches_finite_differences(integrator):
    d = integrator(Pendulum(), 0.05)
    x, u = np.array([0.7, -0.3]), np.array([0.4])
    _, jx_fd, ju_fd = fd_jacobians(d.forward, x, u)
    jx, ju = d.jacobians(x, u)
    np.testing.assert_allclose(jx, jx_fd, atol=1e-8)
    np.testing.assert_allclose(ju, ju_fd, atol=1e-8)


def test_rk4_of_a_python_ode_equals_rk4_by_hand():
    ode, dt = Pendulum(), 0.05
    x, u = np.array([0.7, -0.3]), np.array([0.4])
    k1 = ode.forward(x, u)
    k2 = ode.forward(x + dt / 2 * k1, u)
    k3 = ode.forward(x + dt / 2 * k2, u)
    k4 = ode.forward(x + dt * k3, u)
    np.testing.assert_allclose(dynamics.IntegratorRK4(ode, dt).forward(x, u), x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4), atol=1e-15)


def test_python_stage_function_jacobians_and_rust_wrappers():
    space = manifolds.VectorSpace(2)
    f = Speed(space)
    x, u = np.array([0.3, -1.2]), np.array([0.7])
    sl = f[[1]]
    assert sl.nr == 1
    np.testing.assert_allclose(sl(x, u), [0.49])
    _, jx_fd, ju_fd = fd_jacobians(lambda x, u: sl(x, u), x, u)
    jx, ju = sl.jacobians(x, u)
    np.testing.assert_allclose(jx, jx_fd, atol=1e-8)
    np.testing.assert_allclose(ju, ju_fd, atol=1e-8)
    comp = gharial.LinearFunctionComposition(f, np.array([[2.0, 1.0]]), np.array([0.5]))
    np.testing.assert_allclose(comp(x, u), [2 * 0.3 * -1.2 + 0.49 + 0.5])


def test_python_cost_solves_like_the_rust_cost():
    """The LQR with its quadratic costs written in Python: same iterates as in Rust."""
    a, b = point_mass()
    space = manifolds.VectorSpace(4)
    q, r = 0.1 * np.array([1.0, 1.0, 0.1, 0.1]), 0.1 * np.array([0.1, 0.1])

    def build(cost):
        stages = [gharial.StageModel(cost, dynamics.LinearDiscreteDynamics(a, b)) for _ in range(20)]
        return gharial.TrajOptProblem(np.array([1.0, -0.5, 0.0, 0.2]), stages, QuadCost(space, 0, [10.0] * 4, []))

    py = build(QuadCost(space, 2, q, r))
    rust = build(gharial.QuadraticCost(np.diag(q), np.diag(r)))
    results = []
    for p in (py, rust):
        s = gharial.SolverFDDP(tol=1e-10)
        assert s.run(p)
        results.append(s.results)
    assert results[0].num_iters == results[1].num_iters
    np.testing.assert_allclose(np.array(results[0].us), np.array(results[1].us), atol=1e-12)


def test_python_ode_problem_solves_with_bounds():
    """Pendulum swing-up towards upright with a torque bound, ODE in Python, RK4."""
    space = manifolds.VectorSpace(2)
    d = dynamics.IntegratorRK4(Pendulum(), 0.05)
    stages = []
    for _ in range(40):
        cost = gharial.CostStack(space, 1)
        cost.addCost("x", gharial.QuadraticStateCost(space, 1, np.array([np.pi, 0.0]), [0.1, 0.01]), 1.0)
        cost.addCost("u", gharial.QuadraticControlCost(space, np.zeros(1), [1e-3]), 1.0)
        st = gharial.StageModel(cost, d)
        st.addConstraint(gharial.ControlErrorResidual(space, np.zeros(1)), constraints.BoxConstraint([-5.0], [5.0]))
        stages.append(st)
    term = gharial.QuadraticStateCost(space, 0, np.array([np.pi, 0.0]), [100.0, 10.0])
    problem = gharial.TrajOptProblem(np.zeros(2), stages, term)
    s = gharial.SolverProxDDP(tol=1e-6, max_iters=300)
    s.run(problem)
    r = s.results
    assert r.conv, r
    assert max(abs(u[0]) for u in r.us) <= 5.0 + 1e-6
    for t in range(40):
        np.testing.assert_allclose(r.xs[t + 1], d.forward(r.xs[t], r.us[t]), atol=1e-6)


class Raising(gharial.CostAbstract):
    def __init__(self, space, nu, raise_after):
        super().__init__(space, nu)
        self.calls, self.raise_after = 0, raise_after

    def evaluate(self, x, u):
        self.calls += 1
        if self.calls > self.raise_after:
            raise ZeroDivisionError("boom")
        return float(x @ x + u @ u)

    def derivatives(self, x, u):
        return 2 * x, 2 * u, 2 * np.eye(len(x)), np.zeros((len(x), len(u))), 2 * np.eye(len(u))


def test_an_exception_in_a_python_model_names_the_stage():
    a, b = point_mass()
    space = manifolds.VectorSpace(4)
    lin = dynamics.LinearDiscreteDynamics(a, b)
    stages = [gharial.StageModel(gharial.QuadraticControlCost(space, np.zeros(2), [1.0, 1.0]), lin) for _ in range(5)]
    stages.append(gharial.StageModel(Raising(space, 2, raise_after=1), lin))
    stages += [gharial.StageModel(gharial.QuadraticControlCost(space, np.zeros(2), [1.0, 1.0]), lin) for _ in range(3)]
    problem = gharial.TrajOptProblem(np.ones(4), stages, gharial.QuadraticStateCost(space, 0, np.zeros(4), [1.0] * 4))
    s = gharial.SolverProxDDP()
    with pytest.raises(gharial.GharialError, match=r"ZeroDivisionError.*Raising.*stage 5.*boom") as info:
        s.run(problem, [np.ones(4)] * 10, [np.zeros(2)] * 9)
    assert isinstance(info.value.__cause__, ZeroDivisionError)
    # the solver stays usable
    assert s.run(lqr_problem())


def test_python_models_with_wrong_shapes_are_refused_once():
    space = manifolds.VectorSpace(2)

    class BadOde(dynamics.ODEAbstract):
        def __init__(self):
            super().__init__(space, 1)

        def forward(self, x, u):
            return np.zeros(3)

        def jacobians(self, x, u):
            return np.zeros((2, 2)), np.zeros((2, 1))

    with pytest.raises(ValueError, match="BadOde.forward: xdot: expected 2 entries, got 3"):
        dynamics.IntegratorEuler(BadOde(), 0.1)

    class BadCost(gharial.CostAbstract):
        def __init__(self):
            super().__init__(space, 1)

        def evaluate(self, x, u):
            return 0.0

        def derivatives(self, x, u):
            return np.zeros(2), np.zeros(1), np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((1, 1))

    with pytest.raises(ValueError, match=r"BadCost.derivatives: lxu: expected shape \(2, 1\), got \(2, 2\)"):
        gharial.StageModel(BadCost(), dynamics.IntegratorEuler(Pendulum(), 0.1))

    class NoInit(gharial.CostAbstract):
        def __init__(self):
            pass

    with pytest.raises(TypeError, match="super"):
        gharial.StageModel(NoInit(), dynamics.IntegratorEuler(Pendulum(), 0.1))


def _fd_jacobian(f, z, n, h=1e-6):
    """Central differences of `f` along the `n` tangent directions applied by `z(e)`."""
    cols = []
    for i in range(n):
        e = np.zeros(n)
        e[i] = h
        cols.append((f(z(e)) - f(z(-e))) / (2 * h))
    return np.array(cols).T


@pytest.mark.parametrize(
    "space",
    [
        manifolds.SE3(),
        manifolds.SO3(),
        manifolds.SE2(),
        manifolds.SO2(),
        manifolds.SE3() * manifolds.VectorSpace(2),
    ],
)
def test_manifold_jacobians_equal_finite_differences(space):
    rng = np.random.default_rng(3)
    n = space.ndx
    x0 = space.integrate(space.neutral(), rng.normal(size=n) * 0.7)
    x1 = space.integrate(x0, rng.normal(size=n) * 0.7)
    v = space.difference(x0, x1)
    checks = [
        (space.Jintegrate(x0, v, 0), lambda x: space.difference(x1, space.integrate(x, v)), lambda e: space.integrate(x0, e)),
        (space.Jintegrate(x0, v, 1), lambda w: space.difference(x1, space.integrate(x0, w)), lambda e: v + e),
        (space.Jdifference(x0, x1, 0), lambda x: space.difference(x, x1), lambda e: space.integrate(x0, e)),
        (space.Jdifference(x0, x1, 1), lambda x: space.difference(x0, x), lambda e: space.integrate(x1, e)),
    ]
    for j, f, z in checks:
        np.testing.assert_allclose(j, _fd_jacobian(f, z, n), atol=1e-6)
    with pytest.raises(ValueError, match="arg"):
        space.Jdifference(x0, x1, 2)


def test_manifold_jacobians_refuse_invalid_points():
    se3 = manifolds.SE3()
    with pytest.raises(ValueError, match="not a valid point"):
        se3.Jdifference(np.zeros(7), se3.neutral(), 0)

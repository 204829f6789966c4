"""A pendulum swing-up whose ODE and cost are written in Python (numpy derivatives).

Python models call back into the interpreter at every evaluation: this solve is about
50 times slower than the same problem with Rust models. Rust models are the fast path.
"""
import numpy as np

import gharial
from gharial import constraints, dynamics, manifolds


class Pendulum(dynamics.ODEAbstract):
    """θ'' = -(g / l) sin θ + u / (m l²) with x = (θ, θ')."""

    def __init__(self, g=9.81, length=1.0, mass=1.0):
        super().__init__(manifolds.VectorSpace(2), 1)
        self.a, self.b = g / length, 1.0 / (mass * length**2)

    def forward(self, x, u):
        return np.array([x[1], -self.a * np.sin(x[0]) + self.b * u[0]])

    def jacobians(self, x, u):
        return np.array([[0.0, 1.0], [-self.a * np.cos(x[0]), 0.0]]), np.array([[0.0], [self.b]])


class Upright(gharial.CostAbstract):
    """½ w (θ - π)² + ½ r θ'² + ½ ru ‖u‖²: zero at rest upright."""

    def __init__(self, space, nu, w, r, ru):
        super().__init__(space, nu)
        self.w, self.r, self.ru = w, r, ru

    def evaluate(self, x, u):
        return 0.5 * self.w * (x[0] - np.pi) ** 2 + 0.5 * self.r * x[1] ** 2 + 0.5 * self.ru * float(u @ u)

    def derivatives(self, x, u):
        nu = len(u)
        lx = np.array([self.w * (x[0] - np.pi), self.r * x[1]])
        lxx = np.diag([self.w, self.r])
        return lx, self.ru * u, lxx, np.zeros((2, nu)), self.ru * np.eye(nu)


space = manifolds.VectorSpace(2)
step = dynamics.IntegratorRK4(Pendulum(), 0.05)
stage = gharial.StageModel(Upright(space, 1, 0.1, 0.01, 1e-2), step)
stage.addConstraint(gharial.ControlErrorResidual(space, np.zeros(1)), constraints.BoxConstraint([-10.0], [10.0]))
problem = gharial.TrajOptProblem(np.zeros(2), [stage] * 60, Upright(space, 0, 100.0, 10.0, 0.0))
solver = gharial.SolverProxDDP(tol=1e-6, max_iters=500)
solver.run(problem)
r = solver.results
print(r)
print("final angle %.3f rad (upright: pi), max |u| %.3f" % (r.xs[-1][0], max(abs(u[0]) for u in r.us)))

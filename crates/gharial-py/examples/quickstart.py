"""A point mass in the plane pushed to the origin with bounded forces (the Rust quickstart)."""
import numpy as np

import gharial
from gharial import constraints, dynamics, manifolds

dt, horizon = 0.1, 40
a = np.eye(4)
a[0, 2] = a[1, 3] = dt  # position += dt * velocity
b = np.zeros((4, 2))
b[2, 0] = b[3, 1] = dt  # velocity += dt * force
space = manifolds.VectorSpace(4)  # (position, velocity)

cost = gharial.CostStack(space, 2)
cost.addCost("state", gharial.QuadraticStateCost(space, 2, np.zeros(4), [1.0, 1.0, 0.1, 0.1]), dt)
cost.addCost("control", gharial.QuadraticControlCost(space, np.zeros(2), [0.1, 0.1]), dt)
stage = gharial.StageModel(cost, dynamics.LinearDiscreteDynamics(a, b))
stage.addConstraint(gharial.ControlErrorResidual(space, np.zeros(2)), constraints.BoxConstraint([-2.0] * 2, [2.0] * 2))
terminal = gharial.QuadraticStateCost(space, 0, np.zeros(4), [100.0] * 4)
problem = gharial.TrajOptProblem(np.array([1.0, -1.0, 0.0, 0.0]), [stage] * horizon, terminal)

solver = gharial.SolverProxDDP(tol=1e-8, verbose=True)
solver.run(problem)
r = solver.results
print(r)
print("first forces", r.us[0], "final state", r.xs[-1])

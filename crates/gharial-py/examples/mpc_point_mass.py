"""Model-predictive control of the quickstart's point mass: the first horizon solved to
convergence, then re-solved every step with one ProxDDP iteration, warm-started from
the shifted solution; the policy's control is applied to a plant pushed by a constant
force the controller does not know of (so the point settles off the origin)."""
import numpy as np

import gharial
from gharial import constraints, dynamics, manifolds

dt, horizon = 0.1, 20
a = np.eye(4)
a[0, 2] = a[1, 3] = dt
b = np.zeros((4, 2))
b[2, 0] = b[3, 1] = dt
space = manifolds.VectorSpace(4)

cost = gharial.CostStack(space, 2)
cost.addCost("state", gharial.QuadraticStateCost(space, 2, np.zeros(4), [1.0, 1.0, 0.1, 0.1]), dt)
cost.addCost("control", gharial.QuadraticControlCost(space, np.zeros(2), [0.1, 0.1]), dt)
stage = gharial.StageModel(cost, dynamics.LinearDiscreteDynamics(a, b))
stage.addConstraint(gharial.ControlErrorResidual(space, np.zeros(2)), constraints.BoxConstraint([-2.0] * 2, [2.0] * 2))
terminal = gharial.QuadraticStateCost(space, 0, np.zeros(4), [100.0] * 4)
x = np.array([1.0, -1.0, 0.0, 0.0])
problem = gharial.TrajOptProblem(x, [stage] * horizon, terminal)

first = gharial.SolverProxDDP(tol=1e-8)
first.run(problem)
mpc = gharial.MPC(problem, gharial.SolverProxDDP(), first.results.xs, first.results.us, max_iters=1)
push = np.array([0.0, 0.0, 0.03, -0.02])  # velocity added by the unknown force each step
u_max = 0.0
for step in range(80):
    mpc.solve(x)
    u = mpc.control(x)
    u_max = max(u_max, np.abs(u).max())
    x = a @ x + b @ u + push
    mpc.shift()
print(f"cycles {mpc.cycles}, final position {x[:2]}, final velocity {x[2:]}")
print(f"last control {u} (the push needs {-push[2:] / dt}), largest |u| {u_max:.6f}")

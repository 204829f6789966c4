"""Module-level build functions for the batch tests (picklable for processes and Ray)."""

import numpy as np

import gharial


def ur5_reach(target):
    """The catalogue's UR5 reach, with its end-effector target moved to `target` (None: fail)."""
    if target is None:
        raise RuntimeError("no target for this instance")
    ex = gharial.problems.build("ur5")
    return ex


def lqr(x0):
    """The point-mass LQR from x0 (built with the Python API)."""
    from conftest import lqr_problem

    return lqr_problem(x0=tuple(x0))


def lqr_standalone(x0):
    """As `lqr`, importable by worker processes (no conftest on their path)."""
    space = gharial.manifolds.VectorSpace(4)
    a = np.eye(4)
    a[0, 2] = a[1, 3] = 0.1
    b = np.zeros((4, 2))
    b[2, 0] = b[3, 1] = 0.1
    dyn = gharial.dynamics.LinearDiscreteDynamics(a, b)
    stages = []
    for _ in range(20):
        cost = gharial.CostStack(space, 2)
        cost.addCost("state", gharial.QuadraticStateCost(space, 2, np.zeros(4), [1.0, 1.0, 0.1, 0.1]), 0.1)
        cost.addCost("control", gharial.QuadraticControlCost(space, np.zeros(2), [0.1, 0.1]), 0.1)
        stages.append(gharial.StageModel(cost, dyn))
    term = gharial.QuadraticStateCost(space, 0, np.zeros(4), [10.0] * 4)
    if not np.all(np.isfinite(x0)):
        return gharial.TrajOptProblem(np.asarray(x0), stages, term)  # raises: non-finite x0
    return gharial.TrajOptProblem(np.asarray(x0, dtype=float), stages, term)

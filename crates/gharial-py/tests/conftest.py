"""Shared fixtures: a small LQR built with the Python API and its dense KKT solution."""

import numpy as np
import pytest

import gharial
from gharial import constraints, dynamics, manifolds

DT = 0.1
N = 20


def point_mass():
    """A point mass in the plane: x = (position, velocity), u = force."""
    a = np.eye(4)
    a[0, 2] = a[1, 3] = DT
    b = np.zeros((4, 2))
    b[2, 0] = b[3, 1] = DT
    return a, b


def lqr_problem(x0=(1.0, -0.5, 0.0, 0.2), bounds=None, horizon=N):
    """The point-mass LQR (quadratic state and control costs), optionally with |u| <= bounds."""
    a, b = point_mass()
    space = manifolds.VectorSpace(4)
    stages = []
    for _ in range(horizon):
        cost = gharial.CostStack(space, 2)
        cost.addCost("state", gharial.QuadraticStateCost(space, 2, np.zeros(4), [1.0, 1.0, 0.1, 0.1]), DT)
        cost.addCost("control", gharial.QuadraticControlCost(space, np.zeros(2), [0.1, 0.1]), DT)
        stage = gharial.StageModel(cost, dynamics.LinearDiscreteDynamics(a, b))
        if bounds is not None:
            stage.addConstraint(gharial.ControlErrorResidual(space, np.zeros(2)), constraints.BoxConstraint([-bounds] * 2, [bounds] * 2))
        stages.append(stage)
    terminal = gharial.QuadraticStateCost(space, 0, np.zeros(4), [10.0] * 4)
    return gharial.TrajOptProblem(np.array(x0), stages, terminal)


def lqr_kkt(x0=(1.0, -0.5, 0.0, 0.2), horizon=N):
    """The LQR's optimum by one dense KKT solve in numpy: (xs, us)."""
    a, b = point_mass()
    nx, nu = 4, 2
    q = DT * np.diag([1.0, 1.0, 0.1, 0.1])
    r = DT * np.diag([0.1, 0.1])
    qn = np.diag([10.0] * 4)
    nz = (horizon + 1) * nx + horizon * nu
    hess = np.zeros((nz, nz))
    xi = lambda t: slice(t * nx, (t + 1) * nx)  # noqa: E731
    ui = lambda t: slice((horizon + 1) * nx + t * nu, (horizon + 1) * nx + (t + 1) * nu)  # noqa: E731
    for t in range(horizon):
        hess[xi(t), xi(t)] = q
        hess[ui(t), ui(t)] = r
    hess[xi(horizon), xi(horizon)] = qn
    rows = []
    rhs = []
    e0 = np.zeros((nx, nz))
    e0[:, xi(0)] = np.eye(nx)
    rows.append(e0)
    rhs.append(np.array(x0))
    for t in range(horizon):
        c = np.zeros((nx, nz))
        c[:, xi(t)] = a
        c[:, ui(t)] = b
        c[:, xi(t + 1)] = -np.eye(nx)
        rows.append(c)
        rhs.append(np.zeros(nx))
    c = np.vstack(rows)
    kkt = np.block([[hess, c.T], [c, np.zeros((c.shape[0], c.shape[0]))]])
    sol = np.linalg.solve(kkt, np.concatenate([np.zeros(nz), np.concatenate(rhs)]))
    xs = [sol[xi(t)] for t in range(horizon + 1)]
    us = [sol[ui(t)] for t in range(horizon)]
    return xs, us


@pytest.fixture
def lqr():
    return lqr_problem()

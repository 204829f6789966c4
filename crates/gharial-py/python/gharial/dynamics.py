"""Dynamics (ALIGATOR's ``aligator.dynamics``): ODEs, integrators, discrete models.

Subclass :class:`ODEAbstract` to write an ODE in Python::

    class Pendulum(ODEAbstract):
        def __init__(self):
            super().__init__(VectorSpace(2), 1)
        def forward(self, x, u):          # xdot, a tangent vector (ndx)
            return np.array([x[1], -9.81 * np.sin(x[0]) + u[0]])
        def jacobians(self, x, u):        # (Jx: ndx x ndx, Ju: ndx x nu)
            return np.array([[0, 1], [-9.81 * np.cos(x[0]), 0]]), np.array([[0], [1]])
"""

from ._gharial import (  # noqa: F401
    DynamicsModel,
    IntegratorEuler,
    IntegratorImplicitEuler,
    IntegratorMidpoint,
    IntegratorRK2,
    IntegratorRK4,
    IntegratorSemiImplEuler,
    LinearDiscreteDynamics,
    LinearODE,
    ODEAbstract,
)

__all__ = [
    "ODEAbstract",
    "LinearODE",
    "DynamicsModel",
    "LinearDiscreteDynamics",
    "IntegratorEuler",
    "IntegratorRK2",
    "IntegratorRK4",
    "IntegratorSemiImplEuler",
    "IntegratorImplicitEuler",
    "IntegratorMidpoint",
]

"""gharial: constrained trajectory optimization and model-predictive control for robots.

The solvers, models and robots are Rust (the extension module ``gharial._gharial``);
this package arranges them under ALIGATOR's names. See the package README.
"""

from . import constraints, dynamics, manifolds, problems, robots  # noqa: F401
from .batch import solve_batch  # noqa: F401
from ._gharial import (  # noqa: F401
    ControlErrorResidual,
    CostAbstract,
    CostStack,
    FunctionSlice,
    GharialError,
    LinearFunction,
    LinearFunctionComposition,
    MPC,
    QuadraticControlCost,
    QuadraticCost,
    QuadraticResidualCost,
    QuadraticStateCost,
    Results,
    Solver,
    SolverALTRO,
    SolverBCLDDP,
    SolverBoxDDP,
    SolverBoxFDDP,
    SolverCSQP,
    SolverDDP,
    SolverFDDP,
    SolverProxDDP,
    SolverProxNLP,
    SolverSQP,
    StageFunction,
    StageModel,
    StateErrorResidual,
    TrajOptProblem,
    plot_convergence,
    solver,
    solver_names,
    view,
)

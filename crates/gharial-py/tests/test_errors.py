"""Bad input from Python: ValueError for shapes and dtypes, GharialError (a ValueError)
with the Rust message for invalid models, AttributeError for unknown options."""

import numpy as np
import pytest
from conftest import lqr_problem, point_mass

import gharial
from gharial import constraints, dynamics, manifolds


def test_wrong_shapes_and_dtypes_are_value_errors():
    a, b = point_mass()
    with pytest.raises(ValueError, match="LinearDiscreteDynamics c: expected 4 entries, got 3"):
        dynamics.LinearDiscreteDynamics(a, b, np.zeros(3))
    with pytest.raises(ValueError, match="expected real numbers, got dtype complex128"):
        dynamics.LinearDiscreteDynamics(a.astype(complex), b)
    with pytest.raises(ValueError, match="expected real numbers, got dtype bool"):
        manifolds.VectorSpace(2).integrate(np.array([True, False]), np.zeros(2))
    with pytest.raises(ValueError, match="expected real numbers"):
        manifolds.VectorSpace(2).integrate(["a", "b"], np.zeros(2))
    with pytest.raises(ValueError, match="expected a 2-D array, got 1 dimensions"):
        dynamics.LinearDiscreteDynamics(np.zeros(4), b)
    with pytest.raises(ValueError, match=r"x: expected 3 entries, got 2"):
        manifolds.SO2().__mul__(manifolds.VectorSpace(1)).integrate(np.zeros(2), np.zeros(2))


def test_guesses_of_the_wrong_size_are_errors():
    p = lqr_problem()
    s = gharial.SolverProxDDP()
    with pytest.raises(ValueError, match="us"):
        s.run(p, [np.zeros(4)] * 21, [np.zeros(2)] * 19)
    with pytest.raises(ValueError, match="xs"):
        s.run(p, [np.zeros(3)] * 21, [np.zeros(2)] * 20)
    with pytest.raises(ValueError, match="non-finite"):
        s.run(p, [np.zeros(4)] * 21, [np.array([np.nan, 0.0])] * 20)
    with pytest.raises(ValueError, match="both"):
        s.run(p, [np.zeros(4)] * 21)



def test_rollout_checks_the_controls():
    p = lqr_problem()
    with pytest.raises(ValueError, match=r"us\[0\] size"):
        p.rollout([np.zeros(3)] * 20)
    with pytest.raises(ValueError, match="number of controls"):
        p.rollout([np.zeros(2)] * 3)
    with pytest.raises(ValueError, match="number of controls"):
        p.rollout([np.zeros(2)] * 21)
    with pytest.raises(ValueError, match="non-finite"):
        p.rollout([np.array([np.nan, 0.0])] * 20)


def test_model_errors_carry_the_rust_message():
    space = manifolds.VectorSpace(4)
    a, b = point_mass()
    with pytest.raises(gharial.GharialError, match="BoxConstraint"):
        constraints.BoxConstraint([1.0, 0.0], [0.0, 1.0])
    stage = gharial.StageModel(gharial.QuadraticControlCost(space, np.zeros(2), [1.0, 1.0]), dynamics.LinearDiscreteDynamics(a, b))
    with pytest.raises(gharial.GharialError, match="dimension mismatch"):
        stage.addConstraint(gharial.ControlErrorResidual(space, np.zeros(3)), constraints.EqualityConstraintSet())
    with pytest.raises(gharial.GharialError, match="terminal cost"):
        gharial.TrajOptProblem(np.zeros(4), [stage], gharial.QuadraticStateCost(manifolds.VectorSpace(3), 0, np.zeros(3), [1.0] * 3))
    with pytest.raises(gharial.GharialError, match="at least one stage"):
        gharial.TrajOptProblem(np.zeros(4), [], gharial.QuadraticStateCost(space, 0, np.zeros(4), [1.0] * 4))
    with pytest.raises(gharial.GharialError, match="unknown problem|not in the catalogue|no problem"):
        gharial.problems.build("no-such-problem")
    assert issubclass(gharial.GharialError, ValueError)


def test_solver_constructors_take_aligators_positional_arguments():
    s = gharial.SolverProxDDP(1e-7, 1e-3, max_iters=50, verbose=False)
    assert (s.tol, s.mu_init, s.max_iters) == (1e-7, 1e-3, 50)
    f = gharial.SolverFDDP(1e-7, 20)
    assert (f.tol, f.max_iters) == (1e-7, 20)


def test_options_are_checked_attributes():
    s = gharial.SolverProxDDP()
    s.mu_init = 1e-3
    assert s.mu_init == 1e-3
    with pytest.raises(AttributeError, match="no option `no_such_option`"):
        s.no_such_option = 1.0
    with pytest.raises(AttributeError):
        _ = s.no_such_option
    with pytest.raises(ValueError, match="tol"):
        s.tol = -1.0
    assert s.tol == 1e-6  # the bad value was not kept
    with pytest.raises(ValueError, match="unknown value `sideways`"):
        s.rollout = "sideways"
    assert s.dynamics_step == "auto"
    s.dynamics_step = "proximal"
    assert s.dynamics_step == "proximal"
    with pytest.raises(ValueError, match="unknown value `hard`"):
        s.dynamics_step = "hard"
    with pytest.raises(ValueError, match="max_iters"):
        s.max_iters = "many"
    with pytest.raises(ValueError, match="unknown solver `ipopt`"):
        gharial.solver("ipopt")
    with pytest.raises(AttributeError, match="solver `fddp` has no option `mu_init`"):
        gharial.solver("fddp", mu_init=1.0)
    assert "mu_init" in s.option_names and "verbose" in s.option_names


def test_a_solver_that_refuses_a_problem_says_why():
    p = lqr_problem(bounds=0.3)
    with pytest.raises(gharial.GharialError):
        gharial.SolverFDDP().run(p)


def test_python_subclass_must_call_super_init():
    class Half(gharial.StageFunction):
        def __init__(self):
            pass

    with pytest.raises(TypeError, match="super"):
        gharial.FunctionSlice(Half(), [0])

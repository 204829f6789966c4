"""Solving from Python: every solver against a dense KKT solve, the catalogue against the
Rust command-line tool bit for bit, options, warm starts and results."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import lqr_kkt, lqr_problem

import gharial

ALL = gharial.solver_names()


@pytest.mark.parametrize("name", ALL)
def test_every_solver_reaches_the_dense_kkt_optimum(name):
    problem = lqr_problem()
    xs_ref, us_ref = lqr_kkt()
    s = gharial.solver(name, tol=1e-10, max_iters=200)
    assert s.run(problem), s.results
    r = s.results
    assert r.status == "converged"
    np.testing.assert_allclose(np.array(r.us), np.array(us_ref), atol=1e-7)
    np.testing.assert_allclose(np.array(r.xs), np.array(xs_ref), atol=1e-7)


def test_named_classes_match_the_names():
    for cls, name in [
        (gharial.SolverProxDDP, "proxddp"),
        (gharial.SolverDDP, "ddp"),
        (gharial.SolverFDDP, "fddp"),
        (gharial.SolverBoxDDP, "box-ddp"),
        (gharial.SolverBoxFDDP, "box-fddp"),
        (gharial.SolverSQP, "sqp"),
        (gharial.SolverCSQP, "csqp"),
        (gharial.SolverBCLDDP, "bcl-ddp"),
        (gharial.SolverALTRO, "altro"),
        (gharial.SolverProxNLP, "proxnlp"),
    ]:
        s = cls(tol=1e-7, max_iters=50)
        assert s.name == name and s.tol == 1e-7 and s.max_iters == 50
        assert isinstance(s, gharial.Solver)


def cli(args, tmp_path):
    exe = os.environ.get("GHARIAL_CLI")
    if not exe:
        pytest.skip("GHARIAL_CLI (the gharial binary) is not set; tools/test sets it")
    out = tmp_path / "cli.json"
    subprocess.run([exe, "solve", *args, "--output", str(out)], check=False, capture_output=True)
    return json.loads(out.read_text())


@pytest.mark.parametrize(
    "problem,solver",
    [("pendulum", "proxddp"), ("ur5", "proxddp"), ("ur5", "fddp"), ("ur5", "sqp"), ("lqr-bounds-term", "proxddp"),
     ("ur5-box", "csqp"), ("ur5-box", "box-fddp")],
)
def test_catalogue_solves_equal_the_command_line_bit_for_bit(problem, solver, tmp_path):
    ref = cli([problem, "--solver", solver], tmp_path)
    ex = gharial.problems.build(problem)
    s = ex.solver(solver)
    s.run(ex.problem, ex.xs0, ex.us0)
    r = s.results
    assert r.num_iters == ref["iterations"]
    assert r.traj_cost == ref["cost"]
    assert [list(x) for x in r.xs] == ref["xs"]
    assert [list(u) for u in r.us] == ref["us"]


def test_results_have_the_solution_shapes(lqr):
    s = gharial.SolverProxDDP(tol=1e-8)
    s.run(lqr)
    r = s.results
    assert len(r.xs) == 21 and len(r.us) == 20 and len(r.lams) == 21 and len(r.vs) == 21
    assert all(k.shape == (2, 4) for k in r.gains)
    assert r.history["prim_err"].shape == (r.num_iters,) or r.history["prim_err"].shape == (r.num_iters + 1,)
    d = r.to_dict()
    assert d["status"] == "converged" and d["traj_cost"] == r.traj_cost
    assert "converged" in repr(r)


def test_feedback_gains_are_the_lqr_gains(lqr):
    """K_0 of the last backward pass maps a perturbation of x0 to the change of u0."""
    s = gharial.SolverProxDDP(tol=1e-10)
    s.run(lqr)
    k0 = s.results.gains[0]
    dx = np.array([1e-3, -2e-3, 0.5e-3, 1e-3])
    x0 = np.array([1.0, -0.5, 0.0, 0.2])
    _, us_ref = lqr_kkt(x0=tuple(x0 + dx))
    np.testing.assert_allclose(s.results.us[0] + k0 @ dx, us_ref[0], atol=1e-9)


def test_warm_start_from_the_solution_converges_at_once():
    problem = lqr_problem(bounds=0.3)
    s = gharial.SolverProxDDP(tol=1e-8)
    s.run(problem)
    r = s.results
    assert r.conv and r.num_iters > 1
    s.run(problem, r.xs, r.us, r.lams, r.vs)
    assert s.results.conv and s.results.num_iters <= 1


def test_guesses_as_lists_2d_arrays_or_python_lists_solve_alike(lqr):
    ex = gharial.problems.build("peers-lqr")
    assert ex.problem is ex.problem  # one object: repeated solves reuse the set-up
    s = ex.solver("proxddp")
    runs = []
    for xs, us in [
        (ex.xs0, ex.us0),
        (np.array(ex.xs0), np.array(ex.us0)),
        ([[float(v) for v in x] for x in ex.xs0], [[float(v) for v in u] for u in ex.us0]),
        (ex.xs0, ex.us0),
    ]:
        assert s.run(ex.problem, xs, us)
        assert s.results is s.results  # copied once per solve
        runs.append((s.results.xs, s.results.us, s.results.num_iters))
    for xs, us, iters in runs[1:]:
        assert iters == runs[0][2]
        assert all(np.array_equal(a, b) for a, b in zip(xs + us, runs[0][0] + runs[0][1]))
    # The same solver on a problem of other dimensions: the guess buffers follow.
    fresh = gharial.SolverProxDDP(tol=1e-9)
    s = gharial.SolverProxDDP(tol=1e-9)
    s.run(ex.problem, ex.xs0, ex.us0)
    for solver in (fresh, s):
        assert solver.run(lqr)
    assert all(np.array_equal(a, b) for a, b in zip(s.results.xs, fresh.results.xs))
    xs_short, us_short = fresh.results.xs[:5], fresh.results.us[:4]
    with pytest.raises(gharial.GharialError, match="number of states"):
        s.run(lqr, xs_short, us_short)
    assert s.run(lqr, fresh.results.xs, fresh.results.us)


def test_bounds_hold_and_options_change_the_solve():
    problem = lqr_problem(bounds=0.3)
    s = gharial.SolverProxDDP(tol=1e-8)
    assert s.run(problem)
    assert max(abs(u).max() for u in s.results.us) <= 0.3 + 1e-7
    s.max_iters = 1
    s.run(problem)
    assert s.results.status == "max_iterations" and not s.results.conv


def test_constraints_added_to_the_stage_objects_after_building_reach_the_problem():
    # ALIGATOR's problems hold their stages by reference: `problem.stages[i]` is the
    # stage object, and a constraint added to it (or to the object the problem was built
    # from) holds at the next solve, as a bound given before building does.
    from gharial import constraints, manifolds
    space = manifolds.VectorSpace(4)
    bound = lambda: (gharial.ControlErrorResidual(space, np.zeros(2)), constraints.BoxConstraint([-0.3] * 2, [0.3] * 2))  # noqa: E731
    reference = gharial.SolverProxDDP(tol=1e-8)
    assert reference.run(lqr_problem(bounds=0.3))
    umax = max(abs(u).max() for u in reference.results.us)
    problem = lqr_problem()
    stages = problem.stages
    # The objects given to the constructor, the same at every access.
    rebuilt = gharial.TrajOptProblem(problem.x0_init, stages, gharial.QuadraticStateCost(space, 0, np.zeros(4), [10.0] * 4))
    assert all(a is b for a, b in zip(rebuilt.stages, stages)) and problem.stages[0] is stages[0]
    with pytest.raises(TypeError):
        problem.stages[0] = stages[1]  # a tuple: no replacement that would do nothing
    s = gharial.SolverProxDDP(tol=1e-8)
    assert s.run(problem) and max(abs(u).max() for u in s.results.us) > 0.35
    for stage in stages:
        stage.addConstraint(*bound())
    for p in [problem, rebuilt]:
        assert [st.nc for st in p.stages] == [2] * len(stages)
        assert s.run(p)
        np.testing.assert_allclose(max(abs(u).max() for u in s.results.us), umax, atol=1e-7)
        np.testing.assert_allclose(s.results.traj_cost, reference.results.traj_cost, rtol=1e-9)


def test_x0_can_change_between_solves(lqr):
    s = gharial.SolverFDDP(tol=1e-10)
    lqr.x0_init = np.array([0.5, 0.5, 0.0, 0.0])
    s.run(lqr)
    xs_ref, _ = lqr_kkt(x0=(0.5, 0.5, 0.0, 0.0))
    np.testing.assert_allclose(s.results.xs[-1], xs_ref[-1], atol=1e-7)


def test_cost_stack_weights_change_between_solves():
    space = gharial.manifolds.VectorSpace(4)
    problem = lqr_problem()
    s = gharial.SolverProxDDP(tol=1e-9)
    s.run(problem)
    cost_before = s.results.traj_cost
    stack = gharial.CostStack(space, 2)
    assert stack.names == []
    for stage in problem.stages:
        assert stage.nu == 2
    # the stacks of lqr_problem are not reachable; build one and change its weight
    stack.addCost("control", gharial.QuadraticControlCost(space, np.zeros(2), [1.0, 1.0]), 1.0)
    stack.set_weight("control", 2.0)
    assert stack.weight("control") == 2.0
    u = np.array([1.0, 2.0])
    assert stack.value(np.zeros(4), u) == pytest.approx(2.0 * 0.5 * 5.0)
    assert cost_before > 0


def test_rollout_follows_the_dynamics(lqr):
    us = [np.array([0.1, -0.1])] * 20
    xs = lqr.rollout(us)
    a = np.eye(4)
    a[0, 2] = a[1, 3] = 0.1
    b = np.zeros((4, 2))
    b[2, 0] = b[3, 1] = 0.1
    for t in range(20):
        np.testing.assert_allclose(xs[t + 1], a @ xs[t] + b @ us[t], atol=1e-14)


def test_verbose_prints_the_iteration_table(lqr, capsys):
    s = gharial.SolverProxDDP(tol=1e-8, verbose=True)
    s.run(lqr)
    out = capsys.readouterr().out
    assert "iter" in out and "prim_err" in out


def test_ur5_reach_built_in_python_equals_the_catalogue_bit_for_bit():
    """examples/ur5_reach.py's problem, built from the URDF with the Python API."""
    from gharial import robots

    model = robots.load_builtin("ur5")
    space, dt, q0 = robots.MultibodyPhaseSpace(model), 0.01, np.array([0, -1, 1, -0.5, -0.5, 0.0])
    x0 = np.concatenate([q0, np.zeros(6)])
    step = gharial.dynamics.IntegratorSemiImplEuler(robots.MultibodyFreeFwdDynamics(space), dt)

    def cost(nu, wv, wee, scale):
        c = gharial.CostStack(space, nu)
        c.addCost("state", gharial.QuadraticStateCost(space, nu, x0, [1e-2] * 6 + [wv] * 6), scale)
        if nu:
            c.addCost("control", gharial.QuadraticControlCost(space, np.zeros(nu), [1e-4] * nu), scale)
        ee = robots.FrameTranslationResidual(space, nu, "tool0", [0.3, 0.5, 0.5])
        c.addCost("ee", gharial.QuadraticResidualCost(space, ee, [wee] * 3), scale)
        return c

    problem = gharial.TrajOptProblem(x0, [gharial.StageModel(cost(6, 0.1, 10.0, dt), step)] * 100, cost(0, 1.0, 1000.0, 1.0))
    us = [robots.generalized_gravity(model, q0)] * 100
    xs = problem.rollout(us)
    ex = gharial.problems.build("ur5")
    assert all(np.array_equal(a, b) for a, b in zip(xs, ex.xs0))
    for name in ("proxddp", "fddp"):
        mine, ref = ex.solver(name), ex.solver(name)
        mine.run(problem, xs, us)
        ref.run(ex.problem, ex.xs0, ex.us0)
        assert mine.results.num_iters == ref.results.num_iters
        assert mine.results.traj_cost == ref.results.traj_cost
        assert all(np.array_equal(a, b) for a, b in zip(mine.results.us, ref.results.us))


@pytest.mark.parametrize("example", ["quickstart.py", "ur5_reach.py", "python_cost.py"])
def test_examples_run(example):
    path = os.path.join(os.path.dirname(__file__), "..", "examples", example)
    out = subprocess.run([sys.executable, path], capture_output=True, text=True, check=True).stdout
    assert "status=converged" in out


def test_the_mpc_example_holds_the_point_against_the_unknown_push():
    path = os.path.join(os.path.dirname(__file__), "..", "examples", "mpc_point_mass.py")
    out = subprocess.run([sys.executable, path], capture_output=True, text=True, check=True).stdout
    last = out.strip().splitlines()[-1]
    u = np.array(last.split("[")[1].split("]")[0].split(), dtype=float)
    u_max = float(last.rsplit(" ", 1)[1])
    # At rest the applied force cancels the push (b u = -push: u = (-0.3, 0.2)); the
    # force bound 2 holds to the augmented Lagrangian's slack of one iteration per cycle
    # (measured 1.2e-4).
    np.testing.assert_allclose(u, [-0.3, 0.2], atol=1e-3)
    assert u_max <= 2.0 + 1e-3, last
    assert "cycles 80" in out


def test_proxnlp_kkt_option_dense_and_sparse_take_the_same_iterates():
    ex = gharial.problems.build("pendulum")
    runs = {}
    for kkt in ["dense", "sparse"]:
        s = gharial.SolverProxNLP(kkt=kkt, tol=1e-6)
        assert s.kkt == kkt
        s.run(ex.problem, ex.xs0, ex.us0)
        runs[kkt] = s.results
    assert runs["dense"].num_iters == runs["sparse"].num_iters
    assert abs(runs["dense"].traj_cost - runs["sparse"].traj_cost) <= 1e-10 * abs(runs["dense"].traj_cost)
    np.testing.assert_allclose(np.array(runs["sparse"].us), np.array(runs["dense"].us), atol=1e-9)
    with pytest.raises(ValueError, match="kkt"):
        gharial.SolverProxNLP(kkt="banded")


def test_proxddp_final_residuals_option_keeps_the_step():
    """Without the residuals at the end of the budget the returned point is the same."""
    problem = lqr_problem(bounds=0.3)
    out = {}
    for on in [True, False]:
        s = gharial.SolverProxDDP(tol=1e-12, max_iters=2, final_residuals=on)
        assert s.final_residuals == on
        s.run(problem)
        out[on] = s.results
    assert out[True].num_iters == out[False].num_iters == 2
    assert out[False].status == "max_iterations"
    assert [list(u) for u in out[True].us] == [list(u) for u in out[False].us]
    assert out[True].traj_cost == out[False].traj_cost


def test_csqp_stops_after_repeated_line_search_failures():
    ex = gharial.problems.build("acrobot")
    s = gharial.SolverCSQP(max_iters=20, max_linesearch_failures=5)
    s.run(ex.problem, ex.xs0, ex.us0)
    assert s.results.status == "linesearch_failure" and s.results.num_iters < 20
    s.max_linesearch_failures = 1000
    s.run(ex.problem, ex.xs0, ex.us0)
    assert s.results.status == "max_iterations" and s.results.num_iters == 20


def test_csqp_gains_at_a_binding_second_order_cone():
    # A point mass pushed by a force kept in a friction-like cone |u_xy| <= 0.4 u_z that
    # binds at the first knot. Reference: the sensitivity du0/dx0 by central differences
    # of ProxDDP re-solves. ALTRO's gains match it; CSQP's come from the ADMM's penalty on
    # the active cone (no curvature term): about 60 % off, never zero (they were: the
    # cone's three rows were pinned as equalities).
    from gharial import constraints, dynamics, manifolds
    dt, n, mu, g = 0.05, 30, 0.4, 9.81
    a = np.eye(6)
    a[:3, 3:] = dt * np.eye(3)
    b = np.zeros((6, 3))
    b[3:, :] = dt * np.eye(3)
    c = np.zeros(6)
    c[5] = -g * dt
    space = manifolds.VectorSpace(6)
    target = np.array([1.0, 0.5, 0.0, 0, 0, 0])

    def build(x0):
        cost = gharial.CostStack(space, 3)
        cost.addCost("x", gharial.QuadraticStateCost(space, 3, target, [10, 10, 10, 1, 1, 1]), dt)
        cost.addCost("u", gharial.QuadraticControlCost(space, np.array([0, 0, g]), [0.01] * 3), dt)
        stage = gharial.StageModel(cost, dynamics.LinearDiscreteDynamics(a, b, c))
        cone = np.array([[0, 0, mu], [1, 0, 0], [0, 1, 0.0]])
        stage.addConstraint(gharial.LinearFunction(np.zeros((3, 6)), cone, np.zeros(3)), constraints.SecondOrderCone(3))
        return gharial.TrajOptProblem(x0, [stage] * n, gharial.QuadraticStateCost(space, 0, target, [100.0] * 6))

    def solve(x0, name, **options):
        s = gharial.solver(name, **options)
        assert s.run(build(x0)), (name, s.results.status)
        return s.results

    precise = dict(tol=1e-8, mu_lower_bound=1e-10, max_iters=2000)
    u0 = solve(np.zeros(6), "proxddp", **precise).us[0]
    np.testing.assert_allclose(np.linalg.norm(u0[:2]), mu * u0[2], rtol=1e-6)  # the cone binds
    k_fd = np.zeros((3, 6))
    for i in range(6):
        e = np.zeros(6)
        e[i] = 1e-5
        k_fd[:, i] = (solve(e, "proxddp", **precise).us[0] - solve(-e, "proxddp", **precise).us[0]) / 2e-5
    error = lambda k: np.linalg.norm(np.array(k) - k_fd) / np.linalg.norm(k_fd)  # noqa: E731
    assert error(solve(np.zeros(6), "altro").gains[0]) < 0.01
    assert 0.3 < error(solve(np.zeros(6), "csqp").gains[0]) < 0.7

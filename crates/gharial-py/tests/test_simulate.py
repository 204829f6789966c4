"""Closed-loop scenarios from Python: the same closed loops as the command-line tool bit
for bit, pushes and payloads reaching the plant, and bad input as errors."""

import json
import os
import subprocess

import numpy as np
import pytest

import gharial
from gharial.problems import scenarios, simulate


def cli_simulate(args, tmp_path):
    exe = os.environ.get("GHARIAL_CLI")
    if not exe:
        pytest.skip("GHARIAL_CLI (the gharial binary) is not set; tools/test sets it")
    out = tmp_path / "cli.json"
    p = subprocess.run([exe, "simulate", *args, "--output", str(out)], check=False, capture_output=True)
    assert p.returncode == 0, p.stderr
    return json.loads(out.read_text())


def test_the_scenarios_are_listed():
    names = [n for n, _ in scenarios()]
    assert "ur5-circle-mpc" in names and "solo-walk-mpc" in names


@pytest.mark.parametrize(
    "name,extra,py",
    [
        ("ur5-circle-mpc", ["--payload", "1.5"], {"payload": 1.5}),
        ("ur5-circle-mpc-joint-bound", ["--solver", "csqp", "--max-iters", "3"], {"solver": "csqp", "max_iters": 3}),
        ("solo-walk-mpc", ["--push", "0.03,0,0.25,0", "--slope", "0.05"], {"pushes": [(0.03, (0, 0.25, 0))], "slope": 0.05}),
    ],
)
def test_closed_loops_equal_the_command_line_bit_for_bit(name, extra, py, tmp_path):
    ref = cli_simulate([name, "--duration", "0.1", *extra], tmp_path)
    rec = simulate(name, duration=0.1, **py)
    assert rec["scenario"] == ref["scenario"]
    assert rec["xs"].shape == (101, len(ref["xs"][0])) and rec["us"].shape[0] == 100
    assert np.array_equal(rec["xs"], np.array(ref["xs"]))
    assert np.array_equal(rec["us"], np.array(ref["us"]))
    assert [c["iterations"] for c in rec["cycles"]] == [c["iterations"] for c in ref["cycles"]]
    for metric, (value, _) in rec["metrics"].items():
        assert value == ref["metrics"][metric]["value"], metric


def test_a_push_changes_the_base_velocity_by_the_push():
    plain = simulate("solo-walk-mpc", duration=0.05)
    pushed = simulate("solo-walk-mpc", duration=0.05, pushes=[(0.03, (0.05, -0.3, 0.02))])
    k = 30
    assert np.array_equal(plain["xs"][:k], pushed["xs"][:k])
    base_v = 19  # nq = 19: the base's linear velocity starts the velocity part
    np.testing.assert_allclose(pushed["xs"][k, base_v:base_v + 3] - plain["xs"][k, base_v:base_v + 3],
                               [0.05, -0.3, 0.02], atol=1e-12)


def test_bad_input_is_an_error():
    with pytest.raises(gharial.GharialError, match="unknown MPC scenario"):
        simulate("nope")
    with pytest.raises(gharial.GharialError, match="no floating base"):
        simulate("ur5-circle-mpc", duration=0.1, pushes=[(0.0, (0.1, 0, 0))])
    with pytest.raises(gharial.GharialError, match="payload"):
        simulate("ur5-circle-mpc", duration=0.1, payload=-1.0)
    with pytest.raises(gharial.GharialError, match="slope and speed"):
        simulate("ur5-circle-mpc", duration=0.1, slope=0.1)
    with pytest.raises(ValueError, match="cycle_budget"):
        simulate("ur5-circle-mpc", duration=0.1, cycle_budget=-1.0)
    with pytest.raises(AttributeError, match="no option"):
        simulate("ur5-circle-mpc", duration=0.1, not_an_option=1)
    # The command line's limits hold here too (a huge duration sized the record and
    # aborted the interpreter; a huge budget panicked).
    with pytest.raises(ValueError, match="at most 5000"):
        simulate("ur5-circle-mpc", duration=1e9)
    with pytest.raises(ValueError, match="cycle_budget"):
        simulate("ur5-circle-mpc", duration=0.1, cycle_budget=1e300)
    for kw, what in [(dict(payload=101.0), "payload"), (dict(speed=2.0), "speed"), (dict(slope=0.4), "slope"),
                     (dict(pushes=[(0.1, (11.0, 0, 0))]), "push")]:
        with pytest.raises(ValueError, match=what):
            simulate("solo-walk-mpc", duration=0.1, **kw)


def test_a_fall_stops_the_loop_with_its_record():
    rec = simulate("solo-walk-mpc", duration=0.5, pushes=[(0.02, (3.0, 0.0, 0.0))])
    stopped = rec["stopped"]
    assert stopped is not None and ("diverged" in stopped["reason"] or "fell" in stopped["reason"])
    assert stopped["step"] < 500 and np.isfinite(rec["xs"]).all()
    assert rec["xs"].shape[0] == stopped["step"] + 1 and rec["us"].shape[0] == stopped["step"]
    assert rec["metrics_error"] is None and np.abs(rec["xs"][:, 19:]).max() <= 100.0
    calm = simulate("solo-walk-mpc", duration=0.05)
    assert calm["stopped"] is None and calm["xs"].shape[0] == 51


def test_the_mpc_class_follows_the_dense_kkt_optimum_from_every_measured_state():
    from conftest import lqr_kkt, lqr_problem, point_mass

    problem = lqr_problem()
    xs0, us0 = lqr_kkt()
    solver = gharial.solver("proxddp", tol=1e-10)
    mpc = gharial.MPC(problem, solver, xs0, us0, max_iters=50)
    a, b = point_mass()
    x = np.array([1.0, -0.5, 0.0, 0.2])
    for cycle in range(3):
        r = mpc.solve(x)
        assert r.status == "converged"
        xs_ref, us_ref = lqr_kkt(x0=tuple(x))
        np.testing.assert_allclose(np.array(r.us), np.array(us_ref), atol=1e-7)
        # The policy is the optimal feedback of the LQ: the KKT optimum from another state.
        x_other = x + np.array([0.05, -0.02, 0.01, 0.03])
        _, us_other = lqr_kkt(x0=tuple(x_other))
        np.testing.assert_allclose(mpc.control(x_other), us_other[0], atol=1e-7)
        x = a @ x + b @ mpc.control(x)
        assert mpc.shift() == cycle  # the stage that left comes back at the end
    assert mpc.cycles == 3 and "MPC(proxddp" in repr(mpc)


def test_the_mpc_class_refuses_bad_input():
    from conftest import lqr_problem

    problem = lqr_problem()
    xs0 = [np.zeros(4)] * 21
    us0 = [np.zeros(2)] * 20
    with pytest.raises(gharial.GharialError, match="max_iters"):
        gharial.MPC(problem, gharial.solver("fddp"), xs0, us0, max_iters=0)
    with pytest.raises(ValueError, match="max_time"):
        gharial.MPC(problem, gharial.solver("fddp"), xs0, us0, max_time=-1.0)
    with pytest.raises(ValueError, match="max_time"):
        gharial.MPC(problem, gharial.solver("fddp"), xs0, us0, max_time=float("nan"))
    with pytest.raises(ValueError, match="max_time"):
        gharial.MPC(problem, gharial.solver("fddp"), xs0, us0, max_time=1e300)
    with pytest.raises(ValueError, match="max_time"):
        gharial.solver("fddp", max_time=1e20)
    # An infinite budget is no budget, for the controller and for a solver option.
    unlimited = gharial.MPC(problem, gharial.solver("fddp", max_time=float("inf")), xs0, us0, max_time=float("inf"))
    assert unlimited.solve(np.ones(4)).status == "converged"
    mpc = gharial.MPC(problem, gharial.solver("fddp"), xs0, us0)
    with pytest.raises(ValueError):
        mpc.solve(np.zeros(3))
    with pytest.raises(gharial.GharialError):
        mpc.solve(np.array([np.nan, 0.0, 0.0, 0.0]))


def test_queued_stages_enter_the_horizon_in_turn():
    from conftest import lqr_kkt, lqr_problem

    horizon = lqr_problem(horizon=20)
    queue = lqr_problem(horizon=2).stages  # the same LQR stages, queued
    xs0, us0 = lqr_kkt()
    mpc = gharial.MPC(horizon, gharial.solver("fddp"), xs0, us0, queue=queue, max_iters=20)
    x = np.array([1.0, -0.5, 0.0, 0.2])
    entered = []
    for _ in range(4):
        r = mpc.solve(x)
        xs_ref, us_ref = lqr_kkt(x0=tuple(x))
        np.testing.assert_allclose(np.array(r.us), np.array(us_ref), atol=1e-7)
        entered.append(mpc.shift())
    # The queue's stages (20, 21), then the stages that left in their turn (0, 1).
    assert entered == [20, 21, 0, 1]
    assert mpc.stage_ids[-1] == 1 and len(mpc.stage_ids) == 20


def test_the_mpc_starts_from_the_multipliers_of_a_converged_solve():
    # Without multipliers the first one-iteration cycle from the optimum's own x0 leaves
    # it (torque 0.94 against the 0.6 bound); with them it is the solver's warm start.
    ex = gharial.problems.build("double-pendulum-box")
    p = ex.problem
    s = ex.solver("proxddp")
    assert s.run(p, ex.xs0, ex.us0)
    r0 = s.results
    mpc = gharial.MPC(p, ex.solver("proxddp"), r0.xs, r0.us, max_iters=1, lams_init=r0.lams, vs_init=r0.vs)
    r = mpc.solve(p.x0_init)
    one = ex.solver("proxddp")
    one.max_iters = 1
    one.run(p, r0.xs, r0.us, r0.lams, r0.vs)
    assert np.abs(np.array(r.us)).max() <= 0.6 + 1e-6 and r.primal_infeas < 1e-6
    np.testing.assert_allclose(np.array(r.us), np.array(one.results.us), atol=1e-12)
    with pytest.raises(ValueError, match="lams_init and vs_init"):
        gharial.MPC(p, ex.solver("proxddp"), r0.xs, r0.us, lams_init=r0.lams)


def test_a_cycle_without_iterations_keeps_the_shifted_gains():
    from conftest import lqr_problem
    problem = lqr_problem()
    xs0 = [np.zeros(4)] * 21
    us0 = [np.zeros(2)] * 20
    mpc = gharial.MPC(problem, gharial.solver("proxddp", tol=1e-10), xs0, us0, max_iters=50)
    first = mpc.solve(problem.x0_init)
    k1 = np.array(first.gains[1])
    mpc.shift()
    mpc.set_budget(1, 1e-12)
    x = np.array(first.xs[1]) + 0.01
    second = mpc.solve(x)
    assert second.num_iters == 0 and second.status == "time_budget"
    dx = np.array([0.1, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(mpc.control(x + dx) - mpc.control(x), k1 @ dx, atol=1e-12)
    with pytest.raises(ValueError, match="max_iters"):
        mpc.set_budget(0)

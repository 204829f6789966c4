"""Batch solving on threads, processes and a local Ray cluster equals sequential solves
bit for bit; a failing instance keeps its error and costs the others nothing."""

import os
import sys

import numpy as np
import pytest

import gharial
from gharial.batch import solve_one

sys.path.insert(0, os.path.dirname(__file__))
import batch_build  # noqa: E402

PARAMS = [np.array([1.0, -0.5, 0.0, 0.2]) * s for s in (0.5, 1.0, 2.0, -1.0)] + [np.array([np.nan, 0, 0, 0])]


def sequential(build):
    return [solve_one(build, p, "fddp", {"tol": 1e-10}) for p in PARAMS]


def same(results, reference):
    assert len(results) == len(reference)
    for r, ref in zip(results, reference):
        assert r["status"] == ref["status"]
        if ref["error"] is not None:
            assert r["error"] == ref["error"]
            continue
        assert r["iterations"] == ref["iterations"] and r["cost"] == ref["cost"]
        assert all(np.array_equal(a, b) for a, b in zip(r["xs"], ref["xs"]))
        assert all(np.array_equal(a, b) for a, b in zip(r["us"], ref["us"]))


@pytest.mark.parametrize("backend", ["threads", "processes"])
def test_local_backends_equal_sequential_solves(backend):
    reference = sequential(batch_build.lqr_standalone)
    assert [r["status"] for r in reference[:4]] == ["converged"] * 4
    assert reference[4]["status"] == "error" and "non-finite" in reference[4]["error"]
    results = gharial.solve_batch(batch_build.lqr_standalone, PARAMS, solver="fddp", backend=backend, options={"tol": 1e-10})
    same(results, reference)


def test_catalogue_examples_and_failing_builds_in_a_batch():
    results = gharial.solve_batch(batch_build.ur5_reach, [1, None, 2], solver="proxddp", backend="threads")
    assert [r["status"] for r in results] == ["converged", "error", "converged"]
    assert "no target for this instance" in results[1]["error"]
    assert results[0]["cost"] == results[2]["cost"]


def test_unpicklable_build_is_an_error_per_instance_with_processes():
    results = gharial.solve_batch(lambda p: batch_build.lqr_standalone(p), PARAMS[:2], backend="processes")
    assert all(r["status"] == "error" for r in results)
    # A failed instance has every key of a solved one.
    solved = gharial.solve_batch(batch_build.lqr_standalone, PARAMS[:1])[0]
    assert all(set(r) == set(solved) and r["iterations"] is None for r in results)


def test_misspelt_solver_options_and_bad_worker_counts_fail_up_front():
    with pytest.raises(ValueError, match="unknown solver"):
        gharial.solve_batch(batch_build.lqr_standalone, PARAMS[:2], solver="prox-ddp")
    with pytest.raises(AttributeError, match="no option"):
        gharial.solve_batch(batch_build.lqr_standalone, PARAMS[:2], options={"tolerance": 1e-6})
    for bad in (0, -3, 1.5):
        with pytest.raises(ValueError, match="max_workers"):
            gharial.solve_batch(batch_build.lqr_standalone, PARAMS[:2], max_workers=bad)


def test_unknown_backend():
    with pytest.raises(ValueError, match="backend"):
        gharial.solve_batch(batch_build.lqr_standalone, PARAMS, backend="mpi")


def test_ray_local_cluster_equals_sequential_solves():
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, runtime_env={"env_vars": {"PYTHONPATH": os.path.dirname(__file__)}})
    try:
        results = gharial.solve_batch(batch_build.lqr_standalone, PARAMS, solver="fddp", backend="ray", options={"tol": 1e-10})
    finally:
        ray.shutdown()
    same(results, sequential(batch_build.lqr_standalone))

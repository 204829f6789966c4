"""Batch solving: many problems, each built by ``build(param)``, on threads, processes
or a Ray cluster. A failing instance (its ``build`` raises, its solver refuses it) gives
a result with ``status == "error"`` and never costs the others their results."""

import concurrent.futures as _futures
import multiprocessing as _mp
import os as _os
import traceback as _traceback

BACKENDS = ("threads", "processes", "ray")


def _unpack(built):
    """(problem, xs0, us0, example) from what ``build`` returned."""
    from . import TrajOptProblem
    from .problems import Example

    if isinstance(built, Example):
        return built.problem, built.xs0, built.us0, built
    if isinstance(built, TrajOptProblem):
        return built, None, None, None
    if isinstance(built, tuple) and len(built) == 3:
        return built[0], built[1], built[2], None
    raise TypeError(
        "build(param) must return a TrajOptProblem, a (problem, xs0, us0) tuple or a gharial.problems.Example"
    )


def solve_one(build, param, solver="proxddp", options=None):
    """Builds and solves one instance; returns a plain dict (picklable)."""
    from . import solver as _solver

    options = dict(options or {})
    try:
        problem, xs0, us0, example = _unpack(build(param))
        s = example.solver(solver, **options) if example is not None else _solver(solver, **options)
        if xs0 is None:
            s.run(problem)
        else:
            s.run(problem, xs0, us0)
        r = s.results
        return {
            "param": param,
            "status": r.status,
            "converged": r.conv,
            "iterations": r.num_iters,
            "cost": r.traj_cost,
            "primal_infeas": r.primal_infeas,
            "dual_infeas": r.dual_infeas,
            "solve_time": r.solve_time,
            "xs": r.xs,
            "us": r.us,
            "error": None,
        }
    except Exception as e:  # one instance's failure is its own result
        return _error(param, e)


_RESULT_KEYS = ("iterations", "cost", "primal_infeas", "dual_infeas", "solve_time", "xs", "us")


def _error(param, e):
    """The result of a failed instance: every key of a solved one, ``None`` but for the
    status and the error message."""
    message = "".join(_traceback.format_exception_only(type(e), e)).strip()
    result = {"param": param, "status": "error", "converged": False, "error": message}
    result.update(dict.fromkeys(_RESULT_KEYS))
    return result


def solve_batch(build, params, solver="proxddp", backend="threads", options=None, max_workers=None):
    """Solves ``build(p)`` for every ``p`` in ``params``; returns one result dict per
    parameter, in order (keys: param, status, converged, iterations, cost,
    primal_infeas, dual_infeas, solve_time, xs, us, error).

    backend: ``"threads"`` (Rust solves in parallel, the GIL released), ``"processes"``
    (a spawn-context process pool; ``build`` must be picklable, i.e. a module-level
    function) or ``"ray"`` (Ray tasks on the cluster ``ray.init()`` connects to; the
    ``gharial[ray]`` extra).
    """
    params = list(params)
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if max_workers is not None and not (isinstance(max_workers, int) and max_workers > 0):
        raise ValueError(f"max_workers must be a positive integer or None, got {max_workers!r}")
    # A misspelt solver or option fails every instance alike: say so once, up front.
    from . import solver as _solver

    _solver(solver, **dict(options or {}))
    if backend == "ray":
        return _ray(build, params, solver, options)
    workers = max_workers or _os.cpu_count() or 1
    if backend == "threads":
        pool = _futures.ThreadPoolExecutor(max_workers=workers)
    else:
        pool = _futures.ProcessPoolExecutor(max_workers=workers, mp_context=_mp.get_context("spawn"))
    with pool:
        futures = [pool.submit(solve_one, build, p, solver, options) for p in params]
        return [_collect(f.result, p) for f, p in zip(futures, params)]


def _collect(get, param):
    try:
        return get()
    except Exception as e:  # e.g. build not picklable, a worker died
        return _error(param, e)


def _ray(build, params, solver, options):
    try:
        import ray
    except ImportError as e:
        raise ImportError("backend='ray' needs Ray: pip install 'gharial[ray]'") from e
    if not ray.is_initialized():
        ray.init()
    task = ray.remote(solve_one)
    refs = [task.remote(build, p, solver, options) for p in params]
    return [_collect(lambda r=r: ray.get(r), p) for r, p in zip(refs, params)]

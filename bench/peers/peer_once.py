#!/usr/bin/env python3
"""Solves of a peer solver on a harness problem, for `instructions.sh` and
`interleaved.sh`.

Usage: peer_once.py HARNESS_DIR PROBLEM SOLVER [REPEATS THREADS]
Builds PROBLEM and SOLVER (crocoddyl DDP/FDDP/BoxDDP/BoxFDDP, mim_solvers SQP/CSQP)
with the harness's own code and settings (`py/problems.py`, `py/run_croc.py`, tol 1e-6,
500 iterations) and solves from the harness's guess. With one repeat (the default) it
prints `iterations converged final_cost`; with REPEATS > 1 it times that many solves,
each with a fresh solver (construction not timed), with the shooting problem's
`nthreads` set to THREADS (default 1; the harness leaves crocoddyl's default, 2), and
prints `iterations median_ms min_ms` (after the harness's warm-up: eleven evaluations and
derivative passes).
"""

import os
import statistics
import sys
import time
from types import SimpleNamespace

harness, problem, solver = sys.argv[1:4]
repeats = int(sys.argv[4]) if len(sys.argv) > 4 else 1
threads = int(sys.argv[5]) if len(sys.argv) > 5 else None
sys.path.insert(0, os.path.join(harness, "py"))
import problems as P  # noqa: E402
import run_croc as R  # noqa: E402

b = P.build(problem, R.FAMILY[solver], P.default_robots_dir(), None)
if threads is not None:
    b.problem.nthreads = threads
args = SimpleNamespace(tol=1e-6, max_iters=500, csqp_eps_abs=1e-4,
                       csqp_eps_rel=1e-4, csqp_max_qp_iters=1000)
if repeats == 1:
    s, _ = R.make_solver(solver, b.problem, args, b.N)
    converged = s.solve(b.xs0, b.us0, args.max_iters, False)
    print(s.iter, converged, b.problem.calc(list(s.xs), list(s.us)))
else:
    # As the harness: eleven evaluations and derivative passes before the timed solves.
    for _ in range(11):
        b.problem.calc(b.xs0, b.us0)
        b.problem.calcDiff(b.xs0, b.us0)
    times = []
    for _ in range(repeats):
        s, _ = R.make_solver(solver, b.problem, args, b.N)
        t = time.perf_counter()
        s.solve(b.xs0, b.us0, args.max_iters, False)
        times.append((time.perf_counter() - t) * 1e3)
    print(s.iter, f"{statistics.median(times):.4f}", f"{min(times):.4f}")

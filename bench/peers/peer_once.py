#!/usr/bin/env python3
"""One solve of a peer solver on a harness problem, for `instructions.sh`.

Usage: peer_once.py HARNESS_DIR PROBLEM SOLVER
Builds PROBLEM and SOLVER (crocoddyl DDP/FDDP/BoxDDP/BoxFDDP, mim_solvers SQP/CSQP)
with the harness's own code and settings (`py/problems.py`, `py/run_croc.py`, tol 1e-6,
500 iterations), solves once from the harness's guess and prints
`iterations converged final_cost` on one line.
"""

import os
import sys
from types import SimpleNamespace

harness, problem, solver = sys.argv[1:4]
sys.path.insert(0, os.path.join(harness, "py"))
import problems as P  # noqa: E402
import run_croc as R  # noqa: E402

b = P.build(problem, R.FAMILY[solver], P.default_robots_dir(), None)
args = SimpleNamespace(tol=1e-6, max_iters=500, csqp_eps_abs=1e-4,
                       csqp_eps_rel=1e-4, csqp_max_qp_iters=1000)
s, _ = R.make_solver(solver, b.problem, args, b.N)
converged = s.solve(b.xs0, b.us0, args.max_iters, False)
print(s.iter, converged, b.problem.calc(list(s.xs), list(s.us)))

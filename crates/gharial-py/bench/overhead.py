"""Time spent outside the Rust solve loop when solving with Rust models from Python:
wall time of ``solver.run`` against the solve time the solver reports
(``results.solve_time``), in rounds that interleave the cases (``--block`` consecutive
solves of each case per round, so that most solves find the caches as a repeated solve
does). The difference holds the Python call, the conversion of the guess and the guess
checks of the Rust core.

    python crates/gharial-py/bench/overhead.py [--repeats 30] [--block 3]

Guesses: ``list`` (a list of 1-D arrays, as ``results.xs`` gives), ``2-D`` (one array
per trajectory), ``none`` (the solver rolls out zero controls, in Rust). Build the
package in release mode for this (pip install ./crates/gharial-py).
"""

import argparse
import time

import numpy as np

import gharial

CASES = [
    ("ur5", "proxddp", "list"),
    ("ur5", "fddp", "list"),
    ("pendulum", "proxddp", "list"),
    ("peers-lqr", "proxddp", "list"),
    ("peers-lqr", "proxddp", "2-D"),
    ("peers-lqr", "proxddp", "none"),
]


def guess(ex, kind):
    if kind == "none":
        return ()
    if kind == "2-D":
        return (np.array(ex.xs0), np.array(ex.us0))
    return (list(ex.xs0), list(ex.us0))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--block", type=int, default=3)
    args = ap.parse_args()
    setups = []
    for name, solver, kind in CASES:
        ex = gharial.problems.build(name)
        s = ex.solver(solver)
        g = guess(ex, kind)
        s.run(ex.problem, *g)  # set-up and warm-up
        setups.append(((name, solver, kind), s, ex.problem, g))
    samples = {case: [] for case, *_ in setups}
    for _ in range(args.repeats):  # interleaved rounds of `--block` solves per case
        for case, s, problem, g in setups:
            for _ in range(args.block):
                t0 = time.perf_counter()
                s.run(problem, *g)
                wall = time.perf_counter() - t0
                samples[case].append((wall, s.results.solve_time))
    print(f"{'problem':<11}{'solver':<9}{'guess':<6}{'solve ms':>10}{'outside µs':>12}"
          f"{'outside % median':>18}{'min':>7}{'max':>7}")
    for (name, solver, kind), rows in samples.items():
        wall = np.array([w for w, _ in rows])
        rust = np.array([r for _, r in rows])
        share = 100 * (wall - rust) / wall
        print(f"{name:<11}{solver:<9}{kind:<6}{1e3 * np.median(rust):>10.3f}"
              f"{1e6 * np.median(wall - rust):>12.1f}{np.median(share):>18.2f}"
              f"{share.min():>7.2f}{share.max():>7.2f}")


if __name__ == "__main__":
    main()

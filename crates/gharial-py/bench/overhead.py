"""Time spent in Python around a solve with Rust models: wall time of ``solver.run`` from
Python against the Rust solve time it reports (``results.solve_time``), interleaved.

    python crates/gharial-py/bench/overhead.py [--repeats 30]

Build the package in release mode for this (pip install ./crates/gharial-py).
"""

import argparse
import time

import numpy as np

import gharial

CASES = [("ur5", "proxddp"), ("ur5", "fddp"), ("pendulum", "proxddp"), ("peers-lqr", "proxddp")]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=30)
    args = ap.parse_args()
    setups = []
    for name, solver in CASES:
        ex = gharial.problems.build(name)
        s = ex.solver(solver)
        problem, xs, us = ex.problem, ex.xs0, ex.us0
        s.run(problem, xs, us)  # set-up and warm-up
        setups.append((name, solver, s, problem, xs, us))
    samples = {(n, so): [] for n, so, *_ in setups}
    for _ in range(args.repeats):  # interleaved rounds
        for name, solver, s, problem, xs, us in setups:
            t0 = time.perf_counter()
            s.run(problem, xs, us)
            wall = time.perf_counter() - t0
            samples[(name, solver)].append((wall, s.results.solve_time))
    print(f"{'problem':<12}{'solver':<10}{'solve ms (median)':>18}{'outside Rust % median':>24}{'min':>8}{'max':>8}")
    for (name, solver), rows in samples.items():
        wall = np.array([w for w, _ in rows])
        rust = np.array([r for _, r in rows])
        share = 100 * (wall - rust) / wall
        print(f"{name:<12}{solver:<10}{1e3 * np.median(rust):>18.3f}{np.median(share):>24.2f}{share.min():>8.2f}{share.max():>8.2f}")


if __name__ == "__main__":
    main()

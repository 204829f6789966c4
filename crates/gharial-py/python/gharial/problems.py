"""The catalogue of built-in problems (those of ``gharial list``)::

    ex = gharial.problems.build("ur5")
    solver = ex.solver("fddp")
    solver.run(ex.problem, ex.xs0, ex.us0)

and the closed-loop scenarios (those of ``gharial simulate``)::

    rec = gharial.problems.simulate("solo-walk-mpc", duration=2.0, payload=0.2,
                                    pushes=[(1.0, (0.0, 0.3, 0.0))])
    rec["metrics"]["velocity error / command"], rec["xs"].shape
"""

from ._gharial import problems as _p

Example = _p.Example
build = _p.build
names = _p.names
catalogue = _p.catalogue
scenarios = _p.scenarios
simulate = _p.simulate

__all__ = ["Example", "build", "names", "catalogue", "scenarios", "simulate"]

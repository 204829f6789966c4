"""The catalogue of built-in problems (those of ``gharial list``)::

    ex = gharial.problems.build("ur5")
    solver = ex.solver("fddp")
    solver.run(ex.problem, ex.xs0, ex.us0)
"""

from ._gharial import problems as _p

Example = _p.Example
build = _p.build
names = _p.names
catalogue = _p.catalogue

__all__ = ["Example", "build", "names", "catalogue"]

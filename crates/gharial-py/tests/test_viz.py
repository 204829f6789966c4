"""Pictures from Python: results plotted (files decode as PNG / parse as SVG, the bounds
of a bounded problem drawn), several solves on one convergence plot, and the viewer page
of the UR5 reach (its scene embedded, the robot's configuration taken from the states)."""

import json
import struct
import xml.etree.ElementTree as ET

import numpy as np
import pytest

import gharial
from conftest import lqr_problem


def png_size(path):
    with open(path, "rb") as f:
        head = f.read(24)
    assert head[:8] == b"\x89PNG\r\n\x1a\n", path
    return struct.unpack(">II", head[16:24])


def test_results_plot_writes_convergence_and_trajectory(tmp_path):
    problem = lqr_problem(bounds=0.3)
    s = gharial.SolverProxDDP(tol=1e-8)
    assert s.run(problem)
    files = s.results.plot(str(tmp_path), name="lqr", dt=0.1, problem=problem)
    assert [f.rsplit("/", 1)[1] for f in files] == ["lqr-convergence.png", "lqr-trajectory.png"]
    assert png_size(files[0]) == (900, 560) and png_size(files[1]) == (900, 720)
    svg = s.results.plot(str(tmp_path), name="lqr", problem=problem, format="svg")[1]
    texts = [t.text.strip() for t in ET.parse(svg).iter("{http://www.w3.org/2000/svg}text") if t.text]
    assert "bounds" in texts and "node" in texts  # the bounds' legend; nodes without dt
    with pytest.raises(ValueError, match="png"):
        s.results.plot(str(tmp_path), format="pdf")


def test_several_solvers_on_one_convergence_plot(tmp_path):
    problem = lqr_problem()
    runs = []
    for name in ["proxddp", "fddp", "sqp"]:
        s = gharial.solver(name, tol=1e-9)
        assert s.run(problem)
        runs.append((name, s.results))
    path = str(tmp_path / "c.svg")
    gharial.plot_convergence(runs, path, title="three solvers")
    texts = [t.text.strip() for t in ET.parse(path).iter("{http://www.w3.org/2000/svg}text") if t.text]
    for name in ["proxddp", "fddp", "sqp"]:
        assert any(t.startswith(name) for t in texts), texts
    with pytest.raises(ValueError, match="no runs"):
        gharial.plot_convergence([], path)


def test_view_writes_the_ur5_page(tmp_path):
    ex = gharial.problems.build("ur5")
    s = ex.solver("proxddp")
    assert s.run(ex.problem, ex.xs0, ex.us0)
    robot = gharial.robots.load_builtin("ur5")
    path = gharial.view(s.results.xs, robot, str(tmp_path / "ur5.html"), ex.dt, targets=[(0.3, 0.5, 0.5)], title="UR5")
    html = open(path).read()
    start = html.index('<script id="scene" type="application/json">')
    scene = json.loads(html[html.index(">", start) + 1 : html.index("</script>", start)])
    assert scene["frames"] == len(s.results.xs) and scene["dt"] == ex.dt
    assert scene["markers"][0]["pose"][9:] == [0.3, 0.5, 0.5]
    assert len(scene["bodies"]) >= 6 and all(len(b["poses"]) == scene["frames"] for b in scene["bodies"])
    # A Results object stands for its states.
    again = gharial.view(s.results, robot, str(tmp_path / "again.html"), ex.dt, targets=[(0.3, 0.5, 0.5)], title="UR5")
    assert open(again).read() == html
    with pytest.raises(ValueError, match="entries"):
        gharial.view([np.zeros(3)], robot, str(tmp_path / "x.html"), 0.01)

"""The solver refits after changes, coalesces them, and never publishes a stale fit."""
from __future__ import annotations

from prismstation.gui.solver import Solver
from prismstation.io.project import load_project, solve_project
from prismstation.model.points import Measurement


def test_many_edits_one_current_solution(qtbot, demo):
    project = load_project(demo.path)
    solver = Solver()
    got = []
    solver.solution_changed.connect(got.append)
    solver.set_project(project)
    qtbot.waitUntil(lambda: bool(got) and not solver.busy(), timeout=10000)
    n0 = len(got)
    m = project.measurement("G1", "N")
    for i in range(20):  # one event-loop turn: coalesced by the zero-delay timer
        project.set_measurement(Measurement("G1", "N", m.x + 0.01 * i, m.y))
    qtbot.waitUntil(lambda: not solver.busy() and got[-1].revision == project.revision, timeout=10000)
    assert len(got) - n0 <= 2
    ref = solve_project(project)
    assert got[-1].point("G1").residual_px["N"] == ref.point("G1").residual_px["N"]
    assert solver.last_fit_ms > 0
    solver.shutdown()


def test_a_fit_of_the_previous_project_is_dropped(qtbot, demo):
    a, b = load_project(demo.path), load_project(demo.path)
    b.remove_point("I1")
    solver = Solver()
    got = []
    solver.solution_changed.connect(got.append)
    solver.set_project(a)
    solver._start()          # a's fit is running in the worker...
    solver.set_project(b)    # ...when b is opened
    qtbot.waitUntil(lambda: not solver.busy() and bool(got), timeout=10000)
    qtbot.wait(50)
    assert all(s.point("I1") is None for s in got)
    assert solver.solution.point("I1") is None
    solver.shutdown()


def test_window_without_a_project(qtbot):
    from prismstation.gui.app import make_app
    from prismstation.gui.main_window import MainWindow
    make_app()
    win = MainWindow(interactive=False)
    qtbot.addWidget(win)
    win.show()
    assert not win.a_save.isEnabled() and not win.a_new_point.isEnabled()
    win.place("N", 1.0, 2.0)      # nothing to do, nothing raised
    win.step_point(1)
    win.new_point()
    assert win.export_report("/nonexistent/x.csv") is False
    win.close()

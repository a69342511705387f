"""The solver refits after changes, coalesces them, and never publishes a stale fit."""
from __future__ import annotations

from prismstation.gui.solver import Solver
from prismstation.io.project import load_project
from prismstation.ops.fit import solve_project
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


def test_quick_fits_run_inline_slow_ones_in_the_worker(qtbot, demo):
    """A fit whose predecessor took less than ``inline_ms`` runs on the GUI thread in the same
    event-loop turn (no hand-off); otherwise, and for the first fit, in the worker."""
    import threading

    from prismstation.gui import solver as solver_mod
    project = load_project(demo.path)
    threads = []
    real = solver_mod.solve_project

    def spy(*a, **k):
        threads.append(threading.current_thread())
        return real(*a, **k)
    solver_mod.solve_project = spy
    try:
        solver = Solver()
        solver.set_project(project)
        qtbot.waitUntil(lambda: solver.solution is not None and not solver.busy(), timeout=10000)
        assert threads[-1] is not threading.main_thread()        # the first: no estimate yet
        # the rule, not this machine's speed of the moment: a fit as large as the last is quick
        solver.inline_ms = 10 * solver.last_fit_ms
        m = project.measurement("G1", "N")
        project.set_measurement(Measurement("G1", "N", m.x + 0.5, m.y))
        solver._start()                                          # what the zero-delay timer does
        assert threads[-1] is threading.main_thread()
        assert solver.solution.revision == project.revision and not solver.busy()
        solver.inline_ms = 10 * solver.last_fit_ms
        # an import that makes the project 40 times larger: expected too slow, to the worker
        n = len(project.points)
        project.load([], [Measurement(f"T{i}", "N", 10.0 + i % 500, 10.0 + i // 500)
                          for i in range(40 * n)])
        k = len(threads)
        solver._start()
        qtbot.waitUntil(lambda: solver.solution.revision == project.revision and not solver.busy(),
                        timeout=20000)
        assert len(threads) == k + 1 and threads[-1] is not threading.main_thread()
        solver.inline_ms = 0.0                                   # as if the last fit were slow
        project.set_measurement(Measurement("G1", "N", m.x + 1.0, m.y))
        qtbot.waitUntil(lambda: solver.solution.revision == project.revision and not solver.busy(),
                        timeout=10000)
        assert threads[-1] is not threading.main_thread()
        solver.shutdown()
    finally:
        solver_mod.solve_project = real


def test_an_unexpected_error_in_an_inline_fit_is_reported_not_raised(qtbot, demo):
    from prismstation.gui import solver as solver_mod
    project = load_project(demo.path)
    solver = Solver()
    failed = []
    solver.failed.connect(failed.append)
    solver.set_project(project)
    qtbot.waitUntil(lambda: solver.solution is not None and not solver.busy(), timeout=10000)
    real = solver_mod.solve_project

    def broken(*a, **k):
        raise ZeroDivisionError("boom")
    solver_mod.solve_project = broken
    try:
        m = project.measurement("G1", "N")
        project.set_measurement(Measurement("G1", "N", m.x + 0.5, m.y))
        solver.inline_ms = float("inf")  # inline, whatever this machine's speed now
        solver._start()
    finally:
        solver_mod.solve_project = real
    assert failed and "ZeroDivisionError: boom" in failed[-1]
    solver.shutdown()
